//! Image-level agreement of a GPU backend with the CPU backend, through the `Renderer` trait
//! (used by `render_wgpu.rs`): the same scenes, the same per-frame region statistics, the same
//! bound.

use std::time::Instant;

use glam::{DVec3, Vec3, Vec4, Vec4Swizzles};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::{create, Renderer, RendererKind};
use tracer::pack::{pack, Packed, RenderSettings, Strategy};
use tracer::scene::{self, Scene, Sky};
use tracer::stats::Estimate;

pub const STRATEGIES: [Strategy; 3] = [Strategy::Bsdf, Strategy::Nee, Strategy::Mis];

/// |CPU - GPU| within 5 combined standard errors, per region and channel (a false alarm at
/// 5 sigma is ~1 in 10^6 per comparison; the runs use fixed seeds).
pub const Z_BOUND: f64 = 5.0;

/// Regions per side: the image's 4 x 4 blocks, plus the whole image.
pub const BLOCKS: u32 = 4;

pub fn packed(scene: &Scene, strategy: Strategy, size: u32, max_depth: u32) -> Packed {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: size, height: size, strategy, max_depth };
    pack(scene, &bvh, &settings).expect("pack")
}

/// BoxTextured under a uniform white sky.
pub fn textured_box() -> Scene {
    let mut scene =
        scene::load(&super::test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf")).expect("BoxTextured");
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    scene
}

/// A diffuse plane under the venice_sunset HDR sky.
pub fn sky_lit_plane() -> Scene {
    let mut scene = scene::diffuse_plane(Vec3::splat(0.6));
    scene.sky = Some(scene::load_sky(&super::test_data("scenes/hdri/venice_sunset_1k.hdr"), 1.0, 0.0).expect("sky"));
    scene
}

/// Per-frame estimates of a render: for each frame, the mean of this frame's samples over each
/// 4 x 4 block and, last, the whole image.
pub struct Run {
    pub per_frame: Vec<Vec<DVec3>>,
    pub rejected: u64,
    pub seconds: f64,
}

/// A renderer of `kind` (the GPU ones on their own headless context or device); a runtime that
/// cannot start fails the test with the reason.
pub fn renderer(kind: RendererKind, packed: Packed, seed: u32) -> Box<dyn Renderer> {
    create(kind, packed, seed).unwrap_or_else(|e| panic!("the {} backend must run here: {e}", kind.name()))
}

/// The running sums of an accumulation (rgb: sum of samples, w: finite samples).
pub fn accumulated_sums(accumulation: &[Vec4]) -> Vec<DVec3> {
    accumulation.iter().map(|a| a.xyz().as_dvec3()).collect()
}

/// Renders `frames` frames, recording each frame's region means.
pub fn run(renderer: &mut dyn Renderer, size: u32, frames: u32) -> Run {
    let mut previous = vec![DVec3::ZERO; (size * size) as usize];
    let mut per_frame = Vec::new();
    let t = Instant::now();
    for _ in 0..frames {
        renderer.render_frame().expect("frame");
        let sums = accumulated_sums(&renderer.accumulation().expect("readback"));
        per_frame.push(super::region_means(size, BLOCKS, |i| sums[i] - previous[i]));
        previous = sums;
    }
    let rejected = renderer.rejected_samples().expect("readback");
    Run { per_frame, rejected, seconds: t.elapsed().as_secs_f64() }
}

fn estimate(run: &Run, region: usize, channel: usize) -> Estimate {
    let samples: Vec<f64> = run.per_frame.iter().map(|f| f[region][channel]).collect();
    Estimate::from_samples(&samples)
}

/// Renders `scene` on the CPU and on `kind` with each strategy (independent seeds) and asserts
/// that every region mean agrees within the bound and no sample was rejected. Returns the
/// largest z-score.
pub fn assert_agrees_with_cpu(
    kind: RendererKind,
    what: &str,
    scene: &Scene,
    size: u32,
    frames: u32,
    max_depth: u32,
) -> f64 {
    let name = kind.name();
    let mut worst = 0.0f64;
    for strategy in STRATEGIES {
        let p = packed(scene, strategy, size, max_depth);
        let cpu = run(&mut CpuRenderer::new(p.clone(), 1), size, frames);
        let gpu = run(renderer(kind, p, 2).as_mut(), size, frames);
        assert_eq!(cpu.rejected, 0, "{what} {strategy:?}: the CPU dropped non-finite samples");
        assert_eq!(gpu.rejected, 0, "{what} {strategy:?}: no NaN/Inf may reach the {name} accumulation");
        let mut worst_here = 0.0f64;
        for region in 0..(BLOCKS * BLOCKS) as usize + 1 {
            for c in 0..3 {
                let (a, b) = (estimate(&cpu, region, c), estimate(&gpu, region, c));
                let z = a.z_score(&b);
                assert!(
                    z < Z_BOUND,
                    "{what} {strategy:?} region {region} channel {c}: CPU {} ± {} vs {name} {} ± {} (z = {z:.2})",
                    a.mean,
                    a.std_err,
                    b.mean,
                    b.std_err
                );
                worst_here = worst_here.max(z);
            }
        }
        let whole = estimate(&gpu, (BLOCKS * BLOCKS) as usize, 1);
        eprintln!(
            "{what} {strategy:?} {size}x{size} x {frames} frames: max z {worst_here:.2}; whole-image green {:.4} ± {:.4}; CPU {:.2} s, {name} {:.2} s",
            whole.mean, whole.std_err, cpu.seconds, gpu.seconds
        );
        worst = worst.max(worst_here);
    }
    worst
}

/// The share of pixels whose values agree within 1e-5 (relative).
pub fn share_equal(a: &[Vec3], b: &[Vec3]) -> f64 {
    let close = a.iter().zip(b).filter(|(x, y)| (**x - **y).abs().max_element() <= 1e-5 * x.max_element().max(1e-3));
    close.count() as f64 / a.len() as f64
}

/// With the same seed, the CPU and `kind` draw the same random numbers: one frame's samples
/// agree pixel by pixel; with different seeds they would not (the control). See
/// `render_gl.rs` for why not every pixel: an ulp of `atan2`/`acos` can move a sky lookup.
pub fn assert_same_random_sequence(kind: RendererKind) {
    let (size, seed, name) = (32u32, 12345, kind.name());
    let first_frame = |r: &mut dyn Renderer| {
        r.render_frame().expect("frame");
        r.image().expect("readback").pixels
    };
    for strategy in STRATEGIES {
        let p = packed(&sky_lit_plane(), strategy, size, 3);
        let cpu = first_frame(&mut CpuRenderer::new(p.clone(), seed));
        let other = first_frame(&mut CpuRenderer::new(p.clone(), seed + 1));
        let gpu = first_frame(renderer(kind, p, seed).as_mut());
        let agree = share_equal(&cpu, &gpu);
        let control = share_equal(&cpu, &other);
        eprintln!(
            "{strategy:?}: same seed, CPU vs {name}: {:.2}% of pixels agree; CPU seed vs seed + 1: {:.2}%",
            100.0 * agree,
            100.0 * control
        );
        assert!(control < 0.5, "{strategy:?}: the scene does not expose the random numbers ({control})");
        assert!(agree > 0.95, "{strategy:?}: only {:.2}% of the pixels match the CPU's", 100.0 * agree);
    }
}
