//! The GPU schedules and their plumbing: megakernel, wavefront and persistent give the same
//! image,
//! specialised pipelines the same image as the unspecialised one, batching does not change
//! the image, non-finite samples are dropped and counted alike on both backends, and bad
//! input comes back as typed errors.

mod support;

use glam::Vec3;
use raylume_bvh::GpuBvh;
use raylume_gpu::wgpu;
use raylume_kernels::{
    CpuTracer, Estimator, GpuTracer, KernelError, Schedule, TraceOutput, TraceSettings,
};
use raylume_scene::{Environment, Features, Texture};
use support::*;

#[test]
fn megakernel_and_wavefront_trace_the_same_paths() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("megakernel_and_wavefront_trace_the_same_paths")
    else {
        return;
    };
    for (name, scene) in schedule_scenes() {
        let bvh = bvh(&scene);
        let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
        let s = settings(24, 16, 3, 5, Schedule::Megakernel);
        let mk = tracer.render(&s, &mut |_, _| {}).unwrap();
        let s = TraceSettings {
            schedule: Schedule::Wavefront,
            ..s
        };
        let wf = tracer.render(&s, &mut |_, _| {}).unwrap();
        // The same functions on the same random numbers in the same order: only a compiler's
        // different contraction of a multiply-add could separate them (none was seen on
        // lavapipe, where they are bit-identical).
        let e = relative_rmse(&wf.radiance, &mk.radiance);
        assert!(e < 1e-6, "{name}: relative RMSE {e}");
        assert_eq!(mk.rays_traced, wf.rays_traced, "{name}");
        assert!(mk.timing("trace_paths").is_some() && wf.timing("propagate").is_some());
        // Persistent threads: the same functions per sample, only another thread traces it.
        // With 192 threads each takes 6 samples from the counter, starting them at every
        // bounce depth as others end (few enough for lavapipe's loop limit).
        tracer.set_persistent_threads(Some(192));
        let ps = tracer
            .render(
                &TraceSettings {
                    schedule: Schedule::Persistent,
                    ..s
                },
                &mut |_, _| {},
            )
            .unwrap();
        tracer.set_persistent_threads(None);
        let e = relative_rmse(&ps.radiance, &mk.radiance);
        assert!(e < 1e-6, "{name} persistent: relative RMSE {e}");
        assert_eq!(mk.rays_traced, ps.rays_traced, "{name} persistent");
        assert!(ps.timing("trace_paths").is_some());

        // After the last bounce every ray has ended: the output queue is empty.
        let b = tracer.wavefront_buffers().expect("wavefront buffers");
        let counts: Vec<u32> = ctx.read_buffer(b.queue_counts, 2).unwrap();
        let q = (s.max_bounces & 1) as usize;
        assert_eq!(counts[1 - q], 0, "{name}: rays alive after the last bounce");
    }
}

#[test]
fn specialised_pipelines_render_what_the_reference_renders() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "specialised_pipelines_render_what_the_reference_renders",
    ) else {
        return;
    };
    for scene in [cornell_box(), textured()] {
        assert_ne!(scene.features(), Features::all());
        let bvh = bvh(&scene);
        let s = settings(16, 16, 2, 4, Schedule::Megakernel);
        let special = GpuTracer::new(ctx, &scene, &bvh)
            .unwrap()
            .render(&s, &mut |_, _| {})
            .unwrap();
        let mut reference = GpuTracer::with_features(ctx, &scene, &bvh, Features::all()).unwrap();
        assert_eq!(reference.features(), Features::all());
        let all = reference.render(&s, &mut |_, _| {}).unwrap();
        // Code removed by specialisation is code the scene cannot reach.
        let e = relative_rmse(&special.radiance, &all.radiance);
        assert!(e < 1e-6, "relative RMSE {e}");
    }
    // Specialising away a feature the scene uses is refused.
    let scene = spheres();
    let err = GpuTracer::with_features(ctx, &scene, &bvh(&scene), Features::NONE)
        .err()
        .expect("refused");
    assert!(matches!(err, KernelError::InvalidScene(_)), "{err}");
}

