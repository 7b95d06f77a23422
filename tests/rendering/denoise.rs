//! The denoiser (`tracer::denoise`, its filter in `kernel::denoise`) against the project's own
//! high-sample references: at 16 spp it must be at least 6 dB (PSNR) closer to the reference
//! than the noisy image, at 256 spp never further, and keep the image's mean, on the Cornell
//! box, a textured box under a sky and a scene of alpha-masked holes (glossy metal-roughness
//! surfaces, e.g. DamagedHelmet, are not helped yet: see the README). And bad input: NaN and
//! infinite pixels never spread, black and constant images stay as they are, single rows and
//! single pixels work.

use glam::Vec3;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::{Renderer, RendererKind};
use tracer::denoise::{denoise, denoise_on, filter_on_cpu, first_hit_aovs, SampleMoments};
use tracer::kernel::denoise::Aov;
use tracer::kernel::lights::luminance;
use tracer::kernel::Strategy;
use tracer::output::Image;
use tracer::scene::{self, Scene};
use tracer::stats::{mse, rel_mse};

use crate::common::agreement::{largest_difference, noisy_filter_input, packed, textured_box};

/// `spp` frames of `scene` on the CPU with `seed`: the image, and the variance of each pixel's
/// mean luminance.
fn render(scene: &Scene, size: u32, spp: u32, seed: u32) -> (Image, Vec<f32>, Vec<Aov>) {
    let p = packed(scene, Strategy::Mis, size, 6);
    let aovs = first_hit_aovs(&p.scene);
    let mut r = CpuRenderer::new(p, seed);
    let mut moments = SampleMoments::new((size * size) as usize);
    for _ in 0..spp {
        r.render_frame().expect("frame");
        moments.add_frame(&r.accumulation().expect("accumulation"));
    }
    (r.image().expect("image"), moments.variance_of_mean(), aovs)
}

/// Relative MSE against `reference` (`tracer::stats::rel_mse`) and the PSNR of the MSE with a
/// peak of the reference's largest value.
fn error(image: &Image, reference: &Image) -> (f64, f64) {
    let rel = rel_mse(&image.pixels, &reference.pixels).expect("same size");
    let mse = mse(&image.pixels, &reference.pixels).expect("same size");
    let peak = reference.pixels.iter().map(|p| p.max_element() as f64).fold(0.0, f64::max);
    (rel, 10.0 * (peak * peak / mse).log10())
}

