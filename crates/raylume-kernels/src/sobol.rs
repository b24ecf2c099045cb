//! A low-discrepancy sampler: ZSobol (Ahmed & Wonka 2020, "Screen-space blue-noise diffusion
//! of Monte Carlo sampling error via hierarchical ordering of pixels", SIGGRAPH Asia), after
//! pbrt-v4's `ZSobolSampler` with `RandomizeStrategy::FastOwen` (`samplers.h`,
//! `util/lowdiscrepancy.h`), and a cheaper variant of it (below). Identical in WGSL (`sobol.wgsl`)
//! and Rust; the tracer draws from it through `shade::path_rand4` (`Sampler::ZSobol`,
//! `Sampler::Sobol`).
//!
//! Like [`crate::rng::rand4`] it is a pure function of its key, so no state travels with a
//! ray: [`sobol4`]`(seed, pixel, sample, spp, dim)` gives four numbers in `[0, 1)`, two
//! *pairs*: `(x, y)` is 2D sample dimension pair `2 * dim`, `(z, w)` pair `2 * dim + 1`.
//!
//! How one pair is made (pbrt-v4's `ZSobolSampler::Get2D`):
//! 1. The pixel's Morton code, shifted left by `log2(spp)` (spp rounded up to a power of 2),
//!    with the sample index in the low bits: consecutive Sobol' indices fill a pixel, and
//!    pixels follow the Z curve ([`zsobol_morton_index`]).
//! 2. Every base-4 digit of that index is permuted by one of the 24 permutations of
//!    `{0, 1, 2, 3}`, chosen by a hash of the digits above it and of the pair's key
//!    ([`zsobol_sample_index`]; with an odd `log2(spp)` the lowest digit is one bit, flipped
//!    by a hash bit). This is a bijection that keeps each pixel's indices one aligned block of
//!    `2^log2(spp)`, and each prefix of `2^(log2(spp) mod 2) * 4^j` of them an aligned block,
//!    while shuffling which block a pixel gets: the error of neighbouring pixels decorrelates as
//!    blue noise (Ahmed & Wonka) and different pairs get different, unrelated indices (the
//!    "padding" that lets every pair use Sobol' dimensions 0 and 1 only).
//! 3. Sobol' dimensions 0 and 1 of that index (dimension 0's generator matrix is the bit
//!    reversal, dimension 1's the Pascal matrix mod 2, whose columns follow
//!    `c_{i+1} = c_i ^ (c_i >> 1)`: [`sobol_dim1`]), each Owen-scrambled by pbrt-v4's
//!    `FastOwenScrambler` ([`fast_owen`]) with a seed hashed from (seed, dim).
//! 4. The top 24 bits as a float ([`crate::rng::rand_f32`]): exact on every device, at most
//!    `0x1.fffffep-1` (pbrt-v4's `FloatOneMinusEpsilon`; pbrt multiplies by `0x1p-32` and
//!    clamps, which WGSL could not reproduce bit for bit since its u32-to-f32 rounding is
//!    implementation-defined).
//!
//! Aligned blocks of `2^k` consecutive indices of Sobol' dimensions 0 and 1 are (0, k, 2)-nets
//! in base 2, and both the digit permutation (which maps blocks to blocks) and Owen scrambling
//! keep that: for spp = `2^k`, each pair of a pixel's samples has exactly one point in each
//! of the `2^k` elementary intervals of area `2^-k` (tested below).
//!
//! **The shuffled variant** ([`shuffled_sobol4`], `Sampler::Sobol`) replaces step 2 by
//! Burley's shuffle (Burley 2020, "Practical Hash-based Owen Scrambling"): the index is
//! nested-uniform scrambled by one Laine-Karras hash ([`shuffled_sample_index`]) instead of
//! 16 digit permutations, each with its own hash. Aligned blocks still map to aligned blocks,
//! so every pixel's samples are the same kind of net and different pairs still see them in
//! unrelated orders; what it gives up is part of ZSobol's freedom in placing the pixels'
//! blocks (their errors' blue noise). On the H200 the 16 hashes per pair made the living
//! room's NEE trace 1.34x slower than independent numbers (commit 7121aa9, 500x500, 256 spp).
//!
//! Differences from pbrt-v4, all for a u32-only GPU mirror: the index is 32 bits (pbrt: 64),
//! so the Morton code of the pixel plus `log2(spp)` bits must fit in 32 (e.g. 4096x4096 at
//! 256 spp); beyond that the image is split into tiles that do fit, each with its own seed
//! ([`zsobol_tile`]), rather than letting pixels share samples;
//! all 16 base-4 digits are permuted (pbrt permutes only as many as the resolution needs;
//! the extra digits are zero and their permutation is a fixed bijection); the hashes are
//! `pcg4d` and Wellons' 32-bit `lowbias32` instead of MurmurHash64A and `MixBits`, and the seed
//! is mixed into the digit permutations too (pbrt's depend on the dimension only).
//!
//! spp that is not a power of 2: the pixel's block is that of the next power of 2 and samples
//! `0..spp` use the first `spp` of its (permuted) indices. A prefix of `2^o * 4^j` samples,
//! `o = log2(spp) mod 2`, is still an aligned block and so a (0, 2j + o, 2)-net; other sample
//! counts are stratified only partly (pbrt-v4 warns in this case too).

use glam::{UVec2, Vec4};

use crate::rng::{pcg4d, rand_f32};

/// The 24 permutations of `{0, 1, 2, 3}` in pbrt-v4's order (`ZSobolSampler::GetSampleIndex`),
/// packed: permutation `p` is byte `p & 3` of word `p >> 2`, and maps digit `d` to bits
/// `2d..2d+2` of that byte.
pub const ZSOBOL_PERMUTATIONS: [u32; 6] = pack_permutations();

const PERMUTATIONS: [[u32; 4]; 24] = [
    [0, 1, 2, 3],
    [0, 1, 3, 2],
    [0, 2, 1, 3],
    [0, 2, 3, 1],
    [0, 3, 2, 1],
    [0, 3, 1, 2],
    [1, 0, 2, 3],
    [1, 0, 3, 2],
    [1, 2, 0, 3],
    [1, 2, 3, 0],
    [1, 3, 2, 0],
    [1, 3, 0, 2],
    [2, 1, 0, 3],
    [2, 1, 3, 0],
    [2, 0, 1, 3],
    [2, 0, 3, 1],
    [2, 3, 0, 1],
    [2, 3, 1, 0],
    [3, 1, 2, 0],
    [3, 1, 0, 2],
    [3, 2, 1, 0],
    [3, 2, 0, 1],
    [3, 0, 2, 1],
    [3, 0, 1, 2],
];

const fn pack_permutations() -> [u32; 6] {
    let mut words = [0u32; 6];
    let mut p = 0;
    while p < 24 {
        let mut byte = 0u32;
        let mut d = 0;
        while d < 4 {
            byte |= PERMUTATIONS[p][d] << (2 * d);
            d += 1;
        }
        words[p >> 2] |= byte << (8 * (p & 3));
        p += 1;
    }
    words
}

/// Third word of the `pcg4d` key of the sampler's hashes (so they differ from `rand4`'s).
pub const SOBOL_SALT: u32 = 0x5AB0_1D5E;

/// The largest value [`sobol4`] returns: `0x1.fffffep-1`, pbrt-v4's `FloatOneMinusEpsilon`.
pub const SOBOL_ONE_MINUS_EPSILON: f32 = 1.0 - 1.0 / 16_777_216.0;

