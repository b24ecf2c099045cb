//! The TOML format of `DESIGN.md`: every key parsed into the right place, and every typo or
//! unknown key an error with file, line and column.

mod common;

use common::{TempDir, err_contains, line_col, toml};
use glam::{Vec2, Vec3};
use raylume_scene::{Bloom, Environment, Location, MaterialKind, RenderSettings, SceneError};

/// A one-triangle OBJ (with normals and uvs) and a small MTL-free mesh.
const TRI_OBJ: &str =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\n";

/// Every key of DESIGN.md's example, with values that differ from every default.
fn full_scene(env: &str) -> String {
    format!(
        r#"
[camera]
position = [0.0, 1.0, 6.8]
look_at  = [0.0, 1.0, 0.0]
up       = [1.0, 1.0, 0.0]
vfov     = 19.5

[render]
width = 320
height = 200
spp = 7
max_bounces = 3
seed = 42

{env}

[materials.white]
type = "diffuse"
albedo = [0.73, 0.72, 0.71]
emission = [0.5, 0.25, 0.125]

[materials.mirror]
type = "metal"
albedo = [0.9, 0.8, 0.7]
roughness = 0.25

[materials.glass]
type = "glass"
ior = 1.33
tint = [0.9, 1.0, 0.95]

[materials.wood]
type = "diffuse"
texture = "tex/wood.png"

[[mesh]]
file = "meshes/tri.obj"
material = "white"
translate = [10.0, 0.0, 0.0]
rotate = [0.0, 0.0, 90.0]
scale = 2.0

[[mesh]]
file = "meshes/tri.obj"
scale = [1.0, 3.0, 1.0]

[[sphere]]
center = [0.0, 1.0, 0.0]
radius = 0.5
material = "glass"

[[quad]]
corner = [-0.25, 1.98, -0.25]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
material = "wood"

[post.bloom]
threshold = 1.5
radius = 8
strength = 0.3
"#
    )
}

fn fixtures() -> TempDir {
    let d = TempDir::new("toml-full");
    d.write("meshes/tri.obj", TRI_OBJ);
    d.write("tex/wood.png", common::png_2x2());
    d.write(
        "sky.hdr",
        common::float_image(4, 2, image::ImageFormat::Hdr),
    );
    d
}

