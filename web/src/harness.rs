//! The browser side of the equivalence harness's WebGL2 and WebGPU runtimes
//! (`tracer::backend::harness::browser`): [`HarnessRuntime`] is the native
//! [`GlHarness`] on a WebGL2 context, or the native [`WgpuHarness`] on a WebGPU device, over a
//! program linked from the IR modules the native side sends. `web/www/harness.js` calls it for
//! `tests/web/harness.mjs`. The page's WebGL2 context and WebGPU device are shared by every
//! runtime it creates (one per test), so that no test waits for a device and Chromium's limit
//! on live WebGL contexts is never reached.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

use glam::Vec4;
use lightport_codegen::{ir, Program};
use tracer::backend::gl::GlFilter;
use tracer::backend::harness::{
    decode_resources, decode_scene, GlHarness, GlHarnessOptions, HarnessError, WgpuHarness,
};
use tracer::backend::wgpu::{WgpuDevice, WgpuFilter};
use tracer::kernel::denoise::FilterImage;
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use web_sys::{HtmlCanvasElement, WebGl2RenderingContext};

use crate::js::js_error;

enum Harness {
    Gl(Box<GlHarness>),
    Wgpu(Box<WgpuHarness>),
}

thread_local! {
    static WEBGL2: RefCell<Option<WebGl2RenderingContext>> = const { RefCell::new(None) };
    static WEBGPU: RefCell<Option<Rc<WgpuDevice>>> = const { RefCell::new(None) };
}

fn link(modules_json: &str) -> Result<Program, JsError> {
    let modules: Vec<ir::Module> =
        serde_json::from_str(modules_json).map_err(|e| js_error(format!("the IR modules: {e}")))?;
    Program::link(&modules).map_err(js_error)
}

/// The page's WebGL2 context, created on first use on a canvas of its own.
fn webgl2_context() -> Result<WebGl2RenderingContext, JsError> {
    if let Some(context) = WEBGL2.with(|c| c.borrow().clone()) {
        return Ok(context);
    }
    let document = web_sys::window().and_then(|w| w.document()).ok_or_else(|| js_error("no document"))?;
    let canvas: HtmlCanvasElement = document
        .create_element("canvas")
        .map_err(|e| js_error(format!("{e:?}")))?
        .dyn_into()
        .map_err(|_| js_error("not a canvas"))?;
    let context: WebGl2RenderingContext = canvas
        .get_context("webgl2")
        .map_err(|e| js_error(format!("{e:?}")))?
        .ok_or_else(|| js_error("this browser offers no WebGL2"))?
        .dyn_into()
        .map_err(|_| js_error("not a WebGL2 context"))?;
    WEBGL2.with(|c| *c.borrow_mut() = Some(context.clone()));
    Ok(context)
}

/// The page's WebGPU device, requested on first use (every limit the adapter offers).
async fn webgpu_device() -> Result<Rc<WgpuDevice>, JsError> {
    if let Some(device) = WEBGPU.with(|d| d.borrow().clone()) {
        return Ok(device);
    }
    let device = Rc::new(WgpuHarness::browser_device().await.map_err(js_error)?);
    WEBGPU.with(|d| *d.borrow_mut() = Some(device.clone()));
    Ok(device)
}

/// One harness of the page: WebGL2 or WebGPU.
#[wasm_bindgen]
pub struct HarnessRuntime {
    /// Taken out while a future runs (no borrow is held across an await).
    harness: Rc<RefCell<Option<Harness>>>,
    info: String,
}

fn take(harness: &Rc<RefCell<Option<Harness>>>) -> Result<Harness, HarnessError> {
    harness.borrow_mut().take().ok_or(HarnessError::Layout {
        function: String::new(),
        detail: "the runtime is busy with another request".into(),
    })
}

#[wasm_bindgen]
impl HarnessRuntime {
    /// The GL harness on the page's WebGL2 context.
    pub fn webgl2(modules_json: &str) -> Result<HarnessRuntime, JsError> {
        let context = webgl2_context()?;
        let gl = glow::Context::from_webgl2_context(context);
        let info = {
            use glow::HasContext;
            // SAFETY: plain string queries on the context just created.
            unsafe {
                format!("{} ({})", gl.get_parameter_string(glow::RENDERER), gl.get_parameter_string(glow::VERSION))
            }
        };
        let harness = GlHarness::new(gl, link(modules_json)?, GlHarnessOptions::default()).map_err(js_error)?;
        Ok(HarnessRuntime { harness: Rc::new(RefCell::new(Some(Harness::Gl(Box::new(harness))))), info })
    }

    /// The wgpu harness on the page's WebGPU device.
    pub async fn webgpu(modules_json: String) -> Result<HarnessRuntime, JsError> {
        let program = link(&modules_json)?;
        let device = webgpu_device().await?;
        let info = format!("{} ({}, {})", device.info.adapter, device.info.driver, device.info.backend);
        // A clone shares the page's one device.
        let harness = WgpuHarness::new(WgpuDevice::clone(&device), program);
        Ok(HarnessRuntime { harness: Rc::new(RefCell::new(Some(Harness::Wgpu(Box::new(harness))))), info })
    }

    /// The renderer (WebGL2) or adapter (WebGPU) it runs on.
    pub fn info(&self) -> String {
        self.info.clone()
    }

