//! [`WgpuRenderer`]: the kernel's compute pipeline on a [`WgpuDevice`], one dispatch per frame
//! (or per band of rows) into the accumulation buffer.

use glam::Vec4;
use lightport_codegen::Target;
use wgpu::util::DeviceExt;

use super::{
    bind_group_layouts, check_scene_limits, map_readback, reflect, scene_room, scene_uniform_bytes, start_pipeline,
    storage_limit, u32_uniform_bytes, upload_scene_with_room, Bindings, BufferEntry, OwnResource, PipelineCheck,
    UncapturedErrors, WgpuDevice, WgpuError, WgpuFilter, WgpuInfo, WgpuOptions, ACCUMULATION_BUFFER, SCENE_UNIFORM,
    TARGET_UNIFORM, WORKGROUP_SIZE,
};
use crate::backend::{
    frame_seed, ms_since, update_uniforms, BuildTimes, GuideSums, PendingAccumulation, PendingGuideSums, RenderError,
    Renderer, RendererInfo,
};
use crate::kernel::denoise::FilterImage;
use crate::kernel::scene_data::Scene;
use crate::pack::Packed;

/// The GPU objects a renderer draws with.
struct Pipeline {
    pipeline: wgpu::ComputePipeline,
    /// The scene's buffers and the renderer's own (accumulation, guide, target), bound.
    bindings: Bindings,
    accumulation: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// With the denoiser's guide, its three running sums (`lp_accumulation1..3`) and one
    /// read-back buffer for all three; empty and `None` without.
    guide: Vec<wgpu::Buffer>,
    guide_readback: Option<wgpu::Buffer>,
    /// `lp_target` (the image width and the band of rows a dispatch covers) and its layout.
    target: (wgpu::Buffer, OwnResource),
    /// Workgroups across the image.
    workgroups_x: u32,
    /// What creating the pipeline took on this thread.
    times: BuildTimes,
}

/// The kernel on a wgpu device. Create it from a [`Packed`] scene;
/// [`render_frame`](Self::render_frame) adds one sample per pixel; [`image`](Self::image) reads
/// the mean back, as [`CpuRenderer`](super::cpu::CpuRenderer) does.
pub struct WgpuRenderer {
    device: WgpuDevice,
    /// The options it was created with (limits a moved scene is checked against too).
    options: WgpuOptions,
    packed: Packed,
    seed: u32,
    frames: u32,
    /// The first row of the current frame not rendered yet (0 between frames).
    band_row: u32,
    pipeline: Pipeline,
    /// The denoiser's pass, compiled when first asked for (natively: in the browser
    /// `denoise_passes` cannot block for its read-back, so nothing creates it there yet).
    #[cfg_attr(target_arch = "wasm32", allow(dead_code))]
    filter: Option<WgpuFilter>,
    /// The first error wgpu reported outside an error scope (e.g. a lost device).
    uncaptured: UncapturedErrors,
    /// The last preview's buffer and its size ([`render_preview`](super::DeviceRenderer::render_preview)).
    preview: Option<(wgpu::Buffer, [u32; 2])>,
}

impl WgpuRenderer {
    /// A renderer on `device` for `packed`; `seed` selects the random sequence, as for the CPU
    /// backend.
    pub async fn new(device: WgpuDevice, packed: Packed, seed: u32, options: &WgpuOptions) -> Result<Self, WgpuError> {
        let (renderer, check) = Self::create(device, packed, seed, options)?;
        check.await?;
        Ok(renderer)
    }

