//! The work buffers of one render size (group 1): ray states, sample slots, queues, keys,
//! the image and the statistics. Reallocated only when the render's size or schedule changes.

use raylume_gpu::{GpuContext, wgpu};

use crate::gpu_types::{BounceUniforms, RayState};
use crate::{KernelError, Schedule};

/// What the buffers were sized for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WorkKey {
    pub schedule: Schedule,
    /// Rays in the largest batch.
    pub capacity: u32,
    pub pixels: u32,
    pub batches: u32,
    /// `max_bounces + 1` entries of bounce uniforms.
    pub bounces: u32,
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
    /// Group 1 of even bounces (and of every other entry point): queue 0 in, queue 1 out;
    /// then odd bounces: queue 1 in, queue 0 out.
    pub bind_groups: [wgpu::BindGroup; 2],
    /// The wavefront's ray queues, sort keys and queue lengths (see `WavefrontBuffers`).
    pub ray_queues: [wgpu::Buffer; 2],
    pub ray_keys: wgpu::Buffer,
    pub queue_counts: wgpu::Buffer,
    /// Group 2 of `prepare_propagate`: the dispatch size it writes.
    pub args_bind_group: wgpu::BindGroup,
}

fn entry(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}

impl WorkBuffers {
    pub fn new(
        ctx: &GpuContext,
        layout: &wgpu::BindGroupLayout,
        args_layout: &wgpu::BindGroupLayout,
        key: WorkKey,
    ) -> Result<Self, KernelError> {
        let rays = u64::from(key.capacity);
        let wavefront = key.schedule == Schedule::Wavefront;
        // Buffers a schedule does not use get a minimal placeholder.
        let per_ray = |bytes: u64| if wavefront { rays * bytes } else { bytes };
        let none = wgpu::BufferUsages::empty();
        let ray_states =
            ctx.storage_buffer_zeroed("ray states", per_ray(size_of::<RayState>() as u64), none)?;
        let sample_radiance =
            ctx.storage_buffer_zeroed("sample radiance", rays * 12, wgpu::BufferUsages::COPY_SRC)?;
        let queue_usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let ray_queues = [
            ctx.storage_buffer_zeroed("ray queue 0", per_ray(4), queue_usage)?,
            ctx.storage_buffer_zeroed("ray queue 1", per_ray(4), queue_usage)?,
        ];
        let ray_keys = ctx.storage_buffer_zeroed("ray sort keys", per_ray(4), queue_usage)?;
        let queue_counts = ctx.storage_buffer_zeroed("queue counts", 16, queue_usage)?;
        let dispatch_args =
            ctx.storage_buffer_zeroed("propagate dispatch size", 16, wgpu::BufferUsages::INDIRECT)?;
        let accumulation = ctx.storage_buffer_zeroed(
            "the accumulation image",
            u64::from(key.pixels) * 12,
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        )?;
        let batch_stats = ctx.storage_buffer_zeroed(
            "batch statistics",
            u64::from(key.batches) * 16,
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        )?;
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
        let bind_groups = ctx.scoped("creating the work bind groups", || {
            [0, 1].map(|parity| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(if parity == 0 {
                        "raylume work (even bounces)"
                    } else {
                        "raylume work (odd bounces)"
                    }),
                    layout,
                    entries: &[
                        entry(0, &ray_states),
                        entry(1, &sample_radiance),
                        entry(2, &ray_queues[parity]),
                        entry(3, &ray_keys),
                        entry(4, &queue_counts),
                        entry(5, &ray_queues[1 - parity]),
                        entry(6, &accumulation),
                        entry(7, &batch_stats),
                        wgpu::BindGroupEntry {
                            binding: 8,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &bounce,
                                offset: 0,
                                size: wgpu::BufferSize::new(size_of::<BounceUniforms>() as u64),
                            }),
                        },
                    ],
                })
            })
        })?;
        let args_bind_group = ctx.scoped("creating the dispatch-size bind group", || {
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raylume propagate dispatch size"),
                layout: args_layout,
                entries: &[entry(0, &dispatch_args)],
            })
        })?;
        Ok(Self {
            key,
            sample_radiance,
            args_bind_group,
            bind_groups,
            ray_queues,
            ray_keys,
            queue_counts,
            accumulation,
            batch_stats,
            dispatch_args,
            bounce,
            bounce_stride,
        })
    }

    /// Clears the image and the statistics and writes the bounce uniforms for a render with
    /// `max_bounces` bounces.
    pub fn reset(&self, ctx: &GpuContext, max_bounces: u32) -> Result<(), KernelError> {
        let stride = self.bounce_stride as usize;
        let mut bytes = vec![0u8; (max_bounces as usize + 1) * stride];
        for depth in 0..=max_bounces {
            let u = BounceUniforms {
                depth,
                ..Default::default()
            };
            let at = depth as usize * stride;
            bytes[at..at + size_of::<BounceUniforms>()].copy_from_slice(bytemuck::bytes_of(&u));
        }
        ctx.scoped("clearing the image", || {
            ctx.queue.write_buffer(&self.bounce, 0, &bytes);
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            enc.clear_buffer(&self.accumulation, 0, None);
            enc.clear_buffer(&self.batch_stats, 0, None);
            ctx.queue.submit([enc.finish()]);
        })?;
        Ok(())
    }
}
