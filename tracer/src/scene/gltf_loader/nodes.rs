//! The node hierarchy: transforms, cameras, lights and meshes, and each mesh primitive's
//! triangles, normals, texture coordinates and tangents (decoded once per mesh, instanced per node).

use super::morph::MorphTarget;
use super::*;

/// One primitive's triangles in mesh space, decoded once per mesh and instanced per node.
#[derive(Clone)]
pub(super) struct LocalPrimitive {
    pub(super) positions: Vec<Vec3>,
    pub(super) normals: Option<Vec<Vec3>>,
    pub(super) uvs: Option<Vec<Vec2>>,
    /// `TEXCOORD_1`, read only when the primitive's material samples a texture on it.
    pub(super) uvs1: Option<Vec<Vec2>>,
    pub(super) triangles: Vec<[u32; 3]>,
    /// Per corner of `triangles`: the file's `TANGENT`s, else MikkTSpace's; only for a
    /// material with a normal map.
    pub(super) tangents: Option<Vec<[Vec4; 3]>>,
    pub(super) material: u32,
    /// `JOINTS_0` and `WEIGHTS_0`, per vertex, when the primitive has both (`skin.rs`).
    pub(super) skin: Option<VertexSkin>,
    /// Morph targets (`morph.rs`), in the file's order.
    pub(super) morph: Vec<MorphTarget>,
}

/// Per vertex: up to four joints (indices into the skin's joint list) and their weights.
#[derive(Clone)]
pub(super) struct VertexSkin {
    pub(super) joints: Vec<[u32; 4]>,
    pub(super) weights: Vec<Vec4>,
}

