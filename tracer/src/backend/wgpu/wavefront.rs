//! [`WavefrontRenderer`]: the wavefront schedule (`kernel::wavefront`) on a wgpu device. One
//! WGSL module holds every stage (`main_<stage>`); the pool's arrays, queues and counters live
//! in the `Paths` buffers (bind group 1), the indirect dispatches' sizes in the `Dispatch`
//! buffer (group 2, bound only to the `plan_*` stages: a buffer an indirect dispatch reads may
//! not be bound to the stage it dispatches). A submission is one compute pass of several
//! iterations ([`ITERATION`]): no queue length is read back between stages; the host asks for
//! the counters after each submission to learn whether the frame is complete. Nothing here
//! needs to block: natively the device is polled until the counters arrive; in the browser
//! they arrive with a promise, and [`render_band`](Renderer::render_band) looks for them on
//! its next call (the page's frame loop calls it once the previous submission is done).

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll, Waker};

use glam::Vec4;

use super::wavefront_pool::{pool_resources, PoolBuffer, PoolResources};
use super::{
    bind_group_layouts, check_scene_limits, map_readback, most_buffer_bytes, reflect, scene_room, scene_uniform_bytes,
    start_pipelines, storage_limit, upload_scene_with_room, Bindings, DeviceRenderer, PipelineCheck, UncapturedErrors,
    UniformLayout, WgpuDevice, WgpuError, WgpuOptions, SCENE_UNIFORM,
};
use crate::backend::wavefront::{
    iteration_bound, pool_size, Stage, WavefrontCounts, WavefrontError, ITERATION, ITERATIONS_PER_SUBMISSION,
};
use crate::backend::{
    ms_since, update_uniforms, BuildTimes, GuideSums, PendingAccumulation, PendingGuideSums, RenderError, Renderer,
    RendererInfo, Schedule,
};
use crate::kernel::scene_data::Scene;
use crate::kernel::wavefront::{ARGS_WORDS, COUNTERS, FRAMES_DONE, FREE};
use crate::pack::Packed;

/// The wavefront schedule on a wgpu device, accumulating one sample per pixel per frame as
/// [`WgpuRenderer`](super::WgpuRenderer) does.
pub struct WavefrontRenderer {
    device: WgpuDevice,
    options: WgpuOptions,
    packed: Packed,
    frames: u32,
    pool: u32,
    /// Each stage of an iteration with its pipeline.
    stages: Vec<(Stage, wgpu::ComputePipeline)>,
    /// The scene's buffers and the renderer's own: the pool's and the dispatch sizes' (groups
    /// 1 and 2), bound.
    bindings: Bindings,
    paths_uniform: (wgpu::Buffer, UniformLayout),
    buffers: Vec<PoolBuffer>,
    dispatch_args: wgpu::Buffer,
    counters_readback: wgpu::Buffer,
    image_readback: wgpu::Buffer,
    times: BuildTimes,
    uncaptured: UncapturedErrors,
    /// The frames asked of the device (`Paths::frames_wanted`): `frames + 1` while a frame is
    /// on its way, `frames` between frames.
    wanted: u32,
    /// Iterations submitted for the frame on its way (against [`iteration_bound`]).
    iterations: u32,
    /// Iterations per submission ([`ITERATIONS_PER_SUBMISSION`] unless set for a measurement).
    per_submission: u32,
    /// Iterations the last completed frame took (whole submissions).
    last_iterations: u32,
    /// Restarts so far: tells a counters read asked for before the latest restart.
    generation: u32,
    /// The counters read on its way, if any.
    counters_read: Option<CountersRead>,
    /// The counters the latest read found since the latest restart.
    counters: Vec<u32>,
}

/// A read of the counters, asked for after a submission.
struct CountersRead {
    generation: u32,
    counters: Pin<Box<dyn Future<Output = Result<Vec<u32>, WgpuError>>>>,
}

