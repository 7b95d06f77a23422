//! Packing: a loaded scene and its BVH become the texel arrays and uniforms the kernel reads
//! (`kernel::scene_data::Scene`), plus the [`Features`] the scene uses. The same packed data
//! feeds every backend: the CPU reads the arrays directly, GPUs upload them as textures.
//!
//! Nothing is packed that the scene does not use: no sky means no sky arrays, no textures
//! means no texture atlas (and no per-vertex UVs), flat geometry means no shading normals.

use glam::{UVec4, Vec3, Vec4};
use kernel_dsl::Texels;
use rayon::prelude::*;

use crate::bvh::Bvh;
use crate::kernel::lights::luminance;
use crate::kernel::normal_map::TANGENT_TEXELS;
use crate::kernel::scene_data::{
    self, Scene as KernelScene, LIGHT_POINT, LIGHT_SKY, LIGHT_TEXELS, LIGHT_TRIANGLE, MATERIAL_TEXELS, NODE_TEXELS,
    SHADING_TEXELS, TEXTURE_TEXELS_PER_ELEMENT, TRIANGLE_TEXELS,
};
use crate::kernel::texture_ref::TEXCOORD1_TEXELS;
use crate::scene::{Scene, Wrap};

mod texture_refs;
pub use texture_refs::TextureRefs;

// `Features`, `RenderSettings` and `Strategy` live in the kernel (`kernel::features`); re-exported
// here, where the scene's features are decided, for the callers that pack scenes.
pub use crate::kernel::features::{Features, RenderSettings, Strategy};

/// Used and allocated texels of one packed array once laid out as a 2D texture.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayStats {
    pub name: &'static str,
    pub texels: usize,
    pub width: u32,
    pub height: u32,
    /// Bytes per texel (16 for RGBA32F / RGBA32UI).
    pub texel_bytes: usize,
}

impl ArrayStats {
    pub fn allocated(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// The packed scene.
#[derive(Clone, Debug)]
pub struct Packed {
    pub scene: KernelScene,
    pub features: Features,
    pub triangle_count: usize,
    pub light_count: usize,
}

/// Why a scene cannot be packed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PackError {
    #[error(
        "the scene has {0} triangles; the packed layout stores indices as exact floats, so at most 16,777,216 fit"
    )]
    TooManyTriangles(usize),
    #[error("the BVH references triangle {0}, which the scene does not have")]
    BadBvh(u32),
    #[error("{what} needs {texels} texels, more than a {max}x{max} texture holds")]
    TooLarge { what: &'static str, texels: usize, max: u32 },
    #[error("the BVH needs a traversal stack of {needed} entries; the kernel's holds {max}")]
    BvhTooDeep { needed: u32, max: u32 },
    #[error(transparent)]
    Bvh(crate::bvh::BvhError),
    #[error("the image size {width}x{height} is invalid (each side 1..=16384)")]
    BadSize { width: u32, height: u32 },
    #[error("a BVH leaf holds {triangles} triangles; the kernel's traversal takes at most {max}")]
    LeafTooLarge { triangles: u32, max: u32 },
    #[error("the packed textures were made from another scene (they do not match this scene's textures)")]
    TexturesMismatch,
}

/// Largest integer stored exactly in an f32 texel.
const MAX_EXACT: usize = 1 << 24;

/// Lays out `texels` as a 2D texture of power-of-two width no larger than `max_size`:
/// the narrowest power of two that keeps the height within `max_size` and near-square.
pub fn texture_shape(texels: usize, max_size: u32) -> Option<(u32, u32)> {
    let texels = texels.max(1);
    let mut width = 1u32;
    while (width as usize) * (width as usize) < texels && width < max_size {
        width *= 2;
    }
    let height = texels.div_ceil(width as usize);
    (height <= max_size as usize).then_some((width, height as u32))
}

fn index_value(i: Option<u32>) -> f32 {
    i.map_or(-1.0, |i| i as f32)
}

fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => scene_data::WRAP_REPEAT,
        Wrap::ClampToEdge => scene_data::WRAP_CLAMP,
        Wrap::MirroredRepeat => scene_data::WRAP_MIRROR,
    }
}

/// Vose's alias method: (threshold, alias) per entry for sampling proportionally to `weights`.
fn alias_table(weights: &[f32]) -> Vec<(f32, u32)> {
    let n = weights.len();
    let total: f64 = weights.iter().map(|w| *w as f64).sum();
    let mut scaled: Vec<f64> = weights.iter().map(|w| *w as f64 * n as f64 / total).collect();
    let mut table = vec![(1.0f32, 0u32); n];
    for (i, t) in table.iter_mut().enumerate() {
        t.1 = i as u32;
    }
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
        table[s] = (scaled[s] as f32, l as u32);
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    table
}