/// Denoises `scene` at 1, 4, 16 and 256 spp and compares each with the noisy image against a
/// 4096-spp reference (another seed): at 16 spp at least 6 dB of PSNR and 3 dB of relative MSE
/// gained, at 1, 4 and 256 spp nothing lost (at 1 spp the variance is unknown: the filter
/// leans on its guide alone); the mean within 1 % (or the noisy image's own error) from 16 spp on.
fn assert_denoising_helps(what: &str, scene: &Scene, size: u32) {
    let (reference, _, _) = render(scene, size, 4096, 99);
    let mut gains = Vec::new();
    for spp in [1, 4, 16, 256] {
        let (noisy, variance, aovs) = render(scene, size, spp, 7);
        let denoised = denoise(&noisy, &variance, &aovs).expect("denoise");
        assert_eq!(denoised.replaced, 0, "{what}: finite input");
        let (rel_noisy, psnr_noisy) = error(&noisy, &reference);
        let (rel_denoised, psnr_denoised) = error(&denoised.image, &reference);
        let (mean, noisy_mean, reference_mean) = (denoised.image.mean(), noisy.mean(), reference.mean());
        // The gain in dB of relative MSE (HDR images: PSNR's peak is the light source's).
        let gain = 10.0 * (rel_noisy / rel_denoised).log10();
        eprintln!(
            "{what} {spp:>3} spp: relMSE {rel_noisy:.5} -> {rel_denoised:.5} ({gain:+.2} dB); PSNR {psnr_noisy:.2} -> {psnr_denoised:.2} dB; mean {mean}, noisy {noisy_mean}, reference {reference_mean}"
        );
        // The mean stays within 1 % of the reference's, or no further than the noisy image's
        // own mean is (16 spp of a 48x48 image is itself up to ~2 % off).
        let off = |m: Vec3| ((m - reference_mean).abs() / reference_mean.max(Vec3::splat(1e-3))).max_element();
        // Below 16 spp the filter is not mean-preserving where a few samples carry the light
        // (the masked screen's mean is 3 % off at 1 and 4 spp): printed above, held from 16 on.
        assert!(
            spp < 16 || off(mean) <= off(noisy_mean).max(0.01) + 0.002,
            "{what} {spp} spp: the denoised mean {mean} is {:.4} from the reference's (the noisy image's {:.4})",
            off(mean),
            off(noisy_mean)
        );
        gains.push((gain, psnr_denoised - psnr_noisy));
    }
    let (rel16, psnr16) = gains[2];
    assert!(psnr16 >= 6.0, "{what}: denoising gains {psnr16:.2} dB of PSNR at 16 spp (at least 6 wanted)");
    assert!(rel16 >= 3.0, "{what}: denoising gains {rel16:.2} dB of relative MSE at 16 spp (at least 3 wanted)");
    for (spp, (rel, psnr)) in [(1, gains[0]), (4, gains[1]), (256, gains[3])] {
        assert!(
            psnr >= 0.0 && rel >= 0.0,
            "{what}: denoising loses at {spp} spp: {psnr:.2} dB PSNR, {rel:.2} dB relMSE"
        );
    }
}

#[test]
fn denoising_the_cornell_box_gains_at_least_6_db_at_16_spp() {
    assert_denoising_helps("Cornell box", &scene::cornell_box(), 48);
}

/// Textures keep their edges: the filter works on illumination, the texture comes back after.
#[test]
fn denoising_a_textured_box_keeps_its_texture_and_gains_at_least_6_db() {
    assert_denoising_helps("BoxTextured under a sky", &textured_box(), 48);
}

/// Thin cut-outs keep their holes: the guide sees through them as the camera rays do.
#[test]
fn denoising_alpha_masked_holes_gains_at_least_6_db() {
    assert_denoising_helps("alpha-masked screen", &scene::alpha_masked_screen(), 48);
}

/// Which pixels belong to a class, by their guide.
type PixelClass = fn(&Aov) -> bool;

/// The mean luminance of the pixels whose guide is in class `a` over that of class `b`.
fn contrast(image: &Image, aovs: &[Aov], a: PixelClass, b: PixelClass) -> f64 {
    let mean = |class: PixelClass| {
        let values: Vec<f64> =
            image.pixels.iter().zip(aovs).filter(|(_, aov)| class(aov)).map(|(p, _)| luminance(*p) as f64).collect();
        assert!(values.len() >= 20, "a class of only {} pixels", values.len());
        values.iter().sum::<f64>() / values.len() as f64
    };
    mean(a) / mean(b)
}

