//! The `Sobol` sampler's numbers for one path segment (its light's, scattered direction's and
//! roulette's pair groups), as the CPU tracer draws them: one `SegmentKeys::draw` from the
//! render's table of hashes, against the three per-group draws it replaced (`sobol4_at`,
//! `sobol4_at`, `sobol2_at`, each hashing its group), and the independent sampler's three
//! `rand4`. The pixel's `SobolPixel` is computed once a path, outside the loop.
//!
//! `cargo bench -p raylume-kernels --bench sampler`

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{UVec2, Vec4};
use raylume_kernels::gpu_types::{DIM_LIGHT, DIM_ROULETTE, DIM_SCATTER, DIMS_PER_BOUNCE};
use raylume_kernels::rng::rand4;
use raylume_kernels::sobol::{SegmentKeys, SobolPixel, sobol_pixel, sobol2_at, sobol4_at};

/// Segments drawn per iteration: 1,024 pixels' sample 3 at segments 0..10.
const PIXELS: u32 = 1024;
const SEGMENTS: u32 = 10;

fn bench(c: &mut Criterion) {
    let (seed, spp, sample) = (7u32, 16u32, 3u32);
    let pixels: Vec<SobolPixel> = (0..PIXELS)
        .map(|i| sobol_pixel(seed, UVec2::new(i % 640, i / 640 * 97), spp))
        .collect();
    let keys: Vec<SegmentKeys> = (0..SEGMENTS).map(|b| SegmentKeys::new(seed, b)).collect();
    let mut group = c.benchmark_group("sampler_segment");
    group.throughput(Throughput::Elements(u64::from(PIXELS * SEGMENTS)));
    group.bench_function("sobol_table_draw", |b| {
        b.iter(|| {
            let mut acc = Vec4::ZERO;
            for p in &pixels {
                for k in &keys {
                    let (light, scatter, roulette) = k.draw(*p, sample);
                    acc += light + scatter + roulette;
                }
            }
            black_box(acc)
        })
    });
    group.bench_function("sobol_per_group", |b| {
        b.iter(|| {
            let mut acc = Vec4::ZERO;
            for p in &pixels {
                for bounce in 0..SEGMENTS {
                    let g = |dim| bounce * DIMS_PER_BOUNCE + dim;
                    acc += sobol4_at(true, *p, sample, g(DIM_LIGHT))
                        + sobol4_at(true, *p, sample, g(DIM_SCATTER))
                        + sobol2_at(true, *p, sample, g(DIM_ROULETTE)).x;
                }
            }
            black_box(acc)
        })
    });
    group.bench_function("independent", |b| {
        b.iter(|| {
            let mut acc = Vec4::ZERO;
            for pixel in 0..PIXELS {
                for bounce in 0..SEGMENTS {
                    acc += rand4(seed, pixel, sample, bounce, DIM_LIGHT)
                        + rand4(seed, pixel, sample, bounce, DIM_SCATTER)
                        + rand4(seed, pixel, sample, bounce, DIM_ROULETTE).x;
                }
            }
            black_box(acc)
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
