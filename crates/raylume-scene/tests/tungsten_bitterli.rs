//! Bitterli's two Tungsten scenes (`../shared/scenes-external`; skipped visibly when absent,
//! a failure under `RAYLUME_REQUIRE_EXTERNAL=1`), checked against numbers obtained without the
//! importer: the Cornell box from its JSON by hand and by composing glam rotations here, the
//! living room by reading its OBJ files line by line here.

mod common;

use std::path::Path;

use common::{TempDir, shared_external};
use glam::{DMat4, DVec3, Vec3};
use raylume_scene::{Environment, FovAxis, MaterialKind, Scene, SceneError};
use serde_json::Value;

fn dvec3(v: &Value) -> DVec3 {
    match v {
        Value::Array(a) => DVec3::new(
            a[0].as_f64().unwrap(),
            a[1].as_f64().unwrap(),
            a[2].as_f64().unwrap(),
        ),
        n => DVec3::splat(n.as_f64().unwrap()),
    }
}

/// Tungsten's transform object as T * Ry(-y) * Rx(x) * Rz(z) * S, composed from glam's own
/// rotation matrices (the importer copies Tungsten's closed-form matrix term by term instead).
fn tungsten_matrix(t: &Value) -> DMat4 {
    let pos = t.get("position").map_or(DVec3::ZERO, dvec3);
    let scale = t.get("scale").map_or(DVec3::ONE, dvec3);
    let r = t.get("rotation").map_or(DVec3::ZERO, dvec3);
    DMat4::from_translation(pos)
        * DMat4::from_rotation_y(-r.y.to_radians())
        * DMat4::from_rotation_x(r.x.to_radians())
        * DMat4::from_rotation_z(r.z.to_radians())
        * DMat4::from_scale(scale)
}

/// Every vertex of the triangles with material `name`, deduplicated to 1e-5.
fn vertices_of(s: &Scene, name: &str) -> Vec<Vec3> {
    let m = s
        .materials
        .iter()
        .position(|m| m.name == name)
        .unwrap_or_else(|| panic!("{name}")) as u32;
    let mut out: Vec<Vec3> = Vec::new();
    for t in s.triangles.iter().filter(|t| t.material == m) {
        for p in t.positions {
            if !out.iter().any(|q| (*q - p).abs().max_element() < 1e-5) {
                out.push(p);
            }
        }
    }
    out
}

fn same_set(a: &[Vec3], b: &[Vec3]) -> bool {
    a.len() == b.len()
        && a.iter()
            .all(|p| b.iter().any(|q| (*p - *q).abs().max_element() < 1e-5))
}

