//! `Tracer::start_backend` and `Tracer::prepare_scene`: the GPU device opens on a thread of its
//! own while the scene's BVH is built and its data prepared; the render finds them ready, says
//! so, and makes the image a render without them makes.

use raylume::{Backend, BvhQuality, Error, Tracer};
use raylume_gpu::{AdapterChoice, ContextOptions, GpuContext};

mod common;
use common::cornell;

#[test]
fn a_scene_prepared_ahead_renders_the_image_of_a_plain_render() {
    let scene = cornell(16, 16, 2);
    let plain = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    let mut t = Tracer::new(Backend::Cpu);
    t.prepare_scene(&scene).unwrap();
    let r = t.render(&scene).unwrap();
    let s = &r.stats;
    assert!(
        s.prepared_ahead && !s.bvh_cached && !s.scene_cached,
        "built and prepared ahead, not found from an earlier render: ahead {}, bvh cached {}, \
         scene cached {}",
        s.prepared_ahead,
        s.bvh_cached,
        s.scene_cached
    );
    // The work done ahead is reported as the render's own.
    assert!(
        s.seconds.bvh > 0.0 && s.seconds.upload > 0.0,
        "{:?}",
        s.seconds
    );
    assert_eq!(s.bvh_preset, plain.stats.bvh_preset);
    assert_eq!(r.pixels, plain.pixels);
    // Once rendered with, the tree and the data are the cache's like any others.
    let again = t.render(&scene).unwrap();
    assert!(again.stats.bvh_cached && again.stats.scene_cached && !again.stats.prepared_ahead);
    assert_eq!(again.pixels, plain.pixels);
}

#[test]
fn the_device_opens_while_the_scene_is_prepared() {
    let Some(_) =
        raylume_gpu::testing::context_or_skip("the_device_opens_while_the_scene_is_prepared")
    else {
        return;
    };
    let scene = cornell(16, 16, 2);
    let plain = Tracer::new(Backend::Gpu).render(&scene).unwrap();
    let mut t = Tracer::new(Backend::Gpu);
    t.start_backend();
    t.prepare_scene(&scene).unwrap();
    let r = t.render(&scene).unwrap();
    assert_eq!(r.stats.backend, "gpu");
    assert!(r.stats.prepared_ahead);
    // The pipelines were compiled on the device's thread, for this render.
    assert!(r.stats.pipelines_ahead && !r.stats.pipelines_cached);
    assert!(r.stats.seconds.pipelines > 0.0);
    assert!(
        r.stats.seconds.device > 0.0,
        "the device's opening, on its own thread, is still reported"
    );
    // The same tree and the same data, uploaded: the same image, bit for bit.
    assert_eq!(r.pixels, plain.pixels);
    let again = t.render(&scene).unwrap();
    assert!(again.stats.scene_cached && !again.stats.prepared_ahead);
    assert!(again.stats.pipelines_cached && !again.stats.pipelines_ahead);
    assert_eq!(again.stats.seconds.device, 0.0, "reported once");
    assert_eq!(again.pixels, plain.pixels);

    // The device opened without a word from the caller: `prepare_scene` starts it.
    let mut quiet = Tracer::new(Backend::Gpu);
    quiet.prepare_scene(&scene).unwrap();
    let r = quiet.render(&scene).unwrap();
    assert!(r.stats.prepared_ahead && r.stats.seconds.device > 0.0);
    assert!(r.stats.pipelines_ahead);
    assert_eq!(r.pixels, plain.pixels);

    // A device opened but never asked for pipelines: the render compiles its own.
    let mut unasked = Tracer::new(Backend::Gpu);
    unasked.start_backend();
    let r = unasked.render(&scene).unwrap();
    assert!(!r.stats.pipelines_ahead && !r.stats.pipelines_cached && !r.stats.prepared_ahead);
    assert_eq!(r.pixels, plain.pixels);
}

