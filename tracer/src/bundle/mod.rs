//! Scene bundles: a packed scene ([`Packed`]: BVH built, texel arrays laid out, camera and
//! [`Features`]) as one self-describing binary blob, so a client (the web page, in wasm) renders a
//! scene without loading or building anything.
//!
//! Format (all integers little-endian):
//!
//! ```text
//! header   "LPBUNDLE" (8 bytes) | version: u32 | entry count: u32 | total length in bytes: u64
//! entry    name length: u8 | name (UTF-8) | element type: u8 | components: u8 | reserved: u16 (0)
//!          | count: u64 | zero padding to a multiple of 16 from the start of the bundle
//!          | data: count × components elements of the element type, little-endian
//! ```
//!
//! An entry is one field of [`Packed`], named by its path (`scene.triangles`, `features.sky`,
//! `triangle_count`), plus `meta.name` (the scene's name). A `Texels<Vec4>` is `f32` × 4 × texels,
//! a `Vec3` uniform `f32` × 3 × 1, a `u32` uniform `u32` × 1 × 1, a flag `u8` × 1 × 1 (0 or 1).
//! Data starts 16-byte aligned, so a reader may view the arrays in place.
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
//! No I/O and no threads here: the module compiles for `wasm32-unknown-unknown`.

use glam::{UVec4, Vec3, Vec4};
use kernel_dsl::Texels;

mod bounds;

use crate::kernel::scene_data::{Scene, LIGHT_TEXELS, TRIANGLE_TEXELS};
use crate::kernel::features::Features;
use crate::pack::Packed;

/// The first bytes of every bundle.
pub const MAGIC: [u8; 8] = *b"LPBUNDLE";
/// Bumped whenever the layout or the meaning of a field changes; readers accept only their own.
/// (2: node planes as float texels, `node_children`, `leaf_stack_limit`, triangle lights with
/// their normal and area. 3: `features.traversal_stack`, `features.metal_rough` and
/// `scene.metal_rough`. 4: `features.normal_map`, `scene.has_normal_map`, `scene.tangent_first`,
/// `scene.normal_map_first`. 5: `features.alpha_mask`, `scene.has_alpha_mask`,
/// `scene.alpha_mask_first`, the alpha-mask flag in each triangle's third texel. 6:
/// `features.texture_transform`, `features.texcoord1`, `scene.has_texture_transform`,
/// `scene.has_texcoord1`, `scene.texture_ref_first`, `scene.texcoord1_first`.)
pub const VERSION: u32 = 6;
/// The largest bundle accepted (and produced): well within wasm32's 4 GiB address space.
pub const MAX_BUNDLE_BYTES: u64 = 1 << 30;
/// File extension used for bundles (the server serves `/bundles/<hash>.lpb`).
pub const EXTENSION: &str = "lpb";

const HEADER_BYTES: usize = 8 + 4 + 4 + 8;
/// The longest path a bundle may ask for (the page's depth control goes as far).
pub const MAX_DEPTH: u32 = 64;
const ALIGN: usize = 16;
const NAME_FIELD: &str = "meta.name";
const KERNEL_FIELD: &str = "meta.kernel";

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