#[test]
fn cornell_box() {
    let Some(path) = shared_external("bitterli-cornell-box/scene.json", "cornell_box") else {
        return;
    };
    let s = Scene::load(&path).unwrap();
    // 6 quads x 2 + 2 cubes x 12.
    assert_eq!(s.triangles.len(), 36);
    assert_eq!(s.spheres.len(), 0);
    // 8 BSDFs, each used once; the light's null BSDF carries the emission.
    assert_eq!(s.materials.len(), 8);
    // By hand: the floor is the unit quad scaled to 2 x 2 (x and z), turned 90 degrees about y
    // (still the square [-1,1]^2) at y = 0; the ceiling the same at y = 2; the back wall at
    // z = -1 and the side walls at x = +-1 span y in [0, 2]. Everything else is inside.
    let b = s.bounds();
    assert_eq!(
        (b.min, b.max),
        (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0))
    );

    // The light: scale (0.47, _, 0.38) makes a 0.47 x 0.38 rectangle; rotation (0, 180, 180)
    // maps (x, z) to (x, -z) and +y to -y, so it is centred at (-0.005, 1.98, -0.03), faces
    // down, and has corners x in {-0.24, 0.23}, z in {-0.22, 0.16}.
    let light = s.materials.iter().find(|m| m.name == "Light").unwrap();
    assert_eq!(
        (light.emission, light.albedo, light.two_sided),
        (Vec3::new(17.0, 12.0, 4.0), Vec3::ZERO, false)
    );
    let want: Vec<Vec3> = [(-0.24, -0.22), (-0.24, 0.16), (0.23, -0.22), (0.23, 0.16)]
        .map(|(x, z)| Vec3::new(x, 1.98, z))
        .to_vec();
    assert!(
        same_set(&vertices_of(&s, "Light"), &want),
        "{:?}",
        vertices_of(&s, "Light")
    );
    for t in s
        .triangles
        .iter()
        .filter(|t| s.materials[t.material as usize].name == "Light")
    {
        let [a, b, c] = t.positions;
        assert!(
            (b - a).cross(c - a).normalize().abs_diff_eq(-Vec3::Y, 1e-6),
            "the light faces down"
        );
    }

    // Every quad and cube against glam's composition of Tungsten's transform, corners and
    // facing; the boxes also stand on the floor (z scale 0.6 / 1.2 turned onto y by Rx(90),
    // centred at y = 0.3 / 0.6).
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    for p in doc["primitives"].as_array().unwrap() {
        let m = tungsten_matrix(&p["transform"]);
        let name = p["bsdf"].as_str().unwrap();
        let unit: Vec<DVec3> = match p["type"].as_str().unwrap() {
            "quad" => vec![(-0.5, -0.5), (-0.5, 0.5), (0.5, -0.5), (0.5, 0.5)]
                .into_iter()
                .map(|(x, z)| DVec3::new(x, 0.0, z))
                .collect(),
            _ => (0..8)
                .map(|i| {
                    DVec3::new(
                        [-0.5, 0.5][i & 1],
                        [-0.5, 0.5][(i >> 1) & 1],
                        [-0.5, 0.5][i >> 2],
                    )
                })
                .collect(),
        };
        let want: Vec<Vec3> = unit
            .iter()
            .map(|u| m.transform_point3(*u).as_vec3())
            .collect();
        assert!(same_set(&vertices_of(&s, name), &want), "{name}");
        if p["type"] == "quad" {
            let front = m
                .transform_vector3(DVec3::Z)
                .cross(m.transform_vector3(DVec3::X))
                .normalize()
                .as_vec3();
            for t in s
                .triangles
                .iter()
                .filter(|t| s.materials[t.material as usize].name == name)
            {
                let [a, b, c] = t.positions;
                assert!(
                    (b - a).cross(c - a).normalize().dot(front) > 0.9999,
                    "{name} faces Tungsten's front"
                );
            }
        } else {
            let ys: Vec<f32> = vertices_of(&s, name).iter().map(|v| v.y).collect();
            let top = if name == "TallBox" { 1.2 } else { 0.6 };
            assert!(
                ys.iter().all(|y| y.abs() < 1e-6 || (y - top).abs() < 1e-6),
                "{name}: {ys:?}"
            );
        }
    }
    let albedo = |n: &str| s.materials.iter().find(|m| m.name == n).unwrap().albedo;
    assert_eq!(albedo("LeftWall"), Vec3::new(0.63, 0.065, 0.05));
    assert_eq!(albedo("RightWall"), Vec3::new(0.14, 0.45, 0.091));

    // Pinhole camera; 1024 x 1024 makes the horizontal fov 19.5 also the vertical one.
    let c = s.camera;
    assert_eq!(
        (c.position, c.look_at, c.up),
        (Vec3::new(0.0, 1.0, 6.8), Vec3::new(0.0, 1.0, 0.0), Vec3::Y)
    );
    assert_eq!((c.fov, c.fov_axis), (19.5, FovAxis::Horizontal));
    assert_eq!(
        (
            s.render.width,
            s.render.height,
            s.render.spp,
            s.render.max_bounces
        ),
        (1024, 1024, 16, 64)
    );
    assert!(
        s.warnings
            .iter()
            .any(|w| w == "material 'Light': Tungsten 'null' approximated as black diffuse"),
        "{:?}",
        s.warnings
    );
}

/// The living room's mesh primitives: (OBJ path relative to the scene, translation).
fn living_room_meshes(scene_json: &Path) -> Vec<(String, Vec3)> {
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(scene_json).unwrap()).unwrap();
    doc["primitives"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            assert_eq!(p["type"], "mesh");
            let pos = p["transform"]
                .get("position")
                .map_or(DVec3::ZERO, dvec3)
                .as_vec3();
            (p["file"].as_str().unwrap().to_string(), pos)
        })
        .collect()
}

