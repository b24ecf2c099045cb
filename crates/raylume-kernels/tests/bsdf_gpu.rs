//! The WGSL microfacet materials (`bsdf.wgsl`) compute what their Rust mirrors compute: every
//! sampler and eval of `bsdf.rs`, run in a compute shader on a GPU (lavapipe in CI) over 24 000
//! random inputs (directions on both sides, roughnesses 0 to 1, both dielectric sides, conductor
//! IORs with and without Fresnel), compared with the Rust functions on the same inputs. The
//! GPU's `sin`, `cos` and `sqrt` round differently from Rust's, so results agree to a relative
//! 1e-3 rather than bit for bit, and a sample whose lobe choice sits within rounding of its
//! threshold may legitimately differ (at most 1 in 1000 are allowed to).

use glam::{Vec2, Vec3};
use raylume_gpu::wgpu;
use raylume_kernels::bsdf::*;
use raylume_kernels::math::MATH_WGSL;
use raylume_kernels::rng::rand4;
use raylume_kernels::sampling::SAMPLING_WGSL;

/// Floats per input record and per output record.
const IN: usize = 28;
const OUT: usize = 12;

const KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> inputs: array<f32>;
@group(0) @binding(1) var<storage, read> plastic_tables: array<RoughPlasticTable>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

fn v3(i: u32) -> vec3<f32> {
    return vec3<f32>(inputs[i], inputs[i + 1u], inputs[i + 2u]);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = id.x;
    if (r >= arrayLength(&inputs) / 28u) {
        return;
    }
    let b = 28u * r;
    let dir = v3(b);
    let n = v3(b + 3u);
    let wi = v3(b + 6u);
    let u = v3(b + 9u);
    let alpha = inputs[b + 12u];
    let ior = inputs[b + 13u];
    let kind = u32(inputs[b + 14u]);
    let color = v3(b + 16u);
    let eta3 = v3(b + 19u);
    let k3 = v3(b + 22u);
    var s = bsdf_absorbed(dir);
    var e = bsdf_eval_zero();
    if (kind == 0u) {
        s = sample_conductor(dir, n, alpha, color, eta3, k3, u.xy);
        e = eval_conductor(dir, n, wi, alpha, color, eta3, k3);
    } else if (kind == 1u) {
        s = sample_plastic(dir, n, ior, color, u);
        e = eval_plastic(dir, n, wi, ior, color);
    } else if (kind == 2u) {
        s = sample_rough_plastic(dir, n, alpha, ior, color, 0u, u);
        e = eval_rough_plastic(dir, n, wi, alpha, ior, color, 0u);
    } else {
        s = sample_rough_dielectric(dir, n, alpha, ior, color, u);
        e = eval_rough_dielectric(dir, n, wi, alpha, ior, color);
    }
    let o = 12u * r;
    out[o] = s.dir.x;
    out[o + 1u] = s.dir.y;
    out[o + 2u] = s.dir.z;
    out[o + 3u] = s.weight.x;
    out[o + 4u] = s.weight.y;
    out[o + 5u] = s.weight.z;
    out[o + 6u] = s.pdf;
    out[o + 7u] = select(0.0, 1.0, s.transmitted);
    out[o + 8u] = e.value.x;
    out[o + 9u] = e.value.y;
    out[o + 10u] = e.value.z;
    out[o + 11u] = e.pdf;
}
"#;

struct Input {
    dir: Vec3,
    n: Vec3,
    wi: Vec3,
    u: Vec3,
    alpha: f32,
    ior: f32,
    kind: u32,
    color: Vec3,
    eta: Vec3,
    k: Vec3,
}

impl Input {
    fn flat(&self) -> [f32; IN] {
        let mut f = [0.0; IN];
        f[0..3].copy_from_slice(&self.dir.to_array());
        f[3..6].copy_from_slice(&self.n.to_array());
        f[6..9].copy_from_slice(&self.wi.to_array());
        f[9..12].copy_from_slice(&self.u.to_array());
        f[12] = self.alpha;
        f[13] = self.ior;
        f[14] = self.kind as f32;
        f[16..19].copy_from_slice(&self.color.to_array());
        f[19..22].copy_from_slice(&self.eta.to_array());
        f[22..25].copy_from_slice(&self.k.to_array());
        f
    }

    /// The Rust mirror's results, in the kernel's output layout.
    fn rust(&self, table: &RoughPlasticTable) -> [f32; OUT] {
        let (s, e) = match self.kind {
            0 => (
                sample_conductor(
                    self.dir,
                    self.n,
                    self.alpha,
                    self.color,
                    self.eta,
                    self.k,
                    Vec2::new(self.u.x, self.u.y),
                ),
                eval_conductor(
                    self.dir, self.n, self.wi, self.alpha, self.color, self.eta, self.k,
                ),
            ),
            1 => (
                sample_plastic(self.dir, self.n, self.ior, self.color, self.u),
                eval_plastic(self.dir, self.n, self.wi, self.ior, self.color),
            ),
            2 => (
                sample_rough_plastic(
                    self.dir, self.n, self.alpha, self.ior, self.color, table, self.u,
                ),
                eval_rough_plastic(
                    self.dir, self.n, self.wi, self.alpha, self.ior, self.color, table,
                ),
            ),
            _ => (
                sample_rough_dielectric(self.dir, self.n, self.alpha, self.ior, self.color, self.u),
                eval_rough_dielectric(self.dir, self.n, self.wi, self.alpha, self.ior, self.color),
            ),
        };
        let mut o = [0.0; OUT];
        o[0..3].copy_from_slice(&s.dir.to_array());
        o[3..6].copy_from_slice(&s.weight.to_array());
        o[6] = s.pdf;
        o[7] = if s.transmitted { 1.0 } else { 0.0 };
        o[8..11].copy_from_slice(&e.value.to_array());
        o[11] = e.pdf;
        o
    }
}

