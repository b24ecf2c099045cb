//! Round hooks (`render_with_hook`, `render_to_buffer_with_hook`): after every round the hook
//! sees the running sums of every pixel, also when the image is split into pixel ranges
//! (GPU, a low batch ray limit), and a render it stops is bit for bit the render of the
//! samples traced.

mod support;

use raylume_kernels::batches::{RoundFlow, RoundSums};
use raylume_kernels::{CpuTracer, GpuTracer, Schedule, TraceSettings};
use support::*;

type Rounds = Vec<(u32, u32, Vec<[f32; 3]>)>;

/// A hooked GPU render of `s`: every round's (round, samples done, sums), and the image it
/// leaves, stopping after round `stop_after` if given; `ray_limit` caps the rays per batch.
fn gpu_rounds(
    ctx: &raylume_gpu::GpuContext,
    scene: &raylume_scene::Scene,
    s: &TraceSettings,
    ray_limit: Option<u64>,
    stop_after: Option<u32>,
) -> (Rounds, Vec<[f32; 3]>) {
    let mut t = GpuTracer::new(ctx, scene, &bvh(scene)).unwrap();
    t.set_batch_ray_limit(ray_limit);
    let mut rounds = Vec::new();
    t.render_to_buffer_with_hook(s, &mut |_, _| {}, &mut |r: &RoundSums<'_>| {
        rounds.push((r.round, r.samples_done, r.sums.to_vec()));
        if stop_after == Some(r.round) {
            RoundFlow::Stop
        } else {
            RoundFlow::Continue
        }
    })
    .unwrap();
    let image = ctx
        .read_buffer::<[f32; 3]>(t.image_buffer().unwrap(), (s.width * s.height) as usize)
        .unwrap();
    (rounds, image)
}

#[test]
fn gpu_rounds_of_a_split_image_are_whole_images_and_a_stopped_render_is_exact() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "gpu_rounds_of_a_split_image_are_whole_images_and_a_stopped_render_is_exact",
    ) else {
        return;
    };
    let scene = cornell_box();
    let s = TraceSettings {
        batch_spp: 3,
        ..settings(24, 16, 6, 3, Schedule::Megakernel)
    };
    let pixels = 24 * 16;
    // Whole batches: rounds after 3 and 6 samples.
    let (whole, image) = gpu_rounds(ctx, &scene, &s, None, None);
    let done: Vec<(u32, u32)> = whole.iter().map(|r| (r.0, r.1)).collect();
    assert_eq!(done, vec![(1, 3), (2, 6)]);
    // The hooked render's image is the unhooked one, bit for bit.
    let plain = render_gpu(ctx, &scene, &s);
    assert!(image == plain.radiance, "hooked vs unhooked image");

    // 100 rays per batch: one sample of 100 pixels at a time, 4 pixel ranges per round, so
    // six rounds of one sample; each still sees every pixel, and each pixel's samples are
    // summed in the same order, so the sums after 3 and 6 samples are the same bits.
    let (split, image) = gpu_rounds(ctx, &scene, &s, Some(100), None);
    let done: Vec<u32> = split.iter().map(|r| r.1).collect();
    assert_eq!(done, vec![1, 2, 3, 4, 5, 6]);
    assert!(split.iter().all(|r| r.2.len() == pixels));
    assert!(split[2].2 == whole[0].2, "sums after 3 samples");
    assert!(split[5].2 == whole[1].2, "sums after 6 samples");
    assert!(image == plain.radiance, "split hooked image");

    // Stopped after the 4th round: the image of a 4-sample render.
    let (stopped, image) = gpu_rounds(ctx, &scene, &s, Some(100), Some(4));
    assert_eq!(stopped.len(), 4);
    let four = render_gpu(ctx, &scene, &TraceSettings { spp: 4, ..s });
    assert!(image == four.radiance, "stopped after 4 samples");
}

#[test]
fn cpu_hooked_renders_see_every_round_and_stop_exactly() {
    let scene = cornell_box();
    let s = TraceSettings {
        batch_spp: 2,
        ..settings(16, 12, 7, 3, Schedule::Megakernel)
    };
    let mut t = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
    let mut seen = Vec::new();
    let full = t
        .render_with_hook(&s, &mut |_, _| {}, &mut |r: &RoundSums<'_>| {
            seen.push((r.round, r.samples_done, r.round_samples));
            RoundFlow::Continue
        })
        .unwrap();
    assert_eq!(seen, vec![(1, 2, 2), (2, 4, 2), (3, 6, 2), (4, 7, 1)]);
    assert!(full.radiance == render_cpu(&scene, &s).radiance);
    let stopped = t
        .render_with_hook(&s, &mut |_, _| {}, &mut |r: &RoundSums<'_>| {
            if r.round == 2 {
                RoundFlow::Stop
            } else {
                RoundFlow::Continue
            }
        })
        .unwrap();
    let four = render_cpu(&scene, &TraceSettings { spp: 4, ..s });
    assert!(stopped.radiance == four.radiance);
    assert_eq!(stopped.rays_traced, four.rays_traced);
}
