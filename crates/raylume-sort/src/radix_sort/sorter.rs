//! [`RadixSorter`]: pipelines and scratch buffers, made once.

use raylume_gpu::GpuContext;
use wgpu::util::DeviceExt;

use super::SortPass;
use super::options::{SortOptions, SortPlan};
use super::shader::{self, Stage};
use crate::SortError;

/// A GPU radix sorter with its pipelines and scratch buffers, made once and reused.
///
/// ```no_run
/// use raylume_sort::{RadixSorter, SortLen, SortOptions};
/// # fn demo(ctx: &raylume_gpu::GpuContext, keys: &wgpu::Buffer, values: &wgpu::Buffer,
/// #         live_count: &wgpu::Buffer) -> Result<(), raylume_sort::SortError> {
/// let sorter = RadixSorter::new(ctx, 1 << 20, SortOptions::ray_keys())?;
/// let mut encoder = ctx.device.create_command_encoder(&Default::default());
/// // Sort as many pairs as the GPU counted into `live_count[0]`.
/// let len = SortLen::Indirect { count_buffer: live_count, offset: 0 };
/// sorter.encode(&mut encoder, keys, values, len, None)?;
/// ctx.queue.submit([encoder.finish()]);
/// # Ok(()) }
/// ```
pub struct RadixSorter {
    pub(super) device: wgpu::Device,
    pub(super) plan: SortPlan,
    pub(super) max_len: u32,
    pub(super) pipelines: [wgpu::ComputePipeline; 5],
    pub(super) alt_keys: wgpu::Buffer,
    pub(super) alt_values: wgpu::Buffer,
    pub(super) tile_hist: wgpu::Buffer,
    pub(super) digit_total: wgpu::Buffer,
    pub(super) params: wgpu::Buffer,
    pub(super) dispatch_args: wgpu::Buffer,
    pub(super) count_slot: wgpu::Buffer,
    pub(super) passes: wgpu::Buffer,
    pub(super) pass_stride: u64,
    pub(super) setup_bind_group: wgpu::BindGroup,
    pub(super) scan_bind_group: wgpu::BindGroup,
}

impl std::fmt::Debug for RadixSorter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RadixSorter")
            .field("plan", &self.plan)
            .field("max_len", &self.max_len)
            .finish()
    }
}

pub(super) fn entire(buffer: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
    buffer.as_entire_binding()
}

/// A bind group of `pipeline`'s group 0 from `(binding, resource)` pairs.
pub(super) fn bind_group(
    device: &wgpu::Device,
    pipeline: &wgpu::ComputePipeline,
    label: &str,
    entries: &[(u32, wgpu::BindingResource<'_>)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = entries
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    })
}

