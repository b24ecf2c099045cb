//! The CPU path's instruction-set levels (`raylume_kernels::cpu::isa`): every level this CPU
//! executes renders the same image as the build's own, bit for bit, over the fixture scenes
//! that hold every feature group (spheres; metal, glass, plastic, rough ones; textures; an
//! environment), with each estimator and sampler; two paths traced in turn
//! (`CpuTracer::set_pairs`) render what one segment at a time renders; and the records'
//! copy in huge pages (`CpuTracer::set_huge_pages`) renders what the scene's data renders.

mod support;

use raylume_kernels::{CpuIsa, CpuTracer, Estimator, Sampler, Schedule, Specialisation};
use raylume_scene::Features;
use support::*;

/// The fixture scenes that hold every feature group between them.
fn every_group() -> [(&'static str, raylume_scene::Scene); 5] {
    [
        ("cornell", cornell_box()),
        ("spheres", spheres()),
        ("materials", materials()),
        ("textured", textured()),
        ("environment", environment_lit()),
    ]
}

/// How many pixels of two images differ in any bit.
fn differing_pixels(a: &[[f32; 3]], b: &[[f32; 3]]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits))
        .count()
}

#[test]
fn every_available_level_renders_the_builds_image_bit_for_bit() {
    let levels: Vec<CpuIsa> = CpuIsa::ALL.into_iter().filter(|i| i.available()).collect();
    eprintln!("levels this CPU executes: {levels:?}");
    let scenes = every_group();
    let runs = [
        (
            Estimator::Nee,
            Sampler::Sobol,
            Some(3),
            Specialisation::default(),
        ),
        (
            Estimator::Plain,
            Sampler::Independent,
            None,
            Specialisation::default(),
        ),
        (
            Estimator::Nee,
            Sampler::ZSobol,
            Some(2),
            Specialisation::Generic,
        ),
    ];
    let s = settings(24, 16, 4, 6, Schedule::Persistent);
    for (name, scene) in &scenes {
        let bvh = bvh(scene);
        let mut tracer = CpuTracer::new(scene, &bvh).unwrap();
        for &(estimator, sampler, roulette, specialisation) in &runs {
            tracer.set_estimator(estimator);
            tracer.set_sampler(sampler);
            tracer.set_russian_roulette(roulette);
            tracer.set_specialisation(specialisation, Features::NONE);
            let mut reference = None;
            for &isa in &levels {
                assert_eq!(tracer.set_isa(isa), isa, "an available level is taken");
                let out = tracer.render(&s, &mut |_, _| {}).unwrap();
                let bits: Vec<[u32; 3]> =
                    out.radiance.iter().map(|p| p.map(f32::to_bits)).collect();
                assert!(out.rays_traced > 0);
                match &reference {
                    None => reference = Some((bits, out.rays_traced)),
                    Some((want, rays)) => {
                        let differ = bits.iter().zip(want).filter(|(a, b)| a != b).count();
                        assert_eq!(
                            differ, 0,
                            "{name} {estimator:?} {sampler:?} at {isa:?}: {differ} pixels differ \
                             from the build's image"
                        );
                        assert_eq!(out.rays_traced, *rays, "{name} at {isa:?}: rays traced");
                    }
                }
            }
        }
    }
}

#[test]
fn a_tracer_runs_the_best_level_by_default_and_clamps_what_the_cpu_lacks() {
    let scene = cornell_box();
    let mut tracer = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
    assert_eq!(tracer.isa(), CpuIsa::best());
    assert_eq!(tracer.set_isa(CpuIsa::Build), CpuIsa::Build);
    // Asking for the highest level gets the highest this CPU has, never one it lacks.
    let got = tracer.set_isa(CpuIsa::X86_64V4);
    assert_eq!(got, CpuIsa::best());
    assert!(got.available());
    assert_eq!(tracer.isa(), got);
}