impl WavefrontRenderer {
    /// Writes the packed scene's geometry (just taken) to the device.
    fn upload_geometry(&mut self) -> Result<(), WgpuError> {
        self.bindings.take_geometry(&self.device, &self.options, &self.packed.scene)
    }

    /// A wavefront renderer on `device` for `packed` with `seed` (the megakernel's random
    /// sequence), its pool sized from the device's storage binding limit.
    pub async fn new(
        device: WgpuDevice,
        packed: Packed,
        seed: u32,
        options: &WgpuOptions,
    ) -> Result<Self, RenderError> {
        let (renderer, check) = Self::create(device, packed, seed, options)?;
        check.await?;
        Ok(renderer)
    }

    /// [`new`](Self::new) without waiting for the compiler's verdict (see
    /// [`WgpuRenderer::create`](super::WgpuRenderer::create)).
    pub fn create(
        device: WgpuDevice,
        packed: Packed,
        seed: u32,
        options: &WgpuOptions,
    ) -> Result<(Self, PipelineCheck), RenderError> {
        let uncaptured = UncapturedErrors::watch(&device.device);
        let started = web_time::Instant::now();
        let generated = crate::kernel::wavefront_shader(&packed.features).map_err(WgpuError::from)?;
        let own: Vec<String> = generated
            .bindings
            .iter()
            .filter(|b| b.resources != "Scene")
            .flat_map(|b| b.bindings.iter().map(|x| x.variable.clone()))
            .collect();
        let own_refs: Vec<&str> = own.iter().map(String::as_str).collect();
        let layout = reflect(&generated, SCENE_UNIFORM, &own_refs)?;
        let codegen_ms = ms_since(started);
        let scene = &packed.scene;
        check_scene_limits(&device.limits, options, scene, &layout)?;
        let pixels = scene.width * scene.height;
        let max_binding = most_buffer_bytes(&device.limits, options);
        let pool = pool_size(pixels, max_binding, &packed.features)?;

        let uploading = web_time::Instant::now();
        let d = &device.device;
        let (mut entries, scene_uniform) =
            upload_scene_with_room(d, &layout, scene, scene_room(&device.limits, options, &packed.features))?;
        let pool_resources = pool_resources(d, &generated, &layout, pool, pixels, seed)?;
        let pool_entries = pool_resources.entries.len();
        entries.extend(pool_resources.entries.iter().cloned());
        let PoolResources { buffers, paths_uniform, dispatch_args, .. } = pool_resources;
        let (group_layouts, plan_layout) = bind_group_layouts(d, &entries);
        // The stages dispatched indirectly see groups 0 and 1 only.
        let stage_refs: Vec<Option<&wgpu::BindGroupLayout>> = group_layouts.iter().take(2).map(Some).collect();
        let stage_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("lightport wavefront stage"),
            bind_group_layouts: &stage_refs,
            immediate_size: 0,
        });
        let bindings = Bindings::new(d, layout, group_layouts, entries, pool_entries, scene_uniform);
        let counters_readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wavefront counters readback"),
            size: COUNTERS as u64 * 4,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let image_readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wavefront image readback"),
            size: pixels as u64 * 16,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let upload_ms = ms_since(uploading);
        let compiling = web_time::Instant::now();
        let names: Vec<String> = ITERATION.iter().map(|s| format!("main_{}", s.function)).collect();
        let entry_points: Vec<(&str, Option<&wgpu::PipelineLayout>)> = ITERATION
            .iter()
            .zip(&names)
            .map(|(s, n)| (n.as_str(), Some(if s.args.is_none() { &plan_layout } else { &stage_layout })))
            .collect();
        let (pipelines, check) = start_pipelines(d, &generated, &entry_points);
        let times = BuildTimes { codegen_ms, compile_ms: ms_since(compiling), upload_ms };
        let renderer = WavefrontRenderer {
            options: options.clone(),
            frames: 0,
            pool,
            stages: ITERATION.iter().copied().zip(pipelines).collect(),
            bindings,
            paths_uniform,
            buffers,
            dispatch_args,
            counters_readback,
            image_readback,

            times,
            uncaptured,
            wanted: 0,
            iterations: 0,
            per_submission: ITERATIONS_PER_SUBMISSION,
            last_iterations: 0,
            generation: 0,
            counters_read: None,
            counters: Vec::new(),
            packed,
            device,
        };
        renderer.reset_pool();
        Ok((renderer, check))
    }

    /// A wavefront renderer on its own native device.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn headless(packed: Packed, seed: u32) -> Result<Self, RenderError> {
        let device = WgpuDevice::native()?;
        pollster::block_on(Self::new(device, packed, seed, &WgpuOptions::default()))
    }

    /// Path slots in the pool.
    pub fn pool(&self) -> u32 {
        self.pool
    }

    /// The storage buffer holding array `field` and its byte range.
    fn array(&self, field: &str) -> Option<(&wgpu::Buffer, u64, u64)> {
        self.buffers.iter().find_map(|b| b.range(field).map(|(at, len)| (&b.buffer, at, len)))
    }

    /// Empties the pool: every slot on the free stack, the counters and the image's sums zero.
    fn reset_pool(&self) {
        let queue = &self.device.queue;
        if let Some((buffer, at, _)) = self.array("free") {
            let slots: Vec<u32> = (0..self.pool).collect();
            queue.write_buffer(buffer, at, bytemuck::cast_slice(&slots));
        }
        if let Some((buffer, at, _)) = self.array("counters") {
            let mut counters = [0u32; COUNTERS as usize];
            counters[FREE as usize] = self.pool;
            queue.write_buffer(buffer, at, bytemuck::cast_slice(&counters));
        }
        for sums in ["image", "guide_albedo", "guide_normal", "guide_emission"] {
            if let Some((buffer, at, len)) = self.array(sums) {
                let mut encoder = self.device.device.create_command_encoder(&Default::default());
                encoder.clear_buffer(buffer, at, Some(len));
                queue.submit([encoder.finish()]);
            }
        }
    }

    /// Writes `Paths::frames_wanted`.
    fn want_frames(&self, frames: u32) {
        let (buffer, layout) = &self.paths_uniform;
        if let Some((_, offset)) = layout.members.iter().find(|(n, _)| n == "frames_wanted") {
            self.device.queue.write_buffer(buffer, *offset as u64, &frames.to_le_bytes());
        }
    }

    /// Iterations per submission, [`ITERATIONS_PER_SUBMISSION`] unless set here (at least 1):
    /// for measurements (`examples/bench_wavefront.rs`).
    pub fn set_iterations_per_submission(&mut self, iterations: u32) {
        self.per_submission = iterations.max(1);
    }

    /// Iterations the last completed frame took (whole submissions; natively).
    pub fn last_frame_iterations(&self) -> u32 {
        self.last_iterations
    }

    /// Submits `iterations` iterations as one compute pass.
    fn submit(&self, iterations: u32) {
        self.submit_stages(iterations, 0..self.stages.len());
    }

    /// Submits `iterations` times the stages `range` of an iteration as one compute pass.
    fn submit_stages(&self, iterations: u32, range: std::ops::Range<usize>) {
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("lightport wavefront"),
                timestamp_writes: None,
            });
            for _ in 0..iterations {
                for (stage, pipeline) in &self.stages[range.clone()] {
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, &self.bindings.groups[0], &[]);
                    pass.set_bind_group(1, &self.bindings.groups[1], &[]);
                    match stage.args {
                        None => {
                            pass.set_bind_group(2, &self.bindings.groups[2], &[]);
                            pass.dispatch_workgroups(1, 1, 1);
                        }
                        Some(at) => pass.dispatch_workgroups_indirect(&self.dispatch_args, at as u64 * 4),
                    }
                }
            }
        }
        self.device.queue.submit([encoder.finish()]);
    }

    /// Asks for the counters after the work submitted so far, unless a read is on its way
    /// (its read-back buffer is mapped until it arrives). Natively, waits for them.
    fn request_counters(&mut self) -> Result<(), RenderError> {
        if self.counters_read.is_none() {
            let Some((buffer, at, len)) = self.array("counters") else { return Ok(()) };
            let mut encoder = self.device.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(buffer, at, &self.counters_readback, 0, len);
            self.device.queue.submit([encoder.finish()]);
            let counters = Box::pin(map_readback::<u32>(self.counters_readback.clone()));
            self.counters_read = Some(CountersRead { generation: self.generation, counters });
        }
        #[cfg(not(target_arch = "wasm32"))]
        self.finish()?;
        Ok(())
    }

    /// Takes the counters read if it has arrived (into `counters`, unless a restart made it
    /// stale); never waits.
    fn take_counters(&mut self) -> Result<(), RenderError> {
        let Some(read) = &mut self.counters_read else { return Ok(()) };
        let Poll::Ready(counters) = read.counters.as_mut().poll(&mut Context::from_waker(Waker::noop())) else {
            return Ok(());
        };
        let stale = read.generation != self.generation;
        self.counters_read = None;
        if !stale {
            self.counters = counters?;
        }
        Ok(())
    }

    /// A measurement: renders the next frame with each stage in a submission of its own,
    /// waited for, and returns each stage's seconds over the frame (in [`ITERATION`]'s order)
    /// and the paths each iteration extended (its length is the
    /// iterations the frame took). Between frames only (after [`render_frame`](Renderer::render_frame)).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn profile_frame(&mut self) -> Result<crate::backend::wavefront::FrameProfile, RenderError> {
        let wanted = self.frames + 1;
        self.wanted = wanted;
        self.want_frames(wanted);
        let scene = &self.packed.scene;
        let bound = iteration_bound(scene.width * scene.height, self.pool, scene.max_depth);
        let mut seconds = vec![0.0; self.stages.len()];
        let mut iterations = 0;
        let mut extended = Vec::new();
        let mut segments = self.counts().segments;
        loop {
            for (k, s) in seconds.iter_mut().enumerate() {
                let t = std::time::Instant::now();
                self.submit_stages(1, k..k + 1);
                self.finish()?;
                *s += t.elapsed().as_secs_f64();
            }
            iterations += 1;
            self.request_counters()?;
            self.take_counters()?;
            let now = self.counts().segments;
            extended.push(now.wrapping_sub(segments));
            segments = now;
            if self.wanted_done() {
                break;
            }
            if iterations >= bound {
                return Err(WavefrontError::Stalled { iterations }.into());
            }
        }
        self.frames = wanted;
        Ok((self.stages.iter().map(|(s, _)| s.function).zip(seconds).collect(), extended))
    }

    /// A measurement: seconds to submit and wait for `iterations` iterations in which no path
    /// is started or moves (between frames: every slot is free and no frame is asked for), so
    /// each dispatch has one invocation (a `plan_*` stage) or none: the fixed cost of the
    /// iterations' dispatches and barriers.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn time_idle_iterations(&mut self, iterations: u32) -> Result<f64, RenderError> {
        self.finish()?;
        let t = std::time::Instant::now();
        self.submit(iterations);
        self.finish()?;
        Ok(t.elapsed().as_secs_f64())
    }

    /// Whether the counters last read say that the frame asked for is complete.
    fn wanted_done(&self) -> bool {
        self.counters.get(FRAMES_DONE as usize).copied().unwrap_or(0) >= self.wanted
    }

    /// What the pool has traced since the last restart, as the counters last read say (after
    /// each whole frame natively).
    pub fn counts(&self) -> WavefrontCounts {
        WavefrontCounts::from_counters(&self.counters)
    }

    /// The image's running sums, copied to the read-back buffer now, arriving once the device
    /// has mapped it (natively someone must poll the device).
    fn read_image(&self) -> impl Future<Output = Result<Vec<Vec4>, WgpuError>> + 'static {
        let uncaptured = self.uncaptured.check();
        let read = self.array("image").map(|(buffer, at, len)| {
            let mut encoder = self.device.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(buffer, at, &self.image_readback, 0, len);
            self.device.queue.submit([encoder.finish()]);
            map_readback(self.image_readback.clone())
        });
        async move {
            uncaptured?;
            match read {
                Some(read) => read.await,
                None => Ok(Vec::new()),
            }
        }
    }

    /// The guide's three per-pixel arrays copied now, one after the other, into a read-back
    /// buffer of their own (a read of the image may be on its way in the other), arriving once
    /// the device has mapped it; [`RenderError::NoGuide`] without the guide.
    fn read_guide(&self) -> PendingGuideSums {
        const FIELDS: [&str; 3] = ["guide_albedo", "guide_normal", "guide_emission"];
        let arrays: Option<Vec<_>> = FIELDS.iter().map(|f| self.array(f)).collect();
        let Some(arrays) = arrays else { return Box::pin(std::future::ready(Err(RenderError::NoGuide))) };
        let total: u64 = arrays.iter().map(|a| a.2).sum();
        let readback = self.device.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wavefront guide readback"),
            size: total,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.device.create_command_encoder(&Default::default());
        let mut to = 0;
        for (buffer, at, len) in &arrays {
            encoder.copy_buffer_to_buffer(buffer, *at, &readback, to, *len);
            to += len;
        }
        self.device.queue.submit([encoder.finish()]);
        let read = map_readback::<Vec4>(readback);
        let uncaptured = self.uncaptured.check();
        let pixels = (arrays[0].2 / 16) as usize;
        Box::pin(async move {
            uncaptured?;
            let texels = read.await?;
            Ok(std::array::from_fn(|k| texels[k * pixels..(k + 1) * pixels].to_vec()))
        })
    }
}

