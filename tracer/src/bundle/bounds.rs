//! Decode-time bounds of every index the kernel follows, so that no decoded bundle can make it
//! read out of range, overflow an index computation (a panic in debug builds of the CPU
//! backend, a wrapped read on a GPU) or loop. Found by fuzzing: a texture whose first texel
//! was near 2^32 overflowed `texel_word`'s index, and node children pointing back at the root
//! made traversal endless.
//!
//! The kernel's own arithmetic stays unchecked (it runs per ray); what it relies on is checked
//! here once: child nodes come after their parent and each has one parent (traversal visits
//! every node at most once per ray), leaves are disjoint, leaves, materials, lights and textures lie within their
//! arrays, float-stored indices are exact (-1 or an integer in range), texture sizes keep the
//! texel arithmetic within `i32`/`u32`.

use super::BundleError;
use crate::kernel::instances::INSTANCE_TEXELS;
use crate::kernel::scene_data::{
    Scene, GLASS_TEXELS, LIGHT_SKY, LIGHT_TEXELS, LIGHT_TRIANGLE, MATERIAL_TEXELS, NODE_TEXELS, SHADING_TEXELS,
    TEXTURE_TEXELS_PER_ELEMENT, TRIANGLE_TEXELS, WRAP_MIRROR,
};
use crate::pack::Packed;

fn fail<T>(what: String) -> Result<T, BundleError> {
    Err(BundleError::Inconsistent(what))
}

/// A float-stored index as the kernel reads it (`index_of`): `Some(None)` for -1 (none),
/// `Some(Some(i))` for an integer below `count`, `None` for anything else (a fraction, NaN,
/// another negative, out of range).
fn float_index(x: f32, count: usize) -> Option<Option<usize>> {
    if x == -1.0 {
        Some(None)
    } else if x >= 0.0 && x.fract() == 0.0 && (x as usize) < count {
        Some(Some(x as usize))
    } else {
        None
    }
}

/// Every index check; the array lengths of `Packed`'s counts are checked before (see
/// `check_consistency`).
pub(super) fn check_indices(p: &Packed) -> Result<(), BundleError> {
    let s = &p.scene;
    if s.has_instances != 0 {
        check_two_level_nodes(s, p.triangle_count)?;
    } else {
        check_nodes(s, p.triangle_count)?;
    }
    let textures = check_textures(s)?;
    let materials = check_materials(s, textures)?;
    check_triangles(s, p.triangle_count, materials, p.light_count)?;
    check_lights(s, p.triangle_count, p.light_count)?;
    if s.has_sky != 0 && (s.sky_width == 0 || s.sky_height == 0) {
        return fail(format!("sky {}x{} has no texels", s.sky_width, s.sky_height));
    }
    Ok(())
}

/// The BVH is a tree in the order the kernel walks it: node 0 the root, every other node the
/// child of exactly one node before it (so traversal visits each at most once per ray); a child
/// entry 0 is an unused slot (the root is nobody's child; traversal skips it); leaves name
/// triangles that exist, each triangle in one leaf at most.
fn check_nodes(s: &Scene, triangle_count: usize) -> Result<(), BundleError> {
    let count = s.node_children.len();
    if count == 0 || Some(s.nodes.len()) != count.checked_mul(NODE_TEXELS as usize) {
        return fail(format!("{} node plane texels for {count} nodes (at least the root)", s.nodes.len()));
    }
    check_tree(s, &|_| (triangle_count, true))
}

