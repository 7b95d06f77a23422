//! Bounding volume hierarchy over a scene's triangles: built binary ([`Bvh`], the layout
//! below, also the reference for tests), then widened to the 4-wide hierarchy the kernel
//! traverses ([`Bvh::widen`], [`WideBvh`]; packed by `tracer::pack`).
//!
//! # Layout
//! * `nodes[0]` is the root. A node with `count == 0` is interior: its children are
//!   `nodes[first]` and `nodes[first + 1]` (always a pair, always after their parent). A node
//!   with `count > 0` is a leaf holding triangles `first .. first + count` of the **reordered**
//!   triangle list, where reordered triangle `i` is original triangle `triangle_order[i]`.
//! * A one-triangle scene has a single leaf root. Building over zero triangles is an error
//!   ([`BvhError::Empty`]): scene loading refuses such scenes, so the kernel never has to handle
//!   an empty hierarchy.
//! * Nodes are stored depth-first (each pair of children is allocated when its parent is
//!   visited, left subtree first) and leaves' triangles in the same order, for locality.
//! * Boxes are tight bounds of their triangles, as f32. Traversal should visit the nearer child
//!   first (ordered stack) and make its slab test conservative (see
//!   [`Bvh::intersect_closest`]), since flat boxes around axis-aligned triangles are common.
//!
//! # Building
//! [`build`] uses obvhs' PLOC builder (parallel locally-ordered clustering over Morton-sorted
//! boxes) and its parallel reinsertion optimiser, then converts to this layout in one pass that
//! also collapses subtrees into leaves of at most [`BuildOptions::max_leaf_size`] triangles
//! wherever that lowers the SAH cost (the same criterion as obvhs' leaf collapser, applied to
//! whole subtrees, without its separate node rewrite). Triangles sharing one box with many
//! others (coincident geometry, on which PLOC is quadratic) are built over as one primitive
//! and split evenly afterwards (`coincident`).

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb as ObAabb;
use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::PlocBuilder;

use crate::scene::Triangle;

mod coincident;
mod convert;
use coincident::Coincident;
use convert::convert;

/// One BVH node (32 bytes): a box and either two children or a range of triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNode {
    /// Smallest corner of the box.
    pub min: Vec3,
    /// Largest corner of the box.
    pub max: Vec3,
    /// Interior: index of the first child (the second is `first + 1`). Leaf: index of the first
    /// triangle in the reordered triangle list.
    pub first: u32,
    /// 0 for interior nodes, else the number of triangles in the leaf.
    pub count: u32,
}

impl BvhNode {
    /// Whether this node is a leaf.
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    fn half_area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// A BVH: nodes plus the triangle order its leaves refer to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// The nodes; `nodes[0]` is the root.
    pub nodes: Vec<BvhNode>,
    /// Reordered index -> original triangle index: leaves' triangles, in leaf order.
    pub triangle_order: Vec<u32>,
}

/// Children per node of the hierarchy the kernel traverses ([`Bvh::widen`]).
pub const WIDE: usize = 4;

/// A node of the 4-wide hierarchy: up to [`WIDE`] children, each a box and either a wide node
/// (`count == 0`, `first` its index) or a leaf (triangles `first .. first + count` of the
/// reordered list). Slots from `children` on are unused: empty boxes (min `f32::MAX`, max
/// `-f32::MAX`) that every slab test misses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode {
    pub min: [Vec3; WIDE],
    pub max: [Vec3; WIDE],
    pub first: [u32; WIDE],
    pub count: [u32; WIDE],
    /// Number of used slots (1..=4; slots are filled from 0).
    pub children: u32,
}

impl WideNode {
    /// A node with no children.
    pub const EMPTY: WideNode = WideNode {
        min: [Vec3::splat(f32::MAX); WIDE],
        max: [Vec3::splat(-f32::MAX); WIDE],
        first: [0; WIDE],
        count: [0; WIDE],
        children: 0,
    };
}

