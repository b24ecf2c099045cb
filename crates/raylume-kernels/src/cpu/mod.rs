//! The CPU mirror: the same functions as the WGSL kernels, run with rayon. It traces the same
//! paths as the GPU (same random-number keys, same arithmetic), so images agree closely, and
//! it is the reference the GPU tests compare against. Like the paper's CPU path, it never
//! sorts rays. Scenes of diffuse triangles are traced 8 or 16 paths at a time ([`packet`]),
//! the same image bit for bit.

pub mod isa;
pub mod packet;
pub mod stages;
pub mod variant;

use std::sync::Arc;
use std::time::Instant;

use raylume_bvh::{GpuBvh, HugePageArray};
use raylume_scene::Scene;
use rayon::prelude::*;

use crate::batches::{RoundFlow, RoundHook, RoundSums, ends_round, into_rounds};
use crate::gpu_types::{RayState, SceneUniforms};
use crate::scene_data::{RenderChoices, SceneData, SceneOptions};
use crate::surface::Globals;
use crate::{KernelError, Schedule, Specialisation, TraceOutput, TraceSettings};
use isa::CpuIsa;
use variant::{ForVariant, run_variant, variant_of};

/// Rays per batch on the CPU: bounds the wavefront's ray states to 256 MiB.
pub const CPU_MAX_RAYS_PER_BATCH: u64 = 1 << 22;

/// Paths per rayon task of [`packet`]'s schedule, which traces them `packet::LANES` (or
/// `packet::LANES_AVX512`) at a time.
const PACKET_CHUNK: usize = 2048;

/// Paths per rayon task of the other scenes' schedule, which traces them two at a time
/// ([`stages::trace_paths_in_pairs`]): small enough that a small render still fills every
/// core and the last tasks end together.
const PAIRS_CHUNK: usize = 256;

/// The size of the records a hit's surface reads (primitives, material indices, shading
/// records) from which [`CpuTracer::pairs`] traces two paths at a time by default: a core's
/// L2 cache (1-2 MiB on the dev VMs). Below it the records stay cached and the pairs'
/// bookkeeping costs more than their prefetches save (Cornell plus, 400x400: +7 % in pairs).
pub const PAIRS_MIN_RECORD_BYTES: usize = 1 << 20;

/// The size of the arrays a render reads at random (the records a hit's shading reads:
/// primitives, material indices, shading records, texels; and the walks' node boxes and
/// triangle blocks) from which [`CpuTracer::huge_pages`] places them in 2 MiB pages by
/// default: beyond what a core's TLB covers in 4 KiB pages (1,536-3,072 entries, 6-12 MiB, on
/// the dev VMs' cores). The living room's are 46 MB.
pub const HUGE_PAGES_MIN_BYTES: usize = 8 << 20;

/// How many bytes of those arrays one path sample (a pixel's sample) of a render repays in
/// huge pages: by default a render places them there when it traces at least one path sample
/// per this many bytes. Their first writes cost ~3-4 ms a MB on the AMD dev VM (the kernel
/// gathering free 2 MiB pages: the 3M-triangle grid's ~300 MB took its CPU render's setup
/// from 0.32 to 0.81 s), and a living-room path sample gains ~0.05 us (5-7 % of ~1 us on two
/// cores): about even at one sample per 16 bytes (the living room from 2.9 M path samples,
/// 1000x1000 at 3 spp; the 3M grid from ~20 M).
pub const HUGE_PAGES_BYTES_PER_PATH: u64 = 16;

/// Whether a render of `path_samples` (pixels x spp) repays placing `bytes` of the arrays it
/// reads at random in huge pages: [`CpuTracer::huge_pages`]' default rule (at least
/// [`HUGE_PAGES_MIN_BYTES`], at least a path sample per [`HUGE_PAGES_BYTES_PER_PATH`] bytes).
pub fn huge_pages_repay(bytes: usize, path_samples: u64) -> bool {
    bytes >= HUGE_PAGES_MIN_BYTES
        && path_samples.saturating_mul(HUGE_PAGES_BYTES_PER_PATH) >= bytes as u64
}

