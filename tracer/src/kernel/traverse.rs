#[kernel_dsl::kernel]
pub mod traverse {
    //! BVH traversal with an ordered stack: the nearer child is visited first, and subtrees
    //! entered beyond the closest hit so far are skipped.

    use glam::Vec3;

    use crate::kernel::intersect::{intersect_aabb, intersect_triangle, safe_inverse, MISS};
    use crate::kernel::scene_data::{fetch_triangle, Scene, NODE_TEXELS, NONE};

    /// Traversal stack depth. A deeper tree would drop subtrees (never write out of bounds);
    /// `tracer::bvh` keeps trees well below it.
    pub const STACK_SIZE: usize = 64;

    /// The closest hit: triangle index (in BVH order) or NONE, distance and barycentrics.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Hit {
        pub triangle: u32,
        pub t: f32,
        pub u: f32,
        pub v: f32,
    }

    /// A node's box and payload.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Node {
        pub min: Vec3,
        pub max: Vec3,
        pub first: u32,
        pub count: u32,
    }

    pub fn fetch_node(scene: &Scene, index: u32) -> Node {
        let a = scene.nodes.fetch(index * NODE_TEXELS);
        let b = scene.nodes.fetch(index * NODE_TEXELS + 1);
        Node {
            min: Vec3::new(f32::from_bits(a.x), f32::from_bits(a.y), f32::from_bits(a.z)),
            max: Vec3::new(f32::from_bits(b.x), f32::from_bits(b.y), f32::from_bits(b.z)),
            first: a.w,
            count: b.w,
        }
    }

    /// Largest leaf the stack encoding holds (`tracer::pack` refuses larger leaves).
    pub const MAX_LEAF_TRIANGLES: u32 = 255;

    /// A stack entry for a node: its `first` and `count` in one word (`first < 2^24`, which
    /// packing guarantees, and `count <= MAX_LEAF_TRIANGLES`). Carrying them on the stack
    /// means a popped node is never fetched again: only its children are.
    pub fn stack_entry(first: u32, count: u32) -> u32 {
        (first << 8) | count
    }

    /// Closest intersection along `origin + t * dir` for t in (0, t_max).
    pub fn trace_closest(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
        let inv_dir = safe_inverse(dir);
        let mut hit = Hit { triangle: NONE, t: t_max, u: 0.0, v: 0.0 };
        let mut stack = [0u32; STACK_SIZE];
        let mut stack_t = [0.0f32; STACK_SIZE];
        let mut sp: usize = 0;
        let root = fetch_node(scene, 0);
        let root_t = intersect_aabb(origin, inv_dir, root.min, root.max, t_max);
        if root_t < MISS {
            stack[0] = stack_entry(root.first, root.count);
            stack_t[0] = root_t;
            sp = 1;
        }
        while sp > 0 {
            sp -= 1;
            if stack_t[sp] > hit.t {
                continue;
            }
            let first = stack[sp] >> 8;
            let count = stack[sp] & 255;
            if count > 0 {
                for i in first..first + count {
                    let tri = fetch_triangle(scene, i);
                    let h = intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2);
                    if h.t < hit.t {
                        hit = Hit { triangle: i, t: h.t, u: h.u, v: h.v };
                    }
                }
            } else {
                let left = fetch_node(scene, first);
                let right = fetch_node(scene, first + 1);
                let t_left = intersect_aabb(origin, inv_dir, left.min, left.max, hit.t);
                let t_right = intersect_aabb(origin, inv_dir, right.min, right.max, hit.t);
                // Push the farther child first so that the nearer one is popped next.
                let left_first = t_left <= t_right;
                let left_entry = stack_entry(left.first, left.count);
                let right_entry = stack_entry(right.first, right.count);
                let near = if left_first { left_entry } else { right_entry };
                let far = if left_first { right_entry } else { left_entry };
                let t_near = if left_first { t_left } else { t_right };
                let t_far = if left_first { t_right } else { t_left };
                if t_far < MISS && sp < STACK_SIZE {
                    stack[sp] = far;
                    stack_t[sp] = t_far;
                    sp += 1;
                }
                if t_near < MISS && sp < STACK_SIZE {
                    stack[sp] = near;
                    stack_t[sp] = t_near;
                    sp += 1;
                }
            }
        }
        hit
    }

    /// Whether anything blocks `origin + t * dir` for t in (0, t_max): the shadow-ray test.
    pub fn occluded(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let inv_dir = safe_inverse(dir);
        let mut stack = [0u32; STACK_SIZE];
        let mut sp: usize = 0;
        let root = fetch_node(scene, 0);
        if intersect_aabb(origin, inv_dir, root.min, root.max, t_max) < MISS {
            stack[0] = stack_entry(root.first, root.count);
            sp = 1;
        }
        while sp > 0 {
            sp -= 1;
            let first = stack[sp] >> 8;
            let count = stack[sp] & 255;
            if count > 0 {
                for i in first..first + count {
                    let tri = fetch_triangle(scene, i);
                    if intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2).t < t_max {
                        return true;
                    }
                }
            } else {
                for c in 0..2u32 {
                    let child = fetch_node(scene, first + c);
                    if intersect_aabb(origin, inv_dir, child.min, child.max, t_max) < MISS && sp < STACK_SIZE {
                        stack[sp] = stack_entry(child.first, child.count);
                        sp += 1;
                    }
                }
            }
        }
        false
    }
}