impl DeviceRenderer for WavefrontRenderer {
    fn device(&self) -> &WgpuDevice {
        &self.device
    }

    /// The `Paths` buffer holding the image's sums: [`pool_buffers`](super::wavefront_pool::pool_buffers)
    /// places them first.
    fn sums(&self) -> &wgpu::Buffer {
        match self.array("image") {
            Some((buffer, _, _)) => buffer,
            None => &self.image_readback,
        }
    }

    fn check_uncaptured(&self) -> Result<(), WgpuError> {
        self.uncaptured.check()
    }

    fn watch_uncaptured(&mut self) {
        self.uncaptured = UncapturedErrors::watch(&self.device.device);
    }

    fn build_times(&self) -> BuildTimes {
        self.times
    }

    fn schedule(&self) -> Schedule {
        Schedule::Wavefront
    }
}

impl Renderer for WavefrontRenderer {
    fn describe(&self) -> RendererInfo {
        let info = &self.device.info;
        RendererInfo {
            runtime: "wgpu",
            device: format!("{} ({}), wavefront", info.adapter, info.backend),
            limits: vec![
                ("max_storage_buffer_binding_size", storage_limit(&self.device.limits, &self.options)),
                ("path slots", self.pool as u64),
                ("dispatch args words", ARGS_WORDS as u64),
            ],
        }
    }