#[test]
fn every_key_lands_in_the_scene() {
    let d = fixtures();
    let s = toml(
        &d.0,
        &full_scene("[environment]\nradiance = [0.5, 0.25, 1.0]\nstrength = 2.0"),
    )
    .unwrap();

    let c = s.camera;
    assert_eq!(c.position, Vec3::new(0.0, 1.0, 6.8));
    assert_eq!(c.look_at, Vec3::new(0.0, 1.0, 0.0));
    assert_eq!(c.up, Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(
        (c.fov, c.fov_axis),
        (19.5, raylume_scene::FovAxis::Vertical)
    );

    assert_eq!(
        s.render,
        RenderSettings {
            width: 320,
            height: 200,
            spp: 7,
            max_bounces: 3,
            seed: 42
        }
    );
    // radiance x strength.
    assert_eq!(
        s.environment,
        Environment::Constant(Vec3::new(1.0, 0.5, 2.0))
    );

    // Materials in file order; a texture counts as one texture.
    let names: Vec<_> = s.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["white", "mirror", "glass", "wood", "default"]);
    let [white, mirror, glass, wood] = [0, 1, 2, 3].map(|i| &s.materials[i]);
    assert_eq!(
        (white.kind, white.albedo, white.emission),
        (
            MaterialKind::Diffuse,
            Vec3::new(0.73, 0.72, 0.71),
            Vec3::new(0.5, 0.25, 0.125)
        )
    );
    assert_eq!(
        (mirror.kind, mirror.albedo, mirror.roughness),
        (MaterialKind::Metal, Vec3::new(0.9, 0.8, 0.7), 0.25)
    );
    assert_eq!(
        (glass.kind, glass.ior, glass.tint),
        (MaterialKind::Glass, 1.33, Vec3::new(0.9, 1.0, 0.95))
    );
    assert_eq!(
        (wood.kind, wood.albedo_texture),
        (MaterialKind::Diffuse, Some(0))
    );
    assert_eq!(s.textures.len(), 1);
    assert_eq!((s.textures[0].width, s.textures[0].height), (2, 2));
    assert_eq!(
        s.textures[0].texels.linear(0),
        [1.0, 0.0, 0.0],
        "top-left texel is red"
    );

    // Mesh 1: scale 2, rotate 90 about z, translate +10 x, material override.
    // (1,0,0) -> (2,0,0) -> (0,2,0) -> (10,2,0); (0,1,0) -> (0,2,0) -> (-2,0,0) -> (8,0,0).
    assert_eq!(
        s.triangles.len(),
        1 + 1 + 2,
        "two meshes of 1 + a quad of 2"
    );
    let t = &s.triangles[0];
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 1e-5;
    assert!(close(t.positions[0], Vec3::new(10.0, 0.0, 0.0)));
    assert!(close(t.positions[1], Vec3::new(10.0, 2.0, 0.0)));
    assert!(close(t.positions[2], Vec3::new(8.0, 0.0, 0.0)));
    assert_eq!(t.material, 0);
    // Normal (0,0,1) is unchanged by a rotation about z and a uniform scale; OBJ v is flipped.
    assert!(close(t.normals.unwrap()[0], Vec3::Z));
    assert_eq!(
        t.uvs.unwrap(),
        [
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 0.0)
        ]
    );
    // Mesh 2: per-axis scale, no override: OBJ without MTL gets the default grey diffuse.
    let t2 = &s.triangles[1];
    assert!(close(t2.positions[2], Vec3::new(0.0, 3.0, 0.0)));
    assert_eq!(s.materials[t2.material as usize].name, "default");
    assert_eq!(s.materials[t2.material as usize].albedo, Vec3::splat(0.8));
    // The quad: corner, corner+u, corner+u+v and corner, corner+u+v, corner+v.
    let q = [&s.triangles[2], &s.triangles[3]];
    let (c0, u, v) = (
        Vec3::new(-0.25, 1.98, -0.25),
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.5),
    );
    assert_eq!(q[0].positions, [c0, c0 + u, c0 + u + v]);
    assert_eq!(q[1].positions, [c0, c0 + u + v, c0 + v]);
    assert_eq!(q[0].material, 3);

    assert_eq!(s.spheres.len(), 1);
    assert_eq!(
        (
            s.spheres[0].center,
            s.spheres[0].radius,
            s.spheres[0].material
        ),
        (Vec3::Y, 0.5, 2)
    );
    assert_eq!(
        s.post.bloom,
        Some(Bloom {
            threshold: 1.5,
            radius: 8,
            strength: 0.3
        })
    );
}

#[test]
fn environment_map_strength_and_rotation() {
    let d = fixtures();
    let s = toml(
        &d.0,
        &full_scene("[environment]\nmap = \"sky.hdr\"\nstrength = 3.0\nrotation = 45.0"),
    )
    .unwrap();
    let Environment::Map {
        image,
        strength,
        rotation,
    } = &s.environment
    else {
        panic!("{:?}", s.environment)
    };
    assert_eq!((*strength, *rotation), (3.0, 45.0));
    assert_eq!((image.width, image.height), (4, 2));
    // Float images are linear: texel (x, y) = [x, y, 0.5] (Radiance HDR stores 8-bit
    // mantissas with a shared exponent: 3.0 and 0.5 are exact).
    assert_eq!(image.texels.linear(4 + 3), [3.0, 1.0, 0.5]);
}

#[test]
fn defaults_apply_where_keys_are_absent() {
    let d = TempDir::new("toml-defaults");
    let s = toml(
        &d.0,
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 30\n\
         [materials.m]\ntype = \"metal\"\n[materials.g]\ntype = \"glass\"\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n",
    )
    .unwrap();
    assert_eq!(s.camera.up, Vec3::Y);
    assert_eq!(s.render, RenderSettings::default());
    assert_eq!(s.environment, Environment::Black);
    assert_eq!(s.post.bloom, None);
    let (m, g) = (&s.materials[0], &s.materials[1]);
    assert_eq!(
        (m.albedo, m.roughness, m.emission),
        (Vec3::splat(0.8), 0.0, Vec3::ZERO)
    );
    assert_eq!((g.ior, g.tint), (1.5, Vec3::ONE));
}

