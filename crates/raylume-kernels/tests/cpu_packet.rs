//! The CPU path's packets (`raylume_kernels::cpu::packet`): scenes of diffuse triangles traced
//! eight or sixteen paths at a time, and scenes of triangles that add other materials (whose
//! other hits the packets finish one lane at a time), render the image of one path at a time
//! bit for bit, at every instruction-set level this CPU executes, with each estimator and
//! sampler, over chunks that end part-way through a lane group; scenes with spheres, textures,
//! shading normals or a sky never take the packets.

mod support;

use glam::Vec3;
use raylume_kernels::{CpuIsa, CpuTracer, Estimator, Sampler, Schedule, TraceSettings};
use raylume_scene::{Material, Scene, Sphere};
use support::*;

/// The Cornell box with its light emitting from both faces, a one-sided light facing the
/// back wall (seen from behind by most of the room) and a dim one on the floor: light
/// selection over several lights, both kinds of emitter, lights hit from behind.
fn lit_box() -> Scene {
    let mut scene = cornell_box();
    scene.materials[3].two_sided = true;
    scene
        .materials
        .push(Material::emissive("blue", Vec3::new(0.5, 1.0, 4.0)));
    scene
        .materials
        .push(Material::emissive("dim", Vec3::splat(0.2)));
    let (blue, dim) = (
        scene.materials.len() as u32 - 2,
        scene.materials.len() as u32 - 1,
    );
    scene.triangles.extend(quad(
        Vec3::new(-0.9, 1.2, -0.5),
        Vec3::new(0.0, 0.3, 0.0),
        Vec3::new(0.0, 0.0, 0.4),
        blue,
    ));
    scene.triangles.extend(flat_quad(
        Vec3::new(0.6, 0.001, 0.5),
        Vec3::new(0.3, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.3),
        dim,
    ));
    // Triangles of every orientation (the box's own normals lie along its axes or in the
    // floor's plane, where a sum's order often cannot show).
    let mut state = 0x9e37_79b9u32;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        (state >> 8) as f32 / 16_777_216.0
    };
    // A sliver (its aspect, extent^2 over twice its area, in the thousands) and a triangle
    // with a zero-length edge (never hit), where the offsets' arithmetic meets its extremes.
    for positions in [
        [
            Vec3::new(-0.9, 0.4, 0.2),
            Vec3::new(0.9, 0.41, 0.25),
            Vec3::new(0.0, 0.4052, 0.226),
        ],
        [
            Vec3::new(0.1, 1.0, 0.1),
            Vec3::new(0.1, 1.0, 0.1),
            Vec3::new(0.3, 1.2, 0.0),
        ],
    ] {
        scene.triangles.push(raylume_scene::Triangle {
            positions,
            normals: None,
            uvs: None,
            material: 2,
        });
    }
    for _ in 0..24 {
        let c = Vec3::new(next() * 1.6 - 0.8, next() * 1.6 + 0.2, next() * 1.6 - 0.8);
        let mut v = || c + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.5;
        let (a, b, d) = (v(), v(), v());
        scene.triangles.push(raylume_scene::Triangle {
            positions: [a, b, d],
            normals: None,
            uvs: None,
            material: 1,
        });
    }
    scene
}

/// The lit box with what the packets shade one lane at a time: triangles of every material
/// the variant adds (a mirror, rough metal, smooth and rough glass, smooth and rough plastic)
/// among its diffuse ones.
fn lit_box_of_materials() -> Scene {
    let mut scene = lit_box();
    let first = scene.materials.len() as u32;
    scene.materials.extend([
        Material::metal("mirror", Vec3::new(0.95, 0.9, 0.8), 0.0),
        Material::metal("brushed", Vec3::new(0.9, 0.6, 0.3), 0.3),
        Material::glass("glass", 1.5, Vec3::ONE),
        Material {
            roughness: 0.3,
            ..Material::glass("frosted", 1.5, Vec3::new(0.9, 1.0, 0.9))
        },
        Material::plastic("plastic", Vec3::new(0.8, 0.2, 0.1), 1.5, 0.2),
        Material::plastic("lacquer", Vec3::new(0.1, 0.5, 0.2), 1.5, 0.0),
    ]);
    // A mirror quad on the left wall, and a tilted quad of each other material in the room.
    scene.triangles.extend(quad(
        Vec3::new(-0.98, 0.3, -0.7),
        Vec3::new(0.0, 0.9, 0.0),
        Vec3::new(0.0, 0.0, 0.9),
        first,
    ));
    for (k, m) in (1..6).enumerate() {
        let x = -0.7 + 0.32 * k as f32;
        scene.triangles.extend(quad(
            Vec3::new(x, 0.2 + 0.25 * k as f32, 0.3),
            Vec3::new(0.25, 0.05, -0.1),
            Vec3::new(0.02, 0.3, 0.2),
            first + m,
        ));
    }
    scene
}

fn bits(out: &raylume_kernels::TraceOutput) -> Vec<[u32; 3]> {
    out.radiance.iter().map(|p| p.map(f32::to_bits)).collect()
}

