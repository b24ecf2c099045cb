// raylume-bvh: the linear BVH of lbvh.rs (same names, same arithmetic), for the GPU build
// (raylume-kernels' gpu/lbvh.wgsl). Declares no bindings: the including shader declares, at
// module scope, `lbvh_params: LbvhParams` (a uniform) and `lbvh_codes: array<vec2<u32>>`
// (the sorted Morton codes, low word first).

// 32 bytes, lbvh.rs `LbvhParams`.
struct LbvhParams {
    centre_min: vec3<f32>,
    count: u32,
    scale: vec3<f32>,
    pass_index: u32,
}

// lbvh.rs `LbvhInner`: the children (a leaf's index is its sorted position) and the range.
struct LbvhInner {
    left: u32,
    right: u32,
    left_leaf: bool,
    right_leaf: bool,
}

// bounds.rs `primitive_aabb` of a triangle: its vertices' exact bounds.
fn lbvh_box_min(p: Primitive) -> vec3<f32> {
    return min(min(p.a.xyz, p.b.xyz), p.c.xyz);
}

fn lbvh_box_max(p: Primitive) -> vec3<f32> {
    return max(max(p.a.xyz, p.b.xyz), p.c.xyz);
}

// The LBVH_AXIS_BITS low bits of q to every third bit from bit `axis`, as two words.
fn lbvh_spread(q: u32, axis: u32) -> vec2<u32> {
    var out = vec2<u32>(0u, 0u);
    for (var b = 0u; b < LBVH_AXIS_BITS; b++) {
        let bit = (q >> b) & 1u;
        let at = 3u * b + axis;
        if (at < 32u) {
            out.x |= bit << at;
        } else {
            out.y |= bit << (at - 32u);
        }
    }
    return out;
}

// lbvh.rs `morton_code`: the 63-bit code of a box centre, low word first.
fn morton_code(centre: vec3<f32>) -> vec2<u32> {
    let q = max((centre - lbvh_params.centre_min) * lbvh_params.scale, vec3<f32>(0.0));
    let cell = vec3<u32>(q);
    return lbvh_spread(cell.x, 0u) | lbvh_spread(cell.y, 1u) | lbvh_spread(cell.z, 2u);
}

// Leading zeros of a 64-bit word given low word first.
fn lbvh_clz64(x: vec2<u32>) -> i32 {
    if (x.y != 0u) {
        return i32(countLeadingZeros(x.y));
    }
    return 32 + i32(countLeadingZeros(x.x));
}

// lbvh.rs `lbvh_delta`: the common prefix of keys i and j, -1 outside the leaves.
fn lbvh_delta(i: i32, j: i32) -> i32 {
    if (j < 0 || j >= i32(lbvh_params.count)) {
        return -1;
    }
    let a = lbvh_codes[i];
    let b = lbvh_codes[j];
    if (all(a == b)) {
        return 64 + lbvh_clz64(vec2<u32>(u32(i) ^ u32(j), 0u));
    }
    return lbvh_clz64(a ^ b);
}

// lbvh.rs `lbvh_node`: inner node i's children (Karras' Figure 4).
fn lbvh_node(i: i32) -> LbvhInner {
    var d = -1;
    if (lbvh_delta(i, i + 1) > lbvh_delta(i, i - 1)) {
        d = 1;
    }
    let d_min = lbvh_delta(i, i - d);
    var l_max = 2;
    while (lbvh_delta(i, i + l_max * d) > d_min) {
        l_max *= 2;
    }
    var l = 0;
    var t = l_max / 2;
    while (t >= 1) {
        if (lbvh_delta(i, i + (l + t) * d) > d_min) {
            l += t;
        }
        t /= 2;
    }
    let j = i + l * d;
    let d_node = lbvh_delta(i, j);
    var s = 0;
    t = l;
    loop {
        t = (t + 1) / 2;
        if (lbvh_delta(i, i + (s + t) * d) > d_node) {
            s += t;
        }
        if (t <= 1) {
            break;
        }
    }
    let gamma = i + s * d + min(d, 0);
    let first = min(i, j);
    let last = max(i, j);
    return LbvhInner(u32(gamma), u32(gamma + 1), first == gamma, last == gamma + 1);
}
