//! raylume-kernels: the tracer. WGSL compute kernels run through wgpu, and their CPU mirror:
//! the same functions, with the same names, in Rust, run with rayon.
//!
//! # What it implements
//! - The paper's ray-tracing phase (*Parallelising Ray Tracing on GPUs*, "Ray tracing phase"):
//!   batches of `batch_spp` samples per pixel, ray generation, ray propagation (BVH traversal,
//!   intersection and shading in one kernel), accumulation. Accumulation sums each pixel's
//!   samples in a fixed order in a `resolve` kernel instead of float atomics, so results are
//!   reproducible.
//! - Two GPU schedules over the same per-segment functions ([`Schedule`]): the paper's
//!   **wavefront** (`raygen`, then `propagate` once per bounce over a compacted queue of live
//!   rays, each writing the ray's sort key for a later reordering pass) and a **megakernel**
//!   (`trace_paths`: one thread per pixel sample, the path in registers).
//! - Materials: Lambertian diffuse (cosine sampling); and after Mitsuba 3's plugins ([`bsdf`]):
//!   conductors with complex IORs (perfect mirror, or GGX with Heitz's visible-normal
//!   sampling, "Sampling the GGX Distribution of Visible Normals", JCGT 2018), dielectrics
//!   (exact Fresnel, refraction, total internal reflection; smooth or GGX, Walter et al.
//!   2007) and plastics (a diffuse base under a smooth or rough dielectric coat). Emission on
//!   every material (front faces unless two-sided), constant or equirectangular-map
//!   environments, albedo textures, shading normals, analytic spheres ([`surface`]).
//! - Random numbers: pcg4d (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020)
//!   keyed by (seed, pixel, sample, bounce, dimension) ([`rng`]): the CPU and the GPU, and both
//!   schedules, trace the same paths.
//! - Ray origins: pushed off the surface by a bound on the hit point's rounding error and on
//!   that of re-finding the same primitive (after PBRT 4th ed. §6.8, Pharr, Jakob &
//!   Humphreys), relative to the primitive's coordinates, so images do not change with the
//!   scene's scale or distance from the origin ([`surface::hit_offset`]).
//! - Pipelines specialised on the scene's [`raylume_scene::Features`] through WGSL `override`
//!   constants ([`gpu::pipeline_constants`]).
//! - The BVH built on the GPU, the paper's future work ([`gpu::LbvhBuilder`]): Karras' linear
//!   BVH in WGSL over raylume-sort's radix sort, node for node the CPU reference
//!   `raylume_bvh::lbvh::lbvh_binary`, kept on the GPU ([`gpu::ResidentBvh`],
//!   [`gpu::GpuScene::upload_resident`]); `benches/gpu_build.rs` times it against the CPU's
//!   build (on the H200, 75 ms against ~380 ms for 3M triangles).
//!
//! # Measured
//! `benches/trace.rs`, Cornell box (36 triangles, BVH from raylume-bvh), 1000x1000, 100 spp,
//! 10 bounces, 581 M rays, on an H100 (wgpu 30, Vulkan, 2026-11-23): megakernel 0.23 s of GPU
//! time (0.24 s wall), wavefront 0.20-0.23 s (its compaction keeps warps full as paths end);
//! the bar set for this crate was 0.6 s. Workgroups of 64 beat 128 (1-2 %) and 256 (6-7 %).
//! Brute force over the 36 triangles instead of the BVH was slower (0.40 s).
//!
//! # Reordering
//! The paper's ray sorting ("Ray sorting": 30-bit origin-direction Morton keys, a radix sort
//! between bounces), in the wavefront only ([`Reorder`], [`ReorderMode`]): `propagate` writes
//! each live ray's key beside its slot in the compacted queue of the next bounce; raylume-sort's
//! `RadixSorter` (made once per [`GpuTracer`], for the largest batch) sorts those
//! (key, ray index) pairs in the same command encoder, reading the live count the GPU
//! computed (`SortLen::Indirect`), so only live rays are sorted and every dispatch stays
//! indirect. Then either `propagate` reads the states through the sorted index
//! ([`ReorderMode::SortIndex`]) or `permute_rays` first gathers them into key order
//! ([`ReorderMode::SortPermute`]). A bit mask picks the depths that sort; a [`BatchPolicy`]
//! may pick the schedule and reordering per batch from the measured cost of earlier batches
//! ([`GpuTracer::render_with_policy`]), which is how `raylume`'s `--reorder auto` decides.
//! Sorting changes only which thread traces which ray, never a ray's arithmetic or random
//! numbers, so the image is bit-identical with and without it.
//!
//! # Where to start reading
//! [`shade::trace_ray`] is one path segment, called by both schedules; `gpu/megakernel.wgsl`
//! and `gpu/wavefront.wgsl` are the two schedules; [`cpu::stages`] mirrors their entry points.
//!
//! ```no_run
//! use raylume_kernels::{CpuTracer, TraceSettings};
//! # fn scene_and_bvh() -> (raylume_scene::Scene, raylume_bvh::GpuBvh) { unimplemented!() }
//! let (scene, bvh) = scene_and_bvh();
//! let mut tracer = CpuTracer::new(&scene, &bvh)?;
//! let out = tracer.render(&TraceSettings::from_render(&scene.render), &mut |done, total| {
//!     eprintln!("{done}/{total} spp");
//! })?;
//! println!("{} rays", out.rays_traced);
//! # Ok::<(), raylume_kernels::KernelError>(())
//! ```
//!
//! **Architecture invariant:** the per-segment functions (`trace_ray`, `shade_hit`,
//! `sample_*`, `surface_at`, ...) know nothing of the schedule; only `cpu/` and `gpu/` do.
//! This crate never sorts rays (raylume-sort does) and never post-processes (raylume-post).

