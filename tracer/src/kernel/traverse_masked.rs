#[kernel_dsl::kernel]
pub mod traverse_masked {
    //! Traversal with alpha masks: the closest hit and the shadow-ray test outside the holes of
    //! masked triangles, over the BVH and loops of `kernel::traverse` (`trace_closest` and
    //! `occluded` call in here when the scene has masks).

    use glam::Vec3;

    use crate::kernel::alpha_mask::is_hole;
    use crate::kernel::instances::instance_ray;
    use crate::kernel::intersect::{intersect_triangle, safe_inverse, MISS};
    use crate::kernel::scene_data::{fetch_triangle, Scene, NONE};
    use crate::kernel::traverse::{
        closest_candidate, intersect_node, is_leaf, near_planes, sort_children, stack_entry, Hit, STACK_SIZE,
    };

    // Alpha masks (`Features::alpha_mask`, `alpha_mask::is_hole`). The hole test (a texture
    // lookup) is kept out of the traversal loops: SIMD drivers (llvmpipe, SwiftShader) run both
    // sides of a branch under a lane mask, so a test in a traversal loop costs every node or
    // triangle of every ray its texel fetches, masked or not (2.4x per sample on GL, issue 31).
    // A masked triangle that would be the closest hit (a shadow ray: any masked hit) ends the
    // traversal loop instead; the loop around it tests that one candidate, and traversal resumes
    // where it stopped, one traversal per ray, in one-level scenes (`closest_visible_one_level`,
    // `occluded_masked_one_level`) and two-level ones (`*_two_level`, below).
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
            if in_hole(scene, hit, holes) {
                after = hit;
                holes += 1;
                searching = true;
            }
        }
        hit
    }

    /// Whether the candidate `hit`, found behind `holes` holes, lies in a hole of a masked
    /// triangle: a ray passes through it and searches again behind it. Past `MAX_HOLES` holes a
    /// candidate counts as a hit.
    pub fn in_hole(scene: &Scene, hit: Hit, holes: u32) -> bool {
        let mut hole = false;
        if hit.triangle != NONE && holes < MAX_HOLES {
            let tri = fetch_triangle(scene, hit.triangle);
            hole = tri.masked && is_hole(scene, hit.triangle, tri.material, hit.u, hit.v);
        }
        hole
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

    /// The distance boxes are culled against while `t` is the closest hit: a little beyond
    /// it (1 + 2 * gamma(3), as `intersect_node` widens exits), so that a box whose entry
    /// rounds above a triangle at exactly `t` (a triangle in the plane of one of its faces) is
    /// still visited, and a tie with that triangle is broken by the (t, instance, triangle)
    /// order, as `visible_hit` breaks it, not by the order traversal met the two in.
    #[inline(always)]
    pub fn cull_distance(t: f32) -> f32 {
        let mut widened = t;
        if t < 1e30 {
            widened = t * 1.000_000_8;
        }
        widened
    }

    /// No hit: the triangle NONE (a masked candidate not yet found).
    pub fn no_hit() -> Hit {
        Hit { triangle: NONE, t: 0.0, u: 0.0, v: 0.0, instance: 0 }
    }

    /// The leaf test of `closest_visible_one_level` and `closest_visible_two_level`: the
    /// triangles of leaf `entry` of `instance` (the ray in its space; instance 0 in one-level
    /// scenes); an unmasked one before `hit` in (t, instance, triangle) order becomes `hit`, a
    /// masked one becomes `pending` when it is the next candidate after `after` before both
    /// (its hole test is the caller's, out of the loop). The order decides ties among unmasked
    /// triangles too, as in `visible_hit`: a first-found rule would keep whichever of two
    /// coincident triangles traversal met first, where `visible_hit` keeps the lower index.
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
                        let sorted = sort_children(intersect_node(
                            scene,
                            entry >> 8,
                            origin,
                            inv_dir,
                            near,
                            cull_distance(hit.t),
                        ));
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
                    intersect_leaf_visible(scene, leaves[k], 0, origin, dir, after, &mut hit, &mut pending);
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
                        if !(stack_t[sp] > cull_distance(hit.t)) {
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
                            if !(stack_t[sp] > cull_distance(hit.t)) {
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
                        let sorted =
                            sort_children(intersect_node(scene, entry >> 8, o, inv_dir, near, cull_distance(hit.t)));
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
                        if !(stack_t[sp] > cull_distance(hit.t)) {
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
