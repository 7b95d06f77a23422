//! The first image after a scene loads, rendered small: a **preview**.
//!
//! On a slow GPU a full-resolution frame takes seconds (the Cornell box at 640x480 on
//! SwiftShader: 3.4-4.5 s, every path reaching the maximum depth), so the page would show
//! nothing until then. A renderer can instead render one sample per pixel of the current view at
//! a reduced size first ([`GlRenderer::render_preview`](crate::backend::gl::GlRenderer::render_preview),
//! the wgpu renderer's `render_preview`), with the **same kernel** (no compile: the scene's
//! `width` and `height` uniforms and the viewport or dispatch are the preview's for that one
//! submission) into a **separate target** that is never accumulated: the full-resolution
//! accumulation is exactly what it would be without the preview. The web page shows it upscaled
//! until the first full-resolution frame is complete.
//!
//! The size: [`PREVIEW_DIVISOR`] per side (a quarter of the width and height, 1/16 of the
//! pixels), the largest of three-gpu-pathtracer's `lowResScale` defaults (0.1-0.25 of each
//! side across its versions). The preview costs ~1/16 of a frame's GPU time (the kernel's cost
//! is per pixel) plus a submission's fixed costs, and is submitted whole: 0.6-1.1 s for the
//! Cornell box at 640x480 on SwiftShader (docs/web.md), where a frame takes 3-5 s; 160x120 is
//! enough to see the scene, its framing and its lighting. No cost estimate exists before the
//! first frame (the band policy measures frames, and the first draw on WebGL2 also pays the
//! driver's shader JIT), so the rule is a fixed fraction, not a budget.

/// While no preview is on show, the first frame after a restart shows its rows as its bands
/// are done: its first band at once, then at most this often (ms), and its last band. Drawn
/// per band, every animation frame of the first frame was a long task in headless Chromium on
/// SwiftShader (~130 ms: the canvas, drawn, is composited only once the bands queued on the
/// GPU are done), so the queue ran dry at each: LittlestTokyo's first frame in the frame loop
/// (WebGL2, 640x480) took 1.5x as long as drawn every 250 ms (docs/web.md).
pub const PROGRESS_MS: f64 = 250.0;

/// When the first frame's bands are drawn ([`PROGRESS_MS`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstFrameDraws {
    /// When a band of the first frame was last drawn; `None`: not since the last restart.
    drawn_at_ms: Option<f64>,
}

impl FirstFrameDraws {
    /// The accumulation restarted: its first band is drawn at once.
    pub fn restarted(&mut self) {
        self.drawn_at_ms = None;
    }

    /// Whether a band of the first frame done (submitted) at `now_ms` is drawn; if so, it
    /// counts as drawn then.
    pub fn due(&mut self, now_ms: f64) -> bool {
        let due = self.drawn_at_ms.is_none_or(|t| !(0.0..PROGRESS_MS).contains(&(now_ms - t)));
        if due {
            self.drawn_at_ms = Some(now_ms);
        }
        due
    }
}

/// The preview is this many times smaller than the image on each side.
pub const PREVIEW_DIVISOR: u32 = 4;

/// The preview's size for an image of `width` x `height`: each side divided by
/// [`PREVIEW_DIVISOR`], rounded up (at least one pixel).
pub fn preview_size(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(PREVIEW_DIVISOR).max(1), height.div_ceil(PREVIEW_DIVISOR).max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_preview_is_a_quarter_of_each_side_rounded_up() {
        assert_eq!(preview_size(640, 480), (160, 120));
        assert_eq!(preview_size(641, 481), (161, 121));
        assert_eq!(preview_size(32, 32), (8, 8));
        assert_eq!(preview_size(1, 7), (1, 2));
    }

    #[test]
    fn the_first_frame_draws_its_first_band_then_at_most_every_progress_ms() {
        let mut draws = FirstFrameDraws::default();
        let drawn: Vec<bool> = [0.0, 30.0, 200.0, 250.0, 260.0, 499.0, 520.0].map(|t| draws.due(t)).to_vec();
        assert_eq!(drawn, [true, false, false, true, false, false, true]);
        // A restart draws its first band at once, however recent the last draw.
        draws.restarted();
        assert!(draws.due(530.0));
        assert!(!draws.due(540.0));
        // A clock that went backwards (or NaN) draws rather than waiting for it.
        assert!(draws.due(100.0));
        assert!(draws.due(f64::NAN));
        assert!(draws.due(110.0));
    }
}
