//! Ray / triangle and ray / box intersection on hand-checked and adversarial inputs.

use crate::common;

use common::TestRng;
use glam::Vec3;
use tracer::kernel::intersect::{intersect_aabb, intersect_triangle, safe_inverse, TriangleHit, MISS};

const V0: Vec3 = Vec3::new(0.0, 0.0, 0.0);
const V1: Vec3 = Vec3::new(1.0, 0.0, 0.0);
const V2: Vec3 = Vec3::new(0.0, 1.0, 0.0);

fn hit(t: f32, u: f32, v: f32) -> TriangleHit {
    TriangleHit { t, u, v }
}

fn assert_miss(h: TriangleHit, what: &str) {
    assert_eq!(h.t, MISS, "{what}: expected a miss, got {h:?}");
}

/// From above the unit right triangle in z = 0, straight down onto (x, y).
fn down_at(x: f32, y: f32) -> TriangleHit {
    intersect_triangle(Vec3::new(x, y, 1.0), Vec3::NEG_Z, V0, V1, V2)
}

#[test]
fn triangle_hand_checked_hits() {
    // e1 = X, e2 = Y, p = dir x e2 = X, det = 1, s = (0.25, 0.5, 1), u = s.p = 0.25,
    // q = s x e1 = (0, 1, -0.5), v = dir.q = 0.5, t = e2.q = 1.
    assert_eq!(down_at(0.25, 0.5), hit(1.0, 0.25, 0.5));
    // Two-sided: from below the same point.
    assert_eq!(intersect_triangle(Vec3::new(0.25, 0.5, -2.0), Vec3::Z, V0, V1, V2), hit(2.0, 0.25, 0.5));
    // A non-unit direction: t is in units of `dir`.
    let (a, b, c) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(4.0, 0.0, 1.0), Vec3::new(0.0, 4.0, 1.0));
    assert_eq!(intersect_triangle(Vec3::new(1.0, 1.0, 5.0), Vec3::new(0.0, 0.0, -2.0), a, b, c), hit(2.0, 0.25, 0.25));
    // Reversed winding swaps the barycentrics, not the hit.
    assert_eq!(intersect_triangle(Vec3::new(1.0, 2.0, 5.0), Vec3::new(0.0, 0.0, -2.0), a, c, b), hit(2.0, 0.5, 0.25));
    // An oblique ray from (2, 2, 2) with dir (-1, -1, -2) reaches (1, 1, 0) at t = 1
    // on the triangle (0,0,0), (4,0,0), (0,4,0): u = v = 1/4.
    let h = intersect_triangle(Vec3::splat(2.0), Vec3::new(-1.0, -1.0, -2.0), V0, V1 * 4.0, V2 * 4.0);
    assert!((h.t - 1.0).abs() < 1e-6 && (h.u - 0.25).abs() < 1e-6 && (h.v - 0.25).abs() < 1e-6, "{h:?}");
    // A triangle in x = 3, hit along +X.
    let h = intersect_triangle(
        Vec3::new(0.0, 0.5, 0.25),
        Vec3::X,
        Vec3::new(3.0, 0.0, 0.0),
        Vec3::new(3.0, 1.0, 0.0),
        Vec3::new(3.0, 0.0, 1.0),
    );
    assert_eq!(h, hit(3.0, 0.5, 0.25));
}

#[test]
fn triangle_edges_and_vertices_are_inside() {
    for (x, y, u, v) in [
        (0.0, 0.0, 0.0, 0.0), // v0
        (1.0, 0.0, 1.0, 0.0), // v1
        (0.0, 1.0, 0.0, 1.0), // v2
        (0.5, 0.0, 0.5, 0.0), // edge v0-v1
        (0.0, 0.5, 0.0, 0.5), // edge v0-v2
        (0.5, 0.5, 0.5, 0.5), // edge v1-v2 (u + v = 1)
        (0.25, 0.75, 0.25, 0.75),
        (0.75, 0.25, 0.75, 0.25),
    ] {
        assert_eq!(down_at(x, y), hit(1.0, u, v), "at ({x}, {y})");
    }
    // Just outside each edge.
    let eps = 1e-6;
    for (x, y) in [(0.5, -eps), (-eps, 0.5), (0.5 + eps, 0.5), (0.5, 0.5 + eps), (1.0 + eps, 0.0), (0.0, 1.0 + eps)] {
        assert_miss(down_at(x, y), &format!("({x}, {y})"));
    }
    // Shared edge of two triangles: a ray through it hits both (no crack).
    let v3 = Vec3::new(1.0, 1.0, 0.0);
    let o = Vec3::new(0.5, 0.5, 1.0);
    assert_ne!(intersect_triangle(o, Vec3::NEG_Z, V0, V1, V2).t, MISS);
    assert_ne!(intersect_triangle(o, Vec3::NEG_Z, V1, v3, V2).t, MISS);
}

