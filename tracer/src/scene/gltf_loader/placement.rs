//! Where each node's mesh goes: flattened into the scene's static triangles, or kept once as a
//! [`Mesh`] that [`Instance`]s place (a two-level scene, `Features::instances`).
//!
//! The rule (`place_pending`): a mesh becomes instanced when it is placed at least twice
//! (nodes sharing it, or `EXT_mesh_gpu_instancing`) and instancing saves at least
//! [`MIN_TRIANGLES_SAVED`] triangles (placements − 1 times its triangles), unless it emits light
//! (lights are sampled from the static triangles) or is posed per node (skinned, or morphed by
//! non-zero weights: those copies differ). Everything else is flattened in node order, exactly
//! as before two levels existed, so that a scene without shared meshes keeps the one-level
//! kernel and its speed.

use super::nodes::LocalPrimitive;
use super::*;
use crate::scene::{Aabb, Instance, Mesh};

/// Least number of triangles instancing a mesh must save for it to be instanced: below it the
/// copies cost less memory than a second level costs time (`examples/bench_instancing.rs`).
pub(super) const MIN_TRIANGLES_SAVED: usize = 4096;

/// Most placements (node meshes and `EXT_mesh_gpu_instancing` instances) one scene may have.
pub(super) const MAX_PLACEMENTS: usize = 1 << 22;

/// A placement met while walking the nodes, decided once they are all known.
pub(super) struct Pending {
    mesh: usize,
    /// Its primitives are the mesh's shared decoded ones (not a node's skinned or morphed copy).
    shared: bool,
    prims: Rc<Vec<LocalPrimitive>>,
    world: Mat4,
}

impl Loader<'_> {
    /// Records that `prims`, glTF mesh `mesh`'s primitives (`shared`: its shared decoded ones,
    /// not a node's own posed copy), are placed by `world`.
    pub(super) fn defer(
        &mut self,
        mesh: usize,
        shared: bool,
        prims: Rc<Vec<LocalPrimitive>>,
        world: Mat4,
    ) -> Result<(), SceneError> {
        if self.pending.len() >= MAX_PLACEMENTS {
            return Err(SceneError::TooLarge(format!("more than {MAX_PLACEMENTS} mesh placements")));
        }
        self.pending.push(Pending { mesh, shared, prims, world });
        Ok(())
    }

    /// Applies the rule of this module to every recorded placement, in node order (`flatten`:
    /// instances none, `LoadOptions::flatten`).
    pub(super) fn place_pending(&mut self, flatten: bool) -> Result<(), SceneError> {
        let pending = std::mem::take(&mut self.pending);
        let mut placements: HashMap<usize, usize> = HashMap::new();
        for p in pending.iter().filter(|p| p.shared) {
            *placements.entry(p.mesh).or_default() += 1;
        }
        // glTF mesh -> its index in `self.instanced_meshes`, for meshes the rule instances.
        let mut mesh_slot: HashMap<usize, Option<u32>> = HashMap::new();
        // Slot -> its mesh's bounds (what a placement may not carry beyond the world).
        let mut slot_bounds: HashMap<u32, Aabb> = HashMap::new();
        for p in pending {
            let slot = match (p.shared && !flatten, mesh_slot.get(&p.mesh)) {
                (false, _) => None,
                (true, Some(&slot)) => slot,
                (true, None) => {
                    let slot = self.instanced_mesh(p.mesh, &p.prims, placements[&p.mesh])?;
                    mesh_slot.insert(p.mesh, slot);
                    slot
                }
            };
            match slot {
                Some(slot) => {
                    let instance = Instance { mesh: slot, transform: p.world };
                    let bounds =
                        *slot_bounds.entry(slot).or_insert_with(|| self.instanced_meshes[slot as usize].bounds());
                    if p.world.is_finite() && !instance.world_bounds(bounds).in_world() {
                        // As flattened geometry there is refused (`Scene::validate`).
                        return Err(malformed(format!(
                            "mesh {} is placed beyond {:e} units of the origin (where the renderer's arithmetic overflows)",
                            p.mesh,
                            crate::scene::WORLD_LIMIT
                        )));
                    }
                    if instance.has_valid_transform() {
                        self.instances.push(instance);
                    } else {
                        // A zero scale hides the mesh (flattening drops it too); a transform
                        // that cannot be inverted cannot move rays into the mesh's space.
                        self.warnings.once(&format!("singular placement {}", p.mesh), || {
                            format!(
                                "mesh {} is placed by a transform that cannot be inverted (a zero scale?): that placement is dropped",
                                p.mesh
                            )
                        });
                    }
                }
                None => self.place(p.mesh, &p.prims, &p.world)?,
            }
        }
        Ok(())
    }

    /// Whether glTF mesh `m` (primitives `prims`, placed `placements` times) is instanced by the
    /// rule, and then its slot in the scene's meshes (its triangles in mesh space).
    fn instanced_mesh(
        &mut self,
        m: usize,
        prims: &[LocalPrimitive],
        placements: usize,
    ) -> Result<Option<u32>, SceneError> {
        let triangles: usize = prims.iter().map(|p| p.triangles.len()).sum();
        let emits = prims.iter().any(|p| self.materials.get(p.material as usize).is_some_and(Material::is_emissive));
        if placements < 2 || emits || (placements - 1).saturating_mul(triangles) < MIN_TRIANGLES_SAVED {
            return Ok(None);
        }
        // The mesh's triangles in its own space: placed by the identity into a list of its own.
        let flattened = std::mem::take(&mut self.triangles);
        let placed = self.place(m, prims, &Mat4::IDENTITY);
        let mesh_triangles = std::mem::replace(&mut self.triangles, flattened);
        placed?;
        if mesh_triangles.is_empty() {
            return Ok(None);
        }
        self.instanced_meshes.push(Mesh { triangles: mesh_triangles });
        Ok(Some(self.instanced_meshes.len() as u32 - 1))
    }
}
