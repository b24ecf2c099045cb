//! The batched tracer: backend choice, settings checks, BVH, kernels, post, stats.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_gpu::{AdapterChoice, ContextOptions, GpuContext, GpuError};
use raylume_kernels::batches::{RoundHook, RoundSums};
use raylume_kernels::{
    BatchPlan, CpuIsa, CpuTracer, Estimator, GpuScene, GpuTracer, GpuWorkspace, Reorder,
    ReorderMode, Sampler, Schedule, Specialisation, TraceSettings, TraceStats,
    gpu::{GuideLearner, LbvhBuilder, PathVariant, ResidentBvh, TracerPipelines},
    scene_data::SceneData,
};
use raylume_scene::Scene;

use crate::auto::{AutoDecision, AutoPolicy, AutoState, fingerprint};
use crate::prepared::{Prepared, SceneKey};
use crate::target::TargetRun;
use crate::timeline::mark;
use crate::{DepthSeconds, Error, ImageFormat, Part, PartHeader, RenderStats, SampleRange};

/// Where rays are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Backend {
    /// A hardware GPU if there is one (discrete first, Vulkan over GL), else the CPU. A
    /// software Vulkan adapter (lavapipe) is not picked: raylume's own CPU path is faster.
    #[default]
    Auto,
    /// The best GPU adapter, software adapters included; an error if there is none.
    Gpu,
    /// The Rust CPU path (rayon), the reference the GPU kernels mirror.
    Cpu,
    /// Every hardware GPU adapter at once ([`Tracer::with_gpu_contexts`] chooses the devices):
    /// the samples of every pixel are split between them in proportion to the speed each
    /// showed in the tracer's last render (equally at first), each renders its range in a
    /// thread of its own, and the sums are merged exactly as render parts are
    /// ([`crate::merge`]). The stats list each device's samples and time (`workers`).
    Gpus,
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Backend::Auto),
            "gpu" => Ok(Backend::Gpu),
            "cpu" => Ok(Backend::Cpu),
            "gpus" => Ok(Backend::Gpus),
            _ => Err(format!("unknown backend `{s}`: use auto, gpu, gpus or cpu")),
        }
    }
}

/// Ray reordering between bounces: sorting the live rays by the paper's 30-bit
/// origin-direction Morton key before each bounce (GPU only; the CPU path never sorts, as in
/// the paper, and its stats say so).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ReorderPolicy {
    /// No sorting: the chosen [`Tracer::schedule`], as is.
    #[default]
    Off,
    /// Sorting before every bounce, as [`Tracer::reorder_mode`] says. Sorting needs the
    /// wavefront (the megakernel keeps each path in registers), so `On` runs the wavefront
    /// whatever [`Tracer::schedule`] says; the stats note it when the schedule was the
    /// megakernel.
    On,
    /// Decided per scene, size, bounce count and batch shape from measurement on the scene's
    /// own batches: the megakernel, the unsorted wavefront, or the wavefront sorted before the
    /// depths where sorting measured faster (see [`AutoDecision`] and the module docs of
    /// `auto.rs`); cached in the `Tracer` for later renders.
    Auto,
}

impl std::str::FromStr for ReorderPolicy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "off" => Ok(ReorderPolicy::Off),
            "on" => Ok(ReorderPolicy::On),
            "auto" => Ok(ReorderPolicy::Auto),
            _ => Err(format!("unknown reorder policy `{s}`: use off, on or auto")),
        }
    }
}

/// Progress of a render, reported after every batch ([`Tracer::on_progress`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// Samples per pixel finished so far.
    pub done_spp: u32,
    /// Samples per pixel in total (with [`Tracer::target_error`]: the cap).
    pub total_spp: u32,
    /// Time since tracing began (after the BVH; on the GPU including the upload and pipeline
    /// creation before the first batch): `elapsed * total_spp / done_spp` estimates the whole
    /// trace.
    pub elapsed: Duration,
}

/// The largest image side, and the most pixels, a render accepts: beyond that the HDR image
/// alone (12 bytes a pixel) would not fit a GPU binding or sensible memory.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
/// See [`MAX_IMAGE_SIDE`]: 2^27 pixels, 1.5 GiB of HDR radiance.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 27;
/// The most samples per pixel one render accepts.
pub const MAX_SPP: u32 = 1 << 20;
/// The most bounces a path may take.
pub const MAX_BOUNCES: u32 = 1024;

/// The segments a path is counted for after Russian roulette may start ending it, in the BVH
/// preset's estimate of a render's rays ([`Tracer::bvh_quality`]): a path that survives each
/// segment with probability `p` traces `1 / (1 - p)` more on average; 5 is `p = 0.8`. Without
/// this the estimate took every path to its maximum depth: the living room's 10-spp first
/// image (64 bounces) was estimated at 1.2 G rays where it traces 49 M (H200, e56a59a), and
/// chose the Quality build (0.14-0.26 s on the H200's host) for a 0.076 s trace.
pub const ROULETTE_TAIL_SEGMENTS: u32 = 5;

/// The primitives from which [`Tracer::walk_stage`]'s default turns the wavefront's walk stage
/// on. On the H200 (100 spp) the stage sped up the three large scenes measured (the living
/// room's 142,973 triangles 21 %, the teapots' 123,554 5-8 %) and slowed the three small ones
/// (4 to 38 primitives, 10-17 %), whose walks are too short for its refills to pay; the scenes
/// between were not measured.
pub const WALK_STAGE_MIN_PRIMITIVES: usize = 10_000;

/// The default of [`Tracer::wavefront_min_samples`]: the pixel samples (width x height x
/// samples per pixel) from which a GPU render with next-event estimation whose
/// [`Tracer::schedule`] is not set runs the wavefront, where its walk stage runs, rather than
/// the persistent schedule: 2^26, about 64 spp at 1024x1024. On the H200 (1000x1000, 10
/// bounces, NEE with roulette from 5, the shadow stage on) the wavefront with its stages took
/// the living room's 100 spp in 0.289 s against the persistent schedule's 0.416 (eaf8e01, one
/// call), the teapot's in 0.081-0.082 s (eaf8e01) against the persistent schedule's
/// 0.085-0.086 (c44418f, ba630c5: other calls); at 1 spp the persistent schedule was faster
/// (living room 0.0071 against 0.0081 s; the teapot, plain, 0.0010 against 0.0025-0.0031):
/// the wavefront launches its stages at every bounce of every batch, a cost per batch the
/// persistent schedule does not pay. A straight line through those ends puts the living
/// room's crossing near 2 spp and the teapot's near 64. Renders below it (the living room's
/// 10-spp first image, whose race against Mitsuba was measured with the persistent schedule,
/// among them) keep the persistent schedule. Plain paths keep it whatever the work: the
/// teapot's 100 spp took 0.0585 s persistent against 0.0708 with the walk stage (the living
/// room's 0.460 against 0.384): the stages pay most where they take the shadow rays' walks
/// too. `tools/table1/table1.sh`'s parts `crossing` and `race` measure both choices: on an
/// H100 (2026-12-05) the living room's crossing lay at 2-3 spp with either estimator and the
/// teapots' beyond 100 spp, their paths being short (1.9-2.4 rays a sample against the living
/// room's 5.5 with NEE): the paths' length decides, which is not known when the schedule is
/// chosen. Nor would it alone: on the H200 the living room's own first image (1280x720, 64
/// bounces, 9.2 M samples, long paths) traced 11-15 % slower with the wavefront, which
/// launches its stages at every bounce that still has a ray (docs/RESULTS.md, issue 13).
pub const WAVEFRONT_MIN_SAMPLES: u64 = 1 << 26;

/// The schedule of a GPU render whose [`Tracer::schedule`] is not set: the wavefront when
/// its walk stage runs (`walk_stage_runs`), the estimator samples the lights and the render
/// traces at least `min_samples` pixel samples, else the persistent schedule.
fn default_schedule(
    walk_stage_runs: bool,
    estimator: Estimator,
    pixel_samples: u64,
    min_samples: u64,
) -> Schedule {
    if walk_stage_runs && estimator == Estimator::Nee && pixel_samples >= min_samples {
        Schedule::Wavefront
    } else {
        Schedule::Persistent
    }
}

/// The threads [`Tracer::bvh_quality`]'s estimate counts a build on: at most 4, however many
/// the pool has. The builds do not scale past a few cores: on the H200's 16-core host the 3M
/// grid's `Fast` tree took 0.146 s more than `Fastest`'s, what the per-primitive constant
/// (`raylume_bvh::PRESET_BUILD_SECONDS`, measured on 2 cores) predicts for 4 threads, not 16.
pub const BVH_BUILD_THREADS: usize = 4;

/// Where a render's BVH is built ([`Tracer::bvh_builder`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BvhBuilder {
    /// On the GPU when the render runs on a hardware GPU, the scene has no spheres, no preset
    /// other than `Fastest` was asked for, and the estimate says so
    /// ([`BvhBuilder::gpu_repays`]: a large scene and few rays); on the CPU otherwise.
    #[default]
    Auto,
    /// On the CPU ([`GpuBvh::from_scene_with_layout`]: obvhs' PLOC, or the LBVH on every core
    /// for `Fastest`), in [`Tracer::bvh_layout`].
    Cpu,
    /// On the GPU whenever the render runs on one (a software adapter too) and the scene has
    /// no spheres: Karras' linear BVH in WGSL ([`raylume_kernels::gpu::LbvhBuilder`]), binary
    /// layout, one triangle a leaf, kept on the GPU. Its tree traces slower than the CPU's
    /// trees; it is built in a fraction of their time.
    Gpu,
}

impl BvhBuilder {
    /// Lower-case name for flags and stats ("auto", "cpu", "gpu").
    pub const fn name(self) -> &'static str {
        match self {
            BvhBuilder::Auto => "auto",
            BvhBuilder::Cpu => "cpu",
            BvhBuilder::Gpu => "gpu",
        }
    }

    /// Whether building on the GPU finishes a render of `rays` ray segments over
    /// `primitives` triangles sooner than the CPU's build of `preset` (on `build_threads`
    /// threads, [`BVH_BUILD_THREADS`] at most) would: the least of
    /// `(CPU_FASTEST_BUILD_SECONDS + PRESET_BUILD_SECONDS[preset]) * primitives / threads +
    /// PRESET_TRACE_FACTOR[preset] * trace` and `GPU_BUILD_FIXED_SECONDS + GPU_BUILD_SECONDS * primitives +
    /// GPU_BUILD_TRACE_FACTOR * trace`, `trace` being `rays / rays_per_second` (the GPU's
    /// rate with a `Fastest` tree). An estimate from measured constants.
    pub fn gpu_repays(
        primitives: usize,
        rays: f64,
        rays_per_second: f64,
        build_threads: usize,
        preset: BvhQuality,
    ) -> bool {
        let i = BvhQuality::ALL
            .iter()
            .position(|&q| q == preset)
            .expect("every preset is in ALL");
        let n = primitives as f64;
        let trace = rays / rays_per_second.max(1.0);
        let cpu = (CPU_FASTEST_BUILD_SECONDS + raylume_bvh::PRESET_BUILD_SECONDS[i]) * n
            / build_threads.max(1) as f64
            + raylume_bvh::PRESET_TRACE_FACTOR[i] * trace;
        let gpu = GPU_BUILD_FIXED_SECONDS + GPU_BUILD_SECONDS * n + GPU_BUILD_TRACE_FACTOR * trace;
        gpu < cpu
    }
}

impl std::str::FromStr for BvhBuilder {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(BvhBuilder::Auto),
            "cpu" => Ok(BvhBuilder::Cpu),
            "gpu" => Ok(BvhBuilder::Gpu),
            _ => Err(format!("unknown BVH builder `{s}`: use auto, cpu or gpu")),
        }
    }
}

/// The CPU's `Fastest` build (the LBVH, reinsertion and the eight-wide conversion), seconds
/// per triangle on one thread, for [`BvhBuilder::gpu_repays`]: issue 19's grids on the
/// 2-core machine, 3M triangles in 1.01-1.26 s on 2 threads (`benches/build.rs`, 2026-12-02);
/// on the H200's 16-core host 0.50-0.53 s, what 4 threads at this rate give.
pub const CPU_FASTEST_BUILD_SECONDS: f64 = 0.75e-6;

/// The GPU's build's fixed cost ([`BvhBuilder::Gpu`]): its dispatches, one submission and
/// two read-backs, 2.2 ms for 100k triangles on the H200 (2026-12-02).
pub const GPU_BUILD_FIXED_SECONDS: f64 = 2e-3;

/// The GPU's build ([`BvhBuilder::Gpu`]), seconds per triangle, everything the render's
/// `bvh` stage does for it (the triangles' upload, the order read back): 3M triangles in
/// 0.103-0.106 s on the H200 (commit 0bbbea9, 2026-12-02,
/// `docs/study/h200-0bbbea9-first-image.md`; the build alone 75 ms in criterion).
pub const GPU_BUILD_SECONDS: f64 = 0.035e-6;

/// The trace time over the GPU-built tree (binary, one triangle a leaf, Morton splits)
/// relative to the CPU's `Fastest` tree's (eight-wide), for [`BvhBuilder::gpu_repays`]:
/// on the H200 the 3M grid traced 1.57x as long (0.036 s against 0.023 s), the living room
/// 1.41x as long as over its `Fast` tree (commit c95c2ec).
pub const GPU_BUILD_TRACE_FACTOR: f64 = 1.6;

/// `width x height x spp x (bounces + 1)`: the path segments of a render of `r` whose every
/// path reaches its maximum depth (what the guide's and the texture decoding's rules count).
fn deepest_segments(r: &raylume_scene::RenderSettings) -> f64 {
    f64::from(r.width) * f64::from(r.height) * f64::from(r.spp) * (f64::from(r.max_bounces) + 1.0)
}

