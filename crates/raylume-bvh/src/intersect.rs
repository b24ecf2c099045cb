//! Ray/box, ray/triangle and ray/sphere tests, the building blocks of [`crate::traverse`];
//! `intersect.wgsl` mirrors them function for function, with the same names, constants and
//! operation order.
//!
//! - [`intersect_aabb`]: slab test against a precomputed inverse direction, written so that
//!   direction components of `+0.0`/`-0.0` (inverse `±inf`) and origins lying exactly on a
//!   slab plane (`0 * inf = NaN`) are handled, and conservative under rounding.
//! - [`intersect_triangle`]: watertight (Woop, Benthin & Wald, JCGT 2013), edges and vertices
//!   included, on a ray prepared once by [`shear_ray`].
//! - [`intersect_sphere`]: the nearest root past `t_min`, computed without the cancellations
//!   of the textbook quadratic.
//!
//! Arithmetic is spelled out (`bvh_dot`, no `mul_add`) so that the WGSL evaluates the same
//! expressions in the same order; a GPU compiler may still contract `a * b + c` into a fused
//! multiply-add, which is the one source of CPU/GPU difference.

use glam::{Mat4, Vec3, Vec4};

use crate::{PRIM_SPHERE, Primitive};

/// What the `intersect_*` functions return for "no hit": `f32::MAX`. WGSL: `T_MISS`.
pub const T_MISS: f32 = f32::MAX;

/// The slab test accepts a box when `t_near <= t_far * AABB_T_FAR_SCALE`: 1 + 2^-20, i.e.
/// 16 units of roundoff. Each slab distance `(b - o) * inv_dir` carries one rounding from the
/// subtraction, one from the product and that of `inv_dir` (exact to 1/2 ulp on the CPU, to
/// 2.5 ulp on Vulkan GPUs), at most 7 units in all; scaling `t_far` by `1 + 2 * 7` units makes
/// the test conservative (Ize, *Robust BVH Ray Traversal*, JCGT 2013, with the GPU's division
/// error added). WGSL: `AABB_T_FAR_SCALE`.
pub const AABB_T_FAR_SCALE: f32 = 1.0 + 1.0 / 1_048_576.0;

/// A ray `origin + t * dir`. `dir` need not be normalised but must not be zero; `t` is in
/// units of `dir`. WGSL: `Ray` (a value type, not a buffer layout).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray { origin, dir }
    }
}

