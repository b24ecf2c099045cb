//! The environment guide (`raylume_kernels::env_guide`): the walks find where the sky is seen
//! from, the guided distributions are proper densities that `sample_environment` draws from
//! and `environment_pdf` reports exactly, and estimates with them are unbiased. (The images
//! with and without the guide converge to the same mean: `estimators.rs`; the GPU draws the
//! same samples: `cpu_vs_gpu.rs`.)

mod support;

use glam::{Vec2, Vec3};
use raylume_kernels::cpu::variant::GENERIC;
use raylume_kernels::env_guide::{
    EnvironmentGuide, GUIDE_HEIGHT, GUIDE_UNIFORM_SHARE, cell_index, guide_grid,
    learn_environment_guide,
};
use raylume_kernels::gpu_types::SceneUniforms;
use raylume_kernels::scene_data::{SceneData, SceneOptions};
use raylume_kernels::surface::{Globals, environment_cell, environment_pdf, sample_environment};
use support::*;

fn learned(opening: f32) -> (raylume_scene::Scene, raylume_bvh::GpuBvh, SceneData) {
    let scene = skylight_room(opening);
    let bvh = bvh(&scene);
    let data = SceneData::with_options(
        &scene,
        &bvh,
        &SceneOptions {
            environment_guide: true,
            ..Default::default()
        },
    )
    .unwrap();
    (scene, bvh, data)
}

/// The uniforms that point the sampling functions at `data`'s guided distributions.
fn guided_uniforms(data: &SceneData) -> SceneUniforms {
    let g = data.environment_guided_cdf.expect("a guide was learned");
    SceneUniforms {
        scene_min: data.scene_min.into(),
        scene_extent: data.scene_extent.into(),
        environment_kind: data.environment_kind,
        environment_cdf: g.offset,
        environment_cdf_width: g.width,
        environment_cdf_height: g.height,
        environment_grid: g.grid,
        environment_grid_scale: g.grid_scale.into(),
        ..Default::default()
    }
}

fn globals<'a>(
    u: &'a SceneUniforms,
    data: &'a SceneData,
    bvh: &'a raylume_bvh::GpuBvh,
) -> Globals<'a> {
    Globals {
        scene: u,
        primitives: &bvh.primitives,
        materials: &data.materials,
        prim_materials: &data.prim_materials,
        triangle_shading: &data.triangle_shading,
        texture_headers: &data.texture_headers,
        texels: &data.texels,
        lights: &data.lights,
        plastic_tables: &data.plastic_tables,
        sobol_segments: &[],
    }
}

#[test]
fn the_grid_covers_the_bounds_and_clamps_points_outside() {
    let (grid, scale) = guide_grid(Vec3::new(8.0, 2.0, 0.0));
    assert_eq!(grid, [8, 2, 1]);
    assert_eq!(scale, Vec3::new(1.0, 1.0, 0.0));
    let min = Vec3::new(-4.0, 0.0, 3.0);
    assert_eq!(cell_index(min, min, scale, grid), 0);
    assert_eq!(cell_index(Vec3::new(3.99, 1.99, 3.0), min, scale, grid), 15);
    // Outside the bounds (a ray origin pushed off a boundary face): the nearest cell.
    assert_eq!(cell_index(Vec3::new(-5.0, 9.0, 7.0), min, scale, grid), 8);
    assert_eq!(cell_index(Vec3::new(4.5, -1.0, 3.0), min, scale, grid), 7);
    assert_eq!(guide_grid(Vec3::ZERO), ([1, 1, 1], Vec3::ZERO));
    assert_eq!(guide_grid(Vec3::splat(f32::NAN)), ([1, 1, 1], Vec3::ZERO));
}