#[test]
fn batching_does_not_change_the_image() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("batching_does_not_change_the_image")
    else {
        return;
    };
    let scene = spheres();
    let bvh = bvh(&scene);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let base = settings(20, 12, 5, 4, Schedule::Megakernel);
    let whole = tracer.render(&base, &mut |_, _| {}).unwrap();
    // Each pixel's samples are summed in sample order whatever the batches, so the image is
    // bit-identical: 1 sample per batch, and (with a ray cap below the pixel count) ranges of
    // 100 pixels, one sample at a time, for both schedules.
    let mut calls = Vec::new();
    let one = tracer
        .render(
            &TraceSettings {
                batch_spp: 1,
                ..base
            },
            &mut |d, t| calls.push((d, t)),
        )
        .unwrap();
    assert_eq!(one.radiance, whole.radiance);
    assert_eq!(one.rays_traced, whole.rays_traced);
    assert_eq!(
        calls,
        (1..=5).map(|d| (d, 5)).collect::<Vec<_>>(),
        "progress after each batch"
    );
    tracer.set_batch_ray_limit(Some(100));
    tracer.set_persistent_threads(Some(16));
    for schedule in Schedule::ALL {
        let mut last = (0, 0);
        let chunked = tracer
            .render(&TraceSettings { schedule, ..base }, &mut |d, t| {
                last = (d, t)
            })
            .unwrap();
        assert_eq!(chunked.radiance, whole.radiance, "{schedule:?}");
        assert_eq!(last, (5, 5));
        let (batch, _) = tracer.last_batch_samples().unwrap().unwrap();
        assert!(
            batch.pixel_count <= 100 && batch.sample_count == 1,
            "{batch:?}"
        );
    }
    // The CPU's batches do not change its image either.
    let cpu = |batch_spp| {
        CpuTracer::new(&scene, &bvh)
            .unwrap()
            .render(&TraceSettings { batch_spp, ..base }, &mut |_, _| {})
            .unwrap()
    };
    assert_eq!(cpu(1).radiance, cpu(20).radiance);
}

#[test]
fn non_finite_samples_are_dropped_and_counted_on_both_backends() {
    // A light of infinite emission makes every sample that sees it infinite (or NaN).
    let mut scene = cornell_box();
    scene.materials[3].emission = Vec3::new(f32::INFINITY, 1.0, 1.0);
    let s = settings(16, 16, 4, 3, Schedule::Megakernel);
    let cpu = render_cpu(&scene, &s);
    assert!(cpu.dropped_samples > 0);
    assert!(cpu.radiance.iter().flatten().all(|x| x.is_finite()));
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "non_finite_samples_are_dropped_and_counted_on_both_backends",
    ) else {
        return;
    };
    for schedule in Schedule::ALL {
        let gpu = render_gpu(ctx, &scene, &TraceSettings { schedule, ..s });
        assert_eq!(gpu.dropped_samples, cpu.dropped_samples, "{schedule:?}");
        assert!(gpu.radiance.iter().flatten().all(|x| x.is_finite()));
        assert!(relative_rmse(&gpu.radiance, &cpu.radiance) < 1e-3);
    }
}

#[test]
fn the_image_can_stay_on_the_gpu() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("the_image_can_stay_on_the_gpu") else {
        return;
    };
    let scene = cornell_box();
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh(&scene)).unwrap();
    assert!(tracer.image_buffer().is_none());
    let s = settings(12, 10, 2, 3, Schedule::Megakernel);
    let stats = tracer.render_to_buffer(&s, &mut |_, _| {}).unwrap();
    let buf = tracer.image_buffer().expect("image");
    assert!(buf.size() >= 12 * 10 * 12);
    assert!(
        buf.usage()
            .contains(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC)
    );
    let on_gpu: Vec<[f32; 3]> = ctx.read_buffer(buf, 120).unwrap();
    let rendered = tracer.render(&s, &mut |_, _| {}).unwrap();
    assert_eq!(on_gpu, rendered.radiance);
    assert_eq!(stats.rays_traced, rendered.rays_traced);
    // Re-rendering at another size reallocates and still matches a fresh tracer.
    let s2 = settings(7, 9, 3, 2, Schedule::Wavefront);
    let again = tracer.render(&s2, &mut |_, _| {}).unwrap();
    assert_eq!(again.radiance, render_gpu(ctx, &scene, &s2).radiance);
}

