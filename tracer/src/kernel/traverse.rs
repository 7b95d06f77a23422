#[kernel_dsl::kernel]
pub mod traverse {
    //! Traversal of the 4-wide BVH (`tracer::bvh::Bvh::widen`, packed by `tracer::pack`) with an
    //! ordered stack: a node's four boxes are tested at once (one `Vec4` lane per child: SSE on
    //! the CPU, vec4 in shaders), hit children are pushed farthest first so that the nearest is
    //! visited next, and subtrees entered beyond the closest hit so far are skipped.

    use glam::{UVec3, UVec4, Vec3, Vec4};

    use crate::kernel::alpha_mask::is_hole;
    use crate::kernel::instances::instance_ray;
    use crate::kernel::intersect::{intersect_triangle, safe_inverse, MISS};
    use crate::kernel::scene_data::{fetch_triangle, Scene, NODE_TEXELS, NONE};

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

    // Alpha masks (`Features::alpha_mask`, `alpha_mask::is_hole`). The hole test (a texture
    // lookup) is kept out of the traversal loops: SIMD drivers (llvmpipe, SwiftShader) run both
    // sides of a branch under a lane mask, so a test in a traversal loop costs every node or
    // triangle of every ray its texel fetches, masked or not (2.4x per sample on GL, issue 31).
    // A masked triangle that would be the closest hit (a shadow ray: any masked hit) ends the
    // traversal loop instead; the loop around it tests that one candidate, and traversal resumes
    // where it stopped, one traversal per ray, in one-level scenes (`closest_visible_one_level`,
    // `occluded_masked_one_level`) and two-level ones (`*_two_level` at the end of this module).
    // Specialisation removes all of it: scenes without masks get the code they had.

    /// Most holes one ray passes through: each costs a hole test (in `visible_hit` a traversal).
    /// The candidate after that many holes counts as a hit (a dense canopy seen edge-on darkens).
    pub const MAX_HOLES: u32 = 32;

    /// No candidate yet: the start of the (t, triangle) order (every hit has t > 0).
    pub fn before_any_hit() -> Hit {
        Hit { triangle: NONE, t: -1.0, u: 0.0, v: 0.0, instance: 0 }
    }

    /// Whether a hit on triangle `triangle` at `t` comes after `after` and before `best` in
    /// (t, triangle) order: a total order, so that searching behind a hole neither skips a
    /// triangle at the same distance nor finds the hole again. `best` is the closest so far
    /// (triangle NONE: none yet, its t the exclusive `t_max`). In two-level scenes, where one
    /// triangle is placed by several instances, the order is (t, instance, triangle).
    pub fn is_next_candidate(scene: &Scene, t: f32, triangle: u32, instance: u32, after: Hit, best: Hit) -> bool {
        let mut before_best_tie = triangle < best.triangle;
        let mut past_after_tie = triangle > after.triangle;
        if scene.has_instances != 0 {
            before_best_tie = instance < best.instance || (instance == best.instance && triangle < best.triangle);
            past_after_tie = instance > after.instance || (instance == after.instance && triangle > after.triangle);
        }
        let before_best = t < best.t || (t == best.t && before_best_tie && best.triangle != NONE);
        let past_after = t > after.t || (t == after.t && past_after_tie);
        before_best && past_after
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

    /// The closest hit for t in (0, t_max) outside the holes of alpha masks (of the masked
    /// triangles only, when `only_masked`): the closest candidate, tested; behind a hole, the
    /// next candidate, at most `MAX_HOLES` times. The hole test runs once per candidate, not
    /// once per triangle intersected.
    pub fn visible_hit(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32, only_masked: bool) -> Hit {
        let mut after = before_any_hit();
        let mut hit = after;
        let mut holes = 0u32;
        let mut searching = true;
        while searching {
            hit = closest_candidate(scene, origin, dir, t_max, after, only_masked);
            searching = false;
            if hit.triangle != NONE && holes < MAX_HOLES {
                let tri = fetch_triangle(scene, hit.triangle);
                if tri.masked && is_hole(scene, hit.triangle, tri.material, hit.u, hit.v) {
                    after = hit;
                    holes += 1;
                    searching = true;
                }
            }
        }
        hit
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

    /// `trace_closest` with alpha masks: one traversal that tests candidates as it finds them
    /// (`closest_visible_one_level`, in two-level scenes `closest_visible_two_level`); the same
    /// hit as searching again behind each hole (`visible_hit`, the reference).
    pub fn closest_visible(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
        if scene.has_instances != 0 {
            closest_visible_two_level(scene, origin, dir, t_max)
        } else {
            closest_visible_one_level(scene, origin, dir, t_max)
        }
    }

    /// No hit: the triangle NONE (a masked candidate not yet found).
    pub fn no_hit() -> Hit {
        Hit { triangle: NONE, t: 0.0, u: 0.0, v: 0.0, instance: 0 }
    }

    /// The leaf test of `closest_visible_one_level`: the triangles of leaf `entry` of
    /// `instance`; an unmasked one closer than `hit` becomes `hit`, a masked one becomes
    /// `pending` when it is the next candidate after `after` before both (its hole test is the
    /// caller's, out of the traversal loop).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn intersect_leaf_masked(
        scene: &Scene,
        entry: u32,
        instance: u32,
        origin: Vec3,
        dir: Vec3,
        after: Hit,
        hit: &mut Hit,
        pending: &mut Hit,
    ) {
        let first = entry >> 8;
        for i in first..first + (entry & 255) {
            let tri = fetch_triangle(scene, i);
            let h = intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2);
            if tri.masked {
                let mut best = *hit;
                if pending.triangle != NONE {
                    best = *pending;
                }
                if is_next_candidate(scene, h.t, i, instance, after, best) {
                    *pending = Hit { triangle: i, t: h.t, u: h.u, v: h.v, instance };
                }
            } else if h.t < hit.t {
                *hit = Hit { triangle: i, t: h.t, u: h.u, v: h.v, instance };
            }
        }
    }

