//! The GPU traces the same paths as the CPU mirror: small renders of the fixture scenes agree
//! to a relative RMSE far below Monte Carlo noise, sample by sample.

mod support;

use raylume_bvh::BvhLayout;
use raylume_kernels::{CpuTracer, Estimator, GpuTracer, Sampler, Schedule, TraceSettings};
use support::*;

fn compare(name: &str, scene: &raylume_scene::Scene, w: u32, h: u32, spp: u32, bounces: u32) {
    compare_with(
        name,
        scene,
        [w, h, spp, bounces],
        Schedule::Megakernel,
        Estimator::Plain,
    );
}

fn compare_with(
    name: &str,
    scene: &raylume_scene::Scene,
    [w, h, spp, bounces]: [u32; 4],
    schedule: Schedule,
    estimator: Estimator,
) {
    compare_with_roulette(name, scene, [w, h, spp, bounces], schedule, estimator, None);
}

/// [`compare_with_roulette`] with the sampler `sampler` too.
fn compare_with_roulette(
    name: &str,
    scene: &raylume_scene::Scene,
    size: [u32; 4],
    schedule: Schedule,
    estimator: Estimator,
    roulette: Option<u32>,
) {
    compare_all(
        name,
        scene,
        size,
        schedule,
        (estimator, roulette, Sampler::Independent),
        BvhLayout::Binary,
    );
}

/// [`compare_with`] with Russian roulette from segment `roulette` and the sampler `sampler`
/// on both backends, over a BVH of `layout`.
fn compare_all(
    name: &str,
    scene: &raylume_scene::Scene,
    [w, h, spp, bounces]: [u32; 4],
    schedule: Schedule,
    (estimator, roulette, sampler): (Estimator, Option<u32>, Sampler),
    layout: BvhLayout,
) {
    compare_guided(
        name,
        scene,
        [w, h, spp, bounces],
        schedule,
        (estimator, roulette, sampler),
        layout,
        false,
    );
}

