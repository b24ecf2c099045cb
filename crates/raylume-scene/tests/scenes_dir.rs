//! Every scene shipped in the repository's `scenes/` folder loads with [`Scene::load`], and has
//! the triangle, sphere and material counts and the bounds worked out *independently of the
//! loaders*: by hand from the scene files (derivations in the comments), by the teapot
//! generator's arithmetic, by evaluating the teapot's Bézier patches here, and by parsing the
//! living room's OBJ files here.
//!
//! A cross-check ties the TOML loader and the Tungsten importer together: the hand-transcribed
//! `scenes/cornell-box.toml` and Bitterli's original Tungsten `scene.json` (beside the checkout
//! in `../shared`; skipped visibly when absent, a failure under `RAYLUME_REQUIRE_EXTERNAL=1`)
//! must give the same triangles and materials.

mod common;

use std::path::{Path, PathBuf};

use common::shared_external;
use glam::{DVec3, Vec3};
use raylume_scene::{Environment, MaterialKind, Scene, Triangle};

/// The repository root (this crate lives in `crates/raylume-scene`).
fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scenes_dir() -> PathBuf {
    repo_root().join("scenes")
}

fn load(relative: &str) -> Scene {
    let path = scenes_dir().join(relative);
    match Scene::load(&path) {
        Ok(scene) => scene,
        Err(e) => panic!("scenes/{relative} does not load: {e}"),
    }
}

/// Bounds agree to 1e-4 of the box's diagonal: vertices go through f32 parsing, f32 transforms
/// and (teapot) f64 -> f32 rounding, all ~1e-7 relative; 1e-4 still catches any misplaced
/// primitive or wrong transform.
fn assert_bounds(file: &str, scene: &Scene, min: [f64; 3], max: [f64; 3]) {
    let b = scene.bounds();
    let (min, max) = (DVec3::from(min), DVec3::from(max));
    let tol = 1e-4 * (max - min).length();
    let (got_min, got_max) = (b.min.as_dvec3(), b.max.as_dvec3());
    assert!(
        (got_min - min).abs().max_element() <= tol && (got_max - max).abs().max_element() <= tol,
        "{file}: bounds {got_min:?}..{got_max:?}, expected {min:?}..{max:?} (tolerance {tol:e})"
    );
}

/// What a scene file must load into.
struct Expected {
    file: &'static str,
    triangles: usize,
    spheres: usize,
    materials: usize,
    min: [f64; 3],
    max: [f64; 3],
}

fn check(e: &Expected) -> Scene {
    let scene = load(e.file);
    assert_eq!(scene.triangles.len(), e.triangles, "{}: triangles", e.file);
    assert_eq!(scene.spheres.len(), e.spheres, "{}: spheres", e.file);
    assert_eq!(scene.materials.len(), e.materials, "{}: materials", e.file);
    assert_bounds(e.file, &scene, e.min, e.max);
    scene
}

// ---------------------------------------------------------------------------------------------
// The teapot: its triangle count from the generator's arithmetic, its bounds from the patches.

/// Quads per patch edge used by `examples/make_teapot.rs` for `scenes/teapot/teapot.glb`.
const TEAPOT_GRID: usize = 44;
/// Patches in Newell's data set.
const TEAPOT_PATCHES: usize = 32;
/// Patches with one edge collapsed to a point (the 4 knob patches meet at the lid's apex, the
/// 4 bottom patches at the bottom's centre); the generator drops the one zero-area triangle of
/// each grid quad along such an edge.
const TEAPOT_COLLAPSED_EDGES: usize = 8;

/// 32 * 2 * 44^2 - 8 * 44 = 123,904 - 352 = 123,552.
const TEAPOT_TRIANGLES: usize =
    TEAPOT_PATCHES * 2 * TEAPOT_GRID * TEAPOT_GRID - TEAPOT_COLLAPSED_EDGES * TEAPOT_GRID;

