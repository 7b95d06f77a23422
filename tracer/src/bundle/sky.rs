//! A sky travels as the file it was decoded from (Radiance `.hdr` or OpenEXR), not as texels:
//! decoding the bundle decodes the file again, with the loader's decoder, and computes the CDFs
//! and guide tables from it as packing did (`pack::sky`). The venice sunset sky is 1.4 MB as a
//! `.hdr` and 8 MB of texels, which LZMA2 shrinks to only 2.3 MB (random low mantissa bits) in
//! 6 s, and decodes in ~160 ms where the file decodes in a few tens.
//!
//! Entries: `sky.format` (u8: 0 for no file, 1 `.hdr`, 2 `.exr`) and `sky.file` (its bytes).
//! With a file, `scene.sky` and `scene.sky_rows` are stored empty. A sky made in code (no file)
//! travels as texels, as every other array does.

use super::format::{ElementType, Reader, Writer};
use super::BundleError;
use crate::kernel::scene_data::Scene;
use crate::pack::sky::pack_sky;
use crate::scene::{load_sky_slice, SkyFile, SkyFormat};

const FORMAT: &str = "sky.format";
const FILE: &str = "sky.file";

/// Each file format's code in `sky.format` (0: no file).
const FORMAT_CODES: [(SkyFormat, u8); 2] = [(SkyFormat::Hdr, 1), (SkyFormat::Exr, 2)];

/// Writes the sky's file entries (empty without a file).
pub(super) fn write(file: Option<&SkyFile>, w: &mut Writer) {
    let code = file.and_then(|f| FORMAT_CODES.iter().find(|(format, _)| *format == f.format)).map_or(0, |(_, c)| *c);
    w.entry(FORMAT, ElementType::U8, 1, 1, |out| out.push(code));
    let bytes = file.map_or(&[][..], |f| &f.bytes[..]);
    w.entry(FILE, ElementType::U8, 1, bytes.len() as u64, |out| out.extend_from_slice(bytes));
}

