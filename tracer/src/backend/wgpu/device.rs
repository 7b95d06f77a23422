//! The wgpu runtime's device: an adapter, its device and queue, and the limits they offer.

#[cfg(not(target_arch = "wasm32"))]
use lightport_codegen::Generated;

#[cfg(not(target_arch = "wasm32"))]
use super::compile_pipeline;
use super::WgpuError;

/// What the adapter reports about itself, and the limits the renderer works under.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WgpuInfo {
    /// The adapter's name, e.g. "llvmpipe (LLVM 19.1.7, 256 bits)".
    pub adapter: String,
    /// The driver and its version, e.g. "llvmpipe" / "Mesa 25.0.7 (LLVM 19.1.7)".
    pub driver: String,
    /// "Vulkan", "Metal", "Dx12", "BrowserWebGpu".
    pub backend: String,
    /// The storage-buffer binding size used (the device's, or the smaller option).
    pub max_storage_buffer_binding_size: u64,
    pub max_buffer_size: u64,
}

/// A device and queue with the adapter's limits, as [`WgpuRenderer::new`] takes them, and the
/// instance and adapter they came from (a canvas's surface is created on the instance and
/// configured from the adapter's capabilities). Clones share the device.
#[derive(Clone)]
pub struct WgpuDevice {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: WgpuInfo,
    pub limits: wgpu::Limits,
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
}

impl WgpuDevice {
    /// The best adapter of `backends` (high performance first) and a device with every limit
    /// it offers (WebGPU's defaults, e.g. 128 MiB storage bindings, would refuse scenes the
    /// hardware holds).
    pub async fn request(backends: wgpu::Backends) -> Result<Self, WgpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            })
            .await
            .map_err(|e| WgpuError::NoAdapter { backends: format!("{backends:?}"), detail: e.to_string() })?;
        let adapter_info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("lightport"),
                required_features: wgpu::Features::empty(),
                required_limits: limits.clone(),
                ..Default::default()
            })
            .await
            .map_err(|e| WgpuError::Device { adapter: adapter_info.name.clone(), detail: e.to_string() })?;
        let info = WgpuInfo {
            adapter: adapter_info.name.clone(),
            driver: format!("{} {}", adapter_info.driver, adapter_info.driver_info).trim().to_string(),
            backend: format!("{:?}", adapter_info.backend),
            max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
            max_buffer_size: limits.max_buffer_size,
        };
        Ok(WgpuDevice { device, queue, info, limits, instance, adapter })
    }

    /// Resolves when everything submitted so far has run on the device (never blocks; in the
    /// browser, `onSubmittedWorkDone`).
    pub fn done(&self) -> impl std::future::Future<Output = ()> + 'static {
        let (sender, receiver) = super::oneshot::channel();
        self.queue.on_submitted_work_done(move || sender.send(()));
        async move {
            let _ = receiver.await;
        }
    }

    /// The native default: Vulkan, Metal or DX12 (whichever the platform has).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn native() -> Result<Self, WgpuError> {
        pollster::block_on(Self::request(wgpu::Backends::PRIMARY))
    }

    /// [`compile_pipeline`] with the layout the shader implies, waiting for the result.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn compile(&self, generated: &Generated) -> Result<wgpu::ComputePipeline, WgpuError> {
        pollster::block_on(compile_pipeline(&self.device, generated, None))
    }
}