/// The texture half of packing: the texel atlas and its per-texture table. It depends only on
/// the scene's textures and materials, so it is made once (in parallel with the BVH build, see
/// [`build_and_pack`]) and reused by [`pack_with_textures`] when the geometry or the settings
/// change. Cloning is cheap: the arrays are shared.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PackedTextures {
    /// Whether any material uses a texture (`Features::textures`); when not, nothing is packed.
    pub used: bool,
    /// The kernel's `texture_texels`: every texture's packed sRGBA8 texels, four per element,
    /// each texture starting on an element boundary.
    pub texels: Texels<UVec4>,
    /// The kernel's `texture_info`: `[first texel, width, height, wrap_s | wrap_t << 8]` per
    /// texture, or with [`PackedTextures::refs`] per reference and then their transforms.
    pub info: Texels<UVec4>,
    /// The texture references, when some texture is transformed or read on `TEXCOORD_1`.
    pub refs: Option<TextureRefs>,
    /// Mean linear luminance of each texture some material emits through (`None` for the
    /// others): the emitting triangles' power estimate for light selection.
    pub emissive_mean_luminance: Vec<Option<f32>>,
}

/// Packs the textures of `scene` (see [`PackedTextures`]). A loaded scene's textures already
/// lie in one atlas in the packed layout ([`crate::scene::TextureTexels`]): that atlas is
/// shared, not copied; other textures (made by hand, or a scene's textures changed after
/// loading) are copied into a new one.
pub fn pack_textures(scene: &Scene) -> PackedTextures {
    let textures = &scene.textures;
    let used = scene.materials.iter().any(|m| m.texture_slots().iter().any(Option::is_some)) && !textures.is_empty();
    let mut emissive_mean_luminance = vec![None; textures.len()];
    for m in &scene.materials {
        if let Some(i) = m.emissive_texture.filter(|i| (*i as usize) < textures.len()) {
            emissive_mean_luminance[i as usize].get_or_insert_with(|| textures[i as usize].texels.mean_luminance());
        }
    }
    if !used {
        return PackedTextures { emissive_mean_luminance, ..Default::default() };
    }
    let per = TEXTURE_TEXELS_PER_ELEMENT as usize;
    let mut info = Vec::with_capacity(textures.len());
    // Element ranges of each texture in the atlas.
    let mut ranges = Vec::with_capacity(textures.len());
    let mut elements = 0usize;
    for t in textures {
        info.push(UVec4::new(
            (elements * per) as u32,
            t.width,
            t.height,
            wrap_code(t.wrap_s) | wrap_code(t.wrap_t) << 8,
        ));
        let len = t.texels.len().div_ceil(per);
        ranges.push(elements..elements + len);
        elements += len;
    }
    // The atlas of the first texture is the packed one when every texture lies in it where
    // the packed layout puts it, and nothing else does.
    let atlas = textures[0].texels.atlas();
    let shared = atlas.len() == elements
        && textures.iter().zip(&ranges).all(|(t, range)| {
            std::ptr::eq(t.texels.atlas().as_slice(), atlas.as_slice()) && t.texels.first_element() == range.start
        });
    let texels = if shared {
        atlas.clone()
    } else {
        Texels::from_fill(elements, |atlas| {
            for (t, range) in textures.iter().zip(ranges) {
                let Some(out) = atlas.get_mut(range) else { continue };
                let words = t.texels.chunks_exact(per);
                let tail = words.remainder();
                for (element, four) in out.iter_mut().zip(words) {
                    *element = UVec4::new(four[0], four[1], four[2], four[3]);
                }
                if let Some(last) = out.get_mut(t.texels.len() / per).filter(|_| !tail.is_empty()) {
                    // A partial last element: the lanes past the texture stay zero.
                    let mut lanes = [0u32; 4];
                    lanes[..tail.len()].copy_from_slice(tail);
                    *last = UVec4::from_array(lanes);
                }
            }
        })
    };
    let refs = texture_refs::texture_refs(scene);
    let info = match &refs {
        Some(r) => r.texture_info(&info),
        None => info,
    };
    PackedTextures { used, texels, info: Texels::new(info), refs, emissive_mean_luminance }
}

/// Builds the BVH and packs `scene` for `settings`, packing the textures in parallel with the
/// BVH build (neither needs the other).
pub fn build_and_pack(scene: &Scene, settings: &RenderSettings) -> Result<(Bvh, Packed), BuildAndPackError> {
    let (bvh, textures) = rayon::join(|| crate::bvh::build(&scene.triangles), || pack_textures(scene));
    let bvh = bvh?;
    let packed = pack_with_textures(scene, &bvh, &textures, settings)?;
    Ok((bvh, packed))
}

