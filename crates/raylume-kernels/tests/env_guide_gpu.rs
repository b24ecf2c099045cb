//! The environment guide's walks on the GPU (`raylume_kernels::gpu::GuideLearner`,
//! `env_guide.wgsl`) count what the CPU's (`env_guide::learn_environment_guide`) count, in
//! both BVH layouts, on scenes of triangles and of spheres; and a GPU render learns its guide
//! there (`GpuScene::upload`).

mod support;

use raylume_bvh::BvhLayout;
use raylume_kernels::env_guide::{GuideParams, learn_environment_guide_with};
use raylume_kernels::gpu::{GpuScene, GuideLearner};
use raylume_kernels::scene_data::{SceneData, SceneOptions};
use support::*;

/// The walks' counts on the GPU and on the CPU: the same counters, and the same counts but
/// for at most 0.1 % of the escapes. Why any may differ: the GPU's `sin`, `cos`, `sqrt` and
/// fused multiply-adds round differently from Rust's by an ulp or so, and a probe whose
/// direction lies on a direction cell's border (or a ray through a shared edge) can then
/// land on the other side; each such probe moves one count. Lavapipe has matched exactly.
#[test]
fn gpu_walks_count_what_the_cpu_walks_count() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("gpu_walks_count_what_the_cpu_walks_count")
    else {
        return;
    };
    for layout in [BvhLayout::Wide, BvhLayout::Binary] {
        let learner = GuideLearner::new(ctx, layout).unwrap();
        for (name, scene) in [
            ("skylight room", skylight_room(0.8)),
            ("spheres", spheres()),
            ("environment lit", environment_lit()),
        ] {
            let bvh = bvh_with_layout(&scene, layout);
            let data = SceneData::new(&scene, &bvh).unwrap();
            let g = GuideParams::new(&scene.camera, data.scene_min, data.scene_extent);
            let cpu = learn_environment_guide_with(&g, &bvh);
            let (nodes, primitives) = (
                ctx.storage_buffer(
                    "nodes",
                    bvh.node_bytes(),
                    raylume_gpu::wgpu::BufferUsages::empty(),
                )
                .unwrap(),
                ctx.storage_buffer(
                    "primitives",
                    &bvh.primitives,
                    raylume_gpu::wgpu::BufferUsages::empty(),
                )
                .unwrap(),
            );
            let gpu = learner.learn(ctx, &nodes, &primitives, &g).unwrap();
            assert_eq!(gpu.counts.len(), cpu.counts.len(), "{name}");
            assert_eq!(
                (gpu.grid, gpu.grid_scale, gpu.walks),
                (cpu.grid, cpu.grid_scale, cpu.walks)
            );
            // Enough escapes for the comparison to mean something.
            assert!(cpu.escapes > 1000, "{name}: {} escapes", cpu.escapes);
            let moved: u64 = gpu
                .counts
                .iter()
                .zip(&cpu.counts)
                .map(|(&a, &b)| u64::from(a.abs_diff(b)))
                .sum();
            eprintln!(
                "{name}, {layout:?}: {} escapes on the CPU, {} on the GPU, {moved} counts differ",
                cpu.escapes, gpu.escapes
            );
            assert!(
                moved * 1000 <= cpu.escapes,
                "{name}, {layout:?}: {moved} of {} counts differ",
                cpu.escapes
            );
        }
    }
}

/// `GpuScene::upload` learns the guide on the GPU; its walks and escapes are the CPU's
/// preparation's (within the tolerance above), and without the option nothing is learned.
#[test]
fn a_gpu_upload_learns_the_guide_on_the_gpu() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("a_gpu_upload_learns_the_guide_on_the_gpu")
    else {
        return;
    };
    let scene = skylight_room(0.8);
    let bvh = bvh(&scene);
    let options = SceneOptions {
        environment_guide: true,
        ..Default::default()
    };
    let cpu = SceneData::with_options(&scene, &bvh, &options).unwrap();
    let gpu = GpuScene::upload(ctx, &scene, &bvh, &options).unwrap();
    let (Some((cw, ce)), Some((gw, ge))) = (
        cpu.environment_guide_walks,
        gpu.data().environment_guide_walks,
    ) else {
        panic!("both learned a guide");
    };
    assert_eq!(cw, gw);
    assert!(ce.abs_diff(ge) * 1000 <= ce, "{ce} vs {ge} escapes");
    assert_eq!(
        cpu.environment_guided_cdf.map(|c| c.offset),
        gpu.data().environment_guided_cdf.map(|c| c.offset)
    );
    let plain = GpuScene::upload(ctx, &scene, &bvh, &SceneOptions::default()).unwrap();
    assert_eq!(plain.data().environment_guide_walks, None);
}

