//! Geometry: the BVH's checks against the kernel's traversal, the triangles in BVH order, their
//! shading data (normals, UVs, tangents, the second UV set) and the wide BVH's nodes.

use glam::{UVec4, Vec4};
use kernel_dsl::Texels;
use rayon::prelude::*;

use super::{index_value, PackError};
use crate::bvh::{Bvh, WideBvh};
use crate::kernel::instances::INSTANCE_TEXELS;
use crate::kernel::normal_map::TANGENT_TEXELS;
use crate::kernel::scene_data::{NODE_TEXELS, SHADING_TEXELS, TRIANGLE_TEXELS};
use crate::kernel::texture_ref::TEXCOORD1_TEXELS;
use crate::kernel::Features;
use crate::scene::{Scene, Triangle};

/// Largest integer stored exactly in an f32 texel.
pub(super) const MAX_EXACT: usize = 1 << 24;

/// A scene's triangles in BVH order with the wide BVH, checked against what the kernel's
/// traversal takes.
pub(super) struct Ordered<'a> {
    pub triangles: Vec<&'a Triangle>,
    pub wide: WideBvh,
    /// The traversal stack this BVH needs (`Features::traversal_stack`).
    pub traversal_stack: u32,
    /// The kernel's `leaf_stack_limit`.
    pub leaf_stack_limit: u32,
    /// Two levels (`Features::instances`): `wide` holds the top level first, and these are
    /// the placements' texels in top-level order (`super::instances`). Empty for one level.
    pub instances: Vec<[Vec4; INSTANCE_TEXELS as usize]>,
}

impl<'a> Ordered<'a> {
    pub fn new(scene: &'a Scene, bvh: &Bvh) -> Result<Self, PackError> {
        if !scene.instances.is_empty() {
            return super::instances::two_level(scene, bvh);
        }
        let tri_count = bvh.triangle_order.len();
        if tri_count >= MAX_EXACT || bvh.nodes.len() >= MAX_EXACT {
            return Err(PackError::TooManyTriangles(tri_count));
        }
        let wide = bvh.widen().map_err(PackError::Bvh)?;
        let (traversal_stack, leaf_stack_limit) = check_stack(0, wide.stack_needed, wide.stack_needed_with_leaves)?;
        // The traversal stack carries a leaf's triangle count in 8 bits.
        let max_leaf = crate::kernel::traverse::MAX_LEAF_TRIANGLES;
        if let Some(leaf) = bvh.nodes.iter().find(|n| n.count > max_leaf) {
            return Err(PackError::LeafTooLarge { triangles: leaf.count, max: max_leaf });
        }
        let triangles: Vec<&Triangle> = bvh
            .triangle_order
            .iter()
            .map(|&i| scene.triangles.get(i as usize).ok_or(PackError::BadBvh(i)))
            .collect::<Result<_, _>>()?;
        Ok(Ordered { triangles, wide, traversal_stack, leaf_stack_limit, instances: Vec::new() })
    }

    /// Whether the scene has two levels (a two-level scene has at least one placement).
    pub fn two_level(&self) -> bool {
        !self.instances.is_empty()
    }

    /// Whether some vertex normal differs from its face's (the shading data is needed). The
    /// passes over every triangle run in parallel (they read the triangles in BVH order,
    /// scattered in memory).
    pub fn smooth(&self) -> bool {
        self.triangles.par_iter().any(|t| {
            let face = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]).normalize_or_zero();
            t.normals.iter().any(|n| n.dot(face) < 0.9999)
        })
    }
}

/// The traversal stack and the kernel's `leaf_stack_limit` for `below` entries that stay on the
/// stack throughout (a two-level scene's top level) under a tree that needs `needed` entries
/// with child nodes pushed, `needed_with_leaves` with leaves pushed too.
///
/// Closest-hit traversal pushes leaves too while the stack has room for them: child nodes
/// alone never need more than `needed` entries and leaves are pushed only below the limit, so
/// at most `limit + needed` entries are ever held. A tree that fits with every leaf pushed gets
/// a stack of exactly its need (at least 1: `occluded` starts with the root on it), and the
/// limit never stops a push.
pub(super) fn check_stack(below: u32, needed: u32, needed_with_leaves: u32) -> Result<(u32, u32), PackError> {
    let max = crate::kernel::traverse::STACK_SIZE as u32;
    if below + needed > max {
        return Err(PackError::BvhTooDeep { needed: below + needed, max });
    }
    Ok(if below + needed_with_leaves <= max {
        let need = (below + needed_with_leaves).max(1);
        (need, need)
    } else {
        (max, max - needed)
    })
}

/// The kernel's geometry arrays.
pub(super) struct PackedGeometry {
    pub triangles: Texels<Vec4>,
    pub shading: Texels<Vec4>,
    pub nodes: Texels<Vec4>,
    pub node_children: Texels<UVec4>,
    pub tangent_first: u32,
    pub texcoord1_first: u32,
    /// Where the instances start in `nodes` (0 without).
    pub instance_first: u32,
}