/// The 8-bit texels of `scene`'s textures.
fn srgb8_texels(scene: &Scene) -> u64 {
    scene
        .textures
        .iter()
        .filter(|t| t.texels.is_srgb8())
        .map(|t| t.texels.len() as u64)
        .sum()
}

/// The threads the BVH preset's estimate counts: the pool's, at most [`BVH_BUILD_THREADS`].
pub(crate) fn bvh_build_threads() -> usize {
    rayon::current_num_threads().min(BVH_BUILD_THREADS)
}

/// The ray segments a CPU thread traces a second, as [`Tracer::bvh_quality`]'s choice
/// estimates them: 2 M, what the 2-core development machine measured on the project's scenes
/// and the large grids (1.5–4 M a thread, NEE's shadow rays included).
pub const CPU_RAYS_PER_SECOND_PER_THREAD: f64 = 2e6;
/// The ray segments a (hardware) GPU traces a second, for the same estimate: 2 G, between the
/// H200's measured 1.6 G on the living room and 8.7 G on the Cornell box (`docs/RESULTS.md`).
/// Software adapters are counted as CPUs.
pub const GPU_RAYS_PER_SECOND: f64 = 2e9;

/// Computes what renders of these materials need that depends on them alone (the rough
/// plastics' coat tables: a numerical integration per distinct roughness and index; the living
/// room's three took 0.012 s on the H200's 16-core host before they integrated four cosines
/// at once, 4x less work since), kept for the process: call it on a thread of its own as soon
/// as the materials are known. [`Tracer::prepare_geometry`] and the render compute them beside
/// the BVH build anyway (the `render` example relies on that); a render finds the tables
/// ready, or waits for those still being computed instead of computing them again.
pub fn prepare_materials(materials: &[raylume_scene::Material]) {
    raylume_kernels::scene_data::prepare_plastic_tables_for(materials);
}

/// `scene`'s BVH built on the GPU of `ctx` ([`BvhBuilder::Gpu`]), with `lbvh`'s kernels (made
/// at their first use); a tree deeper than the traversal's stack is built on the CPU instead
/// (binary layout, as the pipelines compiled beside it), and the note says so.
fn build_on_gpu(
    ctx: &GpuContext,
    lbvh: &mut Option<LbvhBuilder>,
    scene: &Scene,
) -> Result<(BuiltBvh, Option<String>), Error> {
    let builder = match lbvh {
        Some(b) => b,
        None => lbvh.insert(LbvhBuilder::new(ctx)?),
    };
    match builder.build_triangles(ctx, &scene.triangles) {
        Ok(r) => Ok((BuiltBvh::Gpu(Arc::new(r)), None)),
        Err(raylume_kernels::KernelError::Bvh(e @ raylume_bvh::BvhError::TooDeep { .. })) => {
            let bvh = GpuBvh::build_with_layout(
                &scene.triangles,
                &[],
                BvhQuality::Fastest,
                BvhLayout::Binary,
            )?;
            let note = format!(
                "LBVH on the CPU, {} threads (the GPU's LBVH: {e})",
                rayon::current_num_threads()
            );
            Ok((BuiltBvh::Cpu(Arc::new(bvh)), Some(note)))
        }
        Err(raylume_kernels::KernelError::Bvh(e)) => Err(e.into()),
        Err(e) => Err(e.into()),
    }
}

/// Reports `p` in `stats` (its seconds; compiled `ahead` on the opening's thread, or taken
/// from `cache`) and puts it first in `cache`.
fn adopt_pipelines(
    cache: &mut Vec<Arc<TracerPipelines>>,
    p: &Arc<TracerPipelines>,
    ahead: bool,
    stats: &mut RenderStats,
) {
    stats.seconds.pipelines = p.seconds();
    stats.pipelines_ahead = ahead;
    stats.pipelines_cached = !ahead && cache.iter().any(|q| Arc::ptr_eq(p, q));
    cache.retain(|q| !Arc::ptr_eq(p, q));
    cache.insert(0, p.clone());
    cache.truncate(PIPELINE_CACHE_ENTRIES);
}

/// The pipelines of `p`, waited for if they are compiling ahead (reported then, and cached).
fn resolve_pipelines(
    p: RenderPipelines,
    ctx: &GpuContext,
    cache: &mut Vec<Arc<TracerPipelines>>,
    stats: &mut RenderStats,
) -> Result<Arc<TracerPipelines>, Error> {
    match p {
        RenderPipelines::Ready(p) => Ok(p),
        RenderPipelines::Ahead(a) => {
            let t = Instant::now();
            let p = a.wait(ctx)?;
            stats.pipelines_wait = t.elapsed().as_secs_f64();
            adopt_pipelines(cache, &p, true, stats);
            Ok(p)
        }
    }
}

/// The environment guide's learner for a render's walks: the one compiling ahead as soon as
/// it is made (the tracer's own pipelines may still compile), else the pipelines' own
/// (waited for and taken into `ready`). Marked on `timeline` when in hand.
fn guide_learner(
    pipelines: &mut Option<RenderPipelines>,
    ready: &mut Option<Arc<TracerPipelines>>,
    ctx: &GpuContext,
    cache: &mut Vec<Arc<TracerPipelines>>,
    stats: &mut RenderStats,
    timeline: &Option<crate::Timeline>,
) -> Result<Arc<GuideLearner>, Error> {
    let learner = match pipelines.as_ref().and_then(RenderPipelines::ahead_learner) {
        Some(l) => l,
        None => {
            let p = match ready.as_ref() {
                Some(p) => p.clone(),
                None => {
                    let p = resolve_pipelines(
                        pipelines.take().expect("taken only with `ready` set"),
                        ctx,
                        cache,
                        stats,
                    )?;
                    *ready = Some(p.clone());
                    p
                }
            };
            p.guide_learner(ctx)?
        }
    };
    mark(timeline, "upload: guide learner in hand");
    Ok(learner)
}

/// A finished render: linear HDR radiance per pixel (after bloom, before tone mapping).
#[derive(Clone, Debug)]
pub struct Render {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Row-major, top row first, mean linear radiance per pixel (for a part: the sum of its
    /// samples, [`Render::part`]).
    pub pixels: Vec<[f32; 3]>,
    /// What ran, on what, and how long it took.
    pub stats: RenderStats,
    /// How [`Render::save`] turns radiance into 8-bit sRGB.
    pub tone: raylume_post::ToneMap,
    /// For a render part ([`Tracer::samples`]): what it belongs to and which samples it
    /// holds; `None` for a whole render.
    pub part: Option<PartHeader>,
}

impl Render {
    /// Saves as `.png` (tone-mapped sRGB) or `.exr` (linear radiance), by extension. Nothing
    /// is left at `path` if it fails.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), Error> {
        let path = path.as_ref();
        if let Some(header) = &self.part {
            // A part holds sums, to be merged: only as an EXR with its header.
            return match ImageFormat::from_path(path)? {
                ImageFormat::Exr => Part {
                    header: header.clone(),
                    sums: self.pixels.clone(),
                }
                .save(path),
                ImageFormat::Png => Err(Error::Output {
                    path: path.to_path_buf(),
                    reason: "a render part holds sums of samples, to be merged: write it as .exr"
                        .into(),
                }),
            };
        }
        match ImageFormat::from_path(path)? {
            ImageFormat::Png => {
                crate::save_png(path, &self.pixels, self.width, self.height, &self.tone)
            }
            ImageFormat::Exr => crate::save_exr(path, &self.pixels, self.width, self.height),
        }
    }

    /// 8-bit sRGB pixels after [`Render::tone`], row-major, top row first: the bytes
    /// [`Render::save`] writes to a `.png`.
    pub fn to_srgb8(&self) -> Result<Vec<[u8; 3]>, Error> {
        self.tone.to_srgb8(&self.pixels).map_err(|e| Error::Output {
            path: std::path::PathBuf::new(),
            reason: e.to_string(),
        })
    }

    /// [`Render::to_srgb8`] as an [`image::RgbImage`].
    pub fn to_image(&self) -> Result<image::RgbImage, Error> {
        let bytes: Vec<u8> = self.to_srgb8()?.into_flattened();
        image::RgbImage::from_raw(self.width, self.height, bytes).ok_or_else(|| Error::Output {
            path: std::path::PathBuf::new(),
            reason: "pixel buffer size mismatch".into(),
        })
    }
}

type ProgressFn = Box<dyn FnMut(Progress) + Send>;
type StartFn = Box<dyn FnMut(&RenderStats) + Send>;

