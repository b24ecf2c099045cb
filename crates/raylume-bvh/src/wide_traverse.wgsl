// raylume-bvh: traversal of the compressed eight-wide layout (Ylitie, Karras & Laine 2017),
// the WGSL mirror of wide_traverse.rs (same names, constants and operation order). The last
// part of WIDE_TRAVERSE_WGSL, after gpu_types.wgsl, intersect.wgsl and hit.wgsl.
//
// Contract: as traverse.wgsl's, with `bvh_nodes: array<TraversalNode>` holding
// GpuBvh::wide_nodes. Node 0 is the root. Rays must have a non-zero direction; t_min must be
// below T_MISS.

alias TraversalNode = WideNode;

// Child boxes are widened by this many grid cells on every side: it covers the builder's
// rounding of the quantised planes and the rounding of the box test below (wide_traverse.rs
// derives both bounds).
const WIDE_QUANT_PAD: f32 = 0.015625;
// 1 + 2^-18: the wide box test's conservative far distance (wide_traverse.rs).
const WIDE_T_FAR_SCALE: f32 = 0x1.00004p+0f;
// |1 / dir| is clamped to 2^80, so that the box test's products stay finite for zero
// direction components (wide_traverse.rs says why this loses no hit).
const WIDE_INV_DIR_LIMIT: f32 = 0x1p+80f;
// XORed into an any-hit walk's oct_inv4: its children entered farthest octant first
// (WIDE_ANY_OCT_FLIP in Rust, whose docs say why).
const WIDE_ANY_OCT_FLIP: u32 = 0x07070707u;

// A ray prepared for intersect_wide_node. A value type, not a buffer layout.
struct WideRay {
    origin: vec3<f32>,
    inv_dir: vec3<f32>,
    // The ray's octant, inverted, in every byte: bit 2 x, bit 1 y, bit 0 z, set for a
    // non-negative component (obvhs' ray_get_octant_inv4).
    oct_inv4: u32,
}

fn wide_ray(ray: Ray) -> WideRay {
    let inv = clamp(1.0 / ray.dir, vec3<f32>(-WIDE_INV_DIR_LIMIT), vec3<f32>(WIDE_INV_DIR_LIMIT));
    let oct = select(0x04040404u, 0u, ray.dir.x < 0.0)
        | select(0x02020202u, 0u, ray.dir.y < 0.0)
        | select(0x01010101u, 0u, ray.dir.z < 0.0);
    return WideRay(ray.origin, inv, oct);
}

// Four child slots' boxes against the ray: bit j set when slot j's (padded) box overlaps
// [t_min, t_max]. near_*/far_*: four slots' near and far planes (one byte each) per axis.
fn wide_overlap4(near_x: u32, far_x: u32, near_y: u32, far_y: u32, near_z: u32, far_z: u32,
                 a: vec3<f32>, b_near: vec3<f32>, b_far: vec3<f32>, t_min: f32,
                 t_max: f32) -> vec4<bool> {
    let tnx = vec4<f32>(unpack4xU8(near_x)) * a.x + b_near.x;
    let tny = vec4<f32>(unpack4xU8(near_y)) * a.y + b_near.y;
    let tnz = vec4<f32>(unpack4xU8(near_z)) * a.z + b_near.z;
    let tfx = vec4<f32>(unpack4xU8(far_x)) * a.x + b_far.x;
    let tfy = vec4<f32>(unpack4xU8(far_y)) * a.y + b_far.y;
    let tfz = vec4<f32>(unpack4xU8(far_z)) * a.z + b_far.z;
    let t_near = max(max(tnx, tny), max(tnz, vec4<f32>(t_min)));
    let t_far = min(min(tfx, tfy), min(tfz, vec4<f32>(t_max)));
    return t_near <= t_far * WIDE_T_FAR_SCALE;
}