#[test]
fn triangle_edge_on_and_parallel_rays_miss() {
    // In the triangle's plane, through its interior, along an edge, and towards a vertex.
    for (origin, dir) in [
        (Vec3::new(-1.0, 0.25, 0.0), Vec3::X),
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::X),
        (Vec3::new(0.25, -1.0, 0.0), Vec3::new(0.0, 2.0, 0.0)),
        (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)),
        (Vec3::new(0.1, 0.1, 0.0), Vec3::new(1.0, 3.0, 0.0)), // origin inside the triangle
    ] {
        assert_miss(intersect_triangle(origin, dir, V0, V1, V2), &format!("edge-on {origin} {dir}"));
    }
    // A tilted triangle in the plane x + y + z = 1 and rays in that plane (exact arithmetic).
    let (a, b, c) = (Vec3::X, Vec3::Y, Vec3::Z);
    for (origin, dir) in [
        (Vec3::new(1.0, 1.0, -1.0), Vec3::new(-1.0, -1.0, 2.0)),
        (Vec3::new(2.0, 0.0, -1.0), Vec3::new(-1.0, 0.0, 1.0)),
    ] {
        assert_miss(intersect_triangle(origin, dir, a, b, c), &format!("edge-on tilted {origin} {dir}"));
    }
    // Parallel to the plane, above it.
    for dir in [Vec3::X, Vec3::Y, Vec3::new(1.0, -1.0, 0.0)] {
        assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), dir, V0, V1, V2), &format!("parallel {dir}"));
    }
}

#[test]
fn triangle_degenerate_triangles_miss() {
    let o = Vec3::new(0.5, 0.0, 1.0);
    let cases = [
        ("all vertices equal", V1, V1, V1),
        ("two vertices equal", V0, V1, V1),
        ("v0 = v2", V0, V1, V0),
        ("collinear on x", V0, V1, Vec3::new(2.0, 0.0, 0.0)),
        ("collinear, middle vertex last", V0, Vec3::new(2.0, 0.0, 0.0), V1),
        ("collinear along (1, 2, 3)", V0, Vec3::new(1.0, 2.0, 3.0), Vec3::new(2.0, 4.0, 6.0)),
    ];
    for (what, a, b, c) in cases {
        // Rays aimed at a point of the degenerate triangle (the segment), from several sides.
        let target = (a + b + c) / 3.0;
        for origin in [o, Vec3::new(0.5, 1.0, 1.0), Vec3::new(-1.0, 3.0, 2.0), Vec3::new(3.0, -2.0, 0.5)] {
            let h = intersect_triangle(origin, target - origin, a, b, c);
            assert_miss(h, &format!("{what}, from {origin}"));
        }
    }
}

#[test]
fn triangle_behind_the_origin_misses() {
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), Vec3::Z, V0, V1, V2), "pointing away");
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, -1.0), Vec3::NEG_Z, V0, V1, V2), "pointing away, below");
    // Starting on the triangle (t = 0) is not a hit: t must be > 0.
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, V0, V1, V2), "t = 0");
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 0.0), Vec3::NEG_Z, V0, V1, V2), "t = 0, down");
    // Zero direction.
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), Vec3::ZERO, V0, V1, V2), "zero direction");
}

