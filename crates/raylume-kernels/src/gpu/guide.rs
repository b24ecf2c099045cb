//! [`GuideLearner`]: the environment guide's walks on the GPU (`env_guide.wgsl`: the mirror of
//! [`crate::env_guide::guide_walk`], each walk split into `GUIDE_PROBES` threads that follow
//! the same path and trace one probe each). On the H200's 16-core host the CPU's walks took
//! ~50 ms of a first image whose trace took 78 ms. The counts are integer sums, so where the
//! GPU computes the same rays as the CPU (which the tests check) it learns the same guide.

use std::time::Instant;

use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_gpu::{GpuContext, wgpu};
use wgpu::util::DeviceExt;

use super::layout::{storage_entry, uniform_entry};
use crate::KernelError;
use crate::env_guide::{
    EnvironmentGuide, GUIDE_HEIGHT, GUIDE_PROBES, GUIDE_VERTICES, GUIDE_WIDTH, GuideParams,
};
use crate::gpu_types::{GPU_TYPES_WGSL, wgsl_constants};

/// Threads per workgroup of `learn_guide`.
pub const GUIDE_WORKGROUP_SIZE: u32 = 64;

/// The walks' WGSL for a tree of `layout`: the traversal, the shared types and functions
/// they use, and `env_guide.wgsl`, with the constants from Rust.
pub fn guide_source(layout: BvhLayout) -> String {
    let u = |name: &str, v: u32| format!("const {name}: u32 = {v}u;\n");
    let mut s = String::from("// raylume-kernels: the environment guide's walks (gpu/guide.rs)\n");
    s += &wgsl_constants();
    s += &u("GUIDE_WIDTH", GUIDE_WIDTH);
    s += &u("GUIDE_HEIGHT", GUIDE_HEIGHT);
    s += &u("GUIDE_VERTICES", GUIDE_VERTICES);
    s += &u("GUIDE_PROBES", GUIDE_PROBES);
    s += &u("GUIDE_WORKGROUP_SIZE", GUIDE_WORKGROUP_SIZE);
    s += raylume_bvh::traverse_wgsl(layout);
    for part in [
        GPU_TYPES_WGSL,
        crate::math::MATH_WGSL,
        crate::rng::RNG_WGSL,
        crate::sampling::SAMPLING_WGSL,
        include_str!("../env_guide.wgsl"),
    ] {
        s += "\n";
        s += part;
    }
    super::compose(&s, raylume_scene::Features::all())
}

/// The compiled walks for trees of one [`BvhLayout`]; [`GuideLearner::learn`] runs them over
/// an uploaded tree. Made once per context and layout (`TracerPipelines::guide_learner`).
pub struct GuideLearner {
    layout: BvhLayout,
    group_layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    seconds: f64,
}

impl std::fmt::Debug for GuideLearner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GuideLearner")
            .field("layout", &self.layout)
            .finish()
    }
}

