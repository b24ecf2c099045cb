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
