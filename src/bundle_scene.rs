//! A scene bundle (`lightport export` writes them: `bundles/<sha256>.lpb`) as a scene to render
//! or chart: its packed arrays as they are, and for a scene that moves, posed at `--time` from
//! its motion section (`tracer::pack::MovingScene::from_bundle`, as the page's `loadBundle`).
//!
//! A bundle is packed already, so the options that change what is loaded or packed cannot
//! apply: `--flatten`, `--sky` (and `--sky-intensity` / `--sky-rotation`, which adjust it),
//! and an `--animation` other than the one the bundle carries are refused by name. The
//! camera is the one the bundle was packed with: where the scene file has none, the one framed
//! around the pose it was exported at.

use std::io::Read;
use std::path::Path;

use anyhow::{bail, Context, Result};
use tracer::bundle::{Bundle, EXTENSION, MAGIC, MAX_BUNDLE_BYTES};
use tracer::pack::{MovingScene, Packed};

use crate::pose::PoseArgs;

/// Whether `path` names a bundle: its extension is `.lpb`, or the file begins with the
/// bundle's magic bytes.
pub fn is_bundle(path: &Path) -> bool {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case(EXTENSION)) {
        return true;
    }
    let mut head = [0u8; MAGIC.len()];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head)).is_ok() && head == MAGIC
}

/// A decoded bundle, posed.
pub struct BundleScene {
    /// The scene's name in the bundle (may be empty).
    pub name: String,
    /// The scene at `--time` (a static bundle's as it was packed).
    pub packed: Packed,
    /// A scene that moves: posed at `--time`, to pose it again (`render --frames`).
    pub moving: Option<MovingScene>,
}

impl BundleScene {
    /// What moves, in words; `None` for a static bundle.
    pub fn describe_motion(&self) -> Option<String> {
        self.moving.as_ref().and_then(|m| m.scene().motion.as_ref()).map(|m| m.describe())
    }
}

/// Reads, decodes and poses the bundle at `path` with `pose` (its `--time`; `--flatten` and
/// another `--animation` are refused). A placement the pose drops is warned about (an error
/// with `strict`).
pub fn load(path: &Path, pose: &PoseArgs, strict: bool) -> Result<BundleScene> {
    if pose.flatten {
        bail!("--flatten cannot apply to a bundle (it is packed already): export the scene with --flatten");
    }
    if !pose.time.is_finite() {
        bail!("--time must be a finite number of seconds");
    }
    let size = std::fs::metadata(path).with_context(|| format!("reading {}", path.display()))?.len();
    if size > MAX_BUNDLE_BYTES {
        bail!("{} is {size} bytes; a bundle has at most {MAX_BUNDLE_BYTES}", path.display());
    }
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let bundle = Bundle::decode(&bytes).with_context(|| format!("decoding the bundle {}", path.display()))?;
    drop(bytes);
    let carried = bundle.moving.as_ref().and_then(|m| m.motion.as_ref()).map(|m| m.name().to_owned());
    if let Some(asked) = &pose.animation {
        match &carried {
            Some(name) if name == asked => {}
            Some(name) => bail!(
                "--animation {asked}: the bundle carries one animation ({}), chosen when it was exported: export the scene with --animation {asked}",
                if name.is_empty() { "unnamed".to_owned() } else { format!("\"{name}\"") }
            ),
            None => bail!(
                "--animation {asked}: the bundle carries no animation (its scene does not move): export the scene with --animation {asked}"
            ),
        }
    }
    let Bundle { name, packed, moving } = bundle;
    let Some(parts) = moving else {
        // A static scene: every time is the same pose (as --time on a scene file that does not move).
        return Ok(BundleScene { name, packed, moving: None });
    };
    let mut moving = MovingScene::from_bundle(&packed, parts).context("posing the bundle's scene")?;
    let known = moving.scene().warnings.len();
    moving.pose(pose.time).with_context(|| format!("posing the bundle's scene at {} s", pose.time))?;
    crate::animate::report_pose_warnings(moving.scene(), known, strict)?;
    let packed = moving.pack().with_context(|| format!("packing the bundle's scene at {} s", pose.time))?;
    Ok(BundleScene { name, packed, moving: Some(moving) })
}

/// Refuses the sky options on a bundle, whose sky (or none) is packed in it.
pub fn refuse_sky(sky: bool, intensity: f32, rotation: f32) -> Result<()> {
    let named = [("--sky", sky), ("--sky-intensity", intensity != 1.0), ("--sky-rotation", rotation != 0.0)];
    if let Some((option, _)) = named.iter().find(|(_, given)| *given) {
        bail!(
            "{option} cannot apply to a bundle: its sky (or none) is packed in it; export the scene with --sky to give it one"
        );
    }
    Ok(())
}