/// [`compare_all`], with NEE toward the environment by the learned guide when `guide`.
fn compare_guided(
    name: &str,
    scene: &raylume_scene::Scene,
    [w, h, spp, bounces]: [u32; 4],
    schedule: Schedule,
    (estimator, roulette, sampler): (Estimator, Option<u32>, Sampler),
    layout: BvhLayout,
    guide: bool,
) {
    let options = raylume_kernels::SceneOptions {
        environment_guide: guide,
        ..Default::default()
    };
    let Some(ctx) = raylume_gpu::testing::context_or_skip(name) else {
        return;
    };
    let s = settings(w, h, spp, bounces, schedule);
    let bvh = bvh_with_layout(scene, layout);
    let cpu_with = || {
        let mut t = CpuTracer::with_options(scene, &bvh, &options).unwrap();
        t.set_estimator(estimator);
        t.set_russian_roulette(roulette);
        t.set_sampler(sampler);
        t
    };
    let cpu_tracer = cpu_with();
    let cpu = cpu_with().render(&s, &mut |_, _| {}).unwrap();
    let features = scene.features();
    let pipelines = raylume_kernels::gpu::TracerPipelines::new(ctx, features, bvh.layout).unwrap();
    // A NEE wavefront is compared twice: light samples inside propagate (the default) and in
    // the next_event stage of their own.
    let stages: &[bool] = match (schedule, estimator) {
        (Schedule::Wavefront, Estimator::Nee) => &[false, true],
        _ => &[false],
    };
    for &stage in stages {
        let mut gpu_tracer =
            GpuTracer::with_options(ctx, scene, &bvh, pipelines.clone(), &options).unwrap();
        gpu_tracer.set_next_event_stage(stage);
        let name = format!("{name}{}", if stage { " (next_event stage)" } else { "" });
        let name = name.as_str();
        // The persistent schedule with half the samples' threads: each takes two, the second
        // started at whatever depth the others are (not more: with the ZSobol sampler's digit
        // loops and NEE, lavapipe's loop limit (GpuTracer::set_persistent_threads) cut threads of
        // 8 samples short).
        gpu_tracer.set_persistent_threads(Some((w * h * spp / 2).max(1)));
        gpu_tracer.set_estimator(estimator);
        gpu_tracer.set_russian_roulette(roulette);
        gpu_tracer.set_sampler(sampler);
        let gpu = gpu_tracer.render(&s, &mut |_, _| {}).unwrap();
        let (batch, samples) = gpu_tracer.last_batch_samples().unwrap().unwrap();
        assert_eq!(batch.rays(), w * h * spp, "one batch holds every sample");
        let mut diverged = 0;
        let mut worst = (0.0f32, 0u32, 0u32);
        for (slot, g) in samples.iter().enumerate() {
            let (p, smp) = (slot as u32 % (w * h), slot as u32 / (w * h));
            let c = cpu_tracer.sample_radiance(&s, p, smp);
            let d = (0..3)
                .map(|k| (g[k] - c[k]).abs() / (1.0 + c[k].abs()))
                .fold(0.0, f32::max);
            if d > 1e-4 {
                diverged += 1;
            }
            if d > worst.0 {
                worst = (d, p, smp);
            }
        }
        let e = relative_rmse(&gpu.radiance, &cpu.radiance);
        // The noise scale: two CPU renders that differ only in their seed.
        let other_seed = cpu_with()
            .render(
                &TraceSettings {
                    seed: s.seed + 1,
                    ..s
                },
                &mut |_, _| {},
            )
            .unwrap();
        let noise = relative_rmse(&other_seed.radiance, &cpu.radiance);
        eprintln!(
            "{name}: rel RMSE {e:.3e} (independent renders: {noise:.3e}), {diverged} of {} samples \
         differ by > 1e-4 (worst {worst:?}); rays {} / {}",
            samples.len(),
            cpu.rays_traced,
            gpu.rays_traced
        );
        // Same random numbers, same functions: a sample differs only by float rounding (1e-7
        // relative: different libm sin/cos/sqrt, fused multiply-adds), unless rounding flips a
        // decision (a Fresnel choice, an edge hit, a side test) and the path goes elsewhere,
        // which changes that sample entirely. We allow such divergence in 1% of the samples
        // (none is seen on lavapipe) and bound the image difference at 1e-3, two orders of
        // magnitude below the Monte Carlo noise of these renders (`noise`, 0.1 to 1): images that
        // merely agree on average could not pass.
        assert!(
            diverged * 100 <= samples.len(),
            "{name}: {diverged} samples diverged"
        );
        let max_rays_apart = diverged as u64 * u64::from(bounces + 1);
        assert!(
            cpu.rays_traced.abs_diff(gpu.rays_traced) <= max_rays_apart,
            "{name}: ray counts"
        );
        assert!(e < 1e-3, "{name}: relative RMSE {e}");
        assert!(
            noise > 30.0 * e.max(1e-4),
            "{name}: the comparison is not sharper than the noise"
        );
        assert_eq!(cpu.dropped_samples + gpu.dropped_samples, 0);
    }
}

#[test]
fn cornell_box_matches_cpu() {
    compare("cornell_box_matches_cpu", &cornell_box(), 32, 32, 4, 4);
}

/// An image of whole 8x4 tiles and one whose last tile column and row are narrower: the
/// megakernel's threads take the pixels tile by tile (`tiled_ray`) and must still cover each
/// pixel sample once and write it to its own slot.
#[test]
fn images_of_partial_pixel_tiles_match_cpu() {
    compare("partial_tiles_match_cpu", &cornell_box(), 21, 13, 2, 3);
}

#[test]
fn spheres_match_cpu() {
    compare("spheres_match_cpu", &spheres(), 32, 32, 4, 6);
}

