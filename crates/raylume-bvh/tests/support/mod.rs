//! Fixture scenes, ray sets and the brute-force reference shared by the integration tests and
//! the bench. Everything is generated here from a seed: no files, no downloads.

#![allow(dead_code)]

use glam::{Mat3, Vec3};
use raylume_bvh::{
    GpuBvh, Hit, INVALID_INDEX, PRIM_SPHERE, PRIM_TRIANGLE, Ray, T_MISS, intersect_sphere,
    intersect_triangle, shear_ray,
};
use raylume_scene::{Sphere, Triangle};

/// A small, fast, seedable generator (SplitMix64), so fixtures need no `rand` crate.
#[derive(Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9e37_79b9_7f4a_7c15)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    pub fn vec3(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    /// Uniform on the unit sphere.
    pub fn direction(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// A test scene: triangles and spheres.
#[derive(Clone, Default)]
pub struct Fixture {
    pub name: &'static str,
    pub triangles: Vec<Triangle>,
    pub spheres: Vec<Sphere>,
}

impl Fixture {
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for t in &self.triangles {
            for p in t.positions {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        for s in &self.spheres {
            lo = lo.min(s.center - Vec3::splat(s.radius));
            hi = hi.max(s.center + Vec3::splat(s.radius));
        }
        (lo, hi)
    }

    pub fn primitive_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }
}

fn tri(a: Vec3, b: Vec3, c: Vec3) -> Triangle {
    Triangle::flat([a, b, c], 0)
}

/// Two triangles of the parallelogram `corner, corner + u, corner + u + v, corner + v`,
/// sharing the diagonal with bit-identical vertices.
pub fn quad(corner: Vec3, u: Vec3, v: Vec3) -> [Triangle; 2] {
    [
        tri(corner, corner + u, corner + u + v),
        tri(corner, corner + u + v, corner + v),
    ]
}

/// `n` random triangles in the unit cube, each within a box of side `size`.
pub fn random_soup(n: usize, size: f32, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let c = rng.vec3(Vec3::ZERO, Vec3::ONE);
            let h = Vec3::splat(size / 2.0);
            tri(
                rng.vec3(c - h, c + h),
                rng.vec3(c - h, c + h),
                rng.vec3(c - h, c + h),
            )
        })
        .collect()
}

