//! The WGSL bloom against its CPU mirror, and against analytic answers.

use std::sync::OnceLock;

use raylume_gpu::{GpuContext, Timestamps, testing::context_or_skip, wgpu};
use raylume_post::{BLOOM_STAGES, BloomParams, GpuBloom, PostError, bloom_cpu, bloom_gpu};

/// One set of pipelines per test binary (compiling them on lavapipe is the slow part).
fn pipelines(ctx: &GpuContext) -> &'static GpuBloom {
    static BLOOM: OnceLock<GpuBloom> = OnceLock::new();
    BLOOM.get_or_init(|| GpuBloom::new(ctx).expect("bloom pipelines"))
}

/// splitmix64, mapped to [0, 1).
fn uniform(seed: u64, i: u64) -> f32 {
    let mut z = seed.wrapping_add(i.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32
}

/// A random HDR image: a fifth of the channels black, the rest log-uniform in [0.01, 100].
fn hdr_image(seed: u64, w: u32, h: u32) -> Vec<[f32; 3]> {
    (0..u64::from(w * h))
        .map(|i| {
            std::array::from_fn(|c| {
                let k = 3 * i + c as u64;
                if uniform(seed ^ 0x55, k) < 0.2 {
                    0.0
                } else {
                    10f32.powf(4.0 * uniform(seed, k) - 2.0)
                }
            })
        })
        .collect()
}

/// GPU and CPU agree within 1e-5 relative. Both sum the same non-negative terms in the same
/// order; the GPU's division may be 2.5 ulp off and its `p + s * b` may be fused into one FMA,
/// a few 1e-7 relative in all; 1e-5 leaves room for drivers that reassociate the sums of up to
/// 2r + 1 = 201 terms (201 * 6e-8 = 1.2e-5 in the worst case, far less in practice).
fn assert_agree(gpu: &[[f32; 3]], cpu: &[[f32; 3]], what: &str) {
    assert_eq!(gpu.len(), cpu.len());
    for (i, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        for k in 0..3 {
            let tol = 1e-5 * c[k].abs().max(g[k].abs()) + 1e-30;
            assert!(
                (g[k] - c[k]).abs() <= tol,
                "{what}: pixel {i} channel {k}: gpu {} cpu {}",
                g[k],
                c[k]
            );
        }
    }
}

fn cpu_bloom(img: &[[f32; 3]], w: u32, h: u32, p: BloomParams) -> Vec<[f32; 3]> {
    let mut out = img.to_vec();
    bloom_cpu(&mut out, w, h, p).unwrap();
    out
}

#[test]
fn gpu_matches_cpu_on_random_hdr_images() {
    let Some(ctx) = context_or_skip("gpu_matches_cpu_on_random_hdr_images") else {
        return;
    };
    let bloom = pipelines(ctx);
    for (seed, (w, h)) in [(1, 1), (7, 3), (33, 17), (64, 65)].into_iter().enumerate() {
        let img = hdr_image(seed as u64, w, h);
        let max = img.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
        for radius in [0, 1, 5, 100] {
            for threshold in [0.0, 1.0, max * 1.5] {
                let p = BloomParams {
                    threshold,
                    radius,
                    strength: 0.7,
                };
                let gpu = bloom.run(ctx, &img, w, h, p).unwrap();
                let cpu = cpu_bloom(&img, w, h, p);
                assert_agree(&gpu, &cpu, &format!("{w}x{h} {p:?}"));
                if threshold > max {
                    // Nothing is above the threshold: the image comes back unchanged.
                    assert_eq!(gpu, img, "{w}x{h} {p:?}");
                }
            }
        }
    }
}

/// The free function compiles its own pipelines and gives the same answer.
#[test]
fn bloom_gpu_convenience_matches_cpu() {
    let Some(ctx) = context_or_skip("bloom_gpu_convenience_matches_cpu") else {
        return;
    };
    let (w, h) = (9, 4);
    let img = hdr_image(11, w, h);
    let p = BloomParams::scene_default();
    let gpu = bloom_gpu(ctx, &img, w, h, p).unwrap();
    assert_agree(&gpu, &cpu_bloom(&img, w, h, p), "bloom_gpu");
}

/// A constant image stays constant everywhere, borders included (windows are normalised by
/// their in-image tap count), for radii inside and beyond the image.
#[test]
fn gpu_constant_image_stays_constant() {
    let Some(ctx) = context_or_skip("gpu_constant_image_stays_constant") else {
        return;
    };
    let (w, h) = (33, 17);
    let img = vec![[5.0f32, 2.0, 0.25]; (w * h) as usize];
    for radius in [1, 5, 100] {
        let p = BloomParams {
            threshold: 1.0,
            radius,
            strength: 0.5,
        };
        let gpu = pipelines(ctx).run(ctx, &img, w, h, p).unwrap();
        // 5 + 0.5 * 4 = 7, 2 + 0.5 * 1 = 2.5, 0.25 + 0 = 0.25; the mean of equal terms is within
        // a few ulps of the term.
        for px in &gpu {
            assert!((px[0] - 7.0).abs() < 1e-5 * 7.0, "r={radius}: {px:?}");
            assert!((px[1] - 2.5).abs() < 1e-5 * 2.5, "r={radius}: {px:?}");
            assert_eq!(px[2], 0.25);
        }
    }
}

/// One bright pixel away from the edges spreads to a (2r+1)^2 box of (b - t) * s / (2r+1)^2.
#[test]
fn gpu_single_pixel_spreads_to_a_box() {
    let Some(ctx) = context_or_skip("gpu_single_pixel_spreads_to_a_box") else {
        return;
    };
    let (w, h, r) = (21u32, 19u32, 3u32);
    let (b, t, s) = (50.0f32, 2.0f32, 0.8f32);
    let mut img = vec![[0.0f32; 3]; (w * h) as usize];
    img[(9 * w + 10) as usize] = [b; 3];
    let p = BloomParams {
        threshold: t,
        radius: r,
        strength: s,
    };
    let gpu = pipelines(ctx).run(ctx, &img, w, h, p).unwrap();
    let spread = (b - t) * s / ((2 * r + 1) * (2 * r + 1)) as f32;
    for y in 0..h {
        for x in 0..w {
            let inside = x.abs_diff(10) <= r && y.abs_diff(9) <= r;
            let base = if (x, y) == (10, 9) { b } else { 0.0 };
            let want = base + if inside { spread } else { 0.0 };
            let got = gpu[(y * w + x) as usize][0];
            // (b - t) / 7 / 7 * s in a few roundings: 1e-5 relative.
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "({x},{y}): {got} vs {want}"
            );
        }
    }
}

