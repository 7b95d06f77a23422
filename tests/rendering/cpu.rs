//! The path-tracing kernel on the CPU backend: analytic scenes, agreement of the three
//! sampling strategies, MIS variance, and no NaN/Inf in the accumulation.

use crate::common;

use glam::{DVec3, Vec3};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::pack;
use tracer::scene::{self, Scene, Sky};
use tracer::stats::Estimate;

/// Renders `frames` frames and returns the renderer plus, per frame, the mean of each of the
/// 4 x 4 image regions and, last, of the whole image (red, green, blue).
fn render(scene: &Scene, strategy: Strategy, size: u32, frames: u32, max_depth: u32) -> (CpuRenderer, Vec<Vec<DVec3>>) {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: size, height: size, strategy, max_depth };
    let mut r = CpuRenderer::new(pack(scene, &bvh, &settings).expect("pack"), 7);
    let mut per_frame = Vec::new();
    let mut previous = vec![DVec3::ZERO; 17];
    for _ in 0..frames {
        r.render_frame().expect("frame");
        let img = r.image().expect("image");
        let n = r.frames() as f64;
        let sums = common::region_means(size, 4, |i| img.pixels[i].as_dvec3() * n);
        per_frame.push(sums.iter().zip(&previous).map(|(s, p)| *s - *p).collect());
        previous = sums;
    }
    (r, per_frame)
}

fn estimate(per_frame: &[Vec<DVec3>], block: usize, channel: usize) -> Estimate {
    let samples: Vec<f64> = per_frame.iter().map(|f| f[block][channel]).collect();
    Estimate::from_samples(&samples)
}

const STRATEGIES: [Strategy; 3] = [Strategy::Bsdf, Strategy::Nee, Strategy::Mis];

/// The statistical bound for agreement: |a - b| within 5 combined standard errors, over 17
/// regions x 3 channels x 3 pairs (a false alarm at 5 sigma is ~1 in 10^6 per comparison).
const Z_BOUND: f64 = 5.0;

#[test]
fn white_furnace_converges_to_the_truncated_geometric_series() {
    // Closed box, albedo a, emission E everywhere: a path of at most D segments collects
    // E * (1 + a + ... + a^(D-1)).
    let (a, e, depth) = (0.5f32, 1.0f32, 6u32);
    let scene = scene::white_furnace(Vec3::splat(a), Vec3::splat(e));
    let exact = (e * (1.0 - a.powi(depth as i32)) / (1.0 - a)) as f64;
    for strategy in STRATEGIES {
        let (r, per_frame) = render(&scene, strategy, 32, 64, depth);
        assert_eq!(r.rejected_samples().expect("accumulation"), 0);
        for block in 0..17 {
            let est = estimate(&per_frame, block, 0);
            let z = est.z_score_to(exact);
            assert!(
                z < Z_BOUND || (est.mean - exact).abs() < 1e-4,
                "{strategy:?} block {block}: {} ± {} vs exact {exact} (z = {z:.1})",
                est.mean,
                est.std_err
            );
        }
    }
}

#[test]
fn diffuse_plane_under_a_uniform_sky_is_albedo_times_sky() {
    let (albedo, sky) = (0.6f32, Vec3::new(1.0, 0.5, 0.25));
    let mut scene = scene::diffuse_plane(Vec3::splat(albedo));
    scene.sky = Some(Sky::uniform(sky));
    for strategy in STRATEGIES {
        let (r, per_frame) = render(&scene, strategy, 32, 64, 2);
        assert_eq!(r.rejected_samples().expect("accumulation"), 0);
        for block in 0..17 {
            for c in 0..3 {
                let exact = (albedo * sky[c]) as f64;
                let est = estimate(&per_frame, block, c);
                let z = est.z_score_to(exact);
                assert!(
                    z < Z_BOUND || (est.mean - exact).abs() < 1e-4 * exact.max(1.0),
                    "{strategy:?} block {block} channel {c}: {} ± {} vs {exact}",
                    est.mean,
                    est.std_err
                );
            }
        }
    }
}

