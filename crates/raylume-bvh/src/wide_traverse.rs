//! CPU traversal of the compressed eight-wide layout ([`WideNode`]): the reference that
//! `wide_traverse.wgsl` mirrors function for function. The traversal is Ylitie, Karras &
//! Laine's (*Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs*, HPG
//! 2017) as obvhs writes it (`cwbvh::traverse_macro`), without triangle postponing: a stack of
//! node groups (a node's first child and the bits of its children still to visit), children
//! visited in an order fixed by the ray's octant, the primitives of a node's hit leaves
//! tested when the node is.
//!
//! # The box test, and why it never loses a hit
//!
//! A child's box is `p + q * cell` per axis, with `q` a byte and `cell` a power of two; the
//! ray meets the plane at cell `q` at `t = q * a + b`, with `a = cell / dir` and
//! `b = (p - origin) / dir`. Two things can make the computed box smaller than the true one:
//!
//! - The builder's rounding (obvhs floors and ceils `(child - p) / cell` after one rounded
//!   subtraction): a plane can sit up to `2^-16` cells inside the child's true box.
//! - The test's own arithmetic: `b`, `q * a` and their sum are each off by a few units in the
//!   last place of `|q * a| + |b|`, at most `~9 * 2^-24 * (|q * cell| + |p - origin|) / |dir|`.
//!
//! Every box is therefore widened by [`WIDE_QUANT_PAD`] cells (`2^-6`) per side, folded into
//! `b`. Where the origin is within `2^15` cells of the node's corner `p`, the pad alone covers
//! both errors (`9 * 2^-24 * (255 + 2^15) < 2^-6`). Farther out, `|t|` is within 1 % of
//! `|p - origin| / |dir|`, so each of the near and far distances is off by under
//! `10 * 2^-24` of itself, and comparing the near one with the far one times
//! [`WIDE_T_FAR_SCALE`] (`1 + 2^-18 > 1 + 20 * 2^-24`) covers that, as
//! [`AABB_T_FAR_SCALE`](crate::AABB_T_FAR_SCALE) does for the binary layout's exact boxes.
//!
//! A zero direction component would make `a` and `b` infinite and their sum `inf - inf`; `1 /
//! dir` is clamped to `±2^80` ([`WIDE_INV_DIR_LIMIT`]) instead. That tests a ray tilted by at
//! most `2^-80` per unit of `t` on that axis: it can leave a slab it should stay in only
//! where the true ray runs within `2^-80 t` of the slab's face, that is (for `t < 2^40`) an
//! origin on the face plane of a box whose cell is under `2^-34`: a box flat on that axis,
//! whose contents lie in the face plane, parallel to the ray, which the watertight triangle
//! test never hits (its determinant is 0).
//!
//! The box test only culls: which primitive is the closest hit (ties to the first found, in
//! an order fixed by the octant alone) does not depend on how the distances round, so the
//! CPU and the GPU find the same hits even where one fuses a multiply-add and the other not.
//!
//! # The CPU's node test
//!
//! On the CPU, [`GpuBvh`]'s traversal tests a node's children against float boxes made from
//! the quantised ones ([`WideBoxes`], [`intersect_wide_boxes`]) instead of decoding the bytes
//! at every visit ([`intersect_wide_node`], which the WGSL mirrors and [`wide_walk`] keeps
//! using): about half the instructions, and no branch on the ray's signs. Each float box
//! holds its padded quantised box, and its slab test carries the same `WIDE_T_FAR_SCALE`
//! margin, so it too culls only boxes that cannot hold a hit closer than the current one;
//! the walk, its order and its triangle tests are the same, so the hits are the same as the
//! quantised walk's and the GPU's (tested against both over every test tree). Living room,
//! diffuse rays, one core: 329-390 -> 260-330 ns a closest hit (`docs/RESULTS.md`, issue 15).
//! Its triangles, four at a time, come from each node's blocks ([`TriangleBlock`],
//! [`triangle_blocks`]: the node's leaves' triangles four a block, one load a coordinate from
//! one 144-byte place) instead of four records gathered and transposed (before 2026-12-04's
//! blocks, from nine columns of the primitive array: nine cache lines a test; the living
//! room's render 2-3 % faster with the blocks).
//! And its stack holds each child still to visit with the distance where the ray enters its
//! box, not node groups (`walk_boxes`): the same order, but a child whose box begins
//! beyond the closest hit found since is passed over without reading its node, and a child's
//! index comes from a table, not a popcount (living room, diffuse rays: 318-327 -> 287-296
//! ns a closest hit; camera rays 155 -> 131 ns; the dev machine, one core, 2026-12-04).

use std::mem::MaybeUninit;

use glam::{UVec2, UVec4, Vec3, Vec4};

use crate::intersect::{
    Ray, ShearedRay, T_MISS, TriangleBlock, intersect_primitive, intersect_triangle_block,
    intersect_triangles4, shear_ray, shear_ray_inv,
};
use crate::traverse::{Hit, T_MAX_LIMIT};
use crate::{GpuBvh, INVALID_INDEX, Primitive, WIDE_STACK_SIZE, WideNode};

/// Cells by which every child box is widened on each side (see the module docs). WGSL:
/// `WIDE_QUANT_PAD`.
pub const WIDE_QUANT_PAD: f32 = 1.0 / 64.0;

/// The wide box test accepts a child when `t_near <= t_far * WIDE_T_FAR_SCALE`
/// (`1 + 2^-18`; see the module docs). WGSL: `WIDE_T_FAR_SCALE`.
pub const WIDE_T_FAR_SCALE: f32 = 1.0 + 1.0 / 262_144.0;

/// XORed into an any-hit walk's [`WideRay::oct_inv4`]: a shadow ray enters a node's children
/// in the opposite order to a closest-hit walk's, the farthest octant first. Whether anything
/// lies on the ray does not depend on the order; how soon a walk finds a blocker does: the
/// living room's rays from its surfaces into random directions (`trace_rate`'s diffuse set,
/// 967,000 rays, mostly blocked) ran 29 % faster so on the CPU (14.1-14.7 -> 18.6-19.0 Mrays/s,
/// 2 threads; the other six flips of the octant fell between; the Cornell box's, rarely
/// blocked, within noise). WGSL: `WIDE_ANY_OCT_FLIP`.
pub const WIDE_ANY_OCT_FLIP: u32 = 0x0707_0707;

/// `|1 / dir|` is clamped to this (`2^80`; see the module docs). WGSL: `WIDE_INV_DIR_LIMIT`.
pub const WIDE_INV_DIR_LIMIT: f32 = f32::from_bits((127 + 80) << 23);

/// A ray prepared for [`intersect_wide_node`]. WGSL: `WideRay`.
#[derive(Clone, Copy, Debug)]
pub struct WideRay {
    pub origin: Vec3,
    /// `1 / dir`, clamped to `±WIDE_INV_DIR_LIMIT`.
    pub inv_dir: Vec3,
    /// The ray's octant, inverted, in every byte: bit 2 x, bit 1 y, bit 0 z, set for a
    /// non-negative component (obvhs' `ray_get_octant_inv4`).
    pub oct_inv4: u32,
}

/// [`wide_ray`] and [`shear_ray`] of `ray` (the same values bit for bit) from one
/// four-lane division for the three `1 / dir` both need: the CPU walk's setup (three
/// scalar divisions and a fourth for the shear, on x86-64 each several cycles of the divider,
/// twice a path segment).
#[inline(always)]
pub(crate) fn walk_rays(ray: &Ray) -> (WideRay, ShearedRay) {
    let inv = (Vec4::ONE / ray.dir.extend(1.0)).truncate();
    (wide_ray_inv(ray, inv), shear_ray_inv(ray, inv))
}