/// Packs the triangles (with their light index and mask flag), their shading data and the
/// nodes. The large arrays are written straight into their shared allocations (no copy).
pub(super) fn pack_geometry(
    ordered: &Ordered,
    features: &Features,
    emissive: &super::lights::Emissive,
    alpha_tested: &[bool],
) -> PackedGeometry {
    let tri_count = ordered.triangles.len();
    let triangles = Texels::par_from_groups::<{ TRIANGLE_TEXELS as usize }>(tri_count, |i| {
        let t = ordered.triangles[i];
        triangle_texels(t, emissive.light_of(i, t), features.alpha_mask && alpha_tested[i])
    });
    let shading = if features.shading { pack_shading(&ordered.triangles, features) } else { Texels::default() };
    let tangent_first = if features.normal_map { (tri_count * SHADING_TEXELS as usize) as u32 } else { 0 };
    let texcoord1_first = if features.texcoord1 {
        (tri_count * (SHADING_TEXELS + if features.normal_map { TANGENT_TEXELS } else { 0 }) as usize) as u32
    } else {
        0
    };
    let (mut nodes, node_children) = pack_nodes(&ordered.wide);
    let mut instance_first = 0;
    if ordered.two_level() {
        instance_first = nodes.len() as u32;
        let texels = nodes.as_slice().iter().copied().chain(ordered.instances.iter().flatten().copied());
        nodes = Texels::new(texels.collect());
    }
    PackedGeometry { triangles, shading, nodes, node_children, tangent_first, texcoord1_first, instance_first }
}

/// A triangle's texels: its corners with its material, its light (or -1) and whether it is
/// alpha-tested.
pub(super) fn triangle_texels(
    t: &Triangle,
    light: Option<u32>,
    alpha_tested: bool,
) -> [Vec4; TRIANGLE_TEXELS as usize] {
    [
        t.positions[0].extend(t.material as f32),
        t.positions[1].extend(index_value(light)),
        t.positions[2].extend(if alpha_tested { 1.0 } else { 0.0 }),
    ]
}

/// A triangle's shading texels: its normals and UVs.
pub(super) fn shading_texels(t: &Triangle) -> [Vec4; SHADING_TEXELS as usize] {
    [
        t.normals[0].extend(t.uvs[0].x),
        t.normals[1].extend(t.uvs[0].y),
        t.normals[2].extend(t.uvs[1].x),
        Vec4::new(t.uvs[1].y, t.uvs[2].x, t.uvs[2].y, 0.0),
    ]
}

/// Normals and UVs per triangle; tangents and the second UV set extend the shading array
/// (`kernel::normal_map`, `kernel::texture_ref`): no new binding.
fn pack_shading(ordered: &[&Triangle], features: &Features) -> Texels<Vec4> {
    let tri_count = ordered.len();
    let shading = Texels::par_from_groups::<{ SHADING_TEXELS as usize }>(tri_count, |i| shading_texels(ordered[i]));
    let tangents = features
        .normal_map
        .then(|| Texels::par_from_groups::<{ TANGENT_TEXELS as usize }>(tri_count, |i| ordered[i].tangents));
    let uvs1 = features.texcoord1.then(|| {
        Texels::par_from_groups::<{ TEXCOORD1_TEXELS as usize }>(tri_count, |i| {
            super::texture_refs::texcoord1_texels(&ordered[i].uvs1)
        })
    });
    if tangents.is_none() && uvs1.is_none() {
        shading
    } else {
        let parts = [Some(&shading), tangents.as_ref(), uvs1.as_ref()];
        Texels::new(parts.into_iter().flatten().flat_map(|t| t.as_slice().iter().copied()).collect())
    }
}

/// The wide BVH's nodes: their children's bounds, and each child's stack entry.
pub(super) fn pack_nodes(wide: &WideBvh) -> (Texels<Vec4>, Texels<UVec4>) {
    let nodes = Texels::par_from_groups::<{ NODE_TEXELS as usize }>(wide.nodes.len(), |i| {
        let n = &wide.nodes[i];
        [
            Vec4::from_array(n.min.map(|c| c.x)),
            Vec4::from_array(n.max.map(|c| c.x)),
            Vec4::from_array(n.min.map(|c| c.y)),
            Vec4::from_array(n.max.map(|c| c.y)),
            Vec4::from_array(n.min.map(|c| c.z)),
            Vec4::from_array(n.max.map(|c| c.z)),
        ]
    });
    let node_children = Texels::par_from_groups::<1>(wide.nodes.len(), |i| {
        let n = &wide.nodes[i];
        [UVec4::from_array(std::array::from_fn(|c| crate::kernel::traverse::stack_entry(n.first[c], n.count[c])))]
    });
    (nodes, node_children)
}
