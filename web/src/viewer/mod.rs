//! The browser viewer: the native backends' renderers on a canvas, through one of two runtimes
//! ([`crate::runtime`]): the GL backend's `GlRenderer` on WebGL2 (wrapped in `glow`), or the
//! wgpu backend's `WgpuRenderer` on the browser's WebGPU. Only the contexts and the frame loop
//! (JavaScript's `requestAnimationFrame`, calling [`Viewer::step`]) are specific to the web; the
//! kernel, its shaders, the scene data and the accumulation are the native code.
//!
//! Which runs: [`Viewer::set_api`] (`auto`, the default: WebGPU when `requestWebGpu()` gave a
//! device and the scene fits its limits, else WebGL2 with a notice saying why; `webgpu` or
//! `webgl2`: that one, or its error). A canvas keeps the first kind of context it gave out, so
//! switching kinds replaces the canvas element (same id and attributes) in the page.
//!
//! Each frame adds one sample per pixel to the accumulation, then a small display pass draws
//! its mean to the canvas through the kernel's display transform (tone curve, exposure, sRGB:
//! what the CLI's PNG output stores with the same settings), on either API. The frame loop
//! submits a frame in bands of rows of at most a time budget (100 ms by default;
//! `tracer::backend::frame_split`), a few bands queued at a time, so that input is handled, and
//! a camera move restarts the accumulation, between bands, also on a GPU that needs seconds per
//! frame.

use js_sys::{Float32Array, Object, Uint8Array};
use tracer::backend::frame_split::{Step, DEFAULT_BUDGET_MS};
use tracer::backend::gl::GlOptions;
use tracer::backend::wgpu::WgpuOptions;
use tracer::backend::{Image, Schedule};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::output::{Display, ToneMap};
use tracer::pack::{MovingScene, Packed};
use wasm_bindgen::prelude::*;

use wasm_bindgen_futures::future_to_promise;
use web_sys::{HtmlCanvasElement, WebGl2RenderingContext};

use crate::camera::OrbitCamera;
use crate::denoise::PageDenoiser;
use crate::files::{self, DroppedFile};
use crate::js::{camel_case, js_error, now_ms, set};
mod camera_input;
mod denoise_controls;
mod measure;
mod playback;
mod prepare;
mod preview;
mod runtime_choice;

use crate::runtime::webgpu::Candidate;
use crate::runtime::{Api, GpuDevice, Runtime};
use crate::schedule_choice::Choice;
use playback::Playback;

/// The loaded scene: the master copy of its packed data (uniforms kept current) and the view.
struct Loaded {
    name: String,
    packed: Packed,
    camera: OrbitCamera,
    /// The scene's own view, for `resetCamera`.
    home: OrbitCamera,
    /// Milliseconds decoding its bundle took (0 for dropped files: see `loadDropped`).
    decode_ms: f64,
}