#[test]
fn packets_render_the_one_path_image_bit_for_bit_at_every_level() {
    let levels: Vec<CpuIsa> = CpuIsa::ALL.into_iter().filter(|i| i.available()).collect();
    let runs = [
        (Estimator::Nee, Sampler::Sobol, Some(3)),
        (Estimator::Nee, Sampler::ZSobol, Some(0)),
        (Estimator::Nee, Sampler::Independent, None),
        (Estimator::Plain, Sampler::Independent, Some(2)),
    ];
    // 2,520 paths a batch: one full chunk of the packet schedule and one that ends part-way
    // through a group of lanes; 5 bounces, then 0 (the camera segment alone).
    let sizes = [
        settings(45, 28, 2, 5, Schedule::Persistent),
        settings(13, 7, 3, 0, Schedule::Megakernel),
    ];
    for (name, scene) in [
        ("cornell", cornell_box()),
        ("lit box", lit_box()),
        ("lit box of materials", lit_box_of_materials()),
    ] {
        let bvh = bvh(&scene);
        let mut tracer = CpuTracer::new(&scene, &bvh).unwrap();
        assert!(
            tracer.packets(),
            "{name}: a scene of triangles without textures or sky takes the packets"
        );
        // A tree of a few dozen triangles is tested flat wherever the walks have AVX.
        #[cfg(target_arch = "x86_64")]
        {
            let limit = if tracer.isa() >= CpuIsa::X86_64V4 {
                raylume_bvh::FLAT_MAX_PRIMITIVES
            } else {
                raylume_bvh::FLAT_MAX_PRIMITIVES_AVX2
            };
            let flat = tracer.isa() >= CpuIsa::X86_64V3 && bvh.primitives.len() <= limit;
            let n = bvh.primitives.len();
            assert_eq!(tracer.walks_flat(), flat, "{name}: {n}, {:?}", tracer.isa());
            if name == "cornell" {
                assert_eq!(flat, tracer.isa() >= CpuIsa::X86_64V3, "{name}: {n}");
            }
        }
        for &(estimator, sampler, roulette) in &runs {
            tracer.set_estimator(estimator);
            tracer.set_sampler(sampler);
            tracer.set_russian_roulette(roulette);
            for s in &sizes {
                tracer.set_isa(CpuIsa::Build);
                tracer.set_packets(false);
                let one = tracer.render(s, &mut |_, _| {}).unwrap();
                let want = bits(&one);
                assert!(one.rays_traced > 0);
                tracer.set_packets(true);
                for &isa in &levels {
                    tracer.set_isa(isa);
                    let out = tracer.render(s, &mut |_, _| {}).unwrap();
                    let differ = bits(&out).iter().zip(&want).filter(|(a, b)| a != b).count();
                    assert_eq!(
                        differ, 0,
                        "{name} {estimator:?} {sampler:?} {}x{} at {isa:?}: {differ} pixels \
                         differ from one path at a time",
                        s.width, s.height
                    );
                    assert_eq!(out.rays_traced, one.rays_traced, "{name} at {isa:?}: rays");
                    assert_eq!(out.dropped_samples, one.dropped_samples);
                }
            }
        }
    }
}

#[test]
fn a_render_part_through_packets_is_the_same_part() {
    let scene = lit_box();
    let bvh = bvh(&scene);
    let mut tracer = CpuTracer::new(&scene, &bvh).unwrap();
    tracer.set_estimator(Estimator::Nee);
    tracer.set_sampler(Sampler::Sobol);
    tracer.set_sample_range(Some(1..3));
    let s: TraceSettings = settings(20, 12, 4, 4, Schedule::Persistent);
    tracer.set_packets(false);
    let one = tracer.render(&s, &mut |_, _| {}).unwrap();
    tracer.set_packets(true);
    let packed = tracer.render(&s, &mut |_, _| {}).unwrap();
    assert_eq!(bits(&packed), bits(&one));
}

#[test]
fn scenes_with_spheres_textures_or_a_sky_are_traced_one_path_at_a_time() {
    for (name, scene) in [
        ("spheres", spheres()),
        ("materials", materials()),
        ("textured", textured()),
        ("environment", environment_lit()),
        ("lit box and a sphere", {
            let mut scene = lit_box();
            scene.spheres.push(Sphere {
                center: Vec3::new(0.3, 0.3, 0.4),
                radius: 0.2,
                material: 1,
            });
            scene
        }),
    ] {
        let tracer = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
        assert!(!tracer.packets(), "{name}");
    }
    // And a scene of diffuse triangles when told so, or specialised on nothing.
    let scene = cornell_box();
    let mut tracer = CpuTracer::new(&scene, &bvh(&scene)).unwrap();
    tracer.set_packets(false);
    assert!(!tracer.packets());
    tracer.set_packets(true);
    tracer.set_specialisation(
        raylume_kernels::Specialisation::Generic,
        raylume_scene::Features::NONE,
    );
    assert!(!tracer.packets(), "the generic variant has every feature");
}
