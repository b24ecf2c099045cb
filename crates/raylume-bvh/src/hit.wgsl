// raylume-bvh: what both traversals return (traverse.rs `Hit`, `T_MAX_LIMIT`); part of
// TRAVERSE_WGSL and WIDE_TRAVERSE_WGSL.

// 2^127: traversal clamps t_max to this so that t_max * AABB_T_FAR_SCALE stays below T_MISS.
const T_MAX_LIMIT: f32 = 0x1p+127f;

// 16 bytes. prim indexes bvh_primitives; u, v: barycentrics of v1, v2 (0 for spheres).
// A miss has prim == INVALID_INDEX.
struct Hit {
    t: f32,
    prim: u32,
    u: f32,
    v: f32,
}
