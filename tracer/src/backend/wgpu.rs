//! The wgpu backend: the kernel's generated WGSL compute shader, dispatched once per frame over
//! the packed scene uploaded as storage buffers, adding one sample per pixel to an accumulation
//! buffer.
//!
//! [`WgpuRenderer`] only needs a [`wgpu::Device`] and its queue, so the same code drives native
//! Vulkan/Metal/DX12 and (on wasm) the browser's WebGPU; only device creation differs.
//! Natively, [`WgpuRenderer::headless`] creates its own device (Vulkan; Mesa lavapipe without a
//! GPU).
//!
//! Layout, as the generated shader expects it (see `shaders-generated/*.wgsl`), read back from
//! the shader itself (naga's reflection) rather than assumed, because specialisation removes
//! arrays and renumbers the bindings:
//! - every `Texels<Vec4>` / `Texels<UVec4>` field `f` of the kernel's `Scene` that the variant
//!   keeps is the read-only storage buffer `scene_f`: the packed array exactly as packed (no 2D
//!   shape: a storage buffer is indexed directly);
//! - the scalar and vector fields are the members of the uniform struct `scene`, at the offsets
//!   WGSL's layout rules give them;
//! - `lp_accumulation` is the running sum (rgb: sum of samples, w: number of finite samples),
//!   one read-write storage buffer updated in place (a compute invocation owns its pixel, so no
//!   ping-pong is needed), and `lp_target` the image size.
//!
//! A resource the shader declares and this backend does not know is an error, as is a `Scene`
//! member it has no value for. The compute path is one dispatch of one entry point over the
//! image; see `docs/backends.md` for how stages over ray queues would extend it.

use std::borrow::Cow;
use std::sync::{Arc, Mutex};

use glam::{Vec4, Vec4Swizzles};
use lightport_codegen::{Generated, Target};
use wgpu::util::DeviceExt;

use super::gl::{scene_bindings, Binding, SCENE_UNIFORM_PREFIX};
use super::{frame_seed, Image};
use crate::kernel::scene_data::Scene;
use crate::kernel::ShaderError;
use crate::pack::Packed;

/// The read-write storage buffer holding the running sum (written by codegen's entry point).
pub const ACCUMULATION_BUFFER: &str = "lp_accumulation";
/// The uniform holding the image size (written by codegen's entry point).
pub const TARGET_UNIFORM: &str = "lp_target";
/// The uniform struct holding the `Scene`'s scalar and vector fields.
pub const SCENE_UNIFORM: &str = "scene";
/// The compute entry point codegen writes.
pub const ENTRY_POINT: &str = "main";
/// Workgroup size of the generated entry point (`@workgroup_size(8, 8)`).
pub const WORKGROUP_SIZE: [u32; 2] = [8, 8];

/// The Debian packages that provide a Vulkan driver without a GPU (Mesa lavapipe).
pub const VULKAN_PACKAGES: &str = "mesa-vulkan-drivers libvulkan1";

