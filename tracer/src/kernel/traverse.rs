#[kernel_dsl::kernel]
pub mod traverse {
    //! BVH traversal with an ordered stack: the nearer child is visited first, and subtrees
    //! entered beyond the closest hit so far are skipped.

    use glam::{Vec3, Vec4Swizzles};

    use crate::kernel::intersect::{intersect_aabb, intersect_triangle, safe_inverse, MISS};
    use crate::kernel::scene_data::{fetch_triangle, index_of, Scene, NODE_TEXELS, NONE};

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
        Node { min: a.xyz(), max: b.xyz(), first: index_of(a.w), count: index_of(b.w) }
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
            stack[0] = 0;
            stack_t[0] = root_t;
            sp = 1;
        }
        while sp > 0 {
            sp -= 1;
            if stack_t[sp] > hit.t {
                continue;
            }
            let node = fetch_node(scene, stack[sp]);
            if node.count > 0 {
                for i in node.first..node.first + node.count {
                    let tri = fetch_triangle(scene, i);
                    let h = intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2);
                    if h.t < hit.t {
                        hit = Hit { triangle: i, t: h.t, u: h.u, v: h.v };
                    }
                }
            } else {
                let left = fetch_node(scene, node.first);
                let right = fetch_node(scene, node.first + 1);
                let t_left = intersect_aabb(origin, inv_dir, left.min, left.max, hit.t);
                let t_right = intersect_aabb(origin, inv_dir, right.min, right.max, hit.t);
                // Push the farther child first so that the nearer one is popped next.
                let left_first = t_left <= t_right;
                let near = if left_first { node.first } else { node.first + 1 };
                let far = if left_first { node.first + 1 } else { node.first };
                let t_near = t_left.min(t_right);
                let t_far = t_left.max(t_right);
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
            sp = 1;
        }
        while sp > 0 {
            sp -= 1;
            let node = fetch_node(scene, stack[sp]);
            if node.count > 0 {
                for i in node.first..node.first + node.count {
                    let tri = fetch_triangle(scene, i);
                    if intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2).t < t_max {
                        return true;
                    }
                }
            } else {
                for c in 0..2u32 {
                    let child = fetch_node(scene, node.first + c);
                    if intersect_aabb(origin, inv_dir, child.min, child.max, t_max) < MISS && sp < STACK_SIZE {
                        stack[sp] = node.first + c;
                        sp += 1;
                    }
                }
            }
        }
        false
    }
}