#[test]
fn triangle_nan_and_infinite_inputs_never_hit_with_nan() {
    let good = [Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, V0, V1, V2];
    assert_ne!(intersect_triangle(good[0], good[1], good[2], good[3], good[4]).t, MISS);
    let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX, f32::MIN_POSITIVE];
    for arg in 0..5 {
        for axis in 0..3 {
            for &value in &specials {
                let mut args = good;
                args[arg][axis] = value;
                let h = intersect_triangle(args[0], args[1], args[2], args[3], args[4]);
                let what = format!("argument {arg} axis {axis} = {value}: {h:?}");
                assert!(!h.t.is_nan() && !h.u.is_nan() && !h.v.is_nan(), "{what}");
                assert!(h.t == MISS || (h.t > 0.0 && h.t.is_finite()), "{what}");
                if value.is_nan() {
                    assert_eq!(h.t, MISS, "{what}");
                }
            }
        }
    }
    // Random combinations of special values anywhere.
    let mut rng = TestRng::new(40);
    for _ in 0..100_000 {
        let mut args = [rng.vec3(2.0), rng.vec3(1.0), rng.vec3(2.0), rng.vec3(2.0), rng.vec3(2.0)];
        for _ in 0..1 + rng.next_u32() % 3 {
            let (arg, axis) = ((rng.next_u32() % 5) as usize, (rng.next_u32() % 3) as usize);
            args[arg][axis] = specials[(rng.next_u32() % specials.len() as u32) as usize];
        }
        let h = intersect_triangle(args[0], args[1], args[2], args[3], args[4]);
        assert!(!h.t.is_nan() && !h.u.is_nan() && !h.v.is_nan(), "{args:?}: {h:?}");
        assert!(h.t == MISS || (h.t > 0.0 && h.t.is_finite()), "{args:?}: {h:?}");
        let has_nan = args.iter().any(|a| a.is_nan());
        assert!(!has_nan || h.t == MISS, "NaN input hit: {args:?}: {h:?}");
    }
}

#[test]
fn triangle_random_rays_agree_with_barycentrics() {
    // Aim at a known barycentric point of a random triangle: the hit must report it.
    let mut rng = TestRng::new(41);
    let mut checked = 0;
    for _ in 0..100_000 {
        let (a, b, c) = (rng.vec3(3.0), rng.vec3(3.0), rng.vec3(3.0));
        let normal = (b - a).cross(c - a);
        if normal.length() < 0.1 {
            continue; // thin triangles make the expected barycentrics ill-conditioned
        }
        let (mut u, mut v) = (rng.f32(), rng.f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let p = a * (1.0 - u - v) + b * u + c * v;
        let origin = rng.vec3(10.0);
        let dir = p - origin;
        let cos = dir.normalize().dot(normal.normalize()).abs();
        if cos < 0.05 || dir.length() < 0.1 {
            continue; // grazing: the point is ill-conditioned
        }
        let h = intersect_triangle(origin, dir, a, b, c);
        let inside_margin = u.min(v).min(1.0 - u - v);
        if inside_margin < 1e-3 {
            continue;
        }
        assert!((h.t - 1.0).abs() < 1e-3, "{origin} {dir} onto ({a}, {b}, {c}) at ({u}, {v}): {h:?}");
        assert!((h.u - u).abs() < 1e-3 && (h.v - v).abs() < 1e-3, "({u}, {v}) vs {h:?}");
        // The same ray reversed (from the far side of the origin) misses.
        assert_miss(intersect_triangle(origin, -dir, a, b, c), "reversed");
        // And a ray aimed outside (past an edge) misses.
        let outside = a * (1.0 + 0.2) + b * -0.1 + c * -0.1;
        assert_miss(intersect_triangle(origin, outside - origin, a, b, c), "outside");
        checked += 1;
    }
    assert!(checked > 50_000, "only {checked} rays checked");
}

// ---------------------------------------------------------------------------------------------
// Ray / box
// ---------------------------------------------------------------------------------------------

const BMIN: Vec3 = Vec3::new(0.0, 0.0, 0.0);
const BMAX: Vec3 = Vec3::new(1.0, 2.0, 3.0);

fn aabb(origin: Vec3, dir: Vec3, t_max: f32) -> f32 {
    let t = intersect_aabb(origin, safe_inverse(dir), BMIN, BMAX, t_max);
    assert!(!t.is_nan(), "{origin} {dir} {t_max}: NaN");
    t
}

#[test]
fn safe_inverse_values() {
    assert_eq!(safe_inverse(Vec3::new(2.0, -4.0, 0.5)), Vec3::new(0.5, -0.25, 2.0));
    let small = 2f32.powi(-64); // 5.4e-20: above the 1e-20 threshold, kept
    assert_eq!(safe_inverse(Vec3::new(small, -small, 1.0)), Vec3::new(2f32.powi(64), -(2f32.powi(64)), 1.0));
    let tiny_inverse = 1.0 / 1.0e-20f32;
    for (d, expected) in [
        (0.0, tiny_inverse),
        (1e-21, tiny_inverse),
        (-1e-21, -tiny_inverse),
        (f32::MIN_POSITIVE, tiny_inverse),
        (-f32::MIN_POSITIVE, -tiny_inverse),
        (1e-45, tiny_inverse), // subnormal
        (-1e-45, -tiny_inverse),
    ] {
        let inv = safe_inverse(Vec3::new(d, d, d));
        assert_eq!(inv, Vec3::splat(expected), "dir component {d:e}");
    }
    // -0.0 gives a finite inverse of either sign (never -inf).
    let inv = safe_inverse(Vec3::new(-0.0, 1.0, 1.0));
    assert!(inv.x.is_finite() && inv.x.abs() == tiny_inverse, "{inv}");
    // Never infinite or NaN for finite input.
    let mut rng = TestRng::new(50);
    for _ in 0..100_000 {
        let d = rng.vec3(1.0) * 10f32.powi((rng.next_u32() % 60) as i32 - 40);
        let inv = safe_inverse(d);
        assert!(inv.is_finite(), "{d} -> {inv}");
        for axis in 0..3 {
            // (-0.0 becomes +1e20: the sign of a zero does not matter to the slab test.)
            if d[axis] != 0.0 {
                assert_eq!(inv[axis].signum(), d[axis].signum(), "{d} -> {inv}: sign kept");
            }
        }
    }
}

#[test]
fn aabb_hits_from_outside() {
    // Along each axis, both directions: the entry distance.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::X, 100.0), 2.0);
    assert_eq!(aabb(Vec3::new(3.0, 1.0, 1.5), Vec3::NEG_X, 100.0), 2.0);
    assert_eq!(aabb(Vec3::new(0.5, -1.0, 1.5), Vec3::Y, 100.0), 1.0);
    assert_eq!(aabb(Vec3::new(0.5, 6.0, 1.5), Vec3::NEG_Y, 100.0), 4.0);
    assert_eq!(aabb(Vec3::new(0.5, 1.0, -0.5), Vec3::Z, 100.0), 0.5);
    assert_eq!(aabb(Vec3::new(0.5, 1.0, 4.0), Vec3::NEG_Z, 100.0), 1.0);
    // A non-unit direction: t in units of dir.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::new(4.0, 0.0, 0.0), 100.0), 0.5);
    // Diagonal: from (-1, -1, -1) along (1, 1, 1) the box is entered at t = 1 (x, y, z all 0).
    assert_eq!(aabb(Vec3::splat(-1.0), Vec3::ONE, 100.0), 1.0);
    // Entering through the corner (1, 2, 3) from beyond it.
    assert_eq!(aabb(Vec3::new(2.0, 3.0, 4.0), Vec3::NEG_ONE, 100.0), 1.0);
    // Entering exactly through a box edge (x = 0, y = 0 at z = 1).
    assert_eq!(aabb(Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 0.0), 100.0), 1.0);
}