impl GuideLearner {
    /// Compiles the walks for trees of `layout`.
    pub fn new(ctx: &GpuContext, layout: BvhLayout) -> Result<Self, KernelError> {
        let start = Instant::now();
        let device = &ctx.device;
        let (group_layout, pipeline) =
            ctx.scoped("compiling the environment guide's walks", || {
                let group_layout =
                    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some("raylume learn_guide"),
                        entries: &[
                            storage_entry(0, true),
                            storage_entry(1, true),
                            uniform_entry(2, false),
                            storage_entry(3, false),
                        ],
                    });
                let pipeline_layout =
                    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("raylume learn_guide"),
                        bind_group_layouts: &[Some(&group_layout)],
                        immediate_size: 0,
                    });
                let module = ctx.shader_module("raylume learn_guide", &guide_source(layout));
                let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("learn_guide"),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some("learn_guide"),
                    compilation_options: Default::default(),
                    cache: None,
                });
                (group_layout, pipeline)
            })?;
        let mut learner = Self {
            layout,
            group_layout,
            pipeline,
            seconds: 0.0,
        };
        learner.warm_up(ctx)?;
        learner.seconds = start.elapsed().as_secs_f64();
        Ok(learner)
    }

    /// One walk over a one-triangle tree, waited for: on the H200 the process's first walks
    /// that read the tree took 16-22 ms however few they were, later ones 0.3-1 ms (the
    /// living room's 25,600: 0.9-1.0 ms), and a dispatch whose threads read nothing (no
    /// walks) did not take that cost away (measured 2026-12-02 with a throwaway timing
    /// binary on the device). Paid here, where the learner is made (beside the BVH build in
    /// `raylume::Tracer`), instead of in the render's upload.
    fn warm_up(&self, ctx: &GpuContext) -> Result<(), KernelError> {
        let one = [raylume_scene::Triangle::flat(
            [glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y],
            0,
        )];
        let tree = GpuBvh::build_with_layout(&one, &[], BvhQuality::Fastest, self.layout)
            .map_err(|e| KernelError::InvalidScene(format!("the guide's warm-up tree: {e}")))?;
        let none = wgpu::BufferUsages::empty();
        let nodes = ctx.storage_buffer("guide warm-up nodes", tree.node_bytes(), none)?;
        let primitives = ctx.storage_buffer("guide warm-up primitives", &tree.primitives, none)?;
        let g = GuideParams::new(
            &raylume_scene::Camera::default(),
            glam::Vec3::ZERO,
            glam::Vec3::ONE,
        );
        let g = GuideParams { walks: 1, ..g };
        self.start(ctx, &nodes, &primitives, &g)?.finish(ctx)?;
        Ok(())
    }

    /// The layout of the trees it walks.
    pub fn layout(&self) -> BvhLayout {
        self.layout
    }

    /// Seconds [`GuideLearner::new`] took.
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// Runs the walks of `g` over the tree in `nodes` (this learner's layout) and `primitives`
    /// and reads their counts back: [`crate::env_guide::learn_environment_guide`]'s guide.
    pub fn learn(
        &self,
        ctx: &GpuContext,
        nodes: &wgpu::Buffer,
        primitives: &wgpu::Buffer,
        g: &GuideParams,
    ) -> Result<EnvironmentGuide, KernelError> {
        self.start(ctx, nodes, primitives, g)?.finish(ctx)
    }

    /// [`GuideLearner::learn`] without waiting: the walks are submitted, and
    /// [`PendingGuide::finish`] reads their counts when they are needed (the CPU prepares the
    /// rest of the scene meanwhile).
    pub fn start(
        &self,
        ctx: &GpuContext,
        nodes: &wgpu::Buffer,
        primitives: &wgpu::Buffer,
        g: &GuideParams,
    ) -> Result<PendingGuide, KernelError> {
        let counters = g.counter_count();
        let counts = ctx
            .storage_buffer_zeroed(
                "environment guide counts",
                (counters * 4) as u64,
                wgpu::BufferUsages::COPY_SRC,
            )
            .map_err(KernelError::from_upload)?;
        ctx.scoped("running the environment guide's walks", || {
            let params = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("environment guide parameters"),
                    contents: bytemuck::bytes_of(g),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raylume learn_guide"),
                layout: &self.group_layout,
                entries: &[(0, nodes), (1, primitives), (2, &params), (3, &counts)].map(
                    |(binding, b)| wgpu::BindGroupEntry {
                        binding,
                        resource: b.as_entire_binding(),
                    },
                ),
            });
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("learn_guide"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &group, &[]);
                // GUIDE_PROBES lanes a walk (env_guide.wgsl): 204,800 threads.
                let threads = g.walks * GUIDE_PROBES;
                pass.dispatch_workgroups(threads.div_ceil(GUIDE_WORKGROUP_SIZE), 1, 1);
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        Ok(PendingGuide { params: *g, counts })
    }
}

/// Walks submitted by [`GuideLearner::start`], their counts not read yet.
pub struct PendingGuide {
    params: GuideParams,
    counts: wgpu::Buffer,
}

impl PendingGuide {
    /// The walks' parameters.
    pub fn params(&self) -> &GuideParams {
        &self.params
    }

    /// Waits for the walks and reads their counts back.
    pub fn finish(self, ctx: &GpuContext) -> Result<EnvironmentGuide, KernelError> {
        let counts = ctx.read_buffer::<u32>(&self.counts, self.params.counter_count())?;
        Ok(EnvironmentGuide::from_counts(&self.params, counts))
    }
}