const TABLE_ALPHA: f32 = 0.2;

fn inputs() -> Vec<Input> {
    let (cu_eta, cu_k) = raylume_scene::conductor_ior("Cu").unwrap();
    let sphere = |r: glam::Vec4| {
        let z = 2.0 * r.x - 1.0;
        let s = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * r.y;
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    };
    let mut v = Vec::new();
    for i in 0..24_000u32 {
        let r = [0, 1, 2, 3].map(|d| rand4(99, i, 0, 0, d));
        let n = sphere(r[0]);
        // Mostly facing the normal; now and then from behind (absorbed or not evaluated).
        let mut dir = sphere(r[1]);
        if dir.dot(n) > 0.0 && r[1].z < 0.95 {
            dir = -dir;
        }
        let wi = sphere(r[2]);
        let kind = i % 4;
        let alpha = [0.0, 0.05, 0.3, 1.0][(i / 4 % 4) as usize];
        let (eta, k) = if i / 16 % 2 == 0 {
            (cu_eta, cu_k)
        } else {
            (Vec3::ZERO, Vec3::ONE)
        };
        let ior = match kind {
            3 => [1.0 / 1.5, 1.5][(i / 32 % 2) as usize],
            _ => 1.5,
        };
        v.push(Input {
            dir,
            n,
            wi,
            u: r[3].truncate(),
            alpha: if kind == 2 { TABLE_ALPHA } else { alpha },
            ior,
            kind,
            color: Vec3::new(r[1].w, r[2].z, r[2].w),
            eta,
            k,
        });
    }
    v
}

#[test]
fn wgsl_bsdfs_match_rust() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("wgsl_bsdfs_match_rust") else {
        return;
    };
    let inputs = inputs();
    let table = RoughPlasticTable::new(TABLE_ALPHA, 1.5);
    let flat: Vec<f32> = inputs.iter().flat_map(|i| i.flat()).collect();
    let in_buf = ctx
        .storage_buffer("bsdf inputs", &flat, wgpu::BufferUsages::empty())
        .unwrap();
    let table_buf = ctx
        .storage_buffer("bsdf table", &[table], wgpu::BufferUsages::empty())
        .unwrap();
    let out_buf = ctx
        .storage_buffer_zeroed(
            "bsdf out",
            (inputs.len() * OUT * 4) as u64,
            wgpu::BufferUsages::COPY_SRC,
        )
        .unwrap();
    let source = format!("{MATH_WGSL}\n{SAMPLING_WGSL}\n{BSDF_WGSL}\n{KERNEL}");
    ctx.scoped("bsdf kernel", || {
        let module = ctx
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("bsdf test"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let pipeline = ctx
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("bsdf test"),
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
                    resource: in_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: table_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: out_buf.as_entire_binding(),
                },
            ],
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups((inputs.len() as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
    })
    .unwrap();
    let out: Vec<f32> = ctx.read_buffer(&out_buf, inputs.len() * OUT).unwrap();
    let mut bad = Vec::new();
    let mut live = [0usize; 4];
    for (i, input) in inputs.iter().enumerate() {
        let want = input.rust(&table);
        let got = &out[OUT * i..OUT * (i + 1)];
        // Sample (direction, weight, pdf, flag) and eval (value, pdf): relative 1e-3 of each
        // group's magnitude, plus 1e-6.
        let groups: [&[usize]; 5] = [&[0, 1, 2], &[3, 4, 5], &[6], &[7], &[8, 9, 10, 11]];
        let ok = groups.iter().all(|g| {
            let scale = g.iter().map(|&j| want[j].abs()).fold(0.0f32, f32::max);
            g.iter()
                .all(|&j| (got[j] - want[j]).abs() <= 1e-3 * scale + 1e-6)
        });
        if want[3..6].iter().any(|w| *w > 0.0) {
            live[input.kind as usize] += 1;
        }
        if !ok {
            bad.push(format!(
                "input {i} kind {} alpha {}: GPU {got:?}, Rust {want:?}",
                input.kind, input.alpha
            ));
        }
    }
    // Every kind was exercised with live samples.
    assert!(live.iter().all(|&l| l > 2000), "{live:?}");
    assert!(
        bad.len() <= inputs.len() / 1000,
        "{} of {} differ:\n{}",
        bad.len(),
        inputs.len(),
        bad.join("\n")
    );
    println!(
        "{} of {} within rounding; live samples per kind {live:?}",
        inputs.len() - bad.len(),
        inputs.len()
    );
}
