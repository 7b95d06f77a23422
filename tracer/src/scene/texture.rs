//! Image decoding (PNG, JPEG and WebP for textures) with size limits, straight into the packed texel
//! layout: one `u32` per texel, 8-bit RGBA as stored in the file (colour sRGB-encoded, alpha
//! linear), red in the low byte. The kernel decodes sRGB to linear when it samples
//! (`kernel::textures::decode_srgba8`), so textures cost 4 bytes per texel from the decoder
//! to the GPU.
//!
//! Loaders probe each image when a material first uses it (format, size and the texel budget
//! are checked then, from the header) and decode all of a scene's textures at the end, in
//! parallel, into one atlas in the kernel's `texture_texels` layout ([`TextureTexels`]), which
//! packing then shares instead of copying.

use std::io::Cursor;
use std::ops::Deref;
use std::sync::{Arc, OnceLock};

use glam::{UVec4, Vec3, Vec4};
use image::{ColorType, DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits};
use kernel_dsl::Texels;
use rayon::prelude::*;

use super::{Material, SceneError, Texture, Wrap, MAX_IMAGE_TEXELS, MAX_TEXTURE_DIMENSION};
use crate::kernel::scene_data::TEXTURE_TEXELS_PER_ELEMENT;

/// Largest allocation an image decoder may make (bytes).
const MAX_DECODE_BYTES: u64 = 2 << 30;

/// Texels per atlas element (`UVec4`).
const PER_ELEMENT: usize = TEXTURE_TEXELS_PER_ELEMENT as usize;

/// A texture's texels ([`Texture::texels`]): `width * height` packed sRGBA8 texels, one `u32`
/// each, dereferencing to `[u32]` (immutable; cloning shares them).
///
/// They lie in an atlas in the kernel's `texture_texels` layout: four texels per `UVec4`
/// element, starting on an element boundary, the lanes after the last texel zero. Loaders
/// decode all of a scene's textures into one atlas, in scene order, which is exactly the
/// packed layout, so `pack::pack_textures` shares it instead of copying it. A texture made
/// from a `Vec` has an atlas of its own (and is copied when packed).
#[derive(Clone)]
pub struct TextureTexels {
    atlas: Texels<UVec4>,
    /// First element of the texture in `atlas`.
    first: usize,
    /// Number of texels.
    len: usize,
    /// [`TextureTexels::mean_luminance`], once computed (loaders compute it while decoding
    /// emissive textures). Shared by clones: the texels cannot change.
    mean_luminance: Arc<OnceLock<f32>>,
    /// The image file these texels were decoded from, when they were ([`TextureTexels::source`]).
    source: Option<EncodedImage>,
}

/// An image file's bytes (PNG, JPEG or WebP) as the scene shipped them, shared by every texture
/// decoded from it. Bundles carry textures this way: a JPEG is a tenth of its texels or less.
pub type EncodedImage = Arc<[u8]>;

impl TextureTexels {
    /// The atlas holding these texels, from element [`TextureTexels::first_element`] on.
    pub fn atlas(&self) -> &Texels<UVec4> {
        &self.atlas
    }

    /// Index of the atlas element holding the first texel.
    pub fn first_element(&self) -> usize {
        self.first
    }

    /// The image file these texels are the decoding of ([`ImageHeader::decode_into`]), when
    /// they were loaded from one; `None` for texels made in code.
    pub fn source(&self) -> Option<&EncodedImage> {
        self.source.as_ref()
    }

    /// Mean linear luminance (sRGB decoded, alpha ignored), the estimate of an emissive
    /// texture's power used for light selection. Computed once.
    pub fn mean_luminance(&self) -> f32 {
        *self.mean_luminance.get_or_init(|| mean_luminance(self))
    }
}

impl Deref for TextureTexels {
    type Target = [u32];

    fn deref(&self) -> &[u32] {
        let words: &[u32] = bytemuck::cast_slice(self.atlas.as_slice());
        words.get(self.first * PER_ELEMENT..).and_then(|w| w.get(..self.len)).unwrap_or(&[])
    }
}

