//! The browser viewer: a WebGL2 context from a canvas, wrapped in `glow`, and the native GL
//! backend's [`GlRenderer`] on it. Only the context and the frame loop (JavaScript's
//! `requestAnimationFrame`, calling [`Viewer::frame`]) are specific to the web; the kernel, its
//! shader, the data textures and the accumulation are the native code.
//!
//! Each frame adds one sample per pixel to the RGBA32F accumulation, then a small display pass
//! draws its mean to the canvas through the kernel's display transform (tone curve, exposure,
//! sRGB: [`GlDisplay`], what the CLI's PNG output stores with the same settings). The frame
//! loop calls [`Viewer::step`], which submits a frame in bands of rows of at most a time budget
//! (50 ms by default; `tracer::backend::frame_split`), one band at a time, so that input is
//! handled, and a camera move restarts the accumulation, between bands, also on a GPU that
//! needs seconds per frame.

use std::fmt;

use glow::HasContext;
use js_sys::{Float32Array, Object, Reflect};
use tracer::backend::frame_split::{Pacer, Step, DEFAULT_BUDGET_MS};
use tracer::backend::gl::{GlDisplay, GlOptions, GlRenderer};
use tracer::output::{Display, ToneMap};
use tracer::pack::{Packed, RenderSettings, Strategy};
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use web_sys::{HtmlCanvasElement, WebGl2RenderingContext, WebGlContextAttributes};

use crate::camera::OrbitCamera;
use crate::files::{self, DroppedFile};

fn js_error(e: impl fmt::Display) -> JsError {
    JsError::new(&e.to_string())
}

fn set(object: &Object, key: &str, value: impl Into<JsValue>) {
    // Setting a plain property on a fresh object cannot fail.
    let _ = Reflect::set(object, &JsValue::from_str(key), &value.into());
}

/// The renderer and its display pass, on one context.
struct Running {
    renderer: GlRenderer,
    /// Always `Some` until dropped (taken to delete it before the renderer's context goes).
    display: Option<GlDisplay>,
    /// Bands of the frame loop (`step`), one on the GPU at a time.
    pacer: Pacer,
}

impl Running {
    fn draw(&self, width: i32, height: i32, settings: &Display) {
        if let Some(display) = &self.display {
            display.draw(&self.renderer, None, [width, height], settings);
        }
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.pacer.forget(self.renderer.gl());
        if let Some(display) = self.display.take() {
            display.delete(self.renderer.gl());
        }
    }
}

/// The loaded scene: the master copy of its packed data (uniforms kept current) and the view.
struct Loaded {
    name: String,
    packed: Packed,
    camera: OrbitCamera,
    /// The scene's own view, for `resetCamera`.
    home: OrbitCamera,
}

/// The path tracer on a canvas. Create it with `new Viewer(canvas)`, load a bundle or dropped
/// files, then call `frame()` from `requestAnimationFrame`.
#[wasm_bindgen]
pub struct Viewer {
    canvas: HtmlCanvasElement,
    context: WebGl2RenderingContext,
    loaded: Option<Loaded>,
    running: Option<Running>,
    settings: RenderSettings,
    options: GlOptions,
    context_lost: bool,
    dropped: Vec<DroppedFile>,
    /// Selects the random sequence, as the native backends' `seed` does (`setSeed`).
    seed: u32,
    /// The longest one band of a frame should take on the GPU (`setBandBudget`); `None`:
    /// frames are not split.
    band_budget_ms: Option<f64>,
    /// How the accumulation is shown and screenshot: tone curve and exposure (`setToneMap`,
    /// `setExposure`), the CLI's `--tonemap` and `--exposure`.
    display: Display,
}

#[wasm_bindgen]
impl Viewer {
    /// A viewer drawing into `canvas`. Fails with a clear message when the browser has no WebGL2.
    #[wasm_bindgen(constructor)]
    pub fn new(canvas: HtmlCanvasElement) -> Result<Viewer, JsError> {
        console_error_panic_hook::set_once();
        let attributes = WebGlContextAttributes::new();
        attributes.set_antialias(false);
        attributes.set_depth(false);
        attributes.set_stencil(false);
        attributes.set_alpha(false);
        attributes.set_power_preference(web_sys::WebGlPowerPreference::HighPerformance);
        let context = canvas
            .get_context_with_context_options("webgl2", &attributes)
            .map_err(|e| JsError::new(&format!("creating a WebGL2 context failed: {e:?}")))?
            .ok_or_else(|| {
                JsError::new(
                    "this browser or device has no WebGL2: the path tracer needs WebGL2 (enable hardware \
                     acceleration, or try a current Chrome, Firefox or Safari)",
                )
            })?
            .dyn_into::<WebGl2RenderingContext>()
            .map_err(|_| JsError::new("the canvas returned a context that is not WebGL2"))?;
        let settings =
            RenderSettings { width: canvas.width().max(1), height: canvas.height().max(1), ..Default::default() };
        Ok(Viewer {
            canvas,
            context,
            loaded: None,
            running: None,
            settings,
            options: GlOptions::default(),
            context_lost: false,
            dropped: Vec::new(),
            seed: 1,
            band_budget_ms: Some(DEFAULT_BUDGET_MS),
            display: Display::default(),
        })
    }

