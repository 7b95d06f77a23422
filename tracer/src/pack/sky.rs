//! The sky: its environment map with a CDF per row (in each texel's `w`) and the CDF over rows,
//! for importance sampling by luminance (`kernel::lights`); nothing for a scene without one.

use glam::Vec4;
use kernel_dsl::Texels;

use crate::kernel::lights::luminance;
use crate::scene::Sky;

/// The kernel's sky arrays.
pub(super) struct PackedSky {
    pub texels: Texels<Vec4>,
    pub rows: Texels<Vec4>,
    /// Mean radiance of the map weighted by solid angle (the sky light's power estimate).
    pub mean_radiance: f32,
}

pub(super) fn pack_sky(sky: Option<&Sky>) -> PackedSky {
    let mut sky_texels = Vec::new();
    let mut sky_rows = Vec::new();
    let mut mean_radiance = 0.0;
    if let Some(sky) = sky {
        let (w, h) = (sky.width as usize, sky.height as usize);
        let mut row_sums = Vec::with_capacity(h);
        sky_texels.reserve(w * h);
        for y in 0..h {
            // Weight by sin(theta): texels near the poles cover less solid angle.
            let sin_theta = (std::f32::consts::PI * (y as f32 + 0.5) / h as f32).sin();
            let weights: Vec<f64> =
                (0..w).map(|x| (luminance(sky.texels[y * w + x]) * sin_theta).max(0.0) as f64).collect();
            let total: f64 = weights.iter().sum();
            let mut acc = 0.0f64;
            for (x, wt) in weights.iter().enumerate() {
                acc += if total > 0.0 { wt / total } else { 1.0 / w as f64 };
                let cdf = if x + 1 == w { 1.0 } else { acc as f32 };
                sky_texels.push(sky.texels[y * w + x].extend(cdf));
            }
            row_sums.push(total);
        }
        let total: f64 = row_sums.iter().sum();
        let mut acc = 0.0f64;
        for (y, s) in row_sums.iter().enumerate() {
            acc += if total > 0.0 { s / total } else { 1.0 / h as f64 };
            let cdf = if y + 1 == h { 1.0 } else { acc as f32 };
            sky_rows.push(Vec4::new(cdf, 0.0, 0.0, 0.0));
        }
        mean_radiance = if total > 0.0 {
            // Mean of luminance * sin(theta) over the map, normalised by the mean of sin(theta) (2/π).
            (total / (w * h) as f64) as f32 / (2.0 / std::f32::consts::PI) * sky.intensity
        } else {
            0.0
        };
    }
    PackedSky { texels: Texels::new(sky_texels), rows: Texels::new(sky_rows), mean_radiance }
}
