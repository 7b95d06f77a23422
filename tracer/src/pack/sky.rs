//! The sky: its environment map with a CDF per row (in each texel's `w`) and the CDF over rows,
//! for importance sampling by luminance (`kernel::lights`); nothing for a scene without one.
//!
//! Each CDF has a **guide table** (Chen and Asau's cutpoint method): bucket `k` of `K` (a power
//! of two) holds the first index whose CDF value exceeds `k / K`, so the kernel's binary search
//! for a uniform `u` starts between buckets `floor(u K)` and the next instead of over the whole
//! row: 2-3 steps instead of 9-10 fetches scattered over the map, for the very index the full
//! search finds (`K` a power of two makes `u K` and `k / K` exact in `f32`). Layout of
//! `sky_rows`: texel `r < H` (the map's height) is `[marginal CDF of row r, row guide entry r
//! (for r < K_rows, else 0), then in texel 0 only K_rows and K_columns (else 0, 0)]`; after
//! them the column guides, `K_columns` entries per row, four to a texel: entry
//! `i = r K_columns + k` is component `i % 4` of texel `H + i / 4`.

use glam::Vec4;
use kernel_dsl::Texels;

use crate::kernel::lights::luminance;
use crate::scene::Sky;

/// The kernel's sky arrays.
pub(crate) struct PackedSky {
    pub texels: Texels<Vec4>,
    pub rows: Texels<Vec4>,
    /// Mean radiance of the map weighted by solid angle (the sky light's power estimate).
    pub mean_radiance: f32,
}

pub(crate) fn pack_sky(sky: Option<&Sky>) -> PackedSky {
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
        sky_rows = rows_with_guides(&sky_texels, &sky_rows, w, h);
        mean_radiance = if total > 0.0 {
            // Mean of luminance * sin(theta) over the map, normalised by the mean of sin(theta) (2/π).
            (total / (w * h) as f64) as f32 / (2.0 / std::f32::consts::PI) * sky.intensity
        } else {
            0.0
        };
    }
    PackedSky { texels: Texels::new(sky_texels), rows: Texels::new(sky_rows), mean_radiance }
}

/// Columns per bucket of a row's guide table, at most (fewer where the width is not a power of
/// two): a quarter of the row CDF's entries, so the guides add 1/16 of the map's bytes.
const COLUMNS_PER_BUCKET: usize = 4;

/// The largest power of two at most `n` (at least 1).
fn buckets_for(n: usize) -> usize {
    1 << n.max(1).ilog2()
}

/// Buckets of the row CDF's guide and of each row's column CDF's, for a `width` x `height` map.
pub(crate) fn guide_buckets(width: usize, height: usize) -> (usize, usize) {
    (buckets_for(height), buckets_for(width / COLUMNS_PER_BUCKET))
}

/// The guide table of `cdf` (non-decreasing, its last entry 1): per bucket `k` of `buckets`,
/// the first index whose value exceeds `k / buckets` (the last index where none does), which
/// is what the kernel's search returns for `u = k / buckets`.
// `!(value > threshold)`: the kernel's search steps past a value that is not above `u`, NaN
// included; the guide must step past the same values.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn guide(cdf: impl Fn(usize) -> f32, len: usize, buckets: usize) -> impl Iterator<Item = u32> {
    let mut j = 0;
    (0..buckets).map(move |k| {
        let threshold = k as f32 / buckets as f32;
        while j + 1 < len && !(cdf(j) > threshold) {
            j += 1;
        }
        j as u32
    })
}

/// `sky_rows` for the map `texels` (`width` x `height`, each row's CDF in `w`) whose first
/// `height` entries hold the marginal CDF in `x`: those entries with the row guide and the
/// bucket counts, then the column guides (the module's layout). Bundles are checked against it.
pub(crate) fn rows_with_guides(texels: &[Vec4], rows: &[Vec4], width: usize, height: usize) -> Vec<Vec4> {
    let (row_buckets, column_buckets) = guide_buckets(width, height);
    let marginal = |y: usize| rows[y].x;
    let mut out: Vec<Vec4> = (0..height).map(|y| Vec4::new(marginal(y), 0.0, 0.0, 0.0)).collect();
    for (row, g) in out.iter_mut().zip(guide(marginal, height, row_buckets)) {
        row.y = g as f32;
    }
    if let Some(first) = out.first_mut() {
        first.z = row_buckets as f32;
        first.w = column_buckets as f32;
    }
    let columns: Vec<f32> = (0..height)
        .flat_map(|y| guide(move |x| texels[y * width + x].w, width, column_buckets))
        .map(|g| g as f32)
        .collect();
    out.extend(columns.chunks(4).map(|c| {
        let mut texel = [0.0; 4];
        texel[..c.len()].copy_from_slice(c);
        Vec4::from_array(texel)
    }));
    out
}