#[test]
fn hfov_and_two_sided_emission_are_read() {
    let d = TempDir::new("toml-hfov");
    let s = toml(
        &d.0,
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nhfov = 70\n\
         [materials.lamp]\ntype = \"diffuse\"\nemission = [2, 2, 2]\ntwo_sided = true\n\
         [materials.bulb]\ntype = \"diffuse\"\nemission = [1, 1, 1]\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"lamp\"\n\
         [[sphere]]\ncenter = [3, 0, 0]\nradius = 1\nmaterial = \"bulb\"\n",
    )
    .unwrap();
    assert_eq!(
        (s.camera.fov, s.camera.fov_axis),
        (70.0, raylume_scene::FovAxis::Horizontal)
    );
    // One-sided unless said otherwise.
    assert!(s.materials[0].two_sided);
    assert!(!s.materials[1].two_sided);
}

#[test]
fn plastic_rough_glass_and_conductors_are_read() {
    let d = TempDir::new("toml-materials");
    let body = |m: &str| {
        format!(
            "[materials.m]\n{m}\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n"
        )
    };
    let one = |m: &str| toml(&d.0, &body(m)).map(|s| s.materials[0].clone());
    let p =
        one("type = \"plastic\"\nalbedo = [0.5, 0.4, 0.3]\nroughness = 0.3\nior = 1.4").unwrap();
    assert_eq!(
        (p.kind, p.albedo, p.roughness, p.ior),
        (MaterialKind::Plastic, Vec3::new(0.5, 0.4, 0.3), 0.3, 1.4)
    );
    // Defaults: a smooth coat of ior 1.5; smooth glass.
    let p = one("type = \"plastic\"").unwrap();
    assert_eq!((p.roughness, p.ior), (0.0, 1.5));
    let g = one("type = \"glass\"\nroughness = 0.2").unwrap();
    assert_eq!((g.kind, g.roughness), (MaterialKind::Glass, 0.2));
    assert_eq!(one("type = \"glass\"").unwrap().roughness, 0.0);
    // A named conductor takes Mitsuba's RGB complex IOR; eta and k may be given instead.
    let au = one("type = \"metal\"\nconductor = \"Au\"\nroughness = 0.1").unwrap();
    let (eta, k) = raylume_scene::conductor_ior("Au").unwrap();
    assert_eq!((au.conductor_eta, au.conductor_k), (eta, k));
    let custom = one("type = \"metal\"\neta = [0.2, 0.9, 1.1]\nk = [3.9, 2.4, 2.1]").unwrap();
    assert_eq!(custom.conductor_eta, Vec3::new(0.2, 0.9, 1.1));
    // Without either: Fresnel 1 (eta 0, k 1), the albedo alone reflects.
    let plain = one("type = \"metal\"").unwrap();
    assert_eq!(
        (plain.conductor_eta, plain.conductor_k),
        (Vec3::ZERO, Vec3::ONE)
    );
    for (m, variant, line, col) in [
        (
            "type = \"metal\"\nconductor = \"Unobtainium\"",
            "InvalidValue",
            3,
            13,
        ),
        (
            "type = \"metal\"\nconductor = \"Au\"\neta = [1, 1, 1]",
            "InvalidValue",
            3,
            13,
        ),
        ("type = \"metal\"\neta = [1, 1, 1]", "MissingKey", 3, 7),
        ("type = \"metal\"\nk = [1, 1, 1]", "MissingKey", 3, 5),
        (
            "type = \"metal\"\neta = [1, -1, 1]\nk = [1, 1, 1]",
            "Negative",
            3,
            7,
        ),
        ("type = \"plastic\"\nroughness = 2", "InvalidValue", 3, 13),
    ] {
        let e = toml(&d.0, &body(m)).unwrap_err();
        assert!(format!("{e:?}").starts_with(variant), "{m}: {e}");
        assert_eq!(e.location(), Some(&line_col(line, col)), "{m}: {e}");
    }
    let e = toml(&d.0, &body("type = \"metal\"\nconductor = \"Unobtainium\"")).unwrap_err();
    assert!(
        e.to_string().contains("Au, "),
        "the error lists the names: {e}"
    );
}

