// raylume-sort: the 30-bit origin-direction Morton key of a ray (the paper's "Ray sorting").
//
// Mirror of `src/morton.rs`: same function names, same constants, bit-identical results (the
// test `morton_wgsl_matches_rust` checks ~100k random rays). No bindings: include this text in a
// kernel (the tracer's `propagate`) and call `ray_sort_key`.
//
// Layout of a key (bit 31 on the left):
//   00 | origin Morton code (bits 29..15) | direction Morton code (bits 14..0)
// Each Morton code interleaves three 5-bit cell indices with x in the lowest bit of each
// triple: bit 3i = x_i, bit 3i+1 = y_i, bit 3i+2 = z_i.
//
// Quantisation avoids division, whose WGSL accuracy is only 2.5 ULP: the cell of `v` inside
// [lo, lo + extent] is the number of k in 1..=31 with fl(k * extent) <= fl(32 * fl(v - lo)),
// which uses only correctly rounded operations (WGSL guarantees correct rounding for +, -, *).
// NaN and infinite inputs are classified by their bits before any float arithmetic (WGSL lets
// implementations assume neither occurs): NaN -> cell 0, +inf -> 31, -inf -> 0. An extent that
// is not a finite normal positive number, or a box corner that is not finite, puts every value
// in cell 0. (Finite inputs so large that `v - lo` overflows are outside this contract.)

/// Bits per axis of one cell index.
const MORTON_AXIS_BITS: u32 = 5u;
/// Cells per axis (2^5).
const MORTON_AXIS_CELLS: u32 = 32u;
/// Bits of a ray sort key that carry information (two 15-bit Morton codes).
const RAY_KEY_BITS: u32 = 30u;
/// Position of the origin code in a ray sort key.
const ORIGIN_KEY_SHIFT: u32 = 15u;
/// The largest key of a live ray: 2^30 - 2. The one all-ones 30-bit pattern is reserved so that
/// dead rays sort strictly after every live ray even when only the low 30 bits are sorted.
const LIVE_RAY_KEY_MAX: u32 = 0x3FFFFFFEu;
/// The key of a dead (terminated) ray: the largest u32, whose low 30 bits are also the largest
/// 30-bit value, so a radix sort of the low 30 bits moves dead rays to the end.
const DEAD_RAY_KEY: u32 = 0xFFFFFFFFu;

/// Spreads the low 5 bits of `v` to bits 0, 3, 6, 9, 12 (bit i goes to bit 3i).
fn expand_bits_5(v: u32) -> u32 {
    var x = v & 0x1Fu;
    x = (x | (x << 8u)) & 0x0000F00Fu;
    x = (x | (x << 4u)) & 0x000C30C3u;
    x = (x | (x << 2u)) & 0x00049249u;
    return x;
}

/// 15-bit Morton code of three 5-bit cell indices, x in the lowest bit of each triple.
fn morton3_5(x: u32, y: u32, z: u32) -> u32 {
    return expand_bits_5(x) | (expand_bits_5(y) << 1u) | (expand_bits_5(z) << 2u);
}

/// Cell index in 0..=31 of `v` inside [lo, lo + extent] (clamped outside; see the header for
/// NaN, infinities and degenerate extents).
fn quantize_5(v: f32, lo: f32, extent: f32) -> u32 {
    let vb = bitcast<u32>(v);
    let eb = bitcast<u32>(extent);
    // Not a finite normal positive extent, or a non-finite box corner: everything in cell 0.
    if (eb < 0x00800000u || eb >= 0x7F800000u || (bitcast<u32>(lo) & 0x7F800000u) == 0x7F800000u) {
        return 0u;
    }
    let mag = vb & 0x7FFFFFFFu;
    if (mag > 0x7F800000u) {
        return 0u; // NaN
    }
    if (mag == 0x7F800000u) {
        return select(MORTON_AXIS_CELLS - 1u, 0u, (vb >> 31u) != 0u); // -inf -> 0, +inf -> 31
    }
    let scaled = 32.0 * (v - lo);
    var q = 0u;
    var step = 16u;
    loop {
        if (step == 0u) {
            break;
        }
        let k = q + step;
        if (f32(k) * extent <= scaled) {
            q = k;
        }
        step = step >> 1u;
    }
    return q;
}

/// The paper's 30-bit origin-direction key: origin quantised inside the scene box
/// [scene_min, scene_min + scene_extent], direction components quantised inside [-1, 1], each
/// triple interleaved into a 15-bit Morton code; origin code in bits 29..15, direction code in
/// bits 14..0; capped at LIVE_RAY_KEY_MAX.
fn ray_sort_key(origin: vec3<f32>, dir: vec3<f32>, scene_min: vec3<f32>, scene_extent: vec3<f32>) -> u32 {
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
    return min((o << ORIGIN_KEY_SHIFT) | d, LIVE_RAY_KEY_MAX);
}
