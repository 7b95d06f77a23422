//! A scene that keeps its animation ([`LoadOptions::keep_motion`]) so that it can be posed at
//! any time without loading it again ([`Scene::pose`]): the host side of scenes that move.
//!
//! What the chosen animation moves is kept apart from the static triangles:
//! - a mesh under a node that a translation, rotation or scale channel moves (the node or an
//!   ancestor) is stored once in its own space and placed by an [`Instance`] whose transform
//!   follows the node: a new pose rewrites transforms only, and the renderer rebuilds the top
//!   level over them;
//! - a skinned mesh, or one whose morph weights are animated, is *deformed*: its triangles are
//!   made again at each pose (morphed, then skinned or placed by its node) as a mesh placed by
//!   the identity, whose bottom level is rebuilt or refitted (`pack::posing`).
//!
//! A pose that cannot place a moving part drops it there, with one warning ([`dropped`];
//! `--strict` refuses it), keeping the scene's numbers of placements and triangles: a
//! placement's transform that cannot be inverted, is not finite or carries its mesh beyond
//! `scene::WORLD_LIMIT` ([`placeable`]), a deformed mesh's joints or morph weights that make a
//! vertex non-finite or carry it beyond the limit (`DeformedMesh::dropped`).
//!
//! Everything else stays as the loader flattens it, so the static part of a scene keeps its
//! one BVH. Lights and cameras stay where the load-time pose put them; an emissive mesh under
//! a moving node stays there too (lights must be static triangles), with a warning.

use std::borrow::Cow;
use std::collections::HashMap;

use super::animation::{pose_at, Channel, NodePose, RestTransform, Target};
use super::morph::{morph_all, MORPH_NOT_FINITE};
use super::nodes::{place_primitives, LocalPrimitive};
use super::skin::{skin_all, SkinJoints, SKIN_NOT_FINITE};
use super::*;
use crate::scene::{Aabb, Instance, Mesh};

/// The chosen animation and what it moves in a loaded scene ([`Scene::motion`]).
#[derive(Clone)]
pub struct Motion {
    channels: Vec<Channel>,
    nodes: Vec<RigNode>,
    /// Every node reachable from a root, each after its parent.
    order: Vec<usize>,
    rigid: Vec<RigidPlacement>,
    deformed: Vec<DeformedMesh>,
    duration: f32,
    /// The chosen animation's name in the file (empty when it has none).
    name: String,
}

/// A node of the hierarchy as the pose needs it.
#[derive(Clone, Debug)]
pub(super) struct RigNode {
    pub(super) parent: Option<usize>,
    pub(super) rest: RestTransform,
    /// The node's matrix, when it is given by one (channels never move such a node).
    pub(super) matrix: Option<Mat4>,
    /// A translation, rotation or scale channel targets it.
    pub(super) moved: bool,
    /// A weights channel targets it.
    pub(super) morphed: bool,
}

/// An instance whose transform is its node's world transform times `local` (the identity, or
/// an `EXT_mesh_gpu_instancing` instance's TRS).
#[derive(Clone, Debug)]
pub(super) struct RigidPlacement {
    pub(super) instance: usize,
    pub(super) node: usize,
    pub(super) local: Mat4,
    /// The placed mesh's bounds in its own space (what a pose may not carry beyond the world).
    pub(super) bounds: Aabb,
}

/// A mesh made again at each pose, placed by the identity: `Scene::meshes[mesh]`.
#[derive(Clone)]
pub(super) struct DeformedMesh {
    pub(super) mesh: usize,
    pub(super) node: usize,
    /// The glTF mesh it was made from (for messages).
    pub(super) gltf_mesh: usize,
    pub(super) prims: Vec<LocalPrimitive>,
    pub(super) skin: Option<SkinJoints>,
    /// The node's (else the mesh's) morph weights, when no channel animates them.
    pub(super) rest_weights: Vec<f32>,
    pub(super) what: String,
}

