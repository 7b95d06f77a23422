//! glTF skins, applied on the host: each skinned vertex is moved by the weighted sum of its
//! (up to four) joints' matrices, `world(joint) × inverseBindMatrix(joint)`, with the joints
//! posed by the chosen animation (`animation.rs`); the skinned node's own transform is not used,
//! as the specification says. Normals and tangents follow the blended matrix's linear part
//! (renormalised: exact for rotations and uniform scales, an approximation under shear).

use super::nodes::VertexSkin;
use super::*;

impl Loader<'_> {
    /// A primitive's `JOINTS_0` / `WEIGHTS_0`, one entry per vertex; `None` (with a warning:
    /// the primitive is then not skinned) when their counts do not match `POSITION`'s.
    pub(super) fn vertex_skin(
        &mut self,
        data: &PrimitiveData,
        joints: usize,
        weights: usize,
        vertex_count: usize,
        what: &str,
    ) -> Result<Option<VertexSkin>, SceneError> {
        let j = self.vertex_f32(data, joints, 4, &format!("{what} JOINTS_0"))?;
        let w = self.vertex_f32(data, weights, 4, &format!("{what} WEIGHTS_0"))?;
        if j.len() != vertex_count * 4 || w.len() != vertex_count * 4 {
            let (nj, nw) = (j.len() / 4, w.len() / 4);
            self.warnings.once(&format!("{what} skin counts"), || {
                format!(
                    "{what}: JOINTS_0 has {nj} and WEIGHTS_0 {nw} elements, POSITION {vertex_count}: it is not skinned"
                )
            });
            return Ok(None);
        }
        if let Some(bad) = j.iter().find(|&&x| !(0.0..=65535.0).contains(&x) || x.fract() != 0.0) {
            return Err(malformed(format!("{what}: JOINTS_0 holds {bad}, not a joint index")));
        }
        let joints = j.chunks_exact(4).map(|c| [c[0] as u32, c[1] as u32, c[2] as u32, c[3] as u32]).collect();
        let weights = w.chunks_exact(4).map(Vec4::from_slice).collect();
        Ok(Some(VertexSkin { joints, weights }))
    }

    /// Appends mesh `mesh` (`prims`, morphed if it has morph targets) as skin `skin` deforms it
    /// (on node `node`, whose transform the specification ignores for skinned meshes). Where
    /// the pose makes a skinned vertex non-finite (a joint's matrix that overflows) and the
    /// animation moves a joint, the mesh is dropped with one warning, as `Motion::apply` drops
    /// it (`--strict` refuses it); where nothing moves, it is an error.
    pub(super) fn instantiate_skinned(
        &mut self,
        mesh: usize,
        prims: &[LocalPrimitive],
        skin: usize,
        node: usize,
    ) -> Result<(), SceneError> {
        let what = format!("node {node} skin {skin}");
        let skin = self.skin_joints(skin, node)?;
        let parents = self.parents()?;
        let mut posed = false;
        let joints = skin.matrices(|j| {
            let (world, moved) = self.world_of(j, &parents)?;
            posed |= moved;
            Ok(world)
        })?;
        match skin_all(prims, &joints, &what)? {
            Some(skinned) => self.defer(mesh, false, Rc::new(skinned), Mat4::IDENTITY),
            None if posed => {
                self.warn_dropped(format!("node {node} mesh {mesh}"), SKIN_NOT_FINITE);
                Ok(())
            }
            None => Err(skin.not_finite(&joints, &what)),
        }
    }

    /// Skin `skin`'s joints and inverse bind matrices (used by node `node`), checked.
    pub(super) fn skin_joints(&mut self, skin: usize, node: usize) -> Result<SkinJoints, SceneError> {
        let root = self.root;
        let what = format!("node {node} skin {skin}");
        let s = root.skins.get(skin).ok_or_else(|| malformed(format!("{what}: the skin does not exist")))?;
        let inverse_bind = match s.inverse_bind_matrices {
            Some(a) => {
                let m = self.buffers.read_f32(a.value(), 16, &format!("{what} inverseBindMatrices"))?;
                m.chunks_exact(16).map(Mat4::from_cols_slice).collect()
            }
            None => vec![Mat4::IDENTITY; s.joints.len()],
        };
        if inverse_bind.len() < s.joints.len() {
            return Err(malformed(format!(
                "{what}: {} inverse bind matrices for {} joints",
                inverse_bind.len(),
                s.joints.len()
            )));
        }
        let joints: Vec<usize> = s.joints.iter().map(|j| j.value()).collect();
        if let Some(&bad) = joints.iter().find(|&&j| j >= root.nodes.len()) {
            return Err(malformed(format!("{what}: joint node {bad} does not exist")));
        }
        Ok(SkinJoints { joints, inverse_bind })
    }

    /// Each node's parent (nodes are a forest: a second parent is refused).
    pub(super) fn parents(&self) -> Result<Vec<Option<usize>>, SceneError> {
        let nodes = &self.root.nodes;
        let mut parents = vec![None; nodes.len()];
        for (p, node) in nodes.iter().enumerate() {
            for child in node.children.iter().flatten() {
                let slot = parents
                    .get_mut(child.value())
                    .ok_or_else(|| malformed(format!("node {p}: child {} does not exist", child.value())))?;
                if slot.replace(p).is_some() {
                    return Err(malformed(format!("node {} has two parents", child.value())));
                }
            }
        }
        Ok(parents)
    }

    /// Node `n`'s world transform in the chosen pose (the product down from its root, finite
    /// or not), and whether the pose animates it or an ancestor.
    fn world_of(&self, n: usize, parents: &[Option<usize>]) -> Result<(Mat4, bool), SceneError> {
        let mut chain = vec![n];
        while let Some(p) = parents.get(*chain.last().unwrap_or(&n)).copied().flatten() {
            if chain.len() > parents.len() {
                return Err(malformed(format!("node {n}: its ancestors form a cycle")));
            }
            chain.push(p);
        }
        let mut world = Mat4::IDENTITY;
        for &i in chain.iter().rev() {
            let node = self.root.nodes.get(i).ok_or_else(|| malformed(format!("node {i} does not exist")))?;
            world *= self.posed_local(node, i)?;
        }
        let posed = chain.iter().any(|i| self.pose.get(i).is_some_and(|p| p.transforms()));
        Ok((world, posed))
    }
}

