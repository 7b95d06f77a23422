//! Scene bundles: a packed scene ([`Packed`]: BVH built, texel arrays laid out, camera and
//! [`Features`]) as one self-describing binary blob, so a client (the web page, in wasm) renders a
//! scene without loading or building anything.
//!
//! Format (all integers little-endian):
//!
//! ```text
//! header   "LPBUNDLE" (8 bytes) | version: u32 | entry count: u32 | total length in bytes: u64
//! entry    name length: u8 | name (UTF-8) | element type: u8 | components: u8 | encoding: u8
//!          | reserved: u8 (0) | count: u64 | zero padding to a multiple of 16 from the start
//!          | data: count × components elements of the element type, little-endian (encoding 0)
//!            or its stored length: u64 and an LZMA2 stream of those elements (encoding 1)
//! ```
//!
//! An entry is one field of [`Packed`], named by its path (`scene.triangles`, `features.sky`,
//! `triangle_count`), plus `meta.name` (the scene's name). A `Texels<Vec4>` is `f32` × 4 × texels,
//! a `Vec3` uniform `f32` × 3 × 1, a `u32` uniform `u32` × 1 × 1, a flag `u8` × 1 × 1 (0 or 1).
//! Plain data starts 16-byte aligned, so a reader may view the arrays in place; numeric arrays
//! over 4 KiB are compressed ([`format`] says why and how). The texture atlas is
//! the exception: it travels as the image files it was decoded from ([`textures`]), so a bundle
//! is no larger than the scene the artist exported.
//!
//! Decoding is strict: wrong magic, another version, a length that disagrees with the input,
//! truncation, an unknown, missing, duplicated or mistyped field, or values that contradict each
//! other are [`BundleError`]s, never panics; sizes are checked before anything is allocated.
//! Encoding is deterministic (same `Packed`, same bytes), so a hash of the bytes names the content.
//!
//! [`record!`] is the one list of fields: it destructures each struct without `..` and builds it
//! with a full struct literal, so a field added to `Packed`, `Features` or the kernel's `Scene`
//! does not compile until the bundle stores it.
//!
//! [`format`] reads and writes the container (header, entries, alignment), [`fields`] maps each
//! field to its entry, [`textures`] stores the atlas as images, [`checks`] (with `bounds`)
//! refuses values that contradict each other.
//!
//! No I/O here: the module compiles for `wasm32-unknown-unknown` (where the texture decoder's rayon
//! runs on the calling thread).

mod bounds;
mod checks;
mod fields;
mod format;
mod textures;

use crate::pack::Packed;
use checks::check_consistency;
use fields::Field;
use format::{Reader, Writer};

/// The first bytes of every bundle.
pub const MAGIC: [u8; 8] = *b"LPBUNDLE";
/// Bumped whenever the layout or the meaning of a field changes; readers accept only their own.
/// (2: node planes as float texels, `node_children`, `leaf_stack_limit`, triangle lights with
/// their normal and area. 3: `features.traversal_stack`, `features.metal_rough` and
/// `scene.metal_rough`. 4: `features.normal_map`, `scene.has_normal_map`, `scene.tangent_first`,
/// `scene.normal_map_first`. 5: `features.alpha_mask`, `scene.has_alpha_mask`,
/// `scene.alpha_mask_first`, the alpha-mask flag in each triangle's third texel. 6:
/// `features.texture_transform`, `features.texcoord1`, `scene.has_texture_transform`,
/// `scene.has_texcoord1`, `scene.texture_ref_first`, `scene.texcoord1_first`. 7: textures as
/// image files, `textures.images`, `textures.image_ends`, `textures.image_of`; LZMA2-compressed
/// entries. 8: `features.transmission`, `features.volume`, `scene.has_transmission`,
/// `scene.has_volume`, `scene.transmission_first`.)
pub const VERSION: u32 = 8;
/// The largest bundle accepted (and produced): well within wasm32's 4 GiB address space.
pub const MAX_BUNDLE_BYTES: u64 = 1 << 30;
/// File extension used for bundles (the server serves `/bundles/<hash>.lpb`).
pub const EXTENSION: &str = "lpb";

pub(crate) const HEADER_BYTES: usize = 8 + 4 + 4 + 8;
/// The longest path a bundle may ask for (the page's depth control goes as far).
pub const MAX_DEPTH: u32 = 64;
pub(crate) const ALIGN: usize = 16;
pub(crate) const NAME_FIELD: &str = "meta.name";
pub(crate) const KERNEL_FIELD: &str = "meta.kernel";

