//! [`TracerPipelines`]: the tracer's shader module, layouts and compute pipelines, apart from
//! any scene's data, so that they can be compiled while the BVH is built and kept for every
//! render of scenes with the same features and BVH layout.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use raylume_bvh::BvhLayout;
use raylume_gpu::{GpuContext, wgpu};
use raylume_scene::Features;

use super::guide::GuideLearner;
use super::layout::bind_group_layouts;
use super::shader::{Specialisation, pipeline_constants, tracer_source_for};
use crate::gpu_types::SAMPLER_FROM_SCENE;
use crate::{Estimator, KernelError, Sampler, Schedule};

/// What a path tracing pipeline is compiled for besides the scene's features: the render's
/// estimator and sampler, as the WGSL overrides `NEXT_EVENT` and `SAMPLER`. The code of the
/// other estimator and samplers is then dead (a plain render carries no light sampling, an
/// independent one no Sobol' points): the same images, fewer instructions for the driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PathVariant {
    /// `Some` for one estimator; `None` holds every estimator's code.
    pub estimator: Option<Estimator>,
    /// `Some` for one sampler; `None` holds every sampler's code.
    pub sampler: Option<Sampler>,
    /// The wavefront's light samples taken by a `next_event` stage of their own after
    /// `propagate` (whose pipeline then holds no light sampling, shadow ray or BSDF
    /// evaluation: the driver compiles the two halves side by side, a first image's wait),
    /// instead of inside it. Off by default: on the H200 (NEE, 100 spp) it made the living
    /// room's wavefront faster at 6f0fa32 (sorted 0.434 -> 0.427 s), but since the path's ray
    /// and its shadow ray share one walk (ba630c5) it is slower on every scene measured
    /// (c44418f: living room sorted 0.381 -> 0.426 s, Cornell box 0.117 -> 0.200 s): storing
    /// the record costs what the shadow ray did, and `next_event` is all extra
    /// (docs/RESULTS.md).
    pub next_event_stage: bool,
    /// The wavefront's path rays walked by a stage of their own before `propagate`
    /// (`trace_hits`, walk_stage.wgsl: a fixed set of threads, each taking the next ray of
    /// the queue when its walk ends, so that a subgroup's lanes do not idle while its longest
    /// walk goes on), `propagate` shading the hits it left. Only with the wide BVH on an
    /// adapter with subgroups ([`TracerPipelines::has_walk_stage`]). The same images. On the
    /// H200 (100 spp) the living room's unsorted wavefront 0.486 -> 0.383 s plain, 0.424 ->
    /// 0.373 s NEE (faster than sorting it: 0.443 and 0.380 s); the teapot 8 % faster; short
    /// walks slower (the Cornell box +17 %): the facade's `Tracer` turns it on for large
    /// scenes only (`docs/RESULTS.md`). The sorted
    /// bounces of a render that sorts are left to `propagate` (`batch::walk_stage_at`).
    pub walk_stage: bool,
    /// With the walk stage and NEE (not the `next_event` stage): the shadow rays of the walk
    /// stage's bounces walked by a stage of their own after `propagate` (`trace_shadows`,
    /// walk_stage.wgsl), whose threads take the next ray when theirs ends, as `trace_hits`'
    /// do. `propagate` (compiled with `DEFER_SHADOW`) samples and evaluates the light as
    /// before and queues the ray with the vertex's two terms (80 bytes); the stage adds them
    /// in `trace_ray`'s order, so the images are the same. On the H200 (100 spp, with the
    /// walk stage) the living room's NEE wavefront 0.376 -> 0.302 s, the teapot's 0.096 ->
    /// 0.086 s, the Cornell box's 0.120 -> 0.135 s (docs/study/h200-2a9a938-shadow-stage.md);
    /// `GpuTracer` and the facade's `Tracer` ask for it by default, so it runs wherever the
    /// walk stage does with NEE. [`PathVariant::defers_shadow_rays`] says when it runs.
    pub shadow_stage: bool,
}

impl PathVariant {
    /// Every estimator's and sampler's code: the uniforms decide at run time.
    pub const ANY: PathVariant = PathVariant {
        estimator: None,
        sampler: None,
        next_event_stage: false,
        walk_stage: false,
        shadow_stage: false,
    };

    /// The variant of renders with `estimator` and `sampler` (no `next_event` stage).
    pub fn of(estimator: Estimator, sampler: Sampler) -> Self {
        PathVariant {
            estimator: Some(estimator),
            sampler: Some(sampler),
            next_event_stage: false,
            walk_stage: false,
            shadow_stage: false,
        }
    }

