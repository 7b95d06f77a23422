//! The kernel's BVH traversal (DSL code, run on the CPU over the packed arrays) finds the
//! same closest hits as brute force over the packed triangles.

use crate::common;

use common::node_child_box;
use glam::Vec3;
use tracer::kernel::intersect::{intersect_aabb, intersect_triangle, safe_inverse, MISS};
use tracer::kernel::scene_data::{fetch_triangle, NODE_TEXELS, NONE};
use tracer::kernel::traverse::{intersect_node, near_planes, occluded, trace_closest, STACK_SIZE};
use tracer::kernel::RenderSettings;
use tracer::pack::pack;
use tracer::scene::{self, Scene};

struct XorShift(u32);
impl XorShift {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        (self.0 >> 8) as f32 / 16_777_216.0
    }
    fn in_box(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(self.next(), self.next(), self.next())
    }
}

fn check(scene: &Scene, rays: usize) {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(scene, &bvh, &RenderSettings::default()).expect("pack");
    let k = &packed.scene;
    // The same traversal with every leaf intersected as soon as its node is visited (the path
    // taken beyond `leaf_stack_limit`) must meet the same standard.
    let mut leaves_at_once = k.clone();
    leaves_at_once.leaf_stack_limit = 0;
    let n = packed.triangle_count as u32;
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.25, b.max + b.diagonal() * 0.25);
    let mut rng = XorShift(12345);
    let (mut hits, mut ties) = (0, 0);
    for _ in 0..rays {
        let origin = rng.in_box(lo, hi);
        let dir = (rng.in_box(b.min, b.max) - origin).normalize();
        let mut best = (NONE, MISS);
        for i in 0..n {
            let t = fetch_triangle(k, i);
            let h = intersect_triangle(origin, dir, t.v0, t.v1, t.v2);
            if h.t < best.1 {
                best = (i, h.t);
            }
        }
        if best.0 != NONE {
            hits += 1;
        }
        for traversal in [k, &leaves_at_once] {
            let got = trace_closest(traversal, origin, dir, MISS);
            if got.triangle != best.0 {
                // Only a near-tie (two triangles at the same distance, e.g. a shared edge) may
                // differ.
                assert!(
                    got.triangle != NONE && (got.t - best.1).abs() <= 1e-5 * best.1.max(1.0),
                    "ray {origin:?} {dir:?} (leaf stack limit {}): BVH {:?} vs brute force {best:?}",
                    traversal.leaf_stack_limit,
                    (got.triangle, got.t)
                );
                // Exact ties (another triangle at the very same distance, as in a stack of
                // identical triangles) are not counted: only rounding near-misses are.
                if got.t != best.1 {
                    ties += 1;
                }
            } else {
                assert_eq!(got.t, best.1);
            }
        }
        // The shadow test agrees with the closest hit.
        assert_eq!(occluded(k, origin, dir, MISS), best.0 != NONE);
        if best.0 != NONE {
            assert!(!occluded(k, origin, dir, best.1 * 0.999));
        }
    }
    assert!(hits > rays / 10, "too few rays hit ({hits} of {rays}): the test would prove little");
    check_node_tests(k, &mut rng);
    assert!(ties < 2 * rays / 100, "{ties} near-ties out of {rays} rays, two traversals each");
}

/// The four-lane node test gives, lane by lane, exactly `intersect_aabb` on each child's box
/// (and a miss for unused slots), for rays through every node, axis-parallel ones from face
/// planes included.
fn check_node_tests(k: &tracer::kernel::scene_data::Scene, rng: &mut XorShift) {
    let nodes = k.nodes.as_slice();
    let mut rare = 0;
    for node in 0..(nodes.len() as u32 / NODE_TEXELS) {
        for ray in 0..24 {
            let c = ray % 4;
            let (lo, hi) = node_child_box(k, node, c);
            let used = lo.cmple(hi).all();
            let target = if used { rng.in_box(lo, hi) } else { Vec3::ZERO };
            let (origin, dir) = if ray % 3 == 0 {
                // Axis-parallel, starting on one of the child's face planes.
                let axis = (ray / 3) % 3;
                let mut dir = Vec3::ZERO;
                dir[axis] = if rng.next() < 0.5 { 1.0 } else { -1.0 };
                let mut origin = target - dir * 10.0;
                let face = (axis + 1) % 3;
                origin[face] = if rng.next() < 0.5 { lo[face] } else { hi[face] };
                rare += 1;
                (origin, dir)
            } else {
                let origin = target + (Vec3::new(rng.next(), rng.next(), rng.next()) - 0.5) * 20.0;
                (origin, (target - origin).normalize_or(Vec3::Y))
            };
            let t_max = if ray % 5 == 0 { 2.0 * rng.next() } else { MISS };
            let inv = safe_inverse(dir);
            let got = intersect_node(k, node, origin, inv, near_planes(inv), t_max).t.to_array();
            for (lane, got) in got.into_iter().enumerate() {
                let (lo, hi) = node_child_box(k, node, lane);
                let want = if lo.cmple(hi).all() { intersect_aabb(origin, inv, lo, hi, t_max) } else { MISS };
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "node {node} lane {lane}, ray {origin:?} {dir:?} t_max {t_max}"
                );
            }
        }
    }
    assert!(rare > 0);
}

