//! Ray/triangle, ray/box, and full BVH traversal (closest and any hit) on DamagedHelmet.

use super::*;

// ---------------------------------------------------------------------------------------------
// Ray/triangle and ray/box.

/// Hit or miss may differ only where the exact answer is on the boundary: the hit side's
/// barycentrics within `EDGE` of an edge. Measured on llvmpipe; see the printed counts.
const EDGE: f32 = 1e-5;

/// Möller–Trumbore where both sides hit: most results are within a few ULP, but GPUs may fuse
/// the cross and dot products' multiply-adds (docs/dsl.md: contraction is not guaranteed either
/// way), which changes the cancellation error. Hits outside `TRIANGLE` must then be within
/// `CONDITIONED` units of [`hit_error_scale`], the forward error bound of the computation.
const TRIANGLE: Tolerance = Tolerance::ulps(16).flushing_subnormals();
const CONDITIONED: f64 = 16.0;

/// The forward error scale of Möller–Trumbore's t, u and v (per unit roundoff): each is a
/// quotient of a triple product by `det`, so its error is about eps * (the products' magnitudes
/// plus the quotient times det's magnitude) / |det|. Large for grazing rays and slivers.
fn hit_error_scale(o: Vec3, d: Vec3, v0: Vec3, v1: Vec3, v2: Vec3, hit: &TriangleHit) -> [f64; 3] {
    let (o, d, v0, v1, v2) = (o.as_dvec3(), d.as_dvec3(), v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    let (e1, e2, s) = (v1 - v0, v2 - v0, o - v0);
    let det = e1.dot(d.cross(e2)).abs();
    let det_magnitude = e1.length() * d.length() * e2.length();
    let eps = f64::from(f32::EPSILON);
    let scale = |triple: f64, value: f32| eps * (triple + det_magnitude * f64::from(value).abs()) / det;
    [
        scale(e2.length() * s.length() * e1.length(), hit.t),
        scale(s.length() * d.length() * e2.length(), hit.u),
        scale(d.length() * s.length() * e1.length(), hit.v),
    ]
}

/// How many error scales apart two hits on the same triangle are (the largest of t, u, v).
fn hit_difference(args: (Vec3, Vec3, Vec3, Vec3, Vec3), a: &TriangleHit, b: &TriangleHit) -> f64 {
    let (o, d, v0, v1, v2) = args;
    let scale = hit_error_scale(o, d, v0, v1, v2, a);
    let diffs = [a.t - b.t, a.u - b.u, a.v - b.v].map(|x| f64::from(x).abs());
    diffs.iter().zip(scale).map(|(d, s)| d / s.max(1e-30)).fold(0.0, f64::max)
}

type TriangleArgs = (Vec3, Vec3, Vec3, Vec3, Vec3);

fn triangle_cases(n: usize) -> Vec<TriangleArgs> {
    let mut r = TestRng::new(6);
    let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
    let above = Vec3::new(0.25, 0.25, 1.0);
    let down = -Vec3::Z;
    let nan = Vec3::new(f32::NAN, 0.0, 0.0);
    let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
    let mut v = vec![
        (above, down, a, b, c),                         // plain hit
        (Vec3::new(0.5, 0.5, 1.0), down, a, b, c),      // on the hypotenuse
        (Vec3::new(0.0, 0.0, 1.0), down, a, b, c),      // on a vertex
        (Vec3::new(-0.5, 0.25, 0.0), Vec3::X, a, b, c), // edge-on: in the plane
        (above, Vec3::X, a, b, c),                      // parallel above
        (above, down, a, a, c),                         // zero-area (two equal vertices)
        (above, down, a, b, Vec3::new(2.0, 0.0, 0.0)),  // collinear
        (above, Vec3::ZERO, a, b, c),                   // zero direction
        (above, -down, a, b, c),                        // behind the origin
        (Vec3::new(0.25, 0.25, 0.0), down, a, b, c),    // origin on the triangle (t = 0)
        (nan, down, a, b, c),
        (above, nan, a, b, c),
        (above, down, nan, b, c),
        (inf, down, a, b, c),
        (above, Vec3::new(0.0, 0.0, f32::NEG_INFINITY), a, b, c),
        (above * 1e30, down, a * 1e30, b * 1e30, c * 1e30),     // huge
        (above * 1e-30, down, a * 1e-30, b * 1e-30, c * 1e-30), // tiny (denormal products)
    ];
    while v.len() < n {
        let v0 = r.vec3(1.0);
        let v1 = v0 + r.vec3(0.5);
        let v2 = v0 + r.vec3(0.5);
        let origin = r.vec3(2.0);
        // Half of the rays aim at a point of the triangle's plane near it (many near edges).
        let target = if r.f32() < 0.5 {
            let (s, t) = (r.range(-0.05, 1.05), r.range(-0.05, 1.05));
            v0 + (v1 - v0) * s * (1.0 - t) + (v2 - v0) * s * t
        } else {
            r.vec3(1.0)
        };
        v.push((origin, (target - origin).normalize(), v0, v1, v2));
    }
    v
}

#[test]
fn ray_triangle_agrees() {
    let mut eq = equivalence();
    let cases = triangle_cases(1 << 17);
    let outcome = eq
        .run(
            "intersect_triangle",
            &cases,
            |_, &(o, d, a, b, c)| (intersect::intersect_triangle(o, d, a, b, c),),
            TRIANGLE,
        )
        .expect("runs");
    report(&outcome);
    let cpu = outcome.output(Backend::Cpu).unwrap();
    let near_edge = |h: &TriangleHit| h.u.min(h.v).min(1.0 - h.u - h.v) <= EDGE;
    for backend in Backend::GPU {
        let gl = outcome.output(backend).unwrap();
        let comparison = outcome.comparison(backend).unwrap();
        let (mut flips, mut conditioned, mut worst) = (0, 0, 0.0f64);
        for &i in &comparison.mismatched {
            let ((want,), (got,)) = (cpu[i], gl[i]);
            if want.t < MISS && got.t < MISS {
                let scales = hit_difference(cases[i], &want, &got);
                assert!(
                    scales <= CONDITIONED,
                    "case {i} {:?}: CPU {want:?} vs {backend} {got:?}: {scales:.1} error scales",
                    cases[i]
                );
                worst = worst.max(scales);
                conditioned += 1;
                continue;
            }
            let hit = if want.t == MISS { got } else { want };
            assert!(near_edge(&hit), "case {i} {:?}: CPU {want:?} vs {backend} {got:?}", cases[i]);
            flips += 1;
        }
        println!(
        "intersect_triangle on {backend}: {flips} hit/miss flips, all within {EDGE} of an edge; {conditioned} common \
         hits beyond {TRIANGLE}, all within {worst:.2} (<= {CONDITIONED}) forward error scales"
    );
        assert!(flips * 1000 <= cases.len(), "{backend}: {flips} flips of {}", cases.len());
        // The special cases (the first ones) agree exactly on hit or miss.
        for i in 0..17 {
            assert_eq!(cpu[i].0.t == MISS, gl[i].0.t == MISS, "{backend}: special case {i} {:?}", cases[i]);
        }
    }
    let hits = cpu.iter().filter(|(h,)| h.t < MISS).count();
    assert!(hits > cases.len() / 10, "{hits} hits: too few to compare");
}

type BoxArgs = (Vec3, Vec3, Vec3, Vec3, f32);

fn box_cases(n: usize) -> Vec<BoxArgs> {
    let mut r = TestRng::new(7);
    let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
    let inv = |d: Vec3| intersect::safe_inverse(d);
    let mut v = vec![
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::X), lo, hi, MISS), // straight in
        (Vec3::new(-2.0, 1.0, 0.0), inv(Vec3::X), lo, hi, MISS), // along a face (y = max)
        (Vec3::new(-2.0, -1.0, -1.0), inv(Vec3::X), lo, hi, MISS), // along an edge
        (Vec3::new(-2.0, 1.0, 0.0), inv(Vec3::new(1.0, -0.0, 0.0)), lo, hi, MISS), // -0.0 component
        (Vec3::ZERO, inv(Vec3::Y), lo, hi, MISS),                // inside
        (Vec3::new(1.0, 0.0, 0.0), inv(Vec3::X), lo, hi, MISS),  // on the exit face
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::X), lo, hi, 0.5),  // t_max before the box
        (Vec3::new(-2.0, 0.0, 0.0), inv(-Vec3::X), lo, hi, MISS), // pointing away
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::X), Vec3::ZERO, Vec3::ZERO, MISS), // point box
        (Vec3::new(f32::NAN, 0.0, 0.0), inv(Vec3::X), lo, hi, MISS),
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::new(f32::NAN, 0.0, 0.0)), lo, hi, MISS),
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::ZERO), lo, hi, MISS), // zero direction
    ];
    let specials = v.len();
    while v.len() < n {
        let c = r.vec3(1.0);
        let e = Vec3::new(r.range(0.0, 0.5), r.range(0.0, 0.5), r.range(0.0, 0.5));
        let origin = r.vec3(2.0);
        let mut dir = r.unit_vector();
        // A quarter of the rays are axis-parallel, some starting on a face plane.
        if r.f32() < 0.25 {
            let axis = (r.next_u32() % 3) as usize;
            let mut d = Vec3::ZERO;
            d[axis] = if r.f32() < 0.5 { 1.0 } else { -1.0 };
            dir = d;
        }
        let mut o = origin;
        if r.f32() < 0.1 {
            let axis = (r.next_u32() % 3) as usize;
            o[axis] = if r.f32() < 0.5 { c[axis] - e[axis] } else { c[axis] + e[axis] };
        }
        let t_max = if r.f32() < 0.2 { r.range(0.0, 3.0) } else { MISS };
        v.push((o, inv(dir), c - e, c + e, t_max));
    }
    assert!(specials < n);
    v
}

