//! The Tungsten importer on small hand-written `scene.json` files: every BSDF type, emitters
//! given by power, spheres, environments, matrix transforms, and typed errors with JSON paths.

mod common;

use common::TempDir;
use glam::Vec3;
use raylume_scene::{Environment, Location, MaterialKind, Scene, SceneError};
use serde_json::{Value, json};

fn load(doc: &Value) -> Result<Scene, SceneError> {
    let d = TempDir::new("tungsten");
    d.write("tex.png", common::png_2x2());
    d.write(
        "sky.hdr",
        common::float_image(4, 2, image::ImageFormat::Hdr),
    );
    Scene::load(d.write("scene.json", doc.to_string()))
}

/// One unit quad per BSDF, stacked along z so that none is degenerate or shared.
fn quads_with(bsdfs: Value) -> Value {
    let prims: Vec<Value> = bsdfs
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(i, b)| json!({ "type": "quad", "bsdf": b["name"], "transform": { "position": [0, 0, i] } }))
        .collect();
    json!({ "bsdfs": bsdfs, "primitives": prims, "camera": { "transform": { "position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, 1] } } })
}

#[test]
fn every_bsdf_type_maps_to_the_documented_material() {
    let bsdfs = json!([
        { "name": "lam", "type": "lambert", "albedo": [0.2, 0.4, 0.6] },
        { "name": "on", "type": "oren_nayar", "albedo": 0.5, "roughness": 1.0 },
        { "name": "pl", "type": "plastic", "albedo": 0.3 },
        { "name": "rp", "type": "rough_plastic", "albedo": "tex.png", "roughness": 0.1 },
        { "name": "ph", "type": "phong", "albedo": 0.7 },
        { "name": "mir", "type": "mirror", "albedo": 0.9 },
        { "name": "cu", "type": "conductor" },
        { "name": "au", "type": "rough_conductor", "material": "Au", "roughness": 0.04 },
        { "name": "ek", "type": "conductor", "eta": 1.5, "k": 0.0 },
        { "name": "die", "type": "dielectric", "ior": 1.33, "albedo": [0.9, 0.95, 1.0] },
        { "name": "rd", "type": "rough_dielectric", "ior": 1.6 },
        { "name": "ts", "type": "thinsheet" },
        { "name": "tr", "type": "transparency", "alpha": 0.5, "base": { "type": "lambert", "albedo": 0.25 } },
        { "name": "trn", "type": "transparency", "base": "lam" },
        { "name": "mix", "type": "mixed", "ratio": 0.25, "bsdf0": "mir", "bsdf1": "lam" },
        { "name": "coat", "type": "smooth_coat", "substrate": { "type": "lambert", "albedo": 0.125 } },
        { "name": "nul", "type": "null" },
        { "name": "bm", "type": "lambert", "albedo": { "type": "bitmap", "file": "tex.png" } },
        { "name": "cst", "type": "lambert", "albedo": { "type": "constant", "value": 0.375 } }
    ]);
    let s = load(&quads_with(bsdfs)).unwrap();
    let m = |n: &str| {
        s.materials
            .iter()
            .find(|m| m.name == n)
            .unwrap_or_else(|| panic!("{n}"))
    };
    let kind = |n: &str| m(n).kind;
    use MaterialKind::*;
    assert_eq!(
        (kind("lam"), m("lam").albedo),
        (Diffuse, Vec3::new(0.2, 0.4, 0.6))
    );
    for n in ["on", "ph", "bm", "cst"] {
        assert_eq!(kind(n), Diffuse, "{n}");
    }
    // Plastics: smooth (alpha 0) and rough (GGX alpha 0.1 -> roughness sqrt(0.1)), ior 1.5.
    assert_eq!(
        (kind("pl"), m("pl").albedo, m("pl").roughness, m("pl").ior),
        (Plastic, Vec3::splat(0.3), 0.0, 1.5)
    );
    assert_eq!(kind("rp"), Plastic);
    assert!((m("rp").roughness - 0.1f32.sqrt()).abs() < 1e-6);
    assert_eq!(
        m("rp").albedo_texture,
        m("bm").albedo_texture,
        "one texture file, loaded once"
    );
    assert_eq!(s.textures.len(), 1);
    assert_eq!(m("cst").albedo, Vec3::splat(0.375));
    assert_eq!(
        (kind("mir"), m("mir").albedo, m("mir").roughness),
        (Metal, Vec3::splat(0.9), 0.0)
    );
    // Tungsten's default conductor is copper, albedo 1, with Mitsuba's RGB complex IOR.
    let ior = |n: &str| (m(n).conductor_eta, m(n).conductor_k);
    assert_eq!((kind("cu"), m("cu").albedo), (Metal, Vec3::ONE));
    assert_eq!(ior("cu"), raylume_scene::conductor_ior("Cu").unwrap());
    // Gold, GGX alpha 0.04 -> roughness 0.2.
    assert_eq!(ior("au"), raylume_scene::conductor_ior("Au").unwrap());
    assert!((m("au").roughness - 0.2).abs() < 1e-6);
    // eta and k given as numbers.
    assert_eq!(ior("ek"), (Vec3::splat(1.5), Vec3::ZERO));
    assert_eq!(
        (kind("die"), m("die").ior, m("die").tint),
        (Glass, 1.33, Vec3::new(0.9, 0.95, 1.0))
    );
    // rough_dielectric: default GGX alpha 0.1.
    assert_eq!((kind("rd"), m("rd").ior), (Glass, 1.6));
    assert!((m("rd").roughness - 0.1f32.sqrt()).abs() < 1e-6);
    assert_eq!(m("die").roughness, 0.0);
    assert_eq!((kind("ts"), m("ts").ior), (Glass, 1.5));
    assert_eq!((kind("tr"), m("tr").albedo), (Diffuse, Vec3::splat(0.25)));
    assert_eq!(
        (kind("trn"), m("trn").albedo),
        (Diffuse, Vec3::new(0.2, 0.4, 0.6))
    );
    // ratio 0.25 is bsdf0's weight: bsdf1 (lambert) is heavier.
    assert_eq!(kind("mix"), Diffuse);
    assert_eq!(
        (kind("coat"), m("coat").albedo),
        (Diffuse, Vec3::splat(0.125))
    );
    assert_eq!((kind("nul"), m("nul").albedo), (Diffuse, Vec3::ZERO));

    // Approximations are named, exact mappings are not.
    let warned = |n: &str, ty: &str| {
        s.warnings
            .iter()
            .any(|w| w.starts_with(&format!("material '{n}': Tungsten '{ty}' approximated as")))
    };
    for (n, ty) in [
        ("on", "oren_nayar"),
        ("ph", "phong"),
        ("ts", "thinsheet"),
        ("tr", "transparency"),
        ("mix", "mixed"),
        ("coat", "smooth_coat"),
        ("nul", "null"),
    ] {
        assert!(warned(n, ty), "no warning for {n} in {:?}", s.warnings);
    }
    for n in [
        "lam", "mir", "die", "bm", "pl", "rp", "cu", "au", "ek", "rd",
    ] {
        assert!(
            !s.warnings
                .iter()
                .any(|w| w.starts_with(&format!("material '{n}'"))),
            "{n}: {:?}",
            s.warnings
        );
    }
}

#[test]
fn power_becomes_radiance_over_area_times_pi() {
    // A 2 x 3 quad (area 6) with power 6 pi emits radiance 1; a sphere of radius 2 (area 16 pi)
    // with power 16 pi^3 emits pi.
    let pi = std::f32::consts::PI;
    let doc = json!({
        "bsdfs": [{ "name": "w", "type": "lambert", "albedo": 0.5 }],
        "primitives": [
            { "type": "quad", "bsdf": "w", "power": 6.0 * pi, "transform": { "scale": [2, 1, 3] } },
            { "type": "sphere", "bsdf": "w", "power": 16.0 * pi * pi * pi, "transform": { "position": [0, 5, 0], "scale": 2 } },
            { "type": "cube", "bsdf": "w", "transform": { "position": [0, -5, 0] } },
            { "type": "quad", "bsdf": "w", "emission": [1, 2, 3], "transform": { "position": [0, 0, 9] } }
        ]
    });
    let s = load(&doc).unwrap();
    assert_eq!((s.triangles.len(), s.spheres.len()), (2 + 12 + 2, 1));
    let e = |i: usize| s.materials[s.triangles[i].material as usize].emission;
    assert!((e(0) - Vec3::ONE).abs().max_element() < 1e-5, "{}", e(0));
    let sp = s.spheres[0];
    assert_eq!((sp.center, sp.radius), (Vec3::new(0.0, 5.0, 0.0), 2.0));
    assert!(
        (s.materials[sp.material as usize].emission - Vec3::splat(pi))
            .abs()
            .max_element()
            < 1e-4
    );
    assert_eq!(e(2), Vec3::ZERO);
    assert_eq!(e(14), Vec3::new(1.0, 2.0, 3.0));
    // The shared BSDF appears once plain and once per distinct emission; names stay apart.
    assert_eq!(s.materials.len(), 4, "{:#?}", s.materials);
    let names: std::collections::HashSet<_> = s.materials.iter().map(|m| m.name.clone()).collect();
    assert_eq!(names.len(), 4);
    // No camera: framed on the bounds.
    assert_eq!(s.camera.fov, 40.0);
}

#[test]
fn environments_and_matrix_transforms() {
    let base = |env: Value| {
        json!({
            "bsdfs": [{ "name": "w", "type": "lambert" }],
            "primitives": [
                // Row-major matrix: translate by (1, 2, 3).
                { "type": "quad", "bsdf": "w", "transform": [1, 0, 0, 1, 0, 1, 0, 2, 0, 0, 1, 3, 0, 0, 0, 1] },
                env
            ]
        })
    };
    let s = load(&base(
        json!({ "type": "infinite_sphere", "emission": [0.5, 0.5, 1.0] }),
    ))
    .unwrap();
    assert_eq!(
        s.environment,
        Environment::Constant(Vec3::new(0.5, 0.5, 1.0))
    );
    let b = s.bounds();
    assert_eq!(
        (b.min, b.max),
        (Vec3::new(0.5, 2.0, 2.5), Vec3::new(1.5, 2.0, 3.5))
    );
    let s = load(&base(
        json!({ "type": "infinite_sphere", "emission": "sky.hdr" }),
    ))
    .unwrap();
    // Tungsten's u = 0.5 + atan2(z, x) / 2 pi; raylume's u = 0.5 + atan2(x, -z) / 2 pi + r / 360.
    // For +x Tungsten reads u = 0.5 and raylume 0.75 + r / 360: r = -90 makes them agree.
    assert!(
        matches!(&s.environment, Environment::Map { image, strength, rotation }
        if image.width == 4 && *strength == 1.0 && *rotation == -90.0)
    );
    let s = load(&base(json!({ "type": "skydome", "intensity": 3.0 }))).unwrap();
    assert_eq!(s.environment, Environment::Constant(Vec3::splat(3.0)));
    assert!(s.warnings.iter().any(|w| w.contains("skydome")));
    let e = load(&base(
        json!({ "type": "infinite_sphere", "emission": "gone.exr" }),
    ))
    .unwrap_err();
    assert!(
        matches!(&e, SceneError::MissingFile { path, referenced_by } if path.ends_with("gone.exr") && referenced_by.as_deref().is_some_and(|r| r.ends_with("primitives[1].emission"))),
        "{e}"
    );
}

/// `check(document, variant, JSON path in the message)`.
fn check(doc: Value, variant: &str, path: &str) {
    let e = load(&doc).unwrap_err();
    assert!(
        format!("{e:?}").starts_with(variant),
        "expected {variant}, got {e}"
    );
    assert!(e.to_string().contains(path), "{e} lacks {path}");
}

#[test]
fn errors_name_the_json_path() {
    let w = || json!([{ "name": "w", "type": "lambert" }]);
    let one = |p: Value| json!({ "bsdfs": w(), "primitives": [p] });
    check(
        one(json!({ "type": "quad", "bsdf": "nope" })),
        "UnknownMaterial",
        "primitives[0].bsdf",
    );
    check(
        one(json!({ "type": "disk", "bsdf": "w" })),
        "Unsupported",
        "primitives[0].type",
    );
    check(
        one(json!({ "type": "quad", "bsdf": "w", "transform": { "scale": "big" } })),
        "WrongType",
        "primitives[0].transform.scale",
    );
    check(
        one(json!({ "type": "quad", "bsdf": "w", "transform": { "position": [0, 0] } })),
        "WrongType",
        "primitives[0].transform.position",
    );
    check(
        one(json!({ "type": "quad", "bsdf": "w", "transform": { "position": [0, 1e39, 0] } })),
        "NotFinite",
        "primitives[0].transform.position",
    );
    check(
        one(json!({ "type": "quad", "bsdf": "w", "emission": [1, -1, 1] })),
        "Negative",
        "material",
    );
    check(
        one(json!({ "type": "mesh", "bsdf": "w", "file": "m.wo3" })),
        "UnsupportedExtension",
        "primitives[0].file",
    );
    check(
        one(json!({ "type": "mesh", "bsdf": "w", "file": "gone.obj" })),
        "MissingFile",
        "primitives[0].file",
    );
    check(
        one(json!({ "type": "mesh", "bsdf": "w" })),
        "MissingKey",
        "primitives[0]",
    );
    check(
        one(json!({ "type": "quad", "bsdf": "w", "power": 1.0, "transform": { "scale": 0 } })),
        "NonPositive",
        "primitives[0].power",
    );
    check(
        json!({ "bsdfs": [{ "name": "h", "type": "hair" }], "primitives": [{ "type": "quad", "bsdf": "h" }] }),
        "Unsupported",
        "bsdfs[0].type",
    );
    check(
        json!({ "bsdfs": [{ "name": "c", "type": "lambert", "albedo": { "type": "checker" } }], "primitives": [{ "type": "quad", "bsdf": "c" }] }),
        "Unsupported",
        "bsdfs[0].albedo",
    );
    check(
        json!({ "bsdfs": [w()[0].clone(), w()[0].clone()], "primitives": [] }),
        "InvalidValue",
        "bsdfs[1].name",
    );
    check(
        json!({ "bsdfs": [{ "name": "a", "type": "transparency", "base": "a" }], "primitives": [{ "type": "quad", "bsdf": "a" }] }),
        "InvalidValue",
        "nested too deeply",
    );
    check(
        json!({ "bsdfs": w(), "primitives": [] }),
        "EmptyScene",
        "scene.json",
    );
    check(
        json!({ "bsdfs": w(), "primitives": [{ "type": "quad", "bsdf": "w" }], "camera": { "fov": 200 } }),
        "Vfov",
        "camera.fov",
    );
    check(
        json!({ "bsdfs": w(), "primitives": [{ "type": "quad", "bsdf": "w" }], "camera": { "resolution": [0, 10] } }),
        "NonPositive",
        "camera.resolution",
    );
    check(
        json!({ "bsdfs": w(), "primitives": [{ "type": "quad", "bsdf": "w" }], "camera": { "transform": { "position": [0, 0, 0], "look_at": [0, 0, 0] } } }),
        "DegenerateCamera",
        "camera",
    );
    check(
        json!({ "bsdfs": w(), "primitives": [{ "type": "quad", "bsdf": "w" }], "renderer": { "spp": -1 } }),
        "WrongType",
        "renderer.spp",
    );
    check(json!([1, 2]), "WrongType", "scene.json");

    let d = TempDir::new("tungsten-syntax");
    let e = Scene::load(d.write(
        "scene.json",
        "{\n  \"bsdfs\": [\n    {\"name\": }\n  ]\n}\n",
    ))
    .unwrap_err();
    assert!(
        matches!(
            &e,
            SceneError::Syntax {
                at: Location::LineCol {
                    line: 3,
                    column: 14
                },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn unread_keys_are_reported_not_silently_dropped() {
    let doc = json!({
        "bsdfs": [{ "name": "w", "type": "lambert", "bump": "b.png" }],
        "primitives": [{ "type": "quad", "bsdf": "w", "sampled_side": -1, "backface_culling": true }],
        "media": [{ "name": "fog" }]
    });
    let s = load(&doc).unwrap();
    let all = s.warnings.join("\n");
    for part in [
        "primitives[0].sampled_side",
        "primitives[0].backface_culling = true",
        "media",
        "bump map ignored",
    ] {
        assert!(all.contains(part), "{part} not in {all}");
    }
}

/// The importer decodes the BSDFs' image files ahead of the materials (on every core, while
/// the meshes parse): what it decoded must be what reading them in order gives (each file
/// once, however many BSDFs and nestings name it), and a file that does not decode must fail
/// with the place that references it, as it did when textures were read one by one.
#[test]
fn prefetched_textures_are_the_referenced_ones_and_errors_keep_their_place() {
    let d = TempDir::new("tungsten-prefetch");
    d.write("tex.png", common::png_2x2());
    d.write("bad.png", b"not a png");
    let ok = json!({
        "bsdfs": [
            { "name": "a", "type": "lambert", "albedo": "tex.png" },
            { "name": "b", "type": "lambert", "albedo": { "type": "bitmap", "file": "tex.png" } },
            { "name": "c", "type": "transparency", "alpha": 1.0, "base": { "type": "lambert", "albedo": "tex.png" } },
            { "name": "d", "type": "lambert", "albedo": 0.5 }
        ],
        "primitives": [
            { "type": "quad", "bsdf": "a" },
            { "type": "quad", "bsdf": "b", "transform": { "position": [0, 0, 1] } },
            { "type": "quad", "bsdf": "c", "transform": { "position": [0, 0, 2] } },
            { "type": "quad", "bsdf": "d", "transform": { "position": [0, 0, 3] } }
        ]
    });
    let s = Scene::load(d.write("ok.json", ok.to_string())).unwrap();
    assert_eq!(s.textures.len(), 1, "one file, one texture");
    let alone = Scene::load(
        d.write(
            "alone.json",
            json!({ "bsdfs": [{ "name": "a", "type": "lambert", "albedo": "tex.png" }],
                "primitives": [{ "type": "quad", "bsdf": "a" }] })
            .to_string(),
        ),
    )
    .unwrap();
    assert_eq!(s.textures, alone.textures);
    for m in ["a", "b", "c"] {
        let m = s.materials.iter().find(|x| x.name == m).unwrap();
        assert_eq!(m.albedo_texture, Some(0));
    }

    // The second BSDF's file is corrupt, the third's missing: the first reference in the
    // materials' order fails, naming its JSON path.
    let bad = json!({
        "bsdfs": [
            { "name": "a", "type": "lambert", "albedo": "tex.png" },
            { "name": "b", "type": "lambert", "albedo": { "type": "bitmap", "file": "bad.png" } },
            { "name": "c", "type": "lambert", "albedo": "gone.png" }
        ],
        "primitives": [
            { "type": "quad", "bsdf": "a" },
            { "type": "quad", "bsdf": "b", "transform": { "position": [0, 0, 1] } },
            { "type": "quad", "bsdf": "c", "transform": { "position": [0, 0, 2] } }
        ]
    });
    let e = Scene::load(d.write("bad.json", bad.to_string())).unwrap_err();
    assert!(
        matches!(e, SceneError::Image { .. }) && e.to_string().contains("bsdfs[1].albedo.file"),
        "{e:?}"
    );
    let gone = json!({
        "bsdfs": [{ "name": "c", "type": "lambert", "albedo": "gone.png" }],
        "primitives": [{ "type": "quad", "bsdf": "c" }]
    });
    let e = Scene::load(d.write("gone.json", gone.to_string())).unwrap_err();
    assert!(e.to_string().contains("bsdfs[0].albedo"), "{e:?}");

    // The meshes are added while the images decode: a corrupt image referenced by a primitive
    // before a broken mesh is the error, and a broken mesh before the corrupt image's first
    // reference is, as in the file's order.
    d.write("broken.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
    let mesh = |bsdf: &str| json!({ "type": "mesh", "file": "broken.obj", "bsdf": bsdf });
    let quad = |bsdf: &str| json!({ "type": "quad", "bsdf": bsdf });
    let bsdfs = json!([
        { "name": "fine", "type": "lambert", "albedo": 0.5 },
        { "name": "corrupt", "type": "lambert", "albedo": "bad.png" }
    ]);
    let texture_first = json!({ "bsdfs": bsdfs, "primitives": [quad("corrupt"), mesh("fine")] });
    let e = Scene::load(d.write("texture-first.json", texture_first.to_string())).unwrap_err();
    assert!(
        matches!(e, SceneError::Image { .. }) && e.to_string().contains("bsdfs[1].albedo"),
        "{e:?}"
    );
    let mesh_first = json!({ "bsdfs": bsdfs, "primitives": [mesh("fine"), quad("corrupt")] });
    let e = Scene::load(d.write("mesh-first.json", mesh_first.to_string())).unwrap_err();
    assert!(
        !matches!(e, SceneError::Image { .. }) && e.to_string().contains("broken.obj"),
        "{e:?}"
    );
}

/// `Scene::load_with` calls its hook once, with the geometry, materials, camera and settings
/// final (degenerate triangles already dropped) while the images may still decode, keeps
/// what the hook changed, and returns the scene `Scene::load` returns; it does not call the
/// hook when loading fails, and the errors keep the file's order: a corrupt image referenced
/// before a bad emitter is the error.
#[test]
fn load_with_hands_over_the_final_geometry_before_the_textures() {
    let d = TempDir::new("tungsten-load-with");
    d.write("tex.png", common::png_2x2());
    d.write("bad.png", b"not a png");
    let doc = json!({
        "bsdfs": [
            { "name": "a", "type": "lambert", "albedo": "tex.png" },
            { "name": "b", "type": "lambert", "albedo": 0.5 }
        ],
        "primitives": [
            { "type": "quad", "bsdf": "a" },
            { "type": "quad", "bsdf": "b", "transform": { "position": [0, 0, 1] } },
            // Degenerate (all its points on a line): dropped before the hook sees the scene.
            { "type": "quad", "bsdf": "b", "transform": { "position": [0, 0, 2], "scale": [0, 1, 1] } }
        ],
        "camera": { "transform": { "position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, 1] } }
    });
    let path = d.write("scene.json", doc.to_string());
    let plain = Scene::load(&path).unwrap();
    let mut calls = 0;
    let mut seen = None;
    let hooked = Scene::load_with(&path, |s| {
        calls += 1;
        seen = Some((s.triangles.clone(), s.materials.clone(), s.camera, s.render));
        s.render.spp = 7;
    })
    .unwrap();
    assert_eq!(calls, 1);
    let (triangles, materials, camera, render) = seen.unwrap();
    assert_eq!(triangles, plain.triangles, "the final geometry");
    assert_eq!(materials, plain.materials);
    assert_eq!((camera, render), (plain.camera, plain.render));
    assert_eq!(
        hooked.textures, plain.textures,
        "the textures settled after the hook"
    );
    assert_eq!(hooked.render.spp, 7, "the hook's change kept");
    assert_eq!(hooked.triangles, plain.triangles);

    // A corrupt image referenced before an unsupported emitter: the image's error, and the
    // hook is never called.
    let bad = json!({
        "bsdfs": [{ "name": "c", "type": "lambert", "albedo": "bad.png" }],
        "primitives": [{ "type": "quad", "bsdf": "c" }],
        "emissions": [{ "type": "nonsense" }]
    });
    let mut called = false;
    let e = Scene::load_with(d.write("bad.json", bad.to_string()), |_| called = true).unwrap_err();
    assert!(
        matches!(e, SceneError::Image { .. }) && e.to_string().contains("bsdfs[0].albedo"),
        "{e:?}"
    );
    assert!(!called);
    // The emitter alone: its own error.
    let emitter = json!({
        "bsdfs": [{ "name": "c", "type": "lambert", "albedo": "tex.png" }],
        "primitives": [{ "type": "quad", "bsdf": "c" }],
        "emissions": [{ "type": "nonsense" }]
    });
    let e = Scene::load_with(d.write("emitter.json", emitter.to_string()), |_| {}).unwrap_err();
    assert!(e.to_string().contains("emission"), "{e:?}");

    // Other formats call the hook once too, at the end.
    let mut toml_calls = 0;
    let s = Scene::load_with(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/cornell-box.toml"),
        |_| toml_calls += 1,
    );
    assert!(s.is_ok(), "{s:?}");
    assert_eq!(toml_calls, 1);
}

#[test]
fn a_folder_is_the_tungsten_scene_it_holds() {
    // Tungsten's and Bitterli's scenes are folders around a scene.json: the folder loads as
    // that file (the same triangles and materials, its textures found beside it).
    let d = TempDir::new("folder");
    d.write("tex.png", common::png_2x2());
    let bsdfs = json!([
        { "name": "lam", "type": "lambert", "albedo": "tex.png" },
        { "name": "pl", "type": "plastic", "albedo": 0.3 },
    ]);
    d.write("scene.json", quads_with(bsdfs).to_string());
    let from_folder = Scene::load(&d.0).unwrap();
    let from_file = Scene::load(d.path("scene.json")).unwrap();
    assert_eq!(from_folder.triangles.len(), 4);
    assert_eq!(
        format!("{:?}", from_folder.triangles),
        format!("{:?}", from_file.triangles)
    );
    assert_eq!(
        format!("{:?}", from_folder.materials),
        format!("{:?}", from_file.materials)
    );
    assert_eq!(from_folder.textures.len(), 1);
    // A folder without one is a typed error that names it, not "unsupported extension".
    let empty = TempDir::new("folder-empty");
    let e = Scene::load(&empty.0).unwrap_err();
    assert!(matches!(e, SceneError::Folder { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains(&empty.0.display().to_string()) && msg.contains("scene.json"),
        "{msg}"
    );
}