impl Loader<'_> {
    /// Walks the node hierarchy depth-first (pre-order, children in file order).
    pub(super) fn visit(&mut self, roots: &[usize]) -> Result<(), SceneError> {
        let root = self.root;
        let mut visited = vec![false; root.nodes.len()];
        // Each node with its parent's world transform and whether a channel moves an ancestor.
        let mut stack: Vec<(usize, Mat4, bool)> = roots.iter().rev().map(|&n| (n, Mat4::IDENTITY, false)).collect();
        while let Some((n, parent, parent_moves)) = stack.pop() {
            let node = root.nodes.get(n).ok_or_else(|| malformed(format!("node {n} does not exist")))?;
            let seen = visited.get_mut(n).ok_or_else(|| malformed(format!("node {n} does not exist")))?;
            if *seen {
                return Err(malformed(format!(
                    "node {n} is reached twice: the node hierarchy must be a tree (no cycles, no shared children)"
                )));
            }
            *seen = true;
            let world = parent * self.posed_local(node, n)?;
            // Without a kept motion, "moving": posed by a channel at the load time (here or above).
            let posed = self.motion.is_none() && self.pose.contains_key(&n);
            let moving = parent_moves || self.channel_moves(n) || posed;
            // A pose that drops a placement: warned about once, as `Motion::apply` does (which
            // warns for a kept motion, whose moving parts `place_moving` drops); without a kept
            // motion a non-finite one drops the node and everything below (warned about where
            // that holds a mesh, a camera or a light: a bare joint's drop is its skinned mesh's,
            // `instantiate_skinned`).
            let finite = world.is_finite();
            let why = if moving && self.motion.is_none() { self.posed_drop(node, &world)? } else { None };
            // A dropped node's mesh is left out (carried beyond the world or made singular, its
            // children may still come back).
            let drop_mesh = why.is_some();
            if let Some(why) = why {
                if self.places_something(n) {
                    self.warn_dropped(format!("node {n}"), why);
                }
                if !finite {
                    continue;
                }
            }
            if !finite && !moving {
                return Err(malformed(format!("node {n} has a non-finite world transform")));
            }
            // (A moving, non-finite node of a kept motion: its lights and camera are skipped,
            // its mesh dropped by `place_moving`.)
            let extensions = node.extensions.as_ref().filter(|_| finite);
            if let Some(ext) = extensions {
                warn_extensions(&mut self.warnings, Some(&ext.others));
                if let Some(l) = &ext.khr_lights_punctual {
                    self.light(l.light.value(), n, &world, moving)?;
                }
            }
            if let Some(c) = node.camera.filter(|_| finite) {
                self.camera(c.value(), n, &world, moving)?;
            }
            if let Some(m) = node.mesh.filter(|_| !drop_mesh) {
                self.place_mesh(n, node, m.value(), world, moving)?;
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world, moving));
            }
        }
        Ok(())
    }

    /// Places node `n`'s mesh `mesh` (world transform `world`; `moving`: a channel moves it or
    /// an ancestor): as a moving part of the kept motion, skinned, once per
    /// `EXT_mesh_gpu_instancing` instance, or once; a mesh its pose's morph weights cannot make
    /// finite is left out with a warning.
    fn place_mesh(
        &mut self,
        n: usize,
        node: &gltf::json::scene::Node,
        mesh: usize,
        world: Mat4,
        moving: bool,
    ) -> Result<(), SceneError> {
        // `None`: the pose's morph weights cannot make the mesh finite (a kept motion
        // morphs it again at each pose, and drops it there: `Motion::apply`).
        let morphed = self.morphed(mesh, node, n)?;
        let prims = match &morphed {
            Some(prims) => prims.clone(),
            None => self.mesh(mesh)?,
        };
        // Morphed copies differ per node: only the shared primitives may be instanced.
        let shared = self.meshes.get(&mesh).is_some_and(|m| Rc::ptr_eq(m, &prims));
        if self.place_moving(n, node, mesh, &prims, world, moving)? {
            // a moving part of the kept motion (`motion.rs`)
        } else if morphed.is_none() {
            self.mesh_instances += 1;
            self.warn_dropped(format!("node {n} mesh {mesh}"), super::morph::MORPH_NOT_FINITE);
        } else if let Some(skin) = node.skin {
            self.mesh_instances += 1;
            self.instantiate_skinned(mesh, &prims, skin.value(), n)?;
        } else if let Some(instancing) = node.extensions.as_ref().and_then(|e| e.others.get("EXT_mesh_gpu_instancing"))
        {
            for instance in self.gpu_instances(instancing, n)? {
                self.mesh_instances += 1;
                self.defer(mesh, shared, prims.clone(), world * instance)?;
            }
        } else {
            self.mesh_instances += 1;
            self.defer(mesh, shared, prims, world)?;
        }
        Ok(())
    }

    /// Why the pose at the load time drops a moving node (`world` its transform there), without
    /// a kept motion: not finite (it and everything below), or its mesh unplaceable
    /// (`motion::unplaceable`). A skinned mesh is placed by its joints, not its node's
    /// transform, so only a non-finite one drops its node.
    fn posed_drop(&mut self, node: &gltf::json::scene::Node, world: &Mat4) -> Result<Option<&'static str>, SceneError> {
        if !world.is_finite() {
            return Ok(Some(super::motion::NOT_FINITE));
        }
        match node.mesh.filter(|_| node.skin.is_none()) {
            Some(m) => {
                let bounds = super::motion::primitives_bounds(&self.mesh(m.value())?);
                Ok(super::motion::unplaceable(*world, bounds))
            }
            None => Ok(None),
        }
    }

    /// Whether node `n` or a node below it holds a mesh, a camera or a light.
    fn places_something(&self, n: usize) -> bool {
        let nodes = &self.root.nodes;
        let mut seen = vec![false; nodes.len()];
        let mut stack = vec![n];
        while let Some(i) = stack.pop() {
            let Some(node) = nodes.get(i) else { continue };
            if std::mem::replace(&mut seen[i], true) {
                continue; // a cycle: refused where the walk reaches it
            }
            let light = node.extensions.as_ref().is_some_and(|e| e.khr_lights_punctual.is_some());
            if node.mesh.is_some() || node.camera.is_some() || light {
                return true;
            }
            stack.extend(node.children.iter().flatten().map(|c| c.value()));
        }
        false
    }

    /// The instance transforms of node `node`'s `EXT_mesh_gpu_instancing`: per instance
    /// T * R * S from its `TRANSLATION`, `ROTATION` (a quaternion, normalised) and `SCALE`
    /// accessors (each optional, all of one count), applied under the node's own transform.
    /// Instances are placed as nodes are (`placement.rs`).
    pub(super) fn gpu_instances(&mut self, instancing: &Value, node: usize) -> Result<Vec<Mat4>, SceneError> {
        let what = format!("node {node} EXT_mesh_gpu_instancing");
        let attributes = instancing
            .get("attributes")
            .and_then(Value::as_object)
            .ok_or_else(|| malformed(format!("{what}: no \"attributes\" object")))?;
        let mut read = |name: &str, components: usize| -> Result<Option<Vec<f32>>, SceneError> {
            let Some(index) = attributes.get(name) else { return Ok(None) };
            let index = index
                .as_u64()
                .and_then(|i| usize::try_from(i).ok())
                .ok_or_else(|| malformed(format!("{what}: {name} is not an accessor index")))?;
            if index >= self.root.accessors.len() {
                return Err(malformed(format!("{what}: {name} uses accessor {index}, which does not exist")));
            }
            self.buffers.read_f32(index, components, &format!("{what} {name}")).map(Some)
        };
        let translation = read("TRANSLATION", 3)?;
        let rotation = read("ROTATION", 4)?;
        let scale = read("SCALE", 3)?;
        let counts: Vec<usize> = [(&translation, 3), (&rotation, 4), (&scale, 3)]
            .iter()
            .filter_map(|(values, n)| values.as_ref().map(|v| v.len() / n))
            .collect();
        let Some(&count) = counts.first() else {
            return Err(malformed(format!("{what}: none of TRANSLATION, ROTATION and SCALE")));
        };
        if counts.iter().any(|&c| c != count) {
            return Err(malformed(format!("{what}: the attributes' counts differ ({counts:?})")));
        }
        if count > MAX_TRIANGLES {
            return Err(SceneError::TooLarge(format!("{what}: {count} instances (at most {MAX_TRIANGLES})")));
        }
        (0..count)
            .map(|i| {
                let t = translation.as_ref().map_or(Vec3::ZERO, |v| Vec3::from_slice(&v[3 * i..]));
                let s = scale.as_ref().map_or(Vec3::ONE, |v| Vec3::from_slice(&v[3 * i..]));
                let q = rotation.as_ref().map_or(Quat::IDENTITY, |v| Quat::from_slice(&v[4 * i..]));
                let length = q.length();
                if length == 0.0 || !length.is_finite() {
                    return Err(malformed(format!("{what}: instance {i}'s ROTATION is not a rotation ({q})")));
                }
                Ok(Mat4::from_scale_rotation_translation(s, q.normalize(), t))
            })
            .collect()
    }

    /// Takes camera `index` at node `node` (world transform `world`) as the scene's, unless one
    /// was taken: the first perspective camera in the walk. One that the pose carries (`moving`)
    /// beyond [`CAMERA_LIMIT`](crate::scene::CAMERA_LIMIT) is ignored with a warning: the next
    /// camera of the walk is taken, else the scene framed (a static one there is refused with
    /// the scene).
    fn camera(&mut self, index: usize, node: usize, world: &Mat4, moving: bool) -> Result<(), SceneError> {
        if self.camera.is_some() {
            return Ok(());
        }
        let cam = self.root.cameras.get(index).ok_or_else(|| malformed(format!("camera {index} does not exist")))?;
        let perspective = match (cam.type_, &cam.perspective) {
            (Checked::Valid(CameraType::Perspective), Some(p)) => p,
            _ => {
                self.saw_orthographic = true;
                return Ok(());
            }
        };
        let yfov = perspective.yfov;
        if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(malformed(format!("camera {index}: yfov {yfov} is not in (0, π)")));
        }
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
        if forward == Vec3::ZERO || up == Vec3::ZERO {
            self.warnings
                .once("degenerate camera", || "a camera node has a degenerate transform: it is ignored".into());
            return Ok(());
        }
        let position = world.transform_point3(Vec3::ZERO);
        if moving && position.abs().max_element() > crate::scene::CAMERA_LIMIT {
            let outcome = "it is ignored (the file's next camera, else a framing of the scene, is used instead)";
            self.warn_carried_beyond(format!("node {node}'s camera"), crate::scene::CAMERA_LIMIT, outcome);
            return Ok(());
        }
        self.camera = Some(FoundCamera { position, forward, up, yfov });
        Ok(())
    }

    /// Adds `KHR_lights_punctual` light `index` at node `node` (world transform `world`) as a
    /// point light. One that the pose carries (`moving`) beyond the world is left out with a
    /// warning, as a mesh placement there is (lights stay where the load-time pose puts them;
    /// a static one there is refused with the scene).
    fn light(&mut self, index: usize, node: usize, world: &Mat4, moving: bool) -> Result<(), SceneError> {
        let light = self
            .root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .and_then(|l| l.lights.get(index))
            .ok_or_else(|| {
                malformed(format!("node {node} uses KHR_lights_punctual light {index}, which does not exist"))
            })?;
        let intensity = Vec3::from(light.color) * light.intensity;
        if !intensity.is_finite()
            || intensity.min_element() < 0.0
            || intensity.max_element() > super::super::MAX_RADIANCE
        {
            return Err(malformed(format!(
                "KHR_lights_punctual light {index}: color x intensity must be finite, >= 0 and at most {:e}",
                super::super::MAX_RADIANCE
            )));
        }
        match light.type_ {
            Checked::Valid(LightType::Point) => {}
            Checked::Valid(LightType::Spot) => self.warnings.once("spot lights", || {
                "KHR_lights_punctual spot lights are treated as point lights (their cone is ignored)".into()
            }),
            Checked::Valid(LightType::Directional) => {
                self.warnings.once("directional lights", || {
                    "KHR_lights_punctual directional lights are not supported: they are ignored".into()
                });
                return Ok(());
            }
            Checked::Invalid => {
                return Err(malformed(format!("KHR_lights_punctual light {index} has an invalid type")))
            }
        }
        let position = world.transform_point3(Vec3::ZERO);
        if moving && !crate::scene::in_world(position) {
            let outcome = "it is left out (lights stay where the load-time pose puts them)";
            self.warn_carried_beyond(format!("node {node}'s light {index}"), crate::scene::WORLD_LIMIT, outcome);
            return Ok(());
        }
        self.point_lights.push(PointLight { position, intensity });
        Ok(())
    }

    /// Warns once that the load-time pose carries `what` (a light, a camera) beyond `limit`
    /// units of the origin, and what becomes of it (`outcome`).
    fn warn_carried_beyond(&mut self, what: String, limit: f32, outcome: &str) {
        let time = self.time;
        self.warnings.once(&format!("{what} beyond the world"), || {
            format!("{what}: the pose at {time} s places it beyond {limit:e} units of the origin: {outcome}")
        });
    }

    /// Appends `prims` (mesh `mesh`'s primitives, or their skinned copies) under `world`,
    /// dropping zero-area triangles.
    pub(super) fn place(&mut self, mesh: usize, prims: &[LocalPrimitive], world: &Mat4) -> Result<(), SceneError> {
        let warnings = &mut self.warnings;
        place_primitives(mesh, prims, world, &mut |p| warnings.keep_triangle(p), &mut self.triangles)
    }

    /// A node's local transform in the load-time pose: its own, or with the animated
    /// components in place (a node given by a matrix keeps it: channels cannot move it).
    pub(super) fn posed_local(&self, node: &gltf::json::scene::Node, n: usize) -> Result<Mat4, SceneError> {
        match self.pose.get(&n) {
            Some(animated) if node.matrix.is_none() => Ok(animated.matrix(node)),
            _ => node_matrix(node, n),
        }
    }

    /// Decodes a mesh's primitives (once per mesh).
    pub(super) fn mesh(&mut self, index: usize) -> Result<Rc<Vec<LocalPrimitive>>, SceneError> {
        if let Some(m) = self.meshes.get(&index) {
            return Ok(m.clone());
        }
        let mesh = self.root.meshes.get(index).ok_or_else(|| malformed(format!("mesh {index} does not exist")))?;
        warn_extensions(&mut self.warnings, mesh.extensions.as_ref().map(|e| &e.others));
        let mut prims = Vec::with_capacity(mesh.primitives.len());
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(local) = self.primitive(index, p, prim)? {
                prims.push(local);
            }
        }
        let prims = Rc::new(prims);
        self.meshes.insert(index, prims.clone());
        Ok(prims)
    }

    fn primitive(
        &mut self,
        m: usize,
        p: usize,
        prim: &gltf::json::mesh::Primitive,
    ) -> Result<Option<LocalPrimitive>, SceneError> {
        let what = format!("mesh {m} primitive {p}");
        let mode = match prim.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => return Err(malformed(format!("{what}: invalid mode"))),
        };
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.warnings.once("non-triangle primitive modes", || {
                format!("primitive mode {mode:?} is not supported: only triangles (lists, strips, fans) are rendered; such primitives are skipped")
            });
            return Ok(None);
        }
        let ext = prim.extensions.as_ref().map(|e| &e.others);
        warn_extensions(&mut self.warnings, ext);
        let meshopt =
            ext.is_some_and(|e| e.contains_key("EXT_meshopt_compression") || e.contains_key("KHR_meshopt_compression"));
        let Attributes { position, normal, uv, uv1, tangent, joints, weights } = self.attributes(prim);
        let Some(position) = position else {
            self.warnings.once("no POSITION", || "primitives without POSITION are skipped".into());
            return Ok(None);
        };
        // Draco: the decoded stream replaces the accessors' data (`draco.rs`).
        let data = self.primitive_data(prim, mode, &what)?;
        if meshopt
            && !data.is_draco()
            && self.root.accessors.get(position).is_some_and(|a| a.buffer_view.is_none() && a.sparse.is_none())
        {
            // Compressed data only, no uncompressed fallback to read.
            return Ok(None);
        }
        let positions = to_vec3(self.vertex_f32(&data, position, 3, &format!("{what} POSITION"))?);
        let vertex_count = positions.len();
        let normals = match normal {
            Some(a) => {
                let n = to_vec3(self.vertex_f32(&data, a, 3, &format!("{what} NORMAL"))?);
                if n.len() != vertex_count {
                    return Err(malformed(format!("{what}: NORMAL has {} elements, POSITION {vertex_count}", n.len())));
                }
                Some(n)
            }
            None => None,
        };
        let uvs = self.texcoords(&data, uv, 0, vertex_count, &what)?;
        let indices = match self.primitive_indices(&data, prim, &what)? {
            Some(indices) => {
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
                    return Err(malformed(format!("{what}: index {bad} is out of range ({vertex_count} vertices)")));
                }
                indices
            }
            None => (0..vertex_count as u32).collect(),
        };
        let triangles = assemble(mode, &indices)
            .ok_or_else(|| malformed(format!("{what}: {} indices do not form whole triangles", indices.len())))?;
        let mut material = self.material(prim.material.map(|i| i.value()))?;
        let uses_set1 = self.materials.get(material as usize).is_some_and(texture_ref::uses_texcoord1);
        let uvs1 = match (uses_set1, uv1) {
            (true, Some(a)) => self.texcoords(&data, Some(a), 1, vertex_count, &what)?,
            (true, None) => {
                material = self.material_without_texcoord1(material, &what);
                None
            }
            (false, _) => None,
        };
        let normal_mapped = self.materials.get(material as usize).is_some_and(|m| m.normal_texture.is_some());
        // MikkTSpace follows the UV set the normal map is read on.
        let normal_set = self.materials.get(material as usize).map_or(0, |m| m.texture_uvs[3].texcoord);
        let map_uvs = if normal_set == 1 { &uvs1 } else { &uvs };
        let tangents =
            self.tangents(&data, normal_mapped, tangent, map_uvs, &positions, normals.as_deref(), &triangles, &what)?;
        let skin = match (joints, weights) {
            (Some(j), Some(w)) => self.vertex_skin(&data, j, w, vertex_count, &what)?,
            _ => None,
        };
        let morph = self.morph_targets(prim, vertex_count, &what)?;
        Ok(Some(LocalPrimitive { positions, normals, uvs, uvs1, triangles, tangents, material, skin, morph }))
    }

    /// The accessors of the attributes a primitive is rendered with (set 0, and TEXCOORD_1);
    /// vertex colours are warned about once.
    fn attributes(&mut self, prim: &gltf::json::mesh::Primitive) -> Attributes {
        let mut a = Attributes::default();
        for (semantic, accessor) in &prim.attributes {
            match semantic {
                Checked::Valid(Semantic::Positions) => a.position = Some(accessor.value()),
                Checked::Valid(Semantic::Normals) => a.normal = Some(accessor.value()),
                Checked::Valid(Semantic::Tangents) => a.tangent = Some(accessor.value()),
                Checked::Valid(Semantic::TexCoords(0)) => a.uv = Some(accessor.value()),
                Checked::Valid(Semantic::TexCoords(1)) => a.uv1 = Some(accessor.value()),
                Checked::Valid(Semantic::Joints(0)) => a.joints = Some(accessor.value()),
                Checked::Valid(Semantic::Weights(0)) => a.weights = Some(accessor.value()),
                Checked::Valid(Semantic::Colors(0)) => self
                    .warnings
                    .once("COLOR_0", || "vertex colours (COLOR_0) are not supported: they are ignored".into()),
                _ => {}
            }
        }
        a
    }

    /// Per-triangle tangents for a normal-mapped primitive: the file's TANGENT, else MikkTSpace
    /// over the UV set the normal map is read on (none without one, with a warning).
    #[allow(clippy::too_many_arguments)]
    fn tangents(
        &mut self,
        data: &PrimitiveData,
        normal_mapped: bool,
        tangent: Option<usize>,
        map_uvs: &Option<Vec<Vec2>>,
        positions: &[Vec3],
        normals: Option<&[Vec3]>,
        triangles: &[[u32; 3]],
        what: &str,
    ) -> Result<Option<Vec<[Vec4; 3]>>, SceneError> {
        let vertex_count = positions.len();
        Ok(match (normal_mapped, tangent, map_uvs) {
            (false, _, _) => None,
            (true, Some(a), _) => {
                let t = self.vertex_f32(data, a, 4, &format!("{what} TANGENT"))?;
                if t.len() != vertex_count * 4 {
                    return Err(malformed(format!(
                        "{what}: TANGENT has {} elements, POSITION {vertex_count}",
                        t.len() / 4
                    )));
                }
                let t: Vec<Vec4> =
                    t.chunks_exact(4).map(|c| super::super::tangents::unit_tangent(Vec4::from_slice(c))).collect();
                Some(triangles.iter().map(|tri| tri.map(|i| t[i as usize])).collect())
            }
            (true, None, Some(uvs)) => super::super::tangents::mikktspace_tangents(positions, normals, uvs, triangles),
            (true, None, None) => {
                self.warnings.once("normal map without TEXCOORD_0", || {
                    format!("{what}: a normal-mapped primitive has no TEXCOORD_0, so no tangents: its normal map is ignored")
                });
                None
            }
        })
    }
}

