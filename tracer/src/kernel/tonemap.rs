#[kernel_dsl::kernel]
pub mod tonemap {
    //! Display transforms: linear radiance to display values, one implementation for the CPU
    //! (PNG output) and the shaders (the browser's display pass). Exposure first (a scale of
    //! `2^EV`), then a tone curve to linear display values in [0, 1], then the sRGB encoding.
    //! Operators: Khronos PBR Neutral (the default: it keeps base colours recognisable, as
    //! glTF product renders want), the fitted ACES curve (Stephen Hill's fit of the RRT + ODT),
    //! AgX (Troy Sobotka's, in Benjamin Wrensch's minimal form with the default look), and
    //! `none`, a clamp to [0, 1].

    use glam::Vec3;

    pub const TONEMAP_NONE: u32 = 0;
    pub const TONEMAP_NEUTRAL: u32 = 1;
    pub const TONEMAP_ACES: u32 = 2;
    pub const TONEMAP_AGX: u32 = 3;

    /// A channel of radiance made displayable: NaN, infinities and negatives become 0.
    pub fn displayable(c: f32) -> f32 {
        if c.is_finite() && c > 0.0 {
            c
        } else {
            0.0
        }
    }

    pub fn clamp_unit(c: f32) -> f32 {
        c.clamp(0.0, 1.0)
    }

    pub fn clamp_unit3(c: Vec3) -> Vec3 {
        Vec3::new(clamp_unit(c.x), clamp_unit(c.y), clamp_unit(c.z))
    }

    /// Khronos PBR Neutral (the reference implementation of the Khronos specification):
    /// colours below 0.76 pass unchanged (but for a small toe offset), brighter ones are
    /// compressed towards white, desaturating as they go.
    pub fn pbr_neutral(color: Vec3) -> Vec3 {
        let start_compression = 0.8 - 0.04;
        let desaturation = 0.15;
        let x = color.min_element();
        let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
        let c = color - Vec3::splat(offset);
        let peak = c.max_element();
        if peak < start_compression {
            return c;
        }
        let d = 1.0 - start_compression;
        let new_peak = 1.0 - d * d / (peak + d - start_compression);
        let scaled = c * (new_peak / peak);
        let g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
        scaled + (Vec3::splat(new_peak) - scaled) * g
    }

    /// The RRT + ODT curve of Stephen Hill's ACES fit, per channel.
    pub fn rrt_and_odt_fit(v: f32) -> f32 {
        let a = v * (v + 0.0245786) - 0.000090537;
        let b = v * (0.983729 * v + 0.432951) + 0.238081;
        a / b
    }

    /// ACES, fitted (Stephen Hill, BakingLab): sRGB to the ACES working space (with the RRT's
    /// saturation), the fitted curve, back to sRGB (with the ODT's saturation).
    pub fn aces_fitted(color: Vec3) -> Vec3 {
        let v = Vec3::new(
            0.59719 * color.x + 0.35458 * color.y + 0.04823 * color.z,
            0.076 * color.x + 0.90834 * color.y + 0.01566 * color.z,
            0.0284 * color.x + 0.13383 * color.y + 0.83777 * color.z,
        );
        let f = Vec3::new(rrt_and_odt_fit(v.x), rrt_and_odt_fit(v.y), rrt_and_odt_fit(v.z));
        let out = Vec3::new(
            1.60475 * f.x - 0.53108 * f.y - 0.07367 * f.z,
            -0.10208 * f.x + 1.10813 * f.y - 0.00605 * f.z,
            -0.00327 * f.x - 0.07276 * f.y + 1.07602 * f.z,
        );
        clamp_unit3(out)
    }

    /// AgX's sigmoid on the log-encoded [0, 1] range: the 6th-order polynomial fit of the
    /// default contrast curve (mean squared error 3.7e-6).
    pub fn agx_contrast(x: f32) -> f32 {
        let x2 = x * x;
        let x4 = x2 * x2;
        15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x - 0.00232
    }

    /// log2 exposure range AgX maps to [0, 1], as stops around middle grey 0.18.
    pub const AGX_MIN_EV: f32 = -12.47393;
    pub const AGX_MAX_EV: f32 = 4.026069;

    pub fn agx_log_encode(v: f32) -> f32 {
        let ev = v.max(1e-10).log2().clamp(AGX_MIN_EV, AGX_MAX_EV);
        (ev - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV)
    }

    /// AgX: the inset matrix (which desaturates bright colours towards white instead of
    /// skewing their hue), log encoding, the sigmoid, the inverse matrix, and the display's
    /// 2.2 power back to linear display values.
    pub fn agx(color: Vec3) -> Vec3 {
        let inset = Vec3::new(
            0.842479062253094 * color.x + 0.0784335999999992 * color.y + 0.0792237451477643 * color.z,
            0.0423282422610123 * color.x + 0.878468636469772 * color.y + 0.0791661274605434 * color.z,
            0.0423756549057051 * color.x + 0.0784336 * color.y + 0.879142973793104 * color.z,
        );
        let s = Vec3::new(
            agx_contrast(agx_log_encode(inset.x)),
            agx_contrast(agx_log_encode(inset.y)),
            agx_contrast(agx_log_encode(inset.z)),
        );
        let outset = Vec3::new(
            1.19687900512017 * s.x - 0.0980208811401368 * s.y - 0.0990297440797205 * s.z,
            -0.0528968517574562 * s.x + 1.15190312990417 * s.y - 0.0989611768448433 * s.z,
            -0.0529716355144438 * s.x - 0.0980434501171241 * s.y + 1.15107367264116 * s.z,
        );
        Vec3::new(clamp_unit(outset.x).powf(2.2), clamp_unit(outset.y).powf(2.2), clamp_unit(outset.z).powf(2.2))
    }

    /// Linear radiance to linear display values in [0, 1]: `exposure_scale` (2^EV) first,
    /// then `operator` (one of the `TONEMAP_` consts; unknown ones clamp, as `none`).
    pub fn tone_map(radiance: Vec3, operator: u32, exposure_scale: f32) -> Vec3 {
        let c = Vec3::new(
            displayable(radiance.x * exposure_scale),
            displayable(radiance.y * exposure_scale),
            displayable(radiance.z * exposure_scale),
        );
        if operator == TONEMAP_NEUTRAL {
            clamp_unit3(pbr_neutral(c))
        } else if operator == TONEMAP_ACES {
            aces_fitted(c)
        } else if operator == TONEMAP_AGX {
            agx(c)
        } else {
            clamp_unit3(c)
        }
    }

    /// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
    pub fn linear_to_srgb(c: f32) -> f32 {
        if c <= 0.0031308 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        }
    }

    /// Linear radiance to sRGB-encoded display values in [0, 1] ([`tone_map`], then the sRGB
    /// encoding): what a PNG stores and what the page shows.
    pub fn display_srgb(radiance: Vec3, operator: u32, exposure_scale: f32) -> Vec3 {
        let c = tone_map(radiance, operator, exposure_scale);
        Vec3::new(linear_to_srgb(c.x), linear_to_srgb(c.y), linear_to_srgb(c.z))
    }
}
