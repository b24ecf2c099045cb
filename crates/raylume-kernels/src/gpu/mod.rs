//! The GPU tracer: the scene uploaded once into storage buffers, pipelines specialised on the
//! scene's features, and the two schedules (megakernel, wavefront) run batch by batch, the
//! wavefront optionally sorting its rays between bounces (raylume-sort).

mod batch;
mod capture;
mod clock;
mod guide;
mod layout;
mod lbvh;
mod pipelines;
mod policy;
mod render;
mod shader;
mod work;

pub use capture::SortCapture;
pub use guide::{GUIDE_WORKGROUP_SIZE, GuideLearner, PendingGuide, guide_source};
pub use lbvh::{LBVH_WORKGROUP_SIZE, LbvhBuilder, ResidentBvh, lbvh_source};
pub use pipelines::{PathVariant, TracerPipelines, entry_constants, walk_stage_source};
pub use policy::{BatchPlan, BatchPolicy, BatchTiming, DepthTiming, StageTime};
pub use shader::{
    Specialisation, compose, pipeline_constants, tracer_source, tracer_source_for,
    tracer_source_uncomposed,
};

use std::sync::Arc;
use std::time::Instant;

use raylume_bvh::{BvhLayout, BvhNode, GpuBvh, Primitive, WideNode};
use raylume_gpu::{GpuContext, wgpu};
use raylume_scene::{Feature, Features, Scene};
use raylume_sort::RadixSorter;

use crate::batches::Batch;
use crate::bsdf::RoughPlasticTable;
use crate::env_guide::GuideParams;
use crate::gpu_types::{GpuLight, GpuMaterial, SceneUniforms, TextureHeader, TriangleShading};
use crate::scene_data::{Leaves, SceneData, SceneOptions};
use crate::{KernelError, TraceOutput, TraceSettings};
use layout::{upload, upload_with_room};
use policy::Fixed;
use work::WorkBuffers;

/// Statistics of a render whose image stays on the GPU ([`GpuTracer::render_to_buffer`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TraceStats {
    pub rays_traced: u64,
    pub dropped_samples: u64,
    /// As [`TraceOutput::timings`], plus `"sort"` (the `sort_keys` passes) and
    /// `"permute_rays"` when rays were reordered.
    pub timings: Vec<(&'static str, f64)>,
    /// Per bounce depth `0..=max_bounces`, summed over the batches (wavefront batches only;
    /// empty when no batch ran the wavefront).
    pub depths: Vec<DepthTiming>,
    /// Each batch: its plan, wall-clock and per-stage times.
    pub batches: Vec<BatchTiming>,
}

/// The wavefront's queue buffers, for tests and debugging.
///
/// After `propagate` at bounce `d` (queue parity `q = d & 1`): `queue_counts` holds `u32`
/// lengths, `[q]` the rays it advanced (`n`), `[1 - q]` those still alive;
/// `ray_queues[1 - q][..live]` holds the live rays, compacted, which bounce `d + 1` reads.
/// When bounce `d + 1` is not sorted, `ray_keys` is left as it was (no key is computed).
/// When it is ([`crate::Reorder::sorts_before`]`(d + 1)`), `ray_keys[i]` for `i < live` is the key of
/// `ray_queues[1 - q][i]`, and the tracer sorts these pairs (with the count read on the GPU)
/// before bounce `d + 1` reads them: only live rays are sorted. All four buffers allow
/// `COPY_SRC` and `COPY_DST`.
pub struct WavefrontBuffers<'b> {
    pub ray_keys: &'b wgpu::Buffer,
    pub ray_queues: [&'b wgpu::Buffer; 2],
    pub queue_counts: &'b wgpu::Buffer,
}

/// A batch and its per-sample radiance in slot order ([`GpuTracer::last_batch_samples`]).
pub type BatchSamples = (Batch, Vec<[f32; 3]>);

/// The scene's storage buffers and their bind group (group 0).
struct SceneBuffers {
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// What a [`GpuTracer`] allocates for rendering rather than for its scene: the work buffers
/// (ray states, queues, keys, the image) and the ray sorters. Handing it from one tracer to the
/// next of the same [`GpuContext`] ([`GpuTracer::take_workspace`],
/// [`GpuTracer::use_workspace`]) spares the next render the allocation of up to gigabytes.
#[derive(Default)]
pub struct GpuWorkspace {
    work: Option<WorkBuffers>,
    sorters: Vec<RadixSorter>,
}

impl std::fmt::Debug for GpuWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuWorkspace")
            .field("work", &self.work.as_ref().map(|w| w.key))
            .field("sorters", &self.sorters.len())
            .finish()
    }
}

