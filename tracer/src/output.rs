//! Writing rendered images. PNG is tone-mapped for display: linear radiance is clamped to
//! [0, 1] (no exposure change, no curve) and encoded with the sRGB transfer function. EXR
//! stays linear float, for comparisons and further processing.

use std::path::Path;

use crate::backend::Image;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("unsupported output format {0:?}: use .png or .exr")]
    Format(String),
    #[error("writing {path}: {source}")]
    Write { path: String, source: image::ImageError },
}

pub fn linear_to_srgb(c: f32) -> f32 {
    let c = if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 };
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// 8-bit sRGB pixels of `image` (RGB, row-major, top row first).
pub fn to_srgb8(image: &Image) -> Vec<u8> {
    image.pixels.iter().flat_map(|p| [p.x, p.y, p.z]).map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8).collect()
}

pub fn write_image(path: &Path, image: &Image) -> Result<(), OutputError> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let err = |source| OutputError::Write { path: path.display().to_string(), source };
    match ext.as_str() {
        "png" => {
            image::save_buffer(path, &to_srgb8(image), image.width, image.height, image::ColorType::Rgb8).map_err(err)
        }
        "exr" => {
            let data: Vec<f32> = image.pixels.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
            let buffer = image::Rgb32FImage::from_raw(image.width, image.height, data)
                .expect("the pixel count matches the image size");
            buffer.save(path).map_err(err)
        }
        other => Err(OutputError::Format(other.to_string())),
    }
}
