//! Specialisation changes no image (issue 14): every scene in `scenes/` renders the same on
//! the GPU with its pipelines specialised on its features (`Tracer::specialise`, the default)
//! and with the generic pipeline, every feature compiled in. The override constants only
//! remove code for effects the scene does not have, so both run the same operations on the
//! same numbers: the images must be equal bit for bit (measured so on lavapipe; a driver that
//! compiled the two differently could move a pixel by rounding, and this test would say so).

use std::path::{Path, PathBuf};

use raylume::{Backend, Scene, Tracer};

fn scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v.push(dir.join("living-room/scene.json"));
    v
}

fn small(path: &Path) -> Scene {
    let mut s = Scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let aspect = s.render.width as f32 / s.render.height as f32;
    s.render.height = 16;
    s.render.width = (16.0 * aspect).round().max(1.0) as u32;
    s.render.spp = 2;
    s.render.max_bounces = 4;
    s
}

#[test]
fn specialised_and_generic_pipelines_render_the_same_image() {
    let Some(_ctx) = raylume_gpu::testing::context_or_skip(
        "specialised_and_generic_pipelines_render_the_same_image",
    ) else {
        return;
    };
    let mut specialised = Tracer::new(Backend::Gpu);
    let mut generic = Tracer::new(Backend::Gpu);
    generic.specialise = false;
    let all = raylume::Features::all().names();
    for path in scenes() {
        let scene = small(&path);
        let name = path.display();
        let s = specialised.render(&scene).unwrap();
        let g = generic.render(&scene).unwrap();
        assert_eq!(
            s.stats.pipeline_features,
            scene.features().names(),
            "{name}"
        );
        assert_eq!(g.stats.pipeline_features, all, "{name}");
        assert!(
            s.stats.pipeline_features.len() < all.len(),
            "{name}: a scene with every feature would test nothing"
        );
        assert!(s.pixels.iter().flatten().any(|v| *v > 0.0), "{name}: black");
        let differ = s
            .pixels
            .iter()
            .zip(&g.pixels)
            .filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits))
            .count();
        assert_eq!(
            differ,
            0,
            "{name}: {differ} of {} pixels differ between the specialised and the generic pipeline",
            s.pixels.len()
        );
        assert_eq!(s.stats.rays_traced, g.stats.rays_traced, "{name}");
    }
    // The CPU mirror is not specialised: it names no pipeline features.
    let cpu = Tracer::new(Backend::Cpu)
        .render(&small(&scenes()[0]))
        .unwrap();
    assert!(cpu.stats.pipeline_features.is_empty());
}
