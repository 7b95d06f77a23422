//! The denoiser on the host: the kernel's filter (`kernel::denoise`, written once in the DSL)
//! driven over an accumulated image. [`first_hit_aovs`] runs the kernel's `first_hit_aov` per
//! pixel, [`SampleMoments`] tracks each pixel's luminance moments from any runtime's
//! accumulation (so any runtime's image can be denoised), and [`denoise`] demodulates the image
//! by the albedo, runs the à-trous passes and remodulates.
//!
//! [`denoise`] runs the passes on the CPU ([`filter_on_cpu`]: `atrous_pixel` as plain Rust, rayon);
//! [`denoise_on`] on a renderer's runtime ([`Renderer::denoise_passes`]), which runs the same
//! function generated as an image pass (`shaders-generated/denoise_pass.*`): a
//! fragment pass on GL/WebGL2, a compute pass on wgpu/WebGPU.

use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};
use kernel_dsl::Texels;
use rayon::prelude::*;

use crate::backend::{RenderError, Renderer};
use crate::kernel::denoise::{atrous_pixel, first_hit_aov, Aov, FilterImage, ATROUS_ITERATIONS, MIN_ALBEDO};
use crate::kernel::intersect::MISS;
use crate::kernel::lights::luminance;
use crate::kernel::scene_data::Scene;
use crate::output::Image;

/// Why an image cannot be denoised.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    #[error("the image is {width}x{height} ({pixels} pixels) but {what} has {len} values")]
    SizeMismatch { width: u32, height: u32, pixels: usize, what: &'static str, len: usize },
    #[error("the filter passes failed: {0}")]
    Passes(Box<RenderError>),
    #[error("the filter passes returned {len} pixels for a {width}x{height} image")]
    PassOutput { width: u32, height: u32, len: usize },
}

/// A denoised image.
#[derive(Clone, Debug)]
pub struct Denoised {
    pub image: Image,
    /// Pixels whose colour, variance or auxiliary values were NaN or infinite: replaced (colour
    /// and variance by zero, the guide by a neutral value) before filtering, so they never spread.
    pub replaced: usize,
}

/// Guide samples per pixel side: the auxiliary values are averaged over a 4x4 grid of film
/// positions in the pixel, as the colour is over its jittered samples. A pixel that straddles
/// texture detail is then demodulated by that detail's mean (not by one texel of it), and one
/// that straddles an edge gets an in-between normal and depth, so the filter leaves it mostly
/// alone rather than pulling it to one side.
const AOV_GRID: u32 = 4;

/// The first hit's auxiliary values of every pixel of `scene`'s image, row by row, each the
/// mean over the pixel (the normal renormalised).
pub fn first_hit_aovs(scene: &Scene) -> Vec<Aov> {
    let width = scene.width.max(1);
    (0..scene.width * scene.height)
        .into_par_iter()
        .map(|i| {
            let corner = Vec2::new((i % width) as f32, (i / width) as f32);
            let cell = 1.0 / AOV_GRID as f32;
            let (mut albedo, mut emission, mut normal, mut depth) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0.0f64);
            for j in 0..AOV_GRID * AOV_GRID {
                let offset = Vec2::new((j % AOV_GRID) as f32 + 0.5, (j / AOV_GRID) as f32 + 0.5) * cell;
                let sample = first_hit_aov(scene, corner + offset);
                albedo += sample.albedo;
                emission += sample.emission;
                normal += sample.normal;
                depth += sample.depth as f64;
            }
            let n = (AOV_GRID * AOV_GRID) as f32;
            Aov {
                albedo: albedo / n,
                emission: emission / n,
                normal: normal.normalize_or(Vec3::Z),
                depth: (depth / n as f64).min(MISS as f64) as f32,
            }
        })
        .collect()
}

/// Per-pixel sums of the samples' luminance and its square, fed frame by frame from a
/// runtime's accumulation (running sums: rgb, and the finite samples' count in w).
#[derive(Clone, Debug)]
pub struct SampleMoments {
    previous: Vec<Vec3>,
    sum: Vec<f64>,
    squares: Vec<f64>,
    frames: u32,
}

impl SampleMoments {
    pub fn new(pixels: usize) -> Self {
        SampleMoments {
            previous: vec![Vec3::ZERO; pixels],
            sum: vec![0.0; pixels],
            squares: vec![0.0; pixels],
            frames: 0,
        }
    }

    /// Adds the frame that took the accumulation to `accumulation` (one sample per pixel).
    pub fn add_frame(&mut self, accumulation: &[Vec4]) {
        for (i, a) in accumulation.iter().enumerate().take(self.previous.len()) {
            let sample = luminance(a.xyz() - self.previous[i]) as f64;
            self.previous[i] = a.xyz();
            if sample.is_finite() {
                self.sum[i] += sample;
                self.squares[i] += sample * sample;
            }
        }
        self.frames += 1;
    }

    /// Each pixel's variance of the mean luminance (the sample variance over the frame count);
    /// with fewer than two frames, unknown: infinite (the filter then leans on its guide alone).
    pub fn variance_of_mean(&self) -> Vec<f32> {
        let n = self.frames as f64;
        if n < 2.0 {
            return vec![f32::INFINITY; self.sum.len()];
        }
        self.sum
            .iter()
            .zip(&self.squares)
            .map(|(s, q)| {
                let mean = s / n;
                (((q / n - mean * mean) * n / (n - 1.0)).max(0.0) / n) as f32
            })
            .collect()
    }
}

/// The largest variance the filter is given: an unknown (infinite) variance becomes this, so
/// that its sums over five passes (at most ~50x per pass) stay finite and a zero weight times it
/// stays zero rather than NaN.
const VARIANCE_CAP: f32 = 1.0e20;