/// The batched tracer. Configure the public fields, then call [`Tracer::render`]; a GPU
/// context, once created, is kept for later renders.
pub struct Tracer {
    /// Where rays are traced (the argument of [`Tracer::new`]).
    pub backend: Backend,
    /// Samples per pixel per batch ([`Tracer::DEFAULT_BATCH_SPP`]; the paper used 20; 0 is
    /// taken as 1, more than the render's spp as its spp). Reduced automatically to fit the
    /// adapter's buffer limits. The image does not depend on it.
    pub batch_spp: u32,
    /// Overrides the scene's seed.
    pub seed: Option<u32>,
    /// Ray reordering between bounces (default [`ReorderPolicy::Off`]).
    pub reorder: ReorderPolicy,
    /// How [`ReorderPolicy::On`] sorts: [`ReorderMode::SortIndex`] (the default) or
    /// [`ReorderMode::SortPermute`]. (`Auto` measures both.)
    pub reorder_mode: ReorderMode,
    /// The top bits of the 30-bit key that `On` and `Auto` sort by (1..=30, default 30: the
    /// paper's whole key; 16 takes half the radix passes). See [`Reorder::key_bits`].
    pub reorder_key_bits: u32,
    /// The GPU schedule: [`Schedule::Persistent`] (all bounces in registers, a thread starting
    /// the next sample when its path ends), [`Schedule::Megakernel`] (a thread a sample) or
    /// [`Schedule::Wavefront`] (the paper's kernels, one per bounce). `None` (the default):
    /// chosen per render, the wavefront where its walk stage runs ([`Tracer::walk_stage`]: by
    /// default scenes of at least [`WALK_STAGE_MIN_PRIMITIVES`] primitives, over the wide BVH
    /// on an adapter with subgroups), the estimator is [`Estimator::Nee`] and the render
    /// traces at least [`Tracer::wavefront_min_samples`] pixel samples, else the persistent
    /// schedule; [`crate::RenderStats::schedule`] says which ran. The CPU runs the persistent
    /// schedule's loop whatever this says.
    pub schedule: Option<Schedule>,
    /// The pixel samples (width x height x samples per pixel of the render, or of its
    /// [`Tracer::samples`]) from which an unset [`Tracer::schedule`] may choose the wavefront
    /// (default [`WAVEFRONT_MIN_SAMPLES`], measured on the H200; another GPU's crossing may lie
    /// elsewhere).
    pub wavefront_min_samples: u64,
    /// Whether the wavefront takes its light samples (NEE) in a `next_event` stage of their
    /// own after each bounce's `propagate`, two pipelines the driver compiles side by side
    /// (default: off). It can shorten a cold process's wait for its pipelines (the living
    /// room's first image on the H200: sooner than the megakernel's in 9 of 11 cold rounds
    /// over four calls, by 0.05-0.56 s, 0.01-0.04 s later in two); it speeds the living
    /// room's NEE wavefront at 100 spp (unsorted 0.488 -> 0.446 s, sorted 0.434 -> 0.427 s)
    /// but costs a small scene a stage's overhead (the Cornell box's 0.113 -> 0.193 s);
    /// [`raylume_kernels::gpu::PathVariant::next_event_stage`].
    pub next_event_stage: bool,
    /// Whether the wavefront walks each bounce's path rays in a stage of their own before
    /// `propagate` shades them (`trace_hits`: a fixed set of GPU threads, each taking the
    /// next ray of the queue when its walk ends; wide BVH and subgroups only, else ignored;
    /// the same images). On large scenes whose rays are not sorted it pays (the living room on
    /// the H200, 100 spp: plain 0.486 -> 0.383 s, NEE 0.424 -> 0.373 s, both faster than
    /// sorting); on small scenes it costs (the Cornell box +17 %); a sorted bounce is walked
    /// as without it; [`raylume_kernels::gpu::PathVariant::walk_stage`]. `None` (the
    /// default): on for scenes of at least [`WALK_STAGE_MIN_PRIMITIVES`] primitives.
    pub walk_stage: Option<bool>,
    /// Whether the wavefront, where its walk stage runs and the estimator samples lights
    /// (NEE, without the `next_event` stage), walks the shadow rays in a stage of their own
    /// after `propagate` (`trace_shadows`, whose threads take the next ray as the walk
    /// stage's do; the same images). On by default: on the H200 at 100 spp it took the living
    /// room's NEE trace from 0.376 to 0.302 s and the teapot's from 0.096 to 0.086 s (with
    /// it off, `propagate` walks them one ray a thread; on the Cornell box, whose 36
    /// triangles do not get the walk stage by default, the pair is slower: 0.120 -> 0.135 s);
    /// [`raylume_kernels::gpu::PathVariant::shadow_stage`].
    pub shadow_stage: bool,
    /// The estimator: next-event estimation with multiple importance sampling
    /// ([`Estimator::Nee`], the default: far less noise per sample where emitters light the
    /// scene; each reflecting hit also casts a shadow ray), or the paper's plain one
    /// ([`Estimator::Plain`]). The same on both backends.
    pub estimator: Estimator,
    /// Where the paths' random numbers come from: [`Sampler::Sobol`] (the default:
    /// Owen-scrambled Sobol' points, each pixel's a net, less error per sample on smooth
    /// integrands), [`Sampler::ZSobol`] (pbrt-v4's default: the same nets, blue noise across
    /// pixels, more arithmetic per number) or [`Sampler::Independent`] (the paper's
    /// independent `pcg4d` numbers).
    pub sampler: Sampler,
    /// The segment from which Russian roulette may end a path (`Some(5)`, the default,
    /// [`Tracer::DEFAULT_RUSSIAN_ROULETTE`]; `Some(4)` is Mitsuba 3's `path` at its default
    /// `rr_depth` 5, which counts hits from 1; `None`: off, every path runs to `max_bounces`
    /// or until it escapes).
    /// After each hit of a segment `>= start` the path goes on with probability
    /// `min(max throughput, 0.95)` and its throughput is divided by it: unbiased, fewer rays.
    pub russian_roulette: Option<u32>,
    /// Whether next-event estimation samples the environment by where the scene leaves it
    /// visible: before the render, diffuse random walks from the camera (on the GPU for a GPU
    /// render) count the directions in which they escape, and the sky is sampled by that (mixed with the unguided
    /// distribution; `raylume_kernels::env_guide`). In a room lit through its windows most
    /// shadow rays toward a uniformly sampled sky hit walls; guided, most pass. `Some(true)`:
    /// always; `Some(false)`: by the environment's radiance alone, as Mitsuba 3; `None` (the
    /// default): when the render's rays repay the walks' ([`Tracer::guide_repays`]: a 500x500
    /// render of 16 spp does, a thumbnail does not). Unbiased either way; the same on both
    /// backends. [`RenderStats::environment_guide`] says what was decided and learned.
    pub environment_guide: Option<bool>,
    /// How the GPU (and the CPU mirror) hold 8-bit textures: `Some(false)` as their sRGB codes
    /// (one 32-bit word a texel, decoded on lookup through a 256-entry table: a quarter of the
    /// memory and upload of floats), `Some(true)` decoded to linear floats (lookups without
    /// the table's load: the living room's 100-spp trace 1.3-2.8 % faster on the H200, its
    /// upload 30 ms longer), `None` (the default): decoded when the render's rays repay it
    /// ([`Tracer::decoding_repays`]). The same image either way;
    /// [`RenderStats::textures`] says which ran.
    pub decode_textures: Option<bool>,
    /// Render until the image's relative MSE (as `raylume_post::relative_mse` measures it
    /// against the converged image), estimated from the spread of its own batches, is below
    /// this value; the scene's `spp` is then the cap. `None` (the default): render the
    /// scene's `spp`. After every batch of `batch_spp` samples of every pixel (a round: see
    /// [`RenderStats::batches`]) the estimate is the mean over pixels and channels of
    /// `Var(pixel mean) / (mean^2 + 1e-2)`, `Var(pixel mean)` the sample variance of the
    /// batches' means divided by their number; it needs at least 2 batches, so a cap of one
    /// batch renders it and reports no estimate. The render stops at the first batch whose
    /// estimate is below the target, and its image is then exactly that of a render of the
    /// samples traced (with the Sobol' samplers, whose points are laid out for the cap: the
    /// first samples of the capped render). The estimate is of the traced radiance, before
    /// bloom. The estimate treats the batches as independent, which they are with
    /// [`Sampler::Independent`]; with the Sobol' samplers the batches' points are stratified
    /// together, so the whole render is better than independent batches would be and the
    /// estimate overstates its error (the furnace scene of `tests/target_error.rs` at 64x64,
    /// 16 batches: 1.04x with batches of 16 spp, 1.4x with batches of 4, measured once): the
    /// render stops later than it needs to rather than earlier (one scene measured, not a
    /// proof). [`RenderStats`] reports `target_error`, `estimated_error`, `target_reached`,
    /// `batches`, `spp` (done) and `spp_cap`. Must be finite and above 0
    /// ([`Error::TargetError`]); on the GPU every batch's image is read back to estimate it.
    pub target_error: Option<f32>,
    /// The BVH build preset. `None` (the default): chosen for each render from the work
    /// ahead ([`BvhQuality::for_work`]: the rays the render may trace, `pixels x spp x
    /// segments`, the segments `bounces + 1` or with Russian roulette at most
    /// [`ROULETTE_TAIL_SEGMENTS`] past its start, twice that with NEE's shadow rays, against
    /// the backend's rate, [`CPU_RAYS_PER_SECOND_PER_THREAD`] a thread or
    /// [`GPU_RAYS_PER_SECOND`], and the build on at most [`BVH_BUILD_THREADS`] threads),
    /// so that a quick look at a large scene does not wait for the `Quality` build a long
    /// render earns back; a tree of the same geometry built with `Quality` and still cached
    /// is used whatever the choice. (`BvhQuality::Fastest` for a 128x128, 4-spp look at a
    /// million triangles on a CPU, `Quality` for a 1000x1000, 100-spp render.) [`RenderStats::bvh_preset`] says what was built.
    pub bvh_quality: Option<BvhQuality>,
    /// The BVH's node layout (default [`BvhLayout::default`]): the binary one or the
    /// compressed eight-wide one. The two find the same hits; which is faster depends on the
    /// scene and the device (`docs/RESULTS.md`).
    pub bvh_layout: BvhLayout,
    /// Where the BVH is built (default [`BvhBuilder::Auto`]). A tree built on the GPU is
    /// binary, whatever [`Tracer::bvh_layout`] says; [`RenderStats::bvh_builder`] says which
    /// ran and [`RenderStats::bvh_layout`] the layout.
    pub bvh_builder: BvhBuilder,
    /// How the GPU pipelines are specialised on the scene's features
    /// ([`Specialisation::Composed`] by default: the code of an effect the scene does not call
    /// for is not in the shader at all; [`Specialisation::Overrides`]: it is, behind WGSL
    /// override constants; [`Specialisation::Generic`]: every feature compiled in, the
    /// baseline, `bench --specialise`). The image is the same every way (`tests/specialise.rs`).
    /// The CPU mirror's per-bounce functions are compiled in sixteen variants by feature group
    /// (`raylume_kernels::cpu::variant`): `Generic` runs the one with every feature, the
    /// others the smallest holding the scene's.
    pub specialisation: Specialisation,
    /// Features compiled into the GPU pipelines (and into the CPU mirror's variant, whose
    /// groups then include theirs) although the scene does not call for them (default none):
    /// for measuring what a feature costs when present but unused (`bench --extra-feature`).
    /// The image is the same.
    pub extra_features: raylume_scene::Features,
    /// The highest instruction-set level the CPU path's kernel may run at
    /// ([`CpuIsa`]; default [`CpuIsa::X86_64V4`]): it runs at the highest level at most this
    /// that the CPU executes, whatever the build targets (a default `cargo build` included),
    /// the same image bit for bit at every level. [`RenderStats::adapter`] says which ran.
    /// For measuring what the wider instructions give (`render --cpu-isa`).
    pub cpu_isa: CpuIsa,
    /// Whether the CPU path traces scenes of triangles without textures, shading normals or a
    /// sky eight paths at a time (sixteen on AVX-512), the shading of their diffuse hits in
    /// vector instructions and their other hits (other materials) one lane at a time
    /// (`raylume_kernels::cpu::packet`; default `true`), or one path at a time as every other
    /// scene. The same image bit for bit; [`RenderStats::adapter`] says `packets` when they
    /// ran. For measuring what they give (`render --cpu-packets`).
    pub cpu_packets: bool,
    /// Whether the CPU path traces the scenes the packets do not take two paths at a time, a
    /// segment of each in turn, each hit's records asked for after its walk and read after
    /// the other path's segment (`raylume_kernels::cpu::stages::trace_paths_in_pairs`):
    /// `Some(true)`, `Some(false)` (one path at a time), or `None` (the default: where those
    /// records exceed `raylume_kernels::cpu::PAIRS_MIN_RECORD_BYTES`, a core's L2 cache).
    /// The same image bit for bit; [`RenderStats::adapter`] says `paths in pairs` when they
    /// ran. For measuring what they give (`render --cpu-pairs`).
    pub cpu_pairs: Option<bool>,
    /// Whether a CPU render places the arrays it reads at random in memory backed by 2 MiB
    /// pages, where the page-table walks of those reads are fewer: a copy of the records its
    /// shading reads (the primitives, their material indices and shading records, the
    /// texels), and the tree's walk arrays where no CPU walk made them before
    /// (`raylume_kernels::cpu::CpuTracer::set_huge_pages`): `Some(true)`, `Some(false)`, or
    /// `None` (the default: where those arrays take at least
    /// `raylume_kernels::cpu::HUGE_PAGES_MIN_BYTES` and the render traces at least a path
    /// sample per `raylume_kernels::cpu::HUGE_PAGES_BYTES_PER_PATH` bytes of them). The copy
    /// takes the records' size in memory again for the render; its time is part of the
    /// stats' `upload`.
    /// The same image bit for bit; [`RenderStats::adapter`] says `records in huge pages` when
    /// it was made. For measuring what it gives (`render --cpu-huge-pages`).
    pub cpu_huge_pages: Option<bool>,
    /// Render only these samples of every pixel (default `None`: all of them): a render
    /// **part**, whose image holds each pixel's *sum* over the range and whose
    /// [`Render::part`] says what it belongs to; parts that tile `0..spp` merge into the
    /// render of all the samples ([`crate::merge`]; [`SampleRange::part`] cuts equal parts).
    /// No bloom runs on a part (it is not linear: run it on the merged image), and a part
    /// cannot stop at a target error.
    pub samples: Option<SampleRange>,
    /// Run the scene's bloom, if it has one (`--no-bloom` clears this).
    pub bloom: bool,
    /// Exposure, tone curve and encoding for `.png` output.
    pub tone: raylume_post::ToneMap,
    /// Where the tracer marks its milestones (default `None`: nowhere): the device's
    /// opening and pipelines, the BVH, the upload, the trace, from every thread it runs;
    /// [`RenderStats::timeline`] carries them ([`crate::timeline`]).
    pub timeline: Option<crate::Timeline>,
    progress: Option<ProgressFn>,
    on_start: Option<StartFn>,
    pub(crate) gpu: Option<GpuContext>,
    /// [`Backend::Gpus`]: one tracer per device, and the samples per second each traced in
    /// the last render (the split's weights).
    pub(crate) gpu_workers: Vec<Tracer>,
    pub(crate) worker_speeds: Vec<f64>,
    gpu_bloom: Option<raylume_post::GpuBloom>,
    /// The GPU work buffers and ray sorters of the last render, handed to the next one so that
    /// repeated renders reuse them instead of reallocating (see `GpuWorkspace`).
    gpu_workspace: Option<GpuWorkspace>,
    /// `Auto`'s measurements and decisions, by [`fingerprint`].
    auto: HashMap<u64, AutoState>,
    /// The GPU pipelines of the last renders (most recent first, at most
    /// [`PIPELINE_CACHE_ENTRIES`]), kept for the next render with the same features and BVH
    /// layout (compiling them is most of a first image's time).
    gpu_pipelines: Vec<Arc<TracerPipelines>>,
    /// Seconds the GPU context took to create, until a render reports them.
    device_seconds: Option<f64>,
    /// A GPU context being created on a thread of its own ([`Tracer::start_backend`]).
    opening: Option<Opening>,
    /// Pipelines the opening's thread compiles (or has compiled) for a render still to come
    /// ([`Tracer::prepare_scene`]), after it handed over the context: that render uploads
    /// its scene meanwhile, then waits for them, and reports them as compiled, not cached.
    pipelines_ahead: Option<AheadPipelines>,
    /// The last BVHs built (at most [`BVH_CACHE_ENTRIES`], the latest first), each for the
    /// geometry, preset and layout it was built from: rendering the same scene again (another
    /// spp, size, seed, or a benchmark's repeats, also alternating the two layouts) skips the
    /// build.
    pub(crate) bvh_cache: Vec<BvhCacheEntry>,
    /// The GPU BVH builder's kernels and sorter (made at its first use on the context).
    lbvh: Option<LbvhBuilder>,
}

/// BVHs the tracer keeps: two, so that a benchmark alternating layouts or presets on one
/// scene builds each tree once.
const BVH_CACHE_ENTRIES: usize = 2;

/// Pipeline sets (features x BVH layout) a tracer keeps: a bench alternating the generic and
/// the specialised pipeline, or two layouts, compiles each once.
const PIPELINE_CACHE_ENTRIES: usize = 4;

/// A built BVH and the exact geometry it was built from, and the scene last prepared for
/// tracing over it ([`crate::prepared`]).
pub(crate) struct BvhCacheEntry {
    pub(crate) key: GeometryKey,
    pub(crate) bvh: BuiltBvh,
    pub(crate) prepared: Prepared,
    /// Built by [`Tracer::prepare_scene`] and not yet rendered with: the seconds it took,
    /// which the first render over it reports as its own `bvh` stage.
    pub(crate) ahead: Option<f64>,
}

/// A tree built on the CPU, or on the GPU and kept there ([`BvhBuilder::Gpu`]).
#[derive(Clone, Debug)]
pub(crate) enum BuiltBvh {
    Cpu(Arc<GpuBvh>),
    Gpu(Arc<ResidentBvh>),
}

impl BuiltBvh {
    fn node_count(&self) -> usize {
        match self {
            BuiltBvh::Cpu(b) => b.stats.node_count,
            BuiltBvh::Gpu(r) => r.node_count(),
        }
    }
}

/// A GPU context in the making ([`Tracer::start_backend`]): the adapters it may pick, and
/// the thread creating it (its result and the seconds it took).
struct Opening {
    choice: AdapterChoice,
    thread: std::thread::JoinHandle<()>,
    /// The context (or why not) and the seconds it took, sent as soon as it is open: the
    /// thread goes on to compile what it was asked for (`compiled`), and its end (~10 ms on
    /// the H200's host after the pipelines) is nobody's wait.
    ready: std::sync::mpsc::Receiver<(Result<GpuContext, GpuError>, f64)>,
    /// The pipelines compiled on the thread, if asked (`asked`).
    compiled: std::sync::mpsc::Receiver<PipelinesResult>,
    /// Their guide learner, as soon as it is made ([`AheadPipelines::learner`]).
    learner: std::sync::mpsc::Receiver<Arc<GuideLearner>>,
    /// What `request` carried, if anything.
    asked: Option<PipelineRequest>,
    /// Where [`Tracer::prepare_scene`] asks for the pipelines the render will need, to be
    /// compiled on the opening's thread as soon as the device is open; dropped (the thread
    /// then compiles nothing) before the thread is joined.
    request: Option<std::sync::mpsc::Sender<PipelineRequest>>,
    /// The adapter's kind, announced before its device is created: `Some(software)`, or
    /// `None` when no adapter qualified (the channel closes without a word when the opening
    /// failed before choosing).
    adapter: std::sync::mpsc::Receiver<Option<bool>>,
    /// What `adapter` said, once read (`Some(None)`: no adapter).
    known: Option<Option<bool>>,
}