/// Stability: edges the guide knows are kept. A checker texture's squares and an alpha-masked
/// screen (the bare floor against the screen and the floor through its holes) keep their
/// contrast within 10 % of the reference's at 4 and 16 spp; a filter that blurred across them
/// would not.
#[test]
fn textures_and_cut_outs_keep_their_contrast() {
    let size = 48;
    let cases: [(&str, Scene, PixelClass, PixelClass); 2] = [
        // Light squares (albedo 0.60) against dark ones (0.033); pixels on an edge are in neither.
        ("checker floor", scene::checker_floor(), |a| a.albedo.x > 0.4, |a| a.albedo.x < 0.05),
        // The bare floor against the screen (green, its holes a pixel or two wide at this size,
        // so most of its pixels mix the floor seen through them).
        (
            "alpha-masked screen",
            scene::alpha_masked_screen(),
            |a| a.albedo.x > 0.75,
            |a| a.albedo.y - a.albedo.x > 0.04,
        ),
    ];
    for (what, scene, a, b) in cases {
        let (reference, _, aovs) = render(&scene, size, 4096, 99);
        let expected = contrast(&reference, &aovs, a, b);
        for spp in [1, 4, 16] {
            let (noisy, variance, aovs) = render(&scene, size, spp, 7);
            let denoised = denoise(&noisy, &variance, &aovs).expect("denoise").image;
            let (got, noisy_contrast) = (contrast(&denoised, &aovs, a, b), contrast(&noisy, &aovs, a, b));
            eprintln!(
                "{what} {spp:>2} spp: contrast {got:.3} denoised, {noisy_contrast:.3} noisy, {expected:.3} reference"
            );
            // At 1 spp the masked screen's noisy image is itself 11 % off (light through
            // pixel-wide holes): printed, held from 4 spp on.
            assert!(
                spp == 1 || (got / expected - 1.0).abs() <= 0.1,
                "{what} at {spp} spp: contrast {got:.3} denoised against {expected:.3} in the reference"
            );
        }
    }
}

fn flat_aovs(n: usize) -> Vec<Aov> {
    vec![Aov { albedo: Vec3::splat(0.5), normal: Vec3::Z, depth: 2.0, emission: Vec3::ZERO }; n]
}

#[test]
fn non_finite_pixels_are_replaced_and_never_spread() {
    let (w, h) = (9u32, 7u32);
    let mut pixels = vec![Vec3::splat(0.25); (w * h) as usize];
    pixels[31] = Vec3::new(f32::NAN, 0.0, 0.0);
    pixels[32] = Vec3::splat(f32::INFINITY);
    let mut variance = vec![0.01f32; pixels.len()];
    variance[10] = f32::NAN;
    let mut aovs = flat_aovs(pixels.len());
    aovs[50].normal = Vec3::splat(f32::NAN);
    let image = Image { width: w, height: h, pixels };
    let out = denoise(&image, &variance, &aovs).expect("denoise");
    assert_eq!(out.replaced, 4, "two colours, one variance and one guide");
    assert!(out.image.pixels.iter().all(|p| p.is_finite()), "{:?}", out.image.pixels);
}

#[test]
fn black_constant_and_tiny_images_stay_as_they_are() {
    for (w, h) in [(1u32, 1u32), (1, 17), (23, 1), (16, 16)] {
        let n = (w * h) as usize;
        for (colour, variance) in [(Vec3::ZERO, 0.0f32), (Vec3::new(0.2, 0.4, 0.8), 0.05), (Vec3::ONE, f32::INFINITY)] {
            let image = Image { width: w, height: h, pixels: vec![colour; n] };
            let out = denoise(&image, &vec![variance; n], &flat_aovs(n)).expect("denoise");
            for p in &out.image.pixels {
                assert!(
                    (*p - colour).abs().max_element() <= 1e-6 * colour.max_element().max(1.0),
                    "{w}x{h}: {p} for {colour}"
                );
            }
        }
    }
    let empty = Image { width: 0, height: 0, pixels: Vec::new() };
    assert!(denoise(&empty, &[], &[]).expect("an empty image").image.pixels.is_empty());
}

#[test]
fn sizes_that_disagree_are_an_error() {
    let image = Image { width: 4, height: 4, pixels: vec![Vec3::ONE; 16] };
    let err = denoise(&image, &[0.0; 15], &flat_aovs(16)).expect_err("15 variances");
    assert!(err.to_string().contains("variance has 15 values"), "{err}");
    let err = denoise(&image, &[0.0; 16], &flat_aovs(3)).expect_err("3 AOVs");
    assert!(err.to_string().contains("AOVs has 3 values"), "{err}");
}

