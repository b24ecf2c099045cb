//! OBJ + MTL: small hand-made files in, triangle counts, transforms and the MTL mapping out;
//! every malformed input a typed error naming the file and line.

mod common;

use common::{TempDir, err_contains, toml};
use glam::{Vec2, Vec3};
use raylume_scene::{Environment, Location, MaterialKind, RenderSettings, Scene, SceneError};

/// A unit cube [0,1]^3 of 6 quads (12 triangles) wound outward, five materials, normals and uvs
/// on every corner.
const CUBE_OBJ: &str = "\
# unit cube
mtllib cube.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 -1
vn 0 0 1
vn 0 -1 0
vn 0 1 0
vn -1 0 0
vn 1 0 0
usemtl red
f 1/1/1 4/4/1 3/3/1 2/2/1
f 5/1/2 6/2/2 7/3/2 8/4/2
usemtl chrome
f 1/1/3 2/2/3 6/3/3 5/4/3
usemtl glass
f 4/1/4 8/2/4 7/3/4 3/4/4
usemtl lamp
f 1/1/5 5/2/5 8/3/5 4/4/5
usemtl wood
f 2/1/6 3/2/6 7/3/6 6/4/6
";

const CUBE_MTL: &str = "\
newmtl red
Kd 0.8 0.1 0.1
Ks 0.04 0.04 0.04
Ns 10
illum 2

newmtl chrome
Kd 0.1 0.1 0.1
Ks 0.9 0.9 0.9
Ns 198
illum 3

newmtl glass
Kd 1 1 1
Ni 1.45
d 0.5
Tf 0.9 1 0.8
illum 4

newmtl lamp
Kd 0.5
Ke 10 9 8

newmtl wood
Kd 1 1 1
map_Kd wood.png
";

fn cube_dir() -> TempDir {
    let d = TempDir::new("obj-cube");
    d.write("cube.obj", CUBE_OBJ);
    d.write("cube.mtl", CUBE_MTL);
    d.write("wood.png", common::png_2x2());
    d
}

#[test]
fn cube_with_mtl_maps_every_material() {
    let d = cube_dir();
    let s = Scene::load(d.path("cube.obj")).unwrap();
    assert_eq!(s.triangles.len(), 12, "6 quads, triangulated");
    let by_name = |n: &str| {
        s.materials
            .iter()
            .position(|m| m.name == n)
            .unwrap_or_else(|| panic!("{n}")) as u32
    };
    let count = |n: &str| {
        s.triangles
            .iter()
            .filter(|t| t.material == by_name(n))
            .count()
    };
    assert_eq!(
        [
            count("red"),
            count("chrome"),
            count("glass"),
            count("lamp"),
            count("wood")
        ],
        [4, 2, 2, 2, 2]
    );

    let m = |n: &str| &s.materials[by_name(n) as usize];
    // Ks 0.04 < Kd 0.8 and illum 2: diffuse.
    assert_eq!(
        (m("red").kind, m("red").albedo),
        (MaterialKind::Diffuse, Vec3::new(0.8, 0.1, 0.1))
    );
    // illum 3 and Ks > Kd: metal, albedo Ks, roughness (2/(198+2))^(1/4) = 0.1^(1/2).
    let c = m("chrome");
    assert_eq!((c.kind, c.albedo), (MaterialKind::Metal, Vec3::splat(0.9)));
    assert!((c.roughness - 0.1f32.sqrt()).abs() < 1e-6);
    // illum 4, Ni, d < 1: glass with ior Ni and tint Tf.
    let g = m("glass");
    assert_eq!(
        (g.kind, g.ior, g.tint),
        (MaterialKind::Glass, 1.45, Vec3::new(0.9, 1.0, 0.8))
    );
    // Ke: emission; a one-number Kd means grey.
    assert_eq!(
        (m("lamp").emission, m("lamp").albedo),
        (Vec3::new(10.0, 9.0, 8.0), Vec3::splat(0.5))
    );
    // map_Kd: a texture (sRGB-decoded), multiplied with Kd.
    assert_eq!(m("wood").albedo_texture, Some(0));
    assert_eq!(s.textures[0].texels.linear(1), [0.0, 1.0, 0.0]);
    assert_eq!(
        s.features().names(),
        [
            "diffuse",
            "rough_metal",
            "glass",
            "emission",
            "textures",
            "triangles",
            "shading_normals"
        ]
    );

    // Every triangle's geometric normal agrees with its shading normal (the OBJ is wound
    // outward), and the cube's bounds are [0,1]^3.
    for t in &s.triangles {
        let [a, b, c] = t.positions;
        let n = (b - a).cross(c - a).normalize();
        assert!(n.dot(t.normals.unwrap()[0]) > 0.999, "{t:?}");
    }
    assert_eq!((s.bounds().min, s.bounds().max), (Vec3::ZERO, Vec3::ONE));
    // uv: OBJ v = 0 at the bottom becomes raylume v = 1 (top-left origin).
    let first = &s.triangles[0];
    assert_eq!(first.uvs.unwrap()[0], Vec2::new(0.0, 1.0));
}

