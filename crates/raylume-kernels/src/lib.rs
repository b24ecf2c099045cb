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
//! - Materials: Lambertian diffuse (cosine sampling), metal (perfect mirror, or GGX with
//!   Heitz's visible-normal sampling, "Sampling the GGX Distribution of Visible Normals",
//!   JCGT 2018), glass (exact dielectric Fresnel, refraction, total internal reflection); see
//!   [`sampling`]. Emission on every material, constant or equirectangular-map environments,
//!   albedo textures, shading normals, analytic spheres ([`surface`]).
//! - Random numbers: pcg4d (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020)
//!   keyed by (seed, pixel, sample, bounce, dimension) ([`rng`]): the CPU and the GPU, and both
//!   schedules, trace the same paths.
//! - Ray origins: pushed off the surface by a bound on the hit point's rounding error and on
//!   that of re-finding the same primitive (after PBRT 4th ed. §6.8, Pharr, Jakob &
//!   Humphreys), relative to the primitive's coordinates, so images do not change with the
//!   scene's scale or distance from the origin ([`surface::hit_offset`]).
//! - Pipelines specialised on the scene's [`raylume_scene::Features`] through WGSL `override`
//!   constants ([`gpu::pipeline_constants`]).
//!
//! # Measured
//! `benches/trace.rs`, Cornell box (36 triangles, BVH from raylume-bvh), 1000x1000, 100 spp,
//! 10 bounces, 581 M rays, on an H100 (wgpu 30, Vulkan, 2026-11-23): megakernel 0.23 s of GPU
//! time (0.24 s wall), wavefront 0.20-0.23 s (its compaction keeps warps full as paths end);
//! the bar set for this crate was 0.6 s. Workgroups of 64 beat 128 (1-2 %) and 256 (6-7 %).
//! Brute force over the 36 triangles instead of the BVH was slower (0.40 s).
//!
//! # Reordering (for the facade)
//! `propagate` writes one sort key per queue slot (raylume-sort's `ray_sort_key`, dead rays
//! `DEAD_RAY_KEY`) and also appends the live rays, compacted, to the next queue, so the
//! wavefront runs without sorting. [`WavefrontBuffers`] documents how a sorter plugs in
//! between two `propagate` launches.
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
pub mod camera;
pub mod cpu;
mod error;
pub mod gpu;
pub mod gpu_types;
pub mod math;
pub mod rng;
pub mod sampling;
pub mod scene_data;
pub mod shade;
pub mod surface;

pub use cpu::CpuTracer;
pub use error::KernelError;
pub use gpu::{GpuTracer, TraceStats, WavefrontBuffers};

use raylume_scene::RenderSettings;

/// Threads per workgroup of every 1D kernel (the paper used 128 threads per block).
pub const WORKGROUP_SIZE: u32 = 64;

/// The largest `max_bounces` accepted (the random-number key holds the bounce in 28 bits;
/// this leaves room and catches nonsense).
pub const MAX_BOUNCES_LIMIT: u32 = 1 << 16;

/// How the GPU (and the CPU mirror) organises the work of a batch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Schedule {
    /// `trace_paths`: one thread per pixel sample, all bounces in registers.
    #[default]
    Megakernel,
    /// The paper's: `raygen`, then one `propagate` launch per bounce over the live rays.
    Wavefront,
}

impl Schedule {
    /// Lower-case name for logs and stats.
    pub const fn name(self) -> &'static str {
        match self {
            Schedule::Megakernel => "megakernel",
            Schedule::Wavefront => "wavefront",
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
    /// Seconds per stage: "upload", then "raygen" + "propagate" (wavefront) or "trace_paths"
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
