//! BVH traversal against brute force (every primitive tested) on fixture scenes, 100,000
//! queries each, with both build presets in both layouts; any-hit against closest-hit's
//! existence.

mod support;

use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use rayon::prelude::*;
use support::{Fixture, SceneHit, brute_force, check_against_brute_force, queries};

const QUERIES: usize = 100_000;

/// Builds `f` with both presets in both layouts, validates, and compares 100,000 queries with brute force.
fn check_fixture(f: Fixture, seed: u64) {
    let qs = queries(&f, QUERIES, seed);
    let reference: Vec<Option<SceneHit>> = qs.par_iter().map(|q| brute_force(&f, q)).collect();
    // The ray set is not vacuous: rays of kind 4 (pointing away from the scene) all miss,
    // and the others hit often.
    for (i, r) in reference.iter().enumerate() {
        if i % 5 == 3 {
            assert!(
                r.is_none(),
                "{}: ray {i} points away yet hits {r:?}",
                f.name
            );
        }
    }
    let hits = reference.iter().filter(|r| r.is_some()).count();
    assert!(
        hits > QUERIES / 10,
        "{}: only {hits} of {QUERIES} queries hit",
        f.name
    );
    for (quality, layout) in BvhQuality::ALL
        .into_iter()
        .flat_map(|q| [(q, BvhLayout::Binary), (q, BvhLayout::Wide)])
    {
        let bvh = GpuBvh::build_with_layout(&f.triangles, &f.spheres, quality, layout).unwrap();
        assert_eq!(bvh.layout, layout);
        bvh.validate()
            .unwrap_or_else(|e| panic!("{} {quality:?} {layout:?}: {e}", f.name));
        let got = check_against_brute_force(&f, &bvh, &qs, &reference);
        assert_eq!(got, hits);
        eprintln!(
            "{} {quality:?} {layout:?}: {} primitives -> {} refs, {} nodes, depth {}, \
             SAH {:.1}; {hits}/{QUERIES} queries hit",
            f.name,
            f.primitive_count(),
            bvh.stats.primitive_refs,
            bvh.stats.node_count,
            bvh.stats.max_depth,
            bvh.stats.sah_cost
        );
    }
    // The tree the GPU build writes (its CPU reference, `lbvh_binary`), over triangles only.
    if f.spheres.is_empty() {
        let source = GpuBvh::lbvh_input(&f.triangles).unwrap();
        let tree = raylume_bvh::lbvh::lbvh_binary(&source);
        assert_eq!(tree.nodes.len(), source.len().max(2) - 1);
        let bvh = GpuBvh::from_lbvh(tree, &source, std::time::Instant::now()).unwrap();
        bvh.validate()
            .unwrap_or_else(|e| panic!("{} LBVH binary: {e}", f.name));
        let got = check_against_brute_force(&f, &bvh, &qs, &reference);
        assert_eq!(got, hits);
        eprintln!(
            "{} LBVH binary: {} nodes, depth {}, SAH {:.1}",
            f.name, bvh.stats.node_count, bvh.stats.max_depth, bvh.stats.sah_cost
        );
    }
}

#[test]
fn triangle_soup_matches_brute_force() {
    check_fixture(support::triangle_soup(), 1);
}

#[test]
fn icosphere_on_plane_matches_brute_force() {
    check_fixture(support::icosphere_on_plane(), 2);
}

#[test]
fn cornell_box_matches_brute_force() {
    check_fixture(support::cornell_box(), 3);
}

#[test]
fn spheres_and_triangles_match_brute_force() {
    check_fixture(support::spheres_and_triangles(), 4);
}

#[test]
fn slivers_in_soup_match_brute_force() {
    check_fixture(support::slivers_in_soup(), 5);
}