// The hit mask of a node (obvhs' CwBvhNode::intersect_ray): bits 24..32 the hit inner
// children, each at bit 24 + (slot ^ octant) so that the highest bit is the child to visit
// first; bits 0..24 the primitives (offsets from prim_base) of the hit leaves.
fn intersect_wide_node(node: WideNode, r: WideRay, t_min: f32, t_max: f32) -> u32 {
    let e = node.e_imask;
    let cell = vec3<f32>(bitcast<f32>((e & 0xffu) << 23u), bitcast<f32>(((e >> 8u) & 0xffu) << 23u),
                         bitcast<f32>(((e >> 16u) & 0xffu) << 23u));
    // t of the plane at cell q is q * a + b.
    let a = cell * r.inv_dir;
    let b = (node.p - r.origin) * r.inv_dir;
    let pad = WIDE_QUANT_PAD * abs(a);
    let b_near = b - pad;
    let b_far = b + pad;
    // A negative direction meets the upper plane first.
    let neg = r.inv_dir < vec3<f32>(0.0);
    let near_x = select(node.q_x.xy, node.q_x.zw, neg.x);
    let far_x = select(node.q_x.zw, node.q_x.xy, neg.x);
    let near_y = select(node.q_y.xy, node.q_y.zw, neg.y);
    let far_y = select(node.q_y.zw, node.q_y.xy, neg.y);
    let near_z = select(node.q_z.xy, node.q_z.zw, neg.z);
    let far_z = select(node.q_z.zw, node.q_z.xy, neg.z);
    let lo = wide_overlap4(near_x.x, far_x.x, near_y.x, far_y.x, near_z.x, far_z.x, a, b_near, b_far,
                           t_min, t_max);
    let hi = wide_overlap4(near_x.y, far_x.y, near_y.y, far_y.y, near_z.y, far_z.y, a, b_near, b_far,
                           t_min, t_max);
    // Per slot: the bits to set (1 for an inner child, the unary primitive count for a leaf)
    // and where (24 + slot ^ octant for an inner child, the primitive offset for a leaf).
    let m = node.child_meta;
    let inner = (m & (m << vec2<u32>(1u))) & vec2<u32>(0x10101010u);
    let inner_bytes = (inner >> vec2<u32>(4u)) * 0xffu;
    let bit_index = (m ^ (vec2<u32>(r.oct_inv4) & inner_bytes)) & vec2<u32>(0x1f1f1f1fu);
    let child_bits = (m >> vec2<u32>(5u)) & vec2<u32>(0x07070707u);
    let bits_lo = select(vec4<u32>(0u), unpack4xU8(child_bits.x) << unpack4xU8(bit_index.x), lo);
    let bits_hi = select(vec4<u32>(0u), unpack4xU8(child_bits.y) << unpack4xU8(bit_index.y), hi);
    let bits = bits_lo | bits_hi;
    return bits.x | bits.y | bits.z | bits.w;
}

// The index of the inner child that `bit` (24..32) of a node group stands for: the group
// (x: the node's child_base, y: its hit mask's inner bits | its imask) counts the inner
// slots before that slot.
fn wide_child_index(group: vec2<u32>, bit: u32, oct_inv4: u32) -> u32 {
    let slot = (bit - 24u) ^ (oct_inv4 & 0xffu);
    return group.x + countOneBits(group.y & ~(0xffffffffu << slot));
}

// The walk both queries share (Ylitie et al.'s traversal without triangle postponing): a
// node group (x: first child node, y: bits 24..32 the children still to visit | imask) is
// entered child by child, the highest bit first, the rest of the group pushed; the
// primitives of a node's hit leaves are tested when the node is. The closest hit with
// t_min < t < t_max, or with any_hit the first one found; a miss has prim == INVALID_INDEX
// and t == min(t_max, T_MAX_LIMIT). Callers pass any_hit as a constant.
fn wide_walk(ray: Ray, t_min: f32, t_max: f32, any_hit: bool) -> Hit {
    var wr = wide_ray(ray);
    if any_hit {
        wr.oct_inv4 ^= WIDE_ANY_OCT_FLIP;
    }
    let sheared = shear_ray(ray);
    var hit = Hit(min(t_max, T_MAX_LIMIT), INVALID_INDEX, 0.0, 0.0);
    var stack: array<vec2<u32>, WIDE_STACK_SIZE>;
    var sp = 0u;
    // The root as the only child of a group.
    var group = vec2<u32>(0u, 0x80000000u);
    loop {
        if (group.y & 0xff000000u) != 0u {
            let bit = firstLeadingBit(group.y);
            let index = wide_child_index(group, bit, wr.oct_inv4);
            group.y &= ~(1u << bit);
            if (group.y & 0xff000000u) != 0u {
                stack[sp] = group;
                sp += 1u;
            }
            let node = bvh_nodes[index];
            let mask = intersect_wide_node(node, wr, t_min, hit.t);
            group = vec2<u32>(node.child_base, (mask & 0xff000000u) | (node.e_imask >> 24u));
            var prims = mask & 0x00ffffffu;
            while prims != 0u {
                let k = firstLeadingBit(prims);
                prims &= ~(1u << k);
                let i = node.prim_base + k;
                let r = intersect_primitive(bvh_primitives[i], sheared, t_min, hit.t);
                if r.x < hit.t {
                    hit = Hit(r.x, i, r.y, r.z);
                    if any_hit {
                        return hit;
                    }
                }
            }
        }
        if (group.y & 0xff000000u) == 0u {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            group = stack[sp];
        }
    }
    return hit;
}

// Closest hit with t_min < t < t_max; a miss has prim == INVALID_INDEX and
// t == min(t_max, T_MAX_LIMIT).
fn trace_closest(ray: Ray, t_min: f32, t_max: f32) -> Hit {
    return wide_walk(ray, t_min, t_max, false);
}

// True if anything is hit with t_min < t < t_max (returns at the first hit).
fn trace_any(ray: Ray, t_min: f32, t_max: f32) -> bool {
    return wide_walk(ray, t_min, t_max, true).prim != INVALID_INDEX;
}

// The walk with the query's kind a value: shade.wgsl's trace_ray traces a path's ray and its
// shadow ray through one call.
fn trace_query(ray: Ray, t_min: f32, t_max: f32, any_hit: bool) -> Hit {
    return wide_walk(ray, t_min, t_max, any_hit);
}
