//! The builder's contract: shapes of tiny trees, typed errors for bad input, the depth
//! fallback on degenerate input, spatial splits, stats.

mod support;

use glam::Vec3;
use raylume_bvh::{
    BvhError, BvhLayout, BvhQuality, Fallback, GpuBvh, INVALID_INDEX, MAX_STACK_DEPTH, PRIM_SPHERE,
    PRIM_TRIANGLE, Ray, WIDE_STACK_SIZE,
};
use raylume_scene::{Scene, Sphere, Triangle};
use support::{Fixture, brute_force, check_against_brute_force, queries};

const QUALITIES: [BvhQuality; 3] = BvhQuality::ALL;

/// The binary layout's tree (these tests read its `nodes`).
fn build_binary(
    triangles: &[Triangle],
    spheres: &[Sphere],
    quality: BvhQuality,
) -> Result<GpuBvh, BvhError> {
    GpuBvh::build_with_layout(triangles, spheres, quality, BvhLayout::Binary)
}

fn unit_triangle() -> Triangle {
    Triangle::flat([Vec3::ZERO, Vec3::X, Vec3::Y], 0)
}

#[test]
fn no_primitives_give_a_root_with_two_empty_slots() {
    for quality in QUALITIES {
        let bvh = build_binary(&[], &[], quality).unwrap();
        bvh.validate().unwrap();
        assert_eq!(bvh.nodes.len(), 1);
        assert!(bvh.primitives.is_empty());
        let root = bvh.nodes[0];
        assert_eq!((root.left_index, root.left_count), (INVALID_INDEX, 0));
        assert_eq!((root.right_index, root.right_count), (INVALID_INDEX, 0));
        let ray = Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z);
        assert_eq!(bvh.trace_closest(&ray, 0.0, f32::INFINITY), None);
        assert!(!bvh.trace_any(&ray, 0.0, f32::INFINITY));
        assert_eq!(bvh.stats.leaf_count, 0);
    }
}

#[test]
fn one_primitive_is_a_left_leaf_with_an_empty_right_slot() {
    let sphere = Sphere {
        center: Vec3::new(0.0, 0.0, 3.0),
        radius: 1.0,
        material: 0,
    };
    for quality in QUALITIES {
        for (tris, spheres, kind, origin, t) in [
            (
                vec![unit_triangle()],
                vec![],
                PRIM_TRIANGLE,
                Vec3::new(0.25, 0.25, -1.0),
                1.0,
            ),
            (
                vec![],
                vec![sphere],
                PRIM_SPHERE,
                Vec3::new(0.0, 0.0, -1.0),
                3.0,
            ),
        ] {
            let bvh = build_binary(&tris, &spheres, quality).unwrap();
            bvh.validate().unwrap();
            assert_eq!(bvh.nodes.len(), 1);
            let root = bvh.nodes[0];
            assert_eq!((root.left_index, root.left_count), (0, 1));
            assert_eq!((root.right_index, root.right_count), (INVALID_INDEX, 0));
            assert_eq!(bvh.primitives[0].kind(), kind);
            assert_eq!(bvh.primitives[0].scene_index(), 0);
            let ray = Ray::new(origin, Vec3::Z);
            let hit = bvh.trace_closest(&ray, 0.0, f32::INFINITY).unwrap();
            assert_eq!((hit.prim, hit.t), (0, t));
            // Beside it: nothing, and nothing past t_max.
            let beside = Ray::new(Vec3::new(5.0, 5.0, -1.0), Vec3::Z);
            assert_eq!(bvh.trace_closest(&beside, 0.0, f32::INFINITY), None);
            assert!(!bvh.trace_any(&ray, 0.0, t * 0.5));
        }
    }
}