/// An icosphere: an icosahedron subdivided `level` times (20 * 4^level triangles), vertices
/// shared between neighbouring triangles (computed once per edge midpoint).
pub fn icosphere(level: u32, center: Vec3, radius: f32) -> Vec<Triangle> {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize, verts: &mut Vec<Vec3>| -> usize {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push(((verts[a] + verts[b]) / 2.0).normalize());
                verts.len() - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut verts);
            let bc = midpoint(b, c, &mut verts);
            let ca = midpoint(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    faces
        .iter()
        .map(|f| {
            tri(
                center + verts[f[0]] * radius,
                center + verts[f[1]] * radius,
                center + verts[f[2]] * radius,
            )
        })
        .collect()
}

/// An axis-aligned box as 12 triangles, rotated by `yaw` radians about +y around its centre.
pub fn cuboid(center: Vec3, half: Vec3, yaw: f32) -> Vec<Triangle> {
    let rot = Mat3::from_rotation_y(yaw);
    let p = |x: f32, y: f32, z: f32| center + rot * (half * Vec3::new(x, y, z));
    let c = [
        p(-1.0, -1.0, -1.0),
        p(1.0, -1.0, -1.0),
        p(1.0, 1.0, -1.0),
        p(-1.0, 1.0, -1.0),
        p(-1.0, -1.0, 1.0),
        p(1.0, -1.0, 1.0),
        p(1.0, 1.0, 1.0),
        p(-1.0, 1.0, 1.0),
    ];
    let faces = [
        [0, 1, 2, 3],
        [5, 4, 7, 6],
        [4, 0, 3, 7],
        [1, 5, 6, 2],
        [3, 2, 6, 7],
        [4, 5, 1, 0],
    ];
    faces
        .iter()
        .flat_map(|f| {
            [
                tri(c[f[0]], c[f[1]], c[f[2]]),
                tri(c[f[0]], c[f[2]], c[f[3]]),
            ]
        })
        .collect()
}

/// A Cornell-box-like room in [-1, 1] x [0, 2] x [-1, 1]: floor, ceiling, back, left and
/// right walls (axis-aligned, exactly on the box's planes), a ceiling light quad, a short and
/// a tall rotated box. 36 triangles.
pub fn cornell_box() -> Fixture {
    let mut t = Vec::new();
    let x = Vec3::X * 2.0;
    let y = Vec3::Y * 2.0;
    let z = Vec3::Z * 2.0;
    t.extend(quad(Vec3::new(-1.0, 0.0, -1.0), z, x)); // floor
    t.extend(quad(Vec3::new(-1.0, 2.0, -1.0), x, z)); // ceiling
    t.extend(quad(Vec3::new(-1.0, 0.0, -1.0), x, y)); // back
    t.extend(quad(Vec3::new(-1.0, 0.0, -1.0), y, z)); // left
    t.extend(quad(Vec3::new(1.0, 0.0, -1.0), z, y)); // right
    t.extend(quad(
        Vec3::new(-0.25, 1.98, -0.25),
        Vec3::X * 0.5,
        Vec3::Z * 0.5,
    )); // light
    t.extend(cuboid(Vec3::new(0.35, 0.3, 0.3), Vec3::splat(0.3), -0.3));
    t.extend(cuboid(
        Vec3::new(-0.35, 0.6, -0.3),
        Vec3::new(0.3, 0.6, 0.3),
        0.3,
    ));
    Fixture {
        name: "cornell box",
        triangles: t,
        spheres: Vec::new(),
    }
}

/// A level-3 icosphere (1280 triangles) resting on a 10 x 10 plane.
pub fn icosphere_on_plane() -> Fixture {
    let mut t = icosphere(3, Vec3::new(0.0, 1.0, 0.0), 1.0);
    t.extend(quad(
        Vec3::new(-5.0, 0.0, -5.0),
        Vec3::Z * 10.0,
        Vec3::X * 10.0,
    ));
    Fixture {
        name: "icosphere + plane",
        triangles: t,
        spheres: Vec::new(),
    }
}

/// 800 random triangles of size 0.1 in the unit cube.
pub fn triangle_soup() -> Fixture {
    Fixture {
        name: "triangle soup",
        triangles: random_soup(800, 0.1, 7),
        spheres: Vec::new(),
    }
}

/// 60 random spheres (some overlapping, some inside others) among 300 random triangles, on a
/// floor, plus a glass-like sphere enclosing part of the soup.
pub fn spheres_and_triangles() -> Fixture {
    let mut rng = Rng::new(11);
    let mut t = random_soup(300, 0.15, 12);
    t.extend(quad(
        Vec3::new(-0.5, -0.05, -0.5),
        Vec3::Z * 2.0,
        Vec3::X * 2.0,
    ));
    let mut spheres: Vec<Sphere> = (0..60)
        .map(|_| Sphere {
            center: rng.vec3(Vec3::ZERO, Vec3::ONE),
            radius: rng.range(0.005, 0.08),
            material: 0,
        })
        .collect();
    spheres.push(Sphere {
        center: Vec3::splat(0.3),
        radius: 0.25,
        material: 0,
    });
    Fixture {
        name: "spheres + triangles",
        triangles: t,
        spheres,
    }
}

/// 300 small random triangles with 12 long, thin triangles laid diagonally across the cube:
/// the case spatial pre-splits are for.
pub fn slivers_in_soup() -> Fixture {
    let mut t = random_soup(300, 0.05, 13);
    let mut rng = Rng::new(14);
    for _ in 0..12 {
        let a = rng.vec3(Vec3::ZERO, Vec3::splat(0.1));
        let b = rng.vec3(Vec3::splat(0.9), Vec3::ONE);
        let w = rng.vec3(Vec3::splat(-0.01), Vec3::splat(0.01));
        t.push(tri(a, b, a + w));
    }
    Fixture {
        name: "slivers in soup",
        triangles: t,
        spheres: Vec::new(),
    }
}

/// Every fixture the brute-force tests run.
pub fn fixtures() -> Vec<Fixture> {
    vec![
        triangle_soup(),
        slivers_in_soup(),
        icosphere_on_plane(),
        cornell_box(),
        spheres_and_triangles(),
    ]
}

/// One query: a ray and its segment.
#[derive(Clone, Copy, Debug)]
pub struct Query {
    pub ray: Ray,
    pub t_min: f32,
    pub t_max: f32,
}

/// A point on a random primitive's surface (for rays that start on a surface).
pub fn surface_point(f: &Fixture, rng: &mut Rng) -> Vec3 {
    let n = f.primitive_count();
    let k = rng.below(n);
    if k < f.triangles.len() {
        let [a, b, c] = f.triangles[k].positions;
        let (mut u, mut v) = (rng.f32(), rng.f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        a + (b - a) * u + (c - a) * v
    } else {
        let s = &f.spheres[k - f.triangles.len()];
        s.center + rng.direction() * s.radius
    }
}

/// `n` queries of five kinds, in equal shares:
/// 1. random origins in the scene's box grown by half its size, random directions;
/// 2. the same with directions along an axis, the other components exactly `+0.0` or `-0.0`
///    (origins snapped half the time onto primitive vertices' planes, so that slab
///    distances hit `0 * inf`);
/// 3. origins on a surface (a point of a random primitive), `t_min` = 1e-4 of the scene size;
/// 4. rays from outside the grown box pointing away from it (must miss);
/// 5. rays aimed from outside at a random surface point, with a finite `t_max` that stops
///    half of them short of it.
pub fn queries(f: &Fixture, n: usize, seed: u64) -> Vec<Query> {
    let mut rng = Rng::new(seed);
    let (lo, hi) = f.bounds();
    let size = (hi - lo).max_element().max(1e-30);
    let grow = (hi - lo) * 0.5 + Vec3::splat(1e-3 * size);
    let (glo, ghi) = (lo - grow, hi + grow);
    let centre = (lo + hi) / 2.0;
    let inf = f32::INFINITY;
    (0..n)
        .map(|i| match i % 5 {
            0 => Query {
                ray: Ray::new(rng.vec3(glo, ghi), rng.direction()),
                t_min: 0.0,
                t_max: inf,
            },
            1 => {
                let axis = rng.below(3);
                let sign = if rng.f32() < 0.5 { -1.0 } else { 1.0 };
                let zero = if rng.f32() < 0.5 { 0.0 } else { -0.0 };
                let mut d = Vec3::splat(zero);
                d[axis] = sign;
                let mut o = rng.vec3(glo, ghi);
                if rng.f32() < 0.5 {
                    // Put the origin on a vertex's coordinate planes of the other axes.
                    let p = surface_vertex(f, &mut rng);
                    for a in 0..3 {
                        if a != axis {
                            o[a] = p[a];
                        }
                    }
                }
                Query {
                    ray: Ray::new(o, d),
                    t_min: 0.0,
                    t_max: inf,
                }
            }
            2 => Query {
                ray: Ray::new(surface_point(f, &mut rng), rng.direction()),
                t_min: 1e-4 * size,
                t_max: inf,
            },
            3 => {
                let d = rng.direction();
                let o = centre + d * (size * 3.0);
                Query {
                    ray: Ray::new(o, d),
                    t_min: 0.0,
                    t_max: inf,
                }
            }
            _ => {
                let target = surface_point(f, &mut rng);
                let o = centre + rng.direction() * (size * 2.0);
                let d = target - o;
                Query {
                    ray: Ray::new(o, d),
                    t_min: 0.0,
                    t_max: if rng.f32() < 0.5 { 0.9 } else { inf },
                }
            }
        })
        .collect()
}

fn surface_vertex(f: &Fixture, rng: &mut Rng) -> Vec3 {
    if f.triangles.is_empty() || (!f.spheres.is_empty() && rng.f32() < 0.2) {
        let s = &f.spheres[rng.below(f.spheres.len())];
        s.center + Vec3::splat(s.radius)
    } else {
        f.triangles[rng.below(f.triangles.len())].positions[rng.below(3)]
    }
}

/// A hit named by what it hit in the scene: (kind, scene index, t).
pub type SceneHit = (u32, u32, f32);

/// The closest hit by testing every scene primitive, in scene order, with the same
/// intersection functions the traversal uses.
pub fn brute_force(f: &Fixture, q: &Query) -> Option<SceneHit> {
    let mut best: Option<SceneHit> = None;
    let mut t_max = q.t_max.min(raylume_bvh::T_MAX_LIMIT);
    let sheared = shear_ray(&q.ray);
    for (i, t) in f.triangles.iter().enumerate() {
        let [a, b, c] = t.positions;
        let r = intersect_triangle(&sheared, a, b, c, q.t_min, t_max);
        if r.x < t_max {
            t_max = r.x;
            best = Some((PRIM_TRIANGLE, i as u32, r.x));
        }
    }
    for (i, s) in f.spheres.iter().enumerate() {
        let t = intersect_sphere(q.ray.origin, q.ray.dir, s.center, s.radius, q.t_min, t_max);
        if t < t_max {
            debug_assert!(t != T_MISS);
            t_max = t;
            best = Some((PRIM_SPHERE, i as u32, t));
        }
    }
    best
}

/// The BVH's closest hit named by scene primitive.
pub fn scene_hit(bvh: &GpuBvh, hit: &Hit) -> SceneHit {
    assert_ne!(hit.prim, INVALID_INDEX);
    let p = &bvh.primitives[hit.prim as usize];
    (p.kind(), p.scene_index(), hit.t)
}

/// Tolerance within which two different primitives hit at "the same" distance may be reported
/// either way: at a shared edge or vertex, where a sphere touches a plane, or where faces
/// coincide, several primitives are hit at one point, and which one a traversal reports
/// depends on the order it meets them in. Their computed `t`s differ by rounding, and
/// Möller–Trumbore's error in `t` scales with the coordinates involved (origin and vertices),
/// not with `t`: a ray starting 1e-3 below a vertex of a unit sphere sees the six triangles
/// around it at `t`s 1e-5 apart relatively but 1e-8 absolutely. So a tie is
/// `|t1 - t2| <= 1e-6 * max(t, scene size / |dir|)`: 1e-6 relative to `t` for distant hits,
/// to the scene's size for near ones (a few ulp either way, ~10x the observed spread).
pub const TIE_RELATIVE: f32 = 1e-6;

/// Compares BVH traversal with brute force on every query, closest-hit and any-hit; panics
/// with the first few disagreements. Returns the number of queries that hit something.
pub fn check_against_brute_force(
    f: &Fixture,
    bvh: &GpuBvh,
    queries: &[Query],
    reference: &[Option<SceneHit>],
) -> usize {
    use rayon::prelude::*;
    let (lo, hi) = f.bounds();
    let size = (hi - lo).max_element();
    let failures: Vec<String> = queries
        .par_iter()
        .zip(reference)
        .enumerate()
        .filter_map(|(i, (q, want))| {
            let got_hit = bvh.trace_closest(&q.ray, q.t_min, q.t_max);
            let got = got_hit.map(|h| scene_hit(bvh, &h));
            let any = bvh.trace_any(&q.ray, q.t_min, q.t_max);
            let closest_ok = match (got, want) {
                (None, None) => true,
                (Some(g), Some(w)) if (g.0, g.1) == (w.0, w.1) => {
                    // Same primitive, same function, same inputs: the same t, bit for bit.
                    g.2 == w.2
                }
                (Some(g), Some(w)) => {
                    let scale = w.2.abs().max(size / q.ray.dir.length());
                    (g.2 - w.2).abs() <= TIE_RELATIVE * scale
                }
                _ => false,
            };
            let any_ok = any == want.is_some();
            // Without spheres the triangles-only walk (on the CPU, leaves four triangles at a
            // time) finds the same hit, bit for bit, ties included.
            let bits = |h: Option<raylume_bvh::Hit>| {
                h.map(|h| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
            };
            let triangles_ok = !f.spheres.is_empty()
                || (bits(bvh.trace_closest_for::<false>(&q.ray, q.t_min, q.t_max))
                    == bits(bvh.trace_closest(&q.ray, q.t_min, q.t_max))
                    && bvh.trace_any_for::<false>(&q.ray, q.t_min, q.t_max) == any);
            // The walks with AVX2 node and triangle tests (where this CPU has AVX2): the
            // same hits bit for bit, the triangles-only one where there are no spheres.
            #[cfg(target_arch = "x86_64")]
            let avx2_ok = !std::arch::is_x86_feature_detected!("avx2") || {
                let (o, t0, t1) = (&q.ray, q.t_min, q.t_max);
                // SAFETY: this CPU has AVX2 (detected above).
                unsafe {
                    bits(bvh.trace_closest_avx2::<true>(o, t0, t1)) == bits(got_hit)
                        && bvh.trace_any_avx2::<true>(o, t0, t1) == any
                        && (!f.spheres.is_empty()
                            || (bits(bvh.trace_closest_avx2::<false>(o, t0, t1)) == bits(got_hit)
                                && bvh.trace_any_avx2::<false>(o, t0, t1) == any))
                }
            };
            // The AVX-512 walks (where this CPU has AVX-512 F): the same, the Cornell box's
            // small tree tested flat sixteen triangles at a time.
            #[cfg(target_arch = "x86_64")]
            let avx2_ok = avx2_ok
                && (!std::arch::is_x86_feature_detected!("avx512f") || {
                    let (o, t0, t1) = (&q.ray, q.t_min, q.t_max);
                    // SAFETY: this CPU has AVX-512 F (detected above) and so AVX2.
                    unsafe {
                        bits(bvh.trace_closest_avx512::<true>(o, t0, t1)) == bits(got_hit)
                            && bvh.trace_any_avx512::<true>(o, t0, t1) == any
                            && (!f.spheres.is_empty()
                                || (bits(bvh.trace_closest_avx512::<false>(o, t0, t1))
                                    == bits(got_hit)
                                    && bvh.trace_any_avx512::<false>(o, t0, t1) == any))
                    }
                });
            #[cfg(not(target_arch = "x86_64"))]
            let avx2_ok = true;
            // A wide tree: the CPU's walk (float boxes) finds what the WGSL's mirror
            // (quantised boxes) finds: the same scene primitive at the same t, u, v, bit for
            // bit (a pre-split triangle's copies may stand in for each other), and the same
            // any-hit answer.
            let mirror_ok = bvh.layout != raylume_bvh::BvhLayout::Wide || {
                use raylume_bvh::wide_traverse;
                let same = |h: raylume_bvh::Hit| {
                    (h.prim != INVALID_INDEX).then(|| {
                        let p = &bvh.primitives[h.prim as usize];
                        (
                            p.kind(),
                            p.scene_index(),
                            h.t.to_bits(),
                            h.u.to_bits(),
                            h.v.to_bits(),
                        )
                    })
                };
                let (n, p) = (&bvh.wide_nodes, &bvh.primitives);
                let mirror = wide_traverse::trace_closest(n, p, &q.ray, q.t_min, q.t_max);
                let cpu = bvh.trace_closest(&q.ray, q.t_min, q.t_max);
                same(mirror) == cpu.and_then(same)
                    && wide_traverse::trace_any(n, p, &q.ray, q.t_min, q.t_max) == any
            };
            (!(closest_ok && any_ok && triangles_ok && mirror_ok && avx2_ok)).then(|| {
                format!(
                    "{} query {i} {q:?}: bvh {got:?} any {any}, brute force {want:?}, \
                     triangles-only walk the same: {triangles_ok}, the quantised walk the \
                     same: {mirror_ok}, the AVX2 walks the same: {avx2_ok}",
                    f.name
                )
            })
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} queries disagree with brute force, e.g.:\n{}",
        failures.len(),
        queries.len(),
        failures[..failures.len().min(8)].join("\n")
    );
    reference.iter().filter(|r| r.is_some()).count()
}