/// A fingerprint of the kernel this build carries (FNV-1a over every kernel module's captured
/// source description). A page and a server built from different kernels would otherwise read
/// each other's arrays with the wrong meaning (e.g. a changed node layout renders black with no
/// error); decoding refuses such a bundle instead.
pub fn kernel_fingerprint() -> u32 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for json in crate::kernel::ir_json() {
        for byte in json.bytes().chain([0]) {
            hash = (hash ^ byte as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    (hash ^ hash >> 32) as u32
}

/// Why bytes are not a bundle this version can read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BundleError {
    #[error("not a Lightport scene bundle (the first bytes are not \"LPBUNDLE\")")]
    BadMagic,
    #[error("the bundle is format version {found}; this build reads version {supported} only (rebuild the bundle)")]
    UnsupportedVersion { found: u32, supported: u32 },
    #[error("the bundle is truncated: {needed} bytes needed, {available} present")]
    Truncated { needed: u64, available: u64 },
    #[error("the bundle declares {declared} bytes but {actual} were given (trailing data)")]
    TrailingBytes { declared: u64, actual: u64 },
    #[error("the bundle is {bytes} bytes; at most {max} are accepted")]
    TooLarge { bytes: u64, max: u64 },
    #[error("malformed entry at byte {offset}: {reason}")]
    BadEntry { offset: u64, reason: &'static str },
    #[error("field `{0}` appears twice")]
    DuplicateField(String),
    #[error("field `{0}` is missing")]
    MissingField(String),
    #[error("field `{0}` is not part of this bundle version")]
    UnknownField(String),
    #[error("field `{field}` is {found}, expected {expected}")]
    WrongType { field: String, expected: String, found: String },
    #[error("field `{field}` is invalid: {reason}")]
    InvalidValue { field: String, reason: String },
    #[error(
        "the bundle was built for another kernel (fingerprint {found:08x}, this build has {expected:08x}): \
         rebuild the page and the server from the same source"
    )]
    OtherKernel { found: u32, expected: u32 },
    #[error("the bundle is inconsistent: {0}")]
    Inconsistent(String),
}

/// A bundle's content: the packed scene and its name.
#[derive(Clone, Debug)]
pub struct Bundle {
    /// What the scene is called (a file stem, `cornell-box`, ...); may be empty.
    pub name: String,
    pub packed: Packed,
}

/// Encodes `packed` with an empty name. See [`Bundle::encode`].
pub fn encode(packed: &Packed) -> Vec<u8> {
    encode_named("", packed)
}

/// Encodes `packed` under `name` (names longer than 255 bytes are cut at a character boundary).
pub fn encode_named(name: &str, packed: &Packed) -> Vec<u8> {
    let mut cut = name.len().min(u8::MAX as usize);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    let mut w = Writer::new();
    name[..cut].to_string().write(NAME_FIELD, &mut w);
    kernel_fingerprint().write(KERNEL_FIELD, &mut w);
    packed.write("", &mut w);
    w.finish()
}

/// Each entry's name and data, in the bundle's order (the container is checked, the data not
/// interpreted): what the bytes of a bundle are spent on.
pub fn entries(bytes: &[u8]) -> Result<Vec<(&str, &[u8])>, BundleError> {
    Ok(Reader::parse(bytes)?.entries().collect())
}

/// Decodes a bundle's packed scene (its name is dropped; see [`Bundle::decode`]).
pub fn decode(bytes: &[u8]) -> Result<Packed, BundleError> {
    Bundle::decode(bytes).map(|b| b.packed)
}

impl Bundle {
    /// The bundle's bytes. Deterministic: the same content always gives the same bytes.
    pub fn encode(&self) -> Vec<u8> {
        encode_named(&self.name, &self.packed)
    }

    /// Reads a bundle written by [`Bundle::encode`] / [`encode`] of the same [`VERSION`].
    pub fn decode(bytes: &[u8]) -> Result<Bundle, BundleError> {
        let mut r = Reader::parse(bytes)?;
        let name = String::read(NAME_FIELD, &mut r)?;
        let kernel = u32::read(KERNEL_FIELD, &mut r)?;
        if kernel != kernel_fingerprint() {
            return Err(BundleError::OtherKernel { found: kernel, expected: kernel_fingerprint() });
        }
        let packed = Packed::read("", &mut r)?;
        r.finish()?;
        check_consistency(&packed)?;
        Ok(Bundle { name, packed })
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::format::ElementType;
    use super::*;
    use crate::backend::cpu::CpuRenderer;
    use crate::backend::Renderer;
    use crate::kernel::features::RenderSettings;
    use crate::pack::pack;

    /// A file of the repository's vendored test data (`tests/data/`, see its README.md).
    fn test_data(rel: &str) -> std::path::PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data")).join(rel)
    }

