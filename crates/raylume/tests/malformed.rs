//! The malformed corpus: every file in `tests/malformed/` (and the binary ones generated below)
//! is run through the built `render` command, which must exit non-zero with a message naming
//! the problem, the file and, where the format has one, the place (line:column, line, JSON or
//! glTF path), print no `panicked`, and leave no output file (nor a temporary one) behind.
//!
//! Each row of the tables below is (scene file, extra flags, fragments the message must
//! contain). A control row renders the corpus's valid scenes, so a broken harness cannot pass.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// A private copy of the corpus with the generated binary files added (`generated/`), made
/// once per test binary. Commands run inside it, so messages name files as the table does.
fn corpus() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed");
        let dir = std::env::temp_dir().join(format!("raylume-malformed-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("generated")).unwrap();
        std::fs::create_dir_all(dir.join("out")).unwrap();
        for entry in std::fs::read_dir(&src).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), dir.join(entry.file_name())).unwrap();
        }
        for (name, bytes) in generated() {
            std::fs::write(dir.join("generated").join(name), bytes).unwrap();
        }
        dir
    })
}

/// Binary inputs, made here rather than committed.
fn generated() -> Vec<(&'static str, Vec<u8>)> {
    // A valid 4x2 EXR and HDR, then broken.
    let encode = |format| {
        let img = image::Rgb32FImage::from_fn(4, 2, |x, y| image::Rgb([x as f32, y as f32, 1.0]));
        let mut out = std::io::Cursor::new(Vec::new());
        image::DynamicImage::ImageRgb32F(img)
            .write_to(&mut out, format)
            .unwrap();
        out.into_inner()
    };
    let exr = encode(image::ImageFormat::OpenExr);
    let hdr = encode(image::ImageFormat::Hdr);
    // A GLB: 12-byte header ("glTF", version 2, total length), then the JSON chunk.
    let glb = |json: &str, declared_total: Option<u32>| {
        let mut j = json.as_bytes().to_vec();
        while !j.len().is_multiple_of(4) {
            j.push(b' ');
        }
        let total = declared_total.unwrap_or(12 + 8 + j.len() as u32);
        let mut out = b"glTF".to_vec();
        out.extend(2u32.to_le_bytes());
        out.extend(total.to_le_bytes());
        out.extend((j.len() as u32).to_le_bytes());
        out.extend(b"JSON");
        out.extend(j);
        out
    };
    let valid_gltf = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed/valid.gltf"),
    )
    .unwrap();
    let position_7 = valid_gltf.replace("\"POSITION\": 0", "\"POSITION\": 7");
    assert_ne!(position_7, valid_gltf);
    // A PNG whose (valid) header claims 100000 x 100000 pixels, and that holds none.
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(100_000u32.to_be_bytes());
    ihdr.extend(100_000u32.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]);
    let mut huge_png = b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0d".to_vec();
    huge_png.extend(&ihdr);
    huge_png.extend(crc32(&ihdr).to_be_bytes());
    for chunk in [&b"IDAT"[..], b"IEND"] {
        huge_png.extend(0u32.to_be_bytes());
        huge_png.extend(chunk);
        huge_png.extend(crc32(chunk).to_be_bytes());
    }
    vec![
        ("truncated.exr", exr[..exr.len() / 2].to_vec()),
        ("garbage.exr", b"v/1\x01\x02\x00\x00\x00garbage".to_vec()),
        ("truncated.hdr", hdr[..hdr.len() - 20].to_vec()),
        ("truncated.glb", glb(&valid_gltf, None)[..30].to_vec()),
        ("wrong_length.glb", glb(&valid_gltf, Some(1 << 30))),
        ("json_garbage.glb", glb("{ not json ]", None)),
        ("position_out_of_range.glb", glb(&position_7, None)),
        ("huge.png", huge_png),
        (
            "not_utf8.toml",
            b"[camera]\nposition = [0.0, 1.0, 5.0]\nvfov = 4\xff0.0\n".to_vec(),
        ),
        (
            "env_truncated_hdr.toml",
            std::fs::read_to_string(
                Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("tests/malformed/env_truncated_exr.toml"),
            )
            .unwrap()
            .replace("generated/truncated.exr", "truncated.hdr")
            .into_bytes(),
        ),
        (
            "texture_huge_png.toml",
            std::fs::read_to_string(
                Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed/texture_garbage.toml"),
            )
            .unwrap()
            .replace("garbage.png", "huge.png")
            .into_bytes(),
        ),
    ]
}