/// A scene uploaded to one [`GpuContext`]: its BVH, primitives, materials, shading data,
/// textures (and environment map and guide), lights and coat tables in storage buffers, and
/// what the uniforms need of it on the CPU ([`SceneData`] without the texels and shading
/// data). Preparing it (the coat tables, the environment guide's walks) and uploading it is
/// most of a render's fixed cost on a large scene; [`GpuTracer::with_scene`] renders it
/// again with any pipelines of its features and layout, any settings.
pub struct GpuScene {
    data: SceneData,
    /// The scene's tracer features (bloom is not one).
    features: Features,
    layout: BvhLayout,
    /// Leaf primitives (the length a pipeline reading shading data needs).
    primitives: u32,
    /// Whether `buffers.shading` holds a record per primitive (else one placeholder).
    full_shading: bool,
    buffers: GpuSceneBuffers,
    /// Words of the texel buffer (its CPU copy is emptied after the upload).
    texel_words: u64,
    upload_seconds: f64,
}

/// A scene uploaded before its environment guide was learned
/// ([`GpuScene::upload_before_guide`]), with room for the guide's distributions.
pub struct PendingScene {
    scene: GpuScene,
    /// Words kept free after the texels for the guide's distributions.
    room: usize,
}

impl PendingScene {
    /// The walks still to run (`None`: the scene is complete).
    pub fn pending_guide(&self) -> Option<GuideParams> {
        self.scene.data.pending_guide()
    }

    /// The scene, its pending guide learned: by `learner` on the GPU over the tree uploaded
    /// (its layout must be the tree's), or without one on the CPU over `bvh` (the tree the
    /// scene was uploaded with); the distributions written after the texels, as
    /// [`GpuScene::upload_with_learner`] places them. A complete scene is returned as it is.
    pub fn finish(
        mut self,
        ctx: &GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        learner: Option<&GuideLearner>,
    ) -> Result<GpuScene, KernelError> {
        let Some(g) = self.scene.data.pending_guide() else {
            return Ok(self.scene);
        };
        let start = Instant::now();
        let guide = match learner {
            Some(l) if l.layout() != self.scene.layout => {
                return Err(KernelError::InvalidSettings(format!(
                    "a guide learner for the {} BVH layout given a {} tree",
                    l.layout().name(),
                    self.scene.layout.name()
                )));
            }
            Some(l) => l.learn(
                ctx,
                &self.scene.buffers.nodes,
                &self.scene.buffers.primitives,
                &g,
            )?,
            None => crate::env_guide::learn_environment_guide_with(&g, bvh),
        };
        let seconds = start.elapsed().as_secs_f64();
        let offset = u32::try_from(self.scene.texel_words).map_err(|_| {
            KernelError::InvalidScene(
                "the textures and the environment's distributions hold more than 2^32 words".into(),
            )
        })?;
        let cdf = self.scene.data.take_guide(scene, &guide, seconds, offset)?;
        if let Some(cdf) = cdf {
            if cdf.len() != self.room {
                return Err(KernelError::InvalidSettings(format!(
                    "the guide's distributions take {} words, {} were kept for them",
                    cdf.len(),
                    self.room
                )));
            }
            ctx.scoped("writing the environment guide", || {
                ctx.queue.write_buffer(
                    &self.scene.buffers.texels,
                    4 * u64::from(offset),
                    bytemuck::cast_slice(&cdf),
                );
            })?;
            self.scene.texel_words += cdf.len() as u64;
        }
        Ok(self.scene)
    }
}

/// [`GpuScene`]'s storage buffers, in binding order after the uniforms (bindings 1 to 9).
struct GpuSceneBuffers {
    nodes: wgpu::Buffer,
    primitives: wgpu::Buffer,
    materials: wgpu::Buffer,
    prim_materials: wgpu::Buffer,
    shading: wgpu::Buffer,
    headers: wgpu::Buffer,
    texels: wgpu::Buffer,
    lights: wgpu::Buffer,
    plastic_tables: wgpu::Buffer,
}

impl std::fmt::Debug for GpuScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuScene")
            .field("features", &self.features)
            .field("layout", &self.layout)
            .field("primitives", &self.primitives)
            .field("upload_seconds", &self.upload_seconds)
            .finish()
    }
}

/// A scene's features the tracer's pipelines must have (all but the post pass, bloom): what
/// [`GpuScene::upload_data`] takes.
pub fn tracer_features(scene: &Scene) -> Features {
    Features::from_bits(scene.features().bits() & !(Feature::Bloom as u32))
}