#[test]
fn aabb_origin_inside_gives_zero() {
    for dir in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Z, Vec3::new(0.3, -0.2, 0.9), Vec3::ZERO] {
        assert_eq!(aabb(Vec3::new(0.5, 1.0, 1.5), dir, 100.0), 0.0, "dir {dir}");
    }
    // On the surface, pointing in or out: inside the closed box at t = 0.
    assert_eq!(aabb(Vec3::new(0.0, 1.0, 1.5), Vec3::X, 100.0), 0.0);
    assert_eq!(aabb(Vec3::new(1.0, 1.0, 1.5), Vec3::X, 100.0), 0.0);
}

#[test]
fn aabb_axis_parallel_rays() {
    // Zero components with the origin inside those slabs: hit; outside: miss.
    for zero in [0.0, -0.0] {
        let dir = Vec3::new(1.0, zero, zero);
        assert_eq!(aabb(Vec3::new(-1.0, 1.0, 1.5), dir, 100.0), 1.0, "inside y and z slabs, dir {dir}");
        assert_eq!(aabb(Vec3::new(-1.0, 2.5, 1.5), dir, 100.0), MISS, "above the y slab");
        assert_eq!(aabb(Vec3::new(-1.0, -0.5, 1.5), dir, 100.0), MISS, "below the y slab");
        assert_eq!(aabb(Vec3::new(-1.0, 1.0, 3.5), dir, 100.0), MISS, "beyond the z slab");
        let dir = Vec3::new(zero, zero, -1.0);
        assert_eq!(aabb(Vec3::new(0.5, 1.0, 5.0), dir, 100.0), 2.0);
        assert_eq!(aabb(Vec3::new(1.5, 1.0, 5.0), dir, 100.0), MISS);
        assert_eq!(aabb(Vec3::new(-0.5, 1.0, 5.0), dir, 100.0), MISS);
    }
    // Tiny (non-zero) components behave like zero.
    assert_eq!(aabb(Vec3::new(-1.0, 1.0, 1.5), Vec3::new(1.0, 1e-30, -1e-30), 100.0), 1.0);
    assert_eq!(aabb(Vec3::new(-1.0, 2.5, 1.5), Vec3::new(1.0, 1e-30, -1e-30), 100.0), MISS);
}