/// The four bytes of `w`, low first (WGSL's `unpack4xU8`).
#[inline(always)]
fn unpack4x_u8(w: u32) -> UVec4 {
    UVec4::new(w & 0xff, (w >> 8) & 0xff, (w >> 16) & 0xff, w >> 24)
}

/// `unpack4x_u8(w).as_vec4()`: on x86-64 by SSE2's byte unpacks and one four-lane
/// conversion (every byte converts exactly, so the values are the same).
#[inline(always)]
fn bytes_as_vec4(w: u32) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[allow(unused_unsafe)]
    // SAFETY: SSE2 is enabled (the cfg), and these intrinsics touch registers only.
    unsafe {
        use std::arch::x86_64::*;
        let z = _mm_setzero_si128();
        let v = _mm_cvtsi32_si128(w as i32);
        Vec4::from(_mm_cvtepi32_ps(_mm_unpacklo_epi16(
            _mm_unpacklo_epi8(v, z),
            z,
        )))
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    unpack4x_u8(w).as_vec4()
}

#[inline(always)]
fn word(bytes: &[u8], i: usize) -> u32 {
    // One four-byte load.
    u32::from_le_bytes(bytes[i..i + 4].try_into().expect("four bytes"))
}

#[inline(always)]
pub fn wide_ray(ray: &Ray) -> WideRay {
    wide_ray_inv(ray, Vec3::ONE / ray.dir)
}

/// [`wide_ray`] given `inv = 1 / ray.dir` (unclamped).
#[inline(always)]
fn wide_ray_inv(ray: &Ray, inv: Vec3) -> WideRay {
    let inv = inv.clamp(
        Vec3::splat(-WIDE_INV_DIR_LIMIT),
        Vec3::splat(WIDE_INV_DIR_LIMIT),
    );
    let oct = (if ray.dir.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if ray.dir.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if ray.dir.z < 0.0 { 0 } else { 0x0101_0101 });
    WideRay {
        origin: ray.origin,
        inv_dir: inv,
        oct_inv4: oct,
    }
}

/// Four child slots' boxes against the ray: lane `j` true when slot `j`'s padded box
/// overlaps `[t_min, t_max]`. `near_*`, `far_*`: the four slots' near and far planes (a
/// byte each) per axis.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn wide_overlap4(
    near_x: u32,
    far_x: u32,
    near_y: u32,
    far_y: u32,
    near_z: u32,
    far_z: u32,
    a: Vec3,
    b_near: Vec3,
    b_far: Vec3,
    t_min: f32,
    t_max: f32,
) -> [bool; 4] {
    let q = bytes_as_vec4;
    let tnx = q(near_x) * a.x + Vec4::splat(b_near.x);
    let tny = q(near_y) * a.y + Vec4::splat(b_near.y);
    let tnz = q(near_z) * a.z + Vec4::splat(b_near.z);
    let tfx = q(far_x) * a.x + Vec4::splat(b_far.x);
    let tfy = q(far_y) * a.y + Vec4::splat(b_far.y);
    let tfz = q(far_z) * a.z + Vec4::splat(b_far.z);
    let t_near = tnx.max(tny).max(tnz.max(Vec4::splat(t_min)));
    let t_far = tfx.min(tfy).min(tfz.min(Vec4::splat(t_max)));
    let hit = t_near.cmple(t_far * WIDE_T_FAR_SCALE);
    [hit.test(0), hit.test(1), hit.test(2), hit.test(3)]
}

/// The hit mask of `node` (obvhs' `CwBvhNode::intersect_ray`): bits 24..32 the hit inner
/// children, each at bit `24 + (slot ^ octant)` so that the highest set bit is the child to
/// visit first; bits 0..24 the primitives (offsets from `prim_base`) of the hit leaves.
#[inline(always)]
pub fn intersect_wide_node(node: &WideNode, r: &WideRay, t_min: f32, t_max: f32) -> u32 {
    let cell = Vec3::from_array(node.cell());
    // t of the plane at cell q is q * a + b.
    let a = cell * r.inv_dir;
    let b = (Vec3::from_array(node.p) - r.origin) * r.inv_dir;
    let pad = WIDE_QUANT_PAD * a.abs();
    let b_near = b - pad;
    let b_far = b + pad;
    // A negative direction meets the upper plane first. Per axis: (lower, upper) words of
    // slots 0..4 and 4..8.
    let planes = |q: &[u8; 16], neg: bool| {
        let (lo, hi) = (
            UVec2::new(word(q, 0), word(q, 4)),
            UVec2::new(word(q, 8), word(q, 12)),
        );
        if neg { (hi, lo) } else { (lo, hi) }
    };
    let (near_x, far_x) = planes(&node.q_x, r.inv_dir.x < 0.0);
    let (near_y, far_y) = planes(&node.q_y, r.inv_dir.y < 0.0);
    let (near_z, far_z) = planes(&node.q_z, r.inv_dir.z < 0.0);
    let lo = wide_overlap4(
        near_x.x, far_x.x, near_y.x, far_y.x, near_z.x, far_z.x, a, b_near, b_far, t_min, t_max,
    );
    let hi = wide_overlap4(
        near_x.y, far_x.y, near_y.y, far_y.y, near_z.y, far_z.y, a, b_near, b_far, t_min, t_max,
    );
    // Per slot: the bits to set (1 for an inner child, the unary primitive count for a leaf)
    // and where (24 + slot ^ octant for an inner child, the primitive offset for a leaf).
    let m = UVec2::new(word(&node.child_meta, 0), word(&node.child_meta, 4));
    let inner = (m & (m << 1u32)) & UVec2::splat(0x1010_1010);
    let inner_bytes = (inner >> 4u32) * 0xff;
    let bit_index = (m ^ (UVec2::splat(r.oct_inv4) & inner_bytes)) & UVec2::splat(0x1f1f_1f1f);
    let child_bits = (m >> 5u32) & UVec2::splat(0x0707_0707);
    let mut bits = 0u32;
    for (hit, cb, bi) in [
        (lo, child_bits.x, bit_index.x),
        (hi, child_bits.y, bit_index.y),
    ] {
        let (cb, bi) = (unpack4x_u8(cb), unpack4x_u8(bi));
        for j in 0..4 {
            // The WGSL's select: no branch.
            bits |= (cb[j] << bi[j]) & 0u32.wrapping_sub(u32::from(hit[j]));
        }
    }
    bits
}

/// A wide node as the CPU's walk reads it ([`intersect_wide_boxes`]): its eight child boxes
/// as floats, per axis the slots' lower planes and upper planes, and the node's fields the
/// walk needs (so that a node is one 256-byte read, not that and its [`WideNode`]). Each
/// plane is the quantised one moved out by [`WIDE_QUANT_PAD`] cells (`p + (q -/+ pad) *
/// cell`, exact in `f64`) and rounded outward to `f32`, so each box holds the padded
/// quantised box the GPU tests, and with it the child's true box. Empty slots hold zeros
/// (their bits are never set: see [`intersect_wide_boxes`]). Made from the nodes by
/// [`wide_boxes`]; the GPU never sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
pub struct WideBoxes {
    /// `planes[axis][slot]` the lower planes, `planes[3 + axis][slot]` the upper ones (one
    /// array, so that the node test picks each axis' nearer plane by its row).
    pub planes: [[f32; 8]; 6],
    /// Per slot, the primitives of a leaf slot as bits of their offsets from `prim_base`
    /// (what [`intersect_wide_node`] sets for the slot when it is hit); 0 for inner and empty
    /// slots. The node test ORs those of the hit slots four lanes at a time.
    pub leaf_prims: [u32; 8],
    /// The node's [`WideNode::child_base`].
    pub child_base: u32,
    /// The node's [`WideNode::prim_base`].
    pub prim_base: u32,
    /// The node's [`WideNode::imask`].
    pub imask: u32,
    /// The index of the node's first [`TriangleBlock`] (see [`triangle_blocks`]).
    pub block_base: u32,
}

