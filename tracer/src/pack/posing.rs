//! A pose step over packed arrays: a moving scene's pose is its first pose's packed arrays with
//! only what moves made again, so that a scene that arrives packed (a bundle, which carries no
//! [`Scene`] but its moving parts) poses exactly as a loaded one does.
//!
//! A two-level scene's packed layout (`docs/two-levels.md`) is
//! `nodes = [top level][level 0][level 1]...[placements]`, with level 0 the static triangles'
//! (when there are any) and then one level per placed mesh in mesh order, and
//! `triangles = [level 0's][level 1's]...`. A pose moves placements and makes deformed
//! (skinned, morphed) meshes again with the same number of triangles, so:
//!
//! - the triangles of every level keep their place; a deformed mesh's are written again in
//!   the order of its bottom level at this pose (its alpha-test flags follow its triangles);
//! - a level that never changes (the static one, a rigid or shared mesh's) keeps its nodes,
//!   moved as a block behind the rebuilt top level (its child entries shifted by the change in
//!   the top level's size); a deformed mesh's level is built again, or, from
//!   [`REFIT_MIN_TRIANGLES`] triangles, its first pose's level refitted (built again past
//!   [`REFIT_BOUND`]);
//! - the top level is built again over the placements' boxes (the static placement's box is
//!   read from the first pose's top level), and the placements' texels written in its order.
//!
//! What no pose changes is read from the first pose's arrays once ([`Posing::new`]): the level
//! boundaries (from the placements' roots), each kept level's stack need (as `Bvh::widen`
//! computes it, from its child entries), the static placement's box, the deformed meshes'
//! alpha-test flags. The light list stays the first pose's: lights are sampled from the static
//! triangles, and only the sky's share of the light samples (which depends on the scene's size)
//! could change, which changes no expected value. Every other array is what packing the posed
//! scene again gives, bit for bit (`tests/rendering/moving.rs`), except a refitted level's
//! nodes and triangle order: those render the same closest hits, but for exact ties in
//! distance (shared edges, coincident faces), which the kernel settles by the order it meets
//! or packs triangles in; and they depend on the first pose (a bundle exported at another time
//! refits from that time's level).

use std::ops::Range;

use glam::{Mat4, UVec4, Vec3, Vec4};
use kernel_dsl::Texels;
use rayon::prelude::*;

use super::geometry::{check_stack, pack_nodes, shading_texels, triangle_texels, MAX_EXACT};
use super::instances::{check_leaves, instance_texels, rebase, top_level};
use super::{PackError, Packed};
use crate::kernel::instances::INSTANCE_TEXELS;
use crate::kernel::normal_map::TANGENT_TEXELS;
use crate::kernel::scene_data::{NODE_TEXELS, SHADING_TEXELS, TRIANGLE_TEXELS};
use crate::kernel::texture_ref::TEXCOORD1_TEXELS;
use crate::scene::{Aabb, Scene};

/// What posing a moving scene reuses: its first pose, packed, and what was read from it.
#[derive(Clone, Debug)]
pub struct Posing {
    first: Packed,
    /// Empty for a scene with one level (nothing can move: every pose is the first).
    levels: Vec<Level>,
    /// The static placement's world box, when the scene has static triangles.
    static_box: Option<Aabb>,
    /// Per mesh, its level (`None`: placed nowhere).
    level_of_mesh: Vec<Option<usize>>,
    instances: usize,
}

#[derive(Clone, Debug)]
struct Level {
    /// The mesh it stores (`None`: the static triangles).
    mesh: Option<usize>,
    triangles: Range<usize>,
    kind: LevelKind,
}

#[derive(Clone, Debug)]
enum LevelKind {
    /// Never changes: its nodes in the first pose, and its stack need (child nodes pushed,
    /// leaves too).
    Kept { nodes: Range<usize>, need: (u32, u32) },
    /// Made again at each pose: per triangle of the mesh (in mesh order), whether the kernel
    /// alpha-tests it; for a mesh of [`REFIT_MIN_TRIANGLES`] or more, its bottom level at the
    /// first pose and that level's SAH cost, which each pose refits.
    Deformed { alpha_tested: Vec<bool>, refit: Option<(crate::bvh::Bvh, f32)> },
}

