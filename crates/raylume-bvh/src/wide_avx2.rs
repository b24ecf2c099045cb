//! The CPU wide walk's node and triangle tests eight lanes at a time, in AVX registers
//! ([`GpuBvh::trace_closest_avx2`](crate::GpuBvh::trace_closest_avx2)): a node's eight child
//! boxes in one register instead of two halves, two of its triangle blocks at once
//! instead of one after the other, and its hit children pushed on the walk's stack in one go
//! ([`push_children`]) instead of a loop over them (the living room's diffuse any-hit walks
//! 13.4-13.5 -> 14.5-14.6 Mrays/s, its render ~3 % faster on the Intel dev VM, session 35).
//!
//! Every lane computes what the four-lane forms in [`wide_traverse`](crate::wide_traverse)
//! and [`intersect`](crate::intersect) compute, the same IEEE operations in the same order
//! (`vmaxps`/`vminps`/`vcmpps` with the predicates of glam's SSE methods, no fused
//! multiply-adds), so the walk visits the same nodes and finds the same hits bit for bit
//! (the crate's brute-force tests, `tests/support`'s `check_against_brute_force`, compare
//! the two walks over every test tree, and a unit test the node tests over every node).
//!
//! Everything here is `#[inline(always)]` and `unsafe`: it must run on a CPU with AVX2, and
//! it is fast only where it is inlined into a function compiled with AVX2 enabled
//! (`raylume_kernels::cpu::isa`'s x86-64-v3/v4 copies of the path); called from elsewhere it
//! computes the same hits with each intrinsic a call.

use std::arch::x86_64::*;

use glam::Vec4;

use crate::intersect::{ShearedRay, T_MISS, TriangleBlock};
use crate::traverse::Hit;
use crate::wide_traverse::{WIDE_T_FAR_SCALE, WideBoxes, WideRay};