/// Chris Wellons' `lowbias32` integer hash (hash-prospector), a 32-bit `MixBits`.
#[inline]
pub fn mix32(x: u32) -> u32 {
    let mut x = x;
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// The low 16 bits of `x` spread to the even bits.
#[inline]
pub fn part_1by1(x: u32) -> u32 {
    let mut x = x & 0xffff;
    x = (x | (x << 8)) & 0x00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333;
    x = (x | (x << 1)) & 0x5555_5555;
    x
}

/// pbrt-v4's `EncodeMorton2(x, y)`: x in the even bits, y in the odd ones (16 bits each).
#[inline]
pub fn encode_morton2(x: u32, y: u32) -> u32 {
    (part_1by1(y) << 1) | part_1by1(x)
}

/// `ceil(log2(spp))`: the pixel's block of Sobol' indices holds `2^this` samples.
#[inline]
pub fn sobol_log2_spp(spp: u32) -> u32 {
    let s = spp.max(1) - 1;
    if s == 0 { 0 } else { 32 - s.leading_zeros() }
}

/// pbrt-v4's `mortonIndex`: the pixel's Morton code above `log2_spp` bits of sample index.
#[inline]
pub fn zsobol_morton_index(pixel: UVec2, sample: u32, log2_spp: u32) -> u32 {
    let morton = encode_morton2(pixel.x, pixel.y);
    let low = zsobol_sample_bits(sample, log2_spp);
    if log2_spp >= 32 {
        low
    } else {
        (morton << log2_spp) | low
    }
}

/// The low `log2_spp` bits of [`zsobol_morton_index`]: the sample's.
#[inline]
pub fn zsobol_sample_bits(sample: u32, log2_spp: u32) -> u32 {
    if log2_spp == 0 {
        0
    } else {
        sample & (u32::MAX >> (32 - log2_spp))
    }
}

/// Digit `d` through permutation `p` (0..24) of [`ZSOBOL_PERMUTATIONS`].
#[inline]
pub fn zsobol_permute_digit(p: u32, d: u32) -> u32 {
    let byte = ZSOBOL_PERMUTATIONS[(p >> 2) as usize] >> (8 * (p & 3));
    (byte >> (2 * d)) & 3
}

/// pbrt-v4's `ZSobolSampler::GetSampleIndex`: each base-4 digit of `m` (aligned to the low
/// end when `log2_spp` is even, to bit 1 when odd) permuted by a hash of the digits above it
/// and `key`; with an odd `log2_spp` bit 0 is flipped by a hash bit and bit 31 is kept.
#[inline]
pub fn zsobol_sample_index(m: u32, log2_spp: u32, key: u32) -> u32 {
    let odd = log2_spp & 1;
    let mut out = 0u32;
    let mut i = odd;
    while i < 16 {
        let shift = 2 * i - odd;
        let digit = (m >> shift) & 3;
        let higher = if shift >= 30 { 0 } else { m >> (shift + 2) };
        let p = (mix32(higher ^ key) >> 24) % 24;
        out |= zsobol_permute_digit(p, digit) << shift;
        i += 1;
    }
    if odd == 1 {
        out |= (m & 1) ^ (mix32((m >> 1) ^ key) & 1);
        out |= m & 0x8000_0000;
    }
    out
}

/// Sobol' dimension 1 of index `a` (the Pascal matrix mod 2; dimension 0 is
/// `a.reverse_bits()`), as 32 bits, the first bit the most significant.
///
/// The matrix's column for index bit `j` has output bit `i` (from the top) set when
/// `C(j, i)` is odd, which by Lucas' theorem is when `i & j == i`: output bit `i` is the xor
/// of the index bits `j` whose positions are supersets of `i`'s. Five shift-mask-xor steps
/// compute that superset sum for all 32 positions at once (each step folds in the positions
/// that differ in one bit of the position number); reversing puts bit `i` at the top. The
/// same numbers as multiplying by the matrix column by column (tested against it), in 5
/// steps instead of up to 32.
#[inline]
pub fn sobol_dim1(a: u32) -> u32 {
    sobol_dim1_unreversed(a).reverse_bits()
}

/// pbrt-v4's `FastOwenScrambler` (after Laine & Karras 2011 and Burley 2020): a nested
/// uniform-like scramble of the bits of `v`, the first bit the most significant.
#[inline]
pub fn fast_owen(v: u32, seed: u32) -> u32 {
    owen_body(v.reverse_bits(), seed, (seed >> 16) | 1).reverse_bits()
}

/// Burley's shuffle (Burley 2020, "Practical Hash-based Owen Scrambling", section 4, after
/// Laine & Karras 2011): `m` nested-uniform scrambled under `key`, each bit flipped by a hash
/// of the bits above it, which is [`fast_owen`]`(m, key)`. Like [`zsobol_sample_index`] a
/// bijection mapping every aligned block of `2^j` indices onto an aligned block of `2^j`
/// (a pixel's samples stay one block, their power-of-2 prefixes nets, and each pair gets its
/// own order of them: the padding), at the cost of one hash for all 32 bits instead of one
/// hash per base-4 digit. It permutes each block's two halves by a hash bit where ZSobol
/// permutes a block's four quarters by one of the 24 permutations: the pixels' blocks are
/// shuffled less freely across the image (the blue noise of neighbouring pixels' errors is
/// weaker), each pixel's own points are the same kind of net.
#[inline]
pub fn shuffled_sample_index(m: u32, key: u32) -> u32 {
    fast_owen(m, key)
}

/// The 32-bit Sobol' points of one pair: dimensions 0 and 1 of the permuted index of
/// [`zsobol_morton_index`] `m` under `key` ([`shuffled_sample_index`] when `shuffled`, else
/// [`zsobol_sample_index`]), Owen-scrambled with `scramble_x` and `scramble_y`.
#[inline(always)]
pub fn zsobol_pair_bits(
    m: u32,
    log2_spp: u32,
    key: u32,
    scramble_x: u32,
    scramble_y: u32,
    shuffled: bool,
) -> [u32; 2] {
    let index = if shuffled {
        shuffled_sample_index(m, key)
    } else {
        zsobol_sample_index(m, log2_spp, key)
    };
    [
        fast_owen(index.reverse_bits(), scramble_x),
        fast_owen(sobol_dim1(index), scramble_y),
    ]
}

/// The Owen seeds of x, y, z, w of pair group `dim`.
#[inline]
pub fn sobol_scrambles(seed: u32, dim: u32) -> [u32; 4] {
    pcg4d([seed, dim, SOBOL_SALT, 0])
}

/// The index-permutation keys of the pairs (x, y) and (z, w) of a pair group, from its Owen
/// seeds ([`sobol_scrambles`]) by another hash (one `pcg4d` a group instead of two).
#[inline]
pub fn sobol_keys(scrambles: [u32; 4]) -> [u32; 2] {
    [
        mix32(scrambles[0] ^ SOBOL_SALT),
        mix32(scrambles[2] ^ SOBOL_SALT),
    ]
}

/// Where a pixel's samples live when the image is too large for the 32-bit index: pixels whose
/// coordinates fit `b = (32 - log2_spp) / 2` bits keep `(seed, pixel)`; any other pixel is
/// placed at its coordinates modulo `2^b` in a tile of its own, whose seed is a hash of the
/// tile's coordinates (so its scrambles and digit permutations, and its points, are
/// independent of every other tile's, instead of repeating the first tile's). Each pixel still
/// gets a whole aligned block of indices, so its samples stay a (0, 2)-net; only the blue
/// noise across tile borders is lost. E.g. 1000x1000 at 8192 spp (b = 9): tiles of 512x512.
#[inline]
pub fn zsobol_tile(seed: u32, pixel: UVec2, log2_spp: u32) -> (u32, UVec2) {
    let b = (32 - log2_spp.min(32)) / 2;
    if b >= 16 {
        return (seed, pixel);
    }
    let (tx, ty) = (pixel.x >> b, pixel.y >> b);
    if tx == 0 && ty == 0 {
        return (seed, pixel);
    }
    let mask = (1u32 << b) - 1;
    let tile_seed = pcg4d([seed, tx, ty, SOBOL_SALT ^ 2])[0];
    (tile_seed, UVec2::new(pixel.x & mask, pixel.y & mask))
}

/// What both pairs of pair group `dim` share: `log2(spp)`, the Morton index of the pixel
/// in its tile ([`zsobol_morton_index`] of sample 0), the tile's Owen seeds
/// ([`sobol_scrambles`]) and index-permutation keys ([`sobol_keys`]), and which permutation
/// ([`zsobol_pair_bits`]).
#[derive(Clone, Copy, Debug)]
pub struct ZSobolSetup {
    pub log2_spp: u32,
    pub morton: u32,
    pub scrambles: [u32; 4],
    pub keys: [u32; 2],
    pub shuffled: bool,
}

/// What every pair group of a pixel's samples shares: its tile's seed ([`zsobol_tile`]),
/// its Morton index in the tile ([`zsobol_morton_index`] of sample 0) and `log2(spp)`. The
/// tracer computes it once per path segment for the segment's three groups (a division by
/// the image width, the tile and the Morton code are then not repeated).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SobolPixel {
    pub seed: u32,
    pub morton: u32,
    pub log2_spp: u32,
}

/// [`SobolPixel`] of (seed, pixel, spp).
#[inline]
pub fn sobol_pixel(seed: u32, pixel: UVec2, spp: u32) -> SobolPixel {
    let log2_spp = sobol_log2_spp(spp);
    let (seed, pixel) = zsobol_tile(seed, pixel, log2_spp);
    SobolPixel {
        seed,
        morton: zsobol_morton_index(pixel, 0, log2_spp),
        log2_spp,
    }
}

/// [`ZSobolSetup`] for (seed, pixel, spp, dim), tiles included ([`zsobol_tile`]).
#[inline]
pub fn zsobol_setup(seed: u32, pixel: UVec2, spp: u32, dim: u32, shuffled: bool) -> ZSobolSetup {
    zsobol_setup_at(sobol_pixel(seed, pixel, spp), dim, shuffled)
}

/// [`ZSobolSetup`] of pair group `dim` of a pixel.
#[inline]
pub fn zsobol_setup_at(p: SobolPixel, dim: u32, shuffled: bool) -> ZSobolSetup {
    let scrambles = sobol_scrambles(p.seed, dim);
    ZSobolSetup {
        log2_spp: p.log2_spp,
        morton: p.morton,
        scrambles,
        keys: sobol_keys(scrambles),
        shuffled,
    }
}

/// Pair `which` (0 or 1) of `z` at `sample`, as floats in `[0, 1)`.
#[inline(always)]
pub fn zsobol_pair(z: &ZSobolSetup, sample: u32, which: usize) -> glam::Vec2 {
    let (sx, sy) = (z.scrambles[2 * which], z.scrambles[2 * which + 1]);
    let a = zsobol_pair_bits(
        z.morton | zsobol_sample_bits(sample, z.log2_spp),
        z.log2_spp,
        z.keys[which],
        sx,
        sy,
        z.shuffled,
    );
    let f = |x: u32| rand_f32(x).min(SOBOL_ONE_MINUS_EPSILON);
    glam::Vec2::new(f(a[0]), f(a[1]))
}

/// Four numbers in `[0, 1)` for (seed, pixel (x, y), sample in `0..spp`, dim): `(x, y)` is
/// ZSobol pair `2 * dim`, `(z, w)` pair `2 * dim + 1`. Images too large for the 32-bit index
/// at this spp are split into tiles ([`zsobol_tile`]).
#[inline]
pub fn sobol4(seed: u32, pixel: UVec2, sample: u32, spp: u32, dim: u32) -> Vec4 {
    sobol4_of(false, seed, pixel, sample, spp, dim)
}

/// The first pair of [`sobol4`] alone, `(x, y)`, at half its cost: for the dimensions that
/// use two numbers or fewer (the camera's jitter, the roulette decision).
#[inline]
pub fn sobol2(seed: u32, pixel: UVec2, sample: u32, spp: u32, dim: u32) -> glam::Vec2 {
    sobol2_of(false, seed, pixel, sample, spp, dim)
}

/// [`sobol4`] with Burley's shuffle ([`shuffled_sample_index`]) in place of ZSobol's digit
/// permutations: the same kind of net in every pixel, for a fraction of the arithmetic
/// (`Sampler::Sobol`).
#[inline]
pub fn shuffled_sobol4(seed: u32, pixel: UVec2, sample: u32, spp: u32, dim: u32) -> Vec4 {
    sobol4_of(true, seed, pixel, sample, spp, dim)
}

/// The first pair of [`shuffled_sobol4`] alone.
#[inline]
pub fn shuffled_sobol2(seed: u32, pixel: UVec2, sample: u32, spp: u32, dim: u32) -> glam::Vec2 {
    sobol2_of(true, seed, pixel, sample, spp, dim)
}