/// The 4-wide hierarchy ([`Bvh::widen`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    /// Depth in wide levels (1 for a root whose children are all leaves).
    pub depth: u32,
    /// The most entries the kernel's traversal stack can hold at once for this tree, whatever
    /// the ray, when only child nodes are pushed (leaves intersected at once): visiting a node
    /// pushes its `k` child nodes and pops the nearest, so a node needs
    /// `max(k, k - 1 + the most any child node needs)`. Chains of leaves (degenerate geometry)
    /// do not deepen it.
    pub stack_needed: u32,
    /// The same bound when leaf children are pushed too (`k` counts every child): about three
    /// entries per level, so long chains can exceed the kernel's stack (see
    /// `tracer::pack`'s `leaf_stack_limit`).
    pub stack_needed_with_leaves: u32,
}

/// Why a BVH could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BvhError {
    /// There are no triangles.
    #[error("cannot build a BVH over zero triangles")]
    Empty,
    /// A vertex is NaN or infinite.
    #[error("triangle {0} has a non-finite vertex")]
    NonFinite(usize),
    /// More triangles than 32-bit node indices can address.
    #[error("{0} triangles exceed the BVH limit of {MAX_TRIANGLES}")]
    TooMany(usize),
    /// The builder produced a hierarchy that does not convert (a bug, reported instead of
    /// panicking).
    #[error("internal BVH error: {0}")]
    Internal(String),
    /// A refit was given another number of triangles than the hierarchy holds.
    #[error("refitting a BVH over {1} triangles to {0}")]
    Refit(usize, usize),
}

/// Most triangles a BVH may hold (node indices are u32 and there are up to 2n - 1 nodes).
pub const MAX_TRIANGLES: usize = (u32::MAX / 2) as usize;

/// Build quality presets (obvhs' presets, with the leaf size overridden).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildQuality {
    /// PLOC search radius 1, no reinsertion: the fastest build.
    Fastest,
    /// PLOC radius 6 (radius 1 for the first 2 passes), 2% reinsertion.
    Fast,
    /// PLOC radius 14 (radius 1 for the first 3 passes), 5% reinsertion before and 10%
    /// after leaf collapse.
    Medium,
    /// PLOC radius 24, 128-bit Morton codes, 20% + 40% reinsertion.
    Slow,
}

/// Options for [`build_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// Which obvhs preset to start from.
    pub quality: BuildQuality,
    /// Most triangles per leaf (1..=255). SAH collapse decides below this.
    pub max_leaf_size: u32,
    /// Cost of visiting a node relative to intersecting one triangle, for the SAH collapse: a
    /// higher value makes bigger leaves.
    pub traversal_cost: f32,
}

impl Default for BuildOptions {
    /// The settings [`build`] uses: [`BuildQuality::Fast`], leaves of at most 4 triangles,
    /// traversal cost 1.5 (see the benchmark in `examples/bench_build.rs`).
    fn default() -> Self {
        Self { quality: BuildQuality::Fast, max_leaf_size: 4, traversal_cost: 1.5 }
    }
}

/// A ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Original index of the triangle hit.
    pub triangle: u32,
    /// Distance along the ray, in units of the direction's length.
    pub t: f32,
    /// Barycentric weight of vertex 1.
    pub u: f32,
    /// Barycentric weight of vertex 2 (vertex 0 has `1 - u - v`).
    pub v: f32,
}

/// Builds a BVH with the default [`BuildOptions`].
pub fn build(triangles: &[Triangle]) -> Result<Bvh, BvhError> {
    build_with(triangles, &BuildOptions::default())
}