/// `pipelines` can render a scene of `features` over a tree of `layout`.
fn check_pipelines(
    features: Features,
    layout: BvhLayout,
    pipelines: &TracerPipelines,
) -> Result<(), KernelError> {
    let missing = Features::from_bits(features.bits() & !pipelines.features().bits());
    if missing != Features::NONE {
        return Err(KernelError::InvalidScene(format!(
            "pipelines specialised without features the scene uses: {missing}"
        )));
    }
    if pipelines.bvh_layout() != layout {
        return Err(KernelError::InvalidSettings(format!(
            "pipelines for the {} BVH layout given a {} tree",
            pipelines.bvh_layout().name(),
            layout.name()
        )));
    }
    Ok(())
}

/// `bvh`'s nodes (in its layout) and primitives, uploaded.
fn upload_tree(
    ctx: &GpuContext,
    bvh: &GpuBvh,
) -> Result<(wgpu::Buffer, wgpu::Buffer), KernelError> {
    let nodes = match bvh.layout {
        BvhLayout::Binary => upload::<BvhNode>(ctx, "BVH nodes", &bvh.nodes)?,
        BvhLayout::Wide => upload::<WideNode>(ctx, "BVH nodes", &bvh.wide_nodes)?,
    };
    Ok((
        nodes,
        upload::<Primitive>(ctx, "BVH primitives", &bvh.primitives)?,
    ))
}

/// What the CPU has of the tree a scene is prepared over: the whole tree, or the leaf order
/// of one built on the GPU over the scene's triangles.
#[derive(Clone, Copy)]
enum OnCpu<'a> {
    Tree(&'a GpuBvh),
    Order(&'a [u32]),
}

impl OnCpu<'_> {
    fn layout(&self) -> BvhLayout {
        match self {
            OnCpu::Tree(b) => b.layout,
            OnCpu::Order(_) => BvhLayout::Binary,
        }
    }

    fn leaves(&self) -> Leaves<'_> {
        match self {
            OnCpu::Tree(b) => Leaves::Primitives(&b.primitives),
            OnCpu::Order(o) => Leaves::Triangles(o),
        }
    }
}

impl GpuScene {
    /// Prepares `scene` with its BVH `bvh` ([`SceneData::with_options`]) and uploads it; the
    /// environment guide, when `options` asks for it, learned on the GPU (a
    /// [`GuideLearner`] made for the purpose: [`GpuScene::upload_with_learner`] takes one
    /// made beforehand, e.g. [`TracerPipelines::guide_learner`]).
    pub fn upload(
        ctx: &GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        options: &SceneOptions,
    ) -> Result<Self, KernelError> {
        let learner = match options.environment_guide {
            true => Some(GuideLearner::new(ctx, bvh.layout)?),
            false => None,
        };
        Self::upload_with_learner(ctx, scene, bvh, options, learner.as_ref())
    }

    /// [`GpuScene::upload`] with the environment guide's walks run by `learner` (on the GPU,
    /// over the tree just uploaded; its layout must be `bvh`'s), or, when `None`, on the CPU
    /// ([`crate::env_guide::learn_environment_guide`]). The counts are the same either way
    /// wherever the GPU computes the CPU's rays (`tests/env_guide_gpu.rs`).
    pub fn upload_with_learner(
        ctx: &GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        options: &SceneOptions,
        learner: Option<&GuideLearner>,
    ) -> Result<Self, KernelError> {
        let start = Instant::now();
        let tree = upload_tree(ctx, bvh)?;
        Self::upload_over(ctx, scene, OnCpu::Tree(bvh), tree, options, learner, start)
    }

    /// [`GpuScene::upload_with_learner`] over a tree built on the GPU ([`LbvhBuilder`]): its
    /// nodes and primitives are used where they are, the scene's other data prepared and
    /// uploaded beside them. The environment guide's walks run on the GPU (the CPU has no
    /// nodes to walk): by `learner` (binary layout), or one made for the purpose.
    pub fn upload_resident(
        ctx: &GpuContext,
        scene: &Scene,
        bvh: &ResidentBvh,
        options: &SceneOptions,
        learner: Option<&GuideLearner>,
    ) -> Result<Self, KernelError> {
        let start = Instant::now();
        let made = match (learner, options.environment_guide) {
            (None, true) => Some(GuideLearner::new(ctx, BvhLayout::Binary)?),
            _ => None,
        };
        let learner = learner.or(made.as_ref());
        let tree = (bvh.nodes.clone(), bvh.primitives.clone());
        let on_cpu = OnCpu::Order(bvh.order());
        Self::upload_over(ctx, scene, on_cpu, tree, options, learner, start)
    }

