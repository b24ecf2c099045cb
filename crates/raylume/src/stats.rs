//! What a render reports about itself (also the `--stats` JSON of the `render` example).

use serde::Serialize;

/// Seconds per phase. `trace` is the paper's "ray tracing phase": ray generation,
/// propagation and accumulation, without loading, BVH building or uploading; on a GPU it comes
/// from GPU timestamps when the adapter has them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StageSeconds {
    /// Reading and validating the scene (filled by whoever loaded it, e.g. the `render` example).
    pub load: f64,
    /// Building and flattening the BVH.
    pub bvh: f64,
    /// Creating pipelines and uploading scene data to the GPU (0 on the CPU).
    pub upload: f64,
    /// The ray-tracing phase.
    pub trace: f64,
    /// Ray sorting (included in `trace`; 0 when reordering is off).
    pub sort: f64,
    /// Post effects (bloom) and tone mapping for the output.
    pub post: f64,
    /// Wall clock from the start of `Tracer::render` (plus `load`) to its end.
    pub total: f64,
}

/// Statistics of one render.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RenderStats {
    /// `"gpu"` or `"cpu"`.
    pub backend: String,
    /// The adapter (`"NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu)"`) or the CPU (`"CPU, 16 threads"`).
    pub adapter: String,
    /// Why this backend was chosen (for `Auto`).
    pub backend_reason: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_bounces: u32,
    pub batch_spp: u32,
    pub seed: u32,
    pub triangles: usize,
    pub spheres: usize,
    /// The scene's features (what the kernels were specialised on).
    pub features: Vec<&'static str>,
    /// Wavefront or megakernel.
    pub schedule: String,
    /// Reorder policy in effect.
    pub reorder: String,
    /// Rays cast (every closest-hit traversal, camera rays included).
    pub rays_traced: u64,
    /// Samples dropped because their radiance was not finite, or so large that summing them
    /// could overflow (`raylume_kernels::math::MAX_SAMPLE_RADIANCE`).
    pub dropped_samples: u64,
    pub seconds: StageSeconds,
    /// Millions of rays per second over the `trace` phase.
    pub mrays_per_s: f64,
    /// Finer per-kernel timings (`raygen`, `propagate`, `trace_paths`, `resolve`, ...).
    pub kernel_seconds: Vec<(String, f64)>,
    /// BVH nodes.
    pub bvh_nodes: usize,
    /// The post-processing passes that ran, in order (`bloom_threshold`, `bloom_h`, ...).
    /// Empty when the scene calls for no post effect: then none is scheduled at all.
    pub post_passes: Vec<&'static str>,
}

impl RenderStats {
    /// Takes the tracer's counts and per-stage timings.
    pub(crate) fn take_trace(&mut self, rays: u64, dropped: u64, timings: &[(&'static str, f64)]) {
        self.rays_traced = rays;
        self.dropped_samples = dropped;
        for (name, secs) in timings {
            match *name {
                "trace" => self.seconds.trace = *secs,
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