/// Builds a BVH over `triangles` with the given options.
pub fn build_with(triangles: &[Triangle], options: &BuildOptions) -> Result<Bvh, BvhError> {
    if triangles.is_empty() {
        return Err(BvhError::Empty);
    }
    if triangles.len() > MAX_TRIANGLES {
        return Err(BvhError::TooMany(triangles.len()));
    }
    let mut aabbs = Vec::with_capacity(triangles.len());
    for (i, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.positions;
        if !(a.is_finite() && b.is_finite() && c.is_finite()) {
            return Err(BvhError::NonFinite(i));
        }
        aabbs.push(triangle_aabb(t));
    }
    build_over(aabbs, options)
}

/// Builds a BVH over boxes (`(min, max)` each; the top level of a two-level scene, over its
/// instances' world bounds): leaves name boxes as they name triangles in [`build_with`].
pub fn build_over_boxes(boxes: &[(Vec3, Vec3)], options: &BuildOptions) -> Result<Bvh, BvhError> {
    if boxes.is_empty() {
        return Err(BvhError::Empty);
    }
    if boxes.len() > MAX_TRIANGLES {
        return Err(BvhError::TooMany(boxes.len()));
    }
    let mut aabbs = Vec::with_capacity(boxes.len());
    for (i, (min, max)) in boxes.iter().enumerate() {
        if !(min.is_finite() && max.is_finite()) {
            return Err(BvhError::NonFinite(i));
        }
        aabbs.push(ObAabb::new(Vec3A::from(*min), Vec3A::from(*max)));
    }
    build_over(aabbs, options)
}

fn build_over(aabbs: Vec<ObAabb>, options: &BuildOptions) -> Result<Bvh, BvhError> {
    let p = preset(options);
    let coincident = Coincident::find(&aabbs);
    let primitives = coincident.as_ref().map_or(&aabbs[..], |c| &c.boxes[..]);
    let indices: Vec<u32> = (0..primitives.len() as u32).collect();
    let mut bvh2 = PlocBuilder::with_capacity(primitives.len()).build(
        p.ploc_search_distance,
        primitives,
        indices,
        p.sort_precision,
        p.search_depth_threshold,
    );
    let max_leaf = options.max_leaf_size.clamp(1, 255);
    let traversal_cost = options.traversal_cost.max(0.0);
    let mut reinsertion = ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh2, p.reinsertion_batch_ratio, None);
    let post_collapse = p.reinsertion_batch_ratio * p.post_collapse_reinsertion_batch_ratio_multiplier;
    if post_collapse > 0.0 {
        // Presets that reinsert again after collapsing need obvhs' collapse first.
        collapse(&mut bvh2, max_leaf, traversal_cost);
        reinsertion.run(&mut bvh2, post_collapse, None);
    }
    let primitives = Primitives { coincident: coincident.as_ref(), aabbs: &aabbs };
    convert(&bvh2, &primitives, max_leaf, traversal_cost)
}

/// A triangle's bounding box, as the builder takes it.
fn triangle_aabb(t: &Triangle) -> ObAabb {
    let [a, b, c] = t.positions.map(Vec3A::from);
    ObAabb::new(a.min(b).min(c), a.max(b).max(c))
}

/// What the builder's primitives stand for: triangles, or groups of coincident triangles.
struct Primitives<'a> {
    coincident: Option<&'a Coincident>,
    /// Every triangle's box.
    aabbs: &'a [ObAabb],
}

impl Primitives<'_> {
    /// Appends primitive `p`'s triangles to `order`; returns how many.
    fn extend(&self, p: u32, order: &mut Vec<u32>) -> u32 {
        match self.coincident {
            Some(c) => {
                let members = c.members(p);
                order.extend_from_slice(members);
                members.len() as u32
            }
            None => {
                order.push(p);
                1
            }
        }
    }

    fn triangle_count(&self, p: u32) -> u32 {
        self.coincident.map_or(1, |c| c.members(p).len() as u32)
    }

    /// Tight bounds of the reordered triangles `order[range]`.
    fn bounds(&self, order: &[u32]) -> (Vec3, Vec3) {
        let mut b = ObAabb::empty();
        for &t in order {
            if let Some(a) = self.aabbs.get(t as usize) {
                b = b.union(a);
            }
        }
        (Vec3::from(b.min), Vec3::from(b.max))
    }
}

