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
//! A tree of at most [`FLAT_MAX_PRIMITIVES_AVX2`] triangles is not walked here: [`flat_hit`]
//! tests them all, eight at a time ([`flat_hit16`]: sixteen, in AVX-512 registers, for the
//! `_avx512` walks, up to [`FLAT_MAX_PRIMITIVES`]), and gives the ray back to the walk only
//! where several triangles hold the closest hit, so that the walk's order picks among them as
//! before. The sixteen-lane test takes the triangles grouped by where they lie
//! ([`FlatSet`]: the walls of a room in a lead block, each object inside it in a block of
//! its own, each block with its box) and passes over a block whose box the ray enters only
//! beyond the closest hit found so far: on Bitterli's Cornell box 1.4 blocks a closest hit
//! instead of 3, 0.45 a shadow ray instead of 2, the render 2-4 % faster (session 41). (One difference: a hit
//! whose distance lies within rounding of `t_max` may sit in a node whose box the walk leaves
//! out, and the flat test, which has no boxes, finds it: a range made to end at a hit shows it
//! (the unit tests' boundary ranges); a render's rays end at the scene's far limit or short
//! of a lamp, where it takes a blocker within rounding of that end.)
//!
//! Everything here is `#[inline(always)]` and `unsafe`: it must run on a CPU with AVX2, and
//! it is fast only where it is inlined into a function compiled with AVX2 enabled
//! (`raylume_kernels::cpu::isa`'s x86-64-v3/v4 copies of the path); called from elsewhere it
//! computes the same hits with each intrinsic a call.

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use glam::Vec4;

use crate::INVALID_INDEX;
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
        let (t_near, hit) = slab_hits(&boxes.planes, r, t_min, t_max);
        let bits = _mm256_movemask_ps(hit) as u32;
        // The leaf words ORed only where a hit slot is not an inner one (an inner slot's word
        // is 0, so the primitives are the same): most nodes the walk visits have no hit
        // leaf, and the walk's branch on whether to test leaves then waits on the mask alone,
        // not on the eight-step reduction (the living room's diffuse closest hits 3 %
        // faster in `trace_rate`, its render ~1 %: `docs/RESULTS.md`, issue 15, session 51).
        let prims = if bits & !boxes.imask & 0xff == 0 {
            0
        } else {
            let words = _mm256_loadu_si256(boxes.leaf_prims.as_ptr().cast());
            let v = _mm256_and_si256(_mm256_castps_si256(hit), words);
            let v = _mm_or_si128(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
            let v = _mm_or_si128(v, _mm_shuffle_epi32::<0b01_00_11_10>(v));
            let v = _mm_or_si128(v, _mm_shuffle_epi32::<0b10_11_00_01>(v));
            _mm_cvtsi128_si32(v) as u32
        };
        let near = [
            Vec4::from(_mm256_castps256_ps128(t_near)),
            Vec4::from(_mm256_extractf128_ps::<1>(t_near)),
        ];
        (bits, prims, near)
    }
}