    fn packed(&self) -> &Packed {
        &self.packed
    }

    fn frames(&self) -> u32 {
        self.frames
    }

    /// A wavefront frame is not split into rows: the image's height between frames, one row
    /// while a frame is on its way (the pool does not tell which rows are done).
    fn rows_left(&self) -> u32 {
        if self.wanted == self.frames {
            self.packed.scene.height
        } else {
            1
        }
    }

    /// Submissions until the frame is done, each waiting for its counters. In the browser,
    /// where they arrive with a promise, the frame loop calls
    /// [`render_band`](Renderer::render_band) instead: an error here.
    fn render_frame(&mut self) -> Result<(), RenderError> {
        #[cfg(not(target_arch = "wasm32"))]
        while !self.render_band(self.rows_left())? {}
        #[cfg(target_arch = "wasm32")]
        return Err(RenderError::Unsupported {
            runtime: "wgpu",
            what: "cannot wait for a wavefront frame in the browser (call render_band from the frame loop)",
        });
        #[cfg(not(target_arch = "wasm32"))]
        Ok(())
    }

    /// Works on the frame, whatever `rows`: one submission of [`ITERATIONS_PER_SUBMISSION`]
    /// iterations (at most that many path segments per slot: the work of a submission is
    /// bounded whatever the paths' depth), then a read of the counters; the frame is done when
    /// a read says so (natively the read arrives at once; in the browser on a later call).
    fn render_band(&mut self, _rows: u32) -> Result<bool, RenderError> {
        self.uncaptured.check()?;
        if self.wanted == self.frames {
            self.wanted = self.frames + 1;
            self.want_frames(self.wanted);
            self.iterations = 0;
        }
        for submit in [false, true] {
            self.take_counters()?;
            if self.wanted_done() {
                self.frames = self.wanted;
                self.last_iterations = self.iterations;
                return Ok(true);
            }
            if submit {
                let scene = &self.packed.scene;
                if self.iterations >= iteration_bound(scene.width * scene.height, self.pool, scene.max_depth) {
                    return Err(WavefrontError::Stalled { iterations: self.iterations }.into());
                }
                self.submit(self.per_submission);
                self.iterations += self.per_submission;
                self.request_counters()?;
            }
        }
        Ok(false)
    }

