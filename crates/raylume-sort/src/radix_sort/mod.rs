//! GPU radix sort of `(u32 key, u32 value)` pairs: LSD, stable, reduce-then-scan.
//!
//! Per pass of `radix_bits` bits, three kernels over tiles of `workgroup_size *
//! items_per_thread` keys (Merrill & Grimshaw's reduce-then-scan; the tile ranking is Onesweep's
//! warp-level multi-split, Adinets & Merrill 2022):
//! 1. `sort_upsweep`: each tile's digit histogram, stored digit-major `[digit][tile]`;
//! 2. `sort_scan`: one workgroup per digit scans its row over the tiles (exclusive) and writes
//!    the digit's total;
//! 3. `sort_downsweep`: each tile ranks its keys stably within their digit (subgroup ballots,
//!    or shared-memory binary splits without subgroups), adds the digit's global offset (an
//!    exclusive scan of the totals, recomputed per workgroup) and its tiles-before count, and
//!    scatters keys and values through shared memory so that writes are coalesced.
//!
//! A one-thread `sort_setup` kernel first reads the element count from a GPU buffer and writes
//! the tile grid's indirect dispatch arguments, so that a count computed on the GPU (the live
//! rays) needs no read-back. No kernel waits on another workgroup (no decoupled look-back), so
//! the sort cannot dead-lock on adapters without forward-progress guarantees.

mod gpu_types;
mod options;
mod shader;

pub use gpu_types::{SortParams, SortPass};
pub use options::{SortOptions, SortPlan};
pub use shader::Stage;

use raylume_gpu::{GpuContext, Timestamps};
use wgpu::util::DeviceExt;

use crate::SortError;

/// How many pairs [`RadixSorter::encode`] sorts.
#[derive(Clone, Copy, Debug)]
pub enum SortLen<'a> {
    /// A count known on the CPU (at most the sorter's `max_len`).
    Fixed(u32),
    /// A count the GPU wrote: the `u32` at byte `offset` of `count_buffer` (which needs
    /// `BufferUsages::COPY_SRC`; `offset` a multiple of 4). It is read when the commands run
    /// and clamped to the sorter's `max_len`.
    Indirect {
        count_buffer: &'a wgpu::Buffer,
        offset: u64,
    },
}

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
    device: wgpu::Device,
    plan: SortPlan,
    max_len: u32,
    pipelines: [wgpu::ComputePipeline; 5],
    alt_keys: wgpu::Buffer,
    alt_values: wgpu::Buffer,
    tile_hist: wgpu::Buffer,
    digit_total: wgpu::Buffer,
    params: wgpu::Buffer,
    dispatch_args: wgpu::Buffer,
    count_slot: wgpu::Buffer,
    passes: wgpu::Buffer,
    pass_stride: u64,
    setup_bind_group: wgpu::BindGroup,
    scan_bind_group: wgpu::BindGroup,
}

impl std::fmt::Debug for RadixSorter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RadixSorter")
            .field("plan", &self.plan)
            .field("max_len", &self.max_len)
            .finish()
    }
}