#[test]
fn walks_in_a_room_escape_only_through_its_skylight() {
    let (scene, bvh, data) = learned(0.8);
    let guide = learn_environment_guide(&scene.camera, &bvh, data.scene_min, data.scene_extent);
    assert!(guide.is_useful(), "{} escapes", guide.escapes);
    // Every escape leaves upward: rows of the top half of the direction grid (v < 1/2).
    let bins = guide.counts.len() / guide.cell_count();
    let downward: u64 = guide
        .counts
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            (i % bins) as u32 >= GUIDE_HEIGHT / 2 * raylume_kernels::env_guide::GUIDE_WIDTH
        })
        .map(|(_, &c)| u64::from(c))
        .sum();
    assert_eq!(
        downward, 0,
        "{downward} of {} escapes went down",
        guide.escapes
    );
    // A closed box: nothing escapes, and no guide is used (the uniform sphere stays).
    let (_, _, closed) = learned(0.0);
    assert_eq!(closed.environment_guide_walks.map(|w| w.1), Some(0));
    assert!(closed.environment_guided_cdf.is_none());
    assert_eq!(
        closed
            .uniforms(&settings(8, 8, 1, 1, raylume_kernels::Schedule::Megakernel))
            .environment_cdf_width,
        0
    );
}

#[test]
fn guided_samples_have_the_pdf_they_report_and_integrate_exactly() {
    let (_, bvh, data) = learned(0.8);
    let u = guided_uniforms(&data);
    let g = globals(&u, &data, &bvh);
    // Cells: under the skylight near the ceiling, in a floor corner, and the one a point
    // outside the bounds clamps to.
    let points = [
        Vec3::new(0.0, 1.9, 0.0),
        Vec3::new(-0.9, 0.05, 0.9),
        Vec3::new(5.0, -3.0, 0.0),
    ];
    for p in points {
        let cell = environment_cell(&g, p);
        // 1. ∫ pdf dω = ∫∫ pdf sin θ dθ dφ = 1, by the midpoint rule on a 512² (θ, φ) grid
        // aligned with the guide's cells (pdf sin θ is constant on each cell, so the rule is
        // exact but for rounding and the few points the polynomial acos/atan2 put into a
        // neighbouring cell): within 0.1 %.
        let m = 512;
        let (mut total, mut up) = (0.0f64, 0.0f64);
        for i in 0..m {
            let theta = std::f64::consts::PI * (f64::from(i) + 0.5) / f64::from(m);
            for j in 0..m {
                let phi = 2.0 * std::f64::consts::PI * (f64::from(j) + 0.5) / f64::from(m);
                let d = Vec3::new(
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                    (-theta.sin() * phi.cos()) as f32,
                );
                let pdf = f64::from(environment_pdf::<GENERIC>(&g, d, cell)) * theta.sin();
                total += pdf;
                if d.y > 0.0 {
                    up += pdf;
                }
            }
        }
        let norm = 2.0 * std::f64::consts::PI * std::f64::consts::PI / f64::from(m * m);
        let (total, up) = (total * norm, up * norm);
        assert!((total - 1.0).abs() < 1e-3, "cell {cell}: ∫ pdf = {total}");
        // The guide sends its share upward (all its escapes were), the uniform share half.
        assert!(
            up > (1.0 - GUIDE_UNIFORM_SHARE) + 0.45 * GUIDE_UNIFORM_SHARE,
            "cell {cell}: {up} of the probability upward"
        );
        // 2. Samples: the pdf they report is environment_pdf's (but for directions on a
        // cell border that the polynomial atan2/acos put into the neighbour), and the
        // estimate of ∫ max(y, 0) dω = π is within 5 standard errors (from the samples' own
        // spread, as if independent: stratified ones vary less) of π.
        let n = 256u32;
        let (mut sum, mut sum2, mut mismatched) = (0.0f64, 0.0f64, 0u32);
        for i in 0..n {
            for j in 0..n {
                let uv = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let (d, pdf) = sample_environment::<GENERIC>(&g, uv, cell);
                assert!(pdf > 0.0 && (d.length() - 1.0).abs() < 1e-5, "{d} {pdf}");
                let again = environment_pdf::<GENERIC>(&g, d, cell);
                if (again - pdf).abs() > 1e-3 * pdf {
                    mismatched += 1;
                }
                let x = f64::from(d.y.max(0.0) / pdf);
                sum += x;
                sum2 += x * x;
            }
        }
        let count = f64::from(n * n);
        let estimate = sum / count;
        let se = ((sum2 / count - estimate * estimate) / count).sqrt();
        assert!(
            mismatched * 1000 < n * n,
            "cell {cell}: {mismatched} pdfs disagree"
        );
        assert!(
            (estimate - std::f64::consts::PI).abs() < 5.0 * se,
            "cell {cell}: ∫ max(y, 0) dω estimated {estimate} ± {se}"
        );
    }
    // Cells differ: the guide is spatial.
    let cdf_of = |p: Vec3| {
        let c = environment_cell(&g, p) as usize;
        let per = (u.environment_cdf_height * (1 + u.environment_cdf_width)) as usize;
        let base = u.environment_cdf as usize + c * per;
        data.texels[base..base + per].to_vec()
    };
    assert_ne!(cdf_of(points[0]), cdf_of(points[1]));
}

