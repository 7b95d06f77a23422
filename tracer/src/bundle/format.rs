//! The container: header, entries (name, element type, components, count, encoding), 16-byte
//! aligned data. Writing appends entries; reading splits the input into entries, bounds-checked,
//! and decompresses the compressed ones before any data is converted.
//!
//! Numeric arrays over [`COMPRESS_FROM`] bytes are stored LZMA2-compressed ([`Encoding::Lzma2`]):
//! the scene's geometry (triangles, shading data, nodes, lights) is floats with random low bits,
//! which gzip (what HTTP gives browsers) shrinks to 30-45 % and LZMA2, tuned to 16-byte texels, to
//! 25 % (DamagedHelmet: 3.56 MB raw, 1.40 MB gzip, 0.89 MB LZMA2). Image files are stored as they are.

use std::borrow::Cow;
use std::io::{Read, Write};

use super::{BundleError, ALIGN, HEADER_BYTES, MAGIC, MAX_BUNDLE_BYTES, VERSION};

/// Numeric entries with more data than this are compressed.
const COMPRESS_FROM: usize = 4096;
/// The LZMA2 dictionary: the largest arrays of the benchmark scenes fit in it.
const LZMA_DICT_BYTES: u32 = 8 << 20;
/// The most bytes a bundle's compressed entries may decode to (a compressed entry declares its
/// size; this bounds what a small, malicious bundle can make a reader allocate).
const MAX_DECODED_BYTES: u64 = 1 << 30;

/// How an entry's data is stored (the first reserved byte of its header).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum Encoding {
    /// The elements themselves.
    Plain = 0,
    /// The stored length (u64), then an LZMA2 stream of the elements (`lc = 0, lp = pb = 4`:
    /// literals and matches aligned to 16-byte texels), dictionary [`LZMA_DICT_BYTES`].
    Lzma2 = 1,
}

/// Element types of an entry's data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub(super) enum ElementType {
    U8 = 1,
    U32 = 2,
    F32 = 3,
    U64 = 4,
}

impl ElementType {
    pub(super) fn from_code(code: u8) -> Option<ElementType> {
        [ElementType::U8, ElementType::U32, ElementType::F32, ElementType::U64].into_iter().find(|t| *t as u8 == code)
    }

    pub(super) fn size(self) -> u64 {
        match self {
            ElementType::U8 => 1,
            ElementType::U32 | ElementType::F32 => 4,
            ElementType::U64 => 8,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            ElementType::U8 => "u8",
            ElementType::U32 => "u32",
            ElementType::F32 => "f32",
            ElementType::U64 => "u64",
        }
    }
}

pub(super) fn describe(element: ElementType, components: u8, count: u64) -> String {
    format!("{} x {components} x {count}", element.name())
}

/// Collects entries; [`Writer::finish`] compresses the large ones (in parallel) and lays them out.
pub(super) struct Writer {
    entries: Vec<PendingEntry>,
}

struct PendingEntry {
    name: String,
    element: ElementType,
    components: u8,
    count: u64,
    bytes: Vec<u8>,
}

impl PendingEntry {
    fn encoding(&self) -> Encoding {
        if self.element != ElementType::U8 && self.bytes.len() > COMPRESS_FROM {
            Encoding::Lzma2
        } else {
            Encoding::Plain
        }
    }
}

impl Writer {
    pub(super) fn new() -> Writer {
        Writer { entries: Vec::new() }
    }

    /// Appends one entry; `data` writes exactly `count * components` elements.
    pub(super) fn entry(
        &mut self,
        name: &str,
        element: ElementType,
        components: u8,
        count: u64,
        data: impl FnOnce(&mut Vec<u8>),
    ) {
        debug_assert!(name.len() <= u8::MAX as usize, "field names are short");
        let mut bytes = Vec::with_capacity((count * components as u64 * element.size()) as usize);
        data(&mut bytes);
        debug_assert_eq!(bytes.len() as u64, count * components as u64 * element.size());
        self.entries.push(PendingEntry { name: name.to_string(), element, components, count, bytes });
    }