#[test]
fn ray_box_agrees() {
    let mut eq = equivalence();
    let dirs: Vec<(Vec3,)> = floats_with_specials(1 << 15, 8, any_float)
        .chunks(3)
        .filter(|c| c.len() == 3)
        .map(|c| (Vec3::new(c[0], c[1], c[2]),))
        .collect();
    // 1 / x: GLSL ES only requires 2.5 ULP for division.
    assert_equivalent(
        &mut eq,
        "safe_inverse",
        &dirs,
        |_, &(d,)| (intersect::safe_inverse(d),),
        Tolerance::ulps(3).flushing_subnormals(),
    );

    let pairs: Vec<(f32, f32)> = floats_with_specials(1 << 14, 21, any_float)
        .chunks(2)
        .filter(|p| p.len() == 2 && !p[0].is_nan() && !p[1].is_nan())
        .map(|p| (p[0], p[1]))
        .collect();
    // Compare-and-select: exact, except that drivers may turn it into min/max, which do not
    // order +0 and -0 (measured: llvmpipe returns +0 for min_no_nan(0, -0), Rust -0).
    for function in ["min_no_nan", "max_no_nan"] {
        let select = |a: f32, b: f32| {
            if function == "min_no_nan" {
                intersect::min_no_nan(a, b)
            } else {
                intersect::max_no_nan(a, b)
            }
        };
        let outcome = eq.run(function, &pairs, |_, &(a, b)| (select(a, b),), Tolerance::EXACT).expect("runs");
        report(&outcome);
        for backend in Backend::GPU {
            let gl = outcome.output(backend).unwrap();
            let mismatched = &outcome.comparison(backend).unwrap().mismatched;
            for &i in mismatched {
                let (a, b) = pairs[i];
                assert!(a == 0.0 && b == 0.0 && gl[i].0 == 0.0, "{function}({a:e}, {b:e}) on {backend}: {}", gl[i].0);
            }
            println!("{function}: {} signed-zero pairs where {backend} picks the other zero", mismatched.len());
        }
    }

    let cases = box_cases(1 << 17);
    let outcome = eq
        .run(
            "intersect_aabb",
            &cases,
            |_, &(o, inv, lo, hi, t)| (intersect::intersect_aabb(o, inv, lo, hi, t),),
            Tolerance::ulps(4).flushing_subnormals(),
        )
        .expect("runs");
    report(&outcome);
    let cpu = outcome.output(Backend::Cpu).unwrap();
    for backend in Backend::GPU {
        let gl = outcome.output(backend).unwrap();
        let mut flips = Vec::new();
        for &i in &outcome.comparison(backend).unwrap().mismatched {
            let ((want,), (got,)) = (cpu[i], gl[i]);
            // Only hit/miss flips may differ, and only where the ray grazes the box: the entry
            // distance equals the exit distance up to rounding.
            let (o, inv, lo, hi, t_max) = cases[i];
            let (t0, t1) = ((lo - o) * inv, (hi - o) * inv);
            let enter = t0.min(t1).max_element().max(0.0);
            let exit = t0.max(t1).min_element().min(t_max);
            let grazing = (enter - exit).abs() <= 1e-5 * enter.abs().max(exit.abs()).max(1.0);
            assert!(
                (want == MISS) != (got == MISS) && grazing,
                "case {i} {:?}: CPU {want} vs {backend} {got}",
                cases[i]
            );
            flips.push(i);
        }
        println!("intersect_aabb on {backend}: {} hit/miss flips, all grazing", flips.len());
        assert!(flips.len() * 1000 <= cases.len(), "{backend}: {} flips", flips.len());
        for i in 0..12 {
            assert_eq!(cpu[i].0.to_bits(), gl[i].0.to_bits(), "{backend}: special case {i} {:?}", cases[i]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Full BVH traversal on DamagedHelmet.

type NodeArgs = (u32, Vec3, Vec3, UVec3, f32);

/// `per_node` rays at each node of `k`'s BVH, aimed through one of its children, a quarter of
/// them axis-parallel from that child's face plane (the slab test's rare "exit == 0" path),
/// some with a short `t_max`.
pub(crate) fn node_rays(k: &Scene, per_node: usize, seed: u64) -> Vec<NodeArgs> {
    let mut r = TestRng::new(seed);
    let nodes = k.nodes.len() as u32 / scene_data::NODE_TEXELS;
    let mut out = Vec::new();
    for node in 0..nodes {
        let used = (0..4).filter(|&c| node_child_box(k, node, c).0.x <= node_child_box(k, node, c).1.x).count();
        for _ in 0..per_node {
            let c = (r.next_u32() as usize) % used.max(1);
            let (lo, hi) = node_child_box(k, node, c);
            let target = lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
            let mut origin = target + r.unit_vector() * (hi - lo).length().max(1e-3) * 2.0;
            let mut dir = (target - origin).normalize_or(Vec3::X);
            if r.f32() < 0.25 {
                let axis = (r.next_u32() % 3) as usize;
                dir = Vec3::ZERO;
                dir[axis] = if r.f32() < 0.5 { 1.0 } else { -1.0 };
                let face = (r.next_u32() % 3) as usize;
                origin = target - dir * (hi - lo).length();
                if face != axis {
                    origin[face] = if r.f32() < 0.5 { lo[face] } else { hi[face] };
                }
            }
            let inv_dir = intersect::safe_inverse(dir);
            let t_max = if r.f32() < 0.2 { r.range(0.0, 2.0 * (target - origin).length()) } else { MISS };
            out.push((node, origin, inv_dir, traverse::near_planes(inv_dir), t_max));
        }
    }
    out
}

/// On DamagedHelmet (15,452 triangles, vendored in `tests/data/`): a real mesh of thin shells,
/// overlapping parts and long thin triangles, whose BVH is deep enough that the GPU kernels'
/// stack is specialised below 64. (This ran on LittlestTokyo, 141,802 triangles, until the test
/// scenes were vendored; that 13 MB scene stays with the benchmarks and
/// `examples/equivalence_report.rs`, which take it from `../shared`.)
#[test]
fn bvh_traversal_on_damaged_helmet() {
    let scene = tracer::scene::load(&test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb"))
        .expect("DamagedHelmet loads");
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    let mut eq = equivalence();
    eq.set_scene(&packed.scene).expect("scene uploads");
    // The GPU runtimes traverse with the stack sized to this scene (fewer than 64 entries), as
    // its kernel does;
    // the CPU keeps 64: a stack one entry short would drop subtrees and miss hits.
    assert!(packed.features.traversal_stack < traverse::STACK_SIZE as u32, "{:?}", packed.features);
    eq.set_specialization(packed.features.specialization());

    // Rays from around and inside the model towards points inside it.
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.1, b.max + b.diagonal() * 0.1);
    let mut r = TestRng::new(9);
    let point = |r: &mut TestRng, lo: Vec3, hi: Vec3| lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
    let rays: Vec<(Vec3, Vec3, f32)> = (0..100_000)
        .map(|_| {
            let o = point(&mut r, lo, hi);
            (o, (point(&mut r, b.min, b.max) - o).normalize(), MISS)
        })
        .collect();
    let closest =
        eq.run("trace_closest", &rays, |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),), TRIANGLE).expect("runs");
    report(&closest);
    let cpu = closest.output(Backend::Cpu).unwrap();
    let k = eq.scene().clone();
    // Any-hit: nothing before the closest hit, something just after it, and the same as the
    // closest-hit answer without a bound.
    let shadow: Vec<(Vec3, Vec3, f32)> = rays
        .iter()
        .zip(cpu)
        .flat_map(|(&(o, d, _), (h,))| {
            let t = if h.triangle == NONE { 1.0 } else { h.t };
            [(o, d, MISS), (o, d, t * 0.999), (o, d, t * 1.001)]
        })
        .collect();
    let any =
        eq.run("occluded", &shadow, |s, &(o, d, t)| (traverse::occluded(s, o, d, t),), Tolerance::EXACT).expect("runs");
    report(&any);
    for backend in Backend::GPU {
        let gl = closest.output(backend).unwrap();
        // The distance from ray i to triangle `tri`, on the CPU.
        let t_of = |i: usize, tri: u32| {
            let (o, d, _) = rays[i];
            let t = scene_data::fetch_triangle(&k, tri);
            intersect::intersect_triangle(o, d, t.v0, t.v1, t.v2).t
        };
        let mut different_triangle = Vec::new();
        let (mut same_triangle_beyond, mut same_triangle_worst) = (0, 0.0f64);
        for &i in &closest.comparison(backend).unwrap().mismatched {
            let ((want,), (got,)): ((Hit,), (Hit,)) = (cpu[i], gl[i]);
            if want.triangle == got.triangle {
                let (o, d, _) = rays[i];
                let t = scene_data::fetch_triangle(&k, want.triangle);
                let as_hit = |h: &Hit| TriangleHit { t: h.t, u: h.u, v: h.v };
                let scales = hit_difference((o, d, t.v0, t.v1, t.v2), &as_hit(&want), &as_hit(&got));
                assert!(
                    scales <= CONDITIONED,
                    "ray {i}: same triangle, CPU {want:?} vs {backend} {got:?}: {scales:.1} error scales"
                );
                same_triangle_worst = same_triangle_worst.max(scales);
                same_triangle_beyond += 1;
                continue;
            }
            // A different triangle: both must be hits at (nearly) the same distance. The gap is
            // measured between the two backends' distances, and between the CPU's distances to
            // both triangles (MISS where the CPU misses the GPU's triangle, e.g. across a shared edge).
            assert!(
                want.triangle != NONE && got.triangle != NONE,
                "ray {i}: hit vs miss: CPU {want:?} vs {backend} {got:?}"
            );
            let gap = (got.t - want.t).abs() / want.t;
            let cpu_gap = (t_of(i, got.triangle) - want.t).abs() / want.t;
            different_triangle.push((i, gap, cpu_gap));
        }
        let hits = cpu.iter().filter(|(h,)| h.triangle != NONE).count();
        println!(
        "trace_closest on {backend}: {hits} of {} rays hit; {same_triangle_beyond} same-triangle hits beyond {TRIANGLE}, all within \
         {same_triangle_worst:.2} forward error scales; {} hit a different triangle, relative t-gaps \
         ({backend} vs CPU t; CPU t of both triangles): {:?}",
        rays.len(),
        different_triangle.len(),
        different_triangle.iter().map(|(i, g, c)| format!("ray {i}: {g:.2e}; {c:.2e}")).collect::<Vec<_>>()
    );
        assert!(hits > rays.len() / 2, "{hits} hits: the rays should mostly hit");
        for &(i, gap, _) in &different_triangle {
            assert!(
                gap <= 1e-5,
                "ray {i}: {backend}'s triangle is {gap:e} (relative) farther than the CPU's: not a near-tie"
            );
        }
        assert!(different_triangle.len() * 1000 <= rays.len(), "{backend}: {} near-ties", different_triangle.len());

        let (cpu_any, gl_any) = (any.output(Backend::Cpu).unwrap(), any.output(backend).unwrap());
        let near_tie = |ray: usize| different_triangle.iter().any(|&(i, _, _)| i == ray);
        let mut disagreements = 0;
        for (ray, hit) in cpu.iter().enumerate() {
            let hit = hit.0.triangle != NONE;
            let gl_hit = gl[ray].0.triangle != NONE;
            let [unbounded, before, after] = [0, 1, 2].map(|j| gl_any[ray * 3 + j].0);
            assert_eq!(unbounded, gl_hit, "ray {ray}: {backend}'s any-hit disagrees with its closest hit");
            assert_eq!(cpu_any[ray * 3].0, hit, "ray {ray}: CPU's any-hit disagrees with its closest hit");
            if hit && !(before == cpu_any[ray * 3 + 1].0 && after == cpu_any[ray * 3 + 2].0) {
                disagreements += 1;
                assert!(
                    near_tie(ray) || !before,
                    "ray {ray}: {backend} finds an occluder before the CPU's closest hit"
                );
            }
        }
        println!("occluded: {disagreements} rays where {backend} and CPU bounded any-hit answers differ");
        assert!(disagreements * 1000 <= rays.len(), "{backend}: {disagreements} bounded any-hit disagreements");
    }

    // Closest hits with every leaf intersected as soon as its node is visited (the path the
    // kernel takes beyond `leaf_stack_limit`, for trees too deep to push every leaf): the GPUs still
    // agrees with the CPU, and both with the hits above.
    assert_eq!(packed.scene.leaf_stack_limit, packed.features.traversal_stack, "Tokyo fits with every leaf pushed");
    let mut at_once = packed.scene.clone();
    at_once.leaf_stack_limit = 0;
    eq.set_scene(&at_once).expect("scene uploads");
    let some = &rays[..20_000];
    let closest_at_once =
        eq.run("trace_closest", some, |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),), TRIANGLE).expect("runs");
    report(&closest_at_once);
    let near = |a: &Hit, b: &Hit| {
        a.triangle == b.triangle || (a.triangle != NONE && b.triangle != NONE && (a.t - b.t).abs() <= 1e-5 * b.t)
    };
    for backend in Backend::GPU {
        let gpu_at_once = closest_at_once.output(backend).unwrap();
        let differ = (0..some.len()).filter(|&i| !near(&gpu_at_once[i].0, &cpu[i].0)).count();
        assert_eq!(
            differ, 0,
            "leaves intersected at once: {differ} {backend} hits are neither the same triangle nor a near-tie"
        );
    }
}