fn entire(buffer: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
    buffer.as_entire_binding()
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
        let max_tiles = max_len.div_ceil(plan.tile);
        let grid_rows = max_tiles.div_ceil(plan.max_grid_x);
        if grid_rows > ctx.limits.max_compute_workgroups_per_dimension {
            return Err(SortError::InvalidOptions(format!(
                "{max_len} pairs need {max_tiles} tiles of {}, more than a {} x {} dispatch grid",
                plan.tile, plan.max_grid_x, ctx.limits.max_compute_workgroups_per_dimension
            )));
        }
        let hist_bytes = u64::from(plan.radix) * u64::from(max_tiles) * 4;
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
                    size: bytes.max(16).div_ceil(16) * 16,
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
                let setup_bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("sort_setup"),
                    layout: &setup.get_bind_group_layout(0),
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: entire(&count_slot),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: entire(&params),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: entire(&dispatch_args),
                        },
                    ],
                });
                let scan_bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("sort_scan"),
                    layout: &scan.get_bind_group_layout(0),
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: entire(&params),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: entire(&tile_hist),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: entire(&digit_total),
                        },
                    ],
                });
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
    fn grid(&self, n: u32) -> (u32, u32) {
        let tiles = n.div_ceil(self.plan.tile);
        let x = tiles.min(self.plan.max_grid_x);
        let y = if x == 0 { 0 } else { tiles.div_ceil(x) };
        (x, y)
    }

    /// What runs on this adapter: workgroup size, tile, passes, subgroups or not.
    pub fn plan(&self) -> &SortPlan {
        &self.plan
    }

    /// Records the sort of the first `len` pairs of `keys` and `values` into `encoder`, as one
    /// compute pass labelled `sort_keys` (timestamped when `timestamps` is given; with
    /// [`SortOptions::stage_timestamps`], one pass and timestamp per kernel instead, labelled
    /// by its entry point, `2 + 3 * passes` of them plus `sort_copy` after an odd count). The sorted
    /// pairs end up back in `keys` and `values` (after an odd number of passes a final
    /// `sort_copy` kernel moves them back from the scratch buffers).
    ///
    /// `keys` and `values` need `BufferUsages::STORAGE` and room for `len` words
    /// (`max_len` words for [`SortLen::Indirect`], whose count is only known on the GPU).
    /// Keys keep their bits above `key_bits`; only the low `key_bits` decide the order, and
    /// pairs with equal low bits keep their input order.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        keys: &wgpu::Buffer,
        values: &wgpu::Buffer,
        len: SortLen<'_>,
        timestamps: Option<&mut Timestamps>,
    ) -> Result<(), SortError> {
        let words = match len {
            SortLen::Fixed(n) => {
                if n > self.max_len {
                    return Err(SortError::TooLong {
                        len: u64::from(n),
                        max_len: self.max_len,
                    });
                }
                n
            }
            SortLen::Indirect { .. } => self.max_len,
        };
        check_buffer("keys", keys, words)?;
        check_buffer("values", values, words)?;
        match len {
            SortLen::Fixed(0) => return Ok(()),
            SortLen::Fixed(n) => {
                let src = self
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("sort fixed count"),
                        contents: bytemuck::bytes_of(&n),
                        usage: wgpu::BufferUsages::COPY_SRC,
                    });
                encoder.copy_buffer_to_buffer(&src, 0, &self.count_slot, 0, 4);
            }
            SortLen::Indirect {
                count_buffer,
                offset,
            } => {
                let problem = if !count_buffer.usage().contains(wgpu::BufferUsages::COPY_SRC) {
                    Some("lacks BufferUsages::COPY_SRC".to_string())
                } else if offset % 4 != 0 || offset + 4 > count_buffer.size() {
                    Some(format!(
                        "has {} bytes; offset {offset} must be a multiple of 4 with 4 bytes after it",
                        count_buffer.size()
                    ))
                } else {
                    None
                };
                if let Some(problem) = problem {
                    return Err(SortError::BadBuffer {
                        which: "count",
                        problem,
                    });
                }
                encoder.copy_buffer_to_buffer(count_buffer, offset, &self.count_slot, 0, 4);
            }
        }

        let [setup, upsweep, scan, downsweep, copy] = &self.pipelines;
        let bind = |pipeline: &wgpu::ComputePipeline,
                    label: &str,
                    entries: &[(u32, wgpu::BindingResource<'_>)]| {
            let entries: Vec<wgpu::BindGroupEntry<'_>> = entries
                .iter()
                .map(|(binding, resource)| wgpu::BindGroupEntry {
                    binding: *binding,
                    resource: resource.clone(),
                })
                .collect();
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            })
        };
        let pass_binding = |p: u32| {
            wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.passes,
                offset: u64::from(p) * self.pass_stride,
                size: wgpu::BufferSize::new(16),
            })
        };
        let mut groups = Vec::with_capacity(self.plan.passes as usize);
        for p in 0..self.plan.passes {
            let (kin, vin, kout, vout) = if p % 2 == 0 {
                (keys, values, &self.alt_keys, &self.alt_values)
            } else {
                (&self.alt_keys, &self.alt_values, keys, values)
            };
            let up = bind(
                upsweep,
                "sort_upsweep",
                &[
                    (0, entire(&self.params)),
                    (1, pass_binding(p)),
                    (2, entire(kin)),
                    (3, entire(&self.tile_hist)),
                ],
            );
            let down = bind(
                downsweep,
                "sort_downsweep",
                &[
                    (0, entire(&self.params)),
                    (1, pass_binding(p)),
                    (2, entire(kin)),
                    (3, entire(vin)),
                    (4, entire(kout)),
                    (5, entire(vout)),
                    (6, entire(&self.tile_hist)),
                    (7, entire(&self.digit_total)),
                ],
            );
            groups.push((up, down));
        }
        let copy_group = (self.plan.passes % 2 == 1).then(|| {
            bind(
                copy,
                "sort_copy",
                &[
                    (0, entire(&self.params)),
                    (2, entire(&self.alt_keys)),
                    (3, entire(&self.alt_values)),
                    (4, entire(keys)),
                    (5, entire(values)),
                ],
            )
        });

        // A count known here gets direct dispatches of the same grid `sort_setup` computes;
        // a GPU count gets indirect ones from `dispatch_args`.
        let grid = match len {
            SortLen::Fixed(n) => Some(self.grid(n)),
            SortLen::Indirect { .. } => None,
        };
        enum Size {
            One,
            Tiles,
            Digits,
        }
        let mut steps: Vec<(Stage, &wgpu::ComputePipeline, &wgpu::BindGroup, Size)> =
            vec![(Stage::Setup, setup, &self.setup_bind_group, Size::One)];
        for (up, down) in &groups {
            steps.push((Stage::Upsweep, upsweep, up, Size::Tiles));
            steps.push((Stage::Scan, scan, &self.scan_bind_group, Size::Digits));
            steps.push((Stage::Downsweep, downsweep, down, Size::Tiles));
        }
        if let Some(group) = &copy_group {
            steps.push((Stage::Copy, copy, group, Size::Tiles));
        }
        let record = |pass: &mut wgpu::ComputePass<'_>,
                      (_, pipeline, group, size): &(
            Stage,
            &wgpu::ComputePipeline,
            &wgpu::BindGroup,
            Size,
        )| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, *group, &[]);
            match (size, grid) {
                (Size::One, _) => pass.dispatch_workgroups(1, 1, 1),
                (Size::Digits, _) => pass.dispatch_workgroups(self.plan.radix, 1, 1),
                (Size::Tiles, Some((x, y))) => pass.dispatch_workgroups(x, y, 1),
                (Size::Tiles, None) => pass.dispatch_workgroups_indirect(&self.dispatch_args, 0),
            }
        };
        match timestamps {
            Some(ts) if self.plan.stage_timestamps => {
                for step in &steps {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(step.0.entry_point()),
                        timestamp_writes: ts.writes(step.0.entry_point()),
                    });
                    record(&mut pass, step);
                }
            }
            ts => {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("sort_keys"),
                    timestamp_writes: ts.and_then(|t| t.writes("sort_keys")),
                });
                for step in &steps {
                    record(&mut pass, step);
                }
            }
        }
        Ok(())
    }

    /// Uploads `keys` and `values`, sorts them with this sorter and reads them back (for tests
    /// and small jobs; the tracer uses [`RadixSorter::encode`] on its own buffers).
    pub fn sort_pairs(
        &self,
        ctx: &GpuContext,
        keys: &[u32],
        values: &[u32],
    ) -> Result<(Vec<u32>, Vec<u32>), SortError> {
        if keys.len() != values.len() {
            return Err(SortError::LengthMismatch {
                keys: keys.len(),
                values: values.len(),
            });
        }
        let n = u32::try_from(keys.len())
            .ok()
            .filter(|&n| n <= self.max_len)
            .ok_or(SortError::TooLong {
                len: keys.len() as u64,
                max_len: self.max_len,
            })?;
        let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let kbuf = ctx.storage_buffer("sort_pairs keys", keys, usage)?;
        let vbuf = ctx.storage_buffer("sort_pairs values", values, usage)?;
        let encoded = ctx.scoped("sort_pairs", || {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let r = self.encode(&mut encoder, &kbuf, &vbuf, SortLen::Fixed(n), None);
            ctx.queue.submit([encoder.finish()]);
            r
        })?;
        encoded?;
        let k = ctx.read_buffer(&kbuf, keys.len())?;
        let v = ctx.read_buffer(&vbuf, values.len())?;
        Ok((k, v))
    }
}