    /// Loads a scene bundle (as served at `/bundles/<hash>.lpb`): no loading or BVH build, the
    /// packed scene is uploaded as it is. Returns the scene's description (see `sceneInfo`).
    #[wasm_bindgen(js_name = loadBundle)]
    pub fn load_bundle(&mut self, bytes: &[u8]) -> Result<JsValue, JsError> {
        let bundle = tracer::bundle::Bundle::decode(bytes).map_err(js_error)?;
        self.install(bundle.name, bundle.packed)
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
        let (name, scene) = files::load_dropped(&dropped).map_err(js_error)?;
        drop(dropped);
        let loaded_at = js_sys::Date::now();
        let packed = files::prepare(&name, &scene, &self.settings).map_err(js_error)?;
        let prepared_at = js_sys::Date::now();
        let info = self.install(name, packed)?;
        let info = Object::from(info);
        set(&info, "loadMs", loaded_at - start);
        set(&info, "buildAndPackMs", prepared_at - loaded_at);
        set(&info, "warnings", scene.warnings.join("; "));
        Ok(info.into())
    }

    /// Makes `packed` the current scene, keeping the viewer's size and strategy. If the GL
    /// renderer refuses it (too large for the device...), the previous scene stays.
    fn install(&mut self, name: String, mut packed: Packed) -> Result<JsValue, JsError> {
        let bundle_depth = packed.scene.max_depth;
        packed.apply(&RenderSettings { max_depth: bundle_depth, ..self.settings });
        let camera = OrbitCamera::from_uniforms(&packed.scene);
        let running = self.start(&packed)?;
        self.settings.max_depth = bundle_depth;
        self.running = Some(running);
        self.loaded = Some(Loaded { name, packed, camera, home: camera });
        Ok(self.scene_info())
    }

    /// A renderer and display pass for `packed` on the canvas's context.
    fn start(&self, packed: &Packed) -> Result<Running, JsError> {
        if self.context_lost {
            return Err(JsError::new("the WebGL context is lost; waiting for the browser to restore it"));
        }
        self.canvas.set_width(packed.scene.width);
        self.canvas.set_height(packed.scene.height);
        let gl = glow::Context::from_webgl2_context(self.context.clone());
        let renderer = GlRenderer::with_options(gl, packed.clone(), self.seed, &self.options).map_err(js_error)?;
        let display = GlDisplay::new(renderer.gl()).map_err(js_error)?;
        let pacer = Pacer::new(packed.scene.height, self.band_budget_ms);
        Ok(Running { renderer, display: Some(display), pacer })
    }

    /// Adds one sample per pixel (the rest of the frame, if `step` began it) in one submission
    /// and draws the converging image (the test hook's `renderFrames`). Does nothing without a
    /// scene or while the context is lost.
    pub fn frame(&mut self) -> Result<(), JsError> {
        if self.context_lost || self.context.is_context_lost() {
            return Ok(());
        }
        let Some(running) = &mut self.running else { return Ok(()) };
        // The band in flight would be timed with this whole frame.
        running.pacer.forget(running.renderer.gl());
        running.renderer.render_frame().map_err(js_error)?;
        running.draw(self.canvas.width() as i32, self.canvas.height() as i32, &self.display);
        Ok(())
    }