fn preset(options: &BuildOptions) -> obvhs::BvhBuildParams {
    let mut p = match options.quality {
        BuildQuality::Fastest => obvhs::BvhBuildParams::fastest_build(),
        BuildQuality::Fast => obvhs::BvhBuildParams::fast_build(),
        BuildQuality::Medium => obvhs::BvhBuildParams::medium_build(),
        BuildQuality::Slow => obvhs::BvhBuildParams::slow_build(),
    };
    // Spatial pre-splits would reference triangles from several leaves; keep one reference each.
    p.pre_split = false;
    p
}

/// 1 + 2·γ(3) (γ(n) = nε / (1 - nε)): scaling a slab test's exit distance by this makes it
/// conservative under f32 rounding (Ize, "Robust BVH Ray Traversal", JCGT 2013).
const ROBUST_SCALE: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

impl Bvh {
    /// Closest hit of the ray `origin + t·dir`, `0 < t < tmax`, with the original triangle list
    /// `triangles` (the one [`build`] was given). Ties in `t` go to the smaller triangle index.
    ///
    /// A plain-Rust reference traversal (ordered stack, nearer child first, Möller–Trumbore,
    /// no back-face culling), for tests; the kernel has its own in the DSL.
    pub fn intersect_closest(&self, triangles: &[Triangle], origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let inv = dir.recip();
        let mut best: Option<Hit> = None;
        let mut best_t = tmax;
        let root = self.nodes.first()?;
        let t_root = slab(root, origin, dir, inv, best_t)?;
        let mut stack: Vec<(u32, f32)> = Vec::with_capacity(64);
        stack.push((0, t_root));
        // In a tree every node is popped at most once; the bound only matters for corrupt input.
        let mut budget = self.nodes.len();
        while let Some((index, t_near)) = stack.pop() {
            if budget == 0 {
                break;
            }
            budget -= 1;
            if t_near > best_t {
                continue;
            }
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            if node.is_leaf() {
                let first = node.first as usize;
                let range = first..first + node.count as usize;
                for &tri in self.triangle_order.get(range).unwrap_or(&[]) {
                    let Some(t) = triangles.get(tri as usize) else {
                        continue;
                    };
                    if let Some((t, u, v)) = intersect_triangle(t, origin, dir) {
                        if closer(t, tri, best_t, best) {
                            best_t = t;
                            best = Some(Hit { triangle: tri, t, u, v });
                        }
                    }
                }
                continue;
            }
            let (a, b) = (node.first, node.first.saturating_add(1));
            let ta = self.nodes.get(a as usize).and_then(|n| slab(n, origin, dir, inv, best_t));
            let tb = self.nodes.get(b as usize).and_then(|n| slab(n, origin, dir, inv, best_t));
            match (ta, tb) {
                (Some(ta), Some(tb)) => {
                    // Push the far child first so the near one is popped next.
                    if ta <= tb {
                        stack.push((b, tb));
                        stack.push((a, ta));
                    } else {
                        stack.push((a, ta));
                        stack.push((b, tb));
                    }
                }
                (Some(ta), None) => stack.push((a, ta)),
                (None, Some(tb)) => stack.push((b, tb)),
                (None, None) => {}
            }
        }
        best
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().filter(|n| n.is_leaf()).count()
    }

    /// Longest root-to-leaf path in nodes (1 for a single leaf): the traversal stack needs at
    /// most `depth() - 1` entries.
    pub fn depth(&self) -> u32 {
        let mut max = 0;
        let mut stack = vec![(0usize, 1u32)];
        let mut steps = 0;
        while let Some((i, d)) = stack.pop() {
            steps += 1;
            if steps > self.nodes.len() {
                break; // not a tree; `validate` says why
            }
            let Some(n) = self.nodes.get(i) else { continue };
            max = max.max(d);
            if !n.is_leaf() {
                stack.push((n.first as usize, d + 1));
                stack.push((n.first as usize + 1, d + 1));
            }
        }
        max
    }

