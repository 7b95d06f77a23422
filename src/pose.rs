//! How a scene file is posed and laid out when it is loaded: the options `render`, `chart`,
//! `serve` and `export` share (so an exported bundle or a chart shows the scene as `render`
//! would).

use anyhow::{bail, Result};
use tracer::scene::{AnimationChoice, LoadOptions, Scene};

#[derive(clap::Args, Clone, Debug, Default)]
pub struct PoseArgs {
    /// The glTF animation that poses the scene: its name or index, or `none` for the nodes'
    /// rest transforms (default: the first animation, as viewers play it).
    #[arg(long, value_name = "NAME|INDEX|none")]
    pub animation: Option<String>,
    /// The time, in seconds, at which the animation poses the scene (clamped to its keyframes).
    #[arg(long, default_value_t = 0.0, value_name = "SECONDS")]
    pub time: f32,
    /// Copy meshes that glTF nodes share into the scene once per placement (one BVH level)
    /// instead of storing them once and placing them by instances (a two-level BVH).
    #[arg(long)]
    pub flatten: bool,
}

impl PoseArgs {
    /// The loader's options for these arguments (`strict`: `LoadOptions::strict`).
    pub fn load_options(&self, strict: bool) -> Result<LoadOptions> {
        if !self.time.is_finite() {
            bail!("--time must be a finite number of seconds");
        }
        let animation = match self.animation.as_deref() {
            None => AnimationChoice::First,
            Some("none") => AnimationChoice::Rest,
            Some(name) => AnimationChoice::Named(name.to_owned()),
        };
        Ok(LoadOptions { strict, animation, time: self.time, flatten: self.flatten, keep_motion: false })
    }

    /// What `--flatten` asks of a scene generated in code (files are flattened as they load).
    pub fn apply_to_generated(&self, scene: &mut Scene) -> Result<()> {
        if self.flatten {
            scene.bake_instances()?;
        }
        Ok(())
    }

    /// The pose in words, for cache keys and read-outs (empty for the defaults).
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(a) = &self.animation {
            parts.push(format!("animation {a}"));
        }
        if self.time != 0.0 {
            parts.push(format!("time {}", self.time));
        }
        if self.flatten {
            parts.push("flattened".into());
        }
        parts.join(", ")
    }
}