/// Why the wgpu backend cannot render.
#[derive(Debug, thiserror::Error)]
pub enum WgpuError {
    #[error(
        "no wgpu adapter ({backends}): {detail}. Install a Vulkan driver; on Debian or Ubuntu, \
         `apt-get install {VULKAN_PACKAGES}` (Mesa lavapipe runs on the CPU)"
    )]
    NoAdapter { backends: String, detail: String },
    #[error("the wgpu device could not be created on {adapter}: {detail}")]
    Device { adapter: String, detail: String },
    #[error("the scene does not fit this device: `{array}` needs {bytes} bytes but {limit} is {max}")]
    SceneTooLarge { array: String, bytes: u64, limit: &'static str, max: u64 },
    #[error("the image is {width}x{height}: {what} needs {needed} but this device's {limit} is {max}")]
    ImageTooLarge { width: u32, height: u32, what: &'static str, needed: u64, limit: &'static str, max: u64 },
    #[error("the shader needs {needed} for {limit} but this device allows {max}")]
    Unsupported { limit: &'static str, needed: u64, max: u64 },
    #[error(transparent)]
    Codegen(#[from] ShaderError),
    #[error("the WGSL compute shader was rejected (wgpu's messages, with the kernel's Rust locations):\n{log}")]
    Compile { log: String },
    #[error("the shader declares `{name}`, which the wgpu backend does not bind{detail}")]
    UnboundResource { name: String, detail: String },
    #[error("the image size is fixed at {width}x{height} when the renderer is created; create one for {wanted}")]
    SizeChanged { width: u32, height: u32, wanted: String },
    #[error("wgpu {what} failed: {detail}")]
    Wgpu { what: &'static str, detail: String },
}

/// Options for [`WgpuRenderer::with_options`].
#[derive(Clone, Debug, Default)]
pub struct WgpuOptions {
    /// Use at most this storage-buffer binding size even where the device allows more (e.g. to
    /// check that a scene fits WebGPU's default 128 MiB, or to test the limit errors).
    pub max_storage_buffer_binding_size: Option<u64>,
}

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

/// A device and queue with the adapter's limits, as [`WgpuRenderer::new`] takes them.
pub struct WgpuDevice {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: WgpuInfo,
    pub limits: wgpu::Limits,
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
        Ok(WgpuDevice { device, queue, info, limits })
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

/// Where each resource of the generated shader is bound, as the shader declares it.
#[derive(Clone, Debug, Default)]
struct ShaderLayout {
    /// The `scene` uniform: binding, size, and each member's (name, offset).
    scene_uniform: Option<UniformLayout>,
    /// (field name, group, binding) of every `scene_*` storage buffer.
    storage: Vec<(String, u32, u32)>,
    accumulation: Option<(u32, u32)>,
    target: Option<UniformLayout>,
}

#[derive(Clone, Debug)]
struct UniformLayout {
    group: u32,
    binding: u32,
    size: u32,
    members: Vec<(String, u32)>,
}

/// Reads the resource layout of the generated shader with naga (the WGSL front end wgpu uses).
fn reflect(generated: &Generated) -> Result<ShaderLayout, WgpuError> {
    let module = naga::front::wgsl::parse_str(&generated.source).map_err(|e| WgpuError::Compile {
        log: annotate_messages(
            &[Message {
                text: e.emit_to_string(&generated.source),
                line: e.location(&generated.source).map(|l| l.line_number),
            }],
            generated,
        ),
    })?;
    let mut layout = ShaderLayout::default();
    for (_, global) in module.global_variables.iter() {
        let (Some(name), Some(binding)) = (&global.name, &global.binding) else { continue };
        let uniform = || match &module.types[global.ty].inner {
            naga::TypeInner::Struct { members, span } => Some(UniformLayout {
                group: binding.group,
                binding: binding.binding,
                size: *span,
                members: members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect(),
            }),
            _ => None,
        };
        match (name.as_str(), global.space) {
            (SCENE_UNIFORM, naga::AddressSpace::Uniform) => layout.scene_uniform = uniform(),
            (TARGET_UNIFORM, naga::AddressSpace::Uniform) => layout.target = uniform(),
            (ACCUMULATION_BUFFER, naga::AddressSpace::Storage { .. }) => {
                layout.accumulation = Some((binding.group, binding.binding))
            }
            (n, naga::AddressSpace::Storage { access }) if n.starts_with(SCENE_UNIFORM_PREFIX) => {
                if access.contains(naga::StorageAccess::STORE) {
                    return Err(WgpuError::UnboundResource {
                        name: n.to_string(),
                        detail: " as a writable buffer (scene data is read-only)".into(),
                    });
                }
                layout.storage.push((n[SCENE_UNIFORM_PREFIX.len()..].to_string(), binding.group, binding.binding));
            }
            (n, space) => {
                return Err(WgpuError::UnboundResource { name: n.to_string(), detail: format!(" (in {space:?})") })
            }
        }
    }
    if layout.accumulation.is_none() || layout.target.is_none() {
        return Err(WgpuError::UnboundResource {
            name: format!("{ACCUMULATION_BUFFER} / {TARGET_UNIFORM}"),
            detail: ": the generated entry point lacks them".into(),
        });
    }
    Ok(layout)
}

/// The bytes of the `scene` uniform struct: each member's value at its WGSL offset.
fn scene_uniform_bytes(layout: &UniformLayout, scene: &Scene) -> Result<Vec<u8>, WgpuError> {
    let bindings = scene_bindings(scene);
    let mut bytes = vec![0u8; layout.size as usize];
    for (member, offset) in &layout.members {
        let value = bindings.iter().find(|(n, _)| n == member).map(|(_, b)| b);
        let words: Vec<u32> = match value {
            Some(Binding::F32(x)) => vec![x.to_bits()],
            Some(Binding::U32(x)) => vec![**x],
            Some(Binding::Vec3(v)) => v.to_array().map(f32::to_bits).to_vec(),
            Some(other) => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{SCENE_UNIFORM}.{member}"),
                    detail: format!(" as a uniform member (the Scene field is {})", other.dsl_type()),
                })
            }
            None => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{SCENE_UNIFORM}.{member}"),
                    detail: String::new(),
                })
            }
        };
        let start = *offset as usize;
        for (i, w) in words.iter().enumerate() {
            bytes[start + 4 * i..start + 4 * i + 4].copy_from_slice(&w.to_le_bytes());
        }
    }
    Ok(bytes)
}