/// The records the CPU's shading reads at random, copied into memory backed by 2 MiB pages
/// ([`raylume_bvh::HugePageArray`]) for the renders that [`CpuTracer::huge_pages`] chooses:
/// the same values, fewer page-table walks (with the walks' arrays in huge pages too, the
/// living room's trace 7 % faster single-threaded side by side, `docs/RESULTS.md`, issue 15,
/// session 47).
struct HugeRecords {
    primitives: HugePageArray<raylume_bvh::Primitive>,
    prim_materials: HugePageArray<u32>,
    triangle_shading: HugePageArray<crate::gpu_types::TriangleShading>,
    texels: HugePageArray<u32>,
}

impl HugeRecords {
    fn copy(bvh: &GpuBvh, data: &SceneData) -> Self {
        Self {
            primitives: HugePageArray::from_slice(&bvh.primitives),
            prim_materials: HugePageArray::from_slice(&data.prim_materials),
            triangle_shading: HugePageArray::from_slice(&data.triangle_shading),
            texels: HugePageArray::from_slice(&data.texels),
        }
    }
}

/// Renders a scene on the CPU with rayon, through the same stage functions as the GPU.
pub struct CpuTracer {
    /// Shared with whoever made the tracer (`CpuTracer::with_shared`): never copied.
    bvh: Arc<GpuBvh>,
    data: Arc<SceneData>,
    /// This tracer's estimator, roulette, sampler, guide use and sample range (the data's
    /// own at first).
    choices: RenderChoices,
    /// The variant of the per-bounce functions the renders run ([`variant`]).
    variant: usize,
    /// The instruction-set level the renders' paths run at ([`isa`]), available on this CPU.
    isa: CpuIsa,
    /// Whether the variant [`packet`] runs traces several paths at once ([`packet`]).
    packets: bool,
    /// Whether the other variants trace two paths at a time ([`CpuTracer::set_pairs`]).
    pairs: Option<bool>,
    /// Whether renders copy the records into huge pages ([`CpuTracer::set_huge_pages`]).
    huge_pages: Option<bool>,
    /// The copy, once a render made it (kept for the next renders).
    huge_records: Option<HugeRecords>,
    prepare_seconds: f64,
}

impl CpuTracer {
    /// The estimator of the next renders (default: the paper's plain one).
    pub fn set_estimator(&mut self, estimator: crate::Estimator) {
        self.choices.estimator = estimator;
    }

    /// Russian roulette from segment `start` on (`None`, the default: off): after each hit of a
    /// segment `>= start` the path goes on with probability `min(max throughput, 0.95)` and
    /// its throughput is divided by it (Mitsuba's `path` at its default `rr_depth` 5 is a
    /// start of 4 here: it counts hits from 1). Unbiased; fewer rays spent on paths that carry
    /// little.
    pub fn set_russian_roulette(&mut self, start: Option<u32>) {
        self.choices.russian_roulette = start;
    }

    /// Where the paths' random numbers come from (default [`crate::Sampler::Independent`]).
    pub fn set_sampler(&mut self, sampler: crate::Sampler) {
        self.choices.sampler = sampler;
    }

    /// Whether next-event estimation samples the environment by where the scene leaves it
    /// visible ([`crate::env_guide`]), when the guide was learned ([`SceneOptions`]; then on
    /// by default): `false` samples by its radiance alone. Unbiased either way; without a
    /// learned guide (not asked for, no environment, no geometry, too few escapes) the
    /// environment is sampled by radiance whatever this says.
    pub fn set_environment_guide(&mut self, on: bool) {
        self.choices.environment_guide = on;
    }

    /// The guide's walks and escapes, if one was learned for this scene.
    pub fn environment_guide_walks(&self) -> Option<(u32, u64)> {
        self.data.environment_guide_walks
    }

    /// How the per-bounce functions are specialised on the scene's features ([`variant`]):
    /// [`Specialisation::Generic`] runs the variant with every feature, the others (the
    /// default) the smallest that holds the scene's and `extra` (features compiled in
    /// although the scene lacks them: what one costs present but unused, `bench
    /// --extra-feature`). The image is the same.
    pub fn set_specialisation(
        &mut self,
        specialisation: Specialisation,
        extra: raylume_scene::Features,
    ) {
        let features = self.data.features.bits() | extra.bits();
        self.variant = variant_of(raylume_scene::Features::from_bits(features), specialisation);
    }