#[test]
fn cornell_box() {
    check(&scene::cornell_box(), 20_000);
}

#[test]
fn duck() {
    let path = common::test_data("scenes/khronos/Duck/glTF/Duck.gltf");
    check(&scene::load(&path).expect("Duck loads"), 3_000);
}

#[test]
fn random_triangle_soup() {
    let mut rng = XorShift(777);
    let mut s = scene::cornell_box();
    s.triangles.clear();
    for _ in 0..2000 {
        let c = rng.in_box(Vec3::splat(-1.0), Vec3::splat(1.0));
        let mut t = scene::cornell_box().triangles[0];
        t.positions = [
            c,
            c + rng.in_box(Vec3::splat(-0.1), Vec3::splat(0.1)),
            c + rng.in_box(Vec3::splat(-0.1), Vec3::splat(0.1)),
        ];
        s.triangles.push(t);
    }
    check(&s, 5_000);
}

/// A chain of leaves (nested triangles, each a little larger than the last, build one;
/// identical ones did too before `tracer::bvh` split them evenly) is too deep to push every
/// leaf: packing lowers `leaf_stack_limit`, and traversal still finds every hit.
#[test]
fn chain_of_nested_triangles() {
    let mut s = scene::cornell_box();
    let template = s.triangles[0];
    let centre = Vec3::new(0.0, 0.7, 0.0);
    s.triangles.extend((0..1500).map(|i| {
        let r = 0.002 * 1.004f32.powi(i);
        let mut t = template;
        t.positions = [Vec3::new(-r, -r, -r), Vec3::new(r, -r, -r), Vec3::new(0.0, r, r)].map(|p| centre + p);
        t
    }));
    let bvh = tracer::bvh::build(&s.triangles).expect("BVH");
    let wide = bvh.widen().expect("wide BVH");
    let stack = STACK_SIZE as u32;
    assert!(wide.stack_needed_with_leaves > stack, "the chain should not fit with leaves pushed: {wide:?}");
    let packed = pack(&s, &bvh, &RenderSettings::default()).expect("pack");
    assert_eq!(packed.scene.leaf_stack_limit, stack - wide.stack_needed);
    assert_eq!(packed.features.traversal_stack, stack, "a tree this deep keeps the whole stack");
    check(&s, 2_000);
}

#[test]
fn trees_that_fit_push_every_leaf() {
    let s = scene::cornell_box();
    let bvh = tracer::bvh::build(&s.triangles).expect("BVH");
    let packed = pack(&s, &bvh, &RenderSettings::default()).expect("pack");
    // The GPU kernel's stack is sized to the tree, and the limit never stops a push.
    let need = bvh.widen().expect("wide BVH").stack_needed_with_leaves;
    assert!(need < STACK_SIZE as u32);
    assert_eq!((packed.features.traversal_stack, packed.scene.leaf_stack_limit), (need, need));
}

