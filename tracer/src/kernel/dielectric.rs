#[kernel_dsl::kernel]
pub mod dielectric {
    //! A rough dielectric interface (glass, water) after Walter et al. 2007, "Microfacet Models
    //! for Refraction through Rough Surfaces", with the metal-roughness lobe's GGX distribution,
    //! visible-normal sampling and height-correlated Smith masking (`kernel::metal_rough`):
    //!
    //! ```text
    //! reflection   f_r = F(wo·h) D(h) G2 / (4 |wo.z| |wi.z|)                   h = normalize(wo + wi)
    //! refraction   f_t = (1 − F) D(h) G2 |wi·h| |wo·h| / (|wi.z| |wo.z| (wi·h + wo·h / η)²) / η²
    //!                                                                        h = normalize(wo + η wi)
    //! ```
    //!
    //! F is the exact (unpolarised) Fresnel reflectance of the interface, 1 beyond the critical
    //! angle (total internal reflection). η is the relative index: that of the side `wi`
    //! refracts into over that of `wo`'s side. The 1 / η² is radiance's: a path tracer carrying
    //! radiance from the camera must scale it by the squared ratio of the indices at each
    //! crossing (Veach 1997, §5.2), so a path that enters and leaves glass keeps its radiance.
    //! Refraction is tinted by the transmission colour (glTF: the base colour); reflection is
    //! not.
    //!
    //! Sampling draws a visible normal, then reflects with probability F and refracts
    //! otherwise: the pdf of each side is F or 1 − F times the visible-normal pdf carried
    //! through the reflection or refraction Jacobian. Below `MIN_ROUGHNESS`, or with η within
    //! [`INDEX_MATCHED`] of 1, the lobe is a delta (a smooth interface): [`dielectric_eval`] and [`dielectric_pdf`] are 0 and
    //! [`dielectric_sample`] returns the mirror or the refracted direction with pdf
    //! [`DELTA_PDF`] and weight 1 or tint / η², never a division by a vanishing pdf.
    //!
    //! Thin-walled surfaces (no volume behind them: glTF's `KHR_materials_transmission`
    //! without `KHR_materials_volume`) transmit without bending: the refracted direction is the
    //! reflected one mirrored through the surface plane, and as the ray enters and leaves the
    //! same sheet there is no η² (and η is always the material's, from either side).
    //!
    //! Directions are local to the shading frame, whose normal faces the viewer (`wo.z > 0`);
    //! `wi.z < 0` is transmission. The parameters travel in the BSDF interface's [`Surface`]
    //! (so that scenes without glass carry the interface they had): see [`glass_surface`].

    use glam::Vec3;

    use crate::kernel::metal_rough::{
        ggx_distribution, sample_ggx_vndf, smith_root, smith_visibility, vndf_reflection_pdf, BrdfSample, Surface,
        MIN_COSINE, MIN_ROUGHNESS,
    };

    /// The pdf a delta lobe's sample reports: not a density (no direction has one), negative
    /// so that `!(pdf > 0)` callers treat it as "not comparable with light sampling", distinct
    /// from 0 (no sample).
    pub const DELTA_PDF: f32 = -1.0;

    /// Relative indices within this of 1 make a (nearly) index-matched interface, whose
    /// rough refraction lobe collapses onto −wo: the refraction half vector `wo + η wi` is a
    /// difference of nearly equal vectors that f32 cannot resolve (at η = 1 it vanishes, and
    /// the rough lobe's samples had no pdf: light was lost). Such an interface is a delta lobe
    /// (reflecting at most ((η − 1) / (η + 1))² = 2.5e-5, by Fresnel, as any smooth one);
    /// what is lost is the spread of a transmitted lobe under 1 % of the roughness's.
    pub const INDEX_MATCHED: f32 = 0.01;

