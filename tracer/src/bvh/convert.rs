//! The binary builder's output (obvhs' `Bvh2`) converted to [`Bvh`]'s layout in one pass: a
//! pre-order walk that checks the node graph is a tree, a bottom-up pass that collapses
//! subtrees into leaves wherever that lowers the SAH cost, and a depth-first emit.

use glam::Vec3;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::Bvh2;

use super::{Bvh, BvhError, BvhNode, Primitives};

/// Converts obvhs' BVH2 into our layout, depth-first, reordering triangles into leaf order and
/// collapsing subtrees into leaves where the SAH says so (at most `max_leaf` triangles, node
/// traversal costing `traversal_cost` triangle tests). Doing the collapse here, in one
/// bottom-up pass over the tree, replaces obvhs' separate collapse step and its node rewrite.
///
/// A builder leaf may stand for more than `max_leaf` triangles (a group of coincident ones,
/// see `super::coincident`): it becomes a balanced subtree over them, halves of its triangle range.
pub(super) fn convert(
    bvh2: &Bvh2,
    primitives: &Primitives,
    max_leaf: u32,
    traversal_cost: f32,
) -> Result<Bvh, BvhError> {
    if bvh2.nodes.is_empty() {
        return Err(internal("the builder returned no nodes"));
    }
    let preorder = preorder(&bvh2.nodes)?;
    let collapse = collapse_by_sah(bvh2, primitives, &preorder, max_leaf, traversal_cost)?;
    let (nodes, order) = emit(bvh2, primitives, &collapse, max_leaf)?;
    if order.len() != primitives.aabbs.len() {
        return Err(internal("leaves do not reference every triangle once"));
    }
    Ok(Bvh { nodes, triangle_order: order })
}

fn internal(message: &str) -> BvhError {
    BvhError::Internal(message.to_owned())
}

/// The two children of an inner node of the binary builder's output.
fn children(src: &[Bvh2Node], n: &Bvh2Node) -> Result<(usize, usize), BvhError> {
    let c = n.first_index as usize;
    if c + 1 < src.len() {
        Ok((c, c + 1))
    } else {
        Err(internal("child index out of range"))
    }
}

/// The builder's nodes in pre-order, checking that the node graph is a tree reachable from the root.
fn preorder(src: &[Bvh2Node]) -> Result<Vec<u32>, BvhError> {
    let mut preorder: Vec<u32> = Vec::with_capacity(src.len());
    let mut stack: Vec<u32> = vec![0];
    while let Some(s) = stack.pop() {
        if preorder.len() >= src.len() {
            return Err(internal("the node graph has a cycle"));
        }
        preorder.push(s);
        let node = src.get(s as usize).ok_or_else(|| internal("node index out of range"))?;
        if !node.is_leaf() {
            let (l, r) = children(src, node)?;
            stack.push(r as u32);
            stack.push(l as u32);
        }
    }
    Ok(preorder)
}

/// Bottom-up (reverse pre-order): triangles per subtree and its best SAH cost, deciding which
/// subtrees become leaves (`true`: collapse the subtree into one leaf).
fn collapse_by_sah(
    bvh2: &Bvh2,
    primitives: &Primitives,
    preorder: &[u32],
    max_leaf: u32,
    traversal_cost: f32,
) -> Result<Vec<bool>, BvhError> {
    let (src, prims) = (&bvh2.nodes, &bvh2.primitive_indices);
    let mut count = vec![0u32; src.len()];
    let mut cost = vec![0f32; src.len()];
    let mut collapse = vec![false; src.len()];
    for &s in preorder.iter().rev() {
        let s = s as usize;
        let node = &src[s];
        let area = node.aabb().half_area();
        if node.is_leaf() {
            let start = node.first_index as usize;
            let range = prims
                .get(start..start + node.prim_count as usize)
                .ok_or_else(|| internal("leaf range out of range"))?;
            count[s] = range.iter().map(|&p| primitives.triangle_count(p)).fold(0, u32::saturating_add);
            cost[s] = area * count[s] as f32;
            continue;
        }
        let (l, r) = children(src, node)?;
        let n = count[l].saturating_add(count[r]);
        let as_split = area * traversal_cost + cost[l] + cost[r];
        let as_leaf = area * n as f32;
        count[s] = n;
        if n <= max_leaf && as_leaf <= as_split {
            collapse[s] = true;
            cost[s] = as_leaf;
        } else {
            cost[s] = as_split;
        }
    }
    Ok(collapse)
}