    /// Runs the paths of the next renders at instruction-set level `isa` ([`isa`]), or at the
    /// highest level below it that this CPU executes when it lacks `isa`'s (default: the
    /// highest it executes, [`CpuIsa::best`]). The image is the same bit for bit at every
    /// level; only the time differs. Returns the level set.
    pub fn set_isa(&mut self, isa: CpuIsa) -> CpuIsa {
        self.isa = CpuIsa::best_up_to(isa);
        self.isa
    }

    /// Whether scenes of triangles without textures, shading normals or a sky
    /// ([`packet::runs`]) are traced [`packet::LANES`] (at x86-64-v4 [`packet::LANES_AVX512`])
    /// paths at a time, their diffuse hits shaded on lanes ([`packet`], default `true`), or one
    /// at a time, as every other scene: the same image bit for bit either way, in less time
    /// with packets.
    pub fn set_packets(&mut self, on: bool) {
        self.packets = on;
    }

    /// Whether scenes the packets do not take are traced two paths at a time, a segment of
    /// each in turn, each hit's records asked for after its walk and read after the other
    /// path's segment ([`stages::trace_paths_in_pairs`]; `Some(true)`), or one path at a time
    /// (`Some(false)`); `None` (the default): in pairs when those records exceed
    /// [`PAIRS_MIN_RECORD_BYTES`]. The same image bit for bit either way.
    pub fn set_pairs(&mut self, on: Option<bool>) {
        self.pairs = on;
    }

    /// Whether the renders trace two paths at a time ([`CpuTracer::set_pairs`]): not where
    /// the packets take the scene.
    pub fn pairs(&self) -> bool {
        !self.packets()
            && self
                .pairs
                .unwrap_or_else(|| self.hit_record_bytes() > PAIRS_MIN_RECORD_BYTES)
    }

    /// Whether a render places the arrays it reads at random in memory backed by 2 MiB pages
    /// (`Some(true)`; [`raylume_bvh::HugePageArray`], on Linux, where the kernel's transparent
    /// huge pages are `always` or `madvise`): it copies the records its shading reads (the
    /// primitives, their material indices and shading records, the texels) there, and the
    /// tree's walk arrays are made there if no walk made them before
    /// ([`GpuBvh::prepare_cpu_walks`]); or reads them in ordinary pages (`Some(false)`);
    /// `None` (the default): where those arrays take at least [`HUGE_PAGES_MIN_BYTES`] and
    /// the render traces at least a path sample per [`HUGE_PAGES_BYTES_PER_PATH`] bytes of
    /// them. The records' copy is made once, kept for the tracer's next renders, and takes
    /// their size in memory again. The same image bit for bit either way.
    pub fn set_huge_pages(&mut self, on: Option<bool>) {
        self.huge_pages = on;
        if on == Some(false) {
            self.huge_records = None;
        }
    }

    /// Whether a render of `path_samples` (pixels x spp) reads the records from huge pages
    /// ([`CpuTracer::set_huge_pages`]).
    pub fn huge_pages(&self, path_samples: u64) -> bool {
        self.huge_pages.unwrap_or_else(|| {
            self.huge_records.is_some()
                || huge_pages_repay(
                    self.record_bytes() + self.bvh.cpu_walk_bytes(),
                    path_samples,
                )
        })
    }

    /// Makes what a render of `path_samples` (pixels x spp) reads before it traces: the
    /// tree's walk arrays (if no walk made them yet) and, where [`CpuTracer::huge_pages`]
    /// says so, the records' copy in huge pages (or drops a copy it says not to keep).
    /// [`CpuTracer::render`] calls it; call it before to keep that work out of the render's
    /// `prepare`. Returns whether the records are read from huge pages.
    pub fn prepare(&mut self, path_samples: u64) -> bool {
        let huge = self.huge_pages(path_samples);
        if self.bvh.layout == raylume_bvh::BvhLayout::Wide {
            // The CPU's float node boxes, made here rather than by the first ray of the
            // parallel loop (see `GpuBvh::wide_boxes`).
            self.bvh.prepare_cpu_walks(huge);
        }
        if !huge {
            self.huge_records = None;
        } else if self.huge_records.is_none() {
            self.huge_records = Some(HugeRecords::copy(&self.bvh, &self.data));
        }
        huge
    }

