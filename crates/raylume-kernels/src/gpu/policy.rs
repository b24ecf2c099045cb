//! What each batch of a GPU render runs ([`BatchPlan`]), who decides it ([`BatchPolicy`]), and
//! what each batch cost ([`BatchTiming`], [`DepthTiming`]): the measurements a reordering policy
//! decides from.

use crate::batches::Batch;
use crate::{Reorder, Schedule, TraceSettings};

pub use super::clock::StageTime;

/// The schedule and reordering of one batch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct BatchPlan {
    pub schedule: Schedule,
    pub reorder: Reorder,
}

impl BatchPlan {
    /// The plan `settings` ask for.
    pub const fn of(settings: &TraceSettings) -> Self {
        Self {
            schedule: settings.schedule,
            reorder: settings.reorder,
        }
    }

    /// True when some bounce of a render with `max_bounces` is sorted (wavefront only).
    pub fn sorts(&self, max_bounces: u32) -> bool {
        self.schedule == Schedule::Wavefront && self.reorder.sorts_any(max_bounces)
    }

    /// `"megakernel"`, `"wavefront"` or e.g. `"wavefront, sort-index before depths 1..=10"`.
    pub fn describe(&self, max_bounces: u32) -> String {
        if self.sorts(max_bounces) {
            format!(
                "{}, {}",
                self.schedule.name(),
                self.reorder.describe(max_bounces)
            )
        } else {
            self.schedule.name().to_string()
        }
    }
}

/// What one batch cost.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchTiming {
    /// Its index in the render's batches.
    pub index: usize,
    pub batch: Batch,
    /// True when it holds as many rays as the largest batch of the render (the batches a
    /// policy can compare).
    pub full: bool,
    pub plan: BatchPlan,
    /// Wall-clock seconds from recording its commands to having its timings back (what the
    /// batch adds to the render's `trace` time).
    pub wall_seconds: f64,
    /// Its GPU stages (timestamps, or the wall clock around each stage without them).
    pub stages: Vec<StageTime>,
}

impl BatchTiming {
    /// Seconds of the stages labelled `label` at `depth`.
    pub fn stage_seconds(&self, label: &str, depth: u32) -> f64 {
        self.stages
            .iter()
            .filter(|s| s.label == label && s.depth == Some(depth))
            .map(|s| s.seconds)
            .sum()
    }
}

/// Seconds spent on one bounce depth over a render's batches.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DepthTiming {
    pub depth: u32,
    /// `propagate` (with its `prepare_propagate`, and the walk stage's `trace_hits` and the
    /// shadow stage's `trace_shadows` when the wavefront has them) at this depth.
    pub propagate: f64,
    /// `next_event`: the light samples `propagate` left, when the render samples lights.
    pub next_event: f64,
    /// `sort_keys`: sorting the rays of this depth before they are traced.
    pub sort: f64,
    /// `permute_rays`: moving their states into key order.
    pub permute: f64,
}

/// Chooses each batch's [`BatchPlan`] and sees what each batch cost: how a reordering policy
/// measures candidates on the real batches of a render.
pub trait BatchPolicy {
    /// Every plan [`BatchPolicy::plan`] may return, so that the tracer prepares their
    /// pipelines, buffers and sorter before the timed batches.
    fn candidates(&self) -> Vec<BatchPlan>;
    /// The plan of batch `index` of `batches`.
    fn plan(&mut self, index: usize, batches: &[Batch]) -> BatchPlan;
    /// Called after each batch with what it cost.
    fn observe(&mut self, timing: &BatchTiming);
}

/// The fixed plan of a [`TraceSettings`].
pub(crate) struct Fixed(pub BatchPlan);

impl BatchPolicy for Fixed {
    fn candidates(&self) -> Vec<BatchPlan> {
        vec![self.0]
    }
    fn plan(&mut self, _: usize, _: &[Batch]) -> BatchPlan {
        self.0
    }
    fn observe(&mut self, _: &BatchTiming) {}
}