    /// [`new`](Self::new) without waiting for the shader compiler's verdict: the renderer at
    /// once (its frames queue behind the compilation) and the check that reports whether the
    /// pipeline compiled. Limits are checked before anything is created. For callers that
    /// cannot await here (the browser's viewer).
    pub fn create(
        device: WgpuDevice,
        packed: Packed,
        seed: u32,
        options: &WgpuOptions,
    ) -> Result<(Self, PipelineCheck), WgpuError> {
        let uncaptured = UncapturedErrors::watch(&device.device);
        let (pipeline, check) = build(&device, &packed, options)?;
        let mut device = device;
        device.info.max_storage_buffer_binding_size = storage_limit(&device.limits, options);
        let options = options.clone();
        let renderer = WgpuRenderer {
            device,
            options,
            packed,
            seed,
            frames: 0,
            band_row: 0,
            pipeline,
            filter: None,
            uncaptured,
            preview: None,
        };
        Ok((renderer, check))
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

    /// What creating the renderer took on this thread: generating (and reflecting) the shader,
    /// creating and filling the buffers, and the pipeline creation calls. WebGPU compiles
    /// asynchronously: the compile itself ends when the creation's check resolves.
    pub fn build_times(&self) -> BuildTimes {
        self.pipeline.times
    }

    pub fn info(&self) -> &WgpuInfo {
        &self.device.info
    }

    pub fn device(&self) -> &WgpuDevice {
        &self.device
    }

    /// The first error wgpu reported outside an error scope since the renderer was created.
    pub fn check_uncaptured(&self) -> Result<(), WgpuError> {
        self.uncaptured.check()
    }

    /// The last preview's pixels (one sample each, row-major from the top), waited for
    /// (natively).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn read_preview(&self) -> Result<Vec<Vec4>, RenderError> {
        let Some((buffer, _)) = &self.preview else {
            return Err(RenderError::Unsupported { runtime: "wgpu", what: "has rendered no preview" });
        };
        let readback = self.device.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("preview readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &readback, 0, buffer.size());
        self.device.queue.submit([encoder.finish()]);
        super::wait_for_read(self, || {
            let read = map_readback(readback);
            async move { Ok(read.await?) }
        })
    }

    /// Queues the copy of the accumulation into the readback buffer and returns the future
    /// that resolves once the device has mapped it. One read at a time: a second before the
    /// first resolved is an error.
    fn read_back(&self) -> impl std::future::Future<Output = Result<Vec<Vec4>, WgpuError>> + 'static {
        let p = &self.pipeline;
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&p.accumulation, 0, &p.readback, 0, p.accumulation.size());
        self.device.queue.submit([encoder.finish()]);
        let read = map_readback(p.readback.clone());
        let uncaptured = self.check_uncaptured();
        async move {
            uncaptured?;
            read.await
        }
    }
}

impl WgpuRenderer {
    /// Writes the packed scene's geometry (just taken) to the device.
    fn upload_geometry(&mut self) -> Result<(), WgpuError> {
        self.pipeline.bindings.take_geometry(&self.device, &self.options, &self.packed.scene)
    }
}

impl super::DeviceRenderer for WgpuRenderer {
    fn device(&self) -> &WgpuDevice {
        &self.device
    }

    fn sums(&self) -> &wgpu::Buffer {
        &self.pipeline.accumulation
    }

    fn check_uncaptured(&self) -> Result<(), WgpuError> {
        self.uncaptured.check()
    }

    fn watch_uncaptured(&mut self) {
        self.uncaptured = UncapturedErrors::watch(&self.device.device);
    }

    fn build_times(&self) -> BuildTimes {
        self.pipeline.times
    }

    fn schedule(&self) -> crate::backend::Schedule {
        crate::backend::Schedule::Megakernel
    }