/// Pipelines compiled, or why not.
type PipelinesResult = Result<Arc<TracerPipelines>, raylume_kernels::KernelError>;

/// Pipelines an opening's thread compiles after handing over its context
/// ([`Tracer::pipelines_ahead`]).
struct AheadPipelines {
    request: PipelineRequest,
    compiled: std::sync::mpsc::Receiver<PipelinesResult>,
    /// The guide's learner once made (only when the request learns a guide), before the
    /// tracer's own pipelines are.
    learner: std::sync::mpsc::Receiver<Arc<GuideLearner>>,
    thread: std::thread::JoinHandle<()>,
}

impl AheadPipelines {
    /// The pipelines, once compiled: the thread's result, its panic resumed here, or (should
    /// the thread have ended without a word) compiled now on `ctx`.
    fn wait(self, ctx: &GpuContext) -> PipelinesResult {
        match self.compiled.recv() {
            Ok(r) => r,
            Err(_) => {
                self.thread
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                self.request.compile(ctx)
            }
        }
    }
}

/// The pipelines a GPU render traces with: compiled (or kept) already, or still compiling on
/// the opening's thread while the render uploads its scene.
enum RenderPipelines {
    Ready(Arc<TracerPipelines>),
    Ahead(AheadPipelines),
}

impl RenderPipelines {
    /// The guide's learner of pipelines compiling ahead, as soon as it is made (the tracer's
    /// own may still compile); `None` for pipelines ready (their learner is theirs to make)
    /// or when the opening's thread made none (an error to come with the pipelines).
    fn ahead_learner(&self) -> Option<Arc<GuideLearner>> {
        match self {
            RenderPipelines::Ready(_) => None,
            RenderPipelines::Ahead(a) => a.learner.recv().ok(),
        }
    }
}

/// The pipelines a render will compile: features, layout and specialisation (the cache's
/// key), the schedule it starts with and the estimator and sampler it runs, and whether it
/// learns an environment guide.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PipelineRequest {
    features: raylume_scene::Features,
    layout: BvhLayout,
    specialisation: Specialisation,
    schedule: Schedule,
    /// The render's estimator and sampler: its path tracing pipelines hold only their code.
    variant: PathVariant,
    guides: bool,
}

impl PipelineRequest {
    /// The pipeline cache's key of what this compiles.
    fn key(&self) -> (raylume_scene::Features, BvhLayout, Specialisation) {
        (self.features, self.layout, self.specialisation)
    }

    /// Makes the module and compiles the schedule's pipelines (and the guide's walks beside
    /// them, when the render learns a guide): what a render's compiling thread does.
    fn compile(
        &self,
        ctx: &GpuContext,
    ) -> Result<Arc<TracerPipelines>, raylume_kernels::KernelError> {
        self.compile_announcing(ctx, |_| ())
    }

    /// [`PipelineRequest::compile`], handing the guide's learner (when the render learns a
    /// guide) to `learner_made` as soon as it is made: it compiles on a thread of its own from
    /// the start, beside the tracer's module and pipelines, so that the render can run the
    /// guide's walks while they compile.
    fn compile_announcing(
        &self,
        ctx: &GpuContext,
        learner_made: impl FnOnce(&Arc<GuideLearner>) + Send,
    ) -> Result<Arc<TracerPipelines>, raylume_kernels::KernelError> {
        // The guide's walks compile (and warm up) beside the tracer's pipelines: on a first
        // run the driver spends ~0.2 s on them, ~1 s on the megakernel.
        std::thread::scope(|inner| {
            let learner = self.guides.then(|| {
                inner.spawn(|| {
                    let l = Arc::new(GuideLearner::new(ctx, self.layout)?);
                    learner_made(&l);
                    Ok::<_, raylume_kernels::KernelError>(l)
                })
            });
            let p =
                TracerPipelines::specialised(ctx, self.features, self.layout, self.specialisation)?;
            p.compile(ctx, self.schedule, self.variant)?;
            if let Some(handle) = learner {
                let l = handle
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))?;
                p.adopt_guide_learner(l)?;
            }
            Ok(p)
        })
    }
}

impl Opening {
    /// Whether the adapter being opened is a software one (`None`: there is none), waiting
    /// for the choice (a fraction of the opening) if it is not made yet.
    fn adapter_is_software(&mut self) -> Option<bool> {
        *self
            .known
            .get_or_insert_with(|| self.adapter.recv().ok().flatten())
    }
}

/// What a BVH depends on: every triangle vertex and sphere, bit for bit (a 64-bit hash plus
/// the counts and bounds), the build preset and the layout. Materials, camera and settings do
/// not matter to it.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) struct GeometryKey {
    hash: u64,
    triangles: usize,
    spheres: usize,
    bounds: [u32; 6],
    quality: BvhQuality,
    layout: BvhLayout,
    /// Built on the GPU (and kept there): never handed to a CPU render.
    on_gpu: bool,
}

impl GeometryKey {
    pub(crate) fn of(scene: &Scene, quality: BvhQuality, layout: BvhLayout) -> Self {
        // A multiply-rotate hash over the raw bits (FxHash's step, two floats a step), per
        // run of 16,384 triangles on every core, in four chains that take the triangles in
        // turn (the multiplies of one chain wait for each other, the four's do not), the
        // runs' hashes then hashed in order; the triangles' bounds in the same pass (one read
        // of the positions, not two). The 3M grid on the 2-core machine: ~20 ms.
        const SEED: u64 = 0x243f_6a88_85a3_08d3;
        let step = |h: u64, w: u64| (h.rotate_left(5) ^ w).wrapping_mul(0x517c_c1b7_2722_0a95);
        let pair = |a: f32, b: f32| u64::from(a.to_bits()) | (u64::from(b.to_bits()) << 32);
        let runs: Vec<(u64, Vec3, Vec3)> = scene
            .triangles
            .par_chunks(1 << 14)
            .map(|run| {
                let mut chains = [SEED, SEED ^ 1, SEED ^ 2, SEED ^ 3];
                let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                for (k, t) in run.iter().enumerate() {
                    let [a, b, c] = t.positions;
                    let h = &mut chains[k & 3];
                    for w in [
                        pair(a.x, a.y),
                        pair(a.z, b.x),
                        pair(b.y, b.z),
                        pair(c.x, c.y),
                        u64::from(c.z.to_bits()),
                    ] {
                        *h = step(*h, w);
                    }
                    lo = lo.min(a).min(b).min(c);
                    hi = hi.max(a).max(b).max(c);
                }
                (chains.into_iter().fold(SEED, step), lo, hi)
            })
            .collect();
        let mut h: u64 = step(SEED, scene.triangles.len() as u64);
        let mut b = raylume_scene::Bounds {
            min: Vec3::INFINITY,
            max: Vec3::NEG_INFINITY,
        };
        for (r, lo, hi) in runs {
            h = step(h, r);
            b.grow(lo);
            b.grow(hi);
        }
        for sp in &scene.spheres {
            h = step(h, pair(sp.center.x, sp.center.y));
            h = step(h, pair(sp.center.z, sp.radius));
            b.grow(sp.center - Vec3::splat(sp.radius));
            b.grow(sp.center + Vec3::splat(sp.radius));
        }
        let bounds = [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z].map(f32::to_bits);
        Self {
            hash: h,
            triangles: scene.triangles.len(),
            spheres: scene.spheres.len(),
            bounds,
            quality,
            layout,
            on_gpu: false,
        }
    }
}

impl std::fmt::Debug for Tracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracer")
            .field("backend", &self.backend)
            .field("batch_spp", &self.batch_spp)
            .field("seed", &self.seed)
            .field("reorder", &self.reorder)
            .field("reorder_mode", &self.reorder_mode)
            .field("reorder_key_bits", &self.reorder_key_bits)
            .field("schedule", &self.schedule)
            .field("wavefront_min_samples", &self.wavefront_min_samples)
            .field("estimator", &self.estimator)
            .field("sampler", &self.sampler)
            .field("next_event_stage", &self.next_event_stage)
            .field("walk_stage", &self.walk_stage)
            .field("shadow_stage", &self.shadow_stage)
            .field("russian_roulette", &self.russian_roulette)
            .field("target_error", &self.target_error)
            .field("bloom", &self.bloom)
            .finish()
    }
}

impl Tracer {
    /// The default batch size: 32 samples per pixel per batch, reduced to what the adapter's
    /// storage bindings hold (on the H200 at 1000x1000: 33 for the plain estimator, 26 with
    /// the shadow stage's records). The paper's 20 left the GPU a fifth more batches to
    /// start and drain: on the H200 at 100 spp, the living room's NEE trace 0.2996 -> 0.2958
    /// s, the teapot's 0.0847 -> 0.0811 s, the plain living room 0.3852 -> 0.3827 s
    /// (`docs/RESULTS.md`, issue 13). The CPU's batches are bounded by its own limit
    /// ([`raylume_kernels::cpu::CPU_MAX_RAYS_PER_BATCH`]: 4 spp at 1000x1000).
    pub const DEFAULT_BATCH_SPP: u32 = 32;

    /// [`RenderStats::environment_guide`]'s words for a render that `guides` (or not) and
    /// whose walks found `walks` (walks, escapes).
    fn describe_guide(&self, guides: bool, walks: Option<(u32, u64)>) -> String {
        match (self.estimator, guides, walks) {
            (Estimator::Plain, _, _) => "unused (plain estimator)".into(),
            (_, false, _) if self.environment_guide.is_none() => {
                "by radiance (the render's rays would not repay learning a guide)".into()
            }
            (_, false, _) => "by radiance (guide off)".into(),
            (_, true, None) => "no guide (no environment or no geometry)".into(),
            (_, true, Some((w, e))) if e < raylume_kernels::env_guide::GUIDE_MIN_ESCAPES => {
                format!("by radiance (too few escapes to guide: {e} from {w} walks)")
            }
            (_, true, Some((w, e))) => format!("guided ({e} escapes from {w} walks)"),
        }
    }

    /// The rays a render of `spp` samples per pixel at `r`'s size may trace, as the BVH
    /// preset's choice estimates them: every path to `r.max_bounces + 1` segments or, with
    /// Russian roulette, to at most [`ROULETTE_TAIL_SEGMENTS`] past its start; two rays a
    /// segment with next-event estimation (its shadow ray).
    pub(crate) fn estimated_rays(&self, r: &raylume_scene::RenderSettings, spp: u32) -> f64 {
        let mut segments = r.max_bounces.saturating_add(1);
        if let Some(rr) = self.russian_roulette {
            segments = segments.min(rr.saturating_add(ROULETTE_TAIL_SEGMENTS));
        }
        let per_segment = if self.estimator == Estimator::Nee {
            2.0
        } else {
            1.0
        };
        f64::from(r.width)
            * f64::from(r.height)
            * f64::from(spp)
            * f64::from(segments)
            * per_segment
    }

    /// Whether a render of these settings traces at least [`Tracer::GUIDE_REPAY_FACTOR`]
    /// times the rays the environment guide's walks may trace
    /// (`raylume_kernels::env_guide::GUIDE_MAX_RAYS`), counting two rays (a segment and a
    /// shadow ray) per segment of every sample: what [`Tracer::environment_guide`]'s `None`
    /// decides by.
    pub fn guide_repays(r: &raylume_scene::RenderSettings) -> bool {
        let rays = deepest_segments(r) * 2.0;
        rays >= Self::GUIDE_REPAY_FACTOR * raylume_kernels::env_guide::GUIDE_MAX_RAYS as f64
    }

    /// How many times the environment guide's rays a render must trace for
    /// [`Tracer::environment_guide`]'s `None` to learn the guide: then the walks cost at most
    /// about a tenth of the render (25,600 walks, at most 0.92 M rays: ~0.3 s on 2 CPU
    /// cores, ~50 ms on the H200's 16-core host; a GPU render runs them on the GPU: ~1 ms
    /// for the living room's on the H200, 2026-12-02, docs/RESULTS.md).
    pub const GUIDE_REPAY_FACTOR: f64 = 10.0;

    /// The Russian-roulette start of [`Tracer::new`]: segment 5, as good an error per second
    /// as any start measured on the Cornell box (2, 8 and off in `docs/ACCURACY.md`; 4 2-3 %
    /// and 1 17-24 % worse in `docs/RESULTS.md`, issue 15). A segment later than Mitsuba
    /// 3's `path` at its default `rr_depth` 5: Mitsuba counts a path's hits from 1 and rolls
    /// after hit `>= rr_depth`, so its first roulette follows segment 4 here (segments count
    /// from 0, the camera ray's); `Some(4)` is its estimator.
    pub const DEFAULT_RUSSIAN_ROULETTE: u32 = 5;