/// Cross-field checks: what the format alone cannot tell, and what would make a renderer
/// misbehave (an image size it cannot allocate, counts that disagree with the arrays).
fn check_consistency(p: &Packed) -> Result<(), BundleError> {
    let s = &p.scene;
    let fail = |what: String| Err(BundleError::Inconsistent(what));
    if !(1..=16384).contains(&s.width) || !(1..=16384).contains(&s.height) {
        return fail(format!("image size {}x{} (each side must be 1..=16384)", s.width, s.height));
    }
    // Uniforms the kernel takes as they are: a NaN scale or camera, an unbounded depth or an
    // unknown strategy would make every sample NaN, or a frame never end (found by fuzzing).
    let vectors = [
        ("camera_position", s.camera_position),
        ("camera_right", s.camera_right),
        ("camera_up", s.camera_up),
        ("camera_forward", s.camera_forward),
    ];
    if let Some((name, v)) = vectors.iter().find(|(_, v)| !v.is_finite()) {
        return fail(format!("{name} {v} is not finite"));
    }
    let scalars = [
        ("lens_radius", s.lens_radius, 0.0),
        ("focus_distance", s.focus_distance, f32::MIN_POSITIVE),
        ("sky_intensity", s.sky_intensity, 0.0),
        ("sky_rotation", s.sky_rotation, f32::MIN),
        ("scene_scale", s.scene_scale, 0.0),
    ];
    if let Some((name, v, min)) = scalars.iter().find(|(_, v, min)| !(v.is_finite() && v >= min)) {
        return fail(format!("{name} is {v} (must be finite and at least {min})"));
    }
    if !(1..=MAX_DEPTH).contains(&s.max_depth) {
        return fail(format!("max_depth {} (must be 1..={MAX_DEPTH})", s.max_depth));
    }
    if s.strategy > crate::kernel::scene_data::STRATEGY_MIS {
        return fail(format!("strategy {} (0, 1 or 2)", s.strategy));
    }
    let stack = crate::kernel::traverse::STACK_SIZE as u32;
    if s.leaf_stack_limit > stack {
        return fail(format!("leaf_stack_limit {} is above the traversal stack ({stack})", s.leaf_stack_limit));
    }
    // A GPU variant's stack is `traversal_stack` entries: the limit must keep pushes within it.
    let sized = p.features.traversal_stack;
    if sized > stack || (sized > 0 && s.leaf_stack_limit > sized) {
        return fail(format!(
            "traversal_stack {sized} with leaf_stack_limit {} (the stack is at most {stack} entries and holds the limit)",
            s.leaf_stack_limit
        ));
    }
    if Some(s.triangles.len()) != p.triangle_count.checked_mul(TRIANGLE_TEXELS as usize) {
        return fail(format!("{} triangle texels for {} triangles", s.triangles.len(), p.triangle_count));
    }
    if s.light_count as usize != p.light_count
        || Some(s.lights.len()) != p.light_count.checked_mul(LIGHT_TEXELS as usize)
    {
        return fail(format!("{} light texels, light count {} / {}", s.lights.len(), s.light_count, p.light_count));
    }
    let f = &p.features;
    let flags = [
        ("sky", f.sky, s.has_sky),
        ("textures", f.textures, s.has_textures),
        ("shading", f.shading, s.has_shading),
        ("lights", f.lights(), s.has_lights),
        ("triangle_lights", f.emissive_triangles, s.has_triangle_lights),
        ("point_lights", f.point_lights, s.has_point_lights),
        ("metal_rough", f.metal_rough, s.has_metal_rough),
        ("normal_map", f.normal_map, s.has_normal_map),
        ("alpha_mask", f.alpha_mask, s.has_alpha_mask),
        ("texture_transform", f.texture_transform, s.has_texture_transform),
        ("texcoord1", f.texcoord1, s.has_texcoord1),
    ];
    for (name, feature, flag) in flags {
        if flag != feature as u32 {
            return fail(format!("feature {name} is {feature} but the kernel flag has_{name} is {flag}"));
        }
    }
    // Normal maps' tangents extend `shading` at the offset the uniform gives; a reader trusting
    // a wrong offset would fetch beyond the array.
    if f.normal_map {
        let first = s.tangent_first as usize;
        // Where the tangents end (the second UV set, or the array's end) is `check_texture_refs`'s.
        if Some(first) != p.triangle_count.checked_mul(crate::kernel::scene_data::SHADING_TEXELS as usize) {
            return fail(format!(
                "normal maps: tangents from {} in {} shading texels, {} triangles",
                s.tangent_first,
                s.shading.len(),
                p.triangle_count
            ));
        }
    }
    check_material_sections(s, f)?;
    if f.sky
        && (s.sky.len() as u64 != s.sky_width as u64 * s.sky_height as u64 || s.sky_rows.len() != s.sky_height as usize)
    {
        return fail(format!(
            "sky {}x{} with {} texels and {} rows",
            s.sky_width,
            s.sky_height,
            s.sky.len(),
            s.sky_rows.len()
        ));
    }
    bounds::check_indices(p)
}

