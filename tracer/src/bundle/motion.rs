//! The motion section: a scene that moves ([`Scene::motion`]) carries its kept animation and
//! the meshes and instances that posing it rewrites, as three entries, written only for such a
//! scene (a static scene's bundle has none of them, byte for byte as before):
//!
//! ```text
//! motion.name    u8 x 1 x len      the chosen animation's name (UTF-8, may be empty)
//! motion.ints    u32 x 1 x count   the integers of the moving parts, in the order of
//! motion.floats  f32 x 1 x count   `scene::motion_streams` (nodes, channels, placements,
//!                                  deformed meshes, meshes, instances), floats beside them
//! ```
//!
//! The three come together or not at all. Reading bounds every count by what the streams
//! still hold and every index by what it names (nodes, joints, vertices, meshes, instances),
//! checks keyframe times and component counts, and refuses a non-finite float, each as
//! [`BundleError::InvalidValue`] on `motion.ints`/`motion.floats`: a decoded motion poses
//! without a panic.

use kernel_dsl::Texels;

use super::fields::Field;
use super::format::{Reader, Writer};
use super::BundleError;
use crate::scene::{motion_streams, moving_from_streams, Scene};

const NAME: &str = "motion.name";
const INTS: &str = "motion.ints";
const FLOATS: &str = "motion.floats";

/// Writes `scene`'s motion section, when it keeps a motion.
pub(super) fn write(scene: &Scene, w: &mut Writer) {
    if let Some((name, ints, floats)) = motion_streams(scene) {
        super::short_name(&name).to_string().write(NAME, w);
        Texels::new(ints).write(INTS, w);
        Texels::new(floats).write(FLOATS, w);
    }
}

/// The moving parts, when the bundle has a motion section.
pub(super) fn read(r: &mut Reader) -> Result<Option<Scene>, BundleError> {
    let present = [NAME, INTS, FLOATS].map(|n| r.has(n));
    if present == [false; 3] {
        return Ok(None);
    }
    if let Some(missing) = [NAME, INTS, FLOATS].iter().zip(present).find(|(_, p)| !p) {
        return Err(BundleError::MissingField(missing.0.to_string()));
    }
    let name = String::read(NAME, r)?;
    let ints = Texels::<u32>::read(INTS, r)?;
    let floats = Texels::<f32>::read(FLOATS, r)?;
    moving_from_streams(&name, ints.as_slice(), floats.as_slice())
        .map(Some)
        .map_err(|reason| BundleError::InvalidValue { field: "motion".into(), reason })
}
