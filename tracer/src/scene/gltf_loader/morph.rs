//! glTF morph targets, applied on the host: a primitive's positions and normals plus the
//! weighted sum of its targets' displacements, with the weights of the chosen animation's
//! `weights` channel, else the node's `weights`, else the mesh's (all 0 without any).
//! Tangent displacements are not applied (normal-mapped morphs keep their base tangents).

use std::rc::Rc;

use super::nodes::LocalPrimitive;
use super::*;

/// One morph target's displacements, per vertex.
#[derive(Clone)]
pub(super) struct MorphTarget {
    pub(super) positions: Option<Vec<Vec3>>,
    pub(super) normals: Option<Vec<Vec3>>,
}

impl Loader<'_> {
    /// A primitive's morph targets; none (with a warning) when a target's counts do not match
    /// `POSITION`'s.
    pub(super) fn morph_targets(
        &mut self,
        prim: &gltf::json::mesh::Primitive,
        vertex_count: usize,
        what: &str,
    ) -> Result<Vec<MorphTarget>, SceneError> {
        let mut targets = Vec::new();
        for (t, target) in prim.targets.iter().flatten().enumerate() {
            let mut read = |a: Option<gltf::json::Index<gltf::json::Accessor>>, name: &str| {
                a.map(|a| self.buffers.read_f32(a.value(), 3, &format!("{what} target {t} {name}")).map(nodes::to_vec3))
                    .transpose()
            };
            let positions = read(target.positions, "POSITION")?;
            let normals = read(target.normals, "NORMAL")?;
            if [&positions, &normals].iter().any(|d| d.as_ref().is_some_and(|d| d.len() != vertex_count)) {
                self.warnings.once(&format!("{what} morph counts"), || {
                    format!("{what}: morph target {t} does not have one displacement per vertex: the primitive is not morphed")
                });
                return Ok(Vec::new());
            }
            targets.push(MorphTarget { positions, normals });
        }
        Ok(targets)
    }

    /// Mesh `mesh`'s primitives as node `n` shows them: morphed by its weights when it has
    /// targets and a non-zero weight. `None` where the animation's weights at this pose are
    /// not finite or make a vertex that is not ([`MORPH_NOT_FINITE`]): the pose drops the mesh
    /// (the caller warns); the node's or the mesh's own weights that are not finite are an
    /// error.
    pub(super) fn morphed(
        &mut self,
        mesh: usize,
        node: &gltf::json::scene::Node,
        n: usize,
    ) -> Result<Option<Rc<Vec<LocalPrimitive>>>, SceneError> {
        let prims = self.mesh(mesh)?;
        if prims.iter().all(|p| p.morph.is_empty()) {
            return Ok(Some(prims));
        }
        let animated = self.pose.get(&n).and_then(|p| p.weights.clone());
        let posed = animated.is_some();
        let weights = match animated {
            Some(animated) => animated,
            None => node
                .weights
                .clone()
                .or_else(|| self.root.meshes.get(mesh).and_then(|m| m.weights.clone()))
                .unwrap_or_default(),
        };
        match morph_all(&prims, &weights) {
            Ok(None) => Ok(Some(prims)),
            Ok(Some(morphed)) => Ok(Some(Rc::new(morphed))),
            Err(_) if posed => Ok(None),
            Err(bad) => Err(malformed(format!("node {n}: {bad}"))),
        }
    }

    /// The number of morph targets of node `n`'s mesh (0 without one), for its `weights` channel.
    pub(super) fn morph_target_count(&mut self, node: &gltf::json::scene::Node) -> Result<usize, SceneError> {
        match node.mesh {
            Some(m) => Ok(self.mesh(m.value())?.iter().map(|p| p.morph.len()).max().unwrap_or(0)),
            None => Ok(0),
        }
    }
}

/// Why a pose drops a morphed mesh (`motion::dropped`).
pub(super) const MORPH_NOT_FINITE: &str =
    "is not finite (its morph weights, or a vertex they morph, or they carry one beyond 1e12 units of the origin)";

/// `prims` morphed by `weights` ([`morph_primitive`]): `None` when every weight is 0 (the
/// primitives as they are); an error (what is not finite) when a weight or a morphed vertex
/// is not finite.
pub(super) fn morph_all(prims: &[LocalPrimitive], weights: &[f32]) -> Result<Option<Vec<LocalPrimitive>>, String> {
    if let Some(bad) = weights.iter().find(|w| !w.is_finite()) {
        return Err(format!("morph weight {bad} is not finite"));
    }
    if weights.iter().all(|&w| w == 0.0) {
        return Ok(None);
    }
    let morphed: Vec<LocalPrimitive> = prims.iter().map(|p| morph_primitive(p, weights)).collect();
    match morphed.iter().all(|p| p.positions.iter().all(|v| crate::scene::in_world(*v))) {
        true => Ok(Some(morphed)),
        false => Err("a morphed vertex is not finite or lies beyond 1e12 units of the origin".into()),
    }
}

/// `p` with `weights` of its targets' displacements added (missing weights count as 0).
pub(super) fn morph_primitive(p: &LocalPrimitive, weights: &[f32]) -> LocalPrimitive {
    let mut out = p.clone();
    for (target, &w) in p.morph.iter().zip(weights) {
        if w == 0.0 {
            continue;
        }
        if let Some(d) = &target.positions {
            out.positions.iter_mut().zip(d).for_each(|(v, d)| *v += *d * w);
        }
        if let (Some(normals), Some(d)) = (&mut out.normals, &target.normals) {
            normals.iter_mut().zip(d).for_each(|(n, d)| *n += *d * w);
        }
    }
    if let Some(normals) = &mut out.normals {
        normals.iter_mut().for_each(|n| *n = n.normalize_or_zero());
    }
    out.morph = Vec::new();
    out
}