    /// This variant with the wavefront's `next_event` stage on or off.
    pub fn with_next_event_stage(self, on: bool) -> Self {
        PathVariant {
            next_event_stage: on,
            ..self
        }
    }

    /// This variant with the wavefront's walk stage on or off.
    pub fn with_walk_stage(self, on: bool) -> Self {
        PathVariant {
            walk_stage: on,
            ..self
        }
    }

    /// This variant with the wavefront's shadow stage on or off.
    pub fn with_shadow_stage(self, on: bool) -> Self {
        PathVariant {
            shadow_stage: on,
            ..self
        }
    }

    /// Whether a wavefront render of this variant runs the shadow stage after the
    /// `propagate` of its walk stage's bounces: it asks for both stages, samples lights (NEE,
    /// or any estimator) and takes them in `propagate` (no `next_event` stage).
    pub fn defers_shadow_rays(self) -> bool {
        self.shadow_stage
            && self.walk_stage
            && !self.next_event_stage
            && self.estimator != Some(Estimator::Plain)
    }

    /// Whether a wavefront render of this variant runs the `next_event` stage: it asks for
    /// it and may sample lights (NEE, or any estimator).
    pub fn defers_light_samples(self) -> bool {
        self.next_event_stage && self.estimator != Some(Estimator::Plain)
    }