#[test]
fn from_scene_builds_triangles_and_spheres_together() {
    let scene = Scene {
        triangles: vec![unit_triangle(); 3],
        spheres: vec![
            Sphere {
                center: Vec3::ONE,
                radius: 0.5,
                material: 0,
            };
            2
        ],
        ..Scene::default()
    };
    let bvh = GpuBvh::from_scene(&scene, BvhQuality::Quality).unwrap();
    bvh.validate().unwrap();
    assert_eq!((bvh.triangle_count, bvh.sphere_count), (3, 2));
    let mut seen: Vec<(u32, u32)> = bvh
        .primitives
        .iter()
        .map(|p| (p.kind(), p.scene_index()))
        .collect();
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(
        seen,
        [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1)],
        "every scene primitive, by kind and index"
    );
}

#[test]
fn non_finite_and_bad_radius_are_typed_errors() {
    let mut bad = unit_triangle();
    bad.positions[2].y = f32::NAN;
    let err = GpuBvh::build(&[unit_triangle(), bad], &[], BvhQuality::Fast).unwrap_err();
    assert!(
        matches!(
            err,
            BvhError::NonFinite {
                kind: "triangle",
                index: 1,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("triangle 1"), "{err}");

    let s = |center: Vec3, radius: f32| Sphere {
        center,
        radius,
        material: 0,
    };
    let err = GpuBvh::build(&[], &[s(Vec3::ZERO, f32::INFINITY)], BvhQuality::Fast).unwrap_err();
    assert!(
        matches!(
            err,
            BvhError::NonFinite {
                kind: "sphere",
                index: 0,
                ..
            }
        ),
        "{err:?}"
    );
    let err = GpuBvh::build(
        &[],
        &[s(Vec3::ZERO, 1.0), s(Vec3::ZERO, 0.0)],
        BvhQuality::Fast,
    )
    .unwrap_err();
    assert_eq!(
        err,
        BvhError::BadRadius {
            index: 1,
            radius: 0.0
        }
    );
    // Finite centre and radius whose bounds overflow f32.
    let err = GpuBvh::build(&[], &[s(Vec3::splat(3e38), 3e38)], BvhQuality::Fast).unwrap_err();
    assert!(
        matches!(
            err,
            BvhError::NonFinite {
                kind: "sphere",
                index: 0,
                ..
            }
        ),
        "{err:?}"
    );
}

/// Thousands of coincident triangles give clustering nothing to work with; whatever obvhs
/// makes of them, the result must be a valid tree within the stack depth that traces like
/// brute force. PLOC (`Fast`, `Quality`) would chain them: those presets take the median
/// fallback. `Fastest`'s linear BVH breaks the ties by index into a balanced tree, and is
/// kept.
#[test]
fn coincident_triangles_give_a_usable_tree() {
    let t = Triangle::flat(
        [
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(1.0, 0.2, 0.4),
            Vec3::new(0.3, 1.5, 0.2),
        ],
        0,
    );
    let f = Fixture {
        name: "5000 coincident triangles",
        triangles: vec![t; 5000],
        spheres: Vec::new(),
    };
    let qs = queries(&f, 2000, 9);
    let reference: Vec<_> = qs.iter().map(|q| brute_force(&f, q)).collect();
    for quality in QUALITIES {
        let bvh = build_binary(&f.triangles, &f.spheres, quality).unwrap();
        bvh.validate().unwrap();
        assert!(bvh.stats.max_depth <= MAX_STACK_DEPTH);
        eprintln!("{quality:?}: {:?}", bvh.stats);
        if quality == BvhQuality::Fastest {
            // Equal codes: the index bits split every range in halves, a leaf of at most
            // `max_prims_per_leaf` after the collapse: no deeper than the halving of 5000.
            assert_eq!(bvh.stats.fallback, None);
            assert!(bvh.stats.max_depth <= (5000f64).log2().ceil() as usize);
            check_against_brute_force(&f, &bvh, &qs, &reference);
            continue;
        }
        assert_eq!(
            bvh.stats.fallback,
            Some(Fallback::CoincidentBoxes { count: 5000 })
        );
        // Median splits halve the count (the larger half ceil(n / 2)) until a node holds at
        // most 4 (the fallback's leaf size): 5000, 2500, 1250, 625, 313, 157, 79, 40, 20,
        // 10, 5 are split, 11 = ceil(log2(5000 / 4)) levels of inner nodes, and a leaf of 3
        // below them. The leaves sit in their parents' child slots in the flat layout, so its
        // depth counts the inner nodes only: 11 (the `+ 1` of median.rs counts the leaf).
        let inner_levels = (5000f64 / 4.0).log2().ceil() as usize;
        assert_eq!(inner_levels, 11);
        assert_eq!(bvh.stats.max_depth, inner_levels);
        eprintln!("{quality:?}: {:?}", bvh.stats);
        check_against_brute_force(&f, &bvh, &qs, &reference);
    }
}

/// Long thin diagonal triangles get pre-split by the Quality preset: copies in several
/// leaves, each leaf box covering its piece (validate checks the union covers the triangle),
/// and traversal still agrees with brute force.
#[test]
fn quality_splits_long_diagonal_triangles() {
    let f = support::slivers_in_soup();
    let fast = build_binary(&f.triangles, &f.spheres, BvhQuality::Fast).unwrap();
    let quality = build_binary(&f.triangles, &f.spheres, BvhQuality::Quality).unwrap();
    fast.validate().unwrap();
    quality.validate().unwrap();
    assert_eq!(fast.stats.primitive_refs, f.primitive_count());
    assert!(
        quality.stats.primitive_refs > f.primitive_count(),
        "expected split copies, got {} refs for {} primitives",
        quality.stats.primitive_refs,
        f.primitive_count()
    );
    assert!(
        quality.stats.sah_cost < fast.stats.sah_cost,
        "splits should lower the SAH cost here: {} vs {}",
        quality.stats.sah_cost,
        fast.stats.sah_cost
    );
    let qs = queries(&f, 20_000, 10);
    let reference: Vec<_> = qs.iter().map(|q| brute_force(&f, q)).collect();
    check_against_brute_force(&f, &quality, &qs, &reference);
}

/// The same slivers far from the origin, where a split piece's box (the splitter clips the
/// triangle in floating point) can fall a few ulp short of the piece, and the wide layout's
/// cells (a node's extent / 255, small against the coordinates' ulp there) no longer round it
/// out: each piece's leaf must get its box from the whole triangle (`flatten::leaf_box`: the
/// binary flatten's, and the wide conversion's pass before obvhs quantises), or the traversal
/// misses grazing hits on the pieces' seams. Both layouts: the split coverage `validate`
/// checks, and rays against brute force. (Each layout's pass removed alone fails this.)
#[test]
fn split_slivers_far_from_the_origin_keep_their_seams() {
    for (offset, scale) in [(1e4f32, 1.0f32), (1e4, 0.1), (3e4, 0.1)] {
        let near = support::slivers_in_soup();
        let shift = Vec3::new(offset, -0.7 * offset, 0.3 * offset);
        let f = Fixture {
            name: "slivers far from the origin",
            triangles: near
                .triangles
                .iter()
                .map(|t| Triangle::flat(t.positions.map(|p| p * scale + shift), 0))
                .collect(),
            spheres: Vec::new(),
        };
        let qs = queries(&f, 20_000, 10);
        let reference: Vec<_> = qs.iter().map(|q| brute_force(&f, q)).collect();
        for layout in [BvhLayout::Binary, BvhLayout::Wide] {
            let bvh =
                GpuBvh::build_with_layout(&f.triangles, &f.spheres, BvhQuality::Quality, layout)
                    .unwrap();
            assert!(
                bvh.stats.primitive_refs > f.primitive_count(),
                "{layout:?} at {offset}: no split copies"
            );
            bvh.validate()
                .unwrap_or_else(|e| panic!("{layout:?} at {offset} x {scale}: {e}"));
            check_against_brute_force(&f, &bvh, &qs, &reference);
        }
    }
}

#[test]
fn stats_describe_the_tree() {
    let f = support::icosphere_on_plane();
    let bvh = build_binary(&f.triangles, &f.spheres, BvhQuality::Fast).unwrap();
    let s = bvh.stats;
    assert_eq!(s.node_count, bvh.nodes.len());
    assert_eq!(s.primitive_refs, bvh.primitives.len());
    // A binary tree with every inner node full: leaves = inner nodes + 1.
    assert_eq!(s.leaf_count, s.node_count + 1);
    let leaf_sizes: Vec<u32> = bvh
        .nodes
        .iter()
        .flat_map(|n| [n.left_count, n.right_count])
        .filter(|&c| c > 0)
        .collect();
    assert_eq!(
        leaf_sizes.iter().sum::<u32>() as usize,
        bvh.primitives.len()
    );
    assert_eq!(s.max_leaf_size, *leaf_sizes.iter().max().unwrap() as usize);
    assert!(
        s.max_leaf_size <= 8,
        "obvhs collapses to at most 8 per leaf"
    );
    assert!(s.max_depth >= (bvh.nodes.len() as f32).log2().ceil() as usize);
    assert!(s.sah_cost > 1.0 && s.sah_cost.is_finite());
    assert_eq!(s.fallback, None);
    assert_eq!(s.quality, BvhQuality::Fast);
}

/// 400 places with 64 coincident triangles each (not more than the coincidence limit):
/// obvhs chains each group into a subtree 64 deep, past the stack; the builder sees the depth
/// and falls back.
#[test]
fn groups_of_coincident_triangles_past_the_stack_fall_back() {
    let k = MAX_STACK_DEPTH;
    let triangles: Vec<Triangle> = (0..400 * k)
        .map(|i| {
            let o = Vec3::new((i / k) as f32 * 0.0025, 0.0, 0.0);
            Triangle::flat(
                [
                    Vec3::new(0.1, 0.2, 0.3) + o,
                    Vec3::new(1.0, 0.2, 0.4) + o,
                    Vec3::new(0.3, 1.5, 0.2) + o,
                ],
                0,
            )
        })
        .collect();
    let f = Fixture {
        name: "400 x 64 coincident triangles",
        triangles,
        spheres: Vec::new(),
    };
    let bvh = build_binary(&f.triangles, &f.spheres, BvhQuality::Fast).unwrap();
    bvh.validate().unwrap();
    assert!(
        matches!(bvh.stats.fallback, Some(Fallback::TooDeep { depth }) if depth > MAX_STACK_DEPTH),
        "{:?}",
        bvh.stats
    );
    assert!(bvh.stats.max_depth <= MAX_STACK_DEPTH);
    let qs = queries(&f, 2000, 15);
    let reference: Vec<_> = qs.iter().map(|q| brute_force(&f, q)).collect();
    check_against_brute_force(&f, &bvh, &qs, &reference);
}

#[test]
fn builds_are_deterministic_on_a_thread_pool() {
    // obvhs builds with its `parallel` feature on (rayon): reinsertion candidates are found in
    // parallel and sorted with a parallel unstable sort, PLOC runs in chunks per thread. The
    // tree must still be the same on every build of the same input (renders reproducible bit
    // for bit; the BVH cache keyed by geometry), on pools of 1, 2 and 3 threads (chunking
    // follows the thread count): a 40,000-triangle height field, both presets, nodes and
    // primitive order compared exactly.
    let n = 100;
    let height = |i: usize, j: usize| {
        let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
        0.05 * (12.0 * x).sin() * (9.0 * z).cos() + 0.02 * (31.0 * x + 17.0 * z).sin()
    };
    let p = |i: usize, j: usize| Vec3::new(i as f32 / n as f32, height(i, j), j as f32 / n as f32);
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            triangles.push(Triangle::flat([a, b, c], 0));
            triangles.push(Triangle::flat([a, c, d], 0));
            // A second, offset layer: overlapping boxes, so reinsertion has ties to order.
            triangles.push(Triangle::flat([a + Vec3::Y * 0.01, c, d], 0));
            triangles.push(Triangle::flat([b + Vec3::Y * 0.01, c, a], 0));
        }
    }
    let scene = Scene {
        triangles,
        ..Default::default()
    };
    for quality in QUALITIES {
        let build = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    [BvhLayout::Binary, BvhLayout::Wide]
                        .map(|l| GpuBvh::from_scene_with_layout(&scene, quality, l).unwrap())
                })
        };
        let first = build(2);
        for threads in [1, 2, 3, 2] {
            let again = build(threads);
            for (a, b) in again.iter().zip(&first) {
                assert!(
                    a.nodes == b.nodes
                        && a.wide_nodes == b.wide_nodes
                        && a.primitives == b.primitives,
                    "{quality:?} {:?}: the tree on {threads} threads differs",
                    a.layout
                );
            }
        }
    }
}