pub mod batches;
pub mod bsdf;
pub mod camera;
pub mod cpu;
pub mod env_guide;
mod error;
pub mod gpu;
pub mod gpu_types;
pub mod math;
pub mod rng;
pub mod sampling;
pub mod scene_data;
pub mod shade;
pub mod sobol;
pub mod surface;

pub use cpu::CpuTracer;
pub use cpu::isa::CpuIsa;
pub use error::KernelError;
pub use gpu::{
    BatchPlan, BatchPolicy, BatchTiming, DepthTiming, GpuScene, GpuTracer, GpuWorkspace,
    PendingScene, SortCapture, Specialisation, StageTime, TraceStats, WavefrontBuffers,
    tracer_features,
};
pub use scene_data::SceneOptions;

use raylume_scene::RenderSettings;

/// Threads per workgroup of every 1D kernel but the megakernel (the paper used 128 threads
/// per block).
pub const WORKGROUP_SIZE: u32 = 64;

/// Threads per workgroup of the megakernel (`trace_paths`): 32. On the H200 (commit 7e3a926,
/// 100 spp, both estimators, two rounds) its trace was 0.7-3.3 % faster than at 64 on five of
/// the project's six scenes and 0-4 % slower on the smallest (four spheres, 0.02 s), while the
/// persistent schedule, which shares the module, was up to 2.6 % slower at 32 than at 64
/// (`docs/RESULTS.md`).
pub const MEGAKERNEL_WORKGROUP_SIZE: u32 = 32;

/// The workgroup size the tracer's 1D kernels are compiled and dispatched with:
/// [`WORKGROUP_SIZE`], or `RAYLUME_WORKGROUP_SIZE` (a multiple of 32 from 32 to 1024; read once
/// per process) for measuring others (`docs/RESULTS.md`).
pub fn workgroup_size() -> u32 {
    static SIZE: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *SIZE.get_or_init(|| size_from_env("RAYLUME_WORKGROUP_SIZE").unwrap_or(WORKGROUP_SIZE))
}

/// The workgroup size the megakernel is compiled and dispatched with:
/// `RAYLUME_MEGAKERNEL_WORKGROUP_SIZE` if set, else `RAYLUME_WORKGROUP_SIZE` if set (which then
/// sizes every kernel alike), else [`MEGAKERNEL_WORKGROUP_SIZE`] (the variables' rules as
/// [`workgroup_size`]'s).
pub fn megakernel_workgroup_size() -> u32 {
    static SIZE: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *SIZE.get_or_init(|| {
        size_from_env("RAYLUME_MEGAKERNEL_WORKGROUP_SIZE")
            .or_else(|| size_from_env("RAYLUME_WORKGROUP_SIZE"))
            .unwrap_or(MEGAKERNEL_WORKGROUP_SIZE)
    })
}