impl std::fmt::Debug for Motion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl Motion {
    /// The motion of `channels` over `root`'s node hierarchy (`parents` per node); no part of
    /// the scene follows it until the loader registers them.
    pub(super) fn new(root: &Root, parents: &[Option<usize>], channels: Vec<Channel>, name: String) -> Self {
        let nodes: Vec<RigNode> = root
            .nodes
            .iter()
            .zip(parents)
            .map(|(node, &parent)| RigNode {
                parent,
                rest: RestTransform::of(node),
                matrix: node.matrix.map(|m| Mat4::from_cols_array(&m)),
                moved: false,
                morphed: false,
            })
            .collect();
        Self::of_nodes(nodes, channels, name)
    }

    /// The motion of `channels` over `nodes` (their `moved` and `morphed` flags set here, each
    /// node's parent before it in no particular order: the walk order is made here).
    pub(super) fn of_nodes(mut nodes: Vec<RigNode>, channels: Vec<Channel>, name: String) -> Self {
        for c in &channels {
            if let Some(node) = nodes.get_mut(c.node) {
                match c.target {
                    Target::Weights => node.morphed = true,
                    _ => node.moved = true,
                }
            }
        }
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
        for (n, node) in nodes.iter().enumerate() {
            if let Some(p) = node.parent {
                children[p].push(n);
            }
        }
        let mut order: Vec<usize> = (0..nodes.len()).filter(|&n| nodes[n].parent.is_none()).collect();
        let mut at = 0;
        while at < order.len() {
            let n = order[at];
            order.extend(&children[n]);
            at += 1;
        }
        let duration = channels.iter().map(Channel::end).fold(0.0, f32::max);
        Motion { channels, nodes, order, rigid: Vec::new(), deformed: Vec::new(), duration, name }
    }

    /// The time of the animation's last keyframe, in seconds (poses after it are its last).
    pub fn duration(&self) -> f32 {
        self.duration
    }

    /// The chosen animation's name in the file (empty when it has none).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Instances whose transforms follow the animation.
    pub fn moving_placements(&self) -> usize {
        self.rigid.len()
    }

    /// Meshes made again at each pose (skinned, or morphed by animated weights).
    pub fn deformed_meshes(&self) -> usize {
        self.deformed.len()
    }

    /// The scene's meshes (indices into `Scene::meshes`) made again at each pose.
    pub fn deformed_mesh_indices(&self) -> Vec<usize> {
        self.deformed.iter().map(|d| d.mesh).collect()
    }

    /// What moves, in words (for read-outs).
    pub fn describe(&self) -> String {
        format!(
            "{} moving placements and {} skinned or morphed meshes, over {:.2} s",
            self.rigid.len(),
            self.deformed.len(),
            self.duration
        )
    }

    /// Its parts, for `motion_data`.
    pub(super) fn parts(&self) -> (&[RigNode], &[Channel], &[RigidPlacement], &[DeformedMesh]) {
        (&self.nodes, &self.channels, &self.rigid, &self.deformed)
    }

    /// Sets what follows the motion (as `motion_data` reads it).
    pub(super) fn set_parts(&mut self, rigid: Vec<RigidPlacement>, deformed: Vec<DeformedMesh>) {
        (self.rigid, self.deformed) = (rigid, deformed);
    }

    /// Checks that every placement and deformed mesh names one of `instances` and `meshes`, as
    /// [`apply`](Self::apply) needs, and takes each moving placement's mesh bounds from them
    /// (a motion read back from a bundle: `motion_data`).
    pub(super) fn attach(&mut self, meshes: &[Mesh], instances: &[Instance]) -> Result<(), String> {
        if let Some(r) = self.rigid.iter().find(|r| r.instance >= instances.len()) {
            return Err(format!("a moving placement names instance {} of {}", r.instance, instances.len()));
        }
        if let Some(d) = self.deformed.iter().find(|d| d.mesh >= meshes.len()) {
            return Err(format!("a deformed mesh is mesh {} of {}", d.mesh, meshes.len()));
        }
        let mut bounds: Vec<Option<Aabb>> = vec![None; meshes.len()];
        for r in &mut self.rigid {
            let mesh = instances[r.instance].mesh as usize;
            let known = bounds.get_mut(mesh).ok_or_else(|| format!("instance {} names mesh {mesh}", r.instance))?;
            r.bounds = *known.get_or_insert_with(|| meshes[mesh].bounds());
        }
        Ok(())
    }

