//! glTF and GLB: a small file written here (JSON by hand, binary buffer from f32/u16 data), in
//! three containers (.gltf + .bin, .gltf with a data URI, .glb), loaded and checked against
//! transforms and the material mapping worked out by hand.

mod common;

use common::{TempDir, base64, f32_bytes, glb, u16_bytes};
use glam::{Mat4, Quat, Vec2, Vec3};
use raylume_scene::{Environment, Location, MaterialKind, Scene, SceneError};
use serde_json::{Value, json};

/// Buffer layout: quad positions (4 x vec3 = 48 bytes) | quad normals (48) | quad uvs (4 x vec2
/// = 32) | quad indices (6 x u16 = 12, padded to 12) | triangle positions (36).
fn buffer() -> Vec<u8> {
    let mut b = f32_bytes(&[0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.]);
    b.extend(f32_bytes(&[0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.]));
    b.extend(f32_bytes(&[0., 1., 1., 1., 1., 0., 0., 0.]));
    b.extend(u16_bytes(&[0, 1, 2, 0, 2, 3]));
    b.extend(f32_bytes(&[0., 0., 0., 0., 0., -1., 0., 1., 0.]));
    b
}

fn document(buffer_uri: Option<String>, len: usize) -> Value {
    let mut buf = json!({ "byteLength": len });
    if let Some(uri) = buffer_uri {
        buf["uri"] = json!(uri);
    }
    json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{ "nodes": [0, 2, 3, 4] }],
        "nodes": [
            { "translation": [10.0, 0.0, 0.0], "children": [1] },
            // 90 degrees about +z, uniform scale 2.
            { "rotation": [0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2], "scale": [2.0, 2.0, 2.0], "mesh": 0 },
            // Column-major matrix: translate (0, 0, -3).
            { "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,-3,1], "mesh": 1 },
            { "translation": [0.0, 1.0, 5.0], "camera": 0 },
            { "mesh": 2 }
        ],
        "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.5, "aspectRatio": 1.5, "znear": 0.1 } }],
        "meshes": [
            { "primitives": [{ "attributes": { "POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2 }, "indices": 3, "material": 0 }] },
            { "primitives": [{ "attributes": { "POSITION": 4 }, "material": 1 }] },
            { "primitives": [
                { "attributes": { "POSITION": 4 }, "material": 2 },
                { "attributes": { "POSITION": 4 }, "material": 3 },
                { "attributes": { "POSITION": 4 } }
            ] }
        ],
        "materials": [
            { "name": "painted", "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.6, 0.7, 1.0], "metallicFactor": 0.0, "baseColorTexture": { "index": 0 } } },
            { "name": "brass", "pbrMetallicRoughness": { "baseColorFactor": [0.9, 0.8, 0.4, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.3 } },
            { "name": "water", "extensions": { "KHR_materials_transmission": { "transmissionFactor": 1.0 }, "KHR_materials_ior": { "ior": 1.33 } } },
            { "name": "neon", "doubleSided": true, "emissiveFactor": [1.0, 0.5, 0.25], "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 4.0 } },
              "pbrMetallicRoughness": { "metallicFactor": 0.2 } }
        ],
        "textures": [{ "source": 0 }],
        "images": [{ "uri": format!("data:image/png;base64,{}", base64(&common::png_2x2())) }],
        "buffers": [buf],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 48 },
            { "buffer": 0, "byteOffset": 48, "byteLength": 48 },
            { "buffer": 0, "byteOffset": 96, "byteLength": 32 },
            { "buffer": 0, "byteOffset": 128, "byteLength": 12 },
            { "buffer": 0, "byteOffset": 140, "byteLength": 36 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0] },
            { "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2" },
            { "bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR" },
            { "bufferView": 4, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,-1], "max": [0,1,0] }
        ]
    })
}

/// The three containers of the same asset.
fn write_all(d: &TempDir) -> [std::path::PathBuf; 3] {
    let bin = buffer();
    d.write("asset.bin", &bin);
    let external = d.write(
        "external.gltf",
        document(Some("asset.bin".into()), bin.len()).to_string(),
    );
    let uri = format!("data:application/octet-stream;base64,{}", base64(&bin));
    let embedded = d.write("embedded.gltf", document(Some(uri), bin.len()).to_string());
    let binary = d.write(
        "binary.glb",
        glb(&document(None, bin.len()).to_string(), &bin),
    );
    [external, embedded, binary]
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

#[test]
fn three_containers_give_the_same_scene() {
    let d = TempDir::new("gltf-three");
    let scenes =
        write_all(&d).map(|p| Scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())));
    for s in &scenes[1..] {
        assert_eq!(s.triangles, scenes[0].triangles);
        assert_eq!(s.materials, scenes[0].materials);
        assert_eq!(s.camera, scenes[0].camera);
    }
}

