//! Helpers shared by the tests that run the `render` command.

#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};

/// The `render` example binary: Cargo builds examples before integration tests, into
/// `target/<profile>/examples/` beside the test binary's `deps/` folder. (A filtered
/// `cargo test --test X` does not rebuild examples: run the whole suite after changing it.)
pub fn render_exe() -> PathBuf {
    example_exe("render")
}

/// The `merge` example binary (see [`render_exe`]).
pub fn merge_exe() -> PathBuf {
    example_exe("merge")
}

fn example_exe(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>");
    let p = profile_dir
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        p.exists(),
        "{} not built; run through `cargo test`",
        p.display()
    );
    p
}