    /// The preparation and upload of `scene` over `tree` (the nodes and primitives of the
    /// tree `on_cpu` describes, on the GPU already).
    fn upload_over(
        ctx: &GpuContext,
        scene: &Scene,
        on_cpu: OnCpu<'_>,
        tree: (wgpu::Buffer, wgpu::Buffer),
        options: &SceneOptions,
        learner: Option<&GuideLearner>,
        start: Instant,
    ) -> Result<Self, KernelError> {
        let learner = match learner {
            Some(l) if options.environment_guide => {
                if l.layout() != on_cpu.layout() {
                    return Err(KernelError::InvalidSettings(format!(
                        "a guide learner for the {} BVH layout given a {} tree",
                        l.layout().name(),
                        on_cpu.layout().name()
                    )));
                }
                Some(l)
            }
            _ => None,
        };
        // The walks start on the GPU now and are read back when the preparation needs them:
        // the CPU packs the textures and looks up the primitives meanwhile. (Started whenever
        // the preparation may learn a guide; unread if it does not, e.g. a black sky.)
        let mut pending = match learner {
            Some(l)
                if !on_cpu.leaves().is_empty()
                    && !matches!(scene.environment, raylume_scene::Environment::Black) =>
            {
                let bounds = scene.bounds();
                let (min, extent) = match bounds.is_empty() {
                    true => (glam::Vec3::ZERO, glam::Vec3::ZERO),
                    false => (bounds.min, bounds.extent()),
                };
                let g = GuideParams::new(&scene.camera, min, extent);
                Some(l.start(ctx, &tree.0, &tree.1, &g)?)
            }
            _ => None,
        };
        let mut walk_on_gpu = |l: &GuideLearner, g: &GuideParams| match pending.take() {
            Some(p) if p.params() == g => p.finish(ctx),
            _ => l.learn(ctx, &tree.0, &tree.1, g),
        };
        let data = match (learner, on_cpu) {
            (Some(l), OnCpu::Tree(bvh)) => {
                SceneData::with_guide_walks(scene, bvh, options, &mut |g| walk_on_gpu(l, g))?
            }
            (Some(l), OnCpu::Order(_)) => {
                SceneData::with_leaves(scene, on_cpu.leaves(), options, &mut |g| walk_on_gpu(l, g))?
            }
            (None, OnCpu::Tree(bvh)) => SceneData::with_options(scene, bvh, options)?,
            (None, OnCpu::Order(_)) => {
                SceneData::with_leaves(scene, on_cpu.leaves(), options, &mut |_| {
                    Err(KernelError::InvalidSettings(
                        "the environment guide over a tree on the GPU needs a GuideLearner".into(),
                    ))
                })?
            }
        };
        let features = tracer_features(scene);
        let (layout, count) = (on_cpu.layout(), on_cpu.leaves().len());
        let mut uploaded = Self::upload_data_over(ctx, features, layout, count, data, tree, 0)?;
        uploaded.upload_seconds = start.elapsed().as_secs_f64();
        Ok(uploaded)
    }

    /// Uploads `data`, prepared from a scene of tracer features `features` and its BVH
    /// `bvh` (the CPU's [`SceneData`] of the same scene, e.g. one kept from an earlier render).
    pub fn upload_data(
        ctx: &GpuContext,
        features: Features,
        bvh: &GpuBvh,
        data: SceneData,
    ) -> Result<Self, KernelError> {
        // Complete data: the pending scene is the scene, with no room kept.
        data.check_bvh(bvh)?;
        data.check_complete()?;
        Ok(Self::upload_before_guide(ctx, features, bvh, data)?.scene)
    }

    /// [`GpuScene::upload_data`] for data whose environment guide may still be pending
    /// ([`SceneData::before_guide_walks`]): everything is uploaded now, with room at the end
    /// of the texel buffer for the guide's distributions, which [`PendingScene::finish`]
    /// learns and writes there. The device can take the scene while it still compiles the
    /// walks; the result is the scene [`GpuScene::upload_with_learner`] makes.
    pub fn upload_before_guide(
        ctx: &GpuContext,
        features: Features,
        bvh: &GpuBvh,
        data: SceneData,
    ) -> Result<PendingScene, KernelError> {
        data.check_bvh(bvh)?;
        let room = data.pending_guide_words();
        let tree = upload_tree(ctx, bvh)?;
        let count = bvh.primitives.len();
        let scene = Self::upload_data_over(ctx, features, bvh.layout, count, data, tree, room)?;
        Ok(PendingScene { scene, room })
    }