/// Element types of an entry's data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum ElementType {
    U8 = 1,
    U32 = 2,
    F32 = 3,
    U64 = 4,
}

impl ElementType {
    fn from_code(code: u8) -> Option<ElementType> {
        [ElementType::U8, ElementType::U32, ElementType::F32, ElementType::U64].into_iter().find(|t| *t as u8 == code)
    }

    fn size(self) -> u64 {
        match self {
            ElementType::U8 => 1,
            ElementType::U32 | ElementType::F32 => 4,
            ElementType::U64 => 8,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ElementType::U8 => "u8",
            ElementType::U32 => "u32",
            ElementType::F32 => "f32",
            ElementType::U64 => "u64",
        }
    }
}

fn describe(element: ElementType, components: u8, count: u64) -> String {
    format!("{} x {components} x {count}", element.name())
}

struct Writer {
    out: Vec<u8>,
    entries: u32,
}

impl Writer {
    fn new() -> Writer {
        let mut out = Vec::with_capacity(1 << 12);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&[0; 4 + 8]); // entry count and total length, patched in `finish`
        Writer { out, entries: 0 }
    }

    /// Appends one entry; `data` writes exactly `count * components` elements.
    fn entry(&mut self, name: &str, element: ElementType, components: u8, count: u64, data: impl FnOnce(&mut Vec<u8>)) {
        debug_assert!(name.len() <= u8::MAX as usize, "field names are short");
        self.out.push(name.len() as u8);
        self.out.extend_from_slice(name.as_bytes());
        self.out.extend_from_slice(&[element as u8, components, 0, 0]);
        self.out.extend_from_slice(&count.to_le_bytes());
        self.out.resize(self.out.len().next_multiple_of(ALIGN), 0);
        let start = self.out.len();
        self.out.reserve((count * components as u64 * element.size()) as usize);
        data(&mut self.out);
        debug_assert_eq!((self.out.len() - start) as u64, count * components as u64 * element.size());
        self.entries += 1;
    }

    fn finish(mut self) -> Vec<u8> {
        let total = self.out.len() as u64;
        self.out[12..16].copy_from_slice(&self.entries.to_le_bytes());
        self.out[16..24].copy_from_slice(&total.to_le_bytes());
        self.out
    }
}

/// One entry as read from the input, its data not yet interpreted.
struct Entry<'a> {
    name: &'a str,
    element: ElementType,
    components: u8,
    count: u64,
    data: &'a [u8],
    taken: bool,
}

struct Reader<'a> {
    entries: Vec<Entry<'a>>,
}

/// Bounds-checked cursor over the input.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: u64) -> Result<&'a [u8], BundleError> {
        let end = (self.at as u64).checked_add(n).filter(|end| *end <= self.bytes.len() as u64);
        let end = end.ok_or(BundleError::Truncated {
            needed: (self.at as u64).saturating_add(n),
            available: self.bytes.len() as u64,
        })? as usize;
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }

    fn u8(&mut self) -> Result<u8, BundleError> {
        Ok(self.take(1)?[0])
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], BundleError> {
        let mut a = [0; N];
        a.copy_from_slice(self.take(N as u64)?);
        Ok(a)
    }
}

