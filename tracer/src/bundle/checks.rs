//! Cross-field checks on a decoded bundle: what the format alone cannot tell (index bounds are
//! `bounds`').

use super::{bounds, BundleError, MAX_DEPTH};
use crate::kernel::features::Features;
use crate::kernel::scene_data::{Scene, LIGHT_TEXELS, TRIANGLE_TEXELS};
use crate::pack::{sky, Packed};

/// Cross-field checks: what the format alone cannot tell, and what would make a renderer
/// misbehave (an image size it cannot allocate, counts that disagree with the arrays).
pub(super) fn check_consistency(p: &Packed) -> Result<(), BundleError> {
    let s = &p.scene;
    let fail = |what: String| Err(BundleError::Inconsistent(what));
    check_uniforms(s)?;
    let stack = crate::kernel::traverse::STACK_SIZE as u32;
    if s.leaf_stack_limit > stack {
        return fail(format!("leaf_stack_limit {} is above the traversal stack ({stack})", s.leaf_stack_limit));
    }
    // A GPU variant's stack is `traversal_stack` entries: the limit must keep pushes within it.
    let sized = p.features.traversal_stack;
    if sized > stack || (sized > 0 && s.leaf_stack_limit > sized) {
        return fail(format!(
            "traversal_stack {sized} with leaf_stack_limit {} (the stack is at most {stack} entries and holds the limit)",
            s.leaf_stack_limit
        ));
    }
    if Some(s.triangles.len()) != p.triangle_count.checked_mul(TRIANGLE_TEXELS as usize) {
        return fail(format!("{} triangle texels for {} triangles", s.triangles.len(), p.triangle_count));
    }
    if s.light_count as usize != p.light_count
        || Some(s.lights.len()) != p.light_count.checked_mul(LIGHT_TEXELS as usize)
    {
        return fail(format!("{} light texels, light count {} / {}", s.lights.len(), s.light_count, p.light_count));
    }
    let f = &p.features;
    if let Some((uniform, feature, flag)) = f.kernel_flag_mismatches(s).first() {
        return fail(format!("the features say {feature} but the kernel flag {uniform} is {flag}"));
    }
    // Normal maps' tangents extend `shading` at the offset the uniform gives; a reader trusting
    // a wrong offset would fetch beyond the array.
    if f.normal_map {
        let first = s.tangent_first as usize;
        // Where the tangents end (the second UV set, or the array's end) is `check_texture_refs`'s.
        if Some(first) != p.triangle_count.checked_mul(crate::kernel::scene_data::SHADING_TEXELS as usize) {
            return fail(format!(
                "normal maps: tangents from {} in {} shading texels, {} triangles",
                s.tangent_first,
                s.shading.len(),
                p.triangle_count
            ));
        }
    }
    check_material_sections(s, f)?;
    if f.sky {
        // A sky file's rows were computed from it on reading (`super::sky`): only rows that
        // travelled as data can disagree with their CDFs.
        check_sky(s, p.sky_file.is_none())?;
    }
    bounds::check_indices(p)?;
    check_texture_images(p)
}

/// The sky's texels and rows are sized for its width and height, and (with `check_guides`) the
/// rows' guide tables (`pack::sky`) are those of its CDFs: a guide that disagrees would have the
/// kernel's search return another texel than the CDFs say (never one out of range: it reads
/// within the rows).
fn check_sky(s: &Scene, check_guides: bool) -> Result<(), BundleError> {
    let (w, h) = (s.sky_width as usize, s.sky_height as usize);
    if w == 0 || h == 0 {
        return Err(BundleError::Inconsistent(format!("sky {w}x{h} has no texels")));
    }
    if s.sky.len() as u64 != s.sky_width as u64 * s.sky_height as u64 || s.sky_rows.len() != sky::rows_len(w, h) {
        return Err(BundleError::Inconsistent(format!(
            "sky {}x{} with {} texels and {} rows (the marginal CDF and guide tables need {})",
            s.sky_width,
            s.sky_height,
            s.sky.len(),
            s.sky_rows.len(),
            sky::rows_len(w, h)
        )));
    }
    if !check_guides {
        return Ok(());
    }
    let rows = s.sky_rows.as_slice();
    let expected = sky::rows_with_guides(s.sky.as_slice(), &rows[..h], w, h);
    if expected.iter().zip(rows).any(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits)) {
        return Err(BundleError::Inconsistent("the sky's guide tables do not match its CDFs".to_string()));
    }
    Ok(())
}

