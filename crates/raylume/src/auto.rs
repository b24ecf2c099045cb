//! `--reorder auto`: choosing the schedule and the ray sorting of a scene from measurement.
//!
//! The candidates are the schedule `off` would run, the other schedules, and the wavefront
//! sorting before every bounce in each [`ReorderMode`]. **A trial is a whole render**: every
//! batch of an exploring render runs the same candidate, and the tracer prepares that
//! candidate alone (its buffers, pipelines and sorter), so a trial render is exactly the render
//! that candidate gives when it is kept. Its cost is the render's batch time per camera
//! sample. (An earlier design measured candidates on single batches inside one render; on the
//! H100 such trials misjudged sorted plans systematically, by up to 50 %, so it was replaced:
//! see `docs/RESULTS.md`.)
//!
//! When every candidate has run once, the per-depth times of the unsorted wavefront and of each
//! sorted one give the depths where sorting paid for itself (sort + permute + sorted
//! `propagate` below unsorted `propagate`); if sorting only there is predicted to beat every
//! measured candidate by more than 1 %, that mask is measured too. Then every candidate runs a
//! second time, in the opposite order, and more rounds follow (at most four in all) while a
//! round still makes some candidate more than 3 % faster than before: on the lent H100, some
//! stretches of a run (often right after the render size changed) ran every kernel 1.2-4.7x
//! slower, easing off render by render, and a one-round comparison favours whichever
//! candidates ran last. Then the leader (the lowest cost so far, each plan judged by its fastest
//! render) is measured until it has [`LEADER_RENDERS`] renders; when it still leads, it is
//! kept, cached in the [`crate::Tracer`] under a fingerprint of the scene, image size, bounces
//! and batch shape.
//!
//! So the first render of a scene runs exactly what `off` runs (`auto` costs nothing over `off`
//! on it), the next renders of the same scene (10 to 20) try the other candidates (a trial is a
//! real render of the same image: nothing is thrown away, but a slower candidate makes that
//! render slower), and from then on every render runs the measured best. A single long render
//! runs the `off` schedule throughout: `auto` pays where a scene is rendered repeatedly
//! (previews, animations of a static scene, benchmarks), which is where it can measure.

use std::collections::VecDeque;
use std::hash::{Hash, Hasher};

use raylume_kernels::batches::Batch;
use raylume_kernels::{
    BatchPlan, BatchPolicy, BatchTiming, Reorder, ReorderMode, Schedule, TraceSettings,
};
use raylume_scene::{Environment, Scene};

/// Renders of the leader before it is kept (the best of three, as the bench reports).
pub const LEADER_RENDERS: usize = 3;
/// A per-depth mask is tried when predicted to beat the best measured plan by this fraction.
const MASK_MIN_GAIN: f64 = 0.01;
/// Trial renders after which the leader is kept whatever is left to measure.
const MAX_TRIAL_RENDERS: u32 = 24;
/// Rounds of trials at most (every candidate once per round).
const MAX_ROUNDS: u32 = 4;
/// A round in which no candidate beat its earlier best by more than this fraction ends the
/// rounds: the machine ran steadily.
const STEADY_WITHIN: f64 = 0.03;

/// What `auto` chose for a scene, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoDecision {
    /// The plan every later batch of the scene runs.
    pub plan: BatchPlan,
    /// E.g. `wavefront, sort-index before depths 2..=10 (fastest measured, ms per million
    /// camera samples: megakernel 3.210 (1 render), ...)`.
    pub summary: String,
}

/// One candidate's measurements.
#[derive(Clone, Debug)]
struct Trial {
    plan: BatchPlan,
    /// Seconds per camera sample of each render it ran (batch wall-clock time over samples).
    seconds: Vec<f64>,
    /// Per depth, per camera sample: `propagate`, and `sort_keys` + `permute_rays` before it,
    /// from its first render.
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
    trials: Vec<Trial>,
    /// Plans still to measure, a render each, in order.
    queue: VecDeque<BatchPlan>,
    /// Whether the per-depth mask was considered.
    refined: bool,
    /// Rounds of trials queued so far (the first: every candidate once, then the mask).
    round: u32,
    /// Whether a render of the current round beat its plan's earlier best by more than
    /// [`STEADY_WITHIN`].
    improved: bool,
    decision: Option<AutoDecision>,
    /// Renders this fingerprint ran as trials.
    pub trial_renders: u32,
}