/// The wide layout's tiny trees: no primitive gives a root with no child (every query
/// misses); one primitive, a root with one leaf slot.
#[test]
fn wide_trees_of_zero_and_one_primitive() {
    for quality in QUALITIES {
        let empty = GpuBvh::build_with_layout(&[], &[], quality, BvhLayout::Wide).unwrap();
        empty.validate().unwrap();
        assert_eq!((empty.wide_nodes.len(), empty.nodes.len()), (1, 0));
        assert_eq!(empty.wide_nodes[0].child_meta, [0; 8]);
        let ray = Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z);
        assert_eq!(empty.trace_closest(&ray, 0.0, f32::INFINITY), None);
        assert!(!empty.trace_any(&ray, 0.0, f32::INFINITY));
        assert_eq!(empty.stats.leaf_count, 0);

        let one =
            GpuBvh::build_with_layout(&[unit_triangle()], &[], quality, BvhLayout::Wide).unwrap();
        one.validate().unwrap();
        assert_eq!(one.wide_nodes.len(), 1);
        assert_eq!(one.wide_nodes[0].imask(), 0);
        assert_eq!(
            one.wide_nodes[0]
                .child_meta
                .iter()
                .filter(|&&m| m != 0)
                .count(),
            1
        );
        let ray = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z);
        let hit = one.trace_closest(&ray, 0.0, f32::INFINITY).unwrap();
        assert_eq!((hit.prim, hit.t), (0, 1.0));
        assert!(!one.trace_any(&ray, 0.0, 0.5));
        let beside = Ray::new(Vec3::new(5.0, 5.0, -1.0), Vec3::Z);
        assert_eq!(one.trace_closest(&beside, 0.0, f32::INFINITY), None);
        assert_eq!(one.stats.leaf_count, 1);
    }
}

