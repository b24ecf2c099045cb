//! [`RadixSorter::encode`]: records a sort into the caller's command encoder.

use raylume_gpu::{GpuContext, Timestamps};
use wgpu::util::DeviceExt;

use super::SortLen;
use super::shader::Stage;
use super::sorter::{RadixSorter, bind_group, entire};
use crate::SortError;

impl RadixSorter {
    /// Records the sort of the first `len` pairs of `keys` and `values` into `encoder`, as one
    /// compute pass labelled `sort_keys` (timestamped when `timestamps` is given; with
    /// [`SortOptions::stage_timestamps`](crate::SortOptions::stage_timestamps), one pass and timestamp per kernel instead, labelled
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
            bind_group(&self.device, pipeline, label, entries)
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
