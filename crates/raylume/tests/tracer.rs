//! The facade's contract: backend choice, progress, bloom only when asked, output files.

use std::path::Path;
use std::sync::{Arc, Mutex};

use raylume::{Backend, Progress, Scene, Tracer};
use raylume_gpu::{AdapterChoice, ContextOptions, GpuContext};

mod common;
use common::cornell;

#[test]
fn auto_picks_a_hardware_gpu_or_says_why_it_did_not() {
    let hardware = GpuContext::new(&ContextOptions {
        choice: AdapterChoice::HardwareOnly,
        adapter_name: None,
    })
    .is_ok();
    let r = Tracer::new(Backend::Auto)
        .render(&cornell(8, 8, 1))
        .unwrap();
    if hardware {
        assert_eq!(r.stats.backend, "gpu");
    } else {
        assert_eq!(r.stats.backend, "cpu");
        assert!(
            r.stats.backend_reason.contains("no hardware GPU"),
            "{}",
            r.stats.backend_reason
        );
    }
}

#[test]
fn progress_reports_every_batch_up_to_the_total() {
    let seen: Arc<Mutex<Vec<Progress>>> = Arc::default();
    let mut t = Tracer::new(Backend::Cpu);
    t.batch_spp = 2;
    let s = seen.clone();
    t.on_progress(move |p| s.lock().unwrap().push(p));
    t.render(&cornell(8, 8, 5)).unwrap();
    let seen = seen.lock().unwrap();
    let done: Vec<u32> = seen.iter().map(|p| p.done_spp).collect();
    assert_eq!(done, vec![2, 4, 5], "batches of 2 spp up to 5");
    assert!(seen.iter().all(|p| p.total_spp == 5));
}

#[test]
fn seed_changes_the_noise_and_is_reproducible() {
    let scene = cornell(16, 16, 2);
    let mut t = Tracer::new(Backend::Cpu);
    t.seed = Some(1);
    let a = t.render(&scene).unwrap().pixels;
    let b = t.render(&scene).unwrap().pixels;
    t.seed = Some(2);
    let c = t.render(&scene).unwrap().pixels;
    assert_eq!(a, b, "same seed, same image, bit for bit");
    assert_ne!(a, c, "another seed, other paths");
}

#[test]
fn bloom_runs_only_when_the_scene_asks_and_the_flag_allows() {
    let mut scene = cornell(16, 16, 2);
    let mut t = Tracer::new(Backend::Cpu);
    let plain = t.render(&scene).unwrap();
    assert!(
        plain.stats.post_passes.is_empty(),
        "no [post.bloom]: no pass"
    );
    scene.post.bloom = Some(raylume_scene::Bloom {
        threshold: 1.0,
        radius: 2,
        strength: 0.5,
    });
    let bloomed = t.render(&scene).unwrap();
    assert_ne!(
        plain.pixels, bloomed.pixels,
        "the light blooms onto the ceiling"
    );
    // Bloom only adds light.
    for (p, b) in plain.pixels.iter().zip(&bloomed.pixels) {
        for c in 0..3 {
            assert!(b[c] >= p[c]);
        }
    }
    t.bloom = false;
    let off = t.render(&scene).unwrap();
    assert_eq!(off.pixels, plain.pixels, "--no-bloom");
    assert!(
        off.stats.post_passes.is_empty(),
        "--no-bloom schedules no pass"
    );
}

