//! Ray reordering in the wavefront: sorting the live rays by their Morton key between bounces
//! (through the index, or permuting the ray states) traces the same paths and gives the same
//! image, really sorts, sorts only at the depths asked for, and batch policies may switch plans
//! between batches.

mod support;

use raylume_kernels::batches::Batch;
use raylume_kernels::cpu::stages::{batch_ray, sample_slot, tiled_ray};
use raylume_kernels::gpu_types::SceneUniforms;
use raylume_kernels::{
    BatchPlan, BatchPolicy, BatchTiming, GpuTracer, KernelError, Reorder, ReorderMode, Schedule,
    SortCapture, TraceSettings,
};
use raylume_sort::ray_sort_key;
use support::*;

const MODES: [ReorderMode; 2] = [ReorderMode::SortIndex, ReorderMode::SortPermute];

fn with(s: TraceSettings, reorder: Reorder) -> TraceSettings {
    TraceSettings {
        schedule: Schedule::Wavefront,
        reorder,
        ..s
    }
}

/// The key of the state of the `i`-th ray of a capture, computed on the CPU.
fn cpu_key(c: &SortCapture, i: usize) -> u32 {
    let s = &c.states[c.rays[i] as usize];
    ray_sort_key(
        s.origin.into(),
        s.dir.into(),
        c.scene_min.into(),
        c.scene_extent.into(),
    )
}

/// (pixel, sample) of every ray a capture's bounce reads, sorted.
fn ray_ids(c: &SortCapture) -> Vec<(u32, u32)> {
    let mut v: Vec<_> = (0..c.count as usize)
        .map(|i| {
            let s = &c.states[c.rays[i] as usize];
            (s.pixel, s.sample)
        })
        .collect();
    v.sort_unstable();
    v
}

#[test]
fn reorder_settings_say_which_depths_sort() {
    let every = Reorder::every_bounce(ReorderMode::SortIndex);
    assert!(!every.sorts_before(0), "camera rays are never sorted");
    assert!((1..200).all(|d| every.sorts_before(d)));
    assert_eq!(every.depth_ranges(10), "1..=10");
    assert_eq!(every.describe(10), "sort-index before depths 1..=10");
    let from3 = Reorder::from_depth(ReorderMode::SortPermute, 3);
    assert_eq!(
        (0..6).map(|d| from3.sorts_before(d)).collect::<Vec<_>>(),
        [false, false, false, true, true, true]
    );
    assert!(from3.sorts_before(1000), "bit 63 covers the deep bounces");
    assert_eq!(from3.describe(4), "sort-permute before depths 3..=4");
    let some = Reorder {
        mode: ReorderMode::SortIndex,
        depths: 0b1011_0110,
        key_bits: 30,
    };
    assert_eq!(some.depth_ranges(10), "1..=2, 4..=5, 7");
    assert!(!Reorder::OFF.sorts_any(10));
    assert_eq!(Reorder::OFF.describe(10), "off");
    // A mask with an Off mode sorts nothing; a mask past max_bounces sorts nothing either.
    let off_mode = Reorder {
        mode: ReorderMode::Off,
        depths: !0,
        key_bits: 30,
    };
    assert!(!off_mode.sorts_any(10));
    assert!(!Reorder::from_depth(ReorderMode::SortIndex, 5).sorts_any(4));
    assert_eq!(
        every.with_key_bits(16).describe(3),
        "sort-index/16 before depths 1..=3"
    );
}

#[test]
fn sample_slot_inverts_batch_ray() {
    // A batch of pixels 30..47 and samples 4..7 of a larger render (a 16x8 image): part of
    // the image, so the megakernel's tiled_ray keeps batch_ray's scanlines too.
    let scene = SceneUniforms {
        width: 16,
        height: 8,
        pixel_begin: 30,
        pixel_count: 17,
        sample_begin: 4,
        sample_count: 3,
        ..Default::default()
    };
    for r in 0..17 * 3 {
        let (pixel, sample) = batch_ray(&scene, r);
        assert_eq!(sample_slot(&scene, pixel, sample), r);
        assert_eq!(tiled_ray(&scene, r), (pixel, sample));
    }
}