/// Russian roulette draws the same decisions on both backends and in both schedules (the
/// wavefront carries the divided throughput between launches).
#[test]
fn russian_roulette_matches_cpu() {
    for schedule in [Schedule::Megakernel, Schedule::Wavefront] {
        compare_with_roulette(
            "russian_roulette_matches_cpu",
            &materials(),
            [32, 32, 4, 8],
            schedule,
            Estimator::Nee,
            Some(1),
        );
    }
}

/// Plastic (smooth, rough with coat tables), conductors with complex IORs, rough glass, in
/// both schedules.
#[test]
fn microfacet_materials_match_cpu() {
    use raylume_scene::Feature::*;
    let f = materials().features();
    for feature in [Plastic, RoughGlass, RoughMetal, Metal, Textures, Emission] {
        assert!(f.contains(feature), "{feature:?} not in the fixture");
    }
    for schedule in [Schedule::Megakernel, Schedule::Wavefront] {
        compare_with(
            "microfacet_materials_match_cpu",
            &materials(),
            [32, 32, 4, 6],
            schedule,
            Estimator::Nee,
        );
    }
}

#[test]
fn textured_matches_cpu() {
    compare("textured_matches_cpu", &textured(), 32, 32, 4, 4);
}

/// `textured()` with its texture stored as 8-bit sRGB codes, and a second, linear texture
/// after it (on the pyramid), so that offsets past a packed texture are exercised too.
fn textured_srgb8() -> raylume_scene::Scene {
    let mut s = textured();
    let t = &s.textures[0];
    let codes: Vec<[u8; 3]> = (0..t.texels.len())
        .map(|i| {
            t.texels
                .linear(i)
                .map(|c| (c * 255.0) as u8 ^ (i as u8 & 7))
        })
        .collect();
    s.textures[0].texels = codes.into();
    s.textures.push(support::test_texture(3, 5));
    let pyramid = s.triangles.last().unwrap().material as usize;
    s.materials[pyramid].albedo_texture = Some(1);
    s
}

#[test]
fn srgb8_textures_match_cpu() {
    let s = textured_srgb8();
    assert!(matches!(
        s.textures[0].texels,
        raylume_scene::Texels::Srgb8(_)
    ));
    compare("srgb8_textures_match_cpu", &s, 32, 32, 4, 4);
}

/// Keeping 8-bit texels as codes is a storage choice, not an approximation: the same scene
/// with the codes decoded to floats on load, or decoded when the tracer's buffers are made
/// (`SceneOptions::decode_textures`), renders the same pixels, bit for bit, on the CPU and
/// on the GPU.
#[test]
fn srgb8_storage_changes_no_pixel() {
    let packed = textured_srgb8();
    let mut floats = packed.clone();
    for t in &mut floats.textures {
        t.texels = raylume_scene::Texels::Linear(t.texels.to_linear());
    }
    let decode = raylume_kernels::SceneOptions {
        decode_textures: true,
        ..Default::default()
    };
    // What is stored: the table and a word a texel of the 8x8 codes, or three words a texel;
    // the linear 5x3 and 3x5 textures three words a texel either way.
    let words = |o: &raylume_kernels::SceneOptions| {
        raylume_kernels::scene_data::SceneData::with_options(&packed, &bvh(&packed), o)
            .unwrap()
            .texels
            .len()
    };
    assert_eq!(words(&Default::default()), 256 + 64 + 2 * 3 * 15);
    assert_eq!(words(&decode), 3 * 64 + 2 * 3 * 15);
    let s = settings(24, 24, 2, 4, Schedule::Megakernel);
    let decoded_cpu = CpuTracer::with_options(&packed, &bvh(&packed), &decode)
        .unwrap()
        .render(&s, &mut |_, _| {})
        .unwrap();
    let cpu = [
        render_cpu(&packed, &s),
        render_cpu(&floats, &s),
        decoded_cpu,
    ];
    assert!(cpu[0].radiance == cpu[1].radiance, "CPU images differ");
    assert!(cpu[0].radiance == cpu[2].radiance, "CPU images differ");
    let Some(ctx) = raylume_gpu::testing::context_or_skip("srgb8_storage_changes_no_pixel") else {
        return;
    };
    let tree = bvh(&packed);
    let pipelines =
        raylume_kernels::gpu::TracerPipelines::new(ctx, packed.features(), tree.layout).unwrap();
    let decoded_gpu = GpuTracer::with_options(ctx, &packed, &tree, pipelines, &decode)
        .unwrap()
        .render(&s, &mut |_, _| {})
        .unwrap();
    let gpu = [
        render_gpu(ctx, &packed, &s),
        render_gpu(ctx, &floats, &s),
        decoded_gpu,
    ];
    assert!(gpu[0].radiance == gpu[1].radiance, "GPU images differ");
    assert!(gpu[0].radiance == gpu[2].radiance, "GPU images differ");
    // And the texture is seen at all: without it the image changes.
    let mut plain = packed.clone();
    plain
        .materials
        .iter_mut()
        .for_each(|m| m.albedo_texture = None);
    plain.textures.clear();
    assert!(render_cpu(&plain, &s).radiance != cpu[0].radiance);
}

