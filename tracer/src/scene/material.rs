//! A scene's materials: base colour, emission, metal-roughness, normal maps, alpha and glass
//! (transmission, ior, volume), each factor with its optional texture slot.

use glam::Vec3;

use super::UvTransform;

/// A diffuse, possibly emissive material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The material's name in the file (empty when it had none).
    pub name: String,
    /// Linear RGB diffuse albedo (glTF `baseColorFactor.rgb`, OBJ `Kd`), each in `[0, 1]`.
    pub base_color: Vec3,
    /// Index into [`Scene::textures`] multiplying `base_color` (texels are linear).
    pub base_color_texture: Option<u32>,
    /// Emitted linear radiance: glTF `emissiveFactor x KHR_materials_emissive_strength`
    /// (OBJ `Ke`). Zero for non-emissive materials.
    pub emission: Vec3,
    /// Index into [`Scene::textures`] multiplying `emission`. Always `None` when `emission` is 0.
    pub emissive_texture: Option<u32>,
    /// glTF `metallicFactor` in `[0, 1]` (0 for OBJ and FBX materials).
    pub metallic: f32,
    /// glTF `roughnessFactor` in `[0, 1]` (1 for OBJ and FBX materials). The kernel clamps it to
    /// at least `kernel::metal_rough::MIN_ROUGHNESS`.
    pub roughness: f32,
    /// glTF `metallicRoughnessTexture`: its blue channel multiplies `metallic`, its green
    /// `roughness` (texels are linear data, not sRGB).
    pub metallic_roughness_texture: Option<u32>,
    /// glTF `normalTexture`: a tangent-space normal map (linear data, `2 * rgb - 1`), which
    /// needs tangents on the triangles ([`Triangle::tangents`]; `Features::normal_map`).
    pub normal_texture: Option<u32>,
    /// glTF `normalTexture.scale`: multiplies the map's x and y before normalising.
    pub normal_scale: f32,
    /// glTF `baseColorFactor.a` in `[0, 1]`: with the base colour texture's alpha, the coverage
    /// that [`Material::alpha_cutoff`] tests (ignored for opaque materials).
    pub alpha: f32,
    /// glTF `alphaMode` MASK's `alphaCutoff` (`BLEND` is loaded as MASK at 0.5): where the
    /// coverage (`alpha` x the base colour texture's alpha) is below it the surface is a hole
    /// for every ray. `None`: opaque (`alphaMode` OPAQUE), alpha ignored.
    pub alpha_cutoff: Option<f32>,
    /// How each of [`Material::texture_slots`] is read (same order): its texture coordinate
    /// set and `KHR_texture_transform`. The default reads `TEXCOORD_0` untransformed.
    pub texture_uvs: [UvTransform; 5],
    /// glTF `KHR_materials_transmission` `transmissionFactor` in `[0, 1]`: the share of the
    /// non-metallic part that light passes through (tinted by the base colour), as a rough
    /// dielectric (`kernel::dielectric`). 0: opaque.
    pub transmission: f32,
    /// `transmissionTexture`: its red channel (linear) multiplies `transmission`.
    pub transmission_texture: Option<u32>,
    /// glTF `KHR_materials_ior` (1.5 by default), at least 1.
    pub ior: f32,
    /// glTF `KHR_materials_volume` `thicknessFactor`: 0 (or no volume) makes a transmissive
    /// surface thin-walled (no refraction: light passes through a sheet); above 0 the mesh
    /// encloses a volume that refracts and absorbs.
    pub thickness: f32,
    /// `attenuationColor`: the colour white light has after `attenuation_distance` inside the
    /// volume (Beer–Lambert: σa = −ln(colour) / distance).
    pub attenuation_color: Vec3,
    /// `attenuationDistance` (infinite: no absorption), above 0.
    pub attenuation_distance: f32,
}

