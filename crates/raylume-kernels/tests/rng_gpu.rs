//! The WGSL random numbers equal the Rust mirror's bit for bit: pcg4d's four words and the
//! four floats of `rand4`, for 100 000 keys (consecutive pixels and samples, as the tracer
//! uses them, and random keys with every bit pattern); and ZSobol's `sobol4` and `sobol2` and
//! their shuffled variants (`Sampler::Sobol`), large images split into tiles included.

use raylume_gpu::wgpu;
use raylume_kernels::rng::{RNG_WGSL, pcg4d, rand4, rng_key};
use raylume_kernels::sobol::{SOBOL_WGSL, shuffled_sobol2, shuffled_sobol4, sobol2, sobol4};

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
    let out = run(ctx, &format!("{RNG_WGSL}\n{KERNEL}"), &flat, keys.len() * 8);
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

/// Runs the test kernel `wgsl` (entry `main`, keys at binding 0, `out_words` words of output
/// at binding 1) over `keys.len()` invocations' worth of workgroups, and reads `out` back.
fn run(ctx: &raylume_gpu::GpuContext, wgsl: &str, keys: &[u32], out_words: usize) -> Vec<u32> {
    let key_buf = ctx
        .storage_buffer("test keys", keys, wgpu::BufferUsages::empty())
        .unwrap();
    let out_buf = ctx
        .storage_buffer_zeroed(
            "test out",
            (out_words * 4) as u64,
            wgpu::BufferUsages::COPY_SRC,
        )
        .unwrap();
    ctx.scoped("test kernel", || {
        let module = ctx
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("rng test"),
                source: wgpu::ShaderSource::Wgsl(wgsl.into()),
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
    ctx.read_buffer(&out_buf, out_words).unwrap()
}

const SOBOL_KERNEL: &str = r#"
const SOBOL_KEY_WORDS: u32 = 6u;
@group(0) @binding(0) var<storage, read> keys: array<u32>;
@group(0) @binding(1) var<storage, read_write> out: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&keys) / SOBOL_KEY_WORDS) {
        return;
    }
    let k = SOBOL_KEY_WORDS * i;
    let f = sobol4(keys[k], vec2<u32>(keys[k + 1u], keys[k + 2u]), keys[k + 3u], keys[k + 4u], keys[k + 5u]);
    let g = sobol2(keys[k], vec2<u32>(keys[k + 1u], keys[k + 2u]), keys[k + 3u], keys[k + 4u], keys[k + 5u]);
    let fs = shuffled_sobol4(keys[k], vec2<u32>(keys[k + 1u], keys[k + 2u]), keys[k + 3u], keys[k + 4u], keys[k + 5u]);
    let gs = shuffled_sobol2(keys[k], vec2<u32>(keys[k + 1u], keys[k + 2u]), keys[k + 3u], keys[k + 4u], keys[k + 5u]);
    let o = 12u * i;
    out[o] = bitcast<u32>(f.x);
    out[o + 1u] = bitcast<u32>(f.y);
    out[o + 2u] = bitcast<u32>(f.z);
    out[o + 3u] = bitcast<u32>(f.w);
    out[o + 4u] = bitcast<u32>(g.x);
    out[o + 5u] = bitcast<u32>(g.y);
    out[o + 6u] = bitcast<u32>(fs.x);
    out[o + 7u] = bitcast<u32>(fs.y);
    out[o + 8u] = bitcast<u32>(fs.z);
    out[o + 9u] = bitcast<u32>(fs.w);
    out[o + 10u] = bitcast<u32>(gs.x);
    out[o + 11u] = bitcast<u32>(gs.y);
}
"#;

#[test]
fn wgsl_sobol_equals_rust_bit_for_bit() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("wgsl_sobol_equals_rust_bit_for_bit")
    else {
        return;
    };
    // (seed, x, y, sample, spp, dim): a small image's pixels and samples as the tracer draws
    // them (spp 1 to 64, powers of 2 and not), the tiles of large images at large spp
    // (1000x1000 at 8192, 5000 x 3000 at 2^20: tiles of 512 and 64 pixels), and random keys.
    let mut keys: Vec<[u32; 6]> = Vec::new();
    for p in 0..4096u32 {
        let spp = [1u32, 4, 7, 16, 50, 64][(p % 6) as usize];
        keys.push([3, p % 64, p / 64, p % spp, spp, p % 40]);
    }
    for p in 0..4096u32 {
        keys.push([11, (p * 37) % 1000, (p * 101) % 1000, p % 8192, 8192, p % 9]);
        keys.push([
            12,
            (p * 97) % 5000,
            (p * 61) % 3000,
            p * 255,
            1 << 20,
            p % 5,
        ]);
    }
    let mut x = 0x2545_F491u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    while keys.len() < 20_000 {
        let spp = 1 + (next() % (1 << 20));
        keys.push([
            next(),
            next() % 32_768,
            next() % 32_768,
            next() % spp,
            spp,
            next() % 64,
        ]);
    }
    let flat: Vec<u32> = keys.iter().flatten().copied().collect();
    let wgsl = format!("{RNG_WGSL}\n{SOBOL_WGSL}\n{SOBOL_KERNEL}");
    let out = run(ctx, &wgsl, &flat, keys.len() * 12);
    for (i, k) in keys.iter().enumerate() {
        let [seed, px, py, sample, spp, dim] = *k;
        let px = glam::UVec2::new(px, py);
        let o = 12 * i;
        let f = sobol4(seed, px, sample, spp, dim)
            .to_array()
            .map(f32::to_bits);
        assert_eq!(&out[o..o + 4], &f, "sobol4 of key {k:?}");
        let g = sobol2(seed, px, sample, spp, dim)
            .to_array()
            .map(f32::to_bits);
        assert_eq!(&out[o + 4..o + 6], &g, "sobol2 of key {k:?}");
        let f = shuffled_sobol4(seed, px, sample, spp, dim)
            .to_array()
            .map(f32::to_bits);
        assert_eq!(&out[o + 6..o + 10], &f, "shuffled_sobol4 of key {k:?}");
        let g = shuffled_sobol2(seed, px, sample, spp, dim)
            .to_array()
            .map(f32::to_bits);
        assert_eq!(&out[o + 10..o + 12], &g, "shuffled_sobol2 of key {k:?}");
    }
}
