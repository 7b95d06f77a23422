//! The denoiser on the host: the kernel's filter (`kernel::denoise`, written once in the DSL)
//! driven over an accumulated image. Its [`Guide`] comes from the path tracer itself: a
//! renderer created with `Features::denoise_guide` sums each path's first hit (albedo, normal,
//! depth, emission) and the samples' luminance moments beside the colour, in the same pass, on
//! every runtime ([`Renderer::guide_sums`]). [`denoise`] demodulates the image by the albedo,
//! runs the à-trous passes and remodulates.
//!
//! [`denoise`] runs the passes on the CPU ([`filter_on_cpu`]: `atrous_pixel` as plain Rust, rayon);
//! [`denoise_on`] on a renderer's runtime ([`Renderer::denoise_passes`]), which runs the same
//! function generated as an image pass (`shaders-generated/denoise_pass.*`): a
//! fragment pass on GL/WebGL2, a compute pass on wgpu/WebGPU.

use glam::{DVec3, Vec3, Vec4, Vec4Swizzles};
use kernel_dsl::Texels;
use rayon::prelude::*;

use crate::backend::{GuideSums, RenderError, Renderer};
use crate::kernel::denoise::{atrous_pixel, FilterImage, ATROUS_ITERATIONS, MIN_ALBEDO};
use crate::kernel::intersect::MISS;
use crate::kernel::lights::luminance;
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

/// What the filter's weights read at a pixel: the mean over its samples of the paths' first hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aov {
    /// What the hit reflects of smooth light: the base colour (factor times texture) of a
    /// Lambert surface, the metal-roughness BRDF's directional albedo (`metal_rough_albedo`:
    /// specular included, so glossy, metallic and dark surfaces demodulate too); 0 where the
    /// ray sees the sky (it reflects nothing: a pixel half sky, half surface demodulates by
    /// its surface's share).
    pub albedo: Vec3,
    /// Shading normal facing the viewer (normal-mapped where the scene has normal maps); the
    /// reversed ray direction for the sky. Unit length (the mean renormalised).
    pub normal: Vec3,
    /// Distance along the ray; at least `SKY_DEPTH` where the sky is seen.
    pub depth: f32,
    /// Radiance the hit emits towards the camera (front faces of emitters, and the sky where
    /// the ray sees it): not the path tracer's noise, so it is taken out before filtering and
    /// added back (the filter sees only reflected light, and its variance is that light's).
    pub emission: Vec3,
}

/// The denoiser's guide for an image: per pixel its first hits' mean [`Aov`] and the variance of
/// its mean luminance, from the sums the path tracer accumulated beside the colour
/// (`Features::denoise_guide`, [`Renderer::guide_sums`]) on any runtime.
#[derive(Clone, Debug, PartialEq)]
pub struct Guide {
    pub aovs: Vec<Aov>,
    /// Each pixel's variance of the mean luminance of its reflected light (the samples' colour
    /// less their first hit's emission: what the filter sees), the sample variance over the
    /// sample count;
    /// with fewer than two samples, unknown: infinite (the filter then leans on the AOVs alone).
    pub variance: Vec<f32>,
}

impl Guide {
    /// The guide from a renderer's [`GuideSums`] after `samples` samples per pixel.
    pub fn from_sums(samples: u32, sums: &GuideSums) -> Guide {
        let n = samples.max(1) as f64;
        let [albedo, normal, emission] = sums;
        let aovs = albedo
            .iter()
            .zip(normal)
            .zip(emission)
            .map(|((a, nd), e)| Aov {
                albedo: a.xyz() / n as f32,
                normal: nd.xyz().normalize_or(Vec3::Z),
                depth: (nd.w as f64 / n).min(MISS as f64) as f32,
                emission: e.xyz() / n as f32,
            })
            .collect();
        let variance = albedo
            .iter()
            .zip(emission)
            .map(|(a, e)| {
                if samples < 2 {
                    return f32::INFINITY;
                }
                let (sum, squares) = (a.w as f64, e.w as f64);
                let mean = sum / n;
                (((squares / n - mean * mean) * n / (n - 1.0)).max(0.0) / n) as f32
            })
            .collect();
        Guide { aovs, variance }
    }