#[test]
fn tiled_rays_are_the_batch_samples_in_tiles() {
    // Whole images: tiles, the edge tiles narrower or shorter (part of an image keeps
    // scanlines: sample_slot_inverts_batch_ray).
    for (w, h) in [(16, 8), (13, 7), (8, 4), (1, 1), (3, 10), (1000, 3)] {
        let scene = SceneUniforms {
            width: w,
            height: h,
            pixel_begin: 0,
            pixel_count: w * h,
            sample_begin: 2,
            sample_count: 3,
            ..Default::default()
        };
        let n = w * h * 3;
        let mut seen = vec![false; n as usize];
        for r in 0..n {
            let (pixel, sample) = tiled_ray(&scene, r);
            // Sample as batch_ray's; every (pixel, sample) of the batch exactly once.
            assert_eq!(sample, batch_ray(&scene, r).1, "{w}x{h} ray {r}");
            let slot = sample_slot(&scene, pixel, sample) as usize;
            assert!(
                !seen[slot],
                "{w}x{h}: ray {r} repeats pixel {pixel}, sample {sample}"
            );
            seen[slot] = true;
            // Where the image is whole tiles, each 32 consecutive rays (a warp) are one
            // tile-aligned 8x4 block of pixels.
            if w % 8 == 0 && h % 4 == 0 {
                let first = tiled_ray(&scene, r - r % 32).0;
                let (x0, y0) = (first % w, first / w);
                let (x, y) = (pixel % w, pixel / w);
                assert!(
                    x0 % 8 == 0 && y0 % 4 == 0,
                    "{w}x{h} ray {r}: tile at {x0},{y0}"
                );
                assert!(
                    (x0..x0 + 8).contains(&x) && (y0..y0 + 4).contains(&y),
                    "{w}x{h} ray {r}"
                );
            }
        }
    }
}

#[test]
fn sorting_needs_the_wavefront() {
    let s = TraceSettings {
        reorder: Reorder::every_bounce(ReorderMode::SortIndex),
        ..settings(8, 8, 1, 3, Schedule::Megakernel)
    };
    let e = s.validate().unwrap_err();
    assert!(matches!(e, KernelError::InvalidSettings(_)), "{e}");
    assert!(e.to_string().contains("wavefront"), "{e}");
    // Zero bounces: nothing to sort, so nothing to refuse.
    assert!(
        TraceSettings {
            max_bounces: 0,
            ..s
        }
        .validate()
        .is_ok()
    );
    // Key widths beyond the key's 30 bits, or none at all.
    for bits in [0, 31] {
        let s = TraceSettings {
            schedule: Schedule::Wavefront,
            reorder: Reorder::every_bounce(ReorderMode::SortIndex).with_key_bits(bits),
            ..s
        };
        let e = s.validate().unwrap_err();
        assert!(e.to_string().contains("key bits"), "{e}");
    }
}

#[test]
fn sorted_wavefront_renders_the_same_image() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("sorted_wavefront_renders_the_same_image")
    else {
        return;
    };
    for (name, scene) in schedule_scenes() {
        let bvh = bvh(&scene);
        let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
        // 3 batches (2 + 2 + 1 samples), so buffers and sorts are reused across batches and
        // the last batch is smaller than the sorter's capacity.
        let base = TraceSettings {
            batch_spp: 2,
            ..settings(24, 16, 5, 6, Schedule::Wavefront)
        };
        let off = tracer.render(&base, &mut |_, _| {}).unwrap();
        assert!(off.timing("sort").is_none(), "{name}: no sort when off");
        for mode in MODES {
            let s = with(base, Reorder::every_bounce(mode));
            let on = tracer.render(&s, &mut |_, _| {}).unwrap();
            // Bit-identical, not merely close: every sample is the same sequence of the same
            // functions on the same random numbers (keyed by pixel, sample, bounce and
            // dimension, never by the ray's slot), it lands in its own slot whichever thread
            // traced it, and `resolve` sums each pixel's samples in sample order. Sorting only
            // changes which thread runs which ray, so not one bit may change.
            assert_eq!(on.radiance, off.radiance, "{name} {mode:?}");
            assert_eq!(on.rays_traced, off.rays_traced, "{name} {mode:?}");
            assert_eq!(on.dropped_samples, off.dropped_samples, "{name} {mode:?}");
            assert!(on.timing("sort").is_some(), "{name} {mode:?}: sort timed");
            assert_eq!(
                on.timing("permute_rays").is_some(),
                mode == ReorderMode::SortPermute,
                "{name} {mode:?}"
            );
        }
    }
}