/// Reads `scenes/teapot/teapot.bpt` (a patch count, then per patch `3 3` and 16 points).
fn teapot_patches() -> Vec<[[DVec3; 4]; 4]> {
    let text = std::fs::read_to_string(scenes_dir().join("teapot/teapot.bpt")).unwrap();
    let mut tokens = text.split_whitespace().map(|t| t.parse::<f64>().unwrap());
    let count = tokens.next().unwrap() as usize;
    (0..count)
        .map(|_| {
            assert_eq!((tokens.next(), tokens.next()), (Some(3.0), Some(3.0)));
            let mut patch = [[DVec3::ZERO; 4]; 4];
            for p in patch.iter_mut().flatten() {
                *p = DVec3::new(
                    tokens.next().unwrap(),
                    tokens.next().unwrap(),
                    tokens.next().unwrap(),
                );
            }
            patch
        })
        .collect()
}

/// Bounds of the teapot's grid points, evaluated here from the patches, converted z-up to
/// y-up as the generator documents: `(x, y, z) -> (x, z, -y)`.
fn teapot_grid_bounds() -> (DVec3, DVec3) {
    let bernstein = |t: f64| {
        let s = 1.0 - t;
        [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t]
    };
    let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let patches = teapot_patches();
    assert_eq!(patches.len(), TEAPOT_PATCHES);
    for patch in &patches {
        for i in 0..=TEAPOT_GRID {
            let bu = bernstein(i as f64 / TEAPOT_GRID as f64);
            for j in 0..=TEAPOT_GRID {
                let bv = bernstein(j as f64 / TEAPOT_GRID as f64);
                let mut p = DVec3::ZERO;
                for (row, wu) in patch.iter().zip(bu) {
                    for (point, wv) in row.iter().zip(bv) {
                        p += wu * wv * *point;
                    }
                }
                let p = DVec3::new(p.x, p.z, -p.y);
                min = min.min(p);
                max = max.max(p);
            }
        }
    }
    (min, max)
}

#[test]
fn teapot_glb_matches_the_patches() {
    let scene = load("teapot/teapot.glb");
    assert_eq!(scene.triangles.len(), TEAPOT_TRIANGLES);
    assert_eq!(scene.spheres.len(), 0);
    let (min, max) = teapot_grid_bounds();
    assert_bounds("teapot/teapot.glb", &scene, min.to_array(), max.to_array());
    // The hand-checkable ends of those bounds: the knob's apex is the control point
    // (0, 0, 3.15), the bottom lies in z = 0, the body's widest circle has radius 2.
    assert!((max.y - 3.15).abs() < 1e-12 && min.y.abs() < 1e-12);
    assert!((max.z - 2.0).abs() < 1e-12 && (min.z + 2.0).abs() < 1e-12);

    // Shading normals are unit length and on the front side of their triangle (winding and
    // normals agree), and the front side is the outside: the signed volume enclosed,
    // sum of a . (b x c) / 6, is positive. The teapot is nearly closed (the spout's and
    // handle's open ends add little), so it is also close to its known volume.
    let mut volume = 0.0;
    for t in &scene.triangles {
        let [a, b, c] = t.positions.map(|p| p.as_dvec3());
        let face = (b - a).cross(c - a).normalize();
        let normals = t.normals.expect("teapot.glb has NORMAL");
        for n in normals {
            assert!(
                (n.length() - 1.0).abs() < 1e-5,
                "normal {n:?} is not unit length"
            );
            // The grid is fine enough that vertex normals stay within ~18 degrees of the
            // face normal (the worst, 0.95, is where the spout meets its tip).
            assert!(
                face.dot(n.as_dvec3()) > 0.9,
                "normal {n:?} vs face {face:?}"
            );
        }
        volume += a.dot(b.cross(c)) / 6.0;
    }
    // Inward-facing triangles would make the sum negative. For scale: the body (radius 1.5 at
    // the bottom and the rim, 2 at its widest, bottom raised by at most ~0.2) contains the
    // cylinder of radius 1.4 between heights 0.2 and 2.4 (pi * 1.4^2 * 2.2 = 13.5), and all
    // but the spout and handle lies in the cylinder of radius 2 and height 3.15 (39.6); the
    // spout and handle (tubes thinner than 1, ~3 long) add less than 5.
    let pi = std::f64::consts::PI;
    let (low, high) = (pi * 1.4 * 1.4 * 2.2, pi * 2.0 * 2.0 * 3.15 + 5.0);
    assert!(
        volume > low && volume < high,
        "signed volume {volume} not in [{low}, {high}]"
    );
}