    /// Whether node `n` is moved by a channel.
    fn moves(&self, n: usize) -> bool {
        self.nodes.get(n).is_some_and(|node| node.moved)
    }

    /// Whether a channel moves node `n` or one of its ancestors (a cycle of parents, which a
    /// decoded motion could hold, ends the walk).
    fn moves_above(&self, n: usize) -> bool {
        let mut at = Some(n);
        for _ in 0..=self.nodes.len() {
            match at.and_then(|i| self.nodes.get(i)) {
                Some(node) if node.moved => return true,
                Some(node) => at = node.parent,
                None => return false,
            }
        }
        false
    }

    /// Every node's world transform in `pose` (the identity for nodes no root reaches).
    fn world_matrices(&self, pose: &HashMap<usize, NodePose>) -> Vec<Mat4> {
        let mut world = vec![Mat4::IDENTITY; self.nodes.len()];
        for &n in &self.order {
            let node = &self.nodes[n];
            let local = match (node.matrix, pose.get(&n)) {
                (Some(m), _) => m,
                (None, Some(p)) => p.local(&node.rest),
                (None, None) => NodePose::default().local(&node.rest),
            };
            world[n] = node.parent.map_or(local, |p| world[p] * local);
        }
        world
    }

    /// Poses `scene` (the scene this motion was loaded with) at `time` seconds: the moving
    /// instances' transforms and the deformed meshes' triangles. On an error the scene is left
    /// as it was.
    pub(crate) fn apply(&self, scene: &mut Scene, time: f32) -> Result<(), SceneError> {
        if !time.is_finite() {
            return Err(malformed(format!("the animation time {time} is not a finite number of seconds")));
        }
        let pose = pose_at(&self.channels, time);
        let world = self.world_matrices(&pose);
        let mut drops = Vec::new();
        let transforms: Vec<Mat4> = self
            .rigid
            .iter()
            .map(|r| {
                let (m, why) = placeable(world[r.node] * r.local, r.bounds, &format!("node {}", r.node));
                drops.extend(why);
                m
            })
            .collect();
        let mut meshes = Vec::with_capacity(self.deformed.len());
        for d in &self.deformed {
            let (triangles, why) = d.posed(&pose, &world, |n| self.moves_above(n))?;
            meshes.push(triangles);
            drops.extend(why);
        }
        let mismatch = || malformed("the scene's instances no longer match its motion (was it changed?)".into());
        if self.rigid.iter().any(|r| r.instance >= scene.instances.len())
            || self.deformed.iter().any(|d| d.mesh >= scene.meshes.len())
        {
            return Err(mismatch());
        }
        for (r, transform) in self.rigid.iter().zip(transforms) {
            scene.instances[r.instance].transform = transform;
        }
        for (d, triangles) in self.deformed.iter().zip(meshes) {
            scene.meshes[d.mesh].triangles = triangles;
        }
        // One warning per placement or deformed mesh, at the first pose that drops it.
        for (what, why) in drops {
            let prefix = format!("{what}: at ");
            if !scene.warnings.iter().any(|w| w.starts_with(&prefix)) {
                scene.warnings.push(dropped(&what, why, time));
            }
        }
        Ok(())
    }
}