#[test]
fn bad_input_is_a_typed_error() {
    let scene = cornell_box();
    let bvh = bvh(&scene);
    let mut cpu = CpuTracer::new(&scene, &bvh).unwrap();
    for bad in [
        TraceSettings {
            spp: 0,
            ..TraceSettings::default()
        },
        TraceSettings {
            width: 0,
            ..TraceSettings::default()
        },
        TraceSettings {
            batch_spp: 0,
            ..TraceSettings::default()
        },
        TraceSettings {
            max_bounces: u32::MAX,
            ..TraceSettings::default()
        },
    ] {
        let e = cpu.render(&bad, &mut |_, _| {}).unwrap_err();
        assert!(matches!(e, KernelError::InvalidSettings(_)), "{e}");
    }
    // A BVH of another scene.
    let other = GpuBvh::from_scene(&spheres(), raylume_bvh::BvhQuality::Fast).unwrap();
    let e = CpuTracer::new(&scene, &other).err().expect("mismatch");
    assert!(e.to_string().contains("BVH"), "{e}");
    // A material pointing at a missing texture.
    let mut broken = scene.clone();
    broken.materials[0].albedo_texture = Some(3);
    let e = CpuTracer::new(&broken, &bvh)
        .err()
        .expect("missing texture");
    assert!(e.to_string().contains("texture 3"), "{e}");
    // Triangles with a material out of range: the error names the first such primitive of
    // the tree (the preparation looks them up on every core, then reports as a loop would).
    let mut bad_materials = scene.clone();
    let last = bad_materials.triangles.len() - 1;
    for t in [2, last] {
        bad_materials.triangles[t].material = 99;
    }
    let first_bad = bvh
        .primitives
        .iter()
        .position(|p| [2, last as u32].contains(&p.scene_index()))
        .unwrap();
    let e = CpuTracer::new(&bad_materials, &bvh)
        .err()
        .expect("material out of range");
    assert!(
        e.to_string()
            .contains(&format!("BVH primitive {first_bad} uses material 99")),
        "{e}"
    );

    let Some(ctx) = raylume_gpu::testing::context_or_skip("bad_input_is_a_typed_error") else {
        return;
    };
    let mut gpu = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let e = gpu
        .render(
            &TraceSettings {
                spp: 0,
                ..TraceSettings::default()
            },
            &mut |_, _| {},
        )
        .unwrap_err();
    assert!(matches!(e, KernelError::InvalidSettings(_)), "{e}");
    // An environment map one texel larger than one storage binding: on a device whose
    // binding limit is lowered to 4 MiB (so that the map is small to build on every adapter,
    // an H200's 2 GiB binding included), where a map one texel smaller is accepted.
    let limited = raylume_gpu::testing::context_with_binding_limit_or_skip(
        "bad_input_is_a_typed_error",
        4 << 20,
    )
    .expect("an adapter: context_or_skip found one above");
    let limit = limited.max_binding_bytes();
    assert_eq!(limit, 4 << 20);
    let env_map = |texels: usize| {
        let mut s = scene.clone();
        s.environment = Environment::Map {
            image: Texture {
                name: "huge".into(),
                width: texels as u32,
                height: 1,
                texels: vec![[0.0; 3]; texels].into(),
            },
            strength: 1.0,
            rotation: 0.0,
        };
        s
    };
    // A w x 1 map takes 12 bytes a texel of radiance, 4 of its sampling distribution's column
    // CDF, and 4 for its one row of the row CDF (scene_data::environment_distribution).
    let bytes_of = |w: usize| w as u64 * 16 + 4;
    let texels = ((limit - 4) / 16) as usize;
    assert!(bytes_of(texels) <= limit && bytes_of(texels + 1) > limit);
    assert!(GpuTracer::new(&limited, &env_map(texels), &bvh).is_ok());
    let e = GpuTracer::new(&limited, &env_map(texels + 1), &bvh)
        .err()
        .expect("too large");
    match &e {
        KernelError::SceneTooLarge {
            what,
            bytes,
            limit: l,
            ..
        } => {
            assert_eq!(what, "texture and environment-map data");
            assert_eq!(*bytes, bytes_of(texels + 1));
            assert_eq!(*l, limit);
        }
        other => panic!("expected SceneTooLarge, got {other}"),
    }
    assert!(
        e.to_string().contains("too large for the GPU adapter"),
        "{e}"
    );
}