    /// Waits until the queue is idle. In the browser nothing blocks: it reports the device's
    /// errors only.
    fn finish(&self) -> Result<(), RenderError> {
        #[cfg(not(target_arch = "wasm32"))]
        self.device
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| WgpuError::Wgpu { what: "waiting for the queue", detail: e.to_string() })?;
        Ok(self.uncaptured.check()?)
    }

    /// [`read_accumulation`](Renderer::read_accumulation) waited for (natively; an error in the
    /// browser).
    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError> {
        super::wait_for_read(self, || self.read_accumulation())
    }

    fn read_accumulation(&self) -> PendingAccumulation {
        let read = self.read_image();
        Box::pin(async move { Ok(read.await?) })
    }

    /// [`read_guide_sums`](Renderer::read_guide_sums) waited for (natively; an error in the
    /// browser).
    fn guide_sums(&self) -> Result<GuideSums, RenderError> {
        super::wait_for_read(self, || self.read_guide_sums())
    }

    fn read_guide_sums(&self) -> PendingGuideSums {
        self.read_guide()
    }

    fn set_uniforms(&mut self, update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError> {
        update_uniforms(&mut self.packed.scene, update)?;
        if let Some((buffer, layout)) = &self.bindings.scene_uniform {
            self.device.queue.write_buffer(buffer, 0, &scene_uniform_bytes(layout, SCENE_UNIFORM, &self.packed.scene)?);
        }
        self.restart()
    }

    /// The moved arrays written over the tails of the scene's buffers, as the megakernel's
    /// renderer does (new buffers are bound with the pool's); the pipelines are kept.
    fn take_geometry(&mut self, mut moved: Packed) -> Result<(), RenderError> {
        self.uncaptured.check()?;
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
        self.uncaptured.check()?;
        self.bindings.take_scene(&self.device, &self.options, &mut self.packed, scene)?;
        self.restart()
    }

    fn wavefront_counts(&self) -> Option<WavefrontCounts> {
        Some(self.counts())
    }

    /// Empties the pool; a counters read on its way is stale.
    fn restart(&mut self) -> Result<(), RenderError> {
        self.uncaptured.check()?;
        self.reset_pool();
        self.want_frames(0);
        self.frames = 0;
        self.wanted = 0;
        self.generation += 1;
        self.counters.clear();
        Ok(())
    }
}
