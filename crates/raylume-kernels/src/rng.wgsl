// Counter-based random numbers (rng.rs): pcg4d from Jarzynski & Olano, "Hash Functions for
// GPU Rendering", JCGT 2020. Identical u32 arithmetic to the Rust mirror.

fn pcg4d(v_in: vec4<u32>) -> vec4<u32> {
    var v = v_in * 1664525u + 1013904223u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v ^= v >> vec4<u32>(16u);
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

fn rng_key(seed: u32, pixel: u32, sample: u32, bounce: u32, dim: u32) -> vec4<u32> {
    return vec4<u32>(pixel, sample, (bounce << 4u) | (dim & 15u), seed);
}

fn rand_f32(x: u32) -> f32 {
    return f32(x >> 8u) * (1.0 / 16777216.0);
}

fn rand4(seed: u32, pixel: u32, sample: u32, bounce: u32, dim: u32) -> vec4<f32> {
    let h = pcg4d(rng_key(seed, pixel, sample, bounce, dim));
    return vec4<f32>(rand_f32(h.x), rand_f32(h.y), rand_f32(h.z), rand_f32(h.w));
}