#[test]
fn exr_holds_the_linear_radiance_exactly() {
    let r = Tracer::new(Backend::Cpu)
        .render(&cornell(12, 10, 2))
        .unwrap();
    let dir = std::env::temp_dir().join(format!("raylume-facade-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("img.exr");
    r.save(&p).unwrap();
    let back = image::open(&p).unwrap().into_rgb32f();
    assert_eq!(back.dimensions(), (12, 10));
    for (a, b) in back.pixels().zip(&r.pixels) {
        assert_eq!([a[0], a[1], a[2]], *b, "32-bit float EXR is lossless");
    }
    let png = dir.join("img.png");
    r.save(&png).unwrap();
    assert_eq!(image::open(&png).unwrap().width(), 12);
    assert!(r.save(dir.join("img.tiff")).is_err());
}

#[test]
fn gpu_and_cpu_facades_agree() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip("gpu_and_cpu_facades_agree") else {
        return;
    };
    let _ = ctx;
    let scene = cornell(16, 16, 2);
    let cpu = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    let gpu = Tracer::new(Backend::Gpu).render(&scene).unwrap();
    assert_eq!(gpu.stats.backend, "gpu");
    assert_eq!(
        cpu.stats.rays_traced, gpu.stats.rays_traced,
        "the same paths, ray for ray"
    );
    let rel = raylume_post::relative_mse(&gpu.pixels, &cpu.pixels).unwrap();
    // Same random numbers, same functions: only float rounding (FMA contraction on the GPU)
    // separates them, far below the noise of 2 spp.
    assert!(rel < 1e-6, "relative MSE {rel}");
}

#[test]
fn gpu_bloom_runs_on_the_traced_image_in_place() {
    if raylume_gpu::testing::context_or_skip("gpu_bloom_runs_on_the_traced_image_in_place")
        .is_none()
    {
        return;
    }
    let mut scene = cornell(20, 14, 2);
    let bloom = raylume_scene::Bloom {
        threshold: 0.5,
        radius: 3,
        strength: 0.7,
    };
    scene.post.bloom = Some(bloom);
    let mut t = Tracer::new(Backend::Gpu);
    let bloomed = t.render(&scene).unwrap();
    assert_eq!(bloomed.stats.post_passes, raylume_post::BLOOM_STAGES);
    t.bloom = false;
    let mut expect = t.render(&scene).unwrap().pixels;
    let params = raylume_post::BloomParams {
        threshold: bloom.threshold,
        radius: bloom.radius,
        strength: bloom.strength,
    };
    raylume_post::bloom_cpu(&mut expect, 20, 14, params).unwrap();
    assert_ne!(
        bloomed.pixels,
        t.render(&scene).unwrap().pixels,
        "bloom changed the image"
    );
    // GPU bloom on the GPU's buffer equals the CPU mirror applied to the read-back image
    // (raylume-post proves the two agree to 1e-5 relative: only summation rounding differs).
    for (g, c) in bloomed.pixels.iter().zip(&expect) {
        for k in 0..3 {
            assert!(
                (g[k] - c[k]).abs() <= 1e-5 * c[k].abs().max(1e-3),
                "{g:?} vs {c:?}"
            );
        }
    }
}

/// Regression test: a scene built by hand skipped the loaders' validation, so a NaN camera,
/// a zero vfov or an empty scene rendered silently (a blank or meaningless image). The tracer
/// now validates every scene and answers with the typed error naming the place.
#[test]
fn scenes_built_by_hand_are_validated() {
    type Break = fn(&mut Scene);
    let cases: [(&str, Break); 4] = [
        ("camera position is not finite", |s| {
            s.camera.position.x = f32::NAN
        }),
        ("vfov 0 degrees", |s| s.camera.fov = 0.0),
        ("the scene is empty", |s| s.triangles.clear()),
        ("emission 1e30 is above 1e20", |s| {
            s.materials[0].emission = glam::Vec3::splat(1e30)
        }),
    ];
    for (message, breaks) in cases {
        let mut scene = cornell(8, 8, 1);
        breaks(&mut scene);
        for backend in [Backend::Cpu, Backend::Auto] {
            let err = Tracer::new(backend).render(&scene).unwrap_err();
            assert!(
                matches!(err, raylume::Error::Scene(_)) && err.to_string().contains(message),
                "{backend:?}: {err}"
            );
        }
    }
}

/// A scene without `[post.bloom]` schedules no post pass on the GPU: no bloom stage is
/// recorded, timed or listed; with it, all four are (and timed where the adapter has
/// timestamps).
#[test]
fn gpu_schedules_no_bloom_pass_for_a_scene_without_bloom() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "gpu_schedules_no_bloom_pass_for_a_scene_without_bloom",
    ) else {
        return;
    };
    let mut t = Tracer::new(Backend::Gpu);
    let plain = t.render(&cornell(8, 8, 1)).unwrap();
    assert!(plain.stats.post_passes.is_empty());
    assert!(
        !plain
            .stats
            .kernel_seconds
            .iter()
            .any(|(k, _)| k.starts_with("bloom")),
        "{:?}",
        plain.stats.kernel_seconds
    );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-bloom.toml");
    let mut scene = Scene::load(path).unwrap();
    scene.render.width = 8;
    scene.render.height = 8;
    scene.render.spp = 1;
    let bloomed = t.render(&scene).unwrap();
    assert_eq!(bloomed.stats.post_passes, raylume_post::BLOOM_STAGES);
    if ctx.has_timestamps() {
        let timed: Vec<&str> = bloomed
            .stats
            .kernel_seconds
            .iter()
            .map(|(k, _)| k.as_str())
            .filter(|k| k.starts_with("bloom"))
            .collect();
        assert_eq!(timed, raylume_post::BLOOM_STAGES);
    }
}