impl DeformedMesh {
    /// The mesh's world-space triangles in `pose` (every triangle kept, so that their number
    /// and order never change from one pose to the next).
    /// A transform that drops the mesh ([`placeable`]), or weights or joints (`moves`: whether
    /// a channel moves a node or an ancestor) that make a vertex non-finite, drop it
    /// ([`DeformedMesh::dropped`]), named with why; where nothing animates them, they are an
    /// error.
    fn posed(
        &self,
        pose: &HashMap<usize, NodePose>,
        world: &[Mat4],
        moves: impl Fn(usize) -> bool,
    ) -> Result<(Vec<Triangle>, Option<Dropped>), SceneError> {
        let animated = pose.get(&self.node).and_then(|p| p.weights.as_deref());
        let weights = animated.unwrap_or(&self.rest_weights);
        let morphed: Cow<[LocalPrimitive]> = match morph_all(&self.prims, weights) {
            Ok(None) => Cow::Borrowed(&self.prims),
            Ok(Some(morphed)) => Cow::Owned(morphed),
            Err(_) if animated.is_some() => return self.dropped(MORPH_NOT_FINITE),
            Err(bad) => return Err(malformed(format!("{}: {bad}", self.what))),
        };
        let mut dropped = None;
        let (prims, placed_by) = match &self.skin {
            Some(skin) => {
                let joints = skin.matrices(|j| Ok(world[j]))?;
                match skin_all(&morphed, &joints, &self.what)? {
                    Some(skinned) => (Cow::Owned(skinned), Mat4::IDENTITY),
                    None if skin.joints.iter().any(|&j| moves(j)) => return self.dropped(SKIN_NOT_FINITE),
                    None => return Err(skin.not_finite(&joints, &self.what)),
                }
            }
            None => {
                let (m, why) = placeable(world[self.node], primitives_bounds(&morphed), &self.what);
                dropped = why;
                (morphed, m)
            }
        };
        let mut triangles = Vec::new();
        place_primitives(self.mesh, &prims, &placed_by, &mut |_| true, &mut triangles)?;
        Ok((triangles, dropped))
    }

    /// The mesh dropped from a pose because its skin or morph weights `why`: its primitives
    /// at rest, a millionth of their size about the origin (as [`placeable`] shrinks a
    /// placement), so that it keeps its number of triangles (which posing over packed arrays,
    /// `pack::Posing`, relies on), each still a triangle (many zero-area ones at one place
    /// would make the bottom level's build quadratic), and no ray practically meets it.
    fn dropped(&self, why: &'static str) -> Result<(Vec<Triangle>, Option<Dropped>), SceneError> {
        let mut triangles = Vec::new();
        place_primitives(self.mesh, &self.prims, &shrunk(Vec3::ZERO), &mut |_| true, &mut triangles)?;
        Ok((triangles, Some((self.what.clone(), why))))
    }
}

/// A placement or deformed mesh a pose drops: what ("node 3", "node 3 mesh 1") and why
/// ([`SINGULAR`], [`NOT_FINITE`], [`BEYOND_WORLD`], `SKIN_NOT_FINITE`, `MORPH_NOT_FINITE`).
type Dropped = (String, &'static str);

/// Why a pose drops a placement ([`dropped`]).
pub(super) const SINGULAR: &str = "cannot be inverted (a scale of zero?)";
pub(super) const NOT_FINITE: &str = "is not finite";
pub(super) const BEYOND_WORLD: &str = "places it beyond 1e12 units of the origin";

/// Why a mesh whose own bounds are `bounds` cannot be placed by `m` ([`SINGULAR`],
/// [`NOT_FINITE`], [`BEYOND_WORLD`]), or `None` when it can: the one rule of every posing path
/// (an instance's [`Instance::has_valid_transform`], and its placed bounds within
/// [`WORLD_LIMIT`](crate::scene::WORLD_LIMIT), as `Scene::check_instances` holds them).
pub(super) fn unplaceable(m: Mat4, bounds: Aabb) -> Option<&'static str> {
    // Beyond the world before singular: a scale of 1e20 overflows the determinant.
    let placed = Instance { mesh: 0, transform: m };
    if !m.is_finite() {
        Some(NOT_FINITE)
    } else if !placed.world_bounds(bounds).in_world() {
        Some(BEYOND_WORLD)
    } else if !placed.has_valid_transform() {
        Some(SINGULAR)
    } else {
        None
    }
}

