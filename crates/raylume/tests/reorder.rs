//! `--reorder off | on | auto` through the facade: sorting traces the same paths and gives
//! the same image bit for bit, `on` runs the wavefront whatever the schedule, `auto` starts
//! with what `off` runs, decides from measurement, caches its decision per scene and renders
//! the same image, and the CPU never sorts.

use std::path::Path;

use raylume::{Backend, ReorderMode, ReorderPolicy, Scene, Schedule, Tracer};

fn scene(file: &str, w: u32, h: u32, spp: u32, bounces: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(file);
    let mut s = Scene::load(path).unwrap();
    s.render.width = w;
    s.render.height = h;
    s.render.spp = spp;
    s.render.max_bounces = bounces;
    s
}

fn gpu_tracer(schedule: Schedule, reorder: ReorderPolicy, batch_spp: u32) -> Tracer {
    let mut t = Tracer::new(Backend::Gpu);
    t.schedule = Some(schedule);
    t.reorder = reorder;
    t.batch_spp = batch_spp;
    t
}

#[test]
fn reorder_on_renders_the_image_off_renders() {
    if raylume_gpu::testing::context_or_skip("reorder_on_renders_the_image_off_renders").is_none() {
        return;
    }
    let mut t = gpu_tracer(Schedule::Megakernel, ReorderPolicy::Off, 2);
    // Diffuse walls, then mirror and glass spheres (cornell-plus), then an open sky (spheres).
    for file in ["cornell-box.toml", "cornell-plus.toml", "spheres.toml"] {
        let s = scene(file, 24, 16, 5, 6);
        t.reorder = ReorderPolicy::Off;
        t.schedule = Some(Schedule::Megakernel);
        let off = t.render(&s).unwrap();
        assert_eq!(
            (off.stats.reorder.as_str(), off.stats.seconds.sort),
            ("off", 0.0)
        );
        assert!(
            off.stats.depth_seconds.is_empty(),
            "megakernel: no bounces to time"
        );
        t.schedule = Some(Schedule::Wavefront);
        let wf = t.render(&s).unwrap();
        assert_eq!(wf.pixels, off.pixels, "{file}: wavefront");
        t.reorder = ReorderPolicy::On;
        for (schedule, mode) in [
            (Schedule::Wavefront, ReorderMode::SortIndex),
            (Schedule::Megakernel, ReorderMode::SortPermute),
        ] {
            t.schedule = Some(schedule);
            t.reorder_mode = mode;
            let on = t.render(&s).unwrap();
            // Bit-identical: sorting only changes which GPU thread traces which ray; random
            // numbers are keyed by (pixel, sample, bounce, dimension), each sample lands in
            // its own slot, and `resolve` sums a pixel's samples in sample order, so not one
            // float operation differs (raylume-kernels' tests/reorder.rs shows the same
            // ray by ray).
            assert_eq!(on.pixels, off.pixels, "{file} {mode:?}");
            assert_eq!(
                on.stats.rays_traced, off.stats.rays_traced,
                "{file} {mode:?}"
            );
            let st = &on.stats;
            assert_eq!(st.schedule, "wavefront");
            assert!(
                st.reorder.starts_with(&format!(
                    "on: wavefront, {} before depths 1..=6",
                    mode.name()
                )),
                "{}",
                st.reorder
            );
            // `--schedule megakernel --reorder on` runs the wavefront and says so.
            assert_eq!(
                st.reorder.contains("the megakernel schedule cannot sort"),
                schedule == Schedule::Megakernel,
                "{}",
                st.reorder
            );
            assert!(st.seconds.sort > 0.0 && st.seconds.sort < st.seconds.trace);
            assert_eq!(st.depth_seconds.len(), 7, "depths 0..=6");
            for d in &st.depth_seconds {
                assert!(d.propagate > 0.0, "{d:?}");
                assert_eq!(
                    d.sort > 0.0,
                    d.depth >= 1,
                    "{d:?}: sorted before depths 1..=6"
                );
                assert_eq!(
                    d.permute > 0.0,
                    d.depth >= 1 && mode == ReorderMode::SortPermute
                );
            }
        }
    }
}