/// Why [`build_and_pack`] failed.
#[derive(Debug, thiserror::Error)]
pub enum BuildAndPackError {
    #[error(transparent)]
    Bvh(#[from] crate::bvh::BvhError),
    #[error(transparent)]
    Pack(#[from] PackError),
}

/// Packs `scene` (with its BVH) for rendering with `settings`: [`pack_textures`], then
/// [`pack_with_textures`].
pub fn pack(scene: &Scene, bvh: &Bvh, settings: &RenderSettings) -> Result<Packed, PackError> {
    pack_with_textures(scene, bvh, &pack_textures(scene), settings)
}

/// Packs `scene` (with its BVH) for rendering with `settings`, taking its textures already
/// packed by [`pack_textures`] (shared, not copied).
pub fn pack_with_textures(
    scene: &Scene,
    bvh: &Bvh,
    textures: &PackedTextures,
    settings: &RenderSettings,
) -> Result<Packed, PackError> {
    let matches = textures.emissive_mean_luminance.len() == scene.textures.len()
        && if textures.used { texture_refs::matches(scene, textures) } else { textures.info.is_empty() };
    if !matches {
        return Err(PackError::TexturesMismatch);
    }
    let (width, height) = (settings.width, settings.height);
    if !(1..=16384).contains(&width) || !(1..=16384).contains(&height) {
        return Err(PackError::BadSize { width, height });
    }
    let tri_count = bvh.triangle_order.len();
    if tri_count >= MAX_EXACT || bvh.nodes.len() >= MAX_EXACT {
        return Err(PackError::TooManyTriangles(tri_count));
    }
    let wide = bvh.widen().map_err(PackError::Bvh)?;
    let max = crate::kernel::traverse::STACK_SIZE as u32;
    if wide.stack_needed > max {
        return Err(PackError::BvhTooDeep { needed: wide.stack_needed, max });
    }
    // Closest-hit traversal pushes leaves too while the stack has room for them: child nodes
    // alone never need more than `stack_needed` entries and leaves are pushed only below the
    // limit, so at most `limit + stack_needed` entries are ever held. A tree that fits with
    // every leaf pushed gets a stack of exactly its need (at least 1: `occluded` starts with
    // the root on it), and the limit never stops a push.
    let (traversal_stack, leaf_stack_limit) = if wide.stack_needed_with_leaves <= max {
        let need = wide.stack_needed_with_leaves.max(1);
        (need, need)
    } else {
        (max, max - wide.stack_needed)
    };
    // The traversal stack carries a leaf's triangle count in 8 bits.
    let max_leaf = crate::kernel::traverse::MAX_LEAF_TRIANGLES;
    if let Some(leaf) = bvh.nodes.iter().find(|n| n.count > max_leaf) {
        return Err(PackError::LeafTooLarge { triangles: leaf.count, max: max_leaf });
    }
    let ordered: Vec<&crate::scene::Triangle> = bvh
        .triangle_order
        .iter()
        .map(|&i| scene.triangles.get(i as usize).ok_or(PackError::BadBvh(i)))
        .collect::<Result<_, _>>()?;

    let textures_used = textures.used;
    // The passes over every triangle run in parallel (they read the triangles in BVH order,
    // scattered in memory).
    let smooth = ordered.par_iter().any(|t| {
        let face = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]).normalize_or_zero();
        t.normals.iter().any(|n| n.dot(face) < 0.9999)
    });
    let emissive_material: Vec<bool> = scene.materials.iter().map(|m| m.is_emissive()).collect();
    let emissive = |t: &crate::scene::Triangle| emissive_material.get(t.material as usize).copied().unwrap_or(false);
    // Indices in BVH order, ascending. Which triangles emit is read in scene order (a stream
    // through memory, not a gather), then permuted.
    let emissive_triangles: Vec<u32> = if emissive_material.contains(&true) {
        let emits: Vec<bool> = scene.triangles.par_iter().map(emissive).collect();
        (bvh.triangle_order.par_iter().with_min_len(1 << 12).enumerate())
            .filter(|(_, &t)| emits[t as usize])
            .map(|(i, _)| i as u32)
            .collect()
    } else {
        Vec::new()
    };
    // Which materials the kernel alpha-tests ([`crate::scene::Material::is_masked`]).
    let masked_material: Vec<bool> = scene.materials.iter().map(|m| m.is_masked(textures_used)).collect();
    let features = Features {
        sky: scene.sky.is_some(),
        textures: textures_used,
        shading: textures_used || smooth,
        point_lights: !scene.point_lights.is_empty(),
        emissive_triangles: !emissive_triangles.is_empty(),
        metal_rough: scene.materials.iter().any(|m| m.uses_metal_rough()),
        normal_map: textures_used && scene.materials.iter().any(|m| m.normal_texture.is_some()),
        alpha_mask: masked_material.contains(&true),
        texture_transform: textures_used && textures.refs.as_ref().is_some_and(|r| r.transform),
        texcoord1: textures_used && textures.refs.as_ref().is_some_and(|r| r.texcoord1),
        traversal_stack,
    };