/// The node tree's structure (see [`check_nodes`]), with `leaf_items(node)` the number of
/// items a leaf of `node` may name, and whether they are triangles (each in one leaf at most)
/// or a two-level scene's top-level placements.
fn check_tree(s: &Scene, leaf_items: &dyn Fn(usize) -> (usize, bool)) -> Result<(), BundleError> {
    let count = s.node_children.len();
    let mut has_parent = vec![false; count];
    let mut leaves = Vec::new();
    for (i, children) in s.node_children.as_slice().iter().enumerate() {
        let (triangle_count, triangles) = leaf_items(i);
        for (slot, entry) in children.to_array().into_iter().enumerate() {
            let (first, leaf) = ((entry >> 8) as usize, (entry & 255) as usize);
            if leaf > 0 {
                if first + leaf > triangle_count {
                    return fail(format!(
                        "node {i} slot {slot}: a leaf of triangles {first}..{} of {triangle_count}",
                        first + leaf
                    ));
                }
                if triangles {
                    leaves.push((first, first + leaf));
                }
            } else if first != 0 {
                if first <= i || first >= count {
                    return fail(format!(
                        "node {i} slot {slot}: child node {first} (children come after their parent, of {count} nodes)"
                    ));
                }
                if std::mem::replace(&mut has_parent[first], true) {
                    return fail(format!("node {first} is the child of two nodes"));
                }
            }
        }
    }
    // Leaves do not share triangles (a ray then tests each triangle at most once).
    leaves.sort_unstable();
    if let Some(w) = leaves.windows(2).find(|w| w[1].0 < w[0].1) {
        return fail(format!("leaves of triangles {}..{} and {}..{} overlap", w[0].0, w[0].1, w[1].0, w[1].1));
    }
    Ok(())
}

/// A two-level scene (`kernel::instances`): the nodes' planes then the placements' texels in
/// `nodes`; the top level (the nodes reachable from the root) has leaves of placements, every
/// other node leaves of triangles; each placement's root is a node outside the top level (so
/// that a placement's traversal never reaches top-level leaves), its transforms are finite, its
/// handedness ±1 and its identity flag 0 or 1.
fn check_two_level_nodes(s: &Scene, triangle_count: usize) -> Result<(), BundleError> {
    let count = s.node_children.len();
    let first = s.instance_first as usize;
    let texels = s.nodes.len();
    if count == 0 || Some(first) != count.checked_mul(NODE_TEXELS as usize) || texels < first {
        return fail(format!("{texels} node texels, placements from {first}, for {count} nodes"));
    }
    let placements = (texels - first) / INSTANCE_TEXELS as usize;
    if placements == 0 || !(texels - first).is_multiple_of(INSTANCE_TEXELS as usize) {
        return fail(format!("{} placement texels: not a whole number of placements", texels - first));
    }
    // The top level: node 0 and the child nodes below it (children come after their parent,
    // which `check_tree` checks, so one pass in order finds them).
    let mut top = vec![false; count];
    top[0] = true;
    for (i, children) in s.node_children.as_slice().iter().enumerate() {
        if top[i] {
            for entry in children.to_array() {
                let (child, leaf) = ((entry >> 8) as usize, entry & 255);
                if leaf == 0 && child != 0 && child < count {
                    top[child] = true;
                }
            }
        }
    }
    check_tree(s, &|node| if top[node] { (placements, false) } else { (triangle_count, true) })?;
    for (p, texel) in s.nodes.as_slice()[first..].chunks_exact(INSTANCE_TEXELS as usize).enumerate() {
        let info = texel[INSTANCE_TEXELS as usize - 1];
        let root = float_index(info.x, count).flatten();
        if root.is_none_or(|r| top[r]) {
            return fail(format!("placement {p}: root node {} (of {count}, outside the top level)", info.x));
        }
        if !texel.iter().all(|t| t.is_finite()) || info.y.abs() != 1.0 || !(info.z == 0.0 || info.z == 1.0) {
            return fail(format!("placement {p}: transform or flags not valid ({texel:?})"));
        }
    }
    Ok(())
}

/// Each texture lies within `texture_texels`, at least 1 x 1, with known wrap modes. Returns
/// the texture count.
fn check_textures(s: &Scene) -> Result<usize, BundleError> {
    let texels = s.texture_texels.len() as u64 * TEXTURE_TEXELS_PER_ELEMENT as u64;
    let count = texture_count(s);
    for (i, info) in s.texture_info.as_slice().iter().take(count).enumerate() {
        let (first, w, h, wrap) = (info.x as u64, info.y as u64, info.z as u64, info.w);
        if w == 0 || h == 0 || first + w * h > texels {
            return fail(format!("texture {i}: {w} x {h} texels from texel {first}, of {texels}"));
        }
        if wrap & 255 > WRAP_MIRROR || wrap >> 8 > WRAP_MIRROR {
            return fail(format!("texture {i}: wrap modes {wrap:#x}"));
        }
    }
    Ok(count)
}

