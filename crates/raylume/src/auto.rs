//! `--reorder auto`: choosing the schedule and the ray sorting of a scene from measurement.
//!
//! The candidates are the schedule `off` would run, the other schedule, and the wavefront
//! sorting before every bounce in each [`ReorderMode`]. Each is measured on a *full* batch of
//! a real render (every batch does real work, so nothing is thrown away; the price of a trial
//! is only that a slower candidate runs that batch): the batch's wall-clock time, what it adds
//! to the render's `trace` time, and its per-bounce GPU times. When all are measured, the
//! per-bounce times of the unsorted wavefront and of each sorted one give the depths where
//! sorting paid for itself (sort + permute + sorted `propagate` below unsorted `propagate`);
//! if sorting only there is predicted to beat every measured candidate by more than 1 %, it
//! is measured too. Candidates within 5 % of the best get a second batch (the minimum of two
//! is kept), so that one noisy batch does not decide. The fastest measured plan is then kept
//! for the rest of the render and cached in the [`crate::Tracer`] under a fingerprint of the
//! scene, image size, bounces and batch shape, so later renders of the same scene run it from
//! their first batch.
//!
//! A render shorter than the trials (a 1-spp render is one batch) measures what it can and
//! the next render of the same fingerprint continues where it stopped: the first render runs
//! exactly what `off` runs, and no render does extra work. So `auto` costs nothing over `off`
//! on a scene's first render, and after a few renders (up to 2 x candidates + 1 batches in
//! all) runs the measured best.

use std::collections::VecDeque;
use std::hash::{Hash, Hasher};

use raylume_kernels::batches::Batch;
use raylume_kernels::{
    BatchPlan, BatchPolicy, BatchTiming, Reorder, ReorderMode, Schedule, TraceSettings,
};
use raylume_scene::{Environment, Scene};

/// Candidates within this fraction of the best are measured a second time.
const REMEASURE_WITHIN: f64 = 0.05;
/// A per-depth mask is tried when predicted to beat the best measured plan by this fraction.
const MASK_MIN_GAIN: f64 = 0.01;

/// What `auto` chose for a scene, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoDecision {
    pub plan: BatchPlan,
    /// E.g. `wavefront, sort-index before depths 2..=10 (measured per 1000000-ray batch:
    /// megakernel 3.21 ms, ...)`.
    pub summary: String,
}

/// One candidate's measurements.
#[derive(Clone, Debug)]
struct Trial {
    plan: BatchPlan,
    /// Wall-clock seconds of each full batch it ran.
    seconds: Vec<f64>,
    /// Per depth: `propagate`, and `sort_keys` + `permute_rays` before it, from its first batch.
    depths: Vec<(f64, f64)>,
}

impl Trial {
    fn best(&self) -> Option<f64> {
        self.seconds.iter().copied().reduce(f64::min)
    }
}

/// The measurements and decision of one fingerprint.
#[derive(Clone, Debug)]
pub(crate) struct AutoState {
    max_bounces: u32,
    /// Rays per full batch (set by the first batch seen).
    batch_rays: u32,
    trials: Vec<Trial>,
    /// Plans still to measure, in order.
    queue: VecDeque<BatchPlan>,
    /// Whether the second round (masks, re-measurements) was planned.
    refined: bool,
    decision: Option<AutoDecision>,
    /// The plan that runs batches a trial cannot use (partial ones) before a decision.
    default: BatchPlan,
    /// Plan of the batch in flight, if it is a trial.
    in_flight: Option<BatchPlan>,
    /// Batches this fingerprint ran as trials, and renders that ran any.
    pub trial_batches: u32,
}

