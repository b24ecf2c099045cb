//! `Tracer::target_error` on the CPU: the estimate agrees with the true relative MSE on a scene
//! whose image is known, the render stops at the first batch whose estimate is below the
//! target (recomputed here from the batches' own sums), an unreachable target stops at the
//! cap and says so, a stopped render is bit for bit the render of the samples it traced, and
//! targets that are not a positive finite number are typed errors.
//!
//! The scene: the camera inside a closed diffuse sphere of albedo `a` emitting `E` (seen from
//! inside, so two-sided). Without roulette every path collects `E (1 - a^(n+1)) / (1 - a)`
//! exactly (kernels' `tests/analytic.rs`); with Russian roulette from the first hit each
//! sample is random with that mean (unbiased), the same distribution in every pixel, and the
//! pixels independent. So the converged image is known exactly and the per-pixel errors are
//! independent and identically distributed. The paper's estimator and independent numbers are
//! set explicitly (the tracer's defaults are NEE and ZSobol).

use glam::{DVec3, Vec3};
use raylume::scene::{Camera, FovAxis, Material, Sphere};
use raylume::{Backend, Error, Estimator, Render, Sampler, Scene, Tracer};
use raylume_kernels::batches::{RoundFlow, RoundSums};
use raylume_kernels::{CpuTracer, Reorder, Schedule, TraceSettings};

const ALBEDO: f32 = 0.6;
const EMISSION: Vec3 = Vec3::new(0.5, 1.0, 2.0);
const BOUNCES: u32 = 12;
const ROULETTE: Option<u32> = Some(1);
const EPS: f64 = raylume_post::metrics::RELATIVE_MSE_EPS;

fn furnace(size: u32, spp: u32) -> Scene {
    let mut m = Material::diffuse("inside", Vec3::splat(ALBEDO));
    m.emission = EMISSION;
    m.two_sided = true;
    let mut scene = Scene {
        camera: Camera {
            position: Vec3::new(0.1, 0.2, 0.0),
            look_at: Vec3::new(0.0, 0.0, -1.0),
            up: Vec3::Y,
            fov: 70.0,
            fov_axis: FovAxis::Vertical,
        },
        materials: vec![m],
        spheres: vec![Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
            material: 0,
        }],
        ..Default::default()
    };
    scene.render.width = size;
    scene.render.height = size;
    scene.render.spp = spp;
    scene.render.max_bounces = BOUNCES;
    scene
}

/// The converged pixel: `E (1 - a^(n+1)) / (1 - a)`, in f64.
fn exact() -> DVec3 {
    let a = f64::from(ALBEDO);
    EMISSION.as_dvec3() * (1.0 - a.powi(BOUNCES as i32 + 1)) / (1.0 - a)
}

fn tracer(batch_spp: u32, target: Option<f32>) -> Tracer {
    let mut t = Tracer::new(Backend::Cpu);
    t.estimator = Estimator::Plain;
    t.sampler = Sampler::Independent;
    t.russian_roulette = ROULETTE;
    t.batch_spp = batch_spp;
    t.target_error = target;
    t
}

fn render(scene: &Scene, batch_spp: u32, target: Option<f32>) -> Render {
    tracer(batch_spp, target).render(scene).unwrap()
}

/// Every round's running sums of a full render of `scene` (no stop), straight from the kernel
/// tracer with the settings the facade uses.
fn round_sums(scene: &Scene, batch_spp: u32) -> Vec<(u32, Vec<[f32; 3]>)> {
    let bvh = raylume_bvh::GpuBvh::from_scene(scene, raylume::BvhQuality::default()).unwrap();
    let mut cpu = CpuTracer::new(scene, &bvh).unwrap();
    cpu.set_estimator(Estimator::Plain);
    cpu.set_sampler(Sampler::Independent);
    cpu.set_russian_roulette(ROULETTE);
    let r = scene.render;
    let settings = TraceSettings {
        width: r.width,
        height: r.height,
        spp: r.spp,
        max_bounces: r.max_bounces,
        seed: r.seed,
        batch_spp,
        schedule: Schedule::Megakernel,
        reorder: Reorder::OFF,
    };
    let mut rounds = Vec::new();
    cpu.render_with_hook(&settings, &mut |_, _| {}, &mut |s: &RoundSums<'_>| {
        rounds.push((s.samples_done, s.sums.to_vec()));
        RoundFlow::Continue
    })
    .unwrap();
    rounds
}