/// A workgroup size from environment variable `name`: a multiple of 32 from 32 to 1024.
fn size_from_env(name: &str) -> Option<u32> {
    std::env::var(name)
        .ok()
        .and_then(|v| v.trim().parse::<u32>().ok())
        .filter(|n| (32..=1024).contains(n) && n % 32 == 0)
}

/// The largest `max_bounces` accepted (the random-number key holds the bounce in 28 bits;
/// this leaves room and catches nonsense).
pub const MAX_BOUNCES_LIMIT: u32 = 1 << 16;

/// How a path's radiance is estimated (the same on both backends).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Estimator {
    /// The paper's: emission counts where a path hits it; each hit scatters one direction
    /// sampled from its material.
    #[default]
    Plain,
    /// Next-event estimation: at every diffuse, rough-metal or plastic hit, a shadow ray to a
    /// point on an emissive triangle or sphere or the sky (chosen by power; on a
    /// sphere, in the cone of its visible cap) adds that light's direct contribution, weighted
    /// by multiple importance sampling against the emission the next scattered ray may hit.
    /// The environment too: a constant sky uniformly over directions, a map by its luminance.
    /// Unbiased; far less noise where small emitters light diffuse surfaces.
    Nee,
}

/// Where a path's random numbers come from (the same numbers on both backends).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Sampler {
    /// Independent uniform numbers: the `pcg4d` hash of (seed, pixel, sample, bounce,
    /// dimension), [`rng::rand4`].
    #[default]
    Independent,
    /// ZSobol (Ahmed & Wonka 2020, pbrt-v4's default): Owen-scrambled Sobol' points, each
    /// pixel's samples a (0, 2)-net per pair of dimensions and neighbouring pixels' errors
    /// blue noise, [`sobol::sobol4`]. Less error per sample on smooth integrands.
    ZSobol,
    /// ZSobol with Burley's hash shuffle of the indices in place of its 16 digit
    /// permutations ([`sobol::shuffled_sobol4`]): the same nets in every pixel, so the same
    /// error per sample, at a fraction of the arithmetic (the living room's NEE trace on the
    /// H200: ZSobol 1.34x slower than independent numbers); weaker blue noise across pixels.
    Sobol,
}

impl Sampler {
    pub fn name(self) -> &'static str {
        match self {
            Sampler::Independent => "independent",
            Sampler::ZSobol => "zsobol",
            Sampler::Sobol => "sobol",
        }
    }

    /// The value of `SceneUniforms::sampler`.
    pub fn uniform(self) -> u32 {
        match self {
            Sampler::Independent => gpu_types::SAMPLER_INDEPENDENT,
            Sampler::ZSobol => gpu_types::SAMPLER_ZSOBOL,
            Sampler::Sobol => gpu_types::SAMPLER_SOBOL,
        }
    }
}

impl std::str::FromStr for Sampler {
    type Err = String;

    /// `independent`, `zsobol` or `sobol`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "independent" => Ok(Sampler::Independent),
            "zsobol" => Ok(Sampler::ZSobol),
            "sobol" => Ok(Sampler::Sobol),
            _ => Err(format!(
                "unknown sampler `{s}`: use independent, zsobol or sobol"
            )),
        }
    }
}

impl Estimator {
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Plain => "plain",
            Estimator::Nee => "nee",
        }
    }
}

impl std::str::FromStr for Estimator {
    type Err = String;

    /// `plain` or `nee`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "plain" => Ok(Estimator::Plain),
            "nee" => Ok(Estimator::Nee),
            _ => Err(format!("unknown estimator `{s}`: use plain or nee")),
        }
    }
}