    /// `closest_candidate_one_level` for scenes with alpha masks: the closest hit outside the
    /// holes, in one traversal. A masked triangle that would become the closest hit is not
    /// taken at once: it ends the inner (traversal) loop as `pending`, the outer loop tests it
    /// for a hole, then traversal resumes where it stopped, with it as the closest hit, or,
    /// behind a hole, by intersecting the same leaves again for the next candidate after it.
    /// The traversal loop appears once and carries no hole test; the hole test runs once per
    /// masked candidate, at most `MAX_HOLES` times (then the candidate counts as a hit).
    // The DSL has no iterators: the leaves are visited by index.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn closest_visible_one_level(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
        let inv_dir = safe_inverse(dir);
        let near = near_planes(inv_dir);
        let mut hit = Hit { triangle: NONE, t: t_max, u: 0.0, v: 0.0, instance: 0 };
        let mut stack = [0u32; STACK_SIZE];
        let mut stack_t = [0.0f32; STACK_SIZE];
        let leaf_limit = scene.leaf_stack_limit as usize;
        let mut sp: usize = 0;
        let mut entry = stack_entry(0, 0);
        let mut visiting = true;
        let mut leaves = [0u32; 3];
        let mut leaf_count: usize = 0;
        let mut descend = false;
        // The masked candidate waiting for its hole test; behind a hole, the leaves of the
        // same iteration are intersected again (`rescan`) for candidates after it (`after`).
        let mut pending = no_hit();
        let mut after = before_any_hit();
        let mut rescan = false;
        let mut holes = 0u32;
        while visiting {
            while visiting && pending.triangle == NONE {
                if !rescan {
                    descend = false;
                    leaf_count = 0;
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
                }
                rescan = false;
                for k in 0..leaf_count {
                    intersect_leaf_masked(scene, leaves[k], 0, origin, dir, after, &mut hit, &mut pending);
                }
                after = before_any_hit();
                if pending.triangle != NONE
                    && !is_next_candidate(scene, pending.t, pending.triangle, 0, before_any_hit(), hit)
                {
                    // An unmasked triangle of the same leaves is closer.
                    pending = no_hit();
                }
                if pending.triangle == NONE && !descend {
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
            if pending.triangle != NONE {
                let tri = fetch_triangle(scene, pending.triangle);
                if holes < MAX_HOLES && is_hole(scene, pending.triangle, tri.material, pending.u, pending.v) {
                    holes += 1;
                    after = pending;
                    rescan = true;
                } else {
                    hit = pending;
                    if !descend {
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
                pending = no_hit();
            }
        }
        hit
    }

    /// `occluded` for one-level scenes with alpha masks, in one traversal: an unmasked triangle
    /// hit ends it; a masked one ends the inner (traversal) loop, the outer loop tests it for a
    /// hole, and behind a hole traversal resumes after it (the rest of its leaf, the node's
    /// other leaves, then the stack). The traversal loop appears once and carries no hole test.
    #[inline(always)]
    pub fn occluded_masked_one_level(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let inv_dir = safe_inverse(dir);
        let near = near_planes(inv_dir);
        let mut stack = [0u32; STACK_SIZE];
        stack[0] = stack_entry(0, 0);
        let mut sp: usize = 1;
        let mut blocked = false;
        let mut leaves = [0u32; 4];
        let mut leaf_count: usize = 0;
        let mut k: usize = 0;
        // The masked triangle hit, waiting for its hole test.
        let mut candidate = NONE;
        let mut hole_material = 0u32;
        let mut hole_u = 0.0f32;
        let mut hole_v = 0.0f32;
        let mut holes = 0u32;
        let mut searching = true;
        while searching {
            while (k < leaf_count || sp > 0) && !blocked && candidate == NONE {
                if k >= leaf_count {
                    sp -= 1;
                    let n = intersect_node(scene, stack[sp] >> 8, origin, inv_dir, near, t_max);
                    leaf_count = 0;
                    k = 0;
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
                }
                while k < leaf_count && !blocked && candidate == NONE {
                    let first = leaves[k] >> 8;
                    let end = first + (leaves[k] & 255);
                    let mut i = first;
                    while i < end && !blocked && candidate == NONE {
                        let tri = fetch_triangle(scene, i);
                        let h = intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2);
                        if h.t < t_max {
                            if tri.masked {
                                candidate = i;
                                hole_material = tri.material;
                                hole_u = h.u;
                                hole_v = h.v;
                            } else {
                                blocked = true;
                            }
                        }
                        i += 1;
                    }
                    if candidate != NONE && i < end {
                        // Resume after the candidate.
                        leaves[k] = stack_entry(i, end - i);
                    } else {
                        k += 1;
                    }
                }
            }
            searching = false;
            if candidate != NONE {
                if holes < MAX_HOLES && is_hole(scene, candidate, hole_material, hole_u, hole_v) {
                    holes += 1;
                    searching = true;
                } else {
                    blocked = true;
                }
                candidate = NONE;
            }
        }
        blocked
    }

    /// The leaf test of `closest_visible_two_level`: the triangles of leaf `entry` of
    /// `instance` (the ray in its space); an unmasked one before `hit` in (t, instance,
    /// triangle) order becomes `hit`, a masked one becomes `pending` when it is the next
    /// candidate after `after` before both (its hole test is the caller's, out of the loop).
    /// The order decides ties among unmasked triangles too, as in `visible_hit`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn intersect_leaf_visible(
        scene: &Scene,
        entry: u32,
        instance: u32,
        origin: Vec3,
        dir: Vec3,
        after: Hit,
        hit: &mut Hit,
        pending: &mut Hit,
    ) {
        let first = entry >> 8;
        for i in first..first + (entry & 255) {
            let tri = fetch_triangle(scene, i);
            let h = intersect_triangle(origin, dir, tri.v0, tri.v1, tri.v2);
            if tri.masked {
                let mut best = *hit;
                if pending.triangle != NONE {
                    best = *pending;
                }
                if is_next_candidate(scene, h.t, i, instance, after, best) {
                    *pending = Hit { triangle: i, t: h.t, u: h.u, v: h.v, instance };
                }
            } else if is_next_candidate(scene, h.t, i, instance, before_any_hit(), *hit) {
                *hit = Hit { triangle: i, t: h.t, u: h.u, v: h.v, instance };
            }
        }
    }

    /// `closest_visible_one_level` for two-level scenes: `closest_candidate_two_level`'s loop
    /// (one stack over both levels, the ray moved into an instance's space at a top-level leaf
    /// and back when the stack drops below it) with the pending candidate of the one-level
    /// loop. A masked triangle that would become the closest hit ends the inner (traversal)
    /// loop as `pending`, with the instance's ray, stack and leaves kept; the outer loop tests
    /// it for a hole, then traversal resumes: with it as the closest hit, or, behind a hole, by
    /// intersecting the same leaves again (same instance) for the next candidate after it. The
    /// traversal loop appears once and carries no hole test. The hit is `visible_hit`'s (the
    /// first candidate in (t, instance, triangle) order outside a hole) for every ray that
    /// meets fewer than `MAX_HOLES` masked triangles: this loop may test a masked triangle
    /// behind the final hit before finding it, so past that many the two may stop apart.
    // The DSL has no iterators: the leaves are visited by index.
    #[allow(clippy::needless_range_loop)]
    // Out of line, as `closest_candidate_two_level`.
    #[inline(never)]
    pub fn closest_visible_two_level(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Hit {
        let world_inv_dir = safe_inverse(dir);
        let world_near = near_planes(world_inv_dir);
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
        let mut entry = stack_entry(0, 0);
        let mut entry_t = 0.0f32;
        let mut visiting = true;
        let mut leaves = [0u32; 3];
        let mut leaf_count: usize = 0;
        let mut descend = false;
        // The masked candidate waiting for its hole test; `resume`: the next inner iteration
        // continues the one the candidate ended (behind a hole its leaves again, for candidates
        // after it: `after`; once it is the hit, none) instead of visiting a new entry.
        let mut pending = no_hit();
        let mut after = before_any_hit();
        let mut resume = false;
        let mut holes = 0u32;
        while visiting {
            while visiting && pending.triangle == NONE {
                if !resume {
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
                    let may_batch = in_instance;
                    descend = false;
                    leaf_count = 0;
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
                }
                resume = false;
                for k in 0..leaf_count {
                    intersect_leaf_visible(scene, leaves[k], instance, o, d, after, &mut hit, &mut pending);
                }
                after = before_any_hit();
                if pending.triangle != NONE
                    && !is_next_candidate(scene, pending.t, pending.triangle, pending.instance, before_any_hit(), hit)
                {
                    // An unmasked triangle of the same leaves comes first.
                    pending = no_hit();
                }
                if pending.triangle == NONE && !descend {
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
            if pending.triangle != NONE {
                let tri = fetch_triangle(scene, pending.triangle);
                if holes < MAX_HOLES && is_hole(scene, pending.triangle, tri.material, pending.u, pending.v) {
                    holes += 1;
                    after = pending;
                } else {
                    // The hit: nothing left in these leaves comes before it.
                    hit = pending;
                    leaf_count = 0;
                }
                resume = true;
                pending = no_hit();
            }
        }
        hit
    }

    /// `occluded` for two-level scenes with alpha masks, in one traversal: `any_hit_two_level`'s
    /// loop with `occluded_masked_one_level`'s candidate. An unmasked triangle hit ends it; a
    /// masked one ends the inner (traversal) loop with the instance's ray and stack kept, the
    /// outer loop tests it for a hole, and behind a hole traversal resumes after it. The same
    /// answer as any unmasked hit or a masked one outside its holes (`any_hit_two_level`, then
    /// `visible_hit` of the masked triangles: the design before) for every ray.
    // Out of line, as `any_hit_two_level`.
    #[inline(never)]
    pub fn occluded_masked_two_level(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
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
        let mut leaves = [0u32; 4];
        let mut leaf_count: usize = 0;
        let mut k: usize = 0;
        // The masked triangle hit, waiting for its hole test.
        let mut candidate = NONE;
        let mut hole_material = 0u32;
        let mut hole_u = 0.0f32;
        let mut hole_v = 0.0f32;
        let mut holes = 0u32;
        let mut searching = true;
        while searching {
            while (k < leaf_count || sp > 0) && !blocked && candidate == NONE {
                if k >= leaf_count {
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
                    leaf_count = 0;
                    k = 0;
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
                }
                while k < leaf_count && !blocked && candidate == NONE {
                    let first = leaves[k] >> 8;
                    let end = first + (leaves[k] & 255);
                    let mut i = first;
                    while i < end && !blocked && candidate == NONE {
                        let tri = fetch_triangle(scene, i);
                        let h = intersect_triangle(o, d, tri.v0, tri.v1, tri.v2);
                        if h.t < t_max {
                            if tri.masked {
                                candidate = i;
                                hole_material = tri.material;
                                hole_u = h.u;
                                hole_v = h.v;
                            } else {
                                blocked = true;
                            }
                        }
                        i += 1;
                    }
                    if candidate != NONE && i < end {
                        // Resume after the candidate.
                        leaves[k] = stack_entry(i, end - i);
                    } else {
                        k += 1;
                    }
                }
            }
            searching = false;
            if candidate != NONE {
                if holes < MAX_HOLES && is_hole(scene, candidate, hole_material, hole_u, hole_v) {
                    holes += 1;
                    searching = true;
                } else {
                    blocked = true;
                }
                candidate = NONE;
            }
        }
        blocked
    }
}
