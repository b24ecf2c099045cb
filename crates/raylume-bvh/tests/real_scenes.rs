//! The project's real scenes (`scenes/`): the teapot (123,554 triangles) and the living room
//! (142,973). Both presets build, validate, and trace 100,000 queries alike; 2,000 of those
//! are also checked against brute force directly (all 100,000 against 140k triangles would
//! take minutes). All 100,000 are checked against an independent implementation, obvhs's own
//! BVH2 traversal with its Möller–Trumbore triangle test, and every query on which it
//! disagrees with ours is settled by brute force. The scenes are part of the repository: a
//! missing file fails the test.

mod support;

use std::path::PathBuf;

use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_scene::Scene;
use rayon::prelude::*;
use support::{Fixture, SceneHit, TIE_RELATIVE, brute_force, check_against_brute_force, queries};

const QUERIES: usize = 100_000;
const BRUTE_FORCE_QUERIES: usize = 2_000;

/// `scenes/<file>` of the workspace. The scenes are tracked in the repository, so a missing
/// one is a broken checkout: a failure, not a skip.
fn load(file: &str) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(file);
    Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn check_real_scene(name: &'static str, file: &str, seed: u64) {
    let scene = load(file);
    let f = Fixture {
        name,
        triangles: scene.triangles.clone(),
        spheres: scene.spheres.clone(),
    };
    let binary = |q| GpuBvh::from_scene_with_layout(&scene, q, BvhLayout::Binary).unwrap();
    let (fast, quality) = (binary(BvhQuality::Fast), binary(BvhQuality::Quality));
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

    check_against_obvhs(&f, &quality, &qs);

    let sample = &qs[..BRUTE_FORCE_QUERIES];
    let reference: Vec<_> = sample.par_iter().map(|q| brute_force(&f, q)).collect();
    let hits = check_against_brute_force(&f, &fast, sample, &reference);
    check_against_brute_force(&f, &quality, sample, &reference);
    // The wide layout of both presets: valid, and the same hits as brute force.
    for preset in [BvhQuality::Fast, BvhQuality::Quality] {
        let wide = GpuBvh::from_scene_with_layout(&scene, preset, BvhLayout::Wide).unwrap();
        wide.validate()
            .unwrap_or_else(|e| panic!("{name} {preset:?} wide: {e}"));
        eprintln!("{name} wide: {:?}", wide.stats);
        check_against_brute_force(&f, &wide, sample, &reference);
    }
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

/// Every query traced by obvhs (its BVH2, its traversal, Möller–Trumbore) and by `bvh`: where
/// they name the same triangle at distances within 1e-5 relative (two different triangle
/// tests), they agree; everywhere else brute force with raylume's watertight test decides,
/// and must agree with `bvh` exactly. Such queries are expected (Möller–Trumbore misses rays
/// through shared edges, which the watertight test catches; grazing hits have ill-conditioned
/// distances; a fifth of the queries start on a surface, at a vertex or along an edge) but a
/// minority: at most 5 % (measured: 2.8 % on the teapot, 1.0 % in the living room), so that
/// the independent implementation carries most of the check.
fn check_against_obvhs(f: &Fixture, bvh: &GpuBvh, qs: &[support::Query]) {
    use obvhs::{BvhBuildParams, ray::RayHit, triangle::Triangle as OTri};
    let tris: Vec<OTri> = f
        .triangles
        .iter()
        .map(|t| OTri {
            v0: t.positions[0].into(),
            v1: t.positions[1].into(),
            v2: t.positions[2].into(),
        })
        .collect();
    let reference = obvhs::bvh2::builder::build_bvh2_from_tris(
        &tris,
        BvhBuildParams::fast_build(),
        &mut std::time::Duration::default(),
    );
    let (lo, hi) = f.bounds();
    let size = (hi - lo).max_element();
    let settled: Vec<usize> = qs
        .par_iter()
        .enumerate()
        .filter_map(|(i, q)| {
            let ray = obvhs::ray::Ray::new(
                q.ray.origin.into(),
                q.ray.dir.into(),
                q.t_min,
                q.t_max.min(raylume_bvh::T_MAX_LIMIT),
            );
            let mut hit = RayHit::none();
            let theirs = reference
                .ray_traverse(ray, &mut hit, |r, id| {
                    tris[reference.primitive_indices[id] as usize].intersect(r)
                })
                .then(|| {
                    (
                        reference.primitive_indices[hit.primitive_id as usize],
                        hit.t,
                    )
                });
            let ours = bvh
                .trace_closest(&q.ray, q.t_min, q.t_max)
                .map(|h| support::scene_hit(bvh, &h));
            match (ours, theirs) {
                (None, None) => None,
                // The same triangle at (nearly) the same distance: two implementations agree.
                // Near-grazing rays make both triangle tests' distances ill-conditioned; those
                // go to brute force like any other disagreement.
                (Some(o), Some(t))
                    if o.1 == t.0
                        && (o.2 - t.1).abs() <= 1e-5 * o.2.abs().max(size / q.ray.dir.length()) =>
                {
                    None
                }
                _ => Some(i),
            }
        })
        .collect();
    let sample: Vec<support::Query> = settled.iter().map(|&i| qs[i]).collect();
    let brute: Vec<_> = sample.par_iter().map(|q| brute_force(f, q)).collect();
    check_against_brute_force(f, bvh, &sample, &brute);
    assert!(
        settled.len() * 20 <= qs.len(),
        "{}: raylume and obvhs disagree on {} of {} queries (brute force sided with raylume)",
        f.name,
        settled.len(),
        qs.len()
    );
    eprintln!(
        "{}: {} queries agree with obvhs; {} settled by brute force in raylume's favour",
        f.name,
        qs.len() - settled.len(),
        settled.len()
    );
}
