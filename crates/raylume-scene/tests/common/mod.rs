//! Test support: temporary folders, fixture writers (OBJ, images, glTF, GLB), error helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use raylume_scene::{Location, Scene, SceneError};

/// A fresh, empty folder under the system temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        static N: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "raylume-scene-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `bytes` to `name` (creating folders) and returns the full path.
    pub fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let p = self.0.join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(&p, bytes).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// True when `RAYLUME_REQUIRE_EXTERNAL=1` (`.ci/run` sets it): the external scenes in
/// `../shared/scenes-external` must be there, and a test that needs them fails without them.
pub fn external_required() -> bool {
    std::env::var("RAYLUME_REQUIRE_EXTERNAL").is_ok_and(|v| v == "1")
}

/// Writes `SKIPPED (reason): test` straight to standard error, past the test harness's
/// capture (which hides `eprintln!` of passing tests), so that the skip shows in the ordinary
/// `cargo test` output. The test is named after its thread, as the harness names it.
pub fn report_skip(test: &str, reason: &str) {
    use std::io::Write;
    let name = match std::thread::current().name() {
        Some(n) if n != "main" => n.to_string(),
        _ => test.to_string(),
    };
    let mut err = std::io::stderr().lock();
    let _ = err.write_all(format!("SKIPPED ({reason}): {name}\n").as_bytes());
    let _ = err.flush();
}

/// The vendored external scenes beside the checkout (`../shared/scenes-external`): the path,
/// or `None` after a visible skip line when they are absent. Panics instead when
/// `RAYLUME_REQUIRE_EXTERNAL=1`.
pub fn shared_external(relative: &str, test: &str) -> Option<PathBuf> {
    let path = repo_root().join("../shared/scenes-external").join(relative);
    if path.exists() {
        return Some(path);
    }
    if external_required() {
        panic!(
            "{test}: RAYLUME_REQUIRE_EXTERNAL=1 but {} is absent",
            path.display()
        );
    }
    report_skip(
        test,
        &format!(
            "../shared/scenes-external/{relative} absent; RAYLUME_REQUIRE_EXTERNAL=1 fails instead"
        ),
    );
    None
}

/// Loads a TOML text held in memory, with `dir` as its folder and label `scene.toml`.
pub fn toml(dir: &Path, text: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_str(text, dir, "scene.toml")
}

/// Asserts that `r` failed, with a message containing every string in `parts`.
pub fn err_contains<T: std::fmt::Debug>(r: Result<T, SceneError>, parts: &[&str]) -> SceneError {
    let e = r.expect_err("expected an error");
    let msg = e.to_string();
    for p in parts {
        assert!(msg.contains(p), "message {msg:?} lacks {p:?}");
    }
    e
}

pub fn line_col(line: usize, column: usize) -> Location {
    Location::LineCol { line, column }
}

/// A 2x2 RGB PNG: red, green / blue, white.
pub fn png_2x2() -> Vec<u8> {
    let mut img = image::RgbImage::new(2, 2);
    img.put_pixel(0, 0, image::Rgb([255, 0, 0]));
    img.put_pixel(1, 0, image::Rgb([0, 255, 0]));
    img.put_pixel(0, 1, image::Rgb([0, 0, 255]));
    img.put_pixel(1, 1, image::Rgb([255, 255, 255]));
    encode(image::DynamicImage::ImageRgb8(img), image::ImageFormat::Png)
}

/// A float image (`w` x `h`, texel (x, y) = [x, y, 0.5]) as .hdr or .exr.
pub fn float_image(w: u32, h: u32, format: image::ImageFormat) -> Vec<u8> {
    let img = image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb([x as f32, y as f32, 0.5]));
    encode(image::DynamicImage::ImageRgb32F(img), format)
}

pub fn encode(img: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), format)
        .unwrap();
    bytes
}

/// Standard base64 with padding (for glTF data URIs).
pub fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(A[(n >> (18 - 6 * i)) as usize & 63] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A GLB container around `json` and `bin`.
pub fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + if b.is_empty() { 0 } else { 8 + b.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    if !b.is_empty() {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    out
}

/// Little-endian bytes of f32s.
pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Little-endian bytes of u16s, padded to 4 bytes.
pub fn u16_bytes(v: &[u16]) -> Vec<u8> {
    let mut out: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    while !out.len().is_multiple_of(4) {
        out.push(0);
    }
    out
}
