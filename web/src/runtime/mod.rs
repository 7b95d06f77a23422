//! The two runtimes the viewer drives, behind one small interface: WebGL2 (the GL backend) and
//! WebGPU (the wgpu backend). Everything the page does (frames, the frame loop's steps, camera
//! and setting changes, read-backs, screenshots, the read-outs) goes through [`Runtime`]: what
//! concerns the renderer through its [`Renderer`] trait object, what concerns the canvas (the
//! display pass, frame pacing, the context) through the runtime itself.

pub mod preview;
pub mod webgl2;
pub mod webgpu;

use std::future::Future;
use std::pin::Pin;

use glam::Vec4;
use js_sys::Object;
use tracer::backend::frame_split::Step;
use tracer::backend::{Renderer, Schedule};
use tracer::kernel::scene_data::Scene;
use tracer::output::Display;
use tracer::pack::Packed;
use wasm_bindgen::JsValue;

use crate::js::set;

pub use preview::{Preview, PreviewState};
pub use webgl2::GlRuntime;
pub use webgpu::{GpuDevice, GpuRuntime};

/// Which graphics API the page asks for (`?api=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Api {
    /// WebGPU where the browser offers it and the scene fits its limits, else WebGL2.
    Auto,
    WebGpu,
    WebGl2,
}

impl Api {
    pub fn parse(name: &str) -> Result<Api, String> {
        match name.to_ascii_lowercase().as_str() {
            "" | "auto" => Ok(Api::Auto),
            "webgpu" => Ok(Api::WebGpu),
            "webgl2" => Ok(Api::WebGl2),
            other => Err(format!("unknown graphics API {other:?}: use auto, webgpu or webgl2")),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Api::Auto => "auto",
            Api::WebGpu => "webgpu",
            Api::WebGl2 => "webgl2",
        }
    }
}

/// What creating a runtime took (the page's first-frame read-out): milliseconds on this thread
/// for generating the kernel's shader (`codegen_ms`), compiling it and the display pass's
/// (`compile_ms`: WebGL2's compile and link, which it answers synchronously; WebGPU's pipeline
/// creation calls only) and getting the scene onto the GPU (`upload_ms`: the data handed over;
/// on WebGL2 also the `finish()` that waits for the driver to take it), and for WebGPU, which
/// compiles asynchronously, when the device's verdict on the kernel's pipeline arrived
/// (`compiled_at`, a `performance.now()` time, to compare with `created_at`, when the runtime
/// was ready), and whether the compile overlapped the bundle's decode (`compiled_while_decoding`).
#[derive(Clone, Debug, Default)]
pub struct Startup {
    pub codegen_ms: f64,
    pub compile_ms: f64,
    pub upload_ms: f64,
    pub created_at: f64,
    pub compiled_at: Option<f64>,
    /// The kernel was compiled from the bundle's features while the bundle was decoded
    /// (`viewer::prepare`): `compile_ms` is then the calls made before the decode plus what
    /// the compile still took after it, not the compile's whole duration.
    pub compiled_while_decoding: bool,
}

impl Startup {
    /// As a JavaScript object: `codegenMs`, `compileMs`, `uploadMs`, `createdAt`,
    /// `compiledAt` (`null` until the device answered) and `compiledWhileDecoding`.
    pub fn describe(&self) -> Object {
        let o = Object::new();
        set(&o, "codegenMs", self.codegen_ms);
        set(&o, "compileMs", self.compile_ms);
        set(&o, "uploadMs", self.upload_ms);
        set(&o, "createdAt", self.created_at);
        set(&o, "compiledAt", self.compiled_at.map_or(JsValue::NULL, JsValue::from));
        set(&o, "compiledWhileDecoding", self.compiled_while_decoding);
        o
    }
}

/// A future of a read-back's result.
pub type Pending<T> = Pin<Box<dyn Future<Output = Result<T, String>>>>;

/// The renderer that runs, with its display pass and frame pacing.
pub enum Runtime {
    // Boxed: a runtime holds its renderer, pacing and display pass inline (up to ~1.4 KB).
    WebGl2(Box<GlRuntime>),
    WebGpu(Box<GpuRuntime>),
}

