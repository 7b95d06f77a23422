//! Meshes placed by instances: the host side of two-level scenes (`Features::instances`).
//! A [`Mesh`] keeps its triangles in its own space, once; each [`Instance`] places it with an
//! affine transform. `tracer::pack` builds one bottom-level BVH per mesh and a top level over
//! the instances; the static triangles of [`Scene::triangles`] stay one bottom level of their
//! own, placed by the identity.

use glam::{Mat4, Vec3};

use super::{Aabb, Scene, Triangle};

/// A mesh that instances place: its triangles in the mesh's own space (normals and tangents
/// too), counter-clockwise seen from the front.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub triangles: Vec<Triangle>,
}

/// One placement of a [`Mesh`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
    /// Mesh space to world space: affine, finite and invertible ([`Instance::check`]).
    pub transform: Mat4,
}

/// Why an instance cannot be placed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InstanceError {
    #[error("instance {instance} names mesh {mesh} of {meshes}")]
    NoMesh { instance: usize, mesh: u32, meshes: usize },
    #[error("instance {instance}: its transform is not finite, not affine or not invertible")]
    BadTransform { instance: usize },
    #[error("instance {instance} places its mesh beyond {limit:e} units of the origin", limit = super::WORLD_LIMIT)]
    BeyondWorld { instance: usize },
    #[error("mesh {mesh} has no triangles")]
    EmptyMesh { mesh: u32 },
    #[error(
        "mesh {mesh} has an emissive material and is placed by instances: lights must be static triangles (bake the \
         instances into the scene with `Scene::bake_instances`)"
    )]
    EmissiveMesh { mesh: u32 },
}

impl Instance {
    /// Whether the transform is one [`Instance`] may carry: finite, affine (last row 0 0 0 1)
    /// and invertible with a finite inverse.
    pub fn has_valid_transform(&self) -> bool {
        let m = self.transform;
        let inverse = m.inverse();
        m.is_finite() && m.row(3) == glam::Vec4::W && m.determinant() != 0.0 && inverse.is_finite()
    }

    /// The world bounds of `mesh_bounds` placed by this instance (the box of its eight corners).
    pub fn world_bounds(&self, mesh_bounds: Aabb) -> Aabb {
        let mut b = Aabb::EMPTY;
        for i in 0..8 {
            let pick = |bit: usize, lo: f32, hi: f32| if i & bit == 0 { lo } else { hi };
            let corner = Vec3::new(
                pick(1, mesh_bounds.min.x, mesh_bounds.max.x),
                pick(2, mesh_bounds.min.y, mesh_bounds.max.y),
                pick(4, mesh_bounds.min.z, mesh_bounds.max.z),
            );
            b.extend(self.transform.transform_point3(corner));
        }
        b
    }
}

impl Mesh {
    /// Bounds of the mesh's triangles in its own space.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in &self.triangles {
            for p in t.positions {
                b.extend(p);
            }
        }
        b
    }
}

/// `t` placed by `m` (normals by its inverse transpose, tangents by its linear part; the winding
/// reversed for a mirroring transform, so that the front stays the front), as glTF nodes are
/// flattened.
pub fn place_triangle(t: &Triangle, m: &Mat4) -> Triangle {
    let linear = glam::Mat3::from_mat4(*m);
    let normal_matrix = linear.inverse().transpose();
    let mirror = linear.determinant() < 0.0;
    let mut out = *t;
    out.positions = t.positions.map(|p| m.transform_point3(p));
    out.normals = t.normals.map(|n| (normal_matrix * n).normalize_or_zero());
    out.tangents = t.tangents.map(|tg| match (linear * tg.truncate()).try_normalize() {
        Some(xyz) if tg != glam::Vec4::ZERO => xyz.extend(if mirror { -tg.w } else { tg.w }),
        _ => glam::Vec4::ZERO,
    });
    if mirror {
        out.positions.swap(1, 2);
        out.normals.swap(1, 2);
        out.uvs.swap(1, 2);
        out.uvs1.swap(1, 2);
        out.tangents.swap(1, 2);
    }
    out
}

