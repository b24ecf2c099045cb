//! Next-event estimation is unbiased and pays: on the CPU mirror (the GPU traces the same
//! paths: `cpu_vs_gpu.rs`), its image converges to the plain estimator's, and at equal
//! samples it is much closer to a converged reference.

mod support;

use raylume_kernels::{CpuTracer, Estimator, Schedule, TraceSettings};
use raylume_scene::Scene;
use support::*;

fn render(scene: &Scene, estimator: Estimator, spp: u32, seed: u32) -> Vec<[f32; 3]> {
    render_sized(scene, estimator, 8, spp, seed)
}

fn render_sized(
    scene: &Scene,
    estimator: Estimator,
    size: u32,
    spp: u32,
    seed: u32,
) -> Vec<[f32; 3]> {
    let s = TraceSettings {
        seed,
        ..settings(size, size, spp, 4, Schedule::Megakernel)
    };
    let mut t = CpuTracer::new(scene, &bvh(scene)).unwrap();
    t.set_estimator(estimator);
    t.render(&s, &mut |_, _| {}).unwrap().radiance
}

/// Per channel: the mean over `seeds` independent renders of the image mean, and its
/// standard error.
fn estimate(scene: &Scene, estimator: Estimator, spp: u32, seeds: u32) -> [(f64, f64); 3] {
    let means: Vec<[f64; 3]> = (0..seeds)
        .map(|k| mean(&render(scene, estimator, spp, 100 + k)))
        .collect();
    std::array::from_fn(|c| {
        let n = f64::from(seeds);
        let m = means.iter().map(|x| x[c]).sum::<f64>() / n;
        let var = means.iter().map(|x| (x[c] - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    })
}

#[test]
fn next_event_estimation_converges_to_the_plain_estimate() {
    // The box seen from above its floor, the light out of view: all its light is the lamp's,
    // direct or bounced (in the full view, the lamp's own pixels would dominate the mean).
    let mut floor_view = cornell_box();
    floor_view.camera.position = glam::Vec3::new(0.0, 1.6, 0.9);
    floor_view.camera.look_at = glam::Vec3::new(0.0, 0.0, -0.2);
    // The same view with glossy materials, where the light samples are weighed against
    // microfacet sampling: a rough plastic floor, smooth plastic walls, rough gold boxes.
    let mut glossy_view = floor_view.clone();
    let au = raylume_scene::conductor_ior("Au").unwrap();
    glossy_view.materials[0] =
        raylume_scene::Material::conductor("gold", au.0, au.1, glam::Vec3::ONE, 0.5);
    glossy_view.materials[1] =
        raylume_scene::Material::plastic("red", glam::Vec3::new(0.65, 0.05, 0.05), 1.5, 0.0);
    glossy_view.materials[2] =
        raylume_scene::Material::plastic("green", glam::Vec3::new(0.12, 0.45, 0.15), 1.5, 0.3);
    // Floor, ceiling and back wall are the first 6 triangles (material 0): the floor (2)
    // becomes a rough plastic of its own.
    glossy_view.materials.push(raylume_scene::Material::plastic(
        "floor",
        glam::Vec3::splat(0.73),
        1.5,
        0.3,
    ));
    let floor_material = glossy_view.materials.len() as u32 - 1;
    for t in &mut glossy_view.triangles[..2] {
        t.material = floor_material;
    }
    let glossy = glossy_view.features();
    for f in [
        raylume_scene::Feature::Plastic,
        raylume_scene::Feature::RoughMetal,
    ] {
        assert!(glossy.contains(f), "{f:?}");
    }
    // The glossy box's plain estimate is heavy-tailed (rare paths that find the lamp through
    // the gold): 8 renders of 1024 spp underestimated its spread (seen 4.9 of their standard
    // errors apart, but 0.9 apart with 32 renders of 4096), so it gets 16 renders of 4096.
    for (name, scene, plain_spp, seeds) in [
        ("cornell box floor", floor_view, 1024, 8),
        ("glossy box floor", glossy_view, 4096, 16),
        ("spheres", spheres(), 1024, 8),
    ] {
        let plain = estimate(&scene, Estimator::Plain, plain_spp, seeds);
        let nee = estimate(&scene, Estimator::Nee, 256, seeds);
        for c in 0..3 {
            let ((mp, sp), (mn, sn)) = (plain[c], nee[c]);
            let se = (sp * sp + sn * sn).sqrt();
            eprintln!("{name} channel {c}: plain {mp:.5} ± {sp:.5}, nee {mn:.5} ± {sn:.5}");
            // Both estimate the same integral: their difference is noise, whose standard
            // deviation `se` is measured from 8 (16) independent renders each. Five of those (a
            // 1-in-3-million chance for a Gaussian) plus 0.5 % of the value leaves no room
            // for a missing, doubled or misweighted light: direct light is most of the box's
            // image.
            assert!(
                (mn - mp).abs() < 5.0 * se + 0.005 * mp,
                "{name} channel {c}: nee {mn} vs plain {mp} (standard error {se})"
            );
        }
    }
}

#[test]
fn next_event_estimation_has_less_noise_at_equal_samples() {
    let scene = cornell_box();
    let reference = render_sized(&scene, Estimator::Nee, 24, 2048, 1);
    let plain = render_sized(&scene, Estimator::Plain, 24, 64, 2);
    let nee = render_sized(&scene, Estimator::Nee, 24, 64, 2);
    // The lit surfaces only: a pixel that sees part of the light itself (radiance 17) is as
    // noisy either way (where in the pixel the light's edge falls), and would dominate.
    let lit: Vec<usize> = (0..reference.len())
        .filter(|&i| reference[i].iter().all(|&c| c < 1.0))
        .collect();
    let pick = |img: &[[f32; 3]]| lit.iter().map(|&i| img[i]).collect::<Vec<_>>();
    let (e_plain, e_nee) = (
        relative_rmse(&pick(&plain), &pick(&reference)),
        relative_rmse(&pick(&nee), &pick(&reference)),
    );
    eprintln!(
        "64 spp against 2048, {} of {} pixels: plain {e_plain:.4}, nee {e_nee:.4}",
        lit.len(),
        reference.len()
    );
    // A small ceiling light over diffuse walls: most plain paths never reach it, every NEE
    // hit samples it. Measured: a third of plain's error (a ninth of its MSE). Not all of
    // the error is the light's: where in each pixel a sample lands (box and shadow edges)
    // is as noisy for both, so the bound asks for half. The reference's own noise (2048 spp,
    // NEE) is under a tenth of plain's 64-spp error and cannot make up the difference.
    assert!(
        lit.len() * 10 > reference.len() * 9,
        "most pixels are lit surfaces"
    );
    assert!(e_nee * 2.0 < e_plain, "plain {e_plain}, nee {e_nee}");
}

/// The red channel's image mean of 16 one-bounce 8x8 renders (seeds `seed0..seed0 + 16`) of
/// `scene` at `spp`, and its standard error.
fn one_bounce_stats(scene: &Scene, estimator: Estimator, spp: u32, seed0: u32) -> (f64, f64) {
    let v: Vec<f64> = (0..16)
        .map(|k| {
            let s = TraceSettings {
                seed: seed0 + k,
                ..settings(8, 8, spp, 1, Schedule::Megakernel)
            };
            let mut t = CpuTracer::new(scene, &bvh(scene)).unwrap();
            t.set_estimator(estimator);
            mean(&t.render(&s, &mut |_, _| {}).unwrap().radiance)[0]
        })
        .collect();
    let m = v.iter().sum::<f64>() / 16.0;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 15.0;
    (m, (var / 16.0).sqrt())
}

#[test]
fn next_event_estimation_on_glossy_floors_converges_to_the_plain_estimate() {
    // Direct light only (one bounce, black sky): a lamp above a glossy floor whose highlight
    // the camera sees, where the light samples and the microfacet samples overlap most. The
    // multiple-importance weights of the two must sum to one for every direction: a missing
    // weight counts the highlight twice, a wrong pdf shifts it. 16 renders each give the
    // standard errors; 5 of them, with no slack, is the bound (the plain estimate of a
    // one-bounce scene has light tails).
    let au = raylume_scene::conductor_ior("Au").unwrap();
    let g = glam::Vec3::splat(0.7);
    for floor in [
        raylume_scene::Material::plastic("rough plastic", g, 1.5, 0.2),
        raylume_scene::Material::plastic("smooth plastic", g, 1.5, 0.0),
        raylume_scene::Material::conductor("rough gold", au.0, au.1, glam::Vec3::ONE, 0.2),
    ] {
        let name = floor.name.clone();
        let mut triangles = flat_quad(
            glam::Vec3::new(-2.0, 0.0, 2.0),
            glam::Vec3::new(4.0, 0.0, 0.0),
            glam::Vec3::new(0.0, 0.0, -4.0),
            0,
        )
        .to_vec();
        // A large, low lamp facing down (u x v = -y): close to the floor its solid angle is
        // wide, so the microfacet samples carry much of the MIS weight there.
        triangles.extend(flat_quad(
            glam::Vec3::new(-0.75, 0.5, -1.5),
            glam::Vec3::new(1.5, 0.0, 0.0),
            glam::Vec3::new(0.0, 0.0, 1.5),
            1,
        ));
        let scene = raylume_scene::Scene {
            camera: raylume_scene::Camera::looking_at(
                glam::Vec3::new(0.0, 0.4, 1.5),
                glam::Vec3::new(0.0, 0.0, -0.5),
                40.0,
            ),
            materials: vec![
                floor,
                raylume_scene::Material::emissive("lamp", glam::Vec3::splat(4.0)),
            ],
            triangles,
            ..Default::default()
        };
        let stats = |estimator, spp| one_bounce_stats(&scene, estimator, spp, 200);
        let ((mp, sp), (mn, sn)) = (stats(Estimator::Plain, 1024), stats(Estimator::Nee, 256));
        let se = (sp * sp + sn * sn).sqrt();
        eprintln!("{name}: plain {mp:.5} ± {sp:.5}, nee {mn:.5} ± {sn:.5}");
        assert!(mp > 0.0, "{name}: the floor is lit");
        assert!(
            (mn - mp).abs() < 5.0 * se,
            "{name}: nee {mn} vs plain {mp} (standard error {se})"
        );
    }
}

/// A small sphere lamp (radius `r`, radiance `l`) at height `h` over a diffuse floor of
/// albedo `rho`, seen at a narrow angle around the floor point `x` off the point below it,
/// direct light only, black sky.
fn sphere_over_floor(r: f32, l: f32, h: f32, rho: f32, x: f32) -> Scene {
    raylume_scene::Scene {
        camera: raylume_scene::Camera::looking_at(
            glam::Vec3::new(x + 1.0, 0.8, 0.6),
            glam::Vec3::new(x, 0.0, 0.0),
            1.0,
        ),
        materials: vec![
            raylume_scene::Material::diffuse("floor", glam::Vec3::splat(rho)),
            raylume_scene::Material::emissive("lamp", glam::Vec3::splat(l)),
        ],
        triangles: flat_quad(
            glam::Vec3::new(-50.0, 0.0, 50.0),
            glam::Vec3::new(100.0, 0.0, 0.0),
            glam::Vec3::new(0.0, 0.0, -100.0),
            0,
        )
        .to_vec(),
        spheres: vec![raylume_scene::Sphere {
            center: glam::Vec3::new(0.0, h, 0.0),
            radius: r,
            material: 1,
        }],
        ..Default::default()
    }
}

#[test]
fn small_bright_spheres_light_what_they_face_at_a_few_samples() {
    // A sphere of radiance L subtending the cone θmax (sin² θmax = r²/d²) from a floor point
    // d away whose normal makes the angle β with the direction to the centre (wholly above
    // the horizon) gives it the irradiance E = π L sin² θmax cos β, exactly (the sphere's
    // disc of directions is a cap of the hemisphere); a Lambertian floor of albedo ρ sends
    // back ρ E / π = ρ L r² h / d³. The camera sees a patch 1° wide around that point
    // (about 0.02 across at 1.4 away): the value varies across it by under 0.1 %.
    let (r, l, h, rho, x) = (0.02f32, 400.0f32, 1.0f32, 0.5f32, 0.5f32);
    let scene = sphere_over_floor(r, l, h, rho, x);
    let d = (h * h + x * x).sqrt();
    let exact = f64::from(rho * l * r * r * h / (d * d * d));
    let direct = |estimator, spp, seed| {
        let s = TraceSettings {
            seed,
            ..settings(8, 8, spp, 1, Schedule::Megakernel)
        };
        let mut t = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
        t.set_estimator(estimator);
        mean(&t.render(&s, &mut |_, _| {}).unwrap().radiance)[1]
    };
    // 4 samples per pixel, 256 in all. The cap's directions are uniform in the cone and
    // the integrand (cos at the floor, 1 inside the cone) varies across the cone by
    // 2 θmax tan β ~ 4 %, so each NEE sample is within ~4 % of the exact value and their
    // mean within 1 % (the MIS weight of a light this small is 1 to within 1e-5: the
    // floor's cosine pdf of the cone's directions is tiny next to the cap's pdf).
    let nee = direct(Estimator::Nee, 4, 1);
    eprintln!("sphere lamp: exact {exact:.5}, nee at 4 spp {nee:.5}");
    assert!(
        (nee - exact).abs() < 0.01 * exact,
        "nee {nee} vs exact {exact}"
    );
    // The plain estimator finds the lamp with probability ~ sin² θmax cos β (a cosine-
    // sampled direction lands in the cone): 3e-4 here, so 256 samples mostly miss it: the
    // estimate is 0 or one hit's worth, never within 10 % (a hit alone is exact / (256 p)
    // ~ 13x the exact value).
    let plain = direct(Estimator::Plain, 4, 1);
    assert!(
        (plain - exact).abs() > 0.1 * exact,
        "plain {plain} vs exact {exact}"
    );
    // Unbiased where the strategies overlap: a large sphere close to the floor (sin² θmax
    // = 0.33 from the patch), where the floor's own samples find it often and the MIS
    // weights matter. Both estimators against the exact value, 5 standard errors measured
    // over 16 renders (the exact value has no error).
    let (r, h) = (0.5f32, 0.7f32);
    let scene = sphere_over_floor(r, 2.0, h, rho, x);
    let d = (h * h + x * x).sqrt();
    let exact = f64::from(rho * 2.0 * r * r * h / (d * d * d));
    for (estimator, spp) in [(Estimator::Nee, 16), (Estimator::Plain, 64)] {
        let v: Vec<f64> = (0..16)
            .map(|k| {
                let s = TraceSettings {
                    seed: 300 + k,
                    ..settings(8, 8, spp, 1, Schedule::Megakernel)
                };
                let mut t = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
                t.set_estimator(estimator);
                mean(&t.render(&s, &mut |_, _| {}).unwrap().radiance)[1]
            })
            .collect();
        let m = v.iter().sum::<f64>() / 16.0;
        let se = (v.iter().map(|y| (y - m).powi(2)).sum::<f64>() / 15.0 / 16.0).sqrt();
        eprintln!("large sphere lamp, {estimator:?}: {m:.5} ± {se:.5}, exact {exact:.5}");
        assert!(
            (m - exact).abs() < 5.0 * se + 1e-3 * exact,
            "{estimator:?}: {m} vs {exact}"
        );
    }
}

#[test]
fn next_event_estimation_through_rough_glass_converges_to_the_plain_estimate() {
    // Direct light only: a camera under a rough glass pane (one interface, normal up) that a
    // lamp above lights. The camera sees the light the pane transmits: NEE's shadow rays leave
    // from behind the pane (`light_side` -1) and are weighed against the transmitted
    // microfacet samples, with the eta² radiance scaling on both. 16 renders each, 5 standard
    // errors. A doubled transmission value (tried) or a shadow ray from the wrong side fails.
    for alpha_roughness in [0.2f32, 0.5] {
        let mut glass = raylume_scene::Material::glass("pane", 1.5, glam::Vec3::splat(0.9));
        glass.roughness = alpha_roughness;
        let mut triangles = flat_quad(
            glam::Vec3::new(-2.0, 0.0, 2.0),
            glam::Vec3::new(4.0, 0.0, 0.0),
            glam::Vec3::new(0.0, 0.0, -4.0),
            0,
        )
        .to_vec();
        triangles.extend(flat_quad(
            glam::Vec3::new(-0.75, 0.6, -0.75),
            glam::Vec3::new(1.5, 0.0, 0.0),
            glam::Vec3::new(0.0, 0.0, 1.5),
            1,
        ));
        let scene = raylume_scene::Scene {
            camera: raylume_scene::Camera::looking_at(
                glam::Vec3::new(0.0, -0.8, 0.3),
                glam::Vec3::new(0.0, 0.0, 0.0),
                50.0,
            ),
            materials: vec![
                glass,
                raylume_scene::Material::emissive("lamp", glam::Vec3::splat(4.0)),
            ],
            triangles,
            ..Default::default()
        };
        assert!(
            scene
                .features()
                .contains(raylume_scene::Feature::RoughGlass)
        );
        let stats = |estimator, spp| one_bounce_stats(&scene, estimator, spp, 400);
        let ((mp, sp), (mn, sn)) = (stats(Estimator::Plain, 1024), stats(Estimator::Nee, 256));
        let se = (sp * sp + sn * sn).sqrt();
        eprintln!("rough glass {alpha_roughness}: plain {mp:.5} ± {sp:.5}, nee {mn:.5} ± {sn:.5}");
        assert!(mp > 0.01, "the pane transmits the lamp's light");
        assert!(
            (mn - mp).abs() < 5.0 * se,
            "rough glass {alpha_roughness}: nee {mn} vs plain {mp} (standard error {se})"
        );
    }
}