/// Reads every OBJ line by line: (triangles after fan triangulation, degenerate ones among
/// them after translation in f32: zero or non-finite cross product, bounds of the rest).
fn count_obj_triangles(dir: &Path, meshes: &[(String, Vec3)]) -> (usize, usize, Vec3, Vec3) {
    let (mut total, mut degenerate) = (0, 0);
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for (file, offset) in meshes {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        let mut v: Vec<Vec3> = Vec::new();
        for line in text.lines() {
            let mut w = line.split_whitespace();
            match w.next() {
                Some("v") => {
                    let c: Vec<f32> = w.take(3).map(|x| x.parse().unwrap()).collect();
                    v.push(Vec3::new(c[0], c[1], c[2]) + *offset);
                }
                Some("f") => {
                    let idx: Vec<usize> = w
                        .map(|t| t.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                        .collect();
                    for k in 1..idx.len() - 1 {
                        total += 1;
                        let (a, b, c) = (v[idx[0]], v[idx[k]], v[idx[k + 1]]);
                        let n = (b - a).cross(c - a).length();
                        if n.is_nan() || n <= 0.0 || !n.is_finite() {
                            degenerate += 1;
                        } else {
                            for p in [a, b, c] {
                                lo = lo.min(p);
                                hi = hi.max(p);
                            }
                        }
                    }
                }
                _ => {}
            }
        }
    }
    (total, degenerate, lo, hi)
}

#[cfg(unix)]
fn stand_in_copy(original: &Path, leaf: bool, sky: bool) -> TempDir {
    use std::os::unix::fs::symlink;
    let d = TempDir::new("livingroom");
    std::fs::copy(original.join("scene.json"), d.path("scene.json")).unwrap();
    symlink(original.join("models"), d.path("models")).unwrap();
    std::fs::create_dir(d.path("textures")).unwrap();
    for t in ["picture8.jpg", "wood.jpg", "wood5.jpg"] {
        symlink(
            original.join("textures").join(t),
            d.path("textures").join(t),
        )
        .unwrap();
    }
    if leaf {
        d.write("textures/leaf.png", common::png_2x2());
    }
    if sky {
        d.write(
            "textures/Sky 19.exr",
            common::float_image(8, 4, image::ImageFormat::OpenExr),
        );
    }
    d
}

#[cfg(unix)]
#[test]
fn living_room() {
    let Some(dir) = shared_external("bitterli-livingroom", "living_room") else {
        return;
    };
    // As vendored: the leaves' texture is missing (the first file the primitives need).
    let e = Scene::load(dir.join("scene.json")).unwrap_err();
    match &e {
        SceneError::MissingFile {
            path,
            referenced_by,
        } => {
            assert!(path.ends_with("textures/leaf.png"), "{e}");
            // Named twice, as the transparency's alpha and its base's albedo.
            assert!(
                referenced_by
                    .as_deref()
                    .is_some_and(|r| r.contains("bsdfs[16].")),
                "{e}"
            );
        }
        other => panic!("{other}"),
    }
    // With a stand-in leaf texture, the missing environment map is the error.
    let d = stand_in_copy(&dir, true, false);
    let e = Scene::load(d.path("scene.json")).unwrap_err();
    assert!(
        matches!(&e, SceneError::MissingFile { path, .. } if path.ends_with("textures/Sky 19.exr")),
        "{e}"
    );
    assert!(e.to_string().contains("emissions[0].radiance"), "{e}");

    // With both stand-ins it loads completely.
    let d = stand_in_copy(&dir, true, true);
    let s = Scene::load(d.path("scene.json")).unwrap();
    let meshes = living_room_meshes(&dir.join("scene.json"));
    assert_eq!(meshes.len(), 65);
    let (total, degenerate, lo, hi) = count_obj_triangles(&dir, &meshes);
    assert_eq!(total, 143_163, "SOURCES.md's count");
    let dropped: usize = s
        .warnings
        .iter()
        .filter_map(|w| {
            w.strip_prefix("dropped ")
                .and_then(|r| r.split(' ').next())
                .map(|n| n.parse::<usize>().unwrap())
        })
        .sum();
    assert_eq!(dropped, degenerate);
    assert_eq!(s.triangles.len(), total - degenerate);
    let b = s.bounds();
    assert!(
        (b.min - lo).abs().max_element() < 1e-6 && (b.max - hi).abs().max_element() < 1e-6,
        "{b:?} vs {lo}..{hi}"
    );

    // Materials: one per BSDF a primitive uses (19 BSDFs, all used), by the documented mapping.
    let m = |n: &str| {
        s.materials
            .iter()
            .find(|m| m.name == n)
            .unwrap_or_else(|| panic!("{n}"))
    };
    assert_eq!(s.materials.len(), 19);
    // rough_plastic, ior 1.5, GGX alpha 0.15 -> roughness sqrt(0.15), the wood texture.
    let floor = m("Floor");
    assert_eq!((floor.kind, floor.ior), (MaterialKind::Plastic, 1.5));
    assert!((floor.roughness - 0.15f32.sqrt()).abs() < 1e-6);
    assert!(floor.albedo_texture.is_some());
    let panel = m("Paneling");
    assert_eq!(
        (panel.kind, panel.albedo),
        (MaterialKind::Plastic, Vec3::splat(0.8))
    );
    assert!((panel.roughness - 0.2f32.sqrt()).abs() < 1e-6);
    assert_eq!(
        (m("Mirror").kind, m("Mirror").roughness),
        (MaterialKind::Metal, 0.0)
    );
    assert_eq!(
        (m("Glass").kind, m("Glass").ior),
        (MaterialKind::Glass, 1.5)
    );
    // rough_conductor Al, roughness 0.02 (GGX alpha) -> sqrt(0.02); albedo 0.578596 scales
    // the Fresnel term of aluminium's complex IOR (Mitsuba's RGB values).
    let steel = m("BrushedStainlessSteel");
    assert_eq!(steel.kind, MaterialKind::Metal);
    assert!((steel.roughness - 0.02f32.sqrt()).abs() < 1e-6);
    assert_eq!(steel.albedo, Vec3::splat(0.578596));
    assert_eq!(
        (steel.conductor_eta, steel.conductor_k),
        raylume_scene::conductor_ior("Al").unwrap()
    );
    assert_eq!(
        m("Leaves")
            .albedo_texture
            .map(|t| s.textures[t as usize].name.ends_with("leaf.png")),
        Some(true)
    );
    // 3 JPEGs and the leaf stand-in.
    assert_eq!(s.textures.len(), 4);
    for w in [
        "material 'PlantPot': Tungsten 'oren_nayar' approximated as diffuse",
        "material 'Leaves': Tungsten 'transparency' approximated as its base BSDF (alpha dropped)",
    ] {
        assert!(
            s.warnings.iter().any(|x| x == w),
            "missing warning {w:?} in {:?}",
            s.warnings
        );
    }
    // Plastics, conductors and dielectrics are modelled, not approximated: no warning names them.
    for exact in ["plastic", "conductor", "dielectric", "mirror"] {
        assert!(
            !s.warnings.iter().any(|w| w.contains(exact)),
            "{exact}: {:?}",
            s.warnings
        );
    }
    assert!(
        matches!(&s.environment, Environment::Map { image, .. } if (image.width, image.height) == (8, 4))
    );

    // fov 90 is horizontal: at the file's 1280x720 the vertical one is 2 atan(tan(45 deg) *
    // 720 / 1280), and at any other size the width still spans 90 degrees.
    assert_eq!((s.render.width, s.render.height), (1280, 720));
    assert_eq!(
        (s.camera.fov, s.camera.fov_axis),
        (90.0, FovAxis::Horizontal)
    );
    let vfov = s.camera.vfov(1280, 720);
    assert!((vfov - 2.0 * (720.0f32 / 1280.0).atan().to_degrees()).abs() < 1e-4);
    assert!((s.camera.vfov(500, 500) - 90.0).abs() < 1e-4);
}
