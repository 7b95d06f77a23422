#[kernel_dsl::kernel]
pub mod metal_rough {
    //! The glTF 2.0 metal-roughness BRDF (the specification's Appendix B): a Lambert diffuse
    //! lobe under a GGX (Trowbridge–Reitz) specular lobe with height-correlated Smith
    //! visibility and Schlick's Fresnel, mixed by `metallic`:
    //!
    //! ```text
    //! c_diff = base × (1 − metallic)       f0 = lerp(0.04, base, metallic)      α = roughness²
    //! F = f0 + (1 − f0) (1 − |V·H|)^5
    //! f = (1 − F) c_diff / π  +  F D(α) V(α)
    //! ```
    //!
    //! Every function works in the local shading frame (the normal is +Z); `wo` points towards
    //! the viewer, `wi` towards the light, both unit length. Sampling picks the specular lobe
    //! with a Fresnel-weighted albedo estimate ([`specular_probability`]), samples it by its
    //! visible normals (Dupuy & Benyoub 2023, "Sampling Visible GGX Normals with Spherical
    //! Caps") and the diffuse lobe by the cosine; every pdf is the combined one of both lobes,
    //! which is what MIS with light sampling needs.

    use glam::{Vec3, Vec4};

    use crate::kernel::lights::luminance;
    use crate::kernel::sampling::{cos_sin_turns, cosine_sample_hemisphere, INV_PI, PI};
    use crate::kernel::scene_data::{fetch_metal_rough, MaterialData, Scene, NONE};
    use crate::kernel::texture_ref::texture_uv;
    use crate::kernel::textures::{base_color_at, sample_data_texture};

    /// Roughness is clamped to at least this (α ≥ 0.002025, Filament's limit for f32): below
    /// it the GGX peak (1 / (π α²)) and its pdf outgrow what f32 paths and sample weights
    /// represent well, and a mirror is indistinguishable from it at any image resolution.
    pub const MIN_ROUGHNESS: f32 = 0.045;
    /// Directions closer to the horizon than this cosine count as below it: the BRDF, its pdf
    /// and its samples are zero there, which keeps the visibility term (~1 / cos) finite.
    pub const MIN_COSINE: f32 = 1.0e-6;
    /// Normal-incidence reflectance of glTF's dielectric (IOR 1.5).
    pub const DIELECTRIC_F0: f32 = 0.04;

