//! Small helpers shared by the loaders: bounded file reads, data URIs, percent-decoding.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::{SceneError, MAX_FILE_BYTES};

/// Reads a whole file, refusing files larger than [`MAX_FILE_BYTES`] before allocating.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, SceneError> {
    let io = |error| SceneError::Io { path: path.to_owned(), error };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    if len > MAX_FILE_BYTES {
        return Err(SceneError::TooLarge(format!("{} is {len} bytes (limit {MAX_FILE_BYTES})", path.display())));
    }
    let mut data = Vec::with_capacity(len as usize);
    // `take` guards against files that grow while being read.
    file.take(MAX_FILE_BYTES + 1).read_to_end(&mut data).map_err(io)?;
    if data.len() as u64 > MAX_FILE_BYTES {
        return Err(SceneError::TooLarge(format!("{} is larger than {MAX_FILE_BYTES} bytes", path.display())));
    }
    Ok(data)
}

/// Where a glTF URI points.
pub(crate) enum UriTarget {
    /// Bytes embedded in a `data:` URI (already decoded).
    Data(Vec<u8>),
    /// A file, resolved against the glTF file's directory.
    File(PathBuf),
}

/// Resolves a glTF URI: `data:` URIs (base64) are decoded, relative references are
/// percent-decoded and joined to `base_dir`. Other schemes (http:, ...) are refused.
pub(crate) fn resolve_uri(uri: &str, base_dir: Option<&Path>, what: &str) -> Result<UriTarget, SceneError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some(pos) = rest.find(";base64,") else {
            return Err(SceneError::Malformed(format!("{what}: data URI is not base64-encoded")));
        };
        let payload = rest.get(pos + ";base64,".len()..).unwrap_or("");
        let bytes = decode_base64(payload)
            .ok_or_else(|| SceneError::Malformed(format!("{what}: invalid base64 in data URI")))?;
        return Ok(UriTarget::Data(bytes));
    }
    // A scheme is letters/digits/+/-/. followed by ':' before any '/' (RFC 3986).
    if let Some(colon) = uri.find(':') {
        let scheme = &uri[..colon];
        let is_scheme = !scheme.is_empty()
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
            // A single letter is a Windows drive ("C:\..."), not a scheme.
            && scheme.len() > 1;
        if is_scheme {
            return Err(SceneError::Malformed(format!(
                "{what}: URI scheme {scheme:?} is not supported (only relative paths and data URIs)"
            )));
        }
    }
    let decoded = percent_decode(uri)
        .ok_or_else(|| SceneError::Malformed(format!("{what}: invalid percent-encoding in URI {uri:?}")))?;
    if decoded.is_empty() {
        return Err(SceneError::Malformed(format!("{what}: empty URI")));
    }
    let Some(base) = base_dir else {
        return Err(SceneError::Malformed(format!(
            "{what}: refers to external file {decoded:?}, but the glTF was loaded from memory"
        )));
    };
    Ok(UriTarget::File(base.join(decoded)))
}

/// Reads what a URI points at.
pub(crate) fn read_uri(uri: &str, base_dir: Option<&Path>, what: &str) -> Result<Vec<u8>, SceneError> {
    match resolve_uri(uri, base_dir, what)? {
        UriTarget::Data(bytes) => Ok(bytes),
        UriTarget::File(path) => read_file(&path),
    }
}

/// Decodes standard base64 (RFC 4648, padding optional, ASCII whitespace ignored).
pub(crate) fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    let mut padding = false;
    for &c in text.as_bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => {
                padding = true;
                continue;
            }
            b' ' | b'\t' | b'\r' | b'\n' => continue,
            _ => return None,
        };
        if padding {
            return None; // data after padding
        }
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

/// Decodes `%XX` escapes; `None` for bad escapes or a result that is not UTF-8.
pub(crate) fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        if b == b'%' {
            let hex = bytes.get(i + 1..i + 3)?;
            let hex = std::str::from_utf8(hex).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trip() {
        assert_eq!(decode_base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(decode_base64("aGVsbG8").unwrap(), b"hello");
        assert_eq!(decode_base64("AAEC").unwrap(), [0, 1, 2]);
        assert!(decode_base64("a*b").is_none());
        assert!(decode_base64("aG=Vs").is_none());
    }

    #[test]
    fn percent() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert!(percent_decode("a%2").is_none());
        assert!(percent_decode("%ff").is_none());
    }

    #[test]
    fn uri_schemes() {
        assert!(resolve_uri("http://x/y.bin", Some(Path::new(".")), "b").is_err());
        assert!(matches!(
            resolve_uri("y.bin", Some(Path::new("/d")), "b").unwrap(),
            UriTarget::File(p) if p == Path::new("/d/y.bin")
        ));
        assert!(resolve_uri("y.bin", None, "b").is_err());
    }
}
