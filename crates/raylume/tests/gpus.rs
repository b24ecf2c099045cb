//! `Backend::Gpus` (issue 16): one render split by samples over several devices, here two
//! lavapipe devices (two contexts on the one software adapter CI has), equals the render on
//! one device within `raylume::merge_bound`, with each device's share in the stats.

mod common;

use raylume::{Backend, SampleRange, Tracer, merge_bound, worst_relative_difference};
use raylume_gpu::{AdapterChoice, ContextOptions, GpuContext};

/// Samples per pixel of the test renders.
const SPP: u32 = 8;

#[test]
fn two_devices_render_what_one_does() {
    if raylume_gpu::testing::context_or_skip("two_devices_render_what_one_does").is_none() {
        return;
    }
    let any = ContextOptions {
        choice: AdapterChoice::Any,
        adapter_name: None,
    };
    let devices = vec![
        GpuContext::new(&any).unwrap(),
        GpuContext::new(&any).unwrap(),
    ];
    let mut two = Tracer::with_gpu_contexts(devices);
    assert_eq!(two.backend, Backend::Gpus);
    let scene = common::small_cornell(SPP);
    let one = Tracer::new(Backend::Gpu).render(&scene).unwrap();
    for round in 0..2 {
        let r = two.render(&scene).unwrap();
        assert_eq!(r.stats.backend, "gpus");
        assert_eq!(r.stats.workers.len(), 2);
        let ranges: Vec<SampleRange> = r.stats.workers.iter().map(|w| w.samples.unwrap()).collect();
        assert_eq!(ranges[0].begin, 0, "round {round}: {ranges:?}");
        assert_eq!(ranges[0].end, ranges[1].begin);
        assert_eq!(ranges[1].end, 8);
        assert!(ranges.iter().all(|r| !r.is_empty()));
        assert!(
            r.stats
                .workers
                .iter()
                .all(|w| w.trace_seconds > 0.0 && w.rays_traced > 0)
        );
        let err = worst_relative_difference(&r.pixels, &one.pixels);
        assert!(
            err <= merge_bound(8),
            "round {round}: {err:.3e} past {:.3e}",
            merge_bound(8)
        );
        assert!(r.part.is_none());
    }
    // A part on two devices: the sums of its samples, as one device's part.
    two.samples = Some(SampleRange { begin: 2, end: 7 });
    let p = two.render(&scene).unwrap();
    let header = p.part.clone().expect("a part");
    assert_eq!(header.samples, SampleRange { begin: 2, end: 7 });
    let mut single = Tracer::new(Backend::Gpu);
    single.samples = two.samples;
    let q = single.render(&scene).unwrap();
    assert_eq!(
        q.part.unwrap(),
        header,
        "the same header on one or two devices"
    );
    assert!(worst_relative_difference(&p.pixels, &q.pixels) <= merge_bound(8));
    // Unsupported: a target error.
    two.samples = None;
    two.target_error = Some(1e-3);
    assert!(two.render(&scene).is_err());
}