/// Fails unless `buffer` is a storage buffer with room for `words` u32s.
fn check_buffer(which: &'static str, buffer: &wgpu::Buffer, words: u32) -> Result<(), SortError> {
    if !buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
        return Err(SortError::BadBuffer {
            which,
            problem: "lacks BufferUsages::STORAGE".into(),
        });
    }
    if buffer.size() < u64::from(words) * 4 {
        return Err(SortError::BadBuffer {
            which,
            problem: format!(
                "has {} bytes but needs {}",
                buffer.size(),
                u64::from(words) * 4
            ),
        });
    }
    Ok(())
}

/// Sorts `(key, value)` pairs by the low 30 bits of the key on the GPU ([`SortOptions::ray_keys`]),
/// stably; a convenience for tests that builds a sorter for this one call.
pub fn sort_pairs(
    ctx: &GpuContext,
    keys: &[u32],
    values: &[u32],
) -> Result<(Vec<u32>, Vec<u32>), SortError> {
    sort_pairs_with(ctx, keys, values, SortOptions::ray_keys())
}

/// [`sort_pairs`] with chosen options.
pub fn sort_pairs_with(
    ctx: &GpuContext,
    keys: &[u32],
    values: &[u32],
    opts: SortOptions,
) -> Result<(Vec<u32>, Vec<u32>), SortError> {
    let len = u32::try_from(keys.len()).map_err(|_| SortError::TooLong {
        len: keys.len() as u64,
        max_len: u32::MAX,
    })?;
    let sorter = RadixSorter::new(ctx, len, opts)?;
    sorter.sort_pairs(ctx, keys, values)
}
