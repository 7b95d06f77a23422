//! The WebGL2 runtime: the native GL backend's [`GlRenderer`] on the canvas's WebGL2 context,
//! its display pass ([`GlDisplay`]) drawing the accumulation's mean to the canvas, and the fenced band pacer
//! (`tracer::backend::frame_split`) that submits each frame in bands within the time budget.

use glow::HasContext;
use tracer::backend::frame_split::Step;
use tracer::backend::gl::Pacer;
use tracer::backend::gl::{GlDisplay, GlFilter, GlOptions, GlRenderer, QueuedFilter};
use tracer::backend::{Image, Renderer};
use tracer::kernel::denoise::FilterImage;
use tracer::output::Display;
use tracer::pack::Packed;
use wasm_bindgen::JsCast;
use web_sys::{HtmlCanvasElement, WebGl2RenderingContext, WebGlContextAttributes};

use super::preview::Preview;
use super::Startup;
use crate::denoise::show::GlImageDisplay;
use crate::js::now_ms;

/// The WebGL2 context of `canvas` (which must not hold another kind of context).
pub fn context(canvas: &HtmlCanvasElement) -> Result<WebGl2RenderingContext, String> {
    let attributes = WebGlContextAttributes::new();
    attributes.set_antialias(false);
    attributes.set_depth(false);
    attributes.set_stencil(false);
    attributes.set_alpha(false);
    attributes.set_power_preference(web_sys::WebGlPowerPreference::HighPerformance);
    canvas
        .get_context_with_context_options("webgl2", &attributes)
        .map_err(|e| format!("creating a WebGL2 context failed: {e:?}"))?
        .ok_or_else(|| {
            "this browser or device has no WebGL2: the path tracer needs WebGL2 or WebGPU (enable hardware \
             acceleration, or try a current Chrome, Firefox or Safari)"
                .to_string()
        })?
        .dyn_into::<WebGl2RenderingContext>()
        .map_err(|_| "the canvas returned a context that is not WebGL2".to_string())
}

/// The renderer and its display pass, on one context.
pub struct GlRuntime {
    context: WebGl2RenderingContext,
    renderer: GlRenderer,
    /// Always `Some` until dropped (taken to delete it before the renderer's context goes).
    display: Option<GlDisplay>,
    /// Bands of the frame loop (`step`), one on the GPU at a time.
    pacer: Pacer,
    startup: Startup,
    /// The denoised image's display pass, created at the first denoised image.
    image_display: Option<GlImageDisplay>,
    /// The denoiser's filter pass (compiled at the first denoise) and its passes on the GPU:
    /// while they run, no band is submitted (one job on the GPU at a time, as bands are).
    filter: Option<GlFilter>,
    queued: Option<QueuedFilter>,
    /// The preview (`super::preview`) and its image, once rendered.
    preview: Preview,
    preview_image: Option<glow::Texture>,
}

impl GlRuntime {
    pub fn new(
        context: &WebGl2RenderingContext,
        packed: &Packed,
        seed: u32,
        options: &GlOptions,
        band_budget_ms: Option<f64>,
    ) -> Result<Self, String> {
        let gl = glow::Context::from_webgl2_context(context.clone());
        let renderer = GlRenderer::with_options(gl, packed.clone(), seed, options).map_err(|e| e.to_string())?;
        let build = renderer.build_times();
        let compiling = now_ms();
        let display = GlDisplay::new(renderer.gl()).map_err(|e| e.to_string())?;
        let display_ms = now_ms() - compiling;
        // The texture uploads were only handed to the browser's GPU process: wait until it
        // has them, so that they count as upload and not as the first frame.
        let waiting = now_ms();
        read_back_pixel(renderer.gl());
        let created_at = now_ms();
        let startup = Startup {
            codegen_ms: build.codegen_ms,
            compile_ms: build.compile_ms + display_ms,
            upload_ms: build.upload_ms + (created_at - waiting),
            created_at,
            compiled_at: Some(created_at),
            compiled_while_decoding: false,
        };
        let pacer = Pacer::new(packed.scene.height, band_budget_ms);
        Ok(GlRuntime {
            context: context.clone(),
            renderer,
            display: Some(display),
            pacer,
            startup,
            image_display: None,
            filter: None,
            queued: None,
            preview: Preview::default(),
            preview_image: None,
        })
    }

    pub fn preview(&self) -> &Preview {
        &self.preview
    }