    /// The bytes of the records a hit's surface reads (primitives, material indices, shading
    /// records): what [`CpuTracer::pairs`] weighs.
    fn hit_record_bytes(&self) -> usize {
        let d = &self.data;
        std::mem::size_of_val(self.bvh.primitives.as_slice())
            + std::mem::size_of_val(d.prim_materials.as_slice())
            + std::mem::size_of_val(d.triangle_shading.as_slice())
    }

    /// The bytes of the records [`CpuTracer::set_huge_pages`] copies: a hit's and the texels.
    fn record_bytes(&self) -> usize {
        self.hit_record_bytes() + std::mem::size_of_val(self.data.texels.as_slice())
    }

    /// Whether the tracer holds the records' copy (made by a render that
    /// [`CpuTracer::huge_pages`] chose; each array in huge pages where it takes at least a
    /// huge page, in ordinary memory below that, as `set_huge_pages(Some(true))` gives a
    /// small scene).
    pub fn records_in_huge_pages(&self) -> bool {
        self.huge_records.is_some()
    }

    /// Whether the renders trace several paths at once where they can ([`CpuTracer::set_packets`]).
    pub fn packets(&self) -> bool {
        self.packets && packet::runs(variant::variant(self.variant))
    }

    /// Whether the renders' walks test the scene's tree flat, every triangle against every
    /// ray, at the level set ([`isa::walks_flat`]: a tree of at most
    /// `raylume_bvh::FLAT_MAX_PRIMITIVES` triangles at x86-64-v4): the same image either way.
    pub fn walks_flat(&self) -> bool {
        isa::walks_flat(self.isa, &self.bvh)
    }

    /// The instruction-set level the renders' paths run at ([`CpuTracer::set_isa`]).
    pub fn isa(&self) -> CpuIsa {
        self.isa
    }

    /// The feature bits of the variant the renders run ([`variant::variant`]).
    pub fn variant_features(&self) -> raylume_scene::Features {
        raylume_scene::Features::from_bits(variant::variant(self.variant))
    }

    /// Trace only samples `range` of every pixel (`None`, the default: all of them) and
    /// leave each pixel's *sum* over the range in the image, not its mean: a render part, to
    /// be added to the other parts' sums and divided by the total count. The random numbers
    /// of a sample depend on its index, not on the range, so parts that tile `0..spp` sum to
    /// the samples of the whole render. A range must lie within `0..spp` (checked when
    /// rendering); round hooks (target error) see the part's sums.
    pub fn set_sample_range(&mut self, range: Option<std::ops::Range<u32>>) {
        self.choices.sample_range = range;
    }

    /// Flattens `scene` for the primitives of `bvh` (built from this scene).
    pub fn new(scene: &Scene, bvh: &GpuBvh) -> Result<Self, KernelError> {
        Self::with_options(scene, bvh, &SceneOptions::default())
    }

    /// [`CpuTracer::new`], also preparing what `options` asks for (the environment guide).
    pub fn with_options(
        scene: &Scene,
        bvh: &GpuBvh,
        options: &SceneOptions,
    ) -> Result<Self, KernelError> {
        let t = Instant::now();
        let data = SceneData::with_options(scene, bvh, options)?;
        Ok(Self {
            bvh: Arc::new(bvh.clone()),
            choices: data.choices(),
            variant: variant_of(data.features, Specialisation::default()),
            isa: CpuIsa::best(),
            packets: true,
            pairs: None,
            huge_pages: None,
            huge_records: None,
            data: Arc::new(data),
            prepare_seconds: t.elapsed().as_secs_f64(),
        })
    }