/// A deformed mesh of at least this many triangles has its first pose's bottom level refitted
/// at each pose ([`crate::bvh::Bvh::refit`]: boxes made tight again over the same topology)
/// instead of built again: a build costs ~0.3 µs a triangle here (release, 2 cores: 30 ms for
/// 100k), a refit a tenth of that. A smaller mesh is built again (about a millisecond or less:
/// LittlestTokyo's 8 skinned meshes have 758 triangles in all), so its pose stays bit for bit
/// what packing the posed scene gives.
pub const REFIT_MIN_TRIANGLES: usize = 4096;

/// A refitted bottom level whose SAH cost grew past this many times its first pose's is built
/// again for that pose. Measured (`examples/bench_refit.rs`, a 100k-triangle grid): bulged
/// and twisted as skins and morphs deform, the ratio reached 2.07 while the refitted level
/// traced as fast as a rebuilt one (0.94-1.23x the rays/s) for a tenth of the time (3 ms
/// against 30); torn apart, it was 3.75 and more, tracing at 0.38x and less.
pub const REFIT_BOUND: f32 = 2.5;

/// Why the moving parts do not match the packed scene.
fn mismatch<T>(what: impl std::fmt::Display) -> Result<T, PackError> {
    Err(PackError::NotThisPose(what.to_string()))
}

impl Posing {
    /// Reads what posing reuses from `first` (a scene packed at some pose by [`super::pack`])
    /// and `parts` (that scene, or its moving parts as a bundle carries them, at the same
    /// pose: its meshes, instances and motion). Every index read from `first` is bounded; a
    /// `parts` that does not match `first` is [`PackError::NotThisPose`].
    pub fn new(first: &Packed, parts: &Scene) -> Result<Posing, PackError> {
        let still = Posing {
            first: first.clone(),
            levels: Vec::new(),
            static_box: None,
            level_of_mesh: Vec::new(),
            instances: 0,
        };
        if !first.features.instances {
            return match parts.instances.is_empty() {
                true => Ok(still),
                false => mismatch("the packed scene has one level, the moving parts have instances"),
            };
        }
        let s = &first.scene;
        let node_count = s.node_children.len();
        let instance_first = s.instance_first as usize;
        if node_count.checked_mul(NODE_TEXELS as usize) != Some(instance_first) || s.nodes.len() < instance_first {
            return mismatch("the nodes and the placements do not line up");
        }
        let placements: Vec<&[Vec4]> = s.nodes.as_slice()[instance_first..].chunks(INSTANCE_TEXELS as usize).collect();
        let has_static = match placements.len().checked_sub(parts.instances.len()) {
            Some(0) => false,
            Some(1) => true,
            _ => return mismatch(format!("{} placements for {} instances", placements.len(), parts.instances.len())),
        };
        // The levels: the static one, then each placed mesh's in mesh order.
        let mut used = vec![false; parts.meshes.len()];
        for i in &parts.instances {
            *used.get_mut(i.mesh as usize).ok_or(PackError::NotThisPose("an instance names no mesh".into()))? = true;
        }
        let mesh_triangles: usize = (0..used.len()).filter(|&m| used[m]).map(|m| parts.meshes[m].triangles.len()).sum();
        let static_triangles = first.triangle_count.checked_sub(mesh_triangles).unwrap_or(usize::MAX);
        if static_triangles == usize::MAX || (static_triangles > 0) != has_static {
            return mismatch(format!("{} triangles, {mesh_triangles} of them placed meshes'", first.triangle_count));
        }
        let mut roots: Vec<usize> = Vec::with_capacity(placements.len());
        for p in &placements {
            let root = p.last().map_or(-1.0, |t| t.x);
            if !(root >= 1.0 && root.fract() == 0.0 && (root as usize) < node_count) {
                return mismatch(format!("a placement's root node is {root}"));
            }
            roots.push(root as usize);
        }
        let mut level_roots = roots.clone();
        level_roots.sort_unstable();
        level_roots.dedup();
        let deformed = parts.motion.as_ref().map_or(Vec::new(), |m| m.deformed_mesh_indices());
        let mut meshes: Vec<Option<usize>> = has_static.then_some(None).into_iter().collect();
        meshes.extend((0..used.len()).filter(|&m| used[m]).map(Some));
        if meshes.len() != level_roots.len() {
            return mismatch(format!(
                "{} levels in the packed scene, {} in the moving parts",
                level_roots.len(),
                meshes.len()
            ));
        }
        let mut levels = Vec::with_capacity(meshes.len());
        let mut level_of_mesh = vec![None; parts.meshes.len()];
        let mut next_triangle = 0;
        for (k, &mesh) in meshes.iter().enumerate() {
            let nodes = level_roots[k]..level_roots.get(k + 1).copied().unwrap_or(node_count);
            let count = mesh.map_or(static_triangles, |m| parts.meshes[m].triangles.len());
            let triangles = next_triangle..next_triangle + count;
            next_triangle += count;
            let kind = match mesh.filter(|m| deformed.contains(m)) {
                Some(m) => {
                    let (alpha_tested, bvh) = deformed_flags(first, parts, m, &triangles)?;
                    let refit = (count >= REFIT_MIN_TRIANGLES).then(|| {
                        let cost = bvh.sah_cost();
                        (bvh, cost)
                    });
                    LevelKind::Deformed { alpha_tested, refit }
                }
                None => LevelKind::Kept { need: kept_need(first, &nodes, &triangles)?, nodes },
            };
            if let Some(m) = mesh {
                level_of_mesh[m] = Some(k);
            }
            levels.push(Level { mesh, triangles, kind });
        }
        let static_box = match has_static {
            true => Some(static_box(first, &roots, level_roots[0])?),
            false => None,
        };
        Ok(Posing { levels, static_box, level_of_mesh, instances: parts.instances.len(), ..still })
    }

