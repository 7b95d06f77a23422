//! Where a runtime's preview stands (`tracer::backend::preview`): after a renderer is created
//! (a scene loaded, a resize, a new device...) and after each restart of its accumulation (a
//! camera move, a setting, an animation's pose) the frame loop's first step renders the current
//! view at a quarter of each side with the same kernel into an image of its own and shows it
//! upscaled; the full-resolution frame follows in bands, and the preview stays on the canvas
//! until that frame is complete. The accumulation never sees the preview's samples. A restart
//! is previewed on a device too slow for whole frames (its frames split into bands): so a drag
//! or a playing animation, which restarts at every step, shows a preview per step there, a
//! sixteenth of a frame's work instead of a whole frame; a device that renders whole frames
//! within the band budget shows full-resolution frames as before.

use js_sys::Object;
use tracer::backend::preview::{preview_size, FirstFrameDraws};
use wasm_bindgen::JsValue;

use crate::js::set;

/// The preview's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PreviewState {
    /// No preview was asked for (`?preview=0`).
    #[default]
    Off,
    /// Asked for: the frame loop's next step renders it (before the accumulation's first frame;
    /// again after each restart).
    Pending,
    /// Rendered and on the canvas, until the first full-resolution frame is complete.
    Shown,
    /// The first full-resolution frame replaced it.
    Replaced,
    /// The accumulation started without one: a whole frame from the test hook, a renderer that
    /// renders no preview (the wavefront), or an error rendering it (`error`, after which the
    /// renderer renders none).
    Skipped,
}

impl PreviewState {
    pub fn name(self) -> &'static str {
        match self {
            PreviewState::Off => "off",
            PreviewState::Pending => "pending",
            PreviewState::Shown => "shown",
            PreviewState::Replaced => "replaced",
            PreviewState::Skipped => "skipped",
        }
    }
}

/// A runtime's preview: its state, size and when it was submitted.
#[derive(Clone, Debug, Default)]
pub struct Preview {
    pub state: PreviewState,
    /// The last one's size (once rendered).
    pub size: Option<(u32, u32)>,
    /// `performance.now()` at the last one's submission.
    pub submitted_at: Option<f64>,
    /// Previews rendered for this renderer (one per restart at most).
    pub rendered: u64,
    /// Why it was not rendered, if it failed.
    pub error: Option<String>,
    /// When the first frame's bands are drawn while no preview is on show.
    draws: FirstFrameDraws,
    /// Bands of first frames drawn (`shows_band`) for this renderer.
    pub band_draws: u64,
}

impl Preview {
    /// A preview for a new renderer: pending if asked for.
    pub fn new(on: bool) -> Self {
        Preview { state: if on { PreviewState::Pending } else { PreviewState::Off }, ..Default::default() }
    }

    /// Whether it is on the canvas now.
    pub fn showing(&self) -> bool {
        self.state == PreviewState::Shown
    }

    /// Renders the preview of a `full`-sized image with `render` (given the preview's size;
    /// `None` from a renderer that renders none) if it is pending and the accumulation has not
    /// begun (`fresh`): the image to show, if it was rendered at `now_ms`.
    pub fn render_if_due<I>(
        &mut self,
        fresh: bool,
        full: (u32, u32),
        now_ms: f64,
        render: impl FnOnce((u32, u32)) -> Result<Option<I>, String>,
    ) -> Option<I> {
        if self.state != PreviewState::Pending || !fresh {
            return None;
        }
        let size = preview_size(full.0, full.1);
        match render(size) {
            Ok(Some(image)) => {
                self.state = PreviewState::Shown;
                self.size = Some(size);
                self.submitted_at = Some(now_ms);
                self.rendered += 1;
                Some(image)
            }
            Ok(None) => {
                self.state = PreviewState::Skipped;
                None
            }
            Err(error) => {
                web_sys::console::warn_1(&format!("no preview: {error}").into());
                self.state = PreviewState::Skipped;
                self.error = Some(error);
                None
            }
        }
    }

    /// Whether a band of the accumulation's first frame (`first_frame`), done at `now_ms`, is
    /// drawn now: not while a preview is on show, else the first band after a (re)start and
    /// then at most every `PROGRESS_MS` (`tracer::backend::preview`). A frame's last band is
    /// always drawn by the caller.
    pub fn shows_band(&mut self, first_frame: bool, now_ms: f64) -> bool {
        let shows = first_frame && !self.showing() && self.draws.due(now_ms);
        self.band_draws += shows as u64;
        shows
    }

    /// A frame of the accumulation was completed: a preview on show is replaced; one not
    /// rendered yet is not rendered any more.
    pub fn frame_done(&mut self) {
        match self.state {
            PreviewState::Shown => self.state = PreviewState::Replaced,
            PreviewState::Pending => self.state = PreviewState::Skipped,
            _ => {}
        }
    }

    /// The accumulation restarted (a camera or setting change, a pose). On a device whose
    /// frames are split into bands (`slow`) the new view is previewed too, unless previews are
    /// off or failed; otherwise a preview on show (of the old view) is dropped, and the new
    /// view is drawn as its bands are done (`shows_band`). A pending one stays pending.
    pub fn restarted(&mut self, slow: bool) {
        self.draws.restarted();
        match self.state {
            PreviewState::Off => {}
            _ if slow && self.error.is_none() => self.state = PreviewState::Pending,
            PreviewState::Shown => self.state = PreviewState::Skipped,
            _ => {}
        }
    }

    /// `sceneInfo().preview`: `{ state, showing, width, height, submittedAt, rendered, bandDraws,
    /// error }`
    /// (the last preview's size and time, null until one is rendered).
    pub fn describe(&self) -> Object {
        let o = Object::new();
        set(&o, "state", self.state.name());
        set(&o, "showing", self.showing());
        let (width, height) = self.size.map_or((JsValue::NULL, JsValue::NULL), |(w, h)| (w.into(), h.into()));
        set(&o, "width", width);
        set(&o, "height", height);
        set(&o, "submittedAt", self.submitted_at.map_or(JsValue::NULL, JsValue::from));
        set(&o, "rendered", self.rendered as f64);
        set(&o, "bandDraws", self.band_draws as f64);
        set(&o, "error", self.error.as_deref().map_or(JsValue::NULL, JsValue::from));
        o
    }
}