/// The slab test of eight boxes (`rows`: `lo.x, lo.y, lo.z, hi.x, hi.y, hi.z`, a box a lane)
/// against the ray in `[t_min, t_max]`: where the ray enters each box, and the lanes whose box
/// it meets (`t_near <= t_far * WIDE_T_FAR_SCALE`, all bits set).
///
/// # Safety
/// The CPU must have AVX.
#[inline(always)]
unsafe fn slab_hits(rows: &[[f32; 8]; 6], r: &WideRay, t_min: f32, t_max: f32) -> (__m256, __m256) {
    // SAFETY: the caller's CPU has AVX; `axis_distances` reads the rows.
    unsafe {
        let o = r.origin.to_array();
        let inv = r.inv_dir.to_array();
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
        (t_near, hit)
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
    // Without a bit left, the second block is the first one again with no lane live (no
    // branch): the lanes wait on both blocks' loads, and the node's first block, read
    // here before, was a second cache miss to wait on where it was not the first.
    let lo_b = if rest == 0 {
        lo_a
    } else {
        (31 - rest.leading_zeros()) & !3
    };
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
        let (mut us, mut vs) = ([0f32; 8], [0f32; 8]);
        _mm256_storeu_ps(us.as_mut_ptr(), u);
        _mm256_storeu_ps(vs.as_mut_ptr(), v);
        let offset = if j >= 4 { lo_a + j - 4 } else { lo_b + j };
        let j = (j & 7) as usize;
        // The hit's distance is the minimum itself, lane j's t (j holds it: the same value;
        // a zero's sign could differ only for a `t_min` below zero), not lane j's t stored and
        // read back: the next node's box test waits on `hit.t`, and this takes the lane
        // search, the store and the reload off that chain (the living room's diffuse closest
        // hits ~2 % faster in `trace_rate`, session 48). `u`, `v` and the primitive, which no
        // test reads before the walk ends, still come from lane j.
        let t_closest = _mm256_cvtss_f32(m);
        let closer = t_closest < hit.t;
        *hit = std::hint::select_unpredictable(
            closer,
            Hit {
                t: t_closest,
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
    // SAFETY: the caller's CPU has AVX2; each load reads 16 bytes at `offset + 16 * vertex`
    // (at most 96 + 32) of a 144-byte block (`triangle_lanes8`'s offsets).
    unsafe {
        triangle_lanes8(
            r,
            |vertex, offset| {
                let at = |b: &TriangleBlock| {
                    _mm_loadu_ps(b.v.as_ptr().cast::<u8>().add(offset + 16 * vertex).cast())
                };
                _mm256_set_m128(at(hi), at(lo))
            },
            48,
            t_min,
            t_max,
        )
    }
}

/// The watertight test of eight triangles against `r`, as
/// [`intersect_triangle_block`](crate::intersect::intersect_triangle_block)'s four-lane
/// form computes it lane by lane: `row(vertex, offset)` loads the eight lanes' coordinate
/// of `vertex` on the axis whose rows begin at byte `offset` (`axis_bytes` times the axis).
#[inline(always)]
unsafe fn triangle_lanes8(
    r: &ShearedRay,
    row: impl Fn(usize, usize) -> __m256,
    axis_bytes: usize,
    t_min: f32,
    t_max: f32,
) -> [__m256; 3] {
    // Each axis' byte offset of its three rows, `k` held below 3 (a `ShearedRay` from
    // `shear_ray` has it so), so that the nine loads below are a base, one of three offsets
    // and a constant, with no bounds check to keep them apart.
    let axis = |k: u32| axis_bytes * k.min(2) as usize;
    let (kx, ky, kz) = (axis(r.kx), axis(r.ky), axis(r.kz));
    let o = r.origin.to_array();
    let (ox, oy, oz) = (
        o[r.kx.min(2) as usize],
        o[r.ky.min(2) as usize],
        o[r.kz.min(2) as usize],
    );
    // SAFETY: the caller's CPU has AVX2; `row` reads what its caller allows.
    unsafe {
        // Coordinate row `offset` of `vertex`, minus the origin's.
        let rel = |vertex: usize, offset: usize, o: f32| {
            _mm256_sub_ps(row(vertex, offset), _mm256_set1_ps(o))
        };
        let (a_x, a_y, a_z) = (rel(0, kx, ox), rel(0, ky, oy), rel(0, kz, oz));
        let (b_x, b_y, b_z) = (rel(1, kx, ox), rel(1, ky, oy), rel(1, kz, oz));
        let (c_x, c_y, c_z) = (rel(2, kx, ox), rel(2, ky, oy), rel(2, kz, oz));
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

/// The most primitives a tree may hold for the CPU's AVX-512 walks to test all of them
/// against every ray instead of walking the tree (`flat_hit16`; only trees of triangles).
/// A walk goes node after node, each node's test waiting on the one before; these tests have
/// no chain from one group of triangles to the next, so they run as fast as the core's vector
/// units allow. On the Intel dev VM (`trace_rate`, two threads, against the walk), Bitterli's
/// Cornell box (36 triangles): closest hits +18-22 %, any hits +52 % (diffuse rays) and 2.1x
/// (primary); with 64 triangles +18-32 % and +60-110 %; with 96 the primary rays' closest
/// hits 5 % slower, with 128 16 % (`docs/RESULTS.md`, issue 15).
pub const FLAT_MAX_PRIMITIVES: usize = 64;

/// [`FLAT_MAX_PRIMITIVES`] for the AVX2 walks (`flat_hit`, eight lanes at a time): with 36
/// triangles closest hits -5 % (primary rays) to +2 % (diffuse), any hits +27-80 %; with 64
/// closest hits 3-35 % slower.
pub const FLAT_MAX_PRIMITIVES_AVX2: usize = 40;

/// Sixteen triangles' vertices for [`flat_hit16`] (and, a half at a time, [`flat_hit`]), as
/// [`TriangleBlock`] holds four: `v[3 * axis + vertex]` holds coordinate `axis` of vertex
/// `vertex` (a, b, c) of the sixteen lanes, one aligned load each.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct FlatBlock {
    pub v: [[f32; 16]; 9],
}

const _: () = assert!(size_of::<FlatBlock>() == 576);

/// The primitives of a tree of at most [`FLAT_MAX_PRIMITIVES`] triangles sixteen a block,
/// primitive `16 i + j` in lane `j` of block `i` (zeros past the last: a degenerate
/// triangle, never hit); empty for a larger tree or one with a sphere.
pub(crate) fn flat_blocks(primitives: &[crate::Primitive]) -> Vec<FlatBlock> {
    if primitives.len() > FLAT_MAX_PRIMITIVES
        || primitives
            .iter()
            .any(|p| p.b[3].to_bits() == crate::PRIM_SPHERE)
    {
        return Vec::new();
    }
    FlatSet::new(primitives, &in_order(primitives.len()), false).blocks
}

/// Primitives `0..n` sixteen a group, in order (at most [`FLAT_MAX_PRIMITIVES`]: at most
/// four groups).
fn in_order(n: usize) -> Vec<Vec<u32>> {
    (0..n as u32)
        .collect::<Vec<_>>()
        .chunks(16)
        .map(<[u32]>::to_vec)
        .collect()
}

/// Blocks of a flat set at most: [`FlatSet::boxes`]' lanes.
pub(crate) const FLAT_SET_MAX_BLOCKS: usize = 8;

/// Relative margin by which [`flat_hit16`] keeps a block whose box begins beyond the closest
/// hit found so far: it passes over a block only when the box's entry distance exceeds that
/// hit's `t` times `1 + 2^-18` (the wide walk's [`WIDE_T_FAR_SCALE`]: its boxes hold their
/// triangles, padded, and the distances of box and triangle are each within a few units of
/// roundoff of the true ones, so a block passed over holds no triangle at or before the hit).
const FLAT_T_SCALE: f32 = WIDE_T_FAR_SCALE;

/// The triangles of a flat tree for [`flat_hit16`]: sixteen a block as [`flat_blocks`]
/// lays them out, but grouped by where they lie, each block with its box, so that a ray
/// tests only the blocks whose box it enters before the closest hit found so far. The
/// hull's faces ([`hull_faces`]: a room's walls, which every ray from inside ends on) come
/// first, in one block with what fits beside them (the block's box is the scene's, entered
/// by every ray); the other triangles follow in groups split by their boxes' areas
/// ([`flat_groups`]). Lane `j` of block `i` is primitive `ids[i][j]` (`INVALID_INDEX` for
/// a padding lane, whose zero triangle is never hit).
#[derive(Clone, Debug, Default)]
pub(crate) struct FlatSet {
    pub blocks: Vec<FlatBlock>,
    pub ids: Vec<[u32; 16]>,
    /// Each block's box, padded (lane = block; lanes past the last are empty): rows
    /// `lo.x, lo.y, lo.z, hi.x, hi.y, hi.z`, as [`WideBoxes::planes`].
    pub boxes: [[f32; 8]; 6],
    /// Whether block 0 is tested first without its box (the hull's faces, whose box is the
    /// scene's: every ray that can hit anything enters it).
    pub lead: bool,
}

impl FlatSet {
    pub(crate) fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// The set of `groups` of `primitives`' indices (each at most 16, at most
    /// [`FLAT_SET_MAX_BLOCKS`] groups), a block each, in that order.
    fn new(primitives: &[crate::Primitive], groups: &[Vec<u32>], lead: bool) -> FlatSet {
        debug_assert!(groups.len() <= FLAT_SET_MAX_BLOCKS);
        let zero = FlatBlock { v: [[0.0; 16]; 9] };
        let mut set = FlatSet {
            blocks: vec![zero; groups.len()],
            ids: vec![[INVALID_INDEX; 16]; groups.len()],
            boxes: [
                [f32::MAX; 8],
                [f32::MAX; 8],
                [f32::MAX; 8],
                [-f32::MAX; 8],
                [-f32::MAX; 8],
                [-f32::MAX; 8],
            ],
            lead: lead && !groups.is_empty(),
        };
        for (i, group) in groups.iter().enumerate() {
            debug_assert!(group.len() <= 16);
            let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(-f32::MAX));
            for (j, &id) in group.iter().enumerate() {
                let p = &primitives[id as usize];
                set.ids[i][j] = id;
                for (vertex, v) in [&p.a, &p.b, &p.c].into_iter().enumerate() {
                    let v3 = glam::Vec3::from_slice(&v[..3]);
                    (lo, hi) = (lo.min(v3), hi.max(v3));
                    for (axis, &x) in v[..3].iter().enumerate() {
                        set.blocks[i].v[3 * axis + vertex][j] = x;
                    }
                }
            }
            // Padded by 2^-16 of the box's largest coordinate or extent on each axis: a box
            // flat on an axis (a wall) keeps a thickness a ray's rounding cannot step over.
            let pad = (lo.abs().max(hi.abs()).max(hi - lo)) * (1.0 / 65_536.0) + f32::MIN_POSITIVE;
            let (lo, hi) = (lo - pad, hi + pad);
            for k in 0..3 {
                set.boxes[k][i] = lo[k];
                set.boxes[3 + k][i] = hi[k];
            }
        }
        set
    }
}

/// A box's half area (`dx dy + dy dz + dz dx`), the measure [`flat_groups`] splits by.
fn half_area(lo: glam::Vec3, hi: glam::Vec3) -> f32 {
    let d = (hi - lo).max(glam::Vec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// The box of `primitives[ids]`.
fn ids_box(primitives: &[crate::Primitive], ids: &[u32]) -> (glam::Vec3, glam::Vec3) {
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(-f32::MAX));
    for &id in ids {
        let p = &primitives[id as usize];
        for v in [&p.a, &p.b, &p.c] {
            let v = glam::Vec3::from_slice(&v[..3]);
            (lo, hi) = (lo.min(v), hi.max(v));
        }
    }
    (lo, hi)
}

/// `ids` split in two by centroid along the axis and at the place where the parts' areas,
/// each times its blocks of 16, sum least, and that sum; `None` for fewer than two.
fn best_split(primitives: &[crate::Primitive], ids: &[u32]) -> Option<(f32, Vec<u32>, Vec<u32>)> {
    if ids.len() < 2 {
        return None;
    }
    let centroid = |id: u32| {
        let p = &primitives[id as usize];
        glam::Vec3::from_slice(&p.a[..3])
            + glam::Vec3::from_slice(&p.b[..3])
            + glam::Vec3::from_slice(&p.c[..3])
    };
    let blocks = |n: usize| n.div_ceil(16) as f32;
    let mut best: Option<(f32, Vec<u32>, Vec<u32>)> = None;
    for axis in 0..3 {
        let mut sorted = ids.to_vec();
        sorted.sort_by(|&a, &b| {
            centroid(a)[axis]
                .total_cmp(&centroid(b)[axis])
                .then(a.cmp(&b))
        });
        for k in 1..sorted.len() {
            let (l, r) = sorted.split_at(k);
            let (ll, lh) = ids_box(primitives, l);
            let (rl, rh) = ids_box(primitives, r);
            let cost = half_area(ll, lh) * blocks(l.len()) + half_area(rl, rh) * blocks(r.len());
            if best.as_ref().is_none_or(|b| cost < b.0) {
                best = Some((cost, l.to_vec(), r.to_vec()));
            }
        }
    }
    best
}

/// `ids` in groups of at most 16 that lie apart: a group of more than 16 is split where
/// [`best_split`] says, and a smaller one where that takes its area (times its blocks) down
/// by a third or more, while there are fewer than `max_groups`; `None` if the groups of at
/// most 16 number more than `max_groups`.
fn flat_groups(
    primitives: &[crate::Primitive],
    ids: Vec<u32>,
    max_groups: usize,
) -> Option<Vec<Vec<u32>>> {
    let mut groups = vec![ids];
    groups.retain(|g| !g.is_empty());
    // The splits a group of more than 16 needs.
    while let Some(i) = groups.iter().position(|g| g.len() > 16) {
        let g = groups.swap_remove(i);
        let (_, l, r) = best_split(primitives, &g).expect("more than 16");
        groups.push(l);
        groups.push(r);
    }
    if groups.len() > max_groups {
        return None;
    }
    // Then the splits that pay, the best first.
    while groups.len() < max_groups {
        let gain = |g: &Vec<u32>| {
            let (lo, hi) = ids_box(primitives, g);
            let before = half_area(lo, hi) * g.len().div_ceil(16) as f32;
            best_split(primitives, g)
                .map(|(after, l, r)| (after / before.max(f32::MIN_POSITIVE), l, r))
        };
        let best = groups
            .iter()
            .enumerate()
            .filter_map(|(i, g)| gain(g).map(|x| (i, x)))
            .min_by(|a, b| a.1.0.total_cmp(&b.1.0));
        match best {
            Some((i, (ratio, l, r))) if ratio <= 2.0 / 3.0 => {
                groups[i] = l;
                groups.push(r);
            }
            _ => break,
        }
    }
    Some(groups)
}

/// The [`FlatSet`]s of a flat tree's triangles: all of them, for the closest and any-hit
/// tests, and those that are not [`hull_faces`], for the any-hit test of a segment between
/// two points of the hull ([`flat_between_blocks`]' triangles). Both empty for a tree of
/// more than [`FLAT_MAX_PRIMITIVES`] primitives or one with a sphere. Where the groups would
/// number more than [`FLAT_SET_MAX_BLOCKS`], the blocks of [`flat_blocks`]' order instead.
pub(crate) fn flat_sets(primitives: &[crate::Primitive]) -> (FlatSet, FlatSet) {
    if primitives.len() > FLAT_MAX_PRIMITIVES
        || primitives
            .iter()
            .any(|p| p.b[3].to_bits() == crate::PRIM_SPHERE)
    {
        return (FlatSet::default(), FlatSet::default());
    }
    let faces = hull_faces(primitives);
    let (hull, inner): (Vec<u32>, Vec<u32>) =
        (0..primitives.len() as u32).partition(|&i| faces[i as usize]);
    let mut all: Vec<Vec<u32>> = hull.chunks(16).map(<[u32]>::to_vec).collect();
    let mut lead = !hull.is_empty();
    let inner_groups = flat_groups(primitives, inner.clone(), FLAT_SET_MAX_BLOCKS - all.len());
    let chunks = |ids: &[u32]| ids.chunks(16).map(<[u32]>::to_vec).collect::<Vec<_>>();
    let between = inner_groups.clone().unwrap_or_else(|| chunks(&inner));
    match inner_groups {
        Some(mut rest) => {
            // The last hull block's spare lanes take whole groups, the largest boxes first
            // (tested with the walls, whose box every ray enters, instead of on their own).
            if let Some(last) = all.last_mut() {
                let area = |g: &Vec<u32>| {
                    let (lo, hi) = ids_box(primitives, g);
                    half_area(lo, hi)
                };
                rest.sort_by(|a, b| area(b).total_cmp(&area(a)));
                rest.retain(|g| {
                    if last.len() + g.len() <= 16 {
                        last.extend_from_slice(g);
                        false
                    } else {
                        true
                    }
                });
            }
            all.extend(rest);
        }
        None => {
            all = in_order(primitives.len());
            lead = false;
        }
    }
    (
        FlatSet::new(primitives, &all, lead),
        FlatSet::new(primitives, &between, false),
    )
}

/// Which of `primitives` are faces of their convex hull: triangles with every vertex of every
/// primitive on one side of their plane or on it (the Cornell box's walls and the boxes'
/// bottoms on its floor: 14 of its 36). A segment between two points of the hull (a shadow
/// ray from a surface toward a point of a lamp) meets such a face's plane only at an end, so
/// the face cannot lie between them ([`flat_between_blocks`]). Decided in `f64`: the
/// vertices' differences and the normal's products are exact there, the signed distances
/// within 1e-16 of their size (a vertex nearer its plane than that counts on the side its
/// rounding gives, far below the `f32` walk's own rounding); a degenerate triangle or a
/// sphere is no face.
pub(crate) fn hull_faces(primitives: &[crate::Primitive]) -> Vec<bool> {
    let vertices: Vec<glam::DVec3> = primitives
        .iter()
        .flat_map(|p| [p.a, p.b, p.c])
        .map(|v| glam::DVec3::new(v[0].into(), v[1].into(), v[2].into()))
        .collect();
    primitives
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if p.b[3].to_bits() == crate::PRIM_SPHERE {
                return false;
            }
            let [a, b, c] = [0, 1, 2].map(|k| vertices[3 * i + k]);
            let n = (b - a).cross(c - a);
            if n == glam::DVec3::ZERO || !n.is_finite() {
                return false;
            }
            let side = |v: &glam::DVec3| n.dot(*v - a);
            vertices.iter().all(|v| side(v) >= 0.0) || vertices.iter().all(|v| side(v) <= 0.0)
        })
        .collect()
}

/// The [`flat_blocks`] of a flat tree's triangles that are not [`hull_faces`], and how many
/// there are: what a segment between two points of the hull may meet
/// ([`GpuBvh::trace_any_between_avx2`](crate::GpuBvh::trace_any_between_avx2); the AVX-512 test takes
/// [`flat_sets`]'). Empty,
/// with the tree's count, for a tree whose `flat` blocks ([`flat_blocks`]) are empty.
pub(crate) fn flat_between_blocks(
    primitives: &[crate::Primitive],
    flat: &[FlatBlock],
) -> (Vec<FlatBlock>, usize) {
    if flat.is_empty() {
        return (Vec::new(), primitives.len());
    }
    let faces = hull_faces(primitives);
    let inner: Vec<crate::Primitive> = primitives
        .iter()
        .zip(&faces)
        .filter(|&(_, &face)| !face)
        .map(|(p, _)| *p)
        .collect();
    let count = inner.len();
    (flat_blocks(&inner), count)
}

/// The hit in lane `j` of a group of `N` lanes (a power of two) whose first primitive is
/// `base`: its `t`, `u` and `v` from the group's lanes stored side by side.
#[inline(always)]
fn lane_hit<const N: usize>(t: &[f32; N], u: &[f32; N], v: &[f32; N], j: u32, base: usize) -> Hit {
    let j = j as usize & (N - 1);
    Hit {
        t: t[j],
        prim: (base + j) as u32,
        u: u[j],
        v: v[j],
    }
}

/// [`lane_hit`] of eight lanes in AVX registers. (A function, not a closure: the closure it
/// was compiled out of line, each intrinsic in it a call.)
///
/// # Safety
/// The CPU must have AVX.
#[inline(always)]
unsafe fn lane_hit8(t: __m256, u: __m256, v: __m256, j: u32, base: usize) -> Hit {
    let (mut ts, mut us, mut vs) = ([0f32; 8], [0f32; 8], [0f32; 8]);
    // SAFETY: the caller's CPU has AVX; each store writes eight f32s to its array.
    unsafe {
        _mm256_storeu_ps(ts.as_mut_ptr(), t);
        _mm256_storeu_ps(us.as_mut_ptr(), u);
        _mm256_storeu_ps(vs.as_mut_ptr(), v);
    }
    lane_hit(&ts, &us, &vs, j, base)
}

/// A flat test's miss, as the walk returns it.
#[inline(always)]
fn flat_miss(t_max: f32) -> Hit {
    Hit {
        t: t_max,
        prim: INVALID_INDEX,
        u: 0.0,
        v: 0.0,
    }
}

/// The walk's hit found without the tree: the first `count` primitives of `blocks`
/// ([`flat_blocks`]) tested eight at a time ([`triangle_lanes8`], the walk's own triangle
/// test), the closest kept. The walk's hit is the least `t` of all in `(t_min, t_max)` (its
/// box tests are conservative), so where one triangle alone holds the least `t` this is the
/// walk's hit bit for bit; where several do (a shared edge, coincident faces, a pre-split
/// triangle's copies) the walk keeps the first it meets, which only the walk knows: `None`,
/// walk it. With `any_hit` the first group with a hit answers. A miss is the walk's:
/// `t_max`, `INVALID_INDEX`.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
pub(crate) unsafe fn flat_hit(
    blocks: &[FlatBlock],
    count: usize,
    sheared: &ShearedRay,
    t_min: f32,
    t_max: f32,
    any_hit: bool,
) -> Option<Hit> {
    const GROUPS: usize = FLAT_MAX_PRIMITIVES / 8;
    let groups = count.div_ceil(8).min(2 * blocks.len()).min(GROUPS);
    // SAFETY: the caller's CPU has AVX2; each group reads its block's rows (`64 * row + 32 *
    // half`, 32 bytes, aligned); the arrays' entries below `groups` are written before they
    // are read.
    unsafe {
        let miss = _mm256_set1_ps(T_MISS);
        let mut ts = [MaybeUninit::<__m256>::uninit(); GROUPS];
        let mut us = [MaybeUninit::<__m256>::uninit(); GROUPS];
        let mut vs = [MaybeUninit::<__m256>::uninit(); GROUPS];
        let mut least = miss;
        for g in 0..groups {
            let rows = blocks[g / 2].v.as_ptr().cast::<u8>().add(32 * (g % 2));
            // Row `3 * axis + vertex` at byte `192 * axis + 64 * vertex`.
            let row = |vertex: usize, offset: usize| {
                _mm256_load_ps(rows.add(offset + 64 * vertex).cast())
            };
            let [t, u, v] = triangle_lanes8(sheared, row, 192, t_min, t_max);
            if any_hit {
                let hits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(t, miss)) as u32;
                if hits != 0 {
                    return Some(lane_hit8(t, u, v, hits.trailing_zeros(), 8 * g));
                }
                continue;
            }
            ts[g].write(t);
            us[g].write(u);
            vs[g].write(v);
            least = _mm256_min_ps(least, t);
        }
        // The least t in every lane.
        let m = _mm256_min_ps(least, _mm256_permute2f128_ps::<1>(least, least));
        let m = _mm256_min_ps(m, _mm256_permute_ps::<0b01_00_11_10>(m));
        let m = _mm256_min_ps(m, _mm256_permute_ps::<0b10_11_00_01>(m));
        if any_hit || _mm256_cvtss_f32(m) == T_MISS {
            return Some(flat_miss(t_max));
        }
        // Which lanes hold it: one, the hit; more, a tie only the walk's order settles.
        let (mut n, mut at) = (0, 0);
        for (g, t) in ts[..groups].iter().enumerate() {
            let bits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t.assume_init(), m)) as u32;
            n += bits.count_ones();
            if bits != 0 {
                at = g;
            }
        }
        if n != 1 {
            return None;
        }
        let t = ts[at].assume_init();
        let j = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t, m)) as u32;
        Some(lane_hit8(
            t,
            us[at].assume_init(),
            vs[at].assume_init(),
            j.trailing_zeros(),
            8 * at,
        ))
    }
}