    // Lights: emissive triangles, point lights, then the sky (the kernel expects it last).
    let bounds = scene.bounds();
    let radius = (0.5 * bounds.diagonal().length()).max(1e-6);
    let mut light_weights = Vec::new();
    let mut light_data: Vec<(u32, Vec4, Vec4)> = Vec::new();
    let texture_mean = &textures.emissive_mean_luminance;
    for &ti in &emissive_triangles {
        let t = ordered[ti as usize];
        let m = &scene.materials[t.material as usize];
        let texture_mean =
            m.emissive_texture.and_then(|i| texture_mean.get(i as usize).copied().flatten()).unwrap_or(1.0);
        // The same arithmetic as the kernel's for a hit triangle (`integrator`), so that both
        // MIS pdfs of a light use the same area.
        let face = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]);
        let area2 = face.length();
        let area = 0.5 * area2;
        let normal = if area2 > 0.0 { face / area2 } else { Vec3::ZERO };
        light_weights.push(luminance(m.emission) as f64 * texture_mean as f64 * area as f64 * std::f64::consts::PI);
        light_data.push((
            LIGHT_TRIANGLE,
            Vec4::new(ti as f32, normal.x, normal.y, normal.z),
            Vec4::new(area, 0.0, 0.0, 0.0),
        ));
    }
    for p in &scene.point_lights {
        light_weights.push(luminance(p.intensity) as f64 * 4.0 * std::f64::consts::PI);
        light_data.push((LIGHT_POINT, p.position.extend(0.0), p.intensity.extend(0.0)));
    }
    let mut sky_texels = Vec::new();
    let mut sky_rows = Vec::new();
    if let Some(sky) = &scene.sky {
        let (w, h) = (sky.width as usize, sky.height as usize);
        let mut row_sums = Vec::with_capacity(h);
        sky_texels.reserve(w * h);
        for y in 0..h {
            // Weight by sin(theta): texels near the poles cover less solid angle.
            let sin_theta = (std::f32::consts::PI * (y as f32 + 0.5) / h as f32).sin();
            let weights: Vec<f64> =
                (0..w).map(|x| (luminance(sky.texels[y * w + x]) * sin_theta).max(0.0) as f64).collect();
            let total: f64 = weights.iter().sum();
            let mut acc = 0.0f64;
            for (x, wt) in weights.iter().enumerate() {
                acc += if total > 0.0 { wt / total } else { 1.0 / w as f64 };
                let cdf = if x + 1 == w { 1.0 } else { acc as f32 };
                sky_texels.push(sky.texels[y * w + x].extend(cdf));
            }
            row_sums.push(total);
        }
        let total: f64 = row_sums.iter().sum();
        let mut acc = 0.0f64;
        for (y, s) in row_sums.iter().enumerate() {
            acc += if total > 0.0 { s / total } else { 1.0 / h as f64 };
            let cdf = if y + 1 == h { 1.0 } else { acc as f32 };
            sky_rows.push(Vec4::new(cdf, 0.0, 0.0, 0.0));
        }
        let mean_radiance = if total > 0.0 {
            // Mean of luminance * sin(theta) over the map, normalised by the mean of sin(theta) (2/π).
            (total / (w * h) as f64) as f32 / (2.0 / std::f32::consts::PI) * sky.intensity
        } else {
            0.0
        };
        light_weights
            .push(mean_radiance as f64 * std::f64::consts::PI * (radius as f64).powi(2) * std::f64::consts::PI);
        light_data.push((LIGHT_SKY, Vec4::ZERO, Vec4::ZERO));
    }
    // Every light keeps a share of the samples: with next event estimation only, a light that
    // is never chosen would be missing from the image. Weights are powers in f64: f32 radiances
    // up to the loaders' limit times areas cannot overflow it, so one huge light cannot turn the
    // mean (and every pmf) into inf/NaN.
    let mean_weight = light_weights.iter().sum::<f64>() / light_weights.len().max(1) as f64;
    let floor = if mean_weight > 0.0 && mean_weight.is_finite() { mean_weight * 1e-3 } else { 1.0 };
    let light_weights: Vec<f32> = light_weights
        .iter()
        .map(|w| {
            let w = if w.is_finite() { w.max(floor) } else { floor };
            // The shares are what the kernel reads; normalise in f64 before narrowing.
            w / mean_weight.max(floor)
        })
        .map(|w| w as f32)
        .collect();
    let total_weight: f32 = light_weights.iter().sum();
    let alias = alias_table(&light_weights);
    let mut lights = Vec::with_capacity(light_data.len() * LIGHT_TEXELS as usize);
    for (i, (kind, a, b)) in light_data.iter().enumerate() {
        let (threshold, alias_index) = alias[i];
        lights.push(Vec4::new(threshold, alias_index as f32, light_weights[i] / total_weight, *kind as f32));
        lights.push(*a);
        lights.push(*b);
    }

    // The large arrays are written straight into their shared allocations (no copy).
    // Emissive triangle `i`'s light is its position in `emissive_triangles` (they come first).
    let triangle_light = |i: usize, t: &crate::scene::Triangle| {
        if emissive(t) {
            emissive_triangles.binary_search(&(i as u32)).ok().map(|l| l as u32)
        } else {
            None
        }
    };
    let masked = |t: &crate::scene::Triangle| masked_material.get(t.material as usize).copied().unwrap_or(false);
    let triangles = Texels::par_from_groups::<{ TRIANGLE_TEXELS as usize }>(tri_count, |i| {
        let t = ordered[i];
        [
            t.positions[0].extend(t.material as f32),
            t.positions[1].extend(index_value(triangle_light(i, t))),
            t.positions[2].extend(if features.alpha_mask && masked(t) { 1.0 } else { 0.0 }),
        ]
    });
    let shading = if features.shading {
        let shading = Texels::par_from_groups::<{ SHADING_TEXELS as usize }>(tri_count, |i| {
            let t = ordered[i];
            [
                t.normals[0].extend(t.uvs[0].x),
                t.normals[1].extend(t.uvs[0].y),
                t.normals[2].extend(t.uvs[1].x),
                Vec4::new(t.uvs[1].y, t.uvs[2].x, t.uvs[2].y, 0.0),
            ]
        });
        // Tangents and the second UV set extend the shading array (`kernel::normal_map`,
        // `kernel::texture_ref`): no new binding.
        let tangents = features
            .normal_map
            .then(|| Texels::par_from_groups::<{ TANGENT_TEXELS as usize }>(tri_count, |i| ordered[i].tangents));
        let uvs1 = features.texcoord1.then(|| {
            Texels::par_from_groups::<{ TEXCOORD1_TEXELS as usize }>(tri_count, |i| {
                texture_refs::texcoord1_texels(&ordered[i].uvs1)
            })
        });
        if tangents.is_none() && uvs1.is_none() {
            shading
        } else {
            let parts = [Some(&shading), tangents.as_ref(), uvs1.as_ref()];
            Texels::new(parts.into_iter().flatten().flat_map(|t| t.as_slice().iter().copied()).collect())
        }
    } else {
        Texels::default()
    };
    let tangent_first = if features.normal_map { (tri_count * SHADING_TEXELS as usize) as u32 } else { 0 };
    let texcoord1_first = if features.texcoord1 {
        (tri_count * (SHADING_TEXELS + if features.normal_map { TANGENT_TEXELS } else { 0 }) as usize) as u32
    } else {
        0
    };
    let nodes = Texels::par_from_groups::<{ NODE_TEXELS as usize }>(wide.nodes.len(), |i| {
        let n = &wide.nodes[i];
        [
            Vec4::from_array(n.min.map(|c| c.x)),
            Vec4::from_array(n.max.map(|c| c.x)),
            Vec4::from_array(n.min.map(|c| c.y)),
            Vec4::from_array(n.max.map(|c| c.y)),
            Vec4::from_array(n.min.map(|c| c.z)),
            Vec4::from_array(n.max.map(|c| c.z)),
        ]
    });
    let node_children = Texels::par_from_groups::<1>(wide.nodes.len(), |i| {
        let n = &wide.nodes[i];
        [UVec4::from_array(std::array::from_fn(|c| crate::kernel::traverse::stack_entry(n.first[c], n.count[c])))]
    });
    let mut materials = Vec::with_capacity(scene.materials.len() * MATERIAL_TEXELS as usize);
    // A material slot's texture, or with texture references its reference.
    let texture_index = |material: usize, slot: usize, i: Option<u32>| match (&textures.refs, features.textures) {
        (_, false) => -1.0,
        (Some(refs), true) => index_value(refs.slots.get(material).and_then(|s| s[slot])),
        (None, true) => index_value(i),
    };
    for (i, m) in scene.materials.iter().enumerate() {
        materials.push(m.base_color.extend(texture_index(i, 0, m.base_color_texture)));
        materials.push(m.emission.extend(texture_index(i, 1, m.emissive_texture)));
    }
    let normal_map_first = if features.normal_map { materials.len() as u32 } else { 0 };
    if features.normal_map {
        for (i, m) in scene.materials.iter().enumerate() {
            materials.push(Vec4::new(texture_index(i, 3, m.normal_texture), m.normal_scale, 0.0, 0.0));
        }
    }
    let alpha_mask_first = if features.alpha_mask { materials.len() as u32 } else { 0 };
    if features.alpha_mask {
        for (i, m) in scene.materials.iter().enumerate() {
            let cutoff = m.alpha_cutoff.unwrap_or(0.0);
            // The base colour slot's texture (or reference: its UV set and transform).
            materials.push(Vec4::new(texture_index(i, 0, m.base_color_texture), m.alpha, cutoff, 0.0));
        }
    }
    let metal_rough = if features.metal_rough {
        let texels = scene.materials.iter().enumerate().map(|(i, m)| {
            let specular = if m.uses_metal_rough() { 1.0 } else { 0.0 };
            Vec4::new(m.metallic, m.roughness, texture_index(i, 2, m.metallic_roughness_texture), specular)
        });
        Texels::new(texels.collect())
    } else {
        Texels::default()
    };

    let cam = &scene.camera;
    let forward = (cam.target - cam.position).normalize_or(Vec3::NEG_Z);
    let tan_half = (0.5 * cam.yfov).tan();
    let aspect = width as f32 / height as f32;
    let right = forward.cross(cam.up).normalize_or(Vec3::X);
    let up = right.cross(forward).normalize_or(Vec3::Y);
    let scene_scale = bounds.min.abs().max(bounds.max.abs()).max_element();
    let sky = scene.sky.as_ref();
    let kernel_scene = KernelScene {
        triangles,
        shading,
        nodes,
        node_children,
        materials: Texels::new(materials),
        lights: Texels::new(lights),
        texture_texels: textures.texels.clone(),
        texture_info: textures.info.clone(),
        sky: Texels::new(sky_texels),
        sky_rows: Texels::new(sky_rows),
        metal_rough,
        tangent_first,
        normal_map_first,
        alpha_mask_first,
        texture_ref_first: textures.refs.as_ref().filter(|_| features.textures).map_or(0, |r| r.refs.len() as u32),
        texcoord1_first,
        camera_position: cam.position,
        camera_right: right * tan_half * aspect,
        camera_up: up * tan_half,
        camera_forward: forward,
        lens_radius: cam.aperture_radius,
        focus_distance: cam.focus_distance,
        width,
        height,
        frame_seed: 0,
        max_depth: settings.max_depth.max(1),
        strategy: settings.strategy.uniform_value(),
        light_count: light_data.len() as u32,
        sky_width: sky.map_or(0, |s| s.width),
        sky_height: sky.map_or(0, |s| s.height),
        sky_intensity: sky.map_or(0.0, |s| s.intensity),
        sky_rotation: sky.map_or(0.0, |s| s.rotation),
        scene_scale: if scene_scale.is_finite() { scene_scale } else { 1.0 },
        leaf_stack_limit,
        has_sky: features.sky as u32,
        has_textures: features.textures as u32,
        has_shading: features.shading as u32,
        has_lights: features.lights() as u32,
        has_triangle_lights: features.emissive_triangles as u32,
        has_point_lights: features.point_lights as u32,
        has_metal_rough: features.metal_rough as u32,
        has_normal_map: features.normal_map as u32,
        has_alpha_mask: features.alpha_mask as u32,
        has_texture_transform: features.texture_transform as u32,
        has_texcoord1: features.texcoord1 as u32,
    };
    Ok(Packed { scene: kernel_scene, features, triangle_count: tri_count, light_count: light_data.len() })
}