/// One message of the shader compiler, at a generated line when it names one.
struct Message {
    text: String,
    line: Option<u32>,
}

/// The messages with, under each that names a generated line, that line and the Rust location
/// it was generated from.
fn annotate_messages(messages: &[Message], generated: &Generated) -> String {
    let mut out = String::new();
    for m in messages {
        out.push_str(m.text.trim_end());
        out.push('\n');
        let Some(n) = m.line else { continue };
        if let Some(text) = generated.source.lines().nth((n as usize).saturating_sub(1)) {
            out.push_str(&format!("    generated line {n}: {}\n", text.trim()));
        }
        if let Some(at) = generated.rust_location(n) {
            out.push_str(&format!("    from {}:{}:{} (in {})\n", at.file, at.span.line, at.span.column, at.function));
        }
    }
    out
}

/// Compiles the generated WGSL into a compute pipeline on `device` with `layout`. Errors carry
/// wgpu's messages (naga's front end and validator, then the driver's pipeline creation), each
/// with its generated line mapped back to the kernel's Rust source.
pub async fn compile_pipeline(
    device: &wgpu::Device,
    generated: &Generated,
    layout: Option<&wgpu::PipelineLayout>,
) -> Result<wgpu::ComputePipeline, WgpuError> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("lightport path tracer"),
        source: wgpu::ShaderSource::Wgsl(Cow::Borrowed(&generated.source)),
    });
    let info = module.get_compilation_info().await;
    let scope = scope.pop().await;
    let errors: Vec<Message> = info
        .messages
        .iter()
        .filter(|m| m.message_type == wgpu::CompilationMessageType::Error)
        .map(|m| Message { text: m.message.clone(), line: m.location.map(|l| l.line_number) })
        .collect();
    if !errors.is_empty() || scope.is_some() {
        let mut messages = errors;
        if messages.is_empty() {
            messages.push(Message { text: scope.map(|e| e.to_string()).unwrap_or_default(), line: None });
        }
        return Err(WgpuError::Compile { log: annotate_messages(&messages, generated) });
    }
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("lightport path tracer"),
        layout,
        module: &module,
        entry_point: Some(ENTRY_POINT),
        compilation_options: Default::default(),
        cache: None,
    });
    if let Some(e) = scope.pop().await {
        return Err(WgpuError::Compile {
            log: format!("creating the compute pipeline (entry point `{ENTRY_POINT}`): {e}"),
        });
    }
    Ok(pipeline)
}

/// The GPU objects a renderer draws with.
struct Pipeline {
    pipeline: wgpu::ComputePipeline,
    bind_groups: Vec<wgpu::BindGroup>,
    scene_uniform: Option<(wgpu::Buffer, UniformLayout)>,
    accumulation: wgpu::Buffer,
    readback: wgpu::Buffer,
    workgroups: [u32; 2],
}

/// The kernel on a wgpu device. Create it from a [`Packed`] scene;
/// [`render_frame`](Self::render_frame) adds one sample per pixel; [`image`](Self::image) reads
/// the mean back, as [`CpuRenderer`](super::cpu::CpuRenderer) does.
pub struct WgpuRenderer {
    device: WgpuDevice,
    packed: Packed,
    seed: u32,
    frames: u32,
    pipeline: Pipeline,
    /// The first error wgpu reported outside an error scope (e.g. a lost device).
    uncaptured: Arc<Mutex<Option<String>>>,
}

