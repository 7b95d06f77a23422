//! Textures: the atlas of every texture's sRGBA8 texels and the per-texture table
//! (`kernel::textures::sample_texture`), made once per scene and shared by every packing of it.

use glam::UVec4;
use kernel_dsl::Texels;

use super::texture_refs::{self, TextureRefs};
use crate::kernel::scene_data::{self, TEXTURE_TEXELS_PER_ELEMENT};
use crate::scene::{EncodedImage, Scene, Wrap};

/// One texture of the atlas as an image: its size and the file its texels were decoded from
/// (`None` for texels made in code). Bundles carry the atlas this way, as image files.
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasImage {
    pub width: u32,
    pub height: u32,
    pub file: Option<EncodedImage>,
}

/// The texture half of packing: the texel atlas and its per-texture table. It depends only on
/// the scene's textures and materials, so it is made once (in parallel with the BVH build, see
/// [`super::build_and_pack`]) and reused by [`super::pack_with_textures`] when the geometry or the settings
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
    /// Each texture of [`PackedTextures::texels`], in order, as an image (empty when unused).
    pub images: Vec<AtlasImage>,
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
    let images = textures
        .iter()
        .map(|t| AtlasImage { width: t.width, height: t.height, file: t.texels.source().cloned() })
        .collect();
    PackedTextures { used, texels, info: Texels::new(info), refs, emissive_mean_luminance, images }
}

pub(super) fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => scene_data::WRAP_REPEAT,
        Wrap::ClampToEdge => scene_data::WRAP_CLAMP,
        Wrap::MirroredRepeat => scene_data::WRAP_MIRROR,
    }
}