/// The path tracer on a canvas. Create it with `new Viewer(canvas)`, optionally give it a
/// WebGPU device (`useWebGpu(await requestWebGpu())`), load a bundle or dropped files, then call
/// `step()` from `requestAnimationFrame`.
#[wasm_bindgen]
pub struct Viewer {
    canvas: HtmlCanvasElement,
    /// The kind of context the canvas gave out (it keeps its first).
    canvas_api: Option<Api>,
    gl_context: Option<WebGl2RenderingContext>,
    api: Api,
    /// The schedule asked for (`setSchedule`): `None` for auto, measured on WebGPU per scene
    /// load (`measure.rs`; [`Schedule::auto`] until then).
    schedule: Option<Schedule>,
    /// Where auto's measurement for the loaded scene stands, and what it chose.
    choice: Choice,
    /// The wavefront being measured beside the running megakernel.
    candidate: Option<Candidate>,
    /// Measurements started (their ids).
    measurements: u32,
    /// Measurements started for the loaded scene (an interrupted one is retried, later after
    /// each interruption: `schedule_choice::settle_frames`).
    measurement_tries: u32,
    /// Test hook: milliseconds per frame (megakernel, wavefront) auto decides on instead.
    injected_times: Option<(f64, f64)>,
    gpu: Option<GpuDevice>,
    /// Why there is no WebGPU device (`webGpuUnavailable`), for auto's notice.
    gpu_unavailable: Option<String>,
    /// Why the scene runs on WebGL2 under auto (WebGPU missing, or a limit the scene exceeds).
    notice: Option<String>,
    loaded: Option<Loaded>,
    running: Option<Runtime>,
    settings: RenderSettings,
    options: GlOptions,
    wgpu_options: WgpuOptions,
    context_lost: bool,
    dropped: Vec<DroppedFile>,
    /// Selects the random sequence, as the native backends' `seed` does (`setSeed`).
    seed: u32,
    /// The longest one band of a frame should take on the GPU (`setBandBudget`); `None`:
    /// frames are not split.
    band_budget_ms: Option<f64>,
    /// WebGPU renderers recreated after an uncaptured device error since the last scene load.
    gpu_recoveries: u32,
    /// How the accumulation is shown and screenshot: tone curve and exposure (`setToneMap`,
    /// `setExposure`), the CLI's `--tonemap` and `--exposure`.
    display: Display,
    /// The denoiser (`setDenoise`; on by default): see `crate::denoise`.
    denoiser: PageDenoiser,
    /// The loaded scene's animation, when it moves (`crate::playback`).
    playback: Option<Playback>,
    /// Whether a new renderer's first image is a preview (`setPreview`; on by default).
    preview: bool,
    /// A renderer compiled for the next bundle while it is decoded (`prepareBundle`).
    prepared: Option<prepare::Prepared>,
}

/// Renderers recreated after uncaptured WebGPU errors before the error is shown instead.
const MAX_GPU_RECOVERIES: u32 = 3;

#[wasm_bindgen]
impl Viewer {
    /// A viewer drawing into `canvas`. No context is created until a scene is loaded.
    #[wasm_bindgen(constructor)]
    pub fn new(canvas: HtmlCanvasElement) -> Viewer {
        console_error_panic_hook::set_once();
        let settings =
            RenderSettings { width: canvas.width().max(1), height: canvas.height().max(1), ..Default::default() };
        Viewer {
            canvas,
            canvas_api: None,
            gl_context: None,
            api: Api::Auto,
            schedule: None,
            choice: Choice::Pending,
            candidate: None,
            measurements: 0,
            measurement_tries: 0,
            injected_times: None,
            gpu: None,
            gpu_unavailable: None,
            notice: None,
            loaded: None,
            running: None,
            settings,
            options: GlOptions::default(),
            wgpu_options: WgpuOptions::default(),
            context_lost: false,
            dropped: Vec::new(),
            seed: 1,
            band_budget_ms: Some(DEFAULT_BUDGET_MS),
            gpu_recoveries: 0,
            display: Display::default(),
            denoiser: PageDenoiser::new(true),
            playback: None,
            preview: true,
            prepared: None,
        }
    }

    /// The canvas drawn into (a new element after a switch between WebGL2 and WebGPU).
    #[wasm_bindgen(getter)]
    pub fn canvas(&self) -> HtmlCanvasElement {
        self.canvas.clone()
    }

    /// Chooses the graphics API: "auto" (default), "webgpu" or "webgl2". Applies to the next
    /// scene loaded (or the current one, recreated).
    #[wasm_bindgen(js_name = setApi)]
    pub fn set_api(&mut self, name: &str) -> Result<(), JsError> {
        let api = Api::parse(name).map_err(|e| JsError::new(&e))?;
        if api != self.api {
            self.api = api;
            if self.running.is_some() {
                self.rebuild()?;
            }
        }
        Ok(())
    }

    /// Chooses how WebGPU organises a frame: "auto" (default: the megakernel, `Schedule::auto`),
    /// "megakernel" or "wavefront" (WebGPU only: WebGL2 has no compute shaders, so with
    /// `webgl2` it is an error and under auto's fallback to WebGL2 a notice). Applies to the
    /// next scene loaded (or the current one, recreated).
    #[wasm_bindgen(js_name = setSchedule)]
    pub fn set_schedule(&mut self, name: &str) -> Result<(), JsError> {
        let auto = matches!(name.to_ascii_lowercase().as_str(), "" | "auto");
        let schedule = (!auto).then(|| Schedule::parse(name)).transpose().map_err(|e| JsError::new(&e))?;
        if schedule != self.schedule {
            self.abandon_measurement("the schedule was changed");
            self.schedule = schedule;
            self.choice = Choice::Pending;
            if self.running.is_some() {
                self.rebuild()?;
            }
        }
        Ok(())
    }

