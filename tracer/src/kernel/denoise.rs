#[kernel_dsl::kernel]
pub mod denoise {
    //! The denoiser's filter, written once for every runtime (its guide, each path's first hit,
    //! comes from the path tracer: `integrator::render_guided_sample`): one pass of an
    //! edge-avoiding à-trous wavelet filter (Dammertz et al. 2010) with SVGF's edge-stopping
    //! functions (Schied et al. 2017): a 5x5 B3-spline kernel at a growing step, weighted by
    //! normal, depth and luminance, where the luminance weight is scaled by the pixel's noise
    //! (its variance). As samples accumulate the variance falls, the luminance weight closes
    //! and the filter leaves the image as it is: the result converges to the unbiased one.
    //!
    //! The filter works on demodulated illumination (colour less the emission the camera sees
    //! directly, divided by albedo, so texture detail and light sources are not blurred) and the
    //! host remodulates (`tracer::denoise`).

    use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};
    use kernel_dsl::Texels;

    use crate::kernel::lights::luminance;

    /// À-trous passes: steps 1, 2, 4, 8 (a 61-pixel footprint). A fifth pass (step 16) measured
    /// 0.4 dB worse at 256 spp on the Cornell box (relative MSE) and barely better at 16.
    pub const ATROUS_ITERATIONS: u32 = 4;
    /// Normal weight `max(0, n_p · n_q)^SIGMA_NORMAL` (SVGF's σn; it uses 128). Tight (half
    /// weight at 2.1°) because the guide's normal is the shading normal: on a normal-mapped,
    /// glossy surface (DamagedHelmet) the illumination follows the map's bumps, real detail
    /// that σn 128 blurred (-1.8 dB at 256 spp at 48x48, -2.6 at 128x128 under
    /// venice_sunset; at 1024, -0.3 and -0.1). Flat walls are not affected (their normals
    /// agree); the Cornell box lost 0.1 dB at 16 spp (`examples/denoise_quality/`).
    pub const SIGMA_NORMAL: f32 = 1024.0;
    /// Depth weight scale: depth differences against the local depth gradient (SVGF's σz).
    pub const SIGMA_DEPTH: f32 = 1.0;
    /// Luminance weight scale: luminance differences against the noise's standard deviation (SVGF's σl).
    pub const SIGMA_LUMINANCE: f32 = 4.0;
    /// Albedo channels below this are not divided out (a black surface keeps its colour as its
    /// illumination), so demodulation never divides by zero.
    pub const MIN_ALBEDO: f32 = 0.01;

    /// The image one à-trous pass reads, per pixel: `color` the demodulated illumination (rgb)
    /// and its variance (w); `guide` the normal (xyz) and depth (w).
    #[resources]
    #[derive(Clone, Debug, Default)]
    pub struct FilterImage {
        pub color: Texels<Vec4>,
        pub guide: Texels<Vec4>,
        pub width: u32,
        pub height: u32,
        /// This pass's step between taps, in pixels (1, 2, 4, ...).
        pub step: u32,
    }

    /// The B3-spline kernel's weight at tap `i` (-2..=2): 1/16, 1/4, 3/8, 1/4, 1/16.
    pub fn b3_weight(i: i32) -> f32 {
        if i == 0 {
            0.375
        } else if i == 1 || i == -1 {
            0.25
        } else {
            0.0625
        }
    }

    /// Depth at pixel (x, y), clamped to the image.
    pub fn guide_depth(image: &FilterImage, x: i32, y: i32) -> f32 {
        let cx = x.clamp(0, image.width as i32 - 1);
        let cy = y.clamp(0, image.height as i32 - 1);
        image.guide.fetch((cy * image.width as i32 + cx) as u32).w
    }

    /// The smaller one-sided depth difference at (x, y) along an axis: the surface's own
    /// gradient, not the jump at a silhouette (where one side is another surface or the sky).
    pub fn depth_slope(image: &FilterImage, x: i32, y: i32, dx: i32, dy: i32) -> f32 {
        let z = guide_depth(image, x, y);
        let ahead = (guide_depth(image, x + dx, y + dy) - z).abs();
        let behind = (z - guide_depth(image, x - dx, y - dy)).abs();
        ahead.min(behind)
    }

    /// The variance at pixel (x, y) blurred by a 3x3 Gaussian (SVGF's g(var)): a variance
    /// estimated from few samples is itself noisy, and a pixel whose samples happened to agree
    /// would otherwise never be filtered.
    pub fn blurred_variance(image: &FilterImage, x: i32, y: i32) -> f32 {
        let mut sum = 0.0f32;
        let mut total = 0.0f32;
        let mut dy = -1;
        while dy <= 1 {
            let mut dx = -1;
            while dx <= 1 {
                let qx = x + dx;
                let qy = y + dy;
                if qx >= 0 && qx < image.width as i32 && qy >= 0 && qy < image.height as i32 {
                    let k = (if dx == 0 { 0.5 } else { 0.25 }) * (if dy == 0 { 0.5 } else { 0.25 });
                    sum += image.color.fetch((qy * image.width as i32 + qx) as u32).w * k;
                    total += k;
                }
                dx += 1;
            }
            dy += 1;
        }
        sum / total
    }

    /// One à-trous pass at pixel (x, y): the weighted mean of the 5x5 taps `image.step` apart
    /// (rgb) and the variance of that mean (w), for the next pass.
    pub fn atrous_pixel(image: &FilterImage, x: u32, y: u32) -> Vec4 {
        let w = image.width as i32;
        let h = image.height as i32;
        let xi = x as i32;
        let yi = y as i32;
        let step = image.step as i32;
        let center = image.color.fetch(y * image.width + x);
        let guide = image.guide.fetch(y * image.width + x);
        let slope = Vec2::new(depth_slope(image, xi, yi, 1, 0), depth_slope(image, xi, yi, 0, 1));
        let lp = luminance(center.xyz());
        let sigma_l = SIGMA_LUMINANCE * blurred_variance(image, xi, yi).max(0.0).sqrt() + 1.0e-10;
        let mut sum = Vec3::ZERO;
        let mut variance = 0.0f32;
        let mut total = 0.0f32;
        let mut dy = -2;
        while dy <= 2 {
            let mut dx = -2;
            while dx <= 2 {
                let qx = xi + dx * step;
                let qy = yi + dy * step;
                if qx >= 0 && qx < w && qy >= 0 && qy < h {
                    let q = (qy * w + qx) as u32;
                    let c = image.color.fetch(q);
                    let g = image.guide.fetch(q);
                    let w_normal = guide.xyz().dot(g.xyz()).max(0.0).powf(SIGMA_NORMAL);
                    let expected =
                        SIGMA_DEPTH * (slope.x * (dx * step).abs() as f32 + slope.y * (dy * step).abs() as f32);
                    let w_depth = (-(guide.w - g.w).abs() / (expected + 1.0e-4 * guide.w.max(1.0))).exp();
                    let w_luminance = (-(lp - luminance(c.xyz())).abs() / sigma_l).exp();
                    let weight = b3_weight(dx) * b3_weight(dy) * w_normal * w_depth * w_luminance;
                    sum += c.xyz() * weight;
                    variance += c.w * weight * weight;
                    total += weight;
                }
                dx += 1;
            }
            dy += 1;
        }
        // The centre tap's weight is 3/8 * 3/8 (its own normal, depth and luminance): total > 0.
        Vec4::new(sum.x / total, sum.y / total, sum.z / total, variance / (total * total))
    }
}