/// The BVH is reused while the geometry is the same, and rebuilt as soon as any vertex moves.
#[test]
fn bvh_is_cached_per_geometry() {
    let mut t = Tracer::new(Backend::Cpu);
    t.bvh_quality = Some(raylume::BvhQuality::Quality);
    let mut scene = cornell(12, 12, 1);
    let first = t.render(&scene).unwrap();
    assert!(!first.stats.bvh_cached);
    // The stats say which preset and which builder made the tree.
    assert_eq!(first.stats.bvh_preset, "quality");
    assert!(
        first.stats.bvh_builder.starts_with("obvhs PLOC on the CPU"),
        "{}",
        first.stats.bvh_builder
    );
    scene.render.spp = 2;
    scene.materials[0].albedo *= 0.5; // materials do not shape the tree
    let second = t.render(&scene).unwrap();
    assert!(
        second.stats.bvh_cached,
        "same geometry, other settings and materials"
    );
    // A fresh tracer (no cache) gives the same image: the cached tree is the same tree.
    assert_eq!(
        Tracer::new(Backend::Cpu).render(&scene).unwrap().pixels,
        second.pixels
    );
    let mut moved = scene.clone();
    moved.triangles[0].positions[0].y += 1e-3;
    let third = t.render(&moved).unwrap();
    assert!(!third.stats.bvh_cached, "one vertex moved by 1e-3: rebuilt");
    t.bvh_quality = Some(raylume::BvhQuality::Fast);
    let fast = t.render(&moved).unwrap();
    assert!(!fast.stats.bvh_cached, "another preset: rebuilt");
    assert_eq!(fast.stats.bvh_preset, "fast");
    assert!(!fast.stats.bvh_preset_chosen, "set, not chosen");
}

/// The geometry's key sees every triangle of a scene hashed in several runs and chains: an
/// inner vertex moved (the bounds unchanged) in any of the four chains of a middle run, or
/// two neighbouring triangles swapped, and the tree is rebuilt.
#[test]
fn bvh_cache_sees_a_change_anywhere_in_a_large_scene() {
    let mut scene = cornell(4, 4, 1);
    common::add_floor_grid(&mut scene); // 20,000 more triangles: past one hashing run
    // A tracer that has just rendered `scene` (its tree cached) renders `other`: cached?
    let after_scene = |other: &raylume::Scene| {
        let mut t = Tracer::new(Backend::Cpu);
        t.bvh_quality = Some(raylume::BvhQuality::Fastest);
        assert!(!t.render(&scene).unwrap().stats.bvh_cached);
        t.render(other).unwrap().stats.bvh_cached
    };
    assert!(after_scene(&scene.clone()), "the same scene: cached");
    let at = scene.triangles.len() - 3_000;
    for k in at..at + 4 {
        let mut moved = scene.clone();
        moved.triangles[k].positions[1].x -= 1e-4;
        assert!(!after_scene(&moved), "triangle {k} moved: rebuilt");
    }
    let mut swapped = scene.clone();
    swapped.triangles.swap(at, at + 1);
    assert!(!after_scene(&swapped), "two swapped: rebuilt");
}

/// Left to choose (`bvh_quality: None`), the tracer builds `Fastest` when the render's rays
/// cannot repay a better build, `Quality` when they can, and takes a cached `Quality` tree
/// of the same geometry over building a cheaper one.
#[test]
fn bvh_preset_follows_the_work() {
    let mut scene = cornell(4, 4, 1);
    // 20,000 small triangles on the floor: a scene large for the rays of a 4x4, 1-spp image.
    common::add_floor_grid(&mut scene);
    let mut t = Tracer::new(Backend::Cpu);
    assert_eq!(t.bvh_quality, None, "chosen by default");
    let quick = t.render(&scene).unwrap();
    assert_eq!(
        quick.stats.bvh_preset, "fastest",
        "few rays, many triangles"
    );
    assert!(quick.stats.bvh_preset_chosen);
    assert!(!quick.stats.bvh_cached);
    // The same geometry at 64x64 and 400 spp: 64 * 64 * 400 * (2 + 1) * 2 = 9.8 M rays
    // repay Quality's extra 3.1e-6 s x 20,036 primitives / threads (0.19 x 9.8e6 / (2e6 x
    // threads) > 0.062 / threads).
    let mut long = scene.clone();
    long.render.width = 64;
    long.render.height = 64;
    long.render.spp = 400;
    long.render.max_bounces = 2;
    let long_render = Tracer::new(Backend::Cpu).render(&long).unwrap();
    assert_eq!(long_render.stats.bvh_preset, "quality");
    // Russian roulette ends paths long before a deep maximum: the estimate counts at most
    // ROULETTE_TAIL_SEGMENTS segments past its start. 32x32, 24 spp, 128 bounces, NEE: without
    // roulette 32 * 32 * 24 * 129 * 2 = 6.3 M rays (Quality on any thread count), with it
    // from segment 5 only 10 segments, 0.49 M (not worth Quality on any).
    let mut deep = scene.clone();
    (deep.render.width, deep.render.height, deep.render.spp) = (32, 32, 24);
    deep.render.max_bounces = 128;
    assert_eq!(raylume::ROULETTE_TAIL_SEGMENTS, 5);
    let preset = |roulette: Option<u32>| {
        let mut t = Tracer::new(Backend::Cpu);
        t.russian_roulette = roulette;
        t.render(&deep).unwrap().stats.bvh_preset
    };
    assert_eq!(preset(None), "quality");
    assert_ne!(preset(Some(5)), "quality");
    // A Quality tree built on request is then reused by a chosen render of the same geometry.
    t.bvh_quality = Some(raylume::BvhQuality::Quality);
    let built = t.render(&scene).unwrap();
    assert_eq!(built.stats.bvh_preset, "quality");
    assert!(!built.stats.bvh_cached, "no Quality tree yet");
    t.bvh_quality = None;
    let again = t.render(&scene).unwrap();
    assert!(again.stats.bvh_cached);
    assert_eq!(again.stats.bvh_preset, "quality", "the cached, better tree");
    assert_eq!(again.pixels, built.pixels);
}

