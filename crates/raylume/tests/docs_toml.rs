//! Every ```toml block of the README and docs/SCENE_FORMAT.md loads as written.
//!
//! Paths inside the blocks are relative to `scenes/` (the blocks say so). A block whose first
//! line is `# fragment: ...` is a part of a scene: it is loaded after a minimal scene (a
//! camera, a material `m`, a sphere), so its keys are checked too. A block whose first line
//! is `# Cargo.toml` is a manifest, not a scene, and is only checked to parse as TOML-like
//! `key = value` lines.

use std::path::{Path, PathBuf};

use raylume::Scene;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The ```toml blocks of `file`, with the line each starts on.
fn toml_blocks(file: &str) -> Vec<(usize, String)> {
    let text = std::fs::read_to_string(repo().join(file)).unwrap();
    let mut blocks = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        match current.as_mut() {
            None if trimmed.starts_with("```toml") => current = Some((i + 2, String::new())),
            None => {}
            Some(_) if trimmed.starts_with("```") => blocks.push(current.take().unwrap()),
            Some((_, b)) => {
                b.push_str(line);
                b.push('\n');
            }
        }
    }
    assert!(current.is_none(), "{file}: an unclosed ```toml block");
    blocks
}

const MINIMAL: &str = "[camera]\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 40.0\n\
     [materials.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
     [[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"m\"\n";

/// Loads every block of `file`; returns how many were whole scenes.
fn check(file: &str) -> usize {
    let scenes = repo().join("scenes");
    let mut whole = 0;
    for (line, block) in toml_blocks(file) {
        let first = block.lines().next().unwrap_or_default();
        let label = format!("{file}:{line}");
        if first.starts_with("# Cargo.toml") {
            for l in block.lines().skip(1).filter(|l| !l.trim().is_empty()) {
                assert!(
                    l.starts_with('[') || l.contains(" = "),
                    "{label}: not a manifest line: {l}"
                );
            }
            continue;
        }
        let text = if first.starts_with("# fragment:") {
            format!("{MINIMAL}{block}")
        } else {
            whole += 1;
            block.clone()
        };
        let scene = Scene::from_toml_str(&text, &scenes, &label)
            .unwrap_or_else(|e| panic!("{label}: the example does not load: {e}\n{block}"));
        assert!(
            scene.warnings.is_empty(),
            "{label}: the example loads with warnings: {:?}",
            scene.warnings
        );
    }
    whole
}

#[test]
fn scene_format_examples_load() {
    assert!(
        check("docs/SCENE_FORMAT.md") >= 1,
        "the format's full example"
    );
}

#[test]
fn readme_examples_load() {
    check("README.md");
}

#[test]
fn scene_format_full_example_uses_every_section() {
    let blocks = toml_blocks("docs/SCENE_FORMAT.md");
    let scene = Scene::from_toml_str(&blocks[0].1, &repo().join("scenes"), "full").unwrap();
    assert!(!scene.triangles.is_empty() && !scene.spheres.is_empty());
    assert!(scene.post.bloom.is_some());
    assert!(!scene.textures.is_empty(), "the texture loads");
    assert!(matches!(
        scene.environment,
        raylume::scene::Environment::Constant(_)
    ));
}