    fn packed(scene: &crate::scene::Scene) -> Packed {
        let bvh = crate::bvh::build(&scene.triangles).expect("BVH");
        // A non-square image: the camera's aspect must survive the round trip too.
        pack(scene, &bvh, &RenderSettings { width: 24, height: 16, ..Default::default() }).expect("pack")
    }

    fn cornell() -> Packed {
        packed(&crate::scene::cornell_box())
    }

    /// The textured scene, with a sky so that the sky arrays are exercised as well.
    fn textured_with_sky() -> Packed {
        let mut scene =
            crate::scene::load(&test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf")).expect("BoxTextured");
        scene.sky =
            Some(crate::scene::load_sky(&test_data("scenes/hdri/venice_sunset_1k.hdr"), 1.0, 0.3).expect("sky"));
        let p = packed(&scene);
        assert!(p.features.textures && p.features.sky, "the scene must use textures and a sky: {:?}", p.features);
        p
    }

    fn render(p: Packed) -> crate::backend::Image {
        let mut r = CpuRenderer::new(p, 7);
        for _ in 0..3 {
            r.render_frame().expect("frame");
        }
        r.image().expect("image")
    }

    #[test]
    fn round_trip_renders_the_same_image_bit_for_bit() {
        for (name, p) in [("cornell-box", cornell()), ("BoxTextured+sky", textured_with_sky())] {
            let bytes = encode_named(name, &p);
            let back = Bundle::decode(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(back.name, name);
            assert_eq!(encode_named(name, &back.packed), bytes, "{name}: re-encoding differs");
            let (a, b) = (render(p), render(back.packed));
            let same = a
                .pixels
                .iter()
                .zip(&b.pixels)
                .all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits));
            assert!(same && a.pixels.len() == b.pixels.len(), "{name}: the decoded scene renders differently");
            assert!(a.mean().max_element() > 0.0, "{name}: a black image would prove nothing");
        }
    }

    #[test]
    fn encoding_is_deterministic_and_names_are_bounded() {
        let p = cornell();
        assert_eq!(encode(&p), encode(&p));
        let long = "é".repeat(200); // 400 bytes: cut to 254 (a character boundary)
        let b = Bundle::decode(&encode_named(&long, &p)).unwrap();
        assert_eq!(b.name, "é".repeat(127));
    }

    /// Byte offset of entry `name`'s element-type byte.
    fn entry_offset(bytes: &[u8], name: &str) -> usize {
        let mut needle = vec![name.len() as u8];
        needle.extend_from_slice(name.as_bytes());
        let at = bytes.windows(needle.len()).position(|w| w == needle).expect("entry present");
        at + needle.len()
    }

