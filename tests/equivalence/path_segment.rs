//! A path segment's steps, which the megakernel (`integrator::trace_path`) and the wavefront's
//! stages (`kernel::wavefront`) share: `start_path` and `shade_hit` on the CPU, wgpu and
//! WebGPU, the runtimes that run the wavefront's language. (`shade_hit` returns 36 words: more
//! than GLSL ES 3.00's four colour attachments hold, see `tests/kernel/codegen.rs`; on GL and
//! WebGL2 the megakernel's images test it.)

use super::*;
use tracer::kernel::integrator::{no_shadow_ray, shade_hit, start_path, FirstHit, PathState, ShadowRay, SKY_DEPTH};

/// Camera paths and second segments are sums of a few products: the BSDF and light sampling
/// functions' tolerance.
const SEGMENT: Tolerance = Tolerance::ulps(64).with_absolute(1e-6).flushing_subnormals();

fn first_hit() -> FirstHit {
    FirstHit { albedo: Vec3::ZERO, normal: Vec3::Z, depth: SKY_DEPTH, emission: Vec3::ZERO }
}

#[test]
fn path_segment_steps_agree_on_the_wavefronts_runtimes() {
    let scene = tracer::scene::cornell_box();
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: 64, height: 64, ..RenderSettings::default() };
    let packed = pack(&scene, &bvh, &settings).expect("pack");
    let mut eq = Equivalence::new(&[Backend::Cpu, Backend::Wgpu, Backend::WebGpu], &[hazards::kernel::kernel_ir()])
        .unwrap_or_else(|e| panic!("wgpu and the browser's WebGPU must run here: {e}"));
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let k = eq.scene().clone();

    // Camera paths of every pixel over two frames.
    let pixels: Vec<(u32, u32, u32, u32)> = (0..2u32)
        .flat_map(|frame| (0..64 * 64).map(move |p| (p % 64, p / 64, rng::seed_of_frame(frame, 3), frame)))
        .collect();
    assert_equivalent(&mut eq, "start_path", &pixels, |s, &(x, y, seed, f)| (start_path(s, x, y, seed, f),), SEGMENT);

    // Each path at its first and second hit (the second with a BSDF pdf: MIS weights), before
    // Russian roulette starts.
    let mut segments: Vec<(PathState, Hit, FirstHit, ShadowRay)> = Vec::new();
    for &(x, y, seed, f) in &pixels {
        let mut path = start_path(&k, x, y, seed, f);
        for _ in 0..2 {
            let hit = traverse::trace_closest(&k, path.origin, path.dir, MISS);
            segments.push((path, hit, first_hit(), no_shadow_ray()));
            let (mut first, mut shadow) = (first_hit(), no_shadow_ray());
            if !shade_hit(&k, &mut path, hit, &mut first, &mut shadow) {
                break;
            }
        }
    }
    let with_shadow = |o: &Outcome<(bool, PathState, FirstHit, ShadowRay)>| {
        o.output(Backend::Cpu).map_or(0, |out| out.iter().filter(|r| r.3.t_max > 0.0).count())
    };
    let outcome = assert_equivalent(
        &mut eq,
        "shade_hit",
        &segments,
        |s, &(path, hit, first, shadow)| {
            let (mut path, mut first, mut shadow) = (path, first, shadow);
            let go_on = shade_hit(s, &mut path, hit, &mut first, &mut shadow);
            (go_on, path, first, shadow)
        },
        SEGMENT,
    );
    let second = segments.iter().filter(|s| s.0.depth == 1).count();
    assert!(second > segments.len() / 3, "second segments: {second} of {}", segments.len());
    assert!(with_shadow(&outcome) > segments.len() / 2, "shadow rays: {}", with_shadow(&outcome));
}