    /// The first pose, packed.
    pub fn first(&self) -> &Packed {
        &self.first
    }

    /// `parts` (posed by `Scene::pose`) packed: the first pose's arrays with the placements,
    /// the top level and the deformed meshes made again.
    pub fn pack(&self, parts: &Scene) -> Result<Packed, PackError> {
        if self.levels.is_empty() {
            return Ok(self.first.clone());
        }
        if parts.instances.len() != self.instances || parts.meshes.len() != self.level_of_mesh.len() {
            return mismatch("the moving parts changed their instances or meshes");
        }
        let remade = self.remade_levels(parts)?;

        // The top level over the placements' boxes: the static one first, then the instances'.
        let mut boxes: Vec<Aabb> = self.static_box.into_iter().collect();
        boxes.extend(parts.placement_boxes());
        let corners: Vec<(Vec3, Vec3)> = boxes.iter().map(|b| (b.min, b.max)).collect();
        let (top, top_wide) = top_level(&corners).map_err(PackError::Bvh)?;
        check_leaves(&top)?;

        // The nodes: the top level, then each level moved behind it, then the placements.
        let (top_planes, top_children) = pack_nodes(&top_wide);
        let levels = self.level_nodes(&remade, top_children.len());
        if levels.node_count >= MAX_EXACT {
            return Err(PackError::TooManyTriangles(self.first.triangle_count));
        }
        let placement_texels = self.placement_texels(parts, &top.triangle_order, &levels.roots)?;
        let top_need = top_wide.stack_needed_with_leaves + 1;
        let (traversal_stack, leaf_stack_limit) = check_stack(top_need, levels.bottom.0, levels.bottom.1)?;
        let (planes, children) = node_arrays(&top_planes, &top_children, &levels, &placement_texels);

        let mut packed = self.first.clone();
        if remade.iter().any(Option::is_some) {
            self.write_deformed_triangles(&mut packed, parts, &remade);
        }
        let s = &mut packed.scene;
        s.nodes = planes;
        s.node_children = children;
        s.instance_first = (levels.node_count * NODE_TEXELS as usize) as u32;
        s.leaf_stack_limit = leaf_stack_limit;
        s.scene_scale = scene_scale(&boxes);
        packed.features.traversal_stack = traversal_stack;
        Ok(packed)
    }