/// A scene prepared once serves many tracers: on the GPU one upload (`GpuScene`) renders
/// with the scene's own pipelines and with the unspecialised ones, the same image as a
/// tracer that uploads it itself; on the CPU one `SceneData` likewise. Data prepared over
/// another scene's tree is refused, not traced out of bounds.
#[test]
fn a_prepared_scene_serves_many_tracers_and_only_its_own_tree() {
    use raylume_kernels::scene_data::{SceneData, SceneOptions};
    use raylume_kernels::{GpuScene, gpu::TracerPipelines};
    use std::sync::Arc;
    let scene = cornell_box();
    let tree = bvh(&scene);
    let s = settings(12, 10, 2, 3, Schedule::Megakernel);
    let data = SceneData::with_options(&scene, &tree, &SceneOptions::default()).unwrap();
    let other = spheres();
    let other_tree = bvh(&other);
    let refused = CpuTracer::with_data(&other_tree, data.clone()).err();
    assert!(
        matches!(refused, Some(KernelError::InvalidScene(_))),
        "{refused:?}"
    );
    let cpu = CpuTracer::with_data(&tree, data.clone())
        .unwrap()
        .render(&s, &mut |_, _| {})
        .unwrap();
    let fresh = CpuTracer::new(&scene, &tree)
        .unwrap()
        .render(&s, &mut |_, _| {})
        .unwrap();
    assert_eq!(cpu.radiance, fresh.radiance);

    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "a_prepared_scene_serves_many_tracers_and_only_its_own_tree",
    ) else {
        return;
    };
    let refused = GpuScene::upload_data(ctx, scene.features(), &other_tree, data.clone()).err();
    assert!(
        matches!(refused, Some(KernelError::InvalidScene(_))),
        "{refused:?}"
    );
    let uploaded = Arc::new(GpuScene::upload_data(ctx, scene.features(), &tree, data).unwrap());
    let own = GpuTracer::new(ctx, &scene, &tree)
        .unwrap()
        .render(&s, &mut |_, _| {})
        .unwrap();
    for features in [scene.features(), Features::all()] {
        let pipelines = TracerPipelines::new(ctx, features, tree.layout).unwrap();
        let shared = GpuTracer::with_scene(ctx, uploaded.clone(), pipelines)
            .unwrap()
            .render(&s, &mut |_, _| {})
            .unwrap();
        let e = relative_rmse(&shared.radiance, &own.radiance);
        assert!(e < 1e-6, "{features:?}: relative RMSE {e}");
    }
    // Pipelines without a feature the uploaded scene uses are refused.
    let scene = spheres();
    let tree = bvh(&scene);
    let uploaded =
        Arc::new(GpuScene::upload(ctx, &scene, &tree, &SceneOptions::default()).unwrap());
    let pipelines = TracerPipelines::new(ctx, Features::NONE, tree.layout).unwrap();
    let err = GpuTracer::with_scene(ctx, uploaded, pipelines).err();
    assert!(matches!(err, Some(KernelError::InvalidScene(_))), "{err:?}");
}

/// One tracer renders one image size with every schedule in turn, NEE and the wavefront's
/// `next_event` stage included, on a device
/// whose storage bindings are small: the work buffers it keeps between renders are the union
/// of what the renders needed only while that union fits a binding (a megakernel render's
/// large batches of 12-byte sample slots against the wavefront's 128-byte light-sample
/// records per ray would not), else they are made for the render at hand. Each image is the
/// one a fresh tracer renders.
#[test]
fn one_tracer_alternates_schedules_within_the_binding_limit() {
    let Some(ctx) = raylume_gpu::testing::context_with_binding_limit_or_skip(
        "one_tracer_alternates_schedules_within_the_binding_limit",
        64 << 10,
    ) else {
        return;
    };
    let scene = cornell_box();
    let bvh = bvh(&scene);
    // 30 x 20 pixels at 8 spp: 4,800 rays, one megakernel batch (64 KiB / 12 bytes = 5,461
    // rays), ten wavefront batches of at most 512 (64 KiB / 128 bytes).
    let base = TraceSettings {
        batch_spp: 8,
        ..settings(30, 20, 8, 4, Schedule::Megakernel)
    };
    let fresh = |schedule| {
        let mut t = GpuTracer::new(&ctx, &scene, &bvh).unwrap();
        t.set_estimator(Estimator::Nee);
        t.set_next_event_stage(true);
        t.render(&TraceSettings { schedule, ..base }, &mut |_, _| {})
            .unwrap()
    };
    let mut tracer = GpuTracer::new(&ctx, &scene, &bvh).unwrap();
    tracer.set_estimator(Estimator::Nee);
    tracer.set_next_event_stage(true);
    for schedule in [
        Schedule::Megakernel,
        Schedule::Wavefront,
        Schedule::Persistent,
        Schedule::Megakernel,
        Schedule::Wavefront,
    ] {
        let out = tracer
            .render(&TraceSettings { schedule, ..base }, &mut |_, _| {})
            .unwrap_or_else(|e| panic!("{schedule:?}: {e}"));
        assert_eq!(out.radiance, fresh(schedule).radiance, "{schedule:?}");
    }
}