impl RadixSorter {
    /// Compiles the pipelines and allocates scratch for sorts of up to `max_len` pairs (at
    /// least 1): two more key/value buffers of `max_len` words and `2^radix_bits` tile counts
    /// per tile.
    pub fn new(ctx: &GpuContext, max_len: u32, opts: SortOptions) -> Result<Self, SortError> {
        let plan = SortPlan::new(ctx, &opts)?;
        let max_len = max_len.max(1);
        let key_bytes = u64::from(max_len) * 4;
        ctx.check_fits("radix sort keys", key_bytes)?;
        // Kernels index with u32: the end of the last tile and every tile counter must fit.
        if max_len > u32::MAX - plan.tile {
            return Err(SortError::InvalidOptions(format!(
                "max_len {max_len} leaves no room for a tile of {} below 2^32",
                plan.tile
            )));
        }
        let max_tiles = max_len.div_ceil(plan.tile);
        let grid_rows = max_tiles.div_ceil(plan.max_grid_x);
        if grid_rows > ctx.limits.max_compute_workgroups_per_dimension {
            return Err(SortError::InvalidOptions(format!(
                "{max_len} pairs need {max_tiles} tiles of {}, more than a {} x {} dispatch grid",
                plan.tile, plan.max_grid_x, ctx.limits.max_compute_workgroups_per_dimension
            )));
        }
        let hist_bytes = u64::from(plan.radix) * u64::from(max_tiles) * 4;
        if hist_bytes / 4 > u64::from(u32::MAX) {
            return Err(SortError::InvalidOptions(format!(
                "{max_tiles} tiles x {} digits overflow u32 indices",
                plan.radix
            )));
        }
        ctx.check_fits("radix sort tile histograms", hist_bytes)?;

        let pass_stride = u64::from(ctx.limits.min_uniform_buffer_offset_alignment).max(16);
        let mut pass_bytes = vec![0u8; (pass_stride * u64::from(plan.passes)) as usize];
        for p in 0..plan.passes {
            let shift = p * plan.radix_bits;
            let bits = plan.radix_bits.min(plan.key_bits - shift);
            let pass = SortPass {
                shift,
                mask: crate::key_mask(bits),
                index: p,
                _pad: 0,
            };
            let at = (u64::from(p) * pass_stride) as usize;
            pass_bytes[at..at + 16].copy_from_slice(bytemuck::bytes_of(&pass));
        }

        let device = &ctx.device;
        let (pipelines, buffers) = ctx.scoped("creating the radix sorter", || {
            let pipelines = Stage::ALL.map(|stage| {
                let src = shader::module_source(&plan, max_len, stage);
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(stage.entry_point()),
                    source: wgpu::ShaderSource::Wgsl(src.into()),
                });
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(stage.entry_point()),
                    layout: None,
                    module: &module,
                    entry_point: Some(stage.entry_point()),
                    // Every stage initialises the workgroup memory it reads; wgpu's zeroing
                    // would write the whole ~26 KiB per workgroup at every dispatch.
                    compilation_options: wgpu::PipelineCompilationOptions {
                        zero_initialize_workgroup_memory: false,
                        ..Default::default()
                    },
                    cache: None,
                })
            });
            let storage = |label: &str, bytes: u64, extra: wgpu::BufferUsages| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    // Multiples of 4, not 16: a binding of the whole buffer must stay within
                    // max_storage_buffer_binding_size (an H100's is 2^31 - 4 bytes).
                    size: bytes.max(4).div_ceil(4) * 4,
                    usage: wgpu::BufferUsages::STORAGE | extra,
                    mapped_at_creation: false,
                })
            };
            let none = wgpu::BufferUsages::empty();
            let buffers = [
                storage("sort alt keys", key_bytes, wgpu::BufferUsages::COPY_SRC),
                storage("sort alt values", key_bytes, wgpu::BufferUsages::COPY_SRC),
                storage("sort tile histograms", hist_bytes, none),
                storage("sort digit totals", u64::from(plan.radix) * 4, none),
                storage("sort params", 16, wgpu::BufferUsages::UNIFORM),
                storage("sort dispatch args", 16, wgpu::BufferUsages::INDIRECT),
                storage("sort count", 16, wgpu::BufferUsages::COPY_DST),
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("sort passes"),
                    contents: &pass_bytes,
                    usage: wgpu::BufferUsages::UNIFORM,
                }),
            ];
            (pipelines, buffers)
        })?;
        let [
            alt_keys,
            alt_values,
            tile_hist,
            digit_total,
            params,
            dispatch_args,
            count_slot,
            passes,
        ] = buffers;

        let [setup, _, scan, _, _] = &pipelines;
        let (setup_bind_group, scan_bind_group) =
            ctx.scoped("creating the radix sorter", || {
                let setup_bg = bind_group(
                    device,
                    setup,
                    "sort_setup",
                    &[
                        (0, entire(&count_slot)),
                        (1, entire(&params)),
                        (2, entire(&dispatch_args)),
                    ],
                );
                let scan_bg = bind_group(
                    device,
                    scan,
                    "sort_scan",
                    &[
                        (0, entire(&params)),
                        (3, entire(&tile_hist)),
                        (4, entire(&digit_total)),
                    ],
                );
                (setup_bg, scan_bg)
            })?;

        Ok(Self {
            device: ctx.device.clone(),
            plan,
            max_len,
            pipelines,
            alt_keys,
            alt_values,
            tile_hist,
            digit_total,
            params,
            dispatch_args,
            count_slot,
            passes,
            pass_stride,
            setup_bind_group,
            scan_bind_group,
        })
    }

    /// The largest number of pairs one `encode` sorts.
    pub fn max_len(&self) -> u32 {
        self.max_len
    }

    /// The tile grid for `n` pairs, as `sort_setup` computes it on the GPU: (per row, rows).
    pub(super) fn grid(&self, n: u32) -> (u32, u32) {
        let tiles = n.div_ceil(self.plan.tile);
        let x = tiles.min(self.plan.max_grid_x);
        let y = if x == 0 { 0 } else { tiles.div_ceil(x) };
        (x, y)
    }

    /// What runs on this adapter: workgroup size, tile, passes, subgroups or not.
    pub fn plan(&self) -> &SortPlan {
        &self.plan
    }
}
