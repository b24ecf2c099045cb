//! The stages of one batch, recorded for [`super::clock::StageClock`]: the megakernel, or the
//! wavefront with its sorts (raylume-sort) and permutations between bounces, and whatever a
//! [`BounceProbe`] injects before a bounce (the tests' copies of the sorted rays).

use std::collections::HashMap;

use raylume_gpu::wgpu;
use raylume_sort::{RadixSorter, SortLen};

use super::BatchPlan;
use super::clock::{Record, Stage};
use super::work::WorkBuffers;
use crate::{Reorder, ReorderMode, Schedule};

/// The ray queue (and queue count, and bind group of group 1) bounce `depth` reads: the two
/// queues alternate by depth parity, as pbrt-v4's wavefront `CurrentRayQueue(depth)`; the
/// bounce appends its continuing rays to the other (`NextRayQueue`).
pub(crate) fn current_queue(depth: u32) -> usize {
    (depth & 1) as usize
}

/// Whether bounce `depth` of a wavefront with a walk stage runs it: the bounces whose queue is
/// not sorted. A sorted queue is coherent, so its lanes end their walks together and the
/// stage's refills cost more than they save (on the H200 the living room's sorted bounces
/// were 25 % slower, gathering the ray states twice in `SortIndex` order); there the
/// `propagate` compiled without `HITS_TRACED` walks, as without the stage
/// (`BounceUniforms::walk_groups` is 0). Nor the bounces before
/// [`crate::walk_stage_from`] (a knob for measuring; by default every bounce).
pub(crate) fn walk_stage_at(reorder: Reorder, depth: u32) -> bool {
    !reorder.sorts_before(depth) && depth >= crate::walk_stage_from()
}

/// The name under which a batch's pipelines hold `propagate` compiled with `HITS_TRACED` (the
/// walk stage's bounces), beside `propagate` itself (the other bounces).
pub(crate) const PROPAGATE_HITS: &str = "propagate (walk stage)";

/// A stage injected before each wavefront bounce is traced, after its sort and permutation:
/// how a test looks at the rays (`GpuTracer::capture_sort`, `capture.rs`) without the
/// production recording knowing what it copies.
pub(crate) trait BounceProbe {
    /// The stage to record before bounce `depth`, whose rays are in ray-state buffer `states`
    /// of `work` and in queue [`current_queue`]`(depth)`; `None`: nothing.
    fn before_bounce<'r>(
        &'r self,
        depth: u32,
        work: &'r WorkBuffers,
        states: usize,
    ) -> Option<Stage<'r>>;
}

/// Builds the stages of one batch.
#[derive(Clone, Copy)]
pub(crate) struct BatchRecorder<'r> {
    pub work: &'r WorkBuffers,
    pub pipes: &'r HashMap<&'static str, wgpu::ComputePipeline>,
    pub scene_bg: &'r wgpu::BindGroup,
    /// One per sorted key width.
    pub sorters: &'r [RadixSorter],
    pub probe: Option<&'r dyn BounceProbe>,
    pub ray_groups: (u32, u32),
    /// The megakernel's dispatch: the batch's samples in groups of
    /// [`crate::megakernel_workgroup_size`].
    pub path_groups: (u32, u32),
    pub pixel_groups: (u32, u32),
    /// The persistent schedule's dispatch: the batch's samples, at most
    /// [`crate::PERSISTENT_THREADS`] threads.
    pub persistent_groups: (u32, u32),
}

impl<'r> BatchRecorder<'r> {
    /// Groups 0 and 1 of `pipe` at bounce `depth` (0 for every other stage), reading ray-state
    /// buffer `states`.
    fn bind(&self, pass: &mut wgpu::ComputePass<'_>, pipe: &str, depth: u32, states: usize) {
        let w = self.work;
        pass.set_pipeline(&self.pipes[pipe]);
        pass.set_bind_group(0, self.scene_bg, &[]);
        let parity = current_queue(depth);
        pass.set_bind_group(
            1,
            &w.bind_groups[2 * states + parity],
            &[depth * w.bounce_stride],
        );
    }

