//! What a render reports about itself (also the `--stats` JSON of the `render` example).

use glam::Vec3;
use raylume_scene::{Environment, Scene};
use rayon::prelude::*;
use serde::Serialize;

/// Seconds per phase. `trace` is the paper's "ray tracing phase": ray generation,
/// propagation and accumulation, without loading, BVH building or uploading; on a GPU it comes
/// from GPU timestamps when the adapter has them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StageSeconds {
    /// Reading and validating the scene (filled by whoever loaded it, e.g. the `render` example).
    pub load: f64,
    /// Building and flattening the BVH, and meanwhile integrating the rough plastics' coat
    /// tables (when the BVH was not cached).
    pub bvh: f64,
    /// Creating the GPU device (0 on the CPU, and when an earlier render already reported it;
    /// see `Tracer::prepare_backend`).
    pub device: f64,
    /// Preparing the scene's data for tracing (materials, textures, lights, coat tables, the
    /// environment guide) and, on the GPU, uploading it; near 0 when the tracer kept it from
    /// its last render of the same scene (`RenderStats::scene_cached`).
    pub upload: f64,
    /// Of `upload`: the environment guide's walks, as long as the preparation waited for them
    /// (on the CPU, all of them; on the GPU they run while the CPU prepares the rest of the
    /// scene, and this is what was left); 0 when no guide was learned or the preparation was
    /// kept from an earlier render.
    pub guide: f64,
    /// Preparing the batch loop on the GPU: work buffers, pipelines not compiled yet (see
    /// `pipelines`), ray sorters, warm-up dispatches (0 on the CPU).
    pub prepare: f64,
    /// Making the shader module and compiling the GPU pipelines the render started with, on a
    /// thread of its own while the BVH was built (so it overlaps `bvh`); when the tracer
    /// reused the last render's pipelines (`RenderStats::pipelines_cached`), what they took
    /// then. 0 on the CPU.
    pub pipelines: f64,
    /// The ray-tracing phase.
    pub trace: f64,
    /// Ray sorting: the `sort_keys` passes (included in `trace`; 0 when no batch sorted).
    /// Moving ray states into key order (`sort-permute`) is `permute_rays` in
    /// [`RenderStats::kernel_seconds`].
    pub sort: f64,
    /// Post effects (bloom) and tone mapping for the output.
    pub post: f64,
    /// Writing the image file (filled by whoever saved it, e.g. the `render` example).
    pub save: f64,
    /// Wall clock from the start of `Tracer::render` to its end; the `render` example makes
    /// it its own wall clock from loading the scene to the written file (loading and opening
    /// the GPU device overlap there, so the parts add up to more).
    pub total: f64,
}