impl WgpuRenderer {
    /// A renderer on `device` for `packed`; `seed` selects the random sequence, as for the CPU
    /// backend.
    pub async fn new(device: WgpuDevice, packed: Packed, seed: u32, options: &WgpuOptions) -> Result<Self, WgpuError> {
        let uncaptured = Arc::new(Mutex::new(None));
        let sink = uncaptured.clone();
        device.device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert_with(|| e.to_string());
        }));
        let pipeline = build(&device, &packed, options).await?;
        let mut device = device;
        device.info.max_storage_buffer_binding_size = storage_limit(&device.limits, options);
        Ok(WgpuRenderer { device, packed, seed, frames: 0, pipeline, uncaptured })
    }

    /// A renderer on its own native device (Vulkan, Metal or DX12).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn headless(packed: Packed, seed: u32) -> Result<Self, WgpuError> {
        Self::headless_with_options(packed, seed, &WgpuOptions::default())
    }

    #[cfg(not(target_arch = "wasm32"))]
    pub fn headless_with_options(packed: Packed, seed: u32, options: &WgpuOptions) -> Result<Self, WgpuError> {
        let device = WgpuDevice::native()?;
        pollster::block_on(Self::new(device, packed, seed, options))
    }

    pub fn info(&self) -> &WgpuInfo {
        &self.device.info
    }

    pub fn device(&self) -> &WgpuDevice {
        &self.device
    }

    pub fn frames(&self) -> u32 {
        self.frames
    }

    pub fn packed(&self) -> &Packed {
        &self.packed
    }

    fn check_uncaptured(&self) -> Result<(), WgpuError> {
        let slot = self.uncaptured.lock().unwrap_or_else(|p| p.into_inner());
        match &*slot {
            Some(detail) => Err(WgpuError::Wgpu { what: "the device", detail: detail.clone() }),
            None => Ok(()),
        }
    }

    /// Adds one sample per pixel (queued on the device; [`finish`](Self::finish) waits).
    pub fn render_frame(&mut self) -> Result<(), WgpuError> {
        self.check_uncaptured()?;
        let p = &self.pipeline;
        let queue = &self.device.queue;
        if let Some((buffer, layout)) = &p.scene_uniform {
            if let Some((_, offset)) = layout.members.iter().find(|(n, _)| n == "frame_seed") {
                queue.write_buffer(buffer, *offset as u64, &frame_seed(self.frames, self.seed).to_le_bytes());
            }
        }
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("lightport frame"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&p.pipeline);
            for (i, group) in p.bind_groups.iter().enumerate() {
                pass.set_bind_group(i as u32, group, &[]);
            }
            pass.dispatch_workgroups(p.workgroups[0], p.workgroups[1], 1);
        }
        queue.submit([encoder.finish()]);
        self.frames += 1;
        Ok(())
    }

    /// Waits until every queued frame has been rendered, e.g. around timings.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn finish(&self) -> Result<(), WgpuError> {
        self.device
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| WgpuError::Wgpu { what: "waiting for the queue", detail: e.to_string() })?;
        self.check_uncaptured()
    }

    /// The running sum per pixel, row y = kernel row y: rgb the sum of samples, w the number
    /// of finite samples.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn accumulation(&self) -> Result<Vec<Vec4>, WgpuError> {
        let p = &self.pipeline;
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&p.accumulation, 0, &p.readback, 0, p.accumulation.size());
        self.device.queue.submit([encoder.finish()]);
        let slice = p.readback.slice(..);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| {
            let _ = sender.send(result);
        });
        self.finish()?;
        receiver
            .recv()
            .map_err(|e| WgpuError::Wgpu { what: "mapping the readback buffer", detail: e.to_string() })?
            .map_err(|e| WgpuError::Wgpu { what: "mapping the readback buffer", detail: e.to_string() })?;
        let texels: Vec<Vec4> = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| WgpuError::Wgpu { what: "reading the readback buffer", detail: e.to_string() })?;
            bytemuck::pod_collect_to_vec(&view)
        };
        p.readback.unmap();
        Ok(texels)
    }

    /// The mean of the accumulated samples (linear RGB), as the CPU backend computes it.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn image(&self) -> Result<Image, WgpuError> {
        let n = self.frames.max(1) as f32;
        Ok(Image {
            width: self.packed.scene.width,
            height: self.packed.scene.height,
            pixels: self.accumulation()?.iter().map(|a| a.xyz() / n).collect(),
        })
    }

    /// Samples that were not finite and were dropped, over the whole image.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn rejected_samples(&self) -> Result<u64, WgpuError> {
        let accumulation = self.accumulation()?;
        let accepted: f64 = accumulation.iter().map(|a| a.w as f64).sum();
        Ok((self.frames as u64 * accumulation.len() as u64).saturating_sub(accepted.round() as u64))
    }

    /// Changes the scene's uniforms (camera, strategy, depth...) and restarts the accumulation,
    /// without recompiling the shader or re-uploading the storage buffers. Texel arrays changed
    /// by `update` are not re-uploaded; the image size cannot change: that is an error.
    pub fn set_uniforms(&mut self, update: impl FnOnce(&mut Scene)) -> Result<(), WgpuError> {
        let (width, height) = (self.packed.scene.width, self.packed.scene.height);
        update(&mut self.packed.scene);
        let scene = &mut self.packed.scene;
        if (scene.width, scene.height) != (width, height) {
            let wanted = format!("{}x{}", scene.width, scene.height);
            (scene.width, scene.height) = (width, height);
            return Err(WgpuError::SizeChanged { width, height, wanted });
        }
        if let Some((buffer, layout)) = &self.pipeline.scene_uniform {
            self.device.queue.write_buffer(buffer, 0, &scene_uniform_bytes(layout, &self.packed.scene)?);
        }
        self.restart()
    }

    /// Drops every accumulated sample: the next frame is sample 1 again.
    pub fn restart(&mut self) -> Result<(), WgpuError> {
        self.check_uncaptured()?;
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.pipeline.accumulation, 0, None);
        self.device.queue.submit([encoder.finish()]);
        self.frames = 0;
        Ok(())
    }
}