    /// Gives the viewer a WebGPU device (from `requestWebGpu()`); after a device loss, the
    /// new one: the renderer is recreated on it from the scene kept in memory.
    #[wasm_bindgen(js_name = useWebGpu)]
    pub fn use_web_gpu(&mut self, device: &GpuDevice) -> Result<(), JsError> {
        self.gpu = Some(device.clone());
        self.gpu_unavailable = None;
        if self.loaded.is_some() && self.api != Api::WebGl2 {
            self.rebuild()?;
        }
        Ok(())
    }

    /// Records why WebGPU cannot be used (`requestWebGpu()` failed, a lost device could not be
    /// replaced, or was lost too often): auto says so when it runs WebGL2. Under auto a loaded
    /// scene not running on WebGL2 yet moves there now (from the scene in memory); an error
    /// (e.g. no WebGL2 context while the browser's GPU process restarts) may be retried.
    #[wasm_bindgen(js_name = webGpuUnavailable)]
    pub fn web_gpu_unavailable(&mut self, why: String) -> Result<(), JsError> {
        self.gpu_unavailable = Some(why);
        self.gpu = None;
        let on_webgl2 = matches!(self.running, Some(Runtime::WebGl2(_)));
        if self.api == Api::Auto && self.loaded.is_some() && !on_webgl2 {
            self.rebuild()?;
        }
        Ok(())
    }

    /// Why the WebGPU device the scene runs on was lost, once it was (the page then requests
    /// a new one and calls `useWebGpu`); `undefined` otherwise.
    #[wasm_bindgen(js_name = webGpuLost)]
    pub fn web_gpu_lost(&self) -> Option<String> {
        let gpu = self.gpu.as_ref()?;
        let relevant = matches!(self.running, Some(Runtime::WebGpu(_))) || self.api == Api::WebGpu;
        if relevant {
            gpu.lost()
        } else {
            None
        }
    }

    /// Test hook: destroys the WebGPU device (`GPUDevice.destroy()`), as a GPU reset would
    /// lose it.
    #[wasm_bindgen(js_name = loseWebGpu)]
    pub fn lose_web_gpu(&self) {
        if let Some(gpu) = &self.gpu {
            gpu.device.device.destroy();
        }
    }

    /// Loads a scene bundle (as served at `/bundles/<hash>.lpb`): no loading or BVH build, the
    /// packed scene is uploaded as it is. Returns the scene's description (see `sceneInfo`).
    #[wasm_bindgen(js_name = loadBundle)]
    pub fn load_bundle(&mut self, bytes: &[u8]) -> Result<JsValue, JsError> {
        let start = now_ms();
        let bundle = tracer::bundle::Bundle::decode(bytes).inspect_err(|_| self.prepared = None).map_err(js_error)?;
        // A scene that moves (its motion section) plays as a dropped one does, posed from
        // what the bundle carries (`tracer::pack::Posing`).
        let playback = match bundle.moving {
            Some(parts) => Some(Playback::new(MovingScene::from_bundle(&bundle.packed, parts).map_err(js_error)?)),
            None => None,
        };
        let decode_ms = now_ms() - start;
        self.install(bundle.name, bundle.packed, decode_ms)?;
        self.playback = playback;
        Ok(self.scene_info())
    }

    /// Adds one dropped file (a `.glb`, a `.gltf`, or a file a `.gltf` references);
    /// `loadDropped` then loads them together.
    #[wasm_bindgen(js_name = addDroppedFile)]
    pub fn add_dropped_file(&mut self, name: String, bytes: Vec<u8>) {
        self.dropped.push(DroppedFile { name, bytes });
    }