    /// Per level, the deformed meshes' bottom levels made again for `parts` (built again or
    /// refitted, see [`deformed_level`]) and widened, `None` for a kept level: in parallel, as
    /// packing does. A deformed mesh whose triangle count changed is no pose of this scene.
    fn remade_levels(&self, parts: &Scene) -> Result<Vec<Remade>, PackError> {
        self.levels
            .par_iter()
            .map(|level| match (&level.kind, level.mesh) {
                (LevelKind::Deformed { refit, .. }, Some(m)) => {
                    let mesh = &parts.meshes[m];
                    if mesh.triangles.len() != level.triangles.len() {
                        return mismatch(format!(
                            "mesh {m} has {} triangles, not {}",
                            mesh.triangles.len(),
                            level.triangles.len()
                        ));
                    }
                    let bvh = deformed_level(refit.as_ref(), &mesh.triangles).map_err(PackError::Bvh)?;
                    check_leaves(&bvh)?;
                    let wide = bvh.widen().map_err(PackError::Bvh)?;
                    Ok(Some((bvh, wide)))
                }
                _ => Ok(None),
            })
            .collect()
    }

    /// The bottom levels' nodes behind a top level of `top_nodes` nodes, in level order: a kept
    /// level's borrowed from the first pose (its child entries to be shifted to where it lands),
    /// a remade one's packed from `remade` at its new place. Kept apart from writing the arrays
    /// because the placements need the levels' roots, and the stack check their needs, first.
    fn level_nodes<'a>(&'a self, remade: &[Remade], top_nodes: usize) -> LevelNodes<'a> {
        let old = &self.first.scene;
        let mut roots = Vec::with_capacity(self.levels.len());
        let mut pieces = Vec::with_capacity(self.levels.len());
        let mut bottom = (0u32, 0u32);
        let mut node_count = top_nodes;
        for (level, remade) in self.levels.iter().zip(remade) {
            roots.push(node_count as u32);
            let piece = match (&level.kind, remade) {
                (LevelKind::Kept { nodes, need }, _) => {
                    bottom = (bottom.0.max(need.0), bottom.1.max(need.1));
                    let texels = nodes.start * NODE_TEXELS as usize..nodes.end * NODE_TEXELS as usize;
                    let shift = node_count as i64 - nodes.start as i64;
                    Piece::Kept(&old.nodes.as_slice()[texels], &old.node_children.as_slice()[nodes.clone()], shift)
                }
                (LevelKind::Deformed { .. }, Some((_, wide))) => {
                    bottom = (bottom.0.max(wide.stack_needed), bottom.1.max(wide.stack_needed_with_leaves));
                    let (root, first_triangle) = (node_count as u32, level.triangles.start as u32);
                    let nodes = wide.nodes.iter().map(|n| rebase(n, root, first_triangle)).collect();
                    let (planes, children) = pack_nodes(&crate::bvh::WideBvh { nodes, ..wide.clone() });
                    Piece::Made(planes, children)
                }
                (LevelKind::Deformed { .. }, None) => unreachable!("every deformed level is rebuilt above"),
            };
            node_count += piece.children_len();
            pieces.push(piece);
        }
        LevelNodes { roots, pieces, bottom, node_count }
    }

    /// The placements' texels in the top level's leaf order (`order`: the static placement,
    /// when there is one, is item 0, instance `i` item `i + 1`), each naming its level's root
    /// in `roots`.
    fn placement_texels(&self, parts: &Scene, order: &[u32], roots: &[u32]) -> Result<Vec<Vec4>, PackError> {
        let has_static = self.static_box.is_some() as usize;
        let mut placement_texels = Vec::with_capacity(order.len() * INSTANCE_TEXELS as usize);
        for &p in order {
            let texels = match (p as usize).checked_sub(has_static) {
                None => instance_texels(Mat4::IDENTITY, roots[0], true),
                Some(i) => {
                    let instance = &parts.instances[i];
                    let level = self.level_of_mesh.get(instance.mesh as usize).copied().flatten();
                    let level = level.ok_or(PackError::NotThisPose(format!(
                        "instance {i} names mesh {}, which had no placement",
                        instance.mesh
                    )))?;
                    instance_texels(instance.transform, roots[level], instance.transform == Mat4::IDENTITY)
                }
            };
            placement_texels.extend_from_slice(&texels);
        }
        Ok(placement_texels)
    }

    /// Writes the deformed meshes' triangles (and their shading, tangent and second-UV
    /// sections, where `packed` has them) in the order of their `remade` bottom levels over
    /// the first pose's, which `packed` starts as: every other triangle keeps its place.
    fn write_deformed_triangles(&self, packed: &mut Packed, parts: &Scene, remade: &[Remade]) {
        let f = &packed.features;
        let s = &mut packed.scene;
        // Each deformed triangle: its index, the triangle, whether it is alpha-tested.
        let each = |write: &mut dyn FnMut(usize, &crate::scene::Triangle, bool)| {
            for (level, remade) in self.levels.iter().zip(remade) {
                let (LevelKind::Deformed { alpha_tested, .. }, Some((bvh, _)), Some(m)) =
                    (&level.kind, remade, level.mesh)
                else {
                    continue;
                };
                for (j, &source) in bvh.triangle_order.iter().enumerate() {
                    let t = &parts.meshes[m].triangles[source as usize];
                    write(level.triangles.start + j, t, f.alpha_mask && alpha_tested[source as usize]);
                }
            }
        };
        s.triangles = Texels::par_from_fill(s.triangles.len(), |out| {
            out.copy_from_slice(s.triangles.as_slice());
            each(&mut |i, t, alpha| put(out, i, TRIANGLE_TEXELS, 0, &triangle_texels(t, None, alpha)));
        });
        if f.shading {
            let (tangent_first, texcoord1_first) = (s.tangent_first, s.texcoord1_first);
            s.shading = Texels::par_from_fill(s.shading.len(), |out| {
                out.copy_from_slice(s.shading.as_slice());
                each(&mut |i, t, _| {
                    put(out, i, SHADING_TEXELS, 0, &shading_texels(t));
                    if f.normal_map {
                        put(out, i, TANGENT_TEXELS, tangent_first, &t.tangents);
                    }
                    if f.texcoord1 {
                        let uvs1 = super::texture_refs::texcoord1_texels(&t.uvs1);
                        put(out, i, TEXCOORD1_TEXELS, texcoord1_first, &uvs1);
                    }
                });
            });
        }
    }
}