/// [`wide_boxes_hits`](crate::wide_traverse::wide_boxes_hits) with the node's eight slots in
/// one AVX register: the hit slots' bits and their leaves' primitives ORed, the same, and
/// every slot's entry distance (lanes 0..4, 4..8), the same value (a zero's sign may
/// differ, which no comparison sees).
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
pub(crate) unsafe fn wide_boxes_hits(
    boxes: &WideBoxes,
    r: &WideRay,
    t_min: f32,
    t_max: f32,
) -> (u32, u32, [Vec4; 2]) {
    // SAFETY: the caller's CPU has AVX2; the loads read the node's own rows (eight f32s each,
    // unaligned loads) and its eight leaf words.
    unsafe {
        let o = r.origin.to_array();
        let inv = r.inv_dir.to_array();
        let rows = &boxes.planes;
        // Per axis both planes' distances, the nearer the smaller (`axis_distances`).
        let (nx, fx) = axis_distances(rows, o[0], inv[0], 0);
        let (ny, fy) = axis_distances(rows, o[1], inv[1], 1);
        let (nz, fz) = axis_distances(rows, o[2], inv[2], 2);
        let t_near = _mm256_max_ps(
            _mm256_max_ps(nx, ny),
            _mm256_max_ps(nz, _mm256_set1_ps(t_min)),
        );
        let t_far = _mm256_min_ps(
            _mm256_min_ps(fx, fy),
            _mm256_min_ps(fz, _mm256_set1_ps(t_max)),
        );
        // glam's `cmple` is `_mm_cmple_ps`: LE, ordered, signalling.
        let hit = _mm256_cmp_ps::<_CMP_LE_OS>(
            t_near,
            _mm256_mul_ps(t_far, _mm256_set1_ps(WIDE_T_FAR_SCALE)),
        );
        let bits = _mm256_movemask_ps(hit) as u32;
        let words = _mm256_loadu_si256(boxes.leaf_prims.as_ptr().cast());
        let v = _mm256_and_si256(_mm256_castps_si256(hit), words);
        let v = _mm_or_si128(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
        let v = _mm_or_si128(v, _mm_shuffle_epi32::<0b01_00_11_10>(v));
        let v = _mm_or_si128(v, _mm_shuffle_epi32::<0b10_11_00_01>(v));
        let prims = _mm_cvtsi128_si32(v) as u32;
        let near = [
            Vec4::from(_mm256_castps256_ps128(t_near)),
            Vec4::from(_mm256_extractf128_ps::<1>(t_near)),
        ];
        (bits, prims, near)
    }
}

/// The distances at which the ray meets axis `k`'s near and far planes of the eight slots:
/// `(plane - origin) * (1 / dir)` of the lower and the upper plane, the nearer the smaller
/// of the two (the four-lane form picks the row by the sign of `1 / dir` instead; both
/// give the same bits: `nearer_plane_by_the_sign_is_the_min_of_both_bit_for_bit`). Rows at
/// fixed offsets: no per-ray row index to compute, keep or reload in the walk's loop.
#[inline(always)]
unsafe fn axis_distances(rows: &[[f32; 8]; 6], o: f32, inv: f32, k: usize) -> (__m256, __m256) {
    // SAFETY: AVX (the caller's); each row is eight f32s.
    unsafe {
        let (o, i) = (_mm256_set1_ps(o), _mm256_set1_ps(inv));
        let lo = _mm256_mul_ps(_mm256_sub_ps(_mm256_loadu_ps(rows[k].as_ptr()), o), i);
        let hi = _mm256_mul_ps(_mm256_sub_ps(_mm256_loadu_ps(rows[3 + k].as_ptr()), o), i);
        (_mm256_min_ps(lo, hi), _mm256_max_ps(lo, hi))
    }
}

/// The hit inner children of a node the walk does not enter now, pushed on its stack in one
/// go, without a loop over them: `rest` holds them as bits `slot ^ oct` (the walk's order);
/// each one's node (`child_base` plus its rank among the node's inner slots, `ranks`) and
/// box entry distance (`near`, lanes by slot) are stored at `nodes[..n]` and `nears[..n]`,
/// lowest bit first, as the walk's loop pushes them (so that the highest is on top); `n`,
/// the count, is returned. Eight lanes are written: both arrays need eight entries of room.
///
/// # Safety
/// The CPU must have AVX2; `nodes` and `nears` must be valid for eight writes.
#[inline(always)]
pub(crate) unsafe fn push_children(
    near: [Vec4; 2],
    child_base: u32,
    ranks: &[u8; 8],
    oct: u32,
    rest: u32,
    nodes: *mut u32,
    nears: *mut f32,
) -> usize {
    // SAFETY: the caller's CPU has AVX2; the two eight-byte loads read `ranks` and a row of
    // `COMPRESS8`; the stores are the caller's eight entries.
    unsafe {
        // Lane j takes the j-th set bit of `rest` (ascending), the slot `bit ^ oct`.
        let order = _mm256_xor_si256(
            _mm256_cvtepu8_epi32(_mm_loadl_epi64(COMPRESS8[rest as usize].as_ptr().cast())),
            _mm256_set1_epi32(oct as i32),
        );
        // The ranks permuted, then the base added (adding first, LLVM permuted the
        // broadcast base too).
        let ranks = _mm256_cvtepu8_epi32(_mm_loadl_epi64(ranks.as_ptr().cast()));
        let children = _mm256_add_epi32(
            _mm256_set1_epi32(child_base as i32),
            _mm256_permutevar8x32_epi32(ranks, order),
        );
        let near = _mm256_set_m128(near[1].into(), near[0].into());
        _mm256_storeu_si256(nodes.cast(), children);
        _mm256_storeu_ps(nears, _mm256_permutevar8x32_ps(near, order));
    }
    rest.count_ones() as usize
}

/// `COMPRESS8[m]`: the positions of the set bits of `m`, ascending (then zeros).
static COMPRESS8: [[u8; 8]; 256] = {
    let mut t = [[0u8; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut n, mut b) = (0, 0);
        while b < 8 {
            if m >> b & 1 == 1 {
                t[m][n] = b as u8;
                n += 1;
            }
            b += 1;
        }
        m += 1;
    }
    t
};

/// [`leaf_block4`](crate::wide_traverse) for up to two of a node's triangle blocks at once:
/// the block around `prims`' highest set bit (lanes 4..8) and the block around the highest
/// bit below it (lanes 0..4; none when no bit is left), their set bits cleared from `prims`
/// and their triangles tested together. `hit` becomes what testing the first block and then
/// the second would make it: the lanes are taken highest offset first, a lane replacing `hit`
/// only if strictly closer, so of equal distances the first in that order stays (both blocks
/// are tested against the `hit.t` before either, which rules out no lane that the closer
/// of the two would not rule out). True if any of them was hit.
///
/// # Safety
/// The CPU must have AVX2; `prims` must be non-zero.
#[inline(always)]
pub(crate) unsafe fn leaf_blocks8(
    blocks: &[TriangleBlock],
    base: u32,
    block_base: u32,
    prims: &mut u32,
    sheared: &ShearedRay,
    t_min: f32,
    hit: &mut Hit,
) -> bool {
    debug_assert!(*prims != 0);
    let lo_a = (31 - prims.leading_zeros()) & !3;
    let lanes_a = (*prims >> lo_a) & 0xf;
    let rest = *prims & !(0xf << lo_a);
    // Without a bit left, the second block is the node's first with no lane live (a read
    // of a block the node has, no branch).
    let lo_b = (31 - (rest | 1).leading_zeros()) & !3;
    let lanes_b = (rest >> lo_b) & 0xf;
    *prims = rest & !(0xf << lo_b);
    let a = &blocks[(block_base + lo_a / 4) as usize];
    let b = &blocks[(block_base + lo_b / 4) as usize];
    // SAFETY: the caller's CPU has AVX2.
    unsafe {
        let [t, u, v] = triangle_blocks8(sheared, b, a, t_min, hit.t);
        // Lane j of the register is lane j of block b, lane 4 + j that of block a.
        let live_bits = _mm256_set1_epi32((lanes_b | lanes_a << 4) as i32);
        let lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let live = _mm256_cmpeq_epi32(_mm256_and_si256(live_bits, lane_bit), lane_bit);
        let t = _mm256_blendv_ps(_mm256_set1_ps(T_MISS), t, _mm256_castsi256_ps(live));
        // The smallest t in every lane (no lane is NaN: misses are T_MISS).
        let m = _mm256_min_ps(t, _mm256_permute2f128_ps::<1>(t, t));
        let m = _mm256_min_ps(m, _mm256_permute_ps::<0b01_00_11_10>(m));
        let m = _mm256_min_ps(m, _mm256_permute_ps::<0b10_11_00_01>(m));
        // The highest lane holding it: block a's before block b's, each highest first (some
        // lane holds it). The lane's hit is built whether or not it is closer, then taken by
        // `select_unpredictable` (whether two blocks hold a closer hit is a coin toss: the
        // `if` around it was ~13 % of Bitterli's Cornell box's mispredicted branches under
        // cachegrind; x86 may still compile the float select as short branches, but this
        // measured faster than that `if`, and an SSE blend slower).
        let j = 31 - (_mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t, m)) as u32).leading_zeros();
        let (mut ts, mut us, mut vs) = ([0f32; 8], [0f32; 8], [0f32; 8]);
        _mm256_storeu_ps(ts.as_mut_ptr(), t);
        _mm256_storeu_ps(us.as_mut_ptr(), u);
        _mm256_storeu_ps(vs.as_mut_ptr(), v);
        let offset = if j >= 4 { lo_a + j - 4 } else { lo_b + j };
        let j = (j & 7) as usize;
        let closer = _mm256_cvtss_f32(m) < hit.t;
        *hit = std::hint::select_unpredictable(
            closer,
            Hit {
                t: ts[j],
                prim: base + offset,
                u: us[j],
                v: vs[j],
            },
            *hit,
        );
        closer
    }
}