    /// The 4-wide hierarchy the kernel traverses (see [`WideBvh`]). Each wide node takes a
    /// binary node's children and repeatedly replaces the interior child with the largest
    /// surface area by its two children, until it has [`WIDE`] children or only leaves, so that
    /// one box test of four lanes replaces about two levels of the binary tree. Leaves and
    /// triangle order are kept, so `triangle_order` still applies. Wide nodes are stored depth
    /// first, root at 0.
    pub fn widen(&self) -> Result<WideBvh, BvhError> {
        let internal = |m: &str| BvhError::Internal(m.to_owned());
        let node = |i: usize| self.nodes.get(i).ok_or_else(|| internal("node index out of range"));
        node(0)?;
        let mut nodes = vec![WideNode::EMPTY];
        let mut depth = 1;
        // (binary node, wide node to fill, its level)
        let mut stack: Vec<(usize, usize, u32)> = vec![(0, 0, 1)];
        while let Some((b, w, level)) = stack.pop() {
            // Every wide node opens at least one distinct binary interior node (a tree has
            // fewer of those than nodes): more means the binary graph is not a tree.
            if nodes.len() > self.nodes.len() {
                return Err(internal("the node graph is not a tree"));
            }
            depth = depth.max(level);
            let n = node(b)?;
            let (mut children, mut len) =
                if n.is_leaf() { ([b, 0, 0, 0], 1) } else { ([n.first as usize, n.first as usize + 1, 0, 0], 2) };
            while len < WIDE {
                let mut widest: Option<(usize, f32)> = None;
                for (slot, &c) in children[..len].iter().enumerate() {
                    let n = node(c)?;
                    if !n.is_leaf() && widest.is_none_or(|(_, area)| n.half_area() > area) {
                        widest = Some((slot, n.half_area()));
                    }
                }
                let Some((slot, _)) = widest else { break };
                let first = node(children[slot])?.first as usize;
                children[slot] = first;
                children[len] = first + 1;
                len += 1;
            }
            let mut out = WideNode::EMPTY;
            let pending = stack.len();
            for (slot, &c) in children[..len].iter().enumerate() {
                let n = node(c)?;
                out.min[slot] = n.min;
                out.max[slot] = n.max;
                if n.is_leaf() {
                    out.first[slot] = n.first;
                    out.count[slot] = n.count;
                } else {
                    out.first[slot] = nodes.len() as u32;
                    stack.push((c, nodes.len(), level + 1));
                    nodes.push(WideNode::EMPTY);
                }
            }
            // Siblings are numbered in slot order; visit the first one's subtree first.
            stack[pending..].reverse();
            out.children = len as u32;
            nodes[w] = out;
        }
        // Children come after their parent: one reverse pass sees them first. Per node: the
        // stack needed pushing child nodes only, and pushing leaves too.
        let mut need = vec![(0u32, 0u32); nodes.len()];
        // `pushed` entries go on the stack and the nearest is popped at once.
        let bound = |pushed: u32, most_below: u32| if pushed == 0 { 0 } else { pushed.max(pushed - 1 + most_below) };
        for i in (0..nodes.len()).rev() {
            let n = &nodes[i];
            let (mut k, mut most, mut most_with_leaves) = (0u32, 0u32, 0u32);
            for c in 0..n.children as usize {
                if n.count[c] == 0 {
                    let (child, child_with_leaves) = need.get(n.first[c] as usize).copied().unwrap_or((0, 0));
                    k += 1;
                    most = most.max(child);
                    most_with_leaves = most_with_leaves.max(child_with_leaves);
                }
            }
            need[i] = (bound(k, most), bound(n.children, most_with_leaves));
        }
        Ok(WideBvh { nodes, depth, stack_needed: need[0].0, stack_needed_with_leaves: need[0].1 })
    }