/// The storage-buffer binding size the renderer works under.
fn storage_limit(limits: &wgpu::Limits, options: &WgpuOptions) -> u64 {
    let device = limits.max_storage_buffer_binding_size;
    options.max_storage_buffer_binding_size.map_or(device, |m| m.min(device))
}

/// Checks the scene and the image against the device's limits.
fn check_limits(
    limits: &wgpu::Limits,
    options: &WgpuOptions,
    packed: &Packed,
    layout: &ShaderLayout,
) -> Result<[u32; 2], WgpuError> {
    let binding_max = storage_limit(limits, options);
    let buffer_max = limits.max_buffer_size;
    let bindings = scene_bindings(&packed.scene);
    for (field, _, _) in &layout.storage {
        let texels = bindings.iter().find(|(n, _)| n == field).and_then(|(_, b)| b.texels()).unwrap_or(0);
        let bytes = texels.max(1) as u64 * 16;
        for (limit, max) in [("max_storage_buffer_binding_size", binding_max), ("max_buffer_size", buffer_max)] {
            if bytes > max {
                return Err(WgpuError::SceneTooLarge {
                    array: format!("{SCENE_UNIFORM_PREFIX}{field}"),
                    bytes,
                    limit,
                    max,
                });
            }
        }
    }
    let storage_buffers = layout.storage.len() as u64 + 1;
    let groups =
        1 + layout.storage.iter().map(|s| s.1).chain([layout.accumulation.map_or(0, |a| a.0)]).max().unwrap_or(0)
            as u64;
    let uniform_size = layout.scene_uniform.as_ref().map_or(0, |u| u.size) as u64;
    for (limit, needed, max) in [
        ("max_storage_buffers_per_shader_stage", storage_buffers, limits.max_storage_buffers_per_shader_stage as u64),
        ("max_bind_groups", groups, limits.max_bind_groups as u64),
        ("max_uniform_buffer_binding_size", uniform_size, limits.max_uniform_buffer_binding_size),
        ("max_compute_workgroup_size_x", WORKGROUP_SIZE[0] as u64, limits.max_compute_workgroup_size_x as u64),
        ("max_compute_workgroup_size_y", WORKGROUP_SIZE[1] as u64, limits.max_compute_workgroup_size_y as u64),
        (
            "max_compute_invocations_per_workgroup",
            (WORKGROUP_SIZE[0] * WORKGROUP_SIZE[1]) as u64,
            limits.max_compute_invocations_per_workgroup as u64,
        ),
    ] {
        if needed > max {
            return Err(WgpuError::Unsupported { limit, needed, max });
        }
    }
    let (width, height) = (packed.scene.width, packed.scene.height);
    let pixels_bytes = width as u64 * height as u64 * 16;
    for (limit, max) in [("max_storage_buffer_binding_size", binding_max), ("max_buffer_size", buffer_max)] {
        if pixels_bytes > max {
            return Err(WgpuError::ImageTooLarge {
                width,
                height,
                what: "the accumulation buffer",
                needed: pixels_bytes,
                limit,
                max,
            });
        }
    }
    let workgroups = [width.div_ceil(WORKGROUP_SIZE[0]), height.div_ceil(WORKGROUP_SIZE[1])];
    let max = limits.max_compute_workgroups_per_dimension;
    if workgroups[0] > max || workgroups[1] > max {
        return Err(WgpuError::ImageTooLarge {
            width,
            height,
            what: "the dispatch",
            needed: workgroups[0].max(workgroups[1]) as u64,
            limit: "max_compute_workgroups_per_dimension",
            max: max as u64,
        });
    }
    Ok(workgroups)
}