    /// A tracer with the defaults a user expects of a path tracer: next-event estimation with
    /// MIS ([`Estimator::Nee`]), scrambled Sobol' points ([`Sampler::Sobol`]) and Russian
    /// roulette from segment 5; batches of [`Tracer::DEFAULT_BATCH_SPP`] samples per pixel,
    /// no ray reordering, the GPU schedule chosen per render ([`Tracer::schedule`]). For the
    /// paper's estimator set [`Tracer::paper_estimator`] (plain, independent numbers, no
    /// roulette), as the Table-1 `bench` does.
    pub fn new(backend: Backend) -> Self {
        Self {
            backend,
            batch_spp: Self::DEFAULT_BATCH_SPP,
            seed: None,
            reorder: ReorderPolicy::Off,
            reorder_mode: ReorderMode::SortIndex,
            reorder_key_bits: raylume_sort::RAY_KEY_BITS,
            schedule: None,
            wavefront_min_samples: WAVEFRONT_MIN_SAMPLES,
            next_event_stage: false,
            walk_stage: None,
            shadow_stage: true,
            estimator: Estimator::Nee,
            sampler: Sampler::Sobol,
            russian_roulette: Some(Self::DEFAULT_RUSSIAN_ROULETTE),
            environment_guide: None,
            decode_textures: None,
            target_error: None,
            bvh_quality: None,
            bvh_layout: BvhLayout::default(),
            specialisation: Specialisation::default(),
            extra_features: raylume_scene::Features::NONE,
            cpu_isa: CpuIsa::X86_64V4,
            cpu_packets: true,
            cpu_pairs: None,
            cpu_huge_pages: None,
            samples: None,
            bloom: true,
            tone: raylume_post::ToneMap::default(),
            timeline: None,
            progress: None,
            on_start: None,
            gpu: None,
            gpu_workers: Vec::new(),
            worker_speeds: Vec::new(),
            gpu_bloom: None,
            gpu_workspace: None,
            auto: HashMap::new(),
            gpu_pipelines: Vec::new(),
            device_seconds: None,
            opening: None,
            pipelines_ahead: None,
            bvh_cache: Vec::new(),
            bvh_builder: BvhBuilder::default(),
            lbvh: None,
        }
    }

    /// What the kernels prepare for a render of `scene`: the environment guide when NEE will
    /// use it ([`Tracer::guides`]), 8-bit textures decoded when [`Tracer::decode_textures`]
    /// says so.
    fn scene_options(&self, scene: &Scene) -> raylume_kernels::SceneOptions {
        raylume_kernels::SceneOptions {
            environment_guide: self.guides(scene),
            decode_textures: self.decodes_textures(scene),
        }
    }

    /// Whether a render of `scene` holds its 8-bit textures decoded: as
    /// [`Tracer::decode_textures`] says, `None` deciding by [`Tracer::decoding_repays`].
    fn decodes_textures(&self, scene: &Scene) -> bool {
        let codes = srgb8_texels(scene);
        codes > 0
            && self
                .decode_textures
                .unwrap_or_else(|| Self::decoding_repays(&scene.render, codes))
    }

    /// [`RenderStats::textures`]' words for a render of `scene`.
    fn describe_textures(&self, scene: &Scene) -> String {
        let codes = srgb8_texels(scene) > 0;
        match (codes, self.decodes_textures(scene), self.decode_textures) {
            (false, _, _) if scene.textures.is_empty() => "none".into(),
            (false, _, _) => "floats".into(),
            (true, true, None) => "decoded to floats (the render's rays repay it)".into(),
            (true, true, _) => "decoded to floats".into(),
            (true, false, None) => "8-bit sRGB codes (decoding would not repay)".into(),
            (true, false, _) => "8-bit sRGB codes".into(),
        }
    }

    /// Whether a render of these settings traces at least [`Tracer::DECODE_REPAY_FACTOR`]
    /// path segments (`width x height x spp x (bounces + 1)`) per 8-bit texel (`texels`):
    /// [`Tracer::decode_textures`]' `None` decides by it.
    pub fn decoding_repays(r: &raylume_scene::RenderSettings, texels: u64) -> bool {
        deepest_segments(r) >= Self::DECODE_REPAY_FACTOR * texels as f64
    }

    /// Path segments per 8-bit texel from which decoding the textures repays its upload
    /// ([`Tracer::decoding_repays`]). Measured on the H200 (commit b7ed47b, the living room's
    /// 4.9 M texels): decoded, the upload takes ~30 ms more and a 1000x1000, 100-spp,
    /// 10-bounce trace (1.1 G segments, 225 a texel) 8-15 ms less; the break-even is near
    /// 400-800 segments a texel.
    pub const DECODE_REPAY_FACTOR: f64 = 600.0;

    /// Whether a render of `scene` learns and uses the environment guide: with NEE, as
    /// [`Tracer::environment_guide`] says, `None` deciding by [`Tracer::guide_repays`]. It
    /// depends on the whole render's settings (not on a part's sample range), so that every
    /// part of a render decides alike.
    pub(crate) fn guides(&self, scene: &Scene) -> bool {
        self.estimator == Estimator::Nee
            && self
                .environment_guide
                .unwrap_or_else(|| Self::guide_repays(&scene.render))
    }

    /// Sets the paper's estimator: [`Estimator::Plain`], [`Sampler::Independent`], no Russian
    /// roulette, no environment guide (what the kernels do by default, and what `bench`
    /// compares with the paper).
    pub fn paper_estimator(&mut self) -> &mut Self {
        self.estimator = Estimator::Plain;
        self.sampler = Sampler::Independent;
        self.russian_roulette = None;
        self.environment_guide = Some(false);
        self
    }

    /// Calls `f` after every batch.
    pub fn on_progress(&mut self, f: impl FnMut(Progress) + Send + 'static) -> &mut Self {
        self.progress = Some(Box::new(f));
        self
    }

    /// Calls `f` once per render, after the backend is chosen and before the BVH is built and
    /// the first batch traced, with what the render will do: [`RenderStats`] with the backend,
    /// adapter, size, spp, bounces, batch size, estimator, sampler, roulette, reorder policy
    /// (`auto` until it has run), light list and warnings filled in (timings and counts still
    /// 0). The `render` command prints its settings line and warnings from it.
    pub fn on_start(&mut self, f: impl FnMut(&RenderStats) + Send + 'static) -> &mut Self {
        self.on_start = Some(Box::new(f));
        self
    }

    /// Frees what the tracer keeps between renders: the GPU work buffers and ray sorters
    /// (grown to the largest render seen at the current image size: up to a few GiB for
    /// 1000x1000 at 20 samples per batch), the cached BVHs and the scenes prepared and
    /// uploaded over them (`RenderStats::scene_cached`). The next render allocates, builds
    /// and uploads them again; `auto`'s decisions, the pipelines and the GPU context are kept.
    pub fn release_memory(&mut self) {
        self.gpu_workspace = None;
        self.bvh_cache.clear();
    }

    /// Drops the GPU context and everything made on it (the pipelines, work buffers, scenes
    /// uploaded and trees built there, the BVH builder's kernels): a lost device stays lost,
    /// so the next render starts over on a new one; a context handed in
    /// ([`Tracer::with_gpu_context`]) replaces it the same way.
    fn forget_device(&mut self) {
        for entry in &mut self.bvh_cache {
            entry.prepared.forget_gpu();
        }
        // Trees kept on the lost device are gone with it.
        self.bvh_cache.retain(|e| !e.key.on_gpu);
        self.lbvh = None;
        self.opening = None;
        self.pipelines_ahead = None;
        self.gpu = None;
        self.gpu_bloom = None;
        self.gpu_workspace = None;
        self.gpu_pipelines.clear();
    }

    /// Where in the cache the tree of `key` is: that tree, or, when the preset was chosen (not
    /// set) and the tree is built on the CPU, the same geometry's Quality tree if that is
    /// cached: it traces at least as fast, for nothing. (A cached Fast tree is not taken for a
    /// Fastest choice: the two are close.)
    fn cached_tree(&self, key: &GeometryKey) -> Option<usize> {
        let better =
            (self.bvh_quality.is_none() && key.quality != BvhQuality::Quality && !key.on_gpu)
                .then_some(GeometryKey {
                    quality: BvhQuality::Quality,
                    ..*key
                });
        self.bvh_cache
            .iter()
            .position(|c| c.key == *key || Some(c.key) == better)
    }

    /// The BVH a render of `scene` builds (preset, layout, and whether on the GPU): on the
    /// CPU (`gpu` None) or on a GPU (`Some(hardware)`: whether a hardware adapter, which
    /// sets the rays' rate and may build on the GPU, [`Tracer::bvh_builder`]).
    fn bvh_plan(&self, scene: &Scene, gpu: Option<bool>) -> (BvhQuality, BvhLayout, bool) {
        let rate = match gpu {
            Some(true) => GPU_RAYS_PER_SECOND,
            _ => CPU_RAYS_PER_SECOND_PER_THREAD * rayon::current_num_threads() as f64,
        };
        let rays = self.estimated_rays(&scene.render, scene.render.spp);
        let quality = self.bvh_quality.unwrap_or_else(|| {
            BvhQuality::for_work(
                scene.triangles.len() + scene.spheres.len(),
                rays,
                rate,
                bvh_build_threads(),
            )
        });
        match self.builds_on_gpu(gpu, scene, quality, rays, rate) {
            true => (BvhQuality::Fastest, BvhLayout::Binary, true),
            false => (quality, self.bvh_layout, false),
        }
    }

    /// [`Tracer::walk_stage`] for `scene`: as set, else by its primitive count.
    fn walk_stage_for(&self, scene: &Scene) -> bool {
        self.walk_stage.unwrap_or_else(|| {
            scene.triangles.len() + scene.spheres.len() >= WALK_STAGE_MIN_PRIMITIVES
        })
    }

    /// The GPU schedule a render of `scene` over a tree of `layout` runs (before the reorder
    /// policy): [`Tracer::schedule`] as set, else `default_schedule`'s choice, the walk stage
    /// running where [`Tracer::walk_stage_for`] asks for it over the wide tree on an adapter
    /// with `subgroups`.
    fn schedule_for(&self, scene: &Scene, layout: BvhLayout, subgroups: bool) -> Schedule {
        self.schedule.unwrap_or_else(|| {
            let r = scene.render;
            let spp = self
                .samples
                .map_or(r.spp, |s| s.end.saturating_sub(s.begin));
            default_schedule(
                self.walk_stage_for(scene) && layout == BvhLayout::Wide && subgroups,
                self.estimator,
                u64::from(r.width) * u64::from(r.height) * u64::from(spp),
                self.wavefront_min_samples,
            )
        })
    }

    /// The pipelines a GPU render of `scene` over a tree of `layout`, starting with
    /// `schedule`, compiles.
    fn pipeline_request(
        &self,
        scene: &Scene,
        layout: BvhLayout,
        schedule: Schedule,
    ) -> PipelineRequest {
        PipelineRequest {
            features: self
                .specialisation
                .features(raylume_scene::Features::from_bits(
                    scene.features().bits() | self.extra_features.bits(),
                )),
            layout,
            specialisation: self.specialisation,
            schedule,
            variant: PathVariant::of(self.estimator, self.sampler)
                .with_next_event_stage(self.next_event_stage)
                .with_walk_stage(self.walk_stage_for(scene))
                .with_shadow_stage(self.shadow_stage),
            guides: self.guides(scene),
        }
    }

    /// Whether a render's BVH is built on the GPU ([`Tracer::bvh_builder`]), the render on
    /// the CPU (`gpu` None) or on a GPU (`Some(hardware)`).
    fn builds_on_gpu(
        &self,
        gpu: Option<bool>,
        scene: &Scene,
        preset: BvhQuality,
        rays: f64,
        rate: f64,
    ) -> bool {
        let possible = gpu.is_some() && scene.spheres.is_empty() && scene.triangles.len() >= 2;
        match self.bvh_builder {
            BvhBuilder::Cpu => false,
            _ if !possible => false,
            BvhBuilder::Gpu => true,
            BvhBuilder::Auto => {
                gpu == Some(true)
                    && self.bvh_quality.is_none_or(|q| q == BvhQuality::Fastest)
                    && BvhBuilder::gpu_repays(
                        scene.triangles.len(),
                        rays,
                        rate,
                        bvh_build_threads(),
                        preset,
                    )
            }
        }
    }

    /// The header of a part of `scene` rendered with this tracer's settings (its range: the
    /// whole render; the caller sets it).
    pub(crate) fn part_header(
        &self,
        scene: &Scene,
        r: raylume_scene::RenderSettings,
    ) -> PartHeader {
        let settings = TraceSettings {
            batch_spp: 1,
            seed: self.seed.unwrap_or(r.seed),
            ..TraceSettings::from_render(&r)
        };
        PartHeader {
            format: 1,
            scene: format!(
                "{:016x}",
                crate::auto::fingerprint(scene, &settings, "part")
            ),
            width: r.width,
            height: r.height,
            spp: r.spp,
            max_bounces: r.max_bounces,
            seed: settings.seed,
            estimator: self.estimator.name().into(),
            sampler: self.sampler.name().into(),
            russian_roulette: self.russian_roulette,
            environment_guide: self.guides(scene),
            samples: SampleRange {
                begin: 0,
                end: r.spp,
            },
        }
    }

    /// A [`Backend::Gpus`] tracer over these devices (two contexts on one adapter work too:
    /// the tests split a render between two lavapipe devices).
    pub fn with_gpu_contexts(contexts: Vec<GpuContext>) -> Self {
        let mut t = Tracer::new(Backend::Gpus);
        t.gpu_workers = contexts
            .into_iter()
            .map(|c| Tracer::new(Backend::Gpu).with_gpu_context(c))
            .collect();
        t
    }

    /// Uses an existing GPU context (and its adapter) for GPU renders.
    pub fn with_gpu_context(mut self, ctx: GpuContext) -> Self {
        self.forget_device();
        self.gpu = Some(ctx);
        // Measurements belong to an adapter.
        self.auto.clear();
        self
    }

    /// The trace settings a render of `scene` runs with (before the reorder policy).
    fn trace_settings(&self, scene: &Scene) -> TraceSettings {
        let r = scene.render;
        TraceSettings {
            width: r.width,
            height: r.height,
            spp: r.spp,
            max_bounces: r.max_bounces,
            seed: self.seed.unwrap_or(r.seed),
            batch_spp: self.batch_spp.clamp(1, r.spp.max(1)),
            // Where not set: what the CPU runs; a GPU render chooses once its tree's
            // layout and adapter are known (`Tracer::schedule_for`).
            schedule: self.schedule.unwrap_or_default(),
            reorder: Reorder::OFF,
        }
    }

