//! The WebGPU runtime: a wgpu backend's renderer (the generated WGSL as compute shaders over
//! storage buffers: the megakernel's [`WgpuRenderer`] or the [`WavefrontRenderer`], by the
//! [`Schedule`] asked for) on a device of the browser's WebGPU, and its display pass
//! ([`tracer::backend::wgpu::DisplayPass`]) drawing to the canvas's WebGPU surface.
//!
//! Nothing here blocks: the shader compiler's verdict, read-backs and the queue's completion
//! are promises. The frame loop submits each frame in bands of rows within the time budget, as
//! the WebGL2 runtime does (`tracer::backend::frame_split`'s [`BandPolicy`]), queued ahead
//! (`BandsInFlight`: up to three budgets of estimated work): each band's `onSubmittedWorkDone`
//! sets a flag, and its time (from its submission, or the news of the band before it, to the
//! animation frame that sees it done) chooses the next bands' height. The wavefront's bands are
//! its submissions (a bounded number of path segments each), one at a time; its frame is done
//! when the counters read after one say so.

use std::cell::{Cell, RefCell};
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use tracer::backend::frame_split::{BandPolicy, BandsInFlight, Step};
use tracer::backend::wgpu::{
    DeviceRenderer, DisplayPass, PipelineCheck, WavefrontRenderer, WgpuDevice, WgpuError, WgpuOptions, WgpuRenderer,
    WORKGROUP_SIZE,
};
use tracer::backend::{Image, Schedule};
use tracer::output::Display;
use tracer::pack::Packed;
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use web_sys::HtmlCanvasElement;

use super::preview::Preview;
use super::Startup;
use crate::denoise::show::GpuImageDisplay;
use crate::js::now_ms;

/// A WebGPU device for the viewer (what `requestWebGpu()` resolves to), and whether it was lost.
#[wasm_bindgen]
#[derive(Clone)]
pub struct GpuDevice {
    pub(crate) device: WgpuDevice,
    /// Why the device was lost (`device.lost`), once it was.
    pub(crate) lost: Arc<Mutex<Option<String>>>,
}

impl GpuDevice {
    /// Whether `other` is this device (a clone of the same handle).
    pub fn same_device(&self, other: &GpuDevice) -> bool {
        Arc::ptr_eq(&self.lost, &other.lost)
    }
}

#[wasm_bindgen]
impl GpuDevice {
    /// The adapter's name, e.g. "google / swiftshader".
    #[wasm_bindgen(getter)]
    pub fn adapter(&self) -> String {
        self.device.info.adapter.clone()
    }
}