/// All three strategies estimate the same image: block means agree within the bound.
fn assert_strategies_agree(scene: &Scene, size: u32, frames: u32) {
    let runs: Vec<_> = STRATEGIES.iter().map(|s| render(scene, *s, size, frames, 6)).collect();
    for (r, _) in &runs {
        assert_eq!(r.rejected_samples().expect("accumulation"), 0, "no NaN/Inf may reach the accumulation buffer");
    }
    for i in 0..3 {
        for j in i + 1..3 {
            for block in 0..17 {
                for c in 0..3 {
                    let a = estimate(&runs[i].1, block, c);
                    let b = estimate(&runs[j].1, block, c);
                    let z = a.z_score(&b);
                    assert!(
                        z < Z_BOUND,
                        "{:?} vs {:?}, block {block} channel {c}: {} ± {} vs {} ± {} (z = {z:.1})",
                        STRATEGIES[i],
                        STRATEGIES[j],
                        a.mean,
                        a.std_err,
                        b.mean,
                        b.std_err
                    );
                }
            }
        }
    }
}

#[test]
fn strategies_agree_on_the_cornell_box() {
    assert_strategies_agree(&scene::cornell_box(), 64, 512);
}

#[test]
fn strategies_agree_on_a_textured_scene() {
    let path = common::test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf");
    let mut scene = scene::load(&path).expect("BoxTextured loads");
    scene.sky = Some(Sky::uniform(Vec3::splat(1.0)));
    assert_strategies_agree(&scene, 32, 128);
}

#[test]
fn mis_variance_is_not_worse_than_the_better_single_strategy() {
    // Sum of per-pixel variances: MIS may pay a little for combining, never much.
    const FACTOR: f64 = 1.5;
    let scene = scene::cornell_box();
    let totals: Vec<f64> = STRATEGIES
        .iter()
        .map(|s| {
            let (r, _) = render(&scene, *s, 32, 128, 6);
            r.variance().iter().map(|v| v.element_sum() as f64).sum()
        })
        .collect();
    let best_single = totals[0].min(totals[1]);
    assert!(totals[2] <= FACTOR * best_single, "variance: bsdf {} nee {} mis {}", totals[0], totals[1], totals[2]);
}

#[test]
fn the_same_seed_gives_the_same_image() {
    let scene = scene::cornell_box();
    let (a, _) = render(&scene, Strategy::Mis, 16, 4, 6);
    let (b, _) = render(&scene, Strategy::Mis, 16, 4, 6);
    assert_eq!(a.image().expect("image"), b.image().expect("image"));
}

/// A frame rendered in bands of rows (`Renderer::render_band`, each band with its frame's seed)
/// is the frame rendered whole, bit for bit; the sample count advances with a frame's last band,
/// and a restart abandons a split frame (`common::bands`, as GL's and wgpu's).
#[test]
fn a_frame_split_into_bands_is_the_unsplit_frame() {
    let base = common::agreement::packed(&scene::cornell_box(), Strategy::Mis, 20, 4);
    common::bands::assert_bands_make_the_whole_frame(
        &mut CpuRenderer::new(base.clone(), 3),
        &mut CpuRenderer::new(base, 3),
        20,
    );
}

/// `set_uniforms` restarts the accumulation and renders what a renderer created with the new
/// uniforms renders; the image size cannot change.
#[test]
fn set_uniforms_renders_like_a_fresh_renderer() {
    let scene = scene::cornell_box();
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: 16, height: 12, strategy: Strategy::Mis, max_depth: 4 };
    let base = pack(&scene, &bvh, &settings).expect("pack");
    let mut moved = base.clone();
    moved.scene.camera_position += Vec3::new(0.2, -0.1, 0.3);
    moved.scene.strategy = Strategy::Nee.uniform_value();
    let camera = (moved.scene.camera_position, moved.scene.strategy);
    let mut reused = CpuRenderer::new(base, 5);
    for _ in 0..3 {
        reused.render_frame().expect("frame");
    }
    reused.render_band(5).expect("band");
    reused
        .set_uniforms(&mut |s| {
            s.camera_position = camera.0;
            s.strategy = camera.1;
        })
        .expect("set_uniforms");
    assert_eq!((reused.frames(), reused.rows_left()), (0, 12));
    let mut fresh = CpuRenderer::new(moved, 5);
    for _ in 0..2 {
        reused.render_frame().expect("frame");
        fresh.render_frame().expect("frame");
    }
    assert_eq!(reused.accumulation().expect("sums"), fresh.accumulation().expect("sums"));
    let err = reused.set_uniforms(&mut |s| s.height += 1).expect_err("the size is fixed");
    assert!(err.to_string().contains("fixed at 16x12"), "{err}");
    assert_eq!(reused.packed().scene.height, 12, "a refused change leaves the size as it was");
}