/// What the albedo divides out of a pixel's colour: the albedo where a channel is at least
/// `MIN_ALBEDO`, else 1 (the colour stays as it is).
fn demodulation(albedo: Vec3) -> Vec3 {
    Vec3::select(albedo.cmpge(Vec3::splat(MIN_ALBEDO)), albedo, Vec3::ONE)
}

/// `image` denoised, given each pixel's variance of the mean luminance (`variance`, e.g.
/// [`SampleMoments::variance_of_mean`]) and its first hit's auxiliary values (`aovs`), the
/// filter passes on the CPU.
pub fn denoise(image: &Image, variance: &[f32], aovs: &[Aov]) -> Result<Denoised, DenoiseError> {
    let Demodulated { filter, modulation, replaced } = demodulate(image, variance, aovs)?;
    remodulate(image, filter_on_cpu(filter), &modulation, replaced)
}

/// [`denoise`] with the filter passes on `renderer`'s runtime
/// ([`Renderer::denoise_passes`]: fragment passes on GL, compute passes on wgpu).
pub fn denoise_on(
    renderer: &mut dyn Renderer,
    image: &Image,
    variance: &[f32],
    aovs: &[Aov],
) -> Result<Denoised, DenoiseError> {
    let Demodulated { filter, modulation, replaced } = demodulate(image, variance, aovs)?;
    // An empty image has nothing to filter (and no runtime draws into a 0x0 target).
    let filtered = if modulation.is_empty() {
        Vec::new()
    } else {
        renderer.denoise_passes(filter).map_err(|e| DenoiseError::Passes(Box::new(e)))?
    };
    remodulate(image, filtered, &modulation, replaced)
}

/// The à-trous passes on the CPU: `ATROUS_ITERATIONS` passes of `atrous_pixel` at steps 1, 2,
/// 4, ... over `image`; the last pass's output per pixel (rgb filtered, w its variance).
pub fn filter_on_cpu(mut image: FilterImage) -> Vec<Vec4> {
    let width = image.width;
    for pass in 0..ATROUS_ITERATIONS {
        image.step = 1 << pass;
        let output: Vec<Vec4> =
            (0..width * image.height).into_par_iter().map(|i| atrous_pixel(&image, i % width, i / width)).collect();
        image.color = Texels::new(output);
    }
    image.color.as_slice().to_vec()
}

/// The filtered illumination times the albedo, plus the emission: the denoised image.
fn remodulate(
    image: &Image,
    filtered: Vec<Vec4>,
    modulation: &[(Vec3, Vec3)],
    replaced: usize,
) -> Result<Denoised, DenoiseError> {
    let (width, height) = (image.width, image.height);
    if filtered.len() != modulation.len() {
        return Err(DenoiseError::PassOutput { width, height, len: filtered.len() });
    }
    let pixels = filtered.iter().zip(modulation).map(|(f, (d, e))| f.xyz() * *d + *e).collect();
    Ok(Denoised { image: Image { width, height, pixels }, replaced })
}

/// What the filter passes are given for `image` (see [`denoise`]): its illumination and
/// variance, and the guide, e.g. to run the passes on several runtimes and compare them.
pub fn filter_input(image: &Image, variance: &[f32], aovs: &[Aov]) -> Result<FilterImage, DenoiseError> {
    Ok(demodulate(image, variance, aovs)?.filter)
}

/// An image made ready for the filter passes.
struct Demodulated {
    filter: FilterImage,
    /// Per pixel, what divided the colour (the albedo) and what was taken out (the emission).
    modulation: Vec<(Vec3, Vec3)>,
    /// Pixels with a non-finite colour, variance or guide, replaced.
    replaced: usize,
}

fn demodulate(image: &Image, variance: &[f32], aovs: &[Aov]) -> Result<Demodulated, DenoiseError> {
    let (width, height) = (image.width, image.height);
    let pixels = image.pixels.len();
    for (what, len) in [("the variance", variance.len()), ("the AOVs", aovs.len())] {
        if len != pixels || pixels != width as usize * height as usize {
            return Err(DenoiseError::SizeMismatch { width, height, pixels, what, len });
        }
    }
    let mut replaced = 0;
    let mut color = Vec::with_capacity(pixels);
    let mut guide = Vec::with_capacity(pixels);
    let mut modulation = Vec::with_capacity(pixels);
    for ((c, v), aov) in image.pixels.iter().zip(variance).zip(aovs) {
        let finite_guide =
            aov.albedo.is_finite() && aov.normal.is_finite() && !aov.depth.is_nan() && aov.emission.is_finite();
        // An unknown variance (infinite: fewer than two frames) is kept: it opens the luminance weight.
        let ok = c.is_finite() && !v.is_nan() && *v >= 0.0 && finite_guide;
        replaced += usize::from(!ok);
        let (c, v) = if c.is_finite() && !v.is_nan() && *v >= 0.0 { (*c, *v) } else { (Vec3::ZERO, 0.0) };
        let d = if finite_guide { demodulation(aov.albedo) } else { Vec3::ONE };
        let (normal, depth, emission) =
            if finite_guide { (aov.normal, aov.depth, aov.emission) } else { (Vec3::Z, MISS, Vec3::ZERO) };
        let scale = luminance(d);
        let illumination = (c - emission) / d;
        color.push(illumination.extend((v / (scale * scale)).min(VARIANCE_CAP)));
        guide.push(normal.extend(depth));
        modulation.push((d, emission));
    }
    let filter = FilterImage { color: Texels::new(color), guide: Texels::new(guide), width, height, step: 1 };
    Ok(Demodulated { filter, modulation, replaced })
}
