//! [`Scene::validate`] on scenes built by hand: one broken invariant at a time, each a typed
//! error naming the index or key; and [`Scene::features`] on scenes that use / do not use each
//! feature.

use glam::{Vec2, Vec3};
use raylume_scene::{
    Bloom, Camera, Environment, Feature, Features, FovAxis, Location, Material, Scene, SceneError,
    Sphere, Texels, Texture, Triangle,
};

/// A valid scene: one triangle, one sphere, two materials, a texture.
fn good() -> Scene {
    let mut s = Scene {
        camera: Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov: 45.0,
            fov_axis: FovAxis::Vertical,
        },
        ..Scene::default()
    };
    s.materials
        .push(Material::diffuse("white", Vec3::splat(0.7)));
    s.materials.push(Material::glass("glass", 1.5, Vec3::ONE));
    s.textures.push(Texture {
        name: "t.png".into(),
        width: 1,
        height: 1,
        texels: vec![[0.5; 3]].into(),
    });
    s.materials[0].albedo_texture = Some(0);
    s.triangles.push(Triangle {
        positions: [Vec3::ZERO, Vec3::X, Vec3::Y],
        normals: Some([Vec3::Z; 3]),
        uvs: Some([Vec2::ZERO; 3]),
        material: 0,
    });
    s.spheres.push(Sphere {
        center: Vec3::new(0.0, 0.0, -2.0),
        radius: 1.0,
        material: 1,
    });
    s
}

/// Breaks `good()` with `f`, expects an error whose Debug starts with `variant` and whose
/// message contains `place`.
fn check(f: impl FnOnce(&mut Scene), variant: &str, place: &str) {
    let mut s = good();
    f(&mut s);
    let e = s.validate().unwrap_err();
    assert!(
        format!("{e:?}").starts_with(variant),
        "expected {variant}, got {e}"
    );
    let msg = e.to_string();
    assert!(
        msg.starts_with("<scene>") && msg.contains(place),
        "{msg} lacks {place}"
    );
}

#[test]
fn a_good_scene_validates() {
    good().validate().unwrap();
}

#[test]
fn every_invariant_has_its_error() {
    let nan = f32::NAN;
    check(
        |s| s.triangles[0].positions[1].y = nan,
        "NotFinite",
        "triangle 0",
    );
    check(
        |s| s.triangles[0].normals = Some([Vec3::new(0.0, f32::INFINITY, 0.0); 3]),
        "NotFinite",
        "triangle 0",
    );
    check(
        |s| s.triangles[0].uvs = Some([Vec2::new(nan, 0.0); 3]),
        "NotFinite",
        "triangle 0",
    );
    check(
        |s| s.triangles[0].normals = Some([Vec3::new(0.0, 0.0, 2.0); 3]),
        "InvalidValue",
        "unit length",
    );
    check(
        |s| s.triangles[0].material = 2,
        "IndexOutOfRange",
        "triangle 0: material index 2 is out of range (there are 2)",
    );
    check(
        |s| s.triangles[0].positions[2] = Vec3::new(2.0, 0.0, 0.0),
        "InvalidValue",
        "zero area",
    );
    check(|s| s.spheres[0].radius = 0.0, "NonPositive", "sphere 0");
    check(
        |s| s.spheres[0].radius = -1.0,
        "NonPositive",
        "sphere radius must be positive, got -1",
    );
    check(|s| s.spheres[0].center.x = nan, "NotFinite", "sphere 0");
    check(|s| s.spheres[0].material = 7, "IndexOutOfRange", "sphere 0");
    check(
        |s| s.materials[0].albedo_texture = Some(3),
        "IndexOutOfRange",
        "material 0 `white`: texture index 3",
    );
    check(
        |s| s.materials[0].albedo.x = -0.1,
        "Negative",
        "material 0 `white`",
    );
    check(|s| s.materials[0].albedo.x = 1.5, "InvalidValue", "above 1");
    check(
        |s| s.materials[0].emission.y = nan,
        "NotFinite",
        "material 0 `white`",
    );
    check(|s| s.materials[0].emission.y = -1.0, "Negative", "emission");
    check(
        |s| s.materials[1].ior = 0.0,
        "NonPositive",
        "material 1 `glass`: ior",
    );
    check(
        |s| s.materials[1].tint = Vec3::splat(-1.0),
        "Negative",
        "tint",
    );
    check(
        |s| s.materials[0].roughness = 2.0,
        "InvalidValue",
        "roughness 2 is outside [0, 1]",
    );
    check(
        |s| s.textures[0].texels = Texels::Linear(Vec::new()),
        "InvalidValue",
        "texture 0 `t.png`",
    );
    check(
        |s| s.textures[0].texels = vec![[0.5, nan, 0.5]].into(),
        "NotFinite",
        "texel (0, 0)",
    );
    check(|s| s.textures[0].width = 0, "NonPositive", "texture width");
    check(
        |s| s.camera.fov = 0.0,
        "Vfov",
        "camera: vfov 0 degrees is outside (0, 180)",
    );
    check(|s| s.camera.fov = 180.0, "Vfov", "camera");
    check(|s| s.camera.fov = nan, "NotFinite", "camera");
    check(
        |s| s.camera.position.z = f32::INFINITY,
        "NotFinite",
        "camera position",
    );
    check(
        |s| s.camera.look_at = s.camera.position,
        "DegenerateCamera",
        "position equals look_at",
    );
    check(
        |s| s.camera.up = Vec3::new(0.0, 0.0, -3.0),
        "DegenerateCamera",
        "parallel",
    );
    check(
        |s| s.camera.up = Vec3::ZERO,
        "DegenerateCamera",
        "up is zero",
    );
    check(
        |s| s.render.width = 0,
        "NonPositive",
        "render: render width",
    );
    check(|s| s.render.height = 0, "NonPositive", "render height");
    check(|s| s.render.spp = 0, "NonPositive", "render spp");
    check(|s| s.render.width = 100_000, "TooLarge", "render width");
    check(
        |s| s.environment = Environment::Constant(Vec3::new(1.0, -1.0, 1.0)),
        "Negative",
        "environment",
    );
    check(
        |s| {
            s.environment = Environment::Map {
                image: s.textures[0].clone(),
                strength: -2.0,
                rotation: 0.0,
            }
        },
        "Negative",
        "environment strength",
    );
    check(
        |s| {
            s.post.bloom = Some(Bloom {
                threshold: 1.0,
                radius: 0,
                strength: 0.3,
            })
        },
        "NonPositive",
        "post.bloom",
    );
    check(
        |s| {
            s.post.bloom = Some(Bloom {
                threshold: nan,
                radius: 2,
                strength: 0.3,
            })
        },
        "NotFinite",
        "bloom threshold",
    );
    check(
        |s| {
            s.triangles.clear();
            s.spheres.clear();
        },
        "EmptyScene",
        "no triangles and no spheres",
    );
}