/// [`flat_hit`] sixteen lanes at a time in AVX-512 registers, over a [`FlatSet`]: the same
/// hits. The triangle test is [`triangle_lanes8`]'s, lane for lane (the same values; see
/// [`triangle_lanes16`] for the predicates it computes otherwise); a hit's `u` and `v` are
/// computed for the one lane kept. A block is tested only if the ray enters its box within
/// `(t_min, t_max)` and, for the closest hit, before the closest hit found in the blocks
/// before it (times [`FLAT_T_SCALE`]): a block passed over holds no triangle at or before
/// the hit, so the least `t`, and whether several triangles hold it, are those of all.
/// `ray` is the walk's [`WideRay`] of the ray `r` is sheared from.
///
/// # Safety
/// The CPU must have AVX-512 F (and AVX2).
#[inline(always)]
pub(crate) unsafe fn flat_hit16(
    set: &FlatSet,
    ray: &WideRay,
    r: &ShearedRay,
    t_min: f32,
    t_max: f32,
    any_hit: bool,
) -> Option<Hit> {
    debug_assert!(t_max <= crate::T_MAX_LIMIT, "a finite t_max: {t_max}");
    let blocks = &set.blocks[..set.blocks.len().min(FLAT_SET_MAX_BLOCKS)];
    // SAFETY: the caller's CPU has AVX-512 F.
    unsafe {
        let mut kept = Kept16::new();
        // The lead block (the walls, whose box is the scene's), without its box.
        let start = usize::from(set.lead);
        if set.lead {
            let l = triangle_lanes16(&blocks[0], r, t_min, t_max);
            if any_hit && l.hit != 0 {
                return Some(lane_hit16(set, &l, u32::from(l.hit).trailing_zeros(), 0));
            }
            kept.keep(&l, &set.ids[0]);
        }
        // Where the ray enters each block's box, and which boxes it meets in the range.
        let (t_near, met) = slab_hits(&set.boxes, ray, t_min, t_max);
        let met = _mm256_movemask_ps(met) as u32;
        let mut near = [0f32; 8];
        _mm256_storeu_ps(near.as_mut_ptr(), t_near);
        for (i, block) in blocks.iter().enumerate().skip(start) {
            // Passed over if some lane's hit so far lies before the box (by the margin).
            let before = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(
                _mm512_mul_ps(kept.t, _mm512_set1_ps(FLAT_T_SCALE)),
                _mm512_set1_ps(near[i]),
            );
            if met & (1 << i) == 0 || before != 0 {
                continue;
            }
            let l = triangle_lanes16(block, r, t_min, t_max);
            if any_hit {
                if l.hit != 0 {
                    return Some(lane_hit16(set, &l, u32::from(l.hit).trailing_zeros(), i));
                }
                continue;
            }
            kept.keep(&l, &set.ids[i]);
        }
        let best = _mm512_reduce_min_ps(kept.t);
        if any_hit || best == T_MISS {
            return Some(flat_miss(t_max));
        }
        // Which lanes hold it: one, held by one block, the hit; more, a tie only the walk's
        // order settles.
        let lanes = _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(kept.t, _mm512_set1_ps(best));
        if lanes.count_ones() != 1 || lanes & kept.tie != 0 {
            return None;
        }
        // Its values taken from the registers by permutes (written out: a closure calling
        // intrinsics is compiled out of line).
        let at = _mm512_set1_epi32(lanes.trailing_zeros() as i32);
        let inv = _mm512_cvtss_f32(_mm512_permutexvar_ps(at, kept.inv_det));
        let id = _mm512_castsi512_si128(_mm512_permutexvar_epi32(at, kept.id));
        Some(Hit {
            t: _mm512_cvtss_f32(_mm512_permutexvar_ps(at, kept.t)),
            prim: _mm_cvtsi128_si32(id) as u32,
            u: _mm512_cvtss_f32(_mm512_permutexvar_ps(at, kept.w1)) * inv,
            v: _mm512_cvtss_f32(_mm512_permutexvar_ps(at, kept.w2)) * inv,
        })
    }
}