    /// A tracer of `data`, prepared beforehand for the scene `bvh` was built from
    /// ([`SceneData::with_options`], e.g. by an earlier tracer): nothing is prepared again.
    pub fn with_data(bvh: &GpuBvh, data: SceneData) -> Result<Self, KernelError> {
        Self::with_shared(Arc::new(bvh.clone()), Arc::new(data))
    }

    /// [`CpuTracer::with_data`] without copying the tree or the data (a large scene's tree and
    /// texels are hundreds of megabytes): both are shared with the caller, and this tracer's
    /// settings (`set_estimator`, ...) start from the data's and stay its own.
    pub fn with_shared(bvh: Arc<GpuBvh>, data: Arc<SceneData>) -> Result<Self, KernelError> {
        data.check_bvh(&bvh)?;
        data.check_complete()?;
        Ok(Self {
            bvh,
            choices: data.choices(),
            variant: variant_of(data.features, Specialisation::default()),
            isa: CpuIsa::best(),
            packets: true,
            pairs: None,
            huge_pages: None,
            huge_records: None,
            data,
            prepare_seconds: 0.0,
        })
    }

    fn globals<'a>(
        &'a self,
        scene: &'a SceneUniforms,
        sobol_segments: &'a [crate::sobol::SegmentKeys],
    ) -> Globals<'a> {
        let d = &self.data;
        let (primitives, prim_materials, triangle_shading, texels) = match &self.huge_records {
            Some(h) => (
                &h.primitives[..],
                &h.prim_materials[..],
                &h.triangle_shading[..],
                &h.texels[..],
            ),
            None => (
                &self.bvh.primitives[..],
                &d.prim_materials[..],
                &d.triangle_shading[..],
                &d.texels[..],
            ),
        };
        Globals {
            scene,
            primitives,
            materials: &self.data.materials,
            prim_materials,
            triangle_shading,
            texture_headers: &self.data.texture_headers,
            texels,
            lights: &self.data.lights,
            plastic_tables: &self.data.plastic_tables,
            sobol_segments,
        }
    }

    /// The radiance of one pixel sample of a render with `settings` (what the GPU writes to
    /// that sample's slot, before the non-finite check): for tests and debugging.
    pub fn sample_radiance(&self, settings: &TraceSettings, pixel: u32, sample: u32) -> [f32; 3] {
        struct OnePath<'a> {
            g: &'a Globals<'a>,
            bvh: &'a GpuBvh,
            pixel: u32,
            sample: u32,
        }
        impl ForVariant for OnePath<'_> {
            type Out = [f32; 3];
            fn run<const F: u32>(self) -> [f32; 3] {
                stages::trace_path::<F>(self.g, self.bvh, self.pixel, self.sample)
                    .0
                    .into()
            }
        }
        let scene = self.data.uniforms_with(settings, &self.choices);
        let keys = crate::sobol::segment_keys(&scene);
        let g = self.globals(&scene, &keys);
        run_variant(
            self.variant,
            OnePath {
                g: &g,
                bvh: &self.bvh,
                pixel,
                sample,
            },
        )
    }

    /// Renders with `settings`, calling `progress(spp_done, spp_total)` after each batch.
    /// Timings are wall-clock: "upload" (flattening the scene in [`CpuTracer::new`]),
    /// "prepare" (the walks' arrays and the records' copy into huge pages where this render
    /// made them: [`CpuTracer::prepare`]), the stages of the chosen schedule, and "trace", the
    /// whole batch loop.
    pub fn render(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<TraceOutput, KernelError> {
        self.render_rounds(settings, progress, None)
    }

    /// As [`CpuTracer::render`], calling `hook` after every round of batches with the image's
    /// running sums ([`RoundSums`]); when it answers [`RoundFlow::Stop`] the render ends
    /// there and its image is the mean of the samples traced, bit for bit the image of a
    /// render of that many samples (without ZSobol, whose points are laid out for
    /// `settings.spp`: there it is the first samples of the full render).
    pub fn render_with_hook(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
        hook: &mut RoundHook<'_>,
    ) -> Result<TraceOutput, KernelError> {
        self.render_rounds(settings, progress, Some(hook))
    }

    fn render_rounds(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
        mut hook: Option<&mut RoundHook<'_>>,
    ) -> Result<TraceOutput, KernelError> {
        settings.validate()?;
        let pixels = settings.width * settings.height;
        let t_records = Instant::now();
        self.prepare(u64::from(pixels) * u64::from(settings.spp));
        let t_records = t_records.elapsed().as_secs_f64();
        let mut batches = crate::batches::plan_render(
            pixels,
            settings,
            self.choices.sample_range.as_ref(),
            CPU_MAX_RAYS_PER_BATCH,
        )?;
        if hook.is_some() {
            into_rounds(&mut batches);
        }
        let (mut round, mut spp_done) = (0u32, settings.spp);
        let base = self.data.uniforms_with(settings, &self.choices);
        let keys = crate::sobol::segment_keys(&base);
        let mut image = vec![[0.0f32; 3]; pixels as usize];
        let mut slots: Vec<[f32; 3]> = Vec::new();
        let mut states: Vec<RayState> = Vec::new();
        let (mut rays_traced, mut dropped) = (0u64, 0u64);
        let (mut t_raygen, mut t_propagate, mut t_paths, mut t_resolve) = (0.0, 0.0, 0.0, 0.0);
        let mut samples_done = 0u64;
        let start = Instant::now();
        for (bi, b) in batches.iter().enumerate() {
            let mut scene = b.uniforms(&base, bi as u32, settings.spp, b.rays());
            if hook.is_some() {
                scene.resolve_scale = 1.0; // sums until the hook stops; divided below
            }
            let g = self.globals(&scene, &keys);
            let bvh = &self.bvh;
            let n = b.rays() as usize;
            slots.clear();
            slots.resize(n, [0.0; 3]);
            let counts = run_variant(
                self.variant,
                BatchRun {
                    g: &g,
                    bvh,
                    scene: &scene,
                    schedule: settings.schedule,
                    isa: self.isa,
                    packets: self.packets,
                    pairs: self.pairs(),
                    max_bounces: settings.max_bounces,
                    rays: b.rays(),
                    slots: &mut slots,
                    states: &mut states,
                },
            );
            rays_traced += counts.rays;
            dropped += counts.dropped;
            t_paths += counts.paths;
            t_raygen += counts.raygen;
            t_propagate += counts.propagate;
            let t = Instant::now();
            let pixel_range = b.pixel_begin as usize..(b.pixel_begin + b.pixel_count) as usize;
            image[pixel_range]
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, acc)| *acc = stages::resolve(&scene, *acc, &slots, i as u32));
            t_resolve += t.elapsed().as_secs_f64();
            samples_done += u64::from(b.rays());
            progress((samples_done / u64::from(pixels)) as u32, settings.spp);
            if let Some(h) = hook.as_mut()
                && ends_round(b, pixels)
            {
                round += 1;
                spp_done = b.sample_begin + b.sample_count;
                let sums = RoundSums {
                    round,
                    samples_done: spp_done,
                    round_samples: b.sample_count,
                    sums: &image,
                };
                if h(&sums) == RoundFlow::Stop {
                    break;
                }
            }
        }
        if hook.is_some() {
            let mean = |p: &mut [f32; 3]| *p = crate::batches::mean_of_sum(*p, spp_done);
            image.par_iter_mut().for_each(mean);
        }
        let trace = start.elapsed().as_secs_f64();
        // "prepare": the walk arrays and the records' copy into huge pages, where this render
        // made them (`CpuTracer::prepare`).
        let mut timings = vec![("upload", self.prepare_seconds), ("prepare", t_records)];
        match settings.schedule {
            Schedule::Megakernel | Schedule::Persistent => timings.push(("trace_paths", t_paths)),
            Schedule::Wavefront => {
                timings.push(("raygen", t_raygen));
                timings.push(("propagate", t_propagate));
            }
        }
        timings.push(("resolve", t_resolve));
        timings.push(("trace", trace));
        Ok(TraceOutput {
            radiance: image,
            rays_traced,
            dropped_samples: dropped,
            timings,
        })
    }
}

