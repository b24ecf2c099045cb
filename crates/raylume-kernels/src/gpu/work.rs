//! The work buffers of one render size (group 1): ray states, sample slots, queues, keys,
//! the image and the statistics. Reallocated only when the render's size, or what its batches
//! may run, changes.

use raylume_gpu::{GpuContext, wgpu};

use crate::KernelError;
use crate::Reorder;
use crate::gpu_types::{BounceUniforms, RayState};

/// What the buffers were sized for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WorkKey {
    /// Some batch may run the wavefront: per-ray states, queues and keys are allocated.
    pub wavefront: bool,
    /// Some batch may run `ReorderMode::SortPermute`: a second state buffer is allocated.
    pub permute: bool,
    /// 16-byte words a ray of the wavefront's deferred records (`nee_records`): the
    /// `next_event` stage's light samples (`size_of::<NeeRecord>() / 16`), the shadow
    /// stage's rays ([`crate::SHADOW_RECORD_WORDS`]), or 0 (a placeholder).
    pub record_words: u32,
    /// The wavefront has a walk stage (`trace_hits`): per-ray hit records are allocated.
    pub walk_stage: bool,
    /// Rays in the largest batch.
    pub capacity: u32,
    pub pixels: u32,
    pub batches: u32,
    /// `max_bounces + 1` entries of bounce uniforms.
    pub bounces: u32,
}

impl WorkKey {
    /// True when buffers sized for `self` can run a render that needs `need`: the same image,
    /// and at least its rays, batches and bounces, and the buffers of its schedules.
    pub fn covers(&self, need: &WorkKey) -> bool {
        self.pixels == need.pixels
            && self.capacity >= need.capacity
            && self.batches >= need.batches
            && self.bounces >= need.bounces
            && (self.wavefront || !need.wavefront)
            && (self.permute || !need.permute)
            && self.record_words >= need.record_words
            && (self.walk_stage || !need.walk_stage)
    }

    /// Bytes per ray of the largest per-ray buffer: the light-sample records, else the ray
    /// states, else the sample slots (12 bytes).
    /// The largest binding's bytes a ray: the records', the states' (the wavefront), or
    /// the sample's radiance.
    pub fn per_ray_bytes(wavefront: bool, record_words: u32) -> u64 {
        if wavefront {
            (size_of::<RayState>() as u64).max(16 * u64::from(record_words))
        } else {
            12
        }
    }

    /// Bytes of the largest buffer allocated for this key, which must fit one storage binding.
    pub fn largest_binding(&self) -> u64 {
        u64::from(self.capacity) * Self::per_ray_bytes(self.wavefront, self.record_words)
    }

    /// The smallest key covering both `self` and `need` (which must have the same image):
    /// what a render reallocates to, so that renders alternating between two needs (as
    /// `auto`'s trials do) settle on one allocation instead of freeing and allocating
    /// gigabytes each time.
    pub fn union(&self, need: &WorkKey) -> WorkKey {
        debug_assert_eq!(self.pixels, need.pixels);
        WorkKey {
            wavefront: self.wavefront || need.wavefront,
            permute: self.permute || need.permute,
            record_words: self.record_words.max(need.record_words),
            walk_stage: self.walk_stage || need.walk_stage,
            capacity: self.capacity.max(need.capacity),
            pixels: need.pixels,
            batches: self.batches.max(need.batches),
            bounces: self.bounces.max(need.bounces),
        }
    }
}

pub(crate) struct WorkBuffers {
    pub key: WorkKey,
    pub accumulation: wgpu::Buffer,
    pub sample_radiance: wgpu::Buffer,
    pub batch_stats: wgpu::Buffer,
    pub dispatch_args: wgpu::Buffer,
    pub bounce: wgpu::Buffer,
    /// Bytes between two bounces' uniforms (the adapter's dynamic-offset alignment).
    pub bounce_stride: u32,
    /// Group 1, indexed by `2 * states + parity`: `states` picks the ray-state buffer (1 only
    /// with `permute`); parity 0 (even bounces and every other entry point) reads queue 0 and
    /// appends to queue 1, parity 1 the other way round.
    pub bind_groups: Vec<wgpu::BindGroup>,
    /// Group 2 of `permute_rays` reading state buffer `s`: it writes state buffer `1 - s`.
    /// Empty without `permute`.
    pub permute_bind_groups: Vec<wgpu::BindGroup>,
    /// The ray states (the second only with `permute`, else a placeholder).
    pub ray_states: [wgpu::Buffer; 2],
    /// The wavefront's ray queues, sort keys and queue lengths (see `WavefrontBuffers`).
    pub ray_queues: [wgpu::Buffer; 2],
    pub ray_keys: wgpu::Buffer,
    pub queue_counts: wgpu::Buffer,
    /// Group 2 of `prepare_propagate`: the dispatch size it writes.
    pub args_bind_group: wgpu::BindGroup,
    /// The bounce uniforms last written (`write_bounces` skips rewriting the same).
    written: Option<(u32, Reorder, u32)>,
}