/// The wide layout on degenerate input: coincident boxes give the median tree (one
/// primitive a leaf before the conversion); 400 chains of 64 coincident triangles, which the
/// binary layout must abandon (over [`MAX_STACK_DEPTH`] deep after its leaf collapse), are
/// under [`WIDE_STACK_SIZE`] deep as wide trees (each wide level takes about three binary
/// ones). Both within the stack and tracing like brute force.
#[test]
fn wide_trees_of_degenerate_input() {
    let t = Triangle::flat(
        [
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(1.0, 0.2, 0.4),
            Vec3::new(0.3, 1.5, 0.2),
        ],
        0,
    );
    let coincident = Fixture {
        name: "5000 coincident triangles",
        triangles: vec![t; 5000],
        spheres: Vec::new(),
    };
    let k = MAX_STACK_DEPTH;
    let chains = Fixture {
        name: "400 x 64 coincident triangles",
        triangles: (0..400 * k)
            .map(|i| {
                let o = Vec3::new((i / k) as f32 * 0.0025, 0.0, 0.0);
                Triangle::flat(t.positions.map(|p| p + o), 0)
            })
            .collect(),
        spheres: Vec::new(),
    };
    // `Fastest` (the linear BVH) needs no fallback for coincident boxes: its ties go by index.
    for (f, quality, fallback) in [
        (
            &coincident,
            BvhQuality::Fast,
            Some(Fallback::CoincidentBoxes { count: 5000 }),
        ),
        (&coincident, BvhQuality::Fastest, None),
        (&chains, BvhQuality::Fast, None),
        (&chains, BvhQuality::Fastest, None),
    ] {
        let bvh =
            GpuBvh::build_with_layout(&f.triangles, &f.spheres, quality, BvhLayout::Wide).unwrap();
        bvh.validate().unwrap();
        eprintln!("{}: {:?}", f.name, bvh.stats);
        assert_eq!(bvh.stats.fallback, fallback, "{} {quality:?}", f.name);
        assert!(bvh.stats.max_depth <= WIDE_STACK_SIZE);
        let qs = queries(f, 2000, 16);
        let reference: Vec<_> = qs.iter().map(|q| brute_force(f, q)).collect();
        check_against_brute_force(f, &bvh, &qs, &reference);
    }
}

