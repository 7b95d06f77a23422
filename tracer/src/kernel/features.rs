//! What a scene uses ([`Features`], which decides what is packed and which kernel variant is
//! generated) and the render settings that become the kernel's uniforms. Plain Rust beside the
//! kernel modules (not kernel code): the kernel's specialisation and `pack` both read it, so
//! the kernel does not depend on `pack`.

use crate::kernel::scene_data::{self, Scene};

/// Declares [`Features`] once: each flag with the kernel uniform that carries it
/// (`Scene.has_*`). Everything that lists the flags (specialisation, [`Features::all`], the
/// kernel uniforms, the bundle's entries and its consistency check, the page's and the site's
/// read-outs) walks [`Features::flags`] or the functions generated here.
macro_rules! features {
    ($($(#[doc = $doc:literal])* $flag:ident => $uniform:ident,)*) => {
        /// What a scene uses; decides what is packed and, on GPUs, which kernel variant is generated.
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
        pub struct Features {
            $($(#[doc = $doc])* pub $flag: bool,)*
            /// Entries the traversal stack needs for this scene's BVH (`WideBvh::stack_needed*`, at
            /// most the kernel's `STACK_SIZE`): GPU variants size their stacks to it instead of
            /// `STACK_SIZE` (the Cornell box needs 11, not 64). 0: not fixed, the kernel's `STACK_SIZE`.
            pub traversal_stack: u32,
            /// The denoiser's guide is wanted (`render --denoise`, the page's denoiser): the path
            /// tracer's entry point is `integrator::render_guided_sample`, which also sums each
            /// path's first hit (albedo, normal, depth, emission) and its luminance moments into
            /// three more targets (`tracer::denoise::Guide`); nothing without. A render setting,
            /// not something a scene uses, so not one of the [`flags`](Self::flags) (bundles and
            /// the read-outs of what a scene uses leave it out); uniform `has_denoise_guide`.
            pub denoise_guide: bool,
        }

        impl Features {
            /// Each flag: its name (the field's), the kernel uniform it sets, and its value.
            pub fn flags(&self) -> Vec<Flag> {
                vec![$(Flag { name: stringify!($flag), uniform: stringify!($uniform), on: self.$flag }),*]
            }

            /// Each flag by name, to set (the bundle's reader).
            pub fn flags_mut(&mut self) -> Vec<(&'static str, &mut bool)> {
                vec![$((stringify!($flag), &mut self.$flag)),*]
            }

            /// Every feature a scene can use on (not the denoiser's guide): the unspecialised kernel, for comparisons.
            pub fn all() -> Features {
                Features { $($flag: true,)* traversal_stack: 0, denoise_guide: false }
            }

            /// The kernel's `has_*` uniforms of `scene` as these flags say (and `has_lights`).
            pub fn set_kernel_flags(&self, scene: &mut Scene) {
                $(scene.$uniform = self.$flag as u32;)*
                scene.has_lights = self.lights() as u32;
                scene.has_denoise_guide = self.denoise_guide as u32;
            }

            /// The kernel uniforms of `scene` that disagree with these flags: `(uniform, flag, uniform's value)`.
            pub fn kernel_flag_mismatches(&self, scene: &Scene) -> Vec<(&'static str, bool, u32)> {
                let flags = [$((stringify!($uniform), self.$flag, scene.$uniform),)* ("has_lights", self.lights(), scene.has_lights), ("has_denoise_guide", self.denoise_guide, scene.has_denoise_guide)];
                flags.into_iter().filter(|&(_, on, value)| value != on as u32).collect()
            }
        }
    };
}

features! {
    sky => has_sky,
    textures => has_textures,
    /// Per-vertex normals or texture coordinates are needed.
    shading => has_shading,
    point_lights => has_point_lights,
    emissive_triangles => has_triangle_lights,
    /// Some material needs the glTF metal-roughness BRDF ([`crate::scene::Material::uses_metal_rough`]):
    /// the specular code and one more texel per material (`Scene::metal_rough`).
    metal_rough => has_metal_rough,
    /// Some material has a normal map (glTF `normalTexture`): the tangent-frame code, per
    /// triangle three tangent texels appended to `Scene::shading` and per material one texel
    /// appended to `Scene::materials` (`kernel::normal_map`); nothing without.
    normal_map => has_normal_map,
    /// Some material is alpha-masked (glTF `alphaMode` MASK, [`crate::scene::Material::alpha_cutoff`]):
    /// the alpha test in traversal and light sampling, a flag in each triangle's third texel and
    /// per material one texel appended to `Scene::materials` (`kernel::alpha_mask::is_hole`); nothing without.
    alpha_mask => has_alpha_mask,
    /// Some texture is read through a `KHR_texture_transform`: materials name texture
    /// references, each with two more `texture_info` texels (`kernel::texture_ref`).
    texture_transform => has_texture_transform,
    /// Some texture is read on `TEXCOORD_1`: texture references as above, and per triangle two
    /// texels of the second UV set appended to `Scene::shading`.
    texcoord1 => has_texcoord1,
    /// Some material transmits (glTF `KHR_materials_transmission`, [`crate::scene::Material::transmission`]):
    /// the dielectric BSDF (`kernel::dielectric`), two-sided light sampling and refracted
    /// continuations in the integrator, and per material two texels appended to
    /// `Scene::materials` (`kernel::scene_data::fetch_glass`); nothing without. Implies
    /// `metal_rough` (the opaque rest of a transmissive material is metal-roughness).
    transmission => has_transmission,
    /// Some transmissive material has a volume that absorbs (glTF `KHR_materials_volume` with
    /// a finite attenuation distance): Beer–Lambert absorption along segments inside it
    /// (`kernel::integrator::volume_transmittance`).
    volume => has_volume,
    /// The scene has instances (meshes placed more than once, `tracer::scene::Instance`): a
    /// two-level BVH, traversed in one loop (`kernel::traverse`), hits carried back to world
    /// space (`kernel::instances`), and per instance `INSTANCE_TEXELS` texels appended to
    /// `Scene::nodes`; scenes without keep the one-level kernel.
    instances => has_instances,
}

/// One feature flag of [`Features`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Flag {
    /// The `Features` field (`emissive_triangles`).
    pub name: &'static str,
    /// The kernel uniform (`has_triangle_lights`).
    pub uniform: &'static str,
    pub on: bool,
}

impl Features {
    /// The kernel's feature flags fixed to this scene's values, for codegen's specialisation.
    pub fn specialization(&self) -> std::collections::BTreeMap<String, u32> {
        self.flags()
            .into_iter()
            .map(|f| (f.uniform, f.on))
            .chain([("has_lights", self.lights()), ("has_denoise_guide", self.denoise_guide)])
            .map(|(k, v)| (format!("Scene.{k}"), v as u32))
            .chain((self.traversal_stack > 0).then(|| ("STACK_SIZE".to_string(), self.traversal_stack)))
            .collect()
    }

    pub fn lights(&self) -> bool {
        self.sky || self.point_lights || self.emissive_triangles
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