/// Generates and compiles the shader, uploads the scene and creates the bind groups.
async fn build(device: &WgpuDevice, packed: &Packed, options: &WgpuOptions) -> Result<Pipeline, WgpuError> {
    let generated = crate::kernel::path_tracer_shader(&packed.features, Target::Wgsl)?;
    let layout = reflect(&generated)?;
    let workgroups = check_limits(&device.limits, options, packed, &layout)?;
    let d = &device.device;
    let scene = &packed.scene;
    let bindings = scene_bindings(scene);

    // (group, binding, buffer, uniform?, read_only?)
    let mut entries: Vec<(u32, u32, wgpu::Buffer, bool, bool)> = Vec::new();
    let mut scene_uniform = None;
    if let Some(u) = &layout.scene_uniform {
        let buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene uniforms"),
            contents: &scene_uniform_bytes(u, scene)?,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        entries.push((u.group, u.binding, buffer.clone(), true, true));
        scene_uniform = Some((buffer, u.clone()));
    }
    for (field, group, binding) in &layout.storage {
        let contents: Cow<[u8]> = match bindings.iter().find(|(n, _)| n == field).map(|(_, b)| b) {
            Some(Binding::Vec4s(t)) if !t.is_empty() => Cow::Borrowed(bytemuck::cast_slice(t.as_slice())),
            Some(Binding::UVec4s(t)) if !t.is_empty() => Cow::Borrowed(bytemuck::cast_slice(t.as_slice())),
            // An array the variant declares but the scene left empty: one zero texel (a
            // binding cannot be empty).
            Some(Binding::Vec4s(_) | Binding::UVec4s(_)) => Cow::Owned(vec![0u8; 16]),
            Some(other) => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{SCENE_UNIFORM_PREFIX}{field}"),
                    detail: format!(" as a storage buffer (the Scene field is {})", other.dsl_type()),
                })
            }
            None => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{SCENE_UNIFORM_PREFIX}{field}"),
                    detail: String::new(),
                })
            }
        };
        let buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(field),
            contents: &contents,
            usage: wgpu::BufferUsages::STORAGE,
        });
        entries.push((*group, *binding, buffer, false, true));
    }
    let (width, height) = (scene.width as u64, scene.height as u64);
    let accumulation = d.create_buffer(&wgpu::BufferDescriptor {
        label: Some(ACCUMULATION_BUFFER),
        size: width * height * 16,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let readback = d.create_buffer(&wgpu::BufferDescriptor {
        label: Some("accumulation readback"),
        size: width * height * 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let (group, binding) = layout.accumulation.expect("checked by reflect");
    entries.push((group, binding, accumulation.clone(), false, false));
    let target = layout.target.as_ref().expect("checked by reflect");
    let mut target_bytes = vec![0u8; target.size as usize];
    for (member, offset) in &target.members {
        let value = match member.as_str() {
            "width" => scene.width,
            "height" => scene.height,
            other => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{TARGET_UNIFORM}.{other}"),
                    detail: String::new(),
                })
            }
        };
        target_bytes[*offset as usize..*offset as usize + 4].copy_from_slice(&value.to_le_bytes());
    }
    let target_buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(TARGET_UNIFORM),
        contents: &target_bytes,
        usage: wgpu::BufferUsages::UNIFORM,
    });
    entries.push((target.group, target.binding, target_buffer, true, true));

    let group_count = entries.iter().map(|e| e.0).max().map_or(0, |g| g + 1);
    let mut group_layouts = Vec::new();
    let mut bind_groups = Vec::new();
    for group in 0..group_count {
        let members: Vec<&(u32, u32, wgpu::Buffer, bool, bool)> = entries.iter().filter(|e| e.0 == group).collect();
        let layout_entries: Vec<wgpu::BindGroupLayoutEntry> = members
            .iter()
            .map(|(_, binding, _, uniform, read_only)| wgpu::BindGroupLayoutEntry {
                binding: *binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: if *uniform {
                        wgpu::BufferBindingType::Uniform
                    } else {
                        wgpu::BufferBindingType::Storage { read_only: *read_only }
                    },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            })
            .collect();
        let group_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lightport"),
            entries: &layout_entries,
        });
        let group_entries: Vec<wgpu::BindGroupEntry> = members
            .iter()
            .map(|(_, binding, buffer, _, _)| wgpu::BindGroupEntry {
                binding: *binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        bind_groups.push(d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lightport"),
            layout: &group_layout,
            entries: &group_entries,
        }));
        group_layouts.push(group_layout);
    }
    let layout_refs: Vec<Option<&wgpu::BindGroupLayout>> = group_layouts.iter().map(Some).collect();
    let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("lightport"),
        bind_group_layouts: &layout_refs,
        immediate_size: 0,
    });
    let pipeline = compile_pipeline(d, &generated, Some(&pipeline_layout)).await?;
    Ok(Pipeline { pipeline, bind_groups, scene_uniform, accumulation, readback, workgroups })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pack::Features;

    /// Every resource of every kernel variant is one the backend binds (reflection only: no
    /// device needed).
    #[test]
    fn every_variant_reflects_into_known_resources() {
        let scene = Scene::default();
        for features in [Features::all(), Features { emissive_triangles: true, ..Default::default() }] {
            let generated = crate::kernel::path_tracer_shader(&features, Target::Wgsl).expect("kernel");
            let layout = reflect(&generated).expect("reflect");
            let uniform = layout.scene_uniform.as_ref().expect("scene uniform");
            scene_uniform_bytes(uniform, &scene).expect("every uniform member has a value");
            assert!(uniform.members.iter().any(|(n, _)| n == "frame_seed"));
        }
        let all = reflect(&crate::kernel::path_tracer_shader(&Features::all(), Target::Wgsl).unwrap()).unwrap();
        assert_eq!(all.storage.len(), 11, "{:?}", all.storage);
    }

    /// The uniform offsets follow WGSL's rules: a vec3 is 16-byte aligned and a scalar may
    /// follow it in its last 4 bytes.
    #[test]
    fn uniform_members_sit_at_wgsl_offsets() {
        let generated = crate::kernel::path_tracer_shader(&Features::all(), Target::Wgsl).unwrap();
        let layout = reflect(&generated).unwrap();
        let u = layout.scene_uniform.unwrap();
        let offset = |name: &str| u.members.iter().find(|(n, _)| n == name).map(|(_, o)| *o);
        assert_eq!(offset("camera_position"), Some(0));
        assert_eq!(offset("camera_right"), Some(16));
        assert_eq!(offset("camera_forward"), Some(48));
        assert_eq!(offset("lens_radius"), Some(60));
    }
}