impl Scene {
    /// Checks what `tracer::pack` relies on: every instance names a mesh with triangles and
    /// carries a valid transform, and no placed mesh emits light.
    pub fn check_instances(&self) -> Result<(), InstanceError> {
        let emissive = |t: &Triangle| self.materials.get(t.material as usize).is_some_and(|m| m.is_emissive());
        let mut placed = vec![false; self.meshes.len()];
        let bounds: Vec<Aabb> = self.meshes.iter().map(Mesh::bounds).collect();
        for (i, inst) in self.instances.iter().enumerate() {
            let mesh = self.meshes.get(inst.mesh as usize).ok_or(InstanceError::NoMesh {
                instance: i,
                mesh: inst.mesh,
                meshes: self.meshes.len(),
            })?;
            if !inst.has_valid_transform() {
                return Err(InstanceError::BadTransform { instance: i });
            }
            if !mesh.triangles.is_empty() && !inst.world_bounds(bounds[inst.mesh as usize]).in_world() {
                return Err(InstanceError::BeyondWorld { instance: i });
            }
            // Each placed mesh is checked once.
            if std::mem::replace(&mut placed[inst.mesh as usize], true) {
                continue;
            }
            if mesh.triangles.is_empty() {
                return Err(InstanceError::EmptyMesh { mesh: inst.mesh });
            }
            if mesh.triangles.iter().any(emissive) {
                return Err(InstanceError::EmissiveMesh { mesh: inst.mesh });
            }
        }
        Ok(())
    }

    /// Moves every placed mesh into [`Scene::triangles`] (one world-space copy per instance)
    /// and clears the instances: the flattened scene, which renders the same image. A scene
    /// that would place more than [`MAX_TRIANGLES`](super::MAX_TRIANGLES) triangles (the stress
    /// field places 102 million) is refused and left as it was.
    pub fn bake_instances(&mut self) -> Result<(), super::SceneError> {
        let placed = self.placed_triangle_count();
        if placed > super::MAX_TRIANGLES {
            return Err(super::SceneError::TooLarge(format!(
                "flattened, the scene would have {placed} triangles (at most {}): keep its instances",
                super::MAX_TRIANGLES
            )));
        }
        // A flattened scene no longer moves: its motion's instances are gone.
        self.motion = None;
        for inst in std::mem::take(&mut self.instances) {
            if let Some(mesh) = self.meshes.get(inst.mesh as usize) {
                self.triangles.extend(mesh.triangles.iter().map(|t| place_triangle(t, &inst.transform)));
            }
        }
        self.meshes.clear();
        Ok(())
    }

    /// Poses the scene at `time` seconds with its kept animation ([`Scene::motion`]): the
    /// moving instances' transforms and the deformed meshes' triangles change, nothing else.
    /// Returns whether anything can move (false, and nothing done, for a scene without motion).
    /// On an error (a non-finite time or pose) the scene is left as it was.
    pub fn pose(&mut self, time: f32) -> Result<bool, super::SceneError> {
        let Some(motion) = self.motion.take() else { return Ok(false) };
        let posed = motion.apply(self, time);
        self.motion = Some(motion);
        posed.map(|()| true)
    }

    /// Each instance's world bounds (its mesh's box placed by its transform), in instance order:
    /// what the top level is built over. An instance naming no mesh gets an empty box.
    pub fn placement_boxes(&self) -> Vec<Aabb> {
        let mesh_bounds: Vec<Aabb> = self.meshes.iter().map(Mesh::bounds).collect();
        self.instances
            .iter()
            .map(|i| mesh_bounds.get(i.mesh as usize).map_or(Aabb::EMPTY, |&b| i.world_bounds(b)))
            .collect()
    }

    /// Triangles the scene places in all: its static ones and every instance's.
    pub fn placed_triangle_count(&self) -> usize {
        self.triangles.len()
            + self
                .instances
                .iter()
                .filter_map(|i| self.meshes.get(i.mesh as usize))
                .map(|m| m.triangles.len())
                .sum::<usize>()
    }
}