/// Statistics of one render.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RenderStats {
    /// `"gpu"` or `"cpu"`.
    pub backend: String,
    /// The adapter (`"NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu)"`) or the CPU and the
    /// instruction-set level its paths ran at (`"CPU, 16 threads, x86-64-v4"`: [`crate::CpuIsa`]).
    pub adapter: String,
    /// Why this backend was chosen (for `Auto`).
    pub backend_reason: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel traced: the scene's, or with a target error where the render stopped.
    pub spp: u32,
    /// With a target error: the scene's `spp`, the most the render could trace.
    pub spp_cap: Option<u32>,
    /// The target relative MSE ([`crate::Tracer::target_error`]), if one was set.
    pub target_error: Option<f32>,
    /// With a target error: the relative MSE estimated from the batches' spread after the last
    /// batch traced; `None` when fewer than 2 batches were traced (no estimate exists).
    pub estimated_error: Option<f64>,
    /// With a target error: true when the render stopped because the estimate fell below the
    /// target, false when it reached the cap (`spp_cap`) first.
    pub target_reached: Option<bool>,
    /// With a target error: the batches traced, each `batch_spp` samples of every pixel (the
    /// last may hold fewer; an image too large for one batch splits each into pixel ranges,
    /// counted once): the number of batch means the estimate used.
    pub batches: Option<u32>,
    /// Bounces after the camera ray.
    pub max_bounces: u32,
    /// Samples per pixel per batch, after fitting the adapter.
    pub batch_spp: u32,
    /// The seed the random numbers were drawn with.
    pub seed: u32,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Spheres in the scene.
    pub spheres: usize,
    /// The scene's features (what the kernels were specialised on).
    pub features: Vec<&'static str>,
    /// The features the code that traced was compiled for (`Tracer::specialisation`): on the
    /// GPU the pipelines' (the scene's, or every one for the generic baseline); on the CPU
    /// the mirror's variant (`raylume_kernels::cpu::variant`: the smallest of its sixteen that
    /// holds the scene's features, or every one).
    pub pipeline_features: Vec<&'static str>,
    /// `Backend::Gpus`: what each device did (its adapter, samples, seconds, rays).
    pub workers: Vec<crate::WorkerStats>,
    /// For a render part (`Tracer::samples`), the samples of every pixel it traced.
    pub samples: Option<crate::SampleRange>,
    /// How the code that traced was specialised: `"composed"`, `"overrides"` or `"generic"`
    /// (on the CPU the first two run the same variant).
    pub specialisation: String,
    /// `megakernel`, `persistent` or `wavefront` (e.g. `megakernel + wavefront (auto
    /// trials)` when `--reorder auto` measured several in this render).
    pub schedule: String,
    /// `plain` (the paper's estimator) or `nee` (next-event estimation with MIS).
    pub estimator: String,
    /// `independent` (the paper's `pcg4d` numbers), `sobol` or `zsobol` (scrambled Sobol'
    /// points; `Sampler`).
    pub sampler: String,
    /// The segment from which Russian roulette may end a path; `None` (JSON `null`): off.
    pub russian_roulette: Option<u32>,
    /// How next-event estimation sampled the environment (`Tracer::environment_guide`):
    /// `guided (E escapes from W walks)`, `by radiance (guide off)`, `by radiance (too few
    /// escapes ...)`, `no guide (no environment or no geometry)` or `unused (plain
    /// estimator)`.
    pub environment_guide: String,
    /// How 8-bit textures were held (`Tracer::decode_textures`): `8-bit sRGB codes`,
    /// `decoded to floats`, each with why when the tracer chose (`... (the render's rays
    /// repay it)`, `... (decoding would not repay)`), `floats` (no 8-bit texture) or `none`.
    pub textures: String,
    /// Bytes of the texel buffer the render read (`SceneData::texels`: textures, the 8-bit
    /// decoding table, an environment map and its distributions, the environment guide's):
    /// how much `textures`' choice holds (0 for `Backend::Gpus`, which does not report it).
    pub texel_bytes: u64,
    /// The reorder policy and what it ran: `off`, `on: wavefront, sort-index before depths
    /// 1..=10`, `auto: <the plan> (fastest measured per N-ray batch: ...)`, `auto: still
    /// measuring (...)`, or why it did not run (the CPU backend).
    pub reorder: String,
    /// Rays cast (every closest-hit traversal, camera rays included; next-event estimation's
    /// shadow rays are not counted).
    pub rays_traced: u64,
    /// Samples dropped because their radiance was not finite, or so large that summing them
    /// could overflow (`raylume_kernels::math::MAX_SAMPLE_RADIANCE`).
    pub dropped_samples: u64,
    /// Seconds per phase.
    pub seconds: StageSeconds,
    /// Millions of rays per second over the `trace` phase.
    pub mrays_per_s: f64,
    /// Finer per-kernel timings (`raygen`, `propagate`, `trace_paths`, `resolve`, ...).
    pub kernel_seconds: Vec<(String, f64)>,
    /// BVH nodes (of the tree's layout: two or up to eight children each).
    pub bvh_nodes: usize,
    /// True when the BVH came from the tracer's cache (the same geometry as the last render:
    /// `seconds.bvh` is then the time to recognise it).
    pub bvh_cached: bool,
    /// True when the scene's preparation for tracing (materials, textures, lights, coat
    /// tables, the environment guide) and, on the GPU, its upload came from the tracer's last
    /// render of the same scene over the same BVH (`seconds.upload` is then the time to
    /// recognise it and bind it).
    pub scene_cached: bool,
    /// True when [`crate::Tracer::prepare_scene`] built this render's BVH (and, where it
    /// could, prepared its scene data) before the render, e.g. while the GPU device opened:
    /// `seconds.bvh` and `seconds.upload` then include that work, done ahead.
    pub prepared_ahead: bool,
    /// The BVH preset the tree was built with (`"fastest"`, `"fast"` or `"quality"`:
    /// `Tracer::bvh_quality`;
    /// for a cached tree, the preset it was built with).
    pub bvh_preset: String,
    /// True when the preset was chosen for this render from the work ahead
    /// (`Tracer::bvh_quality` left `None`), false when it was set.
    pub bvh_preset_chosen: bool,
    /// The BVH's node layout (`"binary"` or `"wide"`: `Tracer::bvh_layout`).
    pub bvh_layout: String,
    /// True when the GPU pipelines came from the tracer's last render (same features and BVH
    /// layout): nothing was compiled.
    pub pipelines_cached: bool,
    /// True when the GPU pipelines were compiled for this render on the device's own thread
    /// as soon as it opened ([`crate::Tracer::prepare_scene`] asked for them), beside the
    /// scene's load and BVH build; `seconds.pipelines` is then what that took.
    pub pipelines_ahead: bool,
    /// With `pipelines_ahead`: the seconds the render waited for them after uploading its
    /// scene, which it did while they compiled (0 when they were done first).
    pub pipelines_wait: f64,
    /// Who built it: `"obvhs PLOC on the CPU, N threads"` (a cached tree: who built it then).
    pub bvh_builder: String,
    /// The post-processing passes that ran, in order (`bloom_threshold`, `bloom_h`, ...).
    /// Empty when the scene calls for no post effect: then none is scheduled at all.
    pub post_passes: Vec<&'static str>,
    /// Per bounce depth of the wavefront batches (empty for the megakernel and the CPU).
    pub depth_seconds: Vec<DepthSeconds>,
    /// The emitters next-event estimation samples ([`LightStats::of`]).
    pub lights: LightStats,
    /// What the scene's loaders approximated or dropped ([`Scene::warnings`]), then what the
    /// render itself warns of: a scene that nothing can light ([`LightStats::is_empty`]: no
    /// emissive triangle or sphere and a black environment, so the image is black and
    /// next-event estimation has no light to sample). The `render` command prints each with
    /// `warning:` before the first batch.
    pub warnings: Vec<String>,
    /// The milestones of [`crate::Tracer::timeline`] up to the render's end (empty without
    /// one): seconds from the timeline's origin, from every thread the render ran.
    pub timeline: Vec<crate::TimelineMark>,
}