#[test]
fn auto_measures_whole_renders_then_keeps_the_fastest() {
    if raylume_gpu::testing::context_or_skip("auto_measures_whole_renders_then_keeps_the_fastest")
        .is_none()
    {
        return;
    }
    let s = scene("cornell-plus.toml", 16, 16, 12, 4);
    let off = gpu_tracer(Schedule::Megakernel, ReorderPolicy::Off, 1)
        .render(&s)
        .unwrap();
    // 12 batches of 1 spp; each exploring render runs one candidate in all of them.
    let mut t = gpu_tracer(Schedule::Megakernel, ReorderPolicy::Auto, 1);
    assert!(t.auto_decision(&s).is_none());
    let first = t.render(&s).unwrap();
    assert_eq!(
        first.pixels, off.pixels,
        "the first render runs what off runs"
    );
    assert_eq!(first.stats.schedule, "megakernel");
    assert_eq!(first.stats.seconds.sort, 0.0);
    let mut renders = 1;
    let mut last = first;
    while t.auto_decision(&s).is_none() {
        last = t.render(&s).unwrap();
        assert_eq!(
            last.pixels, off.pixels,
            "trials are real renders of the same image"
        );
        assert_eq!(last.stats.rays_traced, off.stats.rays_traced);
        assert!(
            ["megakernel", "persistent", "wavefront"].contains(&last.stats.schedule.as_str()),
            "one schedule per render: {}",
            last.stats.schedule
        );
        renders += 1;
        // 5 candidates (the three schedules, the wavefront sorted two ways) and a mask, in at
        // most 4 rounds, then the leader: at most 24.
        assert!(renders <= 24, "undecided after {renders} renders");
    }
    assert!(
        renders >= 5 + 2,
        "every candidate measured, the leader thrice: {renders}"
    );
    let decision = t.auto_decision(&s).expect("decided").clone();
    assert_eq!(last.stats.reorder, format!("auto: {}", decision.summary));
    // The summary lists what was measured: every candidate with its time.
    for c in [
        "megakernel ",
        "persistent ",
        "wavefront ",
        "wavefront, sort-index before depths 1..=4 ",
        "wavefront, sort-permute before depths 1..=4 ",
    ] {
        assert!(decision.summary.contains(c), "{c} in {}", decision.summary);
    }
    let first = last;
    // Later renders of the same scene run the decision from their first batch.
    let again = t.render(&s).unwrap();
    assert_eq!(again.pixels, off.pixels);
    assert_eq!(again.stats.reorder, first.stats.reorder);
    assert_eq!(again.stats.schedule, decision.plan.schedule.name());
    assert_eq!(
        again.stats.seconds.sort > 0.0,
        decision.plan.sorts(4),
        "{}",
        decision.summary
    );

    // Another size, or another scene, is measured afresh.
    let mut bigger = s.clone();
    bigger.render.width = 20;
    assert!(t.auto_decision(&bigger).is_none());
    let mut other = s.clone();
    other.materials[0].albedo *= 0.5;
    assert!(t.auto_decision(&other).is_none());
    assert!(t.auto_decision(&s).is_some());
}

#[test]
fn auto_on_one_batch_renders_starts_as_off_and_decides_over_renders() {
    if raylume_gpu::testing::context_or_skip(
        "auto_on_one_batch_renders_starts_as_off_and_decides_over_renders",
    )
    .is_none()
    {
        return;
    }
    let s = scene("cornell-box.toml", 16, 16, 1, 3);
    let off = gpu_tracer(Schedule::Wavefront, ReorderPolicy::Off, 20)
        .render(&s)
        .unwrap();
    let mut t = gpu_tracer(Schedule::Wavefront, ReorderPolicy::Auto, 20);
    let mut renders = 0;
    while t.auto_decision(&s).is_none() {
        let r = t.render(&s).unwrap();
        assert_eq!(r.pixels, off.pixels, "render {renders}");
        if renders == 0 {
            // One batch: the first render runs exactly what `off` runs.
            assert_eq!(r.stats.schedule, "wavefront");
            assert_eq!(r.stats.seconds.sort, 0.0);
            assert!(
                r.stats
                    .reorder
                    .starts_with("auto: still measuring (1 trial render so far"),
                "{}",
                r.stats.reorder
            );
        }
        renders += 1;
        assert!(renders <= 24, "undecided after {renders} renders");
    }
    assert!(renders >= 4, "every candidate measured: {renders} renders");
    let r = t.render(&s).unwrap();
    assert_eq!(r.pixels, off.pixels);
    assert!(r.stats.reorder.starts_with("auto: "), "{}", r.stats.reorder);
}

#[test]
fn the_cpu_never_reorders() {
    let s = scene("cornell-box.toml", 12, 8, 2, 3);
    let off = Tracer::new(Backend::Cpu).render(&s).unwrap();
    for policy in [ReorderPolicy::On, ReorderPolicy::Auto] {
        let mut t = Tracer::new(Backend::Cpu);
        t.reorder = policy;
        let r = t.render(&s).unwrap();
        assert_eq!(r.pixels, off.pixels);
        assert!(
            r.stats
                .reorder
                .starts_with("off: the CPU backend never reorders"),
            "{}",
            r.stats.reorder
        );
        assert_eq!(r.stats.seconds.sort, 0.0);
        assert!(r.stats.depth_seconds.is_empty());
    }
}

#[test]
fn reorder_on_without_a_sorting_mode_is_an_error() {
    if raylume_gpu::testing::context_or_skip("reorder_on_without_a_sorting_mode_is_an_error")
        .is_none()
    {
        return;
    }
    let mut t = gpu_tracer(Schedule::Wavefront, ReorderPolicy::On, 20);
    t.reorder_mode = ReorderMode::Off;
    let e = t
        .render(&scene("cornell-box.toml", 8, 8, 1, 2))
        .unwrap_err();
    assert!(matches!(e, raylume::Error::Settings(_)), "{e}");
}