#[test]
fn environment_lit_matches_cpu() {
    compare(
        "environment_lit_matches_cpu",
        &environment_lit(),
        32,
        32,
        4,
        6,
    );
}

/// Next-event estimation: the same shadow rays and light choices on both backends, in both
/// schedules (the wavefront carries "the last hit sampled the lights" between launches in
/// its ray states).
#[test]
fn cornell_box_with_next_event_estimation_matches_cpu() {
    for schedule in [Schedule::Megakernel, Schedule::Wavefront] {
        compare_with(
            "cornell_box_with_next_event_estimation_matches_cpu",
            &cornell_box(),
            [32, 32, 4, 4],
            schedule,
            Estimator::Nee,
        );
    }
}

/// Next-event estimation toward triangles and spheres, Russian roulette and the ZSobol
/// sampler (the library's defaults but for the sampler) draw the same numbers and the same shadow rays on both
/// backends, in both schedules: the spheres scene has a sphere lamp and a constant sky, the
/// materials scene a triangle lamp and every microfacet material, the environment-lit scene a
/// sky map sampled by its luminance.
#[test]
fn zsobol_with_nee_and_roulette_matches_cpu() {
    for schedule in [Schedule::Megakernel, Schedule::Wavefront] {
        for (scene, bounces) in [(spheres(), 6), (materials(), 6), (environment_lit(), 4)] {
            compare_all(
                "zsobol_with_nee_and_roulette_matches_cpu",
                &scene,
                [32, 32, 4, bounces],
                schedule,
                (Estimator::Nee, Some(2), Sampler::ZSobol),
                BvhLayout::Binary,
            );
        }
    }
}

/// The persistent schedule (path regeneration, here with 2,048 threads taking the 4,096
/// samples) traces the same paths as the CPU: the library's defaults (its sampler the
/// shuffled Sobol') on the materials scene and the spheres (a sphere lamp and a sky), over
/// both layouts.
#[test]
fn persistent_schedule_matches_cpu() {
    for layout in [BvhLayout::Binary, BvhLayout::Wide] {
        for (scene, bounces) in [(materials(), 6), (spheres(), 6)] {
            compare_all(
                "persistent_schedule_matches_cpu",
                &scene,
                [32, 32, 4, bounces],
                Schedule::Persistent,
                (Estimator::Nee, Some(2), Sampler::Sobol),
                layout,
            );
        }
    }
}

