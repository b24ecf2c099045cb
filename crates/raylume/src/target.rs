//! `Tracer::target_error`: rendering until the image's relative error, estimated from the
//! spread of its own batches, is below a target.
//!
//! The measure is `raylume_post::metrics::relative_mse` of the image against the converged
//! one: the mean over pixels and channels of `(x - ref)^2 / (ref^2 + 1e-2)`. Its expectation
//! is the mean of `Var(x) / (ref^2 + 1e-2)`, `x` a pixel channel's mean over the render's
//! samples; both unknowns come from the render itself. After `B` rounds (each `n_b` samples
//! of every pixel, normally `batch_spp`) with round means `m_b` and `N = sum n_b` samples,
//! `Var(x)` is estimated without bias by `sum_b n_b (m_b - m)^2 / ((B - 1) N)`, `m` the
//! pixel's mean: with equal rounds, the sample variance of the round means divided by `B`.
//! `ref` is replaced by `m`. At least 2 rounds are needed; with one there is no estimate.
//! The image estimated is the traced radiance, before post effects (bloom).
//!
//! The rounds are independent with the independent sampler. With the Sobol' samplers they are not: the
//! points of all rounds together are stratified better than independent rounds would be, so
//! the true error is lower than the estimate (the furnace scene of `tests/target_error.rs` at
//! 64x64, 16 rounds, measured once: 1.04x lower with rounds of 16 spp, 1.4x with rounds of
//! 4): there the render stops later than needed rather than earlier (one scene measured; not
//! a proof).

use raylume_kernels::batches::{RoundFlow, RoundSums};
use raylume_post::metrics::RELATIVE_MSE_EPS;

/// Each pixel channel's weighted mean and sum of squared deviations of the round means
/// (West's 1979 weighted update, in `f64`), and the running sums of the last round.
pub(crate) struct RoundStats {
    previous: Vec<[f32; 3]>,
    mean: Vec<[f64; 3]>,
    m2: Vec<[f64; 3]>,
    samples: f64,
    rounds: u32,
}

impl RoundStats {
    pub fn new(pixels: usize) -> Self {
        Self {
            previous: vec![[0.0; 3]; pixels],
            mean: vec![[0.0; 3]; pixels],
            m2: vec![[0.0; 3]; pixels],
            samples: 0.0,
            rounds: 0,
        }
    }

    /// Takes one round: its means are the growth of the running sums over its samples (the
    /// difference of two `f32` sums is exact in `f64`).
    pub fn add(&mut self, r: &RoundSums<'_>) {
        let n = f64::from(r.round_samples);
        self.samples += n;
        let w = n / self.samples;
        for (((sum, prev), mean), m2) in r
            .sums
            .iter()
            .zip(&mut self.previous)
            .zip(&mut self.mean)
            .zip(&mut self.m2)
        {
            for c in 0..3 {
                let m_b = (f64::from(sum[c]) - f64::from(prev[c])) / n;
                let delta = m_b - mean[c];
                mean[c] += delta * w;
                m2[c] += n * delta * (m_b - mean[c]);
            }
            *prev = *sum;
        }
        self.rounds += 1;
    }

    /// The estimated relative MSE of the image so far; `None` before the second round.
    pub fn estimate(&self) -> Option<f64> {
        if self.rounds < 2 {
            return None;
        }
        let scale = 1.0 / (f64::from(self.rounds - 1) * self.samples);
        let total: f64 = self
            .mean
            .iter()
            .zip(&self.m2)
            .map(|(mean, m2)| {
                (0..3)
                    .map(|c| m2[c] * scale / (mean[c] * mean[c] + RELATIVE_MSE_EPS))
                    .sum::<f64>()
            })
            .sum();
        Some(total / (3 * self.mean.len()).max(1) as f64)
    }
}

/// One render's run toward a target error: the statistics and where it stopped.
pub(crate) struct TargetRun {
    pub target: f32,
    stats: RoundStats,
    /// The estimate after the last round traced.
    pub estimate: Option<f64>,
    pub reached: bool,
    pub rounds: u32,
    pub spp_done: u32,
}

impl TargetRun {
    pub fn new(target: f32, pixels: usize) -> Self {
        Self {
            target,
            stats: RoundStats::new(pixels),
            estimate: None,
            reached: false,
            rounds: 0,
            spp_done: 0,
        }
    }

    /// The round hook: stops at the first round whose estimate is below the target.
    pub fn on_round(&mut self, r: &RoundSums<'_>) -> RoundFlow {
        self.stats.add(r);
        self.rounds = r.round;
        self.spp_done = r.samples_done;
        self.estimate = self.stats.estimate();
        if self.estimate.is_some_and(|e| e < f64::from(self.target)) {
            self.reached = true;
            RoundFlow::Stop
        } else {
            RoundFlow::Continue
        }
    }
}