/// What a render prepares for tracing (materials, textures, lights, coat tables, the
/// environment guide) and uploads is reused by the next render of the same scene over the
/// same tree, whatever its spp, seed or size, and prepared afresh as soon as anything it
/// reads changes: every such change gives the image a fresh tracer renders (a stale
/// preparation would not), on both backends.
#[test]
fn prepared_scene_is_reused_only_for_the_same_scene() {
    let mut backends = vec![Backend::Cpu];
    if raylume_gpu::testing::context_or_skip("prepared_scene_is_reused_only_for_the_same_scene")
        .is_some()
    {
        backends.push(Backend::Gpu);
    }
    for backend in backends {
        let tracer = || {
            let mut t = Tracer::new(backend);
            t.bvh_quality = Some(raylume::BvhQuality::Quality);
            // Learned whatever the size (the default would skip it for renders this small).
            t.environment_guide = Some(true);
            t
        };
        let mut t = tracer();
        let mut scene = cornell(10, 8, 2);
        // A texture on the first material, so that texels are among the inputs.
        scene.textures.push(raylume::scene::Texture {
            name: "checker".into(),
            width: 2,
            height: 1,
            texels: vec![[0.9, 0.2, 0.2], [0.2, 0.9, 0.2]].into(),
        });
        let textured = scene.triangles[0].material as usize;
        scene.materials[textured].albedo_texture = Some(0);
        let first = t.render(&scene).unwrap();
        assert!(
            !first.stats.scene_cached,
            "{backend:?}: nothing prepared yet"
        );
        scene.render.spp = 3;
        scene.render.seed += 1;
        scene.render.width = 12;
        let again = t.render(&scene).unwrap();
        assert!(
            again.stats.scene_cached,
            "{backend:?}: only the render settings changed"
        );
        assert_eq!(again.pixels, tracer().render(&scene).unwrap().pixels);

        type Change = fn(&mut Scene);
        let changes: [(&str, Change); 7] = [
            ("a material's albedo", |s| s.materials[1].albedo *= 0.5),
            ("the camera", |s| {
                s.camera.position += raylume::glam::Vec3::new(0.01, 0.0, 0.0);
            }),
            ("a texel", |s| {
                s.textures[0].texels = vec![[0.1, 0.1, 0.9], [0.2, 0.9, 0.2]].into()
            }),
            ("the environment", |s| {
                s.environment =
                    raylume::scene::Environment::Constant(raylume::glam::Vec3::splat(0.3));
            }),
            ("a triangle's material", |s| {
                let m = s.triangles[2].material;
                s.triangles[2].material = (m + 1) % s.materials.len() as u32;
            }),
            ("a triangle's shading normals", |s| {
                let n = raylume::glam::Vec3::new(0.0, 1.0, 0.2).normalize();
                s.triangles[0].normals = Some([n; 3]);
            }),
            ("a triangle's uvs", |s| {
                s.triangles[0].uvs = Some([raylume::glam::Vec2::new(0.75, 0.5); 3]);
            }),
        ];
        for (what, change) in changes {
            change(&mut scene);
            let changed = t.render(&scene).unwrap();
            assert!(
                !changed.stats.scene_cached,
                "{backend:?}: {what} changed, prepared again"
            );
            assert_eq!(
                changed.pixels,
                tracer().render(&scene).unwrap().pixels,
                "{backend:?}: {what} changed: the image of a fresh tracer"
            );
        }
        // The scene has a sky now: a fresh preparation's walks are timed (`seconds.guide`, on
        // the render's backend), a render without walks reports none.
        let walked = tracer().render(&scene).unwrap().stats;
        assert!(
            walked.seconds.guide > 0.0 && walked.seconds.guide <= walked.seconds.upload,
            "{backend:?}: {:?}",
            walked.seconds
        );
        // The guide is an option of the preparation: turning it off prepares again.
        t.environment_guide = Some(false);
        let unguided = t.render(&scene).unwrap();
        assert!(!unguided.stats.scene_cached, "{backend:?}: guide off");
        assert_eq!(unguided.stats.seconds.guide, 0.0, "{backend:?}: no walks");
        let mut fresh = tracer();
        fresh.environment_guide = Some(false);
        assert_eq!(unguided.pixels, fresh.render(&scene).unwrap().pixels);
        // Two preparations are kept per tree: back to the guide, the first is still there.
        t.environment_guide = Some(true);
        let guided = t.render(&scene).unwrap();
        assert!(guided.stats.scene_cached, "{backend:?}: guide on again");
        assert_eq!(
            guided.stats.seconds.guide, 0.0,
            "{backend:?}: kept, not walked"
        );
        assert_eq!(guided.pixels, tracer().render(&scene).unwrap().pixels);
    }
}