    pub(super) fn finish(self) -> Vec<u8> {
        use rayon::prelude::*;
        let stored: Vec<Option<Vec<u8>>> =
            self.entries.par_iter().map(|e| (e.encoding() == Encoding::Lzma2).then(|| lzma2(&e.bytes))).collect();
        let mut out = Vec::with_capacity(1 << 12);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(self.entries.len() as u32).to_le_bytes());
        out.extend_from_slice(&[0; 8]); // the total length, patched below
        for (e, stored) in self.entries.iter().zip(stored) {
            out.push(e.name.len() as u8);
            out.extend_from_slice(e.name.as_bytes());
            out.extend_from_slice(&[e.element as u8, e.components, e.encoding() as u8, 0]);
            out.extend_from_slice(&e.count.to_le_bytes());
            out.resize(out.len().next_multiple_of(ALIGN), 0);
            match stored {
                None => out.extend_from_slice(&e.bytes),
                Some(stored) => {
                    out.extend_from_slice(&(stored.len() as u64).to_le_bytes());
                    out.extend_from_slice(&stored);
                }
            }
        }
        let total = out.len() as u64;
        out[16..24].copy_from_slice(&total.to_le_bytes());
        out
    }
}

fn lzma2(bytes: &[u8]) -> Vec<u8> {
    let mut options = lzma_rust2::Lzma2Options::with_preset(6);
    options.lzma_options.dict_size = LZMA_DICT_BYTES;
    (options.lzma_options.lc, options.lzma_options.lp, options.lzma_options.pb) = (0, 4, 4);
    let mut writer = lzma_rust2::Lzma2Writer::new(Vec::new(), options);
    writer.write_all(bytes).expect("compressing into memory cannot fail");
    writer.finish().expect("compressing into memory cannot fail")
}

/// Decompresses exactly `len` bytes from `stored`, which must hold nothing more.
fn unlzma2(stored: &[u8], len: u64) -> Result<Vec<u8>, &'static str> {
    let mut reader = lzma_rust2::Lzma2Reader::new(stored, LZMA_DICT_BYTES, None);
    let mut out = vec![0; len as usize];
    reader.read_exact(&mut out).map_err(|_| "the compressed data is corrupt or shorter than its count")?;
    match reader.read(&mut [0]) {
        Ok(0) => Ok(out),
        _ => Err("the compressed data is longer than its count"),
    }
}

/// One entry as read from the input, its data not yet interpreted.
pub(super) struct Entry<'a> {
    name: &'a str,
    element: ElementType,
    components: u8,
    count: u64,
    /// The bytes as stored in the bundle (compressed or not).
    stored: &'a [u8],
    /// The elements (decompressed), or `None` for a compressed entry left compressed
    /// ([`Reader::headers`]).
    data: Option<Cow<'a, [u8]>>,
    /// Where its header starts in the input.
    offset: u64,
    taken: bool,
}

impl<'a> Entry<'a> {
    /// The elements: an entry left compressed is an error (see [`Reader::headers`]).
    pub(super) fn data(&self) -> Result<&[u8], BundleError> {
        self.data.as_deref().ok_or(self.left_compressed())
    }

    /// [`data`](Self::data) as an owned handle (a copy only where it was decompressed).
    pub(super) fn data_cow(&self) -> Result<Cow<'a, [u8]>, BundleError> {
        self.data.clone().ok_or(self.left_compressed())
    }

    fn left_compressed(&self) -> BundleError {
        BundleError::BadEntry { offset: self.offset, reason: "compressed, and not decompressed by a peek" }
    }
}