// 240 bytes of fields, padded to 256 and aligned to a cache line: a node is four whole lines,
// none of its rows straddles two, and its index becomes an address by a shift, not a
// multiply, on the walk's chain of dependent loads.
const _: () = assert!(size_of::<WideBoxes>() == 256);

/// The largest `f32` at most `x`.
fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x { f.next_down() } else { f }
}

/// The smallest `f32` at least `x`.
fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x { f.next_up() } else { f }
}

/// The float boxes of `node`'s children (see [`WideBoxes`]).
pub fn wide_boxes(node: &WideNode) -> WideBoxes {
    let imask = u32::from(node.imask());
    let mut b = WideBoxes {
        child_base: node.child_base,
        prim_base: node.prim_base,
        imask,
        // A leaf slot's meta is its primitive count in unary (bits 5..8) and the first's
        // offset (bits 0..5); an empty slot's is 0.
        leaf_prims: std::array::from_fn(|slot| {
            let meta = u32::from(node.child_meta[slot]);
            if imask >> slot & 1 == 1 {
                0
            } else {
                ((meta >> 5) & 7) << (meta & 0x1f)
            }
        }),
        ..WideBoxes::default()
    };
    let cell = node.cell();
    let pad = f64::from(WIDE_QUANT_PAD);
    for (axis, q) in [&node.q_x, &node.q_y, &node.q_z].into_iter().enumerate() {
        let (p, c) = (f64::from(node.p[axis]), f64::from(cell[axis]));
        for slot in 0..8 {
            if node.child_meta[slot] == 0 {
                continue;
            }
            b.planes[axis][slot] = f32_down(p + (f64::from(q[slot]) - pad) * c);
            b.planes[3 + axis][slot] = f32_up(p + (f64::from(q[slot + 8]) + pad) * c);
        }
    }
    b
}

/// The triangles of every node's leaves in blocks of four ([`TriangleBlock`]): block `k` of
/// a node holds the primitives at offsets `4k..4k + 4` from its `prim_base` (zeros past its
/// last one or the array's end: a degenerate triangle, never hit), and each node's
/// [`WideBoxes::block_base`] is set to its first block.
pub fn triangle_blocks(
    nodes: &[WideNode],
    boxes: &mut [WideBoxes],
    primitives: &[Primitive],
) -> Vec<TriangleBlock> {
    let mut blocks = Vec::new();
    for (node, b) in nodes.iter().zip(boxes.iter_mut()) {
        b.block_base = blocks.len() as u32;
        // Past the highest offset of any leaf slot's primitives.
        let end = 32 - b.leaf_prims.iter().fold(0, |a, &p| a | p).leading_zeros();
        for k in 0..end.div_ceil(4) {
            let mut block = TriangleBlock::default();
            for j in 0..4u32 {
                let i = (node.prim_base + 4 * k + j) as usize;
                if 4 * k + j >= end || i >= primitives.len() {
                    continue;
                }
                block.set_lane(j as usize, &primitives[i]);
            }
            blocks.push(block);
        }
    }
    blocks
}

/// `XOR_PERMUTE8[oct][m]`: bit `s` of the eight bits `m` moved to bit `s ^ oct` (a table of
/// 2 KiB: one load instead of three data-dependent steps).
static XOR_PERMUTE8: [[u8; 256]; 8] = {
    let mut t = [[0u8; 256]; 8];
    let mut oct = 0;
    while oct < 8 {
        let mut m = 0;
        while m < 256 {
            let mut out = 0u32;
            let mut s = 0;
            while s < 8 {
                if m >> s & 1 == 1 {
                    out |= 1 << (s ^ oct);
                }
                s += 1;
            }
            t[oct][m] = out as u8;
            m += 1;
        }
        oct += 1;
    }
    t
};

/// [`intersect_wide_node`]'s hit mask (the same bits for the same hit children) from the
/// node's float boxes: the CPU's form of the node test, about about half its instructions
/// (no byte conversions, no per-slot shifts; `docs/RESULTS.md`, issue 15). The slab test of
/// [`intersect_aabb`](crate::intersect::intersect_aabb) on exact planes, four slots a lane
/// each, accepting `t_near <= t_far * WIDE_T_FAR_SCALE` (a wider margin than that test's own
/// 16 units of roundoff), with `1 / dir` clamped as [`WideRay`] has it (so no `0 * inf`).
/// A box it accepts may differ from the quantised test's only where both hold the child's
/// true box: the walk visits a superset of the nodes that can hold the closest hit, and finds
/// the same primitives in the same order (see the module docs).
#[inline(always)]
pub fn intersect_wide_boxes(boxes: &WideBoxes, r: &WideRay, t_min: f32, t_max: f32) -> u32 {
    let (hit, prims, _) = wide_boxes_hits(boxes, r, t_min, t_max);
    let inner = XOR_PERMUTE8[(r.oct_inv4 & 7) as usize][(hit & boxes.imask) as usize];
    (u32::from(inner) << 24) | prims
}

/// The slab test of [`intersect_wide_boxes`]: bit `slot` set for each child box the ray
/// meets within `[t_min, t_max]` (empty slots' zero boxes included: callers mask them by
/// their metadata), the primitives of the hit leaf slots (their [`WideBoxes::leaf_prims`]
/// ORed, four lanes at a time), and every slot's entry distance (`t_near`, lanes 0..4 and
/// 4..8).
#[inline(always)]
pub fn wide_boxes_hits(
    boxes: &WideBoxes,
    r: &WideRay,
    t_min: f32,
    t_max: f32,
) -> (u32, u32, [Vec4; 2]) {
    let o = r.origin.to_array();
    let inv = r.inv_dir.to_array();
    let rows = &boxes.planes;
    // Per axis, the row of the plane the ray meets first: the lower where `1 / dir` is
    // positive, the upper where negative (a choice the walk's loop hoists). `1 / dir` is
    // finite (clamped) and every box has lower <= upper, so this plane's distance is the
    // smaller of the two, the value a `min` of both would give, bit for bit (subtraction
    // and multiplication round monotonically), without the `min` and `max` per axis.
    let near_row = |k: usize| if inv[k].is_sign_negative() { 3 + k } else { k };
    let half = |h: usize| -> (u32, u32, Vec4) {
        let axis = |k: usize| {
            let (n, f) = (near_row(k), (near_row(k) + 3) % 6);
            let near = Vec4::from_slice(&rows[n][4 * h..4 * h + 4]);
            let far = Vec4::from_slice(&rows[f][4 * h..4 * h + 4]);
            let (o, i) = (Vec4::splat(o[k]), Vec4::splat(inv[k]));
            ((near - o) * i, (far - o) * i)
        };
        let (nx, fx) = axis(0);
        let (ny, fy) = axis(1);
        let (nz, fz) = axis(2);
        let t_near = nx.max(ny).max(nz.max(Vec4::splat(t_min)));
        let t_far = fx.min(fy).min(fz.min(Vec4::splat(t_max)));
        let hit = t_near.cmple(t_far * WIDE_T_FAR_SCALE);
        let leaves: &[u32; 4] = boxes.leaf_prims[4 * h..4 * h + 4].try_into().expect("4");
        (hit.bitmask(), or_where(hit, leaves), t_near)
    };
    let (lo, prims_lo, near_lo) = half(0);
    let (hi, prims_hi, near_hi) = half(1);
    (lo | (hi << 4), prims_lo | prims_hi, [near_lo, near_hi])
}

