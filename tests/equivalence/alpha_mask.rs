//! Alpha masks (`alpha_mask::is_hole` and the functions it uses, `traverse_masked::visible_hit`),
//! and the traversal and light sampling that call them, on the generated alpha-masked scene
//! (`scene::alpha_masked_screen`): every input stated once and run on every runtime.

use super::*;
use tracer::kernel::{alpha_mask, lights, traverse_masked};

/// Coverage is a bilinear texture lookup times a factor: `sample_texture`'s tolerance.
const COVERAGE: Tolerance = Tolerance::ulps(16).with_absolute(1e-6).flushing_subnormals();

/// How far the coverage at (u, v) of `triangle` is from its cutoff (infinite for unmasked
/// triangles): GPU rounding may decide points closer than a margin the other way.
fn cutoff_distance(k: &Scene, triangle: u32, u: f32, v: f32) -> f32 {
    if !scene_data::fetch_triangle(k, triangle).masked {
        return f32::INFINITY;
    }
    let tri = scene_data::fetch_triangle(k, triangle);
    let mask = alpha_mask::fetch_alpha_mask(k, tri.material);
    let uv = scene_data::texcoord(k, triangle, u, v);
    (alpha_mask::coverage(k, mask, uv) - mask.cutoff).abs()
}

/// Whether the segment `o + t d`, t in (0, t_max), crosses a masked triangle near a hole's edge.
fn near_an_edge(k: &Scene, triangles: u32, o: Vec3, d: Vec3, t_max: f32) -> bool {
    (0..triangles).any(|i| {
        let tri = scene_data::fetch_triangle(k, i);
        let h = intersect::intersect_triangle(o, d, tri.v0, tri.v1, tri.v2);
        h.t < t_max && cutoff_distance(k, i, h.u, h.v) < 1e-3
    })
}