#[test]
fn a_tracer_reusing_its_gpu_buffers_renders_what_fresh_tracers_render() {
    if raylume_gpu::testing::context_or_skip(
        "a_tracer_reusing_its_gpu_buffers_renders_what_fresh_tracers_render",
    )
    .is_none()
    {
        return;
    }
    // One tracer keeps its work buffers and sorters from render to render, growing them to
    // cover every need seen (`GpuWorkspace`): buffers larger than a render needs, left over
    // from another scene, schedule, size or batch shape, must not change any image.
    // (scene, [width, height, spp, batch_spp], schedule, reorder, mode)
    type Step = (&'static str, [u32; 4], Schedule, ReorderPolicy, ReorderMode);
    let steps: [Step; 8] = [
        (
            "cornell-box.toml",
            [16, 12, 4, 2],
            Schedule::Megakernel,
            ReorderPolicy::Off,
            ReorderMode::SortIndex,
        ),
        // The wavefront, then more rays per batch and a sorter, then a second state buffer.
        (
            "cornell-plus.toml",
            [16, 12, 2, 2],
            Schedule::Wavefront,
            ReorderPolicy::Off,
            ReorderMode::SortIndex,
        ),
        (
            "cornell-plus.toml",
            [16, 12, 6, 3],
            Schedule::Wavefront,
            ReorderPolicy::On,
            ReorderMode::SortIndex,
        ),
        (
            "cornell-plus.toml",
            [16, 12, 6, 3],
            Schedule::Wavefront,
            ReorderPolicy::On,
            ReorderMode::SortPermute,
        ),
        // Fewer rays than the buffers hold.
        (
            "spheres.toml",
            [16, 12, 2, 1],
            Schedule::Wavefront,
            ReorderPolicy::Off,
            ReorderMode::SortIndex,
        ),
        // Another image size (after `release_memory`), then back.
        (
            "cornell-box.toml",
            [10, 9, 5, 5],
            Schedule::Wavefront,
            ReorderPolicy::On,
            ReorderMode::SortIndex,
        ),
        (
            "cornell-box.toml",
            [10, 9, 2, 2],
            Schedule::Megakernel,
            ReorderPolicy::Off,
            ReorderMode::SortIndex,
        ),
        (
            "cornell-box.toml",
            [16, 12, 4, 2],
            Schedule::Megakernel,
            ReorderPolicy::Off,
            ReorderMode::SortIndex,
        ),
    ];
    let mut kept = Tracer::new(Backend::Gpu);
    for (i, &(file, [w, h, spp, batch_spp], schedule, reorder, mode)) in steps.iter().enumerate() {
        let s = scene(file, w, h, spp, 4);
        let setup = |t: &mut Tracer| {
            t.schedule = Some(schedule);
            t.reorder = reorder;
            t.reorder_mode = mode;
            t.batch_spp = batch_spp;
        };
        setup(&mut kept);
        let mut fresh = Tracer::new(Backend::Gpu);
        setup(&mut fresh);
        let a = kept.render(&s).unwrap();
        let b = fresh.render(&s).unwrap();
        assert_eq!(a.pixels, b.pixels, "step {i}: {file} {w}x{h}");
        assert_eq!(a.stats.rays_traced, b.stats.rays_traced, "step {i}");
        assert_eq!(a.stats.dropped_samples, b.stats.dropped_samples, "step {i}");
        if i == 4 {
            // Freed, then allocated afresh by the next step.
            kept.release_memory();
        }
    }
}

/// The stats name the schedule that ran, each of the three (the persistent schedule was
/// reported as the megakernel before).
#[test]
fn stats_name_the_schedule_that_ran() {
    if raylume_gpu::testing::context_or_skip("stats_name_the_schedule_that_ran").is_none() {
        return;
    }
    let s = scene("cornell-box.toml", 8, 8, 2, 3);
    for schedule in Schedule::ALL {
        let r = gpu_tracer(schedule, ReorderPolicy::Off, 1)
            .render(&s)
            .unwrap();
        assert_eq!(r.stats.schedule, schedule.name());
        // The wavefront's next_event stage is named when it ran (NEE, the default estimator),
        // and asking for it changes nothing the other schedules run.
        let mut t = gpu_tracer(schedule, ReorderPolicy::Off, 1);
        t.next_event_stage = true;
        let r = t.render(&s).unwrap();
        let want = match schedule {
            Schedule::Wavefront => "wavefront + next_event stage".to_string(),
            other => other.name().to_string(),
        };
        assert_eq!(r.stats.schedule, want);
        t.estimator = raylume::Estimator::Plain;
        assert_eq!(t.render(&s).unwrap().stats.schedule, schedule.name());
    }
}
