//! What the page's denoiser needs on WebGPU, where nothing may block: the accumulation read
//! into a staging buffer of its own ([`StagedRead`]), the filter pass compiled and run as
//! promises; and, for both runtimes, the filter's remodulation done by
//! `tracer::denoise` itself over the output the device returned ([`Replay`]).

use std::cell::RefCell;
use std::rc::Rc;

use glam::Vec4;
use tracer::backend::wgpu::{DeviceRenderer, WgpuDevice, WgpuFilter};
use tracer::backend::{GuideSums, RenderError, Renderer, RendererInfo};
use tracer::kernel::denoise::FilterImage;
use tracer::kernel::scene_data::Scene;
use tracer::pack::Packed;

/// A result that a promise fills in; the page's frame loop polls it.
pub type Slot<T> = Rc<RefCell<Option<Result<T, String>>>>;

/// A read of the accumulation into a staging buffer of its own (not the renderer's one
/// read-back buffer, which the page's `readAccumulation` and screenshots use: a second read
/// while one is mapped is an error): the copy is on the queue, the map requested; `mapped` is
/// filled when the device has it.
pub struct StagedRead {
    buffer: wgpu::Buffer,
    mapped: Slot<()>,
}

impl StagedRead {
    /// Queues the copy of `renderer`'s accumulation and its map.
    pub fn queue(renderer: &dyn DeviceRenderer) -> StagedRead {
        let device = renderer.device();
        let source = renderer.sums();
        let scene = &renderer.packed().scene;
        let size = scene.width as u64 * scene.height as u64 * 16;
        let buffer = device.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("lightport denoiser read-back"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = device.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(source, 0, &buffer, 0, size);
        device.queue.submit([encoder.finish()]);
        let mapped: Slot<()> = Rc::new(RefCell::new(None));
        let slot = mapped.clone();
        buffer.slice(..).map_async(wgpu::MapMode::Read, move |result| {
            *slot.borrow_mut() = Some(result.map_err(|e| format!("mapping the accumulation failed: {e}")));
        });
        StagedRead { buffer, mapped }
    }

    /// The accumulation, once mapped (`None`: not yet).
    pub fn take(&self) -> Option<Result<Vec<Vec4>, String>> {
        let mapped = self.mapped.borrow_mut().take()?;
        Some(mapped.and_then(|()| {
            let texels = {
                let view = self.buffer.slice(..).get_mapped_range().map_err(|e| format!("reading the map: {e}"))?;
                view.chunks_exact(16)
                    .map(|t| {
                        let f = |i: usize| f32::from_le_bytes([t[i], t[i + 1], t[i + 2], t[i + 3]]);
                        Vec4::new(f(0), f(4), f(8), f(12))
                    })
                    .collect()
            };
            self.buffer.unmap();
            Ok(texels)
        }))
    }
}

/// The filter pass on a device: compiling (a promise), then compiled, or failed.
pub enum GpuFilter {
    Compiling(Slot<Rc<WgpuFilter>>),
    Ready(Rc<WgpuFilter>),
}

impl GpuFilter {
    /// Starts compiling the filter pass on `device`.
    pub fn compile(device: &WgpuDevice) -> GpuFilter {
        let slot: Slot<Rc<WgpuFilter>> = Rc::new(RefCell::new(None));
        let (filled, device) = (slot.clone(), device.clone());
        wasm_bindgen_futures::spawn_local(async move {
            let filter = WgpuFilter::new(&device).await.map(Rc::new).map_err(|e| e.to_string());
            *filled.borrow_mut() = Some(filter);
        });
        GpuFilter::Compiling(slot)
    }

    /// The compiled filter (`Ok(None)`: still compiling).
    pub fn ready(&mut self) -> Result<Option<Rc<WgpuFilter>>, String> {
        if let GpuFilter::Compiling(slot) = self {
            let Some(result) = slot.borrow_mut().take() else { return Ok(None) };
            *self = GpuFilter::Ready(result.map_err(|e| format!("the WebGPU filter pass: {e}"))?);
        }
        match self {
            GpuFilter::Ready(f) => Ok(Some(f.clone())),
            GpuFilter::Compiling(_) => Ok(None),
        }
    }
}

/// Queues the passes over `image` on `device`; the slot receives the last pass's output.
pub fn run_filter(filter: &WgpuFilter, device: &WgpuDevice, image: &FilterImage) -> Result<Slot<Vec<Vec4>>, String> {
    let read = filter.run(device, image).map_err(|e| e.to_string())?;
    let slot: Slot<Vec<Vec4>> = Rc::new(RefCell::new(None));
    let filled = slot.clone();
    wasm_bindgen_futures::spawn_local(async move {
        let output = read.await.map_err(|e| e.to_string());
        *filled.borrow_mut() = Some(output);
    });
    Ok(slot)
}

/// A "renderer" whose filter passes return the output the device already computed, so that
/// `tracer::denoise::denoise_on` (demodulation, passes, remodulation) finishes an asynchronous
/// run with the very code the CLI runs. It renders nothing.
pub struct Replay<'a> {
    pub packed: &'a Packed,
    pub output: Option<Vec<Vec4>>,
}

impl Replay<'_> {
    fn refuse(what: &'static str) -> RenderError {
        RenderError::Unsupported { runtime: "replay", what }
    }
}

impl Renderer for Replay<'_> {
    fn describe(&self) -> RendererInfo {
        RendererInfo { runtime: "replay", device: "the WebGPU filter's output".into(), limits: Vec::new() }
    }
    fn packed(&self) -> &Packed {
        self.packed
    }
    fn frames(&self) -> u32 {
        0
    }
    fn rows_left(&self) -> u32 {
        0
    }
    fn render_band(&mut self, _rows: u32) -> Result<bool, RenderError> {
        Err(Self::refuse("renders nothing"))
    }
    fn finish(&self) -> Result<(), RenderError> {
        Ok(())
    }
    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError> {
        Err(Self::refuse("has no accumulation"))
    }
    fn guide_sums(&self) -> Result<GuideSums, RenderError> {
        Err(Self::refuse("has no guide"))
    }
    fn set_uniforms(&mut self, _update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError> {
        Err(Self::refuse("has no uniforms"))
    }
    fn take_geometry(&mut self, _moved: Packed) -> Result<(), RenderError> {
        Err(Self::refuse("has no geometry"))
    }
    fn take_scene(&mut self, _scene: Packed) -> Result<(), RenderError> {
        Err(Self::refuse("has no scene of its own"))
    }
    fn restart(&mut self) -> Result<(), RenderError> {
        Ok(())
    }
    fn denoise_passes(&mut self, _image: FilterImage) -> Result<Vec<Vec4>, RenderError> {
        self.output.take().ok_or_else(|| Self::refuse("replays one filter output only once"))
    }
}