    /// The frame's dispatch over `width` x `height` pixels with the scene's `width` and
    /// `height` uniforms set to those for it, into the first `width` x `height` sums of the
    /// accumulation (and the guide's), copied to the preview's own buffer, after which the
    /// accumulation and the guide are cleared again: all in one submission, so the
    /// accumulation is zero again before any frame runs. Only before the accumulation's first
    /// frame (nothing of it dispatched since the last restart). The uniforms are written back
    /// for the next submission.
    fn render_preview(&mut self, width: u32, height: u32) -> Result<Option<wgpu::Buffer>, RenderError> {
        self.check_uncaptured()?;
        if self.frames != 0 || self.band_row != 0 {
            return Err(RenderError::Unsupported {
                runtime: "wgpu",
                what: "renders a preview only before the accumulation's first frame (after a restart)",
            });
        }
        let scene = &self.packed.scene;
        let (width, height) = (width.clamp(1, scene.width), height.clamp(1, scene.height));
        let p = &self.pipeline;
        let Some((uniform, layout)) = &p.bindings.scene_uniform else {
            return Err(RenderError::Unsupported {
                runtime: "wgpu",
                what: "has no image size uniforms to preview with",
            });
        };
        let queue = &self.device.queue;
        let write = |values: &[(&str, u32)]| {
            for &(member, value) in values {
                if let Some((_, offset)) = layout.members.iter().find(|(n, _)| n == member) {
                    queue.write_buffer(uniform, *offset as u64, &value.to_le_bytes());
                }
            }
        };
        write(&[("width", width), ("height", height), ("frame_seed", frame_seed(0, self.seed)), ("frame_index", 0)]);
        let (target, target_layout) = &p.target;
        queue.write_buffer(target, 0, &target_bytes(target_layout, width, 0, height)?);
        let bytes = width as u64 * height as u64 * 16;
        let buffer = match &self.preview {
            Some((buffer, size)) if *size == [width, height] => buffer.clone(),
            _ => self.device.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("preview"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
        };
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("lightport preview"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&p.pipeline);
            for (i, group) in p.bindings.groups.iter().enumerate() {
                pass.set_bind_group(i as u32, group, &[]);
            }
            pass.dispatch_workgroups(width.div_ceil(WORKGROUP_SIZE[0]), height.div_ceil(WORKGROUP_SIZE[1]), 1);
        }
        encoder.copy_buffer_to_buffer(&p.accumulation, 0, &buffer, 0, bytes);
        for sums in std::iter::once(&p.accumulation).chain(&p.guide) {
            encoder.clear_buffer(sums, 0, None);
        }
        queue.submit([encoder.finish()]);
        write(&[("width", scene.width), ("height", scene.height)]);
        self.preview = Some((buffer.clone(), [width, height]));
        Ok(Some(buffer))
    }
}

impl Renderer for WgpuRenderer {
    fn describe(&self) -> RendererInfo {
        let info = &self.device.info;
        let limits = &self.device.limits;
        RendererInfo {
            runtime: "wgpu",
            device: format!("{} ({})", info.adapter, info.backend),
            limits: vec![
                ("max_storage_buffer_binding_size", info.max_storage_buffer_binding_size),
                ("max_buffer_size", info.max_buffer_size),
                ("max_storage_buffers_per_shader_stage", limits.max_storage_buffers_per_shader_stage as u64),
            ],
        }
    }

    fn frames(&self) -> u32 {
        self.frames
    }

    fn packed(&self) -> &Packed {
        &self.packed
    }

    fn rows_left(&self) -> u32 {
        self.packed.scene.height - self.band_row
    }

