//! The wgpu runtime of the harness: codegen's WGSL harness is a compute shader (64 invocations
//! per workgroup) in which invocation `i` reads its argument words from the storage buffer
//! `lp_args` and writes its result words to `lp_results`, for `i < lp_count.n`. The scene is
//! bound as the renderer binds it (group 0: the `scene` uniform and one read-only storage
//! buffer per texel element type), through the same reflection of the generated shader.
//!
//! Compiling and running are futures ([`WgpuHarness::layout_async`],
//! [`WgpuHarness::run_words_async`]) so that the browser's WebGPU (the `lightport-web` crate's
//! harness page) runs this same code; natively [`Runtime`] waits on them.

use std::collections::{BTreeMap, HashMap};
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Waker};

use lightport_codegen::{Program, Target};
use wgpu::util::DeviceExt;

use crate::backend::harness::{generated_layout, harness_selection, HarnessError};
#[cfg(not(target_arch = "wasm32"))]
use crate::backend::harness::{Backend, Runtime};
use crate::backend::wgpu::{
    check_scene_limits, compile_pipeline, pipeline_bind_groups, reflect, u32_uniform_bytes, upload_scene, BufferEntry,
    ShaderLayout, WgpuDevice, WgpuError, WgpuOptions, SCENE_UNIFORM,
};
use crate::kernel::scene_data::Scene;
use crate::kernel::ShaderError;

/// The storage buffer of the generated WGSL harness holding the arguments.
pub const ARGS_BUFFER: &str = "lp_args";
/// The storage buffer the generated WGSL harness writes its results to.
pub const RESULTS_BUFFER: &str = "lp_results";
/// The uniform holding the number of invocations.
pub const COUNT_UNIFORM: &str = "lp_count";
/// Invocations per workgroup of the generated harness (`@workgroup_size(64)`).
pub const WORKGROUP_SIZE: u32 = 64;

/// A compiled harness shader.
struct HarnessShader {
    pipeline: wgpu::ComputePipeline,
    resources: ShaderLayout,
    layout: lightport_codegen::Harness,
}

/// Kernel functions on a wgpu device through codegen's generated WGSL harness.
pub struct WgpuHarness {
    device: WgpuDevice,
    program: Program,
    specialize: BTreeMap<String, u32>,
    /// The scene functions taking `&Scene` read.
    scene: Option<Scene>,
    shaders: HashMap<String, HarnessShader>,
}

impl WgpuHarness {
    /// A harness on `device` for the functions of `program`.
    pub fn new(device: WgpuDevice, program: Program) -> WgpuHarness {
        WgpuHarness { device, program, specialize: BTreeMap::new(), scene: None, shaders: HashMap::new() }
    }