    /// Draws the kernel once (`GlRenderer::warm_up`: a 1x1 preview of the placeholder scene it
    /// was created for, `Packed::placeholder`) and hands that to the GPU process without
    /// waiting for it. SwiftShader compiles a program at its first draw (seconds for the path
    /// tracer), which so happens while this thread goes on, decoding the scene.
    pub fn warm_up(&mut self) -> Result<(), String> {
        self.renderer.warm_up().map_err(|e| format!("warming the kernel up: {e}"))
    }

    /// Takes the scene whose features the runtime was created for (after
    /// [`warm_up`](Self::warm_up)): waits for the warm-up draw, which is what is left of the
    /// compile (counted as compile), then uploads the scene and waits until the GPU process
    /// has it (counted as upload). Both waits read a pixel back ([`sync`](Self::sync)):
    /// `gl.finish()` returns at once in Chromium, which counted SwiftShader's compile (0.9 s
    /// on the Cornell box) in the upload and the preview.
    pub fn take_scene(&mut self, packed: Packed) -> Result<(), String> {
        let waiting = now_ms();
        self.sync();
        let uploading = now_ms();
        self.renderer.take_scene(packed).map_err(|e| e.to_string())?;
        self.sync();
        let created_at = now_ms();
        let s = &mut self.startup;
        s.compile_ms += uploading - waiting;
        s.upload_ms = created_at - uploading;
        (s.created_at, s.compiled_at, s.compiled_while_decoding) = (created_at, Some(created_at), true);
        Ok(())
    }

    pub fn preview_mut(&mut self) -> &mut Preview {
        &mut self.preview
    }

    /// Renders the pending preview now, if the accumulation has not begun, and shows it:
    /// whether it did. The bands in flight are forgotten (the caller waits with `sync`).
    pub fn preview_now(&mut self, now_ms: f64, settings: &Display) -> bool {
        let (w, h) = self.size();
        let fresh = self.renderer.frames() == 0 && self.renderer.rows_left() == h as u32;
        let (renderer, pacer) = (&mut self.renderer, &mut self.pacer);
        let image = self.preview.render_if_due(fresh, (w as u32, h as u32), now_ms, |(width, height)| {
            pacer.forget(renderer.gl());
            renderer.render_preview(width, height).map(Some).map_err(|e| e.to_string())
        });
        let Some(texture) = image else { return false };
        self.preview_image = Some(texture);
        self.draw(settings);
        true
    }

    pub fn renderer(&self) -> &GlRenderer {
        &self.renderer
    }

    pub fn renderer_mut(&mut self) -> &mut GlRenderer {
        &mut self.renderer
    }

    pub fn startup(&self) -> Startup {
        self.startup.clone()
    }

    pub fn pacer(&self) -> &Pacer {
        &self.pacer
    }

    /// Checks, without waiting, which bands (or preview) in flight are done (`Pacer::poll`):
    /// true when nothing is in flight (any more).
    pub fn poll(&mut self, now_ms: f64) -> bool {
        self.pacer.poll(self.renderer.gl(), now_ms)
    }

    pub fn context_lost(&self) -> bool {
        self.context.is_context_lost()
    }

    fn size(&self) -> (i32, i32) {
        let s = &self.renderer.packed().scene;
        (s.width as i32, s.height as i32)
    }

    /// Draws the current image through `settings`: the preview, upscaled, while it shows.
    pub fn draw(&self, settings: &Display) {
        let (w, h) = self.size();
        let Some(display) = &self.display else { return };
        match self.preview_image.filter(|_| self.preview.showing()) {
            Some(image) => display.draw_texture(self.renderer.gl(), image, None, [w, h], 1.0, settings),
            None => display.draw(&self.renderer, None, [w, h], settings),
        }
    }

    /// Draws `image` (a denoised image of the renderer's size, known as `id`) through `settings`.
    pub fn draw_image(&mut self, image: &Image, id: u64, settings: &Display) -> Result<(), String> {
        let Some(pass) = &self.display else { return Ok(()) };
        if self.image_display.is_none() {
            self.image_display = Some(GlImageDisplay::new(self.renderer.gl())?);
        }
        if let Some(display) = &mut self.image_display {
            display.draw(self.renderer.gl(), pass, image, id, settings);
        }
        Ok(())
    }