    /// The scene (as `tracer::backend::harness::encode_scene` words) for functions taking it.
    #[wasm_bindgen(js_name = setScene)]
    pub fn set_scene(&self, words: &[u32]) -> Result<(), JsError> {
        let scene = decode_scene(words).map_err(js_error)?;
        let mut harness = take(&self.harness).map_err(js_error)?;
        let result = match &mut harness {
            Harness::Gl(h) => h.set_scene(&scene),
            Harness::Wgpu(h) => h.set_scene(&scene),
        };
        *self.harness.borrow_mut() = Some(harness);
        result.map_err(js_error)
    }

    /// Specialises the shaders (a JSON object of const names to values).
    #[wasm_bindgen(js_name = setSpecialization)]
    pub fn set_specialization(&self, json: &str) -> Result<(), JsError> {
        let specialize: BTreeMap<String, u32> = serde_json::from_str(json).map_err(js_error)?;
        match self.harness.borrow_mut().as_mut() {
            Some(Harness::Gl(h)) => h.set_specialization(specialize),
            Some(Harness::Wgpu(h)) => h.set_specialization(specialize),
            None => return Err(js_error("the runtime is busy with another request")),
        }
        Ok(())
    }

    /// Compiles `function`'s harness shader; resolves to `[input words, output words]`.
    pub fn layout(&self, function: String) -> js_sys::Promise {
        let cell = self.harness.clone();
        wasm_bindgen_futures::future_to_promise(async move {
            let mut harness = take(&cell).map_err(|e| JsValue::from(js_error(e)))?;
            let layout = match &mut harness {
                Harness::Gl(h) => h.layout(&function),
                Harness::Wgpu(h) => h.layout_async(&function).await,
            };
            *cell.borrow_mut() = Some(harness);
            let layout = layout.map_err(|e| JsValue::from(js_error(e)))?;
            Ok(js_sys::Uint32Array::from(&[layout.input_words, layout.output_words][..]).into())
        })
    }

    /// Runs `function` on `invocations` argument sets; resolves to the output words.
    #[wasm_bindgen(js_name = runWords)]
    pub fn run_words(&self, function: String, invocations: usize, input: Vec<u32>) -> js_sys::Promise {
        let cell = self.harness.clone();
        wasm_bindgen_futures::future_to_promise(async move {
            let mut harness = take(&cell).map_err(|e| JsValue::from(js_error(e)))?;
            let words = match &mut harness {
                Harness::Gl(h) => h.run_words(&function, invocations, &input),
                Harness::Wgpu(h) => h.run_words_async(&function, invocations, &input).await,
            };
            *cell.borrow_mut() = Some(harness);
            let words = words.map_err(|e| JsValue::from(js_error(e)))?;
            Ok(js_sys::Uint32Array::from(words.as_slice()).into())
        })
    }

    /// The denoiser's filter passes over a `FilterImage` (as `encode_resources` words) on this
    /// runtime's context or device: `GlFilter` on WebGL2, `WgpuFilter` on WebGPU (what
    /// `Renderer::denoise_passes` runs natively); resolves to `{ words, ms }`: the last pass's
    /// output as words, and the passes' time in the page (the passes and reading their output
    /// back; not compiling the pass, which a renderer does once).
    #[wasm_bindgen(js_name = runFilter)]
    pub fn run_filter(&self, input: Vec<u32>) -> js_sys::Promise {
        let cell = self.harness.clone();
        wasm_bindgen_futures::future_to_promise(async move {
            let image: FilterImage = decode_resources(&input).map_err(|e| JsValue::from(js_error(e)))?;
            let harness = take(&cell).map_err(|e| JsValue::from(js_error(e)))?;
            let output = match &harness {
                Harness::Gl(h) => gl_filter(h.gl(), &image),
                Harness::Wgpu(h) => wgpu_filter(h.device(), &image).await,
            };
            *cell.borrow_mut() = Some(harness);
            let (output, ms) = output.map_err(|e| JsValue::from(js_error(e)))?;
            let words: Vec<u32> = output.iter().flat_map(|t| t.to_array().map(f32::to_bits)).collect();
            let reply = js_sys::Object::new();
            crate::js::set(&reply, "words", js_sys::Uint32Array::from(words.as_slice()));
            crate::js::set(&reply, "ms", ms);
            Ok(reply.into())
        })
    }
}

/// The passes' output and their time in milliseconds (the compile not counted).
fn gl_filter(gl: &glow::Context, image: &FilterImage) -> Result<(Vec<Vec4>, f64), String> {
    let filter = GlFilter::new(gl).map_err(|e| e.to_string())?;
    let started = crate::js::now_ms();
    let output = filter.run(gl, image).map_err(|e| e.to_string());
    let ms = crate::js::now_ms() - started;
    filter.delete(gl);
    Ok((output?, ms))
}

/// The passes' output and their time in milliseconds (the compile not counted).
async fn wgpu_filter(device: &WgpuDevice, image: &FilterImage) -> Result<(Vec<Vec4>, f64), String> {
    let filter = WgpuFilter::new(device).await.map_err(|e| e.to_string())?;
    let started = crate::js::now_ms();
    let output = filter.run(device, image).map_err(|e| e.to_string())?.await.map_err(|e| e.to_string())?;
    Ok((output, crate::js::now_ms() - started))
}