    /// The same hierarchy over `triangles` moved (the triangles it was built over, each where
    /// a pose put it; the same count): every box made tight again, leaves from their
    /// triangles and interior nodes from their children (children follow their parent, so one
    /// pass from the back). The topology and the triangle order are kept, so its quality
    /// ([`sah_cost`](Self::sah_cost)) degrades as the triangles move apart from where they were
    /// built; a caller rebuilds past a bound (`pack::posing::REFIT_BOUND`).
    pub fn refit(&mut self, triangles: &[Triangle]) -> Result<(), BvhError> {
        if triangles.len() != self.triangle_order.len() {
            return Err(BvhError::Refit(triangles.len(), self.triangle_order.len()));
        }
        if let Some(i) = triangles.iter().position(|t| !t.positions.iter().all(|p| p.is_finite())) {
            return Err(BvhError::NonFinite(i));
        }
        let corrupt = |i: usize| BvhError::Internal(format!("refit: node {i} names what it cannot hold"));
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let (first, count) = (n.first as usize, n.count as usize);
            let (min, max) = if n.is_leaf() {
                let order = self.triangle_order.get(first..first + count).ok_or_else(|| corrupt(i))?;
                let mut b = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                for &t in order {
                    for p in triangles.get(t as usize).ok_or_else(|| corrupt(i))?.positions {
                        b = (b.0.min(p), b.1.max(p));
                    }
                }
                b
            } else {
                // Children follow their parent: refitted already, in one pass from the back.
                match (first > i, self.nodes.get(first), self.nodes.get(first + 1)) {
                    (true, Some(a), Some(b)) => (a.min.min(b.min), a.max.max(b.max)),
                    _ => return Err(corrupt(i)),
                }
            };
            (self.nodes[i].min, self.nodes[i].max) = (min, max);
        }
        Ok(())
    }

    /// Surface-area-heuristic cost with unit traversal and intersection costs:
    /// `(Σ interior area + Σ leaf area x triangle count) / root area`. Lower is better; for
    /// comparing builders on the same triangles.
    pub fn sah_cost(&self) -> f32 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let root_area = root.half_area();
        if root_area <= 0.0 {
            return 0.0;
        }
        let sum: f64 = self
            .nodes
            .iter()
            .map(|n| {
                let area = f64::from(n.half_area());
                if n.is_leaf() {
                    area * f64::from(n.count)
                } else {
                    area
                }
            })
            .sum();
        (sum / f64::from(root_area)) as f32
    }

    /// Checks every structural invariant against the triangles the BVH was built from: every
    /// node reachable exactly once from the root, children after their parent, child boxes
    /// inside their parent's, leaf boxes containing their triangles, every triangle referenced
    /// exactly once. Returns the first violation.
    pub fn validate(&self, triangles: &[Triangle]) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("no nodes".into());
        }
        if self.triangle_order.len() != triangles.len() {
            return Err(format!(
                "triangle_order has {} entries for {} triangles",
                self.triangle_order.len(),
                triangles.len()
            ));
        }
        let mut seen_tri = vec![false; triangles.len()];
        for &t in &self.triangle_order {
            let slot = seen_tri.get_mut(t as usize).ok_or(format!("triangle_order holds {t}, out of range"))?;
            if *slot {
                return Err(format!("triangle {t} is referenced twice"));
            }
            *slot = true;
        }
        let mut reached = vec![false; self.nodes.len()];
        let mut covered = vec![false; self.triangle_order.len()];
        reached[0] = true;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = self.nodes[i];
            if !(n.min.cmple(n.max).all()) {
                return Err(format!("node {i} has an inverted box"));
            }
            if n.is_leaf() {
                let (first, count) = (n.first as usize, n.count as usize);
                for k in first..first + count {
                    let c =
                        covered.get_mut(k).ok_or(format!("leaf {i} range {first}..{} out of bounds", first + count))?;
                    if *c {
                        return Err(format!("reordered triangle {k} is in two leaves"));
                    }
                    *c = true;
                    let tri = &triangles[self.triangle_order[k] as usize];
                    for p in tri.positions {
                        if !(n.min.cmple(p).all() && p.cmple(n.max).all()) {
                            return Err(format!("leaf {i} box does not contain its triangle {k}"));
                        }
                    }
                }
            } else {
                for c in [n.first as usize, n.first as usize + 1] {
                    if c <= i {
                        return Err(format!("node {i} has child {c} before it"));
                    }
                    let child = self.nodes.get(c).ok_or(format!("node {i} child {c} out of range"))?;
                    if reached[c] {
                        return Err(format!("node {c} is reached twice"));
                    }
                    reached[c] = true;
                    if !(n.min.cmple(child.min).all() && child.max.cmple(n.max).all()) {
                        return Err(format!("node {c} box is not inside its parent {i}"));
                    }
                    stack.push(c);
                }
            }
        }
        if let Some(i) = reached.iter().position(|r| !r) {
            return Err(format!("node {i} is unreachable"));
        }
        if let Some(k) = covered.iter().position(|c| !c) {
            return Err(format!("reordered triangle {k} is in no leaf"));
        }
        Ok(())
    }
}