/// Left to decide (`environment_guide: None`, the default), a render learns the environment
/// guide only when its rays repay the walks' (`Tracer::GUIDE_REPAY_FACTOR` times
/// `env_guide::GUIDE_MAX_RAYS`); `Some(true)` learns it for any render, `Some(false)` never.
#[test]
fn the_environment_guide_is_learned_when_the_render_repays_it() {
    let mut scene = cornell(12, 10, 2);
    scene.environment = raylume::scene::Environment::Constant(raylume::glam::Vec3::splat(0.5));
    let render = |guide: Option<bool>, scene: &Scene| {
        let mut t = Tracer::new(Backend::Cpu);
        t.environment_guide = guide;
        t.render(scene).unwrap().stats.environment_guide
    };
    let small = render(None, &scene);
    assert!(small.contains("would not repay"), "{small}");
    let forced = render(Some(true), &scene);
    assert!(
        forced.starts_with("guided") || forced.starts_with("by radiance (too few"),
        "{forced}"
    );
    assert!(forced.contains("walks"), "learned: {forced}");
    assert_eq!(render(Some(false), &scene), "by radiance (guide off)");
    // The threshold itself: rays = w * h * spp * (bounces + 1) * 2 against 10 x 921,600.
    let max = raylume_kernels::env_guide::GUIDE_MAX_RAYS as f64;
    assert_eq!(max, 921_600.0);
    let mut r = scene.render;
    (r.width, r.height, r.max_bounces) = (100, 100, 9);
    r.spp = ((Tracer::GUIDE_REPAY_FACTOR * max) / (100.0 * 100.0 * 10.0 * 2.0)).ceil() as u32;
    assert!(Tracer::guide_repays(&r), "{} spp", r.spp);
    r.spp -= 1;
    assert!(!Tracer::guide_repays(&r), "{} spp", r.spp);
}

/// 8-bit textures are held as their sRGB codes unless the render's segments repay decoding
/// them (`Tracer::decode_textures`: None decides by `decoding_repays`); the image is the same
/// either way, on both backends, and the stats say which ran.
#[test]
fn textures_are_decoded_only_when_the_render_repays_it_and_the_image_is_the_same() {
    let mut scene = cornell(12, 10, 2);
    scene.textures.push(raylume::scene::Texture {
        name: "codes".into(),
        width: 3,
        height: 2,
        texels: vec![
            [250u8, 10, 10],
            [10, 250, 10],
            [10, 10, 250],
            [128, 64, 32],
            [1, 2, 3],
            [200, 200, 0],
        ]
        .into(),
    });
    let textured = scene.triangles[0].material as usize;
    scene.materials[textured].albedo_texture = Some(0);
    let mut backends = vec![Backend::Cpu];
    if raylume_gpu::testing::context_or_skip("textures_are_decoded_only_when_the_render_repays_it")
        .is_some()
    {
        backends.push(Backend::Gpu);
    }
    for backend in backends {
        let render = |decode: Option<bool>| {
            let mut t = Tracer::new(backend);
            t.decode_textures = decode;
            t.render(&scene).unwrap()
        };
        let chosen = render(None);
        assert_eq!(
            chosen.stats.textures, "8-bit sRGB codes (decoding would not repay)",
            "{backend:?}"
        );
        let decoded = render(Some(true));
        assert_eq!(decoded.stats.textures, "decoded to floats", "{backend:?}");
        assert_eq!(render(Some(false)).stats.textures, "8-bit sRGB codes");
        assert_eq!(chosen.pixels, decoded.pixels, "{backend:?}: same numbers");
        // What was held, not only what was said: the codes take a word a texel after the
        // 256-word decoding table, the decoded texels three words each (whatever else the
        // buffer holds is the same either way).
        let table = raylume::scene::srgb8_table().len() as u64;
        assert_eq!(
            chosen.stats.texel_bytes - decoded.stats.texel_bytes,
            4 * (table + 6) - 4 * 3 * 6,
            "{backend:?}"
        );
    }
    // The threshold: segments = w * h * spp * (bounces + 1) against 600 a texel.
    let mut r = scene.render;
    let texels = 6u64;
    let segments = |r: &raylume::scene::RenderSettings| {
        f64::from(r.width * r.height * r.spp * (r.max_bounces + 1))
    };
    // 600 x 6 = 3,600 segments: 60x6, 1 spp, 10 segments is the edge.
    (r.width, r.height, r.spp, r.max_bounces) = (60, 6, 1, 9);
    assert_eq!(segments(&r), Tracer::DECODE_REPAY_FACTOR * texels as f64);
    assert!(Tracer::decoding_repays(&r, texels));
    r.width -= 1;
    assert!(!Tracer::decoding_repays(&r, texels));
}

