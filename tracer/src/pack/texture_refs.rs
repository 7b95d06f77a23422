//! Texture references for `Features::texture_transform` and `Features::texcoord1`
//! (`kernel::texture_ref`): each distinct (texture, UV set, transform) that a material slot
//! reads becomes one reference with its own `texture_info` entry (the texels are not copied),
//! followed by its transform texels, and the materials name references instead of textures.
//! Scenes that use neither feature keep today's layout: materials name textures.

use std::collections::HashMap;

use glam::{UVec4, Vec2};

use crate::kernel::texture_ref::TEXTURE_REF_TEXELS;
use crate::scene::{Scene, UvTransform};

/// The references of a scene that transforms textures or reads `TEXCOORD_1`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TextureRefs {
    /// Per reference, its texture (an index into the scene's textures) and how it is read.
    pub refs: Vec<(u32, UvTransform)>,
    /// Per material, per [`crate::scene::Material::texture_slots`] entry, its reference.
    pub slots: Vec<[Option<u32>; 5]>,
    /// Some reference transforms its UVs (`Features::texture_transform`).
    pub transform: bool,
    /// Some reference reads `TEXCOORD_1` (`Features::texcoord1`).
    pub texcoord1: bool,
}

/// The key of a reference: its texture and the bits of its transform (so `-0.0` and `0.0`
/// are two references, which costs two texels and nothing else).
fn key(texture: u32, uv: &UvTransform) -> (u32, u32, [u32; 5]) {
    let bits = [uv.offset.x, uv.offset.y, uv.rotation, uv.scale.x, uv.scale.y].map(f32::to_bits);
    (texture, uv.texcoord, bits)
}

/// The scene's texture references, or `None` when no texture a material uses is transformed
/// or read on `TEXCOORD_1` (then nothing changes). Slots naming a texture the scene lacks
/// keep no reference.
pub fn texture_refs(scene: &Scene) -> Option<TextureRefs> {
    let used = || {
        scene
            .materials
            .iter()
            .flat_map(|m| m.texture_slots().into_iter().zip(m.texture_uvs).filter_map(|(t, uv)| t.map(|t| (t, uv))))
    };
    let transform = used().any(|(_, uv)| !uv.is_identity());
    let texcoord1 = used().any(|(_, uv)| uv.texcoord == 1);
    if !transform && !texcoord1 {
        return None;
    }
    let mut out = TextureRefs { transform, texcoord1, ..Default::default() };
    let mut index = HashMap::new();
    for m in &scene.materials {
        let mut slots = [None; 5];
        for (slot, (texture, uv)) in slots.iter_mut().zip(m.texture_slots().into_iter().zip(m.texture_uvs)) {
            let Some(texture) = texture.filter(|&t| (t as usize) < scene.textures.len()) else { continue };
            let next = out.refs.len() as u32;
            let r = *index.entry(key(texture, &uv)).or_insert_with(|| {
                out.refs.push((texture, uv));
                next
            });
            *slot = Some(r);
        }
        out.slots.push(slots);
    }
    Some(out)
}

impl TextureRefs {
    /// The kernel's `texture_info` for these references, from the per-texture `info`: one
    /// entry per reference, then `TEXTURE_REF_TEXELS` per reference (`kernel::texture_ref`).
    pub fn texture_info(&self, info: &[UVec4]) -> Vec<UVec4> {
        let mut out: Vec<UVec4> = self.refs.iter().map(|(t, _)| info[*t as usize]).collect();
        out.reserve(self.refs.len() * TEXTURE_REF_TEXELS as usize);
        for (_, uv) in &self.refs {
            let [a, b] = uv.rows();
            out.push(UVec4::new(a.x.to_bits(), a.y.to_bits(), a.z.to_bits(), uv.texcoord));
            out.push(UVec4::new(b.x.to_bits(), b.y.to_bits(), b.z.to_bits(), 0));
        }
        out
    }
}

/// The second UV set's texels of one triangle (`kernel::texture_ref::texcoord1`).
pub fn texcoord1_texels(uvs1: &[Vec2; 3]) -> [glam::Vec4; 2] {
    let [a, b, c] = *uvs1;
    [glam::Vec4::new(a.x, a.y, b.x, b.y), glam::Vec4::new(c.x, c.y, 0.0, 0.0)]
}

/// Whether `textures` (used) were packed from `scene`'s textures: every entry the kernel reads
/// as a texture has the size of the scene texture it stands for.
pub(super) fn matches(scene: &Scene, textures: &super::PackedTextures) -> bool {
    let info = textures.info.as_slice();
    let size = |t: u32, i: &UVec4| scene.textures.get(t as usize).is_some_and(|t| (t.width, t.height) == (i.y, i.z));
    match &textures.refs {
        None => info.len() == scene.textures.len() && (0..).zip(info).all(|(t, i)| size(t, i)),
        Some(refs) => {
            info.len() == refs.refs.len() * (1 + TEXTURE_REF_TEXELS as usize)
                && refs.slots.len() == scene.materials.len()
                && refs.refs.iter().zip(info).all(|((t, _), i)| size(*t, i))
        }
    }
}