impl<'a> Reader<'a> {
    /// Checks the header and splits the input into entries (no data is converted yet).
    fn parse(bytes: &'a [u8]) -> Result<Reader<'a>, BundleError> {
        let actual = bytes.len() as u64;
        if actual > MAX_BUNDLE_BYTES {
            return Err(BundleError::TooLarge { bytes: actual, max: MAX_BUNDLE_BYTES });
        }
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
            // A prefix of the magic is a truncated bundle, anything else is not a bundle.
            return Err(if MAGIC.starts_with(bytes) {
                BundleError::Truncated { needed: HEADER_BYTES as u64, available: actual }
            } else {
                BundleError::BadMagic
            });
        }
        let mut c = Cursor { bytes, at: MAGIC.len() };
        let header = |c: &mut Cursor<'a>| -> Result<(u32, u32, u64), BundleError> {
            Ok((u32::from_le_bytes(c.array()?), u32::from_le_bytes(c.array()?), u64::from_le_bytes(c.array()?)))
        };
        let (version, entry_count, declared) =
            header(&mut c).map_err(|_| BundleError::Truncated { needed: HEADER_BYTES as u64, available: actual })?;
        if version != VERSION {
            return Err(BundleError::UnsupportedVersion { found: version, supported: VERSION });
        }
        if declared > MAX_BUNDLE_BYTES {
            return Err(BundleError::TooLarge { bytes: declared, max: MAX_BUNDLE_BYTES });
        }
        if actual < declared {
            return Err(BundleError::Truncated { needed: declared, available: actual });
        }
        if actual > declared {
            return Err(BundleError::TrailingBytes { declared, actual });
        }
        // Every entry takes at least 16 bytes: a count beyond that is corrupt (and would
        // otherwise size an allocation).
        if entry_count as u64 > actual / 16 {
            return Err(BundleError::BadEntry { offset: 12, reason: "more entries than the bundle can hold" });
        }
        let mut entries: Vec<Entry<'a>> = Vec::with_capacity(entry_count as usize);
        for _ in 0..entry_count {
            let offset = c.at as u64;
            let bad = |reason| BundleError::BadEntry { offset, reason };
            let name_len = c.u8()?;
            let name = std::str::from_utf8(c.take(name_len as u64)?).map_err(|_| bad("the name is not UTF-8"))?;
            let [element, components, reserved @ ..] = c.array::<4>()?;
            let element = ElementType::from_code(element).ok_or(bad("unknown element type"))?;
            if components == 0 || reserved != [0, 0] {
                return Err(bad("zero components or non-zero reserved bytes"));
            }
            let count = u64::from_le_bytes(c.array()?);
            let padding = c.take((c.at.next_multiple_of(ALIGN) - c.at) as u64)?;
            if padding.iter().any(|b| *b != 0) {
                return Err(bad("non-zero padding"));
            }
            let len = count
                .checked_mul(components as u64)
                .and_then(|n| n.checked_mul(element.size()))
                .ok_or(bad("the data size overflows"))?;
            let data = c.take(len)?;
            if entries.iter().any(|e| e.name == name) {
                return Err(BundleError::DuplicateField(name.to_string()));
            }
            entries.push(Entry { name, element, components, count, data, taken: false });
        }
        if c.at != bytes.len() {
            return Err(BundleError::BadEntry { offset: c.at as u64, reason: "bytes after the last entry" });
        }
        Ok(Reader { entries })
    }

    /// The entry `name`, which must hold `components`-element values of type `element`.
    fn take(&mut self, name: &str, element: ElementType, components: u8) -> Result<&Entry<'a>, BundleError> {
        let entry = self
            .entries
            .iter_mut()
            .find(|e| e.name == name)
            .ok_or_else(|| BundleError::MissingField(name.to_string()))?;
        if entry.element != element || entry.components != components {
            return Err(BundleError::WrongType {
                field: name.to_string(),
                expected: format!("{} x {components}", element.name()),
                found: describe(entry.element, entry.components, entry.count),
            });
        }
        entry.taken = true;
        Ok(entry)
    }

    /// A single value (count 1).
    fn scalar(&mut self, name: &str, element: ElementType, components: u8) -> Result<&[u8], BundleError> {
        let entry = self.take(name, element, components)?;
        if entry.count != 1 {
            return Err(BundleError::WrongType {
                field: name.to_string(),
                expected: format!("{} x {components} x 1", element.name()),
                found: describe(entry.element, entry.components, entry.count),
            });
        }
        Ok(entry.data)
    }

    fn finish(self) -> Result<(), BundleError> {
        match self.entries.iter().find(|e| !e.taken) {
            Some(e) => Err(BundleError::UnknownField(e.name.to_string())),
            None => Ok(()),
        }
    }
}