/// The accessors of a primitive's attributes ([`Loader::attributes`]).
#[derive(Default)]
struct Attributes {
    position: Option<usize>,
    normal: Option<usize>,
    uv: Option<usize>,
    uv1: Option<usize>,
    tangent: Option<usize>,
    joints: Option<usize>,
    weights: Option<usize>,
}

pub(super) fn semantic_name(s: &Checked<Semantic>) -> String {
    match s {
        Checked::Valid(Semantic::Positions) => "POSITION".into(),
        Checked::Valid(Semantic::Normals) => "NORMAL".into(),
        Checked::Valid(Semantic::Tangents) => "TANGENT".into(),
        Checked::Valid(Semantic::TexCoords(n)) => format!("TEXCOORD_{n}"),
        Checked::Valid(Semantic::Colors(n)) => format!("COLOR_{n}"),
        Checked::Valid(Semantic::Joints(n)) => format!("JOINTS_{n}"),
        Checked::Valid(Semantic::Weights(n)) => format!("WEIGHTS_{n}"),
        Checked::Valid(other) => format!("{other:?}"),
        Checked::Invalid => "(invalid)".into(),
    }
}

/// Appends `prims` (mesh `mesh`'s primitives) under `world` to `out`, keeping the triangles
/// `keep` accepts (by their world positions). A transform that cannot be inverted (a zero
/// scale) hides the mesh: nothing is appended.
pub(super) fn place_primitives(
    mesh: usize,
    prims: &[LocalPrimitive],
    world: &Mat4,
    keep: &mut dyn FnMut(&[Vec3; 3]) -> bool,
    out: &mut Vec<Triangle>,
) -> Result<(), SceneError> {
    let linear = Mat3::from_mat4(*world);
    let det = linear.determinant();
    if det == 0.0 {
        return Ok(()); // a zero scale hides the mesh: nothing to render
    }
    let normal_matrix = linear.inverse().transpose();
    let flip = det < 0.0;
    let added: usize = prims.iter().map(|p| p.triangles.len()).sum();
    if out.len().saturating_add(added) > MAX_TRIANGLES {
        return Err(SceneError::TooLarge(format!(
            "the scene has more than {MAX_TRIANGLES} triangles after instancing"
        )));
    }
    out.reserve(added);
    for prim in prims.iter() {
        for (t, tri) in prim.triangles.iter().enumerate() {
            let mut idx = *tri;
            if flip {
                idx.swap(1, 2);
            }
            let fetch = |i: u32| prim.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
            let positions = idx.map(|i| world.transform_point3(fetch(i)));
            if !positions.iter().all(|p| p.is_finite()) {
                return Err(malformed(format!("mesh {mesh}: a vertex is not finite after its node transform")));
            }
            if !keep(&positions) {
                continue;
            }
            let flat = flat_normal(&positions);
            let normals = match &prim.normals {
                Some(ns) => idx.map(|i| {
                    let n = ns.get(i as usize).copied().unwrap_or(Vec3::ZERO);
                    let n = (normal_matrix * n).normalize_or_zero();
                    if n == Vec3::ZERO {
                        flat
                    } else {
                        n
                    }
                }),
                None => [flat; 3],
            };
            let corner_uvs = |set: &Option<Vec<Vec2>>| match set {
                Some(uv) => idx.map(|i| uv.get(i as usize).copied().unwrap_or(Vec2::ZERO)),
                None => [Vec2::ZERO; 3],
            };
            let (uvs, uvs1) = (corner_uvs(&prim.uvs), corner_uvs(&prim.uvs1));
            let mut tangents = match &prim.tangents {
                Some(ts) => ts.get(t).map_or([Vec4::ZERO; 3], |c| c.map(|c| world_tangent(&linear, c, flip))),
                None => [Vec4::ZERO; 3],
            };
            if flip {
                tangents.swap(1, 2);
            }
            out.push(Triangle { positions, normals, uvs, uvs1, tangents, material: prim.material });
        }
    }
    Ok(())
}