impl Runtime {
    /// "WebGL2" or "WebGPU", as the read-out shows it.
    pub fn api(&self) -> &'static str {
        match self {
            Runtime::WebGl2(_) => "WebGL2",
            Runtime::WebGpu(_) => "WebGPU",
        }
    }

    /// The renderer, whichever runtime holds it.
    pub fn renderer(&self) -> &dyn Renderer {
        match self {
            Runtime::WebGl2(r) => r.renderer(),
            Runtime::WebGpu(r) => r.renderer(),
        }
    }

    /// How the renderer organises a frame (WebGL2: always the megakernel).
    pub fn schedule(&self) -> Schedule {
        match self {
            Runtime::WebGl2(_) => Schedule::Megakernel,
            Runtime::WebGpu(r) => r.renderer().schedule(),
        }
    }

    fn renderer_mut(&mut self) -> &mut dyn Renderer {
        match self {
            Runtime::WebGl2(r) => r.renderer_mut(),
            Runtime::WebGpu(r) => r.renderer_mut(),
        }
    }

    pub fn frames(&self) -> u32 {
        self.renderer().frames()
    }

    pub fn packed(&self) -> &Packed {
        self.renderer().packed()
    }

    /// What creating it took.
    pub fn startup(&self) -> Startup {
        match self {
            Runtime::WebGl2(r) => r.startup(),
            Runtime::WebGpu(r) => r.startup(),
        }
    }

    /// Its preview (`preview.rs`).
    pub fn preview(&self) -> &Preview {
        match self {
            Runtime::WebGl2(r) => r.preview(),
            Runtime::WebGpu(r) => r.preview(),
        }
    }

    fn preview_mut(&mut self) -> &mut Preview {
        match self {
            Runtime::WebGl2(r) => r.preview_mut(),
            Runtime::WebGpu(r) => r.preview_mut(),
        }
    }

    /// Asks for previews (`on`: before the accumulation's first frame if it has not begun, and
    /// after restarts), or for none (a pending one or one on show is dropped).
    pub fn set_preview(&mut self, on: bool) {
        let (state, fresh) = (self.preview().state, self.frames() == 0);
        match (on, state) {
            (true, PreviewState::Off) => {
                let mut preview = Preview::new(true);
                if !fresh {
                    preview.state = PreviewState::Replaced;
                }
                *self.preview_mut() = preview;
            }
            (false, state) if state != PreviewState::Off => *self.preview_mut() = Preview::new(false),
            _ => {}
        }
    }

    /// How the frame loop splits frames into bands (`tracer::backend::frame_split`).
    fn band_policy(&self) -> &tracer::backend::frame_split::BandPolicy {
        match self {
            Runtime::WebGl2(r) => r.pacer().policy(),
            Runtime::WebGpu(r) => r.policy(),
        }
    }

    /// The accumulation restarted: the preview follows (`Preview::restarted`), previewing the
    /// new view where whole frames were measured to exceed the band budget (not merely split
    /// because nothing was measured yet: a fast device would preview every pose of a playing
    /// animation and never measure a band).
    fn restarted(&mut self) {
        let slow = self.band_policy().frames_exceed_budget();
        self.preview_mut().restarted(slow);
    }

    /// Checks, without waiting, whether the GPU is done with what was submitted (a band, a
    /// preview), recording a band's time if so: true when nothing is in flight.
    pub fn poll(&mut self, now_ms: f64) -> bool {
        match self {
            Runtime::WebGl2(r) => r.poll(now_ms),
            Runtime::WebGpu(r) => r.poll(now_ms),
        }
    }

    /// Renders the pending preview now (the test hook's `renderPreview`) if the accumulation
    /// has not begun, and shows it: whether it did.
    pub fn preview_now(&mut self, now_ms: f64, display: &Display) -> bool {
        match self {
            Runtime::WebGl2(r) => r.preview_now(now_ms, display),
            Runtime::WebGpu(r) => r.preview_now(now_ms, display),
        }
    }

    /// Whether the runtime's context or device is gone (nothing may be drawn).
    pub fn lost(&self) -> bool {
        match self {
            Runtime::WebGl2(r) => r.context_lost(),
            Runtime::WebGpu(_) => false,
        }
    }

    /// The rest of the frame, then the display pass through `display`: whether the frame is
    /// done (the megakernel's always is, in one submission; the wavefront's is done once a
    /// read of its counters, which in the browser arrives with a promise, says so: call
    /// again after [`sync`](Self::sync)).
    pub fn frame(&mut self, display: &Display) -> Result<bool, String> {
        match self {
            Runtime::WebGl2(r) => r.frame(display).map(|()| true),
            Runtime::WebGpu(r) => r.frame(display),
        }
    }

    /// [`frame`](Self::frame) in bands of `rows` rows submitted back to back.
    pub fn frame_in_bands(&mut self, rows: u32, display: &Display) -> Result<bool, String> {
        match self {
            Runtime::WebGl2(r) => r.frame_in_bands(rows, display).map(|()| true),
            Runtime::WebGpu(r) => r.frame_in_bands(rows, display),
        }
    }

    /// The display pass alone (a display setting changed).
    pub fn draw(&self, display: &Display) {
        match self {
            Runtime::WebGl2(r) => r.draw(display),
            Runtime::WebGpu(r) => r.draw(display),
        }
    }

    /// Draws a denoised image of the renderer's size (named `id`: uploaded once) through
    /// `display`, in place of the accumulation's mean.
    pub fn draw_image(&mut self, image: &tracer::backend::Image, id: u64, display: &Display) -> Result<(), String> {
        match self {
            Runtime::WebGl2(r) => r.draw_image(image, id, display),
            Runtime::WebGpu(r) => r.draw_image(image, id, display),
        }
    }

    /// The frame loop's step: a band, unless one is on the GPU.
    pub fn step(&mut self, now_ms: f64, display: &Display) -> Result<Step, String> {
        match self {
            Runtime::WebGl2(r) => r.step(now_ms, display),
            Runtime::WebGpu(r) => r.step(now_ms, display),
        }
    }

    pub fn set_band_budget(&mut self, budget_ms: Option<f64>) {
        match self {
            Runtime::WebGl2(r) => r.set_band_budget(budget_ms),
            Runtime::WebGpu(r) => r.set_band_budget(budget_ms),
        }
    }

    /// Sets uniforms through `update` and restarts the accumulation.
    pub fn set_uniforms(&mut self, mut update: impl FnMut(&mut Scene)) -> Result<(), String> {
        self.renderer_mut().set_uniforms(&mut update).map_err(|e| e.to_string())?;
        self.restarted();
        Ok(())
    }

    /// Takes a moved scene's geometry (`Renderer::take_geometry`) and restarts the accumulation.
    pub fn take_geometry(&mut self, moved: Packed) -> Result<(), tracer::backend::RenderError> {
        self.renderer_mut().take_geometry(moved)?;
        self.restarted();
        Ok(())
    }

    /// Resolves once the GPU has done the work queued so far (WebGL2: already, by a 1-pixel
    /// read-back; WebGPU: `onSubmittedWorkDone`).
    pub fn sync(&self) -> Pin<Box<dyn Future<Output = ()>>> {
        match self {
            Runtime::WebGl2(r) => {
                r.sync();
                Box::pin(std::future::ready(()))
            }
            Runtime::WebGpu(r) => Box::pin(r.sync()),
        }
    }

    /// The running sum per pixel (rows from the top; rgb: sum, w: finite samples).
    pub fn read_accumulation(&self) -> Pending<Vec<Vec4>> {
        let read = self.renderer().read_accumulation();
        Box::pin(async move { read.await.map_err(|e| e.to_string()) })
    }

    /// The read-outs of `sceneInfo`: the API and adapter, and how frames are submitted.
    pub fn describe(&self, info: &Object) {
        set(info, "api", self.api());
        set(info, "schedule", self.schedule().name());
        let policy = self.band_policy();
        let busy = match self {
            Runtime::WebGl2(r) => r.pacer().busy(),
            Runtime::WebGpu(r) => r.busy(),
        };
        set(info, "bands", policy.bands());
        set(info, "bandRows", policy.rows());
        set(info, "bandMs", policy.band_ms().map_or(JsValue::NULL, JsValue::from));
        set(info, "gpuBusy", busy);
        set(info, "preview", self.preview().describe());
        match self {
            Runtime::WebGl2(r) => {
                let gl = r.renderer().info();
                set(info, "adapter", gl.renderer.as_str());
                set(info, "glRenderer", gl.renderer.as_str());
                set(info, "glVersion", gl.version.as_str());
                set(info, "maxTextureSize", gl.max_texture_size);
            }
            Runtime::WebGpu(r) => {
                let w = &r.renderer().device().info;
                set(info, "adapter", w.adapter.as_str());
                set(info, "gpuDriver", w.driver.as_str());
                set(info, "maxStorageBufferBindingSize", w.max_storage_buffer_binding_size as f64);
                set(
                    info,
                    "maxStorageBuffersPerShaderStage",
                    r.renderer().device().limits.max_storage_buffers_per_shader_stage,
                );
            }
        }
    }
}