/// `Auto` renders on a hardware GPU if there is one, else on the CPU; the two rates choose
/// different presets for this scene, so a tree built for the wrong guess would not be the
/// render's. `prepare_scene` waits for the adapter's choice (not the device) and guesses right.
#[test]
fn auto_knows_its_backend_before_the_device_is_open() {
    let mut scene = cornell(32, 32, 160);
    scene.render.max_bounces = 2;
    common::add_floor_grid(&mut scene);
    // 32 x 32 x 160 spp x 3 segments x 2 (NEE's shadow rays): 0.98 M rays.
    let rays = 32.0 * 32.0 * 160.0 * 3.0 * 2.0;
    let threads = rayon::current_num_threads();
    let build_threads = threads.min(raylume::BVH_BUILD_THREADS);
    let primitives = scene.triangles.len();
    let on_cpu = BvhQuality::for_work(
        primitives,
        rays,
        raylume::CPU_RAYS_PER_SECOND_PER_THREAD * threads as f64,
        build_threads,
    );
    let on_gpu = BvhQuality::for_work(
        primitives,
        rays,
        raylume::GPU_RAYS_PER_SECOND,
        build_threads,
    );
    assert_ne!(on_cpu, on_gpu, "the scene tells the two guesses apart");

    let hardware = GpuContext::new(&ContextOptions {
        choice: AdapterChoice::HardwareOnly,
        adapter_name: None,
    })
    .is_ok();
    let mut t = Tracer::new(Backend::Auto);
    t.start_backend();
    t.prepare_scene(&scene).unwrap();
    let r = t.render(&scene).unwrap().stats;
    let expected = if hardware { on_gpu } else { on_cpu };
    assert_eq!(r.backend, if hardware { "gpu" } else { "cpu" });
    assert_eq!(r.bvh_preset, expected.name());
    assert!(
        r.prepared_ahead,
        "the tree built ahead ({}) is the render's",
        r.bvh_preset
    );
}

#[test]
fn settings_changed_after_preparing_make_the_render_build_its_own() {
    let scene = cornell(16, 16, 2);
    let mut t = Tracer::new(Backend::Cpu);
    t.bvh_quality = Some(BvhQuality::Fast);
    t.prepare_scene(&scene).unwrap();
    t.bvh_quality = Some(BvhQuality::Quality);
    let r = t.render(&scene).unwrap();
    assert!(!r.stats.prepared_ahead && !r.stats.bvh_cached);
    assert_eq!(r.stats.bvh_preset, "quality");
    let mut fresh = Tracer::new(Backend::Cpu);
    fresh.bvh_quality = Some(BvhQuality::Quality);
    assert_eq!(r.pixels, fresh.render(&scene).unwrap().pixels);
}

#[test]
fn prepare_scene_refuses_what_render_refuses() {
    let mut t = Tracer::new(Backend::Cpu);
    let mut empty = cornell(16, 16, 2);
    empty.render.width = 0;
    assert!(
        matches!(t.prepare_scene(&empty), Err(Error::Settings(_))),
        "a zero-width image"
    );
    let mut nan = cornell(16, 16, 2);
    nan.triangles[3].positions[1].x = f32::NAN;
    let e = t.prepare_scene(&nan).unwrap_err();
    assert!(matches!(e, Error::Scene(_)), "{e}");
    assert_eq!(
        e.to_string(),
        t.render(&nan).unwrap_err().to_string(),
        "the render's own error"
    );
}

/// With an environment guide learned on the GPU, the guide's walks need the pipelines' learner
/// before the upload: the render takes the pipelines compiling on the device's thread as soon
/// as that learner is made (the tracer's own pipelines may still compile), and makes the image
/// and the guide a render that compiled everything itself makes.
#[test]
fn a_guided_render_takes_the_learner_before_the_pipelines_are_done() {
    let Some(_) = raylume_gpu::testing::context_or_skip(
        "a_guided_render_takes_the_learner_before_the_pipelines_are_done",
    ) else {
        return;
    };
    let mut scene = cornell(16, 16, 2);
    scene.environment = raylume::scene::Environment::Constant(raylume::glam::Vec3::splat(0.5));
    let guided = |t: &mut Tracer| {
        t.environment_guide = Some(true);
    };
    let mut plain = Tracer::new(Backend::Gpu);
    guided(&mut plain);
    let plain = plain.render(&scene).unwrap();
    assert!(
        plain.stats.environment_guide.starts_with("guided")
            || plain
                .stats
                .environment_guide
                .starts_with("by radiance (too few"),
        "the walks ran: {}",
        plain.stats.environment_guide
    );
    let mut t = Tracer::new(Backend::Gpu);
    guided(&mut t);
    t.start_backend();
    t.prepare_scene(&scene).unwrap();
    let r = t.render(&scene).unwrap();
    // The data prepared while the device opened, uploaded before the walks ran.
    assert!(r.stats.prepared_ahead);
    assert!(r.stats.pipelines_ahead && !r.stats.pipelines_cached);
    assert!(r.stats.pipelines_wait >= 0.0 && r.stats.pipelines_wait <= r.stats.seconds.total);
    assert_eq!(r.stats.environment_guide, plain.stats.environment_guide);
    assert_eq!(r.pixels, plain.pixels);
}