/// Regression test: finite but absurd brightness (3e38 is a valid f32) used to pass, and the
/// renderer summed such samples into infinite pixels. Past `limits::MAX_RADIANCE` (1e20) and
/// `limits::MAX_BLOOM_STRENGTH` (1e6) it is a typed error naming the place.
#[test]
fn radiance_and_bloom_strength_have_limits() {
    use raylume_scene::limits::{MAX_BLOOM_STRENGTH, MAX_RADIANCE};
    check(
        |s| s.materials[1].emission = Vec3::new(0.0, 3e38, 0.0),
        "InvalidValue",
        "material 1 `glass`: invalid value: emission 3e38 is above 1e20",
    );
    check(
        |s| s.environment = Environment::Constant(Vec3::splat(1e21)),
        "InvalidValue",
        "environment: invalid value: environment radiance 1e21",
    );
    check(
        |s| {
            s.environment = Environment::Map {
                image: Texture {
                    name: "sky.exr".into(),
                    width: 2,
                    height: 1,
                    texels: vec![[1.0; 3], [1e12, 0.0, 0.0]].into(),
                },
                strength: 1e9,
                rotation: 0.0,
            }
        },
        "InvalidValue",
        "environment map radiance (brightest texel times strength) 1e21",
    );
    check(
        |s| {
            s.post.bloom = Some(Bloom {
                threshold: 1.0,
                radius: 2,
                strength: 1e7,
            })
        },
        "InvalidValue",
        "post.bloom: invalid value: bloom strength 1e7 is above 1e6",
    );
    // The limits themselves are accepted.
    let mut s = good();
    s.materials[0].emission = Vec3::splat(MAX_RADIANCE);
    s.environment = Environment::Constant(Vec3::splat(MAX_RADIANCE));
    s.post.bloom = Some(Bloom {
        threshold: 1.0,
        radius: 2,
        strength: MAX_BLOOM_STRENGTH,
    });
    s.validate().unwrap();
}

#[test]
fn errors_expose_file_and_location() {
    let mut s = good();
    s.spheres[0].radius = -1.0;
    let e = s.validate().unwrap_err();
    assert_eq!(e.file(), "<scene>");
    assert_eq!(e.location(), Some(&Location::path("sphere 0")));
    assert!(matches!(e, SceneError::NonPositive { .. }));
}

// --- Scene::features ------------------------------------------------------------------------

fn tri(material: u32) -> Triangle {
    Triangle::flat([Vec3::ZERO, Vec3::X, Vec3::Y], material)
}

fn with(materials: Vec<Material>, triangles: Vec<Triangle>) -> Scene {
    Scene {
        materials,
        triangles,
        ..Scene::default()
    }
}

