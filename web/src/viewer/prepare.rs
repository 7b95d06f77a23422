//! Compiling a served scene's kernel while its bundle is decoded. A bundle's features, which
//! decide the kernel variant, are read from its header in well under a millisecond
//! (`bundle::peek_features`); its decode (LZMA2 and the texture images, in wasm on the page's
//! thread) takes 0.3-0.8 s. Meanwhile the compile runs in the browser's GPU process: on
//! WebGL2, SwiftShader compiles the program at its first draw (seconds for the path tracer),
//! so the renderer is created for an empty scene of those features (`Packed::placeholder`)
//! and draws one pixel; on WebGPU the pipeline is compiled once created. The renderer then
//! takes the decoded scene (`Renderer::take_scene`: every array uploaded, the kernel kept).
//!
//! The page calls `prepareBundle(bytes)`, on WebGPU yields to the browser (WebGPU sends its
//! commands to the GPU process once the page's task ends), then `loadBundle(bytes)`.
//! The renderer is used only if the load would create the very same one (API, device or
//! context, features, size, seed, schedule, band budget); otherwise it is dropped, and the
//! load creates its renderer as before. A failed take does the same.

use tracer::backend::Schedule;
use tracer::kernel::Features;
use tracer::pack::Packed;
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsValue;
use web_sys::WebGl2RenderingContext;

use super::Viewer;
use crate::runtime::webgpu::{self, GpuRuntime};
use crate::runtime::{webgl2, Api, GlRuntime, GpuDevice};
use crate::schedule_choice::Choice;

/// A renderer created for the features of a bundle not yet decoded.
pub(super) struct Prepared {
    /// What the renderer was created for: the load uses it only for the same.
    features: Features,
    size: (u32, u32),
    seed: u32,
    band_budget_ms: Option<f64>,
    runtime: PreparedRuntime,
}

enum PreparedRuntime {
    WebGl2 { context: WebGl2RenderingContext, runtime: Box<GlRuntime> },
    WebGpu { gpu: Box<GpuDevice>, schedule: Schedule, prepared: Box<webgpu::Prepared> },
}

#[wasm_bindgen]
impl Viewer {
    /// Creates the renderer for the kernel the bundle `bytes` needs, on the API a load would
    /// choose, before the bundle is decoded: `loadBundle(bytes)` then only decodes and uploads
    /// (see the module's comment). The API it did so on, "WebGPU" (the page must then yield
    /// to the browser before `loadBundle`, for WebGPU sends its commands once the page's task
    /// ends) or "WebGL2" (its commands are sent already: `loadBundle` at once, for a yield
    /// would wait for the compile: the browser's rendering update between tasks waits for the
    /// GPU process), or `undefined` where it did not (a bundle it cannot read, or no renderer
    /// a load would create now: a lost context, say); either way `loadBundle` does the rest.
    /// A renderer prepared before is dropped.
    #[wasm_bindgen(js_name = prepareBundle)]
    pub fn prepare_bundle(&mut self, bytes: &[u8]) -> Option<String> {
        self.prepared = None;
        let features = tracer::bundle::peek_features(bytes).ok()?;
        let (width, height) = (self.settings.width, self.settings.height);
        let mut placeholder = Packed::placeholder(features, width, height);
        // As `install` asks of the scene.
        placeholder.set_denoise_guide(self.denoiser.enabled());
        let runtime = match self.planned_api() {
            Some(Api::WebGpu) => self.prepare_webgpu(&placeholder),
            Some(_) => self.prepare_webgl2(&placeholder),
            None => None,
        };
        let api = match runtime.as_ref()? {
            PreparedRuntime::WebGl2 { .. } => "WebGL2",
            PreparedRuntime::WebGpu { .. } => "WebGPU",
        };
        self.prepared = runtime.map(|runtime| Prepared {
            features: placeholder.features,
            size: (width, height),
            seed: self.seed,
            band_budget_ms: self.band_budget_ms,
            runtime,
        });
        Some(api.to_string())
    }
}

impl Viewer {
    fn prepare_webgpu(&self, placeholder: &Packed) -> Option<PreparedRuntime> {
        let gpu = self.gpu.clone()?;
        // A loaded scene starts on the megakernel under auto (its measurement comes later).
        let schedule = self.schedule.unwrap_or_else(|| Choice::default().schedule());
        let prepared = GpuRuntime::prepare(&gpu, placeholder, self.seed, &self.wgpu_options, schedule).ok()?;
        Some(PreparedRuntime::WebGpu { gpu: Box::new(gpu), schedule, prepared: Box::new(prepared) })
    }

    fn prepare_webgl2(&mut self, placeholder: &Packed) -> Option<PreparedRuntime> {
        // Never a new canvas (a switch from WebGPU), which would drop the running renderer.
        if self.context_lost || self.canvas_api.is_some_and(|a| a != Api::WebGl2) {
            return None;
        }
        let context = match &self.gl_context {
            Some(c) => c.clone(),
            None => {
                let canvas = self.canvas_for(Api::WebGl2).ok()?;
                let c = webgl2::context(&canvas).ok()?;
                self.gl_context = Some(c.clone());
                c
            }
        };
        let mut runtime = GlRuntime::new(&context, placeholder, self.seed, &self.options, self.band_budget_ms).ok()?;
        runtime.warm_up().ok()?;
        Some(PreparedRuntime::WebGl2 { context, runtime: Box::new(runtime) })
    }

    /// Whether the prepared renderer is the one a load would create for `packed` now.
    fn prepared_for(&self, packed: &Packed) -> bool {
        self.prepared.as_ref().is_some_and(|p| {
            let s = &packed.scene;
            p.features == packed.features
                && p.size == (s.width, s.height)
                && p.seed == self.seed
                && p.band_budget_ms == self.band_budget_ms
        })
    }

    /// The WebGL2 runtime prepared for `packed` on `context`, having taken it; `None` (and the
    /// prepared renderer dropped) where there is none or it does not fit.
    pub(super) fn take_prepared_webgl2(
        &mut self,
        packed: &Packed,
        context: &WebGl2RenderingContext,
    ) -> Option<GlRuntime> {
        let fits = self.prepared_for(packed);
        let Prepared { runtime: PreparedRuntime::WebGl2 { context: prepared_on, mut runtime }, .. } =
            self.prepared.take()?
        else {
            return None;
        };
        let same_context = JsValue::from(prepared_on) == JsValue::from(context.clone());
        (fits && same_context && runtime.take_scene(packed.clone()).is_ok()).then_some(*runtime)
    }

    /// The WebGPU renderer prepared for `packed` on `gpu` with `schedule`, having taken it;
    /// `None` (and the prepared renderer dropped) where there is none or it does not fit.
    pub(super) fn take_prepared_webgpu(
        &mut self,
        packed: &Packed,
        gpu: &GpuDevice,
        schedule: Schedule,
    ) -> Option<webgpu::Prepared> {
        let fits = self.prepared_for(packed);
        let Prepared { runtime: PreparedRuntime::WebGpu { gpu: prepared_on, schedule: planned, mut prepared }, .. } =
            self.prepared.take()?
        else {
            return None;
        };
        let same_device = prepared_on.same_device(gpu) && gpu.lost().is_none();
        (fits && same_device && planned == schedule && prepared.take_scene(packed.clone()).is_ok()).then_some(*prepared)
    }
}