    fn auto_key(&self, scene: &Scene) -> u64 {
        fingerprint(
            scene,
            &self.trace_settings(scene),
            &format!(
                "{:?} {:?} {} {} {} {:?} {} {:?}",
                self.bvh_quality,
                self.bvh_layout,
                self.reorder_key_bits,
                self.estimator.name(),
                self.sampler.name(),
                self.russian_roulette,
                self.specialisation.name(),
                self.extra_features,
            ),
        )
    }

    /// What [`ReorderPolicy::Auto`] decided for renders of `scene` with its current settings
    /// (size, bounces, samples per batch), once it has measured enough; `None` before.
    pub fn auto_decision(&self, scene: &Scene) -> Option<&AutoDecision> {
        self.auto.get(&self.auto_key(scene))?.decision()
    }

    /// Checks the scene's render settings against what a render accepts.
    pub fn check_settings(scene: &Scene) -> Result<(), Error> {
        let r = &scene.render;
        if r.width == 0 || r.height == 0 {
            return Err(Error::Settings(format!(
                "image size {}x{}: width and height must be at least 1",
                r.width, r.height
            )));
        }
        if r.width > MAX_IMAGE_SIDE
            || r.height > MAX_IMAGE_SIDE
            || u64::from(r.width) * u64::from(r.height) > MAX_IMAGE_PIXELS
        {
            return Err(Error::Settings(format!(
                "image size {}x{} is too large: at most {MAX_IMAGE_SIDE} pixels a side and \
                 {MAX_IMAGE_PIXELS} pixels in all",
                r.width, r.height
            )));
        }
        if r.spp == 0 || r.spp > MAX_SPP {
            return Err(Error::Settings(format!(
                "{} samples per pixel: use 1 to {MAX_SPP}",
                r.spp
            )));
        }
        if r.max_bounces > MAX_BOUNCES {
            return Err(Error::Settings(format!(
                "{} bounces: use 0 to {MAX_BOUNCES}",
                r.max_bounces
            )));
        }
        Ok(())
    }

    /// Opens the GPU device the backend will render on (for [`Backend::Auto`], a hardware
    /// adapter if there is one), so that its cost (0.14-0.16 s on the H200) overlaps other
    /// work, e.g. loading the scene on another thread; [`Tracer::render`] does it otherwise.
    /// Its time is reported in the next render's `seconds.device`. Errors as `render` would
    /// (e.g. [`Backend::Gpu`] without an adapter). [`Tracer::start_backend`] does the same
    /// without waiting.
    pub fn prepare_backend(&mut self) -> Result<(), Error> {
        self.choose_backend().map(|_| ())
    }

    /// Starts opening the GPU device the backend will render on ([`Backend::Gpu`], or
    /// [`Backend::Auto`]'s search for a hardware adapter) on a thread of its own, and returns
    /// at once: the caller loads the scene and builds its BVH meanwhile
    /// ([`Tracer::prepare_scene`]). The first call that needs the device
    /// ([`Tracer::render`], [`Tracer::prepare_backend`]) waits for it and reports what
    /// `prepare_backend` would have: its errors, and its time in `seconds.device`. Does
    /// nothing when a device is open or being opened, or for [`Backend::Cpu`] and
    /// [`Backend::Gpus`] (whose devices open in the render).
    pub fn start_backend(&mut self) {
        let choice = match self.backend {
            Backend::Gpu => AdapterChoice::Any,
            Backend::Auto => AdapterChoice::HardwareOnly,
            Backend::Cpu | Backend::Gpus => return,
        };
        if self.gpu.is_some() || self.opening.is_some() {
            return;
        }
        let (announce, adapter) = std::sync::mpsc::channel();
        let (request, requests) = std::sync::mpsc::channel::<PipelineRequest>();
        let (send_ready, ready) = std::sync::mpsc::channel();
        let (send_compiled, compiled) = std::sync::mpsc::channel();
        let (send_learner, learner) = std::sync::mpsc::channel();
        let timeline = self.timeline.clone();
        let thread = std::thread::spawn(move || {
            let t = Instant::now();
            let options = ContextOptions {
                choice,
                adapter_name: None,
            };
            let ctx = GpuContext::new_announcing(&options, |info| {
                let software = info.map(|i| i.device_type == wgpu::DeviceType::Cpu);
                let _ = announce.send(software);
                mark(&timeline, "device: adapter chosen");
            });
            let seconds = t.elapsed().as_secs_f64();
            let compiling = ctx.as_ref().ok().cloned();
            mark(&timeline, "device: open");
            let _ = send_ready.send((ctx, seconds));
            // The pipelines `prepare_scene` asks for, if it does before the render takes
            // the context; the render uploads its scene meanwhile.
            if let Some(c) = compiling
                && let Ok(r) = requests.recv()
            {
                let made = r.compile_announcing(&c, |l| {
                    mark(&timeline, "pipelines: guide learner made");
                    let _ = send_learner.send(l.clone());
                });
                mark(&timeline, "pipelines: compiled");
                let _ = send_compiled.send(made);
            }
        });
        self.opening = Some(Opening {
            choice,
            thread,
            ready,
            compiled,
            learner,
            asked: None,
            request: Some(request),
            adapter,
            known: None,
        });
    }

    /// Builds the BVH a render of `scene` with this tracer's current settings will use, and
    /// prepares the scene's data for tracing, before [`Tracer::render`]: while the GPU device
    /// opens ([`Tracer::start_backend`], started here if no device is open or opening), which
    /// the build does not need. On the H200 the device takes 0.14-0.16 s; the living room's
    /// load, build and preparation fit beside it where they used to follow it. The render
    /// finds both ready and reports their seconds as its own (`seconds.bvh`,
    /// `seconds.upload`; [`RenderStats::prepared_ahead`] says they were done ahead).
    ///
    /// The render's GPU pipelines are compiled on the device's thread as soon as the device
    /// is open ([`RenderStats::pipelines_ahead`]), not after the build.
    ///
    /// Waits for the device only until its adapter is chosen (a hardware GPU's rate chooses
    /// another preset than a software adapter's or the CPU's). Builds nothing for a tree the
    /// render will build on the GPU ([`BvhBuilder`]) or for [`Backend::Gpus`], and leaves a
    /// GPU render's environment guide to the GPU. Settings changed before the render (size,
    /// spp, preset, estimator, ...) may make it choose another tree or preparation: it makes
    /// its own then, and this was work for nothing, never a wrong image. Errors as `render`
    /// would on the scene (its settings, [`Scene::validate`], the build).
    pub fn prepare_scene(&mut self, scene: &Scene) -> Result<(), Error> {
        Self::check_settings(scene)?;
        scene.validate()?;
        let Some((i, gpu)) = self.prepare_tree(scene)? else {
            return Ok(());
        };
        let options = self.scene_options(scene);
        let entry = &mut self.bvh_cache[i];
        let BuiltBvh::Cpu(bvh) = &entry.bvh else {
            return Ok(());
        };
        let prepared = entry.prepared.of(SceneKey::of(scene, options));
        // Nothing to do when the data is there. A GPU render's data is prepared without its
        // environment guide, which the GPU learns after the upload (the device compiles the
        // walks meanwhile).
        let skip = prepared.ahead.is_some()
            || prepared.cpu.is_some()
            || (gpu.is_some() && prepared.gpu.is_some());
        if !skip {
            let t = Instant::now();
            let data = match gpu {
                Some(_) => SceneData::before_guide_walks(scene, bvh, &options)?,
                None => SceneData::with_options(scene, bvh, &options)?,
            };
            prepared.ahead = Some((data, t.elapsed().as_secs_f64()));
            mark(&self.timeline, "scene data prepared ahead");
        }
        Ok(())
    }

    /// The part of [`Tracer::prepare_scene`] that needs the scene's geometry, materials and
    /// settings only, not its textures' texels: the BVH the render will use (with the rough
    /// plastics' coat tables integrated beside it), and on the GPU the pipelines asked of the
    /// device's thread. What [`Scene::load_with`]'s hook calls while the scene's images still
    /// decode (the `render` example does); `prepare_scene` later finds the tree and prepares
    /// the rest. Checks the settings, not the scene (its textures may be placeholders then):
    /// the render validates it.
    pub fn prepare_geometry(&mut self, scene: &Scene) -> Result<(), Error> {
        Self::check_settings(scene)?;
        self.prepare_tree(scene).map(|_| ())
    }

    /// [`Tracer::prepare_geometry`]'s work: the tree's place in the BVH cache (built now if
    /// it was not there) and the backend expected (`expected_gpu`'s), or `None` when no tree
    /// is built on the CPU for the render (the backend unknown, or the tree built on the GPU).
    fn prepare_tree(&mut self, scene: &Scene) -> Result<Option<(usize, Option<bool>)>, Error> {
        let Some(gpu) = self.expected_gpu() else {
            return Ok(None);
        };
        let (quality, layout, on_gpu) = self.bvh_plan(scene, gpu);
        // The device's thread compiles the render's pipelines as soon as the device is open
        // (the render's own guess of its first schedule: `On` sorts, so starts wavefront).
        if gpu.is_some() {
            // An adapter still opening is taken to have subgroups (every one met so far has;
            // a wrong guess costs the render a compilation, not its image).
            let subgroups = self.gpu.as_ref().is_none_or(|c| c.has_subgroups());
            let schedule = match self.reorder {
                ReorderPolicy::On => Schedule::Wavefront,
                _ => self.schedule_for(scene, layout, subgroups),
            };
            let wanted = self.pipeline_request(scene, layout, schedule);
            if let Some(o) = self.opening.as_mut()
                && let Some(ask) = o.request.take()
                && ask.send(wanted).is_ok()
            {
                o.asked = Some(wanted);
            }
        }
        if on_gpu {
            return Ok(None);
        }
        let key = GeometryKey::of(scene, quality, layout);
        if let Some(i) = self.cached_tree(&key) {
            return Ok(Some((i, gpu)));
        }
        let t = Instant::now();
        let bvh = std::thread::scope(|threads| {
            let tables =
                threads.spawn(|| raylume_kernels::scene_data::prepare_plastic_tables(scene));
            let bvh = GpuBvh::from_scene_with_layout(scene, quality, layout);
            tables
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            bvh
        })?;
        mark(&self.timeline, "bvh: built ahead");
        self.bvh_cache.insert(
            0,
            BvhCacheEntry {
                key,
                bvh: BuiltBvh::Cpu(Arc::new(bvh)),
                prepared: Prepared::default(),
                ahead: Some(t.elapsed().as_secs_f64()),
            },
        );
        self.bvh_cache.truncate(BVH_CACHE_ENTRIES);
        Ok(Some((0, gpu)))
    }

    /// What the next render's backend will be, as far as [`Tracer::prepare_scene`] can tell
    /// without the device: `Some(None)` the CPU, `Some(Some(hardware))` a GPU (a hardware
    /// adapter or not), `None` when it cannot tell (or the render will fail). Starts opening
    /// the device if it is neither open nor opening, and waits until its adapter is chosen.
    fn expected_gpu(&mut self) -> Option<Option<bool>> {
        match self.backend {
            Backend::Cpu => return Some(None),
            Backend::Gpus => return None,
            Backend::Gpu | Backend::Auto => {}
        }
        if let Some(ctx) = &self.gpu {
            let hardware = !ctx.info.is_software;
            // `Auto` holding a software context searches for a hardware one again.
            return (self.backend == Backend::Gpu || hardware).then_some(Some(hardware));
        }
        self.start_backend();
        let software = self.opening.as_mut()?.adapter_is_software();
        match (self.backend, software) {
            (_, Some(software)) => Some(Some(!software)),
            // No adapter: `Auto` renders on the CPU, `Gpu` fails.
            (Backend::Auto, None) => Some(None),
            _ => None,
        }
    }

    /// A new GPU context of adapters `choice`: the one [`Tracer::start_backend`] is opening
    /// (waited for), or one opened now. Its time goes to `device_seconds`.
    fn new_context(&mut self, choice: AdapterChoice) -> Result<GpuContext, GpuError> {
        let (ctx, seconds) = match self.opening.take() {
            Some(mut o) if o.choice == choice => {
                // No more requests: the thread compiles what it was asked for, if anything.
                o.request = None;
                match o.ready.recv() {
                    Ok((ctx, seconds)) => {
                        if let (Ok(_), Some(request)) = (&ctx, o.asked) {
                            self.pipelines_ahead = Some(AheadPipelines {
                                request,
                                compiled: o.compiled,
                                learner: o.learner,
                                thread: o.thread,
                            });
                        }
                        (ctx, seconds)
                    }
                    // The thread ended without a context: it panicked.
                    Err(_) => {
                        o.thread
                            .join()
                            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                        let t = Instant::now();
                        let ctx = GpuContext::new(&ContextOptions {
                            choice,
                            adapter_name: None,
                        });
                        (ctx, t.elapsed().as_secs_f64())
                    }
                }
            }
            // Opened for another backend (changed since): not this one's device.
            _ => {
                let t = Instant::now();
                let ctx = GpuContext::new(&ContextOptions {
                    choice,
                    adapter_name: None,
                });
                (ctx, t.elapsed().as_secs_f64())
            }
        };
        if ctx.is_ok() {
            self.device_seconds = Some(seconds);
        }
        ctx
    }