    /// [`GpuScene::upload_data`] with a tree of `layout` over `leaf_count` leaf primitives
    /// uploaded already (`tree`), `data` checked against it (or prepared from it).
    fn upload_data_over(
        ctx: &GpuContext,
        features: Features,
        layout: BvhLayout,
        leaf_count: usize,
        mut data: SceneData,
        (nodes, primitives): (wgpu::Buffer, wgpu::Buffer),
        texel_room: usize,
    ) -> Result<Self, KernelError> {
        let start = Instant::now();
        let full_shading = !data.triangle_shading.is_empty();
        let buffers = GpuSceneBuffers {
            nodes,
            primitives,
            materials: upload::<GpuMaterial>(ctx, "materials", &data.materials)?,
            prim_materials: upload::<u32>(ctx, "primitive material indices", &data.prim_materials)?,
            shading: upload::<TriangleShading>(
                ctx,
                "triangle shading data",
                &data.triangle_shading,
            )?,
            headers: upload::<TextureHeader>(ctx, "texture headers", &data.texture_headers)?,
            texels: upload_with_room::<u32>(
                ctx,
                "texture and environment-map data",
                &data.texels,
                texel_room,
            )?,
            lights: upload::<GpuLight>(ctx, "light list", &data.lights)?,
            plastic_tables: upload::<RoughPlasticTable>(
                ctx,
                "rough plastic tables",
                &data.plastic_tables,
            )?,
        };
        ctx.wait("uploading the scene")?;
        let texel_words = data.texels.len() as u64;
        // Only what the uniforms need stays on the CPU.
        data.texels = Vec::new();
        data.triangle_shading = Vec::new();
        Ok(Self {
            data,
            features,
            layout,
            primitives: leaf_count as u32,
            full_shading,
            buffers,
            texel_words,
            upload_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The storage buffers `bvh_nodes` and `bvh_primitives` the tracer reads.
    pub fn tree_buffers(&self) -> (&wgpu::Buffer, &wgpu::Buffer) {
        (&self.buffers.nodes, &self.buffers.primitives)
    }

    /// Seconds [`GpuScene::upload`] took (preparing and uploading).
    pub fn upload_seconds(&self) -> f64 {
        self.upload_seconds
    }

    /// Bytes of the texel buffer uploaded ([`SceneData::texels`]: textures, the 8-bit
    /// decoding table, an environment map and its distributions, the guide's).
    pub fn texel_bytes(&self) -> u64 {
        4 * self.texel_words
    }

    /// What was prepared (its texels and shading data emptied: they live on the GPU).
    pub fn data(&self) -> &SceneData {
        &self.data
    }
}

/// Renders a scene on the GPU. Holds the uploaded scene, the compiled pipelines and the
/// work buffers of the last render size; `render` may be called many times.
pub struct GpuTracer<'a> {
    ctx: &'a GpuContext,
    /// The uploaded scene's CPU-side data (what the uniforms need), with this tracer's
    /// estimator, sampler, roulette, guide and sample range.
    data: SceneData,
    scene: SceneBuffers,
    /// The scene's storage buffers (the bind group holds them too).
    uploaded: Arc<GpuScene>,
    /// The module, layouts and pipelines (shared with other tracers of the same features and
    /// BVH layout).
    pipelines: Arc<TracerPipelines>,
    work: Option<WorkBuffers>,
    /// The ray sorters (one per sorted key width), made on the first render that sorts, for
    /// the largest batch, and kept.
    sorters: Vec<RadixSorter>,
    /// The test hook of [`GpuTracer::capture_sort`].
    capture: Option<capture::Capture>,
    /// The last batch rendered (its samples stay in the sample-radiance buffer).
    last_batch: Option<Batch>,
    /// A cap on rays per batch below the adapter's own ([`GpuTracer::set_batch_ray_limit`]).
    batch_ray_limit: Option<u64>,
    /// [`GpuTracer::set_next_event_stage`].
    next_event_stage: bool,
    /// [`GpuTracer::set_walk_stage`].
    walk_stage: bool,
    /// [`GpuTracer::set_shadow_stage`].
    shadow_stage: bool,
    /// See [`GpuTracer::set_walk_stage_groups`].
    walk_stage_groups: Option<u32>,
    /// See [`GpuTracer::set_persistent_threads`].
    persistent_threads: Option<u32>,
    upload_seconds: f64,
}

impl<'a> GpuTracer<'a> {
    /// Uploads `scene` (with its BVH `bvh`) and builds pipelines specialised on
    /// `scene.features()`.
    pub fn new(ctx: &'a GpuContext, scene: &Scene, bvh: &GpuBvh) -> Result<Self, KernelError> {
        Self::with_features(ctx, scene, bvh, scene.features())
    }

    /// As [`GpuTracer::new`], with pipelines specialised on `features` instead (which must
    /// include the scene's own; [`Features::all`] gives the unspecialised reference).
    pub fn with_features(
        ctx: &'a GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        features: Features,
    ) -> Result<Self, KernelError> {
        let start = Instant::now();
        let pipelines = TracerPipelines::new(ctx, features, bvh.layout)?;
        let mut tracer = Self::with_pipelines(ctx, scene, bvh, pipelines)?;
        tracer.upload_seconds = start.elapsed().as_secs_f64();
        Ok(tracer)
    }

    /// As [`GpuTracer::with_features`], over pipelines made beforehand (possibly while the
    /// BVH was built, and shared with earlier tracers): their features must include the
    /// scene's and their BVH layout must be `bvh`'s.
    pub fn with_pipelines(
        ctx: &'a GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        pipelines: Arc<TracerPipelines>,
    ) -> Result<Self, KernelError> {
        Self::with_options(ctx, scene, bvh, pipelines, &SceneOptions::default())
    }

    /// [`GpuTracer::with_pipelines`], also preparing what `options` asks for (the environment
    /// guide, learned on the GPU by `pipelines`' [`TracerPipelines::guide_learner`]).
    pub fn with_options(
        ctx: &'a GpuContext,
        scene: &Scene,
        bvh: &GpuBvh,
        pipelines: Arc<TracerPipelines>,
        options: &SceneOptions,
    ) -> Result<Self, KernelError> {
        let start = Instant::now();
        check_pipelines(tracer_features(scene), bvh.layout, &pipelines)?;
        let learner = match options.environment_guide {
            true => Some(pipelines.guide_learner(ctx)?),
            false => None,
        };
        let uploaded = Arc::new(GpuScene::upload_with_learner(
            ctx,
            scene,
            bvh,
            options,
            learner.as_deref(),
        )?);
        let mut tracer = Self::with_scene(ctx, uploaded, pipelines)?;
        tracer.upload_seconds = start.elapsed().as_secs_f64();
        Ok(tracer)
    }

    /// A tracer of a scene uploaded beforehand ([`GpuScene::upload`], on this context), e.g.
    /// by an earlier tracer: nothing is prepared or uploaded again but the uniforms and the
    /// bind group (so rendering one scene many times, at other spp, sizes or seeds, pays for
    /// its upload once). `pipelines` must have the scene's features and its BVH's layout.
    pub fn with_scene(
        ctx: &'a GpuContext,
        uploaded: Arc<GpuScene>,
        pipelines: Arc<TracerPipelines>,
    ) -> Result<Self, KernelError> {
        let start = Instant::now();
        check_pipelines(uploaded.features, uploaded.layout, &pipelines)?;
        let device = &ctx.device;
        let uniforms = ctx.scoped("creating the scene uniform buffer", || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raylume scene uniforms"),
                size: size_of::<SceneUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        // A pipeline that may read shading data gets a full-length array even when no triangle
        // has any, so that its reads stay in bounds (pipelines with features the scene lacks:
        // the generic ones, or a bench's extra features).
        let features = pipelines.features();
        let needs_shading =
            features.contains(Feature::ShadingNormals) || features.contains(Feature::Textures);
        let zero_shading = if needs_shading && !uploaded.full_shading {
            let zeros = vec![TriangleShading::default(); uploaded.primitives as usize];
            Some(upload::<TriangleShading>(
                ctx,
                "triangle shading data",
                &zeros,
            )?)
        } else {
            None
        };
        let b = &uploaded.buffers;
        let shading = zero_shading.as_ref().unwrap_or(&b.shading);
        let resources = [
            &uniforms,
            &b.nodes,
            &b.primitives,
            &b.materials,
            &b.prim_materials,
            shading,
            &b.headers,
            &b.texels,
            &b.lights,
            &b.plastic_tables,
        ];
        let entries: Vec<wgpu::BindGroupEntry<'_>> = resources
            .iter()
            .enumerate()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        let bind_group = ctx.scoped("binding the scene's buffers", || {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raylume scene"),
                layout: &pipelines.scene_layout,
                entries: &entries,
            })
        })?;
        if zero_shading.is_some() {
            ctx.wait("uploading the scene")?;
        }
        Ok(Self {
            ctx,
            data: uploaded.data.clone(),
            scene: SceneBuffers {
                uniforms,
                bind_group,
            },
            uploaded,
            pipelines,
            work: None,
            sorters: Vec::new(),
            capture: None,
            last_batch: None,
            batch_ray_limit: None,
            next_event_stage: false,
            walk_stage: false,
            shadow_stage: true,
            walk_stage_groups: None,
            persistent_threads: None,
            upload_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The uploaded scene this tracer renders, to hand to the next tracer of the same context
    /// and scene ([`GpuTracer::with_scene`]).
    pub fn uploaded_scene(&self) -> &Arc<GpuScene> {
        &self.uploaded
    }

    /// Caps the rays (pixel samples) of one batch below what the adapter's binding size
    /// allows, e.g. to bound memory; `None` restores the adapter's limit. Batches then hold
    /// fewer samples per pixel, or a range of the pixels when even one sample of every pixel
    /// exceeds the cap. The image does not depend on it.
    pub fn set_batch_ray_limit(&mut self, limit: Option<u64>) {
        self.batch_ray_limit = limit;
    }

    /// Caps the threads of the persistent schedule below [`crate::PERSISTENT_THREADS`] (so
    /// that each takes several samples even in a small render; `None` restores the default:
    /// `PERSISTENT_THREADS` on a hardware adapter, one sample a thread on a software one,
    /// whose loop limit would otherwise cut long-running threads short). The image does not
    /// depend on it.
    pub fn set_persistent_threads(&mut self, threads: Option<u32>) {
        self.persistent_threads = threads.map(|t| t.max(1));
    }

    /// Whether the wavefront's light samples are taken by a `next_event` stage of their own
    /// (default: off; [`PathVariant::next_event_stage`] says what it costs and saves).
    pub fn set_next_event_stage(&mut self, on: bool) {
        self.next_event_stage = on;
    }

    /// Whether the wavefront's path rays are walked by a stage of their own before
    /// `propagate` ([`PathVariant::walk_stage`]; default: off). Where the pipelines have no
    /// walk stage ([`TracerPipelines::has_walk_stage`]: the binary BVH, or an adapter
    /// without subgroups) the wavefront walks in `propagate` whatever this says.
    pub fn set_walk_stage(&mut self, on: bool) {
        self.walk_stage = on;
    }

    /// Whether the shadow rays of the walk stage's bounces are walked by a stage of their own
    /// after `propagate` ([`PathVariant::shadow_stage`]; default: on). It runs only where
    /// the walk stage does, with an estimator that samples lights and without the
    /// `next_event` stage ([`PathVariant::defers_shadow_rays`]); the image is the same.
    pub fn set_shadow_stage(&mut self, on: bool) {
        self.shadow_stage = on;
    }

    /// Whether the next renders ask for the shadow stage ([`GpuTracer::set_shadow_stage`]).
    pub fn shadow_stage(&self) -> bool {
        self.shadow_stage
    }

    /// Caps the walk stage's workgroups (so that its threads take several rays each even in a
    /// small render; `None` restores the default: [`crate::walk_stage_groups`] on a hardware
    /// adapter, a thread per ray on a software one, whose loop limit would otherwise cut
    /// long-running threads short). The image does not depend on it, but on a software
    /// adapter a lane walks up to [`crate::WALK_STAGE_SOFTWARE_SHARE`] times the queue's rays
    /// over the threads, so a cap there must leave each thread a few dozen rays at most (the
    /// tests' two groups take ~10 each): past lavapipe's 65,535 loop iterations an invocation's
    /// walks are cut short and their hits lost.
    pub fn set_walk_stage_groups(&mut self, groups: Option<u32>) {
        self.walk_stage_groups = groups.map(|g| g.max(1));
    }

    /// Whether the next wavefront renders have a walk stage: asked for
    /// ([`GpuTracer::set_walk_stage`]) and possible ([`TracerPipelines::has_walk_stage`]).
    pub fn walk_stage(&self) -> bool {
        self.walk_stage && self.pipelines.has_walk_stage()
    }

    /// The path variant of the next renders: their estimator and sampler, and whether the
    /// wavefront has its `next_event` stage and its walk stage.
    pub(crate) fn path_variant(&self) -> PathVariant {
        PathVariant::of(self.data.estimator, self.data.sampler)
            .with_next_event_stage(self.next_event_stage)
            .with_walk_stage(self.walk_stage())
            .with_shadow_stage(self.shadow_stage)
    }

    /// The estimator of the next renders (default: the paper's plain one).
    pub fn set_estimator(&mut self, estimator: crate::Estimator) {
        self.data.estimator = estimator;
    }

    /// Russian roulette from segment `start` on (`None`, the default: off): after each hit of a
    /// segment `>= start` the path goes on with probability `min(max throughput, 0.95)` and
    /// its throughput is divided by it (Mitsuba's `path` starts at 5). Unbiased; fewer rays
    /// spent on paths that carry little.
    pub fn set_russian_roulette(&mut self, start: Option<u32>) {
        self.data.russian_roulette = start;
    }

    /// Where the paths' random numbers come from (default [`crate::Sampler::Independent`]).
    pub fn set_sampler(&mut self, sampler: crate::Sampler) {
        self.data.sampler = sampler;
    }

    /// Whether next-event estimation samples the environment by where the scene leaves it
    /// visible ([`crate::env_guide`]), when the guide was learned
    /// ([`crate::scene_data::SceneOptions`]; then on by default): `false` samples by its
    /// radiance alone (`CpuTracer::set_environment_guide`, the same rules).
    pub fn set_environment_guide(&mut self, on: bool) {
        self.data.environment_guide = on;
    }

    /// The guide's walks and escapes, if one was learned for this scene.
    pub fn environment_guide_walks(&self) -> Option<(u32, u64)> {
        self.data.environment_guide_walks
    }

    /// Trace only samples `range` of every pixel (`None`, the default: all of them) and
    /// leave each pixel's *sum* over the range in the image, not its mean: a render part
    /// (`CpuTracer::set_sample_range`, the same rules).
    pub fn set_sample_range(&mut self, range: Option<std::ops::Range<u32>>) {
        self.data.sample_range = range;
    }

    /// The features the pipelines are specialised on.
    pub fn features(&self) -> Features {
        self.pipelines.features()
    }

    /// The module, layouts and pipelines this tracer renders with.
    pub fn pipelines(&self) -> &Arc<TracerPipelines> {
        &self.pipelines
    }

    /// The compute pipeline of entry point `entry` for the next renders' estimator and
    /// sampler ([`PathVariant`]), compiled on first use.
    fn pipeline(&self, entry: &'static str) -> Result<wgpu::ComputePipeline, KernelError> {
        self.pipelines
            .pipeline(self.ctx, entry, self.path_variant())
    }

    /// Takes the work buffers and ray sorters out of this tracer (its next render allocates
    /// them again), for another tracer of the same context: see [`GpuWorkspace`].
    pub fn take_workspace(&mut self) -> GpuWorkspace {
        self.last_batch = None;
        GpuWorkspace {
            work: self.work.take(),
            sorters: std::mem::take(&mut self.sorters),
        }
    }

    /// Renders with the work buffers and sorters of `workspace` (taken from a tracer of the
    /// same context), reusing what fits and replacing what does not.
    pub fn use_workspace(&mut self, workspace: GpuWorkspace) {
        self.work = workspace.work;
        self.sorters = workspace.sorters;
        self.last_batch = None;
    }

    /// The image of the last render: mean linear radiance, packed RGB `f32` triples
    /// (12 bytes per pixel, row-major, top row first; the buffer may be padded at the end),
    /// usable as a storage buffer or copy source (e.g. by a bloom pass before read-back).
    pub fn image_buffer(&self) -> Option<&wgpu::Buffer> {
        self.work.as_ref().map(|w| &w.accumulation)
    }

    /// The wavefront's queues, keys and counts, once a wavefront render has allocated them.
    pub fn wavefront_buffers(&self) -> Option<WavefrontBuffers<'_>> {
        let w = self.work.as_ref()?;
        w.key.wavefront.then_some(WavefrontBuffers {
            ray_keys: &w.ray_keys,
            ray_queues: [&w.ray_queues[0], &w.ray_queues[1]],
            queue_counts: &w.queue_counts,
        })
    }

    /// The per-sample radiance of the last batch of the last render, in slot order (slot
    /// `s * pixel_count + p` holds sample `sample_begin + s` of pixel `pixel_begin + p`), and
    /// that batch: for tests and debugging (compare with [`crate::CpuTracer::sample_radiance`]).
    pub fn last_batch_samples(&self) -> Result<Option<BatchSamples>, KernelError> {
        let (Some(b), Some(w)) = (self.last_batch, self.work.as_ref()) else {
            return Ok(None);
        };
        let samples = self
            .ctx
            .read_buffer(&w.sample_radiance, b.rays() as usize)?;
        Ok(Some((b, samples)))
    }

    /// Renders and reads the image back.
    pub fn render(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<TraceOutput, KernelError> {
        let stats = self.render_to_buffer(settings, progress)?;
        let pixels = (settings.width * settings.height) as usize;
        let buffer = &self
            .work
            .as_ref()
            .expect("render_to_buffer allocates work")
            .accumulation;
        let radiance = self.ctx.read_buffer::<[f32; 3]>(buffer, pixels)?;
        Ok(TraceOutput {
            radiance,
            rays_traced: stats.rays_traced,
            dropped_samples: stats.dropped_samples,
            timings: stats.timings,
        })
    }

    /// Renders, leaving the image on the GPU in [`GpuTracer::image_buffer`]. Calls
    /// `progress(spp_done, spp_total)` after each batch.
    pub fn render_to_buffer(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<TraceStats, KernelError> {
        settings.validate()?;
        self.render_with_policy(settings, &mut Fixed(BatchPlan::of(settings)), progress)
    }
}