#[test]
fn guided_next_event_estimation_finds_the_skylight_more_often() {
    // The direct sky light at points of the floor, estimated by shadow rays drawn uniformly
    // and drawn by the guide: the same mean (both unbiased), and the guided one's spread is
    // well below the uniform one's (most uniform rays hit the walls).
    let (_, bvh, data) = learned(0.8);
    let guided = guided_uniforms(&data);
    let uniform = SceneUniforms {
        scene_min: guided.scene_min,
        ..Default::default()
    };
    let (gg, gu) = (
        globals(&guided, &data, &bvh),
        globals(&uniform, &data, &bvh),
    );
    let mut stats = [(0.0f64, 0.0f64); 2];
    let n = 4096u32;
    for (k, g) in [gu, gg].iter().enumerate() {
        for i in 0..n {
            let h = raylume_kernels::rng::pcg4d([i, 7, 11, k as u32]);
            let r = |x: u32| raylume_kernels::rng::rand_f32(x);
            let p = Vec3::new(1.8 * r(h[0]) - 0.9, 1e-3, 1.8 * r(h[1]) - 0.9);
            let cell = environment_cell(g, p);
            let (d, pdf) = sample_environment::<GENERIC>(g, Vec2::new(r(h[2]), r(h[3])), cell);
            let ray = raylume_bvh::Ray::new(p, d);
            let v = if d.y > 0.0 && pdf > 0.0 && !bvh.trace_any(&ray, 0.0, f32::INFINITY) {
                f64::from(d.y / pdf)
            } else {
                0.0
            };
            stats[k].0 += v;
            stats[k].1 += v * v;
        }
    }
    let (m, var): (Vec<f64>, Vec<f64>) = stats
        .iter()
        .map(|&(s, s2)| {
            let m = s / f64::from(n);
            (m, s2 / f64::from(n) - m * m)
        })
        .unzip();
    let se = ((var[0] + var[1]) / f64::from(n)).sqrt();
    eprintln!(
        "uniform {:.4} (var {:.4}), guided {:.4} (var {:.4})",
        m[0], var[0], m[1], var[1]
    );
    assert!(
        (m[0] - m[1]).abs() < 5.0 * se,
        "means {} vs {} (se {se})",
        m[0],
        m[1]
    );
    assert!(
        var[1] * 4.0 < var[0],
        "variance {} guided vs {} uniform",
        var[1],
        var[0]
    );
}

#[test]
fn the_guide_is_deterministic() {
    let (scene, bvh, data) = learned(0.8);
    let a = learn_environment_guide(&scene.camera, &bvh, data.scene_min, data.scene_extent);
    let b = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| {
            learn_environment_guide(&scene.camera, &bvh, data.scene_min, data.scene_extent)
        });
    assert_eq!(a, b);
    let _: &EnvironmentGuide = &a;
}