impl From<Vec<u32>> for TextureTexels {
    fn from(texels: Vec<u32>) -> Self {
        let atlas = Texels::from_fn(texels.len().div_ceil(PER_ELEMENT), |e| {
            let mut lanes = [0u32; PER_ELEMENT];
            let four = texels.get(e * PER_ELEMENT..).unwrap_or(&[]);
            let four = &four[..four.len().min(PER_ELEMENT)];
            lanes[..four.len()].copy_from_slice(four);
            UVec4::from_array(lanes)
        });
        TextureTexels { atlas, first: 0, len: texels.len(), mean_luminance: Arc::default(), source: None }
    }
}

impl FromIterator<u32> for TextureTexels {
    fn from_iter<I: IntoIterator<Item = u32>>(iter: I) -> Self {
        iter.into_iter().collect::<Vec<u32>>().into()
    }
}

impl PartialEq for TextureTexels {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for TextureTexels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// Mean linear luminance of packed sRGBA8 texels (alpha ignored), summed in texel order.
fn mean_luminance(texels: &[u32]) -> f32 {
    let srgb_lut: [f32; 256] = std::array::from_fn(|v| srgb_to_linear(v as f32 / 255.0));
    let sum = texels.iter().fold(Vec3::ZERO, |sum, &texel| {
        let [r, g, b, _] = texel.to_le_bytes();
        sum + Vec3::new(srgb_lut[r as usize], srgb_lut[g as usize], srgb_lut[b as usize])
    });
    crate::kernel::lights::luminance(sum / texels.len().max(1) as f32)
}

/// An image whose header was read ([`probe_srgb`]), to be decoded later.
pub(crate) struct ImageHeader {
    pub width: u32,
    pub height: u32,
    format: ImageFormat,
    name: String,
}

/// What probing an image gave.
pub(crate) enum Probed {
    Image(ImageHeader),
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

/// Reads the header of a PNG, JPEG or WebP whose colour channels are sRGB-encoded, for
/// [`ImageHeader::decode_into`]. Other formats come back as
/// [`Probed::Unsupported`]; a corrupt header is an error, and so is an image with more than
/// `max_texels` texels.
pub(crate) fn probe_srgb(bytes: &[u8], name: &str, max_texels: u64) -> Result<Probed, SceneError> {
    let err = |message: String| SceneError::Image { name: name.to_owned(), message };
    if bytes.is_empty() {
        return Err(err("empty image data".into()));
    }
    let format = if bytes.starts_with(b"\xABKTX 20\xBB") {
        return Ok(Probed::Unsupported("KTX2 (KHR_texture_basisu)".into()));
    } else {
        match image::guess_format(bytes) {
            Ok(f @ (ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::WebP)) => f,
            Ok(other) => return Ok(Probed::Unsupported(format!("{other:?}"))),
            Err(_) => return Err(err("not a PNG, JPEG or WebP image".into())),
        }
    };
    let max_texels = max_texels.min(MAX_IMAGE_TEXELS);
    let (width, height) = catch_decoder_panic(|| -> Result<(u32, u32), SceneError> {
        let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
        reader.limits(limits());
        let decoder = reader.into_decoder().map_err(|e| err(format!("cannot decode {format:?}: {e}")))?;
        Ok(decoder.dimensions())
    })
    .unwrap_or_else(|| Err(err("the image decoder failed unexpectedly".into())))?;
    if width == 0 || height == 0 {
        return Err(err("image has no texels".into()));
    }
    check_texels(width, height, max_texels, name)?;
    check_backed(bytes, format, width, height).map_err(err)?;
    Ok(Probed::Image(ImageHeader { width, height, format, name: name.to_owned() }))
}

/// The most a deflate stream can expand (a 258-byte match in 2 bits: 1032 to 1).
const DEFLATE_MAX_RATIO: u64 = 1032;

/// Refuses an image whose file is too short for the size its header declares, before its
/// texels are allocated (a 100-byte PNG saying 8192 x 8192 would otherwise cost 256 MiB). The
/// bounds are what the formats can possibly compress to: a PNG's filtered rows (a filter byte
/// plus the row's pixel bits) deflated at most [`DEFLATE_MAX_RATIO`] to 1; a Huffman-coded JPEG
/// spends at least one bit per 8 x 8 block of its full-resolution component (the DC code).
fn check_backed(bytes: &[u8], format: ImageFormat, width: u32, height: u32) -> Result<(), String> {
    let (w, h) = (u64::from(width), u64::from(height));
    let needed = match format {
        ImageFormat::Png => {
            // IHDR follows the 8-byte signature and its chunk's length and type.
            let (depth, colour) = (bytes.get(24).copied().unwrap_or(1), bytes.get(25).copied().unwrap_or(0));
            let channels = match colour {
                2 => 3,
                4 => 2,
                6 => 4,
                _ => 1,
            };
            let row_bytes = 1 + (w * channels * u64::from(depth.max(1))).div_ceil(8);
            (h * row_bytes).div_ceil(DEFLATE_MAX_RATIO)
        }
        ImageFormat::Jpeg => (w.div_ceil(8) * h.div_ceil(8)).div_ceil(8),
        _ => 0,
    };
    if (bytes.len() as u64) < needed {
        return Err(format!(
            "the header declares {width} x {height} texels, which take at least {needed} bytes of {format:?} data, \
             but the file has {} (truncated or corrupt)",
            bytes.len()
        ));
    }
    Ok(())
}

impl ImageHeader {
    /// Number of texels.
    pub fn texels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Decodes `bytes` (the image probed) into `out`, `width * height` packed sRGBA8 texels
    /// (see the module docs). Corrupt data is an error. 16-bit images are rounded to 8 bits
    /// per channel (albedo and emission masks need no more).
    pub(crate) fn decode_into(&self, bytes: &[u8], out: &mut [u32]) -> Result<(), SceneError> {
        let err = |message: String| SceneError::Image { name: self.name.clone(), message };
        let format = self.format;
        let cannot = |e: image::ImageError| err(format!("cannot decode {format:?}: {e}"));
        let count = out.len();
        catch_decoder_panic(|| -> Result<(), SceneError> {
            let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
            reader.limits(limits());
            let decoder = reader.into_decoder().map_err(cannot)?;
            let (width, height) = decoder.dimensions();
            if (width, height) != (self.width, self.height) || count as u64 != self.texels() {
                return Err(err("the image changed size between its header and its pixels".into()));
            }
            let channels = match decoder.color_type() {
                ColorType::L8 => 1,
                ColorType::La8 => 2,
                ColorType::Rgb8 => 3,
                ColorType::Rgba8 => 4,
                _ => {
                    // Deeper formats (16-bit PNG) go through the image crate's conversion.
                    let rgba = DynamicImage::from_decoder(decoder).map_err(cannot)?.into_rgba8();
                    for (texel, p) in out.iter_mut().zip(rgba.pixels()) {
                        *texel = u32::from_le_bytes(p.0);
                    }
                    return Ok(());
                }
            };
            // Decode into the texels themselves, then widen each texel to RGBA in place.
            let bytes: &mut [u8] = bytemuck::cast_slice_mut(out);
            decoder.read_image(&mut bytes[..count * channels]).map_err(cannot)?;
            widen_to_rgba_in_place(bytes, channels);
            if cfg!(target_endian = "big") {
                out.iter_mut().for_each(|t| *t = u32::from_le(*t));
            }
            Ok(())
        })
        .unwrap_or_else(|| Err(err("the image decoder failed unexpectedly".into())))
    }
}

/// A texture of a scene being loaded, its image probed but not decoded yet.
pub(crate) struct PendingTexture {
    /// Index of its image in the list given to [`decode_textures`].
    pub image: usize,
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
}

/// Decodes the scene's textures into one shared atlas (see [`TextureTexels`]), in parallel:
/// `images` are the probed images with their bytes, `textures` the scene's textures in order
/// (several may show the same image, with other wrap modes: each gets its own copy, as the
/// packed layout has). The mean luminance of the textures `materials` emit through is computed
/// while their texels are at hand. On failure, every failing image (index in `images`) with
/// its error, in image order.
pub(crate) fn decode_textures(
    images: &[(&[u8], &ImageHeader)],
    textures: &[PendingTexture],
    materials: &[Material],
) -> Result<Vec<Texture>, Vec<(usize, SceneError)>> {
    let emissive: Vec<bool> =
        (0..textures.len() as u32).map(|i| materials.iter().any(|m| m.emissive_texture == Some(i))).collect();
    // Each texture's first element and image header, in scene order.
    let mut layout = Vec::with_capacity(textures.len());
    let mut elements = 0usize;
    for t in textures {
        let header = images
            .get(t.image)
            .ok_or_else(|| vec![(t.image, SceneError::Malformed("a texture has no image".into()))])?
            .1;
        layout.push((elements, header));
        elements += (header.texels() as usize).div_ceil(PER_ELEMENT);
    }
    let mut results = Vec::new();
    let atlas = Texels::<UVec4>::par_from_fill(elements, |atlas| {
        // Each image's slots: the first is decoded into, the others are copies of it.
        let mut targets: Vec<Vec<(usize, &mut [u32])>> = images.iter().map(|_| Vec::new()).collect();
        let mut rest: &mut [u32] = bytemuck::cast_slice_mut(atlas);
        for (i, (t, &(_, header))) in textures.iter().zip(&layout).enumerate() {
            let len = header.texels() as usize;
            let (slot, after) = std::mem::take(&mut rest).split_at_mut(len.div_ceil(PER_ELEMENT) * PER_ELEMENT);
            rest = after;
            if let Some(list) = targets.get_mut(t.image) {
                list.push((i, &mut slot[..len]));
            }
        }
        results = targets
            .into_par_iter()
            .zip(images)
            .map(|(mut slots, &(bytes, header))| -> Result<Option<f32>, SceneError> {
                let Some(((_, first), copies)) = slots.split_first_mut() else { return Ok(None) };
                header.decode_into(bytes, first)?;
                for (_, copy) in copies {
                    copy.copy_from_slice(first);
                }
                let emitted = slots.iter().any(|(i, _)| emissive.get(*i).copied().unwrap_or(false));
                Ok(emitted.then(|| mean_luminance(slots[0].1)))
            })
            .collect::<Vec<_>>();
    });
    // Each image's bytes once, shared by its textures (only the images some texture shows).
    let mut sources: Vec<Option<EncodedImage>> = vec![None; images.len()];
    for t in textures {
        if let (Some(source), Some((bytes, _))) = (sources.get_mut(t.image), images.get(t.image)) {
            source.get_or_insert_with(|| Arc::from(*bytes));
        }
    }
    let mut means = Vec::with_capacity(results.len());
    let mut failures = Vec::new();
    for (image, r) in results.into_iter().enumerate() {
        match r {
            Ok(mean) => means.push(mean),
            Err(e) => failures.push((image, e)),
        }
    }
    if !failures.is_empty() {
        return Err(failures);
    }
    Ok(textures
        .iter()
        .zip(layout)
        .map(|(t, (first, header))| {
            let mean = means.get(t.image).copied().flatten();
            Texture {
                width: header.width,
                height: header.height,
                texels: TextureTexels {
                    atlas: atlas.clone(),
                    first,
                    len: header.texels() as usize,
                    mean_luminance: Arc::new(mean.map(OnceLock::from).unwrap_or_default()),
                    source: sources.get(t.image).cloned().flatten(),
                },
                wrap_s: t.wrap_s,
                wrap_t: t.wrap_t,
            }
        })
        .collect())
}

/// Decodes image files into one atlas in the packed layout (see [`TextureTexels`]), texture `i`
/// showing image `image_of[i]`: how a bundle's textures become texels again. The same decoder
/// as loading, so the texels are the ones the scene was packed with. Every image must be a
/// PNG, JPEG or WebP; `max_texels` bounds all the textures together, checked from the headers
/// before anything is allocated. The textures share one atlas and their images' bytes; their
/// wrap modes are `Repeat` (the caller's to set).
pub fn decode_atlas(images: &[EncodedImage], image_of: &[u32], max_texels: u64) -> Result<Vec<Texture>, SceneError> {
    let mut headers = Vec::with_capacity(images.len());
    for (i, bytes) in images.iter().enumerate() {
        let name = format!("image {i}");
        match probe_srgb(bytes, &name, MAX_IMAGE_TEXELS)? {
            Probed::Image(header) => headers.push(header),
            Probed::Unsupported(format) => {
                return Err(SceneError::Image { name, message: format!("{format} is not a texture format") })
            }
        }
    }
    let mut pending = Vec::with_capacity(image_of.len());
    let mut texels = 0u64;
    for &image in image_of {
        let header = headers.get(image as usize).ok_or_else(|| {
            SceneError::Malformed(format!("a texture shows image {image}; there are {}", images.len()))
        })?;
        texels += header.texels();
        if texels > max_texels {
            return Err(SceneError::Malformed(format!("the textures hold more than {max_texels} texels")));
        }
        pending.push(PendingTexture { image: image as usize, wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat });
    }
    let pairs: Vec<(&[u8], &ImageHeader)> = images.iter().map(|b| &**b).zip(&headers).collect();
    let decoded = decode_textures(&pairs, &pending, &[]).map_err(|mut failures| failures.swap_remove(0).1)?;
    Ok(decoded
        .into_iter()
        .zip(image_of)
        .map(|(t, &image)| Texture {
            texels: TextureTexels { source: images.get(image as usize).cloned(), ..t.texels },
            ..t
        })
        .collect())
}

/// [`decode_textures`], forgiving: an image that does not decode is reported in `problems`
/// (naming the materials that used it), its textures are dropped and the materials render
/// with their factors; the others are decoded again without it. With `strict`, the first
/// failure is the error.
pub(crate) fn decode_textures_forgiving(
    images: &[(&[u8], &ImageHeader)],
    mut textures: Vec<PendingTexture>,
    materials: &mut [Material],
    problems: &mut ImageProblems,
    strict: bool,
) -> Result<Vec<Texture>, SceneError> {
    loop {
        let failures = match decode_textures(images, &textures, materials) {
            Ok(decoded) => return Ok(decoded),
            Err(failures) => failures,
        };
        if strict || failures.iter().any(|(_, e)| !is_texture_problem(e)) {
            let (_, first) = failures.into_iter().find(|(_, e)| strict || !is_texture_problem(e)).expect("non-empty");
            return Err(first);
        }
        for (image, error) in &failures {
            let name = images.get(*image).map_or_else(|| image.to_string(), |(_, h)| format!("image {}", h.name));
            let id = problems.add(name, error);
            for (m, material) in materials.iter().enumerate() {
                let uses = material
                    .texture_slots()
                    .iter()
                    .flatten()
                    .any(|&t| textures.get(t as usize).is_some_and(|t| t.image == *image));
                if uses {
                    problems.used_by(id, &material_label(m, &material.name));
                }
            }
        }
        // Drop the failed images' textures; the others keep their order.
        let failed = |t: &PendingTexture| failures.iter().any(|(image, _)| *image == t.image);
        let mut kept = 0u32;
        let remap: Vec<Option<u32>> = textures
            .iter()
            .map(|t| {
                (!failed(t)).then(|| {
                    kept += 1;
                    kept - 1
                })
            })
            .collect();
        for material in materials.iter_mut() {
            for slot in material.texture_slots_mut() {
                *slot = slot.and_then(|t| remap.get(t as usize).copied().flatten());
            }
        }
        textures.retain(|t| !failed(t));
    }
}

/// Whether a loading error is about one texture's image (a missing or unreadable file, data
/// that does not decode), which a forgiving load turns into a warning, rather than about the
/// scene file itself.
pub(crate) fn is_texture_problem(e: &SceneError) -> bool {
    matches!(e, SceneError::Io { .. } | SceneError::Image { .. })
}

/// How warnings name a material: its name in the file, else its index.
pub(crate) fn material_label(index: usize, name: &str) -> String {
    if name.is_empty() {
        format!("material {index}")
    } else {
        format!("material {index} {name:?}")
    }
}

/// Texture images that could not be used, each with why and the materials that asked for it:
/// one warning per image ([`ImageProblems::warn`]).
#[derive(Default)]
pub(crate) struct ImageProblems {
    list: Vec<ImageProblem>,
}

struct ImageProblem {
    image: String,
    reason: String,
    materials: Vec<String>,
}

impl ImageProblems {
    /// Records that `image` cannot be used because of `reason`; its id for [`ImageProblems::used_by`].
    pub(crate) fn add(&mut self, image: String, reason: &SceneError) -> usize {
        self.list.push(ImageProblem { image, reason: reason.to_string(), materials: Vec::new() });
        self.list.len() - 1
    }

