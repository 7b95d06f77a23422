//! Which triangles of alpha-masked materials the kernel must alpha-test. A triangle whose
//! texture footprint is opaque throughout never has a hole: its mask flag is left clear, so
//! traversal treats it as any opaque triangle and the hole test runs only where holes can be
//! (issue #31: masks cost only where they are). The image is the same bit for bit: the test the
//! kernel skips would have said "opaque" at every point of the triangle.

// `!(x >= threshold)` on purpose: a NaN alpha or cutoff counts as a possible hole.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use rayon::prelude::*;

use crate::kernel::textures::wrap_coordinate;
use crate::scene::{Material, Texture, Triangle, UvTransform};

/// The most texels one triangle's footprint is checked over; a larger triangle keeps its test
/// (checking it would cost more than it can save).
const MAX_FOOTPRINT_TEXELS: i64 = 1 << 16;

/// Margin on the cutoff: the kernel's bilinear blend of texels at or above the cutoff can
/// round a few ulp below it.
const CUTOFF_MARGIN: f32 = 1.0e-5;

/// Per triangle (in `triangles`' order), whether its material is masked (`masked_material`)
/// and some point of it may be a hole, i.e. whether the kernel must alpha-test it.
pub(super) fn needs_alpha_test(
    triangles: &[&Triangle],
    materials: &[Material],
    textures: &[Texture],
    masked_material: &[bool],
) -> Vec<bool> {
    triangles
        .par_iter()
        .map(|t| {
            let material = t.material as usize;
            masked_material.get(material).copied().unwrap_or(false)
                && materials.get(material).is_none_or(|m| may_have_holes(t, m, textures))
        })
        .collect()
}

/// Whether the kernel's `alpha_mask::is_hole` may answer true somewhere on `t`: false only when
/// every texel its bilinear lookups can read (over the bounding box of its texture coordinates,
/// a texel wider on each side for rounding) gives a coverage above the cutoff.
fn may_have_holes(t: &Triangle, m: &Material, textures: &[Texture]) -> bool {
    let Some(cutoff) = m.alpha_cutoff else { return false };
    let threshold = cutoff * (1.0 + CUTOFF_MARGIN) + f32::MIN_POSITIVE;
    let Some(texture) = m.base_color_texture.and_then(|i| textures.get(i as usize)) else {
        // No texture: the coverage is the factor's alpha, the same everywhere.
        return !(m.alpha >= threshold);
    };
    // A transformed texture or one read on TEXCOORD_1 keeps its test (not worth the cases).
    if m.texture_uvs[0] != UvTransform::default() || !(m.alpha >= threshold) {
        return true;
    }
    let (width, height) = (texture.width as i32, texture.height as i32);
    let range = |coordinate: fn(&glam::Vec2) -> f32, size: i32| {
        let texel = t.uvs.map(|uv| coordinate(&uv) * size as f32 - 0.5);
        let (lo, hi) = (
            texel.iter().copied().fold(f32::INFINITY, f32::min),
            texel.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        );
        // The lookup reads floor(x) and floor(x) + 1; one more texel each side for rounding.
        (lo.is_finite() && hi.is_finite() && hi - lo < 1.0e6).then(|| (lo.floor() as i64 - 1, hi.floor() as i64 + 2))
    };
    let (Some((x0, x1)), Some((y0, y1))) = (range(|uv| uv.x, width), range(|uv| uv.y, height)) else {
        return true;
    };
    if (x1 - x0 + 1) * (y1 - y0 + 1) > MAX_FOOTPRINT_TEXELS {
        return true;
    }
    let (wrap_s, wrap_t) = (super::textures::wrap_code(texture.wrap_s), super::textures::wrap_code(texture.wrap_t));
    for y in y0..=y1 {
        let row = wrap_coordinate(y as i32, height, wrap_t) * width;
        for x in x0..=x1 {
            let index = (row + wrap_coordinate(x as i32, width, wrap_s)) as usize;
            let Some(&word) = texture.texels.get(index) else { return true };
            let alpha = (word >> 24) as f32 / 255.0;
            if !(m.alpha * alpha >= threshold) {
                return true;
            }
        }
    }
    false
}
