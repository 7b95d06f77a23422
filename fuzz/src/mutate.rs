//! Mutations: byte-level ones for any input, and structure-aware ones that keep an input
//! parseable while changing what it says (a glTF accessor's count, a bundle entry's length, a
//! request's Content-Length), so the fuzzers get past the parsers into the code behind them.

use serde_json::{Number, Value};

use crate::rng::Rng;
use crate::Target;

/// Integers at the edges of the types and sizes a loader checks.
pub const INTERESTING: [i64; 28] = [
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    16,
    255,
    256,
    4095,
    4096,
    5121,
    5123,
    5125,
    5126,
    65535,
    65536,
    (1 << 24) + 1,
    i32::MAX as i64,
    1 << 31,
    u32::MAX as i64,
    1 << 32,
    (1 << 32) + 4,
    1 << 34,
    1 << 53,
    -1,
    i32::MIN as i64,
];

/// An interesting integer, or one near `around`.
fn interesting(rng: &mut Rng, around: i64) -> i64 {
    match rng.below(6) {
        0 => around.wrapping_add(1),
        1 => around.wrapping_sub(1),
        2 => around.wrapping_mul(2),
        3 => around.wrapping_add(4),
        _ => *rng.pick(&INTERESTING).unwrap_or(&0),
    }
}

/// A structure-aware mutation of `data` for `target`; `None` when the input does not parse
/// (the caller then falls back to byte-level mutations).
pub fn structured(target: Target, data: &[u8], rng: &mut Rng) -> Option<Vec<u8>> {
    match target {
        Target::Gltf => gltf(data, rng),
        Target::Bundle => bundle(data, rng),
        Target::Http => Some(http(data, rng)),
        Target::Obj => Some(text_lines(data, rng, OBJ_WORDS)),
        Target::Texture | Target::Sky => None,
    }
}

/// Applies 1 to 4 random byte-level mutations; `other` is a second input to splice from.
pub fn bytes(data: &mut Vec<u8>, rng: &mut Rng, other: &[u8], max_len: usize) {
    for _ in 0..1 + rng.below(4) {
        let len = data.len();
        match rng.below(9) {
            0 if len > 0 => {
                let at = rng.below(len);
                data[at] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let at = rng.below(len);
                data[at] = *rng.pick(&[0u8, 1, 0x7f, 0x80, 0xff, b'0', b'9', b'"', b'{', b'\n']).unwrap_or(&0);
            }
            2 if len >= 4 => {
                // An interesting integer, little-endian, at an aligned or unaligned offset.
                let width = *rng.pick(&[2usize, 4, 8]).unwrap_or(&4);
                let at = rng.below(len.saturating_sub(width) + 1);
                let v = interesting(rng, 0).to_le_bytes();
                let end = (at + width).min(len);
                data[at..end].copy_from_slice(&v[..end - at]);
            }
            3 => data.truncate(rng.below(len + 1)),
            4 if len > 0 => {
                let at = rng.below(len);
                let n = 1 + rng.below((len - at).min(64));
                data.drain(at..at + n);
            }
            5 if len > 0 => {
                let at = rng.below(len);
                let n = 1 + rng.below((len - at).min(64));
                let copy = data[at..at + n].to_vec();
                let to = rng.below(len + 1);
                data.splice(to..to, copy);
            }
            6 => {
                let at = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let junk: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
                data.splice(at..at, junk);
            }
            7 if !other.is_empty() => {
                // Splice: our head, the other input's tail.
                let cut = rng.below(len + 1);
                let from = rng.below(other.len());
                data.truncate(cut);
                data.extend_from_slice(&other[from..]);
            }
            _ if len > 1 => {
                let (a, b) = (rng.below(len), rng.below(len));
                data.swap(a, b);
            }
            _ => data.push(rng.next_u64() as u8),
        }
    }
    data.truncate(max_len);
}

// ---------------------------------------------------------------------------------------------
// glTF

/// Members a glTF loader reads sizes and references from.
const GLTF_KEYS: [&str; 20] = [
    "byteOffset",
    "byteLength",
    "byteStride",
    "count",
    "componentType",
    "bufferView",
    "buffer",
    "indices",
    "mode",
    "material",
    "source",
    "sampler",
    "mesh",
    "camera",
    "index",
    "texCoord",
    "scene",
    "yfov",
    "normalized",
    "children",
];

