//! Property tests over random triangle soups, degenerate ones included: every build
//! validates, and traversal agrees with brute force (closest hit and any hit).

mod support;

use glam::Vec3;
use proptest::prelude::*;
use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh};
use raylume_scene::{Sphere, Triangle};
use support::{Fixture, Rng, brute_force, check_against_brute_force, queries};

/// What a generated soup looks like.
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// Random triangles of random sizes.
    Random,
    /// One triangle repeated: coincident boxes (past 64 copies, the median fallback).
    Identical,
    /// Triangles whose three vertices lie on one line (zero area).
    Collinear,
    /// Triangles collapsed to a point.
    Points,
    /// Random triangles, duplicates, slivers, degenerate ones and spheres together.
    Mixed,
}

fn kind() -> impl Strategy<Value = Kind> {
    prop_oneof![
        Just(Kind::Random),
        Just(Kind::Identical),
        Just(Kind::Collinear),
        Just(Kind::Points),
        Just(Kind::Mixed),
    ]
}

/// A soup of `n` primitives of `kind` in the unit cube, scaled by `10^scale_exp` and moved
/// by up to 100 times that: coordinates from 1e-12 to 1e14. (Further apart, f32 cannot hold
/// the triangles' shapes and no traversal is meaningful.)
fn soup(kind: Kind, n: usize, scale_exp: i32, seed: u64) -> Fixture {
    let mut rng = Rng::new(seed);
    let scale = 10f32.powi(scale_exp);
    let offset = rng.vec3(Vec3::splat(-100.0), Vec3::splat(100.0)) * scale;
    let place = |p: Vec3| p * scale + offset;
    let rand_tri = |rng: &mut Rng| {
        let c = rng.vec3(Vec3::ZERO, Vec3::ONE);
        let h = Vec3::splat(rng.range(0.001, 0.5));
        [
            rng.vec3(c - h, c + h),
            rng.vec3(c - h, c + h),
            rng.vec3(c - h, c + h),
        ]
    };
    let mut triangles: Vec<[Vec3; 3]> = Vec::new();
    let mut spheres = Vec::new();
    match kind {
        Kind::Random => triangles.extend((0..n).map(|_| rand_tri(&mut rng))),
        Kind::Identical => triangles.extend(std::iter::repeat_n(rand_tri(&mut rng), n)),
        Kind::Collinear => {
            for _ in 0..n {
                let a = rng.vec3(Vec3::ZERO, Vec3::ONE);
                let d = rng.direction() * 0.3;
                triangles.push([a, a + d * rng.f32(), a + d]);
            }
        }
        Kind::Points => {
            for _ in 0..n {
                let p = rng.vec3(Vec3::ZERO, Vec3::ONE);
                triangles.push([p, p, p]);
            }
        }
        Kind::Mixed => {
            for i in 0..n {
                match i % 6 {
                    0 | 1 => triangles.push(rand_tri(&mut rng)),
                    2 => {
                        let t = triangles
                            .last()
                            .copied()
                            .unwrap_or_else(|| rand_tri(&mut rng));
                        triangles.push(t);
                    }
                    3 => {
                        let a = rng.vec3(Vec3::ZERO, Vec3::splat(0.1));
                        let b = rng.vec3(Vec3::splat(0.9), Vec3::ONE);
                        triangles.push([a, b, a + rng.direction() * 0.01]);
                    }
                    4 => {
                        let p = rng.vec3(Vec3::ZERO, Vec3::ONE);
                        triangles.push([p, p, p + Vec3::X * 0.1]);
                    }
                    _ => spheres.push(Sphere {
                        center: place(rng.vec3(Vec3::ZERO, Vec3::ONE)),
                        radius: rng.range(0.001, 0.3) * scale,
                        material: 0,
                    }),
                }
            }
        }
    }
    Fixture {
        name: "proptest soup",
        triangles: triangles
            .into_iter()
            .map(|[a, b, c]| Triangle::flat([place(a), place(b), place(c)], 0))
            .collect(),
        spheres,
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 96,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn soups_build_validate_and_trace_like_brute_force(
        kind in kind(),
        n in 1usize..160,
        scale_exp in -12i32..=12,
        seed in any::<u64>(),
    ) {
        let f = soup(kind, n, scale_exp, seed);
        let qs = queries(&f, 300, seed ^ 0x5eed);
        let reference: Vec<_> = qs.iter().map(|q| brute_force(&f, q)).collect();
        for quality in [BvhQuality::Fast, BvhQuality::Quality] {
            for layout in [BvhLayout::Binary, BvhLayout::Wide] {
                let bvh = GpuBvh::build_with_layout(&f.triangles, &f.spheres, quality, layout)
                    .map_err(|e| TestCaseError::fail(format!("{quality:?} {layout:?}: {e}")))?;
                bvh.validate()
                    .map_err(|e| TestCaseError::fail(format!("{quality:?} {layout:?}: {e}")))?;
                check_against_brute_force(&f, &bvh, &qs, &reference);
            }
        }
    }
}