/// How many texels `sky_rows` has for a `width` x `height` map ([`rows_with_guides`]).
pub(crate) fn rows_len(width: usize, height: usize) -> usize {
    height + (height * guide_buckets(width, height).1).div_ceil(4)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::kernel::lights::{search_sky_column, search_sky_row};
    use crate::kernel::scene_data::Scene as KernelScene;

    /// The kernel's scene holding only `sky`, packed.
    fn kernel_scene(sky: &Sky) -> KernelScene {
        let packed = pack_sky(Some(sky));
        assert_eq!(packed.rows.len(), rows_len(sky.width as usize, sky.height as usize));
        KernelScene {
            sky: packed.texels,
            sky_rows: packed.rows,
            sky_width: sky.width,
            sky_height: sky.height,
            ..Default::default()
        }
    }

    /// The first index in `0..len` whose `cdf` exceeds `u` (the last if none): the search over
    /// the whole CDF that the guides shortcut.
    fn full_search(cdf: impl Fn(u32) -> f32, len: u32, u: f32) -> u32 {
        (0..len).find(|&j| cdf(j) > u).unwrap_or(len - 1)
    }

    fn sky(width: u32, height: u32, radiance: impl Fn(u32, u32) -> f32) -> Sky {
        let texels = (0..width * height).map(|i| Vec3::splat(radiance(i % width, i / width))).collect();
        Sky { width, height, texels, intensity: 1.0, rotation: 0.0, file: None }
    }

    /// Uniforms to search for: random ones, every bucket boundary of a guide with `buckets`
    /// buckets and the f32 just below each (where a wrong bucket would show), and the ends.
    fn uniforms(buckets: u32) -> Vec<f32> {
        let mut state = 12345u32;
        let mut us: Vec<f32> = (0..4000).map(|_| crate::kernel::rng::random_float(&mut state)).collect();
        for k in 0..buckets {
            let edge = k as f32 / buckets as f32;
            us.push(edge);
            us.push(f32::from_bits(edge.to_bits().saturating_sub(1)));
        }
        us.extend([0.0, 0.999_999_94]);
        us
    }

    #[test]
    fn guided_searches_find_the_texel_a_full_search_finds() {
        let skies = [
            // A sun: one texel with most of the power, rows of nothing around it.
            sky(64, 32, |x, y| {
                if (x, y) == (40, 9) {
                    1.0e6
                } else if y < 16 {
                    0.01
                } else {
                    0.0
                }
            }),
            // Widths and heights that are not powers of two, and thin maps.
            sky(37, 13, |x, y| ((x * 7 + y * 3) % 11) as f32),
            sky(1, 9, |_, y| y as f32),
            sky(9, 1, |x, _| (x % 3) as f32),
            sky(5, 3, |_, _| 0.0),
            sky(1, 1, |_, _| 2.0),
        ];
        for (n, sky) in skies.iter().enumerate() {
            let scene = kernel_scene(sky);
            let (row_buckets, column_buckets) = guide_buckets(sky.width as usize, sky.height as usize);
            for u in uniforms(row_buckets as u32) {
                let row = search_sky_row(&scene, u);
                let want = full_search(|j| scene.sky_rows.fetch(j).x, sky.height, u);
                assert_eq!(row, want, "sky {n}: row for u = {u}");
            }
            for row in 0..sky.height {
                for u in uniforms(column_buckets as u32) {
                    let base = row * sky.width;
                    let want = full_search(|j| scene.sky.fetch(base + j).w, sky.width, u);
                    assert_eq!(search_sky_column(&scene, row, u), want, "sky {n}: row {row}, column for u = {u}");
                }
            }
        }
    }

    #[test]
    fn guides_take_a_sixteenth_of_the_map_and_bucket_by_powers_of_two() {
        assert_eq!(guide_buckets(1024, 512), (512, 256));
        assert_eq!(guide_buckets(1000, 500), (256, 128));
        assert_eq!(guide_buckets(3, 1), (1, 1));
        // 512 rows, then 512 x 256 column entries four to a texel: 1/16 of the 512 x 1024 map.
        assert_eq!(rows_len(1024, 512), 512 + 512 * 64);
    }
}
