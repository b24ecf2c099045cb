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
use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_gpu::{ContextOptions, GpuContext};
use raylume_kernels::gpu::LbvhBuilder;
use raylume_scene::Triangle;

/// Issue 19's height field of `n` x `n` quads (`raylume_scene::grid`).
fn grid(n: usize) -> Vec<Triangle> {
    raylume_scene::grid::height_field(n)
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