/// What [`flat_hit16`] keeps of the blocks it tested, lane by lane: the least hit `t` of
/// that lane over the blocks (`T_MISS` for none), the edge functions, `1 / det` and the
/// primitive of the block that holds it, and whether another block's hit in the lane ties
/// it (`tie`).
struct Kept16 {
    t: __m512,
    w1: __m512,
    w2: __m512,
    inv_det: __m512,
    id: __m512i,
    tie: __mmask16,
}

impl Kept16 {
    /// Nothing kept.
    ///
    /// # Safety
    /// The CPU must have AVX-512 F.
    #[inline(always)]
    unsafe fn new() -> Kept16 {
        // SAFETY: the caller's CPU has AVX-512 F.
        unsafe {
            let zero = _mm512_setzero_ps();
            Kept16 {
                t: _mm512_set1_ps(T_MISS),
                w1: zero,
                w2: zero,
                inv_det: zero,
                id: _mm512_setzero_si512(),
                tie: 0,
            }
        }
    }

    /// A block's lanes `l` (primitives `ids`) kept where they hit before what is kept, a tie
    /// noted where they hit at it.
    ///
    /// # Safety
    /// The CPU must have AVX-512 F.
    #[inline(always)]
    unsafe fn keep(&mut self, l: &Lanes16, ids: &[u32; 16]) {
        // SAFETY: the caller's CPU has AVX-512 F; the load reads the sixteen ids.
        unsafe {
            let nearer = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(l.hit, l.t, self.t);
            let at = _mm512_mask_cmp_ps_mask::<_CMP_EQ_OQ>(l.hit, l.t, self.t);
            self.tie = (self.tie & !nearer) | at;
            self.t = _mm512_mask_mov_ps(self.t, nearer, l.t);
            self.w1 = _mm512_mask_mov_ps(self.w1, nearer, l.w1);
            self.w2 = _mm512_mask_mov_ps(self.w2, nearer, l.w2);
            self.inv_det = _mm512_mask_mov_ps(self.inv_det, nearer, l.inv_det);
            let ids = _mm512_loadu_si512(ids.as_ptr().cast());
            self.id = _mm512_mask_mov_epi32(self.id, nearer, ids);
        }
    }
}

