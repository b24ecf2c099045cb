use glam::Vec3;
use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_scene::Triangle;
use std::time::Instant;

fn grid(k: usize) -> Vec<Triangle> {
    let h = |x: usize, z: usize| (((x * 7 + z * 13) % 17) as f32 * 0.37).sin() * 0.5;
    let p = |x: usize, z: usize| Vec3::new(x as f32, h(x, z), z as f32);
    let mut out = Vec::with_capacity(2 * k * k);
    for z in 0..k {
        for x in 0..k {
            out.push(Triangle::flat([p(x, z), p(x + 1, z), p(x + 1, z + 1)], 0));
            out.push(Triangle::flat([p(x, z), p(x + 1, z + 1), p(x, z + 1)], 0));
        }
    }
    out
}

fn main() {
    let t = Instant::now();
    let ctx = raylume_gpu::GpuContext::new(&Default::default()).unwrap();
    println!(
        "context {:.3} s: {}",
        t.elapsed().as_secs_f64(),
        ctx.describe()
    );
    let t = Instant::now();
    let mut b = raylume_kernels::gpu::LbvhBuilder::new(&ctx).unwrap();
    println!("builder compile {:.3} s", t.elapsed().as_secs_f64());
    for k in [224usize, 707, 1224] {
        let tris = grid(k);
        for round in 0..3 {
            let t = Instant::now();
            let source = GpuBvh::lbvh_input(&tris).unwrap();
            let t_in = t.elapsed().as_secs_f64();
            let built = b.build(&ctx, &source).unwrap();
            let total = t.elapsed().as_secs_f64();
            println!(
                "{} tris round {round}: input {:.4} gpu (upload+build) {:.4} total {:.4} depth {} nodes {}",
                tris.len(),
                t_in,
                built.gpu_seconds,
                total,
                built.bvh.stats.max_depth,
                built.bvh.nodes.len()
            );
        }
        for round in 0..2 {
            let t = Instant::now();
            let bvh = GpuBvh::build_with_layout(&tris, &[], BvhQuality::Fastest, BvhLayout::Wide)
                .unwrap();
            println!(
                "{} tris CPU fastest wide round {round}: {:.4} s ({} wide nodes)",
                tris.len(),
                t.elapsed().as_secs_f64(),
                bvh.wide_nodes.len()
            );
        }
    }
}
