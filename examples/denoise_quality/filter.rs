//! The denoiser's filter as the experiments vary it: a parametric host copy of the kernel's
//! `atrous_pixel` (the same weights, every parameter open) and the demodulated inputs it is run
//! on (per pixel, as the shipped denoiser demodulates, or per sample). `main.rs` renders the
//! scenes and tabulates what each variant gains.

use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};
use tracer::denoise::Guide;
use tracer::kernel::denoise::{ATROUS_ITERATIONS, MIN_ALBEDO, SIGMA_DEPTH, SIGMA_LUMINANCE, SIGMA_NORMAL};
use tracer::kernel::lights::luminance;
use tracer::output::Image;

use super::PerSample;

/// The albedo a pixel's illumination is divided by (the kernel's rule: below `MIN_ALBEDO`, 1).
pub fn demodulation(albedo: Vec3) -> Vec3 {
    Vec3::select(albedo.cmpge(Vec3::splat(MIN_ALBEDO)), albedo, Vec3::ONE)
}

/// Filter parameters (the kernel's constants are the defaults).
#[derive(Clone, Copy, Debug)]
pub struct Params {
    pub iterations: u32,
    pub sigma_normal: f32,
    pub sigma_depth: f32,
    pub sigma_luminance: f32,
}

/// The kernel's own filter (`tracer::kernel::denoise`).
pub const SHIPPED: Params = Params {
    iterations: ATROUS_ITERATIONS,
    sigma_normal: SIGMA_NORMAL,
    sigma_depth: SIGMA_DEPTH,
    sigma_luminance: SIGMA_LUMINANCE,
};
/// Before σn went from 128 to 1024.
pub const BEFORE: Params = Params { sigma_normal: 128.0, ..SHIPPED };

pub struct Img {
    color: Vec<Vec4>,
    guide: Vec<Vec4>,
    width: i32,
    height: i32,
}

fn b3(i: i32) -> f32 {
    [0.0625, 0.25, 0.375, 0.25, 0.0625][(i + 2) as usize]
}

fn atrous(img: &Img, p: Params, step: i32, x: i32, y: i32) -> Vec4 {
    let (w, h) = (img.width, img.height);
    let at = |x: i32, y: i32| (y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize;
    let depth = |x: i32, y: i32| img.guide[at(x, y)].w;
    let slope1 = |dx: i32, dy: i32| {
        let z = depth(x, y);
        (depth(x + dx, y + dy) - z).abs().min((z - depth(x - dx, y - dy)).abs())
    };
    let slope = Vec2::new(slope1(1, 0), slope1(0, 1));
    let center = img.color[at(x, y)];
    let guide = img.guide[at(x, y)];
    let mut vs = 0.0;
    let mut vt = 0.0;
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (qx, qy) = (x + dx, y + dy);
            if qx >= 0 && qx < w && qy >= 0 && qy < h {
                let k = (if dx == 0 { 0.5 } else { 0.25 }) * (if dy == 0 { 0.5 } else { 0.25 });
                vs += img.color[at(qx, qy)].w * k;
                vt += k;
            }
        }
    }
    let lp = luminance(center.xyz());
    let sigma_l = p.sigma_luminance * (vs / vt).max(0.0).sqrt() + 1e-10;
    let (mut sum, mut var, mut total) = (Vec3::ZERO, 0.0f32, 0.0f32);
    for dy in -2..=2 {
        for dx in -2..=2 {
            let (qx, qy) = (x + dx * step, y + dy * step);
            if qx >= 0 && qx < w && qy >= 0 && qy < h {
                let c = img.color[at(qx, qy)];
                let g = img.guide[at(qx, qy)];
                let wn = guide.xyz().dot(g.xyz()).max(0.0).powf(p.sigma_normal);
                let expected =
                    p.sigma_depth * (slope.x * (dx * step).abs() as f32 + slope.y * (dy * step).abs() as f32);
                let wd = (-(guide.w - g.w).abs() / (expected + 1e-4 * guide.w.max(1.0))).exp();
                let wl = (-(lp - luminance(c.xyz())).abs() / sigma_l).exp();
                let weight = b3(dx) * b3(dy) * wn * wd * wl;
                sum += c.xyz() * weight;
                var += c.w * weight * weight;
                total += weight;
            }
        }
    }
    (sum / total).extend(var / (total * total))
}

pub fn filter(mut img: Img, p: Params) -> Vec<Vec4> {
    use rayon::prelude::*;
    for pass in 0..p.iterations {
        let step = 1 << pass;
        let out: Vec<Vec4> = (0..img.width * img.height)
            .into_par_iter()
            .map(|i| atrous(&img, p, step, i % img.width, i / img.width))
            .collect();
        img.color = out;
    }
    img.color
}

/// Demodulated input (illumination, variance) and the modulation (albedo divisor, emission).
pub struct Input {
    pub img: Img,
    pub modulation: Vec<(Vec3, Vec3)>,
}

pub fn input_mean(image: &Image, guide: &Guide) -> Input {
    let mut color = Vec::new();
    let mut g = Vec::new();
    let mut modulation = Vec::new();
    for ((c, v), aov) in image.pixels.iter().zip(&guide.variance).zip(&guide.aovs) {
        let d = demodulation(aov.albedo);
        let s = luminance(d);
        color.push(((*c - aov.emission) / d).extend((v / (s * s)).min(1e20)));
        g.push(aov.normal.extend(aov.depth));
        modulation.push((d, aov.emission));
    }
    Input { img: Img { color, guide: g, width: image.width as i32, height: image.height as i32 }, modulation }
}

/// Per-sample demodulation: the mean over surface samples of (c - e) / a, its variance from
/// the samples' moments; remodulated by the mean albedo times the surface share.
pub fn input_per_sample(image: &Image, guide: &Guide, ps: &PerSample) -> Input {
    let mut color = Vec::new();
    let mut g = Vec::new();
    let mut modulation = Vec::new();
    for (i, aov) in guide.aovs.iter().enumerate() {
        let k = ps.surface[i];
        if k == 0.0 {
            color.push(Vec4::new(0.0, 0.0, 0.0, 0.0));
            modulation.push((Vec3::ONE, image.pixels[i]));
        } else {
            let ill = (ps.illumination[i] / k).as_vec3();
            let (m1, m2) = (ps.moments[i].0 / k, ps.moments[i].1 / k);
            let var = if k < 2.0 { 1e20 } else { ((m2 - m1 * m1) * k / (k - 1.0)).max(0.0) / k };
            color.push(ill.extend(var as f32));
            // The mean albedo over all samples already carries the surface share; per sample,
            // a = sum over surface samples / n, so the albedo to remodulate by is the surface
            // samples' mean albedo times k/n: aov.albedo as is.
            let d = aov.albedo.max(Vec3::splat(1e-6));
            modulation.push((d, aov.emission));
        }
        g.push(aov.normal.extend(aov.depth));
    }
    Input { img: Img { color, guide: g, width: image.width as i32, height: image.height as i32 }, modulation }
}
