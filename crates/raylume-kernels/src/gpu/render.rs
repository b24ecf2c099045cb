//! The batch loop of [`GpuTracer`]: per batch, its plan's stages (megakernel, or the wavefront
//! with optional sorting between bounces), timed, then reported to the policy.

use std::collections::HashMap;
use std::time::Instant;

use raylume_gpu::wgpu;
use raylume_sort::{RadixSorter, SortLen, SortOptions};

use super::batch::BatchRecorder;
use super::clock::{StageClock, StageTime};
use super::work::{self, WorkBuffers, WorkLayouts};
use super::{
    BatchPlan, BatchPolicy, BatchTiming, DepthTiming, GpuTracer, TraceStats, TracerPipelines,
};
use crate::batches::{
    Batch, RoundFlow, RoundHook, RoundSums, dispatch_size, ends_round, into_rounds, mean_of_sum,
};
use crate::gpu_types::SceneUniforms;
use crate::{KernelError, ReorderMode, Schedule, TraceSettings, workgroup_size};

/// What a render holds from its preparation ([`GpuTracer::prepare`]) to its last batch.
struct Prepared {
    /// The batches, in order (rounds when a hook watches them).
    batches: Vec<Batch>,
    /// Every pipeline a plan of the policy may run.
    pipes: HashMap<&'static str, wgpu::ComputePipeline>,
    /// Rays of the largest batch: what the work buffers hold.
    capacity: u32,
    /// The render's uniforms, before each batch's own fields.
    base: SceneUniforms,
    /// Whether a plan of the policy permutes rays (a second state buffer).
    permute: bool,
    /// Persistent threads when the caller set none.
    default_threads: u32,
    /// The walk stage's workgroups at most (`BounceUniforms::walk_groups`).
    walk_groups: u32,
    /// Seconds the preparation took.
    seconds: f64,
}