/// Two levels (`kernel::instances`) on every runtime: 100,000 rays through a generated field of
/// placements of one mesh (rotated, scaled non-uniformly, every third mirrored, over static
/// triangles) find on each GPU runtime the CPU's closest hit (the same triangle of the same
/// placement at the same distance, to rounding relative to the coordinates' size, or a
/// near-tie there), and the shadow test agrees.
#[test]
fn two_level_traversal_agrees() {
    let scene = tracer::scene::instanced_shapes(8);
    let packed = tracer::pack::build_and_pack(&scene, &RenderSettings::default()).expect("pack").1;
    assert!(packed.features.instances);
    let mut eq = equivalence();
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.1, b.max + b.diagonal() * 0.1);
    let mut r = TestRng::new(28);
    let point = |r: &mut TestRng, lo: Vec3, hi: Vec3| lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
    let rays: Vec<(Vec3, Vec3, f32)> = (0..100_000)
        .map(|_| {
            let o = point(&mut r, lo, hi);
            (o, (point(&mut r, b.min, b.max) - o).normalize(), MISS)
        })
        .collect();
    let closest =
        eq.run("trace_closest", &rays, |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),), TRIANGLE).expect("runs");
    report(&closest);
    let cpu = closest.output(Backend::Cpu).unwrap();
    let hits = cpu.iter().filter(|(h,)| h.triangle != NONE).count();
    let placed = cpu.iter().filter(|(h,)| h.triangle != NONE && h.instance != cpu[0].0.instance).count();
    assert!(hits > rays.len() / 3 && placed > rays.len() / 10, "{hits} hits, {placed} on other placements");
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
            // Rounding in the move to a placement's space (llvmpipe fuses multiply-adds there)
            // is relative to the coordinates' size, so is the error in t: the gap is measured
            // against the origin's distance from the world origin as well as t.
            let (o, _, _) = rays[i];
            let gap = (got.t - want.t).abs() / want.t.max(o.length()).max(1.0);
            if (want.triangle, want.instance) == (got.triangle, got.instance) {
                assert!(gap <= 1e-5, "ray {i}: same triangle, CPU {want:?} vs {backend} {got:?}");
            } else {
                assert!(gap <= 1e-5, "ray {i}: {backend}'s hit {got:?} is not a near-tie of the CPU's {want:?}");
                near_ties += 1;
            }
        }
        assert!(near_ties * 1000 <= rays.len(), "{backend}: {near_ties} near-ties");
        let (cpu_any, gpu_any) = (any.output(Backend::Cpu).unwrap(), any.output(backend).unwrap());
        let differ = (0..cpu_any.len()).filter(|&k| cpu_any[k].0 != gpu_any[k].0).count();
        println!("two levels on {backend}: {near_ties} near-ties, {differ} any-hit answers differ");
        assert!(differ * 1000 <= shadow.len(), "{backend}: {differ} any-hit disagreements");
        for (k, (hit,)) in cpu.iter().enumerate() {
            assert_eq!(gpu_any[2 * k].0, gpu[k].0.triangle != NONE, "ray {k}: {backend}'s any-hit vs its closest hit");
            assert_eq!(cpu_any[2 * k].0, hit.triangle != NONE, "ray {k}: CPU any-hit vs closest hit");
        }
    }
}