#[test]
fn bare_obj_loads_as_a_scene_framed_on_its_bounds() {
    let d = cube_dir();
    let s = Scene::load(d.path("cube.obj")).unwrap();
    assert_eq!(s.environment, Environment::Black);
    assert_eq!(s.render, RenderSettings::default());
    let c = s.camera;
    assert_eq!((c.look_at, c.up, c.fov), (Vec3::splat(0.5), Vec3::Y, 40.0));
    // On the +z axis through the centre, at bounding radius / sin(20 deg).
    let r = 3f32.sqrt() / 2.0;
    let want = Vec3::new(0.5, 0.5, 0.5 + r / 20f32.to_radians().sin());
    assert!((c.position - want).length() < 1e-5, "{:?}", c.position);
}

#[test]
fn mesh_override_skips_the_mtl_and_transforms_apply() {
    let d = TempDir::new("obj-override");
    // The MTL is absent: with an override it is never read.
    d.write("cube.obj", CUBE_OBJ);
    let text = "[materials.white]\ntype = \"diffuse\"\n\
                [[mesh]]\nfile = \"cube.obj\"\nmaterial = \"white\"\nscale = [2, 1, 1]\nrotate = [0, 90, 0]\ntranslate = [0, 5, 0]\n";
    let s = toml(&d.0, text).unwrap();
    assert_eq!(s.materials.len(), 1);
    assert!(s.triangles.iter().all(|t| t.material == 0));
    // [0,2]x[0,1]x[0,1] rotated 90 degrees about y: x -> -z, z -> x; then y + 5.
    let b = s.bounds();
    assert!(
        (b.min - Vec3::new(0.0, 5.0, -2.0)).abs().max_element() < 1e-6,
        "{b:?}"
    );
    assert!(
        (b.max - Vec3::new(1.0, 6.0, 0.0)).abs().max_element() < 1e-6,
        "{b:?}"
    );
    for t in &s.triangles {
        let [a, b, c] = t.positions;
        let n = (b - a).cross(c - a).normalize();
        let sn = t.normals.unwrap()[0];
        assert!((sn.length() - 1.0).abs() < 1e-6 && n.dot(sn) > 0.999);
    }
    // A mirroring scale keeps geometric and shading normals together (winding is swapped).
    let s = toml(
        &d.0,
        &text.replace("scale = [2, 1, 1]", "scale = [-1, 1, 1]"),
    )
    .unwrap();
    for t in &s.triangles {
        let [a, b, c] = t.positions;
        assert!((b - a).cross(c - a).normalize().dot(t.normals.unwrap()[0]) > 0.999);
    }
}

#[test]
fn polygons_are_fans_and_lines_are_skipped() {
    let d = TempDir::new("obj-poly");
    let p = d.write(
        "p.obj",
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\nl 1 2\n",
    );
    let s = Scene::load(&p).unwrap();
    assert_eq!(s.triangles.len(), 3, "a pentagon is 3 triangles");
    assert!(
        s.warnings.iter().any(|w| w.contains("line elements")),
        "{:?}",
        s.warnings
    );
}

fn load_err(files: &[(&str, &str)], main: &str) -> SceneError {
    let d = TempDir::new("obj-err");
    for (n, t) in files {
        d.write(n, t);
    }
    Scene::load(d.path(main)).unwrap_err()
}

