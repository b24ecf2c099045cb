//! `SceneBuilder` builds what the TOML loader builds from the same description, and rejects
//! what it rejects.

use std::path::{Path, PathBuf};

use raylume::glam::Vec3;
use raylume::scene::{Environment, Material, Scene, SceneError};
use raylume::{Error, SceneBuilder, Transform};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("raylume-builder-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

const CAMERA: &str =
    "[camera]\nposition = [0.0, 1.0, 5.0]\nlook_at = [0.0, 1.0, 0.0]\nvfov = 40.0\n";

fn toml(text: &str, dir: &Path) -> Scene {
    Scene::from_toml_str(&format!("{CAMERA}{text}"), dir, "test.toml")
        .unwrap_or_else(|e| panic!("{e}"))
}

fn builder() -> SceneBuilder {
    let mut b = SceneBuilder::new();
    b.look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::new(0.0, 1.0, 0.0), 40.0);
    b
}

#[test]
fn quad_and_sphere_are_the_toml_ones() {
    let t = toml(
        "[materials.w]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[quad]]\ncorner = [-1.0, 0.0, 1.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 0.0, -2.0]\nmaterial = \"w\"\n\
         [[sphere]]\ncenter = [0.0, 1.0, 0.0]\nradius = 0.5\nmaterial = \"w\"\n",
        Path::new("."),
    );
    let mut b = builder();
    let w = b.material(Material::diffuse("w", Vec3::splat(0.5)));
    b.quad(
        Vec3::new(-1.0, 0.0, 1.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -2.0),
        w,
    )
    .sphere(Vec3::new(0.0, 1.0, 0.0), 0.5, w);
    let s = b.build().unwrap();
    assert_eq!(s.triangles, t.triangles);
    assert_eq!(s.spheres, t.spheres);
    assert_eq!(s.materials, t.materials);
    assert_eq!(s.camera, t.camera);
}

#[test]
fn cuboid_faces_point_outwards() {
    let mut b = builder();
    let w = b.material(Material::diffuse("w", Vec3::ONE));
    // Corners in either order give the same box.
    b.cuboid(Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.0, 0.0), w);
    let s = b.build().unwrap();
    assert_eq!(s.triangles.len(), 12);
    let centre = Vec3::new(0.0, 1.0, 1.5);
    let mut area = 0.0;
    for t in &s.triangles {
        let [a, b, c] = t.positions;
        let n = (b - a).cross(c - a);
        let mid = (a + b + c) / 3.0;
        assert!(n.dot(mid - centre) > 0.0, "{t:?} faces inwards");
        area += 0.5 * n.length();
    }
    // 2 (2x3 + 2x2 + 3x2) = 32.
    assert!((area - 32.0).abs() < 1e-4, "{area}");
}

/// A small OBJ with shading normals and uvs: two triangles.
const OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nvn 0 0 1\nvn 0.6 0 0.8\nvt 0 0\nvt 1 0\nvt 0 1\n\
                   f 1/1/1 2/2/1 3/3/2\nf 2/2/2 4/1/1 3/3/1\n";

#[test]
fn meshes_are_placed_as_the_toml_mesh_is() {
    let d = tmp("mesh");
    std::fs::write(d.join("m.obj"), OBJ).unwrap();
    for (scale, rotate, translate) in [
        ("1.0", "[0.0, 0.0, 0.0]", "[0.0, 0.0, 0.0]"),
        ("[2.0, 1.0, 0.5]", "[0.0, 90.0, 0.0]", "[1.0, 2.0, 3.0]"),
        (
            "[-1.0, 1.0, 1.0]",
            "[30.0, 45.0, 180.0]",
            "[0.0, -1.0, 0.0]",
        ),
    ] {
        let t = toml(
            &format!(
                "[materials.w]\ntype = \"diffuse\"\n\
                 [[mesh]]\nfile = \"m.obj\"\nmaterial = \"w\"\nscale = {scale}\nrotate = {rotate}\ntranslate = {translate}\n"
            ),
            &d,
        );
        let v = |s: &str| -> Vec3 {
            let n: Vec<f32> = s
                .trim_matches(['[', ']'])
                .split(',')
                .map(|x| x.trim().parse().unwrap())
                .collect();
            if n.len() == 1 {
                Vec3::splat(n[0])
            } else {
                Vec3::new(n[0], n[1], n[2])
            }
        };
        let mut b = builder();
        let w = b.material(Material::diffuse("w", Vec3::splat(0.8)));
        let placed = Transform {
            scale: v(scale),
            rotate: v(rotate),
            translate: v(translate),
        };
        b.mesh(d.join("m.obj"), placed, Some(w)).unwrap();
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 2);
        for (a, e) in s.triangles.iter().zip(&t.triangles) {
            for (p, q) in a.positions.iter().zip(e.positions) {
                assert!(
                    p.abs_diff_eq(q, 1e-5),
                    "{scale} {rotate} {translate}: {a:?} vs {e:?}"
                );
            }
            match (a.normals, e.normals) {
                (Some(n), Some(m)) => {
                    for (p, q) in n.iter().zip(m) {
                        assert!(p.abs_diff_eq(q, 1e-5), "{a:?} vs {e:?}");
                    }
                }
                (n, m) => assert_eq!(n.is_some(), m.is_some()),
            }
            assert_eq!(a.uvs, e.uvs);
            assert_eq!(a.material, w.index());
        }
    }
}

