//! GPU faults, provoked where they can be: no adapter, an adapter filter that matches nothing,
//! a scene or an image larger than one storage binding of the adapter, a device that is lost.
//! Each is an `Err` (or, for `Backend::Auto`, a fallback to the CPU with the reason) whose
//! message says what to do, through the library and through the `render` command (non-zero
//! exit, no `panicked`, no output file).
//!
//! Shader validation errors cannot be provoked through the public API (the WGSL is the
//! crates' own and checked by naga in their tests); raylume-gpu's
//! `shader_errors_come_back_as_validation_errors` shows that they come back as
//! `GpuError::Validation` naming the operation.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use raylume::{Backend, Error, Scene, Tracer};
use raylume_gpu::{ContextOptions, GpuContext};
use raylume_kernels::KernelError;
use raylume_scene::{
    Camera, Environment, FovAxis, Material, RenderSettings, Sphere, Texels, Texture,
};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("raylume-faults-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs `render SCENE -o OUT -q --size 8x8 --spp 1 ARGS` with the environment `env`.
fn render(scene: &Path, out: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(common::render_exe());
    cmd.arg(scene)
        .args([
            "-o",
            out.to_str().unwrap(),
            "-q",
            "--size",
            "8x8",
            "--spp",
            "1",
        ])
        .args(args)
        .current_dir(repo())
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .env_remove("RAYLUME_ADAPTER")
        .env_remove("WGPU_BACKEND");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run render")
}

/// A failed command: non-zero exit (not a panic's 101), every fragment in the message, no
/// `panicked`, no output file.
fn assert_failed(o: &Output, out: &Path, parts: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "should fail: {err}");
    assert_ne!(o.status.code(), Some(101), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for part in parts {
        assert!(err.contains(part), "message lacks `{part}`: {err}");
    }
    assert!(!out.exists(), "{} left behind", out.display());
}

/// A wgpu backend that has no adapter on this platform.
fn absent_backend() -> &'static str {
    if cfg!(target_os = "macos") {
        "dx12"
    } else {
        "metal"
    }
}

fn cornell() -> PathBuf {
    repo().join("scenes/cornell-box.toml")
}

#[test]
fn no_adapter_is_a_clear_error_and_auto_falls_back_to_the_cpu() {
    // WGPU_BACKEND restricts wgpu to a backend this platform lacks: no adapter at all.
    // Needs no GPU.
    let d = tmp("no-adapter");
    let out = d.join("out.png");
    let env = [("WGPU_BACKEND", absent_backend())];
    let o = render(&cornell(), &out, &["--backend", "gpu"], &env);
    assert_failed(
        &o,
        &out,
        &[
            "no GPU adapter found",
            "wgpu saw no adapter at all",
            &format!("WGPU_BACKEND={} limits it", absent_backend()),
            "install a Vulkan driver",
            "use the CPU backend",
        ],
    );
    // Auto falls back to the CPU and says why.
    let stats = d.join("stats.json");
    let o = render(
        &cornell(),
        &out,
        &["--backend", "auto", "--stats", stats.to_str().unwrap()],
        &env,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(out.exists());
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    assert_eq!(v["backend"], "cpu");
    let reason = v["backend_reason"].as_str().unwrap();
    assert!(
        reason.contains("no hardware GPU adapter") && reason.contains("using the CPU"),
        "{reason}"
    );
    assert!(err.contains(reason), "the command prints the reason: {err}");
}

#[test]
fn an_adapter_filter_that_matches_nothing_lists_what_exists() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("adapter filter") else {
        return;
    };
    // In the library: the error lists the adapters seen.
    let err = GpuContext::new(&ContextOptions {
        adapter_name: Some("no such gpu".into()),
        ..Default::default()
    })
    .unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("seen but not allowed") && msg.contains(&ctx.info.name),
        "{msg}"
    );
    // Through the command, with RAYLUME_ADAPTER.
    let out = tmp("filter").join("out.png");
    let o = render(
        &cornell(),
        &out,
        &["--backend", "gpu"],
        &[("RAYLUME_ADAPTER", "no such gpu")],
    );
    assert_failed(
        &o,
        &out,
        &[
            "no GPU adapter found",
            "seen but not allowed",
            &ctx.info.name,
        ],
    );
}

fn sphere_scene() -> Scene {
    Scene {
        camera: Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov: 40.0,
            fov_axis: FovAxis::Vertical,
        },
        materials: vec![Material::diffuse("white", Vec3::splat(0.5))],
        spheres: vec![Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
            material: 0,
        }],
        environment: Environment::Constant(Vec3::ONE),
        render: RenderSettings {
            width: 8,
            height: 8,
            spp: 1,
            max_bounces: 2,
            seed: 0,
        },
        ..Default::default()
    }
}

/// The storage-binding limit the "too large" tests give their device (16 MiB), below every
/// adapter's own (lavapipe 128 MiB, an H200 2 GiB): scenes and images past it are small enough
/// to build here, so these tests run the same on every adapter.
const TEST_BINDING_LIMIT: u64 = 16 << 20;