/// Per pixel, after each round `k` (1-based; `None` for `k = 1`), the estimate of that
/// pixel's relative squared error, averaged over its channels, computed the textbook way:
/// round means from differences of the sums, their two-pass sample variance, divided by the
/// number of rounds, over the squared mean plus 1e-2. (Rounds of equal size only.)
fn estimates_per_pixel(rounds: &[(u32, Vec<[f32; 3]>)]) -> Vec<Option<Vec<f64>>> {
    let n = f64::from(rounds[0].0);
    let pixels = rounds[0].1.len();
    let means: Vec<Vec<[f64; 3]>> = (0..rounds.len())
        .map(|k| {
            (0..pixels)
                .map(|p| {
                    std::array::from_fn(|c| {
                        let prev = if k == 0 { 0.0 } else { rounds[k - 1].1[p][c] };
                        (f64::from(rounds[k].1[p][c]) - f64::from(prev)) / n
                    })
                })
                .collect()
        })
        .collect();
    (1..=rounds.len())
        .map(|b| {
            if b < 2 {
                return None;
            }
            assert_eq!(rounds[b - 1].0, b as u32 * rounds[0].0, "equal rounds");
            Some(
                (0..pixels)
                    .map(|p| {
                        (0..3)
                            .map(|c| {
                                let m = (0..b).map(|k| means[k][p][c]).sum::<f64>() / b as f64;
                                let s2 = (0..b).map(|k| (means[k][p][c] - m).powi(2)).sum::<f64>()
                                    / (b - 1) as f64;
                                s2 / b as f64 / (m * m + EPS)
                            })
                            .sum::<f64>()
                            / 3.0
                    })
                    .collect(),
            )
        })
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn sd(v: &[f64]) -> f64 {
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

#[test]
fn the_estimate_agrees_with_the_true_relative_mse() {
    // 96x96 pixels, 16 batches of 16 samples, a target it cannot reach: the estimate after
    // the last batch against the true relative MSE of the image (`relative_mse` against the
    // exact furnace image).
    //
    // The bound. Per pixel p, t_p = mean_c (x - ref)^2 / (ref^2 + eps) (the true error) and
    // e_p = mean_c v_p / (x^2 + eps) (the estimate, v_p the unbiased estimate of Var(x) from
    // the batches): the facade's estimate is mean_p e_p and the truth mean_p t_p. The pixels
    // are independent and identically distributed, so mean_p (e_p - t_p) has standard error
    // sd(e - t) / sqrt(P) (measured on the pixels); 5 of it is the noise allowance. Its mean
    // is not quite 0: E[t_p] = Var(x) / (ref^2 + eps) exactly and E[v_p] = Var(x), but e_p
    // divides by x^2 rather than ref^2. With x = ref (1 + d), 1 / (x^2 + eps) =
    // (1 - 2 r d + O(d^2)) / (ref^2 + eps), r = ref^2 / (ref^2 + eps) <= 1, so the relative
    // bias is at most ~4 E[d^2] (~4 R, R the relative MSE) plus the covariance term
    // 2 Cov(v_p, d) / Var(x) = 2 g sqrt(Var(x) / ref^2) / sqrt(N) ~ 2 |g| sqrt(R / N), g the
    // skewness of one sample, which is sqrt(N) times the skewness of the pixel means (measured
    // here; 1 is added for its own noise). Bound: 5 standard errors plus that bias.
    let scene = furnace(96, 256);
    let r = render(&scene, 16, Some(1e-12));
    let s = &r.stats;
    assert_eq!(
        (s.spp, s.batches, s.target_reached),
        (256, Some(16), Some(false))
    );
    let estimate = s.estimated_error.expect("16 batches give an estimate");
    // The reference image in f32, as `relative_mse` takes it (and t_p below uses it too).
    let exact = exact().as_vec3();
    let reference = vec![exact.to_array(); r.pixels.len()];
    let exact = exact.as_dvec3();
    let truth = raylume_post::relative_mse(&r.pixels, &reference).unwrap();

    // The same estimate, recomputed here from the batches' sums, per pixel.
    let rounds = round_sums(&scene, 16);
    assert_eq!(rounds.len(), 16);
    let e = estimates_per_pixel(&rounds).pop().unwrap().unwrap();
    assert!(
        close(mean(&e), estimate, 1e-9),
        "recomputed {} vs the tracer's {estimate}",
        mean(&e)
    );
    let t: Vec<f64> = r
        .pixels
        .iter()
        .map(|x| {
            (0..3)
                .map(|c| (f64::from(x[c]) - exact[c]).powi(2) / (exact[c] * exact[c] + EPS))
                .sum::<f64>()
                / 3.0
        })
        .collect();
    assert!(close(mean(&t), truth, 1e-9), "{} vs {truth}", mean(&t));
    let d: Vec<f64> = e.iter().zip(&t).map(|(e, t)| e - t).collect();
    let se = sd(&d) / (d.len() as f64).sqrt();
    // Skewness of the pixel means (blue channel; the channels are proportional).
    let xs: Vec<f64> = r.pixels.iter().map(|p| f64::from(p[2])).collect();
    let (mx, sx) = (mean(&xs), sd(&xs));
    let skew = xs.iter().map(|x| ((x - mx) / sx).powi(3)).sum::<f64>() / xs.len() as f64;
    let n = 256.0f64;
    let g = skew.abs() * n.sqrt() + 1.0;
    let bias = truth * (4.0 * truth + 2.0 * g * (truth / n).sqrt());
    let bound = 5.0 * se + bias;
    eprintln!(
        "estimate {estimate:.4e}, true relative MSE {truth:.4e} (ratio {:.3}); bound {bound:.2e} \
         (5 se {:.2e} + bias {bias:.2e}, sample skewness {g:.2})",
        estimate / truth,
        5.0 * se
    );
    assert!(truth > 0.0 && estimate > 0.0);
    assert!(
        (estimate - truth).abs() <= bound,
        "estimate {estimate:.4e} vs true {truth:.4e}: off by more than {bound:.2e}"
    );
    // The bound is tight enough to mean something: within 12 % of the truth (a variance off
    // by the factor B - 1 / B of a biased estimator, 6 %, would not be caught; a missing
    // division by the number of batches, 16x, or by the samples per batch would).
    assert!(bound < 0.12 * truth, "bound {bound:.2e} vs {truth:.2e}");
}

#[test]
fn the_render_stops_at_the_first_batch_whose_estimate_is_below_the_target() {
    // 32x32 pixels, batches of 2 samples, a cap of 64: the estimates after every batch,
    // recomputed here, pick the target (just above the 7th estimate) and where the render
    // must stop: the first batch (from the 2nd on) whose estimate is below it.
    let (batch, cap) = (2, 64);
    let scene = furnace(32, cap);
    let rounds = round_sums(&scene, batch);
    let est: Vec<Option<f64>> = estimates_per_pixel(&rounds)
        .into_iter()
        .map(|e| e.map(|e| mean(&e)))
        .collect();
    let target = (est[6].unwrap() * (1.0 + 1e-4)) as f32;
    let t = f64::from(target);
    let first = est
        .iter()
        .position(|e| e.is_some_and(|e| e < t))
        .expect("the 7th is below")
        + 1;
    assert!(
        est.iter().flatten().all(|e| !close(*e, t, 1e-7)),
        "no estimate within rounding of the target: {est:?}"
    );
    eprintln!("estimates {est:?}; target {target:e}: stop after batch {first}");
    assert!(first >= 2);

    let r = render(&scene, batch, Some(target));
    let s = &r.stats;
    assert_eq!(s.batches, Some(first as u32), "{s:?}");
    assert_eq!(s.spp, first as u32 * batch);
    assert_eq!(s.spp_cap, Some(cap));
    assert_eq!(s.target_reached, Some(true));
    assert_eq!(s.target_error, Some(target));
    let got = s.estimated_error.unwrap();
    assert!(
        got < t && close(got, est[first - 1].unwrap(), 1e-9),
        "{got}"
    );

    // Bit for bit the render of the samples it traced.
    let plain = render(&furnace(32, first as u32 * batch), batch, None);
    assert_eq!(plain.stats.target_error, None);
    assert_eq!(plain.stats.estimated_error, None);
    assert!(
        r.pixels == plain.pixels,
        "the stopped render differs from a {}-spp render",
        s.spp
    );
    assert_eq!(r.stats.rays_traced, plain.stats.rays_traced);
}

#[test]
fn an_unreachable_target_stops_at_the_cap_and_says_so() {
    // 12 spp (not a power of 2: dividing by it differs from multiplying by its reciprocal,
    // so the comparison below sees the very arithmetic of the division).
    let scene = furnace(16, 12);
    let r = render(&scene, 4, Some(1e-9));
    let s = &r.stats;
    assert_eq!(
        (s.spp, s.spp_cap, s.batches, s.target_reached),
        (12, Some(12), Some(3), Some(false))
    );
    assert!(s.estimated_error.is_some_and(|e| e > 1e-9), "{s:?}");
    // The whole capped render, bit for bit (the hooked loop divides the sums itself).
    assert!(r.pixels == render(&scene, 4, None).pixels);

    // A cap of one batch: no estimate can exist, the render runs to the cap and says so.
    let one = render(&furnace(16, 4), 4, Some(1e-3));
    let s = &one.stats;
    assert_eq!(
        (s.spp, s.batches, s.target_reached, s.estimated_error),
        (4, Some(1), Some(false), None)
    );
}

#[test]
fn a_target_that_is_not_a_positive_finite_number_is_a_typed_error() {
    let scene = furnace(4, 4);
    for bad in [0.0, -0.0, -1e-3, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let err = tracer(2, Some(bad)).render(&scene).unwrap_err();
        assert!(
            matches!(err, Error::TargetError(v) if v.to_bits() == bad.to_bits()),
            "{bad}: {err:?}"
        );
        assert!(
            err.to_string().contains("target error") && err.to_string().contains("above 0"),
            "{err}"
        );
    }
    // The smallest positive one is fine.
    assert!(tracer(2, Some(f32::MIN_POSITIVE)).render(&scene).is_ok());
}

#[test]
fn on_the_gpu_the_target_stops_where_the_cpu_does() {
    if raylume_gpu::testing::context_or_skip("on_the_gpu_the_target_stops_where_the_cpu_does")
        .is_none()
    {
        return;
    }
    // The GPU traces the same paths (up to rounding, which may flip a rare roulette decision),
    // so its estimates match the CPU's to far better than the 1e-3 margin kept here between
    // every estimate and the target: it must stop after the same batch, with the same image
    // to rounding.
    let (batch, cap) = (4, 32);
    let scene = furnace(16, cap);
    let est: Vec<f64> = estimates_per_pixel(&round_sums(&scene, batch))
        .into_iter()
        .flatten()
        .map(|e| mean(&e))
        .collect();
    let target = (est[2] * 1.01) as f32;
    assert!(
        est.iter().all(|e| !close(*e, f64::from(target), 1e-3)),
        "{est:?} vs {target}"
    );
    let cpu = render(&scene, batch, Some(target));
    let mut t = tracer(batch, Some(target));
    t.backend = Backend::Gpu;
    let gpu = t.render(&scene).unwrap();
    assert_eq!(gpu.stats.backend, "gpu");
    let (c, g) = (&cpu.stats, &gpu.stats);
    assert_eq!(c.target_reached, Some(true));
    assert_eq!(
        (g.spp, g.batches, g.target_reached),
        (c.spp, c.batches, c.target_reached)
    );
    let (ce, ge) = (c.estimated_error.unwrap(), g.estimated_error.unwrap());
    assert!(close(ce, ge, 1e-3), "CPU {ce} vs GPU {ge}");
    let rel = raylume_post::relative_mse(&gpu.pixels, &cpu.pixels).unwrap();
    assert!(rel < 1e-6, "relative MSE between the backends {rel}");
}