impl Packed {
    /// Sets the render settings that are uniforms (no repacking needed).
    pub fn apply(&mut self, settings: &RenderSettings) {
        let s = &mut self.scene;
        s.max_depth = settings.max_depth.max(1);
        s.strategy = settings.strategy.uniform_value();
        if settings.width != s.width || settings.height != s.height {
            let aspect_old = s.width as f32 / s.height as f32;
            let aspect_new = settings.width as f32 / settings.height as f32;
            s.camera_right *= aspect_new / aspect_old;
            s.width = settings.width;
            s.height = settings.height;
        }
    }

    /// Every packed array with its texture layout for `max_texture_size`; arrays the scene
    /// does not use are absent.
    pub fn arrays(&self, max_texture_size: u32) -> Result<Vec<ArrayStats>, PackError> {
        let s = &self.scene;
        let list: [(&'static str, usize); 11] = [
            ("triangles", s.triangles.len()),
            ("shading", s.shading.len()),
            ("nodes", s.nodes.len()),
            ("node_children", s.node_children.len()),
            ("materials", s.materials.len()),
            ("lights", s.lights.len()),
            ("texture_texels", s.texture_texels.len()),
            ("texture_info", s.texture_info.len()),
            ("sky", s.sky.len()),
            ("sky_rows", s.sky_rows.len()),
            ("metal_rough", s.metal_rough.len()),
        ];
        let mut out = Vec::new();
        for (name, texels) in list {
            if texels == 0 {
                continue;
            }
            let (width, height) = texture_shape(texels, max_texture_size).ok_or(PackError::TooLarge {
                what: name,
                texels,
                max: max_texture_size,
            })?;
            out.push(ArrayStats { name, texels, width, height, texel_bytes: 16 });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{cornell_box, srgb_to_linear, Material, Texture};

    fn texture(width: u32, height: u32, first_word: u32) -> Texture {
        let texels = (0..width * height).map(|i| first_word + i).collect();
        Texture { width, height, texels, wrap_s: Wrap::Repeat, wrap_t: Wrap::ClampToEdge }
    }

    /// The Cornell box with a 3-texel and a 5-texel texture, the first one used by a material.
    fn textured_box() -> Scene {
        let mut scene = cornell_box();
        scene.textures = vec![texture(3, 1, 100), texture(5, 1, 200)];
        scene.materials[0].base_color_texture = Some(0);
        scene
    }

    #[test]
    fn triangle_lights_carry_their_unit_normal_and_area() {
        let scene = cornell_box();
        let bvh = crate::bvh::build(&scene.triangles).unwrap();
        let packed = pack(&scene, &bvh, &RenderSettings::default()).unwrap();
        let k = &packed.scene;
        let lights: Vec<&[Vec4]> = k.lights.as_slice().chunks(LIGHT_TEXELS as usize).collect();
        let triangle_lights: Vec<_> = lights.iter().filter(|l| l[0].w as u32 == LIGHT_TRIANGLE).collect();
        assert_eq!(triangle_lights.len(), 2, "the Cornell box light is one quad");
        for l in triangle_lights {
            let t = crate::kernel::scene_data::fetch_triangle(k, l[1].x as u32);
            let face = (t.v1 - t.v0).cross(t.v2 - t.v0);
            let normal = Vec3::new(l[1].y, l[1].z, l[1].w);
            assert!((normal - face.normalize()).length() < 1e-6, "{normal} vs {face}");
            assert_eq!(l[2].x, 0.5 * face.length());
            // The ceiling light faces down into the room.
            assert!(normal.y < -0.99, "{normal}");
        }
    }

    #[test]
    fn textures_start_on_element_boundaries_and_keep_their_texels() {
        let scene = textured_box();
        let packed = pack_textures(&scene);
        assert!(packed.used);
        // 3 texels fill one element (one lane left zero); the second texture starts at texel 4.
        let info = packed.info.as_slice();
        assert_eq!(info[0], UVec4::new(0, 3, 1, scene_data::WRAP_REPEAT | scene_data::WRAP_CLAMP << 8));
        assert_eq!(info[1].x, 4);
        assert_eq!(
            packed.texels.as_slice(),
            &[UVec4::new(100, 101, 102, 0), UVec4::new(200, 201, 202, 203), UVec4::new(204, 0, 0, 0)]
        );
    }

    /// The Cornell box with textures decoded as loaders do (one shared atlas): a 3x1 and a 2x3.
    fn loaded_textures_box() -> Scene {
        use crate::scene::texture::{decode_textures, probe_srgb, PendingTexture, Probed};
        let png = |w, h| {
            let image = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba([x as u8, y as u8, 7, 200]));
            let mut out = std::io::Cursor::new(Vec::new());
            image.write_to(&mut out, image::ImageFormat::Png).unwrap();
            out.into_inner()
        };
        let files = [png(3, 1), png(2, 3)];
        let headers: Vec<_> = files
            .iter()
            .map(|f| match probe_srgb(f, "test", u64::MAX).unwrap() {
                Probed::Image(h) => h,
                Probed::Unsupported(_) => unreachable!(),
            })
            .collect();
        let images: Vec<_> = files.iter().map(|f| f.as_slice()).zip(&headers).collect();
        let pending = |image| PendingTexture { image, wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat };
        let mut scene = cornell_box();
        scene.textures = decode_textures(&images, &[pending(0), pending(1)], &[]).unwrap();
        scene.materials[0].base_color_texture = Some(1);
        scene
    }

    #[test]
    fn loaded_textures_are_shared_and_others_copied_into_the_same_layout() {
        let scene = loaded_textures_box();
        let packed = pack_textures(&scene);
        assert!(std::ptr::eq(packed.texels.as_slice(), scene.textures[0].texels.atlas().as_slice()));
        // The same texels in textures of their own: copied, the same bytes.
        let mut copied = scene.clone();
        for t in &mut copied.textures {
            t.texels = t.texels.to_vec().into();
        }
        let copy = pack_textures(&copied);
        assert!(!std::ptr::eq(copy.texels.as_slice(), packed.texels.as_slice()));
        assert_eq!(copy, packed);
        // Reordered, or one dropped: the shared atlas no longer matches the layout.
        let mut reordered = scene.clone();
        reordered.textures.reverse();
        let mut expected = reordered.clone();
        for t in &mut expected.textures {
            t.texels = t.texels.to_vec().into();
        }
        assert_eq!(pack_textures(&reordered), pack_textures(&expected));
        let mut first_only = scene.clone();
        first_only.textures.truncate(1);
        first_only.materials[0].base_color_texture = Some(0);
        let packed = pack_textures(&first_only);
        assert_eq!(packed.texels.len(), 1);
        assert_eq!(packed.texels.as_slice()[0].w, 0);
    }

    #[test]
    fn unused_textures_are_not_packed() {
        let mut scene = textured_box();
        scene.materials[0].base_color_texture = None;
        let packed = pack_textures(&scene);
        assert!(!packed.used && packed.texels.is_empty() && packed.info.is_empty());
    }

    #[test]
    fn emissive_texture_mean_is_the_linear_mean_luminance() {
        let mut scene = cornell_box();
        // Two texels: sRGB grey 188 (linear 0.5029) and black, alpha ignored: the mean of the
        // linear values, not of the encoded ones (188 / 255 / 2 = 0.369).
        scene.textures = vec![Texture {
            width: 2,
            height: 1,
            texels: vec![0x00bc_bcbc, 0xff00_0000].into(),
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
        }];
        scene.materials.push(Material { emissive_texture: Some(0), ..Material::emissive("e", Vec3::ONE, Vec3::ONE) });
        let mean = pack_textures(&scene).emissive_mean_luminance;
        assert_eq!(mean.len(), 1);
        let expected = 0.5 * srgb_to_linear(188.0 / 255.0);
        assert!((mean[0].unwrap() - expected).abs() < 1e-6 && (expected - 0.2515).abs() < 1e-3, "{mean:?}");
    }

    #[test]
    fn packed_textures_share_their_arrays_with_the_packed_scene() {
        let scene = textured_box();
        let bvh = crate::bvh::build(&scene.triangles).unwrap();
        let textures = pack_textures(&scene);
        let packed = pack_with_textures(&scene, &bvh, &textures, &RenderSettings::default()).unwrap();
        assert!(std::ptr::eq(packed.scene.texture_texels.as_slice(), textures.texels.as_slice()));
        let whole = pack(&scene, &bvh, &RenderSettings::default()).unwrap().scene;
        assert_eq!(packed.scene.texture_texels, whole.texture_texels);
        assert_eq!(packed.scene.texture_info, whole.texture_info);
        assert_eq!(packed.scene.materials, whole.materials);
    }

    #[test]
    fn textures_of_another_scene_are_refused() {
        let scene = textured_box();
        let bvh = crate::bvh::build(&scene.triangles).unwrap();
        let mut other = textured_box();
        other.textures[1] = texture(4, 2, 0);
        let settings = RenderSettings::default();
        let err = pack_with_textures(&scene, &bvh, &pack_textures(&other), &settings).unwrap_err();
        assert_eq!(err, PackError::TexturesMismatch);
        let err = pack_with_textures(&scene, &bvh, &pack_textures(&cornell_box()), &settings).unwrap_err();
        assert_eq!(err, PackError::TexturesMismatch);
    }

    #[test]
    fn leaves_beyond_the_stack_encoding_are_refused() {
        let scene = cornell_box();
        let mut bvh = crate::bvh::build(&scene.triangles).unwrap();
        let leaf = bvh.nodes.iter_mut().find(|n| n.count > 0).unwrap();
        leaf.count = 256;
        let err = pack(&scene, &bvh, &RenderSettings::default()).unwrap_err();
        assert_eq!(err, PackError::LeafTooLarge { triangles: 256, max: 255 });
    }
    #[test]
    fn light_selection_stays_finite_for_lights_of_extreme_power() {
        // Loaders refuse more than 1e12, but a scene built in code may hold anything finite:
        // f32::MAX / 2 times 4π overflows f32. Its share must not turn the mean, the floor or any
        // pmf into inf/NaN, and the dim light keeps the floor share.
        let mut scene = cornell_box();
        scene.point_lights = vec![
            crate::scene::PointLight { position: Vec3::new(0.0, 1.0, 0.0), intensity: Vec3::splat(f32::MAX / 2.0) },
            crate::scene::PointLight { position: Vec3::new(0.2, 1.0, 0.0), intensity: Vec3::splat(1e-30) },
        ];
        let bvh = crate::bvh::build(&scene.triangles).unwrap();
        let packed = pack(&scene, &bvh, &RenderSettings::default()).unwrap();
        let lights = packed.scene.lights.as_slice();
        let pmfs: Vec<f32> = lights.chunks(LIGHT_TEXELS as usize).map(|l| l[0].z).collect();
        assert!(pmfs.iter().all(|p| p.is_finite() && *p > 0.0), "{pmfs:?}");
        assert!((pmfs.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{pmfs:?}");
        assert!(lights.iter().all(|t| t.is_finite()));
    }
}