impl AutoState {
    /// A fresh state: `off_schedule` first (so a first render runs what `off` runs), then the
    /// other schedules, then the wavefront sorted before every bounce by the top `key_bits` of
    /// the key, in each mode.
    pub fn new(off_schedule: Schedule, max_bounces: u32, key_bits: u32) -> Self {
        let plain = |schedule| BatchPlan {
            schedule,
            reorder: Reorder::OFF,
        };
        // `off_schedule` first, then the other schedules.
        let mut queue: VecDeque<BatchPlan> = std::iter::once(off_schedule)
            .chain(Schedule::ALL.into_iter().filter(|&s| s != off_schedule))
            .map(plain)
            .collect();
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
            trials: Vec::new(),
            queue,
            refined: false,
            round: 1,
            improved: false,
            decision: None,
            trial_renders: 0,
        }
    }

    pub fn decision(&self) -> Option<&AutoDecision> {
        self.decision.as_ref()
    }

    /// The plan the next render runs, all its batches.
    fn next_plan(&self) -> BatchPlan {
        match &self.decision {
            Some(d) => d.plan,
            None => *self
                .queue
                .front()
                .expect("an undecided state always has a plan queued"),
        }
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

    /// The measured plan with the lowest cost, and its cost.
    fn leader(&self) -> Option<(BatchPlan, f64)> {
        self.trials
            .iter()
            .filter_map(|t| Some((t.plan, t.best()?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Records a trial render of `plan` and queues what to measure next (or decides).
    fn record(&mut self, plan: BatchPlan, seconds: f64, depths: Vec<(f64, f64)>) {
        if self.decision.is_some() || self.queue.front() != Some(&plan) {
            return;
        }
        self.queue.pop_front();
        self.trial_renders += 1;
        let trial = self.trial_mut(plan);
        let faster = trial
            .best()
            .is_some_and(|best| seconds < best * (1.0 - STEADY_WITHIN));
        trial.seconds.push(seconds);
        if trial.depths.is_empty() {
            trial.depths = depths;
        }
        self.improved |= faster;
        if !self.queue.is_empty() {
            return;
        }
        if !self.refined {
            self.refined = true;
            if let Some(mask) = self.mask() {
                self.queue.push_back(mask);
                return;
            }
        }
        if self.round < 2 || (self.improved && self.round < MAX_ROUNDS) {
            // Every candidate once more, each round in the opposite order of the one before,
            // until a round improves no candidate's best by more than STEADY_WITHIN: a machine
            // that is slower for a while (fresh allocations, another tenant, clocks) then
            // weighs on every candidate's early renders, not on the first candidates only.
            self.round += 1;
            self.improved = false;
            let mut plans: Vec<BatchPlan> = self.trials.iter().map(|t| t.plan).collect();
            if self.round.is_multiple_of(2) {
                plans.reverse();
            }
            self.queue.extend(plans);
            return;
        }
        let Some((leader, _)) = self.leader() else {
            return;
        };
        let leader_runs = self
            .trials
            .iter()
            .find(|t| t.plan == leader)
            .map_or(0, |t| t.seconds.len());
        if leader_runs < LEADER_RENDERS && self.trial_renders < MAX_TRIAL_RENDERS {
            self.queue.push_back(leader);
            return;
        }
        self.decide(leader);
    }

    /// The per-depth mask predicted to beat every measured plan by [`MASK_MIN_GAIN`], if any:
    /// sorting only before the depths where a sorted trial's sort + propagate took less time
    /// than the unsorted wavefront's propagate.
    fn mask(&self) -> Option<BatchPlan> {
        let (_, best) = self.leader()?;
        let unsorted = self
            .trials
            .iter()
            .find(|t| t.plan.schedule == Schedule::Wavefront && !t.plan.sorts(self.max_bounces))?;
        let mut masks = Vec::new();
        for t in &self.trials {
            let Some(cost) = t.best() else { continue };
            if !t.plan.sorts(self.max_bounces) || t.depths.len() != unsorted.depths.len() {
                continue;
            }
            // gain_d: what sorting before depth d saved (negative: what it cost).
            // (Bit 63 also stands for the depths past 63, which follow depth 63.)
            let mut depths = 0u64;
            let mut predicted = cost;
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
        // The more promising mask only.
        masks
            .into_iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, plan)| plan)
    }

    /// What was measured, per candidate, in ms per million camera samples: `megakernel 3.210
    /// (2 renders)`.
    fn measured(&self) -> Vec<String> {
        self.trials
            .iter()
            .filter_map(|t| {
                Some(format!(
                    "{} {:.3} ({} render{})",
                    t.plan.describe(self.max_bounces),
                    t.best()? * 1e9,
                    t.seconds.len(),
                    if t.seconds.len() == 1 { "" } else { "s" }
                ))
            })
            .collect()
    }

    fn decide(&mut self, plan: BatchPlan) {
        self.queue.clear();
        self.decision = Some(AutoDecision {
            plan,
            summary: format!(
                "{} (fastest measured, ms per million camera samples: {})",
                plan.describe(self.max_bounces),
                self.measured().join(", ")
            ),
        });
    }

    /// One line for [`crate::RenderStats::reorder`].
    pub fn describe(&self) -> String {
        match &self.decision {
            Some(d) => format!("auto: {}", d.summary),
            None => {
                let measured = self.measured();
                format!(
                    "auto: still measuring ({} trial render{} so far{}); later renders of this \
                     scene continue, one candidate per render",
                    self.trial_renders,
                    if self.trial_renders == 1 { "" } else { "s" },
                    if measured.is_empty() {
                        String::new()
                    } else {
                        format!(", ms per million camera samples: {}", measured.join(", "))
                    },
                )
            }
        }
    }
}

/// The [`BatchPolicy`] of one render with `auto`: every batch runs the plan the state gives at
/// the render's start; the render's cost is recorded when its last batch is observed.
pub(crate) struct AutoPolicy<'s> {
    state: &'s mut AutoState,
    plan: BatchPlan,
    /// Whether this render is a trial (no decision yet).
    trial: bool,
    /// The render's batch count (known from the first `plan` call).
    batches: usize,
    seconds: f64,
    samples: u64,
    /// Per depth: `propagate`, and `sort_keys` + `permute_rays`, summed over the batches.
    depths: Vec<(f64, f64)>,
}

impl<'s> AutoPolicy<'s> {
    pub fn new(state: &'s mut AutoState) -> Self {
        Self {
            plan: state.next_plan(),
            trial: state.decision.is_none(),
            state,
            batches: 0,
            seconds: 0.0,
            samples: 0,
            depths: Vec::new(),
        }
    }
}

impl BatchPolicy for AutoPolicy<'_> {
    fn candidates(&self) -> Vec<BatchPlan> {
        vec![self.plan]
    }

    fn plan(&mut self, _index: usize, batches: &[Batch]) -> BatchPlan {
        self.batches = batches.len();
        self.plan
    }

    fn observe(&mut self, t: &BatchTiming) {
        if !self.trial || t.plan != self.plan {
            return;
        }
        self.seconds += t.wall_seconds;
        self.samples += u64::from(t.batch.rays());
        let max_bounces = self.state.max_bounces;
        self.depths.resize(max_bounces as usize + 1, (0.0, 0.0));
        for (d, e) in self.depths.iter_mut().enumerate() {
            let d = d as u32;
            e.0 += t.stage_seconds("propagate", d)
                + t.stage_seconds("trace_hits", d)
                + t.stage_seconds("trace_shadows", d)
                + t.stage_seconds("next_event", d);
            e.1 += t.stage_seconds("sort_keys", d) + t.stage_seconds("permute_rays", d);
        }
        if t.index + 1 == self.batches && self.samples > 0 {
            let n = self.samples as f64;
            let depths = self.depths.iter().map(|&(p, s)| (p / n, s / n)).collect();
            self.state.record(self.plan, self.seconds / n, depths);
            self.trial = false;
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
    f(&mut h, c.fov);
    c.fov_axis.hash(&mut h);
    for m in &scene.materials {
        format!("{:?}{:?}{}", m.kind, m.albedo_texture, m.two_sided).hash(&mut h);
        for v in [m.albedo, m.emission, m.tint, m.conductor_eta, m.conductor_k] {
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

    /// A made-up cost model per batch: per depth, unsorted propagate 1.0, sorted propagate
    /// `sorted[d]`, sort 0.2, permute 0.1 (sort-permute), megakernel `mk` in all; every time
    /// multiplied by the machine's `slowness` at that render.
    struct Model {
        mk: f64,
        sorted: [f64; BOUNCES as usize + 1],
    }

    impl Model {
        fn new(mk: f64, sorted: [f64; BOUNCES as usize + 1]) -> Self {
            Self { mk, sorted }
        }

        fn timing(&self, index: usize, b: Batch, plan: BatchPlan, slowness: f64) -> BatchTiming {
            let mut stages = Vec::new();
            let mut wall = 0.0;
            if plan.schedule != Schedule::Wavefront {
                let s = self.mk * slowness;
                stages.push(StageTime {
                    label: "trace_paths",
                    depth: None,
                    seconds: s,
                });
                wall = s;
            } else {
                for d in 0..=BOUNCES {
                    let mut push = |label, seconds: f64| {
                        let seconds = seconds * slowness;
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

        /// One render of `n` batches; returns the plans its batches ran (checking that the
        /// tracer was asked to prepare exactly them).
        fn render(&self, state: &mut AutoState, n: usize, slowness: f64) -> Vec<BatchPlan> {
            let bs = batches(n);
            let mut policy = AutoPolicy::new(state);
            let prepared = policy.candidates();
            let mut ran = Vec::new();
            for i in 0..n {
                let plan = policy.plan(i, &bs);
                assert!(prepared.contains(&plan));
                ran.push(plan);
                policy.observe(&self.timing(i, bs[i], plan, slowness));
            }
            ran
        }

        /// Renders of `n` batches until `auto` decides; returns the plan of each render.
        fn run(&self, state: &mut AutoState, n: usize) -> Vec<BatchPlan> {
            let mut renders = Vec::new();
            while state.decision().is_none() {
                let ran = self.render(state, n, 1.0);
                assert!(ran.iter().all(|&p| p == ran[0]), "one plan per render");
                renders.push(ran[0]);
                assert!(
                    renders.len() <= MAX_TRIAL_RENDERS as usize,
                    "undecided after {} renders: {}",
                    renders.len(),
                    state.describe()
                );
            }
            renders
        }
    }

    /// Fails unless `s` decided `want`, showing what it measured.
    fn assert_decided(s: &AutoState, want: BatchPlan) {
        let got = s.decision().map(|d| d.plan);
        assert_eq!(got, Some(want), "{}", s.describe());
    }

    fn plain(schedule: Schedule) -> BatchPlan {
        BatchPlan {
            schedule,
            reorder: Reorder::OFF,
        }
    }

    #[test]
    fn the_first_render_runs_what_off_runs_and_the_fastest_measured_plan_wins() {
        // Sorting makes propagate at depths 3 and 4 cheap (0.5) and elsewhere no cheaper:
        // unsorted wavefront 5.0, sorted everywhere 0.2*4 + 1 + 1 + 1 + 0.5 + 0.5 = 4.8,
        // sort-index before 3..=4 only: 1 + 1 + 1 + 0.7 + 0.7 = 4.4; megakernel 4.6.
        let m = Model::new(4.6, [1.0, 1.0, 1.0, 0.5, 0.5]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let renders = m.run(&mut s, 3);
        assert_eq!(
            renders[0],
            plain(Schedule::Megakernel),
            "first render = off"
        );
        let d = s.decision().expect("decided").clone();
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
        // The mask was measured, not guessed, as often as the leader must be; every other
        // candidate twice (two rounds).
        let count = |p: BatchPlan| renders.iter().filter(|&&r| r == p).count();
        assert_eq!(count(want), LEADER_RENDERS);
        assert_eq!(count(plain(Schedule::Megakernel)), 2);
        assert_eq!(s.trial_renders as usize, renders.len());
        // Every render after the decision runs it, whole.
        assert!(m.render(&mut s, 3, 1.0).iter().all(|&p| p == want));
        assert_eq!(s.trial_renders as usize, renders.len());
        // Costs are per camera sample: 4.4 s per 100-sample batch is 4.4e7 ms per million.
        assert!(
            d.summary
                .contains("sort-index before depths 3..=4 44000000.000 (3 renders)"),
            "{}",
            d.summary
        );
    }

    #[test]
    fn when_sorting_never_pays_auto_keeps_an_unsorted_schedule() {
        let m = Model::new(5.5, [1.0; 5]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        m.run(&mut s, 2);
        assert_eq!(s.decision().unwrap().plan, plain(Schedule::Wavefront));
        let m = Model::new(3.0, [1.0; 5]);
        let mut s = AutoState::new(Schedule::Wavefront, BOUNCES, 30);
        m.run(&mut s, 2);
        assert_eq!(s.decision().unwrap().plan, plain(Schedule::Megakernel));
    }

    #[test]
    fn a_slow_first_render_of_the_best_plan_does_not_decide() {
        // The megakernel costs 4.8 per batch but 5.6 on its first render (cold); the unsorted
        // wavefront costs 5.0, sorting never pays. One render each would keep the wavefront.
        let m = Model::new(4.8, [1.0; 5]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let first = m.render(&mut s, 2, 5.6 / 4.8);
        assert_eq!(first[0], plain(Schedule::Megakernel));
        m.run(&mut s, 2);
        assert_decided(&s, plain(Schedule::Megakernel));
    }

    #[test]
    fn a_slow_stretch_of_the_machine_does_not_favour_the_later_candidates() {
        // The wavefront (5.0) beats the megakernel and the persistent schedule (5.5 each) and
        // sorting (5.8, 6.2), but the machine runs 1.6x slower during the first four renders
        // (megakernel, wavefront, persistent, sort-index): one round would keep sort-permute
        // (6.2 < 1.6 x 5.0).
        let m = Model::new(5.5, [1.0; 5]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        for _ in 0..4 {
            m.render(&mut s, 2, 1.6);
        }
        m.render(&mut s, 2, 1.0);
        let after_one_round = s.leader().unwrap().0;
        assert_eq!(
            after_one_round.reorder.mode,
            ReorderMode::SortPermute,
            "{}",
            s.describe()
        );
        m.run(&mut s, 2);
        assert_decided(&s, plain(Schedule::Wavefront));
    }

    #[test]
    fn a_machine_that_speeds_up_render_by_render_is_measured_until_it_is_steady() {
        // The wavefront (5.0) beats the megakernel (5.2); the machine starts 1.6x slow and
        // recovers by 0.06 per render (steady from the 11th render on). Two rounds would
        // still compare renders of different speeds; rounds go on while they improve.
        let m = Model::new(5.2, [1.0; 5]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let mut k = 0;
        while s.decision().is_none() {
            let slowness = (1.6 - 0.06 * k as f64).max(1.0);
            m.render(&mut s, 2, slowness);
            k += 1;
            assert!(k <= MAX_TRIAL_RENDERS, "{}", s.describe());
        }
        assert!(s.round > 2, "{}", s.describe());
        assert_decided(&s, plain(Schedule::Wavefront));
    }

    #[test]
    fn one_batch_renders_decide_over_renders() {
        let m = Model::new(6.0, [1.0, 0.4, 0.4, 0.4, 0.4]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let first = m.render(&mut s, 1, 1.0);
        assert_eq!(first[0], plain(Schedule::Megakernel));
        assert!(
            s.describe()
                .contains("still measuring (1 trial render so far"),
            "{}",
            s.describe()
        );
        m.run(&mut s, 1);
        // Sorting everywhere pays (0.2 + 0.4 < 1 at every depth): sort-index, every bounce.
        assert_eq!(
            s.decision().unwrap().plan,
            BatchPlan {
                schedule: Schedule::Wavefront,
                reorder: Reorder::every_bounce(ReorderMode::SortIndex),
            }
        );
    }

    #[test]
    fn a_render_that_fails_midway_records_nothing() {
        let m = Model::new(6.0, [1.0; 5]);
        let mut s = AutoState::new(Schedule::Megakernel, BOUNCES, 30);
        let bs = batches(3);
        let mut p = AutoPolicy::new(&mut s);
        let plan = p.plan(0, &bs);
        p.observe(&m.timing(0, bs[0], plan, 1.0));
        // (the render stops here: an error after the first batch)
        assert_eq!(s.trial_renders, 0);
        assert_eq!(s.next_plan(), plain(Schedule::Megakernel), "tried again");
    }

    #[test]
    fn zero_bounces_never_sort() {
        let s = AutoState::new(Schedule::Wavefront, 0, 30);
        assert!(s.queue.iter().all(|p| !p.sorts(0)));
        assert_eq!(s.queue.len(), Schedule::ALL.len());
    }
}