/// The OR of the lanes of `words` where `mask` is set: on x86-64 one AND and two
/// shuffle-and-OR steps in SSE2 registers instead of a loop over the set lanes.
#[inline(always)]
fn or_where(mask: glam::BVec4A, words: &[u32; 4]) -> u32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[allow(unused_unsafe)]
    // SAFETY: SSE2 is enabled (the cfg); `words` is four u32s, read unaligned.
    unsafe {
        use std::arch::x86_64::*;
        let m = _mm_castps_si128(std::arch::x86_64::__m128::from(mask));
        let v = _mm_and_si128(m, _mm_loadu_si128(words.as_ptr().cast()));
        let v = _mm_or_si128(v, _mm_shuffle_epi32::<0b01_00_11_10>(v));
        let v = _mm_or_si128(v, _mm_shuffle_epi32::<0b10_11_00_01>(v));
        _mm_cvtsi128_si32(v) as u32
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    or_where_lanes(mask.bitmask(), words)
}

/// [`or_where`] lane by lane, `bits` the mask's lanes (the form without SSE2, and the
/// reference of its test).
#[cfg_attr(all(target_arch = "x86_64", target_feature = "sse2"), allow(dead_code))]
fn or_where_lanes(bits: u32, words: &[u32; 4]) -> u32 {
    (0..4usize)
        .filter(|&j| bits >> j & 1 == 1)
        .fold(0, |a, j| a | words[j])
}

/// The index of the inner child that `bit` (24..32) of a node group stands for: the group
/// (x: the node's `child_base`, y: its hit mask's inner bits | its imask) counts the inner
/// slots before that slot.
#[inline(always)]
pub fn wide_child_index(group: UVec2, bit: u32, oct_inv4: u32) -> u32 {
    let slot = (bit - 24) ^ (oct_inv4 & 0xff);
    group.x + (group.y & !(u32::MAX << slot)).count_ones()
}

/// The highest set bit of a non-zero `x` (WGSL's `firstLeadingBit` on `u32`).
#[inline(always)]
fn first_leading_bit(x: u32) -> u32 {
    31 - x.leading_zeros()
}

/// The walk both queries share (Ylitie et al.'s traversal without triangle postponing): a
/// node group (x: first child node, y: bits 24..32 the children still to visit | imask) is
/// entered child by child, the highest bit first, the rest of the group pushed; the
/// primitives of a node's hit leaves are tested when the node is. The closest hit with
/// `t_min < t < t_max`, or with `any_hit` the first one found; a miss has
/// `prim == INVALID_INDEX` and `t == min(t_max, T_MAX_LIMIT)`. The stack holds at most
/// `depth - 1` groups, which `validate` bounds by [`WIDE_STACK_SIZE`]. `SPHERES`: as
/// [`intersect_primitive`]'s; without it the CPU tests a node's triangles up to four at once
/// (`leaf_group4`), so that an any-hit walk returns the closest hit of the first group
/// that has one (a hit all the same: `trace_any` reads only whether there is one).
#[inline(always)]
pub fn wide_walk<const SPHERES: bool>(
    nodes: &[WideNode],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    any_hit: bool,
) -> Hit {
    let mut wr = wide_ray(ray);
    if any_hit {
        wr.oct_inv4 ^= WIDE_ANY_OCT_FLIP;
    }
    let sheared: ShearedRay = shear_ray(ray);
    let mut hit = Hit {
        t: t_max.min(T_MAX_LIMIT),
        prim: INVALID_INDEX,
        u: 0.0,
        v: 0.0,
    };
    let leaves = Leaves::Records(primitives);
    let mut stack = [UVec2::ZERO; WIDE_STACK_SIZE];
    let mut sp = 0usize;
    // The root as the only child of a group.
    let mut group = UVec2::new(0, 0x8000_0000);
    loop {
        if group.y & 0xff00_0000 != 0 {
            let bit = first_leading_bit(group.y);
            let index = wide_child_index(group, bit, wr.oct_inv4);
            group.y &= !(1 << bit);
            if group.y & 0xff00_0000 != 0 {
                debug_assert!(sp < WIDE_STACK_SIZE);
                stack[sp] = group;
                sp += 1;
            }
            let node = &nodes[index as usize];
            let mask = intersect_wide_node(node, &wr, t_min, hit.t);
            let prim_base = node.prim_base;
            group = UVec2::new(
                node.child_base,
                (mask & 0xff00_0000) | u32::from(node.imask()),
            );
            let prims = mask & 0x00ff_ffff;
            if test_leaves::<SPHERES>(
                leaves, prim_base, 0, prims, &sheared, t_min, any_hit, &mut hit,
            ) {
                return hit;
            }
        }
        if group.y & 0xff00_0000 == 0 {
            if sp == 0 {
                break;
            }
            sp -= 1;
            group = stack[sp];
        }
    }
    hit
}

/// `NEXT_SLOT8[oct][m]`: of the slots set in `m` (non-zero), the one a walk in octant
/// `oct` enters first, the highest `slot ^ oct` (`first_leading_bit(XOR_PERMUTE8[oct][m]) ^
/// oct`), a table of 2 KiB.
static NEXT_SLOT8: [[u8; 256]; 8] = {
    let mut t = [[0u8; 256]; 8];
    let mut oct = 0;
    while oct < 8 {
        let mut m = 1;
        while m < 256 {
            let p = XOR_PERMUTE8[oct][m] as u32;
            t[oct][m] = ((31 - p.leading_zeros()) ^ oct as u32) as u8;
            m += 1;
        }
        oct += 1;
    }
    t
};

