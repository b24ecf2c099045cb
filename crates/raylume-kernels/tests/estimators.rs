//! Every estimator and sampler computes the same image: long renders of the same scene with
//! and without next-event estimation, Russian roulette and each sampler converge to the same
//! mean within a bound derived from their own spread; and the low-discrepancy sampler pays
//! (less error at equal samples). On the CPU mirror (the GPU traces the same paths:
//! `cpu_vs_gpu.rs`).

mod support;

use raylume_kernels::{CpuTracer, Estimator, Sampler, Schedule, TraceSettings};
use raylume_scene::Scene;
use support::*;

#[derive(Clone, Copy, Debug)]
struct Config {
    estimator: Estimator,
    sampler: Sampler,
    roulette: Option<u32>,
    /// NEE toward the environment by the learned guide (`SceneOptions::environment_guide`).
    guide: bool,
}

fn render(scene: &Scene, c: Config, size: u32, spp: u32, bounces: u32, seed: u32) -> Vec<[f32; 3]> {
    let s = TraceSettings {
        seed,
        ..settings(size, size, spp, bounces, Schedule::Megakernel)
    };
    let options = raylume_kernels::SceneOptions {
        environment_guide: c.guide,
        ..Default::default()
    };
    let mut t = CpuTracer::with_options(scene, &bvh(scene), &options).unwrap();
    t.set_estimator(c.estimator);
    t.set_sampler(c.sampler);
    t.set_russian_roulette(c.roulette);
    t.render(&s, &mut |_, _| {}).unwrap().radiance
}

/// The box seen from above its floor, the lamp out of view (its own pixels would dominate).
fn floor_view() -> Scene {
    let mut s = cornell_box();
    s.camera.position = glam::Vec3::new(0.0, 1.6, 0.9);
    s.camera.look_at = glam::Vec3::new(0.0, 0.0, -0.2);
    s
}

#[test]
fn every_estimator_and_sampler_converges_to_the_same_mean() {
    // Scrambled Sobol' renders with different seeds are independent randomisations (each seed
    // hashes new Owen scrambles and digit permutations), so the spread of per-seed image means
    // is an honest standard error for every configuration alike.
    let plain = Config {
        estimator: Estimator::Plain,
        sampler: Sampler::Independent,
        roulette: None,
        guide: false,
    };
    let configs = [
        (
            "nee",
            Config {
                estimator: Estimator::Nee,
                ..plain
            },
        ),
        (
            "nee zsobol",
            Config {
                estimator: Estimator::Nee,
                sampler: Sampler::ZSobol,
                ..plain
            },
        ),
        (
            "nee zsobol roulette from 1",
            Config {
                estimator: Estimator::Nee,
                sampler: Sampler::ZSobol,
                roulette: Some(1),
                guide: false,
            },
        ),
        (
            "nee guided",
            Config {
                estimator: Estimator::Nee,
                guide: true,
                ..plain
            },
        ),
        (
            "nee sobol roulette guided (the library's default)",
            Config {
                estimator: Estimator::Nee,
                sampler: Sampler::Sobol,
                roulette: Some(5),
                guide: true,
            },
        ),
        (
            "plain zsobol",
            Config {
                sampler: Sampler::ZSobol,
                ..plain
            },
        ),
        (
            "plain roulette from 2",
            Config {
                roulette: Some(2),
                ..plain
            },
        ),
    ];
    // The spheres have a sphere lamp and a constant sky; the environment-lit spheres a sky map
    // (importance-sampled by luminance) and nothing else; the materials every microfacet
    // material, rough glass (light sampled through it) among them, and a triangle lamp.
    for (name, scene) in [
        ("cornell box floor", floor_view()),
        ("spheres", spheres()),
        ("environment-lit spheres", environment_lit()),
        ("materials", materials()),
        ("skylight room", skylight_room(0.8)),
    ] {
        let seeds = 8u32;
        let estimate = |c: Config, spp: u32| -> [(f64, f64); 3] {
            let means: Vec<[f64; 3]> = (0..seeds)
                .map(|k| mean(&render(&scene, c, 8, spp, 5, 100 + k)))
                .collect();
            std::array::from_fn(|ch| {
                let n = f64::from(seeds);
                let m = means.iter().map(|x| x[ch]).sum::<f64>() / n;
                let var = means.iter().map(|x| (x[ch] - m).powi(2)).sum::<f64>() / (n - 1.0);
                (m, (var / n).sqrt())
            })
        };
        let reference = estimate(plain, 1024);
        for (cname, c) in configs {
            let e = estimate(c, 256);
            for ch in 0..3 {
                let ((mr, sr), (m, s)) = (reference[ch], e[ch]);
                let se = (sr * sr + s * s).sqrt();
                eprintln!(
                    "{name}, {cname}, channel {ch}: {m:.5} ± {s:.5} vs plain {mr:.5} ± {sr:.5}"
                );
                // Their difference is noise of standard deviation `se` (8 renders each): 5 of
                // them is a 1-in-3-million chance for a Gaussian; 0.5 % of the value allows for
                // the t-distribution of 8-sample standard errors without room for a missing
                // light, a doubled or dropped weight, or a roulette that forgets to divide.
                assert!(
                    (m - mr).abs() < 5.0 * se + 0.005 * mr,
                    "{name}, {cname}, channel {ch}: {m} vs {mr} (standard error {se})"
                );
            }
        }
    }
}