    /// Its override constants.
    fn constants(self) -> [(&'static str, f64); 2] {
        [
            (
                "NEXT_EVENT",
                match self.estimator {
                    Some(Estimator::Plain) => 0.0,
                    _ => 1.0,
                },
            ),
            (
                "SAMPLER",
                f64::from(self.sampler.map_or(SAMPLER_FROM_SCENE, Sampler::uniform)),
            ),
        ]
    }
}

/// The override constants of `entry`'s pipeline for a scene with `features` and renders of
/// `variant` (as compiled: `TracerPipelines` passes [`PathVariant::ANY`] for the entry points
/// that trace no path) on a `software` adapter or not: the features', the variant's,
/// `DEFER_NEE` for `propagate` when the variant leaves its light samples to `next_event`, and
/// the walk and shadow stages' refill and bound ([`crate::WALK_STAGE_SOFTWARE_SHARE`]).
pub fn entry_constants(
    features: Features,
    entry: &str,
    variant: PathVariant,
    software: bool,
) -> Vec<(&'static str, f64)> {
    let mut constants = pipeline_constants(features);
    constants.extend(variant.constants());
    if entry == "propagate" && variant.defers_light_samples() {
        constants.push(("DEFER_NEE", 1.0));
    }
    if entry == "propagate" && variant.walk_stage {
        constants.push(("HITS_TRACED", 1.0));
    }
    if entry == "propagate" && variant.defers_shadow_rays() {
        constants.push(("DEFER_SHADOW", 1.0));
    }
    if entry == "trace_hits" || entry == "trace_shadows" {
        constants.push(("WALK_STAGE_REFILL", f64::from(crate::walk_stage_refill())));
        let share = if software {
            crate::WALK_STAGE_SOFTWARE_SHARE
        } else {
            0
        };
        constants.push(("WALK_STAGE_SHARE", f64::from(share)));
    }
    constants
}

/// The entry points that trace paths (`trace_ray`) or take their light samples: compiled per
/// [`PathVariant`].
const TRACES_PATHS: [&str; 4] = [
    "trace_paths",
    "trace_paths_persistent",
    "propagate",
    "next_event",
];

/// The wavefront's walk stage (`trace_hits`), appended to the tracer's module where the
/// adapter has subgroups and the BVH is wide.
const WALK_STAGE_WGSL: &str = include_str!("walk_stage.wgsl");

/// What [`TracerPipelines`] appends to the tracer's source ([`tracer_source_for`]) for the
/// walk stage ([`PathVariant::walk_stage`]; wide BVH, subgroups): raylume-sort's ballot masks
/// and `trace_hits` (`examples/shader_stats.rs --walk-stage` compiles the same).
pub fn walk_stage_source() -> String {
    let mut source = String::from("\n// ---- raylume-sort: LANE_MASK_WGSL ----\n");
    source += raylume_sort::LANE_MASK_WGSL;
    source += "\n// ---- gpu/walk_stage.wgsl ----\n";
    source += WALK_STAGE_WGSL;
    source
}

/// The tracer's shader module (every entry point, the traversal of one [`BvhLayout`]), its
/// bind group and pipeline layouts, and its compute pipelines specialised on a feature set,
/// each compiled on first use or ahead of it ([`TracerPipelines::compile`]). It depends on no
/// scene data: a renderer can make it while the BVH is being built (on another thread: every
/// method takes `&self`) and hand it to every [`super::GpuTracer`] of scenes with the same
/// features and layout (`GpuTracer::with_pipelines`). Compiling is most of the time to a
/// first image on a GPU (a second on the H200, measured in `docs/RESULTS.md`).
pub struct TracerPipelines {
    features: Features,
    specialisation: Specialisation,
    /// The module holds the walk stage's `trace_hits` ([`Self::has_walk_stage`]).
    walk_stage: bool,
    bvh_layout: BvhLayout,
    pub(crate) scene_layout: wgpu::BindGroupLayout,
    pub(crate) work_layout: wgpu::BindGroupLayout,
    pub(crate) args_layout: wgpu::BindGroupLayout,
    pub(crate) permute_group_layout: wgpu::BindGroupLayout,
    /// Groups 0 and 1: every entry point but `prepare_propagate` and `permute_rays`.
    pipeline_layout: wgpu::PipelineLayout,
    /// Groups 0, 1 and 2: `prepare_propagate`.
    prepare_layout: wgpu::PipelineLayout,
    /// Groups 0, 1 and 2: `permute_rays`.
    permute_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    /// By entry point and [`PathVariant`] (the entry points that trace no path have one).
    compiled: Mutex<HashMap<(&'static str, PathVariant), wgpu::ComputePipeline>>,
    /// The environment guide's walks over trees of this layout, made on first use.
    guide: Mutex<Option<Arc<GuideLearner>>>,
    /// Seconds spent making the module and compiling pipelines so far.
    seconds: Mutex<f64>,
}

impl std::fmt::Debug for TracerPipelines {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let compiled: Vec<(&str, PathVariant)> = self
            .compiled
            .lock()
            .map(|c| c.keys().copied().collect())
            .unwrap_or_default();
        f.debug_struct("TracerPipelines")
            .field("features", &self.features)
            .field("bvh_layout", &self.bvh_layout)
            .field("compiled", &compiled)
            .finish()
    }
}

impl TracerPipelines {
    /// The entry points a schedule runs for renders of `variant`: with its `next_event_stage`
    /// the wavefront's `propagate` leaves light samples to a `next_event` stage of their own
    /// (compiled beside it: the driver compiles the two halves of the path's code at once),
    /// run after it at every bounce.
    pub fn entries(schedule: Schedule, variant: PathVariant) -> &'static [&'static str] {
        match schedule {
            Schedule::Megakernel => &["trace_paths", "resolve"],
            Schedule::Persistent => &["trace_paths_persistent", "resolve"],
            Schedule::Wavefront => match (variant.defers_light_samples(), variant.walk_stage) {
                (true, true) => &[
                    "raygen",
                    "prepare_propagate",
                    "trace_hits",
                    "propagate",
                    "next_event",
                    "resolve",
                ],
                (true, false) => &[
                    "raygen",
                    "prepare_propagate",
                    "propagate",
                    "next_event",
                    "resolve",
                ],
                (false, true) if variant.defers_shadow_rays() => &[
                    "raygen",
                    "prepare_propagate",
                    "trace_hits",
                    "propagate",
                    "trace_shadows",
                    "resolve",
                ],
                (false, true) => &[
                    "raygen",
                    "prepare_propagate",
                    "trace_hits",
                    "propagate",
                    "resolve",
                ],
                (false, false) => &["raygen", "prepare_propagate", "propagate", "resolve"],
            },
        }
    }

    /// Builds the module (WGSL with the traversal of `bvh_layout`, specialised on `features`
    /// the default way, [`Specialisation::default`]) and the layouts; compiles no pipeline yet.
    pub fn new(
        ctx: &GpuContext,
        features: Features,
        bvh_layout: BvhLayout,
    ) -> Result<Arc<Self>, KernelError> {
        Self::specialised(ctx, features, bvh_layout, Specialisation::default())
    }