    /// A harness on its own native device (Vulkan, Metal or DX12).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn headless(program: Program) -> Result<WgpuHarness, HarnessError> {
        Ok(WgpuHarness::new(WgpuDevice::native()?, program))
    }

    /// The browser's WebGPU device, as the harness page (`web/src/harness.rs`) creates it.
    #[cfg(target_arch = "wasm32")]
    pub async fn browser_device() -> Result<WgpuDevice, HarnessError> {
        Ok(WgpuDevice::request(wgpu::Backends::BROWSER_WEBGPU).await?)
    }

    /// The linked kernel program the harness shaders are generated from.
    pub fn program(&self) -> &Program {
        &self.program
    }

    pub fn device(&self) -> &WgpuDevice {
        &self.device
    }

    /// Sets the scene (replacing a previous one) for functions taking `&Scene`: each run binds
    /// the arrays its shader reads, as the renderer does (limits checked per shader).
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        self.scene = Some(scene.clone());
        Ok(())
    }

    /// Specialises the harness shaders from now on as `Selection::specialize` does the kernel's.
    pub fn set_specialization(&mut self, specialize: BTreeMap<String, u32>) {
        if self.specialize != specialize {
            self.specialize = specialize;
            self.shaders.clear();
        }
    }

    /// The generated harness layout of `function`, compiling its shader on first use (waiting
    /// for the device natively; see [`layout_async`](Self::layout_async) on wasm).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        pollster::block_on(self.layout_async(function))
    }

    /// [`layout`](Self::layout) as a future: how the browser's WebGPU runs it, since the page's
    /// thread cannot block on the device.
    pub async fn layout_async(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        Ok(self.shader_for(function).await?.layout.clone())
    }

    async fn shader_for(&mut self, function: &str) -> Result<&HarnessShader, HarnessError> {
        if !self.shaders.contains_key(function) {
            let compiled = self.compile(function).await?;
            self.shaders.insert(function.to_string(), compiled);
        }
        Ok(&self.shaders[function])
    }

    async fn compile(&self, function: &str) -> Result<HarnessShader, HarnessError> {
        let selection = harness_selection(function, &self.specialize);
        let generated = self.program.emit(Target::Wgsl, &selection).map_err(ShaderError::from)?;
        #[cfg(feature = "validate")]
        lightport_codegen::validate::validate(&generated).map_err(ShaderError::from)?;
        let layout = generated_layout(function, &generated)?;
        let resources = reflect(&generated, SCENE_UNIFORM, &[ARGS_BUFFER, RESULTS_BUFFER, COUNT_UNIFORM])?;
        // Borrowed, not cloned: a scene's arrays can be hundreds of megabytes.
        let no_scene = Scene::default();
        let scene = self.scene.as_ref().unwrap_or(&no_scene);
        check_scene_limits(&self.device.limits, &WgpuOptions::default(), scene, &resources)?;
        // The layout wgpu derives from the shader: bind groups are made from it per run.
        let pipeline = compile_pipeline(&self.device.device, &generated, None).await?;
        Ok(HarnessShader { pipeline, resources, layout })
    }

    /// The scene's buffers a shader binds: its uniform (made for its layout) and texel buffers.
    fn scene_entries(&self, function: &str, resources: &ShaderLayout) -> Result<Vec<BufferEntry>, HarnessError> {
        if resources.scene_uniform.is_none() && resources.texel_buffers.is_empty() {
            return Ok(Vec::new());
        }
        let Some(scene) = &self.scene else {
            return Err(HarnessError::NoScene { function: function.to_string(), uniform: SCENE_UNIFORM.into() });
        };
        check_scene_limits(&self.device.limits, &WgpuOptions::default(), scene, resources)?;
        Ok(upload_scene(&self.device.device, resources, scene)?.0)
    }

    /// Runs `function` on `invocations` argument sets given as words (`input_words` per
    /// invocation, in the generated layout) and returns `output_words` per invocation, waiting
    /// for the device (natively; see [`run_words_async`](Self::run_words_async) on wasm).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn run_words(&mut self, function: &str, invocations: usize, input: &[u32]) -> Result<Vec<u32>, HarnessError> {
        pollster::block_on(self.run_words_async(function, invocations, input))
    }

    /// [`run_words`](Self::run_words) as a future. One code path for native and the browser:
    /// the readback's `map_async` is awaited; natively `device.poll` completes it first, in the
    /// browser the page's event loop does (its `poll` returns at once).
    pub async fn run_words_async(
        &mut self,
        function: &str,
        invocations: usize,
        input: &[u32],
    ) -> Result<Vec<u32>, HarnessError> {
        self.shader_for(function).await?;
        let shader = &self.shaders[function];
        let (in_words, out_words) = (shader.layout.input_words as usize, shader.layout.output_words as usize);
        if input.len() != invocations * in_words {
            return Err(HarnessError::Layout {
                function: function.to_string(),
                detail: format!("{} input words for {invocations} invocations of {in_words} words", input.len()),
            });
        }
        let scene_entries = self.scene_entries(function, &shader.resources)?;
        // Invocations per dispatch: within the workgroup count and the buffers' binding size.
        let limits = &self.device.limits;
        let binding_max = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let per_dispatch = (limits.max_compute_workgroups_per_dimension as u64 * WORKGROUP_SIZE as u64)
            .min(binding_max / (4 * in_words.max(1) as u64))
            .min(binding_max / (4 * out_words.max(1) as u64))
            .clamp(1, 1 << 20) as usize;
        let mut output = Vec::with_capacity(invocations * out_words);
        let mut start = 0;
        while start < invocations {
            let count = per_dispatch.min(invocations - start);
            let words = &input[start * in_words..(start + count) * in_words];
            output.extend(self.dispatch(function, shader, &scene_entries, count, words, out_words).await?);
            start += count;
        }
        Ok(output)
    }

    /// One dispatch of `count` invocations; returns their `out_words` result words each.
    async fn dispatch(
        &self,
        function: &str,
        shader: &HarnessShader,
        scene_entries: &[BufferEntry],
        count: usize,
        input: &[u32],
        out_words: usize,
    ) -> Result<Vec<u32>, HarnessError> {
        let d = &self.device.device;
        let r = &shader.resources;
        let scope = d.push_error_scope(wgpu::ErrorFilter::Validation);
        // A binding cannot be empty: at least one word each.
        let args_bytes: &[u8] = if input.is_empty() { &[0u8; 4] } else { bytemuck::cast_slice(input) };
        let args = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(ARGS_BUFFER),
            contents: args_bytes,
            usage: wgpu::BufferUsages::STORAGE,
        });
        let results_size = (count * out_words.max(1) * 4) as u64;
        let results = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some(RESULTS_BUFFER),
            size: results_size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("harness readback"),
            size: results_size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let count_bytes = u32_uniform_bytes(r.own(COUNT_UNIFORM), |m| (m == "n").then_some(count as u32))?;
        let count_buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(COUNT_UNIFORM),
            contents: &count_bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let own = [
            BufferEntry::storage(r.own(ARGS_BUFFER), args, true),
            BufferEntry::storage(r.own(RESULTS_BUFFER), results.clone(), false),
            BufferEntry::uniform(r.own(COUNT_UNIFORM), count_buffer),
        ];
        let entries: Vec<&BufferEntry> = scene_entries.iter().chain(&own).collect();
        let bind_groups = pipeline_bind_groups(d, &shader.pipeline, &entries, "lightport harness");
        let mut encoder = d.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("lightport harness"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&shader.pipeline);
            for (i, group) in bind_groups.iter().enumerate() {
                pass.set_bind_group(i as u32, group, &[]);
            }
            pass.dispatch_workgroups((count as u32).div_ceil(WORKGROUP_SIZE), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&results, 0, &readback, 0, results_size);
        self.device.queue.submit([encoder.finish()]);
        if let Some(e) = scope.pop().await {
            return Err(WgpuError::Wgpu { what: "running the harness", detail: format!("`{function}`: {e}") }.into());
        }
        let slice = readback.slice(..);
        let mapped = Mapped::default();
        let sender = mapped.clone();
        slice.map_async(wgpu::MapMode::Read, move |result| sender.complete(result));
        let failed = |e: String| WgpuError::Wgpu { what: "reading the harness results", detail: e };
        d.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| failed(e.to_string()))?;
        mapped.await.map_err(|e| failed(e.to_string()))?;
        let words: Vec<u32> = {
            let view = slice.get_mapped_range().map_err(|e| failed(e.to_string()))?;
            bytemuck::pod_collect_to_vec(&view)
        };
        readback.unmap();
        Ok(words[..count * out_words].to_vec())
    }
}