    /// Picks the backend; returns whether it is the GPU's and why (a new context's time goes
    /// to `device_seconds`).
    fn choose_backend(&mut self) -> Result<(bool, String), Error> {
        match self.backend {
            Backend::Cpu => Ok((false, "requested".into())),
            Backend::Gpus => {
                self.open_gpu_workers()?;
                Ok((true, "requested".into()))
            }
            Backend::Gpu => {
                if self.gpu.is_none() {
                    self.gpu = Some(self.new_context(AdapterChoice::Any)?);
                }
                Ok((true, "requested".into()))
            }
            Backend::Auto => {
                if self.gpu.as_ref().is_some_and(|g| !g.info.is_software) {
                    return Ok((true, "a hardware GPU adapter was found".into()));
                }
                match self.new_context(AdapterChoice::HardwareOnly) {
                    Ok(ctx) => {
                        self.gpu = Some(ctx);
                        Ok((true, "a hardware GPU adapter was found".into()))
                    }
                    Err(GpuError::NoAdapter { tried }) => Ok((
                        false,
                        format!("no hardware GPU adapter ({tried}); using the CPU"),
                    )),
                    Err(e) => Ok((
                        false,
                        format!("the GPU could not be used ({e}); using the CPU"),
                    )),
                }
            }
        }
    }

    /// Renders `scene` with its `[render]` settings (override them on a clone of the scene).
    /// The scene is validated first ([`Scene::validate`]): one built by hand with a NaN camera,
    /// a degenerate triangle or absurd radiance is an error, not a silently wrong image.
    pub fn render(&mut self, scene: &Scene) -> Result<Render, Error> {
        let t_total = Instant::now();
        mark(&self.timeline, "render: starts");
        Self::check_settings(scene)?;
        if let Some(e) = self.target_error
            && !(e.is_finite() && e > 0.0)
        {
            return Err(Error::TargetError(e));
        }
        scene.validate()?;
        if self.backend == Backend::Gpus {
            return self.render_gpus(scene, t_total);
        }
        if let Some(range) = self.samples {
            if range.is_empty() || range.end > scene.render.spp {
                return Err(Error::Settings(format!(
                    "samples {}..{} are not a non-empty range within the render's 0..{}",
                    range.begin, range.end, scene.render.spp
                )));
            }
            if self.target_error.is_some() {
                return Err(Error::Settings(
                    "a render part (a sample range) cannot also stop at a target error".into(),
                ));
            }
        }
        let (use_gpu, reason) = self.choose_backend()?;
        let device_seconds = self.device_seconds.take().unwrap_or(0.0);
        let r = scene.render;
        let mut settings = self.trace_settings(scene);
        let hardware = self.gpu.as_ref().is_some_and(|c| !c.info.is_software);
        let (quality, layout, gpu_build) = self.bvh_plan(scene, use_gpu.then_some(hardware));
        if use_gpu {
            let subgroups = self.gpu.as_ref().is_some_and(|c| c.has_subgroups());
            settings.schedule = self.schedule_for(scene, layout, subgroups);
        }
        // What the reorder policy runs: a fixed plan (the stats line says which), or `Auto`'s
        // measurements under the scene's fingerprint.
        let mut auto_key = None;
        let reorder = match (use_gpu, self.reorder) {
            (_, ReorderPolicy::Off) => "off".to_string(),
            (false, p) => format!(
                "off: the CPU backend never reorders rays, as in the paper ({} requested)",
                if p == ReorderPolicy::On { "on" } else { "auto" }
            ),
            (true, ReorderPolicy::On) => {
                if self.reorder_mode == ReorderMode::Off {
                    return Err(Error::Settings(
                        "reorder on needs a sorting mode (sort-index or sort-permute), not off"
                            .into(),
                    ));
                }
                settings.schedule = Schedule::Wavefront;
                settings.reorder =
                    Reorder::every_bounce(self.reorder_mode).with_key_bits(self.reorder_key_bits);
                let plan = BatchPlan::of(&settings);
                let mut line = format!("on: {}", plan.describe(r.max_bounces));
                if !plan.sorts(r.max_bounces) {
                    line += " (no bounce to sort)";
                }
                if let Some(s) = self.schedule.filter(|&s| s != Schedule::Wavefront) {
                    line += &format!(
                        "; the {} schedule cannot sort, so the wavefront ran",
                        s.name()
                    );
                }
                line
            }
            (true, ReorderPolicy::Auto) => {
                auto_key = Some(self.auto_key(scene));
                "auto".to_string() // the decision is filled in after the render
            }
        };
        let mut stats = RenderStats {
            backend: if use_gpu { "gpu" } else { "cpu" }.into(),
            backend_reason: reason,
            width: r.width,
            height: r.height,
            spp: r.spp,
            max_bounces: r.max_bounces,
            batch_spp: settings.batch_spp,
            seed: settings.seed,
            triangles: scene.triangles.len(),
            spheres: scene.spheres.len(),
            features: scene.features().names(),
            schedule: settings.schedule.name().into(),
            estimator: self.estimator.name().into(),
            sampler: self.sampler.name().into(),
            russian_roulette: self.russian_roulette,
            reorder,
            adapter: match (use_gpu, self.gpu.as_ref()) {
                (true, Some(ctx)) => ctx.describe(),
                _ => format!("CPU, {} threads", rayon::current_num_threads()),
            },
            lights: crate::LightStats::of(scene),
            warnings: scene.warnings.clone(),
            ..Default::default()
        };
        if stats.lights.is_empty() {
            stats
                .warnings
                .push(crate::stats::NO_LIGHT_WARNING.to_string());
        }
        stats.seconds.device = device_seconds;
        stats.bvh_preset = quality.name().into();
        stats.bvh_preset_chosen = self.bvh_quality.is_none();
        stats.bvh_layout = layout.name().into();
        if let Some(f) = self.on_start.as_mut() {
            f(&stats);
        }

        let t = Instant::now();
        let mut key = GeometryKey {
            on_gpu: gpu_build,
            ..GeometryKey::of(scene, quality, layout)
        };
        let cached = self.cached_tree(&key).map(|i| self.bvh_cache.remove(i));
        if let Some(c) = &cached {
            key = c.key;
            stats.bvh_preset = c.key.quality.name().into();
        }
        // A tree `prepare_scene` built for this render is this render's build, not a cache hit.
        let ahead = cached.as_ref().and_then(|c| c.ahead);
        stats.bvh_cached = cached.is_some() && ahead.is_none();
        stats.prepared_ahead = ahead.is_some();
        // On the GPU, the pipelines (a second of driver compilation on the H200) do not depend
        // on the BVH: they are compiled on another thread while it is built, or come from the
        // last render of a scene with the same features and layout.
        let first_schedule = if settings.reorder.sorts_any(settings.max_bounces) {
            Schedule::Wavefront
        } else {
            settings.schedule
        };
        let request = self.pipeline_request(scene, layout, first_schedule);
        let pipeline_features = request.features;
        if use_gpu {
            stats.pipeline_features = pipeline_features.names();
            stats.specialisation = self.specialisation.name().into();
        }
        let pipeline_key = (pipeline_features, layout, self.specialisation);
        let reuse = self
            .gpu_pipelines
            .iter()
            .find(|p| (p.features(), p.bvh_layout(), p.specialisation()) == pipeline_key)
            .cloned();
        // Compiling on the opening's thread: waited for after the upload (`trace_gpu`).
        let compiling_ahead = match (&reuse, &self.pipelines_ahead) {
            (None, Some(a)) if use_gpu && a.request.key() == pipeline_key => {
                self.pipelines_ahead.take()
            }
            _ => None,
        };
        let gpu = self.gpu.as_ref().filter(|_| use_gpu);
        let mut prepared = Prepared::default();
        let (bvh, pipelines) = std::thread::scope(|threads| {
            let compiling = match (gpu, &reuse, &compiling_ahead) {
                (Some(ctx), None, None) => Some(threads.spawn(move || request.compile(ctx))),
                _ => None,
            };
            // The rough plastics' coat tables need the materials only: integrated beside the
            // build (which leaves cores idle in its serial passes), kept for the preparation.
            let tables = cached.is_none().then(|| {
                threads.spawn(|| raylume_kernels::scene_data::prepare_plastic_tables(scene))
            });
            let bvh = match (cached, gpu) {
                (Some(c), _) => {
                    prepared = c.prepared;
                    Ok((c.bvh, None))
                }
                (None, Some(ctx)) if gpu_build => build_on_gpu(ctx, &mut self.lbvh, scene),
                (None, _) => GpuBvh::from_scene_with_layout(scene, quality, layout)
                    .map(|b| (BuiltBvh::Cpu(Arc::new(b)), None))
                    .map_err(Error::from),
            };
            if let Some(handle) = tables {
                handle
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            }
            stats.seconds.bvh = t.elapsed().as_secs_f64() + ahead.unwrap_or(0.0);
            let pipelines = match compiling {
                Some(handle) => Some(
                    handle
                        .join()
                        .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
                ),
                None => reuse.map(Ok),
            };
            (bvh, pipelines)
        });
        mark(&self.timeline, "render: bvh in hand");
        let (bvh, builder_note) = match bvh {
            Ok(b) => b,
            Err(e) => {
                if e.is_device_lost() {
                    self.forget_device();
                }
                return Err(e);
            }
        };
        let pipelines = match pipelines.transpose() {
            Ok(p) => p,
            Err(e) => {
                let e = Error::from(e);
                if e.is_device_lost() {
                    self.forget_device();
                }
                return Err(e);
            }
        };
        if let Some(p) = &pipelines {
            adopt_pipelines(&mut self.gpu_pipelines, p, false, &mut stats);
        }
        let pipelines = match (pipelines, compiling_ahead) {
            (Some(p), _) => Some(RenderPipelines::Ready(p)),
            (None, Some(a)) => Some(RenderPipelines::Ahead(a)),
            (None, None) => None,
        };
        stats.bvh_nodes = bvh.node_count();
        stats.bvh_builder = match (&bvh, builder_note) {
            (_, Some(note)) => note,
            (BuiltBvh::Gpu(r), None) => format!(
                "LBVH on the GPU ({:.3} s there), {} levels",
                r.gpu_seconds(),
                r.max_depth()
            ),
            (BuiltBvh::Cpu(_), None) => format!(
                "{} on the CPU, {} threads",
                match quality {
                    BvhQuality::Fastest => "LBVH",
                    _ => "obvhs PLOC",
                },
                rayon::current_num_threads()
            ),
        };

        let mut progress = self.progress.take();
        let t_trace = Instant::now();
        let mut report = |done: u32, total: u32| {
            if let Some(p) = progress.as_mut() {
                p(Progress {
                    done_spp: done,
                    total_spp: total,
                    elapsed: t_trace.elapsed(),
                });
            }
        };
        let bloom = if self.bloom && self.samples.is_none() {
            scene.post.bloom.map(|b| raylume_post::BloomParams {
                threshold: b.threshold,
                radius: b.radius,
                strength: b.strength,
            })
        } else {
            None
        };
        let mut target = self
            .target_error
            .map(|e| TargetRun::new(e, (r.width * r.height) as usize));
        let result = if use_gpu {
            self.trace_gpu(
                scene,
                &bvh,
                &mut prepared,
                pipelines.expect("made with the GPU backend"),
                &settings,
                auto_key,
                bloom,
                target.as_mut(),
                &mut stats,
                &mut report,
            )
        } else {
            let BuiltBvh::Cpu(cpu_bvh) = &bvh else {
                return Err(Error::Settings(
                    "internal: a tree kept on the GPU was handed to a CPU render".into(),
                ));
            };
            self.trace_cpu(
                scene,
                cpu_bvh,
                &mut prepared,
                &settings,
                bloom,
                target.as_mut(),
                &mut stats,
                &mut report,
            )
        };
        self.progress = progress;
        self.bvh_cache.insert(
            0,
            BvhCacheEntry {
                key,
                bvh,
                prepared,
                ahead: None,
            },
        );
        self.bvh_cache.truncate(BVH_CACHE_ENTRIES);
        if result.as_ref().is_err_and(Error::is_device_lost) {
            self.forget_device();
        }
        let pixels = result?;
        if let Some(t) = &target {
            stats.target_error = Some(t.target);
            stats.estimated_error = t.estimate;
            stats.target_reached = Some(t.reached);
            stats.batches = Some(t.rounds);
            stats.spp_cap = Some(r.spp);
            stats.spp = t.spp_done;
        }
        stats.seconds.total = t_total.elapsed().as_secs_f64();
        if stats.seconds.trace > 0.0 {
            stats.mrays_per_s = stats.rays_traced as f64 / stats.seconds.trace / 1e6;
        }
        mark(&self.timeline, "render: ends");
        if let Some(t) = &self.timeline {
            stats.timeline = t.marks();
        }
        Ok(self.make_render(scene, pixels, stats))
    }

    /// The [`Render`] of `scene` with these pixels and stats, with a part's header when this
    /// tracer renders a part ([`Tracer::samples`]).
    pub(crate) fn make_render(
        &self,
        scene: &Scene,
        pixels: Vec<[f32; 3]>,
        mut stats: RenderStats,
    ) -> Render {
        let r = scene.render;
        stats.samples = self.samples;
        Render {
            width: r.width,
            height: r.height,
            pixels,
            stats,
            tone: self.tone,
            part: self.samples.map(|samples| PartHeader {
                samples,
                ..self.part_header(scene, r)
            }),
        }
    }