/// A mesh-space tangent (xyz unit, w ±1) in world space under `linear`: tangents are carried
/// like positions (not like normals), and a mirroring transform flips their handedness.
fn world_tangent(linear: &Mat3, t: Vec4, flip: bool) -> Vec4 {
    match (*linear * t.truncate()).try_normalize() {
        Some(xyz) => xyz.extend(if flip { -t.w } else { t.w }),
        None => Vec4::ZERO,
    }
}

/// A node's local transform (matrix, or TRS with the rotation normalised).
pub(super) fn node_matrix(node: &gltf::json::scene::Node, n: usize) -> Result<Mat4, SceneError> {
    if let Some(m) = node.matrix {
        let m = Mat4::from_cols_array(&m);
        if !m.is_finite() {
            return Err(malformed(format!("node {n}: matrix is not finite")));
        }
        return Ok(m);
    }
    let t = Vec3::from(node.translation.unwrap_or([0.0; 3]));
    let s = Vec3::from(node.scale.unwrap_or([1.0; 3]));
    let q = node.rotation.map_or(Quat::IDENTITY, |r| Quat::from_array(r.0));
    if !(t.is_finite() && s.is_finite() && q.is_finite()) {
        return Err(malformed(format!("node {n}: transform is not finite")));
    }
    let len = q.length();
    let q = if len > 0.0 { q / len } else { Quat::IDENTITY };
    Ok(Mat4::from_scale_rotation_translation(s, q, t))
}