fn f32s(data: &[u8]) -> impl Iterator<Item = f32> + '_ {
    data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

fn u32s(data: &[u8]) -> impl Iterator<Item = u32> + '_ {
    data.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// A value stored in a bundle under a name.
trait Field: Sized {
    fn write(&self, name: &str, w: &mut Writer);
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError>;
}

/// A fixed-size texel or vector: `COMPONENTS` elements of one type.
trait Texel: Copy + Default {
    const ELEMENT: ElementType;
    const COMPONENTS: u8;
    fn put(&self, out: &mut Vec<u8>);
    fn get(data: &[u8]) -> Vec<Self>;
}

impl Texel for Vec4 {
    const ELEMENT: ElementType = ElementType::F32;
    const COMPONENTS: u8 = 4;
    fn put(&self, out: &mut Vec<u8>) {
        for c in self.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(data: &[u8]) -> Vec<Self> {
        let v: Vec<f32> = f32s(data).collect();
        v.chunks_exact(4).map(Vec4::from_slice).collect()
    }
}

impl Texel for UVec4 {
    const ELEMENT: ElementType = ElementType::U32;
    const COMPONENTS: u8 = 4;
    fn put(&self, out: &mut Vec<u8>) {
        for c in self.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(data: &[u8]) -> Vec<Self> {
        let v: Vec<u32> = u32s(data).collect();
        v.chunks_exact(4).map(UVec4::from_slice).collect()
    }
}

impl Texel for Vec3 {
    const ELEMENT: ElementType = ElementType::F32;
    const COMPONENTS: u8 = 3;
    fn put(&self, out: &mut Vec<u8>) {
        for c in self.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(data: &[u8]) -> Vec<Self> {
        let v: Vec<f32> = f32s(data).collect();
        v.chunks_exact(3).map(Vec3::from_slice).collect()
    }
}

impl Texel for f32 {
    const ELEMENT: ElementType = ElementType::F32;
    const COMPONENTS: u8 = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn get(data: &[u8]) -> Vec<Self> {
        f32s(data).collect()
    }
}

impl Texel for u32 {
    const ELEMENT: ElementType = ElementType::U32;
    const COMPONENTS: u8 = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn get(data: &[u8]) -> Vec<Self> {
        u32s(data).collect()
    }
}

impl<T: Texel> Field for Texels<T> {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, T::ELEMENT, T::COMPONENTS, self.len() as u64, |out| {
            for t in self.as_slice() {
                t.put(out);
            }
        });
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        Ok(Texels::new(T::get(r.take(name, T::ELEMENT, T::COMPONENTS)?.data)))
    }
}

/// Uniforms: one texel-like value.
macro_rules! single_value_fields {
    ($($ty:ty),*) => {$(
        impl Field for $ty {
            fn write(&self, name: &str, w: &mut Writer) {
                w.entry(name, <$ty as Texel>::ELEMENT, <$ty as Texel>::COMPONENTS, 1, |out| self.put(out));
            }
            fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
                let data = r.scalar(name, <$ty as Texel>::ELEMENT, <$ty as Texel>::COMPONENTS)?;
                Ok(<$ty as Texel>::get(data)[0])
            }
        }
    )*};
}
single_value_fields!(Vec3, f32, u32);

impl Field for bool {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, ElementType::U8, 1, 1, |out| out.push(*self as u8));
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        match r.scalar(name, ElementType::U8, 1)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(BundleError::InvalidValue { field: name.to_string(), reason: format!("flag {v} is not 0 or 1") }),
        }
    }
}

