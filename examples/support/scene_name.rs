//! A scene's short name for tables, shared by the examples that print one (included with
//! `#[path]`: examples are separate binaries).

use std::path::Path;

/// The file's stem, or, for Tungsten's `scene.json` (every Tungsten scene has that name),
/// its folder's name.
pub fn scene_name(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    if stem == "scene" {
        path.parent()
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or(stem)
    } else {
        stem
    }
}