impl AutoState {
    /// A fresh state: `off_schedule` first (so a first render runs what `off` runs), then the
    /// other schedule, then the wavefront sorted before every bounce by the top `key_bits` of
    /// the key, in each mode.
    pub fn new(off_schedule: Schedule, max_bounces: u32, key_bits: u32) -> Self {
        let plain = |schedule| BatchPlan {
            schedule,
            reorder: Reorder::OFF,
        };
        let other = match off_schedule {
            Schedule::Megakernel => Schedule::Wavefront,
            Schedule::Wavefront => Schedule::Megakernel,
        };
        let mut queue = VecDeque::from([plain(off_schedule), plain(other)]);
        if max_bounces > 0 {
            for mode in [ReorderMode::SortIndex, ReorderMode::SortPermute] {
                queue.push_back(BatchPlan {
                    schedule: Schedule::Wavefront,
                    reorder: Reorder::every_bounce(mode).with_key_bits(key_bits),
                });
            }
        }
        Self {
            max_bounces,
            batch_rays: 0,
            trials: Vec::new(),
            queue,
            refined: false,
            decision: None,
            default: plain(off_schedule),
            in_flight: None,
            trial_batches: 0,
        }
    }

    pub fn decision(&self) -> Option<&AutoDecision> {
        self.decision.as_ref()
    }

    fn trial_mut(&mut self, plan: BatchPlan) -> &mut Trial {
        if let Some(i) = self.trials.iter().position(|t| t.plan == plan) {
            &mut self.trials[i]
        } else {
            self.trials.push(Trial {
                plan,
                seconds: Vec::new(),
                depths: Vec::new(),
            });
            self.trials.last_mut().expect("pushed")
        }
    }