/// [`shuffled_sobol4`] when `shuffled`, else [`sobol4`].
#[inline]
pub fn sobol4_of(shuffled: bool, seed: u32, pixel: UVec2, sample: u32, spp: u32, dim: u32) -> Vec4 {
    debug_assert!(sample < spp.max(1), "sample {sample} of {spp}");
    sobol4_at(shuffled, sobol_pixel(seed, pixel, spp), sample, dim)
}

/// [`sobol4_of`] of a pixel whose [`SobolPixel`] is known.
#[inline(always)]
pub fn sobol4_at(shuffled: bool, p: SobolPixel, sample: u32, dim: u32) -> Vec4 {
    let z = zsobol_setup_at(p, dim, shuffled);
    if shuffled {
        // zsobol_pair of both pairs, its four Owen scrambles written as one four-lane loop
        // that the compiler vectorises (the same integers: tested against zsobol_pair).
        let m = z.morton | zsobol_sample_bits(sample, z.log2_spp);
        let index = [
            shuffled_sample_index(m, z.keys[0]),
            shuffled_sample_index(m, z.keys[1]),
        ];
        let points = [
            index[0].reverse_bits(),
            sobol_dim1(index[0]),
            index[1].reverse_bits(),
            sobol_dim1(index[1]),
        ];
        let bits: [u32; 4] = std::array::from_fn(|i| fast_owen(points[i], z.scrambles[i]));
        let f = |x: u32| rand_f32(x).min(SOBOL_ONE_MINUS_EPSILON);
        return Vec4::new(f(bits[0]), f(bits[1]), f(bits[2]), f(bits[3]));
    }
    let (a, b) = (zsobol_pair(&z, sample, 0), zsobol_pair(&z, sample, 1));
    Vec4::new(a.x, a.y, b.x, b.y)
}

/// [`sobol2_of`] of a pixel whose [`SobolPixel`] is known.
#[inline(always)]
pub fn sobol2_at(shuffled: bool, p: SobolPixel, sample: u32, dim: u32) -> glam::Vec2 {
    zsobol_pair(&zsobol_setup_at(p, dim, shuffled), sample, 0)
}

/// [`shuffled_sobol2`] when `shuffled`, else [`sobol2`].
#[inline]
pub fn sobol2_of(
    shuffled: bool,
    seed: u32,
    pixel: UVec2,
    sample: u32,
    spp: u32,
    dim: u32,
) -> glam::Vec2 {
    debug_assert!(sample < spp.max(1), "sample {sample} of {spp}");
    sobol2_at(shuffled, sobol_pixel(seed, pixel, spp), sample, dim)
}

/// The constant multipliers of [`fast_owen`]'s hash (pbrt-v4's), first to last: every form
/// of it takes them from here, and `sobol.wgsl`'s `fast_owen` holds the same (tested).
const OWEN_MULS: [u32; 3] = [0x3d20_adea, 0x0552_6c56, 0x53a2_2864];

/// [`fast_owen`] between its two bit reversals, its multiplier `(seed >> 16) | 1` given, so
/// that a reversal that another cancels can be left out ([`SegmentKeys`]).
#[inline(always)]
fn owen_body(v: u32, seed: u32, mul: u32) -> u32 {
    let mut v = v;
    v ^= v.wrapping_mul(OWEN_MULS[0]);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul(mul);
    v ^= v.wrapping_mul(OWEN_MULS[1]);
    v ^= v.wrapping_mul(OWEN_MULS[2]);
    v
}

/// [`sobol_dim1`] without its final bit reversal (the prefix XOR of the index's bits).
#[inline(always)]
fn sobol_dim1_unreversed(a: u32) -> u32 {
    let mut y = a;
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    y ^= (y >> 16) & 0x0000_ffff;
    y
}

/// The hashes of the three pair groups a path segment draws from with the `Sobol` sampler
/// (the light's four numbers, the scattered direction's four, the roulette's first) for one
/// seed and segment: what [`sobol_scrambles`] and [`sobol_keys`] give for each group, laid out
/// as the lanes of [`SegmentKeys::draw`] (the same for every path of a render, so the CPU
/// computes them once per segment number).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
pub struct SegmentKeys {
    /// The index keys, lanes: light pair 0, light pair 1, scatter pair 0, scatter pair 1,
    /// roulette pair 0, then repeats of it.
    keys: [u32; 8],
    /// Each key's `(key >> 16) | 1`.
    key_muls: [u32; 8],
    /// The Owen seeds, lanes: the light's x, y, z, w, the scattered direction's x, y, z, w.
    scrambles: [u32; 8],
    /// Each seed's `(seed >> 16) | 1`.
    scramble_muls: [u32; 8],
    /// [`SegmentKeys::draw_pairs`]' index keys, lanes: light pair 0, scatter pair 0, (light
    /// pair 0, twice), roulette pair 0, camera, (roulette pair 0, twice).
    pair_keys: [u32; 8],
    /// Each of `pair_keys`' `(key >> 16) | 1`.
    pair_key_muls: [u32; 8],
    /// [`SegmentKeys::draw_pairs`]' Owen seeds, lanes: the light's x, y, the scattered
    /// direction's x, y, the roulette's x (and again), the camera's x, y.
    pair_scrambles: [u32; 8],
    /// Each of `pair_scrambles`' `(seed >> 16) | 1`.
    pair_scramble_muls: [u32; 8],
    /// [`SegmentKeys::draw_pairs4_avx512`]'s index keys, the four distinct ones of
    /// `pair_keys`: light pair 0, scatter pair 0, roulette pair 0, camera (one 128-bit lane).
    quad_keys: [u32; 4],
    /// Each of `quad_keys`' `(key >> 16) | 1`.
    quad_key_muls: [u32; 4],
    /// The roulette's x seed and its multiplier.
    roulette: [u32; 2],
    /// The camera group's (`DIM_CAMERA`, drawn at segment 0 only) index key and its x and y
    /// Owen seeds.
    camera: [u32; 3],
    /// The seed these were hashed under.
    seed: u32,
}

// The AVX2 forms' aligned loads: every array of eight words on a 32-byte boundary, of four
// on a 16-byte one.
const _: () = {
    use std::mem::offset_of;
    assert!(offset_of!(SegmentKeys, keys) % 32 == 0);
    assert!(offset_of!(SegmentKeys, key_muls) % 32 == 0);
    assert!(offset_of!(SegmentKeys, scrambles) % 32 == 0);
    assert!(offset_of!(SegmentKeys, scramble_muls) % 32 == 0);
    assert!(offset_of!(SegmentKeys, pair_keys) % 32 == 0);
    assert!(offset_of!(SegmentKeys, pair_key_muls) % 32 == 0);
    assert!(offset_of!(SegmentKeys, pair_scrambles) % 32 == 0);
    assert!(offset_of!(SegmentKeys, pair_scramble_muls) % 32 == 0);
    assert!(offset_of!(SegmentKeys, quad_keys) % 16 == 0);
    assert!(offset_of!(SegmentKeys, quad_key_muls) % 16 == 0);
    assert!(size_of::<SegmentKeys>() == 320);
};

/// The numbers a path segment of diffuse surfaces draws ([`SegmentKeys::draw_pairs`]): the
/// first pair of its light and scatter groups, the roulette's first number and the camera
/// group's pair (used at segment 0 only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentPairs {
    pub light: glam::Vec2,
    pub scatter: glam::Vec2,
    pub roulette: f32,
    pub camera: glam::Vec2,
}

impl SegmentKeys {
    /// The seed these keys were hashed under: [`SegmentKeys::draw`] gives the numbers of the
    /// pixels whose [`SobolPixel::seed`] it is.
    pub fn seed(&self) -> u32 {
        self.seed
    }

    /// The keys of segment `bounce`'s groups `DIM_LIGHT`, `DIM_SCATTER` and `DIM_ROULETTE`
    /// under `seed` (a [`SobolPixel`]'s).
    pub fn new(seed: u32, bounce: u32) -> Self {
        use crate::gpu_types::{DIM_CAMERA, DIM_LIGHT, DIM_ROULETTE, DIM_SCATTER, DIMS_PER_BOUNCE};
        let group = |dim: u32| {
            let s = sobol_scrambles(seed, bounce * DIMS_PER_BOUNCE + dim);
            (s, sobol_keys(s))
        };
        let (light, scatter, roulette, camera) = (
            group(DIM_LIGHT),
            group(DIM_SCATTER),
            group(DIM_ROULETTE),
            group(DIM_CAMERA),
        );
        let keys = [
            light.1[0],
            light.1[1],
            scatter.1[0],
            scatter.1[1],
            roulette.1[0],
            roulette.1[0],
            roulette.1[0],
            roulette.1[0],
        ];
        let scrambles = [
            light.0[0],
            light.0[1],
            light.0[2],
            light.0[3],
            scatter.0[0],
            scatter.0[1],
            scatter.0[2],
            scatter.0[3],
        ];
        let mul = |k: u32| (k >> 16) | 1;
        let (l, sc, r, c) = (light.1[0], scatter.1[0], roulette.1[0], camera.1[0]);
        let pair_keys = [l, sc, l, l, r, c, r, r];
        let pair_scrambles = [
            light.0[0],
            light.0[1],
            scatter.0[0],
            scatter.0[1],
            roulette.0[0],
            roulette.0[0],
            camera.0[0],
            camera.0[1],
        ];
        Self {
            keys,
            key_muls: keys.map(mul),
            scrambles,
            scramble_muls: scrambles.map(mul),
            roulette: [roulette.0[0], mul(roulette.0[0])],
            camera: [camera.1[0], camera.0[0], camera.0[1]],
            seed,
            pair_keys,
            pair_key_muls: pair_keys.map(mul),
            pair_scrambles,
            pair_scramble_muls: pair_scrambles.map(mul),
            quad_keys: [l, sc, r, c],
            quad_key_muls: [l, sc, r, c].map(mul),
        }
    }