/// The bounds of `prims`' vertices (in their own space).
pub(super) fn primitives_bounds(prims: &[LocalPrimitive]) -> Aabb {
    let mut b = Aabb::EMPTY;
    for p in prims.iter().flat_map(|p| &p.positions) {
        b.extend(*p);
    }
    b
}

/// The warning for a placement (`what`: "node 3") or a skinned or morphed mesh ("node 3 mesh
/// 1") that the pose at `time` drops because its transform `why` ([`SINGULAR`],
/// [`NOT_FINITE`], `skin::SKIN_NOT_FINITE`, `morph::MORPH_NOT_FINITE`); `--strict` refuses it.
pub(super) fn dropped(what: &str, why: &str, time: f32) -> String {
    format!("{what}: at {time} s the animation gives it a transform that {why}: it is dropped where it does")
}

/// `m` as an instance may carry it, or, when it cannot be (a transform that cannot be inverted,
/// as a scale animated to zero gives; or one that is not finite, as a CUBICSPLINE's tangents
/// may give), the placement dropped from the image and what (`what`) and why: it becomes a
/// millionth of a unit's scale at its place (the origin, when that is not finite either), so
/// that rays can still be moved into the mesh's space, no ray practically meets it, and the
/// scene keeps its number of placements from pose to pose (which posing over packed arrays,
/// `pack::Posing`, relies on).
fn placeable(m: Mat4, bounds: Aabb, what: &str) -> (Mat4, Option<Dropped>) {
    let Some(why) = unplaceable(m, bounds) else { return (m, None) };
    let at = Some(m.w_axis.truncate()).filter(|t| crate::scene::in_world(*t)).unwrap_or(Vec3::ZERO);
    (shrunk(at), Some((what.to_owned(), why)))
}

/// A millionth of a unit's scale at `at`: where a pose puts what it drops.
fn shrunk(at: Vec3) -> Mat4 {
    Mat4::from_translation(at) * Mat4::from_scale(Vec3::splat(1e-6))
}

