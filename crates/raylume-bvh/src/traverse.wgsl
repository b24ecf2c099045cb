// raylume-bvh: BVH traversal, the WGSL mirror of traverse.rs (same names, constants,
// struct layouts and operation order). Include it by concatenation (`TRAVERSE_WGSL`).
//
// Contract: this file declares no bindings. The including shader declares, at module scope
// and with bindings of its choosing,
//     var<storage, read> bvh_nodes: array<BvhNode>;         // GpuBvh::nodes
//     var<storage, read> bvh_primitives: array<Primitive>;  // GpuBvh::primitives
// and must not define the names below. Node 0 is the root. Rays must have a non-zero
// direction; t_min must be below T_MISS.

const INVALID_INDEX: u32 = 0xffffffffu;
const MAX_STACK_DEPTH: u32 = 64u;
const PRIM_TRIANGLE: u32 = 0u;
const PRIM_SPHERE: u32 = 1u;
// f32::MAX: what the intersect_* functions return for "no hit".
const T_MISS: f32 = 0x1.fffffep+127f;
// 2^127: traversal clamps t_max to this so that t_max * AABB_T_FAR_SCALE stays below T_MISS.
const T_MAX_LIMIT: f32 = 0x1p+127f;
// 1 + 2^-20: conservative slab test under rounding (Ize 2013; see traverse.rs).
const AABB_T_FAR_SCALE: f32 = 0x1.00001p+0f;

// 64 bytes: both children's boxes; per child count == 0 && index != INVALID_INDEX: inner
// node bvh_nodes[index]; count > 0: leaf bvh_primitives[index .. index + count];
// index == INVALID_INDEX: empty (only in the root).
struct BvhNode {
    left_min: vec3<f32>,
    left_index: u32,
    left_max: vec3<f32>,
    left_count: u32,
    right_min: vec3<f32>,
    right_index: u32,
    right_max: vec3<f32>,
    right_count: u32,
}