/// A deformed level made again at a pose: its bottom level (whose triangle order its triangles
/// are written in) and that level widened (whose nodes are packed); `None` for a kept level.
type Remade = Option<(crate::bvh::Bvh, crate::bvh::WideBvh)>;

/// The bottom levels' nodes at a pose, as [`Posing::level_nodes`] lays them out.
struct LevelNodes<'a> {
    /// Per level, its root node.
    roots: Vec<u32>,
    /// Per level, its nodes.
    pieces: Vec<Piece<'a>>,
    /// The most stack any bottom level needs (child nodes pushed, leaves too).
    bottom: (u32, u32),
    /// All the nodes: the top level's and the levels'.
    node_count: usize,
}

/// The node arrays: the top level's planes and child entries, then each level's nodes
/// (a kept level's child entries shifted to where it now lies), then the placements' texels
/// behind the nodes' planes. Written in place (one copy of each kept level).
fn node_arrays(
    top_planes: &Texels<Vec4>,
    top_children: &Texels<UVec4>,
    levels: &LevelNodes,
    placement_texels: &[Vec4],
) -> (Texels<Vec4>, Texels<UVec4>) {
    let instance_first = levels.node_count * NODE_TEXELS as usize;
    let planes = Texels::par_from_fill(instance_first + placement_texels.len(), |out| {
        let mut at = 0;
        let mut copy = |from: &[Vec4]| {
            out[at..at + from.len()].copy_from_slice(from);
            at += from.len();
        };
        copy(top_planes.as_slice());
        levels.pieces.iter().for_each(|p| copy(p.planes()));
        copy(placement_texels);
    });
    let children = Texels::par_from_fill(levels.node_count, |out| {
        out[..top_children.len()].copy_from_slice(top_children.as_slice());
        let mut at = top_children.len();
        for piece in &levels.pieces {
            let to = &mut out[at..at + piece.children_len()];
            match piece {
                Piece::Kept(_, from, shift) => to.iter_mut().zip(*from).for_each(|(o, c)| *o = shifted(*c, *shift)),
                Piece::Made(_, from) => to.copy_from_slice(from.as_slice()),
            }
            at += to.len();
        }
    });
    (planes, children)
}

