//! Writing rendered images. PNG is for display: exposure and a tone curve
//! ([`Display`], the kernel's `tonemap` module, which the shaders share), then the sRGB
//! encoding. EXR stays linear float, untouched, for comparisons and further processing.

use std::path::Path;

use glam::Vec3;

use crate::kernel::tonemap;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("unsupported output format {0:?}: use .png or .exr")]
    Format(String),
    /// The image crate's error is in the message, not a `source()` (see `SceneError::Io`).
    #[error("writing {path}: {error}")]
    Write { path: String, error: image::ImageError },
}

/// A tone curve from linear radiance to display values (the kernel's `tonemap` module).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToneMap {
    /// Clamp to [0, 1]: radiance above 1 clips to white.
    None,
    /// Khronos PBR Neutral: colours up to 0.76 unchanged, brighter ones rolled off to white.
    #[default]
    Neutral,
    /// The fitted ACES filmic curve (Stephen Hill's fit).
    Aces,
    /// AgX (Troy Sobotka), default look.
    Agx,
}

impl ToneMap {
    /// Every tone curve, in the order the page's control lists them.
    pub const ALL: [ToneMap; 4] = [ToneMap::Neutral, ToneMap::Aces, ToneMap::Agx, ToneMap::None];

    /// The curve's name on the command line (`--tonemap`) and in the page (`tonemap=`).
    pub fn name(self) -> &'static str {
        match self {
            ToneMap::None => "none",
            ToneMap::Neutral => "neutral",
            ToneMap::Aces => "aces",
            ToneMap::Agx => "agx",
        }
    }

    /// The curve called `name` (as [`name`](Self::name) spells it, any case).
    pub fn from_name(name: &str) -> Option<ToneMap> {
        ToneMap::ALL.into_iter().find(|t| t.name().eq_ignore_ascii_case(name))
    }

    /// The operator's id in the kernel (`tonemap::TONEMAP_*`).
    pub fn kernel_id(self) -> u32 {
        match self {
            ToneMap::None => tonemap::TONEMAP_NONE,
            ToneMap::Neutral => tonemap::TONEMAP_NEUTRAL,
            ToneMap::Aces => tonemap::TONEMAP_ACES,
            ToneMap::Agx => tonemap::TONEMAP_AGX,
        }
    }
}

/// How linear radiance becomes a displayed (PNG) pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Display {
    pub tone_map: ToneMap,
    /// Exposure in stops: radiance is scaled by `2^exposure` before the tone curve.
    pub exposure: f32,
}

impl Display {
    /// Radiance clamped to [0, 1] at exposure 0 (no curve): what Lightport wrote before tone
    /// mapping.
    pub const CLAMP: Display = Display { tone_map: ToneMap::None, exposure: 0.0 };

    /// sRGB-encoded display values in [0, 1] of linear radiance `c`.
    pub fn srgb(&self, c: glam::Vec3) -> glam::Vec3 {
        tonemap::display_srgb(c, self.tone_map.kernel_id(), self.exposure.exp2())
    }
}

/// The sRGB transfer function of a linear value, clamped to [0, 1] first (non-finite: 0).
pub fn linear_to_srgb(c: f32) -> f32 {
    tonemap::linear_to_srgb(tonemap::clamp_unit(tonemap::displayable(c)))
}

/// 8-bit sRGB pixels of `image` (RGB, row-major, top row first), clamped ([`Display::CLAMP`]).
pub fn to_srgb8(image: &Image) -> Vec<u8> {
    to_display_srgb8(image, &Display::CLAMP)
}

/// 8-bit sRGB pixels of `image` (RGB, row-major, top row first) through `display`.
pub fn to_display_srgb8(image: &Image, display: &Display) -> Vec<u8> {
    image.pixels.iter().flat_map(|p| display.srgb(*p).to_array()).map(|c| (c * 255.0 + 0.5) as u8).collect()
}

/// Writes `image` as PNG (through `display`) or EXR (linear, `display` unused), by extension.
pub fn write_image(path: &Path, image: &Image, display: &Display) -> Result<(), OutputError> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let err = |error| OutputError::Write { path: path.display().to_string(), error };
    match ext.as_str() {
        "png" => image::save_buffer(
            path,
            &to_display_srgb8(image, display),
            image.width,
            image.height,
            image::ColorType::Rgb8,
        )
        .map_err(err),
        "exr" => {
            let data: Vec<f32> = image.pixels.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
            let buffer = image::Rgb32FImage::from_raw(image.width, image.height, data)
                .expect("the pixel count matches the image size");
            buffer.save(path).map_err(err)
        }
        other => Err(OutputError::Format(other.to_string())),
    }
}

/// A linear-RGB image: the mean of the accumulated samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Image {
    pub fn mean(&self) -> Vec3 {
        let sum: glam::DVec3 = self.pixels.iter().map(|p| p.as_dvec3()).sum();
        (sum / self.pixels.len().max(1) as f64).as_vec3()
    }
}