/// How many textures `texture_info` describes: with texture references, their transform
/// texels follow the textures (`check_texture_refs`).
pub(super) fn texture_count(s: &Scene) -> usize {
    if has_texture_refs(s) {
        (s.texture_ref_first as usize).min(s.texture_info.len())
    } else {
        s.texture_info.len()
    }
}

fn has_texture_refs(s: &Scene) -> bool {
    s.has_texture_transform != 0 || s.has_texcoord1 != 0
}

/// The layout `kernel::texture_ref` reads, at the offsets the uniforms give: with texture
/// transforms or a second UV set, `TEXTURE_REF_TEXELS` per texture after the textures in
/// `texture_info`; `shading` is the per-triangle texels, then the tangents (normal maps), then
/// the second UV set, each where `tangent_first` / `texcoord1_first` say. (Any bits are a
/// usable matrix: a NaN UV samples as the kernel's bilinear lookup bounds it.)
pub(super) fn check_texture_refs(s: &Scene, triangle_count: usize) -> Result<(), String> {
    use crate::kernel::normal_map::TANGENT_TEXELS;
    use crate::kernel::texture_ref::{TEXCOORD1_TEXELS, TEXTURE_REF_TEXELS};
    if has_texture_refs(s) {
        let first = s.texture_ref_first as usize;
        if first.checked_mul(1 + TEXTURE_REF_TEXELS as usize) != Some(s.texture_info.len()) {
            return Err(format!("texture references from {first} in {} texture_info texels", s.texture_info.len()));
        }
    }
    if s.has_shading == 0 {
        return Ok(());
    }
    let per_triangle = |texels: u32, on: bool| if on { triangle_count.checked_mul(texels as usize) } else { Some(0) };
    let base = per_triangle(SHADING_TEXELS, true);
    let tangents = per_triangle(TANGENT_TEXELS, s.has_normal_map != 0);
    let uv1 = per_triangle(TEXCOORD1_TEXELS, s.has_texcoord1 != 0);
    let uv1_first = base.zip(tangents).and_then(|(b, t)| b.checked_add(t));
    let total = uv1_first.zip(uv1).and_then(|(f, u)| f.checked_add(u));
    let uv1_ok = s.has_texcoord1 == 0 || uv1_first == Some(s.texcoord1_first as usize);
    if total != Some(s.shading.len()) || !uv1_ok {
        return Err(format!(
            "{} shading texels for {triangle_count} triangles (tangents from {}, second UV set from {})",
            s.shading.len(),
            s.tangent_first,
            s.texcoord1_first
        ));
    }
    Ok(())
}