/// The outcome of a `map_async`, as a future: resolved by the callback (natively during
/// `device.poll`, in the browser from the event loop).
#[derive(Clone, Default)]
struct Mapped(Arc<Mutex<MapState>>);

#[derive(Default)]
struct MapState {
    result: Option<Result<(), wgpu::BufferAsyncError>>,
    waker: Option<Waker>,
}

impl Mapped {
    fn complete(&self, result: Result<(), wgpu::BufferAsyncError>) {
        let mut state = self.0.lock().unwrap_or_else(|p| p.into_inner());
        state.result = Some(result);
        if let Some(waker) = state.waker.take() {
            waker.wake();
        }
    }
}

impl Future for Mapped {
    type Output = Result<(), wgpu::BufferAsyncError>;
    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Self::Output> {
        let mut state = self.0.lock().unwrap_or_else(|p| p.into_inner());
        match state.result.take() {
            Some(result) => Poll::Ready(result),
            None => {
                state.waker = Some(cx.waker().clone());
                Poll::Pending
            }
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
impl Runtime for WgpuHarness {
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }

    fn backend(&self) -> Backend {
        Backend::Wgpu
    }
    fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        WgpuHarness::set_scene(self, scene)
    }
    fn set_specialization(&mut self, specialize: BTreeMap<String, u32>) {
        WgpuHarness::set_specialization(self, specialize)
    }
    fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        WgpuHarness::layout(self, function)
    }
    fn run_words(&mut self, function: &str, invocations: usize, input: &[u32]) -> Result<Vec<u32>, HarnessError> {
        WgpuHarness::run_words(self, function, invocations, input)
    }
}
