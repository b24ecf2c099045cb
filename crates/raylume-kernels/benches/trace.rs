//! The tracer on the Cornell box: GPU megakernel, wavefront, the wavefront sorting its rays
//! before every bounce (through the index, and permuting the states), and the CPU mirror
//! (with next-event estimation also one path at a time against `cpu::packet`'s eight).
//!
//! Sizes: the paper's 1000x1000, 10 bounces, at `RAYLUME_BENCH_SPP` samples per pixel
//! (default 100) on a hardware GPU; 64x64 at 4 spp on a software adapter (lavapipe) and on
//! the CPU (`RAYLUME_BENCH_CPU_SIZE` overrides the CPU's side). Before measuring, one render
//! per variant prints its stage timings (GPU timestamps) and ray rate.
//!
//! `cargo bench -p raylume-kernels --bench trace`

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use raylume_gpu::{ContextOptions, GpuContext};
use raylume_kernels::{
    CpuTracer, GpuTracer, Reorder, ReorderMode, Schedule, TraceOutput, TraceSettings,
};

#[path = "../tests/support/mod.rs"]
mod support;

fn env_u32(name: &str, default: u32) -> u32 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn report(what: &str, s: &TraceSettings, o: &TraceOutput) {
    let trace = o.timing("trace").unwrap_or(f64::NAN);
    let stages: Vec<String> = o
        .timings
        .iter()
        .map(|(l, t)| format!("{l} {t:.4}s"))
        .collect();
    eprintln!(
        "{what} {}x{} {} spp {} bounces: {:.1} M rays in {trace:.4} s = {:.1} M rays/s [{}]",
        s.width,
        s.height,
        s.spp,
        s.max_bounces,
        o.rays_traced as f64 * 1e-6,
        o.rays_traced as f64 * 1e-6 / trace,
        stages.join(", ")
    );
}

fn bench(c: &mut Criterion) {
    let scene = support::cornell_box();
    // The preset a render would use for this scene (Quality below a million primitives).
    let quality = raylume_bvh::BvhQuality::for_primitive_count(scene.primitive_count());
    let bvh = raylume_bvh::GpuBvh::from_scene(&scene, quality).expect("BVH");
    let mut group = c.benchmark_group("cornell");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));

    match GpuContext::new(&ContextOptions::default()) {
        Ok(ctx) => {
            let (side, spp) = if ctx.info.is_software {
                (64, 4)
            } else {
                (1000, env_u32("RAYLUME_BENCH_SPP", 100))
            };
            eprintln!("adapter: {}", ctx.describe());
            for (schedule, reorder) in [
                (Schedule::Megakernel, Reorder::OFF),
                (Schedule::Wavefront, Reorder::OFF),
                (
                    Schedule::Wavefront,
                    Reorder::every_bounce(ReorderMode::SortIndex),
                ),
                (
                    Schedule::Wavefront,
                    Reorder::every_bounce(ReorderMode::SortPermute),
                ),
            ] {
                let name = match reorder.mode {
                    ReorderMode::Off => schedule.name().to_string(),
                    mode => format!("{}_{}", schedule.name(), mode.name()),
                };
                let s = TraceSettings {
                    width: side,
                    height: side,
                    spp,
                    max_bounces: 10,
                    seed: 0,
                    batch_spp: env_u32("RAYLUME_BENCH_BATCH_SPP", 20),
                    schedule,
                    reorder,
                };
                let mut tracer = GpuTracer::new(&ctx, &scene, &bvh).expect("GPU tracer");
                let out = tracer.render(&s, &mut |_, _| {}).expect("render");
                report(&format!("gpu {name}"), &s, &out);
                group.bench_function(format!("gpu_{name}_{side}x{side}_{spp}spp"), |b| {
                    b.iter(|| tracer.render_to_buffer(&s, &mut |_, _| {}).expect("render"))
                });
            }
        }
        Err(e) => eprintln!("no GPU adapter ({e}); GPU benches skipped"),
    }

    let side = env_u32("RAYLUME_BENCH_CPU_SIZE", 64);
    let s = TraceSettings {
        width: side,
        height: side,
        spp: 4,
        max_bounces: 10,
        seed: 0,
        batch_spp: 20,
        schedule: Schedule::Megakernel,
        reorder: raylume_kernels::Reorder::OFF,
    };
    let mut cpu = CpuTracer::new(&scene, &bvh).expect("CPU tracer");
    report("cpu", &s, &cpu.render(&s, &mut |_, _| {}).expect("render"));
    group.bench_function(format!("cpu_{side}x{side}_4spp"), |b| {
        b.iter(|| cpu.render(&s, &mut |_, _| {}).expect("render"))
    });
    // Next-event estimation with the Sobol' sampler and roulette (the library's defaults),
    // eight paths at a time (`cpu::packet`, this scene's default) and one at a time: the
    // same image, what the packets save.
    cpu.set_estimator(raylume_kernels::Estimator::Nee);
    cpu.set_sampler(raylume_kernels::Sampler::Sobol);
    cpu.set_russian_roulette(Some(5));
    for (packets, name) in [(true, "packets"), (false, "one_path")] {
        cpu.set_packets(packets);
        report(
            &format!("cpu nee {name}"),
            &s,
            &cpu.render(&s, &mut |_, _| {}).expect("render"),
        );
        group.bench_function(format!("cpu_nee_{name}_{side}x{side}_4spp"), |b| {
            b.iter(|| cpu.render(&s, &mut |_, _| {}).expect("render"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