/// Materials are whole and name textures that exist (metal-roughness, normal maps and alpha
/// masks too, when used). Returns the material count.
fn check_materials(s: &Scene, textures: usize) -> Result<usize, BundleError> {
    let per = MATERIAL_TEXELS as usize;
    // Normal maps and alpha masks, one texel per material each, follow the materials (from
    // `normal_map_first` and `alpha_mask_first`, which `check_material_sections` has checked
    // against the array length: each section holds exactly one texel per material).
    let glass = if s.has_transmission != 0 { GLASS_TEXELS as usize } else { 0 };
    let extra = (s.has_normal_map != 0) as usize + (s.has_alpha_mask != 0) as usize + glass;
    let count = s.materials.len() / (per + extra);
    let all = s.materials.as_slice();
    let section =
        |on: u32, first: u32| if on != 0 { all.get(first as usize..first as usize + count) } else { Some(&[][..]) };
    let (Some(materials), Some(normal_maps), Some(masks)) = (
        all.get(..per * count),
        section(s.has_normal_map, s.normal_map_first),
        section(s.has_alpha_mask, s.alpha_mask_first),
    ) else {
        return fail(format!("{} material texels for {count} materials", all.len()));
    };
    if let Some(i) = normal_maps.iter().position(|t| float_index(t.x, textures).is_none()) {
        return fail(format!("material {i}: normal-map texture {} of {textures}", normal_maps[i].x));
    }
    if let Some(i) = masks.iter().position(|t| float_index(t.x, textures).is_none()) {
        return fail(format!("material {i}: alpha-mask texture {} of {textures}", masks[i].x));
    }
    if s.has_transmission != 0 {
        let first = s.transmission_first as usize;
        let Some(glass) = all.get(first..first + glass * count) else {
            return fail(format!("{} material texels for {count} glass materials", all.len()));
        };
        for (i, g) in glass.chunks_exact(GLASS_TEXELS as usize).enumerate() {
            if float_index(g[0].z, textures).is_none() {
                return fail(format!("material {i}: transmission texture {} of {textures}", g[0].z));
            }
        }
    }
    for (i, m) in materials.chunks_exact(per).enumerate() {
        if float_index(m[0].w, textures).is_none() || float_index(m[1].w, textures).is_none() {
            return fail(format!("material {i}: texture {} / {} of {textures}", m[0].w, m[1].w));
        }
    }
    if s.has_metal_rough != 0 {
        if s.metal_rough.len() != count {
            return fail(format!("{} metal-roughness texels for {count} materials", s.metal_rough.len()));
        }
        if let Some(i) = s.metal_rough.as_slice().iter().position(|t| float_index(t.z, textures).is_none()) {
            return fail(format!(
                "material {i}: metal-roughness texture {} of {textures}",
                s.metal_rough.as_slice()[i].z
            ));
        }
    }
    Ok(count)
}

/// Triangles use a material that exists and name a light that exists (or none); their shading
/// texels are all there when the kernel reads them.
fn check_triangles(s: &Scene, triangle_count: usize, materials: usize, lights: usize) -> Result<(), BundleError> {
    for (i, t) in s.triangles.as_slice().chunks_exact(TRIANGLE_TEXELS as usize).enumerate() {
        if !matches!(float_index(t[0].w, materials), Some(Some(_))) {
            return fail(format!("triangle {i}: material {} of {materials}", t[0].w));
        }
        if float_index(t[1].w, lights).is_none() {
            return fail(format!("triangle {i}: light {} of {lights}", t[1].w));
        }
        // The alpha-mask flag: 0, or 1 where the kernel alpha-tests (only with the feature).
        if !(t[2].w == 0.0 || (t[2].w == 1.0 && s.has_alpha_mask != 0)) {
            return fail(format!("triangle {i}: alpha-mask flag {}", t[2].w));
        }
    }
    // With normal maps, tangents follow the shading texels from `tangent_first` (checked with
    // the array length by `check_consistency`).
    // The shading texels, tangents and second UV set lie where the uniforms say.
    check_texture_refs(s, triangle_count).map_err(BundleError::Inconsistent)?;
    Ok(())
}

/// Lights: alias entries within the table, known kinds, triangle lights on triangles that
/// exist; with a sky, the sky is the last light (the kernel's MIS weight looks it up there).
fn check_lights(s: &Scene, triangle_count: usize, lights: usize) -> Result<(), BundleError> {
    for (i, l) in s.lights.as_slice().chunks_exact(LIGHT_TEXELS as usize).enumerate() {
        let (alias, kind) = (float_index(l[0].y, lights), float_index(l[0].w, LIGHT_SKY as usize + 1));
        let (Some(Some(_)), Some(Some(kind))) = (alias, kind) else {
            return fail(format!("light {i}: alias {} of {lights}, kind {}", l[0].y, l[0].w));
        };
        if kind == LIGHT_TRIANGLE as usize && !matches!(float_index(l[1].x, triangle_count), Some(Some(_))) {
            return fail(format!("light {i}: triangle {} of {triangle_count}", l[1].x));
        }
    }
    let last_kind = s.lights.as_slice().chunks_exact(LIGHT_TEXELS as usize).last().map(|l| l[0].w);
    if s.has_sky != 0 && last_kind != Some(LIGHT_SKY as f32) {
        return fail(format!("a sky, but the last of the {lights} lights is not the sky"));
    }
    Ok(())
}
