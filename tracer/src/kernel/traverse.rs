#[kernel_dsl::kernel]
pub mod traverse {
    //! Traversal of the 4-wide BVH (`tracer::bvh::Bvh::widen`, packed by `tracer::pack`) with an
    //! ordered stack: a node's four boxes are tested at once (one `Vec4` lane per child: SSE on
    //! the CPU, vec4 in shaders), hit children are pushed farthest first so that the nearest is
    //! visited next, and subtrees entered beyond the closest hit so far are skipped.

    use glam::{UVec3, UVec4, Vec3, Vec4};

    use crate::kernel::instances::instance_ray;
    use crate::kernel::intersect::{intersect_triangle, safe_inverse, MISS};
    use crate::kernel::scene_data::{fetch_triangle, Scene, NODE_TEXELS, NONE};
    use crate::kernel::traverse_masked::{
        before_any_hit, closest_visible, is_next_candidate, occluded_masked_one_level, occluded_masked_two_level,
    };

    /// Traversal stack depth: `tracer::pack` refuses a tree whose child nodes alone could need
    /// more (`tracer::bvh::WideBvh::stack_needed`) and limits the leaves pushed on top of them
    /// (`Scene::leaf_stack_limit`). A deeper stack would drop subtrees, never write out of
    /// bounds.
    pub const STACK_SIZE: usize = 64;