#[test]
fn features_follow_the_materials_that_are_used() {
    let white = Material::diffuse("w", Vec3::ONE);
    let mirror = Material::metal("m", Vec3::ONE, 0.0);
    let rough = Material::metal("r", Vec3::ONE, 0.3);
    let glass = Material::glass("g", 1.5, Vec3::ONE);
    let lamp = Material::emissive("l", Vec3::splat(3.0));

    let s = with(
        vec![
            white.clone(),
            mirror.clone(),
            rough.clone(),
            glass.clone(),
            lamp.clone(),
        ],
        vec![tri(0)],
    );
    assert_eq!(
        s.features(),
        Features::NONE
            .with(Feature::Diffuse)
            .with(Feature::Triangles),
        "unused materials do not count"
    );
    let s = with(
        vec![white.clone(), mirror, rough, glass.clone(), lamp],
        (0..5).map(tri).collect(),
    );
    assert_eq!(
        s.features().names(),
        [
            "diffuse",
            "metal",
            "rough_metal",
            "glass",
            "emission",
            "triangles"
        ]
    );

    // Textures count on diffuse and metal, not on glass.
    let mut textured = white.clone();
    textured.albedo_texture = Some(0);
    let mut tinted_glass = glass;
    tinted_glass.albedo_texture = Some(0);
    assert!(
        with(vec![textured], vec![tri(0)])
            .features()
            .contains(Feature::Textures)
    );
    assert!(
        !with(vec![tinted_glass], vec![tri(0)])
            .features()
            .contains(Feature::Textures)
    );

    // Shading normals, spheres, environments, bloom.
    let mut s = with(vec![white], vec![tri(0)]);
    assert!(!s.features().contains(Feature::ShadingNormals));
    s.triangles[0].normals = Some([Vec3::Z; 3]);
    assert!(s.features().contains(Feature::ShadingNormals));
    assert!(!s.features().contains(Feature::Spheres));
    s.spheres.push(Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
        material: 0,
    });
    assert!(s.features().contains(Feature::Spheres));
    s.triangles.clear();
    assert!(!s.features().contains(Feature::Triangles));
    s.environment = Environment::Constant(Vec3::ZERO);
    assert!(
        !s.features().contains(Feature::ConstantEnvironment),
        "a black constant is no environment"
    );
    s.environment = Environment::Constant(Vec3::ONE);
    assert!(s.features().contains(Feature::ConstantEnvironment));
    s.environment = Environment::Map {
        image: Texture {
            name: "e".into(),
            width: 1,
            height: 1,
            texels: vec![[1.0; 3]].into(),
        },
        strength: 1.0,
        rotation: 0.0,
    };
    assert!(
        s.features().contains(Feature::EnvironmentMap)
            && !s.features().contains(Feature::ConstantEnvironment)
    );
    assert!(!s.features().contains(Feature::Bloom));
    s.post.bloom = Some(Bloom {
        threshold: 1.0,
        radius: 4,
        strength: 0.5,
    });
    assert!(s.features().contains(Feature::Bloom));
}

/// On a scene split between threads (`features` scans the triangles on every core): a
/// material used by one triangle only, and shading normals on one triangle only, count
/// wherever that triangle is, first, in the middle or last.
#[test]
fn features_see_every_triangle_of_a_large_scene() {
    let n = 200_000;
    let base = || {
        with(
            vec![
                Material::diffuse("w", Vec3::ONE),
                Material::metal("m", Vec3::ONE, 0.0),
            ],
            (0..n).map(|_| tri(0)).collect(),
        )
    };
    assert!(!base().features().contains(Feature::Metal));
    for at in [0, n / 2 + 1, n - 1] {
        let mut s = base();
        s.triangles[at].material = 1;
        assert!(s.features().contains(Feature::Metal), "metal at {at}");
        assert!(!s.features().contains(Feature::ShadingNormals));
        let mut s = base();
        s.triangles[at].normals = Some([Vec3::Z; 3]);
        assert!(
            s.features().contains(Feature::ShadingNormals),
            "normals at {at}"
        );
        assert!(!s.features().contains(Feature::Metal));
    }
}

#[test]
fn features_of_loaded_scenes() {
    // The TOML loader: spheres + glass + bloom + map; the doctest in lib.rs covers a plain one.
    let d = std::env::temp_dir().join(format!("raylume-scene-features-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let hdr = image::Rgb32FImage::from_pixel(2, 1, image::Rgb([1.0, 1.0, 1.0]));
    image::DynamicImage::ImageRgb32F(hdr)
        .save(d.join("sky.hdr"))
        .unwrap();
    let text = "[environment]\nmap = \"sky.hdr\"\n[materials.g]\ntype = \"glass\"\n\
                [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"g\"\n\
                [post.bloom]\nthreshold = 1\nradius = 2\nstrength = 0.5\n";
    let s = Scene::from_toml_str(text, &d, "f.toml").unwrap();
    std::fs::remove_dir_all(&d).unwrap();
    assert_eq!(
        s.features().names(),
        ["glass", "spheres", "environment_map", "bloom"]
    );
}
