//! The preview (`tracer::backend::preview`): a first image at a reduced size, drawn by the
//! renderer's own kernel into a target of its own. On each GPU runtime (GL on a headless EGL
//! context, wgpu natively): the preview is, exactly, the first frame a renderer created at the
//! preview's size renders (same seed: the same samples; so the same kernel at that size, not a
//! crop of the full image nor a sample from another frame), and the accumulation after it is,
//! exactly, the one a renderer that rendered no preview has (its colour and the denoiser's guide
//! sums): nothing of the preview is accumulated.

use glam::Vec4;
use tracer::backend::gl::GlRenderer;
use tracer::backend::preview::preview_size;
use tracer::backend::wgpu::{DeviceRenderer, WgpuRenderer};
use tracer::backend::Renderer;
use tracer::kernel::Strategy;
use tracer::pack::Packed;
use tracer::scene;

use crate::common::agreement::packed;

/// The Cornell box at `width` x `height` with the denoiser's guide (its sums must stay clean too).
fn cornell(width: u32, height: u32) -> Packed {
    let mut p = packed(&scene::cornell_box(), Strategy::Mis, width.max(height), 4);
    p.scene.width = width;
    p.scene.height = height;
    p.set_denoise_guide(true);
    p
}

const SIZE: (u32, u32) = (40, 28);
const SEED: u32 = 7;

/// `preview` renders a preview of `size` and returns its pixels.
fn assert_preview_is_the_small_first_frame_and_not_accumulated<R: Renderer>(
    make: impl Fn(Packed) -> R,
    preview: impl Fn(&mut R, u32, u32) -> Vec<Vec4>,
) {
    let (width, height) = SIZE;
    let (pw, ph) = preview_size(width, height);
    assert_eq!((pw, ph), (10, 7));

    let mut with_preview = make(cornell(width, height));
    let shown = preview(&mut with_preview, pw, ph);
    assert_eq!(shown.len(), (pw * ph) as usize);
    assert_eq!(with_preview.frames(), 0, "a preview is no frame of the accumulation");
    let mut small = make(cornell(pw, ph));
    small.render_frame().expect("frame");
    let first = small.accumulation().expect("accumulation");
    assert!(shown.iter().any(|p| p.truncate().max_element() > 0.0), "the preview shows light");
    assert_eq!(shown, first, "the preview is the first frame at its size");

    let mut without = make(cornell(width, height));
    for r in [&mut with_preview, &mut without] {
        for _ in 0..2 {
            r.render_frame().expect("frame");
        }
    }
    assert_eq!(with_preview.frames(), 2);
    let (a, b) = (with_preview.accumulation().expect("a"), without.accumulation().expect("b"));
    assert_eq!(a, b, "the accumulation after a preview is the one without");
    assert!(a.iter().all(|p| p.w == 2.0), "two samples per pixel, none more");
    let (ga, gb) = (with_preview.guide_sums().expect("guide a"), without.guide_sums().expect("guide b"));
    assert_eq!(ga, gb, "the guide's sums after a preview are the ones without");

    // Only before the first frame of an accumulation; after a restart, again.
    let preview_after_a_frame = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        preview(&mut with_preview, pw, ph);
    }));
    assert!(preview_after_a_frame.is_err(), "no preview over an accumulation in progress");
}

#[test]
fn a_gl_preview_is_the_first_frame_at_its_size_and_is_not_accumulated() {
    assert_preview_is_the_small_first_frame_and_not_accumulated(
        |p| GlRenderer::headless(p, SEED).unwrap_or_else(|e| panic!("the GL backend must run here: {e}")),
        |r, w, h| {
            r.render_preview(w, h).expect("preview");
            r.read_preview().expect("read the preview")
        },
    );
}

#[test]
fn a_wgpu_preview_is_the_first_frame_at_its_size_and_is_not_accumulated() {
    assert_preview_is_the_small_first_frame_and_not_accumulated(
        |p| WgpuRenderer::headless(p, SEED).unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}")),
        |r, w, h| {
            assert!(r.render_preview(w, h).expect("preview").is_some(), "the megakernel renders previews");
            r.read_preview().expect("read the preview")
        },
    );
}
