//! The paper's 30-bit origin-direction Morton key of a ray, in Rust; `morton.wgsl` is the same
//! code in WGSL ([`MORTON_WGSL`]), bit for bit.
//!
//! Layout of a key (bit 31 on the left):
//!
//! ```text
//! 00 | origin Morton code (bits 29..15) | direction Morton code (bits 14..0)
//! ```
//!
//! Each Morton code interleaves three 5-bit cell indices with **x in the lowest bit of each
//! triple**: bit `3i` holds bit `i` of x, bit `3i + 1` bit `i` of y, bit `3i + 2` bit `i` of z.
//! The origin is quantised inside the scene's bounding box, each direction component inside
//! [-1, 1]; values outside are clamped to the first or last cell.
//!
//! Quantisation uses no division (WGSL division is only accurate to 2.5 ULP, so the GPU could
//! disagree with the CPU near cell boundaries): the cell of `v` inside `[lo, lo + extent]` is
//! the number of `k` in `1..=31` with `fl(k * extent) <= fl(32 * fl(v - lo))`, found by a 5-step
//! binary search over correctly rounded products. Non-finite inputs are classified by their
//! bits first (WGSL lets a GPU assume they never occur): NaN goes to cell 0, +inf to 31, -inf
//! to 0; an extent that is not a finite, normal, positive number (or a non-finite box corner)
//! puts every value in cell 0. Finite inputs so large that `v - lo` overflows are outside the
//! contract.
//!
//! Live keys are capped at [`LIVE_RAY_KEY_MAX`] = 2^30 - 2 so that [`DEAD_RAY_KEY`], whose low
//! 30 bits are all ones, sorts strictly after every live ray in a 30-bit sort (the one cell pair
//! that would have produced 2^30 - 1 shares the key of its neighbour).

use glam::Vec3;

/// Bits per axis of one cell index.
pub const MORTON_AXIS_BITS: u32 = 5;
/// Cells per axis (2^5).
pub const MORTON_AXIS_CELLS: u32 = 32;
/// Bits of a ray sort key that carry information (two 15-bit Morton codes).
pub const RAY_KEY_BITS: u32 = 30;
/// Position of the origin code in a ray sort key.
pub const ORIGIN_KEY_SHIFT: u32 = 15;
/// The largest key of a live ray, 2^30 - 2: the all-ones 30-bit pattern is left to dead rays.
pub const LIVE_RAY_KEY_MAX: u32 = 0x3FFF_FFFE;
/// The key of a dead (terminated) ray: the largest `u32`, whose low 30 bits are also the
/// largest 30-bit value, so a radix sort of the low 30 bits moves dead rays after all live ones.
pub const DEAD_RAY_KEY: u32 = 0xFFFF_FFFF;

/// The WGSL twin of this module (`morton.wgsl`): the constants and functions above with the same
/// names, no bindings. Concatenate it into a kernel and call `ray_sort_key`.
pub const MORTON_WGSL: &str = include_str!("morton.wgsl");

/// Spreads the low 5 bits of `v` to bits 0, 3, 6, 9, 12 (bit `i` goes to bit `3i`).
#[inline]
pub const fn expand_bits_5(v: u32) -> u32 {
    let mut x = v & 0x1F;
    x = (x | (x << 8)) & 0x0000_F00F;
    x = (x | (x << 4)) & 0x000C_30C3;
    x = (x | (x << 2)) & 0x0004_9249;
    x
}

/// 15-bit Morton code of three 5-bit cell indices, x in the lowest bit of each triple.
#[inline]
pub const fn morton3_5(x: u32, y: u32, z: u32) -> u32 {
    expand_bits_5(x) | (expand_bits_5(y) << 1) | (expand_bits_5(z) << 2)
}

/// Cell index in `0..=31` of `v` inside `[lo, lo + extent]`, clamped outside (see the module
/// docs for NaN, infinities and degenerate extents).
#[inline]
pub fn quantize_5(v: f32, lo: f32, extent: f32) -> u32 {
    let vb = v.to_bits();
    let eb = extent.to_bits();
    if !(0x0080_0000..0x7F80_0000).contains(&eb) || (lo.to_bits() & 0x7F80_0000) == 0x7F80_0000 {
        return 0;
    }
    let mag = vb & 0x7FFF_FFFF;
    if mag > 0x7F80_0000 {
        return 0; // NaN
    }
    if mag == 0x7F80_0000 {
        return if vb >> 31 != 0 {
            0
        } else {
            MORTON_AXIS_CELLS - 1
        };
    }
    let scaled = 32.0 * (v - lo);
    let mut q = 0u32;
    let mut step = 16u32;
    while step != 0 {
        let k = q + step;
        if k as f32 * extent <= scaled {
            q = k;
        }
        step >>= 1;
    }
    q
}