/// The scene's scale (the largest coordinate of the placements' `boxes`, skipping empty
/// ones; 1 when there is none), as packing the posed scene computes it: the kernel's ray
/// offsets scale with it, so it must follow what moves.
fn scene_scale(boxes: &[Aabb]) -> f32 {
    let mut bounds = Aabb::EMPTY;
    for b in boxes.iter().filter(|b| b.min.cmple(b.max).all()) {
        bounds.extend(b.min);
        bounds.extend(b.max);
    }
    let scene_scale = bounds.min.abs().max(bounds.max.abs()).max_element();
    if scene_scale.is_finite() {
        scene_scale
    } else {
        1.0
    }
}

/// A level's nodes in a pose: a kept level's (its planes, its child entries and how far its
/// child nodes move) or a rebuilt one's.
enum Piece<'a> {
    Kept(&'a [Vec4], &'a [UVec4], i64),
    Made(Texels<Vec4>, Texels<UVec4>),
}

impl Piece<'_> {
    fn planes(&self) -> &[Vec4] {
        match self {
            Piece::Kept(planes, _, _) => planes,
            Piece::Made(planes, _) => planes.as_slice(),
        }
    }

    fn children_len(&self) -> usize {
        match self {
            Piece::Kept(_, children, _) => children.len(),
            Piece::Made(_, children) => children.len(),
        }
    }
}

/// Writes triangle `i`'s `N` texels of a section of `per` texels per triangle from `first`.
fn put<const N: usize>(out: &mut [Vec4], i: usize, per: u32, first: u32, texels: &[Vec4; N]) {
    // Within the array (a decoded bundle's lengths are checked against its counts).
    let at = first as usize + i * per as usize;
    if let Some(slots) = out.get_mut(at..at + N) {
        slots.copy_from_slice(texels);
    }
}

/// A node's child entries with its child nodes' indices moved by `shift` (leaves and unused
/// slots stay).
fn shifted(c: UVec4, shift: i64) -> UVec4 {
    UVec4::from_array(c.to_array().map(|e| {
        let (first, count) = (e >> 8, e & 255);
        if e == 0 || count > 0 {
            e
        } else {
            crate::kernel::traverse::stack_entry((first as i64 + shift) as u32, 0)
        }
    }))
}

/// A kept level's stack need, as `Bvh::widen` computes it, from its child entries (nodes
/// `nodes` of the first pose): a node pushing `k` entries needs `max(k, k - 1 + the most a
/// child node needs)`. Its child nodes must lie within it, after their parent, and its leaves
/// within its triangles.
fn kept_need(first: &Packed, nodes: &Range<usize>, triangles: &Range<usize>) -> Result<(u32, u32), PackError> {
    let entries = &first.scene.node_children.as_slice()[nodes.clone()];
    let mut need = vec![(0u32, 0u32); entries.len()];
    let bound = |pushed: u32, most_below: u32| if pushed == 0 { 0 } else { pushed.max(pushed - 1 + most_below) };
    for i in (0..entries.len()).rev() {
        let (mut k, mut used, mut most, mut most_with_leaves) = (0u32, 0u32, 0u32, 0u32);
        for e in entries[i].to_array() {
            let (child, count) = ((e >> 8) as usize, (e & 255) as usize);
            if e == 0 {
                continue;
            }
            used += 1;
            if count > 0 {
                if child < triangles.start || child + count > triangles.end {
                    return mismatch(format!("a leaf of triangles {child}.. outside its level's {triangles:?}"));
                }
                continue;
            }
            let Some(c) = child.checked_sub(nodes.start).filter(|&c| c > i && c < entries.len()) else {
                return mismatch(format!("node {} has child node {child}, outside its level", nodes.start + i));
            };
            k += 1;
            most = most.max(need[c].0);
            most_with_leaves = most_with_leaves.max(need[c].1);
        }
        need[i] = (bound(k, most), bound(used, most_with_leaves));
    }
    need.first().copied().map_or_else(|| mismatch("a level without nodes"), Ok)
}