    /// Loads, BVH-builds and packs the dropped files in the browser, then renders them. The
    /// files are consumed; on error the current scene keeps rendering.
    #[wasm_bindgen(js_name = loadDropped)]
    pub fn load_dropped(&mut self) -> Result<JsValue, JsError> {
        let dropped = std::mem::take(&mut self.dropped);
        let start = js_sys::Date::now();
        let (name, mut scene) = files::load_dropped(&dropped).map_err(js_error)?;
        // As `lightport serve` lights such a scene (its warning is in scenes.json).
        if let Some(warning) = scene.light_if_unlit() {
            scene.warnings.push(warning);
        }
        drop(dropped);
        let loaded_at = js_sys::Date::now();
        let warnings = scene.warnings.join("; ");
        let (packed, playback) = match scene.motion {
            Some(_) => {
                let (moving, packed) = MovingScene::new(scene, &self.settings).map_err(js_error)?;
                (packed, Some(Playback::new(moving)))
            }
            None => (files::prepare(&name, &scene, &self.settings).map_err(js_error)?, None),
        };
        let prepared_at = js_sys::Date::now();
        self.install(name, packed, 0.0)?;
        self.playback = playback;
        let info = Object::from(self.scene_info());
        set(&info, "loadMs", loaded_at - start);
        set(&info, "buildAndPackMs", prepared_at - loaded_at);
        set(&info, "warnings", warnings);
        Ok(info.into())
    }

    /// Makes `packed` the current scene, keeping the viewer's size and strategy. If the GL
    /// renderer refuses it (too large for the device...), the previous scene stays.
    fn install(&mut self, name: String, mut packed: Packed, decode_ms: f64) -> Result<JsValue, JsError> {
        let bundle_depth = packed.scene.max_depth;
        // The path tracer accumulates the denoiser's guide while the denoiser is on.
        packed.set_denoise_guide(self.denoiser.enabled());
        packed.apply(&RenderSettings { max_depth: bundle_depth, ..self.settings });
        let camera = OrbitCamera::from_uniforms(&packed.scene);
        // A new scene is measured again; the old one's choice stays if this one is refused.
        self.abandon_measurement("another scene was loaded");
        let previous = std::mem::take(&mut self.choice);
        let started = self.start(&packed);
        // A renderer prepared for this scene was taken by `start`; one for another is dropped.
        self.prepared = None;
        let running = started.inspect_err(|_| self.choice = previous)?;
        self.measurement_tries = 0;
        self.gpu_recoveries = 0;
        self.settings.max_depth = bundle_depth;
        self.running = Some(running);
        self.denoiser.new_runtime();
        self.loaded = Some(Loaded { name, packed, camera, home: camera, decode_ms });
        self.playback = None;
        Ok(self.scene_info())
    }

    /// Adds one sample per pixel (the rest of the frame, if `step` began it) in one submission
    /// and draws the converging image (the test hook's `renderFrames`): `false` while the
    /// frame is not done yet (the wavefront's, whose counters arrive with a promise: call again
    /// after `sync()`). Does nothing without a scene or while the context or device is lost.
    pub fn frame(&mut self) -> Result<bool, JsError> {
        self.render_frame(None)
    }

    /// [`frame`](Self::frame) with the frame's rows submitted in bands of `rows` back to back
    /// (the test hook's `renderFramesInBands`: a band's cost beyond its rows, measured).
    #[wasm_bindgen(js_name = frameInBands)]
    pub fn frame_in_bands(&mut self, rows: u32) -> Result<bool, JsError> {
        self.render_frame(Some(rows.max(1)))
    }

    /// Draws the image again (the denoised one where there is one), e.g. before copying the
    /// canvas in the same task.
    pub fn draw(&mut self) {
        self.redraw();
    }