/// A stage that only moves work between threads leaves the render as it was: the same rays
/// traced, the same samples dropped, the same image bit for bit.
fn assert_same_render(staged: &TraceOutput, walked: &TraceOutput, what: &str) {
    assert_eq!(staged.rays_traced, walked.rays_traced, "{what}");
    assert_eq!(staged.dropped_samples, walked.dropped_samples, "{what}");
    let differ = staged
        .radiance
        .iter()
        .zip(&walked.radiance)
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(differ, 0, "{what}: {differ} pixels differ");
}

/// The wavefront's shadow stage (`trace_shadows`, walk_stage.wgsl) walks the shadow rays that
/// `propagate` (with `DEFER_SHADOW`) queued at the walk stage's bounces and adds their
/// vertices' terms as `trace_ray` adds them: the same image bit for bit as the walk stage
/// alone, with roulette ending paths at the vertices whose terms wait (their samples are
/// written by the stage), with some bounces sorted (whose `propagate` walks its own shadow
/// rays) or none, a thread per ray or a few taking the queue's rays in turn. It does not run
/// for the plain estimator, which traces no shadow rays.
#[test]
fn the_shadow_stage_adds_what_propagate_would() {
    let Some(ctx) = raylume_gpu::testing::subgroup_context_or_skip(
        "the_shadow_stage_adds_what_propagate_would",
    ) else {
        return;
    };
    for (name, scene) in schedule_scenes() {
        let bvh = bvh(&scene);
        for reorder in [raylume_kernels::Reorder::OFF, sorted_from(3)] {
            let s = TraceSettings {
                reorder,
                ..settings(24, 16, 3, 5, Schedule::Wavefront)
            };
            let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
            tracer.set_estimator(Estimator::Nee);
            tracer.set_russian_roulette(Some(1));
            tracer.set_walk_stage(true);
            // The tracer's default is on: the reference without it.
            tracer.set_shadow_stage(false);
            let walked = tracer.render(&s, &mut |_, _| {}).unwrap();
            assert!(walked.timing("trace_shadows").is_none());
            tracer.set_shadow_stage(true);
            for groups in [None, Some(2)] {
                tracer.set_walk_stage_groups(groups);
                let staged = tracer.render(&s, &mut |_, _| {}).unwrap();
                let what = format!("{name}, {}, {groups:?} groups", reorder.describe(5));
                assert!(
                    staged.timing("trace_shadows").is_some(),
                    "{what}: no shadow stage ran"
                );
                assert_same_render(&staged, &walked, &what);
            }
        }
    }
    // The plain estimator traces no shadow rays: asked for, the stage does not run.
    let scene = cornell_box();
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh(&scene)).unwrap();
    tracer.set_walk_stage(true);
    tracer.set_shadow_stage(true);
    let out = tracer
        .render(&settings(8, 8, 1, 3, Schedule::Wavefront), &mut |_, _| {})
        .unwrap();
    assert!(out.timing("trace_hits").is_some());
    assert!(out.timing("trace_shadows").is_none());
}