/// CRC-32 (IEEE), as PNG chunks carry it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn run(scene: &str, extra: &[&str], out: &Path) -> Output {
    let out_s = out.to_str().unwrap();
    let mut args = vec![scene, "-o", out_s, "--backend", "cpu", "-q"];
    args.extend(extra);
    Command::new(common::render_exe())
        .args(&args)
        .current_dir(corpus())
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("run render")
}

/// One malformed input: its scene file (relative to the corpus), extra flags, and the
/// fragments its error message must contain.
type Case = (
    &'static str,
    &'static [&'static str],
    &'static [&'static str],
);

/// Runs every case; collects every failure before failing, so one run shows them all.
fn check_all(cases: &[Case]) {
    let mut failures = Vec::new();
    for (i, (scene, extra, parts)) in cases.iter().enumerate() {
        let name = format!("{scene} {}", extra.join(" "));
        let out = corpus()
            .join("out")
            .join(format!("{}-{i}.png", scene.replace('/', "_")));
        let o = run(scene, extra, &out);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let stdout = String::from_utf8_lossy(&o.stdout);
        let mut problems = Vec::new();
        if o.status.success() {
            problems.push("exited 0".to_string());
        }
        // 101 is the exit code of a Rust panic.
        if o.status.code() == Some(101)
            || stderr.contains("panicked")
            || stdout.contains("panicked")
        {
            problems.push("panicked".into());
        }
        for part in *parts {
            if !stderr.contains(part) {
                problems.push(format!("message lacks `{part}`"));
            }
        }
        if out.exists() {
            problems.push(format!("left {}", out.display()));
        }
        let leftovers: Vec<_> = std::fs::read_dir(corpus().join("out"))
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(&format!("-{i}.")))
            .collect();
        if !leftovers.is_empty() {
            problems.push(format!("left temporary files {leftovers:?}"));
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{name}: {}\n    stderr: {stderr}",
                problems.join("; ")
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} malformed inputs mishandled:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

#[test]
fn the_valid_scenes_of_the_corpus_render() {
    // The control: the harness and the corpus's valid files work, so the failures below are
    // the malformed parts.
    for scene in ["valid.toml", "valid.gltf", "valid.json"] {
        let out = corpus().join("out").join(format!("{scene}.png"));
        let o = run(scene, &["--size", "8x8", "--spp", "1"], &out);
        assert!(
            o.status.success(),
            "{scene}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(out.exists(), "{scene}");
    }
}

#[test]
#[rustfmt::skip]
fn malformed_toml_scenes() {
    check_all(&[
        ("truncated.toml", &[], &["truncated.toml:2:", "syntax error", "unclosed array"]),
        ("garbage.toml", &[], &["garbage.toml:1:", "syntax error"]),
        ("generated/not_utf8.toml", &[], &["not_utf8.toml:3", "not valid UTF-8"]),
        ("empty.toml", &[], &["empty.toml", "the scene is empty"]),
        ("nan_camera.toml", &[], &["nan_camera.toml:2:", "position is not finite"]),
        // 1e39 overflows f32: it must not become a sphere of infinite radius.
        ("overflow_radius.toml", &[], &["overflow_radius.toml:12:", "radius is not finite"]),
        ("huge_emission.toml", &[], &["huge_emission.toml", "material 0 `white`", "emission 3e38 is above 1e20"]),
        ("negative_radius.toml", &[], &["negative_radius.toml:12:", "radius must be positive, got -1"]),
        ("unknown_key.toml", &[], &["unknown_key.toml:4:1", "unknown key `fov`", "`vfov`"]),
        ("wrong_type.toml", &[], &["wrong_type.toml:12:", "wrong type", "\"large\""]),
        ("unknown_material.toml", &[], &["unknown_material.toml:13:", "unknown material `chrome`"]),
        ("missing_mesh.toml", &[], &["meshes/missing.obj", "file not found", "referenced by missing_mesh.toml:11:"]),
        ("huge_image.toml", &[], &["huge_image.toml", "render width is 100000", "limit is 32768"]),
        ("zero_spp.toml", &[], &["zero_spp.toml:11:", "spp must be positive, got 0"]),
        ("mesh_bad_obj.toml", &[], &["face_out_of_range.obj:4", "vertex index 99 is out of range"]),
        ("mesh_cyclic_gltf.toml", &[], &["cyclic.gltf", "nodes[0]", "cycle"]),
        // The camera's fov and the materials' newer keys.
        ("both_fovs.toml", &[], &["both_fovs.toml:5:8", "`vfov` or `hfov`, not both"]),
        ("no_fov.toml", &[], &["no_fov.toml:1:1", "missing key `vfov` or `hfov`"]),
        ("two_sided_no_emission.toml", &[], &["two_sided_no_emission.toml:3:13", "needs a nonzero `emission`"]),
        ("unknown_conductor.toml", &[], &["unknown_conductor.toml:3:13", "unknown conductor `Chrome`", "Cr, "]),
        ("eta_without_k.toml", &[], &["eta_without_k.toml:3:7", "missing key `k`"]),
        ("plastic_tint.toml", &[], &["plastic_tint.toml:3:8", "unknown key `tint`", "plastic"]),
        ("rough_glass_nan.toml", &[], &["rough_glass_nan.toml:3:13", "roughness", "not finite"]),
    ]);
}

#[test]
#[rustfmt::skip]
fn malformed_obj_and_mtl() {
    check_all(&[
        ("face_out_of_range.obj", &[], &["face_out_of_range.obj:4", "vertex index 99 is out of range (there are 3)"]),
        ("zero_index.obj", &[], &["zero_index.obj:4", "vertex index 0 is out of range"]),
        ("truncated.obj", &[], &["truncated.obj:2", "syntax error"]),
        ("garbage.obj", &[], &["garbage.obj", "the scene is empty"]),
        ("nan_vertex.obj", &[], &["nan_vertex.obj", "triangle 0", "not finite"]),
        ("overflow_vertex.obj", &[], &["overflow_vertex.obj", "triangle 0", "not finite"]),
        ("missing_mtl.obj", &[], &["missing.mtl", "file not found", "referenced by missing_mtl.obj:1"]),
        ("bad_mtl.obj", &[], &["garbage.mtl:2", "syntax error"]),
        ("missing_map.obj", &[], &["textures/missing.png", "file not found", "missing_map.mtl", "map_Kd"]),
    ]);
}

#[test]
#[rustfmt::skip]
fn malformed_gltf_and_glb() {
    check_all(&[
        ("truncated.gltf", &[], &["truncated.gltf:", "syntax error", "EOF"]),
        // gltf-json itself panicked on this one; raylume checks it first.
        ("accessor_out_of_range.gltf", &[], &["accessor_out_of_range.gltf", "meshes[0].primitives[0].attributes.POSITION", "accessor index 7 is out of range (there are 2)"]),
        ("indices_out_of_range.gltf", &[], &["indices_out_of_range.gltf", "mesh 0 primitive 0 indices", "vertex index 9 is out of range (there are 3)"]),
        ("node_mesh_out_of_range.gltf", &[], &["node_mesh_out_of_range.gltf", "nodes[0].mesh", "out of bounds"]),
        ("cyclic.gltf", &[], &["cyclic.gltf", "nodes[0]", "a cycle or a shared child"]),
        ("missing_buffer.gltf", &[], &["buffers/missing.bin", "file not found", "missing_buffer.gltf: buffers[0]"]),
        ("accessor_past_buffer.gltf", &[], &["accessor_past_buffer.gltf", "accessor 0", "reads past the end of buffer view 0"]),
        ("overflow_translation.gltf", &[], &["overflow_translation.gltf", "nodes[0]", "not finite"]),
        ("generated/truncated.glb", &[], &["truncated.glb", "syntax error"]),
        ("generated/wrong_length.glb", &[], &["wrong_length.glb", "syntax error"]),
        ("generated/json_garbage.glb", &[], &["json_garbage.glb", "syntax error"]),
        ("generated/position_out_of_range.glb", &[], &["position_out_of_range.glb", "attributes.POSITION", "accessor index 7"]),
    ]);
}

#[test]
#[rustfmt::skip]
fn malformed_tungsten_json() {
    check_all(&[
        ("truncated.json", &[], &["truncated.json:21:1", "syntax error"]),
        ("unknown_bsdf.json", &[], &["unknown_bsdf.json", "primitives[0].bsdf", "unknown material `chrome`"]),
        ("bad_transform.json", &[], &["bad_transform.json", "primitives[0].transform.position", "expected a number"]),
        ("missing_mesh_file.json", &[], &["meshes/missing.obj", "file not found", "missing_mesh_file.json: primitives[0].file"]),
        ("overflow_scale.json", &[], &["overflow_scale.json", "primitives[0].transform.scale", "not finite"]),
    ]);
}

#[test]
#[rustfmt::skip]
fn malformed_images() {
    check_all(&[
        ("env_garbage_hdr.toml", &[], &["garbage.hdr", "cannot decode image", "referenced by env_garbage_hdr.toml:11:"]),
        ("generated/env_truncated_hdr.toml", &[], &["truncated.hdr", "cannot decode image"]),
        // The size is refused from the header, before anything is allocated.
        ("env_huge_hdr.toml", &[], &["huge_header.hdr", "too large", "100000x100000", "limit is 16384"]),
        ("env_truncated_exr.toml", &[], &["truncated.exr", "cannot decode image", "env_truncated_exr.toml:11:"]),
        ("env_garbage_exr.toml", &[], &["garbage.exr", "cannot decode image"]),
        ("env_missing.toml", &[], &["missing.hdr", "file not found", "env_missing.toml:11:"]),
        ("texture_garbage.toml", &[], &["garbage.png", "cannot decode image", "texture_garbage.toml:8:"]),
        ("generated/texture_huge_png.toml", &[], &["huge.png", "too large", "100000x100000", "limit is 16384"]),
    ]);
}

#[test]
#[rustfmt::skip]
fn absurd_flags() {
    check_all(&[
        ("valid.toml", &["--size", "0x0"], &["image size 0x0", "at least 1"]),
        ("valid.toml", &["--size", "100000x100000"], &["image size 100000x100000 is too large"]),
        ("valid.toml", &["--size", "99999999999x2"], &["99999999999x2"]),
        ("valid.toml", &["--spp", "0"], &["0 samples per pixel"]),
        ("valid.toml", &["--spp", "4294967295"], &["4294967295 samples per pixel: use 1 to 1048576"]),
        ("valid.toml", &["--bounces", "100000"], &["100000 bounces: use 0 to 1024"]),
        ("valid.toml", &["--exposure", "nan"], &["exposure nan stops"]),
        ("valid.toml", &["--exposure", "1e30"], &["exposure 1e30 stops"]),
        ("valid.toml", &["--schedule", "sideways"], &["unknown schedule `sideways`"]),
        ("valid.toml", &["--estimator", "guess"], &["unknown estimator `guess`"]),
        ("missing-scene.toml", &[], &["missing-scene.toml", "file not found"]),
        ("valid.stl", &[], &["valid.stl", "unsupported file extension"]),
        ("generated", &[], &["generated", "a folder, not a scene file", "scene.json"]),
    ]);
}
