//! What a scene uses ([`Features`], which decides what is packed and which kernel variant is
//! generated) and the render settings that become the kernel's uniforms. Plain Rust beside the
//! kernel modules (not kernel code): the kernel's specialisation and `pack` both read it, so
//! the kernel does not depend on `pack`.

use crate::kernel::scene_data;

/// What a scene uses; decides what is packed and, on GPUs, which kernel variant is generated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Features {
    pub sky: bool,
    pub textures: bool,
    /// Per-vertex normals or texture coordinates are needed.
    pub shading: bool,
    pub point_lights: bool,
    pub emissive_triangles: bool,
    /// Some material needs the glTF metal-roughness BRDF ([`crate::scene::Material::uses_metal_rough`]):
    /// the specular code and one more texel per material (`Scene::metal_rough`).
    pub metal_rough: bool,
    /// Some material has a normal map (glTF `normalTexture`): the tangent-frame code, per
    /// triangle three tangent texels appended to `Scene::shading` and per material one texel
    /// appended to `Scene::materials` (`kernel::normal_map`); nothing without.
    pub normal_map: bool,
    /// Some material is alpha-masked (glTF `alphaMode` MASK, [`crate::scene::Material::alpha_cutoff`]):
    /// the alpha test in traversal and light sampling, a flag in each triangle's third texel and
    /// per material one texel appended to `Scene::materials` (`kernel::scene_data::is_hole`); nothing without.
    pub alpha_mask: bool,
    /// Some texture is read through a `KHR_texture_transform`: materials name texture
    /// references, each with two more `texture_info` texels (`kernel::texture_ref`).
    pub texture_transform: bool,
    /// Some texture is read on `TEXCOORD_1`: texture references as above, and per triangle two
    /// texels of the second UV set appended to `Scene::shading`.
    pub texcoord1: bool,
    /// Some material transmits (glTF `KHR_materials_transmission`, [`crate::scene::Material::transmission`]):
    /// the dielectric BSDF (`kernel::dielectric`), two-sided light sampling and refracted
    /// continuations in the integrator, and per material two texels appended to
    /// `Scene::materials` (`kernel::scene_data::fetch_glass`); nothing without. Implies
    /// `metal_rough` (the opaque rest of a transmissive material is metal-roughness).
    pub transmission: bool,
    /// Some transmissive material has a volume that absorbs (glTF `KHR_materials_volume` with
    /// a finite attenuation distance): Beer–Lambert absorption along segments inside it
    /// (`kernel::integrator::volume_transmittance`).
    pub volume: bool,
    /// Entries the traversal stack needs for this scene's BVH (`WideBvh::stack_needed*`, at
    /// most the kernel's `STACK_SIZE`): GPU variants size their stacks to it instead of
    /// `STACK_SIZE` (the Cornell box needs 11, not 64). 0: not fixed, the kernel's `STACK_SIZE`.
    pub traversal_stack: u32,
}

impl Features {
    /// The kernel's feature flags fixed to this scene's values, for codegen's specialisation.
    pub fn specialization(&self) -> std::collections::BTreeMap<String, u32> {
        [
            ("has_sky", self.sky),
            ("has_textures", self.textures),
            ("has_shading", self.shading),
            ("has_lights", self.lights()),
            ("has_triangle_lights", self.emissive_triangles),
            ("has_point_lights", self.point_lights),
            ("has_metal_rough", self.metal_rough),
            ("has_normal_map", self.normal_map),
            ("has_alpha_mask", self.alpha_mask),
            ("has_texture_transform", self.texture_transform),
            ("has_texcoord1", self.texcoord1),
            ("has_transmission", self.transmission),
            ("has_volume", self.volume),
        ]
        .into_iter()
        .map(|(k, v)| (format!("Scene.{k}"), v as u32))
        .chain((self.traversal_stack > 0).then(|| ("STACK_SIZE".to_string(), self.traversal_stack)))
        .collect()
    }

    pub fn lights(&self) -> bool {
        self.sky || self.point_lights || self.emissive_triangles
    }

    /// Every feature on: the unspecialised kernel, for comparisons.
    pub fn all() -> Features {
        Features {
            sky: true,
            textures: true,
            shading: true,
            point_lights: true,
            emissive_triangles: true,
            metal_rough: true,
            normal_map: true,
            alpha_mask: true,
            texture_transform: true,
            texcoord1: true,
            transmission: true,
            volume: true,
            traversal_stack: 0,
        }
    }
}

/// Which estimator the kernel uses (all three converge to the same image).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Strategy {
    /// BSDF sampling only (point lights, which BSDF rays cannot hit, are still sampled).
    Bsdf,
    /// Next event estimation only.
    Nee,
    /// Both, combined with multiple importance sampling (power heuristic).
    #[default]
    Mis,
}

impl Strategy {
    pub const ALL: [Strategy; 3] = [Strategy::Bsdf, Strategy::Nee, Strategy::Mis];

    pub fn uniform_value(self) -> u32 {
        match self {
            Strategy::Bsdf => scene_data::STRATEGY_BSDF,
            Strategy::Nee => scene_data::STRATEGY_NEE,
            Strategy::Mis => scene_data::STRATEGY_MIS,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Strategy::Bsdf => "bsdf",
            Strategy::Nee => "nee",
            Strategy::Mis => "mis",
        }
    }
}

/// Render settings that become uniforms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub strategy: Strategy,
    /// Maximum number of path segments (camera to light).
    pub max_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings { width: 512, height: 512, strategy: Strategy::Mis, max_depth: 8 }
    }
}