#[test]
fn teapot_scenes() {
    // teapot.glb plus the ground quad (2 triangles), which spans x, z in [-10, 10] at y = 0;
    // the teapot reaches y = 3.15 (knob apex) and lies inside the quad's x, z range.
    for (file, kind) in [
        ("teapot.toml", MaterialKind::Metal),
        ("glass-teapot.toml", MaterialKind::Glass),
    ] {
        let scene = check(&Expected {
            file,
            triangles: TEAPOT_TRIANGLES + 2,
            spheres: 0,
            materials: 2,
            min: [-10.0, 0.0, -10.0],
            max: [10.0, 3.15, 10.0],
        });
        let kinds: Vec<_> = scene
            .triangles
            .iter()
            .map(|t| scene.materials[t.material as usize].kind)
            .collect();
        assert_eq!(
            kinds.iter().filter(|&&k| k == kind).count(),
            TEAPOT_TRIANGLES,
            "{file}"
        );
        assert_eq!(
            kinds
                .iter()
                .filter(|&&k| k == MaterialKind::Diffuse)
                .count(),
            2,
            "{file}"
        );
        if kind == MaterialKind::Glass {
            let glass = scene
                .materials
                .iter()
                .find(|m| m.kind == MaterialKind::Glass)
                .unwrap();
            assert_eq!(glass.ior, 1.5);
        }
        assert_eq!(
            scene.environment,
            Environment::Constant(Vec3::new(0.8, 0.85, 1.0))
        );
        assert!(scene.warnings.is_empty(), "{file}: {:?}", scene.warnings);
    }
}

// ---------------------------------------------------------------------------------------------
// Spheres and the Cornell boxes.

#[test]
fn spheres() {
    // Ground sphere centre y = -1000, radius 1000: x, z in [-1000, 1000], y in [-2000, 0];
    // the three unit spheres at y = 1 reach y = 2 and lie within the ground's x, z range.
    let scene = check(&Expected {
        file: "spheres.toml",
        triangles: 0,
        spheres: 4,
        materials: 4,
        min: [-1000.0, -2000.0, -1000.0],
        max: [1000.0, 2.0, 1000.0],
    });
    let mut kinds: Vec<_> = scene
        .spheres
        .iter()
        .map(|s| format!("{:?}", scene.materials[s.material as usize].kind))
        .collect();
    kinds.sort();
    assert_eq!(kinds, ["Diffuse", "Diffuse", "Glass", "Metal"]);
    assert_eq!(
        scene.environment,
        Environment::Constant(Vec3::new(0.75, 0.85, 1.0))
    );
}

/// Bounds of Bitterli's Cornell box, by hand from its scene.json: the floor (y = 0) and the
/// ceiling (position y = 2) are quads scaled 2 in x and z, so they span x, z in [-1, 1]; the
/// back wall sits at z = -1, the left and right walls at x = -1 and x = 1, each spanning
/// 2 x 2; the boxes (tops at y = 0.6 and 1.2) and the light (y = 1.98, 0.47 x 0.38 about
/// (-0.005, -0.03)) lie inside. So [-1, 0, -1] .. [1, 2, 1].
const CORNELL_MIN: [f64; 3] = [-1.0, 0.0, -1.0];
const CORNELL_MAX: [f64; 3] = [1.0, 2.0, 1.0];

