//! Two-level scenes (`Features::instances`, `kernel::instances`): one bottom-level BVH per
//! placed mesh and one over the static triangles (placed by the identity), a top level over
//! the placements, all in one node array: the top level first (its root is node 0, its leaves
//! name placements), then each bottom level, its child nodes and leaves rebased.

use glam::{Mat4, Vec3, Vec4};
use rayon::prelude::*;

use super::geometry::{check_stack, Ordered, MAX_EXACT};
use super::PackError;
use crate::bvh::{BuildOptions, Bvh, WideBvh, WideNode};
use crate::kernel::instances::INSTANCE_TEXELS;
use crate::scene::{Aabb, Scene, Triangle};

/// One placement as the top level sees it: which bottom level, where.
struct Placement {
    level: usize,
    transform: Mat4,
    identity: bool,
    bounds: Aabb,
}

/// The bottom levels, each a BVH in its own space: their triangles in BVH order one level
/// after the other, each level's wide BVH with its first triangle, and the placements (the
/// static level's first, by the identity).
struct Bottom<'a> {
    triangles: Vec<&'a Triangle>,
    levels: Vec<(WideBvh, u32)>,
    placements: Vec<Placement>,
}

fn bottom_levels<'a>(scene: &'a Scene, bvh: &Bvh) -> Result<Bottom<'a>, PackError> {
    let mut used = vec![false; scene.meshes.len()];
    for inst in &scene.instances {
        used[inst.mesh as usize] = true;
    }
    let mesh_bvhs: Vec<Option<Bvh>> = scene
        .meshes
        .par_iter()
        .zip(&used)
        .map(|(mesh, &used)| used.then(|| crate::bvh::build(&mesh.triangles)).transpose())
        .collect::<Result<_, _>>()
        .map_err(PackError::Bvh)?;
    let mut b = Bottom { triangles: Vec::new(), levels: Vec::new(), placements: Vec::new() };
    if !scene.triangles.is_empty() {
        check_leaves(bvh)?;
        b.levels.push((bvh.widen().map_err(PackError::Bvh)?, 0));
        for &i in &bvh.triangle_order {
            b.triangles.push(scene.triangles.get(i as usize).ok_or(PackError::BadBvh(i))?);
        }
        let mut bounds = Aabb::EMPTY;
        scene.triangles.iter().flat_map(|t| t.positions).for_each(|p| bounds.extend(p));
        b.placements.push(Placement { level: 0, transform: Mat4::IDENTITY, identity: true, bounds });
    }
    let mut level_of_mesh = vec![usize::MAX; scene.meshes.len()];
    for (m, mesh_bvh) in mesh_bvhs.iter().enumerate() {
        if let Some(mesh_bvh) = mesh_bvh {
            check_leaves(mesh_bvh)?;
            level_of_mesh[m] = b.levels.len();
            b.levels.push((mesh_bvh.widen().map_err(PackError::Bvh)?, b.triangles.len() as u32));
            b.triangles.extend(mesh_bvh.triangle_order.iter().map(|&i| &scene.meshes[m].triangles[i as usize]));
        }
    }
    for (inst, bounds) in scene.instances.iter().zip(scene.placement_boxes()) {
        b.placements.push(Placement {
            level: level_of_mesh[inst.mesh as usize],
            transform: inst.transform,
            identity: inst.transform == Mat4::IDENTITY,
            bounds,
        });
    }
    Ok(b)
}