    /// `prepare_propagate` of bounce `depth`: the indirect dispatch size over its live rays.
    fn prepare(&self, pass: &mut wgpu::ComputePass<'_>, depth: u32, states: usize) {
        self.bind(pass, "prepare_propagate", depth, states);
        pass.set_bind_group(2, &self.work.args_bind_group, &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }

    pub fn stages(self, plan: &BatchPlan, max_bounces: u32) -> Vec<Stage<'r>> {
        let (rx, ry) = self.ray_groups;
        let (px, py) = self.pixel_groups;
        let resolve = move |pass: &mut wgpu::ComputePass<'_>| {
            self.bind(pass, "resolve", 0, 0);
            pass.dispatch_workgroups(px, py, 1);
        };
        let mut out = Vec::new();
        if plan.schedule == Schedule::Megakernel {
            let (mx, my) = self.path_groups;
            out.push(Stage::pass("trace_paths", None, move |pass| {
                self.bind(pass, "trace_paths", 0, 0);
                pass.dispatch_workgroups(mx, my, 1);
            }));
            out.push(Stage::pass("resolve", None, resolve));
            return out;
        }
        if plan.schedule == Schedule::Persistent {
            let w = self.work;
            let (tx, ty) = self.persistent_groups;
            // The sample counter (queue_counts[3]) starts at 0 in every batch.
            out.push(Stage {
                label: "clear_counter",
                depth: None,
                submit_after: false,
                record: Record::Untimed(Box::new(move |enc| {
                    enc.clear_buffer(&w.queue_counts, 12, Some(4));
                })),
            });
            out.push(Stage::pass("trace_paths", None, move |pass| {
                self.bind(pass, "trace_paths_persistent", 0, 0);
                pass.dispatch_workgroups(tx, ty, 1);
            }));
            out.push(Stage::pass("resolve", None, resolve));
            return out;
        }
        out.push(Stage::pass("raygen", None, move |pass| {
            self.bind(pass, "raygen", 0, 0);
            pass.dispatch_workgroups(rx, ry, 1);
        }));
        // The ray-state buffer the rays are in: permute_rays moves them to the other one.
        let mut states = 0usize;
        let w = self.work;
        for depth in 0..=max_bounces {
            if plan.reorder.sorts_before(depth) {
                // propagate(depth - 1) left the live rays and their keys in the queue this
                // bounce reads, with their count at the same parity.
                let q = current_queue(depth);
                let sorter = self
                    .sorters
                    .iter()
                    .find(|s| s.plan().key_bits == plan.reorder.key_bits)
                    .expect("check_plan: a sorting plan has its sorter");
                out.push(Stage {
                    label: "sort_keys",
                    depth: Some(depth),
                    submit_after: false,
                    record: Record::Encoder(Box::new(move |enc, ts| {
                        let len = SortLen::Indirect {
                            count_buffer: &w.queue_counts,
                            offset: 4 * q as u64,
                        };
                        sorter
                            .encode(enc, &w.ray_keys, &w.ray_queues[q], len, ts)
                            .map_err(crate::KernelError::from)
                    })),
                });
                if plan.reorder.mode == ReorderMode::SortPermute {
                    let s = states;
                    out.push(Stage::pass("permute_rays", Some(depth), move |pass| {
                        self.prepare(pass, depth, s);
                        self.bind(pass, "permute_rays", depth, s);
                        pass.set_bind_group(2, &w.permute_bind_groups[s], &[]);
                        pass.dispatch_workgroups_indirect(&w.dispatch_args, 0);
                    }));
                    states = 1 - states;
                }
            }
            if let Some(stage) = self.probe.and_then(|p| p.before_bounce(depth, w, states)) {
                out.push(stage);
            }
            let s = states;
            let staged =
                self.pipes.contains_key("trace_hits") && walk_stage_at(plan.reorder, depth);
            if staged {
                // The bounce's closest hits, for propagate to shade (prepare_propagate zeroes
                // the stage's slot counter and sizes its dispatch to the bounce's rays).
                out.push(Stage::pass("trace_hits", Some(depth), move |pass| {
                    self.prepare(pass, depth, s);
                    self.bind(pass, "trace_hits", depth, s);
                    pass.dispatch_workgroups_indirect(&w.dispatch_args, 16);
                }));
            }
            let propagate = if staged { PROPAGATE_HITS } else { "propagate" };
            out.push(Stage::pass("propagate", Some(depth), move |pass| {
                self.prepare(pass, depth, s);
                self.bind(pass, propagate, depth, s);
                pass.dispatch_workgroups_indirect(&w.dispatch_args, 0);
            }));
            if staged && self.pipes.contains_key("trace_shadows") {
                // The shadow rays that propagate queued (at most one a ray of the bounce: the
                // walk stage's dispatch size suffices).
                out.push(Stage::pass("trace_shadows", Some(depth), move |pass| {
                    self.bind(pass, "trace_shadows", depth, s);
                    pass.dispatch_workgroups_indirect(&w.dispatch_args, 16);
                }));
            }
            if self.pipes.contains_key("next_event") {
                // The light samples propagate left, over the same rays (the dispatch size
                // prepare_propagate wrote for it).
                out.push(Stage::pass("next_event", Some(depth), move |pass| {
                    self.bind(pass, "next_event", depth, s);
                    pass.dispatch_workgroups_indirect(&w.dispatch_args, 0);
                }));
            }
            // When the next bounce sorts, let the GPU trace this one while the sort is
            // recorded.
            if let Some(last) = out.last_mut() {
                last.submit_after = plan.reorder.sorts_before(depth + 1);
            }
        }
        out.push(Stage::pass("resolve", None, resolve));
        out
    }
}