/// Closest hit by testing every triangle (same intersection routine and tie rule as
/// [`Bvh::intersect_closest`]), for tests.
pub fn intersect_brute_force(triangles: &[Triangle], origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let mut best_t = tmax;
    for (i, tri) in triangles.iter().enumerate() {
        if let Some((t, u, v)) = intersect_triangle(tri, origin, dir) {
            if closer(t, i as u32, best_t, best) {
                best_t = t;
                best = Some(Hit { triangle: i as u32, t, u, v });
            }
        }
    }
    best
}

/// Whether a hit at `t` on triangle `tri` beats the current best (ties: smaller index).
fn closer(t: f32, tri: u32, best_t: f32, best: Option<Hit>) -> bool {
    t < best_t || (t == best_t && best.is_some_and(|b| tri < b.triangle))
}

/// Möller–Trumbore ray/triangle intersection, both faces: `(t, u, v)` for `t > 0`.
pub fn intersect_triangle(tri: &Triangle, origin: Vec3, dir: Vec3) -> Option<(f32, f32, f32)> {
    let [p0, p1, p2] = tri.positions;
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let pvec = dir.cross(e2);
    let det = e1.dot(pvec);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let tvec = origin - p0;
    let u = tvec.dot(pvec) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let v = dir.dot(qvec) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qvec) * inv_det;
    (t > 0.0 && t.is_finite()).then_some((t, u, v))
}

/// Conservative slab test: entry distance if the ray meets the (slightly padded) box before
/// `tmax`. Axes the ray is parallel to are handled explicitly (no 0·∞).
fn slab(n: &BvhNode, origin: Vec3, dir: Vec3, inv: Vec3, tmax: f32) -> Option<f32> {
    // Pad by a few ulps of the box's magnitude: Möller–Trumbore accepts hits a rounding error
    // outside a triangle, which can lie just outside its tight box.
    let pad = 4.0 * f32::EPSILON * n.min.abs().max(n.max.abs()).max_element();
    let (lo, hi) = (n.min - pad, n.max + pad);
    let mut t0 = 0.0f32;
    let mut t1 = tmax;
    for axis in 0..3 {
        let (o, d) = (origin[axis], dir[axis]);
        if d == 0.0 {
            if o < lo[axis] || o > hi[axis] {
                return None;
            }
            continue;
        }
        let (mut a, mut b) = ((lo[axis] - o) * inv[axis], (hi[axis] - o) * inv[axis]);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        t0 = t0.max(a);
        t1 = t1.min(b * ROBUST_SCALE);
    }
    (t0 <= t1).then_some(t0)
}