/// `prepare_geometry` (what `Scene::load_with`'s hook calls while the images decode) builds the
/// render's tree; `prepare_scene` then finds it and prepares the rest, and the render makes
/// the image of a plain render, reporting the build as done ahead.
#[test]
fn the_tree_built_from_the_geometry_alone_is_the_renders() {
    let scene = cornell(16, 16, 2);
    let plain = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    let mut t = Tracer::new(Backend::Cpu);
    t.prepare_geometry(&scene).unwrap();
    t.prepare_scene(&scene).unwrap();
    let r = t.render(&scene).unwrap();
    assert!(
        r.stats.prepared_ahead && !r.stats.bvh_cached,
        "{:?}",
        r.stats.seconds
    );
    assert!(r.stats.seconds.bvh > 0.0);
    assert_eq!(r.pixels, plain.pixels);
    // A scene the render refuses: refused here as well.
    let mut empty = scene.clone();
    empty.render.width = 0;
    assert!(matches!(
        Tracer::new(Backend::Cpu).prepare_geometry(&empty),
        Err(Error::Settings(_))
    ));
}

#[test]
fn the_timeline_holds_the_milestones_in_the_order_they_depend_on() {
    let Some(_) = raylume_gpu::testing::context_or_skip(
        "the_timeline_holds_the_milestones_in_the_order_they_depend_on",
    ) else {
        return;
    };
    let scene = cornell(16, 16, 2);
    let timeline = raylume::Timeline::new();
    let mut t = Tracer::new(Backend::Gpu);
    t.timeline = Some(timeline.clone());
    t.start_backend();
    t.prepare_scene(&scene).unwrap();
    timeline.mark("prepared");
    let r = t.render(&scene).unwrap();
    let marks = &r.stats.timeline;
    let at = |event: &str| {
        let found: Vec<f64> = marks
            .iter()
            .filter(|m| m.event == event)
            .map(|m| m.seconds)
            .collect();
        assert_eq!(found.len(), 1, "`{event}` once in {marks:#?}");
        found[0]
    };
    // Each milestone after what it needs: the tree before the render that uses it, the
    // device before its pipelines and the upload, the upload and pipelines before the trace.
    assert!(at("device: adapter chosen") <= at("device: open"));
    assert!(at("device: open") <= at("pipelines: compiled"));
    assert!(at("bvh: built ahead") <= at("prepared"));
    assert!(at("prepared") <= at("render: starts"));
    assert!(at("device: open") <= at("upload: done"));
    assert!(at("pipelines: compiled") <= at("render: pipelines in hand"));
    assert!(at("upload: done") <= at("render: traced"));
    assert!(at("render: pipelines in hand") <= at("render: traced"));
    assert!(at("render: traced") <= at("render: image read back"));
    assert_eq!(marks.last().unwrap().event, "render: ends", "{marks:#?}");
    assert!(marks.windows(2).all(|w| w[0].seconds <= w[1].seconds));
    // What the caller marks after the render joins the same timeline.
    timeline.mark("saved");
    assert_eq!(timeline.marks().len(), marks.len() + 1);

    // A tracer without a timeline marks nothing.
    let r = Tracer::new(Backend::Gpu).render(&scene).unwrap();
    assert!(r.stats.timeline.is_empty());
}

/// Data prepared for a GPU render leaves the environment guide to the GPU
/// (`SceneData::before_guide_walks`); should the render run on the CPU after all (here the
/// backend changed between `prepare_scene` and `render`), the CPU learns the guide itself and
/// the image is a plain CPU render's, bit for bit.
#[test]
fn data_prepared_for_the_gpu_completes_its_guide_on_the_cpu() {
    let Some(_) = raylume_gpu::testing::context_or_skip(
        "data_prepared_for_the_gpu_completes_its_guide_on_the_cpu",
    ) else {
        return;
    };
    let mut scene = cornell(16, 16, 2);
    scene.environment = raylume::scene::Environment::Constant(raylume::glam::Vec3::splat(0.5));
    let mut plain = Tracer::new(Backend::Cpu);
    plain.environment_guide = Some(true);
    let plain = plain.render(&scene).unwrap();
    assert!(
        plain.stats.environment_guide.starts_with("guided"),
        "{}",
        plain.stats.environment_guide
    );
    let mut t = Tracer::new(Backend::Gpu);
    t.environment_guide = Some(true);
    t.prepare_scene(&scene).unwrap();
    t.backend = Backend::Cpu;
    let r = t.render(&scene).unwrap();
    assert_eq!(r.stats.backend, "cpu");
    assert!(r.stats.prepared_ahead, "the GPU's preparation was taken");
    assert_eq!(r.stats.environment_guide, plain.stats.environment_guide);
    assert_eq!(r.pixels, plain.pixels);
}