/// A deformed mesh's bottom level at a pose (`triangles`): its first pose's `refit` (the level
/// and its SAH cost), refitted, unless that degraded it past [`REFIT_BOUND`]; else built.
fn deformed_level(
    refit: Option<&(crate::bvh::Bvh, f32)>,
    triangles: &[crate::scene::Triangle],
) -> Result<crate::bvh::Bvh, crate::bvh::BvhError> {
    if let Some((first, cost)) = refit.filter(|(_, cost)| cost.is_finite() && *cost > 0.0) {
        let mut bvh = first.clone();
        bvh.refit(triangles)?;
        if bvh.sah_cost() <= REFIT_BOUND * cost {
            return Ok(bvh);
        }
    }
    crate::bvh::build(triangles)
}

/// A deformed mesh's alpha-test flags per triangle in mesh order (and its bottom level): its level in `first` is its
/// triangles in the order of its bottom level, built again here from `parts` (the same pose)
/// and checked against the packed corners.
fn deformed_flags(
    first: &Packed,
    parts: &Scene,
    m: usize,
    triangles: &Range<usize>,
) -> Result<(Vec<bool>, crate::bvh::Bvh), PackError> {
    let mesh = &parts.meshes[m];
    let bvh = crate::bvh::build(&mesh.triangles).map_err(PackError::Bvh)?;
    let packed = first.scene.triangles.as_slice();
    let mut flags = vec![false; mesh.triangles.len()];
    if bvh.triangle_order.len() != triangles.len() || packed.len() < triangles.end * TRIANGLE_TEXELS as usize {
        return mismatch(format!("mesh {m}'s triangles are not those packed"));
    }
    for (j, &t) in bvh.triangle_order.iter().enumerate() {
        let at = (triangles.start + j) * TRIANGLE_TEXELS as usize;
        let texels = &packed[at..at + TRIANGLE_TEXELS as usize];
        let t = t as usize;
        if (0..3).any(|c| texels[c].truncate() != mesh.triangles[t].positions[c]) {
            return mismatch(format!("mesh {m}'s triangle {t} is not the one packed at {}", triangles.start + j));
        }
        flags[t] = texels[2].w == 1.0;
    }
    Ok((flags, bvh))
}

/// The static placement's world box: its top-level leaf's box in `first` (the placement whose
/// root is the static level's).
fn static_box(first: &Packed, roots: &[usize], static_root: usize) -> Result<Aabb, PackError> {
    let s = &first.scene;
    let index = roots.iter().position(|&r| r == static_root).expect("the static level's root is a placement's");
    for node in 0..static_root {
        for (slot, e) in s.node_children.as_slice()[node].to_array().into_iter().enumerate() {
            let (first_item, count) = ((e >> 8) as usize, (e & 255) as usize);
            if count > 0 && (first_item..first_item + count).contains(&index) {
                let planes = &s.nodes.as_slice()[node * NODE_TEXELS as usize..(node + 1) * NODE_TEXELS as usize];
                return Ok(Aabb {
                    min: Vec3::new(planes[0][slot], planes[2][slot], planes[4][slot]),
                    max: Vec3::new(planes[1][slot], planes[3][slot], planes[5][slot]),
                });
            }
        }
    }
    mismatch("no top-level leaf holds the static placement")
}
