//! `CpuTracer::with_shared`: tracers over one tree and one prepared scene, shared rather than
//! copied, each with its own estimator, roulette, sampler and sample range, render exactly what
//! a tracer with its own copy renders, and leave the shared data as it was.

mod support;

use std::sync::Arc;

use raylume_kernels::scene_data::SceneData;
use raylume_kernels::{CpuTracer, Estimator, Sampler, Schedule};
use support::*;

#[test]
fn shared_tracers_render_what_copies_render_with_their_own_settings() {
    let scene = cornell_box();
    let bvh = Arc::new(bvh(&scene));
    let data = Arc::new(SceneData::new(&scene, &bvh).unwrap());
    let before = data.choices();
    let s = settings(24, 24, 4, 4, Schedule::Megakernel);
    let set = |t: &mut CpuTracer, nee: bool| {
        if nee {
            t.set_estimator(Estimator::Nee);
            t.set_russian_roulette(Some(2));
            t.set_sampler(Sampler::Sobol);
            t.set_sample_range(Some(1..3));
        }
    };
    let mut renders = Vec::new();
    for nee in [true, false] {
        let mut shared = CpuTracer::with_shared(bvh.clone(), data.clone()).unwrap();
        set(&mut shared, nee);
        // The reference: its own copy of the data, the settings written into that copy's
        // fields (no setter involved).
        let mut own = SceneData::clone(&data);
        if nee {
            own.estimator = Estimator::Nee;
            own.russian_roulette = Some(2);
            own.sampler = Sampler::Sobol;
            own.sample_range = Some(1..3);
        }
        let mut copy = CpuTracer::with_data(&bvh, own).unwrap();
        let a = shared.render(&s, &mut |_, _| {}).unwrap();
        let b = copy.render(&s, &mut |_, _| {}).unwrap();
        assert_eq!(a.radiance, b.radiance, "nee {nee}");
        assert_eq!(a.rays_traced, b.rays_traced);
        renders.push(a.radiance);
    }
    assert_ne!(
        renders[0], renders[1],
        "the two tracers' settings took effect"
    );
    assert_eq!(
        data.choices(),
        before,
        "the shared data's own settings are untouched"
    );
    assert_eq!(
        Arc::strong_count(&data),
        1,
        "the tracers dropped their shares"
    );
}