/// How the GPU (and the CPU mirror) organises the work of a batch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Schedule {
    /// `trace_paths`: one thread per pixel sample, all bounces in registers.
    Megakernel,
    /// The paper's: `raygen`, then one `propagate` launch per bounce over the live rays.
    Wavefront,
    /// `trace_paths_persistent`: the megakernel with path regeneration. At most
    /// [`PERSISTENT_THREADS`] threads take pixel samples from a counter one bounce at a time,
    /// so a thread whose path ended starts the next sample while the other lanes of its warp
    /// trace on. The same paths and image as [`Schedule::Megakernel`] (the CPU mirror runs
    /// both alike). The default: on the H200 it traced every project scene 7-31 % faster
    /// than the megakernel, NEE or plain, at 10, 100 and 1,000 spp (`docs/RESULTS.md`); on a
    /// software adapter it runs one sample a thread (the megakernel's work, in scanlines).
    #[default]
    Persistent,
}

/// Threads the persistent schedule launches at most: more than an H200 keeps resident (132
/// multiprocessors x 2048), fewer than the samples of a large batch. The environment variable
/// `RAYLUME_PERSISTENT_THREADS` overrides it on hardware adapters (for measuring).
pub const PERSISTENT_THREADS: u32 = 1 << 20;

/// Workgroups the wavefront's walk stage ([`gpu::PathVariant::walk_stage`]) launches at most
/// on a hardware adapter: its threads walk the bounce's queue, each taking the next ray when
/// its own is done, so about as many as stay resident suffice (4096 x 64 threads: ~2,000 a
/// multiprocessor on the H200: 4096 traced the living room 0.5-1 % faster than 2048, 22 %
/// faster than 1024, as fast as 8192). A software adapter gets a thread per ray (its loop limit, see
/// [`PERSISTENT_THREADS`]). `RAYLUME_WALK_STAGE_GROUPS` overrides it on hardware adapters
/// (for measuring).
pub const WALK_STAGE_GROUPS: u32 = 4096;

/// The walk stage refills the idle lanes of a subgroup (32 on NVIDIA) once this many wait for
/// a ray, or all of them do: one atomic per refill, while the others walk on (measured on the
/// H200, `docs/RESULTS.md`). `RAYLUME_WALK_STAGE_REFILL` overrides it (for measuring).
pub const WALK_STAGE_REFILL: u32 = 8;

/// On a software adapter a lane of the walk stage (and of the shadow stage) takes at most this
/// many times its even share of the queue (the queue's rays over the stage's threads: one ray
/// with the thread per ray a software adapter gets), so that its loops stay short: llvmpipe
/// (lavapipe) leaves every loop of an invocation once they have run 65,535 iterations between
/// them (`LP_MAX_TGSI_LOOP_ITERATIONS`), and runs a workgroup's subgroups one after another,
/// so that without a bound the first subgroups took most of a large queue in turn and were cut
/// off with rays taken and not walked (the living room at 240x135, 1 spp: 5-25 hits of a
/// bounce missing and the image different from run to run, before 2026-12-04). Hardware
/// adapters have no such limit: there a lane takes rays as long as the queue has them.
pub const WALK_STAGE_SOFTWARE_SHARE: u32 = 4;

/// The word of the wavefront's queue counts that counts the walk stage's queue slots taken
/// (words 0 and 1 are the two queues' lengths, 3 the persistent schedule's sample counter).
pub const WALK_STAGE_COUNTER: u32 = 2;

/// The word of the wavefront's queue counts that counts a bounce's shadow rays left by
/// `propagate` to the shadow stage ([`gpu::PathVariant::shadow_stage`]).
pub const SHADOW_QUEUE_COUNTER: u32 = 4;

/// The word of the wavefront's queue counts that counts the shadow stage's slots taken.
pub const SHADOW_STAGE_COUNTER: u32 = 5;

/// Words (of 16 bytes) of a shadow stage record in `nee_records` (a structure of arrays by
/// shadow queue slot, as the `next_event` stage's records): the ray (origin, `t_max`; direction,
/// the path's ray index), the throughput at the vertex and the record's state, the light's
/// term, the vertex's emission. The emission's word is written and read only where the
/// emission is not zero ([`SHADOW_HAS_EMISSION`]), the light's only where the ray is not
/// blocked: most vertices emit nothing, and about half of the living room's shadow rays are
/// blocked.
pub const SHADOW_RECORD_WORDS: u32 = 5;

