//! `ray_sort_key` in WGSL (`MORTON_WGSL`, included into a test kernel exactly as the tracer
//! includes it) against the Rust function: bit-identical on ~100k random rays and on edge
//! cases (cell boundaries, outside the box, NaN, infinities, degenerate boxes).

use glam::Vec3;
use raylume_sort::morton::{expand_bits_5, morton3_5, quantize_5};
use raylume_sort::{DEAD_RAY_KEY, MORTON_WGSL, ray_sort_key};

/// One ray and its box, as the test kernel reads it: 4 x vec4<f32>.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct KeyInput {
    origin: [f32; 4],
    dir: [f32; 4],
    scene_min: [f32; 4],
    scene_extent: [f32; 4],
}

const KERNEL: &str = r#"
struct KeyInput {
    origin: vec4<f32>,
    dir: vec4<f32>,
    scene_min: vec4<f32>,
    scene_extent: vec4<f32>,
}
@group(0) @binding(0) var<storage, read> inputs: array<KeyInput>;
@group(0) @binding(1) var<storage, read_write> keys: array<u32>;
// Also the helpers on their own, on integers: [expand_bits_5(i), morton3_5(i, i >> 5, i >> 10)].
@group(0) @binding(2) var<storage, read_write> helpers: array<u32>;

@compute @workgroup_size(64)
fn morton_test(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i < arrayLength(&keys)) {
        let r = inputs[i];
        keys[i] = ray_sort_key(r.origin.xyz, r.dir.xyz, r.scene_min.xyz, r.scene_extent.xyz);
    }
    if (i < 32768u) {
        helpers[2u * i] = expand_bits_5(i);
        helpers[2u * i + 1u] = morton3_5(i, i >> 5u, i >> 10u);
    }
    // The constant is visible to including kernels.
    if (i == 0u) {
        helpers[65536u] = DEAD_RAY_KEY;
    }
}
"#;

struct Rng(u64);
impl Rng {
    fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as u32
    }
    fn unit(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / (1 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

fn v4(v: Vec3) -> [f32; 4] {
    [v.x, v.y, v.z, 0.0]
}

fn inputs() -> Vec<KeyInput> {
    let mut rng = Rng(2024);
    let mut out = Vec::new();
    let boxes = [
        (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(2.0, 2.0, 2.0)),
        (Vec3::new(-278.0, -0.5, 0.0), Vec3::new(556.0, 548.8, 559.2)),
        (Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.7, 1e-3, 13.0)),
    ];
    // Random rays in and slightly around each box, random unit and non-unit directions.
    for i in 0..100_000 {
        let (lo, ext) = boxes[i % boxes.len()];
        let t = Vec3::new(
            rng.range(-0.1, 1.1),
            rng.range(-0.1, 1.1),
            rng.range(-0.1, 1.1),
        );
        let o = lo + t * ext;
        let d = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let d = if i % 3 == 0 {
            d * 1.3
        } else {
            d.normalize_or_zero()
        };
        out.push(KeyInput {
            origin: v4(o),
            dir: v4(d),
            scene_min: v4(lo),
            scene_extent: v4(ext),
        });
    }
    // Exactly on cell boundaries: origin = lo + k/32 * ext, direction = -1 + k/16.
    let (lo, ext) = boxes[1];
    for k in 0..=33 {
        let f = k as f32 / 32.0;
        out.push(KeyInput {
            origin: v4(lo + ext * f),
            dir: v4(Vec3::splat(-1.0 + 2.0 * f)),
            scene_min: v4(lo),
            scene_extent: v4(ext),
        });
    }
    // Non-finite and degenerate inputs.
    let specials = [
        f32::NAN,
        -f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        1e-40,
        f32::MAX,
        f32::MIN,
    ];
    for &a in &specials {
        for &b in &specials {
            out.push(KeyInput {
                origin: [a, b, 0.5, 0.0],
                dir: [b, a, 0.25, 0.0],
                scene_min: [0.0, 0.0, 0.0, 0.0],
                scene_extent: [1.0, 1.0, 1.0, 0.0],
            });
            out.push(KeyInput {
                origin: [0.5, 0.5, 0.5, 0.0],
                dir: [0.0, 0.0, 0.0, 0.0],
                scene_min: [a, 0.0, b, 0.0],
                scene_extent: [b, a, 1.0, 0.0],
            });
        }
    }
    out
}

#[test]
fn morton_wgsl_matches_rust() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("morton_wgsl_matches_rust") else {
        return;
    };
    let inputs = inputs();
    let n = inputs.len();
    let src = format!("{MORTON_WGSL}\n{KERNEL}");
    let usage = wgpu::BufferUsages::COPY_SRC;
    let in_buf = ctx.storage_buffer("morton inputs", &inputs, usage).unwrap();
    let key_buf = ctx
        .storage_buffer_zeroed("morton keys", n as u64 * 4, usage)
        .unwrap();
    let helper_buf = ctx
        .storage_buffer_zeroed("morton helpers", (65536 + 1) * 4, usage)
        .unwrap();
    ctx.scoped("morton test kernel", || {
        let module = ctx
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("morton_test"),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            });
        let pipeline = ctx
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("morton_test"),
                layout: None,
                module: &module,
                entry_point: Some("morton_test"),
                compilation_options: Default::default(),
                cache: None,
            });
        let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("morton_test"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: in_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: key_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: helper_buf.as_entire_binding(),
                },
            ],
        });
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups((n.max(32768) as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([encoder.finish()]);
    })
    .unwrap();
    let gpu: Vec<u32> = ctx.read_buffer(&key_buf, n).unwrap();
    let helpers: Vec<u32> = ctx.read_buffer(&helper_buf, 65537).unwrap();

    let mut mismatches = Vec::new();
    for (i, r) in inputs.iter().enumerate() {
        let f = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        let cpu = ray_sort_key(f(r.origin), f(r.dir), f(r.scene_min), f(r.scene_extent));
        if cpu != gpu[i] {
            mismatches.push((i, cpu, gpu[i]));
        }
    }
    assert!(
        mismatches.is_empty(),
        "{} of {n} keys differ, first (index, cpu, gpu): {:x?}",
        mismatches.len(),
        &mismatches[..mismatches.len().min(10)]
    );
    for i in 0..32768u32 {
        assert_eq!(
            helpers[2 * i as usize],
            expand_bits_5(i),
            "expand_bits_5({i})"
        );
        assert_eq!(
            helpers[2 * i as usize + 1],
            morton3_5(i, i >> 5, i >> 10),
            "morton3_5 at {i}"
        );
    }
    assert_eq!(helpers[65536], DEAD_RAY_KEY);
    // The inputs cover every cell of every axis (else the comparison would prove little).
    let mut seen = [[false; 32]; 3];
    for r in &inputs[..100_000] {
        for a in 0..3 {
            seen[a][quantize_5(r.origin[a], r.scene_min[a], r.scene_extent[a]) as usize] = true;
        }
    }
    assert!(seen.iter().all(|axis| axis.iter().all(|&s| s)));
}