/// A ray that lies exactly in the plane of one of the box's faces, travelling parallel to it
/// and entering the face's extent at t = 1: it touches the closed box.
fn face_plane_rays() -> Vec<(&'static str, Vec3, Vec3)> {
    let mut rays = Vec::new();
    for zero in [0.0f32, -0.0] {
        rays.push(("x = min", Vec3::new(0.0, -1.0, 1.5), Vec3::new(zero, 1.0, zero)));
        rays.push(("x = max", Vec3::new(1.0, -1.0, 1.5), Vec3::new(zero, 1.0, zero)));
        rays.push(("y = min", Vec3::new(-1.0, 0.0, 1.5), Vec3::new(1.0, zero, zero)));
        rays.push(("y = max", Vec3::new(-1.0, 2.0, 1.5), Vec3::new(1.0, zero, zero)));
        rays.push(("z = min", Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, zero, zero)));
        rays.push(("z = max", Vec3::new(-1.0, 1.0, 3.0), Vec3::new(1.0, zero, zero)));
    }
    rays
}

#[test]
fn aabb_ray_in_a_face_plane_lower_faces() {
    for (what, origin, dir) in face_plane_rays().into_iter().filter(|(what, _, _)| what.ends_with("min")) {
        assert_eq!(aabb(origin, dir, 100.0), 1.0, "{what}: {origin} {dir}");
    }
}

#[test]
fn aabb_ray_in_a_face_plane_touches_the_closed_box() {
    // Edges and faces of triangles count as inside (see `triangle_edges_and_vertices_are_inside`),
    // so a box must not cull a ray that runs along its face: a triangle with an edge in that
    // face is hit by the triangle test.
    let mut failures = Vec::new();
    for (what, origin, dir) in face_plane_rays() {
        let t = aabb(origin, dir, 100.0);
        if t != 1.0 {
            failures.push(format!("{what}: origin {origin} dir {dir:?} -> {t}"));
        }
    }
    assert!(failures.is_empty(), "rays in a face plane missed the closed box:\n{}", failures.join("\n"));
}

#[test]
fn aabb_does_not_cull_a_triangle_hit_on_its_max_face() {
    // A triangle in x = 0.5 with its edge a-b in the plane z = 3, the top of its bounding box.
    let (a, b, c) = (Vec3::new(0.5, 0.0, 3.0), Vec3::new(0.5, 2.0, 3.0), Vec3::new(0.5, 1.0, 0.0));
    let (bmin, bmax) = (a.min(b).min(c), a.max(b).max(c));
    let (origin, dir) = (Vec3::new(-1.0, 1.0, 3.0), Vec3::X);
    // By hand: e1 = (0, 2, 0), e2 = (0, 1, -3), p = (0, 3, 1), det = 6, s = (-1.5, 1, 0),
    // u = 3/6, q = (0, 0, -3), v = 0 (on the edge a-b), t = 9/6.
    assert_eq!(intersect_triangle(origin, dir, a, b, c), TriangleHit { t: 1.5, u: 0.5, v: 0.0 });
    let t = intersect_aabb(origin, safe_inverse(dir), bmin, bmax, MISS);
    assert!(t <= 1.5, "the triangle's own box culls its hit: {t}");
}

#[test]
fn aabb_misses_and_t_max_clipping() {
    // Pointing away.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::NEG_X, 100.0), MISS);
    // Passing beside.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::new(1.0, 2.0, 0.0), 100.0), MISS);
    // Box behind the origin along the ray's line.
    assert_eq!(aabb(Vec3::new(5.0, 1.0, 1.5), Vec3::X, 100.0), MISS);
    // t_max clips: the box spans t in [2, 3] along this ray.
    let o = Vec3::new(-2.0, 1.0, 1.5);
    assert_eq!(aabb(o, Vec3::X, 1.999), MISS);
    assert_eq!(aabb(o, Vec3::X, 2.0), 2.0, "t_max at the entry: inclusive");
    assert_eq!(aabb(o, Vec3::X, 2.5), 2.0);
    assert_eq!(aabb(o, Vec3::X, MISS), 2.0);
    // Inside the box, t_max = 0 still reports 0.
    assert_eq!(aabb(Vec3::new(0.5, 1.0, 1.5), Vec3::X, 0.0), 0.0);
    // A negative t_max (no valid interval) misses.
    assert_eq!(aabb(Vec3::new(0.5, 1.0, 1.5), Vec3::X, -1.0), MISS);
}