    /// The frame loop's step (call it once per animation frame with `performance.now()`):
    /// unless the previous band is still on the GPU (its fence polled without blocking),
    /// submits the next band of the frame, and when that completes the frame, draws the image
    /// (during the first frame after a restart: after every band, the new view band by band).
    /// Returns 0: waited (nothing submitted), 1: a band was submitted, 2: the band completed a
    /// frame (one more sample per pixel).
    pub fn step(&mut self, now_ms: f64) -> Result<u32, JsError> {
        if self.context_lost || self.context.is_context_lost() {
            return Ok(0);
        }
        let Some(running) = &mut self.running else { return Ok(0) };
        let (w, h) = (self.canvas.width() as i32, self.canvas.height() as i32);
        let display = running.display.as_ref();
        let settings = &self.display;
        let step = running
            .pacer
            .step(&mut running.renderer, now_ms, |renderer, frame_done| {
                // Each band of the first frame after a restart shows; later, each whole frame.
                if let (true, Some(display)) = (frame_done || renderer.frames() == 0, display) {
                    display.draw(renderer, None, [w, h], settings);
                }
            })
            .map_err(js_error)?;
        Ok(match step {
            Step::Waiting => 0,
            Step::Submitted { frame_done: false } => 1,
            Step::Submitted { frame_done: true } => 2,
        })
    }

    /// The longest one band of a frame should take on the GPU, in milliseconds (default 50);
    /// 0: do not split frames (one submission per frame). Restarts the band-height adaptation.
    #[wasm_bindgen(js_name = setBandBudget)]
    pub fn set_band_budget(&mut self, ms: f64) -> Result<(), JsError> {
        if !(ms.is_finite() && ms >= 0.0) {
            return Err(JsError::new(&format!("invalid band budget {ms} ms (a number >= 0; 0: no splitting)")));
        }
        self.band_budget_ms = (ms > 0.0).then_some(ms);
        if let Some(running) = &mut self.running {
            running.pacer.forget(running.renderer.gl());
            running.pacer = Pacer::new(running.renderer.packed().scene.height, self.band_budget_ms);
        }
        Ok(())
    }

