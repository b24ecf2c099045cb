//! The GPU traces the same paths as the CPU mirror: small renders of the fixture scenes agree
//! to a relative RMSE far below Monte Carlo noise, sample by sample.

mod support;

use raylume_kernels::{CpuTracer, GpuTracer, Schedule};
use support::*;

fn compare(name: &str, scene: &raylume_scene::Scene, w: u32, h: u32, spp: u32, bounces: u32) {
    let Some(ctx) = raylume_gpu::testing::context_or_skip(name) else {
        return;
    };
    let s = settings(w, h, spp, bounces, Schedule::Megakernel);
    let bvh = bvh(scene);
    let cpu_tracer = CpuTracer::new(scene, &bvh).unwrap();
    let cpu = CpuTracer::new(scene, &bvh)
        .unwrap()
        .render(&s, &mut |_, _| {})
        .unwrap();
    let mut gpu_tracer = GpuTracer::new(ctx, scene, &bvh).unwrap();
    let gpu = gpu_tracer.render(&s, &mut |_, _| {}).unwrap();
    let (batch, samples) = gpu_tracer.last_batch_samples().unwrap().unwrap();
    assert_eq!(batch.rays(), w * h * spp, "one batch holds every sample");
    let mut diverged = 0;
    let mut worst = (0.0f32, 0u32, 0u32);
    for (slot, g) in samples.iter().enumerate() {
        let (p, smp) = (slot as u32 % (w * h), slot as u32 / (w * h));
        let c = cpu_tracer.sample_radiance(&s, p, smp);
        let d = (0..3)
            .map(|k| (g[k] - c[k]).abs() / (1.0 + c[k].abs()))
            .fold(0.0, f32::max);
        if d > 1e-4 {
            diverged += 1;
        }
        if d > worst.0 {
            worst = (d, p, smp);
        }
    }
    let e = relative_rmse(&gpu.radiance, &cpu.radiance);
    eprintln!(
        "{name}: rel RMSE {e:.3e}, {diverged} of {} samples differ by > 1e-4, worst {worst:?}; rays {} / {}",
        samples.len(),
        cpu.rays_traced,
        gpu.rays_traced
    );
    assert!(e < 1e-3, "{name}: relative RMSE {e}");
}

#[test]
fn cornell_box_matches_cpu() {
    compare("cornell_box_matches_cpu", &cornell_box(), 32, 32, 4, 4);
}

#[test]
fn spheres_match_cpu() {
    compare("spheres_match_cpu", &spheres(), 32, 32, 4, 6);
}

#[test]
fn textured_matches_cpu() {
    compare("textured_matches_cpu", &textured(), 32, 32, 4, 4);
}

#[test]
fn environment_lit_matches_cpu() {
    compare(
        "environment_lit_matches_cpu",
        &environment_lit(),
        32,
        32,
        4,
        6,
    );
}
