//! Specialisation changes no image (issue 14): every scene in `scenes/` renders the same on
//! the GPU with its pipelines composed for its features (`Specialisation::Composed`, the
//! default), specialised by override constants only, and generic (every feature compiled in).
//! Both ways only remove code for effects the scene does not have, so all three run the same
//! operations on the same numbers: the images must be equal bit for bit (measured so on
//! lavapipe; a driver that compiled them differently could move a pixel by rounding, and this
//! test would say so).

mod common;

use raylume::{Backend, Specialisation, Tracer};

#[test]
fn composed_overridden_and_generic_pipelines_render_the_same_image() {
    let Some(_ctx) = raylume_gpu::testing::context_or_skip(
        "composed_overridden_and_generic_pipelines_render_the_same_image",
    ) else {
        return;
    };
    let mut composed = Tracer::new(Backend::Gpu);
    assert_eq!(composed.specialisation, Specialisation::Composed);
    let mut overrides = Tracer::new(Backend::Gpu);
    overrides.specialisation = Specialisation::Overrides;
    let mut generic = Tracer::new(Backend::Gpu);
    generic.specialisation = Specialisation::Generic;
    let all = raylume::Features::all().names();
    for path in common::project_scenes() {
        let scene = common::small_scene(&path, 16);
        let name = path.display();
        let s = composed.render(&scene).unwrap();
        assert_eq!(s.stats.specialisation, "composed");
        assert_eq!(
            s.stats.pipeline_features,
            scene.features().names(),
            "{name}"
        );
        assert!(
            s.stats.pipeline_features.len() < all.len(),
            "{name}: a scene with every feature would test nothing"
        );
        assert!(s.pixels.iter().flatten().any(|v| *v > 0.0), "{name}: black");
        for (other, kind) in [(&mut overrides, "overrides"), (&mut generic, "generic")] {
            let o = other.render(&scene).unwrap();
            assert_eq!(o.stats.specialisation, kind);
            let expected = if kind == "generic" {
                all.clone()
            } else {
                scene.features().names()
            };
            assert_eq!(o.stats.pipeline_features, expected, "{name}");
            let differ = s
                .pixels
                .iter()
                .zip(&o.pixels)
                .filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits))
                .count();
            assert_eq!(
                differ,
                0,
                "{name}: {differ} of {} pixels differ between the composed and the {kind} pipeline",
                s.pixels.len()
            );
            assert_eq!(s.stats.rays_traced, o.stats.rays_traced, "{name}");
        }
    }
    // The CPU mirror is not specialised: it names no pipeline features.
    let cpu = Tracer::new(Backend::Cpu)
        .render(&common::small_scene(&common::project_scenes()[0], 16))
        .unwrap();
    assert!(cpu.stats.pipeline_features.is_empty());
    assert!(cpu.stats.specialisation.is_empty());
}
