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

    use crate::kernel::metal_rough::{
        metal_rough_eval, metal_rough_pdf, metal_rough_sample, surface_at, BrdfSample, Surface,
    };
    use crate::kernel::rng::random_float;
    use crate::kernel::sampling::{cosine_sample_hemisphere, INV_PI};
    use crate::kernel::scene_data::{base_color_at, MaterialData, Scene};
    use crate::kernel::traverse::Hit;

    /// Lambert: a diffuse albedo (`Bsdf::surface.diffuse`), the only kind of a scene without
    /// `Features::metal_rough`.
    pub const BSDF_LAMBERT: u32 = 0;
    /// glTF metal-roughness (`kernel::metal_rough`): every material of a scene with
    /// `Features::metal_rough`, its Lambert-only materials included (`Surface::specular` 0).
    pub const BSDF_METAL_ROUGH: u32 = 1;

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
        } else {
            ns
        }
    }

    /// f(wo, wi), without the cosine.
    #[inline(always)]
    pub fn bsdf_eval(scene: &Scene, b: Bsdf, wo: Vec3, wi: Vec3) -> Vec3 {
        if scene.has_metal_rough != 0 && b.kind == BSDF_METAL_ROUGH {
            metal_rough_eval(b.surface, wo, wi)
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
        } else {
            wi.z.max(0.0) * INV_PI
        }
    }

    /// A direction sampled from `wo` (pdf 0: none), drawing the uniforms it needs from `rng`:
    /// two for Lambert (cosine-weighted), three for metal-roughness (x, y sample the lobe
    /// that z picks).
    #[inline(always)]
    pub fn bsdf_sample(scene: &Scene, b: Bsdf, wo: Vec3, rng: &mut u32) -> BrdfSample {
        let u1 = random_float(rng);
        let u2 = random_float(rng);
        if scene.has_metal_rough != 0 && b.kind == BSDF_METAL_ROUGH {
            let u3 = random_float(rng);
            metal_rough_sample(b.surface, wo, Vec3::new(u1, u2, u3))
        } else {
            let wi = cosine_sample_hemisphere(u1, u2);
            BrdfSample { dir: wi, pdf: wi.z * INV_PI, weight: b.surface.diffuse }
        }
    }
}