const GLTF_STRINGS: [&str; 10] = [
    "",
    "data:application/octet-stream;base64,",
    "data:application/octet-stream;base64,AAAAAAAAAAAAAAAA",
    "data:image/png;base64,iVBORw0KGgo=",
    "../outside.bin",
    "%ZZ",
    "VEC3",
    "MAT4",
    "SCALAR",
    "KHR_draco_mesh_compression",
];

/// A JSON-aware mutation of a `.gltf` or of a `.glb`'s JSON chunk (the GLB is rebuilt with
/// consistent chunk lengths, its BIN chunk kept).
pub fn gltf(data: &[u8], rng: &mut Rng) -> Option<Vec<u8>> {
    if let Some((json, bin)) = crate::glb::split(data) {
        let json = gltf_json(json, rng)?;
        return Some(crate::glb::build(&json, bin));
    }
    gltf_json(data, rng)
}

fn gltf_json(json: &[u8], rng: &mut Rng) -> Option<Vec<u8>> {
    let mut root: Value = serde_json::from_slice(json).ok()?;
    for _ in 0..1 + rng.below(3) {
        mutate_value(&mut root, rng);
    }
    serde_json::to_vec(&root).ok()
}

/// JSON pointers to every value in `v`, with the value's kind.
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(o) => {
            for (k, child) in o {
                pointers(child, format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")), out);
            }
        }
        Value::Array(a) => {
            for (i, child) in a.iter().enumerate() {
                pointers(child, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
    out.push(at);
}

fn mutate_value(root: &mut Value, rng: &mut Rng) {
    let mut all = Vec::new();
    pointers(root, String::new(), &mut all);
    let numbers: Vec<&String> = all.iter().filter(|p| root.pointer(p).is_some_and(Value::is_number)).collect();
    let choice = rng.below(11);
    match choice {
        // Most often: a number becomes an interesting one (sizes, offsets, indices, enums).
        0..=3 if !numbers.is_empty() => {
            let p = rng.pick(&numbers).map(|p| p.to_string()).unwrap_or_default();
            if let Some(v) = root.pointer_mut(&p) {
                let old = v.as_i64().unwrap_or(0);
                *v = if rng.one_in(8) {
                    Value::Number(
                        Number::from_f64(*rng.pick(&[0.5, -0.0, 1e308, -1e308, 1e-45]).unwrap_or(&0.5))
                            .unwrap_or(0.into()),
                    )
                } else {
                    Value::Number(interesting(rng, old).into())
                };
            }
        }
        4 => {
            // Add (or overwrite) a member the loader reads, in a random object.
            let objects: Vec<&String> = all.iter().filter(|p| root.pointer(p).is_some_and(Value::is_object)).collect();
            let p = rng.pick(&objects).map(|p| p.to_string()).unwrap_or_default();
            let key = rng.pick(&GLTF_KEYS).copied().unwrap_or("count");
            let value = Value::Number(interesting(rng, 0).into());
            if let Some(Value::Object(o)) = root.pointer_mut(&p) {
                o.insert(key.to_owned(), value);
            }
        }
        5 => {
            // Remove a member or an array element.
            if let Some(p) = rng.pick(&all).cloned() {
                if let Some((parent, last)) = p.rsplit_once('/') {
                    match root.pointer_mut(parent) {
                        Some(Value::Object(o)) => {
                            o.remove(&last.replace("~1", "/").replace("~0", "~"));
                        }
                        Some(Value::Array(a)) => {
                            if let Ok(i) = last.parse::<usize>() {
                                if i < a.len() {
                                    a.remove(i);
                                }
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
        6 => {
            // Duplicate an array element (more nodes, accessors, primitives...; or a cycle).
            let arrays: Vec<&String> = all
                .iter()
                .filter(|p| root.pointer(p).is_some_and(|v| v.as_array().is_some_and(|a| !a.is_empty())))
                .collect();
            // (No non-empty array: nothing to do. Defaulting to the root, as the other cases
            // may, indexed an empty root array and panicked: found by the gltf run's silent end.)
            let Some(p) = rng.pick(&arrays).map(|p| p.to_string()) else { return };
            if let Some(Value::Array(a)) = root.pointer_mut(&p) {
                if let Some(copy) = a.get(rng.below(a.len())).cloned() {
                    a.push(copy);
                }
            }
        }
        7 => {
            // A string becomes an interesting one (URIs, types, extension names).
            let strings: Vec<&String> = all.iter().filter(|p| root.pointer(p).is_some_and(Value::is_string)).collect();
            let p = rng.pick(&strings).map(|p| p.to_string()).unwrap_or_default();
            let s = rng.pick(&GLTF_STRINGS).copied().unwrap_or("");
            if let Some(v) = root.pointer_mut(&p) {
                *v = Value::String(s.to_owned());
            }
        }
        8 => {
            // Swap two numbers (e.g. a count and an offset).
            if numbers.len() >= 2 {
                let a = rng.pick(&numbers).map(|p| p.to_string()).unwrap_or_default();
                let b = rng.pick(&numbers).map(|p| p.to_string()).unwrap_or_default();
                let va = root.pointer(&a).cloned();
                let vb = root.pointer(&b).cloned();
                if let (Some(va), Some(vb)) = (va, vb) {
                    if let Some(x) = root.pointer_mut(&a) {
                        *x = vb;
                    }
                    if let Some(x) = root.pointer_mut(&b) {
                        *x = va;
                    }
                }
            }
        }
        9 => grow_accessor_count(root, rng),
        _ => {
            // A reference to a small index (often out of range, or self-referencing).
            let p = rng.pick(&numbers).map(|p| p.to_string()).unwrap_or_default();
            if let Some(v) = root.pointer_mut(&p) {
                *v = Value::Number((rng.below(6) as i64).into());
            }
        }
    }
}
/// An accessor's count grown (doubled, times up to 100,000, or to 3,000,000), half the time
/// with its buffer view dropped: the specification zero-fills such an accessor, so a few bytes
/// of JSON declare millions of coincident vertices (issue 31's hang was one; the loader and
/// the BVH build must stay O(n log n) on them).
fn grow_accessor_count(root: &mut Value, rng: &mut Rng) {
    let Some(Value::Array(accessors)) = root.get_mut("accessors") else { return };
    if accessors.is_empty() {
        return;
    }
    let i = rng.below(accessors.len());
    let Some(accessor) = accessors[i].as_object_mut() else { return };
    let old = accessor.get("count").and_then(Value::as_u64).unwrap_or(1).max(1);
    let grown = match rng.below(3) {
        0 => old.saturating_mul(2),
        1 => old.saturating_mul(2 + rng.below(100_000) as u64),
        _ => 3_000_000,
    };
    accessor.insert("count".to_owned(), grown.into());
    if rng.one_in(2) {
        accessor.remove("bufferView");
    }
}

// ---------------------------------------------------------------------------------------------
// Bundles (see tracer::bundle for the format)

/// One entry of a bundle: where its header and its data are.
struct Entry {
    /// Offset of the element type byte (the name comes before it).
    kind_at: usize,
    /// Offset of the u64 count.
    count_at: usize,
    data_at: usize,
    data_len: usize,
}

fn entries(data: &[u8]) -> Option<Vec<Entry>> {
    if !data.starts_with(b"LPBUNDLE") || data.len() < 24 {
        return None;
    }
    let n = u32::from_le_bytes(data.get(12..16)?.try_into().ok()?) as usize;
    let mut out = Vec::new();
    let mut pos = 24;
    for _ in 0..n.min(256) {
        let name_len = *data.get(pos)? as usize;
        let kind_at = pos + 1 + name_len;
        let kind = *data.get(kind_at)?;
        let components = *data.get(kind_at + 1)? as usize;
        let count_at = kind_at + 4;
        let count = u64::from_le_bytes(data.get(count_at..count_at + 8)?.try_into().ok()?) as usize;
        let data_at = (count_at + 8).div_ceil(16) * 16;
        let size = match kind {
            1 => 1,
            _ => 4,
        };
        let data_len = count.checked_mul(components)?.checked_mul(size)?;
        if data_at.checked_add(data_len)? > data.len() {
            return None;
        }
        out.push(Entry { kind_at, count_at, data_at, data_len });
        pos = data_at + data_len;
    }
    Some(out)
}

/// Interesting f32 bit patterns for bundle data.
const FLOATS: [f32; 10] =
    [0.0, -0.0, 1.0, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN_POSITIVE, 1e-30];

/// An entry-aware mutation of a bundle: a data element becomes an interesting integer or
/// float (indices out of range, NaN, huge counts, which decode but contradict the rest), or a
/// header field changes (count, element type, components). The total length is kept right.
pub fn bundle(data: &[u8], rng: &mut Rng) -> Option<Vec<u8>> {
    let list = entries(data)?;
    let e = rng.pick(&list)?;
    let mut out = data.to_vec();
    match rng.below(8) {
        0 => {
            let v = interesting(rng, u64::from_le_bytes(out[e.count_at..e.count_at + 8].try_into().ok()?) as i64);
            out[e.count_at..e.count_at + 8].copy_from_slice(&v.to_le_bytes());
        }
        1 => out[e.kind_at] = rng.below(6) as u8,
        2 => out[e.kind_at + 1] = *rng.pick(&[0u8, 1, 2, 3, 4, 5, 255]).unwrap_or(&1),
        _ if e.data_len >= 4 => {
            let at = e.data_at + rng.below(e.data_len / 4) * 4;
            let word = if rng.one_in(2) {
                rng.pick(&FLOATS).copied().unwrap_or(0.0).to_bits()
            } else {
                interesting(rng, u32::from_le_bytes(out[at..at + 4].try_into().ok()?) as i64) as u32
            };
            out[at..at + 4].copy_from_slice(&word.to_le_bytes());
        }
        _ if e.data_len > 0 => out[e.data_at] = rng.next_u64() as u8,
        _ => return None,
    }
    Some(out)
}

// ---------------------------------------------------------------------------------------------
// Text formats: OBJ lines and HTTP requests

const OBJ_WORDS: &[&str] = &[
    "v 1e38 1e38 1e38",
    "v nan 0 0",
    "vt 0.5 inf",
    "vn 0 0 0",
    "f 1 2 3",
    "f -1 -2 -3",
    "f 1/1/1 2/2/2 3/3/3",
    "f 0 0 0",
    "f 4294967295 1 2",
    "f 1 2 3 4 5 6 7 8",
    "usemtl light",
    "usemtl missing",
    "mtllib a.mtl",
    "newmtl light",
    "Kd 1 1 1",
    "Kd -1 nan 2",
    "Ke 1e30 1 1",
    "map_Kd t.png",
    "map_Ke -bm 1 t.jpg",
    "map_Kd missing",
    "o object",
    "g group",
    "s 1",
];

/// A line-level mutation of a text format: a line is removed, duplicated, or replaced by (or
/// followed by) one of `words`; numbers on a line become interesting ones.
pub fn text_lines(data: &[u8], rng: &mut Rng, words: &[&str]) -> Vec<u8> {
    let text = String::from_utf8_lossy(data);
    let mut lines: Vec<String> = text.split('\n').map(str::to_owned).collect();
    let i = rng.below(lines.len());
    let word = rng.pick(words).copied().unwrap_or("").to_owned();
    match rng.below(5) {
        0 => {
            lines.remove(i);
        }
        1 => {
            let copy = lines[i].clone();
            lines.insert(i, copy);
        }
        2 => lines[i] = word,
        3 => lines.insert(i, word),
        _ => {
            let mut parts: Vec<String> = lines[i].split(' ').map(str::to_owned).collect();
            let j = rng.below(parts.len());
            parts[j] = interesting(rng, parts[j].parse().unwrap_or(0)).to_string();
            lines[i] = parts.join(" ");
        }
    }
    lines.join("\n").into_bytes()
}

const HTTP_LINES: &[&str] = &[
    "GET / HTTP/1.1",
    "GET /scenes.json HTTP/1.1",
    "HEAD /index.html HTTP/1.1",
    "POST / HTTP/1.1",
    "GET /../Cargo.toml HTTP/1.1",
    "GET /%2e%2e/%2e%2e/etc/passwd HTTP/1.1",
    "GET //bundles/ HTTP/1.1",
    "GET /bundles/0000000000000000000000000000000000000000000000000000000000000000.lpb HTTP/1.1",
    "GET /?a=b&c HTTP/1.0",
    "GET * HTTP/1.1",
    "GET / HTTP/2.0",
    "GET / HTTP/1.1 extra",
    "Host: 127.0.0.1",
    "Host:",
    "Connection: close",
    "Connection: keep-alive",
    "Accept-Encoding: gzip",
    "Accept-Encoding: br;q=1, gzip;q=0, *;q=0.5",
    "Content-Length: 5",
    "Content-Length: -1",
    "Content-Length: 18446744073709551616",
    "Content-Length: 1\r\nContent-Length: 2",
    "Transfer-Encoding: chunked",
    "If-None-Match: \"x\"",
    "If-None-Match: *",
    "If-Modified-Since: Thu, 01 Jan 1970 00:00:00 GMT",
    "Range: bytes=0-0",
    "Range: bytes=99999999999999999999-",
    "Expect: 100-continue",
    "Upgrade: h2c",
    " folded: header",
    "X: \u{0}\u{7f}",
    "",
];

/// A request-aware mutation: lines (request line, headers, body) removed, duplicated or
/// replaced, numbers made interesting, a header made very long.
pub fn http(data: &[u8], rng: &mut Rng) -> Vec<u8> {
    let text = String::from_utf8_lossy(data);
    let mut lines: Vec<String> = text.split("\r\n").map(str::to_owned).collect();
    if rng.one_in(10) {
        let i = rng.below(lines.len());
        let n = *rng.pick(&[100usize, 4000, 9000, 70000]).unwrap_or(&100);
        lines.insert(i, format!("X-Long: {}", "a".repeat(n)));
        return lines.join("\r\n").into_bytes();
    }
    let mut out = text_lines(lines.join("\n").as_bytes(), rng, HTTP_LINES);
    // Back to CRLF (a few bare LFs are kept by chance: also worth sending).
    if !rng.one_in(8) {
        let s = String::from_utf8_lossy(&out).replace('\n', "\r\n");
        out = s.into_bytes();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gltf_mutations_keep_json_parseable_and_change_it() {
        let json = br#"{"accessors":[{"count":3,"bufferView":0}],"bufferViews":[{"byteLength":12}]}"#;
        let mut rng = Rng::new(7);
        let mut changed = 0;
        for _ in 0..100 {
            let out = gltf(json, &mut rng).expect("JSON in, JSON out");
            let _: Value = serde_json::from_slice(&out).expect("still JSON");
            changed += usize::from(out != json.to_vec());
        }
        assert!(changed > 50, "{changed} of 100 mutations changed the input");
        let glb = crate::glb::build(json, Some(&[0; 12]));
        let out = gltf(&glb, &mut rng).unwrap();
        let (j, bin) = crate::glb::split(&out).expect("still a GLB");
        assert!(serde_json::from_slice::<Value>(j).is_ok() && bin == Some(&[0u8; 12][..]));
    }

    #[test]
    fn accessor_counts_grow_to_millions_with_and_without_their_buffer_view() {
        let json = br#"{"accessors":[{"count":3,"bufferView":0}],"bufferViews":[{"byteLength":12}]}"#;
        let mut rng = Rng::new(11);
        let (mut millions, mut zero_filled) = (0, 0);
        for _ in 0..2000 {
            let out: Value = serde_json::from_slice(&gltf(json, &mut rng).unwrap()).unwrap();
            let accessor = &out["accessors"][0];
            if accessor["count"].as_u64().is_some_and(|c| c >= 1_000_000) {
                millions += 1;
                zero_filled += usize::from(accessor.get("bufferView").is_none());
            }
        }
        assert!(millions >= 20 && zero_filled >= 5, "{millions} grown to millions, {zero_filled} of them zero-filled");
    }

    #[test]
    fn byte_mutations_respect_the_length_limit() {
        let mut rng = Rng::new(1);
        for _ in 0..1000 {
            let mut data = b"hello world".to_vec();
            bytes(&mut data, &mut rng, b"other input", 16);
            assert!(data.len() <= 16);
        }
    }
}