fn entry(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}

/// The layouts `WorkBuffers::new` builds bind groups for: group 1, `prepare_propagate`'s group
/// 2 and `permute_rays`' group 2.
pub(crate) struct WorkLayouts<'l> {
    pub work: &'l wgpu::BindGroupLayout,
    pub args: &'l wgpu::BindGroupLayout,
    pub permute: &'l wgpu::BindGroupLayout,
}

impl WorkBuffers {
    pub fn new(
        ctx: &GpuContext,
        layouts: WorkLayouts<'_>,
        key: WorkKey,
    ) -> Result<Self, KernelError> {
        let rays = u64::from(key.capacity);
        // Buffers a schedule does not use get a minimal placeholder.
        let per_ray = |used: bool, bytes: u64| if used { rays * bytes } else { bytes };
        let wavefront = key.wavefront;
        let state_bytes = size_of::<RayState>() as u64;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let ray_states = [
            ctx.storage_buffer_zeroed("ray states", per_ray(wavefront, state_bytes), copy)?,
            ctx.storage_buffer_zeroed(
                "permuted ray states",
                per_ray(wavefront && key.permute, state_bytes),
                copy,
            )?,
        ];
        let sample_radiance = ctx.storage_buffer_zeroed("sample radiance", rays * 12, copy)?;
        let ray_queues = [
            ctx.storage_buffer_zeroed("ray queue 0", per_ray(wavefront, 4), copy)?,
            ctx.storage_buffer_zeroed("ray queue 1", per_ray(wavefront, 4), copy)?,
        ];
        let ray_keys = ctx.storage_buffer_zeroed("ray sort keys", per_ray(wavefront, 4), copy)?;
        // The wavefront's deferred light samples or shadow rays (a placeholder without
        // them), kept alive by the bind groups.
        let nee_records = ctx.storage_buffer_zeroed(
            "deferred light samples",
            per_ray(
                wavefront && key.record_words > 0,
                16 * u64::from(key.record_words),
            ),
            copy,
        )?;
        // The walk stage's hits (a placeholder without it).
        let queue_hits = ctx.storage_buffer_zeroed(
            "walk stage hits",
            per_ray(wavefront && key.walk_stage, 16),
            copy,
        )?;
        let queue_counts = ctx.storage_buffer_zeroed("queue counts", 32, copy)?;
        // propagate's dispatch size (words 0-2), the walk stage's (words 4-6).
        let dispatch_args =
            ctx.storage_buffer_zeroed("propagate dispatch size", 32, wgpu::BufferUsages::INDIRECT)?;
        let accumulation =
            ctx.storage_buffer_zeroed("the accumulation image", u64::from(key.pixels) * 12, copy)?;
        let batch_stats =
            ctx.storage_buffer_zeroed("batch statistics", u64::from(key.batches) * 16, copy)?;
        let bounce_stride = ctx
            .limits
            .min_uniform_buffer_offset_alignment
            .max(size_of::<BounceUniforms>() as u32);
        let bounce = ctx.scoped("creating the bounce uniforms", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raylume bounce uniforms"),
                size: u64::from(key.bounces) * u64::from(bounce_stride),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        let state_sets = if wavefront && key.permute { 2 } else { 1 };
        let (bind_groups, permute_bind_groups, args_bind_group) =
            ctx.scoped("creating the work bind groups", || {
                let mut groups = Vec::new();
                for (s, states) in ray_states.iter().enumerate().take(state_sets) {
                    for parity in 0..2 {
                        groups.push(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                            label: Some(match (s, parity) {
                                (0, 0) => "raylume work (even bounces)",
                                (0, _) => "raylume work (odd bounces)",
                                (_, 0) => "raylume work (even bounces, permuted states)",
                                _ => "raylume work (odd bounces, permuted states)",
                            }),
                            layout: layouts.work,
                            entries: &[
                                entry(0, states),
                                entry(1, &sample_radiance),
                                entry(2, &ray_queues[parity]),
                                entry(3, &ray_keys),
                                entry(4, &queue_counts),
                                entry(5, &ray_queues[1 - parity]),
                                entry(6, &accumulation),
                                entry(7, &batch_stats),
                                entry(9, &nee_records),
                                entry(10, &queue_hits),
                                wgpu::BindGroupEntry {
                                    binding: 8,
                                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                        buffer: &bounce,
                                        offset: 0,
                                        size: wgpu::BufferSize::new(
                                            size_of::<BounceUniforms>() as u64
                                        ),
                                    }),
                                },
                            ],
                        }));
                    }
                }
                let permuting = if state_sets == 2 { 0..2 } else { 0..0 };
                let permute = permuting
                    .map(|s| {
                        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                            label: Some("raylume permuted ray states"),
                            layout: layouts.permute,
                            entries: &[entry(1, &ray_states[1 - s])],
                        })
                    })
                    .collect();
                let args = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("raylume propagate dispatch size"),
                    layout: layouts.args,
                    entries: &[entry(0, &dispatch_args)],
                });
                (groups, permute, args)
            })?;
        // Clear everything now: wgpu zeroes a buffer lazily on its first use, which would
        // otherwise land in the first (timed) batch of a render.
        ctx.scoped("clearing the work buffers", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            for b in ray_states.iter().chain(&ray_queues).chain([
                &ray_keys,
                &queue_counts,
                &nee_records,
                &queue_hits,
                &sample_radiance,
                &accumulation,
                &batch_stats,
            ]) {
                enc.clear_buffer(b, 0, None);
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        Ok(Self {
            key,
            sample_radiance,
            args_bind_group,
            bind_groups,
            permute_bind_groups,
            ray_states,
            ray_queues,
            ray_keys,
            queue_counts,
            accumulation,
            batch_stats,
            dispatch_args,
            bounce,
            bounce_stride,
            written: None,
        })
    }

    /// Clears the image and the statistics.
    pub fn reset(&mut self, ctx: &GpuContext) -> Result<(), KernelError> {
        ctx.scoped("clearing the image", || {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            enc.clear_buffer(&self.accumulation, 0, None);
            enc.clear_buffer(&self.batch_stats, 0, None);
            ctx.queue.submit([enc.finish()]);
        })?;
        self.written = None;
        Ok(())
    }

    /// Writes the bounce uniforms of a batch with `max_bounces` bounces sorted as `reorder`
    /// says (queued before the next submission), unless they are already there.
    pub fn write_bounces(
        &mut self,
        ctx: &GpuContext,
        max_bounces: u32,
        reorder: Reorder,
        walk_groups: u32,
    ) {
        if self.written == Some((max_bounces, reorder, walk_groups)) {
            return;
        }
        let stride = self.bounce_stride as usize;
        let mut bytes = vec![0u8; (max_bounces as usize + 1) * stride];
        for depth in 0..=max_bounces {
            let sort_next = depth < max_bounces && reorder.sorts_before(depth + 1);
            let u = BounceUniforms {
                depth,
                sort_next: u32::from(sort_next),
                sort_shift: if sort_next {
                    raylume_sort::RAY_KEY_BITS - reorder.key_bits
                } else {
                    0
                },
                // Where the bounce has no walk stage, 0: propagate walks its rays itself.
                walk_groups: if super::batch::walk_stage_at(reorder, depth) {
                    walk_groups
                } else {
                    0
                },
            };
            let at = depth as usize * stride;
            bytes[at..at + size_of::<BounceUniforms>()].copy_from_slice(bytemuck::bytes_of(&u));
        }
        ctx.queue.write_buffer(&self.bounce, 0, &bytes);
        self.written = Some((max_bounces, reorder, walk_groups));
    }
}