/// Orders a scene with instances: the static triangles (BVH `bvh`, empty when there are none)
/// and the placed meshes' triangles, each level after the other, with the combined nodes and
/// the placements' texels in top-level order.
pub(super) fn two_level<'a>(scene: &'a Scene, bvh: &Bvh) -> Result<Ordered<'a>, PackError> {
    scene.check_instances().map_err(PackError::Instance)?;
    let Bottom { triangles, levels, placements } = bottom_levels(scene, bvh)?;
    if triangles.len() >= MAX_EXACT || placements.len() >= MAX_EXACT {
        return Err(PackError::TooManyTriangles(triangles.len().max(placements.len())));
    }

    let boxes: Vec<(Vec3, Vec3)> = placements.iter().map(|p| (p.bounds.min, p.bounds.max)).collect();
    let (top, top_wide) = top_level(&boxes).map_err(PackError::Bvh)?;
    check_leaves(&top)?;

    let mut nodes = top_wide.nodes.clone();
    let mut roots = Vec::with_capacity(levels.len());
    for (wide, tri_offset) in &levels {
        let node_offset = nodes.len() as u32;
        roots.push(node_offset);
        nodes.extend(wide.nodes.iter().map(|n| rebase(n, node_offset, *tri_offset)));
    }
    if nodes.len() >= MAX_EXACT {
        return Err(PackError::TooManyTriangles(triangles.len()));
    }
    let instances = top
        .triangle_order
        .iter()
        .map(|&p| {
            let p = &placements[p as usize];
            instance_texels(p.transform, roots[p.level], p.identity)
        })
        .collect();

    // The stack: the top level's entries (leaves pushed, one more for a leaf's remaining
    // placements) below any bottom level's.
    let top_need = top_wide.stack_needed_with_leaves + 1;
    let bottom_need = levels.iter().map(|(w, _)| w.stack_needed).max().unwrap_or(0);
    let bottom_need_with_leaves = levels.iter().map(|(w, _)| w.stack_needed_with_leaves).max().unwrap_or(0);
    let (traversal_stack, leaf_stack_limit) = check_stack(top_need, bottom_need, bottom_need_with_leaves)?;
    let depth = top_wide.depth + levels.iter().map(|(w, _)| w.depth).max().unwrap_or(0);
    let wide = WideBvh {
        nodes,
        depth,
        stack_needed: top_need + bottom_need,
        stack_needed_with_leaves: top_need + bottom_need_with_leaves,
    };
    Ok(Ordered { triangles, wide, traversal_stack, leaf_stack_limit, instances })
}

/// The top level over placements' world boxes, binary and widened: one placement per leaf
/// where it can (a leaf of several is entered one placement after the other). What a frame in
/// which placements move rebuilds (`examples/bench_instancing.rs` and the page time it), so
/// built with the fastest preset (PLOC radius 1, no reinsertion): 10,000 placements in 2.8 ms
/// in wasm against 14.9 ms with the default preset, at the same render speed.
pub fn top_level(boxes: &[(Vec3, Vec3)]) -> Result<(Bvh, WideBvh), crate::bvh::BvhError> {
    let options =
        BuildOptions { max_leaf_size: 1, quality: crate::bvh::BuildQuality::Fastest, ..BuildOptions::default() };
    let top = crate::bvh::build_over_boxes(boxes, &options)?;
    let wide = top.widen()?;
    Ok((top, wide))
}

/// The traversal stack carries a leaf's count in 8 bits.
pub(super) fn check_leaves(bvh: &Bvh) -> Result<(), PackError> {
    let max_leaf = crate::kernel::traverse::MAX_LEAF_TRIANGLES;
    match bvh.nodes.iter().find(|n| n.count > max_leaf) {
        Some(leaf) => Err(PackError::LeafTooLarge { triangles: leaf.count, max: max_leaf }),
        None => Ok(()),
    }
}

/// A bottom level's node moved to `node_offset`, its leaves to `tri_offset`.
pub(super) fn rebase(n: &WideNode, node_offset: u32, tri_offset: u32) -> WideNode {
    let mut out = *n;
    for c in 0..n.children as usize {
        out.first[c] += if n.count[c] > 0 { tri_offset } else { node_offset };
    }
    out
}

/// A placement's texels (`kernel::instances`): world-to-mesh rows, mesh-to-world rows, then
/// `[root node, handedness, identity, 0]`.
pub(super) fn instance_texels(m: Mat4, root: u32, identity: bool) -> [Vec4; INSTANCE_TEXELS as usize] {
    let inv = m.inverse();
    let handedness = if m.determinant() < 0.0 { -1.0 } else { 1.0 };
    [
        inv.row(0),
        inv.row(1),
        inv.row(2),
        m.row(0),
        m.row(1),
        m.row(2),
        Vec4::new(root as f32, handedness, if identity { 1.0 } else { 0.0 }, 0.0),
    ]
}