    /// The guide `renderer` accumulated (it must have been created with the guide: see
    /// [`Renderer::guide_sums`]). Blocks for the read-back, as `accumulation` does.
    pub fn read(renderer: &dyn Renderer) -> Result<Guide, RenderError> {
        Ok(Guide::from_sums(renderer.frames(), &renderer.guide_sums()?))
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

/// `image` denoised with its `guide`, the filter passes on the CPU.
pub fn denoise(image: &Image, guide: &Guide) -> Result<Denoised, DenoiseError> {
    let Demodulated { filter, modulation, reflected, replaced } = demodulate(image, guide)?;
    remodulate(image, filter_on_cpu(filter), &modulation, reflected, replaced)
}

/// [`denoise`] with the filter passes on `renderer`'s runtime
/// ([`Renderer::denoise_passes`]: fragment passes on GL, compute passes on wgpu).
pub fn denoise_on(renderer: &mut dyn Renderer, image: &Image, guide: &Guide) -> Result<Denoised, DenoiseError> {
    let Demodulated { filter, modulation, reflected, replaced } = demodulate(image, guide)?;
    // An empty image has nothing to filter (and no runtime draws into a 0x0 target).
    let filtered = if modulation.is_empty() {
        Vec::new()
    } else {
        renderer.denoise_passes(filter).map_err(|e| DenoiseError::Passes(Box::new(e)))?
    };
    remodulate(image, filtered, &modulation, reflected, replaced)
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

/// The filtered illumination times the albedo, plus the emission: the denoised image, its
/// reflected light scaled per channel so that its total is the noisy image's (`reflected`).
///
/// Why the scale: each pixel's à-trous weights sum to one, but a pixel's share of its
/// neighbours' outputs does not, so the filter moves light between pixels; where few samples
/// carry the light (one bright sample among dark neighbours) the image's mean drifted by 3 % at
/// 1 and 4 spp. The noisy image's mean is the unbiased one: the scale keeps it.
fn remodulate(
    image: &Image,
    filtered: Vec<Vec4>,
    modulation: &[(Vec3, Vec3)],
    reflected: DVec3,
    replaced: usize,
) -> Result<Denoised, DenoiseError> {
    let (width, height) = (image.width, image.height);
    if filtered.len() != modulation.len() {
        return Err(DenoiseError::PassOutput { width, height, len: filtered.len() });
    }
    let remodulated: Vec<Vec3> = filtered.iter().zip(modulation).map(|(f, (d, _))| f.xyz() * *d).collect();
    let total = remodulated.iter().fold(DVec3::ZERO, |sum, r| sum + r.as_dvec3());
    let scale = DVec3::select(total.cmpgt(DVec3::ZERO) & reflected.cmpge(DVec3::ZERO), reflected / total, DVec3::ONE);
    let scale = if scale.is_finite() { scale.as_vec3() } else { Vec3::ONE };
    let pixels = remodulated.iter().zip(modulation).map(|(r, (_, e))| *r * scale + *e).collect();
    Ok(Denoised { image: Image { width, height, pixels }, replaced })
}

/// What the filter passes are given for `image` (see [`denoise`]): its illumination and
/// variance, and the guide, e.g. to run the passes on several runtimes and compare them.
pub fn filter_input(image: &Image, guide: &Guide) -> Result<FilterImage, DenoiseError> {
    Ok(demodulate(image, guide)?.filter)
}

/// An image made ready for the filter passes.
struct Demodulated {
    filter: FilterImage,
    /// Per pixel, what divided the colour (the albedo) and what was taken out (the emission).
    modulation: Vec<(Vec3, Vec3)>,
    /// The image's total reflected light (its colour less the emission, summed over the pixels).
    reflected: DVec3,
    /// Pixels with a non-finite colour, variance or guide, replaced.
    replaced: usize,
}

fn demodulate(image: &Image, guide: &Guide) -> Result<Demodulated, DenoiseError> {
    let (width, height) = (image.width, image.height);
    let (variance, aovs) = (&guide.variance, &guide.aovs);
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
    let mut reflected = DVec3::ZERO;
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
        reflected += (illumination * d).as_dvec3();
        color.push(illumination.extend((v / (scale * scale)).min(VARIANCE_CAP)));
        guide.push(normal.extend(depth));
        modulation.push((d, emission));
    }
    let filter = FilterImage { color: Texels::new(color), guide: Texels::new(guide), width, height, step: 1 };
    Ok(Demodulated { filter, modulation, reflected, replaced })
}
