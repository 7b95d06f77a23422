//! The denoiser's guide as the path tracer accumulates it (`integrator::render_guided_sample`,
//! `Features::denoise_guide`): one sample's colour and its first hit's albedo, normal, depth and
//! emission per pixel, on every runtime, over the Cornell box (Lambert, no shading normals, area
//! lights seen directly) and DamagedHelmet (textures, shading and normal maps, metal-roughness,
//! emissive textures). Paths end at their first hit (`max_depth` 1), so the colour is what the
//! camera ray sees and the comparison is not a bounce's rounding.

use super::*;

/// A camera ray, a traversal and a normalised (possibly normal-mapped) normal: a few ULP of GPU
/// rounding in each. Pixels whose ray grazes an edge between triangles may hit the other one:
/// counted, at most 1 %.
const GUIDE: Tolerance = Tolerance::ulps(256).with_absolute(2e-5).flushing_subnormals();

fn assert_guides_agree(eq: &mut Equivalence, what: &str, scene: &tracer::scene::Scene, size: u32) {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: size, height: size, max_depth: 1, ..RenderSettings::default() };
    let mut packed = pack(scene, &bvh, &settings).expect("pack");
    packed.set_denoise_guide(true);
    packed.scene.frame_seed = 12345;
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let pixels: Vec<(u32, u32)> = (0..size * size).map(|i| (i % size, i / size)).collect();
    let outcome = eq
        .run("render_guided_sample", &pixels, |s, &(x, y)| (integrator::render_guided_sample(s, x, y),), GUIDE)
        .unwrap_or_else(|e| panic!("render_guided_sample: {e}"));
    report(&outcome);
    // The guard: the pixels see both surfaces and (Cornell box) the light, so every field is exercised.
    let cpu: Vec<_> = pixels.iter().map(|&(x, y)| integrator::render_guided_sample(&packed.scene, x, y)).collect();
    assert!(
        cpu.iter().any(|g| g.normal.w < 1.0e19) && cpu.iter().any(|g| g.albedo.x < 0.99),
        "{what}: no surface seen"
    );
    for c in &outcome.comparisons {
        let share = c.mismatched.len() as f64 / c.invocations.max(1) as f64;
        assert!(
            share <= 0.01,
            "{what} on {}: {} of {} pixels differ: {outcome}",
            c.backend,
            c.mismatched.len(),
            c.invocations
        );
    }
}

#[test]
fn guided_samples_agree() {
    let mut eq = equivalence();
    let cornell = tracer::scene::cornell_box();
    assert_guides_agree(&mut eq, "Cornell box", &cornell, 48);
    let helmet =
        tracer::scene::load(&test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb")).expect("loads");
    assert_guides_agree(&mut eq, "DamagedHelmet", &helmet, 48);
}