/// The light list of a scene: what emits, and so what next-event estimation
/// ([`crate::Estimator::Nee`]) samples. An emitter is picked with probability proportional to
/// its power (area times emitted luminance; for the environment, its mean luminance over a
/// disc of the scene's bounding radius, as pbrt-v4 estimates it).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LightStats {
    /// Triangles whose material emits (emission luminance above 0).
    pub triangles: usize,
    /// Spheres whose material emits.
    pub spheres: usize,
    /// Whether the environment emits: a constant of luminance above 0, or a map with a texel
    /// of luminance above 0 and a strength above 0 (not [`Environment::Black`]).
    pub environment: bool,
    /// How an emitter is chosen for a shadow ray: `"power"`.
    pub selection: &'static str,
}

/// Rec. 709 luminance weights (the kernels' `LUMINANCE`).
const LUMINANCE: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

impl LightStats {
    /// Counts the emitters of `scene` as the kernels' light list does.
    pub fn of(scene: &Scene) -> Self {
        let emits = |m: u32| {
            scene
                .materials
                .get(m as usize)
                .is_some_and(|m| m.emission.dot(LUMINANCE) > 0.0)
        };
        let environment = match &scene.environment {
            Environment::Black => false,
            Environment::Constant(c) => c.dot(LUMINANCE) > 0.0,
            Environment::Map {
                image, strength, ..
            } => {
                *strength > 0.0
                    && (0..image.texels.len())
                        .any(|i| Vec3::from(image.texels.linear(i)).dot(LUMINANCE) > 0.0)
            }
        };
        Self {
            triangles: scene
                .triangles
                .par_iter()
                .filter(|t| emits(t.material) && t.double_area() > 0.0)
                .count(),
            spheres: scene
                .spheres
                .iter()
                .filter(|s| emits(s.material) && s.radius > 0.0)
                .count(),
            environment,
            selection: "power",
        }
    }

    /// True when nothing emits: every render of the scene is black.
    pub fn is_empty(&self) -> bool {
        self.triangles == 0 && self.spheres == 0 && !self.environment
    }

    /// `2 emissive triangles, 0 emissive spheres, no environment (picked by power)`, or
    /// `none`.
    pub fn describe(&self) -> String {
        if self.is_empty() {
            return "none".into();
        }
        format!(
            "{} emissive triangle{}, {} emissive sphere{}, {} (picked by {})",
            self.triangles,
            if self.triangles == 1 { "" } else { "s" },
            self.spheres,
            if self.spheres == 1 { "" } else { "s" },
            if self.environment {
                "the environment"
            } else {
                "no environment"
            },
            self.selection
        )
    }
}

/// The warning for a scene that nothing lights (see [`RenderStats::warnings`]).
pub const NO_LIGHT_WARNING: &str = "the scene cannot be lit: no emissive triangle or sphere \
     and a black environment, so the image will be black (and next-event estimation has no \
     light to sample); give a material an `emission` or add an `[environment]`";

/// Seconds spent on one bounce depth, summed over a render's wavefront batches (GPU
/// timestamps where the adapter has them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct DepthSeconds {
    /// The segment traced (0: camera rays).
    pub depth: u32,
    /// `propagate` at this depth.
    pub propagate: f64,
    /// `next_event` at this depth: the light samples `propagate` left (renders that sample
    /// lights).
    pub next_event: f64,
    /// Sorting the rays before this depth (`sort_keys`).
    pub sort: f64,
    /// Moving their states into key order (`permute_rays`, `sort-permute` only).
    pub permute: f64,
}

impl RenderStats {
    /// Takes the tracer's counts and per-stage timings.
    pub(crate) fn take_trace(&mut self, rays: u64, dropped: u64, timings: &[(&'static str, f64)]) {
        self.rays_traced = rays;
        self.dropped_samples = dropped;
        for (name, secs) in timings {
            match *name {
                "trace" => self.seconds.trace = *secs,
                "prepare" => self.seconds.prepare = *secs,
                "sort" => self.seconds.sort = *secs,
                _ => {}
            }
            self.kernel_seconds.push((name.to_string(), *secs));
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}
