//! Image decoding (PNG/JPEG for textures) with size limits, and sRGB -> linear conversion.

use std::io::Cursor;

use glam::Vec4;
use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits};

use super::{SceneError, MAX_IMAGE_TEXELS, MAX_TEXTURE_DIMENSION};

/// Largest allocation an image decoder may make (bytes).
const MAX_DECODE_BYTES: u64 = 2 << 30;

/// A decoded texture image.
pub(crate) struct Image {
    pub width: u32,
    pub height: u32,
    /// Linear RGBA, row 0 = top.
    pub texels: Vec<Vec4>,
}

/// What decoding an embedded image gave.
pub(crate) enum Decoded {
    Image(Image),
    /// A recognised image format Lightport does not decode (named), e.g. WebP or KTX2.
    Unsupported(String),
}

/// Decoder limits used for every image.
pub(crate) fn limits() -> Limits {
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_DIMENSION);
    limits.max_image_height = Some(MAX_TEXTURE_DIMENSION);
    limits.max_alloc = Some(MAX_DECODE_BYTES);
    limits
}

/// Decodes a PNG or JPEG whose colour channels are sRGB-encoded, returning linear texels.
/// Formats other than PNG and JPEG come back as [`Decoded::Unsupported`]; corrupt PNG/JPEG data
/// is an error, and so is an image with more than `max_texels` texels (checked from its header).
pub(crate) fn decode_srgb(bytes: &[u8], name: &str, max_texels: u64) -> Result<Decoded, SceneError> {
    let err = |message: String| SceneError::Image { name: name.to_owned(), message };
    if bytes.is_empty() {
        return Err(err("empty image data".into()));
    }
    let format = if bytes.starts_with(b"\xABKTX 20\xBB") {
        return Ok(Decoded::Unsupported("KTX2 (KHR_texture_basisu)".into()));
    } else {
        match image::guess_format(bytes) {
            Ok(f @ (ImageFormat::Png | ImageFormat::Jpeg)) => f,
            Ok(other) => return Ok(Decoded::Unsupported(format!("{other:?}"))),
            Err(_) => return Err(err("not a PNG or JPEG image".into())),
        }
    };
    let img = decode_limited(bytes, format, max_texels.min(MAX_IMAGE_TEXELS), name)?;
    let (width, height) = (img.width(), img.height());
    if width == 0 || height == 0 {
        return Err(err("image has no texels".into()));
    }
    Ok(Decoded::Image(Image { width, height, texels: srgb_to_linear_texels(img) }))
}

/// Decodes with [`limits`], refusing images with more than `max_texels` texels before their
/// pixels are decoded.
pub(crate) fn decode_limited(
    bytes: &[u8],
    format: ImageFormat,
    max_texels: u64,
    name: &str,
) -> Result<DynamicImage, SceneError> {
    let err = |message: String| SceneError::Image { name: name.to_owned(), message };
    catch_decoder_panic(|| {
        let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
        reader.limits(limits());
        let decoder = reader.into_decoder().map_err(|e| err(format!("cannot decode {format:?}: {e}")))?;
        let (w, h) = decoder.dimensions();
        if u64::from(w) * u64::from(h) > max_texels {
            return Err(SceneError::TooLarge(format!(
                "image {name} is {w} x {h}: more texels than the {max_texels} allowed here"
            )));
        }
        DynamicImage::from_decoder(decoder).map_err(|e| err(format!("cannot decode {format:?}: {e}")))
    })
    .unwrap_or_else(|| Err(err("the image decoder failed unexpectedly".into())))
}

/// Converts any decoded image to linear RGBA, treating its colour channels as sRGB-encoded.
fn srgb_to_linear_texels(img: DynamicImage) -> Vec<Vec4> {
    let high_precision = !matches!(
        img,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_)
    );
    if high_precision {
        img.into_rgba32f()
            .pixels()
            .map(|p| Vec4::new(srgb_to_linear(p[0]), srgb_to_linear(p[1]), srgb_to_linear(p[2]), p[3]))
            .collect()
    } else {
        let lut: Vec<f32> = (0..=255u8).map(|v| srgb_to_linear(f32::from(v) / 255.0)).collect();
        let at = |v: u8| lut.get(usize::from(v)).copied().unwrap_or(0.0);
        img.into_rgba8().pixels().map(|p| Vec4::new(at(p[0]), at(p[1]), at(p[2]), f32::from(p[3]) / 255.0)).collect()
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Runs a third-party decoder, turning a panic inside it into `None`.
///
/// Decoders are fuzzed upstream, but a panic on a hostile file must not take the renderer down:
/// this is defence in depth around code Lightport does not own. (The panic message still goes
/// to the panic hook.)
pub(crate) fn catch_decoder_panic<T>(f: impl FnOnce() -> T) -> Option<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).ok()
}
