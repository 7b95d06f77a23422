#[kernel_dsl::kernel]
pub mod intersect {
    //! Ray/triangle (Möller–Trumbore) and ray/box (slab) tests. Comparisons are written so
    //! that NaN (from degenerate or parallel cases) always means "miss" on every target.

    use glam::Vec3;

    /// The `t` of a miss. Finite, so that it compares and survives arithmetic on every target.
    pub const MISS: f32 = f32::MAX;

    /// A ray/triangle intersection: distance along the ray and barycentrics of v1 and v2.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct TriangleHit {
        pub t: f32,
        pub u: f32,
        pub v: f32,
    }

    /// Möller–Trumbore, two-sided. A hit needs 0 < t, u >= 0, v >= 0, u + v <= 1 (edges and
    /// vertices count as inside). Rays in the triangle's plane and zero-area triangles miss.
    // Inlined into the traversal loops on the CPU (as LLVM chose to before the two-level loop).
    #[inline(always)]
    pub fn intersect_triangle(origin: Vec3, dir: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> TriangleHit {
        let miss = TriangleHit { t: MISS, u: 0.0, v: 0.0 };
        let e1 = v1 - v0;
        let e2 = v2 - v0;
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            return miss;
        }
        let inv_det = 1.0 / det;
        let s = origin - v0;
        let u = s.dot(p) * inv_det;
        let q = s.cross(e1);
        let v = dir.dot(q) * inv_det;
        let t = e2.dot(q) * inv_det;
        // One test of all the conditions rather than a return after each: each would be a
        // branch that rays take or not almost at random.
        if u >= 0.0 && u <= 1.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < MISS {
            TriangleHit { t, u, v }
        } else {
            miss
        }
    }

    /// `1 / dir` with zero components replaced by a tiny value of the same sign (-0.0 counts as
    /// positive), so that
    /// slab tests never compute `0 * inf` (NaN, and GLSL's min/max are undefined on NaN).
    pub fn safe_inverse(dir: Vec3) -> Vec3 {
        let tiny = 1.0e-20;
        let x = if dir.x.abs() < tiny {
            if dir.x >= 0.0 {
                tiny
            } else {
                -tiny
            }
        } else {
            dir.x
        };
        let y = if dir.y.abs() < tiny {
            if dir.y >= 0.0 {
                tiny
            } else {
                -tiny
            }
        } else {
            dir.y
        };
        let z = if dir.z.abs() < tiny {
            if dir.z >= 0.0 {
                tiny
            } else {
                -tiny
            }
        } else {
            dir.z
        };
        Vec3::new(1.0 / x, 1.0 / y, 1.0 / z)
    }

    /// The smaller of `a` and `b` as a compare and select: one instruction on CPUs, where
    /// `f32::min` also has to order NaN. The slab test never produces NaN (see `safe_inverse`).
    pub fn min_no_nan(a: f32, b: f32) -> f32 {
        if a < b {
            a
        } else {
            b
        }
    }

    /// The larger of `a` and `b` as a compare and select (see `min_no_nan`).
    pub fn max_no_nan(a: f32, b: f32) -> f32 {
        if a > b {
            a
        } else {
            b
        }
    }

    /// Slab test against the closed box [bmin, bmax] for t in [0, t_max]: the entry distance
    /// (0 when the origin is inside), or `MISS`. `inv_dir` comes from `safe_inverse`.
    pub fn intersect_aabb(origin: Vec3, inv_dir: Vec3, bmin: Vec3, bmax: Vec3, t_max: f32) -> f32 {
        let t0 = (bmin - origin) * inv_dir;
        let t1 = (bmax - origin) * inv_dir;
        let far = Vec3::new(max_no_nan(t0.x, t1.x), max_no_nan(t0.y, t1.y), max_no_nan(t0.z, t1.z));
        let near = Vec3::new(min_no_nan(t0.x, t1.x), min_no_nan(t0.y, t1.y), min_no_nan(t0.z, t1.z));
        let enter = max_no_nan(max_no_nan(max_no_nan(near.x, near.y), near.z), 0.0);
        let mut exit = min_no_nan(min_no_nan(far.x, far.y), far.z);
        if exit == 0.0 {
            // An exit distance of exactly 0 comes from an origin on a face plane; for a ray
            // parallel to that face it would close the slab (0 * 1e20 = 0) although the ray runs
            // along the face. Treat such an axis as unbounded: at worst a box is entered
            // needlessly, never culled wrongly. (Rare: tested only when the exit is 0, which
            // gives the same result as testing every axis.)
            let far_x = if far.x == 0.0 { MISS } else { far.x };
            let far_y = if far.y == 0.0 { MISS } else { far.y };
            let far_z = if far.z == 0.0 { MISS } else { far.z };
            exit = min_no_nan(min_no_nan(far_x, far_y), far_z);
        }
        // Widen the exit by 1 + 2 * gamma(3) (Ize 2013) so rounding never culls a box that the
        // exact slab test would enter.
        let exit = min_no_nan(exit * 1.000_000_8, t_max);
        if enter <= exit {
            enter
        } else {
            MISS
        }
    }
}