pub(super) struct Reader<'a> {
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
    /// Checks the header and splits the input into entries, decompressing the compressed ones
    /// (no data is converted yet).
    pub(super) fn parse(bytes: &'a [u8]) -> Result<Reader<'a>, BundleError> {
        Self::split(bytes, true)
    }

    /// [`parse`](Self::parse) without decompressing anything: the header and every entry's
    /// header are checked, the plain entries can be read, and reading a compressed one is an
    /// error. For peeking at a bundle's small entries (`bundle::peek_features`) in a fraction
    /// of what decoding it takes.
    pub(super) fn headers(bytes: &'a [u8]) -> Result<Reader<'a>, BundleError> {
        Self::split(bytes, false)
    }

    fn split(bytes: &'a [u8], decompress: bool) -> Result<Reader<'a>, BundleError> {
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
        let mut decoded = 0u64;
        for _ in 0..entry_count {
            let offset = c.at as u64;
            let bad = |reason| BundleError::BadEntry { offset, reason };
            let name_len = c.u8()?;
            let name = std::str::from_utf8(c.take(name_len as u64)?).map_err(|_| bad("the name is not UTF-8"))?;
            let [element, components, encoding, reserved] = c.array::<4>()?;
            let element = ElementType::from_code(element).ok_or(bad("unknown element type"))?;
            if components == 0 || reserved != 0 {
                return Err(bad("zero components or a non-zero reserved byte"));
            }
            let encoding = [Encoding::Plain, Encoding::Lzma2]
                .into_iter()
                .find(|e| *e as u8 == encoding)
                .ok_or(bad("unknown encoding"))?;
            let count = u64::from_le_bytes(c.array()?);
            let padding = c.take((c.at.next_multiple_of(ALIGN) - c.at) as u64)?;
            if padding.iter().any(|b| *b != 0) {
                return Err(bad("non-zero padding"));
            }
            let len = count
                .checked_mul(components as u64)
                .and_then(|n| n.checked_mul(element.size()))
                .ok_or(bad("the data size overflows"))?;
            if entries.iter().any(|e| e.name == name) {
                return Err(BundleError::DuplicateField(name.to_string()));
            }
            let (stored, data) = match encoding {
                Encoding::Plain => {
                    let data = c.take(len)?;
                    (data, Some(Cow::Borrowed(data)))
                }
                Encoding::Lzma2 => {
                    decoded = decoded.saturating_add(len);
                    if decoded > MAX_DECODED_BYTES {
                        return Err(bad("the compressed entries decode to more than 1 GiB"));
                    }
                    let stored_len = u64::from_le_bytes(c.array()?);
                    let stored = c.take(stored_len)?;
                    let data = if decompress { Some(Cow::Owned(unlzma2(stored, len).map_err(bad)?)) } else { None };
                    (stored, data)
                }
            };
            entries.push(Entry { name, element, components, count, stored, data, offset, taken: false });
        }
        if c.at != bytes.len() {
            return Err(BundleError::BadEntry { offset: c.at as u64, reason: "bytes after the last entry" });
        }
        Ok(Reader { entries })
    }

    /// Every entry's name and its bytes as stored (compressed or not), in order.
    pub(super) fn entries(&self) -> impl Iterator<Item = (&'a str, &'a [u8])> + '_ {
        self.entries.iter().map(|e| (e.name, e.stored))
    }

    /// The entry `name`, which must hold `components`-element values of type `element`.
    pub(super) fn take(&mut self, name: &str, element: ElementType, components: u8) -> Result<&Entry<'a>, BundleError> {
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

    /// Whether the bundle has an entry `name` (for optional sections).
    pub(super) fn has(&self, name: &str) -> bool {
        self.entries.iter().any(|e| e.name == name)
    }

    /// A single value (count 1).
    pub(super) fn scalar(&mut self, name: &str, element: ElementType, components: u8) -> Result<&[u8], BundleError> {
        let entry = self.take(name, element, components)?;
        if entry.count != 1 {
            return Err(BundleError::WrongType {
                field: name.to_string(),
                expected: format!("{} x {components} x 1", element.name()),
                found: describe(entry.element, entry.components, entry.count),
            });
        }
        entry.data()
    }

    pub(super) fn finish(self) -> Result<(), BundleError> {
        match self.entries.iter().find(|e| !e.taken) {
            Some(e) => Err(BundleError::UnknownField(e.name.to_string())),
            None => Ok(()),
        }
    }
}

pub(super) fn f32s(data: &[u8]) -> impl Iterator<Item = f32> + '_ {
    data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

pub(super) fn u32s(data: &[u8]) -> impl Iterator<Item = u32> + '_ {
    data.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}