/// `INNER_RANK8[m][s]`: the set bits of `m` below bit `s` (a node's inner children before
/// slot `s`, with `m` its imask), a table of 2 KiB: one load where the baseline x86-64
/// target has no `popcnt`.
static INNER_RANK8: [[u8; 8]; 256] = {
    let mut t = [[0u8; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let mut s = 0;
        while s < 8 {
            t[m][s] = (m & ((1 << s) - 1)).count_ones() as u8;
            s += 1;
        }
        m += 1;
    }
    t
};

/// Stack entries of [`walk_boxes`]: at most seven children wait at each node of the path,
/// which is at most [`WIDE_STACK_SIZE`] nodes deep.
const BOX_STACK_SIZE: usize = 7 * WIDE_STACK_SIZE;

/// The CPU's form of [`wide_walk`] (`GpuBvh`'s traversal of a wide tree): nodes tested by
/// their float boxes ([`wide_boxes_hits`]), triangles four at a time from the node's
/// blocks ([`leaf_block4`]) unless `SPHERES`. Where [`wide_walk`] keeps a node group
/// (the node's children still to visit) on its stack, this keeps each child to visit with
/// its box's entry distance, pushed so that they are taken in the same order (the highest
/// `slot ^ octant` first), and passes over a child whose box begins beyond the closest hit
/// found since (`t_near > t * WIDE_T_FAR_SCALE`, the box test's own criterion) without
/// reading its node; it also leaves out the groups' bit juggling. The same primitives are
/// tested in the same order, but for those in boxes that cannot hold a closer hit, so the
/// hits are the same (tested against [`wide_walk`] over every test tree: visiting the
/// children in another order fails those tests, on ties).
#[inline(always)]
fn walk_boxes<const SPHERES: bool, const AVX2: bool>(
    boxes: &[WideBoxes],
    blocks: &[TriangleBlock],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    any_hit: bool,
) -> Hit {
    let (wr, sheared) = walk_rays(ray);
    let oct = (wr.oct_inv4 ^ if any_hit { WIDE_ANY_OCT_FLIP } else { 0 }) & 7;
    let next_slot = &NEXT_SLOT8[oct as usize];
    let mut hit = Hit {
        t: t_max.min(T_MAX_LIMIT),
        prim: INVALID_INDEX,
        u: 0.0,
        v: 0.0,
    };
    let leaves = if AVX2 {
        Leaves::BlocksAvx2(blocks, primitives)
    } else {
        Leaves::Blocks(blocks, primitives)
    };
    // The children waiting and their boxes' entry distances. Uninitialised (no 1.8 KB to
    // zero for every ray); only entries below `sp` are read, each written before. Eight
    // entries of room past the last: the AVX2 push writes eight.
    let mut stack_node = [MaybeUninit::<u32>::uninit(); BOX_STACK_SIZE + 8];
    let mut stack_near = [MaybeUninit::<f32>::uninit(); BOX_STACK_SIZE + 8];
    let mut sp = 0usize;
    let mut node = 0u32;
    loop {
        let b = &boxes[node as usize];
        let (mask, prims, near) = if AVX2 {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `AVX2` only from the `_avx2` methods, whose callers' CPUs have it.
            unsafe {
                crate::wide_avx2::wide_boxes_hits(b, &wr, t_min, hit.t)
            }
            #[cfg(not(target_arch = "x86_64"))]
            unreachable!("AVX2 walks on x86-64 only")
        } else {
            wide_boxes_hits(b, &wr, t_min, hit.t)
        };
        if test_leaves::<SPHERES>(
            leaves,
            b.prim_base,
            b.block_base,
            prims,
            &sheared,
            t_min,
            any_hit,
            &mut hit,
        ) {
            return hit;
        }
        // The hit inner children, bit `slot ^ octant` for each: the highest is entered now,
        // the others pushed lowest first, so that the next highest is on top.
        let hit_inner = (mask & b.imask) as usize;
        if hit_inner != 0 {
            let ranks = &INNER_RANK8[(b.imask & 0xff) as usize];
            let child = |slot: u32| b.child_base + u32::from(ranks[slot as usize]);
            // The slot entered now straight from a table: one load after the mask, where the
            // highest bit of the permuted mask took a load, a bit scan and an XOR on the
            // walk's chain from one node to the next. The others as permuted bits.
            let slot = u32::from(next_slot[hit_inner]);
            let inner = u32::from(XOR_PERMUTE8[oct as usize][hit_inner]);
            let mut rest = inner & !(1 << (slot ^ oct));
            if AVX2 {
                #[cfg(target_arch = "x86_64")]
                {
                    // At most 7 entries a level of a tree `validate` holds to WIDE_STACK_SIZE
                    // levels; checked all the same (one predictable branch), as the
                    // loop's indexing below checks it: the eight writes stay in the arrays.
                    assert!(sp <= BOX_STACK_SIZE, "the walk's stack overflowed");
                    // SAFETY: `AVX2` only from the `_avx2` methods, whose callers' CPUs have
                    // it; `sp` is at most BOX_STACK_SIZE (just checked), so eight entries fit
                    // from it.
                    sp += unsafe {
                        crate::wide_avx2::push_children(
                            near,
                            b.child_base,
                            ranks,
                            oct,
                            rest,
                            stack_node.as_mut_ptr().add(sp).cast(),
                            stack_near.as_mut_ptr().add(sp).cast(),
                        )
                    };
                }
            } else if rest != 0 {
                let near = [near[0].to_array(), near[1].to_array()];
                while rest != 0 {
                    let slot = rest.trailing_zeros() ^ oct;
                    rest &= rest - 1;
                    stack_node[sp] = MaybeUninit::new(child(slot));
                    stack_near[sp] =
                        MaybeUninit::new(near[(slot >> 2) as usize][(slot & 3) as usize]);
                    sp += 1;
                }
            }
            node = child(slot);
            continue;
        }
        loop {
            if sp == 0 {
                return hit;
            }
            sp -= 1;
            // SAFETY: every entry below `sp` was written by the pushes above.
            let t_near = unsafe { stack_near[sp].assume_init() };
            if t_near <= hit.t * WIDE_T_FAR_SCALE {
                // SAFETY: as `t_near`.
                node = unsafe { stack_node[sp].assume_init() };
                break;
            }
        }
    }
}

/// Where a walk's four-wide triangle tests read their triangles.
#[derive(Clone, Copy)]
enum Leaves<'a> {
    /// Gathered from the primitive records ([`leaf_group4`]): the quantised walk's.
    Records(&'a [Primitive]),
    /// From the nodes' blocks ([`leaf_block4`]): the CPU walk's; the records for spheres.
    Blocks(&'a [TriangleBlock], &'a [Primitive]),
    /// As `Blocks`, two blocks at a time in AVX registers (`wide_avx2::leaf_blocks8`): only
    /// on a CPU with AVX2 (the `_avx2` walks).
    BlocksAvx2(&'a [TriangleBlock], &'a [Primitive]),
}

/// The primitives `prims` (offsets from `base`) of a node's hit leaves against the ray, in
/// the walks' order (the highest offset first), `hit` becoming the closer of it and theirs;
/// true when `any_hit` and one was hit (the walk returns it). Without `SPHERES` up to four
/// at a time, as `leaves` holds them (same hits: see [`leaf_group4`]); from
/// [`Leaves::Blocks`] even one alone, through its block (the scalar test's indexing of a
/// vector by the ray's axes costs more than the three lanes it spares: with the lanes picked
/// without a branch, Bitterli's Cornell box 4-5 % faster on the CPU, `docs/RESULTS.md`, issue
/// 15); `block_base` is the node's first block in [`Leaves::Blocks`] (unread for the
/// records).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn test_leaves<const SPHERES: bool>(
    leaves: Leaves,
    base: u32,
    block_base: u32,
    prims: u32,
    sheared: &ShearedRay,
    t_min: f32,
    any_hit: bool,
    hit: &mut Hit,
) -> bool {
    let primitives = match leaves {
        Leaves::Records(p) | Leaves::Blocks(_, p) | Leaves::BlocksAvx2(_, p) => p,
    };
    let mut prims = prims;
    while prims != 0 {
        if !SPHERES && (!matches!(leaves, Leaves::Records(..)) || prims.count_ones() > 1) {
            let found = match leaves {
                Leaves::Records(p) => leaf_group4(p, base, &mut prims, sheared, t_min, hit),
                Leaves::Blocks(b, _) => {
                    leaf_block4(b, base, block_base, &mut prims, sheared, t_min, hit)
                }
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `BlocksAvx2` only from the `_avx2` walks, whose callers' CPUs have
                // AVX2; `prims` is non-zero (the loop's condition).
                Leaves::BlocksAvx2(b, _) => unsafe {
                    crate::wide_avx2::leaf_blocks8(
                        b, base, block_base, &mut prims, sheared, t_min, hit,
                    )
                },
                #[cfg(not(target_arch = "x86_64"))]
                Leaves::BlocksAvx2(..) => unreachable!("AVX2 walks on x86-64 only"),
            };
            if found && any_hit {
                return true;
            }
            continue;
        }
        let k = first_leading_bit(prims);
        prims &= !(1 << k);
        let i = base + k;
        let r = intersect_primitive::<SPHERES>(&primitives[i as usize], sheared, t_min, hit.t);
        if r.x < hit.t {
            *hit = Hit {
                t: r.x,
                prim: i,
                u: r.y,
                v: r.z,
            };
            if any_hit {
                return true;
            }
        }
    }
    false
}

