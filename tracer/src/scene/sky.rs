//! Equirectangular environment maps from Radiance `.hdr` and OpenEXR `.exr` files.

use std::path::Path;

use glam::Vec3;
use image::ImageFormat;

use super::texture::{catch_decoder_panic, decode_limited};
use super::util::read_file;
use super::{SceneError, Sky, SkyFile, MAX_IMAGE_TEXELS, MAX_RADIANCE};

/// Loads an equirectangular sky (see [`Sky`] for the mapping) from a `.hdr` or `.exr` file.
///
/// `intensity` (finite, >= 0) scales the radiance; `rotation` (radians, finite) turns the map
/// about +Y. Texels must be finite and, times `intensity`, at most [`MAX_RADIANCE`] (a NaN,
/// infinite or huge texel is an error naming it, not something silently clamped: it means a
/// broken file); negative values (which some EXR tools produce) are clamped to zero.
pub fn load_sky(path: &Path, intensity: f32, rotation: f32) -> Result<Sky, SceneError> {
    check_parameters(intensity, rotation)?;
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    let format = match ext.as_str() {
        "hdr" => SkyFormat::Hdr,
        "exr" => SkyFormat::Exr,
        _ => return Err(SceneError::UnsupportedFileType(ext)),
    };
    let bytes = read_file(path)?;
    load_sky_slice(&bytes, format, &path.display().to_string(), intensity, rotation)
}

/// The file formats a sky is read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SkyFormat {
    /// Radiance RGBE (`.hdr`).
    Hdr,
    /// OpenEXR (`.exr`).
    Exr,
}

fn check_parameters(intensity: f32, rotation: f32) -> Result<(), SceneError> {
    if !(intensity.is_finite() && intensity >= 0.0) {
        return Err(SceneError::InvalidParameter(format!("sky intensity must be finite and >= 0, got {intensity}")));
    }
    if !rotation.is_finite() {
        return Err(SceneError::InvalidParameter(format!("sky rotation must be finite, got {rotation}")));
    }
    Ok(())
}

/// The most texels a Radiance HDR file can describe per byte: its run-length scanlines spend 2
/// bytes per run of at most 127 texels in each of 4 channels (127 / 8 < 16). (The 1990s
/// "old-style" run length can do more; such files are refused when they exceed this.)
pub const MAX_HDR_TEXELS_PER_BYTE: u64 = 16;
/// The most texels an OpenEXR file can describe per byte: deflate (ZIP) expands at most 1032:1
/// and a texel holds at least one 16-bit sample; RLE (64:1), PIZ and B44 compress less.
pub const MAX_EXR_TEXELS_PER_BYTE: u64 = 516;

/// Refuses a sky whose header declares more texels than its bytes can encode (the decoders
/// allocate the declared image before they find the data missing: a 100-byte HDR could cost
/// 1.5 GiB and seconds; found by fuzzing). Only the header is parsed here.
fn check_backed(bytes: &[u8], format: ImageFormat, name: &str) -> Result<(), SceneError> {
    let per_byte = if format == ImageFormat::OpenExr { MAX_EXR_TEXELS_PER_BYTE } else { MAX_HDR_TEXELS_PER_BYTE };
    let dimensions =
        catch_decoder_panic(|| image::ImageReader::with_format(std::io::Cursor::new(bytes), format).into_dimensions());
    let most = per_byte * bytes.len() as u64;
    // A tiled EXR's decoder allocates whole tiles: a tile's size is bounded the same way (a
    // 727-byte 8 x 4 EXR declared 16776000 x 64 tiles, 1.9 GiB; found by fuzzing).
    if format == ImageFormat::OpenExr {
        if let Some((tw, th)) = exr_tile_sizes(bytes).find(|&(tw, th)| tw * th > most) {
            return Err(SceneError::Image {
                name: name.to_owned(),
                message: format!(
                    "the header declares tiles of {tw} x {th} texels, more than its {} bytes can encode",
                    bytes.len()
                ),
            });
        }
    }
    // A header that does not parse is reported by the decoder itself.
    let Some(Ok((w, h))) = dimensions else { return Ok(()) };
    let declared = u64::from(w) * u64::from(h);
    if declared > most {
        return Err(SceneError::Image {
            name: name.to_owned(),
            message: format!(
                "the header declares {w} x {h} texels, more than its {} bytes can encode ({per_byte} per byte at most \
                 in {format:?})",
                bytes.len()
            ),
        });
    }
    Ok(())
}

/// The tile sizes of every `tiles` attribute (`tiledesc`: size 9, x size, y size, mode) in an
/// EXR's headers, found by their name and type.
fn exr_tile_sizes(bytes: &[u8]) -> impl Iterator<Item = (u64, u64)> + '_ {
    const ATTRIBUTE: &[u8] = b"tiles\0tiledesc\0";
    bytes.windows(ATTRIBUTE.len()).enumerate().filter(|(_, w)| *w == ATTRIBUTE).filter_map(|(at, _)| {
        let u32_at = |i: usize| bytes.get(i..i + 4).map(|b| u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])));
        let data = at + ATTRIBUTE.len() + 4;
        Some((u32_at(data)?, u32_at(data + 4)?))
    })
}

/// [`load_sky`] from bytes in memory; `name` names the image in errors.
pub fn load_sky_slice(
    bytes: &[u8],
    format: SkyFormat,
    name: &str,
    intensity: f32,
    rotation: f32,
) -> Result<Sky, SceneError> {
    check_parameters(intensity, rotation)?;
    let image_format = match format {
        SkyFormat::Hdr => ImageFormat::Hdr,
        SkyFormat::Exr => ImageFormat::OpenExr,
    };
    let err = |message: String| SceneError::Image { name: name.to_owned(), message };
    check_backed(bytes, image_format, name)?;
    let img = decode_limited(bytes, image_format, MAX_IMAGE_TEXELS, name)?;
    let (width, height) = (img.width(), img.height());
    if width == 0 || height == 0 {
        return Err(err("image has no texels".into()));
    }
    let rgb = img.into_rgb32f();
    let mut texels = Vec::with_capacity(width as usize * height as usize);
    for (i, p) in rgb.pixels().enumerate() {
        let v = Vec3::new(p[0], p[1], p[2]);
        let w = width as usize;
        let (x, y) = (i % w.max(1), i / w.max(1));
        if !v.is_finite() {
            return Err(err(format!("texel ({x}, {y}) is not finite")));
        }
        if v.max_element() > MAX_RADIANCE {
            return Err(err(format!(
                "texel ({x}, {y}) is {}, above the largest radiance Lightport accepts ({MAX_RADIANCE:e})",
                v.max_element()
            )));
        }
        if v.max_element() * intensity > MAX_RADIANCE {
            return Err(SceneError::InvalidParameter(format!(
                "sky intensity {intensity} times texel ({x}, {y}) ({}) is above the largest radiance Lightport \
                 accepts ({MAX_RADIANCE:e})",
                v.max_element()
            )));
        }
        texels.push(v.max(Vec3::ZERO));
    }
    let file = Some(SkyFile { format, bytes: bytes.into() });
    Ok(Sky { width, height, texels, intensity, rotation, file })
}