impl Material {
    /// A plain diffuse material.
    pub fn diffuse(name: &str, base_color: Vec3) -> Self {
        Self {
            name: name.to_owned(),
            base_color,
            base_color_texture: None,
            emission: Vec3::ZERO,
            emissive_texture: None,
            metallic: 0.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            alpha: 1.0,
            alpha_cutoff: None,
            texture_uvs: [UvTransform::default(); 5],
            transmission: 0.0,
            transmission_texture: None,
            ior: 1.5,
            thickness: 0.0,
            attenuation_color: Vec3::ONE,
            attenuation_distance: f32::INFINITY,
        }
    }

    /// Whether the kernel must alpha-test the material (`Features::alpha_mask`): it is masked
    /// and some point can be a hole, through its base colour texture (when `textures` are
    /// packed) or a factor below the cutoff. A masked material whose factor passes and that
    /// has no texture is opaque everywhere and needs no test.
    pub fn is_masked(&self, textures: bool) -> bool {
        self.alpha_cutoff.is_some_and(|c| (textures && self.base_color_texture.is_some()) || self.alpha < c)
    }

    /// A glTF metal-roughness material.
    pub fn metal_rough(name: &str, base_color: Vec3, metallic: f32, roughness: f32) -> Self {
        Self { metallic, roughness, ..Self::diffuse(name, base_color) }
    }

    /// Whether the material needs the metal-roughness BRDF (`Features::metal_rough`). A
    /// material with metallic 0, roughness 1 and no metal-roughness texture is rendered by the
    /// Lambert kernel, exactly as before the BRDF existed: the specification's rough 4 %
    /// dielectric specular layer is left out for it (at roughness 1 it moves reflected
    /// energy by a few percent, most at grazing angles).
    pub fn uses_metal_rough(&self) -> bool {
        self.metallic != 0.0 || self.roughness != 1.0 || self.metallic_roughness_texture.is_some() || self.transmits()
    }

    /// Whether some light passes through the material (`Features::transmission`).
    pub fn transmits(&self) -> bool {
        self.transmission > 0.0
    }

    /// A smooth (roughness 0) transmissive glass of index `ior`: with `volume`, a solid that
    /// refracts (thickness 1, no absorption); without, a thin-walled sheet.
    pub fn glass(name: &str, tint: Vec3, ior: f32, volume: bool) -> Self {
        let thickness = if volume { 1.0 } else { 0.0 };
        Self { transmission: 1.0, ior, thickness, roughness: 0.0, ..Self::diffuse(name, tint) }
    }

    /// Whether the material encloses a volume (`thickness` > 0), so refracts rather than
    /// passing light straight through a sheet.
    pub fn has_volume(&self) -> bool {
        self.transmits() && self.thickness > 0.0
    }

    /// The volume's Beer–Lambert absorption coefficient σa = −ln(attenuation colour) /
    /// attenuation distance (per scene unit), 0 without a volume or with an infinite distance.
    /// A colour channel of 0 absorbs as 1e-6 would (finite σa).
    pub fn absorption(&self) -> Vec3 {
        let d = self.attenuation_distance;
        if !self.has_volume() || !d.is_finite() || d <= 0.0 {
            return Vec3::ZERO;
        }
        let c = self.attenuation_color.clamp(Vec3::splat(1e-6), Vec3::ONE);
        Vec3::new(-c.x.ln(), -c.y.ln(), -c.z.ln()) / self.attenuation_distance
    }

    /// A diffuse material that also emits `emission` radiance.
    pub fn emissive(name: &str, base_color: Vec3, emission: Vec3) -> Self {
        Self { emission, ..Self::diffuse(name, base_color) }
    }

    /// Whether the material emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// Its texture references (indices into [`Scene::textures`]), every map it has.
    pub fn texture_slots(&self) -> [Option<u32>; 5] {
        [
            self.base_color_texture,
            self.emissive_texture,
            self.metallic_roughness_texture,
            self.normal_texture,
            self.transmission_texture,
        ]
    }

    /// [`Material::texture_slots`], to rewrite (loaders drop textures that fail to decode).
    pub(crate) fn texture_slots_mut(&mut self) -> [&mut Option<u32>; 5] {
        [
            &mut self.base_color_texture,
            &mut self.emissive_texture,
            &mut self.metallic_roughness_texture,
            &mut self.normal_texture,
            &mut self.transmission_texture,
        ]
    }
}
