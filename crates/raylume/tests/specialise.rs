//! Specialisation changes no image (issue 14): every scene in `scenes/` renders the same on
//! the GPU with its pipelines composed for its features (`Specialisation::Composed`, the
//! default), specialised by override constants only, and generic (every feature compiled in).
//! Both ways only remove code for effects the scene does not have, so all three run the same
//! operations on the same numbers: the images must be equal bit for bit (measured so on
//! lavapipe; a driver that compiled them differently could move a pixel by rounding, and this
//! test would say so).

mod common;

use raylume::{Backend, Specialisation, Tracer};

/// Pixels of `a` and `b` that are not equal bit for bit.
fn differing_pixels(a: &[[f32; 3]], b: &[[f32; 3]]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.map(f32::to_bits) != y.map(f32::to_bits))
        .count()
}

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
            let differ = differing_pixels(&s.pixels, &o.pixels);
            assert_eq!(
                differ,
                0,
                "{name}: {differ} of {} pixels differ between the composed and the {kind} pipeline",
                s.pixels.len()
            );
            assert_eq!(s.stats.rays_traced, o.stats.rays_traced, "{name}");
        }
    }
}

/// The CPU mirror's variants (`raylume_kernels::cpu::variant`): every scene renders the same,
/// bit for bit, with the per-bounce functions compiled for its feature groups and with every
/// feature compiled in; the variant holds the scene's features and, for every scene here,
/// lacks some (or the test would compare the generic code with itself).
#[test]
fn the_cpu_mirror_specialised_and_generic_render_the_same_image() {
    let mut specialised = Tracer::new(Backend::Cpu);
    let mut generic = Tracer::new(Backend::Cpu);
    generic.specialisation = Specialisation::Generic;
    // Every feature but bloom, a post pass and not the tracer's.
    let mut every = raylume::Features::all();
    every.remove(raylume::Feature::Bloom);
    let all = every.names();
    for path in common::project_scenes() {
        let scene = common::small_scene(&path, 16);
        let name = path.display();
        let s = specialised.render(&scene).unwrap();
        assert_eq!(s.stats.specialisation, "composed");
        let variant = &s.stats.pipeline_features;
        for f in raylume_kernels::tracer_features(&scene).names() {
            assert!(
                variant.contains(&f),
                "{name}: the variant {variant:?} lacks {f}"
            );
        }
        assert!(
            variant.len() < all.len(),
            "{name}: the variant has every feature, so this compares nothing"
        );
        assert!(s.pixels.iter().flatten().any(|v| *v > 0.0), "{name}: black");
        let g = generic.render(&scene).unwrap();
        assert_eq!(g.stats.specialisation, "generic");
        assert_eq!(g.stats.pipeline_features, all, "{name}");
        let differ = differing_pixels(&s.pixels, &g.pixels);
        assert_eq!(
            differ,
            0,
            "{name}: {differ} of {} pixels differ between the CPU's variant and its generic code",
            s.pixels.len()
        );
        assert_eq!(s.stats.rays_traced, g.stats.rays_traced, "{name}");
    }
    // A feature compiled in although the scene lacks it (`bench --extra-feature`): its group
    // joins the variant, and the image stays.
    let scene = common::small_cornell(2);
    let plain = specialised.render(&scene).unwrap();
    assert!(!plain.stats.pipeline_features.contains(&"spheres"));
    let mut extra = Tracer::new(Backend::Cpu);
    extra.extra_features.insert(raylume::Feature::Spheres);
    let with_spheres = extra.render(&scene).unwrap();
    assert!(with_spheres.stats.pipeline_features.contains(&"spheres"));
    assert_eq!(with_spheres.pixels, plain.pixels);
}
