//! The kernel's BVH traversal (DSL code, run on the CPU over the packed arrays) finds the
//! same closest hits as brute force over the packed triangles.

use glam::Vec3;
use tracer::kernel::intersect::{intersect_triangle, MISS};
use tracer::kernel::scene_data::{fetch_triangle, NONE};
use tracer::kernel::traverse::{occluded, trace_closest};
use tracer::pack::{pack, RenderSettings};
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
    let n = packed.triangle_count as u32;
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.25, b.max + b.diagonal() * 0.25);
    let mut rng = XorShift(12345);
    let (mut hits, mut ties) = (0, 0);
    for _ in 0..rays {
        let origin = rng.in_box(lo, hi);
        let dir = (rng.in_box(b.min, b.max) - origin).normalize();
        let got = trace_closest(k, origin, dir, MISS);
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
        if got.triangle != best.0 {
            // Only a near-tie (two triangles at the same distance, e.g. a shared edge) may differ.
            assert!(
                got.triangle != NONE && (got.t - best.1).abs() <= 1e-5 * best.1.max(1.0),
                "ray {origin:?} {dir:?}: BVH {:?} vs brute force {best:?}",
                (got.triangle, got.t)
            );
            ties += 1;
        } else {
            assert_eq!(got.t, best.1);
        }
        // The shadow test agrees with the closest hit.
        assert_eq!(occluded(k, origin, dir, MISS), best.0 != NONE);
        if best.0 != NONE {
            assert!(!occluded(k, origin, dir, best.1 * 0.999));
        }
    }
    assert!(hits > rays / 10, "too few rays hit ({hits} of {rays}): the test would prove little");
    assert!(ties < rays / 100, "{ties} near-ties out of {rays}");
}

#[test]
fn cornell_box() {
    check(&scene::cornell_box(), 20_000);
}

#[test]
fn duck() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/scenes/khronos/Duck/glTF/Duck.gltf");
    check(&scene::load(std::path::Path::new(path)).expect("Duck loads"), 3_000);
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
