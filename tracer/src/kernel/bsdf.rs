#[kernel_dsl::kernel]
pub mod bsdf {
    //! The BSDF interface the integrator sees: a surface point's scattering parameters
    //! ([`Bsdf`], from [`bsdf_at`]) and four functions over them, each dispatching on the
    //! material kind: [`bsdf_eval`] (f, without the cosine), [`bsdf_pdf`] (the solid-angle pdf
    //! of [`bsdf_sample`]), [`bsdf_sample`] (a direction, its pdf and the weight f · cos / pdf)
    //! and [`bsdf_normal`] (the normal its local frame is built around). Directions are local
    //! to the shading frame (the normal is +Z); `wo` points towards the viewer, `wi` towards the
    //! light.
    //!
    //! A material kind is one module with those functions (`metal_rough`), one `BSDF_*` kind,
    //! one feature flag and one branch in each function here. Every branch tests its scene
    //! feature first (`scene.has_metal_rough != 0 && ...`): specialisation folds the flag of a
    //! scene without the kind, so that scene's kernel carries only the Lambert code (the
    //! Cornell box's kernel has no GGX in it).

    use glam::Vec3;

    use crate::kernel::dielectric::{dielectric_eval, dielectric_pdf, dielectric_sample, glass_surface};
    use crate::kernel::metal_rough::{
        metal_rough_eval, metal_rough_pdf, metal_rough_sample, metal_rough_surface, surface_at, BrdfSample, Surface,
    };
    use crate::kernel::rng::random_float;
    use crate::kernel::sampling::{cosine_sample_hemisphere, INV_PI};
    use crate::kernel::scene_data::{fetch_glass, fetch_metal_rough, MaterialData, Scene, NONE};
    use crate::kernel::texture_ref::texture_uv;
    use crate::kernel::textures::{base_color_at, sample_data_texture};
    use crate::kernel::traverse::Hit;

    /// Lambert: a diffuse albedo (`Bsdf::surface.diffuse`), the only kind of a scene without
    /// `Features::metal_rough`.
    pub const BSDF_LAMBERT: u32 = 0;
    /// glTF metal-roughness (`kernel::metal_rough`): every material of a scene with
    /// `Features::metal_rough`, its Lambert-only materials included (`Surface::specular` 0).
    pub const BSDF_METAL_ROUGH: u32 = 1;
    /// A rough or smooth dielectric interface (`kernel::dielectric`): the transmissive share of
    /// a glTF material with `KHR_materials_transmission` (`Features::transmission`, [`glass_at`]).
    pub const BSDF_DIELECTRIC: u32 = 2;