    #[test]
    fn bad_headers_are_typed_errors() {
        let good = encode(&cornell());
        let mut bad = good.clone();
        bad[0] = b'X';
        assert_eq!(decode(&bad).unwrap_err(), BundleError::BadMagic);
        assert_eq!(decode(b"GIF89a, not a bundle at all").unwrap_err(), BundleError::BadMagic);

        let mut bad = good.clone();
        bad[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes());
        assert_eq!(
            decode(&bad).unwrap_err(),
            BundleError::UnsupportedVersion { found: VERSION + 1, supported: VERSION }
        );

        let mut bad = good.clone();
        bad.push(0);
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::TrailingBytes { .. }));

        let mut bad = good.clone();
        bad[16..24].copy_from_slice(&(MAX_BUNDLE_BYTES + 1).to_le_bytes());
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::TooLarge { .. }));

        let mut bad = good.clone();
        bad[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::BadEntry { .. }));
    }

    #[test]
    fn every_truncation_is_reported_as_truncated() {
        let good = encode(&cornell());
        for len in 0..good.len() {
            match decode(&good[..len]) {
                Err(BundleError::Truncated { available, .. }) => assert_eq!(available, len as u64),
                other => panic!("prefix of {len} bytes: {other:?}"),
            }
        }
    }

    #[test]
    fn bad_entries_are_typed_errors() {
        let good = encode(&cornell());

        // A count so large that the size overflows, and one that points past the end.
        let count_at = |bytes: &[u8], name| entry_offset(bytes, name) + 4;
        let mut bad = good.clone();
        let at = count_at(&bad, "scene.triangles");
        bad[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::BadEntry { reason: "the data size overflows", .. }));
        let mut bad = good.clone();
        bad[at..at + 8].copy_from_slice(&(1u64 << 40).to_le_bytes());
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::Truncated { .. }));

        // Wrong element type, unknown element type, bad flag value.
        let mut bad = good.clone();
        let at = entry_offset(&bad, "scene.width");
        bad[at] = ElementType::F32 as u8;
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::WrongType { field, .. } if field == "scene.width"));
        bad[at] = 99;
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::BadEntry { reason: "unknown element type", .. }));
        let mut bad = good.clone();
        let at = entry_offset(&bad, "features.sky");
        let data = (at + 12).next_multiple_of(ALIGN);
        bad[data] = 2;
        assert!(
            matches!(decode(&bad).unwrap_err(), BundleError::InvalidValue { field, .. } if field == "features.sky")
        );

        // A renamed field is missing.
        let mut bad = good.clone();
        let at = entry_offset(&bad, "scene.nodes");
        bad[at - 1] = b'z';
        assert_eq!(decode(&bad).unwrap_err(), BundleError::MissingField("scene.nodes".into()));
    }

    #[test]
    fn compressed_entries_are_checked() {
        let good = encode(&textured_with_sky());
        let at = entry_offset(&good, "scene.sky");
        assert_eq!(good[at + 2], 1, "the sky is large enough to be compressed");
        let data = (at + 12).next_multiple_of(ALIGN);
        let stored = u64::from_le_bytes(good[data..data + 8].try_into().unwrap()) as usize;
        assert_eq!(stored, entries(&good).unwrap().iter().find(|e| e.0 == "scene.sky").unwrap().1.len());
        let bad_entry = |bytes: &[u8], says: &str| match decode(bytes).unwrap_err() {
            BundleError::BadEntry { reason, .. } => assert!(reason.contains(says), "{reason}"),
            other => panic!("expected a bad entry ({says}), got {other}"),
        };
        // Corrupt compressed data, a count it does not fill, an unknown encoding.
        let mut bad = good.clone();
        bad[data + 8 + stored / 2..data + 8 + stored / 2 + 16].fill(0x55);
        bad_entry(&bad, "corrupt");
        let mut bad = good.clone();
        let count = u64::from_le_bytes(good[at + 4..at + 12].try_into().unwrap());
        bad[at + 4..at + 12].copy_from_slice(&(count + 1).to_le_bytes());
        bad_entry(&bad, "corrupt or shorter");
        bad[at + 4..at + 12].copy_from_slice(&(count - 1).to_le_bytes());
        bad_entry(&bad, "longer than its count");
        bad[at + 4..at + 12].copy_from_slice(&(1u64 << 40).to_le_bytes());
        bad_entry(&bad, "more than 1 GiB");
        let mut bad = good.clone();
        bad[at + 2] = 7;
        bad_entry(&bad, "unknown encoding");
        // A stored length past the end.
        let mut bad = good;
        bad[data..data + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::Truncated { .. }));
    }

    #[test]
    fn a_bundle_from_another_kernel_is_refused() {
        let mut bad = encode(&cornell());
        let at = (entry_offset(&bad, KERNEL_FIELD) + 12).next_multiple_of(ALIGN);
        bad[at] ^= 1;
        assert!(matches!(decode(&bad).unwrap_err(), BundleError::OtherKernel { .. }));
    }

    #[test]
    fn unknown_duplicate_and_inconsistent_fields_are_refused() {
        let p = cornell();
        let with_extra = |extra: &dyn Fn(&mut Writer)| {
            let mut w = Writer::new();
            String::new().write(NAME_FIELD, &mut w);
            kernel_fingerprint().write(KERNEL_FIELD, &mut w);
            p.write("", &mut w);
            extra(&mut w);
            w.finish()
        };
        let extra = with_extra(&|w| 1u32.write("scene.future_field", w));
        assert_eq!(decode(&extra).unwrap_err(), BundleError::UnknownField("scene.future_field".into()));
        let twice = with_extra(&|w| 1u32.write("scene.width", w));
        assert_eq!(decode(&twice).unwrap_err(), BundleError::DuplicateField("scene.width".into()));

        let mut q = p.clone();
        q.triangle_count += 1;
        assert!(matches!(decode(&encode(&q)).unwrap_err(), BundleError::Inconsistent(_)));
        let mut q = p.clone();
        q.scene.width = 0;
        assert!(matches!(decode(&encode(&q)).unwrap_err(), BundleError::Inconsistent(_)));
        let mut q = p.clone();
        q.features.sky = true;
        assert!(matches!(decode(&encode(&q)).unwrap_err(), BundleError::Inconsistent(_)));
    }

    /// Random corruption: every outcome is a value (Ok when only data bytes changed), never a panic.
    #[test]
    fn corrupted_bundles_never_panic() {
        let good = encode(&cornell());
        let mut state = 0x2545_f491_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        for _ in 0..3000 {
            let mut bad = good.clone();
            for _ in 0..1 + next() % 4 {
                let i = next() as usize % bad.len();
                bad[i] = next() as u8;
            }
            let _ = decode(&bad);
        }
    }
}