/// Up to four of the primitives in `prims` (offsets from `base`; the highest bits, which the
/// loop over them in [`wide_walk`] takes first), cleared from it and tested at once
/// ([`intersect_triangles4`]; all of them triangles): `hit` becomes what that loop would make
/// it, taking them in its order, a lane replacing `hit` only if strictly closer, so that of
/// equal distances the first in that order stays. True if any of them was hit.
#[inline(always)]
fn leaf_group4(
    primitives: &[Primitive],
    base: u32,
    prims: &mut u32,
    sheared: &ShearedRay,
    t_min: f32,
    hit: &mut Hit,
) -> bool {
    let mut index = [0u32; 4];
    let mut n = 0;
    while *prims != 0 && n < 4 {
        let k = first_leading_bit(*prims);
        *prims &= !(1 << k);
        index[n] = base + k;
        n += 1;
    }
    // Unused lanes repeat the last primitive: a repeat is never strictly closer.
    for j in n..4 {
        index[j] = index[n - 1];
    }
    let tris = index.map(|i| &primitives[i as usize]);
    debug_assert!(
        tris.iter().all(|p| p.b[3].to_bits() != crate::PRIM_SPHERE),
        "a sphere traced without SPHERES"
    );
    let [t, u, v] = intersect_triangles4(sheared, tris, t_min, hit.t);
    let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
    let mut found = false;
    for j in 0..n {
        if t[j] < hit.t {
            *hit = Hit {
                t: t[j],
                prim: index[j],
                u: u[j],
                v: v[j],
            };
            found = true;
        }
    }
    found
}

/// [`leaf_group4`] from the node's triangle blocks: the four offsets `4k..4k + 4` (block `k`
/// of the node's, from `block_base`) around `prims`' highest set bit, its set bits among
/// them cleared from it and those tested at once ([`intersect_triangle_block`]; lanes whose
/// bit is clear are tested too and ignored). `hit` becomes what the one-at-a-time loop would
/// make it: the lanes are taken highest offset first, as that loop takes them, a lane
/// replacing `hit` only if strictly closer. True if any of them was hit.
#[inline(always)]
fn leaf_block4(
    blocks: &[TriangleBlock],
    base: u32,
    block_base: u32,
    prims: &mut u32,
    sheared: &ShearedRay,
    t_min: f32,
    hit: &mut Hit,
) -> bool {
    let lo = first_leading_bit(*prims) & !3;
    let lanes = (*prims >> lo) & 0xf;
    *prims &= !(0xf << lo);
    let first = base + lo;
    let block = &blocks[(block_base + lo / 4) as usize];
    let [t, u, v] = intersect_triangle_block(sheared, block, t_min, hit.t);
    // The lanes whose bit is set, their misses at T_MISS; the one-at-a-time loop (highest lane
    // first, strictly closer replacing) ends at their smallest t, of equal ones the highest
    // lane: found without a branch per lane.
    let live = LANE_MASKS[lanes as usize];
    let t = Vec4::select(live, t, Vec4::splat(T_MISS));
    let t_best = t.min_element();
    if t_best < hit.t {
        let j = first_leading_bit(t.cmpeq(Vec4::splat(t_best)).bitmask()) as usize;
        *hit = Hit {
            // The smallest t itself (lane j's value), as the AVX2 form takes it: for a
            // `t_min` below zero, where two lanes could hold +0 and -0, the two forms'
            // reductions may keep a different zero's sign; no other t differs.
            t: t_best,
            prim: first + j as u32,
            u: u.to_array()[j],
            v: v.to_array()[j],
        };
        true
    } else {
        false
    }
}

/// `LANE_MASKS[m]`: lane `j` set where bit `j` of `m` is.
static LANE_MASKS: [glam::BVec4A; 16] = {
    let mut t = [glam::BVec4A::FALSE; 16];
    let mut m = 0;
    while m < 16 {
        t[m] = glam::BVec4A::new(m & 1 != 0, m & 2 != 0, m & 4 != 0, m & 8 != 0);
        m += 1;
    }
    t
};

/// The closest hit with `t_min < t < t_max` in the wide tree `nodes` over `primitives`, or a
/// miss (`prim == INVALID_INDEX`, `t == min(t_max, T_MAX_LIMIT)`).
pub fn trace_closest(
    nodes: &[WideNode],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
) -> Hit {
    wide_walk::<true>(nodes, primitives, ray, t_min, t_max, false)
}

/// True if anything is hit with `t_min < t < t_max`: [`wide_walk`] returning at the first
/// primitive hit (a shadow ray).
pub fn trace_any(
    nodes: &[WideNode],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
) -> bool {
    wide_walk::<true>(nodes, primitives, ray, t_min, t_max, true).prim != INVALID_INDEX
}