    /// What a segment of diffuse surfaces draws ([`SegmentPairs`]): the `x`, `y` of
    /// [`SegmentKeys::draw`]'s light and scatter groups and its roulette number, and (these
    /// keys being segment 0's) [`SegmentKeys::draw_camera`]'s pair, bit for bit: one pass
    /// of index hashes and one of scrambles over eight lanes, where `draw` and `draw_camera`
    /// take two passes and a scalar hash, and another path of scalar hashes.
    #[inline(always)]
    pub fn draw_pairs(&self, p: SobolPixel, sample: u32) -> SegmentPairs {
        debug_assert_eq!(p.seed, self.seed);
        let m = p.morton | zsobol_sample_bits(sample, p.log2_spp);
        let rm = m.reverse_bits();
        let index: [u32; 8] = std::array::from_fn(|j| {
            owen_body(rm, self.pair_keys[j], self.pair_key_muls[j]).reverse_bits()
        });
        // As `_mm256_unpacklo_epi32(index, pre)`: lanes 0, 1 and 4, 5 with their prefixes.
        let pre = |j: usize| sobol_dim1_unreversed(index[j]);
        let points = [
            index[0],
            pre(0),
            index[1],
            pre(1),
            index[4],
            pre(4),
            index[5],
            pre(5),
        ];
        let f = |j: usize| {
            let bits = owen_body(
                points[j],
                self.pair_scrambles[j],
                self.pair_scramble_muls[j],
            )
            .reverse_bits();
            rand_f32(bits).min(SOBOL_ONE_MINUS_EPSILON)
        };
        SegmentPairs {
            light: glam::Vec2::new(f(0), f(1)),
            scatter: glam::Vec2::new(f(2), f(3)),
            roulette: f(4),
            camera: glam::Vec2::new(f(6), f(7)),
        }
    }

    /// The camera's two numbers at pixel `p`, `sample` (`p.seed` must be
    /// [`SegmentKeys::seed`]'s; these keys must be segment 0's): [`sobol2_at`]`(true, ..)` of
    /// the group `DIM_CAMERA`, bit for bit, without hashing its keys again for every path.
    #[inline(always)]
    pub fn draw_camera(&self, p: SobolPixel, sample: u32) -> glam::Vec2 {
        debug_assert_eq!(p.seed, self.seed);
        let [key, sx, sy] = self.camera;
        let m = p.morton | zsobol_sample_bits(sample, p.log2_spp);
        let a = zsobol_pair_bits(m, p.log2_spp, key, sx, sy, true);
        let f = |x: u32| rand_f32(x).min(SOBOL_ONE_MINUS_EPSILON);
        glam::Vec2::new(f(a[0]), f(a[1]))
    }

    /// The segment's numbers at pixel `p`, `sample` (`p.seed` must be [`SegmentKeys::seed`]'s):
    /// [`sobol4_at`]`(true, ..)` of its light and scatter groups and the `x` of
    /// [`sobol2_at`]`(true, ..)` of its roulette group, bit for bit, as eight-lane loops
    /// (the index hashes, then the scrambles) with the reversals that cancel left out.
    #[inline(always)]
    pub fn draw(&self, p: SobolPixel, sample: u32) -> (Vec4, Vec4, f32) {
        debug_assert_eq!(p.seed, self.seed);
        let m = p.morton | zsobol_sample_bits(sample, p.log2_spp);
        let rm = m.reverse_bits();
        // shuffled_sample_index(m, key) for the five keys.
        let index: [u32; 8] =
            std::array::from_fn(|j| owen_body(rm, self.keys[j], self.key_muls[j]).reverse_bits());
        let pre: [u32; 4] = std::array::from_fn(|j| sobol_dim1_unreversed(index[j]));
        // fast_owen(index.reverse_bits(), sx) and fast_owen(sobol_dim1(index), sy).
        let points = [
            index[0], pre[0], index[1], pre[1], index[2], pre[2], index[3], pre[3],
        ];
        let bits: [u32; 8] = std::array::from_fn(|j| {
            owen_body(points[j], self.scrambles[j], self.scramble_muls[j]).reverse_bits()
        });
        let r = owen_body(index[4], self.roulette[0], self.roulette[1]).reverse_bits();
        let f = |x: u32| rand_f32(x).min(SOBOL_ONE_MINUS_EPSILON);
        let v: [f32; 8] = std::array::from_fn(|j| f(bits[j]));
        (
            Vec4::new(v[0], v[1], v[2], v[3]),
            Vec4::new(v[4], v[5], v[6], v[7]),
            f(r),
        )
    }
}

#[cfg(target_arch = "x86_64")]
impl SegmentKeys {
    /// [`SegmentKeys::draw`] in AVX2 instructions, bit for bit: each of its eight-lane steps
    /// one instruction (or a few: the bit reversals by byte shuffles), which the compiler does
    /// not find for the scalar loops (the sampler was ~15 % of a Cornell box segment's
    /// instructions).
    ///
    /// # Safety
    /// The CPU must have AVX2 (`cpu::isa`'s x86-64-v3 and v4 copies call it).
    #[inline(always)]
    pub unsafe fn draw_avx2(&self, p: SobolPixel, sample: u32) -> (Vec4, Vec4, f32) {
        use std::arch::x86_64::*;
        debug_assert_eq!(p.seed, self.seed);
        // SAFETY: the caller's CPU has AVX2; the loads read this struct's 32-byte-aligned
        // arrays of eight words.
        unsafe {
            let (index, pre) = avx2::indices(p, sample, &self.keys, &self.key_muls);
            // [index0, pre0, index1, pre1, index2, pre2, index3, pre3].
            let points = _mm256_permute2x128_si256::<0x20>(
                _mm256_unpacklo_epi32(index, pre),
                _mm256_unpackhi_epi32(index, pre),
            );
            let v = avx2::scrambled(points, &self.scrambles, &self.scramble_muls);
            let index4 = _mm256_extract_epi32::<4>(index) as u32;
            let r = owen_body(index4, self.roulette[0], self.roulette[1]).reverse_bits();
            (
                Vec4::new(v[0], v[1], v[2], v[3]),
                Vec4::new(v[4], v[5], v[6], v[7]),
                rand_f32(r).min(SOBOL_ONE_MINUS_EPSILON),
            )
        }
    }
}

