//! The denoiser's guide (`kernel::denoise::first_hit_aov`): the first hit's albedo, normal and
//! depth per pixel, on every runtime, over the Cornell box (Lambert, no shading normals) and
//! DamagedHelmet (textures, shading and normal maps, metal-roughness).

use super::*;

/// A camera ray, a traversal and a normalised (possibly normal-mapped) normal: a few ULP of GPU
/// rounding in each. Pixels whose ray grazes an edge between triangles may hit the other one:
/// counted, at most 1 %.
const AOV: Tolerance = Tolerance::ulps(256).with_absolute(2e-5).flushing_subnormals();

fn assert_aovs_agree(eq: &mut Equivalence, what: &str, scene: &tracer::scene::Scene, size: u32) {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: size, height: size, ..RenderSettings::default() };
    let packed = pack(scene, &bvh, &settings).expect("pack");
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    // Pixel centres, and a quarter-pixel grid as the host's albedo average takes it.
    let films: Vec<(Vec2,)> = (0..size * size * 4)
        .map(|i| (Vec2::new((i % (2 * size)) as f32 * 0.5 + 0.25, (i / (2 * size)) as f32 * 0.5 + 0.25),))
        .collect();
    let outcome = eq
        .run("first_hit_aov", &films, |s, &(film,)| (denoise::first_hit_aov(s, film),), AOV)
        .unwrap_or_else(|e| panic!("first_hit_aov: {e}"));
    report(&outcome);
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
fn first_hit_aovs_agree() {
    let mut eq = equivalence();
    assert_aovs_agree(&mut eq, "Cornell box", &tracer::scene::cornell_box(), 48);
    let helmet =
        tracer::scene::load(&test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb")).expect("loads");
    assert_aovs_agree(&mut eq, "DamagedHelmet", &helmet, 48);
}
