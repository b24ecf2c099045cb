//! Buffer and image URIs: `data:` (base64) and relative paths.

use std::path::{Path, PathBuf};

use super::invalid;
use crate::error::{Location, SceneError};

/// Standard base64 (RFC 4648, padding optional) for `data:` URIs.
pub(crate) fn base64_decode(s: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
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

/// `%20` and friends in relative URIs.
pub(super) fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Bytes of a `data:` URI, or the path of a relative one.
pub(super) enum UriData {
    Bytes(Vec<u8>),
    File(PathBuf),
}

pub(super) fn resolve_uri(
    uri: &str,
    dir: &Path,
    file: &str,
    at: &str,
) -> Result<UriData, SceneError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((meta, data)) = rest.split_once(',') else {
            return Err(invalid(file, at, "malformed data URI"));
        };
        if !meta.ends_with(";base64") {
            return Err(SceneError::Unsupported {
                file: file.into(),
                at: Location::path(at),
                message: "data URI that is not base64".into(),
            });
        }
        return base64_decode(data)
            .map(UriData::Bytes)
            .ok_or_else(|| invalid(file, at, "data URI is not valid base64"));
    }
    if uri.contains("://") {
        return Err(SceneError::Unsupported {
            file: file.into(),
            at: Location::path(at),
            message: format!("URI scheme of `{uri}` (only relative paths and data URIs)"),
        });
    }
    Ok(UriData::File(dir.join(percent_decode(uri))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_vectors() {
        // RFC 4648 test vectors.
        assert_eq!(base64_decode("").unwrap(), b"");
        assert_eq!(base64_decode("Zg==").unwrap(), b"f");
        assert_eq!(base64_decode("Zm8=").unwrap(), b"fo");
        assert_eq!(base64_decode("Zm9v").unwrap(), b"foo");
        assert_eq!(base64_decode("Zm9vYmFy").unwrap(), b"foobar");
        assert!(base64_decode("Zm9v!").is_none());
    }

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("a%20b.bin"), "a b.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("x%2"), "x%2");
    }
}