#[test]
fn a_mesh_without_a_material_brings_its_own() {
    let d = tmp("own");
    std::fs::write(d.join("m.obj"), format!("mtllib m.mtl\nusemtl red\n{OBJ}")).unwrap();
    std::fs::write(d.join("m.mtl"), "newmtl red\nKd 0.8 0.1 0.1\n").unwrap();
    let mut b = builder();
    let w = b.material(Material::diffuse("w", Vec3::ONE));
    b.sphere(Vec3::ZERO, 1.0, w);
    b.mesh(d.join("m.obj"), Transform::default(), None).unwrap();
    let s = b.build().unwrap();
    assert_eq!(s.materials.len(), 2);
    assert_eq!(s.materials[1].name, "red");
    assert!(s.triangles.iter().all(|t| t.material == 1));

    let e = b
        .mesh(d.join("missing.obj"), Transform::default(), None)
        .unwrap_err();
    assert!(matches!(e, Error::Scene(_)), "{e}");
    assert!(e.to_string().contains("missing.obj"), "{e}");
    let e = b
        .mesh(d.join("m.stl"), Transform::default(), None)
        .unwrap_err();
    assert!(
        matches!(e, Error::Scene(SceneError::UnsupportedExtension { .. })),
        "{e}"
    );
}

#[test]
fn environment_maps_load_as_the_toml_ones() {
    let d = tmp("env");
    let pixels: Vec<[f32; 3]> = (0..8 * 4).map(|i| [i as f32 * 0.1, 0.5, 1.0]).collect();
    raylume::save_exr(d.join("sky.exr"), &pixels, 8, 4).unwrap();
    let t = toml(
        "[materials.w]\ntype = \"diffuse\"\n[[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"w\"\n\
         [environment]\nmap = \"sky.exr\"\nstrength = 2.5\nrotation = 30.0\n",
        &d,
    );
    let mut b = builder();
    b.environment_map(d.join("sky.exr"), 2.5, 30.0).unwrap();
    assert_eq!(b.scene().environment, t.environment);
    assert!(matches!(t.environment, Environment::Map { .. }));

    let e = b
        .environment_map(d.join("sky.exr"), f32::NAN, 0.0)
        .unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
    let e = b.environment_map(d.join("none.exr"), 1.0, 0.0).unwrap_err();
    assert!(e.to_string().contains("none.exr"), "{e}");
}

#[test]
fn build_rejects_what_the_loader_rejects() {
    // No primitive.
    let e = builder().build().unwrap_err();
    assert!(
        matches!(e, Error::Scene(SceneError::EmptyScene { .. })),
        "{e}"
    );
    // A negative radius.
    let mut b = builder();
    let w = b.material(Material::diffuse("w", Vec3::ONE));
    b.sphere(Vec3::ZERO, -1.0, w);
    assert!(matches!(
        b.build(),
        Err(Error::Scene(SceneError::NonPositive { .. }))
    ));
    // A zero-area quad.
    let mut b = builder();
    let w = b.material(Material::diffuse("w", Vec3::ONE));
    b.quad(Vec3::ZERO, Vec3::X, Vec3::X * 2.0, w);
    assert!(matches!(
        b.build(),
        Err(Error::Scene(SceneError::InvalidValue { .. }))
    ));
    // A material from another builder.
    let mut other = builder();
    other.material(Material::diffuse("a", Vec3::ONE));
    let far = other.material(Material::diffuse("b", Vec3::ONE));
    let mut b = builder();
    b.sphere(Vec3::ZERO, 1.0, far);
    assert!(matches!(
        b.build(),
        Err(Error::Scene(SceneError::IndexOutOfRange { .. }))
    ));
    // A NaN camera.
    let mut b = builder();
    let w = b.material(Material::diffuse("w", Vec3::ONE));
    b.sphere(Vec3::ZERO, 1.0, w)
        .look_at(Vec3::NAN, Vec3::ZERO, 40.0);
    assert!(matches!(
        b.build(),
        Err(Error::Scene(SceneError::NotFinite { .. }))
    ));
    // And a valid one renders.
    let mut b = builder();
    let w = b.material(Material::emissive("w", Vec3::ONE));
    b.sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, w).size(8, 8).spp(1);
    let r = raylume::Tracer::new(raylume::Backend::Cpu)
        .render(&b.into_scene().unwrap())
        .unwrap();
    assert!(r.pixels.iter().any(|p| p[0] > 0.0));
}
