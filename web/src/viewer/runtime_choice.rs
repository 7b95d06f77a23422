//! Which runtime runs the scene: the API asked for (`setApi`), WebGPU's limits and failures
//! (auto falls back to WebGL2 with a notice), the canvas for each kind of context, and what an
//! error of the running renderer does.

use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use web_sys::HtmlCanvasElement;

use tracer::backend::wavefront::WavefrontError;
use tracer::backend::Schedule;
use tracer::pack::Packed;

use super::{Viewer, MAX_GPU_RECOVERIES};
use crate::runtime::{webgl2, Api, GlRuntime, GpuRuntime, Runtime};
use crate::schedule_choice::Choice;

impl Viewer {
    /// A renderer and display pass for `packed`, on the API chosen ([`set_api`](Self::set_api)),
    /// its first image a preview unless turned off (`setPreview`).
    pub(super) fn start(&mut self, packed: &Packed) -> Result<Runtime, JsError> {
        let mut runtime = self.start_runtime(packed)?;
        runtime.set_preview(self.preview);
        Ok(runtime)
    }

    /// The API [`start_runtime`](Self::start_runtime) tries first now (`None`: it refuses, a
    /// wavefront asked of WebGL2); also what a renderer compiled ahead is made for
    /// (`prepare.rs`).
    pub(super) fn planned_api(&self) -> Option<Api> {
        let gpu_ready = self.gpu.as_ref().is_some_and(|g| g.lost().is_none());
        match self.api {
            Api::WebGpu => Some(Api::WebGpu),
            Api::Auto if gpu_ready => Some(Api::WebGpu),
            Api::WebGl2 if self.schedule == Some(Schedule::Wavefront) => None,
            Api::WebGl2 | Api::Auto => Some(Api::WebGl2),
        }
    }

    fn start_runtime(&mut self, packed: &Packed) -> Result<Runtime, JsError> {
        self.notice = None;
        let no_compute = || JsError::new(&WavefrontError::NoCompute { runtime: "WebGL2" }.to_string());
        let planned = self.planned_api().ok_or_else(no_compute)?;
        if planned == Api::WebGpu {
            match self.start_webgpu(packed) {
                Ok(runtime) => return Ok(runtime),
                Err(e) if self.api == Api::WebGpu => return Err(JsError::new(&e)),
                Err(e) => self.notice = Some(format!("WebGPU cannot run this scene, so WebGL2 does: {e}")),
            }
        } else if self.api == Api::Auto {
            let why = self.gpu_unavailable.as_deref().unwrap_or("no WebGPU device was requested");
            self.notice = Some(format!("WebGPU is not available, so WebGL2 runs: {why}"));
        }
        if self.schedule == Some(Schedule::Wavefront) {
            if let Some(notice) = &mut self.notice {
                notice.push_str(" (with the megakernel: the wavefront needs WebGPU's compute shaders)");
            }
        }
        self.start_webgl2(packed)
    }

    pub(super) fn start_webgpu(&mut self, packed: &Packed) -> Result<Runtime, String> {
        let gpu = self.gpu.clone().ok_or_else(|| {
            let why = self.gpu_unavailable.as_deref().unwrap_or("requestWebGpu() was not called");
            format!("WebGPU is not available: {why}")
        })?;
        // Limits are checked and the scene uploaded before the canvas gets a WebGPU context.
        // Under auto, what the scene's measurement chose (the megakernel until then).
        let schedule = self.schedule.unwrap_or_else(|| self.choice.schedule());
        let taken = self.take_prepared_webgpu(packed, &gpu, schedule).map(Ok);
        let prepared =
            match taken.unwrap_or_else(|| GpuRuntime::prepare(&gpu, packed, self.seed, &self.wgpu_options, schedule)) {
                Err(e) if self.schedule.is_none() && schedule == Schedule::Wavefront => {
                    // The wavefront auto chose no longer builds (e.g. a size beyond its pool).
                    self.choice = Choice::Failed(format!("recreating it failed: {e}"));
                    GpuRuntime::prepare(&gpu, packed, self.seed, &self.wgpu_options, Schedule::Megakernel)?
                }
                prepared => prepared?,
            };
        let canvas = self.canvas_for(Api::WebGpu)?;
        canvas.set_width(packed.scene.width);
        canvas.set_height(packed.scene.height);
        Ok(Runtime::WebGpu(Box::new(GpuRuntime::attach(prepared, &canvas, self.band_budget_ms)?)))
    }

