//! Materials: two texels each (base colour and emission, each with a texture index), the
//! normal-map and alpha-mask sections appended to the same array when the scene uses them, and
//! the metal-roughness array (`kernel::scene_data::fetch_material`, `kernel::metal_rough`).

use glam::Vec4;
use kernel_dsl::Texels;

use super::{index_value, PackedTextures};
use crate::kernel::scene_data::MATERIAL_TEXELS;
use crate::kernel::Features;
use crate::scene::Scene;

/// The kernel's material arrays.
pub(super) struct PackedMaterials {
    pub materials: Texels<Vec4>,
    pub metal_rough: Texels<Vec4>,
    pub normal_map_first: u32,
    pub alpha_mask_first: u32,
    pub transmission_first: u32,
}

pub(super) fn pack_materials(scene: &Scene, textures: &PackedTextures, features: &Features) -> PackedMaterials {
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
    let transmission_first = if features.transmission { materials.len() as u32 } else { 0 };
    if features.transmission {
        // `kernel::scene_data::fetch_glass`: two texels per material (GLASS_TEXELS).
        for (i, m) in scene.materials.iter().enumerate() {
            let thin = if m.has_volume() { 0.0 } else { 1.0 };
            let transmission = if m.transmits() { m.transmission.min(1.0) } else { 0.0 };
            materials.push(Vec4::new(transmission, m.ior, texture_index(i, 4, m.transmission_texture), thin));
            materials.push(m.absorption().extend(0.0));
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
    PackedMaterials {
        materials: Texels::new(materials),
        metal_rough,
        normal_map_first,
        alpha_mask_first,
        transmission_first,
    }
}