#[test]
fn cornell_box() {
    // 5 walls + 1 light = 6 quads, 2 boxes x 6 faces = 12 quads: 18 quads, 36 triangles;
    // 8 materials, one per Tungsten bsdf.
    let scene = check(&Expected {
        file: "cornell-box.toml",
        triangles: 36,
        spheres: 0,
        materials: 8,
        min: CORNELL_MIN,
        max: CORNELL_MAX,
    });
    let emitters: Vec<_> = scene.materials.iter().filter(|m| m.is_emissive()).collect();
    assert_eq!(emitters.len(), 1);
    assert_eq!(emitters[0].emission, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!(scene.environment, Environment::Black);
    // The light faces down, the walls face into the room (u x v as written in the file).
    let walls = ["Floor", "Ceiling", "BackWall", "LeftWall", "RightWall"];
    let mut wall_triangles = 0;
    for t in &scene.triangles {
        let [a, b, c] = t.positions;
        let n = (b - a).cross(c - a).normalize();
        let material = &scene.materials[t.material as usize];
        if material.is_emissive() {
            assert!(n.dot(Vec3::NEG_Y) > 0.999, "light normal {n:?}");
        } else if walls.contains(&material.name.as_str()) {
            let to_room = Vec3::new(0.0, 1.0, 0.0) - (a + b + c) / 3.0;
            assert!(n.dot(to_room) > 0.0, "{} faces {n:?}", material.name);
            wall_triangles += 1;
        }
    }
    assert_eq!(wall_triangles, 10);
}

#[test]
fn cornell_bloom() {
    // cornell-box.toml's geometry and materials plus [post.bloom] as written in the file.
    let scene = check(&Expected {
        file: "cornell-bloom.toml",
        triangles: 36,
        spheres: 0,
        materials: 8,
        min: CORNELL_MIN,
        max: CORNELL_MAX,
    });
    let box_scene = load("cornell-box.toml");
    assert_eq!(scene.triangles, box_scene.triangles);
    assert_eq!(scene.camera, box_scene.camera);
    assert_eq!(box_scene.post.bloom, None);
    assert_eq!(
        scene.post.bloom,
        Some(raylume_scene::Bloom {
            threshold: 1.0,
            radius: 24,
            strength: 0.5
        })
    );
    assert!(scene.features().contains(raylume_scene::Feature::Bloom));
}

#[test]
fn cornell_plus() {
    // The box's 36 triangles and 8 materials, plus 2 spheres and their 2 materials; both
    // spheres lie inside the room: mirror centre (-0.335, 1.45, -0.291) radius 0.25, glass
    // centre (-0.45, 0.3, 0.55) radius 0.3.
    let scene = check(&Expected {
        file: "cornell-plus.toml",
        triangles: 36,
        spheres: 2,
        materials: 10,
        min: CORNELL_MIN,
        max: CORNELL_MAX,
    });
    let box_scene = load("cornell-box.toml");
    assert_eq!(
        scene.triangles, box_scene.triangles,
        "the box is cornell-box.toml's"
    );
    let mut kinds: Vec<_> = scene
        .spheres
        .iter()
        .map(|s| scene.materials[s.material as usize].clone())
        .collect();
    kinds.sort_by_key(|m| format!("{:?}", m.kind));
    assert_eq!((kinds[0].kind, kinds[0].ior), (MaterialKind::Glass, 1.5));
    assert_eq!(
        (kinds[1].kind, kinds[1].roughness),
        (MaterialKind::Metal, 0.0)
    );
}

/// A triangle as its corners sorted lexicographically, so that winding and the starting corner
/// do not matter.
fn corner_set(t: &Triangle) -> [Vec3; 3] {
    let mut c = t.positions;
    c.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
    c
}

#[test]
fn cornell_toml_matches_tungsten_original() {
    let Some(json) = shared_external(
        "bitterli-cornell-box/scene.json",
        "cornell_toml_matches_tungsten_original",
    ) else {
        return;
    };
    let original = Scene::load(&json).unwrap_or_else(|e| panic!("{}: {e}", json.display()));
    let toml = load("cornell-box.toml");
    assert_eq!(original.triangles.len(), toml.triangles.len());

    // Every transcribed triangle has one original triangle with the same corners (to 1e-5:
    // the transcription rounds to 7 decimals, the importer computes in f32), the same albedo
    // where it scatters light and the same emission. Matching is one to one.
    let mut unmatched: Vec<&Triangle> = original.triangles.iter().collect();
    for t in &toml.triangles {
        let corners = corner_set(t);
        let found = unmatched.iter().position(|o| {
            corner_set(o)
                .iter()
                .zip(&corners)
                .all(|(p, q)| (*p - *q).abs().max_element() < 1e-5)
        });
        let Some(k) = found else {
            panic!(
                "cornell-box.toml triangle {:?} is not in the Tungsten original",
                t.positions
            );
        };
        let o = unmatched.swap_remove(k);
        let (mt, mo) = (
            &toml.materials[t.material as usize],
            &original.materials[o.material as usize],
        );
        assert_eq!(mt.emission, mo.emission, "{} vs {}", mt.name, mo.name);
        if !mt.is_emissive() {
            assert_eq!(
                (mt.kind, mt.albedo),
                (mo.kind, mo.albedo),
                "{} vs {}",
                mt.name,
                mo.name
            );
        }
    }
    assert!(unmatched.is_empty());

    // Same camera: the fov is horizontal in Tungsten, which for the square 1024 x 1024 image
    // equals the vertical one.
    let (a, b) = (toml.camera, original.camera);
    assert_eq!((a.position, a.look_at, a.up), (b.position, b.look_at, b.up));
    let (va, vb) = (a.vfov(1024, 1024), b.vfov(1024, 1024));
    assert!((va - vb).abs() < 1e-4, "vfov {va} vs {vb}");
}

// ---------------------------------------------------------------------------------------------
// The living room: counts and bounds from the OBJ files, parsed here.

/// Triangles of the living room as listed by its scene.json, read here with a plain OBJ
/// reader: `v` lines and `f` lines (fans for polygons; every face in these files is a
/// triangle), each mesh moved by its transform's `position` (the only transform key the file
/// uses; anything else fails the test). Returns the triangles with an area and the number of
/// degenerate ones (zero area, or no finite normal, in f32), which the loader drops with a
/// warning.
fn living_room_obj_triangles() -> (Vec<[Vec3; 3]>, usize) {
    let dir = scenes_dir().join("living-room");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scene.json")).unwrap()).unwrap();
    let mut all = Vec::new();
    let mut degenerate = 0;
    for prim in json["primitives"].as_array().unwrap() {
        if prim["type"] != "mesh" {
            continue;
        }
        let transform = prim["transform"].as_object().unwrap();
        assert!(
            transform.keys().all(|k| k == "position"),
            "unexpected transform {transform:?}"
        );
        let offset = transform.get("position").map_or(Vec3::ZERO, |p| {
            let p: Vec<f32> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap() as f32)
                .collect();
            Vec3::new(p[0], p[1], p[2])
        });
        let text = std::fs::read_to_string(dir.join(prim["file"].as_str().unwrap())).unwrap();
        let mut vertices = Vec::new();
        for line in text.lines() {
            let mut words = line.split_whitespace();
            match words.next() {
                Some("v") => {
                    let p: Vec<f32> = words.take(3).map(|w| w.parse().unwrap()).collect();
                    vertices.push(Vec3::new(p[0], p[1], p[2]));
                }
                Some("f") => {
                    let corners: Vec<Vec3> = words
                        .map(|w| {
                            let i: i64 = w.split('/').next().unwrap().parse().unwrap();
                            let i = if i > 0 {
                                i - 1
                            } else {
                                vertices.len() as i64 + i
                            };
                            vertices[i as usize] + offset
                        })
                        .collect();
                    for k in 1..corners.len() - 1 {
                        let [a, b, c] = [corners[0], corners[k], corners[k + 1]];
                        let n = (b - a).cross(c - a);
                        let len = n.length();
                        if len > 0.0 && (n / len).is_finite() {
                            all.push([a, b, c]);
                        } else {
                            degenerate += 1;
                        }
                    }
                }
                _ => {}
            }
        }
    }
    (all, degenerate)
}