    /// The closest hit: triangle index (in BVH order) or NONE, distance and barycentrics, and
    /// the instance whose triangle it is (`kernel::instances`; 0 in scenes without instances).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Hit {
        pub triangle: u32,
        pub t: f32,
        pub u: f32,
        pub v: f32,
        pub instance: u32,
    }

    /// The slab tests of a node's four children: entry distance per child (`MISS` for a miss
    /// or an unused slot) and each child's stack entry.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct NodeHits {
        pub t: Vec4,
        pub entries: UVec4,
    }

    /// Largest leaf the stack encoding holds (`tracer::pack` refuses larger leaves).
    pub const MAX_LEAF_TRIANGLES: u32 = 255;

    /// A stack entry: a child's `first` and `count` in one word (`first < 2^24`, which packing
    /// guarantees, and `count <= MAX_LEAF_TRIANGLES`); count 0 is a node, `first` its index.
    /// Nodes store their children's entries, so a popped entry needs no other fetch.
    pub fn stack_entry(first: u32, count: u32) -> u32 {
        (first << 8) | count
    }

    /// Per axis, which of a node's two plane texels the ray enters through: the minimum planes
    /// (0) for a positive direction, the maximum planes (1) for a negative one. Choosing by
    /// the ray's sign once makes the per-node slab test free of min/max on the distances.
    pub fn near_planes(inv_dir: Vec3) -> UVec3 {
        UVec3::new(
            if inv_dir.x < 0.0 { 1 } else { 0 },
            if inv_dir.y < 0.0 { 1 } else { 0 },
            if inv_dir.z < 0.0 { 1 } else { 0 },
        )
    }

    /// `v` with zero lanes replaced by `MISS` (see `intersect_node`).
    pub fn zero_to_miss(v: Vec4) -> Vec4 {
        Vec4::new(
            if v.x == 0.0 { MISS } else { v.x },
            if v.y == 0.0 { MISS } else { v.y },
            if v.z == 0.0 { MISS } else { v.z },
            if v.w == 0.0 { MISS } else { v.w },
        )
    }

    /// Slab tests of the four children of `node` for t in [0, t_max], lane by lane the same
    /// arithmetic as `intersect::intersect_aabb` (the same result for every box, bit for bit):
    /// entry distance (0 when the origin is inside) or `MISS`. `inv_dir` comes from
    /// `safe_inverse`, `near` from `near_planes`. (`#[inline(always)]` only affects the CPU
    /// build: inlined into both traversals, the node test keeps the ray in registers.)
    #[inline(always)]
    pub fn intersect_node(scene: &Scene, node: u32, origin: Vec3, inv_dir: Vec3, near: UVec3, t_max: f32) -> NodeHits {
        let base = node * NODE_TEXELS;
        let ox = Vec4::splat(origin.x);
        let oy = Vec4::splat(origin.y);
        let oz = Vec4::splat(origin.z);
        let enter_x = (scene.nodes.fetch(base + near.x) - ox) * inv_dir.x;
        let exit_x = (scene.nodes.fetch(base + 1 - near.x) - ox) * inv_dir.x;
        let enter_y = (scene.nodes.fetch(base + 2 + near.y) - oy) * inv_dir.y;
        let exit_y = (scene.nodes.fetch(base + 3 - near.y) - oy) * inv_dir.y;
        let enter_z = (scene.nodes.fetch(base + 4 + near.z) - oz) * inv_dir.z;
        let exit_z = (scene.nodes.fetch(base + 5 - near.z) - oz) * inv_dir.z;
        let enter = enter_x.max(enter_y).max(enter_z).max(Vec4::ZERO);
        let mut exit = exit_x.min(exit_y).min(exit_z);
        if exit.x == 0.0 || exit.y == 0.0 || exit.z == 0.0 || exit.w == 0.0 {
            // An origin on a face plane with the ray parallel to that face (see
            // `intersect_aabb`): treat such axes as unbounded. Lanes whose exit is not 0 keep
            // it (a zero plane distance there is not the smallest), so all lanes may be redone.
            exit = zero_to_miss(exit_x).min(zero_to_miss(exit_y)).min(zero_to_miss(exit_z));
        }
        // Widened by 1 + 2 * gamma(3) as in `intersect_aabb`.
        let exit = (exit * 1.000_000_8).min(Vec4::splat(t_max));
        // An unused slot's entry is 0, the root, which is nobody's child: it is never followed,
        // whatever its box (a NaN ray can pass an empty box, a bundle can pair entry 0 with a
        // real box; following it restarted traversal at the root for ever: found by fuzzing).
        let e = scene.node_children.fetch(node);
        let t = Vec4::new(
            if enter.x <= exit.x && e.x != 0 { enter.x } else { MISS },
            if enter.y <= exit.y && e.y != 0 { enter.y } else { MISS },
            if enter.z <= exit.z && e.z != 0 { enter.z } else { MISS },
            if enter.w <= exit.w && e.w != 0 { enter.w } else { MISS },
        );
        NodeHits { t, entries: e }
    }

    /// Intersects the triangles of the leaf `entry` (a stack entry with count > 0) of
    /// `instance` (0 without instances; the ray in its space), keeping the closest hit in `hit`;
    /// with alpha masks, the closest candidate after `after` (of the masked triangles only,
    /// when `only_masked`), holes included.
    // Inlined into the traversal loops (the CPU build: with the instance argument LLVM stopped
    // inlining it, and the Cornell box lost 15 % per sample).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn intersect_leaf(
        scene: &Scene,
        entry: u32,
        instance: u32,
        origin: Vec3,
        dir: Vec3,
        after: Hit,
        only_masked: bool,
        hit: &mut Hit,
    ) {
        let first = entry >> 8;
        for i in first..first + (entry & 255) {
            let tri = fetch_triangle(scene, i);
            let h = intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2);
            if scene.has_alpha_mask != 0 {
                if (tri.masked || !only_masked) && is_next_candidate(scene, h.t, i, instance, after, *hit) {
                    *hit = Hit { triangle: i, t: h.t, u: h.u, v: h.v, instance };
                }
            } else if h.t < hit.t {
                *hit = Hit { triangle: i, t: h.t, u: h.u, v: h.v, instance };
            }
        }
    }
    /// Whether any triangle of the leaf `entry` is hit for t in (0, t_max); with alpha masks,
    /// any unmasked one (`occluded` tests the masked ones apart).
    pub fn leaf_occludes(scene: &Scene, entry: u32, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let first = entry >> 8;
        let mut blocked = false;
        for i in first..first + (entry & 255) {
            let tri = fetch_triangle(scene, i);
            if scene.has_alpha_mask != 0 && tri.masked {
            } else if intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2).t < t_max {
                blocked = true;
                break;
            }
        }
        blocked
    }

    /// Whether a stack entry is a leaf.
    pub fn is_leaf(entry: u32) -> bool {
        (entry & 255) > 0
    }

    /// Closest intersection along `origin + t * dir` for t in (0, t_max) (outside the holes of
    /// alpha masks).
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn trace_closest(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
        if scene.has_alpha_mask != 0 {
            closest_visible(scene, origin, dir, t_max)
        } else {
            closest_candidate(scene, origin, dir, t_max, before_any_hit(), false)
        }
    }

    /// A node's children sorted by entry distance: a five-exchange sorting network, misses (at
    /// `MISS`) last.
    // The DSL has no `std::mem::swap`: the network swaps through temporaries.
    #[allow(clippy::manual_swap)]
    #[inline(always)]
    pub fn sort_children(n: NodeHits) -> NodeHits {
        let mut t0 = n.t.x;
        let mut t1 = n.t.y;
        let mut t2 = n.t.z;
        let mut t3 = n.t.w;
        let mut e0 = n.entries.x;
        let mut e1 = n.entries.y;
        let mut e2 = n.entries.z;
        let mut e3 = n.entries.w;
        if t1 < t0 {
            let t = t0;
            t0 = t1;
            t1 = t;
            let e = e0;
            e0 = e1;
            e1 = e;
        }
        if t3 < t2 {
            let t = t2;
            t2 = t3;
            t3 = t;
            let e = e2;
            e2 = e3;
            e3 = e;
        }
        if t2 < t0 {
            let t = t0;
            t0 = t2;
            t2 = t;
            let e = e0;
            e0 = e2;
            e2 = e;
        }
        if t3 < t1 {
            let t = t1;
            t1 = t3;
            t3 = t;
            let e = e1;
            e1 = e3;
            e3 = e;
        }
        if t2 < t1 {
            let t = t1;
            t1 = t2;
            t2 = t;
            let e = e1;
            e1 = e2;
            e2 = e;
        }
        NodeHits { t: Vec4::new(t0, t1, t2, t3), entries: UVec4::new(e0, e1, e2, e3) }
    }

    /// Closest intersection along `origin + t * dir` for t in (0, t_max); with alpha masks, the
    /// closest candidate after `after` in (t, triangle) order, holes included (`intersect_leaf`):
    /// the one-level loop, or in two-level scenes the loop over both levels.
    // Two loops rather than one with the instance state in it: the CPU backend is not
    // specialised, and one loop cost the Cornell box 6 % per sample there against 2 % with two
    // (medians of 5 alternating renders; GL and wgpu, specialised, were unchanged either way).
    // Each GPU variant keeps only the loop its scene needs.
    #[inline(always)]
    pub fn closest_candidate(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32, after: Hit, only_masked: bool) -> Hit {
        if scene.has_instances != 0 {
            closest_candidate_two_level(scene, origin, dir, t_max, after, only_masked)
        } else {
            closest_candidate_one_level(scene, origin, dir, t_max, after, only_masked)
        }
    }

    /// Closest intersection along `origin + t * dir` for t in (0, t_max); with alpha masks, the
    /// closest candidate after `after` in (t, triangle) order, holes included (`intersect_leaf`).
    ///
    /// A node's nearest hit child is visited next; its other hit children are pushed, farthest
    /// first and leaves included, and popped (nearest first) when a leaf or a node without hit
    /// children ends the descent. A visited leaf is intersected. Pushing leaves keeps one leaf
    /// test in the loop (a compact loop, most of the time in registers), but chains of leaves,
    /// as degenerate geometry builds, would deepen the stack by up to three entries per level:
    /// leaves are pushed only below `scene.leaf_stack_limit` entries and intersected at once
    /// beyond it (see `tracer::pack`, which sets the limit so that the stack cannot overflow).
    /// Either way the leaves of an iteration are intersected at one place, after the node.
    // The DSL has no iterators: the leaves are visited by index.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn closest_candidate_one_level(
        scene: &Scene,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        after: Hit,
        only_masked: bool,
    ) -> Hit {
        let inv_dir = safe_inverse(dir);
        let near = near_planes(inv_dir);
        let mut hit = Hit { triangle: NONE, t: t_max, u: 0.0, v: 0.0, instance: 0 };
        let mut stack = [0u32; STACK_SIZE];
        let mut stack_t = [0.0f32; STACK_SIZE];
        let leaf_limit = scene.leaf_stack_limit as usize;
        let mut sp: usize = 0;
        // The entry being visited: the root (entered unconditionally: its children's boxes are
        // the first test), then the nearest hit child of each node, else the next one popped.
        let mut entry = stack_entry(0, 0);
        let mut visiting = true;
        // The leaves to intersect in this iteration: the one visited, or a node's hit leaves
        // that do not go on the stack (at most three: the nearest child is visited next).
        let mut leaves = [0u32; 3];
        while visiting {
            let mut descend = false;
            let mut leaf_count: usize = 0;
            if is_leaf(entry) {
                leaves[0] = entry;
                leaf_count = 1;
            } else {
                let sorted = sort_children(intersect_node(scene, entry >> 8, origin, inv_dir, near, hit.t));
                let t0 = sorted.t.x;
                let t1 = sorted.t.y;
                let t2 = sorted.t.z;
                let t3 = sorted.t.w;
                let e0 = sorted.entries.x;
                let e1 = sorted.entries.y;
                let e2 = sorted.entries.z;
                let e3 = sorted.entries.w;
                // Farthest first, the nearest visited next without a round trip through the
                // stack. (The box tests were clipped to the closest hit, so every hit child is
                // worth visiting; the pop test below catches hits found meanwhile.)
                if t3 < MISS {
                    if sp >= leaf_limit && is_leaf(e3) {
                        leaves[leaf_count] = e3;
                        leaf_count += 1;
                    } else if sp < STACK_SIZE {
                        stack[sp] = e3;
                        stack_t[sp] = t3;
                        sp += 1;
                    }
                }
                if t2 < MISS {
                    if sp >= leaf_limit && is_leaf(e2) {
                        leaves[leaf_count] = e2;
                        leaf_count += 1;
                    } else if sp < STACK_SIZE {
                        stack[sp] = e2;
                        stack_t[sp] = t2;
                        sp += 1;
                    }
                }
                if t1 < MISS {
                    if sp >= leaf_limit && is_leaf(e1) {
                        leaves[leaf_count] = e1;
                        leaf_count += 1;
                    } else if sp < STACK_SIZE {
                        stack[sp] = e1;
                        stack_t[sp] = t1;
                        sp += 1;
                    }
                }
                if t0 < MISS {
                    entry = e0;
                    descend = true;
                }
            }
            for k in 0..leaf_count {
                intersect_leaf(scene, leaves[k], 0, origin, dir, after, only_masked, &mut hit);
            }
            if !descend {
                // Pop the nearest pending entry that may still hold a closer hit.
                visiting = false;
                while sp > 0 && !visiting {
                    sp -= 1;
                    if !(stack_t[sp] > hit.t) {
                        entry = stack[sp];
                        visiting = true;
                    }
                }
            }
        }
        hit
    }

    /// Closest intersection along `origin + t * dir` for t in (0, t_max); with alpha masks, the
    /// closest candidate after `after` in (t, triangle) order, holes included (`intersect_leaf`).
    ///
    /// A node's nearest hit child is visited next; its other hit children are pushed, farthest
    /// first and leaves included, and popped (nearest first) when a leaf or a node without hit
    /// children ends the descent. A visited leaf is intersected. Pushing leaves keeps one leaf
    /// test in the loop (a compact loop, most of the time in registers), but chains of leaves,
    /// as degenerate geometry builds, would deepen the stack by up to three entries per level:
    /// leaves are pushed only below `scene.leaf_stack_limit` entries and intersected at once
    /// beyond it (see `tracer::pack`, which sets the limit so that the stack cannot overflow).
    /// Either way the leaves of an iteration are intersected at one place, after the node.
    ///
    /// Two-level scenes (`kernel::instances`) run the same loop: a top-level leaf (always
    /// pushed, never intersected at once) is entered by moving the ray into its instance's space
    /// and visiting the instance's root; the stack depth at that moment is kept, and popping
    /// back to it restores the world ray. A leaf of several instances enters the first and
    /// pushes the rest.
    // The DSL has no iterators: the leaves are visited by index.
    #[allow(clippy::needless_range_loop)]
    // Out of line: inlined into the CPU row loop beside the one-level loop, it slows that one.
    #[inline(never)]
    pub fn closest_candidate_two_level(
        scene: &Scene,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        after: Hit,
        only_masked: bool,
    ) -> Hit {
        let world_inv_dir = safe_inverse(dir);
        let world_near = near_planes(world_inv_dir);
        // The ray in the space being traversed: the world's, or an instance's.
        let mut o = origin;
        let mut d = dir;
        let mut inv_dir = world_inv_dir;
        let mut near = world_near;
        let mut instance = 0u32;
        let mut in_instance = false;
        let mut instance_sp: usize = 0;
        let mut hit = Hit { triangle: NONE, t: t_max, u: 0.0, v: 0.0, instance: 0 };
        let mut stack = [0u32; STACK_SIZE];
        let mut stack_t = [0.0f32; STACK_SIZE];
        let leaf_limit = scene.leaf_stack_limit as usize;
        let mut sp: usize = 0;
        // The entry being visited: the root (entered unconditionally: its children's boxes are
        // the first test), then the nearest hit child of each node, else the next one popped.
        let mut entry = stack_entry(0, 0);
        let mut entry_t = 0.0f32;
        let mut visiting = true;
        // The leaves to intersect in this iteration: the one visited, or a node's hit leaves
        // that do not go on the stack (at most three: the nearest child is visited next).
        let mut leaves = [0u32; 3];
        while visiting {
            if !in_instance && is_leaf(entry) {
                let first = entry >> 8;
                if (entry & 255) > 1 && sp < STACK_SIZE {
                    stack[sp] = stack_entry(first + 1, (entry & 255) - 1);
                    stack_t[sp] = entry_t;
                    sp += 1;
                }
                let r = instance_ray(scene, first, origin, dir);
                o = r.origin;
                d = r.dir;
                inv_dir = safe_inverse(d);
                near = near_planes(inv_dir);
                instance = first;
                in_instance = true;
                instance_sp = sp;
                entry = stack_entry(r.root, 0);
            }
            // Leaves are intersected at once only at the bottom level.
            let may_batch = in_instance;
            let mut descend = false;
            let mut leaf_count: usize = 0;
            if is_leaf(entry) {
                leaves[0] = entry;
                leaf_count = 1;
            } else {
                let sorted = sort_children(intersect_node(scene, entry >> 8, o, inv_dir, near, hit.t));
                let t0 = sorted.t.x;
                let t1 = sorted.t.y;
                let t2 = sorted.t.z;
                let t3 = sorted.t.w;
                let e0 = sorted.entries.x;
                let e1 = sorted.entries.y;
                let e2 = sorted.entries.z;
                let e3 = sorted.entries.w;
                // Farthest first, the nearest visited next without a round trip through the
                // stack. (The box tests were clipped to the closest hit, so every hit child is
                // worth visiting; the pop test below catches hits found meanwhile.)
                if t3 < MISS {
                    if sp >= leaf_limit && is_leaf(e3) && may_batch {
                        leaves[leaf_count] = e3;
                        leaf_count += 1;
                    } else if sp < STACK_SIZE {
                        stack[sp] = e3;
                        stack_t[sp] = t3;
                        sp += 1;
                    }
                }
                if t2 < MISS {
                    if sp >= leaf_limit && is_leaf(e2) && may_batch {
                        leaves[leaf_count] = e2;
                        leaf_count += 1;
                    } else if sp < STACK_SIZE {
                        stack[sp] = e2;
                        stack_t[sp] = t2;
                        sp += 1;
                    }
                }
                if t1 < MISS {
                    if sp >= leaf_limit && is_leaf(e1) && may_batch {
                        leaves[leaf_count] = e1;
                        leaf_count += 1;
                    } else if sp < STACK_SIZE {
                        stack[sp] = e1;
                        stack_t[sp] = t1;
                        sp += 1;
                    }
                }
                if t0 < MISS {
                    entry = e0;
                    entry_t = t0;
                    descend = true;
                }
            }
            for k in 0..leaf_count {
                intersect_leaf(scene, leaves[k], instance, o, d, after, only_masked, &mut hit);
            }
            if !descend {
                // Pop the nearest pending entry that may still hold a closer hit.
                visiting = false;
                while sp > 0 && !visiting {
                    if in_instance && sp == instance_sp {
                        // The instance's entries are done: back to the world ray.
                        o = origin;
                        d = dir;
                        inv_dir = world_inv_dir;
                        near = world_near;
                        in_instance = false;
                    }
                    sp -= 1;
                    if !(stack_t[sp] > hit.t) {
                        entry = stack[sp];
                        entry_t = stack_t[sp];
                        visiting = true;
                    }
                }
            }
        }
        hit
    }

    /// Whether anything blocks `origin + t * dir` for t in (0, t_max): the shadow-ray test. With
    /// alpha masks, an unmasked triangle or a masked one outside its holes, in one traversal.
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn occluded(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        if scene.has_alpha_mask == 0 || scene.has_instances == 0 {
            any_hit(scene, origin, dir, t_max)
        } else {
            occluded_masked_two_level(scene, origin, dir, t_max)
        }
    }

    /// Whether any triangle is hit for t in (0, t_max): one level (with alpha masks, outside the
    /// holes: `occluded_masked_one_level`) or two (with alpha masks, the unmasked ones only).
    #[inline(always)]
    pub fn any_hit(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        if scene.has_instances != 0 {
            any_hit_two_level(scene, origin, dir, t_max)
        } else if scene.has_alpha_mask != 0 {
            occluded_masked_one_level(scene, origin, dir, t_max)
        } else {
            any_hit_one_level(scene, origin, dir, t_max)
        }
    }
    /// Whether any triangle is hit for t in (0, t_max) (without alpha masks): children in slot
    /// order, leaves at once, a stack of child nodes only (`WideBvh::stack_needed` bounds it).
    #[inline(always)]
    pub fn any_hit_one_level(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let inv_dir = safe_inverse(dir);
        let near = near_planes(inv_dir);
        let mut stack = [0u32; STACK_SIZE];
        stack[0] = stack_entry(0, 0);
        let mut sp: usize = 1;
        let mut blocked = false;
        // A node's hit leaves, intersected after its hit nodes are pushed: one site (above).
        let mut leaves = [0u32; 4];
        while sp > 0 && !blocked {
            sp -= 1;
            let n = intersect_node(scene, stack[sp] >> 8, origin, inv_dir, near, t_max);
            let mut leaf_count: usize = 0;
            if n.t.x < MISS {
                if is_leaf(n.entries.x) {
                    leaves[leaf_count] = n.entries.x;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.x;
                    sp += 1;
                }
            }
            if n.t.y < MISS {
                if is_leaf(n.entries.y) {
                    leaves[leaf_count] = n.entries.y;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.y;
                    sp += 1;
                }
            }
            if n.t.z < MISS {
                if is_leaf(n.entries.z) {
                    leaves[leaf_count] = n.entries.z;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.z;
                    sp += 1;
                }
            }
            if n.t.w < MISS {
                if is_leaf(n.entries.w) {
                    leaves[leaf_count] = n.entries.w;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.w;
                    sp += 1;
                }
            }
            let mut k: usize = 0;
            while k < leaf_count && !blocked {
                blocked = leaf_occludes(scene, leaves[k], origin, dir, t_max);
                k += 1;
            }
        }
        blocked
    }

    /// Whether any triangle (with alpha masks, any unmasked one) is hit for t in (0, t_max).
    /// Any hit ends it, so children are visited in slot order, and leaves are intersected at
    /// once: the stack holds child nodes only (`tracer::bvh::WideBvh::stack_needed` bounds it).
    /// In two-level scenes, top-level leaves are pushed too and entered when popped, as in
    /// `closest_candidate`.
    // Out of line, as `closest_candidate_two_level`.
    #[inline(never)]
    pub fn any_hit_two_level(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let world_inv_dir = safe_inverse(dir);
        let world_near = near_planes(world_inv_dir);
        let mut o = origin;
        let mut d = dir;
        let mut inv_dir = world_inv_dir;
        let mut near = world_near;
        let mut in_instance = false;
        let mut instance_sp: usize = 0;
        let mut stack = [0u32; STACK_SIZE];
        stack[0] = stack_entry(0, 0);
        let mut sp: usize = 1;
        let mut blocked = false;
        // A node's hit leaves, intersected after its hit nodes are pushed: one site (above).
        let mut leaves = [0u32; 4];
        while sp > 0 && !blocked {
            if in_instance && sp == instance_sp {
                o = origin;
                d = dir;
                inv_dir = world_inv_dir;
                near = world_near;
                in_instance = false;
            }
            sp -= 1;
            let mut node = stack[sp];
            if is_leaf(node) {
                // A top-level leaf (only those are pushed): enter its first instance.
                let first = node >> 8;
                if (node & 255) > 1 && sp < STACK_SIZE {
                    stack[sp] = stack_entry(first + 1, (node & 255) - 1);
                    sp += 1;
                }
                let r = instance_ray(scene, first, origin, dir);
                o = r.origin;
                d = r.dir;
                inv_dir = safe_inverse(d);
                near = near_planes(inv_dir);
                in_instance = true;
                instance_sp = sp;
                node = stack_entry(r.root, 0);
            }
            let may_batch = in_instance;
            let n = intersect_node(scene, node >> 8, o, inv_dir, near, t_max);
            let mut leaf_count: usize = 0;
            if n.t.x < MISS {
                if is_leaf(n.entries.x) && may_batch {
                    leaves[leaf_count] = n.entries.x;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.x;
                    sp += 1;
                }
            }
            if n.t.y < MISS {
                if is_leaf(n.entries.y) && may_batch {
                    leaves[leaf_count] = n.entries.y;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.y;
                    sp += 1;
                }
            }
            if n.t.z < MISS {
                if is_leaf(n.entries.z) && may_batch {
                    leaves[leaf_count] = n.entries.z;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.z;
                    sp += 1;
                }
            }
            if n.t.w < MISS {
                if is_leaf(n.entries.w) && may_batch {
                    leaves[leaf_count] = n.entries.w;
                    leaf_count += 1;
                } else if sp < STACK_SIZE {
                    stack[sp] = n.entries.w;
                    sp += 1;
                }
            }
            let mut k: usize = 0;
            while k < leaf_count && !blocked {
                blocked = leaf_occludes(scene, leaves[k], o, d, t_max);
                k += 1;
            }
        }
        blocked
    }
}