#[test]
fn wide_stats_describe_the_tree() {
    let f = support::icosphere_on_plane();
    let bvh =
        GpuBvh::build_with_layout(&f.triangles, &f.spheres, BvhQuality::Fast, BvhLayout::Wide)
            .unwrap();
    let s = bvh.stats;
    assert_eq!(s.node_count, bvh.wide_nodes.len());
    assert_eq!(s.primitive_refs, bvh.primitives.len());
    // Every node's leaf slots and the unary counts in their meta bytes.
    let (mut leaves, mut prims, mut largest) = (0, 0, 0);
    for n in &bvh.wide_nodes {
        for slot in 0..8 {
            if n.child_meta[slot] != 0 && n.imask() & (1 << slot) == 0 {
                let count = (n.child_meta[slot] >> 5).count_ones() as usize;
                leaves += 1;
                prims += count;
                largest = largest.max(count);
            }
        }
    }
    assert_eq!(s.leaf_count, leaves);
    assert_eq!(prims, bvh.primitives.len());
    assert_eq!(s.max_leaf_size, largest);
    assert!(largest <= 3, "wide leaves hold at most 3 primitives");
    // Eight-wide: fewer nodes and levels than the binary tree of the same build.
    let binary = GpuBvh::build_with_layout(
        &f.triangles,
        &f.spheres,
        BvhQuality::Fast,
        BvhLayout::Binary,
    )
    .unwrap();
    assert!(s.node_count < binary.stats.node_count && s.max_depth < binary.stats.max_depth);
    assert!(s.max_depth >= (bvh.primitives.len() as f32).log(8.0).ceil() as usize - 1);
    assert!(s.sah_cost > 1.0 && s.sah_cost.is_finite());
    assert_eq!(s.fallback, None);
}