impl GpuDevice {
    pub fn lost(&self) -> Option<String> {
        self.lost.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// Requests the browser's WebGPU adapter and a device with the adapter's limits (WebGPU's
/// defaults, e.g. 8 storage buffers per stage and 128 MiB bindings, are below what scenes
/// need). Rejects with a clear message where the browser has no WebGPU (`navigator.gpu` is
/// missing, or only exists in a secure context) or no adapter.
#[wasm_bindgen(js_name = requestWebGpu)]
pub async fn request_web_gpu() -> Result<GpuDevice, JsError> {
    let window = web_sys::window().ok_or_else(|| JsError::new("no window"))?;
    let gpu = js_sys::Reflect::get(&window.navigator(), &JsValue::from_str("gpu")).unwrap_or(JsValue::UNDEFINED);
    if gpu.is_undefined() || gpu.is_null() {
        return Err(JsError::new(
            "this browser has no WebGPU (navigator.gpu is missing: it needs a current Chrome, Edge or Safari, and a \
             secure context: https or http://127.0.0.1)",
        ));
    }
    // The adapter request goes out now, and the kernel's modules are parsed and linked while
    // the browser answers it (the first scene's shader is generated from them: a third of its
    // code generation, which the page would otherwise pay after the bundle's download).
    let adapter = request_adapter(&gpu);
    if let Err(e) = tracer::kernel::linked_kernel() {
        // Reported again, at the scene, by the shader that needs it.
        web_sys::console::warn_1(&format!("the kernel does not link: {e}").into());
    }
    let label = match adapter {
        Some(promise) => adapter_label(promise).await,
        None => None,
    };
    let mut device = WgpuDevice::request(wgpu::Backends::BROWSER_WEBGPU).await.map_err(|e| {
        // wgpu's own words name native drivers and apt packages: speak to a person in a browser.
        JsError::new(&match e {
            WgpuError::NoAdapter { .. } => "this browser offers WebGPU but no graphics adapter for it (WebGPU may \
                                            be turned off, or the GPU blocklisted: see chrome://gpu)"
                .to_string(),
            WgpuError::Device { detail, .. } => format!("the browser's WebGPU adapter refused a device: {detail}"),
            other => other.to_string(),
        })
    })?;
    if device.info.adapter.is_empty() {
        // wgpu names a browser adapter by its `description`, which Chromium leaves empty.
        device.info.adapter = label.unwrap_or_else(|| "unnamed WebGPU adapter".into());
    }
    let lost = Arc::new(Mutex::new(None));
    let sink = lost.clone();
    device.device.set_device_lost_callback(move |reason, message| {
        let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
        slot.get_or_insert_with(|| format!("{reason:?}: {message}"));
    });
    Ok(GpuDevice { device, lost })
}

/// `navigator.gpu.requestAdapter()` with wgpu's options, sent now (not when awaited).
fn request_adapter(gpu: &JsValue) -> Option<js_sys::Promise> {
    let request: js_sys::Function = js_sys::Reflect::get(gpu, &"requestAdapter".into()).ok()?.dyn_into().ok()?;
    let options = js_sys::Object::new();
    js_sys::Reflect::set(&options, &"powerPreference".into(), &"high-performance".into()).ok()?;
    request.call1(gpu, &options).ok()?.dyn_into().ok()
}

/// "vendor / architecture" (and the description, if any) of the adapter the browser gives for
/// the same request (`request_adapter`), from `GPUAdapter.info`; `None` where it tells nothing.
async fn adapter_label(request: js_sys::Promise) -> Option<String> {
    let get = |o: &JsValue, k: &str| js_sys::Reflect::get(o, &JsValue::from_str(k)).ok();
    let adapter = wasm_bindgen_futures::JsFuture::from(request).await.ok()?;
    let info = get(&adapter, "info")?;
    let field = |k: &str| get(&info, k).and_then(|v| v.as_string()).filter(|s| !s.is_empty());
    let mut label = [field("vendor"), field("architecture")].into_iter().flatten().collect::<Vec<_>>().join(" / ");
    if let Some(description) = field("description") {
        label = if label.is_empty() { description } else { format!("{label} ({description})") };
    }
    (!label.is_empty()).then_some(label)
}

/// The renderer, the canvas's surface and the display pass.
pub struct GpuRuntime {
    renderer: Box<dyn DeviceRenderer>,
    surface: wgpu::Surface<'static>,
    display: DisplayPass,
    /// How many rows each band covers, from the measured band times.
    policy: BandPolicy,
    /// The bands (and the preview) on the GPU, each with the flag its queue sets when done.
    in_flight: BandsInFlight<Arc<AtomicBool>>,
    /// The shader compiler's verdict, once it arrived with an error.
    compile_error: Rc<RefCell<Option<String>>>,
    /// What creating it took; `compiled_at` once the verdict arrived.
    startup: Startup,
    compiled_at: Rc<Cell<Option<f64>>>,
    /// The denoised image, as the display pass reads it.
    image_display: GpuImageDisplay,
    /// The preview (`super::preview`) and its pixels, once rendered.
    preview: Preview,
    preview_image: Option<wgpu::Buffer>,
}

/// Bands of `height` rows within `budget_ms`, each a whole number of the megakernel's
/// workgroup rows (a band of 1 row dispatches 8: 1.60x a whole frame's time on SwiftShader, 8
/// rows 0.99x; `BandPolicy::aligned_to`). With 8-row blocks one band timed at a fraction of its
/// time grows by a whole block: `BandsInFlight` bounds its rate from above for that reason
/// (news that came in bursts had timed 32 rows at "~3 ms" of a 2.3 s frame).
fn policy_for(height: u32, budget_ms: Option<f64>) -> BandPolicy {
    BandPolicy::new(height, budget_ms).aligned_to(WORKGROUP_SIZE[1])
}

/// Work in flight for `renderer`'s bands sized by `policy`: queued ahead for the megakernel;
/// one submission at a time for the wavefront, whose next submission follows from the last's
/// counters.
fn in_flight_for(renderer: &dyn DeviceRenderer, policy: &BandPolicy) -> BandsInFlight<Arc<AtomicBool>> {
    if renderer.schedule() == Schedule::Wavefront {
        BandsInFlight::new(0.0)
    } else {
        BandsInFlight::for_policy(policy)
    }
}

/// A renderer created on the device (limits checked, scene uploaded), not yet on a canvas:
/// a scene that does not fit is refused before the canvas is given a WebGPU context.
pub struct Prepared {
    renderer: Box<dyn DeviceRenderer>,
    check: PipelineCheck,
    /// What [`Prepared::take_scene`] took to upload the scene, if it took one.
    taken_upload_ms: Option<f64>,
}

impl Prepared {
    /// Takes the scene whose features the renderer was prepared for (a renderer of
    /// `Packed::placeholder`, whose pipeline the device compiled meanwhile): uploaded into new
    /// buffers. The verdict on the pipeline may still be on its way.
    pub fn take_scene(&mut self, packed: Packed) -> Result<(), String> {
        let (ms, taken) = timed(|| self.renderer.take_scene(packed));
        taken.map_err(|e| e.to_string())?;
        self.taken_upload_ms = Some(ms);
        Ok(())
    }
}

/// Milliseconds `run` took on this thread, and what it returned.
fn timed<T>(run: impl FnOnce() -> T) -> (f64, T) {
    let start = now_ms();
    let out = run();
    (now_ms() - start, out)
}

/// The device's verdict on a renderer's pipelines: the error, once one arrived.
type CompileError = Rc<RefCell<Option<String>>>;

/// Awaits the device's verdict on a renderer's pipelines in the background: the error, once one
/// arrived, and when the verdict did.
fn watch_verdict(check: PipelineCheck) -> (CompileError, Rc<Cell<Option<f64>>>) {
    let compile_error = Rc::new(RefCell::new(None));
    let compiled_at = Rc::new(Cell::new(None));
    let (slot, at) = (compile_error.clone(), compiled_at.clone());
    wasm_bindgen_futures::spawn_local(async move {
        let verdict = check.await;
        at.set(Some(now_ms()));
        if let Err(e) = verdict {
            web_sys::console::error_1(&format!("the WebGPU kernel: {e}").into());
            *slot.borrow_mut() = Some(e.to_string());
        }
    });
    (compile_error, compiled_at)
}

/// A second renderer on the running one's device, off the canvas: `auto`'s contender while the
/// page measures it against the running renderer (`crate::schedule_choice`).
pub struct Candidate {
    renderer: Box<dyn DeviceRenderer>,
    compile_error: CompileError,
}

impl Candidate {
    pub fn new(prepared: Prepared) -> Candidate {
        let Prepared { renderer, check, .. } = prepared;
        let (compile_error, _) = watch_verdict(check);
        Candidate { renderer, compile_error }
    }

    pub fn schedule(&self) -> Schedule {
        self.renderer.schedule()
    }

    /// The rest of a frame in one submission, drawn nowhere: whether the frame is done (a
    /// wavefront's once its counters say so: call again after the device's `done()`). An error
    /// the device reported since (the compiler's verdict on its pipelines, an uncaptured error:
    /// the candidate, created last, receives the device's) fails it.
    pub fn frame(&mut self) -> Result<bool, String> {
        if let Some(e) = self.compile_error.borrow().as_ref() {
            return Err(e.clone());
        }
        self.renderer.check_uncaptured().map_err(|e| e.to_string())?;
        self.renderer.render_band(self.renderer.rows_left()).map_err(|e| e.to_string())
    }
}

impl GpuRuntime {
    /// Puts `candidate`'s renderer in the running one's place (same device and canvas), its
    /// accumulation restarted; the running renderer is dropped.
    pub fn adopt(&mut self, candidate: Candidate) -> Result<(), String> {
        let Candidate { mut renderer, compile_error } = candidate;
        renderer.restart().map_err(|e| e.to_string())?;
        self.renderer = renderer;
        self.compile_error = compile_error;
        self.policy = policy_for(self.renderer.packed().scene.height, self.policy.budget_ms());
        self.in_flight = in_flight_for(self.renderer.as_ref(), &self.policy);
        Ok(())
    }

    /// The running renderer watches the device's uncaptured errors again (a candidate created on
    /// the same device took them over).
    pub fn watch_uncaptured(&mut self) {
        self.renderer.watch_uncaptured();
    }

    pub fn prepare(
        gpu: &GpuDevice,
        packed: &Packed,
        seed: u32,
        options: &WgpuOptions,
        schedule: Schedule,
    ) -> Result<Prepared, String> {
        if let Some(why) = gpu.lost() {
            return Err(format!("the WebGPU device was lost ({why})"));
        }
        let (device, packed) = (gpu.device.clone(), packed.clone());
        let (renderer, check): (Box<dyn DeviceRenderer>, _) = match schedule {
            Schedule::Megakernel => {
                let (r, check) = WgpuRenderer::create(device, packed, seed, options).map_err(|e| e.to_string())?;
                (Box::new(r), check)
            }
            Schedule::Wavefront => {
                let (r, check) = WavefrontRenderer::create(device, packed, seed, options).map_err(|e| e.to_string())?;
                (Box::new(r), check)
            }
        };
        Ok(Prepared { renderer, check, taken_upload_ms: None })
    }

    /// The prepared renderer drawing to `canvas` (sized to the image already).
    pub fn attach(prepared: Prepared, canvas: &HtmlCanvasElement, band_budget_ms: Option<f64>) -> Result<Self, String> {
        let Prepared { renderer, check, taken_upload_ms } = prepared;
        let device = renderer.device();
        let surface = device
            .instance
            .create_surface(wgpu::SurfaceTarget::Canvas(canvas.clone()))
            .map_err(|e| format!("the canvas has no WebGPU context: {e}"))?;
        let (width, height) = (renderer.packed().scene.width, renderer.packed().scene.height);
        let mut config = surface
            .get_default_config(&device.adapter, width, height)
            .ok_or("the WebGPU adapter cannot present to this canvas")?;
        // The display pass encodes sRGB itself (as the WebGL2 pass does): a linear format.
        let caps = surface.get_capabilities(&device.adapter);
        config.format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .ok_or_else(|| format!("the canvas offers only sRGB formats ({:?})", caps.formats))?;
        config.alpha_mode = wgpu::CompositeAlphaMode::Opaque;
        surface.configure(&device.device, &config);
        let (display_ms, display) = timed(|| DisplayPass::new(&device.device, config.format));
        let display = display.map_err(|e| e.to_string())?;
        let (compile_error, compiled_at) = watch_verdict(check);
        let build = renderer.build_times();
        let startup = Startup {
            codegen_ms: build.codegen_ms,
            compile_ms: build.compile_ms + display_ms,
            upload_ms: taken_upload_ms.unwrap_or(build.upload_ms),
            created_at: now_ms(),
            compiled_at: None,
            compiled_while_decoding: taken_upload_ms.is_some(),
        };
        let policy = policy_for(height, band_budget_ms);
        let in_flight = in_flight_for(renderer.as_ref(), &policy);
        Ok(GpuRuntime {
            renderer,
            surface,
            display,
            policy,
            in_flight,
            compile_error,
            startup,
            compiled_at,
            image_display: GpuImageDisplay::default(),
            preview: Preview::default(),
            preview_image: None,
        })
    }

    pub fn preview(&self) -> &Preview {
        &self.preview
    }

    pub fn preview_mut(&mut self) -> &mut Preview {
        &mut self.preview
    }

    /// Renders the pending preview now, if the accumulation has not begun, and shows it:
    /// whether it did (the wavefront renders none). The bands in flight are forgotten.
    pub fn preview_now(&mut self, now_ms: f64, settings: &Display) -> bool {
        let scene = &self.renderer.packed().scene;
        let full = (scene.width, scene.height);
        let fresh = self.renderer.frames() == 0 && self.renderer.rows_left() == full.1;
        let renderer = &mut self.renderer;
        let image = self.preview.render_if_due(fresh, full, now_ms, |(width, height)| {
            renderer.render_preview(width, height).map_err(|e| e.to_string())
        });
        let Some(buffer) = image else { return false };
        self.in_flight.clear(drop);
        self.preview_image = Some(buffer);
        self.draw(settings);
        true
    }

    pub fn renderer(&self) -> &dyn DeviceRenderer {
        self.renderer.as_ref()
    }

    pub fn renderer_mut(&mut self) -> &mut dyn DeviceRenderer {
        self.renderer.as_mut()
    }

    pub fn startup(&self) -> Startup {
        Startup { compiled_at: self.compiled_at.get(), ..self.startup.clone() }
    }

    pub fn busy(&self) -> bool {
        !self.in_flight.is_empty()
    }

    /// Checks, without waiting, which work in flight is done; records the bands' times. True
    /// when nothing is in flight (any more).
    pub fn poll(&mut self, now_ms: f64) -> bool {
        self.in_flight.poll(now_ms, &mut self.policy, |done| Some(done.load(Ordering::Acquire)), drop)
    }

    pub fn policy(&self) -> &BandPolicy {
        &self.policy
    }

    pub fn set_band_budget(&mut self, budget_ms: Option<f64>) {
        self.policy = policy_for(self.renderer.packed().scene.height, budget_ms);
        // The bands in flight were sized by the old policy: not measured.
        self.in_flight = in_flight_for(self.renderer.as_ref(), &self.policy);
    }

    /// Whether the device rejected the kernel's shader (recreating the renderer would not help).
    pub fn shader_rejected(&self) -> bool {
        self.compile_error.borrow().is_some()
    }

    /// An error the device reported since (the shader compiler's, or an uncaptured one).
    fn check(&self) -> Result<(), String> {
        if let Some(e) = self.compile_error.borrow().as_ref() {
            return Err(e.clone());
        }
        self.renderer.check_uncaptured().map_err(|e| e.to_string())
    }

    /// Draws the current mean to the canvas through `settings` (skipped when the surface has no
    /// texture now).
    pub fn draw(&self, settings: &Display) {
        let texture = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            _ => return,
        };
        let view = texture.texture.create_view(&Default::default());
        match self.preview_image.as_ref().filter(|_| self.preview.showing()) {
            Some(image) => {
                let device = self.renderer.device();
                let scene = &self.renderer.packed().scene;
                let size = self.preview.size.map_or([1, 1], |(w, h)| [w, h]);
                let target = [scene.width, scene.height];
                self.display.draw_upscaled(&device.device, &device.queue, &view, image, size, target, 1.0, settings);
            }
            None => self.display.draw(self.renderer.as_ref(), &view, settings),
        }
        self.renderer.device().queue.present(texture);
    }

    /// Draws `image` (a denoised image of the renderer's size, known as `id`) through
    /// `settings` (skipped when the surface has no texture now).
    pub fn draw_image(&mut self, image: &Image, id: u64, settings: &Display) -> Result<(), String> {
        let device = self.renderer.device();
        let texture = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            _ => return Ok(()),
        };
        let view = texture.texture.create_view(&Default::default());
        self.image_display.draw(&device.device, &device.queue, &self.display, &view, image, id, settings);
        device.queue.present(texture);
        Ok(())
    }