    /// Queues the denoiser's passes over `image` (the previous queued ones, if any, dropped);
    /// [`filter_output`](Self::filter_output) has their output once they are done.
    pub fn queue_filter(&mut self, image: &FilterImage) -> Result<(), String> {
        let gl = self.renderer.gl();
        if let Some(old) = self.queued.take() {
            old.delete(gl);
        }
        if self.filter.is_none() {
            self.filter = Some(GlFilter::new(gl).map_err(|e| e.to_string())?);
        }
        let filter = self.filter.as_ref().expect("created above");
        self.queued = Some(filter.queue(gl, image).map_err(|e| e.to_string())?);
        Ok(())
    }

    /// The queued passes' output once they are done (`None`: none queued, or not done yet).
    pub fn filter_output(&mut self) -> Option<Result<Vec<glam::Vec4>, String>> {
        let gl = self.renderer.gl();
        if !self.queued.as_ref()?.done(gl) {
            return None;
        }
        let queued = self.queued.take()?;
        Some(queued.read(gl).map_err(|e| e.to_string()))
    }

    /// One whole frame in one submission, then the display pass.
    pub fn frame(&mut self, settings: &Display) -> Result<(), String> {
        // The bands in flight would be timed with this whole frame.
        self.pacer.forget(self.renderer.gl());
        self.renderer.render_frame().map_err(|e| e.to_string())?;
        self.preview.frame_done();
        self.draw(settings);
        Ok(())
    }

    /// The rest of the frame in bands of `rows` rows submitted back to back, then the display
    /// pass (the test hook's `renderFramesInBands`: what a band costs beyond its rows).
    pub fn frame_in_bands(&mut self, rows: u32, settings: &Display) -> Result<(), String> {
        self.pacer.forget(self.renderer.gl());
        while !self.renderer.render_band(rows).map_err(|e| e.to_string())? {}
        self.preview.frame_done();
        self.draw(settings);
        Ok(())
    }

    /// The frame loop's step (see `Viewer::step`).
    pub fn step(&mut self, now_ms: f64, settings: &Display) -> Result<Step, String> {
        if self.queued.as_ref().is_some_and(|q| !q.done(self.renderer.gl())) {
            return Ok(Step::Waiting);
        }
        let (w, h) = self.size();
        if self.preview.state == super::preview::PreviewState::Pending {
            // First the preview, alone on the GPU: its draw waits for the bands in flight.
            if !self.pacer.poll(self.renderer.gl(), now_ms) {
                return Ok(Step::Waiting);
            }
            if self.preview_now(now_ms, settings) {
                self.pacer.track(self.renderer.gl(), now_ms);
                return Ok(Step::Preview);
            }
        }
        let (display, preview) = (self.display.as_ref(), &mut self.preview);
        let step = self
            .pacer
            .step(&mut self.renderer, now_ms, |renderer, frame_done| {
                // The first frame after a restart shows as its bands are done (unless the
                // preview does until the frame is complete); later, each whole frame.
                let first = preview.shows_band(renderer.frames() == 0, now_ms);
                if let (true, Some(display)) = (frame_done || first, display) {
                    display.draw(renderer, None, [w, h], settings);
                }
            })
            .map_err(|e| e.to_string())?;
        if step == (Step::Submitted { frame_done: true }) {
            self.preview.frame_done();
        }
        Ok(step)
    }

    pub fn set_band_budget(&mut self, budget_ms: Option<f64>) {
        self.pacer.forget(self.renderer.gl());
        self.pacer = Pacer::new(self.renderer.packed().scene.height, budget_ms);
    }

    /// Waits for the GPU: reads one pixel of the canvas back.
    pub fn sync(&self) {
        read_back_pixel(self.renderer.gl());
    }
}

/// Waits until the GPU process has run every command sent so far, by reading one pixel of the
/// canvas back (`gl.finish()` returns at once in Chromium).
fn read_back_pixel(gl: &glow::Context) {
    let mut pixel = [0u8; 4];
    // SAFETY: reads one RGBA8 pixel of the default framebuffer into a 4-byte buffer.
    unsafe {
        gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        gl.read_pixels(0, 0, 1, 1, glow::RGBA, glow::UNSIGNED_BYTE, glow::PixelPackData::Slice(Some(&mut pixel)));
    }
}

impl Drop for GlRuntime {
    fn drop(&mut self) {
        self.pacer.forget(self.renderer.gl());
        if let Some(display) = self.display.take() {
            display.delete(self.renderer.gl());
        }
        if let Some(display) = self.image_display.take() {
            display.delete(self.renderer.gl());
        }
        if let Some(queued) = self.queued.take() {
            queued.delete(self.renderer.gl());
        }
        if let Some(filter) = self.filter.take() {
            filter.delete(self.renderer.gl());
        }
    }
}