    /// Records that `material` wanted the image of problem `id`.
    pub(crate) fn used_by(&mut self, id: usize, material: &str) {
        if let Some(p) = self.list.get_mut(id) {
            if !p.materials.iter().any(|m| m == material) {
                p.materials.push(material.to_owned());
            }
        }
    }

    /// One warning per image, naming it, why, and the materials that render without it.
    pub(crate) fn warn(self, warnings: &mut super::Warnings) {
        for p in self.list {
            let users = match p.materials.len() {
                0 => "no material uses it".to_owned(),
                1 => format!("{} renders with its factors instead", p.materials[0]),
                _ => format!("{} render with their factors instead", p.materials.join(", ")),
            };
            warnings.once(&format!("texture {}", p.image), || format!("texture ignored: {}; {users}", p.reason));
        }
    }
}

fn check_texels(w: u32, h: u32, max_texels: u64, name: &str) -> Result<(), SceneError> {
    if u64::from(w) * u64::from(h) > max_texels {
        return Err(SceneError::TooLarge(format!(
            "image {name} is {w} x {h}: more texels than the {max_texels} allowed here"
        )));
    }
    Ok(())
}

/// `bytes` holds `bytes.len() / 4` texels of `channels` (1: L, 2: LA, 3: RGB, 4: RGBA) bytes
/// each, packed at its start; rewrites them as RGBA (grey replicated, alpha 255 when absent).
fn widen_to_rgba_in_place(bytes: &mut [u8], channels: usize) {
    match channels {
        1 => widen::<1>(bytes, |&[l]| [l, l, l, 255]),
        2 => widen::<2>(bytes, |&[l, a]| [l, l, l, a]),
        3 => widen::<3>(bytes, |&[r, g, b]| [r, g, b, 255]),
        _ => {}
    }
}

/// [`widen_to_rgba_in_place`] for `C` channels. Runs from the last texel back, so no texel is
/// overwritten before it is read: texel `i` is read from `C * i..` and written to `4 * i..`,
/// at or after where it was. Whole blocks of texels are read before any of them is written,
/// which lets the compiler vectorise the conversion.
fn widen<const C: usize>(bytes: &mut [u8], rgba: impl Fn(&[u8; C]) -> [u8; 4]) {
    const BLOCK: usize = 16;
    let count = bytes.len() / 4;
    let blocks = count / BLOCK;
    // The texels after the last whole block, last first.
    for i in (blocks * BLOCK..count).rev() {
        let texel: [u8; C] = std::array::from_fn(|k| bytes[C * i + k]);
        bytes[4 * i..4 * i + 4].copy_from_slice(&rgba(&texel));
    }
    for block in (0..blocks).rev() {
        let mut texels = [[0u8; C]; BLOCK];
        texels.as_flattened_mut().copy_from_slice(&bytes[C * BLOCK * block..C * BLOCK * (block + 1)]);
        let widened = texels.map(|t| rgba(&t));
        bytes[4 * BLOCK * block..4 * BLOCK * (block + 1)].copy_from_slice(widened.as_flattened());
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
pub use crate::kernel::textures::srgb_to_linear;

/// A packed sRGBA8 texel (red in the low byte) as linear RGBA, for code outside the kernel:
/// the kernel's `decode_srgba8`, so both decode identically.
pub fn srgba8_to_linear(texel: u32) -> Vec4 {
    crate::kernel::textures::decode_srgba8(texel)
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
mod tests;