#[test]
fn sobol_samplers_have_less_error_than_independent_samples() {
    // Direct light from the box's lamp (one bounce): a smooth integrand over the pixel area
    // and the light's area, where stratified points pay most. Against a 4096-spp reference.
    let scene = floor_view();
    let nee = |sampler| Config {
        estimator: Estimator::Nee,
        sampler,
        roulette: None,
        guide: false,
    };
    let reference = render(&scene, nee(Sampler::Independent), 16, 4096, 1, 7);
    for spp in [16, 64] {
        let err = |sampler| {
            // The mean over 4 seeds of the squared relative error, so one lucky seed
            // does not decide.
            let e: f64 = (0..4)
                .map(|k| {
                    relative_rmse(
                        &render(&scene, nee(sampler), 16, spp, 1, 20 + k),
                        &reference,
                    )
                    .powi(2)
                })
                .sum::<f64>()
                / 4.0;
            e.sqrt()
        };
        let indep = err(Sampler::Independent);
        for sampler in [Sampler::ZSobol, Sampler::Sobol] {
            let e = err(sampler);
            eprintln!("{spp} spp, direct light: independent {indep:.4}, {sampler:?} {e:.4}");
            // Measured on this scene: ZSobol's error is 0.64x independent's at 16 spp and
            // 0.57x at 64 (its advantage grows with spp, as stratification should); the
            // shuffled Sobol' 0.62x and 0.61x (2026-12-02). The reference's own error (4096 spp,
            // ~0.003) is far below either. Asked: 0.8x.
            assert!(
                e < 0.8 * indep,
                "{spp} spp: {sampler:?} {e}, independent {indep}"
            );
        }
    }
}

#[test]
fn a_convex_diffuse_object_under_a_constant_sky_is_lit_exactly() {
    // A Lambertian sphere of albedo rho under a sky of radiance L: every direction leaving it
    // escapes (it is convex), so it sends back exactly rho L, whatever the bounces. The camera
    // sees only the sphere. NEE samples the sky uniformly on the sphere of directions and
    // weighs that against the cosine-sampled escape: both see L, so only the MIS weights and
    // the half of the shadow rays that point into the surface vary. A dropped weight counts
    // the sky twice (2 rho L), a pdf off by 2 shifts it by a third.
    let rho = 0.6f32;
    let l = glam::Vec3::new(1.0, 0.5, 0.25);
    let scene = Scene {
        camera: raylume_scene::Camera::looking_at(
            glam::Vec3::new(0.0, 0.0, 4.0),
            glam::Vec3::ZERO,
            8.0,
        ),
        materials: vec![raylume_scene::Material::diffuse(
            "white",
            glam::Vec3::splat(rho),
        )],
        spheres: vec![raylume_scene::Sphere {
            center: glam::Vec3::ZERO,
            radius: 1.0,
            material: 0,
        }],
        environment: raylume_scene::Environment::Constant(l),
        ..Default::default()
    };
    for sampler in [Sampler::Independent, Sampler::ZSobol, Sampler::Sobol] {
        let c = Config {
            estimator: Estimator::Nee,
            sampler,
            roulette: None,
            guide: false,
        };
        let img = render(&scene, c, 8, 16, 4, 5);
        let m = mean(&img);
        for ch in 0..3 {
            let exact = f64::from(rho * l[ch]);
            // 1024 samples; each NEE estimate lies within [0, 2 rho L] (MIS weights in
            // [0, 1] for both halves), so its standard deviation is below rho L and the
            // mean's below rho L / 32: 3 % of the value is 1 such deviation at worst, and the
            // measured spread is far smaller (the estimates vary little).
            eprintln!("{sampler:?} channel {ch}: {:.5} vs exact {exact:.5}", m[ch]);
            assert!(
                (m[ch] - exact).abs() < 0.03 * exact,
                "{sampler:?} channel {ch}: {} vs {exact}",
                m[ch]
            );
        }
    }
}
