//! Timing the stages of a batch: GPU timestamps when the adapter has them, else the wall
//! clock around a wait per stage.

use std::time::Instant;

use raylume_gpu::{GpuContext, Timestamps, wgpu};

use crate::KernelError;

/// A stage of a batch: its name and how to record it into a compute pass.
pub(crate) type Stage<'s> = (&'static str, &'s dyn Fn(&mut wgpu::ComputePass<'_>));

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
            timestamps: Timestamps::new(ctx, 4),
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

    /// Records, submits and waits for `stages`.
    pub fn run(&mut self, during: &str, stages: &[Stage<'_>]) -> Result<(), KernelError> {
        let ctx = self.ctx;
        if let Some(ts) = self.timestamps.as_mut() {
            ctx.scoped(during, || {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                for (label, record) in stages {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(label),
                        timestamp_writes: ts.writes(label),
                    });
                    record(&mut pass);
                }
                ts.resolve(&mut enc);
                ctx.queue.submit([enc.finish()]);
            })?;
            let times = ts.read(ctx)?;
            for (label, t) in times {
                self.add(label, t);
            }
        } else {
            for (label, record) in stages {
                let t = Instant::now();
                ctx.scoped(during, || {
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    {
                        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some(label),
                            timestamp_writes: None,
                        });
                        record(&mut pass);
                    }
                    ctx.queue.submit([enc.finish()]);
                })?;
                ctx.wait(during)?;
                self.add(label, t.elapsed().as_secs_f64());
            }
        }
        Ok(())
    }
}
