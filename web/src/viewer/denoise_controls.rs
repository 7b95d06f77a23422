//! The page's denoiser controls (`setDenoise`, `pollDenoise`, `setDenoiseSchedule`,
//! `denoiseNow`, `readDenoised`) and drawing the denoised image; the denoiser itself is
//! `crate::denoise`.

use js_sys::{Float32Array, Object};
use wasm_bindgen::prelude::*;

use super::Viewer;
use crate::js::set;

#[wasm_bindgen]
impl Viewer {
    /// Turns the denoiser on (the default) or off: on, the canvas shows the accumulation
    /// denoised (at 4 spp, then each time the samples per pixel double: see
    /// `web/src/denoise/mod.rs`); off, the raw accumulation, redrawn now. The path tracer must
    /// accumulate the denoiser's guide: switched on over a renderer created without it, the
    /// renderer is recreated (the accumulation restarts); switched off, it keeps the guide (and
    /// its samples) until it is next recreated. Works with no scene loaded or a lost context
    /// (it applies to the renderer created next).
    #[wasm_bindgen(js_name = setDenoise)]
    pub fn set_denoise(&mut self, on: bool) -> Result<(), JsError> {
        self.denoiser.set_enabled(on);
        let lacks_guide = self.running.as_ref().is_some_and(|r| !r.packed().features.denoise_guide);
        if on && lacks_guide && !self.halted() {
            self.rebuild()?;
        }
        self.redraw();
        Ok(())
    }

    /// Call once per animation frame, also while no frame is rendered: collects what WebGPU
    /// finished for the denoiser, starts a denoise that is due and shows a new denoised image.
    #[wasm_bindgen(js_name = pollDenoise)]
    pub fn poll_denoise(&mut self) {
        // Denoising would share the device with the frames measured.
        if self.halted() || self.measuring_schedule() {
            return;
        }
        let Some(running) = &mut self.running else { return };
        if self.denoiser.poll(running) {
            self.show_denoised();
        }
    }

    /// Whether the page's rule starts denoises (on, the default: at 4 spp, then each time the
    /// samples per pixel double); off, only `denoiseNow` does (`lightport chart --denoise`).
    #[wasm_bindgen(js_name = setDenoiseSchedule)]
    pub fn set_denoise_schedule(&mut self, on: bool) {
        self.denoiser.set_schedule(on);
    }

    /// Asks for a denoise of the accumulation as it is now, whatever the page's rule says; it
    /// starts at the next `pollDenoise` or frame, and `sceneInfo().denoise.shownSpp` says when
    /// it shows. An error when the denoiser is off, no scene renders, the renderer lacks the
    /// guide or the denoiser failed on this accumulation.
    #[wasm_bindgen(js_name = denoiseNow)]
    pub fn denoise_now(&mut self) -> Result<(), JsError> {
        if self.halted() {
            return Err(JsError::new("the WebGL context or the WebGPU device is lost"));
        }
        let running = self.running.as_ref().ok_or_else(|| JsError::new("no scene is loaded"))?;
        self.denoiser.request(running).map_err(|e| JsError::new(&e))
    }

    /// The denoised image on show: `{ spp, width, height, data: Float32Array (rgb per pixel,
    /// rows from the top: the mean, not a sum), filterMs (the whole denoise: read-backs,
    /// passes, remodulation) }`, or null when the current accumulation shows none.
    #[wasm_bindgen(js_name = readDenoised)]
    pub fn read_denoised(&self) -> JsValue {
        let Some((spp, image, filter_ms)) = self.denoiser.shown() else { return JsValue::NULL };
        let o = Object::new();
        set(&o, "spp", spp);
        set(&o, "width", image.width);
        set(&o, "height", image.height);
        let floats: Vec<f32> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
        set(&o, "data", Float32Array::from(floats.as_slice()));
        set(&o, "filterMs", filter_ms);
        o.into()
    }
}

impl Viewer {
    /// Draws the denoised image over the raw one, when the current accumulation has one.
    pub(super) fn show_denoised(&mut self) {
        if self.halted() {
            return;
        }
        let (Some(running), Some((image, id))) = (&mut self.running, self.denoiser.current()) else { return };
        if let Err(e) = running.draw_image(image, id, &self.display) {
            self.denoiser.fail(format!("drawing the denoised image failed: {e}"));
        }
    }
}