/// `BvhBuilder::Gpu` builds the tree on the GPU (the stats say so: binary layout, `fastest`),
/// keeps it for the next render of the same geometry, and renders the image the CPU's tree
/// gives; a scene with spheres is built on the CPU whatever was asked; `Auto` builds a small
/// scene on the CPU.
#[test]
fn the_bvh_is_built_on_the_gpu_when_asked_and_the_image_is_the_same() {
    let Some(_) = raylume_gpu::testing::context_or_skip(
        "the_bvh_is_built_on_the_gpu_when_asked_and_the_image_is_the_same",
    ) else {
        return;
    };
    let scene = cornell(16, 16, 2);
    let mut on_gpu = Tracer::new(Backend::Gpu);
    on_gpu.bvh_builder = raylume::BvhBuilder::Gpu;
    let first = on_gpu.render(&scene).unwrap();
    let s = &first.stats;
    assert!(
        s.bvh_builder.starts_with("LBVH on the GPU"),
        "{}",
        s.bvh_builder
    );
    assert_eq!(
        (s.bvh_layout.as_str(), s.bvh_preset.as_str()),
        ("binary", "fastest")
    );
    assert_eq!(
        s.bvh_nodes,
        scene.triangles.len() - 1,
        "one triangle a leaf"
    );
    let again = on_gpu.render(&scene).unwrap();
    assert!(again.stats.bvh_cached && again.stats.scene_cached);
    assert_eq!(again.pixels, first.pixels);

    let mut on_cpu = Tracer::new(Backend::Gpu);
    on_cpu.bvh_builder = raylume::BvhBuilder::Cpu;
    let cpu_tree = on_cpu.render(&scene).unwrap();
    assert!(
        cpu_tree.stats.bvh_builder.contains("on the CPU"),
        "{}",
        cpu_tree.stats.bvh_builder
    );
    // Two trees of the same triangles find the same hits (ties between triangles at one
    // distance aside, which these random paths do not meet): the same paths, ray for ray.
    assert_eq!(cpu_tree.stats.rays_traced, first.stats.rays_traced);
    let rel = raylume_post::relative_mse(&first.pixels, &cpu_tree.pixels).unwrap();
    assert!(rel < 1e-6, "relative MSE {rel}");

    // Spheres: the GPU build takes triangles only.
    let mut spheres = scene.clone();
    spheres.spheres.push(raylume::scene::Sphere {
        center: raylume::glam::Vec3::new(0.0, 0.3, 0.0),
        radius: 0.2,
        material: scene.triangles[0].material,
    });
    let mixed = on_gpu.render(&spheres).unwrap();
    assert!(
        mixed.stats.bvh_builder.contains("on the CPU"),
        "{}",
        mixed.stats.bvh_builder
    );

    let auto = Tracer::new(Backend::Gpu).render(&scene).unwrap();
    assert!(
        auto.stats.bvh_builder.contains("on the CPU"),
        "{}",
        auto.stats.bvh_builder
    );
}

/// `BvhBuilder::gpu_repays`: a brief look at millions of triangles is built on the GPU, a
/// long render of a room on the CPU (its better tree repays the build).
#[test]
fn the_gpu_build_is_chosen_for_large_scenes_and_few_rays() {
    use raylume::{BvhBuilder, BvhQuality, GPU_RAYS_PER_SECOND};
    let rays = |w: f64, h: f64, spp: f64, segments: f64| w * h * spp * segments * 2.0;
    // The 3M grid at 1000x1000, 10 spp: the CPU's Fastest build ~0.56 s on 4 threads.
    assert!(BvhBuilder::gpu_repays(
        3_000_000,
        rays(1000.0, 1000.0, 10.0, 10.0),
        GPU_RAYS_PER_SECOND,
        4,
        BvhQuality::Fastest
    ));
    // The living room (143k triangles) at 1000x1000, 100 spp: the trace dominates.
    assert!(!BvhBuilder::gpu_repays(
        143_000,
        rays(1000.0, 1000.0, 100.0, 10.0),
        GPU_RAYS_PER_SECOND,
        4,
        BvhQuality::Quality
    ));
    // A tiny scene: nothing to save.
    assert!(!BvhBuilder::gpu_repays(
        36,
        1e3,
        GPU_RAYS_PER_SECOND,
        4,
        BvhQuality::Fastest
    ));
    for b in [BvhBuilder::Auto, BvhBuilder::Cpu, BvhBuilder::Gpu] {
        assert_eq!(b.name().parse::<BvhBuilder>(), Ok(b));
    }
}