    /// The rest of the frame in one submission (the megakernel's rows left; the wavefront's
    /// next submission), then the display pass once the frame is done: whether it is.
    pub fn frame(&mut self, settings: &Display) -> Result<bool, String> {
        self.frame_in_bands(self.renderer.rows_left(), settings)
    }

    /// The rest of the frame in bands of `rows` rows submitted back to back (a wavefront's
    /// next submission, whose size is its own), then the display pass once the frame is done:
    /// whether it is (the test hook's `renderFramesInBands`).
    pub fn frame_in_bands(&mut self, rows: u32, settings: &Display) -> Result<bool, String> {
        self.check()?;
        // The bands in flight would be timed with these.
        self.in_flight.clear(drop);
        let mut done = false;
        for _ in 0..self.renderer.packed().scene.height {
            done = self.renderer.render_band(rows).map_err(|e| e.to_string())?;
            if done || self.renderer.schedule() != Schedule::Megakernel {
                break;
            }
        }
        if done {
            self.preview.frame_done();
            self.draw(settings);
        }
        Ok(done)
    }

    /// The frame loop's step: records the times of the bands seen done, then renders the
    /// pending preview (alone on the GPU) or tops the queue up with bands of the policy's height
    /// (a frame's first band once the last frame's are done), drawing each band of the first
    /// frame after a restart, later each whole frame. `Waiting` if nothing was submitted.
    pub fn step(&mut self, now_ms: f64, settings: &Display) -> Result<Step, String> {
        self.check()?;
        if self.poll(now_ms) && self.preview_now(now_ms, settings) {
            self.track(now_ms, 0);
            return Ok(Step::Preview);
        }
        let mut step = Step::Waiting;
        let height = self.renderer.packed().scene.height;
        while self.in_flight.admits(now_ms, self.renderer.rows_left() == height, self.policy.band_ms()) {
            let rows = self.policy.rows().min(self.renderer.rows_left());
            let frame_done = self.renderer.render_band(rows).map_err(|e| e.to_string())?;
            if frame_done {
                self.preview.frame_done();
            }
            // The first frame after a restart shows as its bands are done (unless the preview
            // does until the frame is complete); later, each whole frame.
            if frame_done || self.preview.shows_band(self.renderer.frames() == 0, now_ms) {
                self.draw(settings);
            }
            self.track(now_ms, rows);
            step = Step::Submitted { frame_done };
        }
        Ok(step)
    }

    /// Queues what was just submitted behind a flag the device sets when it is done: a band of
    /// `rows`, or other work (0 rows: waited for, not timed).
    fn track(&mut self, now_ms: f64, rows: u32) {
        let done = Arc::new(AtomicBool::new(false));
        let flag = done.clone();
        let finished = self.renderer.device().done();
        wasm_bindgen_futures::spawn_local(async move {
            finished.await;
            flag.store(true, Ordering::Release);
        });
        let estimate = if rows > 0 { self.policy.band_ms() } else { None };
        self.in_flight.push(done, now_ms, rows, estimate);
    }

    /// Resolves once the queued work is done.
    pub fn sync(&self) -> impl std::future::Future<Output = ()> + 'static {
        self.renderer.device().done()
    }
}