/// The compressed wide BVH: the same paths on both backends, in both schedules, for every
/// fixture scene (triangles, spheres, textures, environment maps, every material), with the
/// library's defaults and with the paper's plain estimator.
#[test]
fn wide_bvh_matches_cpu() {
    let scenes = [
        ("cornell box", cornell_box(), 4),
        ("spheres", spheres(), 6),
        ("materials", materials(), 6),
        ("textured", textured(), 4),
        ("environment lit", environment_lit(), 4),
    ];
    for schedule in Schedule::ALL {
        for (name, scene, bounces) in &scenes {
            for (estimator, roulette, sampler) in [
                (Estimator::Nee, Some(2), Sampler::Sobol),
                (Estimator::Plain, None, Sampler::Independent),
            ] {
                eprintln!("wide_bvh_matches_cpu: {name}, {schedule:?}, {estimator:?}");
                compare_all(
                    "wide_bvh_matches_cpu",
                    scene,
                    [32, 32, 4, *bounces],
                    schedule,
                    (estimator, roulette, sampler),
                    BvhLayout::Wide,
                );
            }
        }
    }
}

/// The two layouts find the same hits (ties at shared edges aside), so the CPU renders the
/// same image over either: every fixture scene within a relative RMSE of 1e-3 (as the
/// GPU-CPU comparison: far below the noise of these renders; a tie flips one sample).
#[test]
fn wide_and_binary_bvh_render_the_same_image() {
    for (name, scene) in [
        ("cornell box", cornell_box()),
        ("spheres", spheres()),
        ("materials", materials()),
        ("textured", textured()),
        ("environment lit", environment_lit()),
    ] {
        let s = settings(32, 32, 4, 6, Schedule::Megakernel);
        let render = |layout| {
            let bvh = bvh_with_layout(&scene, layout);
            CpuTracer::new(&scene, &bvh)
                .unwrap()
                .render(&s, &mut |_, _| {})
                .unwrap()
        };
        let (binary, wide) = (render(BvhLayout::Binary), render(BvhLayout::Wide));
        let e = relative_rmse(&wide.radiance, &binary.radiance);
        eprintln!("{name}: wide vs binary rel RMSE {e:.3e}");
        assert!(e < 1e-3, "{name}: relative RMSE {e}");
        assert!(
            binary.rays_traced.abs_diff(wide.rays_traced) * 100 <= binary.rays_traced,
            "{name}: rays {} vs {}",
            binary.rays_traced,
            wide.rays_traced
        );
    }
}

/// NEE toward the environment by the learned guide: the same distributions (learned once on
/// the CPU, uploaded) and the same samples on both backends, in both schedules, for a constant
/// sky (one distribution per cell of the scene's grid: the spheres, the skylight room) and a
/// sky map (all cells' guide times its luminance).
#[test]
fn guided_environment_matches_cpu() {
    for schedule in [Schedule::Megakernel, Schedule::Wavefront] {
        for (name, scene, bounces) in [
            ("spheres", spheres(), 6),
            ("environment lit", environment_lit(), 4),
            ("skylight room", skylight_room(0.8), 4),
        ] {
            eprintln!("guided_environment_matches_cpu: {name}, {schedule:?}");
            compare_guided(
                "guided_environment_matches_cpu",
                &scene,
                [32, 32, 4, bounces],
                schedule,
                (Estimator::Nee, Some(2), Sampler::Sobol),
                BvhLayout::Wide,
                true,
            );
        }
    }
}

/// The megakernels `pipelines` compiled so far, by variant.
fn megakernels(
    pipelines: &raylume_kernels::gpu::TracerPipelines,
) -> Vec<raylume_kernels::gpu::PathVariant> {
    pipelines
        .compiled()
        .into_iter()
        .filter(|(e, _)| *e == "trace_paths")
        .map(|(_, v)| v)
        .collect()
}

/// `gpu`'s render of `scene` with `estimator` and `sampler` against the CPU mirror's: their
/// relative RMSE.
fn render_against_cpu(
    gpu: &mut GpuTracer,
    scene: &raylume_scene::Scene,
    bvh: &raylume_bvh::GpuBvh,
    s: &TraceSettings,
    (estimator, sampler): (Estimator, Sampler),
) -> f64 {
    gpu.set_estimator(estimator);
    gpu.set_sampler(sampler);
    let g = gpu.render(s, &mut |_, _| {}).unwrap();
    let mut cpu = CpuTracer::new(scene, bvh).unwrap();
    cpu.set_estimator(estimator);
    cpu.set_sampler(sampler);
    let c = cpu.render(s, &mut |_, _| {}).unwrap();
    relative_rmse(&g.radiance, &c.radiance)
}