    /// [`TracerPipelines::new`] specialised on `features` the `specialisation` way (for
    /// [`Specialisation::Generic`], on every feature whatever `features` says).
    pub fn specialised(
        ctx: &GpuContext,
        features: Features,
        bvh_layout: BvhLayout,
        specialisation: Specialisation,
    ) -> Result<Arc<Self>, KernelError> {
        let features = specialisation.features(features);
        let composed_for = match specialisation {
            Specialisation::Composed => features,
            Specialisation::Generic | Specialisation::Overrides => Features::all(),
        };
        let start = Instant::now();
        let device = &ctx.device;
        let [scene_layout, work_layout, args_layout, permute_group_layout] =
            bind_group_layouts(device);
        let (pipeline_layout, prepare_layout, permute_layout, module) =
            ctx.scoped("building the tracer's shader and layouts", || {
                let layout = |label, groups: &[Option<&wgpu::BindGroupLayout>]| {
                    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some(label),
                        bind_group_layouts: groups,
                        immediate_size: 0,
                    })
                };
                let tracer = layout("raylume tracer", &[Some(&scene_layout), Some(&work_layout)]);
                let prepare = layout(
                    "raylume prepare_propagate",
                    &[Some(&scene_layout), Some(&work_layout), Some(&args_layout)],
                );
                let permute = layout(
                    "raylume permute_rays",
                    &[
                        Some(&scene_layout),
                        Some(&work_layout),
                        Some(&permute_group_layout),
                    ],
                );
                let mut source = tracer_source_for(
                    ctx.limits.max_compute_workgroups_per_dimension,
                    bvh_layout,
                    composed_for,
                );
                if Self::walk_stage_possible(ctx, bvh_layout) {
                    source += &walk_stage_source();
                }
                let module = ctx.shader_module("raylume tracer", &source);
                (tracer, prepare, permute, module)
            })?;
        Ok(Arc::new(Self {
            features,
            specialisation,
            walk_stage: Self::walk_stage_possible(ctx, bvh_layout),
            bvh_layout,
            scene_layout,
            work_layout,
            args_layout,
            permute_group_layout,
            pipeline_layout,
            prepare_layout,
            permute_layout,
            module,
            compiled: Mutex::new(HashMap::new()),
            guide: Mutex::new(None),
            seconds: Mutex::new(start.elapsed().as_secs_f64()),
        }))
    }

    /// The features the pipelines are specialised on (all of them for the generic ones).
    pub fn features(&self) -> Features {
        self.features
    }

    /// How they are specialised.
    pub fn specialisation(&self) -> Specialisation {
        self.specialisation
    }

    /// The BVH layout whose traversal the module holds.
    pub fn bvh_layout(&self) -> BvhLayout {
        self.bvh_layout
    }

    /// Whether the module holds the wavefront's walk stage ([`PathVariant::walk_stage`]):
    /// with the wide BVH on an adapter with subgroups (the stage's lanes share the queue's
    /// slots through subgroup operations).
    pub fn has_walk_stage(&self) -> bool {
        self.walk_stage
    }

    fn walk_stage_possible(ctx: &GpuContext, bvh_layout: BvhLayout) -> bool {
        ctx.has_subgroups() && bvh_layout == BvhLayout::Wide
    }

    /// Seconds spent so far making the module and compiling pipelines.
    pub fn seconds(&self) -> f64 {
        *self.seconds.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Compiles the pipelines `schedule` runs for renders of `variant` (those not compiled
    /// yet), side by side, a thread each (the driver compiles one pipeline on one thread;
    /// the wavefront's halves, `propagate` and `next_event`, then take as long as the larger
    /// of them): the path tracing entry points are compiled per estimator and sampler
    /// ([`PathVariant`]).
    pub fn compile(
        &self,
        ctx: &GpuContext,
        schedule: Schedule,
        variant: PathVariant,
    ) -> Result<(), KernelError> {
        // Without the walk stage in the module, the wavefront walks in `propagate`.
        let variant = variant.with_walk_stage(variant.walk_stage && self.walk_stage);
        // A walk stage's wavefront also runs `propagate` without `HITS_TRACED`, at its sorted
        // bounces (`batch::walk_stage_at`).
        let mut wanted: Vec<(&'static str, PathVariant)> = Self::entries(schedule, variant)
            .iter()
            .map(|&e| (e, variant))
            .collect();
        if schedule == Schedule::Wavefront && variant.walk_stage {
            wanted.push(("propagate", variant.with_walk_stage(false)));
        }
        let missing: Vec<(&'static str, PathVariant)> = {
            let compiled = self.compiled.lock().unwrap_or_else(|e| e.into_inner());
            wanted
                .into_iter()
                .filter(|&(e, v)| !compiled.contains_key(&(e, self.variant(e, v))))
                .collect()
        };
        std::thread::scope(|s| {
            let others: Vec<_> = missing
                .iter()
                .skip(1)
                .map(|&(entry, v)| s.spawn(move || self.pipeline(ctx, entry, v).map(drop)))
                .collect();
            let first = missing
                .first()
                .map_or(Ok(()), |&(entry, v)| self.pipeline(ctx, entry, v).map(drop));
            others.into_iter().fold(first, |done, h| {
                let r = h.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
                done.and(r)
            })
        })
    }

    /// The pipelines compiled so far, sorted: (entry point, the variant it was compiled
    /// for; [`PathVariant::ANY`] for the entry points that trace no path and for generic
    /// pipelines).
    pub fn compiled(&self) -> Vec<(&'static str, PathVariant)> {
        let mut v: Vec<_> = self
            .compiled
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .keys()
            .copied()
            .collect();
        v.sort_unstable();
        v
    }

    /// What `entry`'s pipeline for renders of `variant` is compiled for: `variant` for the
    /// entry points that trace paths, [`PathVariant::ANY`] for the rest (compiled once) and
    /// for every entry point of [`Specialisation::Generic`] pipelines (the baseline holds
    /// every estimator's and sampler's code too); the `next_event` stage matters to
    /// `propagate` and `next_event` alone, the walk and shadow stages to `propagate` alone
    /// (the shadow stage only where it runs, [`PathVariant::defers_shadow_rays`]).
    fn variant(&self, entry: &str, variant: PathVariant) -> PathVariant {
        match TRACES_PATHS.contains(&entry) && self.specialisation != Specialisation::Generic {
            true if entry == "propagate" => variant.with_shadow_stage(variant.defers_shadow_rays()),
            true if entry == "next_event" => {
                variant.with_walk_stage(false).with_shadow_stage(false)
            }
            true => variant
                .with_next_event_stage(false)
                .with_walk_stage(false)
                .with_shadow_stage(false),
            false => PathVariant::ANY,
        }
    }

    /// The environment guide's walks over trees of this module's layout
    /// ([`GuideLearner`]), compiled on first use (its time counted in [`Self::seconds`]).
    pub fn guide_learner(&self, ctx: &GpuContext) -> Result<Arc<GuideLearner>, KernelError> {
        let cached = || self.guide.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if let Some(l) = cached() {
            return Ok(l);
        }
        let learner = Arc::new(GuideLearner::new(ctx, self.bvh_layout)?);
        *self.seconds.lock().unwrap_or_else(|e| e.into_inner()) += learner.seconds();
        // Two threads asking at once both compile; the first stored wins.
        Ok(self
            .guide
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get_or_insert(learner)
            .clone())
    }

    /// Keeps `learner` (made on another thread, over this module's BVH layout) as
    /// [`Self::guide_learner`]'s, unless one is kept already; its time counts in
    /// [`Self::seconds`].
    pub fn adopt_guide_learner(&self, learner: Arc<GuideLearner>) -> Result<(), KernelError> {
        if learner.layout() != self.bvh_layout {
            return Err(KernelError::InvalidSettings(format!(
                "a guide learner for the {} BVH layout offered to pipelines of the {} layout",
                learner.layout().name(),
                self.bvh_layout.name()
            )));
        }
        let mut guide = self.guide.lock().unwrap_or_else(|e| e.into_inner());
        if guide.is_none() {
            *self.seconds.lock().unwrap_or_else(|e| e.into_inner()) += learner.seconds();
            *guide = Some(learner);
        }
        Ok(())
    }

    /// The compute pipeline of entry point `entry`, compiled on first use.
    pub(crate) fn pipeline(
        &self,
        ctx: &GpuContext,
        entry: &'static str,
        variant: PathVariant,
    ) -> Result<wgpu::ComputePipeline, KernelError> {
        let variant = self.variant(entry, variant);
        let key = (entry, variant);
        let lock = |m: &Mutex<HashMap<(&'static str, PathVariant), wgpu::ComputePipeline>>| {
            m.lock()
                .unwrap_or_else(|e| e.into_inner())
                .get(&key)
                .cloned()
        };
        if let Some(p) = lock(&self.compiled) {
            return Ok(p);
        }
        let start = Instant::now();
        let constants = entry_constants(self.features, entry, variant, ctx.info.is_software);
        let p = ctx.scoped(&format!("compiling the `{entry}` pipeline"), || {
            ctx.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(match entry {
                        "prepare_propagate" => &self.prepare_layout,
                        "permute_rays" => &self.permute_layout,
                        _ => &self.pipeline_layout,
                    }),
                    module: &self.module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        zero_initialize_workgroup_memory: true,
                    },
                    cache: None,
                })
        })?;
        // Two threads asking at once both compile; the first stored wins.
        let p = self
            .compiled
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .entry(key)
            .or_insert(p)
            .clone();
        *self.seconds.lock().unwrap_or_else(|e| e.into_inner()) += start.elapsed().as_secs_f64();
        Ok(p)
    }
}
