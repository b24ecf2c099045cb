// raylume-bvh: ray/box, ray/triangle and ray/sphere tests, the WGSL mirror of intersect.rs
// (same names, constants and operation order). Part of TRAVERSE_WGSL.

// f32::MAX: what the intersect_* functions return for "no hit".
const T_MISS: f32 = 0x1.fffffep+127f;
// 1 + 2^-20: conservative slab test under rounding (Ize 2013; see intersect.rs).
const AABB_T_FAR_SCALE: f32 = 0x1.00001p+0f;

// origin + t * dir. A value type, not a buffer layout.
struct Ray {
    origin: vec3<f32>,
    dir: vec3<f32>,
}

fn bvh_dot(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// Slab test: entry distance (>= t_min) if [t_min, t_max] overlaps the box, else T_MISS.
// select(b, a, a > b) is max(a, b) returning b when a is NaN (NaN compares false); a NaN
// arises only as 0 * inf (zero direction component, origin on the slab plane), and dropping
// it makes the closed slab contain the ray. Explicit compares rather than min/max, whose NaN
// behaviour SPIR-V leaves undefined.
fn intersect_aabb(bmin: vec3<f32>, bmax: vec3<f32>, origin: vec3<f32>, inv_dir: vec3<f32>,
                  t_min: f32, t_max: f32) -> f32 {
    let t0 = (bmin - origin) * inv_dir;
    let t1 = (bmax - origin) * inv_dir;
    let lo = vec3<f32>(t_min);
    let hi = vec3<f32>(t_max);
    let near = min(select(lo, t0, t0 > lo), select(lo, t1, t1 > lo));
    let far = max(select(hi, t0, t0 < hi), select(hi, t1, t1 < hi));
    let t_near = max(near.x, max(near.y, near.z));
    let t_far = min(far.x, min(far.y, far.z));
    return select(T_MISS, t_near, t_near <= t_far * AABB_T_FAR_SCALE);
}

// A ray prepared for intersect_triangle (Woop, Benthin & Wald 2013): kz = axis of the
// direction's largest component, kx, ky the next two; shear = (dir[kx] / dir[kz],
// dir[ky] / dir[kz], 1 / dir[kz]). A value type, not a buffer layout.
struct ShearedRay {
    origin: vec3<f32>,
    dir: vec3<f32>,
    shear: vec3<f32>,
    kx: u32,
    ky: u32,
    kz: u32,
}

fn shear_ray(ray: Ray) -> ShearedRay {
    let d = ray.dir;
    let ad = abs(d);
    let kz = select(select(2u, 1u, ad.y >= ad.z), 0u, ad.x >= ad.y && ad.x >= ad.z);
    let kx = (kz + 1u) % 3u;
    let ky = (kx + 1u) % 3u;
    let sz = 1.0 / d[kz];
    return ShearedRay(ray.origin, d, vec3<f32>(d[kx] * sz, d[ky] * sz, sz), kx, ky, kz);
}

// Watertight, edge-inclusive ray/triangle test: (t, u, v) for t_min < t < t_max, else
// (T_MISS, 0, 0). 2D edge functions in ray space, exactly antisymmetric between neighbours
// (without FMA contraction); t is the barycentric mean of the vertices' depths. Only
// det == 0 is rejected. See intersect.rs.
//
// `a[kx]` is read as axis_pick(a, kx): two selects, no arithmetic, so the value is a[kx] bit
// for bit whatever the compiler fuses. Dynamic vector indexing cost ~14% of the Cornell box's
// render time on the H100 (docs/RESULTS.md).
fn intersect_triangle(r: ShearedRay, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>,
                      t_min: f32, t_max: f32) -> vec3<f32> {
    let miss = vec3<f32>(T_MISS, 0.0, 0.0);
    let a = v0 - r.origin;
    let b = v1 - r.origin;
    let c = v2 - r.origin;
    let a_z = axis_pick(a, r.kz);
    let b_z = axis_pick(b, r.kz);
    let c_z = axis_pick(c, r.kz);
    let ax = axis_pick(a, r.kx) - r.shear.x * a_z;
    let ay = axis_pick(a, r.ky) - r.shear.y * a_z;
    let bx = axis_pick(b, r.kx) - r.shear.x * b_z;
    let by = axis_pick(b, r.ky) - r.shear.y * b_z;
    let cx = axis_pick(c, r.kx) - r.shear.x * c_z;
    let cy = axis_pick(c, r.ky) - r.shear.y * c_z;
    let w0 = cx * by - cy * bx;
    let w1 = ax * cy - ay * cx;
    let w2 = bx * ay - by * ax;
    let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
    let det = w0 + w1 + w2;
    if !inside || det == 0.0 {
        return miss;
    }
    let az = r.shear.z * a_z;
    let bz = r.shear.z * b_z;
    let cz = r.shear.z * c_z;
    let inv_det = 1.0 / det;
    let t = (w0 * az + w1 * bz + w2 * cz) * inv_det;
    if t > t_min && t < t_max {
        return vec3<f32>(t, w1 * inv_det, w2 * inv_det);
    }
    return miss;
}

// v[k] for an axis k (0, 1, 2), by selects (Rust: `v[k]`).
fn axis_pick(v: vec3<f32>, k: u32) -> f32 {
    return select(select(v.z, v.y, k == 1u), v.x, k == 0u);
}

// Smallest root t_min < t < t_max, else T_MISS; from inside, the far side. Roots tc ± s
// computed without cancellation or underflow (see intersect.rs).
fn intersect_sphere(origin: vec3<f32>, dir: vec3<f32>, center: vec3<f32>, radius: f32,
                    t_min: f32, t_max: f32) -> f32 {
    let oc = center - origin;
    let inv_a = 1.0 / bvh_dot(dir, dir);
    let tc = bvh_dot(oc, dir) * inv_a;
    let r2 = radius * radius;
    let l = oc - dir * tc;
    let h = (r2 - bvh_dot(l, l)) * inv_a;
    if h < 0.0 {
        return T_MISS;
    }
    let s = sqrt(h);
    let q = select(tc - s, tc + s, tc >= 0.0);
    if q == 0.0 {
        return T_MISS;
    }
    let ta = (bvh_dot(oc, oc) - r2) * inv_a / q;
    let t_lo = min(ta, q);
    let t_hi = max(ta, q);
    let t = select(t_hi, t_lo, t_lo > t_min);
    return select(T_MISS, t, t > t_min && t < t_max);
}

// One primitive of either kind: (t, u, v) as intersect_triangle returns it. The tracer's
// source composed for a scene without spheres (raylume-kernels' `compose`) has no sphere
// test here.
fn intersect_primitive(p: Primitive, r: ShearedRay, t_min: f32, t_max: f32) -> vec3<f32> {
    //#if spheres
    if bitcast<u32>(p.b.w) == PRIM_SPHERE {
        return vec3<f32>(intersect_sphere(r.origin, r.dir, p.a.xyz, p.a.w, t_min, t_max), 0.0, 0.0);
    }
    //#endif
    return intersect_triangle(r, p.a.xyz, p.b.xyz, p.c.xyz, t_min, t_max);
}