/// Reads the sky's file entries and, where there is a file, decodes it into `scene.sky` and
/// `scene.sky_rows` (which must have been stored empty). Returns the file.
pub(super) fn read(r: &mut Reader, scene: &mut Scene) -> Result<Option<SkyFile>, BundleError> {
    let invalid = |field: &str, reason: String| BundleError::InvalidValue { field: field.to_string(), reason };
    let code = r.scalar(FORMAT, ElementType::U8, 1)?[0];
    let bytes = r.take(FILE, ElementType::U8, 1)?.data_cow()?;
    let format = match FORMAT_CODES.iter().find(|(_, c)| *c == code) {
        Some((format, _)) => *format,
        None if code == 0 && bytes.is_empty() => return Ok(None),
        None if code == 0 => return Err(invalid(FILE, format!("{} bytes of a sky file with no format", bytes.len()))),
        None => return Err(invalid(FORMAT, format!("{code} is not a sky format (0: none, 1: .hdr, 2: .exr)"))),
    };
    if !scene.sky.is_empty() || !scene.sky_rows.is_empty() {
        return Err(BundleError::Inconsistent("the sky is stored as texels and as a file".into()));
    }
    let sky = load_sky_slice(&bytes, format, "the bundle's sky", scene.sky_intensity, scene.sky_rotation)
        .map_err(|e| invalid(FILE, e.to_string()))?;
    if (sky.width, sky.height) != (scene.sky_width, scene.sky_height) {
        return Err(BundleError::Inconsistent(format!(
            "the sky file is {}x{}, the scene's sky {}x{}",
            sky.width, sky.height, scene.sky_width, scene.sky_height
        )));
    }
    let packed = pack_sky(Some(&sky));
    (scene.sky, scene.sky_rows) = (packed.texels, packed.rows);
    Ok(sky.file)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::bundle::{decode, encode, entries, BundleError};
    use crate::kernel::features::RenderSettings;
    use crate::pack::{build_and_pack, Packed};
    use crate::scene::{load_sky, Sky};

    const VENICE: &str = "scenes/hdri/venice_sunset_1k.hdr";

    fn test_data(rel: &str) -> std::path::PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data")).join(rel)
    }

    fn cornell_under(sky: Sky) -> Packed {
        let mut scene = crate::scene::cornell_box();
        scene.sky = Some(sky);
        build_and_pack(&scene, &RenderSettings { width: 8, height: 8, ..Default::default() }).expect("pack").1
    }

    fn entry<'a>(bytes: &'a [u8], name: &str) -> &'a [u8] {
        entries(bytes).unwrap().into_iter().find(|(n, _)| *n == name).expect("entry").1
    }

    /// A 3x2 Radiance HDR of distinct texels, written by the `image` crate.
    fn small_hdr() -> Vec<u8> {
        let texels: Vec<image::Rgb<f32>> =
            (0..6).map(|i| image::Rgb([i as f32 + 0.5, 2.0 * i as f32, 0.25 + i as f32 * 0.125])).collect();
        let mut out = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut out).encode(&texels, 3, 2).expect("encode");
        out
    }

    #[test]
    fn a_sky_from_a_file_travels_as_the_file_and_decodes_to_the_same_arrays() {
        let path = test_data(VENICE);
        let p = cornell_under(load_sky(&path, 1.5, 0.3).expect("sky"));
        let bytes = encode(&p);
        let file = std::fs::read(&path).unwrap();
        assert_eq!(entry(&bytes, FILE), &file[..], "the sky must travel as its file");
        assert_eq!(entry(&bytes, FORMAT), &[1]);
        assert!(entry(&bytes, "scene.sky").is_empty() && entry(&bytes, "scene.sky_rows").is_empty());
        assert!(
            bytes.len() < file.len() + 16 * 1024,
            "the bundle is {} bytes, the sky file {}",
            bytes.len(),
            file.len()
        );
        let back = decode(&bytes).expect("decode");
        let bits = |t: &kernel_dsl::Texels<glam::Vec4>| -> Vec<[u32; 4]> {
            t.as_slice().iter().map(|v| v.to_array().map(f32::to_bits)).collect()
        };
        assert!(bits(&back.scene.sky) == bits(&p.scene.sky), "sky texels differ");
        assert!(bits(&back.scene.sky_rows) == bits(&p.scene.sky_rows), "sky rows differ");
        assert_eq!(back.sky_file, p.sky_file);
        assert_eq!(encode(&back), bytes, "re-encoding differs");
    }

    #[test]
    fn a_sky_made_in_code_travels_as_texels() {
        let p = cornell_under(Sky::uniform(glam::Vec3::new(0.5, 1.0, 2.0)));
        let bytes = encode(&p);
        assert!(entry(&bytes, FILE).is_empty() && entry(&bytes, FORMAT) == [0]);
        assert!(!entry(&bytes, "scene.sky").is_empty());
        let back = decode(&bytes).expect("decode");
        assert_eq!(back.scene.sky.as_slice(), p.scene.sky.as_slice());
        assert_eq!(back.sky_file, None);
    }

    #[test]
    fn bad_sky_files_are_typed_errors() {
        let sky = crate::scene::load_sky_slice(&small_hdr(), SkyFormat::Hdr, "small", 1.0, 0.0).expect("small sky");
        let p = cornell_under(sky);
        assert!(decode(&encode(&p)).is_ok());
        let with_file = |format: SkyFormat, bytes: Vec<u8>| {
            let mut q = p.clone();
            q.sky_file = Some(SkyFile { format, bytes: bytes.into() });
            decode(&encode(&q)).unwrap_err()
        };
        let invalid = |e: BundleError, field: &str, says: &str| match e {
            BundleError::InvalidValue { field: f, reason } if f == field => {
                assert!(reason.contains(says), "{reason}")
            }
            other => panic!("expected an invalid {field}, got {other}"),
        };
        invalid(with_file(SkyFormat::Hdr, b"#?RADIANCE\nnot a sky".to_vec()), FILE, "the bundle's sky");
        invalid(with_file(SkyFormat::Exr, small_hdr()), FILE, "the bundle's sky");
        let truncated = small_hdr()[..small_hdr().len() - 4].to_vec();
        invalid(with_file(SkyFormat::Hdr, truncated), FILE, "the bundle's sky");
        // A file of another size than the scene's sky uniforms say.
        let mut other = image::Rgb32FImage::new(4, 2);
        other.pixels_mut().for_each(|t| *t = image::Rgb([1.0, 1.0, 1.0]));
        let mut hdr = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut hdr)
            .encode(other.pixels().copied().collect::<Vec<_>>().as_slice(), 4, 2)
            .unwrap();
        let e = with_file(SkyFormat::Hdr, hdr);
        assert!(matches!(&e, BundleError::Inconsistent(m) if m.contains("sky file is 4x2")), "{e}");
        // An unknown format, bytes without a format, the sky stored as texels and as a file.
        let mut bytes = encode(&p);
        let at = entry(&bytes, FORMAT).as_ptr() as usize - bytes.as_ptr() as usize;
        bytes[at] = 9;
        invalid(decode(&bytes).unwrap_err(), FORMAT, "9 is not a sky format");
        bytes[at] = 0;
        invalid(decode(&bytes).unwrap_err(), FILE, "with no format");
        let mut both = encode(&Packed { sky_file: None, ..p.clone() });
        let at = entry(&both, FORMAT).as_ptr() as usize - both.as_ptr() as usize;
        both[at] = 1;
        let e = decode(&both).unwrap_err();
        assert!(matches!(&e, BundleError::Inconsistent(m) if m.contains("as texels and as a file")), "{e}");
    }
}