#[test]
fn sorting_works_on_pixel_range_batches() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("sorting_works_on_pixel_range_batches")
    else {
        return;
    };
    let scene = cornell_box();
    let bvh = bvh(&scene);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let base = settings(20, 12, 3, 5, Schedule::Megakernel);
    let whole = tracer.render(&base, &mut |_, _| {}).unwrap();
    // A ray cap below the pixel count: ranges of 100 pixels, one sample at a time, each
    // sorted in its own batch (the last range has 40 pixels).
    tracer.set_batch_ray_limit(Some(100));
    for mode in MODES {
        let s = with(base, Reorder::every_bounce(mode));
        let chunked = tracer.render(&s, &mut |_, _| {}).unwrap();
        assert_eq!(chunked.radiance, whole.radiance, "{mode:?}");
        assert_eq!(chunked.rays_traced, whole.rays_traced, "{mode:?}");
    }
}

#[test]
fn sorting_orders_the_live_rays_by_key() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("sorting_orders_the_live_rays_by_key")
    else {
        return;
    };
    let scene = cornell_box();
    let bvh = bvh(&scene);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let base = settings(32, 32, 2, 5, Schedule::Wavefront);
    for depth in [1, 3] {
        tracer.capture_sort(Some(depth));
        tracer.render(&base, &mut |_, _| {}).unwrap();
        let off = tracer.sort_capture().unwrap().expect("captured");
        assert_eq!(off.depth, depth);
        assert!(
            off.count > 100,
            "depth {depth}: only {} live rays",
            off.count
        );
        // Unsorted, the live rays are in compaction order, far from key order: the test
        // below could tell the difference.
        let off_keys: Vec<u32> = (0..off.count as usize).map(|i| cpu_key(&off, i)).collect();
        let descents = off_keys.windows(2).filter(|w| w[0] > w[1]).count();
        assert!(descents > off_keys.len() / 10, "depth {depth}: {descents}");

        for mode in MODES {
            let s = with(base, Reorder::every_bounce(mode));
            tracer.render(&s, &mut |_, _| {}).unwrap();
            let c = tracer.sort_capture().unwrap().expect("captured");
            assert_eq!(c.plan.reorder.mode, mode);
            // The same live rays as without sorting (same paths), each once.
            assert_eq!(c.count, off.count, "depth {depth} {mode:?}");
            assert_eq!(ray_ids(&c), ray_ids(&off), "depth {depth} {mode:?}");
            for i in 0..c.count as usize {
                let st = &c.states[c.rays[i] as usize];
                assert_eq!((st.alive, st.depth), (1, depth), "{mode:?} ray {i}");
                // Each key is the key of the ray beside it (recomputed on the CPU from the
                // ray's state: the WGSL key is bit-identical to raylume-sort's Rust one) ...
                assert_eq!(c.keys[i], cpu_key(&c, i), "depth {depth} {mode:?} ray {i}");
            }
            // ... and the keys are in order: the bounce reads its rays sorted.
            assert!(
                c.keys.windows(2).all(|w| w[0] <= w[1]),
                "depth {depth} {mode:?}: keys not sorted"
            );
            if mode == ReorderMode::SortPermute {
                // The states themselves were moved into key order: the queue is the identity.
                assert!(
                    c.rays.iter().enumerate().all(|(i, &r)| r == i as u32),
                    "{mode:?}"
                );
            }
        }
    }
}

