//! Bloom at 1000x1000 (the paper's resolution), radius 8 (the scene format's example), on the
//! GPU and on the CPU.
//!
//! - `bloom_1000x1000/gpu_r8`: GPU time of the four passes from timestamp queries (wall time
//!   around submit + wait where the adapter has no timestamps).
//! - `bloom_1000x1000/gpu_wall_r8`: wall time of encode + submit + wait, image reset included
//!   (a 12 MB buffer copy), i.e. what one bloom costs the host.
//! - `bloom_1000x1000/cpu_r8`: `bloom_cpu` on all cores (rayon).
//!
//! Before the GPU benchmarks, one line per radius gives the median time of each stage over
//! 21 runs, which shows what the separate threshold and add passes cost.
//!
//! `RAYLUME_BENCH_RADII=2,8,32` benchmarks other radii. Run:
//! `cargo bench -p raylume-post --bench bloom`, or the built binary
//! (`target/release/deps/bloom-*`) with `--bench`.

use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use raylume_gpu::{ContextOptions, GpuContext, Timestamps, wgpu};
use raylume_post::{BLOOM_STAGES, BloomParams, GpuBloom, bloom_cpu};

const W: u32 = 1000;
const H: u32 = 1000;

fn radii() -> Vec<u32> {
    std::env::var("RAYLUME_BENCH_RADII")
        .ok()
        .map(|s| s.split(',').filter_map(|r| r.trim().parse().ok()).collect())
        .filter(|v: &Vec<u32>| !v.is_empty())
        .unwrap_or_else(|| vec![8])
}

fn params(radius: u32) -> BloomParams {
    BloomParams {
        radius,
        ..BloomParams::scene_default()
    }
}

/// A deterministic HDR image: smooth gradients with a sparse set of very bright pixels.
fn image() -> Vec<[f32; 3]> {
    (0..W * H)
        .map(|i| {
            let (x, y) = ((i % W) as f32, (i / W) as f32);
            let base = 0.5 + 0.4 * (x * 0.01).sin() * (y * 0.013).cos();
            let hot = if i.wrapping_mul(2_654_435_761) % 97 == 0 {
                20.0
            } else {
                0.0
            };
            [base + hot, base * 0.8, base * 0.6 + hot * 0.5]
        })
        .collect()
}

fn bench_cpu(c: &mut Criterion) {
    let img = image();
    let mut g = c.benchmark_group("bloom_1000x1000");
    g.throughput(Throughput::Elements(u64::from(W * H)));
    for r in radii() {
        g.bench_function(format!("cpu_r{r}"), |b| {
            b.iter_batched_ref(
                || img.clone(),
                |px| bloom_cpu(px, W, H, params(r)).expect("cpu bloom"),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

struct Gpu {
    ctx: GpuContext,
    bloom: GpuBloom,
    source: wgpu::Buffer,
    image: wgpu::Buffer,
    ts: Option<Timestamps>,
}

impl Gpu {
    fn new() -> Option<Self> {
        let ctx = match GpuContext::new(&ContextOptions::default()) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("SKIPPED GPU bloom benchmarks: {e}");
                return None;
            }
        };
        eprintln!("GPU: {}", ctx.describe());
        let img = image();
        let bloom = GpuBloom::new(&ctx).expect("bloom pipelines");
        let source = ctx
            .storage_buffer("bench source", &img, wgpu::BufferUsages::COPY_SRC)
            .expect("source");
        let image = ctx
            .storage_buffer_zeroed(
                "bench image",
                u64::from(W * H) * 12,
                wgpu::BufferUsages::COPY_DST,
            )
            .expect("image");
        let ts = Timestamps::new(&ctx, BLOOM_STAGES.len() as u32);
        Some(Self {
            ctx,
            bloom,
            source,
            image,
            ts,
        })
    }

    /// Resets the image, runs bloom once, waits. Returns per-stage GPU seconds (empty without
    /// timestamps) and the wall time.
    fn run(&mut self, r: u32, timed: bool) -> (Vec<(&'static str, f64)>, Duration) {
        let start = Instant::now();
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(&self.source, 0, &self.image, 0, u64::from(W * H) * 12);
        let ts = if timed { self.ts.as_mut() } else { None };
        self.bloom
            .encode(&self.ctx, &mut enc, &self.image, W, H, params(r), ts)
            .expect("encode");
        if let (true, Some(ts)) = (timed, &self.ts) {
            ts.resolve(&mut enc);
        }
        self.ctx.queue.submit([enc.finish()]);
        self.ctx.wait("bloom bench").expect("wait");
        let wall = start.elapsed();
        let stages = match (&mut self.ts, timed) {
            (Some(ts), true) => ts.read(&self.ctx).expect("timestamps"),
            _ => Vec::new(),
        };
        (stages, wall)
    }
}

fn bench_gpu(c: &mut Criterion) {
    let Some(mut gpu) = Gpu::new() else {
        return;
    };
    for r in radii() {
        // Per-stage medians, to see what each pass costs.
        let runs: Vec<Vec<(&str, f64)>> = (0..21).map(|_| gpu.run(r, true).0).collect();
        if runs[0].is_empty() {
            eprintln!("r={r}: no timestamp queries on this adapter");
        } else {
            let mut line = format!("r={r} median GPU time per stage:");
            for (k, stage) in BLOOM_STAGES.iter().enumerate() {
                let mut t: Vec<f64> = runs.iter().map(|s| s[k].1).collect();
                t.sort_by(f64::total_cmp);
                line += &format!(" {stage} {:.1} us", t[t.len() / 2] * 1e6);
            }
            eprintln!("{line}");
        }
    }
    let mut g = c.benchmark_group("bloom_1000x1000");
    g.throughput(Throughput::Elements(u64::from(W * H)));
    for r in radii() {
        g.bench_function(format!("gpu_r{r}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let (stages, wall) = gpu.run(r, true);
                    total += if stages.is_empty() {
                        wall
                    } else {
                        Duration::from_secs_f64(stages.iter().map(|s| s.1).sum())
                    };
                }
                total
            })
        });
        g.bench_function(format!("gpu_wall_r{r}"), |b| {
            b.iter_custom(|iters| (0..iters).map(|_| gpu.run(r, false).1).sum())
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_gpu, bench_cpu
}
criterion_main!(benches);