/// An independent slab test in f64 with true infinities: (entry, exit) or `None`.
fn reference_slab(origin: Vec3, dir: Vec3, bmin: Vec3, bmax: Vec3, t_max: f64) -> Option<(f64, f64)> {
    let (mut enter, mut exit) = (0.0f64, t_max);
    for axis in 0..3 {
        let (o, d) = (origin[axis] as f64, dir[axis] as f64);
        let (lo, hi) = (bmin[axis] as f64, bmax[axis] as f64);
        if d == 0.0 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo - o) / d, (hi - o) / d);
        enter = enter.max(a.min(b));
        exit = exit.min(a.max(b));
    }
    (enter <= exit).then_some((enter, exit))
}

#[test]
fn aabb_random_rays_agree_with_a_reference() {
    let mut rng = TestRng::new(51);
    let (mut hits, mut misses) = (0, 0);
    for i in 0..200_000 {
        let c = rng.vec3(2.0);
        let half = Vec3::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0));
        let (bmin, bmax) = (c - half, c + half);
        let origin = rng.vec3(4.0);
        let mut dir = if i % 2 == 0 {
            // Towards a random point of the box (grown a little, so some rays pass beside it).
            let target = c + half * rng.vec3(1.2);
            (target - origin).normalize()
        } else {
            rng.unit_vector()
        };
        if i % 4 == 0 {
            dir[(rng.next_u32() % 3) as usize] = 0.0; // axis-parallel to one slab
        }
        let t_max = if i % 3 == 0 { rng.range(0.0, 6.0) } else { MISS };
        let t = intersect_aabb(origin, safe_inverse(dir), bmin, bmax, t_max);
        assert!(!t.is_nan());
        let reference = reference_slab(origin, dir, bmin, bmax, t_max as f64);
        match reference {
            // Skip rays within rounding of touching the box or of t_max.
            Some((enter, exit)) if exit - enter > 1e-4 => {
                assert!(
                    (t as f64 - enter).abs() <= 1e-4 * enter.max(1.0),
                    "{origin} {dir} {bmin} {bmax}: {t} vs {enter}"
                );
                hits += 1;
            }
            None => {
                let grown = reference_slab(origin, dir, bmin - 1e-4, bmax + 1e-4, t_max as f64 + 1e-4);
                if grown.is_none() {
                    assert_eq!(t, MISS, "{origin} {dir} {bmin} {bmax} {t_max}");
                    misses += 1;
                }
            }
            Some(_) => {}
        }
    }
    assert!(hits > 10_000 && misses > 10_000, "{hits} hits, {misses} misses checked");
}

#[test]
fn aabb_nan_inputs_never_give_nan() {
    // NaN or infinite inputs may give a (conservative) hit or a miss, but never a NaN
    // distance, nor one before the origin or past t_max.
    let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0];
    let mut rng = TestRng::new(52);
    for _ in 0..100_000 {
        let mut args = [rng.vec3(3.0), rng.unit_vector(), rng.vec3(1.0) - 1.0, rng.vec3(1.0) + 1.0];
        for _ in 0..1 + rng.next_u32() % 3 {
            let (arg, axis) = ((rng.next_u32() % 4) as usize, (rng.next_u32() % 3) as usize);
            args[arg][axis] = specials[(rng.next_u32() % specials.len() as u32) as usize];
        }
        let t_max = if rng.next_u32().is_multiple_of(5) { f32::NAN } else { 100.0 };
        let t = intersect_aabb(args[0], safe_inverse(args[1]), args[2], args[3], t_max);
        assert!(!t.is_nan(), "{args:?} t_max {t_max}: NaN");
        // A hit is at or after the origin and not beyond t_max (a NaN t_max clips nothing).
        assert!(t == MISS || (t >= 0.0 && (t_max.is_nan() || t <= t_max)), "{args:?} t_max {t_max}: {t}");
    }
}