    /// The same dispatch as a whole frame over fewer rows, so the pixels and their random
    /// sequence are the unsplit frame's; each invocation adds its sample in place. See
    /// [`frame_split`](super::frame_split).
    fn render_band(&mut self, rows: u32) -> Result<bool, RenderError> {
        self.check_uncaptured()?;
        let p = &self.pipeline;
        let queue = &self.device.queue;
        let rows = rows.clamp(1, self.rows_left());
        let (first_row, end_row) = (self.band_row, self.band_row + rows);
        if let Some((buffer, layout)) = &p.bindings.scene_uniform {
            for (member, value) in [("frame_seed", frame_seed(self.frames, self.seed)), ("frame_index", self.frames)] {
                if let Some((_, offset)) = layout.members.iter().find(|(n, _)| n == member) {
                    queue.write_buffer(buffer, *offset as u64, &value.to_le_bytes());
                }
            }
        }
        let (target, target_layout) = &p.target;
        queue.write_buffer(target, 0, &target_bytes(target_layout, self.packed.scene.width, first_row, end_row)?);
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("lightport frame"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&p.pipeline);
            for (i, group) in p.bindings.groups.iter().enumerate() {
                pass.set_bind_group(i as u32, group, &[]);
            }
            pass.dispatch_workgroups(p.workgroups_x, rows.div_ceil(WORKGROUP_SIZE[1]), 1);
        }
        queue.submit([encoder.finish()]);
        self.band_row = end_row;
        let frame_done = self.band_row == self.packed.scene.height;
        if frame_done {
            self.band_row = 0;
            self.frames += 1;
        }
        Ok(frame_done)
    }

    /// Waits until the queue is idle. In the browser nothing blocks: it reports the device's
    /// errors only (await [`WgpuRenderer::done`] instead).
    fn finish(&self) -> Result<(), RenderError> {
        #[cfg(not(target_arch = "wasm32"))]
        self.device
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| WgpuError::Wgpu { what: "waiting for the queue", detail: e.to_string() })?;
        Ok(self.check_uncaptured()?)
    }

    /// [`read_accumulation`](Renderer::read_accumulation) waited for (natively; an error in the
    /// browser).
    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError> {
        super::wait_for_read(self, || self.read_accumulation())
    }

    fn read_accumulation(&self) -> PendingAccumulation {
        let read = self.read_back();
        Box::pin(async move { Ok(read.await?) })
    }

    /// [`read_guide_sums`](Renderer::read_guide_sums) waited for (natively; an error in the
    /// browser).
    fn guide_sums(&self) -> Result<GuideSums, RenderError> {
        super::wait_for_read(self, || self.read_guide_sums())
    }

    /// The three guide buffers copied into one read-back buffer, mapped, split.
    fn read_guide_sums(&self) -> PendingGuideSums {
        let p = &self.pipeline;
        let Some(readback) = &p.guide_readback else {
            return Box::pin(std::future::ready(Err(RenderError::NoGuide)));
        };
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        for (k, buffer) in p.guide.iter().enumerate() {
            encoder.copy_buffer_to_buffer(buffer, 0, readback, k as u64 * buffer.size(), buffer.size());
        }
        self.device.queue.submit([encoder.finish()]);
        let read = map_readback(readback.clone());
        let uncaptured = self.check_uncaptured();
        let pixels = self.packed.scene.width as usize * self.packed.scene.height as usize;
        Box::pin(async move {
            uncaptured?;
            let texels = read.await?;
            Ok(std::array::from_fn(|k| texels[k * pixels..(k + 1) * pixels].to_vec()))
        })
    }

    /// Rewrites the `scene` uniform; the storage buffers stay as uploaded.
    fn set_uniforms(&mut self, update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError> {
        update_uniforms(&mut self.packed.scene, update)?;
        if let Some((buffer, layout)) = &self.pipeline.bindings.scene_uniform {
            self.device.queue.write_buffer(buffer, 0, &scene_uniform_bytes(layout, SCENE_UNIFORM, &self.packed.scene)?);
        }
        self.restart()
    }

    /// The moved arrays written over the tails of the scene's buffers (`take_scene_geometry`:
    /// in place while they fit, else new buffers bound with the pipeline's own); the pipeline
    /// and every other array (textures, materials, sky) are kept, and nothing is copied on
    /// the host. A pose the device's limits refuse leaves the renderer as it was.
    fn take_geometry(&mut self, mut moved: Packed) -> Result<(), RenderError> {
        self.check_uncaptured()?;
        self.packed.exchange_geometry(&mut moved)?;
        if let Err(e) = self.upload_geometry() {
            // Back to the geometry the buffers hold (the exchange was just checked).
            let _ = self.packed.exchange_geometry(&mut moved);
            return Err(e.into());
        }
        self.restart()
    }

    /// Every array written to new buffers and bound again; the pipeline is kept.
    fn take_scene(&mut self, scene: Packed) -> Result<(), RenderError> {
        self.check_uncaptured()?;
        self.pipeline.bindings.take_scene(&self.device, &self.options, &mut self.packed, scene)?;
        self.restart()
    }

    /// Compute passes of the kernel's `atrous_pixel` on this renderer's device ([`WgpuFilter`]).
    /// Natively the device is polled until they are read back; in the browser a read-back
    /// cannot block: an error.
    fn denoise_passes(&mut self, image: FilterImage) -> Result<Vec<Vec4>, RenderError> {
        self.check_uncaptured()?;
        #[cfg(not(target_arch = "wasm32"))]
        {
            if self.filter.is_none() {
                self.filter = Some(pollster::block_on(WgpuFilter::new(&self.device))?);
            }
            let filter = self.filter.as_ref().expect("created above");
            let read = filter.run(&self.device, &image)?;
            self.finish()?;
            Ok(pollster::block_on(read)?)
        }
        #[cfg(target_arch = "wasm32")]
        {
            let _ = image;
            Err(RenderError::Unsupported {
                runtime: "wgpu",
                what: "cannot block for the filter's read-back in the browser",
            })
        }
    }

    fn restart(&mut self) -> Result<(), RenderError> {
        self.check_uncaptured()?;
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        for buffer in std::iter::once(&self.pipeline.accumulation).chain(&self.pipeline.guide) {
            encoder.clear_buffer(buffer, 0, None);
        }
        self.device.queue.submit([encoder.finish()]);
        self.frames = 0;
        self.band_row = 0;
        Ok(())
    }
}