#[test]
fn paths_in_pairs_render_what_one_segment_at_a_time_renders() {
    // `CpuTracer::set_pairs`: two paths in flight, a segment of each in turn
    // (`cpu::stages::trace_paths_in_pairs`), against the wavefront schedule, which runs every
    // path's segments one at a time through `propagate` (the one-path functions): the same
    // image bit for bit and the same rays, on every fixture scene (the packets off, so that
    // the Cornell box runs in pairs too), with NEE and roulette and with the plain estimator,
    // at the best level (the pairs' draws and walks) against the wavefront's build level (the
    // first test: every level the same). Odd sizes and sample counts: chunks end mid-pair.
    // Seen failing with a finished path's sample written to the other path's slot.
    let scenes = every_group();
    for (name, scene) in &scenes {
        let bvh = bvh(scene);
        let mut tracer = CpuTracer::new(scene, &bvh).unwrap();
        tracer.set_packets(false);
        for (estimator, sampler, roulette) in [
            (Estimator::Nee, Sampler::Sobol, Some(2)),
            (Estimator::Plain, Sampler::Independent, None),
        ] {
            tracer.set_estimator(estimator);
            tracer.set_sampler(sampler);
            tracer.set_russian_roulette(roulette);
            let s = settings(23, 15, 3, 6, Schedule::Wavefront);
            let one = tracer.render(&s, &mut |_, _| {}).unwrap();
            for pairs in [true, false] {
                tracer.set_pairs(Some(pairs));
                assert_eq!(tracer.pairs(), pairs);
                let s = settings(23, 15, 3, 6, Schedule::Megakernel);
                let out = tracer.render(&s, &mut |_, _| {}).unwrap();
                let differ = differing_pixels(&out.radiance, &one.radiance);
                assert_eq!(
                    differ, 0,
                    "{name} {estimator:?}, pairs {pairs}: {differ} pixels differ from the \
                     wavefront's"
                );
                assert_eq!(out.rays_traced, one.rays_traced, "{name} {estimator:?}");
                assert_eq!(out.dropped_samples, one.dropped_samples, "{name}");
            }
            tracer.set_pairs(None);
        }
    }
    // By default the fixtures' few records stay one path at a time; the packets' scenes never
    // run in pairs.
    let scene = textured();
    let mut tracer = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
    assert!(!tracer.pairs());
    tracer.set_pairs(Some(true));
    assert!(tracer.pairs());
    let scene = cornell_box();
    let mut tracer = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
    tracer.set_pairs(Some(true));
    assert!(tracer.packets() && !tracer.pairs());
}

#[test]
fn records_in_huge_pages_render_what_the_scene_data_renders() {
    // `CpuTracer::set_huge_pages`: the primitives, material indices, shading records and
    // texels copied into `HugePageArray`s and read from there: the same image bit for bit and
    // the same rays as reading them where the scene's data holds them, on every fixture scene,
    // through both schedules (the one-path loop and the wavefront's `propagate` read them
    // through the same `Globals`). (The fixtures' arrays are below a huge page, so this tests
    // the copy and its use; `raylume_bvh::huge_pages`' own tests the advice on large arrays.)
    // Seen failing with the copy's material indices reversed.
    for (name, scene) in &every_group() {
        let bvh = bvh(scene);
        let mut tracer = CpuTracer::new(scene, &bvh).unwrap();
        tracer.set_estimator(Estimator::Nee);
        tracer.set_russian_roulette(Some(2));
        for schedule in [Schedule::Megakernel, Schedule::Wavefront] {
            let s = settings(23, 15, 3, 6, schedule);
            tracer.set_huge_pages(Some(false));
            let plain = tracer.render(&s, &mut |_, _| {}).unwrap();
            assert!(!tracer.records_in_huge_pages(), "{name}");
            tracer.set_huge_pages(Some(true));
            let huge = tracer.render(&s, &mut |_, _| {}).unwrap();
            assert!(tracer.records_in_huge_pages(), "{name}");
            let differ = differing_pixels(&huge.radiance, &plain.radiance);
            assert_eq!(differ, 0, "{name} {schedule:?}: {differ} pixels differ");
            assert_eq!(huge.rays_traced, plain.rays_traced, "{name} {schedule:?}");
        }
    }
    // By default a render copies the records only where they are large and it is long: not
    // the fixtures' few kilobytes, whatever the render; a copy once made is kept until
    // switched off.
    let scene = textured();
    let mut tracer = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
    assert!(!tracer.huge_pages(u64::MAX));
    tracer
        .render(
            &settings(23, 15, 3, 6, Schedule::Megakernel),
            &mut |_, _| {},
        )
        .unwrap();
    assert!(!tracer.records_in_huge_pages());
    tracer.set_huge_pages(Some(true));
    tracer
        .render(
            &settings(23, 15, 3, 6, Schedule::Megakernel),
            &mut |_, _| {},
        )
        .unwrap();
    tracer.set_huge_pages(None);
    assert!(tracer.records_in_huge_pages() && tracer.huge_pages(1));
    tracer.set_huge_pages(Some(false));
    assert!(!tracer.records_in_huge_pages());
}