    /// The frame loop's step (call it once per animation frame with `performance.now()`):
    /// unless the previous band (WebGL2) or frame (WebGPU) is still on the GPU (polled without
    /// blocking), submits the next, and when that completes the frame, draws the image (on
    /// WebGL2, during the first frame after a restart: after every band, the new view band by
    /// band). Returns 0: waited (nothing submitted), 1: a band was submitted, 2: the band
    /// completed a frame (one more sample per pixel), 3: a preview was submitted and shown (a
    /// new renderer's first step: `preview.rs`).
    pub fn step(&mut self, now_ms: f64) -> Result<u32, JsError> {
        // The page's loop waits while auto measures; a step meanwhile gives the measurement up.
        self.abandon_measurement("the frame loop went on");
        if self.halted() {
            return Ok(0);
        }
        self.advance_animation(now_ms)?;
        let Some(running) = &mut self.running else { return Ok(0) };
        let step = match running.step(now_ms, &self.display) {
            Ok(step) => step,
            Err(e) => {
                self.recover(e)?;
                return Ok(0);
            }
        };
        if step == (Step::Submitted { frame_done: true }) {
            self.denoiser.poll(running);
            self.show_denoised();
        }
        Ok(match step {
            Step::Waiting => 0,
            Step::Submitted { frame_done: false } => 1,
            Step::Submitted { frame_done: true } => 2,
            Step::Preview => 3,
        })
    }

    /// The longest one band of a frame should take on the GPU, in milliseconds (default 50);
    /// 0: do not split frames (one submission per frame). Restarts the band-height adaptation.
    /// Both runtimes split frames (WebGL2: scissored draws; WebGPU: dispatches over fewer rows;
    /// the wavefront: submissions of a bounded number of path segments).
    #[wasm_bindgen(js_name = setBandBudget)]
    pub fn set_band_budget(&mut self, ms: f64) -> Result<(), JsError> {
        if !(ms.is_finite() && ms >= 0.0) {
            return Err(JsError::new(&format!("invalid band budget {ms} ms (a number >= 0; 0: no splitting)")));
        }
        self.band_budget_ms = (ms > 0.0).then_some(ms);
        if let Some(running) = &mut self.running {
            running.set_band_budget(self.band_budget_ms);
        }
        Ok(())
    }

    /// Resolves once the queued frames are rendered (WebGL2: after a 1-pixel read-back, done
    /// before this returns; WebGPU: the queue's `onSubmittedWorkDone`), e.g. around timings.
    pub fn sync(&self) -> js_sys::Promise {
        let wait = self.running.as_ref().filter(|_| !self.halted()).map(Runtime::sync);
        future_to_promise(async move {
            if let Some(wait) = wait {
                wait.await;
            }
            Ok(JsValue::UNDEFINED)
        })
    }

    /// Milliseconds to build the top level over the placements of the stress field
    /// (`instanced_field(side)`: side² placements) as packing does (`pack::top_level`), median
    /// of 5: what a frame in which placements move rebuilds, timed in wasm
    /// (`tests/web/run.mjs toplevel`).
    #[wasm_bindgen(js_name = topLevelBuildMs)]
    pub fn top_level_build_ms(side: u32) -> Result<f64, JsError> {
        let boxes: Vec<(glam::Vec3, glam::Vec3)> = tracer::scene::instanced_field(side.clamp(1, 1000) as usize)
            .placement_boxes()
            .iter()
            .map(|b| (b.min, b.max))
            .collect();
        let mut times = Vec::with_capacity(5);
        for _ in 0..5 {
            let start = now_ms();
            std::hint::black_box(tracer::pack::top_level(&boxes).map_err(js_error)?);
            times.push(now_ms() - start);
        }
        times.sort_by(f64::total_cmp);
        Ok(times[2])
    }

    /// Samples per pixel accumulated since the last restart.
    pub fn spp(&self) -> u32 {
        self.running.as_ref().map_or(0, Runtime::frames)
    }

    /// A checksum of the loaded scene's texels (`Packed::texture_checksum`), for tests that
    /// check the page decoded a bundle's images to the native loader's texels; `None` without
    /// a scene. Not part of [`scene_info`](Self::scene_info): it reads every texel (~100-400 ms
    /// for LittlestTokyo in wasm), and the page calls `sceneInfo` every animation frame, where
    /// it stalled the frame loop so long that bands fell to one row (docs/web.md, "Slow devices").
    #[wasm_bindgen(js_name = textureChecksum)]
    pub fn texture_checksum(&self) -> Option<u32> {
        self.loaded.as_ref().map(|l| l.packed.texture_checksum())
    }