#[test]
fn alpha_mask_functions_agree() {
    let scene = tracer::scene::alpha_masked_screen();
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    assert!(packed.features.alpha_mask && packed.features.textures, "{:?}", packed.features);
    let mut eq = equivalence();
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let k = eq.scene().clone();
    let triangles = packed.triangle_count as u32;
    let materials = scene.materials.len() as u32;
    let mut r = TestRng::new(57);

    let indices: Vec<(u32,)> = (0..materials).map(|i| (i,)).collect();
    assert_equivalent(
        &mut eq,
        "fetch_alpha_mask",
        &indices,
        |s, &(i,)| (alpha_mask::fetch_alpha_mask(s, i),),
        Tolerance::EXACT,
    );
    let tris: Vec<(u32,)> = (0..triangles).map(|i| (i,)).collect();
    let fetched = assert_equivalent(
        &mut eq,
        "fetch_triangle",
        &tris,
        |s, &(i,)| (scene_data::fetch_triangle(s, i),),
        Tolerance::EXACT,
    );
    let masked_count = fetched.output(Backend::Cpu).unwrap().iter().filter(|(t,)| t.masked).count();
    assert_eq!(masked_count, 4, "the screen's and the light's two triangles each");

    // Coverage of every material's mask over uv in and beyond [0, 1] (clamped textures).
    let lookups: Vec<(alpha_mask::AlphaMaskData, Vec2)> = (0..1 << 14)
        .map(|i| {
            let mask = alpha_mask::fetch_alpha_mask(&k, i % materials);
            (mask, Vec2::new(r.range(-0.5, 1.5), r.range(-0.5, 1.5)))
        })
        .collect();
    assert_equivalent(&mut eq, "coverage", &lookups, |s, &(m, uv)| (alpha_mask::coverage(s, m, uv),), COVERAGE);

    // Holes at random points of every triangle, away from the cutoff (where rounding decides).
    let points: Vec<(u32, u32, f32, f32)> = (0..1 << 15)
        .map(|_| {
            let (u, v) = (r.f32(), r.f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let i = r.next_u32() % triangles;
            (i, scene_data::fetch_triangle(&k, i).material, u, v)
        })
        .filter(|&(i, _, u, v)| cutoff_distance(&k, i, u, v) > 1e-3)
        .collect();
    let holes = assert_equivalent(
        &mut eq,
        "is_hole",
        &points,
        |s, &(i, m, u, v)| (alpha_mask::is_hole(s, i, m, u, v),),
        Tolerance::EXACT,
    );
    let hole_count = holes.output(Backend::Cpu).unwrap().iter().filter(|(h,)| *h).count();
    println!("is_hole: {hole_count} holes of {} points", points.len());
    assert!(hole_count > points.len() / 8 && hole_count < points.len() / 2, "{hole_count} holes");

    // Traversal: rays from around the scene through the screen and the light, away from the
    // holes' edges. Closest hits continue behind holes; shadow rays ignore them.
    let (lo, hi) = (Vec3::new(-1.5, -0.5, -1.5), Vec3::new(1.5, 2.5, 1.5));
    let point = |r: &mut TestRng, lo: Vec3, hi: Vec3| lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
    let rays: Vec<(Vec3, Vec3, f32)> = (0..50_000)
        .map(|_| {
            let o = point(&mut r, lo, hi);
            let target = point(&mut r, Vec3::new(-0.6, 0.7, -0.6), Vec3::new(0.6, 1.7, 0.6));
            (o, (target - o).normalize(), MISS)
        })
        .filter(|&(o, d, t)| !near_an_edge(&k, triangles, o, d, t))
        .collect();
    let closest = assert_equivalent(
        &mut eq,
        "trace_closest",
        &rays,
        |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),),
        // Barycentrics near 0 are differences of nearly equal products (Möller–Trumbore): GL
        // rounds them a few 1e-7 apart (2.4e-7 measured on llvmpipe); the triangle is the same.
        Tolerance::ulps(16).with_absolute(1e-6).flushing_subnormals(),
    );
    let cpu = closest.output(Backend::Cpu).unwrap();
    // The rays do meet holes: some pass through a masked triangle to something behind it.
    let through = rays
        .iter()
        .zip(cpu)
        .filter(|(&(o, d, _), (h,))| {
            (0..triangles).any(|i| {
                let tri = scene_data::fetch_triangle(&k, i);
                tri.masked && intersect::intersect_triangle(o, d, tri.v0, tri.v1, tri.v2).t < h.t
            })
        })
        .count();
    println!("trace_closest: {through} of {} rays passed through a hole", rays.len());
    assert!(through > rays.len() / 20, "{through} rays through holes");
    let shadow: Vec<(Vec3, Vec3, f32)> = rays
        .iter()
        .zip(cpu)
        .flat_map(|(&(o, d, _), (h,))| {
            let t = if h.triangle == NONE { 1.0 } else { h.t };
            [(o, d, MISS), (o, d, t * 0.999), (o, d, t * 1.001)]
        })
        .filter(|&(o, d, t)| !near_an_edge(&k, triangles, o, d, t))
        .collect();
    assert_equivalent(
        &mut eq,
        "occluded",
        &shadow,
        |s, &(o, d, t)| (traverse::occluded(s, o, d, t),),
        Tolerance::EXACT,
    );

    // One traversal that resumes behind a hole (`closest_visible_one_level`,
    // `occluded_masked_one_level`, issue 31) finds what searching again from the root behind
    // each hole (`visible_hit`, the design before) finds, on the CPU.
    for &(o, d, t) in &rays {
        assert_eq!(traverse::trace_closest(&k, o, d, t), traverse_masked::visible_hit(&k, o, d, t, false), "{o} {d}");
    }
    for &(o, d, t) in &shadow {
        let searched = traverse::any_hit_one_level(&k, o, d, t)
            || traverse_masked::visible_hit(&k, o, d, t, true).triangle != NONE;
        assert_eq!(traverse::occluded(&k, o, d, t), searched, "{o} {d} {t}");
    }

    // Each segment against a leaf of one triangle: an unmasked triangle hit blocks; masked
    // ones are left to `visible_hit` (the hole test stays out of traversal's loops).
    let segments: Vec<(u32, Vec3, Vec3, f32)> = shadow
        .iter()
        .enumerate()
        .map(|(j, &(o, d, t))| (traverse::stack_entry(j as u32 % triangles, 1), o, d, t))
        .collect();
    let occludes = assert_equivalent(
        &mut eq,
        "leaf_occludes",
        &segments,
        |s, &(leaf, o, d, t)| (traverse::leaf_occludes(s, leaf, o, d, t),),
        Tolerance::EXACT,
    );
    let blocked = occludes.output(Backend::Cpu).unwrap().iter().filter(|(b,)| *b).count();
    assert!(blocked > 0 && blocked < segments.len(), "{blocked} of {} segments blocked", segments.len());
    // The masked triangles alone, holes skipped: what shadow rays test after the loop.
    let masked_only: Vec<(Vec3, Vec3, f32, bool)> = shadow.iter().map(|&(o, d, t)| (o, d, t, true)).collect();
    let visible = assert_equivalent(
        &mut eq,
        "visible_hit",
        &masked_only,
        |s, &(o, d, t, only_masked)| (traverse_masked::visible_hit(s, o, d, t, only_masked),),
        Tolerance::ulps(16).with_absolute(1e-6).flushing_subnormals(),
    );
    let masked_hits = visible.output(Backend::Cpu).unwrap().iter().filter(|(h,)| h.triangle != NONE).count();
    assert!(
        masked_hits > 0 && masked_hits < shadow.len(),
        "{masked_hits} of {} segments meet a masked texel",
        shadow.len()
    );

    // Light sampling on the masked emitter: samples in its holes are invalid (pdf 0).
    let light_cases: Vec<(Vec3, Vec3)> = (0..1 << 14)
        .map(|_| {
            (point(&mut r, Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 1.5, 1.0)), Vec3::new(r.f32(), r.f32(), r.f32()))
        })
        .filter(|&(p, u)| {
            // Away from the light's holes' edges.
            let b = tracer::kernel::sampling::uniform_sample_triangle(u.y, u.z);
            let light = lights::choose_light(&k, u.x);
            let tri = k.lights.as_slice()[(light * scene_data::LIGHT_TEXELS + 1) as usize].x as u32;
            p.is_finite() && cutoff_distance(&k, tri, b.x, b.y) > 1e-3
        })
        .collect();
    let samples = assert_equivalent(
        &mut eq,
        "sample_light",
        &light_cases,
        |s, &(p, u)| (lights::sample_light(s, p, u),),
        Tolerance::ulps(64).with_absolute(1e-6).flushing_subnormals(),
    );
    let invalid = samples.output(Backend::Cpu).unwrap().iter().filter(|(l,)| l.pdf == 0.0).count();
    println!("sample_light: {invalid} of {} samples in the emitter's holes or behind it", light_cases.len());
    assert!(invalid > light_cases.len() / 4, "{invalid}: half of the light is holes");
}