/// Two levels (`kernel::instances`): traversal of the top level and the placed meshes in one
/// loop finds, for every ray, the closest hit that brute force finds over the same scene
/// flattened (`Scene::bake_instances`), at the same distance; mirrored and non-uniformly
/// scaled placements included, with leaves pushed or intersected at once, and the shadow test
/// agrees.
fn check_two_level(scene: &Scene, rays: usize) {
    let packed = tracer::pack::build_and_pack(scene, &RenderSettings::default()).expect("pack").1;
    assert!(packed.features.instances, "{:?}", packed.features);
    let k = &packed.scene;
    let mut leaves_at_once = k.clone();
    leaves_at_once.leaf_stack_limit = 0;
    let mut flat = scene.clone();
    flat.bake_instances().expect("bakes");
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.25, b.max + b.diagonal() * 0.25);
    let mut rng = XorShift(4242);
    let (mut hits, mut ties) = (0, 0);
    for _ in 0..rays {
        let origin = rng.in_box(lo, hi);
        let dir = (rng.in_box(b.min, b.max) - origin).normalize();
        let best = tracer::bvh::intersect_brute_force(&flat.triangles, origin, dir, MISS);
        hits += best.is_some() as usize;
        for traversal in [k, &leaves_at_once] {
            let got = trace_closest(traversal, origin, dir, MISS);
            match best {
                None => assert_eq!(got.triangle, NONE, "ray {origin:?} {dir:?}: a hit where brute force finds none"),
                Some(want) => {
                    assert!(got.triangle != NONE, "ray {origin:?} {dir:?}: missed {want:?}");
                    let gap = (got.t - want.t).abs() / want.t.max(1.0);
                    // Hits in a placement's space are computed there: distances agree to rounding.
                    assert!(gap <= 1e-4, "ray {origin:?} {dir:?}: t {} vs brute force {}", got.t, want.t);
                    ties += (gap > 1e-6) as usize;
                }
            }
        }
        assert_eq!(occluded(k, origin, dir, MISS), best.is_some());
        if let Some(want) = best {
            assert!(!occluded(k, origin, dir, want.t * 0.999), "ray {origin:?} {dir:?}: occluded before {want:?}");
        }
    }
    assert!(hits > rays / 10, "too few rays hit ({hits} of {rays}): the test would prove little");
    assert!(ties < rays / 100, "{ties} hits whose distance differs beyond 1e-6");
}

#[test]
fn two_level_instanced_shapes() {
    check_two_level(&scene::instanced_shapes(6), 20_000);
}

/// A placement-only scene (no static triangles), several placements with the same bounds (a
/// top-level leaf of several is entered one placement after the other).
#[test]
fn two_level_coincident_placements_without_static_triangles() {
    let mut s = scene::instanced_shapes(3);
    s.triangles.retain(|t| t.material != 2);
    s.triangles.clear();
    let first = s.instances[0];
    s.instances.extend(std::iter::repeat_n(first, 40));
    check_two_level(&s, 5_000);
}

/// The (triangle, t, u, v, instance) of a hit, bit for bit.
fn hit_bits(h: &tracer::kernel::traverse::Hit) -> (u32, u32, u32, u32, u32) {
    (h.triangle, h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.instance)
}

/// Issue 31: two-level scenes with alpha masks find the closest visible hit and answer shadow
/// rays in one traversal (`closest_visible_two_level`, `occluded_masked_two_level`) where they
/// searched again from the root behind each hole (`visible_hit`, kept as the reference). On a
/// generated field of masked leaves (mirrored and non-uniformly scaled placements, coincident
/// masked quads, an opaque triangle coincident with a masked one, placements twice: holes and
/// ties at shared distances), 120,000 rays find bit for bit the hit the search again finds
/// (with leaves pushed and intersected at once), and the shadow test agrees with the unmasked
/// test then `visible_hit` of the masked triangles, before, at and beyond each hit.
///
/// One difference is allowed, and counted: the search again can lose a triangle at exactly the
/// distance of a candidate it found (a box whose entry rounds above that distance is culled
/// once that candidate is the closest; behind a hole, triangles before it in (t, instance,
/// triangle) order are excluded), so it may even see through the opaque twin of a hole. One
/// traversal culls against visible hits only, never against a hole, and may find that
/// triangle: a visible one at the distance of a hole passed or of the hit, before it in the
/// order. Rays that meet `MAX_HOLES` masked triangles or more are left out (past that many
/// the two may stop apart: `closest_visible_two_level`).
#[test]
fn two_level_alpha_masks_take_one_traversal_and_find_what_searching_again_finds() {
    check_one_masked_traversal(scene::instanced_masked_leaves(6), true);
}

/// The same field flattened into one level (`closest_visible_one_level`,
/// `occluded_masked_one_level`): the placements made twice are coincident unmasked triangles,
/// whose tie the one traversal must break as the search again does, by index (it kept the
/// first it met, and 1 % of these rays found the other twin).
#[test]
fn one_level_alpha_masks_take_one_traversal_and_find_what_searching_again_finds() {
    let mut scene = scene::instanced_masked_leaves(6);
    scene.bake_instances().expect("bake");
    check_one_masked_traversal(scene, false);
}

