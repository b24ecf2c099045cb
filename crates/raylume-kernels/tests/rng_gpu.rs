//! The WGSL random numbers equal the Rust mirror's bit for bit: pcg4d's four words and the
//! four floats of `rand4`, for 100 000 keys (consecutive pixels and samples, as the tracer
//! uses them, and random keys with every bit pattern).

use raylume_gpu::wgpu;
use raylume_kernels::rng::{RNG_WGSL, pcg4d, rand4, rng_key};

const KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> keys: array<u32>;
@group(0) @binding(1) var<storage, read_write> out: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&keys) / 5u) {
        return;
    }
    let k = 5u * i;
    let seed = keys[k];
    let pixel = keys[k + 1u];
    let sample = keys[k + 2u];
    let bounce = keys[k + 3u];
    let dim = keys[k + 4u];
    let h = pcg4d(rng_key(seed, pixel, sample, bounce, dim));
    let f = rand4(seed, pixel, sample, bounce, dim);
    let o = 8u * i;
    out[o] = h.x;
    out[o + 1u] = h.y;
    out[o + 2u] = h.z;
    out[o + 3u] = h.w;
    out[o + 4u] = bitcast<u32>(f.x);
    out[o + 5u] = bitcast<u32>(f.y);
    out[o + 6u] = bitcast<u32>(f.z);
    out[o + 7u] = bitcast<u32>(f.w);
}
"#;

fn keys() -> Vec<[u32; 5]> {
    let mut keys = Vec::new();
    // The tracer's pattern: consecutive pixels and samples, small bounces and dimensions.
    for pixel in 0..20_000 {
        keys.push([0, pixel, pixel % 7, pixel % 11, pixel % 3]);
        keys.push([1234, pixel, 100 + pixel / 1000, 10, 1]);
    }
    // Random keys over the full ranges (a xorshift stream, reproducible).
    let mut x = 0x9E37_79B9u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    while keys.len() < 100_000 {
        keys.push([next(), next(), next(), next() >> 4, next() & 15]);
    }
    keys
}

#[test]
fn wgsl_rng_equals_rust_bit_for_bit() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("wgsl_rng_equals_rust_bit_for_bit")
    else {
        return;
    };
    let keys = keys();
    let flat: Vec<u32> = keys.iter().flatten().copied().collect();
    let key_buf = ctx
        .storage_buffer("rng keys", &flat, wgpu::BufferUsages::empty())
        .unwrap();
    let out_buf = ctx
        .storage_buffer_zeroed(
            "rng out",
            (keys.len() * 32) as u64,
            wgpu::BufferUsages::COPY_SRC,
        )
        .unwrap();
    ctx.scoped("rng kernel", || {
        let module = ctx
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("rng test"),
                source: wgpu::ShaderSource::Wgsl(format!("{RNG_WGSL}\n{KERNEL}").into()),
            });
        let pipeline = ctx
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("rng test"),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
        let bg = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: key_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: out_buf.as_entire_binding(),
                },
            ],
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups((keys.len() as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
    })
    .unwrap();
    let out: Vec<u32> = ctx.read_buffer(&out_buf, keys.len() * 8).unwrap();
    for (i, k) in keys.iter().enumerate() {
        let [seed, pixel, sample, bounce, dim] = *k;
        let h = pcg4d(rng_key(seed, pixel, sample, bounce, dim));
        let f = rand4(seed, pixel, sample, bounce, dim)
            .to_array()
            .map(f32::to_bits);
        assert_eq!(&out[8 * i..8 * i + 4], &h, "pcg4d of key {k:?}");
        assert_eq!(&out[8 * i + 4..8 * i + 8], &f, "rand4 of key {k:?}");
    }
}
