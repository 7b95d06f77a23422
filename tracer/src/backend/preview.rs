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
}