/// The wavefront's walk stage (`trace_hits`, walk_stage.wgsl) walks each ray of a bounce's
/// queue as `propagate` would, only in another thread: the same hits, so the same image bit
/// for bit, with either estimator (NEE walks its shadow rays in `propagate` still), with some
/// bounces sorted (which `propagate` walks) or none, and the binary layout (which has no walk
/// stage) untouched.
#[test]
fn the_walk_stage_traces_the_hits_propagate_would() {
    let Some(ctx) = raylume_gpu::testing::subgroup_context_or_skip(
        "the_walk_stage_traces_the_hits_propagate_would",
    ) else {
        return;
    };
    // Sorted from the third bounce on (the stage walks bounces 0 to 2, the `propagate` compiled
    // without HITS_TRACED the sorted ones: `walk_stage_at`), and from the first (the stage
    // walks the camera rays alone).
    for (name, scene) in schedule_scenes() {
        let bvh = bvh(&scene);
        for estimator in [Estimator::Plain, Estimator::Nee] {
            for reorder in [
                raylume_kernels::Reorder::OFF,
                sorted_from(3),
                sorted_from(1),
            ] {
                let s = TraceSettings {
                    reorder,
                    ..settings(24, 16, 3, 5, Schedule::Wavefront)
                };
                let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
                tracer.set_estimator(estimator);
                // NEE's shadow rays walked in propagate, as without the walk stage (the
                // shadow stage has its own test below).
                tracer.set_shadow_stage(false);
                let walked = tracer.render(&s, &mut |_, _| {}).unwrap();
                assert!(walked.timing("trace_hits").is_none());
                tracer.set_walk_stage(true);
                assert!(tracer.walk_stage(), "wide BVH and subgroups: a walk stage");
                // A thread per ray (lavapipe's default), then two workgroups for the 1,152
                // camera rays: each thread takes the queue's next ray when its own is done,
                // some ten in turn (few enough steps for lavapipe's loop limit).
                for groups in [None, Some(2)] {
                    tracer.set_walk_stage_groups(groups);
                    let staged = tracer.render(&s, &mut |_, _| {}).unwrap();
                    let what = format!(
                        "{name}, {estimator:?}, {}, {groups:?} groups",
                        reorder.describe(5)
                    );
                    assert!(
                        staged.timing("trace_hits").is_some(),
                        "{what}: no walk stage ran"
                    );
                    assert_same_render(&staged, &walked, &what);
                }
            }
        }
    }
    // The binary layout has no walk stage: asked for, the wavefront walks in propagate.
    let scene = cornell_box();
    let binary = bvh_with_layout(&scene, raylume_bvh::BvhLayout::Binary);
    let mut tracer = GpuTracer::new(ctx, &scene, &binary).unwrap();
    tracer.set_walk_stage(true);
    assert!(!tracer.walk_stage());
    let out = tracer
        .render(&settings(8, 8, 1, 3, Schedule::Wavefront), &mut |_, _| {})
        .unwrap();
    assert!(out.timing("trace_hits").is_none());
}

/// A bounce's queue far larger than the stage's lanes can walk in lavapipe's loop limit is
/// walked whole: on a software adapter a lane takes at most `WALK_STAGE_SOFTWARE_SHARE` times
/// its even share of the queue. Without that bound, lavapipe, which runs a workgroup's
/// subgroups one after another and leaves every loop of an invocation once they have run
/// 65,535 iterations between them, let the first subgroups take most of the queue and cut them
/// off with rays taken and never walked: the living room's 57,600 camera rays, two bounces,
/// lost hits at every walked bounce, and the image changed from run to run. (The fixtures of
/// the tests above are too small for it.) On a hardware adapter it checks the same thing.
#[test]
fn a_large_queue_is_walked_whole() {
    let Some(ctx) = raylume_gpu::testing::subgroup_context_or_skip("a_large_queue_is_walked_whole")
    else {
        return;
    };
    // Tracked in the repository: a missing file is a broken checkout, not a skip.
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes/living-room/scene.json");
    let scene =
        raylume_scene::Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let bvh = bvh(&scene);
    let s = settings(320, 180, 1, 2, Schedule::Wavefront);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    tracer.set_estimator(Estimator::Nee);
    tracer.set_walk_stage(false);
    let walked = tracer.render(&s, &mut |_, _| {}).unwrap();
    tracer.set_walk_stage(true);
    tracer.set_shadow_stage(true);
    let staged = tracer.render(&s, &mut |_, _| {}).unwrap();
    assert!(staged.timing("trace_hits").is_some() && staged.timing("trace_shadows").is_some());
    assert_same_render(
        &staged,
        &walked,
        "living room, 320x180, walk and shadow stages",
    );
}