#[test]
fn hierarchy_materials_and_camera() {
    let d = TempDir::new("gltf-check");
    let [path, ..] = write_all(&d);
    let s = Scene::load(&path).unwrap();
    // Quad (2) + triangle (1) + the triangle three times under mesh 2.
    assert_eq!(s.triangles.len(), 2 + 1 + 3);

    // Node 1 under node 0: world = T(10,0,0) * R_z(90) * S(2). Quad corner (1,0,0) -> (2,0,0)
    // -> (0,2,0) -> (10,2,0); (1,1,0) -> (2,2,0) -> (-2,2,0) -> (8,2,0).
    let world = Mat4::from_translation(Vec3::new(10.0, 0.0, 0.0))
        * Mat4::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_z(90f32.to_radians()),
            Vec3::ZERO,
        );
    let quad = &s.triangles[0..2];
    assert!(close(quad[0].positions[1], Vec3::new(10.0, 2.0, 0.0)));
    assert!(close(quad[0].positions[2], Vec3::new(8.0, 2.0, 0.0)));
    for (t, idx) in quad.iter().zip([[0, 1, 2], [0, 2, 3]]) {
        let corners = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        for (p, i) in t.positions.iter().zip(idx) {
            assert!(close(*p, world.transform_point3(corners[i])));
        }
        // Normal (0,0,1) under a rotation about z stays (0,0,1); uvs as stored (top-left origin).
        assert!(close(t.normals.unwrap()[0], Vec3::Z));
    }
    assert_eq!(
        quad[0].uvs.unwrap(),
        [
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 0.0)
        ]
    );
    // Node 2: the matrix moves the triangle to z - 3.
    assert_eq!(
        s.triangles[2].positions,
        [
            Vec3::new(0.0, 0.0, -3.0),
            Vec3::new(0.0, 0.0, -4.0),
            Vec3::new(0.0, 1.0, -3.0)
        ]
    );

    let m = |i: usize| &s.materials[s.triangles[i].material as usize];
    let painted = m(0);
    assert_eq!(
        (painted.name.as_str(), painted.kind, painted.albedo),
        ("painted", MaterialKind::Plastic, Vec3::new(0.5, 0.6, 0.7))
    );
    // glTF's dielectric: F0 0.04 = ior 1.5, roughnessFactor's default 1.
    assert_eq!((painted.ior, painted.roughness), (1.5, 1.0));
    assert_eq!(
        s.textures[painted.albedo_texture.unwrap() as usize]
            .texels
            .linear(2),
        [0.0, 0.0, 1.0]
    );
    let brass = m(2);
    assert_eq!(
        (brass.kind, brass.albedo, brass.roughness),
        (MaterialKind::Metal, Vec3::new(0.9, 0.8, 0.4), 0.3)
    );
    let water = m(3);
    assert_eq!(
        (water.kind, water.ior, water.tint),
        (MaterialKind::Glass, 1.33, Vec3::ONE)
    );
    let neon = m(4);
    assert_eq!(
        (neon.kind, neon.emission, neon.two_sided),
        (MaterialKind::Plastic, Vec3::new(4.0, 2.0, 1.0), true)
    );
    // glTF materials are single-sided by default: their emission leaves the front face only.
    assert!(!m(1).two_sided && !m(2).two_sided);
    // A primitive without a material: the grey default diffuse, not glTF's rough metal.
    assert_eq!(
        (m(5).name.as_str(), m(5).kind),
        ("default", MaterialKind::Diffuse)
    );

    // Camera at node 3: looking down -z from (0,1,5); yfov 0.5 rad; aspect 1.5 sets the width.
    let c = s.camera;
    assert_eq!(
        (c.position, c.look_at, c.up),
        (Vec3::new(0.0, 1.0, 5.0), Vec3::new(0.0, 1.0, 4.0), Vec3::Y)
    );
    assert!((c.fov - 0.5f32.to_degrees()).abs() < 1e-4);
    assert_eq!(c.fov_axis, raylume_scene::FovAxis::Vertical);
    assert_eq!((s.render.width, s.render.height), (768, 512));
    assert_eq!(s.environment, Environment::Black);
}

#[test]
fn toml_mesh_of_a_glb_with_override_and_transform() {
    let d = TempDir::new("gltf-toml");
    write_all(&d);
    let text = "[camera]\nposition = [0, 0, 20]\nlook_at = [0, 0, 0]\nvfov = 30\n\
                [materials.white]\ntype = \"diffuse\"\n\
                [[mesh]]\nfile = \"binary.glb\"\nmaterial = \"white\"\ntranslate = [0, 0, 100]\n";
    let s = Scene::from_toml_str(text, &d.0, "s.toml").unwrap();
    assert_eq!(s.materials.len(), 1, "the file's materials are not loaded");
    assert_eq!(s.textures.len(), 0);
    assert!(s.triangles.iter().all(|t| t.material == 0));
    assert_eq!(s.triangles[2].positions[0], Vec3::new(0.0, 0.0, 97.0));
    assert_eq!(
        s.camera.position,
        Vec3::new(0.0, 0.0, 20.0),
        "the TOML camera wins"
    );
}