/// The hit in lane `j` of block `i` of `set`, tested as `l`: `u` and `v` as
/// `triangle_lanes8` computes them (the same product, one lane), each value taken from its
/// register by a permute, not stored and read back. (A function, not a closure: closures
/// calling intrinsics were compiled out of line, each intrinsic a call.)
///
/// # Safety
/// The CPU must have AVX-512 F.
#[inline(always)]
unsafe fn lane_hit16(set: &FlatSet, l: &Lanes16, j: u32, i: usize) -> Hit {
    // SAFETY: the caller's CPU has AVX-512 F.
    unsafe {
        let at = _mm512_set1_epi32((j & 15) as i32);
        let inv = _mm512_cvtss_f32(_mm512_permutexvar_ps(at, l.inv_det));
        Hit {
            t: _mm512_cvtss_f32(_mm512_permutexvar_ps(at, l.t)),
            prim: set.ids[i][(j & 15) as usize],
            u: _mm512_cvtss_f32(_mm512_permutexvar_ps(at, l.w1)) * inv,
            v: _mm512_cvtss_f32(_mm512_permutexvar_ps(at, l.w2)) * inv,
        }
    }
}

/// [`triangle_lanes16`]'s results: `t` (any value where missed), the edge functions `w1`,
/// `w2` and `1 / det` (a hit's `u` is `w1 * inv_det`, its `v` `w2 * inv_det`) and the hit
/// lanes.
#[derive(Clone, Copy)]
struct Lanes16 {
    t: __m512,
    w1: __m512,
    w2: __m512,
    inv_det: __m512,
    hit: __mmask16,
}