#[test]
fn living_room() {
    let (kept, degenerate) = living_room_obj_triangles();
    // SOURCES.md counts 143,163 triangles in the 65 files (190 of them have zero area).
    assert_eq!(kept.len() + degenerate, 143_163);
    let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for p in kept.iter().flatten() {
        min = min.min(p.as_dvec3());
        max = max.max(p.as_dvec3());
    }

    // 19 bsdfs, all used by some mesh: one material each.
    let scene = check(&Expected {
        file: "living-room/scene.json",
        triangles: kept.len(),
        spheres: 0,
        materials: 19,
        min: min.to_array(),
        max: max.to_array(),
    });
    assert_eq!(scene.environment, Environment::Constant(Vec3::ONE));
    // The loader reports what it dropped: as many degenerate triangles as counted here.
    let dropped: usize = scene
        .warnings
        .iter()
        .filter_map(|w| w.strip_prefix("dropped "))
        .filter_map(|w| w.split_once(" degenerate triangles"))
        .map(|(n, _)| n.parse::<usize>().unwrap())
        .sum();
    assert_eq!(dropped, degenerate, "{:#?}", scene.warnings);
    // Tungsten's pinhole fov (90) is horizontal: for 1280 x 720 the vertical one is
    // 2 atan(tan(45 deg) * 720 / 1280) = 58.7155 degrees.
    let vfov = 2.0 * (720.0f64 / 1280.0).atan().to_degrees();
    let got = scene.camera.vfov(1280, 720);
    assert!((got as f64 - vfov).abs() < 1e-3, "vfov {got}");
    assert_eq!(scene.camera.fov_axis, raylume_scene::FovAxis::Horizontal);
    assert_eq!((scene.render.width, scene.render.height), (1280, 720));
    // Three textures: wood.jpg, wood5.jpg, picture8.jpg.
    assert_eq!(scene.textures.len(), 3);
}