fn check_one_masked_traversal(scene: Scene, two_level: bool) {
    use tracer::kernel::alpha_mask::is_hole;
    use tracer::kernel::traverse::{any_hit_one_level, any_hit_two_level, closest_candidate, Hit};
    use tracer::kernel::traverse_masked::{before_any_hit, visible_hit, MAX_HOLES};
    let packed = tracer::pack::build_and_pack(&scene, &RenderSettings::default()).expect("pack").1;
    assert_eq!(packed.features.instances, two_level, "{:?}", packed.features);
    assert!(packed.features.alpha_mask, "{:?}", packed.features);
    let k = &packed.scene;
    let unmasked_hit = |o, d, t| {
        if two_level {
            any_hit_two_level(k, o, d, t)
        } else {
            any_hit_one_level(k, o, d, t)
        }
    };
    let mut leaves_at_once = k.clone();
    leaves_at_once.leaf_stack_limit = 0;
    let hole = |h: &Hit| {
        let tri = fetch_triangle(k, h.triangle);
        tri.masked && is_hole(k, h.triangle, tri.material, h.u, h.v)
    };
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.25, b.max + b.diagonal() * 0.25);
    let mut rng = XorShift(31);
    let rays = 120_000;
    let (mut compared, mut through_holes, mut ties, mut many_masked, mut lost_ties) = (0, 0, 0, 0, 0);
    for _ in 0..rays {
        let origin = rng.in_box(lo, hi);
        let dir = (rng.in_box(b.min, b.max) - origin).normalize();
        // The masked triangles along the ray, up to MAX_HOLES.
        let mut after = before_any_hit();
        let mut masked = 0;
        while masked < MAX_HOLES {
            let c = closest_candidate(k, origin, dir, MISS, after, true);
            if c.triangle == NONE {
                break;
            }
            masked += 1;
            after = c;
        }
        if masked >= MAX_HOLES {
            many_masked += 1;
            continue;
        }
        compared += 1;
        // The search again step by step: the holes it passes, then its hit.
        let mut passed = Vec::new();
        let mut want = closest_candidate(k, origin, dir, MISS, before_any_hit(), false);
        while want.triangle != NONE && hole(&want) {
            passed.push(want);
            want = closest_candidate(k, origin, dir, MISS, want, false);
        }
        assert_eq!(hit_bits(&want), hit_bits(&visible_hit(k, origin, dir, MISS, false)));
        through_holes += !passed.is_empty() as usize;
        let first = passed.first().copied().unwrap_or(want);
        if first.triangle != NONE {
            ties += (closest_candidate(k, origin, dir, MISS, first, false).t == first.t) as usize;
        }
        for traversal in [k, &leaves_at_once] {
            let got = trace_closest(traversal, origin, dir, MISS);
            if hit_bits(&got) == hit_bits(&want) {
                continue;
            }
            let lost = got.triangle != NONE
                && !hole(&got)
                && passed.iter().chain([&want]).any(|h| {
                    h.t == got.t && (got.instance, got.triangle) < (h.instance, h.triangle) && got.t <= want.t
                });
            assert!(lost, "ray {origin:?} {dir:?}: {got:?}, searching again {want:?} behind {passed:?}");
            lost_ties += 1;
        }
        let t = if want.triangle == NONE { 1.0 } else { want.t };
        for t_max in [MISS, t * 0.999, t, t * 1.001] {
            let searched =
                unmasked_hit(origin, dir, t_max) || visible_hit(k, origin, dir, t_max, true).triangle != NONE;
            for traversal in [k, &leaves_at_once] {
                assert_eq!(occluded(traversal, origin, dir, t_max), searched, "ray {origin:?} {dir:?} to {t_max}");
            }
        }
    }
    println!(
        "{compared} rays compared: {through_holes} through holes, {ties} first hits tied, {lost_ties} ties the \
         search again lost, {many_masked} rays left out"
    );
    assert!(compared >= 100_000, "{compared} rays compared");
    assert!(through_holes > compared / 20, "{through_holes} rays through holes");
    assert!(ties > compared / 100, "{ties} rays with a tie at the first hit");
    assert!(lost_ties * 200 < compared, "{lost_ties} lost ties");
}