impl GpuTracer<'_> {
    /// Renders with each batch's schedule and reordering chosen by `policy`, which also sees
    /// what every batch cost (how `raylume`'s `--reorder auto` measures its candidates on the
    /// real batches of a render). `settings.schedule` and `settings.reorder` are ignored; every
    /// plan the policy returns must need no more than its
    /// [`candidates`](BatchPolicy::candidates) (wavefront buffers, the sorter, a second state
    /// buffer), or the render fails with [`KernelError::InvalidSettings`].
    pub fn render_with_policy(
        &mut self,
        settings: &TraceSettings,
        policy: &mut dyn BatchPolicy,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<TraceStats, KernelError> {
        self.render_with_policy_and_hook(settings, policy, progress, None)
    }

    /// [`GpuTracer::render_to_buffer`] with a round hook: see
    /// [`GpuTracer::render_with_policy_and_hook`].
    pub fn render_to_buffer_with_hook(
        &mut self,
        settings: &TraceSettings,
        progress: &mut dyn FnMut(u32, u32),
        hook: &mut RoundHook<'_>,
    ) -> Result<TraceStats, KernelError> {
        settings.validate()?;
        let mut fixed = super::policy::Fixed(BatchPlan::of(settings));
        self.render_with_policy_and_hook(settings, &mut fixed, progress, Some(hook))
    }

    /// [`GpuTracer::render_with_policy`], calling `hook` (if given) after every round of
    /// batches with the image's running sums, read back from the GPU ([`RoundSums`]); when it
    /// answers [`RoundFlow::Stop`] the render ends there and the image buffer holds the mean
    /// of the samples traced, computed as `resolve` computes it (so, as on the CPU, the
    /// image of a render of that many samples).
    pub fn render_with_policy_and_hook(
        &mut self,
        settings: &TraceSettings,
        policy: &mut dyn BatchPolicy,
        progress: &mut dyn FnMut(u32, u32),
        mut hook: Option<&mut RoundHook<'_>>,
    ) -> Result<TraceStats, KernelError> {
        let p = self.prepare(settings, &*policy, hook.is_some())?;
        let ctx = self.ctx;
        let pixels = settings.width * settings.height;
        let max_bounces = settings.max_bounces;
        let mut clock = StageClock::new(ctx);
        let (mut round, mut batches_run) = (0u32, 0usize);
        let mut sums: Vec<[f32; 3]> = Vec::new();
        let mut samples_done = 0u64;
        let mut timings_of_batches = Vec::with_capacity(p.batches.len());
        let mut depths: Vec<DepthTiming> = Vec::new();
        let start = Instant::now();
        for (bi, b) in p.batches.iter().enumerate() {
            let plan = policy.plan(bi, &p.batches);
            self.check_plan(&plan, settings, p.permute)?;
            let t_batch = Instant::now();
            let (u, times) = self.run_batch(&p, &plan, bi, settings, hook.is_some(), &mut clock)?;
            let wall_seconds = t_batch.elapsed().as_secs_f64();
            if let Some(c) = self.capture.as_mut() {
                c.batch_done(plan, &u, max_bounces);
            }
            add_depth_times(&mut depths, &times);
            let timing = BatchTiming {
                index: bi,
                batch: *b,
                full: b.rays() == p.capacity,
                plan,
                wall_seconds,
                stages: times,
            };
            policy.observe(&timing);
            timings_of_batches.push(timing);
            samples_done += u64::from(b.rays());
            progress((samples_done / u64::from(pixels)) as u32, settings.spp);
            batches_run = bi + 1;
            if let Some(h) = hook.as_mut()
                && ends_round(b, pixels)
            {
                round += 1;
                let work = self.work.as_ref().expect("allocated by prepare");
                sums = ctx.read_buffer::<[f32; 3]>(&work.accumulation, pixels as usize)?;
                let round_sums = RoundSums {
                    round,
                    samples_done: b.sample_begin + b.sample_count,
                    round_samples: b.sample_count,
                    sums: &sums,
                };
                if h(&round_sums) == RoundFlow::Stop {
                    break;
                }
            }
        }
        if hook.is_some() {
            let done = p.batches[batches_run - 1];
            let spp = done.sample_begin + done.sample_count;
            let means: Vec<[f32; 3]> = sums.iter().map(|s| mean_of_sum(*s, spp)).collect();
            let work = self.work.as_ref().expect("allocated by prepare");
            ctx.scoped("writing the image's means", || {
                ctx.queue
                    .write_buffer(&work.accumulation, 0, bytemuck::cast_slice(&means))
            })?;
        }
        let trace = start.elapsed().as_secs_f64();
        self.last_batch = p.batches[..batches_run].last().copied();
        self.finish(
            &clock,
            p.seconds,
            trace,
            batches_run,
            depths,
            timings_of_batches,
        )
    }

    /// Everything before the first batch (pbrt-v4's wavefront `Render()` calls it the
    /// preparation): the batches, work buffers that fit every plan the policy may choose,
    /// those plans' pipelines, a ray sorter per key width, the capture buffers, a warm-up of
    /// every pipeline, the accumulation cleared.
    fn prepare(
        &mut self,
        settings: &TraceSettings,
        policy: &dyn BatchPolicy,
        rounds: bool,
    ) -> Result<Prepared, KernelError> {
        settings.validate()?;
        let t_prepare = Instant::now();
        let ctx = self.ctx;
        let max_bounces = settings.max_bounces;
        let candidates = policy.candidates();
        for c in &candidates {
            TraceSettings {
                schedule: c.schedule,
                reorder: c.reorder,
                ..*settings
            }
            .validate()?;
        }
        let wavefront = candidates.iter().any(|c| c.schedule == Schedule::Wavefront);
        let permute = candidates
            .iter()
            .any(|c| c.sorts(max_bounces) && c.reorder.mode == ReorderMode::SortPermute);

        let variant = self.path_variant();
        // The `next_event` stage's records, or the shadow stage's (the same buffer).
        let record_words = match (wavefront, variant) {
            (true, v) if v.defers_light_samples() => {
                (size_of::<crate::gpu_types::NeeRecord>() / 16) as u32
            }
            (true, v) if v.defers_shadow_rays() => crate::SHADOW_RECORD_WORDS,
            _ => 0,
        };
        let walk_stage = wavefront && variant.walk_stage;
        let pixels = settings.width * settings.height;
        // Every schedule a batch may run must fit: the wavefront's 64-byte states (and its
        // deferred records: 128-byte light samples, 80-byte shadow rays) bound it.
        let per_ray = work::WorkKey::per_ray_bytes(wavefront, record_words);
        let max_rays =
            (ctx.max_binding_bytes() / per_ray).min(self.batch_ray_limit.unwrap_or(u64::MAX));
        let mut batches = crate::batches::plan_render(
            pixels,
            settings,
            self.data.sample_range.as_ref(),
            max_rays,
        )?;
        if rounds {
            into_rounds(&mut batches);
        }
        let capacity = batches.iter().map(|b| b.rays()).max().unwrap_or(1);
        let need = work::WorkKey {
            wavefront,
            permute,
            record_words,
            walk_stage,
            capacity,
            pixels,
            batches: batches.len() as u32,
            bounces: max_bounces + 1,
        };
        // Buffers that can run this render are kept (they may be larger); otherwise they are
        // reallocated to cover both the old need and this one, if the image is the same and
        // the union still fits a binding (a megakernel render's large batches and a
        // wavefront's per-ray buffers may not), else to this need alone.
        let key = match self.work.as_ref() {
            Some(w) if w.key.covers(&need) => w.key,
            Some(w)
                if w.key.pixels == need.pixels
                    && w.key.union(&need).largest_binding() <= ctx.max_binding_bytes() =>
            {
                w.key.union(&need)
            }
            _ => need,
        };
        if self.work.as_ref().is_none_or(|w| w.key != key) {
            self.work = None; // free the old buffers first
            self.work = Some(WorkBuffers::new(
                ctx,
                WorkLayouts {
                    work: &self.pipelines.work_layout,
                    args: &self.pipelines.args_layout,
                    permute: &self.pipelines.permute_group_layout,
                },
                key,
            )?);
        }
        let mut stages: Vec<&'static str> = Vec::new();
        for c in &candidates {
            stages.extend_from_slice(TracerPipelines::entries(c.schedule, variant));
        }
        if permute {
            stages.push("permute_rays");
        }
        let mut pipes = HashMap::new();
        for s in stages {
            if !pipes.contains_key(s) {
                pipes.insert(s, self.pipeline(s)?);
            }
        }
        if variant.walk_stage && pipes.contains_key("trace_hits") {
            // `propagate` of the walk stage's bounces reads the stage's hits; the sorted
            // bounces' walks (`batch::walk_stage_at`).
            pipes.insert(super::batch::PROPAGATE_HITS, pipes["propagate"].clone());
            let walking =
                self.pipelines
                    .pipeline(ctx, "propagate", variant.with_walk_stage(false))?;
            pipes.insert("propagate", walking);
        }
        let mut key_bits: Vec<u32> = candidates
            .iter()
            .filter(|c| c.sorts(max_bounces))
            .map(|c| c.reorder.key_bits)
            .collect();
        key_bits.sort_unstable();
        key_bits.dedup();
        self.prepare_sorters(&key_bits, key.capacity)?;
        if let Some(c) = self.capture.as_mut() {
            c.prepare(ctx, capacity, wavefront)?;
        }
        let base = self.data.uniforms(settings);
        self.warm_pipelines(&pipes, &base, capacity)?;
        self.work.as_mut().expect("allocated above").reset(ctx)?;
        // Lavapipe ends every loop of a shader once its invocations have run 65,535 loop
        // iterations together (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS, "shared between every
        // loop"), silently: a persistent thread taking dozens of samples passes it and drops
        // the rest (seen: 16 of 4,096 samples lost with 64 threads). On a software adapter the
        // persistent schedule therefore runs one sample a thread unless told otherwise
        // (`set_persistent_threads`; the tests keep each thread to a few samples).
        let default_threads = if ctx.info.is_software {
            u32::MAX
        } else {
            std::env::var("RAYLUME_PERSISTENT_THREADS")
                .ok()
                .and_then(|v| v.parse::<u32>().ok())
                .filter(|&t| t > 0)
                .unwrap_or(crate::PERSISTENT_THREADS)
        };
        // The walk stage's workgroups at most: a thread per ray on a software adapter (its
        // loop limit, as above), else about as many as stay resident, taking the queue's rays
        // in turn (prepare_propagate sizes each bounce's dispatch within this).
        let walk_groups = match self.walk_stage_groups {
            Some(g) => g,
            None if ctx.info.is_software => u32::MAX,
            None => crate::walk_stage_groups(),
        };
        Ok(Prepared {
            batches,
            pipes,
            capacity,
            base,
            permute,
            default_threads,
            walk_groups,
            seconds: t_prepare.elapsed().as_secs_f64(),
        })
    }

    /// A ray sorter for each key width in `key_bits`, for exactly `work_capacity` rays (a
    /// sorter of an indirect length needs key and value buffers of its `max_len`), each run
    /// once so that wgpu's lazy zeroing of its scratch buffers and the first use of its
    /// pipelines do not land in a timed batch.
    fn prepare_sorters(&mut self, key_bits: &[u32], work_capacity: u32) -> Result<(), KernelError> {
        let ctx = self.ctx;
        for &bits in key_bits {
            if self
                .sorters
                .iter()
                .any(|s| s.plan().key_bits == bits && s.max_len() == work_capacity)
            {
                continue;
            }
            self.sorters.retain(|s| s.plan().key_bits != bits);
            let opts = SortOptions::ray_keys().with_key_bits(bits);
            let sorter = RadixSorter::new(ctx, work_capacity, opts).map_err(KernelError::from)?;
            let w = self.work.as_ref().expect("allocated by prepare");
            let primed = ctx.scoped("preparing the ray sorter", || {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let r = sorter.encode(
                    &mut enc,
                    &w.ray_keys,
                    &w.ray_queues[0],
                    SortLen::Fixed(1),
                    None,
                );
                ctx.queue.submit([enc.finish()]);
                r
            })?;
            primed.map_err(KernelError::from)?;
            ctx.wait("preparing the ray sorter")?;
            self.sorters.push(sorter);
        }
        Ok(())
    }

    /// Batch `bi` of `p` under `plan`: its uniforms written (sums kept undivided when
    /// `rounds`), its stages recorded by a [`BatchRecorder`] and run on `clock`. Returns the
    /// uniforms and the stages' times.
    fn run_batch(
        &mut self,
        p: &Prepared,
        plan: &BatchPlan,
        bi: usize,
        settings: &TraceSettings,
        rounds: bool,
        clock: &mut StageClock<'_>,
    ) -> Result<(SceneUniforms, Vec<StageTime>), KernelError> {
        let ctx = self.ctx;
        let b = &p.batches[bi];
        let max_bounces = settings.max_bounces;
        let mut u = b.uniforms(&p.base, bi as u32, settings.spp, p.capacity);
        if rounds {
            u.resolve_scale = 1.0; // sums until the hook stops; divided at the end
        }
        ctx.queue
            .write_buffer(&self.scene.uniforms, 0, bytemuck::bytes_of(&u));
        if plan.schedule == Schedule::Wavefront {
            self.work
                .as_mut()
                .expect("allocated by prepare")
                .write_bounces(ctx, max_bounces, plan.reorder, p.walk_groups);
        }
        let work = self.work.as_ref().expect("allocated by prepare");
        let max_dim = ctx.limits.max_compute_workgroups_per_dimension;
        let during = format!("rendering batch {} of {}", bi + 1, p.batches.len());
        let stages = BatchRecorder {
            work,
            pipes: &p.pipes,
            scene_bg: &self.scene.bind_group,
            sorters: &self.sorters,
            probe: self.capture.as_ref().and_then(|c| c.probe()),
            ray_groups: dispatch_size(b.rays(), workgroup_size(), max_dim),
            path_groups: dispatch_size(b.rays(), crate::megakernel_workgroup_size(), max_dim),
            persistent_groups: dispatch_size(
                b.rays()
                    .min(self.persistent_threads.unwrap_or(p.default_threads)),
                workgroup_size(),
                max_dim,
            ),
            pixel_groups: dispatch_size(b.pixel_count, workgroup_size(), max_dim),
        }
        .stages(plan, max_bounces);
        let times = clock.run(&during, &stages)?;
        Ok((u, times))
    }

    /// After the last batch: the rays traced and the samples dropped read back, and the
    /// timings (upload, preparation, each stage's total, the whole trace).
    fn finish(
        &self,
        clock: &StageClock<'_>,
        prepare: f64,
        trace: f64,
        batches_run: usize,
        depths: Vec<DepthTiming>,
        batches: Vec<BatchTiming>,
    ) -> Result<TraceStats, KernelError> {
        let work = self.work.as_ref().expect("allocated by prepare");
        let stats: Vec<u32> = self.ctx.read_buffer(&work.batch_stats, 4 * batches_run)?;
        let (mut rays_traced, mut dropped_samples) = (0u64, 0u64);
        for s in stats.chunks_exact(4) {
            rays_traced += u64::from(s[0]) | (u64::from(s[1]) << 32);
            dropped_samples += u64::from(s[2]);
        }
        let mut timings = vec![("upload", self.upload_seconds), ("prepare", prepare)];
        for (label, name) in [
            ("raygen", "raygen"),
            ("trace_hits", "trace_hits"),
            ("propagate", "propagate"),
            ("trace_shadows", "trace_shadows"),
            ("next_event", "next_event"),
            ("sort_keys", "sort"),
            ("permute_rays", "permute_rays"),
            ("trace_paths", "trace_paths"),
            ("resolve", "resolve"),
        ] {
            if let Some(t) = clock.total(label) {
                timings.push((name, t));
            }
        }
        timings.push(("trace", trace));
        Ok(TraceStats {
            rays_traced,
            dropped_samples,
            timings,
            depths,
            batches,
        })
    }

    /// Runs every pipeline of the render once on an empty batch (no rays, no pixels: each
    /// kernel returns at once), outside the timed batches: some drivers finish compiling a
    /// pipeline at its first dispatch (lavapipe took 0.7 s there), which would otherwise land
    /// in the first batch and mislead a policy comparing batches.
    fn warm_pipelines(
        &self,
        pipes: &HashMap<&'static str, wgpu::ComputePipeline>,
        base: &SceneUniforms,
        capacity: u32,
    ) -> Result<(), KernelError> {
        let ctx = self.ctx;
        let w = self.work.as_ref().expect("allocated before");
        let empty = SceneUniforms {
            pixel_count: 0,
            sample_count: 0,
            rays_in_batch: 0,
            batch_index: 0,
            queue_capacity: capacity,
            ..*base
        };
        ctx.scoped("preparing the tracer's pipelines", || {
            ctx.queue
                .write_buffer(&self.scene.uniforms, 0, bytemuck::bytes_of(&empty));
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            enc.clear_buffer(&w.queue_counts, 0, None);
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                for (name, pipe) in pipes {
                    pass.set_pipeline(pipe);
                    pass.set_bind_group(0, &self.scene.bind_group, &[]);
                    pass.set_bind_group(1, &w.bind_groups[0], &[0]);
                    match *name {
                        "prepare_propagate" => {
                            pass.set_bind_group(2, &w.args_bind_group, &[]);
                        }
                        "permute_rays" => {
                            pass.set_bind_group(2, &w.permute_bind_groups[0], &[]);
                        }
                        _ => {}
                    }
                    pass.dispatch_workgroups(1, 1, 1);
                }
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        ctx.wait("preparing the tracer's pipelines")?;
        Ok(())
    }

    /// Fails unless this render's buffers and sorter can run `plan`.
    fn check_plan(
        &self,
        plan: &BatchPlan,
        settings: &TraceSettings,
        permute: bool,
    ) -> Result<(), KernelError> {
        TraceSettings {
            schedule: plan.schedule,
            reorder: plan.reorder,
            ..*settings
        }
        .validate()?;
        let wavefront = self.work.as_ref().is_some_and(|w| w.key.wavefront);
        let capacity = self.work.as_ref().map_or(0, |w| w.key.capacity);
        let sorts = plan.sorts(settings.max_bounces);
        let sorter = self
            .sorters
            .iter()
            .any(|s| s.plan().key_bits == plan.reorder.key_bits && s.max_len() == capacity);
        let ok = (plan.schedule != Schedule::Wavefront || wavefront)
            && (!sorts || sorter)
            && (!sorts || plan.reorder.mode != ReorderMode::SortPermute || permute);
        if ok {
            Ok(())
        } else {
            Err(KernelError::InvalidSettings(format!(
                "a batch policy asked for `{}`, which none of its candidates prepared for",
                plan.describe(settings.max_bounces)
            )))
        }
    }
}

/// Adds the bounce-stage times of one batch (`trace_hits`, `propagate`, `trace_shadows`,
/// `next_event`, `sort_keys`, `permute_rays`, each
/// with its depth) to the render's per-depth totals.
fn add_depth_times(depths: &mut Vec<DepthTiming>, times: &[StageTime]) {
    for st in times {
        let Some(d) = st.depth else { continue };
        if depths.len() <= d as usize {
            depths.resize_with(d as usize + 1, Default::default);
        }
        let e = &mut depths[d as usize];
        e.depth = d;
        match st.label {
            // The walk and shadow stages' shares of the bounce's rays count as propagate's.
            "propagate" | "trace_hits" | "trace_shadows" => e.propagate += st.seconds,
            "next_event" => e.next_event += st.seconds,
            "sort_keys" => e.sort += st.seconds,
            "permute_rays" => e.permute += st.seconds,
            _ => {}
        }
    }
}