/// Set in a shadow record's state word (beside `NEE_PENDING` or `NEE_ENDED`) when the
/// vertex's emission is not zero, bit for bit, and so was written to the record's last word;
/// without it the shadow stage adds a zero emission, as `trace_ray` adds the zero it holds.
pub const SHADOW_HAS_EMISSION: u32 = 0x8000_0000;

/// [`WALK_STAGE_GROUPS`], or `RAYLUME_WALK_STAGE_GROUPS` when set to a positive number (read
/// once per process).
pub fn walk_stage_groups() -> u32 {
    static GROUPS: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *GROUPS
        .get_or_init(|| positive_from_env("RAYLUME_WALK_STAGE_GROUPS").unwrap_or(WALK_STAGE_GROUPS))
}

/// [`WALK_STAGE_REFILL`], or `RAYLUME_WALK_STAGE_REFILL` when set to a positive number (read
/// once per process).
pub fn walk_stage_refill() -> u32 {
    static REFILL: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *REFILL
        .get_or_init(|| positive_from_env("RAYLUME_WALK_STAGE_REFILL").unwrap_or(WALK_STAGE_REFILL))
}

/// The first bounce the wavefront's walk stage walks ([`gpu::PathVariant::walk_stage`]): 0,
/// every bounce whose queue is not sorted, the camera rays' among them. The environment
/// variable `RAYLUME_WALK_STAGE_FROM` overrides it on every adapter (for measuring: the bounces
/// before it are walked by `propagate`, one ray a thread; the images do not change).
pub const WALK_STAGE_FROM: u32 = 0;

/// [`WALK_STAGE_FROM`], or `RAYLUME_WALK_STAGE_FROM` when set to a number (read once per
/// process).
pub fn walk_stage_from() -> u32 {
    static FROM: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *FROM.get_or_init(|| {
        std::env::var("RAYLUME_WALK_STAGE_FROM")
            .ok()
            .and_then(|v| v.parse::<u32>().ok())
            .unwrap_or(WALK_STAGE_FROM)
    })
}

fn positive_from_env(name: &str) -> Option<u32> {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse::<u32>().ok())
        .filter(|&v| v > 0)
}

impl Schedule {
    /// Lower-case name for logs and stats.
    pub const fn name(self) -> &'static str {
        match self {
            Schedule::Megakernel => "megakernel",
            Schedule::Wavefront => "wavefront",
            Schedule::Persistent => "persistent",
        }
    }

    /// Every schedule, for benchmarks and tests.
    pub const ALL: [Schedule; 3] = [
        Schedule::Megakernel,
        Schedule::Wavefront,
        Schedule::Persistent,
    ];
}

impl std::str::FromStr for Schedule {
    type Err = String;

    /// `megakernel`, `wavefront` or `persistent`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "megakernel" => Ok(Schedule::Megakernel),
            "wavefront" => Ok(Schedule::Wavefront),
            "persistent" => Ok(Schedule::Persistent),
            _ => Err(format!(
                "unknown schedule `{s}`: use megakernel, wavefront or persistent"
            )),
        }
    }
}

/// How the wavefront reorders rays before a bounce (GPU only; the CPU never sorts, as in the
/// paper). After `propagate` the live rays of the next queue are sorted by their 30-bit
/// origin-direction Morton key (raylume-sort's `ray_sort_key`, `RadixSorter`); then either
/// the queue alone is in key order ([`ReorderMode::SortIndex`]) or the ray states are moved
/// into key order too ([`ReorderMode::SortPermute`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ReorderMode {
    /// No sorting: each bounce reads the live rays in the order compaction appended them.
    #[default]
    Off,
    /// Sort (key, ray index); `propagate` reads each ray's state through the sorted index
    /// (a gather of 64-byte states, scattered writes back).
    SortIndex,
    /// Sort (key, ray index), then the `permute_rays` kernel gathers the states into key order
    /// in a second state buffer, so that `propagate` reads and writes them contiguously
    /// (one more read and write of the live states per sorted bounce, and twice the memory).
    SortPermute,
}

impl ReorderMode {
    /// Lower-case name for logs and stats: `off`, `sort-index`, `sort-permute`.
    pub const fn name(self) -> &'static str {
        match self {
            ReorderMode::Off => "off",
            ReorderMode::SortIndex => "sort-index",
            ReorderMode::SortPermute => "sort-permute",
        }
    }
}