    /// A surface point's BRDF parameters.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Surface {
        /// Diffuse albedo `c_diff = base × (1 − metallic)`.
        pub diffuse: Vec3,
        /// Specular reflectance at normal incidence `f0 = lerp(0.04, base, metallic)`.
        pub f0: Vec3,
        /// GGX `α = roughness²`, roughness clamped to `[MIN_ROUGHNESS, 1]`.
        pub alpha: f32,
        /// 1: the specification's model; 0: Lambert only (the specular layer and its Fresnel
        /// left out), for materials the Lambert kernel renders (see `tracer::pack`).
        pub specular: f32,
    }

    /// A sampled direction: `dir` (local), its combined pdf (0: no sample) and the weight
    /// `f · cos / pdf`.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct BrdfSample {
        pub dir: Vec3,
        pub pdf: f32,
        pub weight: Vec3,
    }

    /// The BRDF parameters of a glTF material: base colour, metallic and roughness in [0, 1]
    /// (NaN counts as 0 metallic, full roughness).
    pub fn metal_rough_surface(base_color: Vec3, metallic: f32, roughness: f32, specular: f32) -> Surface {
        let m = if metallic > 0.0 { metallic.min(1.0) } else { 0.0 };
        let r = if roughness < 1.0 { roughness.max(MIN_ROUGHNESS) } else { 1.0 };
        Surface {
            diffuse: base_color * (1.0 - m),
            f0: Vec3::splat(DIELECTRIC_F0) * (1.0 - m) + base_color * m,
            alpha: r * r,
            specular,
        }
    }

    /// Schlick's Fresnel for the cosine `c` between the view (or light) and the half vector,
    /// scaled by the surface's `specular` switch.
    pub fn schlick_fresnel(s: Surface, c: f32) -> Vec3 {
        let m = (1.0 - c).clamp(0.0, 1.0);
        let m2 = m * m;
        (s.f0 + (Vec3::ONE - s.f0) * (m2 * m2 * m)) * s.specular
    }

    /// The GGX normal distribution D(h) for a unit half vector `h` (local), written as
    /// 1 / (π α² t²) with t = (h.x² + h.y²) / α² + h.z² so that it keeps its precision at
    /// small α (the textbook cos²(α² − 1) + 1 cancels).
    pub fn ggx_distribution(alpha: f32, h: Vec3) -> f32 {
        if !(h.z > 0.0) {
            0.0
        } else {
            let a2 = alpha * alpha;
            let t = (h.x * h.x + h.y * h.y) / a2 + h.z * h.z;
            1.0 / (PI * a2 * t * t)
        }
    }

    /// `sqrt(α² (1 − c²) + c²)`: the Smith Λ term's root for a direction at cosine `c`.
    pub fn smith_root(alpha: f32, c: f32) -> f32 {
        let a2 = alpha * alpha;
        (a2 + c * c * (1.0 - a2)).max(0.0).sqrt()
    }

    /// Height-correlated Smith visibility V = G2 / (4 |N·L| |N·V|) (glTF's `V_GGX`).
    pub fn smith_visibility(alpha: f32, nl: f32, nv: f32) -> f32 {
        let denominator = nl * smith_root(alpha, nv) + nv * smith_root(alpha, nl);
        if denominator > 0.0 {
            0.5 / denominator
        } else {
            0.0
        }
    }

    /// The BRDF f(wo, wi) (without the cosine); zero unless both directions are above the
    /// surface (by more than `MIN_COSINE`).
    pub fn metal_rough_eval(s: Surface, wo: Vec3, wi: Vec3) -> Vec3 {
        if !(wo.z > MIN_COSINE) || !(wi.z > MIN_COSINE) {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize();
        let f = schlick_fresnel(s, wo.dot(h));
        let specular = f * (ggx_distribution(s.alpha, h) * smith_visibility(s.alpha, wi.z, wo.z));
        (Vec3::ONE - f) * s.diffuse * INV_PI + specular
    }

    /// The probability of sampling the specular lobe when looking from `wo` (cosine `nv`):
    /// the specular lobe's Fresnel-weighted albedo estimate F(nv) against the diffuse lobe's
    /// (1 − F(nv)) c_diff, by luminance. Positive wherever the specular lobe is, below 1
    /// wherever the diffuse lobe is.
    pub fn specular_probability(s: Surface, nv: f32) -> f32 {
        let f = schlick_fresnel(s, nv);
        let specular = luminance(f);
        let diffuse = luminance((Vec3::ONE - f) * s.diffuse);
        if specular + diffuse > 0.0 {
            specular / (specular + diffuse)
        } else {
            1.0
        }
    }

    /// Solid-angle pdf of the reflected direction whose half vector is `h` under visible-normal
    /// sampling: D(h) G1(wo) / (4 wo.z), with G1(wo) / wo.z written without the division (it
    /// stays finite at grazing `wo`).
    pub fn vndf_reflection_pdf(alpha: f32, wo: Vec3, h: Vec3) -> f32 {
        ggx_distribution(alpha, h) / (2.0 * (wo.z + smith_root(alpha, wo.z)))
    }

    /// The combined pdf of [`metal_rough_sample`] for `wi` seen from `wo`.
    pub fn metal_rough_pdf(s: Surface, wo: Vec3, wi: Vec3) -> f32 {
        if !(wo.z > MIN_COSINE) || !(wi.z > MIN_COSINE) {
            return 0.0;
        }
        let p = specular_probability(s, wo.z);
        let h = (wo + wi).normalize();
        p * vndf_reflection_pdf(s.alpha, wo, h) + (1.0 - p) * wi.z * INV_PI
    }

    /// A GGX half vector distributed as the normals visible from `wo` (local, `wo.z > 0`), from
    /// two uniforms in [0, 1): the spherical-cap construction of Dupuy & Benyoub (2023).
    pub fn sample_ggx_vndf(alpha: f32, wo: Vec3, u1: f32, u2: f32) -> Vec3 {
        // The view direction in the hemisphere configuration (stretched by 1 / α).
        let v = Vec3::new(wo.x * alpha, wo.y * alpha, wo.z).normalize();
        // A point on the spherical cap that the visible hemisphere projects to.
        let cs = cos_sin_turns(u1);
        let z = (1.0 - u2) * (1.0 + v.z) - v.z;
        let sin_theta = (1.0 - z * z).clamp(0.0, 1.0).sqrt();
        let h = Vec3::new(sin_theta * cs.x, sin_theta * cs.y, z) + v;
        // Back to the ellipsoid configuration.
        Vec3::new(h.x * alpha, h.y * alpha, h.z.max(0.0)).normalize()
    }

    /// Samples a direction from `wo` with three uniforms in [0, 1): `u.z` picks the lobe,
    /// `u.x`, `u.y` sample it.
    pub fn metal_rough_sample(s: Surface, wo: Vec3, u: Vec3) -> BrdfSample {
        if !(wo.z > MIN_COSINE) {
            return BrdfSample { dir: Vec3::Z, pdf: 0.0, weight: Vec3::ZERO };
        }
        let wi = if u.z < specular_probability(s, wo.z) {
            let h = sample_ggx_vndf(s.alpha, wo, u.x, u.y);
            h * (2.0 * wo.dot(h)) - wo
        } else {
            cosine_sample_hemisphere(u.x, u.y)
        };
        let pdf = metal_rough_pdf(s, wo, wi);
        let weight = if pdf > 0.0 { metal_rough_eval(s, wo, wi) * (wi.z / pdf) } else { Vec3::ZERO };
        BrdfSample { dir: wi, pdf, weight }
    }

    /// The BRDF's directional albedo seen from cosine `nv` (the share of uniform incoming light
    /// it reflects), approximated without sampling: the diffuse lobe's `(1 − F(nv)) c_diff` plus
    /// the specular lobe's `f0 A + B`, with A and B from Karis' analytic fit of the split-sum
    /// integral ("Physically Based Shading on Mobile", 2014). The denoiser's guide divides a
    /// pixel's colour by it (`integrator::FirstHit`): under smooth lighting what remains is
    /// smooth even where roughness, metalness or a dark base colour vary.
    pub fn metal_rough_albedo(s: Surface, nv: f32) -> Vec3 {
        let c = nv.clamp(0.0, 1.0);
        let roughness = s.alpha.sqrt();
        let r = Vec4::new(-1.0, -0.0275, -0.572, 0.022) * roughness + Vec4::new(1.0, 0.0425, 1.04, -0.04);
        let a004 = (r.x * r.x).min((-9.28 * c).exp2()) * r.x + r.y;
        let scale = -1.04 * a004 + r.z;
        let bias = 1.04 * a004 + r.w;
        let specular = (s.f0 * scale + Vec3::splat(bias)) * s.specular;
        (Vec3::ONE - schlick_fresnel(s, c)) * s.diffuse + specular.max(Vec3::ZERO)
    }

    /// The BRDF parameters of material `material_index` (`material`: its fetched data) at
    /// barycentrics (u, v) of `triangle`: the factors times the base-colour and metal-roughness
    /// textures (glTF: roughness in green, metallic in blue).
    pub fn surface_at(
        scene: &Scene,
        material: MaterialData,
        material_index: u32,
        triangle: u32,
        u: f32,
        v: f32,
    ) -> Surface {
        let params = fetch_metal_rough(scene, material_index);
        let base = base_color_at(scene, material, triangle, u, v);
        let mut metallic = params.metallic;
        let mut roughness = params.roughness;
        if scene.has_textures != 0 && params.texture != NONE {
            let mr = sample_data_texture(scene, params.texture, texture_uv(scene, params.texture, triangle, u, v));
            roughness *= mr.y;
            metallic *= mr.z;
        }
        metal_rough_surface(base, metallic, roughness, params.specular)
    }
}