// 48 bytes. Triangle: vertices a.xyz, b.xyz, c.xyz. Sphere: centre a.xyz, radius a.w.
// b.w: kind (PRIM_TRIANGLE / PRIM_SPHERE) and c.w: scene index, both as u32 bits.
struct Primitive {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

// 16 bytes. prim indexes bvh_primitives; u, v: barycentrics of v1, v2 (0 for spheres).
// A miss has prim == INVALID_INDEX.
struct Hit {
    t: f32,
    prim: u32,
    u: f32,
    v: f32,
}

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
// det == 0 is rejected. See traverse.rs.
fn intersect_triangle(r: ShearedRay, v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>,
                      t_min: f32, t_max: f32) -> vec3<f32> {
    let miss = vec3<f32>(T_MISS, 0.0, 0.0);
    let a = v0 - r.origin;
    let b = v1 - r.origin;
    let c = v2 - r.origin;
    let ax = a[r.kx] - r.shear.x * a[r.kz];
    let ay = a[r.ky] - r.shear.y * a[r.kz];
    let bx = b[r.kx] - r.shear.x * b[r.kz];
    let by = b[r.ky] - r.shear.y * b[r.kz];
    let cx = c[r.kx] - r.shear.x * c[r.kz];
    let cy = c[r.ky] - r.shear.y * c[r.kz];
    let w0 = cx * by - cy * bx;
    let w1 = ax * cy - ay * cx;
    let w2 = bx * ay - by * ax;
    let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
    let det = w0 + w1 + w2;
    if !inside || det == 0.0 {
        return miss;
    }
    let az = r.shear.z * a[r.kz];
    let bz = r.shear.z * b[r.kz];
    let cz = r.shear.z * c[r.kz];
    let inv_det = 1.0 / det;
    let t = (w0 * az + w1 * bz + w2 * cz) * inv_det;
    if t > t_min && t < t_max {
        return vec3<f32>(t, w1 * inv_det, w2 * inv_det);
    }
    return miss;
}

// Smallest root t_min < t < t_max, else T_MISS; from inside, the far side. Roots tc ± s
// computed without cancellation or underflow (see traverse.rs).
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

fn intersect_primitive(p: Primitive, r: ShearedRay, t_min: f32, t_max: f32) -> vec3<f32> {
    if bitcast<u32>(p.b.w) == PRIM_SPHERE {
        return vec3<f32>(intersect_sphere(r.origin, r.dir, p.a.xyz, p.a.w, t_min, t_max), 0.0, 0.0);
    }
    return intersect_triangle(r, p.a.xyz, p.b.xyz, p.c.xyz, t_min, t_max);
}

fn intersect_leaf_closest(ray: ShearedRay, first: u32, count: u32, t_min: f32,
                          hit: ptr<function, Hit>) {
    for (var i = first; i < first + count; i += 1u) {
        let r = intersect_primitive(bvh_primitives[i], ray, t_min, (*hit).t);
        if r.x < (*hit).t {
            *hit = Hit(r.x, i, r.y, r.z);
        }
    }
}

fn intersect_leaf_any(ray: ShearedRay, first: u32, count: u32, t_min: f32, t_max: f32) -> bool {
    for (var i = first; i < first + count; i += 1u) {
        let r = intersect_primitive(bvh_primitives[i], ray, t_min, t_max);
        if r.x < t_max {
            return true;
        }
    }
    return false;
}

// Closest hit with t_min < t < t_max; a miss has prim == INVALID_INDEX and
// t == min(t_max, T_MAX_LIMIT).
fn trace_closest(ray: Ray, t_min: f32, t_max: f32) -> Hit {
    let inv_dir = 1.0 / ray.dir;
    let sheared = shear_ray(ray);
    var hit = Hit(min(t_max, T_MAX_LIMIT), INVALID_INDEX, 0.0, 0.0);
    var stack: array<u32, MAX_STACK_DEPTH>;
    var sp = 0u;
    var node_index = 0u;
    loop {
        let node = bvh_nodes[node_index];
        var t_left = intersect_aabb(node.left_min, node.left_max, ray.origin, inv_dir, t_min, hit.t);
        var t_right = intersect_aabb(node.right_min, node.right_max, ray.origin, inv_dir, t_min, hit.t);
        t_left = select(t_left, T_MISS, node.left_index == INVALID_INDEX);
        t_right = select(t_right, T_MISS, node.right_index == INVALID_INDEX);
        let swap = t_right < t_left;
        let t_near = select(t_left, t_right, swap);
        let near_index = select(node.left_index, node.right_index, swap);
        let near_count = select(node.left_count, node.right_count, swap);
        let t_far = select(t_right, t_left, swap);
        let far_index = select(node.right_index, node.left_index, swap);
        let far_count = select(node.right_count, node.left_count, swap);
        if near_count > 0u && t_near <= hit.t * AABB_T_FAR_SCALE {
            intersect_leaf_closest(sheared, near_index, near_count, t_min, &hit);
        }
        if far_count > 0u && t_far <= hit.t * AABB_T_FAR_SCALE {
            intersect_leaf_closest(sheared, far_index, far_count, t_min, &hit);
        }
        let go_near = near_count == 0u && t_near <= hit.t * AABB_T_FAR_SCALE;
        let go_far = far_count == 0u && t_far <= hit.t * AABB_T_FAR_SCALE;
        if go_near {
            if go_far {
                stack[sp] = far_index;
                sp += 1u;
            }
            node_index = near_index;
        } else if go_far {
            node_index = far_index;
        } else if sp > 0u {
            sp -= 1u;
            node_index = stack[sp];
        } else {
            break;
        }
    }
    return hit;
}

// True if anything is hit with t_min < t < t_max (returns at the first hit).
fn trace_any(ray: Ray, t_min: f32, t_max_in: f32) -> bool {
    let inv_dir = 1.0 / ray.dir;
    let sheared = shear_ray(ray);
    let t_max = min(t_max_in, T_MAX_LIMIT);
    var stack: array<u32, MAX_STACK_DEPTH>;
    var sp = 0u;
    var node_index = 0u;
    loop {
        let node = bvh_nodes[node_index];
        var t_left = intersect_aabb(node.left_min, node.left_max, ray.origin, inv_dir, t_min, t_max);
        var t_right = intersect_aabb(node.right_min, node.right_max, ray.origin, inv_dir, t_min, t_max);
        t_left = select(t_left, T_MISS, node.left_index == INVALID_INDEX);
        t_right = select(t_right, T_MISS, node.right_index == INVALID_INDEX);
        let swap = t_right < t_left;
        let t_near = select(t_left, t_right, swap);
        let near_index = select(node.left_index, node.right_index, swap);
        let near_count = select(node.left_count, node.right_count, swap);
        let t_far = select(t_right, t_left, swap);
        let far_index = select(node.right_index, node.left_index, swap);
        let far_count = select(node.right_count, node.left_count, swap);
        if near_count > 0u && t_near < T_MISS {
            if intersect_leaf_any(sheared, near_index, near_count, t_min, t_max) {
                return true;
            }
        }
        if far_count > 0u && t_far < T_MISS {
            if intersect_leaf_any(sheared, far_index, far_count, t_min, t_max) {
                return true;
            }
        }
        let go_near = near_count == 0u && t_near < T_MISS;
        let go_far = far_count == 0u && t_far < T_MISS;
        if go_near {
            if go_far {
                stack[sp] = far_index;
                sp += 1u;
            }
            node_index = near_index;
        } else if go_far {
            node_index = far_index;
        } else if sp > 0u {
            sp -= 1u;
            node_index = stack[sp];
        } else {
            break;
        }
    }
    return false;
}