/// Which bounces of the wavefront read their rays in sort-key order, and how.
///
/// Bit `d` of `depths` (for `d` in `1..=63`) sorts the rays before segment `d` is traced,
/// i.e. between `propagate` at depth `d - 1` and at depth `d`; bit 63 also stands for every
/// depth above 63. Bit 0 is ignored: camera rays come from `raygen` in pixel order, already
/// coherent, and have no keys yet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Reorder {
    pub mode: ReorderMode,
    pub depths: u64,
    /// The top bits of the paper's 30-bit key that are sorted, 1..=30 (default 30, the whole
    /// key: four 8-bit radix passes). Fewer bits sort more coarsely and more cheaply, the
    /// paper's "much cheaper approximate sort": 16 bits (the origin's 15-bit Morton code and
    /// the top bit of the direction's) take two passes, 24 three.
    pub key_bits: u32,
}

impl Default for Reorder {
    fn default() -> Self {
        Self::OFF
    }
}

impl Reorder {
    /// No sorting.
    pub const OFF: Reorder = Reorder {
        mode: ReorderMode::Off,
        depths: 0,
        key_bits: raylume_sort::RAY_KEY_BITS,
    };

    /// Sorting before every bounce after the camera rays (depths 1 and up), by the whole key.
    pub const fn every_bounce(mode: ReorderMode) -> Self {
        Self {
            mode,
            depths: !1,
            key_bits: raylume_sort::RAY_KEY_BITS,
        }
    }

    /// This reordering sorting by the top `key_bits` bits of the key only.
    pub const fn with_key_bits(mut self, key_bits: u32) -> Self {
        self.key_bits = key_bits;
        self
    }

    /// Sorting before depths `first` and up (`first` at least 1; above 63 it counts as 63).
    pub const fn from_depth(mode: ReorderMode, first: u32) -> Self {
        let first = if first < 1 {
            1
        } else if first > 63 {
            63
        } else {
            first
        };
        Self {
            mode,
            depths: !0u64 << first,
            key_bits: raylume_sort::RAY_KEY_BITS,
        }
    }

    /// True when the rays of segment `depth` are sorted before it is traced.
    pub const fn sorts_before(&self, depth: u32) -> bool {
        let bit = if depth > 63 { 63 } else { depth };
        !matches!(self.mode, ReorderMode::Off) && depth >= 1 && (self.depths >> bit) & 1 == 1
    }

    /// True when some depth in `1..=max_bounces` is sorted.
    pub fn sorts_any(&self, max_bounces: u32) -> bool {
        (1..=max_bounces.min(64)).any(|d| self.sorts_before(d))
    }

    /// The depths in `1..=max_bounces` that are sorted, as ranges: `"2..=10"`, `"1, 3..=5"`,
    /// or `"none"`.
    pub fn depth_ranges(&self, max_bounces: u32) -> String {
        let mut parts = Vec::new();
        let mut d = 1;
        while d <= max_bounces {
            if self.sorts_before(d) {
                let start = d;
                while d < max_bounces && self.sorts_before(d + 1) {
                    d += 1;
                }
                parts.push(if start == d {
                    format!("{d}")
                } else {
                    format!("{start}..={d}")
                });
            }
            d += 1;
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(", ")
        }
    }

    /// `"off"`, or e.g. `"sort-index before depths 1..=10"` (`"sort-index/16 before ..."`
    /// when sorting 16 of the key's 30 bits) for a render of `max_bounces`.
    pub fn describe(&self, max_bounces: u32) -> String {
        if self.sorts_any(max_bounces) {
            let bits = if self.key_bits == raylume_sort::RAY_KEY_BITS {
                String::new()
            } else {
                format!("/{}", self.key_bits)
            };
            format!(
                "{}{bits} before depths {}",
                self.mode.name(),
                self.depth_ranges(max_bounces)
            )
        } else {
            "off".into()
        }
    }
}