    /// The render size, scene and renderer (an object; see the fields set here). The page
    /// calls it every animation frame: nothing here may cost more than a few microseconds.
    #[wasm_bindgen(js_name = sceneInfo)]
    pub fn scene_info(&self) -> JsValue {
        let info = Object::new();
        set(&info, "width", self.settings.width);
        set(&info, "height", self.settings.height);
        set(&info, "strategy", self.settings.strategy.name());
        set(&info, "maxDepth", self.settings.max_depth);
        set(&info, "spp", self.spp());
        set(&info, "contextLost", self.context_lost);
        set(&info, "toneMap", self.display.tone_map.name());
        set(&info, "exposure", self.display.exposure);
        let rendering = match &self.running {
            _ if self.context_lost => Err("the WebGL context is lost"),
            _ if self.web_gpu_lost().is_some() => Err("the WebGPU device is lost"),
            Some(running) => Ok(running),
            None => Err("no scene"),
        };
        set(&info, "denoise", self.denoiser.describe(rendering));
        if let Some(playback) = &self.playback {
            set(&info, "animation", playback.describe());
        }
        if let Some(loaded) = &self.loaded {
            let f = &loaded.packed.features;
            set(&info, "name", loaded.name.as_str());
            set(&info, "triangles", loaded.packed.triangle_count as u32);
            set(&info, "placements", loaded.packed.placement_count() as u32);
            set(&info, "lights", loaded.packed.light_count as u32);
            let features = Object::new();
            for flag in f.flags() {
                set(&features, &camel_case(flag.name), flag.on);
            }
            set(&info, "features", features);
        }
        let budget = self.band_budget_ms.unwrap_or(0.0);
        set(&info, "bandBudgetMs", budget);
        set(&info, "apiRequested", self.api.name());
        set(&info, "scheduleRequested", self.schedule.map_or("auto", Schedule::name));
        set(&info, "scheduleChoice", self.describe_schedule_choice());
        set(&info, "notice", self.notice.as_deref().map_or(JsValue::NULL, JsValue::from));
        set(&info, "webGpuLost", self.web_gpu_lost().map_or(JsValue::NULL, JsValue::from));
        if let Some(running) = &self.running {
            running.describe(&info);
            // What the scene's way to its first frame took in here (see `Startup`), with the
            // bundle's decode: the page's first-frame read-out.
            let startup = running.startup().describe();
            set(&startup, "decodeMs", self.loaded.as_ref().map_or(0.0, |l| l.decode_ms));
            set(&info, "startup", startup);
        }
        info.into()
    }

    /// Sets the render size (the canvas's drawing buffer). A new size needs new accumulation
    /// textures: the renderer is recreated and the accumulation restarts.
    #[wasm_bindgen(js_name = setSize)]
    pub fn set_size(&mut self, width: u32, height: u32) -> Result<(), JsError> {
        if !(1..=16384).contains(&width) || !(1..=16384).contains(&height) {
            return Err(JsError::new(&format!("invalid render size {width}x{height} (each side 1..=16384)")));
        }
        if (width, height) == (self.settings.width, self.settings.height) {
            return Ok(());
        }
        let previous = self.settings;
        self.settings.width = width;
        self.settings.height = height;
        if let Err(e) = self.rebuild() {
            // Keep rendering at the size that worked (e.g. the new one exceeds the device).
            self.settings = previous;
            let _ = self.rebuild();
            return Err(e);
        }
        Ok(())
    }

    /// Recreates the renderer for the current settings and camera (after a resize, a lost
    /// context or device, a new seed or API).
    fn rebuild(&mut self) -> Result<(), JsError> {
        self.interrupt_measurement("the renderer was recreated (a new size, seed, device or setting)");
        self.running = None;
        let Some(loaded) = &mut self.loaded else {
            self.canvas.set_width(self.settings.width);
            self.canvas.set_height(self.settings.height);
            return Ok(());
        };
        loaded.packed.apply(&self.settings);
        loaded.packed.set_denoise_guide(self.denoiser.enabled());
        loaded.camera.apply(&mut loaded.packed.scene);
        let packed = loaded.packed.clone();
        let running = self.start(&packed)?;
        self.running = Some(running);
        self.denoiser.new_runtime();
        Ok(())
    }