#[test]
fn no_camera_table_frames_the_bounds() {
    let d = TempDir::new("toml-frame");
    let s = toml(&d.0, "[materials.m]\ntype = \"diffuse\"\n[[sphere]]\ncenter = [1, 2, 3]\nradius = 1\nmaterial = \"m\"\n").unwrap();
    assert_eq!(s.camera.look_at, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(s.camera.fov, 40.0);
    assert!(s.camera.position.z > 3.0 + 1.0);
}

/// Each table with one misspelt key: the error names the key, the file, and the key's line
/// and column.
#[test]
fn unknown_keys_are_errors_with_line_and_column() {
    let d = fixtures();
    let base = full_scene("[environment]\nradiance = [1.0, 1.0, 1.0]");
    let cases: &[(&str, &str)] = &[
        ("vfov     = 19.5", "vfov     = 19.5\nfov = 20"),
        ("seed = 42", "seed = 42\nsamples = 3"),
        (
            "radiance = [1.0, 1.0, 1.0]",
            "radiance = [1.0, 1.0, 1.0]\nrotate = 1",
        ),
        (
            "emission = [0.5, 0.25, 0.125]",
            "emission = [0.5, 0.25, 0.125]\nalbdo = [1, 1, 1]",
        ),
        ("scale = 2.0", "scale = 2.0\nrotation = [0, 0, 0]"),
        ("radius = 0.5", "radius = 0.5\nradious = 1"),
        ("u = [0.5, 0.0, 0.0]", "u = [0.5, 0.0, 0.0]\nw = [1, 1, 1]"),
        ("strength = 0.3", "strength = 0.3\nsigma = 2"),
        ("[render]", "[rendr]\nx = 1\n[render]"),
        ("[post.bloom]", "[post.glow]\n[post.bloom]"),
    ];
    for (from, to) in cases {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let bad_line = to
            .lines()
            .nth(if to.starts_with('[') { 0 } else { 1 })
            .unwrap();
        let key = bad_line
            .trim_start_matches('[')
            .split([' ', '.', ']'])
            .find(|k| !k.is_empty() && *k != "post")
            .unwrap();
        let line = text.lines().position(|l| l == bad_line).unwrap() + 1;
        let col = if bad_line.starts_with("[post.") {
            7
        } else if bad_line.starts_with('[') {
            2
        } else {
            1
        };
        let e = toml(&d.0, &text).unwrap_err();
        match &e {
            SceneError::UnknownKey {
                file, at, key: k, ..
            } => {
                assert_eq!((file.as_str(), k.as_str()), ("scene.toml", key), "{e}");
                assert_eq!(*at, line_col(line, col), "{e}");
            }
            other => panic!("{to}: expected UnknownKey, got {other}"),
        }
        assert!(
            e.to_string()
                .starts_with(&format!("scene.toml:{line}:{col}: unknown key `{key}`")),
            "{e}"
        );
    }
}

#[test]
fn keys_that_do_not_apply_to_a_material_type_are_errors() {
    let d = TempDir::new("toml-matkeys");
    for (ty, key, value) in [
        ("diffuse", "ior", "1.5"),
        ("diffuse", "roughness", "0.1"),
        ("metal", "tint", "[1, 1, 1]"),
        ("glass", "albedo", "[1, 1, 1]"),
        ("glass", "texture", "\"a.png\""),
        ("plastic", "tint", "[1, 1, 1]"),
        ("metal", "ior", "1.5"),
        ("glass", "conductor", "\"Au\""),
        ("diffuse", "eta", "[1, 1, 1]"),
    ] {
        let text = format!(
            "[materials.m]\ntype = \"{ty}\"\n{key} = {value}\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n"
        );
        let e = toml(&d.0, &text).unwrap_err();
        assert!(
            matches!(&e, SceneError::UnknownKey { key: k, at, .. } if k == key && *at == line_col(3, key.len() + 4)),
            "{ty}.{key}: {e}"
        );
    }
    let e = toml(&d.0, "[materials.m]\ntype = \"velvet\"\n").unwrap_err();
    assert!(
        matches!(&e, SceneError::InvalidValue { at, .. } if *at == line_col(2, 8)),
        "{e}"
    );
}

/// `check(text, expected variant name, line, column)`.
fn check(text: &str, variant: &str, line: usize, column: usize) {
    let d = TempDir::new("toml-check");
    d.write("meshes/tri.obj", TRI_OBJ);
    let e = toml(&d.0, text).unwrap_err();
    let name = format!("{e:?}");
    assert!(
        name.starts_with(variant),
        "{text}\nexpected {variant}, got {e}"
    );
    assert_eq!(e.location(), Some(&line_col(line, column)), "{text}\n{e}");
    assert!(
        e.to_string()
            .starts_with(&format!("scene.toml:{line}:{column}: ")),
        "{e}"
    );
}

const SPHERE: &str = "[materials.m]\ntype = \"diffuse\"\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n";

#[test]
fn bad_values_are_typed_errors_at_their_place() {
    let cam = |body: &str| format!("{SPHERE}[camera]\n{body}");
    // Line 7 is `[camera]`; its keys follow.
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = 0"),
        "Vfov",
        10,
        8,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = 180"),
        "Vfov",
        10,
        8,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = nan"),
        "NotFinite",
        10,
        8,
    );
    check(
        &cam("position = [0, inf, 1]\nlook_at = [0, 0, 0]\nvfov = 40"),
        "NotFinite",
        8,
        12,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 1]\nvfov = 40"),
        "DegenerateCamera",
        7,
        1,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nup = [0, 0, 2]\nvfov = 40"),
        "DegenerateCamera",
        10,
        6,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = \"wide\""),
        "WrongType",
        10,
        8,
    );
    check(
        &cam("position = [0, 0]\nlook_at = [0, 0, 0]\nvfov = 40"),
        "WrongType",
        8,
        12,
    );
    check(&cam("position = [0, 0, 1]\nvfov = 40"), "MissingKey", 7, 1);
    // The field of view: `vfov` or `hfov`, exactly one.
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]"),
        "MissingKey",
        7,
        1,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = 40\nhfov = 40"),
        "InvalidValue",
        11,
        8,
    );
    check(
        &cam("position = [0, 0, 1]\nlook_at = [0, 0, 0]\nhfov = 180"),
        "Vfov",
        10,
        8,
    );
    // `two_sided` needs an emission to apply to.
    check(
        "[materials.m]\ntype = \"diffuse\"\ntwo_sided = true\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n",
        "InvalidValue",
        3,
        13,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\nemission = [1, 1, 1]\ntwo_sided = 1\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n",
        "WrongType",
        4,
        13,
    );
    check(&format!("{SPHERE}[render]\nwidth = 0"), "NonPositive", 8, 9);
    check(&format!("{SPHERE}[render]\nspp = 0"), "NonPositive", 8, 7);
    check(
        &format!("{SPHERE}[render]\nheight = -3"),
        "WrongType",
        8,
        10,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 0\nmaterial = \"m\"\n",
        "NonPositive",
        5,
        10,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\n[[sphere]]\ncenter = [0, 0, 0]\nradius = -2\nmaterial = \"m\"\n",
        "NonPositive",
        5,
        10,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"n\"\n",
        "UnknownMaterial",
        6,
        12,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\nemission = [1, -1, 1]\n",
        "Negative",
        3,
        12,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\nalbedo = [1, nan, 1]\n",
        "NotFinite",
        3,
        10,
    );
    check(
        "[materials.m]\ntype = \"metal\"\nroughness = 1.5\n",
        "InvalidValue",
        3,
        13,
    );
    check(
        "[materials.m]\ntype = \"glass\"\nior = 0\n",
        "NonPositive",
        3,
        7,
    );
    check(
        &format!(
            "{SPHERE}[[quad]]\ncorner = [0, 0, 0]\nu = [1, 0, 0]\nv = [2, 0, 0]\nmaterial = \"m\""
        ),
        "NonPositive",
        7,
        1,
    );
    check(
        &format!("{SPHERE}[[mesh]]\nfile = \"meshes/tri.obj\"\nscale = [1, 0, 1]"),
        "NonPositive",
        9,
        9,
    );
    check(
        &format!("{SPHERE}[[mesh]]\nfile = \"meshes/tri.obj\"\nscale = 0"),
        "NonPositive",
        9,
        9,
    );
    check(
        &format!("{SPHERE}[[mesh]]\nfile = \"meshes/tri.obj\"\nmaterial = \"nope\""),
        "UnknownMaterial",
        9,
        12,
    );
    check(
        &format!("{SPHERE}[environment]\nradiance = [1, 1, 1]\nmap = \"sky.hdr\""),
        "InvalidValue",
        9,
        7,
    );
    check(
        &format!("{SPHERE}[environment]\nstrength = 2"),
        "MissingKey",
        7,
        1,
    );
    check(
        &format!("{SPHERE}[environment]\nradiance = [1, 1, 1]\nstrength = -1"),
        "Negative",
        9,
        12,
    );
    check(
        &format!("{SPHERE}[post.bloom]\nthreshold = 1\nradius = 0\nstrength = 1"),
        "NonPositive",
        9,
        10,
    );
    check(
        &format!("{SPHERE}[post.bloom]\nthreshold = 1\nradius = 2"),
        "MissingKey",
        7,
        1,
    );
    check(
        "[materials.m]\ntype = \"diffuse\"\n[[sphere]\n",
        "Syntax",
        3,
        10,
    );
    check("a = 1\na = 2\n", "Syntax", 2, 1);
}