/// One tracer rendering with either estimator and each sampler in turn: its path tracing
/// pipelines are compiled per estimator and sampler (`PathVariant`: a plain render's without
/// next-event estimation's code, an independent one's without the Sobol' samplers'), and each
/// image is still the CPU mirror's, pixel for pixel within rounding.
#[test]
fn estimators_and_samplers_get_their_own_pipelines() {
    use raylume_kernels::gpu::PathVariant;
    let name = "estimators_and_samplers_get_their_own_pipelines";
    let Some(ctx) = raylume_gpu::testing::context_or_skip(name) else {
        return;
    };
    let scene = cornell_box();
    let s = settings(24, 24, 2, 4, Schedule::Megakernel);
    let bvh = bvh_with_layout(&scene, BvhLayout::Wide);
    let pipelines =
        raylume_kernels::gpu::TracerPipelines::new(ctx, scene.features(), bvh.layout).unwrap();
    let mut gpu = GpuTracer::with_pipelines(ctx, &scene, &bvh, pipelines.clone()).unwrap();
    let rounds = [
        (Estimator::Plain, Sampler::Independent),
        (Estimator::Nee, Sampler::Independent),
        (Estimator::Plain, Sampler::Sobol),
        (Estimator::Nee, Sampler::ZSobol),
        (Estimator::Plain, Sampler::Independent),
    ];
    for (round, &(estimator, sampler)) in rounds.iter().enumerate() {
        let e = render_against_cpu(&mut gpu, &scene, &bvh, &s, (estimator, sampler));
        eprintln!("{name}: round {round} {estimator:?} {sampler:?}: rel RMSE {e:.3e}");
        // As `compare_guided`: far below these renders' noise (0.1 to 1).
        assert!(
            e < 1e-3,
            "round {round} {estimator:?} {sampler:?}: relative RMSE {e}"
        );
        // Every variant rendered so far, each compiled once.
        let mut want: Vec<PathVariant> = rounds[..=round]
            .iter()
            .map(|&(e, s)| PathVariant::of(e, s))
            .collect();
        want.sort_unstable();
        want.dedup();
        assert_eq!(
            megakernels(&pipelines),
            want,
            "round {round}: the megakernels compiled"
        );
    }
}

/// The generic pipelines (`Specialisation::Generic`, the baseline specialisation is measured
/// against) hold every estimator's and sampler's code too: one path tracing pipeline for any
/// render, and the CPU mirror's image from it.
#[test]
fn generic_pipelines_hold_every_estimator_and_sampler() {
    use raylume_kernels::gpu::{PathVariant, Specialisation, TracerPipelines};
    let name = "generic_pipelines_hold_every_estimator_and_sampler";
    let Some(ctx) = raylume_gpu::testing::context_or_skip(name) else {
        return;
    };
    let scene = cornell_box();
    let s = settings(16, 16, 2, 3, Schedule::Megakernel);
    let bvh = bvh_with_layout(&scene, BvhLayout::Wide);
    let pipelines =
        TracerPipelines::specialised(ctx, scene.features(), bvh.layout, Specialisation::Generic)
            .unwrap();
    let mut gpu = GpuTracer::with_pipelines(ctx, &scene, &bvh, pipelines.clone()).unwrap();
    for variant in [
        (Estimator::Plain, Sampler::Independent),
        (Estimator::Nee, Sampler::Sobol),
    ] {
        let e = render_against_cpu(&mut gpu, &scene, &bvh, &s, variant);
        assert!(e < 1e-3, "{variant:?}: relative RMSE {e}");
    }
    assert_eq!(megakernels(&pipelines), vec![PathVariant::ANY]);
}