/// Writes `doc` (with the standard buffer as asset.bin) and loads it.
fn load_doc(doc: &Value) -> SceneError {
    let d = TempDir::new("gltf-err");
    d.write("asset.bin", buffer());
    Scene::load(d.write("bad.gltf", doc.to_string())).unwrap_err()
}

#[test]
fn malformed_files_are_typed_errors_with_indices() {
    let len = buffer().len();
    let ok = document(Some("asset.bin".into()), len);

    // An accessor that reads past its buffer view.
    let mut doc = ok.clone();
    doc["accessors"][4]["count"] = json!(4);
    let e = load_doc(&doc);
    assert!(
        matches!(&e, SceneError::InvalidValue { at: Location::Path(p), .. } if p.contains("accessor 4")),
        "{e}"
    );

    // A buffer view past the end of its buffer.
    let mut doc = ok.clone();
    doc["bufferViews"][4]["byteLength"] = json!(400);
    doc["accessors"][4]["count"] = json!(30);
    let e = load_doc(&doc);
    assert!(matches!(&e, SceneError::InvalidValue { .. }), "{e}");

    // An index past the vertices.
    let mut bin = buffer();
    bin[128..130].copy_from_slice(&7u16.to_le_bytes());
    let d = TempDir::new("gltf-index");
    d.write("asset.bin", &bin);
    let e = Scene::load(d.write("i.gltf", ok.to_string())).unwrap_err();
    assert!(
        matches!(&e, SceneError::IndexOutOfRange { index: 7, len: 4, at: Location::Path(p), .. } if p.contains("mesh 0 primitive 0")),
        "{e}"
    );

    // POSITION that is not VEC3 f32.
    let mut doc = ok.clone();
    doc["accessors"][4]["type"] = json!("VEC2");
    let e = load_doc(&doc);
    assert!(
        matches!(
            &e,
            SceneError::WrongType { .. } | SceneError::InvalidValue { .. }
        ),
        "{e}"
    );

    // A node that is its own child.
    let mut doc = ok.clone();
    doc["nodes"][4]["children"] = json!([4]);
    let e = load_doc(&doc);
    assert!(matches!(&e, SceneError::InvalidValue { .. }), "{e}");
    assert!(e.to_string().contains("nodes[4]"), "{e}");

    // The buffer file is missing.
    let d = TempDir::new("gltf-missing");
    let e = Scene::load(d.write("m.gltf", ok.to_string())).unwrap_err();
    match &e {
        SceneError::MissingFile {
            path,
            referenced_by,
        } => {
            assert!(path.ends_with("asset.bin"));
            assert!(
                referenced_by
                    .as_deref()
                    .is_some_and(|r| r.ends_with("m.gltf: buffers[0]")),
                "{e}"
            );
        }
        other => panic!("{other}"),
    }

    // Broken JSON: line and column.
    let d = TempDir::new("gltf-json");
    let e = Scene::load(d.write(
        "j.gltf",
        "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [}\n",
    ))
    .unwrap_err();
    assert!(
        matches!(
            &e,
            SceneError::Syntax {
                at: Location::LineCol { line: 3, .. },
                ..
            }
        ),
        "{e}"
    );

    // A shorter buffer than byteLength says.
    let mut doc = ok.clone();
    doc["buffers"][0]["byteLength"] = json!(len + 100);
    let e = load_doc(&doc);
    assert!(e.to_string().contains("buffers[0]"), "{e}");

    // Sparse accessors are refused by name.
    let mut doc = ok.clone();
    doc["accessors"][4]["sparse"] = json!({ "count": 1, "indices": { "bufferView": 3, "componentType": 5123 }, "values": { "bufferView": 4 } });
    let e = load_doc(&doc);
    assert!(matches!(&e, SceneError::Unsupported { .. }), "{e}");
}

#[test]
fn glb_without_a_camera_is_framed() {
    let d = TempDir::new("gltf-nocam");
    let bin = buffer();
    let mut doc = document(None, bin.len());
    doc["scenes"][0]["nodes"] = json!([2]);
    let s = Scene::load(d.write("t.glb", glb(&doc.to_string(), &bin))).unwrap();
    assert_eq!(s.triangles.len(), 1);
    // The triangle spans (0,0,-4)..(0,1,-3): centre (0, 0.5, -3.5).
    assert_eq!(s.camera.look_at, Vec3::new(0.0, 0.5, -3.5));
    assert_eq!(s.camera.fov, 40.0);
}