    /// A surface point's BSDF: its kind (`BSDF_*`) and parameters.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Bsdf {
        pub kind: u32,
        /// The metal-roughness parameters; Lambert uses `diffuse` only.
        pub surface: Surface,
    }

    /// The BSDF of material `material_index` (`material`: its fetched data) where `hit` is.
    #[inline(always)]
    pub fn bsdf_at(scene: &Scene, material: MaterialData, material_index: u32, hit: Hit) -> Bsdf {
        if scene.has_metal_rough != 0 {
            let surface = surface_at(scene, material, material_index, hit.triangle, hit.u, hit.v);
            Bsdf { kind: BSDF_METAL_ROUGH, surface }
        } else {
            let albedo = base_color_at(scene, material, hit.triangle, hit.u, hit.v);
            let surface = Surface { diffuse: albedo, f0: Vec3::ZERO, alpha: 1.0, specular: 0.0 };
            Bsdf { kind: BSDF_LAMBERT, surface }
        }
    }

    /// The normal of the BSDF's local frame at a point with facing geometric normal `ng` and
    /// shading normal `ns` (on `ng`'s side), seen along `dir`. Metal-roughness needs the viewer
    /// above its normal: the shading normal while it is, else the geometric one (which always
    /// faces the viewer). Lambert does not depend on the viewer: the shading normal.
    #[inline(always)]
    pub fn bsdf_normal(scene: &Scene, b: Bsdf, ns: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
        if scene.has_metal_rough != 0 && b.kind == BSDF_METAL_ROUGH {
            if ns.dot(dir) < 0.0 {
                ns
            } else {
                ng
            }
        } else if scene.has_transmission != 0 && b.kind == BSDF_DIELECTRIC {
            // As metal-roughness: the viewer above the frame's normal.
            if ns.dot(dir) < 0.0 {
                ns
            } else {
                ng
            }
        } else {
            ns
        }
    }

    /// f(wo, wi), without the cosine.
    #[inline(always)]
    pub fn bsdf_eval(scene: &Scene, b: Bsdf, wo: Vec3, wi: Vec3) -> Vec3 {
        if scene.has_metal_rough != 0 && b.kind == BSDF_METAL_ROUGH {
            metal_rough_eval(b.surface, wo, wi)
        } else if scene.has_transmission != 0 && b.kind == BSDF_DIELECTRIC {
            dielectric_eval(b.surface, wo, wi)
        } else if wi.z > 0.0 {
            b.surface.diffuse * INV_PI
        } else {
            Vec3::ZERO
        }
    }

    /// The solid-angle pdf of [`bsdf_sample`] choosing `wi` seen from `wo`.
    #[inline(always)]
    pub fn bsdf_pdf(scene: &Scene, b: Bsdf, wo: Vec3, wi: Vec3) -> f32 {
        if scene.has_metal_rough != 0 && b.kind == BSDF_METAL_ROUGH {
            metal_rough_pdf(b.surface, wo, wi)
        } else if scene.has_transmission != 0 && b.kind == BSDF_DIELECTRIC {
            dielectric_pdf(b.surface, wo, wi)
        } else {
            wi.z.max(0.0) * INV_PI
        }
    }

    /// A direction sampled from `wo` (pdf 0: none; `dielectric::DELTA_PDF`: a delta lobe's),
    /// drawing the uniforms it needs from `rng`: two for Lambert (cosine-weighted), three for
    /// metal-roughness and the dielectric (x, y sample the lobe that z picks).
    #[inline(always)]
    pub fn bsdf_sample(scene: &Scene, b: Bsdf, wo: Vec3, rng: &mut u32) -> BrdfSample {
        let u1 = random_float(rng);
        let u2 = random_float(rng);
        if scene.has_metal_rough != 0 && b.kind == BSDF_METAL_ROUGH {
            let u3 = random_float(rng);
            metal_rough_sample(b.surface, wo, Vec3::new(u1, u2, u3))
        } else if scene.has_transmission != 0 && b.kind == BSDF_DIELECTRIC {
            let u3 = random_float(rng);
            dielectric_sample(b.surface, wo, Vec3::new(u1, u2, u3))
        } else {
            let wi = cosine_sample_hemisphere(u1, u2);
            BrdfSample { dir: wi, pdf: wi.z * INV_PI, weight: b.surface.diffuse }
        }
    }

    /// The BSDF of a material in a scene with `Features::transmission` (instead of [`bsdf_at`]):
    /// glTF's transmissive share `transmission × (1 − metallic)` (the factor times the
    /// transmission texture's red channel) is a dielectric interface, the rest the
    /// metal-roughness BRDF with its metallic share renormalised to that rest. The uniform `u`
    /// picks one with those probabilities (each then weighted 1: the expected BSDF is glTF's
    /// mix, and light sampling and BSDF sampling at the point see the same pick). `flip` < 0:
    /// the viewer is behind the geometric front face (inside a volume), so the relative index
    /// is 1 / ior there (thin-walled surfaces: ior from either side).
    pub fn glass_at(scene: &Scene, material: MaterialData, material_index: u32, hit: Hit, flip: f32, u: f32) -> Bsdf {
        let glass = fetch_glass(scene, material_index);
        let params = fetch_metal_rough(scene, material_index);
        let base = base_color_at(scene, material, hit.triangle, hit.u, hit.v);
        let mut metallic = params.metallic;
        let mut roughness = params.roughness;
        let mut transmission = glass.transmission;
        if scene.has_textures != 0 && params.texture != NONE {
            let uv = texture_uv(scene, params.texture, hit.triangle, hit.u, hit.v);
            let mr = sample_data_texture(scene, params.texture, uv);
            roughness *= mr.y;
            metallic *= mr.z;
        }
        if scene.has_textures != 0 && glass.texture != NONE {
            let uv = texture_uv(scene, glass.texture, hit.triangle, hit.u, hit.v);
            transmission *= sample_data_texture(scene, glass.texture, uv).x;
        }
        let m = if metallic > 0.0 { metallic.min(1.0) } else { 0.0 };
        let t = if transmission > 0.0 { transmission.min(1.0) } else { 0.0 };
        let p_glass = t * (1.0 - m);
        if u < p_glass {
            let eta = if glass.thin || flip > 0.0 { glass.ior } else { 1.0 / glass.ior };
            return Bsdf { kind: BSDF_DIELECTRIC, surface: glass_surface(base, roughness, eta, glass.thin) };
        }
        let m_rest = if p_glass < 1.0 { (m / (1.0 - p_glass)).min(1.0) } else { 1.0 };
        Bsdf { kind: BSDF_METAL_ROUGH, surface: metal_rough_surface(base, m_rest, roughness, params.specular) }
    }
}
