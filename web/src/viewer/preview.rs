//! The viewer's preview controls (`crate::runtime::preview`): whether a new renderer's first
//! image is a preview (`setPreview`, the page's `?preview=`), and the test hook's way to render
//! the pending one now (`renderPreview`).

use wasm_bindgen::prelude::*;

use super::Viewer;
use crate::js::now_ms;

#[wasm_bindgen]
impl Viewer {
    /// On (the default): each new renderer (a scene loaded, a resize, a new device...) first
    /// renders a preview at a quarter of each side, shown upscaled until its first
    /// full-resolution frame is complete, and so does each restart (a camera move, a pose) on a
    /// device whose frames are split into bands. Off: none; a preview pending or on show is
    /// dropped (the canvas shows the accumulation at the next draw).
    #[wasm_bindgen(js_name = setPreview)]
    pub fn set_preview(&mut self, on: bool) {
        self.preview = on;
        if let Some(running) = &mut self.running {
            running.set_preview(on);
        }
    }

    /// Renders the pending preview now, as the frame loop's first step would (one submission;
    /// `sync()` waits for it), and shows it: whether one was rendered (none when off, already
    /// rendered, or the accumulation has begun). `sceneInfo().preview` describes it.
    #[wasm_bindgen(js_name = renderPreview)]
    pub fn render_preview(&mut self) -> bool {
        if self.halted() {
            return false;
        }
        let display = self.display;
        self.running.as_mut().is_some_and(|r| r.preview_now(now_ms(), &display))
    }
}