impl Loader<'_> {
    /// Warns once that `what` ("node 3", "node 3 mesh 1"), as posed at the load time, is
    /// dropped because its transform or vertices `why` ([`dropped`]).
    pub(super) fn warn_dropped(&mut self, what: String, why: &'static str) {
        let time = self.time;
        self.warnings.once(&format!("dropped {what}"), || dropped(&what, why, time));
    }

    /// Places node `n`'s mesh `mesh` (`prims`, as morphed by the load-time pose; `world` its
    /// node's world transform; `moving`: a channel moves the node or an ancestor) as a moving
    /// part of the kept motion, and returns true; false when the mesh is static (or no motion
    /// is kept) and the caller places it as before.
    pub(super) fn place_moving(
        &mut self,
        n: usize,
        node: &gltf::json::scene::Node,
        mesh: usize,
        prims: &Rc<Vec<LocalPrimitive>>,
        world: Mat4,
        moving: bool,
    ) -> Result<bool, SceneError> {
        let Some(motion) = &self.motion else { return Ok(false) };
        let deformed = node.skin.is_some() || motion.nodes.get(n).is_some_and(|node| node.morphed);
        if !deformed && !moving {
            return Ok(false);
        }
        let base = self.mesh(mesh)?;
        if base.iter().any(|p| self.materials.get(p.material as usize).is_some_and(Material::is_emissive)) {
            self.warnings.once("moving emitter", || {
                "an emissive mesh is moved by the animation: it stays where the load-time pose puts it (lights are static)"
                    .into()
            });
            return Ok(false);
        }
        self.mesh_instances += 1;
        match deformed {
            true => self.place_deformed(n, node, mesh, &base)?,
            false => self.place_rigid(n, node, mesh, &base, prims, world)?,
        }
        Ok(true)
    }

    /// Node `n`'s mesh `mesh` (primitives `base`, before morphing) as a mesh made again at each
    /// pose, placed by the identity (its triangles come with the first pose).
    fn place_deformed(
        &mut self,
        n: usize,
        node: &gltf::json::scene::Node,
        mesh: usize,
        base: &[LocalPrimitive],
    ) -> Result<(), SceneError> {
        let skin = node.skin.map(|s| self.skin_joints(s.value(), n)).transpose()?;
        let rest_weights = node
            .weights
            .clone()
            .or_else(|| self.root.meshes.get(mesh).and_then(|m| m.weights.clone()))
            .unwrap_or_default();
        let slot = self.instanced_meshes.len();
        self.instanced_meshes.push(Mesh::default());
        self.instances.push(Instance { mesh: slot as u32, transform: Mat4::IDENTITY });
        let what = format!("node {n} mesh {mesh}");
        let d = DeformedMesh { mesh: slot, node: n, gltf_mesh: mesh, prims: base.to_vec(), skin, rest_weights, what };
        self.motion.as_mut().expect("a kept motion").deformed.push(d);
        Ok(())
    }

    /// Node `n`'s mesh `mesh` (`prims`, as the load-time pose morphs it; `base` its shared
    /// primitives) stored in its own space, once per glTF mesh unless morphed per node, and
    /// placed by instances that follow the node (`world` at the load time).
    fn place_rigid(
        &mut self,
        n: usize,
        node: &gltf::json::scene::Node,
        mesh: usize,
        base: &Rc<Vec<LocalPrimitive>>,
        prims: &Rc<Vec<LocalPrimitive>>,
        world: Mat4,
    ) -> Result<(), SceneError> {
        let shared = Rc::ptr_eq(base, prims);
        let slot = match self.moving_meshes.get(&mesh).filter(|_| shared) {
            Some(&slot) => slot,
            None => {
                let mut triangles = Vec::new();
                let keep = &mut |p: &[Vec3; 3]| self.warnings.keep_triangle(p);
                place_primitives(mesh, prims, &Mat4::IDENTITY, keep, &mut triangles)?;
                if triangles.is_empty() {
                    return Ok(()); // nothing to render at any pose
                }
                self.instanced_meshes.push(Mesh { triangles });
                let slot = self.instanced_meshes.len() - 1;
                if shared {
                    self.moving_meshes.insert(mesh, slot);
                }
                slot
            }
        };
        let bounds = self.instanced_meshes[slot].bounds();
        let locals = match node.extensions.as_ref().and_then(|e| e.others.get("EXT_mesh_gpu_instancing")) {
            Some(instancing) => self.gpu_instances(instancing, n)?,
            None => vec![Mat4::IDENTITY],
        };
        for local in locals {
            // A placement this pose drops is warned about by `Motion::apply`, which poses it next.
            let (transform, _) = placeable(world * local, bounds, &format!("node {n}"));
            let instance = self.instances.len();
            self.instances.push(Instance { mesh: slot as u32, transform });
            let rigid = RigidPlacement { instance, node: n, local, bounds };
            self.motion.as_mut().expect("a kept motion").rigid.push(rigid);
        }
        Ok(())
    }

    /// Whether a channel of the kept motion moves node `n`.
    pub(super) fn channel_moves(&self, n: usize) -> bool {
        self.motion.as_ref().is_some_and(|m| m.moves(n))
    }
}

#[cfg(test)]
mod tests {
    /// The drop reasons that name the world's limit name `scene::WORLD_LIMIT` as it is.
    #[test]
    fn the_reasons_name_the_world_limit() {
        let limit = format!("{:e} units", crate::scene::WORLD_LIMIT);
        for why in [super::BEYOND_WORLD, super::SKIN_NOT_FINITE, super::MORPH_NOT_FINITE] {
            assert!(why.contains(&limit), "{why:?} does not say {limit:?}");
        }
    }
}
