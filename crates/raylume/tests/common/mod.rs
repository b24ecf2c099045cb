//! Helpers shared by the facade's integration tests: the example binaries, the project's
//! scenes at test sizes, image comparison.

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

/// The `compare` example binary (see [`render_exe`]).
pub fn compare_exe() -> PathBuf {
    example_exe("compare")
}

/// The `trace_rate` example binary (see [`render_exe`]).
pub fn trace_rate_exe() -> PathBuf {
    example_exe("trace_rate")
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

/// The repository's root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every scene of `scenes/`: its TOML files in name order, then the living room.
pub fn project_scenes() -> Vec<PathBuf> {
    let dir = repo().join("scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v.push(dir.join("living-room/scene.json"));
    v
}

/// The scene at `path`, `height` pixels high (its aspect kept), 2 spp, 4 bounces.
pub fn small_scene(path: &Path, height: u32) -> raylume::Scene {
    let mut s = raylume::Scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let aspect = s.render.width as f32 / s.render.height as f32;
    s.render.height = height;
    s.render.width = (height as f32 * aspect).round().max(1.0) as u32;
    s.render.spp = 2;
    s.render.max_bounces = 4;
    s
}

/// The project's Cornell box at 16x12, `spp` samples per pixel, 3 bounces.
pub fn small_cornell(spp: u32) -> raylume::Scene {
    let mut s = raylume::Scene::load(repo().join("scenes/cornell-box.toml")).unwrap();
    s.render.width = 16;
    s.render.height = 12;
    s.render.spp = spp;
    s.render.max_bounces = 3;
    s
}

/// The project's Cornell box at `w` x `h`, `spp` samples per pixel, 3 bounces.
pub fn cornell(w: u32, h: u32, spp: u32) -> raylume::Scene {
    let mut s = small_cornell(spp);
    s.render.width = w;
    s.render.height = h;
    s
}

/// Adds 20,000 small triangles (a 100 x 100 grid of quads, 1 cm each) on the floor of
/// `scene`, in the material of its first triangle: a scene large for the rays of a small,
/// brief render, whose BVH preset the work ahead decides.
pub fn add_floor_grid(scene: &mut raylume::Scene) {
    let m = scene.triangles[0].material;
    for i in 0..10_000 {
        let (x, z) = ((i % 100) as f32 * 0.01, (i / 100) as f32 * 0.01);
        let p = |dx: f32, dz: f32| raylume::glam::Vec3::new(x + dx, 1e-3, z + dz);
        scene.triangles.push(raylume::scene::Triangle::flat(
            [p(0.0, 0.0), p(0.01, 0.0), p(0.01, 0.01)],
            m,
        ));
        scene.triangles.push(raylume::scene::Triangle::flat(
            [p(0.0, 0.0), p(0.01, 0.01), p(0.0, 0.01)],
            m,
        ));
    }
}