/// The paper's 30-bit origin-direction sort key of a ray (layout in the module docs). `dir`
/// need not be normalised; its components are clamped to [-1, 1].
#[inline]
pub fn ray_sort_key(origin: Vec3, dir: Vec3, scene_min: Vec3, scene_extent: Vec3) -> u32 {
    let o = morton3_5(
        quantize_5(origin.x, scene_min.x, scene_extent.x),
        quantize_5(origin.y, scene_min.y, scene_extent.y),
        quantize_5(origin.z, scene_min.z, scene_extent.z),
    );
    let d = morton3_5(
        quantize_5(dir.x, -1.0, 2.0),
        quantize_5(dir.y, -1.0, 2.0),
        quantize_5(dir.z, -1.0, 2.0),
    );
    ((o << ORIGIN_KEY_SHIFT) | d).min(LIVE_RAY_KEY_MAX)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Inverse of `expand_bits_5`, for the tests.
    fn compact_bits_5(v: u32) -> u32 {
        (0..5).map(|i| ((v >> (3 * i)) & 1) << i).sum()
    }

    #[test]
    fn expand_bits_5_places_bit_i_at_3i() {
        for i in 0..5 {
            assert_eq!(expand_bits_5(1 << i), 1 << (3 * i));
        }
        assert_eq!(expand_bits_5(0x1F), 0b1_001_001_001_001);
        // Bits above the fifth are ignored.
        assert_eq!(expand_bits_5(0xFFFF_FFE0), 0);
    }

    #[test]
    fn hand_computed_keys() {
        let min = Vec3::new(-1.0, 0.0, 2.0);
        let ext = Vec3::new(4.0, 8.0, 16.0);
        // 1) Origin at the box minimum, direction (-1, -1, -1): every cell is 0, key 0.
        assert_eq!(ray_sort_key(min, Vec3::splat(-1.0), min, ext), 0);

        // 2) Origin (0, 3, 14): x: 32 * (0 - -1) = 32, largest k with 4k <= 32 is 8;
        //    y: 32 * 3 = 96, 8k <= 96 -> 12; z: 32 * 12 = 384, 16k <= 384 -> 24.
        //    Direction (0, 0.5, -1): x: 16 * (0 + 1) = 16 -> 16; y: 16 * 1.5 = 24 -> 24; z -> 0.
        //    Origin code: x = 8 = 0b01000 -> bit 3 of x at bit 9: 0x200;
        //      y = 12 = 0b01100 -> bits 2, 3 of y at bits 7, 10: 0x480;
        //      z = 24 = 0b11000 -> bits 3, 4 of z at bits 11, 14: 0x4800;
        //      code = 0x200 | 0x480 | 0x4800 = 0x4E80.
        //    Direction code: x = 16 -> bit 4 of x at bit 12: 0x1000;
        //      y = 24 -> bits 3, 4 of y at bits 10, 13: 0x2400; z = 0;
        //      code = 0x3400.
        //    Key = 0x4E80 << 15 | 0x3400 = 0x2740_0000 | 0x3400 = 0x2740_3400.
        let key = ray_sort_key(
            Vec3::new(0.0, 3.0, 14.0),
            Vec3::new(0.0, 0.5, -1.0),
            min,
            ext,
        );
        assert_eq!(key, 0x2740_3400);

        // 3) Origin (3, 8, 18) is the box maximum -> cells (31, 31, 31) (clamped: 32 would be the
        //    count of k <= 32, but k stops at 31); direction (1, 1, 0.9999) -> (31, 31, 31):
        //    16 * 1.9999 = 31.9984 -> 31. All 30 bits set, which is reserved for dead rays, so
        //    the key is capped at 2^30 - 2.
        let key = ray_sort_key(
            Vec3::new(3.0, 8.0, 18.0),
            Vec3::new(1.0, 1.0, 0.9999),
            min,
            ext,
        );
        assert_eq!(key, LIVE_RAY_KEY_MAX);

        // 4) Direction (0.0625, -0.0625, 0) with origin cell 0: x: 16 * 1.0625 = 17 -> 17 =
        //    0b10001 -> bits 0, 12; y: 16 * 0.9375 = 15 = 0b01111 -> bits 1, 4, 7, 10;
        //    z: 16 -> bit 4 of z at bit 14. Code = 0x1001 | 0x492 | 0x4000 = 0x5493.
        let key = ray_sort_key(min, Vec3::new(0.0625, -0.0625, 0.0), min, ext);
        assert_eq!(key, 0x5493);
    }

    #[test]
    fn non_finite_inputs_are_clamped_deterministically() {
        let min = Vec3::ZERO;
        let ext = Vec3::ONE;
        assert_eq!(quantize_5(f32::NAN, 0.0, 1.0), 0);
        assert_eq!(quantize_5(-f32::NAN, 0.0, 1.0), 0);
        assert_eq!(quantize_5(f32::INFINITY, 0.0, 1.0), 31);
        assert_eq!(quantize_5(f32::NEG_INFINITY, 0.0, 1.0), 0);
        assert_eq!(quantize_5(0.5, 0.0, 0.0), 0, "zero extent");
        assert_eq!(quantize_5(0.5, 0.0, -1.0), 0, "negative extent");
        assert_eq!(quantize_5(0.5, 0.0, f32::NAN), 0, "NaN extent");
        assert_eq!(quantize_5(0.5, 0.0, f32::INFINITY), 0, "infinite extent");
        assert_eq!(quantize_5(0.5, f32::NAN, 1.0), 0, "NaN corner");
        assert_eq!(quantize_5(1e30, 0.0, 1.0), 31);
        assert_eq!(quantize_5(-1e30, 0.0, 1.0), 0);
        let k = ray_sort_key(Vec3::NAN, Vec3::NAN, min, ext);
        assert_eq!(k, 0);
    }

    /// Cell index by the obvious formula in f64, for comparison away from cell boundaries.
    fn cell_f64(v: f32, lo: f32, extent: f32) -> (i64, f64) {
        let t = (f64::from(v) - f64::from(lo)) / f64::from(extent) * 32.0;
        (t.floor().clamp(0.0, 31.0) as i64, t)
    }

    proptest! {
        #[test]
        fn quantize_5_matches_floor_away_from_boundaries(
            v in -20.0f32..20.0, lo in -10.0f32..10.0, extent in 0.01f32..15.0
        ) {
            let q = quantize_5(v, lo, extent);
            prop_assert!(q <= 31);
            let (expect, t) = cell_f64(v, lo, extent);
            // Within 1e-3 of a cell boundary, f32 rounding may legitimately pick either side.
            if (t - t.round()).abs() > 1e-3 {
                prop_assert_eq!(i64::from(q), expect);
            } else {
                prop_assert!((i64::from(q) - expect).abs() <= 1);
            }
        }

        #[test]
        fn quantize_5_is_monotone(a in -20.0f32..20.0, b in -20.0f32..20.0,
                                  lo in -10.0f32..10.0, extent in 0.001f32..15.0) {
            let (lo_v, hi_v) = if a <= b { (a, b) } else { (b, a) };
            prop_assert!(quantize_5(lo_v, lo, extent) <= quantize_5(hi_v, lo, extent));
        }

        #[test]
        fn key_is_monotone_in_each_component(
            o in proptest::array::uniform3(-1.0f32..2.0),
            d in proptest::array::uniform3(-1.2f32..1.2),
            axis in 0usize..6, delta in 0.0f32..1.5,
        ) {
            let min = Vec3::ZERO;
            let ext = Vec3::new(1.0, 0.5, 0.25);
            let (o, d) = (Vec3::from(o), Vec3::from(d));
            let (mut o2, mut d2) = (o, d);
            if axis < 3 { o2[axis] += delta } else { d2[axis - 3] += delta }
            let k1 = ray_sort_key(o, d, min, ext);
            let k2 = ray_sort_key(o2, d2, min, ext);
            prop_assert!(k1 <= k2, "{k1:#x} > {k2:#x}");
            prop_assert!(k2 <= LIVE_RAY_KEY_MAX);
        }

        #[test]
        fn key_decodes_to_its_cells(
            o in proptest::array::uniform3(-0.5f32..1.5),
            d in proptest::array::uniform3(-1.0f32..1.0),
        ) {
            let min = Vec3::splat(0.0);
            let ext = Vec3::splat(1.0);
            let key = ray_sort_key(Vec3::from(o), Vec3::from(d), min, ext);
            let cells: Vec<u32> = (0..3)
                .map(|a| quantize_5(o[a], 0.0, 1.0))
                .chain((0..3).map(|a| quantize_5(d[a], -1.0, 2.0)))
                .collect();
            let oc = key >> ORIGIN_KEY_SHIFT;
            let dc = key & 0x7FFF;
            let decoded = [
                compact_bits_5(oc), compact_bits_5(oc >> 1), compact_bits_5(oc >> 2),
                compact_bits_5(dc), compact_bits_5(dc >> 1), compact_bits_5(dc >> 2),
            ];
            if key != LIVE_RAY_KEY_MAX {
                prop_assert_eq!(&decoded[..], &cells[..]);
            }
        }
    }
}