/// A learner made on another thread is adopted by pipelines of its layout (and then is theirs:
/// `guide_learner` returns it, compiling none) and refused, with a typed error, by pipelines
/// of the other layout.
#[test]
fn pipelines_adopt_a_learner_of_their_layout_only() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("pipelines_adopt_a_learner_of_their_layout_only")
    else {
        return;
    };
    use raylume_kernels::gpu::TracerPipelines;
    let features = raylume_scene::Features::all();
    let wide = TracerPipelines::specialised(
        ctx,
        features,
        BvhLayout::Wide,
        raylume_kernels::Specialisation::Composed,
    )
    .unwrap();
    let binary = std::sync::Arc::new(GuideLearner::new(ctx, BvhLayout::Binary).unwrap());
    assert!(matches!(
        wide.adopt_guide_learner(binary),
        Err(raylume_kernels::KernelError::InvalidSettings(_))
    ));
    let learner = std::sync::Arc::new(GuideLearner::new(ctx, BvhLayout::Wide).unwrap());
    wide.adopt_guide_learner(learner.clone()).unwrap();
    assert!(std::sync::Arc::ptr_eq(
        &wide.guide_learner(ctx).unwrap(),
        &learner
    ));
}

/// A scene uploaded before its guide was learned (`GpuScene::upload_before_guide`, what a GPU
/// render does with the data it prepared while the device opened) is, once `finish` has run
/// the walks and written their distributions into the room kept for them, the scene
/// `upload_with_learner` makes: the same walks, the same distributions at the same place, the
/// same texel buffer and the same image (bit for bit), for a constant sky and for a map.
/// Finished on the CPU (`learn_pending_guide`) the data is the CPU's own preparation.
#[test]
fn a_scene_uploaded_before_its_guide_is_the_scene_uploaded_with_it() {
    use std::sync::Arc;
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "a_scene_uploaded_before_its_guide_is_the_scene_uploaded_with_it",
    ) else {
        return;
    };
    let options = SceneOptions {
        environment_guide: true,
        ..Default::default()
    };
    for (name, scene) in [
        ("skylight room (constant sky)", skylight_room(0.8)),
        ("environment lit (map)", environment_lit()),
    ] {
        let bvh = bvh(&scene);
        let learner = GuideLearner::new(ctx, bvh.layout).unwrap();
        let with =
            GpuScene::upload_with_learner(ctx, &scene, &bvh, &options, Some(&learner)).unwrap();
        let before = SceneData::before_guide_walks(&scene, &bvh, &options).unwrap();
        assert!(before.pending_guide().is_some(), "{name}");
        assert!(before.pending_guide_words() > 0, "{name}");
        let features = raylume_kernels::tracer_features(&scene);
        // Data with a guide pending is refused where a complete one is expected.
        let refused = GpuScene::upload_data(ctx, features, &bvh, before.clone()).err();
        assert!(
            matches!(
                refused,
                Some(raylume_kernels::KernelError::InvalidSettings(_))
            ),
            "{name}: {refused:?}"
        );
        let pending = GpuScene::upload_before_guide(ctx, features, &bvh, before.clone()).unwrap();
        assert!(pending.pending_guide().is_some());
        let done = pending.finish(ctx, &scene, &bvh, Some(&learner)).unwrap();
        let (a, b) = (done.data(), with.data());
        assert!(a.environment_guided_cdf.is_some(), "{name}: a useful guide");
        assert_eq!(a.environment_guided_cdf, b.environment_guided_cdf, "{name}");
        assert_eq!(
            a.environment_guide_walks, b.environment_guide_walks,
            "{name}"
        );
        assert_eq!(done.texel_bytes(), with.texel_bytes(), "{name}");
        let s = settings(24, 16, 2, 4, raylume_kernels::Schedule::Megakernel);
        let image = |uploaded: GpuScene| {
            let pipelines =
                raylume_kernels::gpu::TracerPipelines::new(ctx, features, bvh.layout).unwrap();
            let mut t =
                raylume_kernels::GpuTracer::with_scene(ctx, Arc::new(uploaded), pipelines).unwrap();
            t.set_estimator(raylume_kernels::Estimator::Nee);
            t.set_environment_guide(true);
            t.render(&s, &mut |_, _| {}).unwrap().radiance
        };
        assert_eq!(image(done), image(with), "{name}: the same image");

        // Nor does the CPU tracer render it.
        let refused = raylume_kernels::CpuTracer::with_shared(
            Arc::new(bvh.clone()),
            Arc::new(before.clone()),
        )
        .err();
        assert!(
            matches!(
                refused,
                Some(raylume_kernels::KernelError::InvalidSettings(_))
            ),
            "{name}: {refused:?}"
        );
        let mut on_cpu = before;
        on_cpu.learn_pending_guide(&scene, &bvh).unwrap();
        assert!(on_cpu.pending_guide().is_none());
        let cpu = SceneData::with_options(&scene, &bvh, &options).unwrap();
        assert_eq!(on_cpu.texels, cpu.texels, "{name}");
        assert_eq!(on_cpu.environment_guided_cdf, cpu.environment_guided_cdf);
        assert_eq!(on_cpu.environment_guide_walks, cpu.environment_guide_walks);
        // A guide is added once.
        assert!(on_cpu.learn_pending_guide(&scene, &bvh).is_ok());
        let guide = learn_environment_guide_with(
            &GuideParams::new(&scene.camera, cpu.scene_min, cpu.scene_extent),
            &bvh,
        );
        assert!(on_cpu.add_guide(&scene, guide, 0.0).is_err());
    }
}