/// The bytes of `lp_target`: the image's width and the band of rows `[first_row, end_row)`.
fn target_bytes(target: &OwnResource, width: u32, first_row: u32, end_row: u32) -> Result<Vec<u8>, WgpuError> {
    u32_uniform_bytes(target, |member| match member {
        "width" => Some(width),
        "first_row" => Some(first_row),
        "end_row" => Some(end_row),
        _ => None,
    })
}

/// Checks the renderer's workgroups and image against the device's limits; returns the
/// dispatch size of a whole frame.
fn check_image_limits(limits: &wgpu::Limits, options: &WgpuOptions, scene: &Scene) -> Result<[u32; 2], WgpuError> {
    for (limit, needed, max) in [
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
    let (width, height) = (scene.width, scene.height);
    let pixels_bytes = width as u64 * height as u64 * 16;
    let binding_max = storage_limit(limits, options);
    for (limit, max) in [("max_storage_buffer_binding_size", binding_max), ("max_buffer_size", limits.max_buffer_size)]
    {
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
fn build(device: &WgpuDevice, packed: &Packed, options: &WgpuOptions) -> Result<(Pipeline, PipelineCheck), WgpuError> {
    let started = web_time::Instant::now();
    let generated = crate::kernel::path_tracer_shader(&packed.features, Target::Wgsl)?;
    // The kernel's outputs after the colour: the denoiser's guide sums, if asked for.
    let guide_names: Vec<String> = if packed.features.denoise_guide {
        (1..4).map(|k| format!("{ACCUMULATION_BUFFER}{k}")).collect()
    } else {
        Vec::new()
    };
    let own: Vec<&str> =
        [ACCUMULATION_BUFFER, TARGET_UNIFORM].into_iter().chain(guide_names.iter().map(String::as_str)).collect();
    let layout = reflect(&generated, SCENE_UNIFORM, &own)?;
    let codegen_ms = ms_since(started);
    let scene = &packed.scene;
    check_scene_limits(&device.limits, options, scene, &layout)?;
    let workgroups = check_image_limits(&device.limits, options, scene)?;
    let d = &device.device;
    let uploading = web_time::Instant::now();
    let (mut entries, scene_uniform) =
        upload_scene_with_room(d, &layout, scene, scene_room(&device.limits, options, &packed.features))?;

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
    entries.push(BufferEntry::storage(layout.own(ACCUMULATION_BUFFER), accumulation.clone(), false));
    let mut guide = Vec::new();
    for name in &guide_names {
        let buffer = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some(name),
            size: width * height * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        entries.push(BufferEntry::storage(layout.own(name), buffer.clone(), false));
        guide.push(buffer);
    }
    let guide_readback = (!guide.is_empty()).then(|| {
        d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("guide readback"),
            size: width * height * 16 * guide.len() as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    });
    let target = layout.own(TARGET_UNIFORM).clone();
    let target_buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(TARGET_UNIFORM),
        contents: &target_bytes(&target, scene.width, 0, scene.height)?,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    });
    entries.push(BufferEntry::uniform(&target, target_buffer.clone()));
    let (group_layouts, pipeline_layout) = bind_group_layouts(d, &entries);
    let bindings = Bindings::new(d, layout, group_layouts, entries, own.len(), scene_uniform);
    let upload_ms = ms_since(uploading);
    let compiling = web_time::Instant::now();
    let (pipeline, check) = start_pipeline(d, &generated, Some(&pipeline_layout));
    let times = BuildTimes { codegen_ms, compile_ms: ms_since(compiling), upload_ms };
    let target = (target_buffer, target);
    let workgroups_x = workgroups[0];
    let pipeline =
        Pipeline { pipeline, bindings, accumulation, readback, guide, guide_readback, target, workgroups_x, times };
    Ok((pipeline, check))
}
