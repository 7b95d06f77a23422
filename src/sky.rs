//! The `--sky` option `render`, `chart`, `serve` and `export` share: an equirectangular file,
//! or `none`. Without it, a scene that nothing lights is lit by the default white sky
//! ([`tracer::scene::Scene::light_if_unlit`]), with a warning, as the page lights a dropped one.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use tracer::scene::Scene;

/// What `--sky` asked for.
#[derive(Clone, Debug, PartialEq)]
pub enum SkyArg {
    /// An equirectangular .hdr or .exr.
    File(PathBuf),
    /// No sky, even for a scene that nothing else lights (it renders black).
    None,
}

impl FromStr for SkyArg {
    type Err = std::convert::Infallible;

    /// `none` is the keyword (a file of that name is `./none`); anything else is a path.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(if s == "none" { SkyArg::None } else { SkyArg::File(PathBuf::from(s)) })
    }
}

impl SkyArg {
    /// The file, if one was given.
    pub fn file(sky: Option<&SkyArg>) -> Option<&Path> {
        match sky {
            Some(SkyArg::File(path)) => Some(path),
            _ => None,
        }
    }
}

/// Without `--sky`, lights `scene` with the default sky if nothing lights it, and adds the
/// warning that says so to its warnings; returns that warning if it did. With `--sky` (a file
/// already set, or `none`) it does nothing.
pub fn light_unless_told<'s>(scene: &'s mut Scene, sky: Option<&SkyArg>) -> Option<&'s str> {
    let warning = sky.is_none().then(|| scene.light_if_unlit()).flatten()?;
    scene.warnings.push(format!(
        "{warning}; give it a sky with `--sky FILE.hdr` (an equirectangular .hdr or .exr), or `--sky none` to keep it \
         unlit"
    ));
    scene.warnings.last().map(String::as_str)
}