/// The wide layout's `validate` rejects what the traversal could not trust: a child box cut
/// short on one axis (a primitive outside what the traversal reaches), a leaf whose unary
/// count is not one, and a primitive in two leaves.
#[test]
fn wide_validate_rejects_broken_trees() {
    let f = support::icosphere_on_plane();
    let good =
        GpuBvh::build_with_layout(&f.triangles, &f.spheres, BvhQuality::Fast, BvhLayout::Wide)
            .unwrap();
    good.validate().unwrap();
    let (node, slot) = good
        .wide_nodes
        .iter()
        .enumerate()
        .find_map(|(i, n)| {
            (0..8)
                .find(|&s| n.child_meta[s] != 0 && n.imask() & (1 << s) == 0)
                .map(|s| (i, s))
        })
        .expect("a leaf slot");
    let broken = |edit: &dyn Fn(&mut raylume_bvh::WideNode)| {
        let mut bvh = good.clone();
        edit(&mut bvh.wide_nodes[node]);
        bvh.validate()
    };
    // The upper x plane moved below the lower one.
    let cut = broken(&|n| n.q_x[8 + slot] = n.q_x[slot].saturating_sub(1));
    assert!(cut.is_err(), "a cut box passed");
    let meta = broken(&|n| n.child_meta[slot] = 0b0100_0000 | (n.child_meta[slot] & 0b1_1111));
    assert!(meta.unwrap_err().contains("leaf meta"));
    let twice = broken(&|n| {
        let other =
            (0..8).find(|&s| s != slot && n.child_meta[s] != 0 && n.imask() & (1 << s) == 0);
        if let Some(o) = other {
            n.child_meta[o] = n.child_meta[slot];
        } else {
            n.child_meta[slot] = 0;
        }
    });
    assert!(
        twice.is_err(),
        "a primitive in two leaves (or in none) passed"
    );
}