    /// Chooses the estimator: "bsdf", "nee" or "mis". Restarts the accumulation.
    #[wasm_bindgen(js_name = setStrategy)]
    pub fn set_strategy(&mut self, name: &str) -> Result<(), JsError> {
        let strategy = Strategy::ALL
            .into_iter()
            .find(|s| s.name() == name.to_ascii_lowercase())
            .ok_or_else(|| JsError::new(&format!("unknown strategy {name:?}: use bsdf, nee or mis")))?;
        self.settings.strategy = strategy;
        self.update_uniforms()
    }

    /// Longest path in segments (1..=64). Restarts the accumulation.
    #[wasm_bindgen(js_name = setMaxDepth)]
    pub fn set_max_depth(&mut self, depth: u32) -> Result<(), JsError> {
        if !(1..=64).contains(&depth) {
            return Err(JsError::new(&format!("invalid path depth {depth} (1..=64)")));
        }
        self.settings.max_depth = depth;
        self.update_uniforms()
    }

    /// Selects the random sequence (default 1): the same seed, scene and settings render the
    /// same samples as the native backends with that seed (`lightport chart` compares them).
    /// Recreates the renderer: the accumulation restarts.
    #[wasm_bindgen(js_name = setSeed)]
    pub fn set_seed(&mut self, seed: u32) -> Result<(), JsError> {
        if seed == self.seed {
            return Ok(());
        }
        self.seed = seed;
        if self.running.is_some() {
            self.rebuild()?;
        }
        Ok(())
    }

    /// Uses at most this texture size, below the device's (0: the device's own). For checking
    /// that a scene fits smaller devices; applies to the next scene loaded.
    #[wasm_bindgen(js_name = setMaxTextureSize)]
    pub fn set_max_texture_size(&mut self, size: u32) {
        self.options.max_texture_size = (size > 0).then_some(size);
    }

    /// Writes the camera and settings into the master copy and the renderer's uniforms, and
    /// restarts the accumulation.
    pub(crate) fn update_uniforms(&mut self) -> Result<(), JsError> {
        self.interrupt_measurement("the view or a setting changed");
        let settings = self.settings;
        let Some(loaded) = &mut self.loaded else { return Ok(()) };
        let camera = loaded.camera;
        let update = |scene: &mut tracer::kernel::scene_data::Scene| {
            camera.apply(scene);
            scene.strategy = settings.strategy.uniform_value();
            scene.max_depth = settings.max_depth;
        };
        update(&mut loaded.packed.scene);
        let halted = self.halted();
        if let Some(running) = &mut self.running {
            if !halted {
                running.set_uniforms(update).map_err(|e| JsError::new(&e))?;
            }
        }
        self.denoiser.restart();
        Ok(())
    }

    /// Resolves to the accumulation: per pixel (rows from the top) the sum of samples in rgb
    /// and the number of finite samples in a; `spp()` frames so far.
    #[wasm_bindgen(js_name = readAccumulation)]
    pub fn read_accumulation(&self) -> Result<js_sys::Promise, JsError> {
        let running = self.running.as_ref().ok_or_else(|| JsError::new("no scene is loaded"))?;
        let read = running.read_accumulation();
        Ok(future_to_promise(async move {
            let texels = read.await.map_err(|e| JsValue::from(JsError::new(&e)))?;
            let floats: Vec<f32> = texels.iter().flat_map(|t| t.to_array()).collect();
            Ok(Float32Array::from(floats.as_slice()).into())
        }))
    }

    /// The tone curve of the display and of screenshots by name (`neutral`, the default, `aces`,
    /// `agx` or `none`, as the CLI's `--tonemap`): the image is redrawn, the accumulation goes on.
    #[wasm_bindgen(js_name = setToneMap)]
    pub fn set_tone_map(&mut self, name: &str) -> Result<(), JsError> {
        let names: Vec<&str> = ToneMap::ALL.iter().map(|t| t.name()).collect();
        self.display.tone_map = ToneMap::from_name(name)
            .ok_or_else(|| JsError::new(&format!("unknown tone map {name:?}: one of {}", names.join(", "))))?;
        self.redraw();
        Ok(())
    }

