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
    t.schedule = schedule;
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
        t.schedule = Schedule::Megakernel;
        let off = t.render(&s).unwrap();
        assert_eq!(
            (off.stats.reorder.as_str(), off.stats.seconds.sort),
            ("off", 0.0)
        );
        assert!(
            off.stats.depth_seconds.is_empty(),
            "megakernel: no bounces to time"
        );
        t.schedule = Schedule::Wavefront;
        let wf = t.render(&s).unwrap();
        assert_eq!(wf.pixels, off.pixels, "{file}: wavefront");
        t.reorder = ReorderPolicy::On;
        for (schedule, mode) in [
            (Schedule::Wavefront, ReorderMode::SortIndex),
            (Schedule::Megakernel, ReorderMode::SortPermute),
        ] {
            t.schedule = schedule;
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
                st.reorder.contains("the megakernel cannot sort"),
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
fn auto_measures_on_real_batches_then_keeps_the_fastest() {
    if raylume_gpu::testing::context_or_skip("auto_measures_on_real_batches_then_keeps_the_fastest")
        .is_none()
    {
        return;
    }
    let s = scene("cornell-plus.toml", 16, 16, 12, 4);
    let off = gpu_tracer(Schedule::Megakernel, ReorderPolicy::Off, 1)
        .render(&s)
        .unwrap();
    // 12 batches of 1 spp: enough for every trial (4 candidates, at most 4 second batches and
    // one per-depth mask) in the first render.
    let mut t = gpu_tracer(Schedule::Megakernel, ReorderPolicy::Auto, 1);
    assert!(t.auto_decision(&s).is_none());
    let first = t.render(&s).unwrap();
    assert_eq!(
        first.pixels, off.pixels,
        "trials are real batches of the same image"
    );
    assert_eq!(first.stats.rays_traced, off.stats.rays_traced);
    assert_eq!(first.stats.schedule, "megakernel + wavefront (auto trials)");
    let decision = t
        .auto_decision(&s)
        .expect("decided in the first render")
        .clone();
    assert_eq!(first.stats.reorder, format!("auto: {}", decision.summary));
    // The summary lists what was measured: every candidate with its time.
    for c in [
        "megakernel ",
        "wavefront ",
        "wavefront, sort-index before depths 1..=4 ",
        "wavefront, sort-permute before depths 1..=4 ",
    ] {
        assert!(decision.summary.contains(c), "{c} in {}", decision.summary);
    }
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
                r.stats.reorder.starts_with("auto: still measuring"),
                "{}",
                r.stats.reorder
            );
        }
        renders += 1;
        // 4 candidates, at most 4 second measurements and one mask.
        assert!(renders <= 9, "undecided after {renders} renders");
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