#[test]
fn a_scene_larger_than_a_binding_says_what_does_not_fit() {
    let Some(ctx) = raylume_gpu::testing::context_with_binding_limit_or_skip(
        "a_scene_larger_than_a_binding_says_what_does_not_fit",
        TEST_BINDING_LIMIT,
    ) else {
        return;
    };
    // An environment map one row larger than a storage binding holds: 12 bytes a texel of
    // radiance, 4 of its sampling distribution's column CDF, and 4 a row of the row CDF
    // (raylume_kernels::scene_data::environment_distribution): 4096 x 1024 under the 16 MiB
    // limit.
    let limit = ctx.max_binding_bytes();
    assert_eq!(limit, TEST_BINDING_LIMIT);
    let width = 4096u64;
    let row_bytes = width * 16 + 4;
    let height = limit / row_bytes + 1;
    let bytes_of = |h: u64| h * row_bytes;
    assert!(bytes_of(height) > limit && bytes_of(height - 1) <= limit);
    assert!(height <= 16384, "within the loaders' texture limit");
    let mut scene = sphere_scene();
    scene.environment = Environment::Map {
        image: Texture {
            name: "big sky".into(),
            width: width as u32,
            height: height as u32,
            texels: vec![[0.5, 0.6, 0.7]; (width * height) as usize].into(),
        },
        strength: 1.0,
        rotation: 0.0,
    };
    // One row less fits: the limit is what refuses the map, nothing else.
    let mut fits = scene.clone();
    if let Environment::Map { image, .. } = &mut fits.environment {
        image.height -= 1;
        if let Texels::Linear(t) = &mut image.texels {
            t.truncate((width * (height - 1)) as usize);
        }
    }
    let mut tracer = Tracer::new(Backend::Gpu).with_gpu_context(ctx);
    // By radiance alone: the environment guide would add a second distribution as large as
    // the first (the map's texels times the guide), and the arithmetic above counts one.
    tracer.environment_guide = Some(false);
    let ok = tracer.render(&fits).unwrap();
    assert_eq!(ok.stats.backend, "gpu");
    let err = tracer.render(&scene).unwrap_err();
    match &err {
        Error::Kernels(KernelError::SceneTooLarge {
            what,
            bytes,
            limit: l,
            ..
        }) => {
            assert_eq!(what, "texture and environment-map data");
            assert_eq!(*bytes, bytes_of(height));
            assert_eq!(*l, limit);
        }
        other => panic!("expected SceneTooLarge, got {other:?}"),
    }
    let msg = err.to_string();
    for part in [
        "too large for the GPU adapter",
        &format!("{} bytes", bytes_of(height)),
        &format!("at most {limit} bytes"),
        "or the CPU backend",
    ] {
        assert!(msg.contains(part), "lacks `{part}`: {msg}");
    }
    // The CPU has no such limit.
    let cpu = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    assert_eq!(cpu.pixels.len(), 64);

    // Through the command, its device limited the same way (GpuContext::MAX_BINDING_ENV):
    // the same map as an HDR file (run-length encoded: under 1 MB).
    let d = tmp("too-large");
    let img = image::Rgb32FImage::from_pixel(width as u32, height as u32, image::Rgb([0.5; 3]));
    image::DynamicImage::ImageRgb32F(img)
        .save(d.join("big.hdr"))
        .unwrap();
    let toml = d.join("big.toml");
    std::fs::write(
        &toml,
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40\n\
         [environment]\nmap = \"big.hdr\"\n[materials.white]\ntype = \"diffuse\"\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"white\"\n",
    )
    .unwrap();
    let out = d.join("out.png");
    let limit_env = [(GpuContext::MAX_BINDING_ENV, &*limit.to_string())];
    let o = render(&toml, &out, &["--backend", "gpu"], &limit_env);
    assert_failed(
        &o,
        &out,
        &[
            "too large for the GPU adapter",
            "texture and environment-map data",
            &format!("at most {limit} bytes"),
            "or the CPU backend",
        ],
    );
    let o = render(&toml, &out, &["--backend", "cpu"], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn an_image_larger_than_a_binding_says_what_does_not_fit() {
    if raylume_gpu::testing::context_or_skip(
        "an_image_larger_than_a_binding_says_what_does_not_fit",
    )
    .is_none()
    {
        return;
    }
    // The accumulated image (12 bytes a pixel) must fit one binding; a square image just past
    // the test limit (1184 x 1184 for 16 MiB), rendered by the command with its device's
    // binding limit lowered to it (GpuContext::MAX_BINDING_ENV).
    let limit = TEST_BINDING_LIMIT;
    let side = ((limit / 12) as f64).sqrt().ceil() as u64 + 1;
    assert!(side * side * 12 > limit && side * side <= 1 << 27);
    let out = tmp("image").join("out.png");
    let size = format!("{side}x{side}");
    let mut cmd = Command::new(common::render_exe());
    let o = cmd
        .args([
            cornell().to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "-q",
        ])
        .args([
            "--size",
            &size,
            "--spp",
            "1",
            "--bounces",
            "0",
            "--backend",
            "gpu",
        ])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .env(GpuContext::MAX_BINDING_ENV, limit.to_string())
        .output()
        .unwrap();
    assert_failed(
        &o,
        &out,
        &[
            "accumulation image needs",
            &format!("{} bytes", side * side * 12),
            &format!("at most {limit} bytes"),
            "CPU backend",
        ],
    );
}

#[test]
fn a_lost_device_is_an_error_and_the_next_render_recovers() {
    if raylume_gpu::testing::context_or_skip("device lost").is_none() {
        return;
    }
    // Device::destroy is how wgpu lets a program lose its device on purpose (a driver reset
    // looks the same). Its own context: the shared one must survive.
    let ctx = GpuContext::new(&ContextOptions::default()).unwrap();
    ctx.device.destroy();
    let mut tracer = Tracer::new(Backend::Gpu).with_gpu_context(ctx);
    let scene = sphere_scene();
    let err = tracer.render(&scene).unwrap_err();
    assert!(err.is_device_lost(), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("the GPU device was lost") && msg.contains("use the CPU backend"),
        "{msg}"
    );
    // The tracer dropped the dead device: the next render runs on a new one.
    let r = tracer.render(&scene).unwrap();
    assert_eq!(r.stats.backend, "gpu");
    let cpu = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    assert_eq!(r.stats.rays_traced, cpu.stats.rays_traced);
}