    /// The display's exposure in stops (radiance scaled by 2^EV before the tone curve, as the
    /// CLI's `--exposure`), within ±20 EV.
    #[wasm_bindgen(js_name = setExposure)]
    pub fn set_exposure(&mut self, stops: f32) -> Result<(), JsError> {
        if !(stops.is_finite() && stops.abs() <= 20.0) {
            return Err(JsError::new(&format!("exposure {stops} EV is out of range: give -20 to 20 stops")));
        }
        self.display.exposure = stops;
        self.redraw();
        Ok(())
    }

    /// Draws the image again (a display setting changed; no sample is added).
    fn redraw(&mut self) {
        if self.halted() {
            return;
        }
        if let Some(running) = &self.running {
            running.draw(&self.display);
        }
        self.show_denoised();
    }

    /// Resolves to the current image (the denoised one while it shows) as PNG bytes, through
    /// the display's tone curve and exposure (as the CLI's PNG output with the same
    /// `--tonemap` and `--exposure`).
    #[wasm_bindgen(js_name = screenshotPng)]
    pub fn screenshot_png(&self) -> Result<js_sys::Promise, JsError> {
        let running = self.running.as_ref().ok_or_else(|| JsError::new("no scene is loaded"))?;
        let (width, height) = (running.packed().scene.width, running.packed().scene.height);
        let n = running.frames().max(1) as f32;
        let denoised = self.denoiser.current().map(|(image, _)| image.clone());
        let read = running.read_accumulation();
        let display = self.display;
        Ok(future_to_promise(async move {
            let fail = |e: String| JsValue::from(JsError::new(&e));
            let image = match denoised {
                Some(image) => image,
                None => {
                    let texels = read.await.map_err(fail)?;
                    Image { width, height, pixels: texels.iter().map(|t| t.truncate() / n).collect() }
                }
            };
            let pixels = tracer::output::to_display_srgb8(&image, &display);
            let mut png = Vec::new();
            let encoder = image::codecs::png::PngEncoder::new(&mut png);
            image::ImageEncoder::write_image(encoder, &pixels, width, height, image::ExtendedColorType::Rgb8)
                .map_err(|e| fail(e.to_string()))?;
            Ok(Uint8Array::from(png.as_slice()).into())
        }))
    }

    /// Test override: at most this many storage buffers per shader stage on WebGPU (0: the
    /// device's), as a device with fewer would allow; applies to the next renderer created.
    #[wasm_bindgen(js_name = setMaxStorageBuffers)]
    pub fn set_max_storage_buffers(&mut self, count: u32) {
        self.wgpu_options.max_storage_buffers_per_shader_stage = (count > 0).then_some(count);
    }

    /// The browser lost the WebGL context (`webglcontextlost`): stop drawing. GL objects died
    /// with the context; the scene stays in memory for `contextRestored`.
    #[wasm_bindgen(js_name = contextLost)]
    pub fn context_lost(&mut self) {
        if !matches!(self.running, Some(Runtime::WebGl2(_))) {
            return;
        }
        self.context_lost = true;
        // Deleting objects of a lost context is a no-op in WebGL.
        self.running = None;
        self.denoiser.new_runtime();
    }

    /// The context is back (`webglcontextrestored`): recreate the renderer and continue with the
    /// same scene, camera and settings (the accumulation restarts).
    #[wasm_bindgen(js_name = contextRestored)]
    pub fn context_restored(&mut self) -> Result<(), JsError> {
        if !self.context_lost {
            return Ok(());
        }
        self.context_lost = false;
        self.rebuild()
    }
}

impl Viewer {
    /// [`frame`](Self::frame) (`rows` `None`: the rest of the frame in one submission) or
    /// [`frame_in_bands`](Self::frame_in_bands).
    fn render_frame(&mut self, rows: Option<u32>) -> Result<bool, JsError> {
        // Its frames would count in the measurement's times.
        self.abandon_measurement("frames were rendered outside it");
        if self.halted() {
            return Ok(true);
        }
        let Some(running) = &mut self.running else { return Ok(true) };
        let done = match rows {
            Some(rows) => running.frame_in_bands(rows, &self.display),
            None => running.frame(&self.display),
        };
        match done {
            Ok(false) => Ok(false),
            Ok(true) => {
                self.denoiser.poll(running);
                self.show_denoised();
                Ok(true)
            }
            Err(e) => self.recover(e).map(|()| true),
        }
    }
}