impl GpuBvh {
    /// [`wide_walk`]'s hits for a tree of [`BvhLayout::Wide`](crate::BvhLayout::Wide), found
    /// the CPU's way: nodes tested by their float boxes ([`intersect_wide_boxes`]) and,
    /// without `SPHERES`, triangles read four at a time from the nodes' blocks
    /// ([`intersect_triangle_block`]), both from [`GpuBvh::cpu_arrays`].
    /// With `AVX2`, the node and triangle tests eight lanes at a time in AVX registers (the
    /// crate's `wide_avx2` module), and a tree of at most `FLAT_MAX_PRIMITIVES_AVX2`
    /// triangles not walked but tested whole (`flat_hit`; with `AVX512` sixteen lanes at a
    /// time and up to `FLAT_MAX_PRIMITIVES`, `flat_hit16`, which passes over the blocks whose
    /// boxes begin beyond the closest hit so far) unless several triangles hold the closest
    /// hit: the same hits bit for bit.
    ///
    /// # Safety
    /// With `AVX2`, the CPU must have AVX2, with `AVX512` AVX-512 F too (without, none).
    #[inline(always)]
    pub(crate) unsafe fn wide_walk<const SPHERES: bool, const AVX2: bool, const AVX512: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        any_hit: bool,
        between: bool,
    ) -> Hit {
        let arrays = self.cpu_walk_arrays();
        debug_assert_eq!(self.wide_nodes.len(), arrays.boxes.len());
        // A small tree of triangles: all of them tested, unless several share the closest
        // hit (then the walk's order decides).
        #[cfg(target_arch = "x86_64")]
        if AVX2 && !SPHERES {
            if AVX512 {
                if !arrays.flat.is_empty() {
                    let (wide, sheared) = walk_rays(ray);
                    let t_max = t_max.min(T_MAX_LIMIT);
                    // A segment between two points of the scene: the triangles it may meet.
                    let set = if between {
                        &arrays.flat_between16
                    } else {
                        &arrays.flat
                    };
                    // SAFETY: `AVX512` only from the `_avx512` methods, whose callers' CPUs
                    // have AVX2 and AVX-512 F.
                    let hit = unsafe {
                        crate::wide_avx2::flat_hit16(set, &wide, &sheared, t_min, t_max, any_hit)
                    };
                    if let Some(hit) = hit {
                        return hit;
                    }
                }
            } else if !arrays.flat_avx2.is_empty() {
                let sheared = crate::intersect::shear_ray(ray);
                let t_max = t_max.min(T_MAX_LIMIT);
                // A segment between two points of the scene: the triangles it may meet.
                let (flat, count) = if between {
                    (&arrays.flat_between.0, arrays.flat_between.1)
                } else {
                    (&arrays.flat_avx2, self.primitives.len())
                };
                // SAFETY: `AVX2` only from the `_avx2` and `_avx512` methods, whose callers'
                // CPUs have it.
                let hit = unsafe {
                    crate::wide_avx2::flat_hit(flat, count, &sheared, t_min, t_max, any_hit)
                };
                if let Some(hit) = hit {
                    return hit;
                }
            }
        }
        walk_boxes::<SPHERES, AVX2>(
            &arrays.boxes,
            &arrays.blocks,
            &self.primitives,
            ray,
            t_min,
            t_max,
            any_hit,
        )
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use raylume_scene::Triangle;

    use super::*;
    use crate::{BvhLayout, BvhQuality, wide::slot_box};

    #[test]
    fn inner_rank_table_counts_the_inner_slots_before_each_slot() {
        for m in 0..256u32 {
            for slot in 0..8u32 {
                let want = (0..slot).filter(|s| m >> s & 1 == 1).count();
                assert_eq!(usize::from(INNER_RANK8[m as usize][slot as usize]), want);
            }
        }
    }

    #[test]
    fn xor_permute_table_moves_bit_s_to_s_xor_oct() {
        for oct in 0..8u32 {
            for s in 0..8u32 {
                let m = XOR_PERMUTE8[oct as usize][1 << s];
                assert_eq!(u32::from(m), 1 << (s ^ oct), "oct {oct}, bit {s}");
            }
            // Bits move independently: the table is linear over OR.
            let table = &XOR_PERMUTE8[oct as usize];
            for (m, &moved) in table.iter().enumerate() {
                let each = (0..8)
                    .filter(|s| m >> s & 1 == 1)
                    .fold(0u8, |a, s| a | table[1 << s]);
                assert_eq!(moved, each);
            }
        }
    }

    #[test]
    fn next_slot_table_is_the_slot_of_the_highest_permuted_bit() {
        for oct in 0..8u32 {
            for m in 1..256u32 {
                // The slot whose `slot ^ oct` is the largest among those set in `m`.
                let want = (0..8u32)
                    .filter(|s| m >> s & 1 == 1)
                    .max_by_key(|s| s ^ oct)
                    .unwrap();
                assert_eq!(
                    u32::from(NEXT_SLOT8[oct as usize][m as usize]),
                    want,
                    "oct {oct}, m {m:#b}"
                );
            }
        }
    }

    /// A random soup of small triangles in a box of size `scale` about `offset`.
    fn soup(n: usize, scale: f32, offset: Vec3, seed: u64) -> Vec<Triangle> {
        let mut s = seed;
        let mut r = || crate::test_rand(&mut s);
        (0..n)
            .map(|_| {
                let c = Vec3::new(r(), r(), r());
                let mut v = || offset + (c + (Vec3::new(r(), r(), r()) - 0.5) * 0.05) * scale;
                Triangle::flat([v(), v(), v()], 0)
            })
            .collect()
    }

    #[test]
    fn float_boxes_are_the_tightest_that_hold_the_padded_quantised_boxes() {
        // The CPU's node test culls by these boxes: each must hold the box the GPU's
        // quantised test sees (which `validate` proves holds the child's contents), and be
        // the smallest f32 box that does (outward rounding by one step at most).
        for (scale, offset) in [
            (1.0, Vec3::ZERO),
            (3e4, Vec3::splat(-7e5)),
            (1e-3, Vec3::ONE),
        ] {
            let tris = soup(400, scale, offset, 7);
            let bvh =
                GpuBvh::build_with_layout(&tris, &[], BvhQuality::Fast, BvhLayout::Wide).unwrap();
            assert!(bvh.wide_nodes.len() > 8);
            for (node, boxes) in bvh.wide_nodes.iter().zip(bvh.wide_boxes()) {
                assert_eq!(
                    (boxes.child_base, boxes.prim_base),
                    (node.child_base, node.prim_base)
                );
                assert_eq!(boxes.imask, u32::from(node.imask()));
                // Each leaf slot's primitives as the quantised test sets them for it.
                for slot in 0..8 {
                    let meta = u32::from(node.child_meta[slot]);
                    let want = if node.imask() >> slot & 1 == 1 {
                        0
                    } else {
                        ((meta >> 5) & 7) << (meta & 0x1f)
                    };
                    assert_eq!(boxes.leaf_prims[slot], want, "slot {slot}");
                }
                for slot in (0..8).filter(|&s| node.child_meta[s] != 0) {
                    let (lo, hi) = slot_box(node, slot);
                    for k in 0..3 {
                        let (l, h) = (boxes.planes[k][slot], boxes.planes[3 + k][slot]);
                        assert!(f64::from(l) <= lo[k] && f64::from(l.next_up()) > lo[k]);
                        assert!(f64::from(h) >= hi[k] && f64::from(h.next_down()) < hi[k]);
                    }
                }
            }
        }
    }

    /// The walk's one-division setup is `wide_ray` and `shear_ray` bit for bit, on random
    /// directions and on the edge cases: zero components of either sign, components so
    /// small that `1 / dir` is clamped or infinite, ties for the largest axis.
    #[test]
    fn walk_rays_is_wide_ray_and_shear_ray() {
        let mut state = 7u64;
        let mut rnd = || crate::test_rand(&mut state) * 2.0 - 1.0;
        let mut dirs: Vec<Vec3> = (0..20_000)
            .map(|_| Vec3::new(rnd(), rnd(), rnd()))
            .collect();
        let odd = [
            0.0,
            -0.0,
            1e-30,
            -1e-30,
            f32::MIN_POSITIVE,
            1e-45,
            1.0,
            -1.0,
            0.5,
            3e38,
        ];
        for &x in &odd {
            for &y in &odd {
                for &z in &odd {
                    dirs.push(Vec3::new(x, y, z));
                }
            }
        }
        for dir in dirs {
            let ray = Ray {
                origin: Vec3::new(0.25, -3.0, 1e3),
                dir,
            };
            let (w, s) = walk_rays(&ray);
            let (w0, s0) = (wide_ray(&ray), shear_ray(&ray));
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            assert_eq!(bits(w.inv_dir), bits(w0.inv_dir), "{dir:?}");
            assert_eq!((w.origin, w.oct_inv4), (w0.origin, w0.oct_inv4), "{dir:?}");
            assert_eq!(bits(s.shear), bits(s0.shear), "{dir:?}");
            assert_eq!(
                (s.kx, s.ky, s.kz, s.origin),
                (s0.kx, s0.ky, s0.kz, s0.origin)
            );
        }
    }

    #[test]
    fn or_where_ors_the_masked_lanes() {
        let words = [0x1u32, 0x30, 0x700, 0xf000_0000];
        for bits in 0..16u32 {
            let mask =
                glam::BVec4A::new(bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0);
            let want: u32 = (0..4)
                .filter(|j| bits >> j & 1 == 1)
                .map(|j| words[j])
                .sum();
            assert_eq!(or_where(mask, &words), want, "lanes {bits:04b}");
            assert_eq!(or_where_lanes(bits, &words), want, "lanes {bits:04b}");
        }
    }

    #[test]
    fn nearer_plane_by_the_sign_is_the_min_of_both_bit_for_bit() {
        // `wide_boxes_hits` reads each axis' nearer plane by the sign of `1 / dir` instead of
        // taking the min and max of both planes' distances: the same bits and the same entry
        // distances, to the bit, for rays of every octant, axis-parallel ones (`1 / dir`
        // clamped, either sign of zero) and boxes the origin is inside or beyond.
        let tris = soup(300, 1.0, Vec3::ZERO, 5);
        let bvh = GpuBvh::build_with_layout(&tris, &[], BvhQuality::Fast, BvhLayout::Wide).unwrap();
        let both_planes = |b: &WideBoxes, r: &WideRay, t_min: f32, t_max: f32| {
            let mut mask = 0u32;
            let near: [f32; 8] = std::array::from_fn(|slot| {
                let (mut t_near, mut t_far) = (t_min, t_max);
                for k in 0..3 {
                    let o = r.origin[k];
                    let t0 = (b.planes[k][slot] - o) * r.inv_dir[k];
                    let t1 = (b.planes[3 + k][slot] - o) * r.inv_dir[k];
                    t_near = t_near.max(t0.min(t1));
                    t_far = t_far.min(t0.max(t1));
                }
                mask |= u32::from(t_near <= t_far * WIDE_T_FAR_SCALE) << slot;
                t_near
            });
            (mask, near)
        };
        let mut s = 9u64;
        let mut r = || crate::test_rand(&mut s);
        let mut hits = 0;
        for i in 0..3000 {
            let origin = Vec3::new(r(), r(), r()) * 1.4 - 0.2;
            let mut dir = Vec3::new(r(), r(), r()) - 0.5;
            // Every tenth ray parallel to an axis plane, with +0 or -0 across it.
            if i % 10 == 0 {
                dir[i / 10 % 3] = if i % 20 == 0 { 0.0 } else { -0.0 };
            }
            let wr = wide_ray(&Ray {
                origin,
                dir: dir.normalize_or(Vec3::X),
            });
            let t_max = 0.1 + 2.0 * r();
            for b in bvh.wide_boxes() {
                let (mask, prims, near) = wide_boxes_hits(b, &wr, 0.0, t_max);
                let (want, want_near) = both_planes(b, &wr, 0.0, t_max);
                assert_eq!(mask, want);
                // The AVX2 form (min and max of both planes, eight slots at once), where this
                // CPU has AVX2: the same slots, primitives and entry distances.
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: this CPU has AVX2 (just detected).
                    let (m8, p8, n8) =
                        unsafe { crate::wide_avx2::wide_boxes_hits(b, &wr, 0.0, t_max) };
                    assert_eq!((m8, p8), (mask, prims));
                    for (a, c) in n8.iter().zip(&near) {
                        assert!(a.cmpeq(*c).all(), "{a:?} {c:?}");
                    }
                }
                let got: Vec<u32> = near
                    .iter()
                    .flat_map(|v| v.to_array())
                    .map(f32::to_bits)
                    .collect();
                let want_bits: Vec<u32> = want_near.iter().map(|t| t.to_bits()).collect();
                // Lanes whose entry is -0 in one and +0 in the other compare equal; none
                // differs otherwise.
                for (g, w) in got.iter().zip(&want_bits) {
                    assert!(
                        g == w || f32::from_bits(*g) == f32::from_bits(*w),
                        "{g:x} {w:x}"
                    );
                }
                hits += mask.count_ones();
            }
        }
        // (5,245 slots of 3000 rays through 300 triangles' nodes here.)
        assert!(hits > 2000, "{hits} slots hit");
    }

    /// The AVX2 push stores what the walk's loop over the children pushes, in its order, for
    /// every octant and set of children.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_push_is_the_loops_pushes() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let near = [Vec4::new(0.5, 1.5, 2.5, 3.5), Vec4::new(4.5, 5.5, 6.5, 7.5)];
        for imask in [0xffu32, 0b1011_0110, 0b0100_0001] {
            let ranks = &INNER_RANK8[imask as usize];
            for oct in 0..8u32 {
                for rest in 0..256u32 {
                    let (mut nodes, mut nears) = ([u32::MAX; 8], [f32::NAN; 8]);
                    // SAFETY: AVX2 detected above; eight entries each.
                    let n = unsafe {
                        crate::wide_avx2::push_children(
                            near,
                            100,
                            ranks,
                            oct,
                            rest,
                            nodes.as_mut_ptr(),
                            nears.as_mut_ptr(),
                        )
                    };
                    let (mut want_nodes, mut want_nears) = (vec![], vec![]);
                    let mut bits = rest;
                    while bits != 0 {
                        let slot = bits.trailing_zeros() ^ oct;
                        bits &= bits - 1;
                        want_nodes.push(100 + u32::from(ranks[slot as usize]));
                        want_nears.push(near[(slot >> 2) as usize][(slot & 3) as usize]);
                    }
                    assert_eq!(n, want_nodes.len(), "{rest:08b} {oct}");
                    assert_eq!(&nodes[..n], &want_nodes[..], "{rest:08b} {oct}");
                    assert_eq!(&nears[..n], &want_nears[..], "{rest:08b} {oct}");
                }
            }
        }
    }

    #[test]
    fn float_box_test_sets_the_quantised_tests_bits() {
        // The same bits for the same children: inner children at 24 + (slot ^ octant), the
        // primitives of hit leaves at their offsets. The two tests may disagree only for a
        // ray grazing a face (the boxes differ by under a step of f32), so over random rays
        // through a soup nearly every mask must be the same, and many must be non-zero.
        let tris = soup(600, 1.0, Vec3::ZERO, 11);
        let bvh = GpuBvh::build_with_layout(&tris, &[], BvhQuality::Fast, BvhLayout::Wide).unwrap();
        let mut s = 3u64;
        let mut r = || crate::test_rand(&mut s);
        let (mut differ, mut inner, mut leaves, mut tests) = (0, 0, 0, 0);
        for _ in 0..2000 {
            let origin = Vec3::new(r(), r(), r()) * 1.4 - 0.2;
            let dir = (Vec3::new(r(), r(), r()) - 0.5).normalize_or(Vec3::X);
            let wr = wide_ray(&Ray { origin, dir });
            let t_max = 0.2 + 2.0 * r();
            for (node, boxes) in bvh.wide_nodes.iter().zip(bvh.wide_boxes()) {
                let q = intersect_wide_node(node, &wr, 0.0, t_max);
                let f = intersect_wide_boxes(boxes, &wr, 0.0, t_max);
                tests += 1;
                differ += usize::from(q != f);
                inner += usize::from(q & 0xff00_0000 != 0);
                leaves += usize::from(q & 0x00ff_ffff != 0);
            }
        }
        assert!(differ * 1000 < tests, "{differ} of {tests} masks differ");
        // (2906 and 615 of 152,000 node tests here: most rays miss most of the 76 nodes.)
        assert!(inner > 1000 && leaves > 200, "{inner}, {leaves} of {tests}");
    }
}