/// The eight-lane steps of [`SegmentKeys::draw_avx2`] and [`SegmentKeys::draw_pairs_avx2`]:
/// each of the scalar forms' steps one instruction (or a few: the bit reversals by byte
/// shuffles). Every function needs a CPU with AVX2 (their callers' contracts).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::{OWEN_MULS, SOBOL_ONE_MINUS_EPSILON, SobolPixel, zsobol_sample_bits};

    /// The index hashes of pixel `p`'s `sample` under eight keys (`keys`, their `muls`:
    /// `shuffled_sample_index`, lane by lane) and their prefix XORs (`sobol_dim1` before its
    /// reversal): `(index, pre)`. `keys` and `muls` must be 32-byte aligned (`SegmentKeys`'
    /// arrays).
    #[inline(always)]
    pub(super) unsafe fn indices(
        p: SobolPixel,
        sample: u32,
        keys: &[u32; 8],
        muls: &[u32; 8],
    ) -> (__m256i, __m256i) {
        // SAFETY: the caller's CPU has AVX2; the loads read two aligned arrays of eight words.
        unsafe {
            let m = p.morton | zsobol_sample_bits(sample, p.log2_spp);
            let index = reverse(owen(
                _mm256_set1_epi32(m.reverse_bits() as i32),
                _mm256_load_si256(keys.as_ptr().cast()),
                _mm256_load_si256(muls.as_ptr().cast()),
            ));
            (index, dim1_unreversed(index))
        }
    }

    /// `points` Owen-scrambled under eight seeds (`seeds`, their `muls`; `fast_owen` of the
    /// reversed points, lane by lane) as numbers in `[0, 1)`. `seeds` and `muls` must be
    /// 32-byte aligned.
    #[inline(always)]
    pub(super) unsafe fn scrambled(points: __m256i, seeds: &[u32; 8], muls: &[u32; 8]) -> [f32; 8] {
        // SAFETY: the caller's CPU has AVX2; the loads read two aligned arrays of eight words.
        unsafe {
            let bits = reverse(owen(
                points,
                _mm256_load_si256(seeds.as_ptr().cast()),
                _mm256_load_si256(muls.as_ptr().cast()),
            ));
            let mut v = [0.0f32; 8];
            _mm256_storeu_ps(v.as_mut_ptr(), unit_floats(bits));
            v
        }
    }

    /// `owen_body`, lane by lane.
    #[inline(always)]
    pub(super) unsafe fn owen(v: __m256i, seed: __m256i, mul: __m256i) -> __m256i {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            let splat = |x: u32| _mm256_set1_epi32(x as i32);
            let mut v = _mm256_xor_si256(v, _mm256_mullo_epi32(v, splat(OWEN_MULS[0])));
            v = _mm256_add_epi32(v, seed);
            v = _mm256_mullo_epi32(v, mul);
            v = _mm256_xor_si256(v, _mm256_mullo_epi32(v, splat(OWEN_MULS[1])));
            _mm256_xor_si256(v, _mm256_mullo_epi32(v, splat(OWEN_MULS[2])))
        }
    }

    /// `u32::reverse_bits`, lane by lane: the bytes reversed, then each byte's bits by
    /// two table lookups of its nibbles.
    #[inline(always)]
    pub(super) unsafe fn reverse(v: __m256i) -> __m256i {
        // Each nibble's bits reversed, placed high (for the low nibble) or low.
        const R: [u8; 16] = [
            0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf,
        ];
        const HI: [u8; 32] = {
            let mut t = [0u8; 32];
            let mut i = 0;
            while i < 32 {
                t[i] = R[i % 16] << 4;
                i += 1;
            }
            t
        };
        const LO: [u8; 32] = {
            let mut t = [0u8; 32];
            let mut i = 0;
            while i < 32 {
                t[i] = R[i % 16];
                i += 1;
            }
            t
        };
        // SAFETY: the caller's CPU has AVX2; the loads read the 32-byte tables above.
        unsafe {
            let bytes = _mm256_setr_epi8(
                3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12, 3, 2, 1, 0, 7, 6, 5, 4, 11,
                10, 9, 8, 15, 14, 13, 12,
            );
            let v = _mm256_shuffle_epi8(v, bytes);
            let nibble = _mm256_set1_epi8(0x0f);
            let (hi, lo) = (&HI, &LO);
            let hi_of_lo = _mm256_loadu_si256(hi.as_ptr().cast());
            let lo_of_hi = _mm256_loadu_si256(lo.as_ptr().cast());
            let low = _mm256_and_si256(v, nibble);
            let high = _mm256_and_si256(_mm256_srli_epi16::<4>(v), nibble);
            _mm256_or_si256(
                _mm256_shuffle_epi8(hi_of_lo, low),
                _mm256_shuffle_epi8(lo_of_hi, high),
            )
        }
    }

    /// `sobol_dim1_unreversed`, lane by lane.
    #[inline(always)]
    pub(super) unsafe fn dim1_unreversed(index: __m256i) -> __m256i {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            let mut pre = index;
            for (shift, mask) in [
                (1, 0x5555_5555u32),
                (2, 0x3333_3333),
                (4, 0x0f0f_0f0f),
                (8, 0x00ff_00ff),
                (16, 0x0000_ffff),
            ] {
                let shifted = _mm256_srlv_epi32(pre, _mm256_set1_epi32(shift));
                pre = _mm256_xor_si256(
                    pre,
                    _mm256_and_si256(shifted, _mm256_set1_epi32(mask as i32)),
                );
            }
            pre
        }
    }

    /// `rand_f32(x).min(SOBOL_ONE_MINUS_EPSILON)`, lane by lane: exact (24 bits), never NaN.
    #[inline(always)]
    pub(super) unsafe fn unit_floats(bits: __m256i) -> __m256 {
        // SAFETY: the caller's CPU has AVX2.
        unsafe {
            _mm256_min_ps(
                _mm256_mul_ps(
                    _mm256_cvtepi32_ps(_mm256_srli_epi32::<8>(bits)),
                    _mm256_set1_ps(1.0 / 16_777_216.0),
                ),
                _mm256_set1_ps(SOBOL_ONE_MINUS_EPSILON),
            )
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl SegmentKeys {
    /// [`SegmentKeys::draw_pairs`] in AVX2 instructions, bit for bit (the forms of
    /// [`SegmentKeys::draw_avx2`]).
    ///
    /// # Safety
    /// The CPU must have AVX2 (`cpu::isa`'s x86-64-v3 and v4 copies call it).
    #[inline(always)]
    pub unsafe fn draw_pairs_avx2(&self, p: SobolPixel, sample: u32) -> SegmentPairs {
        use std::arch::x86_64::*;
        debug_assert_eq!(p.seed, self.seed);
        // SAFETY: the caller's CPU has AVX2; the loads read this struct's 32-byte-aligned
        // arrays of eight words.
        unsafe {
            let (index, pre) = avx2::indices(p, sample, &self.pair_keys, &self.pair_key_muls);
            let points = _mm256_unpacklo_epi32(index, pre);
            let v = avx2::scrambled(points, &self.pair_scrambles, &self.pair_scramble_muls);
            SegmentPairs {
                light: glam::Vec2::new(v[0], v[1]),
                scatter: glam::Vec2::new(v[2], v[3]),
                roulette: v[4],
                camera: glam::Vec2::new(v[6], v[7]),
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl SegmentKeys {
    /// [`SegmentKeys::draw_pairs`] of four paths at once, bit for bit: path `k` at pixel
    /// `p[k]`, `sample[k]`, under `keys[k]` (its segment's; `p[k].seed` must be their seed).
    /// The index hashes of the four paths' four distinct keys in one sixteen-lane pass, the
    /// scrambles of two paths' eight points in each of two more, where four
    /// [`SegmentKeys::draw_pairs_avx2`] take eight eight-lane passes (half of their first
    /// passes' lanes repeats a key).
    ///
    /// # Safety
    /// The CPU must have AVX-512 F and BW (`cpu::isa`'s x86-64-v4 copies call it).
    #[inline(always)]
    pub unsafe fn draw_pairs4_avx512(
        keys: [&SegmentKeys; 4],
        p: [SobolPixel; 4],
        sample: [u32; 4],
    ) -> [SegmentPairs; 4] {
        use std::arch::x86_64::*;
        // SAFETY: the caller's CPU has AVX-512 F and BW; the loads read the keys' 16- and
        // 32-byte-aligned arrays of four and eight words.
        unsafe {
            for k in 0..4 {
                debug_assert_eq!(p[k].seed, keys[k].seed);
            }
            let index_of = |k: usize| p[k].morton | zsobol_sample_bits(sample[k], p[k].log2_spp);
            let m = [index_of(0), index_of(1), index_of(2), index_of(3)];
            // Path k's index in each lane of 128-bit lane k, reversed.
            let rm = avx512::reverse(_mm512_permutexvar_epi32(
                _mm512_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3),
                _mm512_castsi128_si512(_mm_loadu_si128(m.as_ptr().cast())),
            ));
            let quad_keys = [0, 1, 2, 3].map(|k| &keys[k].quad_keys);
            let quad_muls = [0, 1, 2, 3].map(|k| &keys[k].quad_key_muls);
            // Lanes per path: light pair 0, scatter pair 0, roulette pair 0, camera.
            let index = avx512::reverse(avx512::owen(
                rm,
                avx512::quads(quad_keys),
                avx512::quads(quad_muls),
            ));
            let pre = avx512::dim1_unreversed(index);
            // Per path: [light x, y, scatter x, y] and [roulette x, (y), camera x, y].
            let (lo, hi) = (
                _mm512_unpacklo_epi32(index, pre),
                _mm512_unpackhi_epi32(index, pre),
            );
            // Two paths' points: [lo a, lo b, hi a, hi b], scrambled.
            let [d0, d1] = avx512::two_paths(
                _mm512_shuffle_i32x4::<0b01_00_01_00>(lo, hi),
                keys[0],
                keys[1],
            );
            let [d2, d3] = avx512::two_paths(
                _mm512_shuffle_i32x4::<0b11_10_11_10>(lo, hi),
                keys[2],
                keys[3],
            );
            [d0, d1, d2, d3]
        }
    }
}

/// [`avx2`]'s steps sixteen lanes at a time. Every function needs a CPU with AVX-512 F and
/// BW (their callers' contracts).
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::*;

    use super::{OWEN_MULS, SOBOL_ONE_MINUS_EPSILON, SegmentKeys, SegmentPairs};

    /// Four arrays of four words (16-byte aligned), one a 128-bit lane.
    #[inline(always)]
    pub(super) unsafe fn quads(a: [&[u32; 4]; 4]) -> __m512i {
        // SAFETY: the caller's CPU has AVX-512 F; the loads read aligned arrays of four words.
        unsafe {
            let v = _mm512_castsi128_si512(_mm_load_si128(a[0].as_ptr().cast()));
            let v = _mm512_inserti32x4::<1>(v, _mm_load_si128(a[1].as_ptr().cast()));
            let v = _mm512_inserti32x4::<2>(v, _mm_load_si128(a[2].as_ptr().cast()));
            _mm512_inserti32x4::<3>(v, _mm_load_si128(a[3].as_ptr().cast()))
        }
    }

    /// Two arrays of eight words (32-byte aligned) `[a0, a1]` and `[b0, b1]` (halves) as
    /// `[a0, b0, a1, b1]`.
    #[inline(always)]
    pub(super) unsafe fn halves(a: &[u32; 8], b: &[u32; 8]) -> __m512i {
        // SAFETY: the caller's CPU has AVX-512 F; the loads read aligned arrays of eight words.
        unsafe {
            let v = _mm512_inserti64x4::<1>(
                _mm512_castsi256_si512(_mm256_load_si256(a.as_ptr().cast())),
                _mm256_load_si256(b.as_ptr().cast()),
            );
            _mm512_shuffle_i32x4::<0b11_01_10_00>(v, v)
        }
    }

    /// The pairs of two paths from their points `[light and scatter of a, of b, roulette and
    /// camera of a, of b]`, scrambled under `a`'s and `b`'s seeds.
    #[inline(always)]
    pub(super) unsafe fn two_paths(
        points: __m512i,
        a: &SegmentKeys,
        b: &SegmentKeys,
    ) -> [SegmentPairs; 2] {
        // SAFETY: the caller's CPU has AVX-512 F and BW.
        unsafe {
            let bits = reverse(owen(
                points,
                halves(&a.pair_scrambles, &b.pair_scrambles),
                halves(&a.pair_scramble_muls, &b.pair_scramble_muls),
            ));
            let mut v = [0.0f32; 16];
            _mm512_storeu_ps(v.as_mut_ptr(), unit_floats(bits));
            [
                SegmentPairs {
                    light: glam::Vec2::new(v[0], v[1]),
                    scatter: glam::Vec2::new(v[2], v[3]),
                    roulette: v[8],
                    camera: glam::Vec2::new(v[10], v[11]),
                },
                SegmentPairs {
                    light: glam::Vec2::new(v[4], v[5]),
                    scatter: glam::Vec2::new(v[6], v[7]),
                    roulette: v[12],
                    camera: glam::Vec2::new(v[14], v[15]),
                },
            ]
        }
    }

    /// `owen_body`, lane by lane.
    #[inline(always)]
    pub(super) unsafe fn owen(v: __m512i, seed: __m512i, mul: __m512i) -> __m512i {
        // SAFETY: the caller's CPU has AVX-512 F.
        unsafe {
            let splat = |x: u32| _mm512_set1_epi32(x as i32);
            let mut v = _mm512_xor_si512(v, _mm512_mullo_epi32(v, splat(OWEN_MULS[0])));
            v = _mm512_add_epi32(v, seed);
            v = _mm512_mullo_epi32(v, mul);
            v = _mm512_xor_si512(v, _mm512_mullo_epi32(v, splat(OWEN_MULS[1])));
            _mm512_xor_si512(v, _mm512_mullo_epi32(v, splat(OWEN_MULS[2])))
        }
    }

    /// `u32::reverse_bits`, lane by lane (as `avx2::reverse`: the bytes reversed, then each
    /// byte's bits by two table lookups of its nibbles).
    #[inline(always)]
    pub(super) unsafe fn reverse(v: __m512i) -> __m512i {
        // SAFETY: the caller's CPU has AVX-512 F and BW.
        unsafe {
            let bytes = _mm512_set4_epi32(0x0c0d_0e0f, 0x0809_0a0b, 0x0405_0607, 0x0001_0203);
            let v = _mm512_shuffle_epi8(v, bytes);
            // Each nibble's bits reversed, placed high (for the low nibble) or low.
            let lo_of_hi = _mm512_set4_epi32(0x0f07_0b03, 0x0d05_0901, 0x0e06_0a02, 0x0c04_0800);
            let hi_of_lo = _mm512_slli_epi32::<4>(lo_of_hi);
            let nibble = _mm512_set1_epi8(0x0f);
            let low = _mm512_and_si512(v, nibble);
            let high = _mm512_and_si512(_mm512_srli_epi16::<4>(v), nibble);
            _mm512_or_si512(
                _mm512_shuffle_epi8(hi_of_lo, low),
                _mm512_shuffle_epi8(lo_of_hi, high),
            )
        }
    }

    /// `sobol_dim1_unreversed`, lane by lane.
    #[inline(always)]
    pub(super) unsafe fn dim1_unreversed(index: __m512i) -> __m512i {
        // SAFETY: the caller's CPU has AVX-512 F.
        unsafe {
            let step = |y: __m512i, shifted: __m512i, mask: u32| {
                _mm512_xor_si512(y, _mm512_and_si512(shifted, _mm512_set1_epi32(mask as i32)))
            };
            let mut y = index;
            y = step(y, _mm512_srli_epi32::<1>(y), 0x5555_5555);
            y = step(y, _mm512_srli_epi32::<2>(y), 0x3333_3333);
            y = step(y, _mm512_srli_epi32::<4>(y), 0x0f0f_0f0f);
            y = step(y, _mm512_srli_epi32::<8>(y), 0x00ff_00ff);
            step(y, _mm512_srli_epi32::<16>(y), 0x0000_ffff)
        }
    }

    /// `rand_f32(x).min(SOBOL_ONE_MINUS_EPSILON)`, lane by lane (`avx2::unit_floats`).
    #[inline(always)]
    pub(super) unsafe fn unit_floats(bits: __m512i) -> __m512 {
        // SAFETY: the caller's CPU has AVX-512 F.
        unsafe {
            _mm512_min_ps(
                _mm512_mul_ps(
                    _mm512_cvtepi32_ps(_mm512_srli_epi32::<8>(bits)),
                    _mm512_set1_ps(1.0 / 16_777_216.0),
                ),
                _mm512_set1_ps(SOBOL_ONE_MINUS_EPSILON),
            )
        }
    }
}

/// Segments whose [`SegmentKeys`] [`segment_keys`] makes at most (320 KiB): paths that go on
/// past them hash their groups as they draw.
pub const SEGMENT_KEYS_MAX: u32 = 1024;

/// The [`SegmentKeys`] of segments `0..=scene.max_bounces` (at most [`SEGMENT_KEYS_MAX`]) for
/// `scene.seed` when `scene` draws from the `Sobol` sampler; empty for the others.
pub fn segment_keys(scene: &crate::gpu_types::SceneUniforms) -> Vec<SegmentKeys> {
    if scene.sampler != crate::gpu_types::SAMPLER_SOBOL {
        return Vec::new();
    }
    let n = scene.max_bounces.saturating_add(1).min(SEGMENT_KEYS_MAX);
    (0..n).map(|b| SegmentKeys::new(scene.seed, b)).collect()
}

/// The WGSL source of the functions above (it uses `pcg4d` and `rand_f32` from `rng.wgsl`).
pub const SOBOL_WGSL: &str = include_str!("sobol.wgsl");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::rand4;

    /// The first 32 columns of pbrt-v4's `SobolMatrices32` for dimension 1
    /// (`util/sobolmatrices.cpp`), as the Sobol' construction gives them for the primitive
    /// polynomial x + 1 with m_1 = 1.
    fn dim1_columns_by_construction() -> [u32; 32] {
        // Bratley & Fox: v_k = v_{k-1} ^ (v_{k-1} >> 1) for degree 1, v_0 = 1 << 31.
        let mut v = [0u32; 32];
        v[0] = 1 << 31;
        for k in 1..32 {
            v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        }
        v
    }

    #[test]
    fn sobol_dim1_is_the_generator_matrix_product() {
        let cols = dim1_columns_by_construction();
        // pbrt-v4's table starts 0x80000000, 0xc0000000, 0xa0000000, 0xf0000000, 0x88000000.
        assert_eq!(
            &cols[..5],
            &[
                0x8000_0000,
                0xc000_0000,
                0xa000_0000,
                0xf000_0000,
                0x8800_0000
            ]
        );
        let mut x = 0x1234_5678u32;
        for _ in 0..10_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let mut v = 0;
            for (bit, c) in cols.iter().enumerate() {
                if (x >> bit) & 1 == 1 {
                    v ^= c;
                }
            }
            assert_eq!(sobol_dim1(x), v, "index {x:#x}");
        }
    }

    #[test]
    fn permutation_table_is_all_24_permutations() {
        let mut seen = std::collections::HashSet::new();
        for p in 0..24 {
            let perm: Vec<u32> = (0..4).map(|d| zsobol_permute_digit(p, d)).collect();
            assert_eq!(perm, PERMUTATIONS[p as usize].to_vec());
            let mut sorted = perm.clone();
            sorted.sort();
            assert_eq!(sorted, vec![0, 1, 2, 3]);
            seen.insert(perm);
        }
        assert_eq!(seen.len(), 24);
    }

    #[test]
    fn wgsl_has_the_rust_constants() {
        for w in ZSOBOL_PERMUTATIONS {
            assert!(SOBOL_WGSL.contains(&format!("{w:#010x}u")), "{w:#010x}");
        }
        assert!(SOBOL_WGSL.contains(&format!("{SOBOL_SALT:#010x}u")));
        for m in OWEN_MULS {
            assert!(SOBOL_WGSL.contains(&format!("v * {m:#010x}u")), "{m:#010x}");
        }
    }

    #[test]
    fn log2_spp_rounds_up() {
        let cases = [
            (0, 0),
            (1, 0),
            (2, 1),
            (3, 2),
            (4, 2),
            (5, 3),
            (64, 6),
            (65, 7),
        ];
        for (spp, l) in cases {
            assert_eq!(sobol_log2_spp(spp), l, "spp {spp}");
        }
        assert_eq!(sobol_log2_spp(u32::MAX), 32);
    }

    /// Both index permutations under one name: ZSobol's digits, or Burley's shuffle.
    fn permuted_index(shuffled: bool, m: u32, log2_spp: u32, key: u32) -> u32 {
        if shuffled {
            shuffled_sample_index(m, key)
        } else {
            zsobol_sample_index(m, log2_spp, key)
        }
    }

    #[test]
    fn sample_index_is_a_bijection_keeping_pixel_blocks() {
        // Every pixel's 2^k samples map to one aligned block of 2^k indices, and distinct
        // pixels to distinct blocks (odd and even k), under both permutations.
        for (shuffled, log2_spp) in [false, true]
            .into_iter()
            .flat_map(|s| [0, 1, 2, 3, 4, 5].map(|k| (s, k)))
        {
            let mut blocks = std::collections::HashSet::new();
            for y in 0..16 {
                for x in 0..16 {
                    let px = UVec2::new(x, y);
                    let idx: Vec<u32> = (0..1 << log2_spp)
                        .map(|s| {
                            permuted_index(
                                shuffled,
                                zsobol_morton_index(px, s, log2_spp),
                                log2_spp,
                                0xdead_beef,
                            )
                        })
                        .collect();
                    let block = idx[0] >> log2_spp;
                    let mut low: Vec<u32> = idx
                        .iter()
                        .map(|i| {
                            assert_eq!(i >> log2_spp, block, "pixel {px} k {log2_spp}");
                            i & ((1 << log2_spp) - 1)
                        })
                        .collect();
                    low.sort();
                    assert_eq!(low, (0..1 << log2_spp).collect::<Vec<u32>>());
                    assert!(blocks.insert(block), "block reused, k {log2_spp}");
                }
            }
        }
    }

    #[test]
    fn shuffle_keeps_every_aligned_block_and_depends_on_the_key() {
        // Burley's shuffle is nested: for every j, the 2^j indices sharing their bits above
        // j land on 2^j indices sharing theirs (any power-of-2 prefix of a pixel's samples is
        // an aligned block, so a net). Each bit is flipped by a hash of the bits above it, so
        // bit 31 by the key alone.
        for key in [0u32, 1, 0xdead_beef, 0x8000_0000] {
            for j in [1u32, 3, 8, 12] {
                for base in [0u32, 0x1234_5000, 0xffff_f000, 0x0abc_d000] {
                    let base = base & !((1u32 << j) - 1);
                    let mut low: Vec<u32> = (0..1u32 << j)
                        .map(|i| {
                            let out = shuffled_sample_index(base | i, key);
                            assert_eq!(
                                out >> j,
                                shuffled_sample_index(base, key) >> j,
                                "key {key:#x}, j {j}"
                            );
                            out & ((1 << j) - 1)
                        })
                        .collect();
                    low.sort();
                    assert_eq!(low, (0..1u32 << j).collect::<Vec<_>>());
                }
            }
        }
        // Different keys order a pixel's 256 samples differently (padding): of the 256
        // positions, two keys agree on few (independent orders: 1 expected).
        let order = |key| (0..256u32).map(move |i| shuffled_sample_index(0x4500 | i, key));
        let same = order(7).zip(order(8)).filter(|(a, b)| a == b).count();
        assert!(same < 32, "{same} of 256 positions agree across keys");
    }

    /// For each elementary interval shape (2^a x 2^b cells, a + b = k), true when `pts`
    /// (2^k of them) has exactly one point per cell.
    fn is_02_net(pts: &[[f32; 2]], k: u32) -> Result<(), String> {
        assert_eq!(pts.len(), 1 << k);
        for a in 0..=k {
            let b = k - a;
            let mut count = vec![0u32; 1 << k];
            for p in pts {
                let cx = (p[0] * (1u32 << a) as f32) as u32;
                let cy = (p[1] * (1u32 << b) as f32) as u32;
                count[((cy << a) | cx) as usize] += 1;
            }
            if let Some(c) = count.iter().position(|&c| c != 1) {
                return Err(format!(
                    "{}x{} cells: cell {c} has {}",
                    1 << a,
                    1 << b,
                    count[c]
                ));
            }
        }
        Ok(())
    }

    #[test]
    fn each_pixel_pair_is_a_02_net() {
        for k in [1, 2, 3, 4, 5, 6, 8] {
            let spp = 1u32 << k;
            for (px, seed, dim) in [
                (UVec2::new(0, 0), 0, 0),
                (UVec2::new(3, 5), 7, 1),
                (UVec2::new(1000, 77), 0xffff_ffff, 6),
                (UVec2::new(17, 4000), 12345, 15),
            ] {
                for shuffled in [false, true] {
                    let s: Vec<Vec4> = (0..spp)
                        .map(|i| sobol4_of(shuffled, seed, px, i, spp, dim))
                        .collect();
                    for (name, pts) in [
                        ("xy", s.iter().map(|v| [v.x, v.y]).collect::<Vec<_>>()),
                        ("zw", s.iter().map(|v| [v.z, v.w]).collect::<Vec<_>>()),
                    ] {
                        if let Err(e) = is_02_net(&pts, k) {
                            panic!(
                                "{spp} spp, pixel {px}, seed {seed}, dim {dim}, {name}, \
                             shuffled {shuffled}: {e}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn large_images_get_independent_tiles_and_keep_their_nets() {
        // 1000x1000 at 8192 spp needs 20 + 13 bits: pixels (x, y) and (x, y + 512) would share
        // every sample without tiles (y's top bit is the Morton code's 20th). With them, each pixel's first 2048 samples (2 * 4^5, an
        // aligned block for the odd log2 13: a (0, 11, 2)-net) stay a net, and pixels a tile
        // apart draw different points.
        let spp = 8192;
        let first = |px: UVec2| -> Vec<[f32; 2]> {
            (0..2048)
                .map(|i| {
                    let v = sobol4(9, px, i, spp, 3);
                    [v.x, v.y]
                })
                .collect()
        };
        for px in [UVec2::new(5, 7), UVec2::new(517, 519), UVec2::new(999, 600)] {
            is_02_net(&first(px), 11).unwrap_or_else(|e| panic!("pixel {px}: {e}"));
        }
        let (a, b) = (first(UVec2::new(5, 7)), first(UVec2::new(5, 519)));
        let same = a.iter().zip(&b).filter(|(p, q)| p == q).count();
        assert!(
            same < 4,
            "{same} of 1024 samples repeat across the tile border"
        );
        // Inside the first tile nothing changes: the image's top-left 512x512 pixels draw
        // what they drew before tiles existed.
        assert_eq!(
            zsobol_tile(9, UVec2::new(511, 3), 13),
            (9, UVec2::new(511, 3))
        );
        assert_ne!(zsobol_tile(9, UVec2::new(512, 3), 13).0, 9);
        // Up to 65536 x 65536 pixels at 1 spp nothing is tiled.
        assert_eq!(
            zsobol_tile(4, UVec2::new(65535, 65535), 0),
            (4, UVec2::new(65535, 65535))
        );
    }

    #[test]
    fn prefixes_are_nets_when_spp_is_not_a_power_of_2() {
        // spp 50 (block of 64, even log2): the first 4 and 16 samples are nets; spp 100
        // (block of 128, odd log2: the lowest digit is one bit): the first 2, 8 and 32.
        for (spp, prefixes) in [(50u32, &[4usize, 16][..]), (100, &[2, 8, 32][..])] {
            for (px, shuffled) in [
                (UVec2::new(0, 0), false),
                (UVec2::new(9, 2), false),
                (UVec2::new(0, 0), true),
                (UVec2::new(9, 2), true),
            ] {
                let s: Vec<Vec4> = (0..spp)
                    .map(|i| sobol4_of(shuffled, 3, px, i, spp, 2))
                    .collect();
                for &n in prefixes {
                    let pts: Vec<[f32; 2]> = s[..n].iter().map(|v| [v.x, v.y]).collect();
                    is_02_net(&pts, n.trailing_zeros()).unwrap_or_else(|e| {
                        panic!("spp {spp}, prefix {n}, shuffled {shuffled}: {e}")
                    });
                }
            }
        }
    }

    #[test]
    fn sobol2_is_the_first_pair_of_sobol4() {
        for i in 0..20_000u32 {
            let (px, spp) = (UVec2::new(i % 700, (i * 7) % 900), 1 + (i * 13) % 4096);
            let (sample, dim) = (i % spp, i % 37);
            let four = sobol4(i, px, sample, spp, dim);
            assert_eq!(sobol2(i, px, sample, spp, dim), four.truncate().truncate());
            let four = shuffled_sobol4(i, px, sample, spp, dim);
            assert_eq!(
                shuffled_sobol2(i, px, sample, spp, dim),
                four.truncate().truncate()
            );
            // The two permutations draw different points.
            if spp >= 64 && i % 97 == 0 {
                assert_ne!(four, sobol4(i, px, sample, spp, dim), "key {i}");
            }
        }
    }

    #[test]
    fn values_stay_below_one() {
        assert_eq!(SOBOL_ONE_MINUS_EPSILON.to_bits(), 0x3f7f_ffff);
        assert!(rand_f32(u32::MAX).min(SOBOL_ONE_MINUS_EPSILON) < 1.0);
        for px in 0..64 {
            for i in 0..16 {
                for shuffled in [false, true] {
                    let v = sobol4_of(shuffled, px * 31, UVec2::new(px, 63 - px), i, 16, px % 16);
                    assert!(v.cmplt(Vec4::ONE).all() && v.cmpge(Vec4::ZERO).all(), "{v}");
                }
            }
        }
    }

    /// Chi-square of `values` in `bins` equal bins against uniform.
    fn chi2(values: impl Iterator<Item = f32>, bins: usize) -> (f64, usize) {
        let mut h = vec![0u64; bins];
        let mut n = 0;
        for v in values {
            h[((v * bins as f32) as usize).min(bins - 1)] += 1;
            n += 1;
        }
        let e = n as f64 / bins as f64;
        (h.iter().map(|&c| (c as f64 - e).powi(2) / e).sum(), n)
    }

    #[test]
    fn dimensions_are_uniform_and_pairs_uncorrelated_across_pixels() {
        uniform_and_uncorrelated(false);
    }

    #[test]
    fn shuffled_dimensions_are_uniform_and_pairs_uncorrelated_across_pixels() {
        uniform_and_uncorrelated(true);
    }

    fn uniform_and_uncorrelated(shuffled: bool) {
        // One sample of 16 per pixel over a 128x128 tile: each of the 8 coordinates (dim 0
        // and 1, x y z w) in 64 bins has chi-square with 63 degrees of freedom: mean 63,
        // sd 11.2; 130 is > 6 sd (measured: all below 90). Correlation between coordinates of
        // different pairs (which share no hash or index): |r| < 5 / sqrt(n) ~ 0.039.
        let n = 128 * 128;
        let spp = 16;
        let mut cols: Vec<Vec<f32>> = (0..8).map(|_| Vec::with_capacity(n)).collect();
        for y in 0..128 {
            for x in 0..128 {
                let sample = (x * 7 + y * 3) % spp;
                for dim in 0..2 {
                    let v = sobol4_of(shuffled, 99, UVec2::new(x, y), sample, spp, dim);
                    for c in 0..4 {
                        cols[(4 * dim + c) as usize].push(v[c as usize]);
                    }
                }
            }
        }
        for (i, c) in cols.iter().enumerate() {
            let (x2, _) = chi2(c.iter().copied(), 64);
            assert!(x2 < 130.0, "coordinate {i}: chi-square {x2}");
        }
        let corr = |a: &[f32], b: &[f32]| {
            let m = a.len() as f64;
            let (ma, mb) = (
                a.iter().map(|&x| x as f64).sum::<f64>() / m,
                b.iter().map(|&x| x as f64).sum::<f64>() / m,
            );
            let cov: f64 = a
                .iter()
                .zip(b)
                .map(|(&x, &y)| (x as f64 - ma) * (y as f64 - mb))
                .sum::<f64>()
                / m;
            cov * 12.0
        };
        let bound = 5.0 / (n as f64).sqrt();
        for i in 0..8 {
            for j in (i + 1)..8 {
                // x and y of one pair are one net point, fine to be dependent; all the others
                // come from different permuted indices or scrambles.
                let same_pair = i / 2 == j / 2;
                if !same_pair {
                    let r = corr(&cols[i], &cols[j]);
                    assert!(r.abs() < bound, "coordinates {i} and {j}: r = {r}");
                }
            }
        }
        // Pixel neighbours: x of pixel p against x of pixel p + 1 in the same row.
        let r = corr(&cols[0][..n - 1], &cols[0][1..]);
        assert!(r.abs() < bound, "neighbours: r = {r}");
    }

    /// RMS over `pixels` pixels of the error of `spp`-sample estimates of
    /// ∫∫ exp(-x² - y²) over [0, 1]² = (√π/2 · erf 1)² = 0.557746285351034.
    fn rms_error(pixels: u32, spp: u32, draw: impl Fn(u32, u32) -> [f32; 2]) -> f64 {
        const EXACT: f64 = 0.557_746_285_351_034;
        let mut se = 0.0;
        for p in 0..pixels {
            let mut sum = 0.0;
            for s in 0..spp {
                let [x, y] = draw(p, s);
                sum += (-(x as f64).powi(2) - (y as f64).powi(2)).exp();
            }
            se += (sum / spp as f64 - EXACT).powi(2);
        }
        (se / pixels as f64).sqrt()
    }

    #[test]
    fn converges_faster_than_independent_random_numbers() {
        converges_faster(false);
    }

    #[test]
    fn shuffled_converges_faster_than_independent_random_numbers() {
        // Measured (2026-12-02): the same errors as ZSobol's to 4 digits. Over a whole 64x64
        // tile both permutations hand out the same blocks of Sobol' indices, to other pixels
        // and in other orders: the pixels' means are the same numbers, shuffled.
        converges_faster(true);
    }

    fn converges_faster(shuffled: bool) {
        // 4096 pixels (a 64x64 tile), both pairs of dim 0, seed 5. Measured (2026-12-01):
        //   spp 16: rand4 5.30e-2, sobol4 (x, y) 3.80e-3, (z, w) 5.04e-3  (14x, 11x better)
        //   spp 64: rand4 2.70e-2, sobol4 (x, y) 6.93e-4, (z, w) 4.31e-4  (39x, 63x better)
        // rand4 halves from 16 to 64 (N^-0.5); sobol4 falls 5.5x and 11.7x (N^-1.2..-1.8,
        // against N^-1.5 expected for Owen-scrambled nets on a smooth integrand).
        let pixels = 4096;
        let width = 64;
        let px = |p: u32| UVec2::new(p % width, p / width);
        let mut report = String::new();
        let mut results = Vec::new();
        for spp in [16u32, 64] {
            let random = rms_error(pixels, spp, |p, s| {
                let r = rand4(5, p, s, 0, 0);
                [r.x, r.y]
            });
            let xy = rms_error(pixels, spp, |p, s| {
                let r = sobol4_of(shuffled, 5, px(p), s, spp, 0);
                [r.x, r.y]
            });
            let zw = rms_error(pixels, spp, |p, s| {
                let r = sobol4_of(shuffled, 5, px(p), s, spp, 0);
                [r.z, r.w]
            });
            report += &format!("spp {spp}: rand4 {random:.3e}, sobol xy {xy:.3e}, zw {zw:.3e}\n");
            results.push((spp, random, xy, zw));
        }
        eprint!("{report}");
        for &(spp, random, xy, zw) in &results {
            // Independent sampling: sd of exp(-x²-y²) on the square ~0.2, / sqrt(spp).
            assert!(random > 0.1 / (spp as f64).sqrt(), "{report}");
            assert!(xy < random / 8.0 && zw < random / 8.0, "{report}");
        }
        let (_, _, xy16, _) = results[0];
        let (_, _, xy64, zw64) = results[1];
        // From 16 to 64 samples: independent sampling halves the error, Owen-scrambled
        // Sobol' on a smooth integrand divides it by ~8 (N^-1.5; measured 5.5 for (x, y));
        // ask for more than 3.
        assert!(xy64 < xy16 / 3.0, "{report}");
        assert!(xy64 < SOBOL_RMS_64 && zw64 < SOBOL_RMS_64, "{report}");
    }

    /// The bound on the RMS error at 64 spp: twice the 6.9e-4 measured, still 18x below rand4's.
    const SOBOL_RMS_64: f64 = 1.5e-3;

    /// `sobol4_at`'s four-lane form of the shuffled sampler gives `zsobol_pair`'s numbers of
    /// both pairs, bit for bit.
    #[test]
    fn shuffled_sobol4_is_its_two_pairs() {
        for seed in [0u32, 1, 0xdead_beef] {
            for spp in [1u32, 3, 16, 1000] {
                for (k, pixel) in [(0, 0), (1, 0), (17, 5), (999, 637), (4095, 4095)]
                    .into_iter()
                    .enumerate()
                {
                    let p = sobol_pixel(seed, UVec2::new(pixel.0, pixel.1), spp);
                    for sample in (0..spp).step_by(1 + spp as usize / 7) {
                        for dim in [0u32, 1, 5, 31, 200 + k as u32] {
                            let z = zsobol_setup_at(p, dim, true);
                            let (a, b) = (zsobol_pair(&z, sample, 0), zsobol_pair(&z, sample, 1));
                            let want = Vec4::new(a.x, a.y, b.x, b.y);
                            let got = sobol4_at(true, p, sample, dim);
                            assert_eq!(
                                got.to_array().map(f32::to_bits),
                                want.to_array().map(f32::to_bits),
                                "seed {seed} spp {spp} pixel {pixel:?} sample {sample} dim {dim}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// A segment's three groups drawn at once from its `SegmentKeys` are the numbers the
    /// tracer draws one group at a time (`sobol4_at` of the light's and the scattered
    /// direction's groups, the `x` of `sobol2_at` of the roulette's), bit for bit: pixels of
    /// the sampler's tiles included (each with its own seed's keys), spp odd and even, deep
    /// segments.
    #[test]
    fn segment_keys_draw_the_groups_the_tracer_draws() {
        use crate::gpu_types::{DIM_CAMERA, DIM_LIGHT, DIM_ROULETTE, DIM_SCATTER, DIMS_PER_BOUNCE};
        for seed in [0u32, 1, 0xdead_beef] {
            for spp in [1u32, 3, 16, 1000, 1 << 20] {
                for pixel in [
                    (0, 0),
                    (1, 0),
                    (17, 5),
                    (999, 637),
                    (4095, 4095),
                    (70_000, 3),
                ] {
                    let p = sobol_pixel(seed, UVec2::new(pixel.0, pixel.1), spp);
                    for bounce in [0u32, 1, 4, 9, 63, SEGMENT_KEYS_MAX] {
                        let keys = SegmentKeys::new(p.seed, bounce);
                        let group = |dim| bounce * DIMS_PER_BOUNCE + dim;
                        for sample in (0..spp).step_by(1 + spp as usize / 7) {
                            let (light, scatter, roulette) = keys.draw(p, sample);
                            let bits = |v: Vec4| v.to_array().map(f32::to_bits);
                            let at = format!(
                                "seed {seed} spp {spp} pixel {pixel:?} segment {bounce} sample {sample}"
                            );
                            assert_eq!(
                                bits(light),
                                bits(sobol4_at(true, p, sample, group(DIM_LIGHT))),
                                "{at}"
                            );
                            assert_eq!(
                                bits(scatter),
                                bits(sobol4_at(true, p, sample, group(DIM_SCATTER))),
                                "{at}"
                            );
                            let want = sobol2_at(true, p, sample, group(DIM_ROULETTE)).x;
                            assert_eq!(roulette.to_bits(), want.to_bits(), "{at}");
                            if bounce == 0 {
                                let cam = keys.draw_camera(p, sample);
                                let want = sobol2_at(true, p, sample, group(DIM_CAMERA));
                                assert_eq!(cam.x.to_bits(), want.x.to_bits(), "{at}");
                                assert_eq!(cam.y.to_bits(), want.y.to_bits(), "{at}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// `n` random draws to compare forms over: a pixel of an image up to 70,000 x 5,000 at
    /// 1-5,000 spp under any seed, a segment's keys (segments 0..80) and a sample.
    fn draw_cases(seed: u32, n: usize) -> Vec<(SobolPixel, SegmentKeys, u32)> {
        let mut state = seed;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        (0..n)
            .map(|_| {
                let spp = 1 + next() % 5000;
                let pixel = UVec2::new(next() % 70_000, next() % 5000);
                let p = sobol_pixel(next(), pixel, spp);
                let keys = SegmentKeys::new(p.seed, next() % 80);
                (p, keys, next() % spp)
            })
            .collect()
    }

    /// `SegmentKeys::draw_avx2` draws `SegmentKeys::draw`'s numbers bit for bit (where this
    /// CPU has AVX2).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn segment_keys_draw_in_avx2_the_scalar_numbers() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        }
        for (p, keys, sample) in draw_cases(0x1234_5678, 20_000) {
            let (a, b, c) = keys.draw(p, sample);
            // SAFETY: AVX2 detected above.
            let (x, y, z) = unsafe { keys.draw_avx2(p, sample) };
            let bits = |v: Vec4| v.to_array().map(f32::to_bits);
            assert_eq!(bits(a), bits(x));
            assert_eq!(bits(b), bits(y));
            assert_eq!(c.to_bits(), z.to_bits());
        }
    }

    /// `SegmentKeys::draw_pairs` draws `draw`'s light and scatter pairs and roulette number
    /// and `draw_camera`'s pair bit for bit, and so does `draw_pairs_avx2` (where this CPU
    /// has AVX2).
    #[test]
    fn segment_pairs_are_the_groups_numbers() {
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        for (p, keys, sample) in draw_cases(0x9e37_79b9, 20_000) {
            let (light, scatter, roulette) = keys.draw(p, sample);
            let camera = keys.draw_camera(p, sample);
            let pairs = keys.draw_pairs(p, sample);
            let bits = |v: glam::Vec2| v.to_array().map(f32::to_bits);
            assert_eq!(bits(pairs.light), bits(light.truncate().truncate()));
            assert_eq!(bits(pairs.scatter), bits(scatter.truncate().truncate()));
            assert_eq!(pairs.roulette.to_bits(), roulette.to_bits());
            assert_eq!(bits(pairs.camera), bits(camera));
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: AVX2 detected above.
                let wide = unsafe { keys.draw_pairs_avx2(p, sample) };
                assert_eq!(bits(wide.light), bits(pairs.light));
                assert_eq!(bits(wide.scatter), bits(pairs.scatter));
                assert_eq!(wide.roulette.to_bits(), pairs.roulette.to_bits());
                assert_eq!(bits(wide.camera), bits(pairs.camera));
            }
        }
    }

    /// `SegmentKeys::draw_pairs4_avx512` draws each of its four paths' `draw_pairs` bit for
    /// bit, every path under its own keys (where this CPU has AVX-512 F and BW).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn four_paths_draw_their_own_pairs() {
        if !(std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw"))
        {
            eprintln!("no AVX-512 here: nothing to compare");
            return;
        }
        let bits = |v: glam::Vec2| v.to_array().map(f32::to_bits);
        for four in draw_cases(0x2545_f491, 20_000).chunks_exact(4) {
            let keys = std::array::from_fn(|k| &four[k].1);
            let p = std::array::from_fn(|k| four[k].0);
            let sample = std::array::from_fn(|k| four[k].2);
            // SAFETY: AVX-512 F and BW detected above.
            let wide = unsafe { SegmentKeys::draw_pairs4_avx512(keys, p, sample) };
            for (k, w) in wide.iter().enumerate() {
                let pairs = keys[k].draw_pairs(p[k], sample[k]);
                assert_eq!(bits(w.light), bits(pairs.light), "path {k}");
                assert_eq!(bits(w.scatter), bits(pairs.scatter), "path {k}");
                assert_eq!(w.roulette.to_bits(), pairs.roulette.to_bits(), "path {k}");
                assert_eq!(bits(w.camera), bits(pairs.camera), "path {k}");
            }
        }
    }
}