/// What to render. `Copy`; build it from the scene's [`RenderSettings`] with
/// [`TraceSettings::from_render`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel, at least 1.
    pub spp: u32,
    /// Bounces after the camera ray (at most [`MAX_BOUNCES_LIMIT`]).
    pub max_bounces: u32,
    pub seed: u32,
    /// Samples per pixel per batch (the paper: 20); reduced automatically to fit the adapter.
    pub batch_spp: u32,
    pub schedule: Schedule,
    /// Ray sorting between bounces; anything but [`Reorder::OFF`] needs
    /// [`Schedule::Wavefront`] (the megakernel keeps each path in registers), and the CPU
    /// ignores it.
    pub reorder: Reorder,
}

impl TraceSettings {
    /// The paper's batch size.
    pub const DEFAULT_BATCH_SPP: u32 = 20;

    /// The scene's render settings with the default batch size and schedule.
    pub const fn from_render(r: &RenderSettings) -> Self {
        Self {
            width: r.width,
            height: r.height,
            spp: r.spp,
            max_bounces: r.max_bounces,
            seed: r.seed,
            batch_spp: Self::DEFAULT_BATCH_SPP,
            schedule: Schedule::Megakernel,
            reorder: Reorder::OFF,
        }
    }

    /// Fails with [`KernelError::InvalidSettings`] naming what is out of range.
    pub fn validate(&self) -> Result<(), KernelError> {
        let bad = |m: String| Err(KernelError::InvalidSettings(m));
        if self.width == 0 || self.height == 0 {
            return bad(format!(
                "the image is {}x{}; both sides must be at least 1",
                self.width, self.height
            ));
        }
        if u64::from(self.width) * u64::from(self.height) * 3 > u64::from(u32::MAX) {
            return bad(format!(
                "the image is {}x{}; at most {} pixels are supported",
                self.width,
                self.height,
                u32::MAX / 3
            ));
        }
        if self.spp == 0 {
            return bad("spp is 0; at least one sample per pixel is needed".into());
        }
        if self.batch_spp == 0 {
            return bad("batch_spp is 0; at least one sample per batch is needed".into());
        }
        if self.max_bounces > MAX_BOUNCES_LIMIT {
            return bad(format!(
                "max_bounces is {}; at most {MAX_BOUNCES_LIMIT} is supported",
                self.max_bounces
            ));
        }
        if !(1..=raylume_sort::RAY_KEY_BITS).contains(&self.reorder.key_bits) {
            return bad(format!(
                "reordering by {} key bits; use 1 to {}",
                self.reorder.key_bits,
                raylume_sort::RAY_KEY_BITS
            ));
        }
        if self.schedule != Schedule::Wavefront && self.reorder.sorts_any(self.max_bounces) {
            return bad(format!(
                "reordering ({}) needs the wavefront schedule: the {} keeps each path in \
                 registers and cannot sort rays",
                self.reorder.describe(self.max_bounces),
                self.schedule.name()
            ));
        }
        Ok(())
    }
}

impl Default for TraceSettings {
    fn default() -> Self {
        Self::from_render(&RenderSettings::default())
    }
}

/// A finished render.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceOutput {
    /// Mean linear radiance per pixel, row-major, top row first.
    pub radiance: Vec<[f32; 3]>,
    /// `trace_closest` calls (camera rays and every bounce).
    pub rays_traced: u64,
    /// Samples whose radiance was not finite or above [`math::MAX_SAMPLE_RADIANCE`] (so bright
    /// that summing them could overflow): written as zero and counted here.
    pub dropped_samples: u64,
    /// Seconds per stage: "upload", "prepare" (GPU: work buffers, pipelines compiled on first
    /// use, ray sorters, one warm-up dispatch each; before the batch loop), then "raygen" +
    /// "propagate" (wavefront, with "sort" for
    /// the `sort_keys` passes and "permute_rays" when rays were reordered) or "trace_paths"
    /// (megakernel), "resolve", and "trace", the whole batch loop (the paper's ray-tracing
    /// phase without the upload). GPU stages come from timestamps when the adapter has them.
    pub timings: Vec<(&'static str, f64)>,
}

impl TraceOutput {
    /// The time recorded for `stage`, if any.
    pub fn timing(&self, stage: &str) -> Option<f64> {
        self.timings
            .iter()
            .find(|(s, _)| *s == stage)
            .map(|(_, t)| *t)
    }
}
