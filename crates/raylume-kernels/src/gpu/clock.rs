//! Timing the stages of a batch: GPU timestamps when the adapter has them, else the wall
//! clock around a wait per stage.

use std::time::Instant;

use raylume_gpu::{GpuContext, Timestamps, wgpu};

use crate::KernelError;

/// Compute passes (two timestamps each) per submission; a batch with more stages (thousands
/// of bounces) is split into several submissions.
const MAX_TIMED_PASSES: u32 = 1024;

/// Records a stage that makes its own compute pass (ray sorting), given the timestamps for
/// exactly one pass labelled with the stage's label.
pub(crate) type EncoderFn<'s> =
    Box<dyn Fn(&mut wgpu::CommandEncoder, Option<&mut Timestamps>) -> Result<(), KernelError> + 's>;

/// How a stage is recorded.
pub(crate) enum Record<'s> {
    /// Into one compute pass of its own.
    Pass(Box<dyn Fn(&mut wgpu::ComputePass<'_>) + 's>),
    /// Into the encoder, as one compute pass it begins itself.
    Encoder(EncoderFn<'s>),
    /// Into the encoder, untimed (copies for tests).
    Untimed(Box<dyn Fn(&mut wgpu::CommandEncoder) + 's>),
}

/// A stage of a batch: its name, the bounce it belongs to, and how to record it.
pub(crate) struct Stage<'s> {
    pub label: &'static str,
    pub depth: Option<u32>,
    pub record: Record<'s>,
    /// Submit what is recorded so far after this stage, so that the GPU starts on it while
    /// the CPU records the rest (ray sorting takes ~0.1 ms of CPU time per sort to record).
    pub submit_after: bool,
}

impl<'s> Stage<'s> {
    pub fn pass(
        label: &'static str,
        depth: Option<u32>,
        f: impl Fn(&mut wgpu::ComputePass<'_>) + 's,
    ) -> Self {
        Self {
            label,
            depth,
            record: Record::Pass(Box::new(f)),
            submit_after: false,
        }
    }
}

/// One timed stage of one batch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageTime {
    /// The pass: `raygen`, `propagate`, `sort_keys`, `permute_rays`, `trace_paths`, `resolve`.
    pub label: &'static str,
    /// The bounce (segment) it belongs to: for `sort_keys` and `permute_rays`, the bounce
    /// whose rays they reorder.
    pub depth: Option<u32>,
    pub seconds: f64,
}

/// Times named stages: with GPU timestamps, all stages of a batch go into one submission, a
/// pass each; without, each stage is submitted and waited for on its own and timed by the
/// wall clock.
pub(crate) struct StageClock<'c> {
    ctx: &'c GpuContext,
    timestamps: Option<Timestamps>,
    totals: Vec<(&'static str, f64)>,
}

impl<'c> StageClock<'c> {
    pub fn new(ctx: &'c GpuContext) -> Self {
        Self {
            ctx,
            timestamps: Timestamps::new(ctx, MAX_TIMED_PASSES),
            totals: Vec::new(),
        }
    }

    fn add(&mut self, label: &'static str, seconds: f64) {
        match self.totals.iter_mut().find(|(l, _)| *l == label) {
            Some((_, t)) => *t += seconds,
            None => self.totals.push((label, seconds)),
        }
    }

    pub fn total(&self, label: &str) -> Option<f64> {
        self.totals
            .iter()
            .find(|(l, _)| *l == label)
            .map(|(_, t)| *t)
    }

    /// Records, submits and waits for `stages`; returns each timed stage's time.
    pub fn run(
        &mut self,
        during: &str,
        stages: &[Stage<'_>],
    ) -> Result<Vec<StageTime>, KernelError> {
        let ctx = self.ctx;
        let mut out = Vec::with_capacity(stages.len());
        if let Some(ts) = self.timestamps.as_mut() {
            let mut rest = stages;
            while !rest.is_empty() {
                // As many stages as fit the timestamps of one submission.
                let mut take = 0;
                let mut timed = 0;
                while take < rest.len() {
                    let t = u32::from(!matches!(rest[take].record, Record::Untimed(_)));
                    if timed + t > MAX_TIMED_PASSES {
                        break;
                    }
                    timed += t;
                    take += 1;
                }
                let (chunk, after) = rest.split_at(take);
                rest = after;
                let recorded = ctx.scoped(during, || -> Result<(), KernelError> {
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    for (i, stage) in chunk.iter().enumerate() {
                        match &stage.record {
                            Record::Pass(record) => {
                                let mut pass =
                                    enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                                        label: Some(stage.label),
                                        timestamp_writes: ts.writes(stage.label),
                                    });
                                record(&mut pass);
                            }
                            Record::Encoder(record) => record(&mut enc, Some(&mut *ts))?,
                            Record::Untimed(record) => record(&mut enc),
                        }
                        if stage.submit_after && i + 1 < chunk.len() {
                            // The timestamps are resolved at the end, in the last submission.
                            let done = std::mem::replace(
                                &mut enc,
                                ctx.device.create_command_encoder(&Default::default()),
                            );
                            ctx.queue.submit([done.finish()]);
                        }
                    }
                    ts.resolve(&mut enc);
                    ctx.queue.submit([enc.finish()]);
                    Ok(())
                })?;
                recorded?;
                let times = ts.read(ctx)?;
                let timed: Vec<&Stage<'_>> = chunk
                    .iter()
                    .filter(|s| !matches!(s.record, Record::Untimed(_)))
                    .collect();
                debug_assert_eq!(times.len(), timed.len());
                for (stage, (label, t)) in timed.iter().zip(times) {
                    debug_assert_eq!(stage.label, label);
                    out.push(StageTime {
                        label: stage.label,
                        depth: stage.depth,
                        seconds: t,
                    });
                }
            }
        } else {
            for stage in stages {
                let t = Instant::now();
                let recorded = ctx.scoped(during, || -> Result<(), KernelError> {
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    match &stage.record {
                        Record::Pass(record) => {
                            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                                label: Some(stage.label),
                                timestamp_writes: None,
                            });
                            record(&mut pass);
                        }
                        Record::Encoder(record) => record(&mut enc, None)?,
                        Record::Untimed(record) => record(&mut enc),
                    }
                    ctx.queue.submit([enc.finish()]);
                    Ok(())
                })?;
                recorded?;
                ctx.wait(during)?;
                if !matches!(stage.record, Record::Untimed(_)) {
                    out.push(StageTime {
                        label: stage.label,
                        depth: stage.depth,
                        seconds: t.elapsed().as_secs_f64(),
                    });
                }
            }
        }
        for s in &out {
            self.add(s.label, s.seconds);
        }
        Ok(out)
    }
}