    /// Traces on the GPU (with `Auto`'s policy under `auto_key`, if given), runs bloom on the
    /// image while it is still there, reads it back.
    #[allow(clippy::too_many_arguments)]
    fn trace_gpu(
        &mut self,
        scene: &Scene,
        bvh: &BuiltBvh,
        prepared: &mut Prepared,
        pipelines: RenderPipelines,
        settings: &TraceSettings,
        auto_key: Option<u64>,
        bloom: Option<raylume_post::BloomParams>,
        target: Option<&mut TargetRun>,
        stats: &mut RenderStats,
        report: &mut dyn FnMut(u32, u32),
    ) -> Result<Vec<[f32; 3]>, Error> {
        let ctx = self.gpu.as_ref().expect("the backend choice created it");
        stats.adapter = ctx.describe();
        let t = Instant::now();
        let options = self.scene_options(scene);
        let prepared = prepared.of(SceneKey::of(scene, options));
        // Whether the scene was prepared (and its guide learned) by this render.
        let mut fresh = false;
        let mut pipelines = Some(pipelines);
        let mut ready = None;
        let uploaded = match (&prepared.gpu, &prepared.cpu, bvh) {
            (Some(g), _, _) => {
                stats.scene_cached = true;
                g.clone()
            }
            // Prepared by `prepare_scene` before the device was open: uploaded now (moved),
            // while the device may still compile the environment guide's walks, which then
            // run and write the guide's distributions after the rest.
            (None, _, BuiltBvh::Cpu(bvh)) if prepared.ahead.is_some() => {
                let (data, seconds) = prepared.ahead.take().expect("matched");
                stats.prepared_ahead = true;
                stats.seconds.upload += seconds;
                let pending = GpuScene::upload_before_guide(
                    ctx,
                    raylume_kernels::tracer_features(scene),
                    bvh,
                    data,
                )?;
                let learner = match pending.pending_guide() {
                    Some(_) => {
                        mark(&self.timeline, "upload: all but the guide");
                        fresh = true;
                        Some(guide_learner(
                            &mut pipelines,
                            &mut ready,
                            ctx,
                            &mut self.gpu_pipelines,
                            stats,
                            &self.timeline,
                        )?)
                    }
                    None => None,
                };
                Arc::new(pending.finish(ctx, scene, bvh, learner.as_deref())?)
            }
            // The CPU's preparation of the same scene (an earlier CPU render), uploaded.
            (None, Some(data), BuiltBvh::Cpu(bvh)) => Arc::new(GpuScene::upload_data(
                ctx,
                raylume_kernels::tracer_features(scene),
                bvh,
                SceneData::clone(data),
            )?),
            // The environment guide's walks on the GPU, by the pipelines' learner (compiled
            // beside the BVH when the render guides).
            (None, _, bvh) => {
                fresh = true;
                let learner = match options.environment_guide {
                    // The learner as soon as it is made: the walks run while the tracer's
                    // pipelines may still compile on the opening's thread.
                    true => Some(guide_learner(
                        &mut pipelines,
                        &mut ready,
                        ctx,
                        &mut self.gpu_pipelines,
                        stats,
                        &self.timeline,
                    )?),
                    false => None,
                };
                Arc::new(match bvh {
                    BuiltBvh::Cpu(bvh) => GpuScene::upload_with_learner(
                        ctx,
                        scene,
                        bvh,
                        &options,
                        learner.as_deref(),
                    )?,
                    BuiltBvh::Gpu(bvh) => {
                        GpuScene::upload_resident(ctx, scene, bvh, &options, learner.as_deref())?
                    }
                })
            }
        };
        mark(&self.timeline, "upload: done");
        if fresh {
            stats.seconds.guide = uploaded.data().environment_guide_seconds;
        }
        let uploaded_bytes = uploaded.texel_bytes();
        prepared.gpu = Some(uploaded.clone());
        // Pipelines still compiling on the opening's thread were given the upload's time.
        let pipelines = match (ready, pipelines) {
            (Some(p), _) => p,
            (None, Some(p)) => resolve_pipelines(p, ctx, &mut self.gpu_pipelines, stats)?,
            (None, None) => unreachable!("taken only with `ready` set"),
        };
        mark(&self.timeline, "render: pipelines in hand");
        let mut tracer = GpuTracer::with_scene(ctx, uploaded, pipelines)?;
        tracer.set_next_event_stage(self.next_event_stage);
        tracer.set_walk_stage(self.walk_stage_for(scene));
        tracer.set_shadow_stage(self.shadow_stage);
        tracer.set_estimator(self.estimator);
        tracer.set_sampler(self.sampler);
        let guides = self.guides(scene);
        tracer.set_environment_guide(guides);
        stats.environment_guide = self.describe_guide(guides, tracer.environment_guide_walks());
        stats.textures = self.describe_textures(scene);
        stats.texel_bytes = uploaded_bytes;
        tracer.set_russian_roulette(self.russian_roulette);
        tracer.set_sample_range(self.samples.map(|r| r.begin..r.end));
        if let Some(workspace) = self.gpu_workspace.take() {
            tracer.use_workspace(workspace);
        }
        stats.seconds.upload += t.elapsed().as_secs_f64();
        let mut on_round = target.map(|t| move |r: &RoundSums<'_>| t.on_round(r));
        let hook = on_round.as_mut().map(|f| f as &mut RoundHook<'_>);
        let out = match (auto_key, hook) {
            (None, None) => tracer.render_to_buffer(settings, report)?,
            (None, Some(hook)) => tracer.render_to_buffer_with_hook(settings, report, hook)?,
            (Some(key), hook) => {
                let (off_schedule, bits) = (settings.schedule, self.reorder_key_bits);
                let state = self
                    .auto
                    .entry(key)
                    .or_insert_with(|| AutoState::new(off_schedule, settings.max_bounces, bits));
                let mut policy = AutoPolicy::new(state);
                let out =
                    tracer.render_with_policy_and_hook(settings, &mut policy, report, hook)?;
                stats.reorder = state.describe();
                out
            }
        };
        mark(&self.timeline, "render: traced");
        stats.schedule = schedules_run(&out);
        if out.timings.iter().any(|&(stage, _)| stage == "next_event") {
            stats.schedule += " + next_event stage";
        }
        if out.timings.iter().any(|&(stage, _)| stage == "trace_hits") {
            stats.schedule += " + walk stage";
        }
        if out
            .timings
            .iter()
            .any(|&(stage, _)| stage == "trace_shadows")
        {
            stats.schedule += " + shadow stage";
        }
        stats.take_trace(out.rays_traced, out.dropped_samples, &out.timings);
        stats.depth_seconds = out
            .depths
            .iter()
            .map(|d| DepthSeconds {
                depth: d.depth,
                propagate: d.propagate,
                next_event: d.next_event,
                sort: d.sort,
                permute: d.permute,
            })
            .collect();
        let image = tracer
            .image_buffer()
            .expect("render_to_buffer leaves the image on the GPU");
        let t = Instant::now();
        if let Some(params) = bloom {
            if self.gpu_bloom.is_none() {
                self.gpu_bloom = Some(raylume_post::GpuBloom::new(ctx)?);
            }
            let gpu_bloom = self.gpu_bloom.as_ref().expect("created above");
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("bloom"),
                });
            let mut ts = raylume_gpu::Timestamps::new(ctx, raylume_post::BLOOM_STAGES.len() as u32);
            gpu_bloom.encode(
                ctx,
                &mut enc,
                image,
                settings.width,
                settings.height,
                params,
                ts.as_mut(),
            )?;
            if let Some(ts) = &ts {
                ts.resolve(&mut enc);
            }
            ctx.scoped("bloom", || ctx.queue.submit([enc.finish()]))?;
            ctx.wait("bloom")?;
            if let Some(ts) = ts.as_mut() {
                for (stage, secs) in ts.read(ctx)? {
                    stats.kernel_seconds.push((stage.to_string(), secs));
                }
            }
            if !params.is_identity() {
                stats.post_passes.extend(raylume_post::BLOOM_STAGES);
            }
        }
        stats.seconds.post = t.elapsed().as_secs_f64();
        let pixels = (settings.width * settings.height) as usize;
        let pixels = ctx.read_buffer::<[f32; 3]>(image, pixels)?;
        mark(&self.timeline, "render: image read back");
        self.gpu_workspace = Some(tracer.take_workspace());
        Ok(pixels)
    }

    /// Traces on the CPU and runs bloom there.
    #[allow(clippy::too_many_arguments)]
    fn trace_cpu(
        &self,
        scene: &Scene,
        bvh: &Arc<GpuBvh>,
        prepared: &mut Prepared,
        settings: &TraceSettings,
        bloom: Option<raylume_post::BloomParams>,
        target: Option<&mut TargetRun>,
        stats: &mut RenderStats,
        report: &mut dyn FnMut(u32, u32),
    ) -> Result<Vec<[f32; 3]>, Error> {
        let t = Instant::now();
        let path_samples = u64::from(settings.width * settings.height) * u64::from(settings.spp);
        // The tree's walk arrays in huge pages where this render repays them, decided before
        // the environment guide's learning walks below would make them in ordinary pages (the
        // first CPU walk of a tree decides; `tracer.prepare` decides again with the records
        // counted, and copies those).
        let tree_bytes = bvh.cpu_walk_bytes() + std::mem::size_of_val(bvh.primitives.as_slice());
        if bvh.layout == raylume_bvh::BvhLayout::Wide
            && self
                .cpu_huge_pages
                .unwrap_or_else(|| raylume_kernels::cpu::huge_pages_repay(tree_bytes, path_samples))
        {
            bvh.prepare_cpu_walks(true);
        }
        let options = self.scene_options(scene);
        let prepared = prepared.of(SceneKey::of(scene, options));
        let data = match (&prepared.cpu, prepared.ahead.take()) {
            (Some(d), _) => {
                stats.scene_cached = true;
                d.clone()
            }
            // Prepared by `prepare_scene` (for a GPU render that became a CPU one: its guide,
            // left to the GPU, is learned here).
            (None, Some((mut d, seconds))) => {
                stats.prepared_ahead = true;
                stats.seconds.upload += seconds;
                d.learn_pending_guide(scene, bvh)?;
                Arc::new(d)
            }
            (None, None) => Arc::new(SceneData::with_options(scene, bvh, &options)?),
        };
        if !stats.scene_cached {
            stats.seconds.guide = data.environment_guide_seconds;
        }
        prepared.cpu = Some(data.clone());
        // The tree and the data are shared, not copied (hundreds of MB for a large scene).
        let mut tracer = CpuTracer::with_shared(bvh.clone(), data.clone())?;
        tracer.set_specialisation(self.specialisation, self.extra_features);
        let isa = tracer.set_isa(self.cpu_isa);
        tracer.set_packets(self.cpu_packets);
        tracer.set_pairs(self.cpu_pairs);
        tracer.set_huge_pages(self.cpu_huge_pages);
        // The walks' arrays (before `walks_flat` below asks for them) and, for a long render
        // of a large scene, the records' copy in huge pages: part of the upload.
        let huge = tracer.prepare(path_samples);
        stats.adapter = format!("{}, {}", stats.adapter, isa.name());
        if tracer.packets() {
            stats.adapter += ", packets";
        }
        if tracer.pairs() {
            stats.adapter += ", paths in pairs";
        }
        if huge {
            stats.adapter += ", records in huge pages";
        }
        if tracer.walks_flat() {
            stats.adapter += ", flat tree";
        }
        stats.specialisation = self.specialisation.name().into();
        stats.pipeline_features = tracer.variant_features().names();
        stats.seconds.upload += t.elapsed().as_secs_f64();
        mark(&self.timeline, "upload: done");
        tracer.set_estimator(self.estimator);
        tracer.set_sampler(self.sampler);
        let guides = self.guides(scene);
        tracer.set_environment_guide(guides);
        stats.environment_guide = self.describe_guide(guides, tracer.environment_guide_walks());
        stats.textures = self.describe_textures(scene);
        stats.texel_bytes = 4 * data.texels.len() as u64;
        tracer.set_russian_roulette(self.russian_roulette);
        tracer.set_sample_range(self.samples.map(|r| r.begin..r.end));
        let out = match target {
            None => tracer.render(settings, report)?,
            Some(t) => tracer.render_with_hook(settings, report, &mut |r| t.on_round(r))?,
        };
        mark(&self.timeline, "render: traced");
        stats.take_trace(out.rays_traced, out.dropped_samples, &out.timings);
        let mut pixels = out.radiance;
        let t = Instant::now();
        if let Some(params) = bloom {
            raylume_post::bloom_cpu(&mut pixels, settings.width, settings.height, params)?;
            if !params.is_identity() {
                stats.post_passes.extend(raylume_post::BLOOM_STAGES);
            }
        }
        stats.seconds.post = t.elapsed().as_secs_f64();
        Ok(pixels)
    }
}

/// The schedule the batches ran: one name, or those `Auto` tried in this render joined by
/// ` + ` (`megakernel + wavefront (auto trials)`); `megakernel` when no batch ran (the CPU
/// runs none through these plans).
fn schedules_run(out: &TraceStats) -> String {
    let ran: Vec<&str> = Schedule::ALL
        .into_iter()
        .filter(|&s| out.batches.iter().any(|b| b.plan.schedule == s))
        .map(Schedule::name)
        .collect();
    match ran.as_slice() {
        [] => "megakernel".into(),
        [one] => (*one).into(),
        many => format!("{} (auto trials)", many.join(" + ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `default_schedule` turns to the wavefront only with all three: the walk stage, NEE and
    /// at least `min_samples` pixel samples (the GPU test of the same rule needs an adapter
    /// with subgroups; this one runs everywhere).
    #[test]
    fn the_default_schedule_needs_the_walk_stage_nee_and_the_samples() {
        let (nee, plain) = (Estimator::Nee, Estimator::Plain);
        let min = WAVEFRONT_MIN_SAMPLES;
        assert_eq!(default_schedule(true, nee, min, min), Schedule::Wavefront);
        assert_eq!(
            default_schedule(true, nee, u64::MAX, min),
            Schedule::Wavefront
        );
        assert_eq!(
            default_schedule(true, nee, min - 1, min),
            Schedule::Persistent
        );
        assert_eq!(default_schedule(false, nee, min, min), Schedule::Persistent);
        assert_eq!(
            default_schedule(true, plain, min, min),
            Schedule::Persistent
        );
        // The living room at 100 spp on the H200's Table 1 size turns; its 10-spp first image
        // (1280x720) does not.
        assert_eq!(
            default_schedule(true, nee, 1000 * 1000 * 100, min),
            Schedule::Wavefront
        );
        assert_eq!(
            default_schedule(true, nee, 1280 * 720 * 10, min),
            Schedule::Persistent
        );
    }
}