/// The image size and the uniforms the kernel takes as they are.
fn check_uniforms(s: &Scene) -> Result<(), BundleError> {
    let fail = |what: String| Err(BundleError::Inconsistent(what));
    if !(1..=16384).contains(&s.width) || !(1..=16384).contains(&s.height) {
        return fail(format!("image size {}x{} (each side must be 1..=16384)", s.width, s.height));
    }
    // Uniforms the kernel takes as they are: a NaN scale or camera, an unbounded depth or an
    // unknown strategy would make every sample NaN, or a frame never end (found by fuzzing).
    let vectors = [
        ("camera_position", s.camera_position),
        ("camera_right", s.camera_right),
        ("camera_up", s.camera_up),
        ("camera_forward", s.camera_forward),
    ];
    if let Some((name, v)) = vectors.iter().find(|(_, v)| !v.is_finite()) {
        return fail(format!("{name} {v} is not finite"));
    }
    let scalars = [
        ("lens_radius", s.lens_radius, 0.0),
        ("focus_distance", s.focus_distance, f32::MIN_POSITIVE),
        ("sky_intensity", s.sky_intensity, 0.0),
        ("sky_rotation", s.sky_rotation, f32::MIN),
        ("scene_scale", s.scene_scale, 0.0),
    ];
    if let Some((name, v, min)) = scalars.iter().find(|(_, v, min)| !(v.is_finite() && v >= min)) {
        return fail(format!("{name} is {v} (must be finite and at least {min})"));
    }
    if !(1..=MAX_DEPTH).contains(&s.max_depth) {
        return fail(format!("max_depth {} (must be 1..={MAX_DEPTH})", s.max_depth));
    }
    if s.strategy > crate::kernel::scene_data::STRATEGY_MIS {
        return fail(format!("strategy {} (0, 1 or 2)", s.strategy));
    }
    Ok(())
}

/// `materials` holds the base texels of `n` materials (`MATERIAL_TEXELS` each), then with
/// normal maps one texel each from `normal_map_first`, then with alpha masks one texel each
/// from `alpha_mask_first`, then with glass `GLASS_TEXELS` each from `transmission_first`, and
/// nothing else: the offsets the uniforms give must be those.
fn check_material_sections(s: &Scene, f: &Features) -> Result<(), BundleError> {
    use crate::kernel::scene_data::{GLASS_TEXELS, MATERIAL_TEXELS};
    let glass = if f.transmission { GLASS_TEXELS as usize } else { 0 };
    let per = MATERIAL_TEXELS as usize + f.normal_map as usize + f.alpha_mask as usize + glass;
    let n = s.materials.len() / per;
    let maps = if f.normal_map { MATERIAL_TEXELS as usize * n } else { 0 };
    let masks = if f.alpha_mask { (MATERIAL_TEXELS as usize + f.normal_map as usize) * n } else { 0 };
    let glass_first = if f.transmission { (per - glass) * n } else { 0 };
    if !s.materials.len().is_multiple_of(per)
        || s.normal_map_first as usize != maps
        || s.alpha_mask_first as usize != masks
        || s.transmission_first as usize != glass_first
        || (f.transmission && !f.metal_rough)
        || (f.volume && !f.transmission)
    {
        return Err(BundleError::Inconsistent(format!(
            "{} material texels (normal maps {}, alpha masks {}, glass {}) with normal maps from {}, alpha masks \
             from {} and glass from {} (metal-roughness {}, volume {})",
            s.materials.len(),
            f.normal_map,
            f.alpha_mask,
            f.transmission,
            s.normal_map_first,
            s.alpha_mask_first,
            s.transmission_first,
            f.metal_rough,
            f.volume
        )));
    }
    Ok(())
}

/// The textures' images are the textures `texture_info` describes: each entry (a texture, or
/// with texture references a reference to one) is where one image lies in the atlas, at its size.
fn check_texture_images(p: &Packed) -> Result<(), BundleError> {
    let images = &p.texture_images;
    if images.is_empty() {
        return Ok(());
    }
    let fail = |what: String| Err(BundleError::Inconsistent(what));
    let count = bounds::texture_count(&p.scene);
    let references = p.scene.has_texture_transform != 0 || p.scene.has_texcoord1 != 0;
    if !p.features.textures || (!references && images.len() != count) {
        return fail(format!(
            "{} texture images for {count} textures (textures: {})",
            images.len(),
            p.features.textures
        ));
    }
    // Where each image lies: the atlas is the images one after another, each from an element.
    let per = crate::kernel::scene_data::TEXTURE_TEXELS_PER_ELEMENT;
    let mut first = 0u32;
    let layout: Vec<(u32, u32, u32)> = images
        .iter()
        .map(|image| {
            let at = (first, image.width, image.height);
            first += (image.width * image.height).div_ceil(per) * per;
            at
        })
        .collect();
    for (i, info) in p.scene.texture_info.as_slice().iter().take(count).enumerate() {
        let entry = (info.x, info.y, info.z);
        let matches = if references { layout.contains(&entry) } else { layout[i] == entry };
        if !matches {
            return fail(format!(
                "texture {i} is {} x {} from texel {}, where no image of the bundle lies",
                info.y, info.z, info.x
            ));
        }
    }
    Ok(())
}
