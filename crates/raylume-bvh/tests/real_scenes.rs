//! The project's real scenes (`scenes/`): the teapot (123,554 triangles) and the living room
//! (142,973). Both presets build, validate, and trace 100,000 queries alike; 2,000 of those
//! are also checked against brute force (all 100,000 against 140k triangles would take
//! minutes). Skipped, visibly, when the scene files are absent.

mod support;

use std::path::PathBuf;

use raylume_bvh::{BvhQuality, GpuBvh};
use raylume_scene::Scene;
use rayon::prelude::*;
use support::{Fixture, SceneHit, TIE_RELATIVE, brute_force, check_against_brute_force, queries};

const QUERIES: usize = 100_000;
const BRUTE_FORCE_QUERIES: usize = 2_000;

/// `scenes/<file>` of the workspace, or `None` after printing why the test is skipped.
fn load(test: &str, file: &str) -> Option<Scene> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(file);
    if !path.exists() {
        eprintln!("SKIPPED {test}: {} not found", path.display());
        return None;
    }
    Some(Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

fn check_real_scene(name: &'static str, file: &str, seed: u64) {
    let Some(scene) = load(name, file) else {
        return;
    };
    let f = Fixture {
        name,
        triangles: scene.triangles.clone(),
        spheres: scene.spheres.clone(),
    };
    let fast = GpuBvh::from_scene(&scene, BvhQuality::Fast).unwrap();
    let quality = GpuBvh::from_scene(&scene, BvhQuality::Quality).unwrap();
    for bvh in [&fast, &quality] {
        bvh.validate()
            .unwrap_or_else(|e| panic!("{name} {:?}: {e}", bvh.stats.quality));
        eprintln!("{name}: {:?}", bvh.stats);
    }
    let qs = queries(&f, QUERIES, seed);

    // The two trees agree on every query (ties allowed, as against brute force).
    let (lo, hi) = f.bounds();
    let size = (hi - lo).max_element();
    let scene_hit = |bvh: &GpuBvh, i: usize| -> Option<SceneHit> {
        let q = &qs[i];
        bvh.trace_closest(&q.ray, q.t_min, q.t_max)
            .map(|h| support::scene_hit(bvh, &h))
    };
    let disagree: Vec<usize> = (0..QUERIES)
        .into_par_iter()
        .filter(|&i| {
            let q = &qs[i];
            let (a, b) = (scene_hit(&fast, i), scene_hit(&quality, i));
            let any_ok = fast.trace_any(&q.ray, q.t_min, q.t_max) == a.is_some()
                && quality.trace_any(&q.ray, q.t_min, q.t_max) == b.is_some();
            let closest_ok = match (a, b) {
                (None, None) => true,
                (Some(a), Some(b)) if (a.0, a.1) == (b.0, b.1) => a.2 == b.2,
                (Some(a), Some(b)) => {
                    let scale = a.2.abs().max(size / q.ray.dir.length());
                    (a.2 - b.2).abs() <= TIE_RELATIVE * scale
                }
                _ => false,
            };
            !(closest_ok && any_ok)
        })
        .collect();
    assert!(
        disagree.is_empty(),
        "{name}: Fast and Quality trees disagree on {} of {QUERIES} queries, e.g. {:?}",
        disagree.len(),
        &disagree[..disagree.len().min(5)]
            .iter()
            .map(|&i| (qs[i], scene_hit(&fast, i), scene_hit(&quality, i)))
            .collect::<Vec<_>>()
    );

    let sample = &qs[..BRUTE_FORCE_QUERIES];
    let reference: Vec<_> = sample.par_iter().map(|q| brute_force(&f, q)).collect();
    let hits = check_against_brute_force(&f, &fast, sample, &reference);
    check_against_brute_force(&f, &quality, sample, &reference);
    assert!(hits > BRUTE_FORCE_QUERIES / 5, "{name}: only {hits} hits");
}

#[test]
fn teapot_both_presets_agree_and_match_brute_force() {
    check_real_scene("teapot", "teapot.toml", 31);
}

#[test]
fn living_room_both_presets_agree_and_match_brute_force() {
    check_real_scene("living room", "living-room/scene.json", 32);
}