/// A scene whose GPU-built tree would be deeper than the traversal's stack (Morton codes that
/// make the radix tree a chain) is built on the CPU instead, in the binary layout the
/// pipelines were compiled for, and the stats say why; the image is the CPU tree's.
#[test]
fn a_gpu_tree_too_deep_falls_back_to_the_cpu_build() {
    let Some(_) =
        raylume_gpu::testing::context_or_skip("a_gpu_tree_too_deep_falls_back_to_the_cpu_build")
    else {
        return;
    };
    use raylume::glam::Vec3;
    let mut scene = cornell(8, 8, 1);
    let m = scene.triangles[0].material;
    // One small triangle per leading-bit position of the 63-bit code (a centre at 1.5 x 2^k
    // grid cells along one axis, the grid 2^21 cells over the extent), and copies at 0.
    let tri = |c: Vec3| {
        let e = 1e-6;
        raylume::scene::Triangle::flat(
            [c, c + Vec3::new(e, 0.0, 0.0), c + Vec3::new(0.0, e, 0.0)],
            m,
        )
    };
    let mut chain = vec![tri(Vec3::ZERO); 8];
    for axis in 0..3 {
        for k in 0..21 {
            let mut c = Vec3::ZERO;
            c[axis] = 1.5 * (1u32 << k) as f32 / (1u32 << 21) as f32;
            chain.push(tri(c));
        }
    }
    let source = raylume_bvh::GpuBvh::lbvh_input(&chain).unwrap();
    let depth = raylume_bvh::lbvh::lbvh_binary(&source).max_depth;
    assert!(
        depth > raylume_bvh::MAX_STACK_DEPTH,
        "the chain is only {depth} deep"
    );
    scene.triangles = chain;

    let mut t = Tracer::new(Backend::Gpu);
    t.bvh_builder = raylume::BvhBuilder::Gpu;
    let fell_back = t.render(&scene).unwrap();
    let s = &fell_back.stats;
    assert!(
        s.bvh_builder.starts_with("LBVH on the CPU") && s.bvh_builder.contains("deep"),
        "{}",
        s.bvh_builder
    );
    assert_eq!(s.bvh_layout, "binary");
    let mut cpu = Tracer::new(Backend::Gpu);
    cpu.bvh_builder = raylume::BvhBuilder::Cpu;
    cpu.bvh_layout = raylume::BvhLayout::Binary;
    cpu.bvh_quality = Some(raylume::BvhQuality::Fastest);
    assert_eq!(cpu.render(&scene).unwrap().pixels, fell_back.pixels);
}

/// A tracer handed another device (`with_gpu_context`) forgets what lived on the one before:
/// a tree built there (`BvhBuilder::Gpu`), the scene uploaded there, the builder's kernels;
/// its next render runs wholly on the new device, with the same image.
#[test]
fn a_new_device_forgets_the_trees_and_scenes_of_the_old_one() {
    let Some(_) = raylume_gpu::testing::context_or_skip(
        "a_new_device_forgets_the_trees_and_scenes_of_the_old_one",
    ) else {
        return;
    };
    let any = || {
        GpuContext::new(&ContextOptions {
            choice: AdapterChoice::Any,
            adapter_name: None,
        })
        .unwrap()
    };
    let scene = cornell(16, 16, 2);
    let mut t = Tracer::new(Backend::Gpu).with_gpu_context(any());
    t.bvh_builder = raylume::BvhBuilder::Gpu;
    let first = t.render(&scene).unwrap();
    assert!(first.stats.bvh_builder.starts_with("LBVH on the GPU"));
    let mut t = t.with_gpu_context(any());
    let second = t.render(&scene).unwrap();
    assert!(
        !second.stats.bvh_cached,
        "the tree lived on the other device"
    );
    assert!(!second.stats.scene_cached, "so did the scene's upload");
    assert!(second.stats.bvh_builder.starts_with("LBVH on the GPU"));
    assert_eq!(second.pixels, first.pixels);
}

/// `Tracer::walk_stage`'s default turns the wavefront's walk stage on for a scene of at least
/// `WALK_STAGE_MIN_PRIMITIVES` primitives and leaves it off below; either way, or set, the
/// image is the same, and the stats say when the stage ran.
#[test]
fn the_walk_stage_by_default_walks_large_scenes_only() {
    if raylume_gpu::testing::subgroup_context_or_skip(
        "the_walk_stage_by_default_walks_large_scenes_only",
    )
    .is_none()
    {
        return;
    }
    let small = cornell(12, 12, 2);
    let mut large = cornell(12, 12, 2);
    common::add_floor_grid(&mut large);
    assert!(small.triangles.len() < raylume::WALK_STAGE_MIN_PRIMITIVES);
    assert!(large.triangles.len() >= raylume::WALK_STAGE_MIN_PRIMITIVES);
    for (scene, by_default) in [(&small, false), (&large, true)] {
        let mut images = Vec::new();
        for setting in [None, Some(false), Some(true)] {
            let mut t = Tracer::new(Backend::Gpu);
            t.schedule = Some(raylume::Schedule::Wavefront);
            t.walk_stage = setting;
            let r = t.render(scene).unwrap();
            let ran = setting.unwrap_or(by_default);
            assert_eq!(
                r.stats.schedule,
                if ran {
                    // The tracer's default estimator (NEE) runs the shadow stage beside it.
                    "wavefront + walk stage + shadow stage"
                } else {
                    "wavefront"
                },
                "{} triangles, walk_stage {setting:?}",
                scene.triangles.len()
            );
            images.push(r.pixels);
        }
        assert!(images.windows(2).all(|w| w[0] == w[1]));
    }
}