#[test]
fn living_room_data_is_the_vendored_copy() {
    let Some(original) = shared_external(
        "bitterli-livingroom",
        "living_room_data_is_the_vendored_copy",
    ) else {
        return;
    };
    let ours = scenes_dir().join("living-room");
    let mut compared = 0;
    for sub in ["models", "textures"] {
        for entry in std::fs::read_dir(original.join(sub)).unwrap() {
            let name = entry.unwrap().file_name();
            let a = std::fs::read(original.join(sub).join(&name)).unwrap();
            let b = std::fs::read(ours.join(sub).join(&name))
                .unwrap_or_else(|e| panic!("scenes/living-room/{sub}/{name:?}: {e}"));
            assert!(
                a == b,
                "scenes/living-room/{sub}/{name:?} differs from the original"
            );
            compared += 1;
        }
    }
    assert_eq!(compared, 65 + 3);
}

// ---------------------------------------------------------------------------------------------

/// Every scene file in `scenes/` is covered by a test above: a new scene needs its expected
/// numbers here too.
#[test]
fn every_scene_is_checked() {
    let mut files: Vec<String> = std::fs::read_dir(scenes_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    files.sort();
    assert_eq!(
        files,
        [
            "cornell-bloom.toml",
            "cornell-box.toml",
            "cornell-plus.toml",
            "glass-teapot.toml",
            "spheres.toml",
            "teapot.toml"
        ]
    );
    assert!(scenes_dir().join("living-room/scene.json").exists());
}