    /// Waits until the queued frames are rendered (reads one pixel back), e.g. around timings.
    pub fn sync(&self) -> Result<(), JsError> {
        let Some(running) = &self.running else { return Ok(()) };
        let gl = running.renderer.gl();
        let mut pixel = [0u8; 4];
        // SAFETY: reads one RGBA8 pixel of the default framebuffer into a 4-byte buffer.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.read_pixels(0, 0, 1, 1, glow::RGBA, glow::UNSIGNED_BYTE, glow::PixelPackData::Slice(Some(&mut pixel)));
        }
        Ok(())
    }

    /// Samples per pixel accumulated since the last restart.
    pub fn spp(&self) -> u32 {
        self.running.as_ref().map_or(0, |r| r.renderer.frames())
    }

    /// The render size, scene and renderer (an object; see the fields set here).
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
        if let Some(loaded) = &self.loaded {
            let f = &loaded.packed.features;
            set(&info, "name", loaded.name.as_str());
            set(&info, "triangles", loaded.packed.triangle_count as u32);
            set(&info, "lights", loaded.packed.light_count as u32);
            let features = Object::new();
            for (name, on) in [
                ("sky", f.sky),
                ("textures", f.textures),
                ("shading", f.shading),
                ("pointLights", f.point_lights),
                ("emissiveTriangles", f.emissive_triangles),
                ("metalRough", f.metal_rough),
                ("normalMap", f.normal_map),
            ] {
                set(&features, name, on);
            }
            set(&info, "features", features);
        }
        let budget = self.band_budget_ms.unwrap_or(0.0);
        set(&info, "bandBudgetMs", budget);
        if let Some(running) = &self.running {
            let policy = running.pacer.policy();
            set(&info, "bands", policy.bands());
            set(&info, "bandRows", policy.rows());
            set(&info, "bandMs", policy.band_ms().map_or(JsValue::NULL, JsValue::from));
            set(&info, "gpuBusy", running.pacer.busy());
            let gl = running.renderer.info();
            set(&info, "glRenderer", gl.renderer.as_str());
            set(&info, "glVersion", gl.version.as_str());
            set(&info, "maxTextureSize", gl.max_texture_size);
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

    /// Recreates the renderer for the current settings and camera (after a resize or a lost
    /// context).
    fn rebuild(&mut self) -> Result<(), JsError> {
        self.running = None;
        let Some(loaded) = &mut self.loaded else {
            self.canvas.set_width(self.settings.width);
            self.canvas.set_height(self.settings.height);
            return Ok(());
        };
        loaded.packed.apply(&self.settings);
        loaded.camera.apply(&mut loaded.packed.scene);
        let packed = loaded.packed.clone();
        self.running = Some(self.start(&packed)?);
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

    /// Orbit: turns the eye around the target (radians). Restarts the accumulation.
    pub fn orbit(&mut self, yaw: f32, pitch: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.orbit(yaw, pitch))
    }

    /// Fly: turns the view around the eye (radians). Restarts the accumulation.
    pub fn look(&mut self, yaw: f32, pitch: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.look(yaw, pitch))
    }

    /// Moves eye and target sideways by fractions of the view height. Restarts the accumulation.
    pub fn pan(&mut self, dx: f32, dy: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.pan(dx, dy))
    }

    /// Scales the eye's distance to the target. Restarts the accumulation.
    pub fn dolly(&mut self, factor: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.dolly(factor))
    }

    /// Moves eye and target (scene-size units) along the view, right and +Y. Restarts.
    pub fn fly(&mut self, forward: f32, right: f32, up: f32) -> Result<(), JsError> {
        self.move_camera(|c| c.fly(forward, right, up))
    }

    /// The scene's own camera again. Restarts the accumulation.
    #[wasm_bindgen(js_name = resetCamera)]
    pub fn reset_camera(&mut self) -> Result<(), JsError> {
        let Some(home) = self.loaded.as_ref().map(|l| l.home) else { return Ok(()) };
        self.move_camera(|c| *c = home)
    }

    fn move_camera(&mut self, change: impl FnOnce(&mut OrbitCamera)) -> Result<(), JsError> {
        let Some(loaded) = &mut self.loaded else { return Ok(()) };
        change(&mut loaded.camera);
        self.update_uniforms()
    }

    /// Writes the camera and settings into the master copy and the renderer's uniforms, and
    /// restarts the accumulation.
    fn update_uniforms(&mut self) -> Result<(), JsError> {
        let settings = self.settings;
        let Some(loaded) = &mut self.loaded else { return Ok(()) };
        let camera = loaded.camera;
        let update = |scene: &mut tracer::kernel::scene_data::Scene| {
            camera.apply(scene);
            scene.strategy = settings.strategy.uniform_value();
            scene.max_depth = settings.max_depth;
        };
        update(&mut loaded.packed.scene);
        if let Some(running) = &mut self.running {
            if !self.context_lost {
                running.renderer.set_uniforms(update).map_err(js_error)?;
            }
        }
        Ok(())
    }

    /// The accumulation: per pixel (rows from the top) the sum of samples in rgb and the
    /// number of finite samples in a; `spp()` frames so far.
    #[wasm_bindgen(js_name = readAccumulation)]
    pub fn read_accumulation(&self) -> Result<Float32Array, JsError> {
        let running = self.running.as_ref().ok_or_else(|| JsError::new("no scene is loaded"))?;
        let texels = running.renderer.accumulation().map_err(js_error)?;
        let floats: Vec<f32> = texels.iter().flat_map(|t| t.to_array()).collect();
        Ok(Float32Array::from(floats.as_slice()))
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
    fn redraw(&self) {
        if self.context_lost || self.context.is_context_lost() {
            return;
        }
        if let Some(running) = &self.running {
            running.draw(self.canvas.width() as i32, self.canvas.height() as i32, &self.display);
        }
    }

    /// The current image as PNG bytes, through the display's tone curve and exposure (as the
    /// CLI's PNG output with the same `--tonemap` and `--exposure`).
    #[wasm_bindgen(js_name = screenshotPng)]
    pub fn screenshot_png(&self) -> Result<Vec<u8>, JsError> {
        let running = self.running.as_ref().ok_or_else(|| JsError::new("no scene is loaded"))?;
        let image = running.renderer.image().map_err(js_error)?;
        let pixels = tracer::output::to_display_srgb8(&image, &self.display);
        let mut png = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut png);
        image::ImageEncoder::write_image(encoder, &pixels, image.width, image.height, image::ExtendedColorType::Rgb8)
            .map_err(js_error)?;
        Ok(png)
    }

    /// The browser lost the WebGL context (`webglcontextlost`): stop drawing. GL objects died
    /// with the context; the scene stays in memory for `contextRestored`.
    #[wasm_bindgen(js_name = contextLost)]
    pub fn context_lost(&mut self) {
        self.context_lost = true;
        // Deleting objects of a lost context is a no-op in WebGL.
        self.running = None;
    }

    /// The context is back (`webglcontextrestored`): recreate the renderer and continue with the
    /// same scene, camera and settings (the accumulation restarts).
    #[wasm_bindgen(js_name = contextRestored)]
    pub fn context_restored(&mut self) -> Result<(), JsError> {
        self.context_lost = false;
        self.rebuild()
    }
}
