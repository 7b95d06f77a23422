//! Image decoding (PNG/JPEG for textures) with size limits, straight into the packed texel
//! layout: one `u32` per texel, 8-bit RGBA as stored in the file (colour sRGB-encoded, alpha
//! linear), red in the low byte. The kernel decodes sRGB to linear when it samples
//! (`kernel::scene_data::decode_srgba8`), so textures cost 4 bytes per texel from the decoder
//! to the GPU.

use std::io::Cursor;

use glam::Vec4;
use image::{ColorType, DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits};

use super::{SceneError, Texture, MAX_IMAGE_TEXELS, MAX_TEXTURE_DIMENSION};

/// Largest allocation an image decoder may make (bytes).
const MAX_DECODE_BYTES: u64 = 2 << 30;

/// A decoded texture image.
pub(crate) struct Image {
    pub width: u32,
    pub height: u32,
    /// Packed sRGBA8 texels (see the module docs), row 0 = top.
    pub texels: Vec<u32>,
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

/// Decodes a PNG or JPEG whose colour channels are sRGB-encoded into packed sRGBA8 texels.
/// Formats other than PNG and JPEG come back as [`Decoded::Unsupported`]; corrupt PNG/JPEG data
/// is an error, and so is an image with more than `max_texels` texels (checked from its header).
/// 16-bit images are rounded to 8 bits per channel (albedo and emission masks need no more).
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
    let max_texels = max_texels.min(MAX_IMAGE_TEXELS);
    let cannot = move |e: image::ImageError| err(format!("cannot decode {format:?}: {e}"));
    let image = catch_decoder_panic(|| -> Result<Image, SceneError> {
        let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
        reader.limits(limits());
        let decoder = reader.into_decoder().map_err(cannot)?;
        let (width, height) = decoder.dimensions();
        if width == 0 || height == 0 {
            return Err(err("image has no texels".into()));
        }
        check_texels(width, height, max_texels, name)?;
        let count = width as usize * height as usize;
        let channels = match decoder.color_type() {
            ColorType::L8 => 1,
            ColorType::La8 => 2,
            ColorType::Rgb8 => 3,
            ColorType::Rgba8 => 4,
            _ => {
                // Deeper formats (16-bit PNG) go through the image crate's conversion.
                let rgba = DynamicImage::from_decoder(decoder).map_err(cannot)?.into_rgba8();
                let texels = rgba.pixels().map(|p| u32::from_le_bytes(p.0)).collect();
                return Ok(Image { width, height, texels });
            }
        };
        // Decode into the texel buffer itself, then widen each texel to RGBA in place.
        let mut texels = vec![0u32; count];
        let bytes = words_as_bytes_mut(&mut texels);
        decoder.read_image(&mut bytes[..count * channels]).map_err(cannot)?;
        widen_to_rgba_in_place(bytes, channels);
        if cfg!(target_endian = "big") {
            texels.iter_mut().for_each(|t| *t = u32::from_le(*t));
        }
        Ok(Image { width, height, texels })
    })
    .unwrap_or_else(|| Err(err("the image decoder failed unexpectedly".into())))?;
    Ok(Decoded::Image(image))
}

fn check_texels(w: u32, h: u32, max_texels: u64, name: &str) -> Result<(), SceneError> {
    if u64::from(w) * u64::from(h) > max_texels {
        return Err(SceneError::TooLarge(format!(
            "image {name} is {w} x {h}: more texels than the {max_texels} allowed here"
        )));
    }
    Ok(())
}

/// The bytes of a texel buffer, to decode into.
fn words_as_bytes_mut(words: &mut [u32]) -> &mut [u8] {
    // SAFETY: u8 has no alignment requirement and no invalid bit patterns; the byte slice
    // covers exactly the words' memory and borrows them mutably for its lifetime.
    unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), std::mem::size_of_val(words)) }
}

/// `bytes` holds `bytes.len() / 4` texels of `channels` (1: L, 2: LA, 3: RGB, 4: RGBA) bytes
/// each, packed at its start; rewrites them as RGBA (grey replicated, alpha 255 when absent).
/// Runs from the last texel back, so no texel is overwritten before it is read: texel `i`
/// is read from `channels * i..` and written to `4 * i..`, at or after where it was.
fn widen_to_rgba_in_place(bytes: &mut [u8], channels: usize) {
    if channels == 4 {
        return;
    }
    let count = bytes.len() / 4;
    for i in (0..count).rev() {
        let at = channels * i;
        let rgba = match channels {
            1 => [bytes[at], bytes[at], bytes[at], 255],
            2 => [bytes[at], bytes[at], bytes[at], bytes[at + 1]],
            _ => [bytes[at], bytes[at + 1], bytes[at + 2], 255],
        };
        bytes[4 * i..4 * i + 4].copy_from_slice(&rgba);
    }
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
        check_texels(w, h, max_texels, name)?;
        DynamicImage::from_decoder(decoder).map_err(|e| err(format!("cannot decode {format:?}: {e}")))
    })
    .unwrap_or_else(|| Err(err("the image decoder failed unexpectedly".into())))
}