/// The 2-wide tree as emitted depth-first (each pair of children allocated when its parent is
/// visited), and the triangle order its leaves reference.
fn emit(
    bvh2: &Bvh2,
    primitives: &Primitives,
    collapse: &[bool],
    max_leaf: u32,
) -> Result<(Vec<BvhNode>, Vec<u32>), BvhError> {
    let (src, prims) = (&bvh2.nodes, &bvh2.primitive_indices);
    let mut nodes: Vec<BvhNode> = Vec::with_capacity(src.len());
    let mut order: Vec<u32> = Vec::with_capacity(primitives.aabbs.len());
    let placeholder = BvhNode { min: Vec3::ZERO, max: Vec3::ZERO, first: 0, count: 0 };
    nodes.push(placeholder);
    let mut stack: Vec<Emit> = vec![Emit::Node { source: 0, to: 0 }];
    let mut gather: Vec<usize> = Vec::new();
    while let Some(job) = stack.pop() {
        let (s, d) = match job {
            Emit::Node { source, to } => (source, to),
            Emit::Range { first, count, to } => {
                let range = order.get(first as usize..(first + count) as usize).unwrap_or(&[]);
                let (min, max) = primitives.bounds(range);
                let out = if count <= max_leaf {
                    BvhNode { min, max, first, count }
                } else {
                    let child = nodes.len();
                    nodes.push(placeholder);
                    nodes.push(placeholder);
                    let half = count / 2;
                    stack.push(Emit::Range { first: first + half, count: count - half, to: child + 1 });
                    stack.push(Emit::Range { first, count: half, to: child });
                    BvhNode { min, max, first: child as u32, count: 0 }
                };
                *nodes.get_mut(to).ok_or_else(|| internal("destination out of range"))? = out;
                continue;
            }
        };
        let node = &src[s]; // every `s` here was reached by `preorder`
        let (min, max) = (Vec3::from(node.aabb().min), Vec3::from(node.aabb().max));
        let out = if node.is_leaf() || collapse[s] {
            let first = order.len() as u32;
            gather.push(s);
            while let Some(g) = gather.pop() {
                let n = &src[g];
                if n.is_leaf() {
                    let start = n.first_index as usize;
                    let range = prims
                        .get(start..start + n.prim_count as usize)
                        .ok_or_else(|| internal("leaf range out of range"))?;
                    for &p in range {
                        primitives.extend(p, &mut order);
                    }
                } else {
                    let (l, r) = children(src, n)?;
                    gather.push(r);
                    gather.push(l);
                }
            }
            let count = order.len() as u32 - first;
            if count > max_leaf {
                // More coincident triangles than a leaf holds: split their range in halves.
                stack.push(Emit::Range { first, count, to: d });
                continue;
            }
            BvhNode { min, max, first, count }
        } else {
            let (l, r) = children(src, node)?;
            let child = nodes.len();
            nodes.push(placeholder);
            nodes.push(placeholder);
            stack.push(Emit::Node { source: r, to: child + 1 });
            stack.push(Emit::Node { source: l, to: child });
            BvhNode { min, max, first: child as u32, count: 0 }
        };
        *nodes.get_mut(d).ok_or_else(|| internal("destination out of range"))? = out;
    }
    Ok((nodes, order))
}

/// A pending step of [`convert`]'s output pass: a builder node to emit at `nodes[to]`, or a
/// range of the reordered triangles (one oversized leaf's) to split into a subtree there.
enum Emit {
    Node { source: usize, to: usize },
    Range { first: u32, count: u32, to: usize },
}