/// Triangles from an index list in one of the triangle modes; `None` when a TRIANGLES list is
/// not a multiple of three.
fn assemble(mode: Mode, idx: &[u32]) -> Option<Vec<[u32; 3]>> {
    match mode {
        Mode::Triangles => {
            if !idx.len().is_multiple_of(3) {
                return None;
            }
            Some(idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
        }
        Mode::TriangleStrip => Some(
            idx.windows(3)
                .enumerate()
                .map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[0], w[2], w[1]] })
                // Strips join with repeated indices; those triangles have no area.
                .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
                .collect(),
        ),
        Mode::TriangleFan => {
            let Some(&first) = idx.first() else {
                return Some(Vec::new());
            };
            Some(idx.get(1..).unwrap_or(&[]).windows(2).map(|w| [w[0], w[1], first]).collect())
        }
        _ => Some(Vec::new()),
    }
}

pub(super) fn to_vec3(v: Vec<f32>) -> Vec<Vec3> {
    v.chunks_exact(3).map(Vec3::from_slice).collect()
}

pub(super) fn to_vec2(v: Vec<f32>) -> Vec<Vec2> {
    v.chunks_exact(2).map(Vec2::from_slice).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans() {
        assert_eq!(assemble(Mode::TriangleStrip, &[0, 1, 2, 3]).unwrap(), vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(assemble(Mode::TriangleFan, &[0, 1, 2, 3]).unwrap(), vec![[1, 2, 0], [2, 3, 0]]);
        assert!(assemble(Mode::Triangles, &[0, 1]).is_none());
        assert_eq!(assemble(Mode::TriangleFan, &[]).map(|v| v.len()), Some(0));
    }
}