    /// The measured plan with the shortest batch, and its seconds.
    fn best(&self) -> Option<(BatchPlan, f64)> {
        self.trials
            .iter()
            .filter_map(|t| Some((t.plan, t.best()?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// After the first round: a per-depth mask per sort mode where predicted to pay, and
    /// second batches for the close candidates.
    fn refine(&mut self) {
        self.refined = true;
        let Some((_, best)) = self.best() else { return };
        let unsorted = self
            .trials
            .iter()
            .find(|t| t.plan.schedule == Schedule::Wavefront && !t.plan.sorts(self.max_bounces))
            .cloned();
        if let Some(unsorted) = unsorted {
            let mut masks = Vec::new();
            for t in &self.trials {
                let Some(wall) = t.best() else { continue };
                if !t.plan.sorts(self.max_bounces) || t.depths.len() != unsorted.depths.len() {
                    continue;
                }
                // gain_d: what sorting before depth d saved (negative: what it cost).
                // (Bit 63 also stands for the depths past 63, which follow depth 63.)
                let mut depths = 0u64;
                let mut predicted = wall;
                for d in 1..=self.max_bounces.min(63) as usize {
                    let (Some(&(p_off, _)), Some(&(p_on, s_on))) =
                        (unsorted.depths.get(d), t.depths.get(d))
                    else {
                        continue;
                    };
                    let gain = p_off - (p_on + s_on);
                    if gain > 0.0 {
                        depths |= 1 << d;
                    } else {
                        predicted += gain;
                    }
                }
                let plan = BatchPlan {
                    schedule: Schedule::Wavefront,
                    reorder: Reorder {
                        depths,
                        ..t.plan.reorder
                    },
                };
                if plan.sorts(self.max_bounces)
                    && plan != t.plan
                    && predicted < best * (1.0 - MASK_MIN_GAIN)
                {
                    masks.push((predicted, plan));
                }
            }
            // The more promising mask only: one verification batch.
            if let Some((_, plan)) = masks.into_iter().min_by(|a, b| a.0.total_cmp(&b.0)) {
                self.queue.push_back(plan);
            }
        }
        for t in &self.trials {
            if let Some(s) = t.best()
                && t.seconds.len() < 2
                && s <= best * (1.0 + REMEASURE_WITHIN)
            {
                self.queue.push_back(t.plan);
            }
        }
    }

    fn decide(&mut self) {
        let Some((plan, _)) = self.best() else { return };
        let ms = |s: f64| format!("{:.3} ms", s * 1e3);
        let measured: Vec<String> = self
            .trials
            .iter()
            .filter_map(|t| {
                Some(format!(
                    "{} {}",
                    t.plan.describe(self.max_bounces),
                    ms(t.best()?)
                ))
            })
            .collect();
        self.decision = Some(AutoDecision {
            plan,
            summary: format!(
                "{} (fastest measured per {}-ray batch: {})",
                plan.describe(self.max_bounces),
                self.batch_rays,
                measured.join(", ")
            ),
        });
    }

    /// One line for [`crate::RenderStats::reorder`].
    pub fn describe(&self) -> String {
        match &self.decision {
            Some(d) => format!("auto: {}", d.summary),
            None => {
                let measured: Vec<String> = self
                    .trials
                    .iter()
                    .filter_map(|t| {
                        Some(format!(
                            "{} {:.3} ms",
                            t.plan.describe(self.max_bounces),
                            t.best()? * 1e3
                        ))
                    })
                    .collect();
                format!(
                    "auto: still measuring ({} trial batches so far: {}; {} to go); later \
                     renders of this scene continue",
                    self.trial_batches,
                    if measured.is_empty() {
                        "none full".to_string()
                    } else {
                        measured.join(", ")
                    },
                    self.queue.len() + usize::from(!self.refined)
                )
            }
        }
    }
}

/// The [`BatchPolicy`] of one render with `auto`.
pub(crate) struct AutoPolicy<'s> {
    pub state: &'s mut AutoState,
}

impl BatchPolicy for AutoPolicy<'_> {
    fn candidates(&self) -> Vec<BatchPlan> {
        match &self.state.decision {
            Some(d) => vec![d.plan],
            // Every plan a trial may run (mask plans need what the every-bounce ones need).
            None => {
                let mut v: Vec<BatchPlan> = self.state.queue.iter().copied().collect();
                v.extend(self.state.trials.iter().map(|t| t.plan));
                v.push(self.state.default);
                v
            }
        }
    }

    fn plan(&mut self, index: usize, batches: &[Batch]) -> BatchPlan {
        let s = &mut *self.state;
        s.in_flight = None;
        if let Some(d) = &s.decision {
            return d.plan;
        }
        let full = batches.iter().map(|b| b.rays()).max().unwrap_or(0);
        if batches[index].rays() == full
            && let Some(plan) = s.queue.front().copied()
        {
            s.in_flight = Some(plan);
            return plan;
        }
        // A partial batch (or nothing left to try): the best so far.
        s.best().map_or(s.default, |(p, _)| p)
    }

    fn observe(&mut self, t: &BatchTiming) {
        let s = &mut *self.state;
        if s.decision.is_some() || s.in_flight.take() != Some(t.plan) || !t.full {
            return;
        }
        if s.batch_rays == 0 {
            s.batch_rays = t.batch.rays();
        }
        s.queue.pop_front();
        s.trial_batches += 1;
        let max_bounces = s.max_bounces;
        let trial = s.trial_mut(t.plan);
        trial.seconds.push(t.wall_seconds);
        if trial.depths.is_empty() {
            trial.depths = (0..=max_bounces)
                .map(|d| {
                    (
                        t.stage_seconds("propagate", d),
                        t.stage_seconds("sort_keys", d) + t.stage_seconds("permute_rays", d),
                    )
                })
                .collect();
        }
        if s.queue.is_empty() {
            if !s.refined {
                s.refine();
            }
            if s.queue.is_empty() {
                s.decide();
            }
        }
    }
}

/// A fingerprint of what decides the cost of a render: the scene (counts, camera, materials,
/// environment, and a sample of at most ~4096 triangles and spheres spread over the lists),
/// the image size, bounces, batch shape, and `policy` (BVH quality, the key width sorted).
/// A false match between two scenes only
/// costs speed (the other scene's decision), never correctness.
pub(crate) fn fingerprint(scene: &Scene, settings: &TraceSettings, policy: &str) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    let f = |h: &mut std::collections::hash_map::DefaultHasher, v: f32| v.to_bits().hash(h);
    let v3 = |h: &mut std::collections::hash_map::DefaultHasher, v: glam::Vec3| {
        for c in v.to_array() {
            f(h, c);
        }
    };
    (settings.width, settings.height, settings.max_bounces).hash(&mut h);
    settings.batch_spp.min(settings.spp).hash(&mut h);
    policy.hash(&mut h);
    let c = &scene.camera;
    v3(&mut h, c.position);
    v3(&mut h, c.look_at);
    v3(&mut h, c.up);
    f(&mut h, c.vfov);
    for m in &scene.materials {
        format!("{:?}{:?}", m.kind, m.albedo_texture).hash(&mut h);
        for v in [m.albedo, m.emission, m.tint] {
            v3(&mut h, v);
        }
        f(&mut h, m.roughness);
        f(&mut h, m.ior);
    }
    for t in &scene.textures {
        (t.width, t.height).hash(&mut h);
    }
    match &scene.environment {
        Environment::Black => 0u8.hash(&mut h),
        Environment::Constant(c) => {
            1u8.hash(&mut h);
            v3(&mut h, *c);
        }
        Environment::Map {
            image,
            strength,
            rotation,
        } => {
            2u8.hash(&mut h);
            (image.width, image.height).hash(&mut h);
            f(&mut h, *strength);
            f(&mut h, *rotation);
        }
    }
    (scene.triangles.len(), scene.spheres.len()).hash(&mut h);
    let step = scene.triangles.len().div_ceil(4096).max(1);
    for t in scene.triangles.iter().step_by(step) {
        for p in t.positions {
            v3(&mut h, p);
        }
        t.material.hash(&mut h);
    }
    let step = scene.spheres.len().div_ceil(4096).max(1);
    for s in scene.spheres.iter().step_by(step) {
        v3(&mut h, s.center);
        f(&mut h, s.radius);
        s.material.hash(&mut h);
    }
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use raylume_kernels::StageTime;

    const BOUNCES: u32 = 4;

    fn batches(n: usize) -> Vec<Batch> {
        (0..n)
            .map(|i| Batch {
                pixel_begin: 0,
                pixel_count: 100,
                sample_begin: i as u32,
                sample_count: 1,
                last_for_pixels: i + 1 == n,
            })
            .collect()
    }

    /// A made-up cost model: per depth, unsorted propagate 1.0, sorted propagate
    /// `sorted[d]`, sort 0.2, permute 0.1 (sort-permute), megakernel `mk` in all.
    struct Model {
        mk: f64,
        sorted: [f64; BOUNCES as usize + 1],
    }

    impl Model {
        fn timing(&self, index: usize, b: Batch, plan: BatchPlan) -> BatchTiming {
            let mut stages = Vec::new();
            let mut wall = 0.0;
            if plan.schedule == Schedule::Megakernel {
                stages.push(StageTime {
                    label: "trace_paths",
                    depth: None,
                    seconds: self.mk,
                });
                wall = self.mk;
            } else {
                for d in 0..=BOUNCES {
                    let mut push = |label, seconds| {
                        stages.push(StageTime {
                            label,
                            depth: Some(d),
                            seconds,
                        });
                        wall += seconds;
                    };
                    if plan.reorder.sorts_before(d) {
                        push("sort_keys", 0.2);
                        if plan.reorder.mode == ReorderMode::SortPermute {
                            push("permute_rays", 0.1);
                        }
                        push("propagate", self.sorted[d as usize]);
                    } else {
                        push("propagate", 1.0);
                    }
                }
            }
            BatchTiming {
                index,
                batch: b,
                full: true,
                plan,
                wall_seconds: wall,
                stages,
            }
        }

        /// Runs renders of `n` batches until `auto` decides; returns the plans each batch ran.
        fn run(&self, state: &mut AutoState, n: usize) -> Vec<BatchPlan> {
            let bs = batches(n);
            let mut policy = AutoPolicy { state };
            let mut ran = Vec::new();
            for i in 0..n {
                let plan = policy.plan(i, &bs);
                ran.push(plan);
                let t = self.timing(i, bs[i], plan);
                policy.observe(&t);
            }
            ran
        }
    }

    fn plain(schedule: Schedule) -> BatchPlan {
        BatchPlan {
            schedule,
            reorder: Reorder::OFF,
        }
    }

    #[test]
    fn the_first_batch_runs_what_off_runs_and_the_fastest_measured_plan_wins() {
        // Sorting makes propagate at depths 3 and 4 cheap (0.5) and elsewhere no cheaper:
        // unsorted wavefront 5.0, sorted everywhere 0.2*4 + 1 + 1 + 1 + 0.5 + 0.5 = 4.8,
        // sort-index before 3..=4 only: 1 + 1 + 1 + 0.7 + 0.7 = 4.4; megakernel 4.6.
        let m = Model {
            mk: 4.6,
            sorted: [1.0, 1.0, 1.0, 0.5, 0.5],
        };
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let ran = m.run(&mut s, 20);
        assert_eq!(ran[0], plain(Schedule::Megakernel), "first batch = off");
        let d = s.decision().expect("decided within 20 batches").clone();
        let want = BatchPlan {
            schedule: Schedule::Wavefront,
            reorder: Reorder {
                depths: (1 << 3) | (1 << 4),
                ..Reorder::every_bounce(ReorderMode::SortIndex)
            },
        };
        assert_eq!(d.plan, want, "{}", d.summary);
        assert!(
            d.summary.contains("sort-index before depths 3..=4"),
            "{}",
            d.summary
        );
        // The trials were few, and every batch after them runs the decision.
        let trials = s.trial_batches as usize;
        assert!(trials <= 2 * 4 + 1, "{trials}");
        assert!(
            ran[..trials].contains(&want),
            "the mask was measured, not guessed"
        );
        assert!(ran[trials..].iter().all(|&p| p == want));
    }

    #[test]
    fn when_sorting_never_pays_auto_keeps_an_unsorted_schedule() {
        let m = Model {
            mk: 5.5,
            sorted: [1.0; 5],
        };
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        m.run(&mut s, 20);
        assert_eq!(s.decision().unwrap().plan, plain(Schedule::Wavefront));
        let m = Model {
            mk: 3.0,
            sorted: [1.0; 5],
        };
        let mut s = AutoState::new(Schedule::Wavefront, BOUNCES, 30);
        m.run(&mut s, 20);
        assert_eq!(s.decision().unwrap().plan, plain(Schedule::Megakernel));
    }

    #[test]
    fn one_batch_renders_measure_across_renders() {
        let m = Model {
            mk: 6.0,
            sorted: [1.0, 0.4, 0.4, 0.4, 0.4],
        };
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let mut renders = 0;
        while s.decision().is_none() {
            let ran = m.run(&mut s, 1);
            if renders == 0 {
                assert_eq!(ran[0], plain(Schedule::Megakernel));
                assert!(s.describe().contains("still measuring"), "{}", s.describe());
            }
            renders += 1;
            assert!(renders <= 9, "undecided after {renders} renders");
        }
        // Sorting everywhere pays (0.2 + 0.4 < 1 at every depth): sort-index, every bounce.
        assert_eq!(
            s.decision().unwrap().plan,
            BatchPlan {
                schedule: Schedule::Wavefront,
                reorder: Reorder::every_bounce(ReorderMode::SortIndex),
            }
        );
        // Partial batches never count as trials.
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let mut p = AutoPolicy { state: &mut s };
        let bs = batches(1);
        let plan = p.plan(0, &bs);
        let mut t = m.timing(0, bs[0], plan);
        t.full = false;
        p.observe(&t);
        assert_eq!(s.trial_batches, 0);
    }

    #[test]
    fn zero_bounces_never_sort() {
        let s = AutoState::new(Schedule::Wavefront, 0, 30);
        assert!(s.queue.iter().all(|p| !p.sorts(0)));
        assert_eq!(s.queue.len(), 2);
    }
}