/// Dispatches folded into 2D (as images over 16.7M pixels need) cover every pixel once.
#[test]
fn gpu_folded_dispatch_covers_every_pixel() {
    let Some(ctx) = context_or_skip("gpu_folded_dispatch_covers_every_pixel") else {
        return;
    };
    let folded = GpuBloom::new(ctx).unwrap().with_max_groups_per_dim(5);
    let (w, h) = (64, 65); // 4160 pixels = 17 workgroups of 256: a 5x4 grid, 3 groups idle.
    let img = hdr_image(5, w, h);
    let p = BloomParams {
        threshold: 0.5,
        radius: 2,
        strength: 1.0,
    };
    let gpu = folded.run(ctx, &img, w, h, p).unwrap();
    assert_agree(&gpu, &cpu_bloom(&img, w, h, p), "folded");
}

/// `encode` records into the caller's encoder: two calls with different parameters in one
/// encoder apply one after the other (each call has its own uniforms), and the passes carry
/// timestamps named after the stages.
#[test]
fn encode_twice_in_one_encoder_with_timestamps() {
    let Some(ctx) = context_or_skip("encode_twice_in_one_encoder_with_timestamps") else {
        return;
    };
    let (w, h) = (17, 12);
    let img = hdr_image(9, w, h);
    let p1 = BloomParams {
        threshold: 1.0,
        radius: 2,
        strength: 0.5,
    };
    let p2 = BloomParams {
        threshold: 3.0,
        radius: 6,
        strength: 0.25,
    };
    let buf = ctx
        .storage_buffer("image", &img, wgpu::BufferUsages::COPY_SRC)
        .unwrap();
    let mut ts = Timestamps::new(ctx, 8);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let bloom = pipelines(ctx);
    bloom
        .encode(ctx, &mut enc, &buf, w, h, p1, ts.as_mut())
        .unwrap();
    bloom
        .encode(ctx, &mut enc, &buf, w, h, p2, ts.as_mut())
        .unwrap();
    if let Some(ts) = &ts {
        ts.resolve(&mut enc);
    }
    ctx.queue.submit([enc.finish()]);
    let gpu: Vec<[f32; 3]> = ctx.read_buffer(&buf, img.len()).unwrap();
    let cpu = cpu_bloom(&cpu_bloom(&img, w, h, p1), w, h, p2);
    assert_agree(&gpu, &cpu, "two encodes");
    match ts.as_mut() {
        Some(ts) => {
            let t = ts.read(ctx).unwrap();
            let names: Vec<&str> = t.iter().map(|(n, _)| *n).collect();
            let want: Vec<&str> = BLOOM_STAGES.iter().chain(&BLOOM_STAGES).copied().collect();
            assert_eq!(names, want);
            assert!(t.iter().all(|(_, s)| (0.0..1.0).contains(s)), "{t:?}");
        }
        None => eprintln!("{}: no timestamps; names not checked", ctx.describe()),
    }
}

#[test]
fn encode_rejects_bad_buffers_and_sizes() {
    let Some(ctx) = context_or_skip("encode_rejects_bad_buffers_and_sizes") else {
        return;
    };
    let bloom = pipelines(ctx);
    let p = BloomParams::scene_default();
    let small = ctx
        .storage_buffer_zeroed("small", 12 * 10, wgpu::BufferUsages::empty())
        .unwrap();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let err = bloom
        .encode(ctx, &mut enc, &small, 8, 8, p, None)
        .unwrap_err();
    assert!(
        matches!(err, PostError::BadBuffer { .. }) && err.to_string().contains("768"),
        "{err}"
    );
    let err = bloom
        .encode(ctx, &mut enc, &small, 0, 8, p, None)
        .unwrap_err();
    assert!(matches!(err, PostError::ZeroSize { .. }), "{err}");
    let not_storage = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("not storage"),
        size: 1024,
        usage: wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let err = bloom
        .encode(ctx, &mut enc, &not_storage, 4, 4, p, None)
        .unwrap_err();
    assert!(
        matches!(err, PostError::BadBuffer { .. }) && err.to_string().contains("STORAGE"),
        "{err}"
    );
    let bad = BloomParams {
        threshold: f32::NAN,
        ..p
    };
    let err = bloom
        .encode(ctx, &mut enc, &small, 2, 2, bad, None)
        .unwrap_err();
    assert!(matches!(err, PostError::BadParam { .. }), "{err}");
    let err = bloom.run(ctx, &[[1.0; 3]; 5], 2, 2, p).unwrap_err();
    assert!(matches!(err, PostError::SizeMismatch { .. }), "{err}");
    // Nothing bad was recorded: the encoder still finishes and submits cleanly.
    ctx.scoped("submitting after rejected encodes", || {
        ctx.queue.submit([enc.finish()])
    })
    .unwrap();
}