#[test]
fn per_depth_masks_sort_only_where_asked() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("per_depth_masks_sort_only_where_asked")
    else {
        return;
    };
    let scene = cornell_box();
    let bvh = bvh(&scene);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let base = settings(32, 32, 2, 6, Schedule::Wavefront);
    let off = tracer.render(&base, &mut |_, _| {}).unwrap();
    for mode in MODES {
        // Depths 2 and 4 only.
        let r = Reorder {
            depths: (1 << 2) | (1 << 4),
            ..Reorder::every_bounce(mode)
        };
        let s = with(base, r);
        for (depth, sorted) in [(2, true), (3, false), (4, true), (5, false)] {
            tracer.capture_sort(Some(depth));
            let stats = tracer.render_to_buffer(&s, &mut |_, _| {}).unwrap();
            let c = tracer.sort_capture().unwrap().unwrap();
            let keys: Vec<u32> = (0..c.count as usize).map(|i| cpu_key(&c, i)).collect();
            let in_order = keys.windows(2).all(|w| w[0] <= w[1]);
            assert_eq!(in_order, sorted, "{mode:?} depth {depth}");
            // Sort (and permute) passes ran exactly at depths 2 and 4, in every batch.
            let sorted_depths: Vec<u32> = stats.batches[0]
                .stages
                .iter()
                .filter(|st| st.label == "sort_keys")
                .filter_map(|st| st.depth)
                .collect();
            assert_eq!(sorted_depths, [2, 4], "{mode:?}");
            let permuted = stats.batches[0]
                .stages
                .iter()
                .filter(|st| st.label == "permute_rays")
                .count();
            assert_eq!(
                permuted,
                if mode == ReorderMode::SortPermute {
                    2
                } else {
                    0
                }
            );
            assert_eq!(stats.depths.len(), 7, "depths 0..=6");
            for d in &stats.depths {
                assert!(d.propagate > 0.0, "{d:?}");
                assert_eq!(d.sort > 0.0, d.depth == 2 || d.depth == 4, "{d:?}");
            }
        }
        tracer.capture_sort(None);
        let img = tracer.render(&s, &mut |_, _| {}).unwrap();
        assert_eq!(img.radiance, off.radiance, "{mode:?}");
    }
}

/// A policy that runs its plans in turn, one per batch, and records what it saw.
struct Rotate {
    plans: Vec<BatchPlan>,
    seen: Vec<(usize, BatchPlan, bool, f64)>,
}

impl BatchPolicy for Rotate {
    fn candidates(&self) -> Vec<BatchPlan> {
        self.plans.clone()
    }
    fn plan(&mut self, index: usize, batches: &[Batch]) -> BatchPlan {
        assert!(index < batches.len());
        self.plans[index % self.plans.len()]
    }
    fn observe(&mut self, t: &BatchTiming) {
        let stage_sum: f64 = t.stages.iter().map(|s| s.seconds).sum();
        assert!(t.wall_seconds > 0.0 && stage_sum > 0.0, "{t:?}");
        self.seen.push((t.index, t.plan, t.full, t.wall_seconds));
    }
}