/// A skin's joint nodes and their inverse bind matrices.
#[derive(Clone, Debug)]
pub(super) struct SkinJoints {
    pub(super) joints: Vec<usize>,
    pub(super) inverse_bind: Vec<Mat4>,
}

/// Why a pose drops a skinned mesh (`motion::dropped`): the transform that skins it.
pub(super) const SKIN_NOT_FINITE: &str =
    "is not finite (a joint's matrix, or a vertex it skins, or it carries one beyond 1e12 units of the origin)";

impl SkinJoints {
    /// Each joint's `world(joint) × inverseBindMatrix(joint)`, `world` giving a node's world
    /// transform in the pose (finite or not: [`skin_all`] says whether the skinned mesh is).
    pub(super) fn matrices(
        &self,
        mut world: impl FnMut(usize) -> Result<Mat4, SceneError>,
    ) -> Result<Vec<Mat4>, SceneError> {
        self.joints.iter().zip(&self.inverse_bind).map(|(&j, ibm)| Ok(world(j)? * *ibm)).collect()
    }

    /// The error for a skinned mesh (`what`) that `joints` (from [`matrices`](Self::matrices))
    /// cannot make finite, where no animation moves its joints.
    pub(super) fn not_finite(&self, joints: &[Mat4], what: &str) -> SceneError {
        match self.joints.iter().zip(joints).find(|(_, m)| !m.is_finite()) {
            Some((j, _)) => malformed(format!("{what}: joint node {j} has a non-finite transform")),
            None => malformed(format!(
                "{what}: a skinned vertex is not finite or lies beyond {:e} units of the origin",
                crate::scene::WORLD_LIMIT
            )),
        }
    }
}

/// `prims` skinned by `joints` ([`skin_primitive`]), or `None` when a skinned vertex is not
/// finite (a joint whose matrix is not finite, or one that overflows a vertex; joints no
/// vertex weighs do not matter) or lies beyond [`WORLD_LIMIT`](crate::scene::WORLD_LIMIT).
pub(super) fn skin_all(
    prims: &[LocalPrimitive],
    joints: &[Mat4],
    what: &str,
) -> Result<Option<Vec<LocalPrimitive>>, SceneError> {
    let skinned: Vec<LocalPrimitive> =
        prims.iter().map(|p| skin_primitive(p, joints, what)).collect::<Result<_, _>>()?;
    let finite = skinned.iter().all(|p| p.positions.iter().all(|v| crate::scene::in_world(*v)));
    Ok(finite.then_some(skinned))
}

/// `p` with its vertices (and normals, tangents) moved by their blended joint matrices; a
/// primitive without joints and weights is left in the skin's space.
pub(super) fn skin_primitive(p: &LocalPrimitive, joints: &[Mat4], what: &str) -> Result<LocalPrimitive, SceneError> {
    let Some(skin) = &p.skin else { return Ok(p.clone()) };
    let blended: Vec<Mat4> = skin
        .joints
        .iter()
        .zip(&skin.weights)
        .map(|(j, w)| {
            let sum = w.x + w.y + w.z + w.w;
            if sum <= 0.0 {
                return Ok(Mat4::IDENTITY);
            }
            let mut m = Mat4::ZERO;
            for k in 0..4 {
                if w[k] != 0.0 {
                    let joint = joints.get(j[k] as usize).ok_or_else(|| {
                        malformed(format!("{what}: joint {} of {} does not exist", j[k], joints.len()))
                    })?;
                    m += *joint * (w[k] / sum);
                }
            }
            Ok(m)
        })
        .collect::<Result<_, SceneError>>()?;
    let mut out = p.clone();
    for (v, m) in out.positions.iter_mut().zip(&blended) {
        *v = m.transform_point3(*v);
    }
    if let Some(normals) = &mut out.normals {
        for (n, m) in normals.iter_mut().zip(&blended) {
            *n = Mat3::from_mat4(*m).inverse().transpose().mul_vec3(*n).normalize_or_zero();
        }
    }
    if let Some(tangents) = &mut out.tangents {
        for (corners, tri) in tangents.iter_mut().zip(&p.triangles) {
            for (t, &v) in corners.iter_mut().zip(tri) {
                let m = Mat3::from_mat4(blended[v as usize]);
                *t = (m * t.truncate()).normalize_or_zero().extend(t.w);
            }
        }
    }
    out.skin = None;
    Ok(out)
}