#[test]
fn files_named_by_the_scene_must_exist_and_be_readable() {
    let d = TempDir::new("toml-files");
    let text = format!("{SPHERE}[[mesh]]\nfile = \"meshes/gone.obj\"\n");
    let e = toml(&d.0, &text).unwrap_err();
    match &e {
        SceneError::MissingFile {
            path,
            referenced_by,
        } => {
            assert!(path.ends_with("meshes/gone.obj"));
            assert_eq!(referenced_by.as_deref(), Some("scene.toml:8:8"));
        }
        other => panic!("{other}"),
    }
    common::err_contains(
        toml(&d.0, &format!("{SPHERE}[[mesh]]\nfile = \"bunny.ply\"\n")),
        &["bunny.ply", "unsupported file extension", "scene.toml:8:8"],
    );
    common::err_contains(
        toml(&d.0, &format!("{SPHERE}[environment]\nmap = \"sky.png\"\n")),
        &["sky.png", "unsupported file extension", ".hdr or .exr"],
    );
    let e = common::err_contains(
        toml(&d.0, &format!("{SPHERE}[environment]\nmap = \"sky.exr\"\n")),
        &["sky.exr", "file not found", "scene.toml:8:7"],
    );
    assert!(matches!(e, SceneError::MissingFile { .. }));
    d.write("broken.png", b"\x89PNG\r\n\x1a\nnot really");
    let text = "[materials.m]\ntype = \"diffuse\"\ntexture = \"broken.png\"\n";
    let e = err_contains(
        toml(&d.0, text),
        &["broken.png", "cannot decode image", "scene.toml:3:11"],
    );
    assert!(matches!(e, SceneError::Image { .. }), "{e}");
    // A texture wider than the limit is refused before decoding its pixels.
    let wide = image::RgbImage::new(raylume_scene::limits::MAX_TEXTURE_SIZE + 1, 1);
    d.write(
        "wide.png",
        common::encode(
            image::DynamicImage::ImageRgb8(wide),
            image::ImageFormat::Png,
        ),
    );
    let e = toml(
        &d.0,
        "[materials.m]\ntype = \"diffuse\"\ntexture = \"wide.png\"\n",
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            SceneError::TooLarge {
                count: 16385,
                limit: 16384,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn empty_scene_and_clamped_albedo() {
    let d = TempDir::new("toml-empty");
    let e = toml(&d.0, "[materials.m]\ntype = \"diffuse\"\n").unwrap_err();
    assert!(
        matches!(&e, SceneError::EmptyScene { file } if file == "scene.toml"),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "scene.toml: the scene is empty: it has no triangles and no spheres"
    );

    let s = toml(
        &d.0,
        &SPHERE.replace(
            "type = \"diffuse\"",
            "type = \"diffuse\"\nalbedo = [1.5, 0.5, 1.0]",
        ),
    )
    .unwrap();
    assert_eq!(s.materials[0].albedo, Vec3::new(1.0, 0.5, 1.0));
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("material 'm'") && w.contains("clamped")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn syntax_errors_name_line_and_column() {
    let d = TempDir::new("toml-syntax");
    let e = toml(&d.0, "[camera]\nposition = [0, 0, 1\n").unwrap_err();
    assert!(
        matches!(
            e,
            SceneError::Syntax {
                at: Location::LineCol { line: 2 | 3, .. },
                ..
            }
        ),
        "{e}"
    );
}