/// The sRGB transfer function's inverse: the kernel's own function (one definition).
pub use crate::kernel::scene_data::srgb_to_linear;

/// A packed sRGBA8 texel (red in the low byte) as linear RGBA, for code outside the kernel:
/// the kernel's `decode_srgba8`, so both decode identically.
pub fn srgba8_to_linear(texel: u32) -> Vec4 {
    crate::kernel::scene_data::decode_srgba8(texel)
}

impl Texture {
    /// Texel `index` (`y * width + x`) as linear RGBA.
    pub fn linear(&self, index: usize) -> Option<Vec4> {
        self.texels.get(index).map(|&t| srgba8_to_linear(t))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widening_in_place_gives_rgba_for_every_channel_count() {
        // Three texels per layout, packed at the start of a 12-byte buffer.
        let cases: [(usize, &[u8], [u8; 12]); 4] = [
            (1, &[10, 20, 30], [10, 10, 10, 255, 20, 20, 20, 255, 30, 30, 30, 255]),
            (2, &[10, 1, 20, 2, 30, 3], [10, 10, 10, 1, 20, 20, 20, 2, 30, 30, 30, 3]),
            (3, &[1, 2, 3, 4, 5, 6, 7, 8, 9], [1, 2, 3, 255, 4, 5, 6, 255, 7, 8, 9, 255]),
            (4, &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12], [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]),
        ];
        for (channels, packed, expected) in cases {
            let mut bytes = [0u8; 12];
            bytes[..packed.len()].copy_from_slice(packed);
            widen_to_rgba_in_place(&mut bytes, channels);
            assert_eq!(bytes, expected, "{channels} channels");
        }
    }

    fn png(image: DynamicImage) -> Vec<u8> {
        let mut out = Cursor::new(Vec::new());
        image.write_to(&mut out, ImageFormat::Png).unwrap();
        out.into_inner()
    }

    fn decode(bytes: &[u8]) -> Image {
        match decode_srgb(bytes, "test", u64::MAX).unwrap() {
            Decoded::Image(image) => image,
            Decoded::Unsupported(f) => panic!("unsupported {f}"),
        }
    }

    #[test]
    fn every_png_layout_decodes_to_packed_srgba8() {
        let rgba = image::RgbaImage::from_fn(3, 2, |x, y| image::Rgba([x as u8 * 80, y as u8 * 200, 7, 100 + x as u8]));
        let expected = |keep_alpha: bool, grey: bool| -> Vec<u32> {
            rgba.pixels()
                .map(|p| {
                    let [r, g, b, a] = p.0;
                    let (r, g, b) = if grey { (r, r, r) } else { (r, g, b) };
                    u32::from_le_bytes([r, g, b, if keep_alpha { a } else { 255 }])
                })
                .collect()
        };
        let rgb = DynamicImage::ImageRgba8(rgba.clone()).to_rgb8();
        assert_eq!(decode(&png(DynamicImage::ImageRgba8(rgba.clone()))).texels, expected(true, false));
        assert_eq!(decode(&png(DynamicImage::ImageRgb8(rgb))).texels, expected(false, false));
        // Grey images: the red channel as the grey level.
        let luma = image::GrayImage::from_fn(3, 2, |x, y| image::Luma([rgba.get_pixel(x, y).0[0]]));
        let luma_alpha = image::GrayAlphaImage::from_fn(3, 2, |x, y| {
            image::LumaA([rgba.get_pixel(x, y).0[0], rgba.get_pixel(x, y).0[3]])
        });
        assert_eq!(decode(&png(DynamicImage::ImageLuma8(luma))).texels, expected(false, true));
        assert_eq!(decode(&png(DynamicImage::ImageLumaA8(luma_alpha))).texels, expected(true, true));
        // 16 bits per channel: rounded to 8.
        let deep =
            image::ImageBuffer::<image::Rgba<u16>, _>::from_fn(1, 1, |_, _| image::Rgba([65535, 257 * 9, 0, 65535]));
        assert_eq!(decode(&png(DynamicImage::ImageRgba16(deep))).texels, vec![u32::from_le_bytes([255, 9, 0, 255])]);
    }

    #[test]
    fn linear_texels_decode_the_srgb_colour_and_keep_alpha_linear() {
        let v = srgba8_to_linear(u32::from_le_bytes([255, 0, 188, 51]));
        assert_eq!(v.x, 1.0);
        assert_eq!(v.y, 0.0);
        assert!((v.z - srgb_to_linear(188.0 / 255.0)).abs() < 1e-7 && (v.z - 0.5).abs() < 0.01, "{v}");
        assert_eq!(v.w, 0.2);
    }
}