/// The watertight test of a [`FlatBlock`]'s sixteen triangles against `r`, lane for lane as
/// [`triangle_lanes8`]: the same operations, operands and order for every value, and the
/// same hits, which it finds with fewer instructions (`t_max` must be finite, as the walks'
/// `min(t_max, T_MAX_LIMIT)`):
/// - inside: the least of `w0, w1, w2` at least 0 or the greatest at most 0, which is all
///   three `>= 0` or all `<= 0` unless one is NaN; then `det` and `t` are NaN, and `t > t_min`
///   is false in both forms;
/// - `det != 0` is not tested: a zero `det` makes `t` infinite or NaN, never inside the
///   finite `(t_min, t_max)`;
/// - the comparisons of `t` are masked by the ones before (no separate ANDs), and `u`, `v`
///   are left to the lane kept ([`Lanes16`]).
///
/// # Safety
/// The CPU must have AVX-512 F.
#[inline(always)]
unsafe fn triangle_lanes16(block: &FlatBlock, r: &ShearedRay, t_min: f32, t_max: f32) -> Lanes16 {
    // Each axis' byte offset of its three rows, `k` held below 3 (as `triangle_lanes8`).
    let axis = |k: u32| 192 * k.min(2) as usize;
    let (kx, ky, kz) = (axis(r.kx), axis(r.ky), axis(r.kz));
    let o = r.origin.to_array();
    // SAFETY: the caller's CPU has AVX-512 F; each load reads a row of the block (`64 * row`,
    // 64 bytes, aligned).
    unsafe {
        let zero = _mm512_setzero_ps();
        let (ox, oy, oz) = (
            _mm512_set1_ps(o[r.kx.min(2) as usize]),
            _mm512_set1_ps(o[r.ky.min(2) as usize]),
            _mm512_set1_ps(o[r.kz.min(2) as usize]),
        );
        let (sx, sy, sz) = (
            _mm512_set1_ps(r.shear.x),
            _mm512_set1_ps(r.shear.y),
            _mm512_set1_ps(r.shear.z),
        );
        let (lo, hi) = (_mm512_set1_ps(t_min), _mm512_set1_ps(t_max));
        let rows = block.v.as_ptr().cast::<u8>();
        let row =
            |vertex: usize, offset: usize| _mm512_load_ps(rows.add(offset + 64 * vertex).cast());
        let (add, sub, mul) = (_mm512_add_ps, _mm512_sub_ps, _mm512_mul_ps);
        let (a_x, a_y, a_z) = (
            sub(row(0, kx), ox),
            sub(row(0, ky), oy),
            sub(row(0, kz), oz),
        );
        let (b_x, b_y, b_z) = (
            sub(row(1, kx), ox),
            sub(row(1, ky), oy),
            sub(row(1, kz), oz),
        );
        let (c_x, c_y, c_z) = (
            sub(row(2, kx), ox),
            sub(row(2, ky), oy),
            sub(row(2, kz), oz),
        );
        let ax = sub(a_x, mul(sx, a_z));
        let ay = sub(a_y, mul(sy, a_z));
        let bx = sub(b_x, mul(sx, b_z));
        let by = sub(b_y, mul(sy, b_z));
        let cx = sub(c_x, mul(sx, c_z));
        let cy = sub(c_y, mul(sy, c_z));
        let w0 = sub(mul(cx, by), mul(cy, bx));
        let w1 = sub(mul(ax, cy), mul(ay, cx));
        let w2 = sub(mul(bx, ay), mul(by, ax));
        // glam's cmpge / cmple / cmpgt / cmplt: GE_OS, LE_OS, GT_OS, LT_OS.
        let least = _mm512_min_ps(_mm512_min_ps(w0, w1), w2);
        let most = _mm512_max_ps(_mm512_max_ps(w0, w1), w2);
        let inside = _mm512_cmp_ps_mask::<_CMP_GE_OS>(least, zero)
            | _mm512_cmp_ps_mask::<_CMP_LE_OS>(most, zero);
        let det = add(add(w0, w1), w2);
        let az = mul(sz, a_z);
        let bz = mul(sz, b_z);
        let cz = mul(sz, c_z);
        let inv_det = _mm512_div_ps(_mm512_set1_ps(1.0), det);
        let t = mul(add(add(mul(w0, az), mul(w1, bz)), mul(w2, cz)), inv_det);
        let hit = _mm512_mask_cmp_ps_mask::<_CMP_GT_OS>(inside, t, lo);
        let hit = _mm512_mask_cmp_ps_mask::<_CMP_LT_OS>(hit, t, hi);
        Lanes16 {
            t,
            w1,
            w2,
            inv_det,
            hit,
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use raylume_scene::{Sphere, Triangle};

    use super::*;
    use crate::{BvhLayout, BvhQuality, GpuBvh, Ray};

    /// `n` random triangles in the unit cube, then `copies` of the first ones again (faces
    /// that coincide exactly: ties the walk's order settles), and a 2 x 2 quad grid whose
    /// triangles share edges and vertices.
    fn scene(n: usize, copies: usize, seed: u64) -> Vec<Triangle> {
        let mut state = seed;
        let mut r = || crate::test_rand(&mut state);
        let mut tris: Vec<Triangle> = (0..n)
            .map(|_| {
                let c = Vec3::new(r(), r(), r());
                let mut v = || c + (Vec3::new(r(), r(), r()) - 0.5) * 0.4;
                Triangle::flat([v(), v(), v()], 0)
            })
            .collect();
        tris.extend_from_within(..copies);
        for (i, j) in [(0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5)] {
            let p = |x: f32, z: f32| Vec3::new(i + x, 0.5, j + z);
            tris.push(Triangle::flat([p(0.0, 0.0), p(0.5, 0.0), p(0.5, 0.5)], 0));
            tris.push(Triangle::flat([p(0.0, 0.0), p(0.5, 0.5), p(0.0, 0.5)], 0));
        }
        tris
    }

    /// Rays from random points towards random points, towards the triangles' vertices and
    /// edge midpoints (where neighbours tie), and along the axes.
    fn rays(tris: &[Triangle], n: usize, seed: u64) -> Vec<(Ray, f32, f32)> {
        let mut state = seed;
        let mut r = || crate::test_rand(&mut state);
        (0..n)
            .map(|i| {
                let mut origin = Vec3::new(r(), r(), r()) * 2.0 - 0.5;
                let tri = &tris[(r() * tris.len() as f32) as usize % tris.len()];
                let [a, b, c] = tri.positions;
                let target = match i % 5 {
                    0 => Vec3::new(r(), r(), r()),
                    1 => [a, b, c][i / 5 % 3],
                    2 => (a + b) * 0.5,
                    3 => origin + Vec3::Y * if r() < 0.5 { 1.0 } else { -1.0 },
                    // In the triangle's plane (a zero or nearly zero determinant), at a
                    // vertex or through the triangle.
                    _ => {
                        origin = a + (b - a) * (1.0 + r()) - (c - a) * r();
                        if r() < 0.5 { c } else { (a + c) * 0.5 }
                    }
                };
                let (t_min, t_max) = if i % 7 == 0 {
                    (0.3, 0.8)
                } else {
                    (1e-4, f32::MAX)
                };
                (Ray::new(origin, target - origin), t_min, t_max)
            })
            .collect()
    }

    fn bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
        h.map(|h| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
    }

    /// `set` holds each primitive `wanted` once and no other, each in its block's box, at
    /// most 16 a block and `FLAT_SET_MAX_BLOCKS` blocks.
    fn check_set(set: &FlatSet, primitives: &[crate::Primitive], wanted: impl Fn(usize) -> bool) {
        assert!(set.blocks.len() <= FLAT_SET_MAX_BLOCKS);
        assert_eq!(set.ids.len(), set.blocks.len());
        let mut seen = vec![0; primitives.len()];
        for (i, (ids, block)) in set.ids.iter().zip(&set.blocks).enumerate() {
            for (j, &id) in ids.iter().enumerate() {
                let rows: Vec<f32> = (0..9).map(|row| block.v[row][j]).collect();
                if id == INVALID_INDEX {
                    assert!(
                        rows.iter().all(|&x| x == 0.0),
                        "a padding lane is the zero triangle"
                    );
                    continue;
                }
                seen[id as usize] += 1;
                let p = &primitives[id as usize];
                for (vertex, v) in [&p.a, &p.b, &p.c].into_iter().enumerate() {
                    for axis in 0..3 {
                        assert_eq!(rows[3 * axis + vertex], v[axis]);
                        assert!(set.boxes[axis][i] < v[axis] && v[axis] < set.boxes[3 + axis][i]);
                    }
                }
            }
        }
        for (i, &n) in seen.iter().enumerate() {
            assert_eq!(n, usize::from(wanted(i)), "primitive {i}");
        }
    }

    /// The AVX2 and AVX-512 walks of a tree of at most `FLAT_MAX_PRIMITIVES` triangles test
    /// them all (`flat_hit`, `flat_hit16`) and must find the walk's hits bit for bit: where
    /// one triangle holds the least distance, its hit; where several do (the copies, the
    /// grid's shared edges), `None`, so that the walk decides. Every quality (pre-splits make
    /// copies too).
    #[test]
    fn flat_hits_are_the_walks_hits_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: this CPU has no AVX2");
            return;
        }
        let avx512 = std::arch::is_x86_feature_detected!("avx512f");
        let (mut ties, mut boundary_hits) = (0, 0);
        for (n, copies, seed) in [(30, 6, 3u64), (40, 8, 5), (8, 2, 9), (1, 0, 11)] {
            let tris = scene(n, copies, seed);
            for quality in [BvhQuality::Fast, BvhQuality::Quality] {
                let bvh = GpuBvh::build_with_layout(&tris, &[], quality, BvhLayout::Wide).unwrap();
                let arrays = bvh.cpu_walk_arrays();
                // (Quality's pre-splits may take a tree past the limit: walked, then.)
                let flat_tree = bvh.primitives.len() <= FLAT_MAX_PRIMITIVES;
                assert_eq!(
                    !arrays.flat.is_empty(),
                    flat_tree,
                    "{n} + {copies}, {quality:?}"
                );
                if flat_tree {
                    check_set(&arrays.flat, &bvh.primitives, |_| true);
                    let faces = hull_faces(&bvh.primitives);
                    check_set(&arrays.flat_between16, &bvh.primitives, |i| !faces[i]);
                }
                // The eight-lane test's blocks, in the tree's order.
                let flat8 = if flat_tree {
                    flat_blocks(&bvh.primitives)
                } else {
                    Vec::new()
                };
                for (ray, t_min, t_max) in rays(&tris, 4000, seed + 1) {
                    // SAFETY: this CPU has AVX2 (checked above).
                    let (closest, any) = unsafe {
                        (
                            bvh.trace_closest_avx2::<false>(&ray, t_min, t_max),
                            bvh.trace_any_avx2::<false>(&ray, t_min, t_max),
                        )
                    };
                    let want = bvh.trace_closest_for::<false>(&ray, t_min, t_max);
                    assert_eq!(bits(closest), bits(want), "{ray:?} {t_min} {t_max}");
                    assert_eq!(any, want.is_some(), "{ray:?} {t_min} {t_max}");
                    if avx512 {
                        // SAFETY: this CPU has AVX-512 F (checked above) and AVX2.
                        let (closest, any) = unsafe {
                            (
                                bvh.trace_closest_avx512::<false>(&ray, t_min, t_max),
                                bvh.trace_any_avx512::<false>(&ray, t_min, t_max),
                            )
                        };
                        assert_eq!(bits(closest), bits(want), "{ray:?} {t_min} {t_max}");
                        assert_eq!(any, want.is_some(), "{ray:?} {t_min} {t_max}");
                    }
                    let (wide, sheared) = crate::wide_traverse::walk_rays(&ray);
                    let t_max = t_max.min(crate::T_MAX_LIMIT);
                    let count = bvh.primitives.len();
                    // SAFETY: as above; `flat8` is `flat_blocks`'.
                    let flat = unsafe { flat_hit(&flat8, count, &sheared, t_min, t_max, false) };
                    ties += usize::from(flat.is_none() && !flat8.is_empty());
                    if avx512 && !arrays.flat.is_empty() {
                        // The range ending or starting at the walk's hit, or one step past or
                        // short of it: the sixteen-lane test's answers, which pass over the
                        // blocks whose boxes begin beyond the hit, are those of `flat_hit`,
                        // which tests every triangle (the same values, eight lanes at a time).
                        // Not always the walk's: its boxes may leave out a hit within rounding
                        // of `t_max`, which a test of every triangle finds.
                        let t = want.map_or(0.5, |h| h.t);
                        let step =
                            |x: f32, d: i32| f32::from_bits(x.to_bits().wrapping_add_signed(d));
                        for (t_min, t_max) in [
                            (t_min, t),
                            (t_min, step(t, 1)),
                            (t, t_max),
                            (step(t, -1), t_max),
                        ] {
                            for any_hit in [false, true] {
                                // SAFETY: this CPU has AVX-512 F and AVX2 (checked above);
                                // `flat8` is `flat_blocks`'.
                                let (h8, h16) = unsafe {
                                    (
                                        flat_hit(&flat8, count, &sheared, t_min, t_max, any_hit),
                                        flat_hit16(
                                            &arrays.flat,
                                            &wide,
                                            &sheared,
                                            t_min,
                                            t_max,
                                            any_hit,
                                        ),
                                    )
                                };
                                if any_hit {
                                    // Whether anything is hit: the blocks come in another
                                    // order, so the hit found first may be another.
                                    let hit = |h: Option<Hit>| h.unwrap().prim != INVALID_INDEX;
                                    assert_eq!(hit(h16), hit(h8), "{ray:?} {t_min} {t_max}");
                                    let h = h16.unwrap();
                                    assert!(
                                        h.prim == INVALID_INDEX || (t_min < h.t && h.t < t_max),
                                        "{ray:?} {t_min} {t_max}: {h:?}"
                                    );
                                } else {
                                    assert_eq!(bits(h16), bits(h8), "{ray:?} {t_min} {t_max}");
                                }
                                boundary_hits +=
                                    usize::from(h16.is_some_and(|h| h.prim != INVALID_INDEX));
                            }
                        }
                    }
                }
            }
        }
        // The copies must have made the flat test hand some rays back to the walk.
        assert!(ties > 100, "{ties} ties");
        // And the ranges at the hits held hits as well as misses.
        assert!(
            !avx512 || boundary_hits > 1000,
            "{boundary_hits} hits at the ranges' ends"
        );
    }

    /// A room (six walls, 12 triangles), a box standing on its floor turned about the
    /// vertical (its bottom in the floor's plane), a lamp below the ceiling and a tetrahedron
    /// in the air: 30 triangles, the first 12 and the box's bottom (12, 13) the hull's faces.
    fn room() -> Vec<Triangle> {
        let mut tris = Vec::new();
        let mut quad = |o: Vec3, e1: Vec3, e2: Vec3| {
            tris.push(Triangle::flat([o, o + e1, o + e1 + e2], 0));
            tris.push(Triangle::flat([o, o + e1 + e2, o + e2], 0));
        };
        let (x, y, z) = (Vec3::X * 2.0, Vec3::Y * 2.0, Vec3::Z * 2.0);
        let c = Vec3::new(-1.0, 0.0, -1.0);
        quad(c, x, z); // floor
        quad(c + y, z, x); // ceiling
        quad(c, y, x); // back
        quad(c + z, x, y); // front
        quad(c, z, y); // left
        quad(c + x, y, z); // right
        let (s, co) = 0.4f32.sin_cos();
        let (u, w) = (Vec3::new(co, 0.0, s) * 0.6, Vec3::new(-s, 0.0, co) * 0.6);
        let (b, h) = (Vec3::new(0.2, 0.0, 0.1), Vec3::Y * 0.7);
        quad(b, u, w); // the box's bottom, on the floor
        quad(b + h, w, u);
        quad(b, h, u);
        quad(b + w, u, h);
        quad(b, w, h);
        quad(b + u, h, w);
        quad(Vec3::new(-0.25, 1.98, -0.2), Vec3::X * 0.5, Vec3::Z * 0.4); // lamp
        let t = [
            Vec3::new(-0.6, 1.0, -0.2),
            Vec3::new(-0.2, 1.1, -0.5),
            Vec3::new(-0.4, 1.4, 0.1),
            Vec3::new(-0.7, 1.3, -0.6),
        ];
        for [i, j, k] in [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] {
            tris.push(Triangle::flat([t[i], t[j], t[k]], 0));
        }
        tris
    }

    /// A shadow ray is a segment between two points of the scene: from a surface point (offset
    /// off its triangle toward the ray's side) to a point of a lamp, `t_max` short of it by
    /// `SHADOW_T_SCALE`'s margin. The flat walks' `trace_any_between` leave the hull's faces
    /// out and must answer as the walk's full test does, for segments between random points
    /// of random triangles, many from near their triangle's edges (near the room's corners,
    /// where a wall's plane passes within rounding of the origin). Rays that are not such
    /// segments (from outside the room) show the walls are left out.
    #[test]
    fn flat_between_answers_the_any_hit_test() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: this CPU has no AVX2");
            return;
        }
        let avx512 = std::arch::is_x86_feature_detected!("avx512f");
        let tris = room();
        let mut state = 7u64;
        let mut r = || crate::test_rand(&mut state);
        for quality in [BvhQuality::Fast, BvhQuality::Quality] {
            let bvh = GpuBvh::build_with_layout(&tris, &[], quality, BvhLayout::Wide).unwrap();
            assert!(bvh.cpu_walks_flat(true) && bvh.cpu_walks_flat(false));
            // The hull's faces: the walls and the box's bottom, by their scene index.
            let faces = hull_faces(&bvh.primitives);
            for (p, face) in bvh.primitives.iter().zip(&faces) {
                let index = p.c[3].to_bits();
                assert_eq!(*face, index < 14, "triangle {index}, {quality:?}");
            }
            let inner = faces.iter().filter(|f| !**f).count();
            let arrays = bvh.cpu_walk_arrays();
            assert_eq!(arrays.flat_between.1, inner);
            // The sixteen-lane sets: the hull's faces in the lead block, which the lamp's
            // two triangles join (the largest group that fits beside them); the box, the lamp
            // and the tetrahedron, which lie apart, each in a block of its own (the scene's
            // triangles 14..24, 24..26, 26..30).
            let object = |id: u32| match bvh.primitives[id as usize].c[3].to_bits() {
                0..14 => 0,
                14..24 => 1,
                24..26 => 2,
                _ => 3,
            };
            let objects = |set: &FlatSet| -> Vec<Vec<u32>> {
                set.ids
                    .iter()
                    .map(|ids| {
                        let mut o: Vec<u32> = ids
                            .iter()
                            .filter(|&&id| id != INVALID_INDEX)
                            .map(|&id| object(id))
                            .collect();
                        o.dedup();
                        o
                    })
                    .collect()
            };
            assert!(arrays.flat.lead && !arrays.flat_between16.lead);
            assert_eq!(
                objects(&arrays.flat),
                [vec![0, 2], vec![1], vec![3]],
                "{quality:?}"
            );
            let mut between = objects(&arrays.flat_between16);
            between.sort();
            assert_eq!(between, [[1], [2], [3]], "{quality:?}");
            let (mut blocked, mut open, mut at_start) = (0, 0, 0);
            for i in 0..20_000 {
                let mut point = |near_edge: bool| {
                    let t = &tris[(r() * tris.len() as f32) as usize % tris.len()];
                    let [a, b, c] = t.positions;
                    let (mut u, mut v) = (r(), r());
                    if u + v > 1.0 {
                        (u, v) = (1.0 - u, 1.0 - v);
                    }
                    if near_edge {
                        u *= 1e-5;
                    }
                    (
                        a + (b - a) * u + (c - a) * v,
                        (b - a).cross(c - a).normalize(),
                    )
                };
                let (from, n) = point(i % 3 == 0);
                let (to, _) = point(false);
                let side = if n.dot(to - from) >= 0.0 { 1.0 } else { -1.0 };
                let origin = from + n * side * 1e-4;
                let ray = Ray::new(origin, to - origin);
                let (t_min, t_max) = (0.0, 0.9999);
                if avx512 {
                    // The closest hit of the ray, which the sixteen-lane test finds passing
                    // over the blocks whose boxes begin beyond the walls' hit (or the box's).
                    let want = bvh.trace_closest_for::<false>(&ray, t_min, f32::MAX);
                    // SAFETY: this CPU has AVX-512 F (checked above) and AVX2.
                    let got = unsafe { bvh.trace_closest_avx512::<false>(&ray, t_min, f32::MAX) };
                    assert_eq!(bits(got), bits(want), "{ray:?}, {quality:?}");
                }
                let want = bvh.trace_any_for::<false>(&ray, t_min, t_max);
                // SAFETY: this CPU has AVX2 (checked above).
                let mut got =
                    vec![unsafe { bvh.trace_any_between_avx2::<false>(&ray, t_min, t_max) }];
                if avx512 {
                    // SAFETY: this CPU has AVX-512 F (checked above) and AVX2.
                    got.push(unsafe { bvh.trace_any_between_avx512::<false>(&ray, t_min, t_max) });
                }
                if got.iter().any(|&g| g != want) {
                    // Only where the full test meets a wall at the segment's very start: an
                    // origin in a corner, on another wall's plane.
                    let hit = bvh.trace_closest_for::<false>(&ray, t_min, t_max).unwrap();
                    assert!(
                        want && got.iter().all(|g| !g) && faces[hit.prim as usize] && hit.t < 1e-5,
                        "{ray:?}, {quality:?}: {hit:?}"
                    );
                    at_start += 1;
                }
                if want {
                    blocked += 1;
                } else {
                    open += 1;
                }
            }
            // Both answers common: the box and the tetrahedron block a share of the segments.
            assert!(
                blocked > 2000 && open > 2000,
                "{blocked} blocked, {open} open"
            );
            // The corners' origins are rare even here, where a third of the origins lie within
            // 1e-5 of an edge.
            eprintln!("{quality:?}: {blocked} blocked, {open} open, {at_start} at a wall's plane");
            assert!(at_start < 100, "{at_start}");
            // From outside, through the floor and the back wall: the full test meets them.
            let outside = Ray::new(Vec3::new(0.1, -1.0, -2.0), Vec3::new(0.0, 1.5, 1.5));
            assert!(bvh.trace_any_for::<false>(&outside, 0.0, 0.9));
            // SAFETY: as above.
            assert!(!unsafe { bvh.trace_any_between_avx2::<false>(&outside, 0.0, 0.9) });
            if avx512 {
                // SAFETY: as above.
                assert!(!unsafe { bvh.trace_any_between_avx512::<false>(&outside, 0.0, 0.9) });
            }
        }
    }

    /// Larger trees and trees with a sphere walk as before: no flat array.
    #[test]
    fn only_small_trees_of_triangles_are_tested_flat() {
        let big = scene(FLAT_MAX_PRIMITIVES, 0, 1);
        let bvh = GpuBvh::build_with_layout(&big, &[], BvhQuality::Fast, BvhLayout::Wide).unwrap();
        assert!(bvh.primitives.len() > FLAT_MAX_PRIMITIVES);
        assert!(bvh.cpu_walk_arrays().flat.is_empty());
        let small = scene(10, 0, 1);
        let sphere = Sphere {
            center: Vec3::splat(0.5),
            radius: 0.1,
            material: 0,
        };
        let bvh = GpuBvh::build_with_layout(&small, &[sphere], BvhQuality::Fast, BvhLayout::Wide)
            .unwrap();
        assert!(bvh.cpu_walk_arrays().flat.is_empty());
        let bvh =
            GpuBvh::build_with_layout(&small, &[], BvhQuality::Fast, BvhLayout::Wide).unwrap();
        assert!(!bvh.cpu_walk_arrays().flat.is_empty());
        assert_eq!(bvh.cpu_walk_arrays().flat_avx2.len(), 2);
        assert!(bvh.cpu_walks_flat(true) && bvh.cpu_walks_flat(false));
        // 40 < 56 <= 64 triangles: flat at x86-64-v4 only.
        let mid = scene(48, 0, 1);
        let bvh = GpuBvh::build_with_layout(&mid, &[], BvhQuality::Fast, BvhLayout::Wide).unwrap();
        assert!(bvh.cpu_walks_flat(true) && !bvh.cpu_walks_flat(false));
        // A binary tree is walked (its walk has no flat test).
        let bvh =
            GpuBvh::build_with_layout(&small, &[], BvhQuality::Fast, BvhLayout::Binary).unwrap();
        assert!(!bvh.cpu_walks_flat(true));
    }
}
