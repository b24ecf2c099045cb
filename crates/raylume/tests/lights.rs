//! The light list a render reports, and the warning for a scene nothing lights.

use std::sync::{Arc, Mutex};

use raylume::glam::Vec3;
use raylume::scene::{Environment, Material, Scene, Sphere, Triangle};
use raylume::{Backend, LightStats, NO_LIGHT_WARNING, Tracer};

fn sphere_scene(material: Material) -> Scene {
    let mut s = Scene::default();
    s.render.width = 8;
    s.render.height = 8;
    s.render.spp = 1;
    s.materials = vec![material];
    s.spheres.push(Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
        material: 0,
    });
    s
}

#[test]
fn unlit_scene_warns_in_the_stats_before_the_first_batch() {
    let scene = sphere_scene(Material::diffuse("white", Vec3::splat(0.5)));
    assert!(LightStats::of(&scene).is_empty());
    let seen: Arc<Mutex<Vec<String>>> = Arc::default();
    let mut t = Tracer::new(Backend::Cpu);
    let s = seen.clone();
    t.on_start(move |stats| s.lock().unwrap().extend(stats.warnings.iter().cloned()));
    let s = seen.clone();
    t.on_progress(move |_| s.lock().unwrap().push("progress".into()));
    let r = t.render(&scene).unwrap();
    assert_eq!(r.stats.warnings, [NO_LIGHT_WARNING]);
    assert!(r.stats.lights.is_empty());
    assert_eq!(
        *seen.lock().unwrap(),
        [NO_LIGHT_WARNING, "progress"],
        "on_start sees the warning before the first batch"
    );
    assert!(
        r.pixels.iter().all(|p| *p == [0.0; 3]),
        "and the image is black"
    );
}

#[test]
fn lit_scenes_do_not_warn_and_count_their_emitters() {
    // An emissive sphere.
    let scene = sphere_scene(Material::emissive("lamp", Vec3::splat(2.0)));
    let r = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    assert!(r.stats.warnings.is_empty(), "{:?}", r.stats.warnings);
    assert_eq!(
        r.stats.lights,
        LightStats {
            triangles: 0,
            spheres: 1,
            environment: false,
            selection: "power"
        }
    );

    // A constant environment lights a diffuse sphere; a zero one does not.
    let mut scene = sphere_scene(Material::diffuse("white", Vec3::splat(0.5)));
    scene.environment = Environment::Constant(Vec3::splat(1.0));
    let r = Tracer::new(Backend::Cpu).render(&scene).unwrap();
    assert!(r.stats.warnings.is_empty(), "{:?}", r.stats.warnings);
    assert!(r.stats.lights.environment);
    scene.environment = Environment::Constant(Vec3::ZERO);
    assert!(LightStats::of(&scene).is_empty());

    // Emissive triangles count; a triangle with a black material does not.
    let mut scene = sphere_scene(Material::diffuse("white", Vec3::splat(0.5)));
    scene
        .materials
        .push(Material::emissive("lamp", Vec3::new(1.0, 0.0, 0.0)));
    let tri = [
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(1.0, 2.0, 0.0),
        Vec3::new(0.0, 2.0, 1.0),
    ];
    scene.triangles.push(Triangle::flat(tri, 1));
    scene.triangles.push(Triangle::flat(tri, 0));
    let lights = LightStats::of(&scene);
    assert_eq!(
        (lights.triangles, lights.spheres, lights.environment),
        (1, 0, false)
    );
    assert_eq!(
        lights.describe(),
        "1 emissive triangle, 0 emissive spheres, no environment (picked by power)"
    );
}
