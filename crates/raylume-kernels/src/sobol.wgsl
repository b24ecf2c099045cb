// ZSobol low-discrepancy samples (sobol.rs): Ahmed & Wonka 2020 after pbrt-v4's ZSobolSampler
// with FastOwen scrambling. Identical u32 arithmetic to the Rust mirror; uses pcg4d and
// rand_f32 from rng.wgsl. The constants are sobol.rs's (checked there).

// The 24 permutations of {0, 1, 2, 3} (pbrt-v4's order), four 8-bit permutations a word.
const ZSOBOL_PERMUTATIONS = array<u32, 6>(0x78d8b4e4u, 0xb1e19c6cu, 0x8d2d39c9u, 0x72d236c6u, 0x87271e4eu, 0x93634b1bu);
const SOBOL_SALT: u32 = 0x5ab01d5eu;
const SOBOL_ONE_MINUS_EPSILON: f32 = 0.99999994;

fn mix32(x_in: u32) -> u32 {
    var x = x_in;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn part_1by1(x_in: u32) -> u32 {
    var x = x_in & 0xffffu;
    x = (x | (x << 8u)) & 0x00ff00ffu;
    x = (x | (x << 4u)) & 0x0f0f0f0fu;
    x = (x | (x << 2u)) & 0x33333333u;
    x = (x | (x << 1u)) & 0x55555555u;
    return x;
}

fn encode_morton2(x: u32, y: u32) -> u32 {
    return (part_1by1(y) << 1u) | part_1by1(x);
}

fn sobol_log2_spp(spp: u32) -> u32 {
    let s = max(spp, 1u) - 1u;
    return select(32u - countLeadingZeros(s), 0u, s == 0u);
}

fn zsobol_morton_index(pixel: vec2<u32>, sample: u32, log2_spp: u32) -> u32 {
    let morton = encode_morton2(pixel.x, pixel.y);
    let low = zsobol_sample_bits(sample, log2_spp);
    // Shifts by 32 are masked in WGSL: select the cases explicitly.
    return select((morton << log2_spp) | low, low, log2_spp >= 32u);
}

fn zsobol_sample_bits(sample: u32, log2_spp: u32) -> u32 {
    return select(sample & (0xffffffffu >> (32u - log2_spp)), 0u, log2_spp == 0u);
}

fn zsobol_permute_digit(p: u32, d: u32) -> u32 {
    var perms = ZSOBOL_PERMUTATIONS;
    let byte = perms[p >> 2u] >> (8u * (p & 3u));
    return (byte >> (2u * d)) & 3u;
}

fn zsobol_sample_index(m: u32, log2_spp: u32, key: u32) -> u32 {
    let odd = log2_spp & 1u;
    var out = 0u;
    for (var i = odd; i < 16u; i++) {
        let shift = 2u * i - odd;
        let digit = (m >> shift) & 3u;
        let higher = select(m >> (shift + 2u), 0u, shift >= 30u);
        let p = (mix32(higher ^ key) >> 24u) % 24u;
        out |= zsobol_permute_digit(p, digit) << shift;
    }
    if (odd == 1u) {
        out |= (m & 1u) ^ (mix32((m >> 1u) ^ key) & 1u);
        out |= m & 0x80000000u;
    }
    return out;
}

// sobol.rs `sobol_dim1`: the Pascal matrix as a superset sum over bit positions (Lucas).
fn sobol_dim1(a: u32) -> u32 {
    var y = a;
    y ^= (y >> 1u) & 0x55555555u;
    y ^= (y >> 2u) & 0x33333333u;
    y ^= (y >> 4u) & 0x0f0f0f0fu;
    y ^= (y >> 8u) & 0x00ff00ffu;
    y ^= (y >> 16u) & 0x0000ffffu;
    return reverseBits(y);
}

fn fast_owen(v_in: u32, seed: u32) -> u32 {
    var v = reverseBits(v_in);
    v ^= v * 0x3d20adeau;
    v += seed;
    v *= (seed >> 16u) | 1u;
    v ^= v * 0x05526c56u;
    v ^= v * 0x53a22864u;
    return reverseBits(v);
}

// sobol.rs `shuffled_sample_index`: Burley's shuffle.
fn shuffled_sample_index(m: u32, key: u32) -> u32 {
    return fast_owen(m, key);
}

fn zsobol_pair_bits(m: u32, log2_spp: u32, key: u32, scramble_x: u32, scramble_y: u32, shuffled: u32) -> vec2<u32> {
    var index: u32;
    if (shuffled != 0u) {
        index = shuffled_sample_index(m, key);
    } else {
        index = zsobol_sample_index(m, log2_spp, key);
    }
    return vec2<u32>(fast_owen(reverseBits(index), scramble_x), fast_owen(sobol_dim1(index), scramble_y));
}

// Owen seeds of x, y, z, w; the digit-permutation keys of (x, y) and (z, w) are sobol_keys.
fn sobol_scrambles(seed: u32, dim: u32) -> vec4<u32> {
    return pcg4d(vec4<u32>(seed, dim, SOBOL_SALT, 0u));
}

fn sobol_keys(scrambles: vec4<u32>) -> vec2<u32> {
    return vec2<u32>(mix32(scrambles.x ^ SOBOL_SALT), mix32(scrambles.z ^ SOBOL_SALT));
}

// sobol.rs `zsobol_tile`: (seed, pixel) of the pixel's tile when the image is too large for
// the 32-bit index at this spp.
struct ZSobolTile {
    seed: u32,
    pixel: vec2<u32>,
}

fn zsobol_tile(seed: u32, pixel: vec2<u32>, log2_spp: u32) -> ZSobolTile {
    let b = (32u - min(log2_spp, 32u)) / 2u;
    if (b >= 16u) {
        return ZSobolTile(seed, pixel);
    }
    let t = pixel >> vec2<u32>(b);
    if (t.x == 0u && t.y == 0u) {
        return ZSobolTile(seed, pixel);
    }
    let mask = (1u << b) - 1u;
    let tile_seed = pcg4d(vec4<u32>(seed, t.x, t.y, SOBOL_SALT ^ 2u)).x;
    return ZSobolTile(tile_seed, pixel & vec2<u32>(mask));
}

// sobol.rs `ZSobolSetup` / `zsobol_setup`: what both pairs of a pair group share.
struct ZSobolSetup {
    log2_spp: u32,
    morton: u32,
    scrambles: vec4<u32>,
    keys: vec2<u32>,
    // sobol.rs `shuffled` (a bool there): 1 for Burley's shuffle, 0 for ZSobol's digits.
    shuffled: u32,
}

// sobol.rs `SobolPixel` / `sobol_pixel`: what every pair group of a pixel's samples shares.
struct SobolPixel {
    seed: u32,
    morton: u32,
    log2_spp: u32,
}

fn sobol_pixel(seed: u32, pixel: vec2<u32>, spp: u32) -> SobolPixel {
    let log2_spp = sobol_log2_spp(spp);
    let tile = zsobol_tile(seed, pixel, log2_spp);
    return SobolPixel(tile.seed, zsobol_morton_index(tile.pixel, 0u, log2_spp), log2_spp);
}

fn zsobol_setup(seed: u32, pixel: vec2<u32>, spp: u32, dim: u32, shuffled: u32) -> ZSobolSetup {
    return zsobol_setup_at(sobol_pixel(seed, pixel, spp), dim, shuffled);
}

fn zsobol_setup_at(p: SobolPixel, dim: u32, shuffled: u32) -> ZSobolSetup {
    let scrambles = sobol_scrambles(p.seed, dim);
    return ZSobolSetup(p.log2_spp, p.morton, scrambles, sobol_keys(scrambles), shuffled);
}

// sobol.rs `zsobol_pair`: pair `which` (0 or 1) as floats in [0, 1).
fn zsobol_pair(z: ZSobolSetup, sample: u32, which: u32) -> vec2<f32> {
    var sx = z.scrambles.x;
    var sy = z.scrambles.y;
    var key = z.keys.x;
    if (which == 1u) {
        sx = z.scrambles.z;
        sy = z.scrambles.w;
        key = z.keys.y;
    }
    let a = zsobol_pair_bits(z.morton | zsobol_sample_bits(sample, z.log2_spp), z.log2_spp, key, sx, sy, z.shuffled);
    return vec2<f32>(min(rand_f32(a.x), SOBOL_ONE_MINUS_EPSILON), min(rand_f32(a.y), SOBOL_ONE_MINUS_EPSILON));
}

// sobol.rs `sobol4_of` / `sobol2_of` (shuffled: 0 or 1) and the four names over them.
fn sobol4_of(shuffled: u32, seed: u32, pixel: vec2<u32>, sample: u32, spp: u32, dim: u32) -> vec4<f32> {
    return sobol4_at(shuffled, sobol_pixel(seed, pixel, spp), sample, dim);
}

fn sobol2_of(shuffled: u32, seed: u32, pixel: vec2<u32>, sample: u32, spp: u32, dim: u32) -> vec2<f32> {
    return sobol2_at(shuffled, sobol_pixel(seed, pixel, spp), sample, dim);
}

fn sobol4_at(shuffled: u32, p: SobolPixel, sample: u32, dim: u32) -> vec4<f32> {
    let z = zsobol_setup_at(p, dim, shuffled);
    return vec4<f32>(zsobol_pair(z, sample, 0u), zsobol_pair(z, sample, 1u));
}

fn sobol2_at(shuffled: u32, p: SobolPixel, sample: u32, dim: u32) -> vec2<f32> {
    return zsobol_pair(zsobol_setup_at(p, dim, shuffled), sample, 0u);
}

fn sobol4(seed: u32, pixel: vec2<u32>, sample: u32, spp: u32, dim: u32) -> vec4<f32> {
    return sobol4_of(0u, seed, pixel, sample, spp, dim);
}

// sobol.rs `sobol2`: the first pair of sobol4 alone.
fn sobol2(seed: u32, pixel: vec2<u32>, sample: u32, spp: u32, dim: u32) -> vec2<f32> {
    return sobol2_of(0u, seed, pixel, sample, spp, dim);
}

fn shuffled_sobol4(seed: u32, pixel: vec2<u32>, sample: u32, spp: u32, dim: u32) -> vec4<f32> {
    return sobol4_of(1u, seed, pixel, sample, spp, dim);
}

fn shuffled_sobol2(seed: u32, pixel: vec2<u32>, sample: u32, spp: u32, dim: u32) -> vec2<f32> {
    return sobol2_of(1u, seed, pixel, sample, spp, dim);
}