#[inline(always)]
fn bvh_dot(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// `max(a, b)` that returns `b` when `a` is NaN (a NaN compares false). WGSL:
/// `select(b, a, a > b)`.
#[inline(always)]
fn max_or_second(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// `min(a, b)` that returns `b` when `a` is NaN. WGSL: `select(b, a, a < b)`.
#[inline(always)]
fn min_or_second(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// Slab test of the box `[bmin, bmax]` against the ray segment `[t_min, t_max]`: the entry
/// distance (at least `t_min`) when they overlap, else [`T_MISS`]. `inv_dir = 1 / dir` per
/// component, `±inf` for `±0` components. Requires `t_max <= T_MAX_LIMIT` (see
/// [`crate::T_MAX_LIMIT`]) and `t_min < T_MISS`.
///
/// Per axis, with `t0 = (bmin - o) * inv`, `t1 = (bmax - o) * inv`:
/// `near = min(max'(t0, t_min), max'(t1, t_min))` and
/// `far = max(min'(t0, t_max), min'(t1, t_max))`, where `max'`/`min'` return their second
/// operand when the first is NaN (T. Barnes, *Fast, Branchless Ray/Bounding Box
/// Intersections, Part 3: Boundaries*, 2022). Without NaNs this is the usual
/// `near = max(t_min, min(t0, t1))`. A NaN arises only as `0 * inf`: the direction component
/// is zero and the origin lies exactly on that slab's plane, so the ray runs inside the
/// (closed) slab; the NaN then drops out and the axis does not constrain the interval, which is
/// the right answer for a boundary-inclusive box (a flat box, `bmin == bmax`, included).
///
/// The box is hit when `max(near) <= min(far) * AABB_T_FAR_SCALE` (see there).
#[inline(always)]
pub fn intersect_aabb(
    bmin: Vec3,
    bmax: Vec3,
    origin: Vec3,
    inv_dir: Vec3,
    t_min: f32,
    t_max: f32,
) -> f32 {
    let t0 = (bmin - origin) * inv_dir;
    let t1 = (bmax - origin) * inv_dir;
    let near_x = max_or_second(t0.x, t_min).min(max_or_second(t1.x, t_min));
    let near_y = max_or_second(t0.y, t_min).min(max_or_second(t1.y, t_min));
    let near_z = max_or_second(t0.z, t_min).min(max_or_second(t1.z, t_min));
    let far_x = min_or_second(t0.x, t_max).max(min_or_second(t1.x, t_max));
    let far_y = min_or_second(t0.y, t_max).max(min_or_second(t1.y, t_max));
    let far_z = min_or_second(t0.z, t_max).max(min_or_second(t1.z, t_max));
    let t_near = near_x.max(near_y.max(near_z));
    let t_far = far_x.min(far_y.min(far_z));
    if t_near <= t_far * AABB_T_FAR_SCALE {
        t_near
    } else {
        T_MISS
    }
}

/// A ray prepared for [`intersect_triangle`] (Woop, Benthin & Wald, *Watertight Ray/Triangle
/// Intersection*, JCGT 2013): `kz` is the axis of the direction's largest component, `kx`,
/// `ky` the next two cyclically, and `shear = (dir[kx] / dir[kz], dir[ky] / dir[kz],
/// 1 / dir[kz])`. WGSL: `ShearedRay` (a value type, not a buffer layout).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShearedRay {
    pub origin: Vec3,
    pub dir: Vec3,
    pub shear: Vec3,
    pub kx: u32,
    pub ky: u32,
    pub kz: u32,
}

/// Prepares `ray` for [`intersect_triangle`]; traversal calls it once per ray.
#[inline(always)]
pub fn shear_ray(ray: &Ray) -> ShearedRay {
    let (kx, ky, kz) = shear_axes(ray.dir);
    let sz = 1.0 / ray.dir.to_array()[kz as usize];
    sheared(ray, kx, ky, kz, sz)
}

/// [`shear_ray`] given `inv = 1 / ray.dir` (unclamped, per component): the same ray bit for
/// bit (its `1 / dir[kz]` is `inv[kz]`), for a walk that divides once for both its box tests
/// and its triangle tests.
#[inline(always)]
pub(crate) fn shear_ray_inv(ray: &Ray, inv: Vec3) -> ShearedRay {
    let (kx, ky, kz) = shear_axes(ray.dir);
    sheared(ray, kx, ky, kz, inv.to_array()[kz as usize])
}

/// `(kx, ky, kz)` of [`ShearedRay`] for direction `d`.
#[inline(always)]
fn shear_axes(d: Vec3) -> (u32, u32, u32) {
    let ad = d.abs();
    // The WGSL's two selects, without a branch: which axis is largest is a coin toss for
    // diffuse rays (living room, closest hits on the CPU: 293-303 -> 278-289 ns).
    let x_first = (ad.x >= ad.y) & (ad.x >= ad.z);
    let kz: u32 = if x_first {
        0
    } else {
        2 - u32::from(ad.y >= ad.z)
    };
    let kx = (kz + 1) % 3;
    let ky = (kx + 1) % 3;
    (kx, ky, kz)
}

/// The [`ShearedRay`] of `ray` on axes `(kx, ky, kz)` with `sz = 1 / dir[kz]`.
#[inline(always)]
fn sheared(ray: &Ray, kx: u32, ky: u32, kz: u32, sz: f32) -> ShearedRay {
    let d = ray.dir;
    let da = d.to_array();
    ShearedRay {
        origin: ray.origin,
        dir: d,
        shear: Vec3::new(da[kx as usize] * sz, da[ky as usize] * sz, sz),
        kx,
        ky,
        kz,
    }
}

/// Ray/triangle test: `(t, u, v)` for a hit with `t_min < t < t_max`, else
/// `(T_MISS, 0, 0)`. Both faces count; edges and vertices are included.
///
/// **Watertight** (Woop, Benthin & Wald, JCGT 2013). The vertices, relative to the ray
/// origin, are sheared into ray space, where the ray is the `z` axis:
/// `x = p[kx] - shear.x * p[kz]`, `y = p[ky] - shear.y * p[kz]`. The three edge functions
/// are 2D cross products of two vertices each, `w0 = cx by - cy bx` (edge v1 v2),
/// `w1 = ax cy - ay cx`, `w2 = bx ay - by ax`, and the ray is inside when all three have one
/// sign, zero counting as either. A vertex's sheared coordinates are computed the same way in
/// every triangle that has it, and an edge function is exactly antisymmetric in IEEE
/// arithmetic without contraction (products commute, `fl(p - q) = -fl(q - p)`): the
/// neighbour across an edge computes the same value with the opposite sign, so a ray through a
/// shared edge (bit-identical vertices) hits at least one of the two triangles. The sheared
/// coordinates are distances from the ray's line, so the test loses precision only linearly
/// with the origin's distance, as Möller–Trumbore does.
///
/// Möller–Trumbore (JGT 1997) with inclusive barycentric tests, the usual choice, computes
/// an edge's barycentric from a different base vertex in each triangle and is not
/// watertight: in `tests/edges.rs` it lets 258 of 30,000 rays aimed at shared edges of a
/// closed icosphere slip through the mesh (11–14 % of them miss both triangles of the edge
/// they aim at); this test lets none through. It costs a handful more operations.
///
/// `u = w1 / det`, `v = w2 / det` with `det = w0 + w1 + w2`; `t` is the depth `z = shear.z *
/// p[kz]` interpolated with those weights, `(w0 az + w1 bz + w2 cz) / det`, a weighted mean of
/// three nearly equal numbers with weights of one sign, so it does not cancel.
///
/// Near-zero determinant: only `det == 0` is rejected (the ray lies in the triangle's plane,
/// or the triangle is degenerate, in ray space). An absolute threshold such as
/// `|det| < 1e-8` would wrongly reject small triangles, since `det` scales with the
/// triangle's projected area; once all three edge functions share a sign, a tiny `det` still
/// gives barycentrics in [0, 1] and a `t` between the vertices' depths.
///
/// On a GPU that contracts `x * y - z * w` into a fused multiply-add the antisymmetry holds
/// only to an ulp, so there a ray exactly through an edge may, rarely, slip through.
#[inline(always)]
pub fn intersect_triangle(
    r: &ShearedRay,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Vec3 {
    let miss = Vec3::new(T_MISS, 0.0, 0.0);
    let (kx, ky, kz) = (r.kx as usize, r.ky as usize, r.kz as usize);
    let a = v0 - r.origin;
    let b = v1 - r.origin;
    let c = v2 - r.origin;
    let ax = a[kx] - r.shear.x * a[kz];
    let ay = a[ky] - r.shear.y * a[kz];
    let bx = b[kx] - r.shear.x * b[kz];
    let by = b[ky] - r.shear.y * b[kz];
    let cx = c[kx] - r.shear.x * c[kz];
    let cy = c[ky] - r.shear.y * c[kz];
    let w0 = cx * by - cy * bx;
    let w1 = ax * cy - ay * cx;
    let w2 = bx * ay - by * ax;
    let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
    let det = w0 + w1 + w2;
    if !inside || det == 0.0 {
        return miss;
    }
    let az = r.shear.z * a[kz];
    let bz = r.shear.z * b[kz];
    let cz = r.shear.z * c[kz];
    let inv_det = 1.0 / det;
    let t = (w0 * az + w1 * bz + w2 * cz) * inv_det;
    if t > t_min && t < t_max {
        Vec3::new(t, w1 * inv_det, w2 * inv_det)
    } else {
        miss
    }
}

/// [`intersect_triangle`] of four triangles at once, one per lane of glam's `Vec4` (SSE2 on
/// x86-64, NEON on aarch64): `(t, u, v)` per lane, `t = T_MISS` where that triangle is missed.
/// The CPU's form of the loop over a leaf's primitives (the GPU tests one per iteration); each
/// lane computes what [`intersect_triangle`] computes for its triangle, operation for
/// operation (the same products, sums and division in the same order, none fused), so the
/// values are the same bit for bit (tested).
#[inline(always)]
pub fn intersect_triangles4(
    r: &ShearedRay,
    tris: [&Primitive; 4],
    t_min: f32,
    t_max: f32,
) -> [Vec4; 3] {
    // Lane j of row i of each matrix: coordinate i of triangle j's vertex.
    let rows = |v: [&[f32; 4]; 4]| {
        Mat4::from_cols(
            Vec4::from_array(*v[0]),
            Vec4::from_array(*v[1]),
            Vec4::from_array(*v[2]),
            Vec4::from_array(*v[3]),
        )
        .transpose()
    };
    let (va, vb, vc) = (
        rows(tris.map(|p| &p.a)),
        rows(tris.map(|p| &p.b)),
        rows(tris.map(|p| &p.c)),
    );
    triangles4_core(r, |vertex, k| [&va, &vb, &vc][vertex].col(k), t_min, t_max)
}

/// Four triangles' vertices, interleaved for the CPU's wide walk (a node's leaves' triangles,
/// [`triangle_blocks`](crate::wide_traverse::triangle_blocks)): `v[3 * axis + vertex]` holds
/// coordinate `axis` of vertex `vertex` (a, b, c) of the four lanes, one load each, 144
/// bytes in one place (nine columns of the primitive array would take nine cache lines).
/// Axis-major, so that a ray's three axes `kx`, `ky`, `kz` are three offsets for the nine
/// loads (each `3 * k + vertex`), not nine.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct TriangleBlock {
    pub v: [Vec4; 9],
}

impl TriangleBlock {
    /// Puts the triangle `p`'s vertices in lane `lane` (0..4).
    pub fn set_lane(&mut self, lane: usize, p: &Primitive) {
        for (vertex, v) in [&p.a, &p.b, &p.c].into_iter().enumerate() {
            for (axis, &x) in v[..3].iter().enumerate() {
                self.v[3 * axis + vertex][lane] = x;
            }
        }
    }
}

/// [`intersect_triangles4`] of a block's four triangles (a lane of zeros, a degenerate
/// triangle, is a miss): the same values, bit for bit.
#[inline(always)]
pub fn intersect_triangle_block(
    r: &ShearedRay,
    block: &TriangleBlock,
    t_min: f32,
    t_max: f32,
) -> [Vec4; 3] {
    triangles4_core(r, |vertex, k| block.v[3 * k + vertex], t_min, t_max)
}

/// The arithmetic of [`intersect_triangles4`], lane by lane that of [`intersect_triangle`];
/// `coord(vertex, axis)` gives the four lanes' coordinate `axis` of vertex `vertex`.
#[inline(always)]
fn triangles4_core(
    r: &ShearedRay,
    coord: impl Fn(usize, usize) -> Vec4,
    t_min: f32,
    t_max: f32,
) -> [Vec4; 3] {
    let (kx, ky, kz) = (r.kx as usize, r.ky as usize, r.kz as usize);
    let o = r.origin.to_array();
    // p[k] - origin[k]: the component of `v0 - r.origin` that intersect_triangle picks.
    let rel = |vertex: usize, k: usize| coord(vertex, k) - Vec4::splat(o[k]);
    let (a_x, a_y, a_z) = (rel(0, kx), rel(0, ky), rel(0, kz));
    let (b_x, b_y, b_z) = (rel(1, kx), rel(1, ky), rel(1, kz));
    let (c_x, c_y, c_z) = (rel(2, kx), rel(2, ky), rel(2, kz));
    let (sx, sy, sz) = (
        Vec4::splat(r.shear.x),
        Vec4::splat(r.shear.y),
        Vec4::splat(r.shear.z),
    );
    let ax = a_x - sx * a_z;
    let ay = a_y - sy * a_z;
    let bx = b_x - sx * b_z;
    let by = b_y - sy * b_z;
    let cx = c_x - sx * c_z;
    let cy = c_y - sy * c_z;
    let w0 = cx * by - cy * bx;
    let w1 = ax * cy - ay * cx;
    let w2 = bx * ay - by * ax;
    let zero = Vec4::ZERO;
    let inside = (w0.cmpge(zero) & w1.cmpge(zero) & w2.cmpge(zero))
        | (w0.cmple(zero) & w1.cmple(zero) & w2.cmple(zero));
    let det = w0 + w1 + w2;
    let az = sz * a_z;
    let bz = sz * b_z;
    let cz = sz * c_z;
    let inv_det = Vec4::ONE / det;
    let t = (w0 * az + w1 * bz + w2 * cz) * inv_det;
    let hit = inside & det.cmpne(zero) & t.cmpgt(Vec4::splat(t_min)) & t.cmplt(Vec4::splat(t_max));
    [
        Vec4::select(hit, t, Vec4::splat(T_MISS)),
        Vec4::select(hit, w1 * inv_det, zero),
        Vec4::select(hit, w2 * inv_det, zero),
    ]
}

/// Ray/sphere test: the smallest root `t` with `t_min < t < t_max`, else [`T_MISS`]. A ray
/// starting inside the sphere (or on its surface, `t_min` past the root at its origin) hits
/// the far side, which is what refraction through glass needs.
///
/// With `oc = center - origin` and `a = dir . dir`, the roots of
/// `|t dir - oc|^2 = r^2` are `tc ± s` where `tc = (oc . dir) / a` is the closest approach
/// and `s^2 = (r^2 - |l|^2) / a`, `l = oc - tc dir` the offset of the centre from the line.
/// Computing `s^2` from `|l|`, not as the textbook `b^2 - a c`, keeps small, distant spheres
/// from cancelling (Haines et al., *Precision Improvements for Ray/Sphere Intersection*, Ray
/// Tracing Gems, 2019); dividing by `a` before multiplying keeps every intermediate quadratic
/// in the scene's scale, so nothing underflows for scenes of size 1e-12 either. The root
/// nearer `0` is taken as `(c / a) / q` with `q = tc ± s` of the sign of `tc` (the product of
/// the roots is `c / a`, `c = |oc|^2 - r^2`), so that neither root subtracts nearly equal
/// numbers.
#[inline(always)]
pub fn intersect_sphere(
    origin: Vec3,
    dir: Vec3,
    center: Vec3,
    radius: f32,
    t_min: f32,
    t_max: f32,
) -> f32 {
    let oc = center - origin;
    let inv_a = 1.0 / bvh_dot(dir, dir);
    let tc = bvh_dot(oc, dir) * inv_a;
    let r2 = radius * radius;
    let l = oc - dir * tc;
    let h = (r2 - bvh_dot(l, l)) * inv_a;
    if h < 0.0 {
        return T_MISS;
    }
    let s = h.sqrt();
    let q = if tc >= 0.0 { tc + s } else { tc - s };
    if q == 0.0 {
        // tc == 0 and s == 0: a ray tangent to the sphere at its own origin.
        return T_MISS;
    }
    let ta = (bvh_dot(oc, oc) - r2) * inv_a / q;
    let t_lo = ta.min(q);
    let t_hi = ta.max(q);
    let t = if t_lo > t_min { t_lo } else { t_hi };
    if t > t_min && t < t_max { t } else { T_MISS }
}

/// One primitive of either kind: `(t, u, v)` as [`intersect_triangle`] returns it. With
/// `SPHERES` false the sphere test is left out (every primitive is read as a triangle), as in
/// the tracer's WGSL composed for a scene without spheres (its `//#if spheres` block): only
/// for trees without spheres.
#[inline(always)]
pub fn intersect_primitive<const SPHERES: bool>(
    p: &Primitive,
    r: &ShearedRay,
    t_min: f32,
    t_max: f32,
) -> Vec3 {
    let a = Vec3::new(p.a[0], p.a[1], p.a[2]);
    debug_assert!(
        SPHERES || p.b[3].to_bits() != PRIM_SPHERE,
        "a sphere traced without SPHERES"
    );
    if SPHERES && p.b[3].to_bits() == PRIM_SPHERE {
        let t = intersect_sphere(r.origin, r.dir, a, p.a[3], t_min, t_max);
        Vec3::new(t, 0.0, 0.0)
    } else {
        let b = Vec3::new(p.b[0], p.b[1], p.b[2]);
        let c = Vec3::new(p.c[0], p.c[1], p.c[2]);
        intersect_triangle(r, a, b, c, t_min, t_max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::T_MAX_LIMIT;

    const INF: f32 = f32::INFINITY;

    fn unit_box() -> (Vec3, Vec3) {
        (Vec3::ZERO, Vec3::ONE)
    }

    fn aabb(origin: Vec3, dir: Vec3) -> f32 {
        let (lo, hi) = unit_box();
        intersect_aabb(lo, hi, origin, Vec3::ONE / dir, 0.0, T_MAX_LIMIT)
    }

    #[test]
    fn aabb_entry_distance_and_misses() {
        assert_eq!(aabb(Vec3::new(-1.0, 0.5, 0.5), Vec3::X), 1.0);
        assert_eq!(
            aabb(Vec3::new(0.5, 0.5, 0.5), Vec3::X),
            0.0,
            "inside: t_min"
        );
        assert_eq!(aabb(Vec3::new(2.0, 0.5, 0.5), Vec3::X), T_MISS, "behind");
        assert_eq!(aabb(Vec3::new(-1.0, 2.0, 0.5), Vec3::X), T_MISS, "beside");
        let (lo, hi) = unit_box();
        let inv = Vec3::ONE / Vec3::X;
        assert_eq!(
            intersect_aabb(lo, hi, Vec3::new(-5.0, 0.5, 0.5), inv, 0.0, 4.0),
            T_MISS
        );
    }

    #[test]
    fn aabb_zero_direction_components_of_both_signs() {
        for zero in [0.0f32, -0.0] {
            let dir = Vec3::new(1.0, zero, zero);
            assert_eq!(
                (Vec3::ONE / dir).y,
                if zero.is_sign_positive() { INF } else { -INF }
            );
            // Inside the y and z slabs, outside them, and exactly on each of their planes
            // (where (b - o) * inv = 0 * inf = NaN): boundary-inclusive.
            assert_eq!(aabb(Vec3::new(-1.0, 0.5, 0.5), dir), 1.0);
            assert_eq!(aabb(Vec3::new(-1.0, 1.5, 0.5), dir), T_MISS);
            assert_eq!(aabb(Vec3::new(-1.0, -0.5, 0.5), dir), T_MISS);
            for y in [0.0, 1.0] {
                for z in [0.0, 0.5, 1.0] {
                    assert_eq!(
                        aabb(Vec3::new(-1.0, y, z), dir),
                        1.0,
                        "on plane y={y} z={z}"
                    );
                }
            }
        }
    }

    #[test]
    fn aabb_flat_box_is_hit_on_and_across_its_plane() {
        let (lo, hi) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 1.0));
        let inv = Vec3::ONE / Vec3::new(0.0, -1.0, 0.0);
        let t = intersect_aabb(lo, hi, Vec3::new(0.5, 2.0, 0.5), inv, 0.0, 10.0);
        assert_eq!(t, 2.0);
        // A ray lying in the box's plane, direction exactly parallel: NaN on y, still a hit.
        let inv = Vec3::ONE / Vec3::new(1.0, 0.0, 0.0);
        let t = intersect_aabb(lo, hi, Vec3::new(-1.0, 0.0, 0.5), inv, 0.0, 10.0);
        assert_eq!(t, 1.0);
    }

    fn tri(o: Vec3, d: Vec3, v0: Vec3, v1: Vec3, v2: Vec3, t_min: f32, t_max: f32) -> Vec3 {
        intersect_triangle(&shear_ray(&Ray::new(o, d)), v0, v1, v2, t_min, t_max)
    }

    #[test]
    fn triangle_barycentrics_edges_and_faces() {
        let (v0, v1, v2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let r = tri(Vec3::new(0.25, 0.5, 1.0), -Vec3::Z, v0, v1, v2, 0.0, INF);
        assert_eq!(r, Vec3::new(1.0, 0.25, 0.5));
        // Back face counts too.
        let r = tri(Vec3::new(0.25, 0.5, -2.0), Vec3::Z, v0, v1, v2, 0.0, INF);
        assert_eq!(r, Vec3::new(2.0, 0.25, 0.5));
        // Vertices and edge points are included.
        for p in [
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (0.5, 0.5),
            (0.5, 0.0),
            (0.0, 0.5),
        ] {
            let r = tri(Vec3::new(p.0, p.1, 1.0), -Vec3::Z, v0, v1, v2, 0.0, INF);
            assert_eq!(r.x, 1.0, "point {p:?}");
        }
        // Outside, behind t_min, beyond t_max, in-plane.
        let o = Vec3::new(0.6, 0.6, 1.0);
        assert_eq!(tri(o, -Vec3::Z, v0, v1, v2, 0.0, INF).x, T_MISS);
        let o = Vec3::new(0.2, 0.2, 1.0);
        assert_eq!(tri(o, -Vec3::Z, v0, v1, v2, 1.0, INF).x, T_MISS);
        assert_eq!(tri(o, -Vec3::Z, v0, v1, v2, 0.0, 1.0).x, T_MISS);
        let o = Vec3::new(-1.0, 0.2, 0.0);
        assert_eq!(tri(o, Vec3::X, v0, v1, v2, 0.0, INF).x, T_MISS);
    }

    #[test]
    fn triangle_scale_invariance_of_the_determinant_guard() {
        // A triangle of size 1e-6 seen from 1e-6 away: det ~ 1e-12, still a hit.
        let s = 1e-6;
        let r = tri(
            Vec3::new(0.25 * s, 0.25 * s, s),
            -Vec3::Z,
            Vec3::ZERO,
            Vec3::X * s,
            Vec3::Y * s,
            0.0,
            INF,
        );
        assert!((r.x - s).abs() <= s * 1e-6, "{r}");
    }

    #[test]
    fn sphere_near_far_inside_tangent() {
        let c = Vec3::new(0.0, 0.0, -5.0);
        // From outside: the near root.
        assert_eq!(
            intersect_sphere(Vec3::ZERO, -Vec3::Z, c, 1.0, 0.0, INF),
            4.0
        );
        // Non-normalised direction: t in units of dir.
        assert_eq!(
            intersect_sphere(Vec3::ZERO, -Vec3::Z * 2.0, c, 1.0, 0.0, INF),
            2.0
        );
        // From the centre (inside): the far side.
        assert_eq!(intersect_sphere(c, Vec3::X, c, 1.0, 0.0, INF), 1.0);
        // From the surface going in, t_min past the root at the origin: the far side.
        let on = Vec3::new(0.0, 0.0, -4.0);
        let t = intersect_sphere(on, -Vec3::Z, c, 1.0, 1e-4, INF);
        assert_eq!(t, 2.0);
        // From the surface going out: nothing.
        assert_eq!(intersect_sphere(on, Vec3::Z, c, 1.0, 1e-4, INF), T_MISS);
        // Behind, beside, beyond t_max.
        assert_eq!(
            intersect_sphere(Vec3::ZERO, Vec3::Z, c, 1.0, 0.0, INF),
            T_MISS
        );
        assert_eq!(
            intersect_sphere(Vec3::new(2.0, 0.0, 0.0), -Vec3::Z, c, 1.0, 0.0, INF),
            T_MISS
        );
        assert_eq!(
            intersect_sphere(Vec3::ZERO, -Vec3::Z, c, 1.0, 0.0, 3.0),
            T_MISS
        );
    }

    #[test]
    fn sphere_small_and_far_does_not_cancel() {
        // r = 1e-3 at distance 1e4: the textbook b^2 - ac loses every digit here (b^2 ~ 1e8,
        // the difference ~ 1e-6 * a).
        let c = Vec3::new(0.0, 0.0, -1e4);
        let o = Vec3::new(0.0, 0.5e-3, 0.0);
        let t = intersect_sphere(o, -Vec3::Z, c, 1e-3, 0.0, INF);
        let exact = 1e4 - (1e-6f64 - 0.25e-6).sqrt();
        assert!(
            (f64::from(t) - exact).abs() <= exact * 1e-6,
            "{t} vs {exact}"
        );
    }

    /// Every lane of `intersect_triangles4` is `intersect_triangle` of its triangle bit for
    /// bit (t, u, v; misses as misses), over rays and triangles on a coarse grid (so that rays
    /// run exactly through edges and vertices, triangles come out degenerate or edge-on, and
    /// distances tie) and with `t_min`/`t_max` cutting through the hits.
    #[test]
    fn four_triangles_at_once_are_the_single_test_bit_for_bit() {
        let mut state = 0x9e37_79b9_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        // Coordinates in {-2, -1.5, ..., 2}: exact, often shared.
        let coord = |x: u32| (x % 9) as f32 * 0.5 - 2.0;
        let mut lanes = 0usize;
        let mut hits = 0usize;
        for _ in 0..20_000 {
            let tris: Vec<Primitive> = (0..4)
                .map(|_| {
                    Primitive::triangle(
                        [
                            [coord(next()), coord(next()), coord(next())],
                            [coord(next()), coord(next()), coord(next())],
                            [coord(next()), coord(next()), coord(next())],
                        ],
                        0,
                    )
                })
                .collect();
            let o = Vec3::new(coord(next()), coord(next()), coord(next())) * 2.0;
            // Mostly aimed at a vertex, an edge's midpoint or the centroid of one of the
            // triangles (exact edge and vertex hits), else anywhere.
            let aim = next() % 5;
            let p = &tris[(next() % 4) as usize];
            let (a, b, c) = (
                Vec3::from_slice(&p.a[..3]),
                Vec3::from_slice(&p.b[..3]),
                Vec3::from_slice(&p.c[..3]),
            );
            let d = match aim {
                0 => a - o,
                1 => (a + b) * 0.5 - o,
                2 => (a + b + c) / 3.0 - o,
                3 => (b + c) * 0.5 - o,
                _ => Vec3::new(coord(next()), coord(next()), coord(next())),
            };
            if d == Vec3::ZERO {
                continue;
            }
            let r = shear_ray(&Ray::new(o, d));
            let t_min = [0.0, 0.5, 1.0][lanes % 3];
            let t_max = [T_MISS, 2.0, 3.5][(lanes / 3) % 3];
            let [t, u, v] =
                intersect_triangles4(&r, [&tris[0], &tris[1], &tris[2], &tris[3]], t_min, t_max);
            // The same four read from a block (the CPU walk's form), and the last three
            // shifted down a lane (a zero lane after them, as past a node's last triangle:
            // a miss).
            let block = |tris: &[Primitive]| {
                let mut b = TriangleBlock::default();
                for (j, p) in tris.iter().enumerate() {
                    b.set_lane(j, p);
                }
                b
            };
            let bits = |l: [Vec4; 3]| l.map(|x| x.to_array().map(f32::to_bits));
            assert_eq!(
                bits(intersect_triangle_block(&r, &block(&tris), t_min, t_max)),
                bits([t, u, v])
            );
            let [t1, u1, v1] = intersect_triangle_block(&r, &block(&tris[1..]), t_min, t_max);
            for j in 0..3 {
                let got = [t1[j], u1[j], v1[j]].map(f32::to_bits);
                assert_eq!(got, [t[j + 1], u[j + 1], v[j + 1]].map(f32::to_bits));
            }
            assert_eq!((t1[3], u1[3], v1[3]), (T_MISS, 0.0, 0.0));
            for (j, p) in tris.iter().enumerate() {
                let (a, b, c) = (
                    Vec3::from_slice(&p.a[..3]),
                    Vec3::from_slice(&p.b[..3]),
                    Vec3::from_slice(&p.c[..3]),
                );
                let want = intersect_triangle(&r, a, b, c, t_min, t_max);
                let got = Vec3::new(t[j], u[j], v[j]);
                assert_eq!(
                    got.to_array().map(f32::to_bits),
                    want.to_array().map(f32::to_bits),
                    "lane {j}: ray {o} {d}, triangle {p:?}, t in ({t_min}, {t_max})"
                );
                lanes += 1;
                hits += usize::from(want.x != T_MISS);
            }
        }
        // The cases must include hits, misses and both kinds in one call.
        assert!(
            hits > lanes / 20 && hits < lanes / 2,
            "{hits} hits of {lanes}"
        );
    }
}
