//! The BVH built on the GPU (`gpu::LbvhBuilder::build_triangles`: upload, Morton codes, two
//! radix sorts, the radix tree, the refit passes, the order read back) against the CPU's
//! `Fastest` build of the same triangles (the LBVH, reinsertion and the eight-wide
//! conversion on every core), over issue 19's height-field grids.
//!
//! Run: `cargo bench -p raylume-kernels --bench gpu_build`. `RAYLUME_BENCH_GRIDS=707,1224`
//! (quads per side): these grids; default 224 (100k triangles), 64 on a software adapter
//! (lavapipe builds a 100k-triangle tree in seconds). Without a GPU only the CPU build runs.

use std::time::Duration;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_gpu::{ContextOptions, GpuContext};
use raylume_kernels::gpu::LbvhBuilder;
use raylume_scene::Triangle;

/// An `n` x `n` grid of quads over the unit square, two triangles each (the heights of
/// raylume-bvh's `benches/build.rs`).
fn grid(n: usize) -> Vec<Triangle> {
    let height = |i: usize, j: usize| {
        let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
        0.05 * (12.0 * x).sin() * (9.0 * z).cos() + 0.02 * (31.0 * x + 17.0 * z).sin()
    };
    let p = |i: usize, j: usize| Vec3::new(i as f32 / n as f32, height(i, j), j as f32 / n as f32);
    let mut out = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            out.push(Triangle::flat([a, b, c], 0));
            out.push(Triangle::flat([a, c, d], 0));
        }
    }
    out
}

fn grids(software: bool) -> Vec<usize> {
    match std::env::var("RAYLUME_BENCH_GRIDS") {
        Ok(list) => list
            .split(',')
            .map(|s| {
                s.trim()
                    .parse()
                    .expect("RAYLUME_BENCH_GRIDS: quads per side")
            })
            .collect(),
        Err(_) if software => vec![64],
        Err(_) => vec![224],
    }
}

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::new(&ContextOptions::default()).ok();
    let mut builder = ctx
        .as_ref()
        .map(|ctx| LbvhBuilder::new(ctx).expect("the kernels"));
    let software = ctx.as_ref().is_none_or(|c| c.info.is_software);
    if let Some(ctx) = &ctx {
        eprintln!("adapter: {}", ctx.describe());
    }
    let mut group = c.benchmark_group("bvh_build");
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(if software { 3 } else { 5 }));
    for n in grids(software) {
        let triangles = grid(n);
        group.throughput(Throughput::Elements(triangles.len() as u64));
        if let (Some(ctx), Some(builder)) = (&ctx, builder.as_mut()) {
            group.bench_function(format!("gpu_lbvh/{}", triangles.len()), |b| {
                b.iter(|| builder.build_triangles(ctx, &triangles).expect("built"))
            });
        }
        group.bench_function(format!("cpu_fastest_wide/{}", triangles.len()), |b| {
            b.iter(|| {
                GpuBvh::build_with_layout(&triangles, &[], BvhQuality::Fastest, BvhLayout::Wide)
                    .expect("built")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
