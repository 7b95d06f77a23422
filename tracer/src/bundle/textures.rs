//! Textures travel as image files, not texels: each texture of the atlas is stored as the PNG,
//! JPEG or WebP it was decoded from (or, for texels made in code, as a PNG written here), and
//! decoding the bundle decodes the images again, with the loader's decoder, into the same atlas.
//! A JPEG is a tenth of its texels or less, and gzip cannot shrink texels that much.
//!
//! Entries: `textures.images` (every distinct image's bytes, one after another), `textures.image_ends`
//! (where each image ends in them) and `textures.image_of` (per texture of the atlas, in order,
//! its image). With images, `scene.texture_texels` is stored empty.

use std::collections::HashMap;
use std::sync::Arc;

use glam::UVec4;
use kernel_dsl::Texels;

use super::format::{ElementType, Reader, Writer};
use super::{BundleError, MAX_BUNDLE_BYTES};
use crate::kernel::scene_data::TEXTURE_TEXELS_PER_ELEMENT;
use crate::pack::AtlasImage;
use crate::scene::texture::decode_atlas;
use crate::scene::EncodedImage;

const IMAGES: &str = "textures.images";
const IMAGE_ENDS: &str = "textures.image_ends";
const IMAGE_OF: &str = "textures.image_of";

/// Texels per atlas element.
const PER_ELEMENT: usize = TEXTURE_TEXELS_PER_ELEMENT as usize;

/// Writes the textures of `atlas` as images (see the module docs).
pub(super) fn write(images: &[AtlasImage], atlas: &Texels<UVec4>, w: &mut Writer) {
    let mut distinct: Vec<EncodedImage> = Vec::new();
    let mut index_of: HashMap<EncodedImage, u32> = HashMap::new();
    let mut image_of = Vec::with_capacity(images.len());
    let mut first = 0usize;
    for image in images {
        let texels = image.width as usize * image.height as usize;
        let file = image.file.clone().unwrap_or_else(|| png(atlas, first, image.width, image.height));
        first += texels.div_ceil(PER_ELEMENT);
        let next = distinct.len() as u32;
        let index = *index_of.entry(file.clone()).or_insert_with(|| {
            distinct.push(file);
            next
        });
        image_of.push(index);
    }
    let total: usize = distinct.iter().map(|i| i.len()).sum();
    w.entry(IMAGES, ElementType::U8, 1, total as u64, |out| distinct.iter().for_each(|i| out.extend_from_slice(i)));
    w.entry(IMAGE_ENDS, ElementType::U64, 1, distinct.len() as u64, |out| {
        let mut end = 0u64;
        for i in &distinct {
            end += i.len() as u64;
            out.extend_from_slice(&end.to_le_bytes());
        }
    });
    w.entry(IMAGE_OF, ElementType::U32, 1, image_of.len() as u64, |out| {
        image_of.iter().for_each(|i| out.extend_from_slice(&i.to_le_bytes()))
    });
}

/// A texture made in code, written as an 8-bit RGBA PNG (lossless: it decodes to the same texels).
fn png(atlas: &Texels<UVec4>, first_element: usize, width: u32, height: u32) -> EncodedImage {
    let words: &[u32] = bytemuck::cast_slice(atlas.as_slice());
    let texels = &words[first_element * PER_ELEMENT..][..width as usize * height as usize];
    let rgba: Vec<u8> = texels.iter().flat_map(|t| t.to_le_bytes()).collect();
    let mut out = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut out),
        &rgba,
        width,
        height,
        image::ExtendedColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .expect("encoding 8-bit RGBA as PNG into memory cannot fail");
    Arc::from(out)
}

/// Reads the textures' images and decodes them into the atlas: the atlas (empty without
/// textures) and each texture as an image.
pub(super) fn read(r: &mut Reader) -> Result<(Texels<UVec4>, Vec<AtlasImage>), BundleError> {
    let invalid = |field: &str, reason: String| BundleError::InvalidValue { field: field.to_string(), reason };
    let bytes = r.take(IMAGES, ElementType::U8, 1)?.data_cow()?;
    let ends: Vec<u64> = r.take(IMAGE_ENDS, ElementType::U64, 1)?.data()?.chunks_exact(8).map(le_u64).collect();
    let image_of: Vec<u32> = r.take(IMAGE_OF, ElementType::U32, 1)?.data()?.chunks_exact(4).map(le_u32).collect();
    let mut images = Vec::with_capacity(ends.len());
    let mut start = 0u64;
    for &end in &ends {
        if end < start || end > bytes.len() as u64 {
            return Err(invalid(IMAGE_ENDS, format!("image bytes {start}..{end} of {}", bytes.len())));
        }
        images.push(EncodedImage::from(&bytes[start as usize..end as usize]));
        start = end;
    }
    if start != bytes.len() as u64 {
        return Err(invalid(IMAGE_ENDS, format!("the images end at byte {start} of {}", bytes.len())));
    }
    if image_of.is_empty() {
        return Ok((Texels::default(), Vec::new()));
    }
    // The decoded atlas is at most as large as the largest bundle.
    let max_texels = MAX_BUNDLE_BYTES / 4;
    let textures = decode_atlas(&images, &image_of, max_texels).map_err(|e| invalid(IMAGES, e.to_string()))?;
    let atlas = textures[0].texels.atlas().clone();
    let images = textures
        .iter()
        .map(|t| AtlasImage { width: t.width, height: t.height, file: t.texels.source().cloned() })
        .collect();
    Ok((atlas, images))
}