    /// The BSDF parameters of a dielectric interface in the interface's [`Surface`]:
    /// `diffuse` the transmission tint, `f0.x` the relative index η (the far side's over the
    /// viewer's side), `f0.y` 1 for a thin-walled surface (else 0), `alpha` the GGX α (0: a
    /// smooth or index-matched interface, a delta lobe), `specular` 1.
    pub fn glass_surface(tint: Vec3, roughness: f32, eta: f32, thin: bool) -> Surface {
        let rough = roughness >= MIN_ROUGHNESS && !((eta - 1.0).abs() < INDEX_MATCHED);
        let alpha = if rough { roughness.min(1.0) * roughness.min(1.0) } else { 0.0 };
        let thin_flag = if thin { 1.0 } else { 0.0 };
        Surface { diffuse: tint, f0: Vec3::new(eta, thin_flag, 0.0), alpha, specular: 1.0 }
    }

    /// Fresnel reflectance of a dielectric interface for the cosine `cos_i` (> 0) between the
    /// incident direction and the (micro)normal, with relative index `eta` (transmitted side
    /// over incident side): 1 under total internal reflection.
    pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
        let c = cos_i.clamp(0.0, 1.0);
        let sin2_t = (1.0 - c * c) / (eta * eta);
        if sin2_t >= 1.0 {
            return 1.0;
        }
        let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
        let rs = (c - eta * cos_t) / (c + eta * cos_t);
        let rp = (eta * c - cos_t) / (eta * c + cos_t);
        0.5 * (rs * rs + rp * rp)
    }

    /// `wo` (unit, `wo·h > 0`) refracted through the microfacet with normal `h` into the side of
    /// relative index `eta`; the caller has checked there is no total internal reflection.
    pub fn refract_dir(wo: Vec3, h: Vec3, eta: f32) -> Vec3 {
        let c = wo.dot(h);
        let sin2_t = (1.0 - c * c) / (eta * eta);
        let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
        (h * (c / eta - cos_t) - wo / eta).normalize()
    }

    /// Whether `s` is a smooth interface (a delta lobe).
    pub fn is_delta(s: Surface) -> bool {
        !(s.alpha > 0.0)
    }

    /// The generalised half vector of a refraction from `wo` to `wi` (`wi.z < 0`), on the
    /// viewer's side (`h.z ≥ 0`); zero where there is none (η = 1 and wi = −wo).
    pub fn refraction_half(wo: Vec3, wi: Vec3, eta: f32) -> Vec3 {
        let h = wo + wi * eta;
        let len = h.length();
        if !(len > 0.0) {
            return Vec3::ZERO;
        }
        if h.z < 0.0 {
            h / -len
        } else {
            h / len
        }
    }

    /// f(wo, wi) without the cosine (0 for a delta lobe, and unless both directions are more
    /// than `MIN_COSINE` off the surface).
    pub fn dielectric_eval(s: Surface, wo: Vec3, wi: Vec3) -> Vec3 {
        if is_delta(s) || !(wo.z > MIN_COSINE) || !(wi.z.abs() > MIN_COSINE) {
            return Vec3::ZERO;
        }
        let eta = s.f0.x;
        if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            let f = fresnel_dielectric(wo.dot(h), eta);
            return Vec3::splat(f * ggx_distribution(s.alpha, h) * smith_visibility(s.alpha, wi.z, wo.z));
        }
        if s.f0.y > 0.0 {
            // Thin-walled: the transmitted direction is a reflected one mirrored through the sheet.
            let wr = Vec3::new(wi.x, wi.y, -wi.z);
            let h = (wo + wr).normalize();
            let f = fresnel_dielectric(wo.dot(h), eta);
            return s.diffuse * ((1.0 - f) * ggx_distribution(s.alpha, h) * smith_visibility(s.alpha, wr.z, wo.z));
        }
        let h = refraction_half(wo, wi, eta);
        let ho = wo.dot(h);
        let hi = wi.dot(h);
        // Only microfacets facing the viewer, and with the light behind them, refract.
        if !(ho > 0.0) || !(hi < 0.0) {
            return Vec3::ZERO;
        }
        let f = fresnel_dielectric(ho, eta);
        let denom = hi + ho / eta;
        // 4 V = G2 / (|wi.z| wo.z).
        let g = 4.0 * smith_visibility(s.alpha, -wi.z, wo.z);
        let ft = (1.0 - f) * ggx_distribution(s.alpha, h) * g * (-hi * ho) / (denom * denom * eta * eta);
        s.diffuse * ft
    }

    /// The solid-angle pdf of [`dielectric_sample`] choosing `wi` from `wo` (0 for a delta lobe).
    pub fn dielectric_pdf(s: Surface, wo: Vec3, wi: Vec3) -> f32 {
        if is_delta(s) || !(wo.z > MIN_COSINE) || !(wi.z.abs() > MIN_COSINE) {
            return 0.0;
        }
        let eta = s.f0.x;
        if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            return fresnel_dielectric(wo.dot(h), eta) * vndf_reflection_pdf(s.alpha, wo, h);
        }
        if s.f0.y > 0.0 {
            let h = (wo + Vec3::new(wi.x, wi.y, -wi.z)).normalize();
            return (1.0 - fresnel_dielectric(wo.dot(h), eta)) * vndf_reflection_pdf(s.alpha, wo, h);
        }
        let h = refraction_half(wo, wi, eta);
        let ho = wo.dot(h);
        let hi = wi.dot(h);
        if !(ho > 0.0) || !(hi < 0.0) {
            return 0.0;
        }
        let denom = hi + ho / eta;
        // The visible-normal density D(h) G1(wo) (wo·h) / wo.z, times the refraction Jacobian
        // |wi·h| / (wi·h + wo·h / η)².
        let visible = ggx_distribution(s.alpha, h) * ho * 2.0 / (wo.z + smith_root(s.alpha, wo.z));
        (1.0 - fresnel_dielectric(ho, eta)) * visible * (-hi) / (denom * denom)
    }

    /// Samples a direction from `wo` with three uniforms in [0, 1): `u.x`, `u.y` draw a visible
    /// microfacet normal, `u.z` reflection (below F) or refraction. A delta lobe's sample has pdf
    /// [`DELTA_PDF`]; pdf 0 is no sample.
    pub fn dielectric_sample(s: Surface, wo: Vec3, u: Vec3) -> BrdfSample {
        if !(wo.z > MIN_COSINE) {
            return BrdfSample { dir: Vec3::Z, pdf: 0.0, weight: Vec3::ZERO };
        }
        let eta = s.f0.x;
        let thin = s.f0.y > 0.0;
        if is_delta(s) {
            let f = fresnel_dielectric(wo.z, eta);
            if u.z < f {
                return BrdfSample { dir: Vec3::new(-wo.x, -wo.y, wo.z), pdf: DELTA_PDF, weight: Vec3::ONE };
            }
            if thin {
                return BrdfSample { dir: -wo, pdf: DELTA_PDF, weight: s.diffuse };
            }
            let wt = refract_dir(wo, Vec3::Z, eta);
            return BrdfSample { dir: wt, pdf: DELTA_PDF, weight: s.diffuse / (eta * eta) };
        }
        let h = sample_ggx_vndf(s.alpha, wo, u.x, u.y);
        let ho = wo.dot(h);
        let f = fresnel_dielectric(ho, eta);
        let reflected = h * (2.0 * ho) - wo;
        let mut wi = reflected;
        let reflect = u.z < f;
        if !reflect {
            if thin {
                wi = Vec3::new(reflected.x, reflected.y, -reflected.z);
            } else {
                wi = refract_dir(wo, h, eta);
            }
        }
        // A reflection below the surface or a refraction above it is no sample.
        if (reflect && !(wi.z > 0.0)) || (!reflect && !(wi.z < 0.0)) {
            return BrdfSample { dir: wi, pdf: 0.0, weight: Vec3::ZERO };
        }
        let pdf = dielectric_pdf(s, wo, wi);
        let weight = if pdf > 0.0 { dielectric_eval(s, wo, wi) * (wi.z.abs() / pdf) } else { Vec3::ZERO };
        BrdfSample { dir: wi, pdf, weight }
    }
}