#[test]
fn a_policy_may_switch_plans_between_batches() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("a_policy_may_switch_plans_between_batches")
    else {
        return;
    };
    let scene = spheres();
    let bvh = bvh(&scene);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let base = TraceSettings {
        batch_spp: 2,
        ..settings(20, 12, 9, 5, Schedule::Megakernel)
    };
    let whole = tracer.render(&base, &mut |_, _| {}).unwrap();
    let plans = vec![
        BatchPlan {
            schedule: Schedule::Megakernel,
            reorder: Reorder::OFF,
        },
        BatchPlan {
            schedule: Schedule::Wavefront,
            reorder: Reorder::every_bounce(ReorderMode::SortPermute),
        },
        BatchPlan {
            schedule: Schedule::Wavefront,
            reorder: Reorder::OFF,
        },
        BatchPlan {
            schedule: Schedule::Wavefront,
            reorder: Reorder::from_depth(ReorderMode::SortIndex, 2),
        },
    ];
    let mut policy = Rotate {
        plans: plans.clone(),
        seen: Vec::new(),
    };
    let stats = tracer
        .render_with_policy(&base, &mut policy, &mut |_, _| {})
        .unwrap();
    let pixels = (base.width * base.height) as usize;
    let img: Vec<[f32; 3]> = ctx
        .read_buffer(tracer.image_buffer().unwrap(), pixels)
        .unwrap();
    assert_eq!(img, whole.radiance);
    assert_eq!(stats.rays_traced, whole.rays_traced);
    // 9 spp in batches of 2: five batches, the last (1 spp) not full.
    let seen: Vec<_> = policy.seen.iter().map(|s| (s.0, s.1, s.2)).collect();
    let expect: Vec<_> = (0..5).map(|i| (i, plans[i % 4], i < 4)).collect();
    assert_eq!(seen, expect);
    assert_eq!(stats.batches.len(), 5);

    // A plan beyond the candidates (permuting, when no candidate did) is refused.
    struct Sneaky;
    impl BatchPolicy for Sneaky {
        fn candidates(&self) -> Vec<BatchPlan> {
            vec![BatchPlan {
                schedule: Schedule::Wavefront,
                reorder: Reorder::every_bounce(ReorderMode::SortIndex),
            }]
        }
        fn plan(&mut self, _: usize, _: &[Batch]) -> BatchPlan {
            BatchPlan {
                schedule: Schedule::Wavefront,
                reorder: Reorder::every_bounce(ReorderMode::SortPermute),
            }
        }
        fn observe(&mut self, _: &BatchTiming) {}
    }
    let e = tracer
        .render_with_policy(&base, &mut Sneaky, &mut |_, _| {})
        .unwrap_err();
    assert!(matches!(e, KernelError::InvalidSettings(_)), "{e}");
    assert!(e.to_string().contains("sort-permute"), "{e}");
}

#[test]
fn sorting_by_the_top_key_bits_sorts_coarsely_and_changes_nothing_else() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "sorting_by_the_top_key_bits_sorts_coarsely_and_changes_nothing_else",
    ) else {
        return;
    };
    let scene = cornell_box();
    let bvh = bvh(&scene);
    let mut tracer = GpuTracer::new(ctx, &scene, &bvh).unwrap();
    let base = settings(32, 32, 2, 4, Schedule::Wavefront);
    let off = tracer.render(&base, &mut |_, _| {}).unwrap();
    tracer.capture_sort(Some(2));
    for (mode, bits) in [(ReorderMode::SortIndex, 16), (ReorderMode::SortPermute, 9)] {
        let s = with(base, Reorder::every_bounce(mode).with_key_bits(bits));
        let img = tracer.render(&s, &mut |_, _| {}).unwrap();
        assert_eq!(img.radiance, off.radiance, "{mode:?} {bits}");
        let c = tracer.sort_capture().unwrap().unwrap();
        // The sorted keys are the top `bits` of each ray's key, in order; below them the
        // order is whatever compaction left (a stable sort keeps it).
        let shift = 30 - bits;
        for i in 0..c.count as usize {
            assert_eq!(
                c.keys[i],
                cpu_key(&c, i) >> shift,
                "{mode:?} {bits} ray {i}"
            );
        }
        assert!(c.keys.windows(2).all(|w| w[0] <= w[1]), "{mode:?} {bits}");
        let full: Vec<u32> = (0..c.count as usize).map(|i| cpu_key(&c, i)).collect();
        assert!(
            full.windows(2).any(|w| w[0] > w[1]),
            "{mode:?} {bits}: coarser than a full sort"
        );
    }
    // Two key widths in one render: both sorters exist side by side.
    let mut policy = Rotate {
        plans: vec![
            BatchPlan {
                schedule: Schedule::Wavefront,
                reorder: Reorder::every_bounce(ReorderMode::SortIndex).with_key_bits(16),
            },
            BatchPlan {
                schedule: Schedule::Wavefront,
                reorder: Reorder::every_bounce(ReorderMode::SortIndex),
            },
        ],
        seen: Vec::new(),
    };
    let s = TraceSettings {
        batch_spp: 1,
        ..base
    };
    tracer
        .render_with_policy(&s, &mut policy, &mut |_, _| {})
        .unwrap();
    let img: Vec<[f32; 3]> = ctx
        .read_buffer(tracer.image_buffer().unwrap(), 32 * 32)
        .unwrap();
    assert_eq!(img, off.radiance);
    assert_eq!(policy.seen.len(), 2);
}