fn le_u64(b: &[u8]) -> u64 {
    u64::from_le_bytes(b.try_into().expect("chunks of 8"))
}

fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes(b.try_into().expect("chunks of 4"))
}

#[cfg(test)]
mod tests {
    use std::io::Write;
    use std::path::Path;

    use super::*;
    use crate::bundle::{decode, encode, entries, Bundle};
    use crate::kernel::features::RenderSettings;
    use crate::pack::{build_and_pack, Packed};
    use crate::scene::{Scene, Texture, Wrap};

    fn test_data(rel: &str) -> std::path::PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data")).join(rel)
    }

    fn packed(scene: &Scene) -> Packed {
        build_and_pack(scene, &RenderSettings { width: 16, height: 16, ..Default::default() }).expect("pack").1
    }

    fn gzip(bytes: &[u8]) -> usize {
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        encoder.write_all(bytes).unwrap();
        encoder.finish().unwrap().len()
    }

    fn entry<'a>(bytes: &'a [u8], name: &str) -> &'a [u8] {
        entries(bytes).unwrap().into_iter().find(|(n, _)| *n == name).expect("entry").1
    }

    /// Where entry `name`'s data starts in `bytes`.
    fn data_offset(bytes: &[u8], name: &str) -> usize {
        entry(bytes, name).as_ptr() as usize - bytes.as_ptr() as usize
    }

    #[test]
    fn a_jpeg_textured_scene_travels_as_its_files_and_decodes_to_the_same_texels() {
        let path = test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
        let p = packed(&crate::scene::load(&path).expect("DamagedHelmet"));
        assert!(p.texture_images.len() >= 4 && p.texture_images.iter().all(|i| i.file.is_some()));
        let bytes = encode(&p);
        assert!(entry(&bytes, "scene.texture_texels").is_empty(), "the texels must not travel as well");
        let source = std::fs::metadata(&path).unwrap().len() as usize;
        let zipped = gzip(&bytes);
        assert!(zipped <= source, "the bundle is {zipped} bytes gzip-compressed, its source {source}");
        let back = decode(&bytes).expect("decode");
        assert_eq!(back.scene.texture_texels.as_slice(), p.scene.texture_texels.as_slice(), "texels differ");
        assert_eq!(back.texture_images, p.texture_images);
        assert_eq!(encode(&back), bytes, "re-encoding differs");
    }

    #[test]
    fn textures_made_in_code_travel_as_png_and_come_back_texel_for_texel() {
        let mut scene = crate::scene::cornell_box();
        let texels: Vec<u32> = (0..7 * 5).map(|i: u32| i.wrapping_mul(0x9e37_79b9) | 0x0100_0000).collect();
        scene.textures =
            vec![Texture { width: 7, height: 5, texels: texels.into(), wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat }];
        scene.materials[0].base_color_texture = Some(0);
        let p = packed(&scene);
        assert_eq!(p.texture_images.len(), 1);
        assert!(p.texture_images[0].file.is_none());
        let bytes = encode(&p);
        assert!(entry(&bytes, "textures.images").starts_with(b"\x89PNG"));
        let back = Bundle::decode(&bytes).expect("decode").packed;
        assert_eq!(back.scene.texture_texels.as_slice(), p.scene.texture_texels.as_slice());
        assert_eq!(encode(&back), bytes);
    }

    #[test]
    fn bad_texture_images_are_typed_errors() {
        let scene = crate::scene::load(&test_data("scenes/khronos/BoxTextured/glTF-Binary/BoxTextured.glb")).unwrap();
        let good = encode(&packed(&scene));
        let invalid = |bytes: &[u8], field: &str, says: &str| match decode(bytes).unwrap_err() {
            BundleError::InvalidValue { field: f, reason } => {
                assert_eq!(f, field);
                assert!(reason.contains(says), "{reason}");
            }
            other => panic!("expected an invalid {field}, got {other}"),
        };
        let at = data_offset(&good, IMAGE_OF);
        let mut bad = good.clone();
        bad[at..at + 4].copy_from_slice(&9u32.to_le_bytes());
        invalid(&bad, IMAGES, "shows image 9");
        let at = data_offset(&good, IMAGE_ENDS);
        let mut bad = good.clone();
        bad[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        invalid(&bad, IMAGE_ENDS, "image bytes 0..");
        let at = data_offset(&good, IMAGES);
        let mut bad = good.clone();
        bad[at..at + 8].fill(0);
        invalid(&bad, IMAGES, "not a PNG, JPEG or WebP");
        // Cut the image short (its bytes stay in the entry, declared as trailing garbage).
        let mut bad = good.clone();
        let end = entry(&good, IMAGES).len() as u64;
        bad[data_offset(&good, IMAGE_ENDS)..][..8].copy_from_slice(&(end / 2).to_le_bytes());
        invalid(&bad, IMAGE_ENDS, "the images end at byte");
    }
}