#[test]
fn malformed_files_name_file_and_line() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let e = load_err(&[("a.obj", &format!("{tri}f 1 2 4\n"))], "a.obj");
    assert!(
        matches!(
            &e,
            SceneError::IndexOutOfRange {
                at: Location::Line(4),
                index: 4,
                len: 3,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("a.obj:4: vertex index 4 is out of range (there are 3)"),
        "{e}"
    );
    let e = load_err(
        &[("a.obj", &format!("{tri}vn 0 0 1\nf 1//1 2//1 3//-2\n"))],
        "a.obj",
    );
    assert!(
        matches!(
            &e,
            SceneError::IndexOutOfRange {
                at: Location::Line(5),
                ..
            }
        ),
        "{e}"
    );
    let e = load_err(&[("a.obj", "v 0 0 0\nv 1 zero 0\n")], "a.obj");
    assert!(
        matches!(
            &e,
            SceneError::Syntax {
                at: Location::Line(2),
                ..
            }
        ),
        "{e}"
    );
    let e = load_err(&[("a.obj", &format!("{tri}f 1 2 x\n"))], "a.obj");
    assert!(
        matches!(
            &e,
            SceneError::Syntax {
                at: Location::Line(4),
                ..
            }
        ),
        "{e}"
    );
    let d = TempDir::new("obj-utf8");
    let e = Scene::load(d.write("a.obj", b"v 0 0 0\n\xff\n")).unwrap_err();
    assert!(
        matches!(
            &e,
            SceneError::Syntax {
                at: Location::Line(2),
                ..
            }
        ),
        "{e}"
    );

    // MTL problems name the MTL and its line.
    let obj = format!("mtllib m.mtl\n{tri}usemtl a\nf 1 2 3\n");
    let e = load_err(
        &[("a.obj", &obj), ("m.mtl", "newmtl a\nKd 0.5 0.5\n")],
        "a.obj",
    );
    assert!(
        matches!(&e, SceneError::Syntax { file, at: Location::Line(2), .. } if file.ends_with("m.mtl")),
        "{e}"
    );
    let e = load_err(
        &[("a.obj", &obj), ("m.mtl", "newmtl a\nNs lots\n")],
        "a.obj",
    );
    assert!(
        matches!(&e, SceneError::Syntax { file, at: Location::Line(2), .. } if file.ends_with("m.mtl")),
        "{e}"
    );
    // A missing MTL names the OBJ line that asked for it.
    let e = load_err(&[("a.obj", &obj)], "a.obj");
    match &e {
        SceneError::MissingFile {
            path,
            referenced_by,
        } => {
            assert!(path.ends_with("m.mtl"));
            assert!(
                referenced_by
                    .as_deref()
                    .is_some_and(|r| r.ends_with("a.obj:1")),
                "{e}"
            );
        }
        other => panic!("{other}"),
    }
    // usemtl of a name the MTL lacks.
    let e = load_err(
        &[("a.obj", &obj), ("m.mtl", "newmtl b\nKd 1 1 1\n")],
        "a.obj",
    );
    assert!(
        matches!(&e, SceneError::UnknownMaterial { at: Location::Line(5), name, .. } if name == "a"),
        "{e}"
    );
    // A missing texture names the MTL material that wants it.
    let e = load_err(
        &[("a.obj", &obj), ("m.mtl", "newmtl a\nmap_Kd gone.png\n")],
        "a.obj",
    );
    err_contains::<()>(
        Err(e),
        &["gone.png", "file not found", "m.mtl: material `a` map_Kd"],
    );
}

#[test]
fn usemtl_without_mtllib_warns_and_uses_the_default() {
    let d = TempDir::new("obj-nomtl");
    let p = d.write(
        "a.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\n",
    );
    let s = Scene::load(&p).unwrap();
    assert_eq!(
        s.materials[s.triangles[0].material as usize].name,
        "default"
    );
    assert!(
        s.warnings.iter().any(|w| w.contains("no `mtllib`")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn degenerate_triangles_are_dropped_and_counted_nan_is_an_error() {
    let d = TempDir::new("obj-degen");
    // Triangle 2 repeats a vertex, triangle 3 is collinear, triangle 4 overflows f32 in the
    // cross product (finite corners, infinite normal).
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 1e30 0 0\nv 0 1e30 0\n\
                f 1 2 3\nf 1 1 3\nf 1 2 4\nf 1 5 6\n";
    let p = d.write("d.obj", text);
    let s = Scene::load(&p).unwrap();
    assert_eq!(s.triangles.len(), 1);
    let want = format!("dropped 3 degenerate triangles from {}", p.display());
    assert!(s.warnings.contains(&want), "{:?}", s.warnings);

    // NaN is an error naming the triangle's index in its file, not a dropped triangle.
    let p = d.write(
        "n.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nf 1 2 3\nf 1 2 4\n",
    );
    let e = Scene::load(&p).unwrap_err();
    assert!(
        matches!(&e, SceneError::NotFinite { at: Location::Path(at), .. } if at.starts_with("triangle 1 of ") && at.ends_with("n.obj")),
        "{e}"
    );

    // Zero-length normals: flat shading for that triangle, with a warning.
    let p = d.write(
        "z.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n",
    );
    let s = Scene::load(&p).unwrap();
    assert_eq!(s.triangles[0].normals, None);
    assert!(
        s.warnings.iter().any(|w| w.contains("zero-length normals")),
        "{:?}",
        s.warnings
    );

    // Only degenerate triangles: an empty scene.
    let p = d.write("e.obj", "v 0 0 0\nv 1 0 0\nf 1 2 2\n");
    assert!(matches!(
        Scene::load(&p).unwrap_err(),
        SceneError::EmptyScene { .. }
    ));
}