/// One batch's paths on every core (`trace_paths`, or `raygen` then `propagate` per segment),
/// run by [`run_variant`] with the functions of the tracer's variant.
struct BatchRun<'a> {
    g: &'a Globals<'a>,
    bvh: &'a GpuBvh,
    scene: &'a SceneUniforms,
    schedule: Schedule,
    isa: CpuIsa,
    packets: bool,
    pairs: bool,
    max_bounces: u32,
    rays: u32,
    slots: &'a mut Vec<[f32; 3]>,
    states: &'a mut Vec<RayState>,
}

/// The batch's `slots` in rayon tasks of `size` paths, each traced by `trace(r0, chunk)` (its
/// first ray's index in the batch and its slots): the segments traced and the samples
/// dropped, summed over the tasks.
fn trace_chunks(
    slots: &mut [[f32; 3]],
    size: usize,
    trace: impl Fn(u32, &mut [[f32; 3]]) -> (u64, u64) + Sync,
) -> (u64, u64) {
    slots
        .par_chunks_mut(size)
        .enumerate()
        .map(|(i, chunk)| trace((i * size) as u32, chunk))
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// What a [`BatchRun`] traced, dropped, and spent per stage (seconds).
#[derive(Default)]
struct BatchCounts {
    rays: u64,
    dropped: u64,
    paths: f64,
    raygen: f64,
    propagate: f64,
}

impl ForVariant for BatchRun<'_> {
    type Out = BatchCounts;

    fn run<const F: u32>(self) -> BatchCounts {
        let BatchRun {
            g,
            bvh,
            scene,
            schedule,
            isa,
            packets,
            pairs,
            max_bounces,
            rays,
            slots,
            states,
        } = self;
        let mut c = BatchCounts::default();
        match schedule {
            // The persistent schedule only changes which GPU thread traces a sample.
            Schedule::Megakernel | Schedule::Persistent => {
                let t = Instant::now();
                if packets && packet::runs(F) {
                    // Scenes of diffuse triangles: `packet::LANES` paths at a time.
                    (c.rays, c.dropped) = trace_chunks(slots, PACKET_CHUNK, |r0, chunk| {
                        isa::trace_chunk::<F>(isa, g, bvh, r0, chunk)
                    });
                    c.paths = t.elapsed().as_secs_f64();
                    return c;
                }
                if pairs {
                    // Large scenes: two paths at a time, a segment of each in turn.
                    (c.rays, c.dropped) = trace_chunks(slots, PAIRS_CHUNK, |r0, chunk| {
                        isa::trace_paths_in_pairs::<F>(isa, g, bvh, r0, chunk)
                    });
                    c.paths = t.elapsed().as_secs_f64();
                    return c;
                }
                (c.rays, c.dropped) = slots
                    .par_iter_mut()
                    .enumerate()
                    .map(|(r, slot)| {
                        let (v, d, traced) = isa::trace_paths::<F>(isa, g, bvh, r as u32);
                        *slot = v;
                        (u64::from(traced), u64::from(d))
                    })
                    .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
                c.paths = t.elapsed().as_secs_f64();
            }
            Schedule::Wavefront => {
                let t = Instant::now();
                states.clear();
                (0..rays)
                    .into_par_iter()
                    .map(|r| stages::raygen(scene, r))
                    .collect_into_vec(states);
                c.raygen = t.elapsed().as_secs_f64();
                let t = Instant::now();
                for depth in 0..=max_bounces {
                    let (traced, drops) = states
                        .par_iter_mut()
                        .zip(slots.par_iter_mut())
                        .filter(|(ray, _)| ray.alive != 0)
                        .map(
                            |(ray, slot)| match stages::propagate::<F>(g, bvh, ray, depth) {
                                Some((v, d)) => {
                                    *slot = v;
                                    (1u64, u64::from(d))
                                }
                                None => (1, 0),
                            },
                        )
                        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
                    c.rays += traced;
                    c.dropped += drops;
                    if traced == 0 {
                        break;
                    }
                }
                c.propagate = t.elapsed().as_secs_f64();
            }
        }
        c
    }
}