/// A renderer of each runtime (CPU, GL, wgpu) on a small Cornell box: what runs the filter
/// passes. A machine without a GL or Vulkan driver fails here, with the reason.
fn runtimes() -> Vec<Box<dyn Renderer>> {
    RendererKind::ALL
        .iter()
        .map(|kind| {
            let p = packed(&scene::cornell_box(), Strategy::Mis, 8, 4);
            tracer::backend::create(*kind, p, 1).unwrap_or_else(|e| panic!("the {} runtime: {e}", kind.name()))
        })
        .collect()
}

/// CPU ≡ GL ≡ wgpu on the filter passes: the same `atrous_pixel`, generated as a fragment pass
/// and a compute pass, gives the CPU's output on a noisy Cornell box and a textured box under a
/// sky, at sizes that are not multiples of the workgroup (8x8) and a single row and column.
#[test]
fn the_filter_passes_agree_on_every_runtime() {
    let inputs = [
        ("Cornell box 37x23, 4 spp", noisy_filter_input(&scene::cornell_box(), 37, 23, 4)),
        ("textured box 24x24, 2 spp", noisy_filter_input(&textured_box(), 24, 24, 2)),
        ("Cornell box 1x19, 4 spp", noisy_filter_input(&scene::cornell_box(), 1, 19, 4)),
        ("Cornell box 19x1, 4 spp", noisy_filter_input(&scene::cornell_box(), 19, 1, 4)),
    ];
    for mut runtime in runtimes() {
        let name = runtime.describe().runtime;
        for (what, input) in &inputs {
            let expected = filter_on_cpu(input.clone());
            let got = runtime.denoise_passes(input.clone()).unwrap_or_else(|e| panic!("{name}, {what}: {e}"));
            assert_eq!(got.len(), expected.len(), "{name}, {what}");
            let difference = largest_difference(&got, &expected);
            eprintln!("{name}, {what}: largest relative difference {difference:.2e}");
            // f32 exp/pow differ by a few ulp between drivers; four passes compound them.
            assert!(difference <= 1e-4, "{name}, {what}: the filter differs from the CPU's by {difference:.2e}");
        }
    }
}

/// Bad input on every runtime: a black, a constant and an unknown-variance image of 1x1, 1x17,
/// 23x1 and 16x16 come back as they went in; non-finite pixels never spread.
#[test]
fn every_runtime_filters_tiny_and_flat_images_and_contains_non_finite_pixels() {
    for mut runtime in runtimes() {
        let name = runtime.describe().runtime;
        for (w, h) in [(1u32, 1u32), (1, 17), (23, 1), (16, 16)] {
            let n = (w * h) as usize;
            for (colour, variance) in
                [(Vec3::ZERO, 0.0f32), (Vec3::new(0.2, 0.4, 0.8), 0.05), (Vec3::ONE, f32::INFINITY)]
            {
                let image = Image { width: w, height: h, pixels: vec![colour; n] };
                let out = denoise_on(runtime.as_mut(), &image, &vec![variance; n], &flat_aovs(n))
                    .unwrap_or_else(|e| panic!("{name}, {w}x{h}: {e}"));
                for p in &out.image.pixels {
                    assert!(
                        (*p - colour).abs().max_element() <= 1e-5 * colour.max_element().max(1.0),
                        "{name}, {w}x{h}: {p} for {colour}"
                    );
                }
            }
        }
        let (w, h) = (9u32, 7u32);
        let mut pixels = vec![Vec3::splat(0.25); (w * h) as usize];
        pixels[31] = Vec3::new(f32::NAN, 0.0, 0.0);
        pixels[32] = Vec3::splat(f32::INFINITY);
        let image = Image { width: w, height: h, pixels };
        let out = denoise_on(runtime.as_mut(), &image, &vec![0.01; 63], &flat_aovs(63)).expect("denoise");
        assert_eq!(out.replaced, 2, "{name}");
        assert!(out.image.pixels.iter().all(|p| p.is_finite()), "{name}: {:?}", out.image.pixels);
    }
}