/// Two levels with alpha masks (`Features::instances` and `alpha_mask`, issue 31): one
/// traversal per ray (`traverse_masked::closest_visible_two_level`, `occluded_masked_two_level`) on
/// every runtime, over the generated field of masked leaves (mirrored and non-uniformly scaled
/// placements, coincident masked quads, placements twice). Rays whose masked crossings are all
/// away from a cutoff (where rounding decides) find on each GPU runtime the CPU's hit (the same
/// triangle of the same placement, t to rounding in the move to a placement's space, or a
/// near-tie there, as `two_level_traversal_agrees`), and shadow rays agree.
#[test]
fn two_level_alpha_masks_agree() {
    let scene = tracer::scene::instanced_masked_leaves(4);
    let packed = tracer::pack::build_and_pack(&scene, &RenderSettings::default()).expect("pack").1;
    assert!(packed.features.instances && packed.features.alpha_mask, "{:?}", packed.features);
    let mut eq = equivalence();
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let k = eq.scene().clone();
    // Every masked triangle the segment crosses is hit away from its cutoff.
    let away_from_edges = |o: Vec3, d: Vec3, t_max: f32| {
        let mut after = traverse_masked::before_any_hit();
        for _ in 0..64 {
            let c = traverse::closest_candidate(&k, o, d, t_max, after, true);
            if c.triangle == NONE {
                return true;
            }
            if cutoff_distance(&k, c.triangle, c.u, c.v) < 1e-3 {
                return false;
            }
            after = c;
        }
        false
    };
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.1, b.max + b.diagonal() * 0.1);
    let mut r = TestRng::new(31);
    let point = |r: &mut TestRng, lo: Vec3, hi: Vec3| lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
    let rays: Vec<(Vec3, Vec3, f32)> = (0..30_000)
        .map(|_| {
            let o = point(&mut r, lo, hi);
            (o, (point(&mut r, b.min, b.max) - o).normalize(), MISS)
        })
        .filter(|&(o, d, t)| away_from_edges(o, d, t))
        .collect();
    let closest = eq
        .run(
            "trace_closest",
            &rays,
            |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),),
            Tolerance::ulps(16).with_absolute(1e-6).flushing_subnormals(),
        )
        .expect("runs");
    report(&closest);
    let cpu = closest.output(Backend::Cpu).unwrap();
    let through = rays
        .iter()
        .zip(cpu)
        .filter(|(&(o, d, t), (h,))| {
            traverse::closest_candidate(&k, o, d, t, traverse_masked::before_any_hit(), false) != *h
        })
        .count();
    let placed = cpu.iter().filter(|(h,)| h.triangle != NONE && h.instance != cpu[0].0.instance).count();
    println!("two levels with masks: {} rays, {through} through holes, {placed} on other placements", rays.len());
    assert!(through > rays.len() / 20 && placed > rays.len() / 10, "{through} through holes, {placed} placed");
    let shadow: Vec<(Vec3, Vec3, f32)> = rays
        .iter()
        .zip(cpu)
        .flat_map(|(&(o, d, _), (h,))| [(o, d, MISS), (o, d, if h.triangle == NONE { 1.0 } else { h.t * 0.999 })])
        .collect();
    let any =
        eq.run("occluded", &shadow, |s, &(o, d, t)| (traverse::occluded(s, o, d, t),), Tolerance::EXACT).expect("runs");
    report(&any);
    for backend in Backend::GPU {
        let gpu = closest.output(backend).unwrap();
        let mut near_ties = 0;
        for &i in &closest.comparison(backend).unwrap().mismatched {
            let ((want,), (got,)) = (cpu[i], gpu[i]);
            assert!(
                want.triangle != NONE && got.triangle != NONE,
                "ray {i}: hit vs miss: CPU {want:?} vs {backend} {got:?}"
            );
            let (o, _, _) = rays[i];
            let gap = (got.t - want.t).abs() / want.t.max(o.length()).max(1.0);
            assert!(gap <= 1e-5, "ray {i}: CPU {want:?} vs {backend} {got:?}");
            near_ties += ((want.triangle, want.instance) != (got.triangle, got.instance)) as usize;
        }
        assert!(near_ties * 1000 <= rays.len(), "{backend}: {near_ties} near-ties");
        let (cpu_any, gpu_any) = (any.output(Backend::Cpu).unwrap(), any.output(backend).unwrap());
        let differ = (0..cpu_any.len()).filter(|&j| cpu_any[j].0 != gpu_any[j].0).count();
        println!("two levels with masks on {backend}: {near_ties} near-ties, {differ} shadow answers differ");
        assert!(differ * 1000 <= shadow.len(), "{backend}: {differ} shadow disagreements");
    }
}