/// `Tracer::schedule`'s default (`None`) runs the persistent schedule unless the walk stage
/// runs, the estimator is NEE and the render traces at least `Tracer::wavefront_min_samples`
/// pixel samples; then the wavefront with its stages. The image is the persistent schedule's
/// either way, a set schedule is kept whatever the work, and the CPU (which has no walk
/// stage) runs the persistent loop. (The walk stage is asked for on the small Cornell box and
/// the threshold lowered to 2^20 samples: on lavapipe `WAVEFRONT_MIN_SAMPLES` samples of a
/// 10,000-triangle scene would take the test many minutes.)
#[test]
fn the_default_schedule_is_the_wavefront_for_large_nee_work_with_the_walk_stage() {
    if raylume_gpu::testing::subgroup_context_or_skip(
        "the_default_schedule_is_the_wavefront_for_large_nee_work_with_the_walk_stage",
    )
    .is_none()
    {
        return;
    }
    let (w, h, min_samples) = (16u32, 16u32, 1u64 << 20);
    let spp = (min_samples / u64::from(w * h)) as u32;
    let mut scene = cornell(w, h, spp);
    scene.render.max_bounces = 2;
    let render = |scene: &raylume::Scene, schedule, walk_stage, estimator| {
        let mut t = Tracer::new(Backend::Gpu);
        assert_eq!(t.schedule, None);
        assert_eq!(t.wavefront_min_samples, raylume::WAVEFRONT_MIN_SAMPLES);
        t.wavefront_min_samples = min_samples;
        t.estimator = estimator;
        t.schedule = schedule;
        t.walk_stage = walk_stage;
        t.render(scene).unwrap()
    };
    let nee = raylume::Estimator::Nee;
    let chosen = render(&scene, None, Some(true), nee);
    assert_eq!(
        chosen.stats.schedule,
        "wavefront + walk stage + shadow stage"
    );
    let persistent = render(&scene, Some(raylume::Schedule::Persistent), Some(true), nee);
    assert_eq!(persistent.stats.schedule, "persistent");
    assert_eq!(chosen.pixels, persistent.pixels);
    // No walk stage, plain paths, or a sample fewer: persistent.
    let plain = raylume::Estimator::Plain;
    assert_eq!(
        render(&scene, None, Some(false), nee).stats.schedule,
        "persistent"
    );
    assert_eq!(
        render(&scene, None, Some(true), plain).stats.schedule,
        "persistent"
    );
    let mut fewer = scene.clone();
    fewer.render.spp -= 1;
    assert_eq!(
        render(&fewer, None, Some(true), nee).stats.schedule,
        "persistent"
    );
    // The CPU runs the persistent schedule's loop.
    let mut cpu = Tracer::new(Backend::Cpu);
    cpu.walk_stage = Some(true);
    cpu.wavefront_min_samples = 1;
    fewer.render.spp = 1;
    assert_eq!(cpu.render(&fewer).unwrap().stats.schedule, "persistent");
}

/// `Tracer::shadow_stage` reaches the GPU tracer: asked for with the walk stage and NEE (and
/// so by default), the render's schedule says the shadow stage ran, and the image is the one
/// without it.
#[test]
fn the_shadow_stage_is_asked_for_through_the_tracer() {
    if raylume_gpu::testing::subgroup_context_or_skip(
        "the_shadow_stage_is_asked_for_through_the_tracer",
    )
    .is_none()
    {
        return;
    }
    let scene = cornell(12, 12, 2);
    let mut images = Vec::new();
    // `None`: the tracer's default.
    for setting in [Some(false), Some(true), None] {
        let mut t = Tracer::new(Backend::Gpu);
        t.schedule = Some(raylume::Schedule::Wavefront);
        t.estimator = raylume::Estimator::Nee;
        t.walk_stage = Some(true);
        if let Some(on) = setting {
            t.shadow_stage = on;
        }
        let shadow_stage = setting.unwrap_or(true);
        let r = t.render(&scene).unwrap();
        assert_eq!(
            r.stats.schedule,
            if shadow_stage {
                "wavefront + walk stage + shadow stage"
            } else {
                "wavefront + walk stage"
            }
        );
        images.push(r.pixels);
    }
    assert!(
        images.windows(2).all(|w| w[0] == w[1]),
        "the shadow stage changed the image"
    );
}
