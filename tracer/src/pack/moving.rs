//! A scene that moves ([`Scene::motion`]), packed again at each pose: the first pose is packed
//! whole; a pose then rebuilds only what moves (the placed meshes that deform, the top level
//! over the placements) over the first pose's arrays ([`Posing`]). A renderer takes the result
//! with `Renderer::take_geometry`, without recompiling its kernel. A bundle's moving scene
//! ([`MovingScene::from_bundle`]) poses the same way from its packed arrays and moving parts.

use super::{pack_textures, pack_with_textures, static_bvh, BuildAndPackError, PackError, Packed, Posing};
use crate::kernel::RenderSettings;
use crate::scene::{Scene, SceneError};

/// Traversal stack entries a moving scene's kernel holds beyond what its first pose needs.
pub const STACK_HEADROOM: u32 = 4;

/// A scene that keeps its motion, with what packing it at any pose reuses.
pub struct MovingScene {
    /// The scene, or (from a bundle) its moving parts: meshes, instances and motion.
    scene: Scene,
    posing: Posing,
}

/// Why a pose could not be packed.
#[derive(Debug, thiserror::Error)]
pub enum PoseError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Pack(#[from] PackError),
}

impl MovingScene {
    /// `scene` (as loaded, posed at the load time) packed for a new renderer
    /// ([`pack_for_kernel`](Self::pack_for_kernel)), and what packs it again at other poses.
    pub fn new(scene: Scene, settings: &RenderSettings) -> Result<(Self, Packed), BuildAndPackError> {
        let (bvh, textures) = rayon::join(|| static_bvh(&scene), || pack_textures(&scene));
        let first = pack_with_textures(&scene, &bvh?, &textures, settings)?;
        let posing = Posing::new(&first, &scene)?;
        let moving = MovingScene { scene, posing };
        let packed = moving.pack_for_kernel()?;
        Ok((moving, packed))
    }

    /// A bundle's moving scene: `packed` (the bundle's scene, packed at some pose) and `parts`
    /// (its motion section's moving parts, `Bundle::moving`, at the same pose). A `parts` that
    /// does not match `packed` is [`PackError::NotThisPose`].
    pub fn from_bundle(packed: &Packed, parts: Scene) -> Result<Self, PackError> {
        let posing = Posing::new(packed, &parts)?;
        Ok(MovingScene { scene: parts, posing })
    }

    /// The scene as posed now, packed for creating a renderer: its kernel's traversal stack
    /// has [`STACK_HEADROOM`] entries more than this pose needs, since the top level rebuilt
    /// at each pose needs a little more or less (LittlestTokyo: 59 or 60 entries from pose to
    /// pose), and a pose needing more than the kernel's stack would recompile it.
    pub fn pack_for_kernel(&self) -> Result<Packed, PackError> {
        Ok(Self::for_kernel(self.pack()?))
    }

    /// `packed` (a pose [`pack`](Self::pack) gave) made ready for creating a renderer, as
    /// [`pack_for_kernel`](Self::pack_for_kernel) packs it: without packing the pose again.
    pub fn for_kernel(mut packed: Packed) -> Packed {
        let stack = &mut packed.features.traversal_stack;
        if *stack > 0 {
            *stack = (*stack + STACK_HEADROOM).min(crate::kernel::traverse::STACK_SIZE as u32);
        }
        packed
    }

    /// The scene (from a bundle: its moving parts), as posed now.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The animation's length in seconds (0 for a scene that does not move).
    pub fn duration(&self) -> f32 {
        self.scene.motion.as_ref().map_or(0.0, |m| m.duration())
    }

    /// Poses the scene at `time` seconds (`Scene::pose`); false for a scene that does not move.
    pub fn pose(&mut self, time: f32) -> Result<bool, SceneError> {
        self.scene.pose(time)
    }

    /// The scene as posed now, packed (for `Renderer::take_geometry`): the first pose's
    /// arrays with what moves made again ([`Posing::pack`]).
    pub fn pack(&self) -> Result<Packed, PackError> {
        self.posing.pack(&self.scene)
    }

    /// [`pose`](Self::pose) then [`pack`](Self::pack).
    pub fn packed_at(&mut self, time: f32) -> Result<Packed, PoseError> {
        self.pose(time)?;
        Ok(self.pack()?)
    }
}