/// [`intersect_triangle_block`](crate::intersect::intersect_triangle_block) of two blocks at
/// once, `lo`'s triangles in lanes 0..4 and `hi`'s in 4..8: `[t, u, v]` per lane, the four-lane
/// form's values bit for bit (its operations, operands and order).
#[inline(always)]
unsafe fn triangle_blocks8(
    r: &ShearedRay,
    lo: &TriangleBlock,
    hi: &TriangleBlock,
    t_min: f32,
    t_max: f32,
) -> [__m256; 3] {
    // Each axis' byte offset of its three rows in a block (`v[3 * k + vertex]`), `k` held
    // below 3 (a `ShearedRay` from `shear_ray` has it so), so that the nine loads below are
    // a base, one of three offsets and a constant, with no bounds check to keep them apart.
    let row = |k: u32| 48 * k.min(2) as usize;
    let (kx, ky, kz) = (row(r.kx), row(r.ky), row(r.kz));
    let o = r.origin.to_array();
    let (ox, oy, oz) = (
        o[r.kx.min(2) as usize],
        o[r.ky.min(2) as usize],
        o[r.kz.min(2) as usize],
    );
    // SAFETY: the caller's CPU has AVX2; each load reads 16 bytes at `offset + 16 * vertex`
    // (at most 96 + 32) of a 144-byte block.
    unsafe {
        // Coordinate row `offset` of `vertex`, minus the origin's: hi's lanes above lo's.
        #[inline(always)]
        unsafe fn rel(
            lo: &TriangleBlock,
            hi: &TriangleBlock,
            vertex: usize,
            offset: usize,
            o: f32,
        ) -> __m256 {
            // SAFETY: AVX (the caller's); `offset + 16 * vertex + 16 <= 144` (the caller's).
            unsafe {
                let at = |b: &TriangleBlock| {
                    _mm_loadu_ps(b.v.as_ptr().cast::<u8>().add(offset + 16 * vertex).cast())
                };
                _mm256_sub_ps(_mm256_set_m128(at(hi), at(lo)), _mm256_set1_ps(o))
            }
        }
        let (a_x, a_y, a_z) = (
            rel(lo, hi, 0, kx, ox),
            rel(lo, hi, 0, ky, oy),
            rel(lo, hi, 0, kz, oz),
        );
        let (b_x, b_y, b_z) = (
            rel(lo, hi, 1, kx, ox),
            rel(lo, hi, 1, ky, oy),
            rel(lo, hi, 1, kz, oz),
        );
        let (c_x, c_y, c_z) = (
            rel(lo, hi, 2, kx, ox),
            rel(lo, hi, 2, ky, oy),
            rel(lo, hi, 2, kz, oz),
        );
        let (sx, sy, sz) = (
            _mm256_set1_ps(r.shear.x),
            _mm256_set1_ps(r.shear.y),
            _mm256_set1_ps(r.shear.z),
        );
        let (add, sub, mul) = (_mm256_add_ps, _mm256_sub_ps, _mm256_mul_ps);
        let ax = sub(a_x, mul(sx, a_z));
        let ay = sub(a_y, mul(sy, a_z));
        let bx = sub(b_x, mul(sx, b_z));
        let by = sub(b_y, mul(sy, b_z));
        let cx = sub(c_x, mul(sx, c_z));
        let cy = sub(c_y, mul(sy, c_z));
        let w0 = sub(mul(cx, by), mul(cy, bx));
        let w1 = sub(mul(ax, cy), mul(ay, cx));
        let w2 = sub(mul(bx, ay), mul(by, ax));
        let zero = _mm256_setzero_ps();
        // glam's cmpge / cmple / cmpne / cmpgt / cmplt: GE_OS, LE_OS, NEQ_UQ, GT_OS, LT_OS.
        let (and, or) = (_mm256_and_ps, _mm256_or_ps);
        #[inline(always)]
        unsafe fn ge(x: __m256) -> __m256 {
            // SAFETY: AVX (the caller's).
            unsafe { _mm256_cmp_ps::<_CMP_GE_OS>(x, _mm256_setzero_ps()) }
        }
        #[inline(always)]
        unsafe fn le(x: __m256) -> __m256 {
            // SAFETY: AVX (the caller's).
            unsafe { _mm256_cmp_ps::<_CMP_LE_OS>(x, _mm256_setzero_ps()) }
        }
        let inside = or(
            and(and(ge(w0), ge(w1)), ge(w2)),
            and(and(le(w0), le(w1)), le(w2)),
        );
        let det = add(add(w0, w1), w2);
        let az = mul(sz, a_z);
        let bz = mul(sz, b_z);
        let cz = mul(sz, c_z);
        let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
        let t = mul(add(add(mul(w0, az), mul(w1, bz)), mul(w2, cz)), inv_det);
        let hit = and(
            and(
                and(inside, _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero)),
                _mm256_cmp_ps::<_CMP_GT_OS>(t, _mm256_set1_ps(t_min)),
            ),
            _mm256_cmp_ps::<_CMP_LT_OS>(t, _mm256_set1_ps(t_max)),
        );
        [
            _mm256_blendv_ps(_mm256_set1_ps(T_MISS), t, hit),
            _mm256_blendv_ps(zero, mul(w1, inv_det), hit),
            _mm256_blendv_ps(zero, mul(w2, inv_det), hit),
        ]
    }
}