impl Field for usize {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, ElementType::U64, 1, 1, |out| out.extend_from_slice(&(*self as u64).to_le_bytes()));
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let data = r.scalar(name, ElementType::U64, 1)?;
        let v = u64::from_le_bytes(data.try_into().expect("a u64 entry of count 1 holds 8 bytes"));
        usize::try_from(v).map_err(|_| BundleError::InvalidValue {
            field: name.to_string(),
            reason: format!("{v} does not fit this platform's usize"),
        })
    }
}

impl Field for String {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, ElementType::U8, 1, self.len() as u64, |out| out.extend_from_slice(self.as_bytes()));
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let data = r.take(name, ElementType::U8, 1)?.data;
        String::from_utf8(data.to_vec())
            .map_err(|_| BundleError::InvalidValue { field: name.to_string(), reason: "not UTF-8".into() })
    }
}

fn field_name(prefix: &str, field: &str) -> String {
    if prefix.is_empty() {
        field.to_string()
    } else {
        format!("{prefix}.{field}")
    }
}

/// A struct stored field by field under `<prefix>.<field>`. The destructuring pattern and the
/// struct literal both name every field (no `..`): a field added to the struct is a compile
/// error here until it is listed, and the list cannot name a field the struct lacks.
macro_rules! record {
    ($ty:ident { $($field:ident),* $(,)? }) => {
        impl Field for $ty {
            fn write(&self, prefix: &str, w: &mut Writer) {
                let $ty { $($field),* } = self;
                $( $field.write(&field_name(prefix, stringify!($field)), w); )*
            }
            fn read(prefix: &str, r: &mut Reader) -> Result<Self, BundleError> {
                Ok($ty { $($field: Field::read(&field_name(prefix, stringify!($field)), r)?),* })
            }
        }
    };
}

record!(Packed { scene, features, triangle_count, light_count });
record!(Features {
    sky,
    textures,
    shading,
    point_lights,
    emissive_triangles,
    metal_rough,
    normal_map,
    alpha_mask,
    texture_transform,
    texcoord1,
    traversal_stack
});
record!(Scene {
    triangles,
    shading,
    nodes,
    node_children,
    materials,
    lights,
    texture_texels,
    texture_info,
    sky,
    sky_rows,
    metal_rough,
    tangent_first,
    normal_map_first,
    alpha_mask_first,
    texture_ref_first,
    texcoord1_first,
    camera_position,
    camera_right,
    camera_up,
    camera_forward,
    lens_radius,
    focus_distance,
    width,
    height,
    frame_seed,
    max_depth,
    strategy,
    light_count,
    sky_width,
    sky_height,
    sky_intensity,
    sky_rotation,
    scene_scale,
    leaf_stack_limit,
    has_sky,
    has_textures,
    has_shading,
    has_lights,
    has_triangle_lights,
    has_point_lights,
    has_metal_rough,
    has_normal_map,
    has_alpha_mask,
    has_texture_transform,
    has_texcoord1,
});

/// `materials` holds the base texels of `n` materials (`MATERIAL_TEXELS` each), then with
/// normal maps one texel each from `normal_map_first`, then with alpha masks one texel each
/// from `alpha_mask_first`, and nothing else: the offsets the uniforms give must be those.
fn check_material_sections(s: &Scene, f: &Features) -> Result<(), BundleError> {
    use crate::kernel::scene_data::MATERIAL_TEXELS;
    let per = MATERIAL_TEXELS as usize + f.normal_map as usize + f.alpha_mask as usize;
    let n = s.materials.len() / per;
    let maps = if f.normal_map { MATERIAL_TEXELS as usize * n } else { 0 };
    let masks = if f.alpha_mask { (MATERIAL_TEXELS as usize + f.normal_map as usize) * n } else { 0 };
    if !s.materials.len().is_multiple_of(per)
        || s.normal_map_first as usize != maps
        || s.alpha_mask_first as usize != masks
    {
        return Err(BundleError::Inconsistent(format!(
            "{} material texels (normal maps {}, alpha masks {}) with normal maps from {} and alpha masks from {}",
            s.materials.len(),
            f.normal_map,
            f.alpha_mask,
            s.normal_map_first,
            s.alpha_mask_first
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

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