    pub(super) fn start_webgl2(&mut self, packed: &Packed) -> Result<Runtime, JsError> {
        if self.context_lost {
            return Err(JsError::new("the WebGL context is lost; waiting for the browser to restore it"));
        }
        let canvas = self.canvas_for(Api::WebGl2).map_err(|e| JsError::new(&e))?;
        let size = |canvas: &HtmlCanvasElement| {
            canvas.set_width(packed.scene.width);
            canvas.set_height(packed.scene.height);
        };
        // The renderer compiled while the bundle was decoded takes the scene before the canvas
        // is resized (a resize waits for the GPU process: for the compile it is finishing,
        // which the take counts as compile).
        if let Some(context) = self.gl_context.clone() {
            if let Some(runtime) = self.take_prepared_webgl2(packed, &context) {
                size(&canvas);
                return Ok(Runtime::WebGl2(Box::new(runtime)));
            }
        }
        size(&canvas);
        let context = match &self.gl_context {
            Some(c) => c.clone(),
            None => {
                let c = webgl2::context(&canvas).map_err(|e| JsError::new(&e))?;
                self.gl_context = Some(c.clone());
                c
            }
        };
        let runtime = GlRuntime::new(&context, packed, self.seed, &self.options, self.band_budget_ms)
            .map_err(|e| JsError::new(&e))?;
        Ok(Runtime::WebGl2(Box::new(runtime)))
    }

    /// The canvas for a context of `api`: the current one, unless it already gave out the
    /// other kind; then a new canvas element with the same attributes takes its place.
    pub(super) fn canvas_for(&mut self, api: Api) -> Result<HtmlCanvasElement, String> {
        if self.canvas_api.is_none_or(|a| a == api) {
            self.canvas_api = Some(api);
            return Ok(self.canvas.clone());
        }
        let failed = |e: JsValue| format!("replacing the canvas failed: {e:?}");
        let document = self.canvas.owner_document().ok_or("the canvas is not in a document")?;
        let fresh: HtmlCanvasElement =
            document.create_element("canvas").map_err(failed)?.dyn_into().map_err(|_| "not a canvas".to_string())?;
        for name in self.canvas.get_attribute_names().iter().filter_map(|n| n.as_string()) {
            if let Some(value) = self.canvas.get_attribute(&name) {
                fresh.set_attribute(&name, &value).map_err(failed)?;
            }
        }
        if self.canvas.is_connected() {
            self.canvas.replace_with_with_node_1(&fresh).map_err(failed)?;
        }
        // The old canvas's renderer (drawing into the detached element) goes now.
        self.running = None;
        self.canvas = fresh;
        self.canvas_api = Some(api);
        self.gl_context = None;
        self.context_lost = false;
        Ok(self.canvas.clone())
    }

    /// Whether nothing may be drawn now (a lost WebGL context or WebGPU device).
    pub(super) fn halted(&self) -> bool {
        match &self.running {
            None => true,
            Some(Runtime::WebGl2(r)) => self.context_lost || r.context_lost(),
            Some(Runtime::WebGpu(_)) => self.gpu.as_ref().is_none_or(|g| g.lost().is_some()),
        }
    }

    /// An error of the running renderer: on WebGPU (an uncaptured device error), the renderer
    /// is recreated from the scene in memory, a few times, with a notice; then, or at once for
    /// a shader the device rejected, auto moves to WebGL2 with a notice; else the error.
    pub(super) fn recover(&mut self, error: String) -> Result<(), JsError> {
        let Some(Runtime::WebGpu(gpu)) = &self.running else { return Err(JsError::new(&error)) };
        let rejected = gpu.shader_rejected();
        if !rejected && self.gpu_recoveries < MAX_GPU_RECOVERIES {
            self.gpu_recoveries += 1;
            self.rebuild()?;
            self.notice = Some(format!("WebGPU reported an error; the renderer was recreated: {error}"));
            return Ok(());
        }
        if self.api == Api::Auto {
            let why = if rejected { "it rejected the kernel" } else { "it kept reporting errors" };
            return self.web_gpu_unavailable(format!("{why} ({error})"));
        }
        Err(JsError::new(&error))
    }
}
