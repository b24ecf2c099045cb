// A local stand-in for raylume-sort's key (sort_key.rs): the paper's 30-bit key, origin
// (relative to the scene bounds) and direction quantised to 5 bits per component, each
// interleaved into a 15-bit Morton code; origin code in bits 29..15, direction in 14..0.

fn spread_bits_5(x: u32) -> u32 {
    var r = 0u;
    for (var i = 0u; i < 5u; i++) {
        r |= ((x >> i) & 1u) << (3u * i);
    }
    return r;
}

fn morton15(q: vec3<u32>) -> u32 {
    return (spread_bits_5(q.x) << 2u) | (spread_bits_5(q.y) << 1u) | spread_bits_5(q.z);
}

fn local_ray_sort_key(origin: vec3<f32>, dir: vec3<f32>, scene_min: vec3<f32>, scene_extent: vec3<f32>) -> u32 {
    let o = clamp((origin - scene_min) / max(scene_extent, vec3<f32>(1e-30)), vec3<f32>(0.0), vec3<f32>(1.0));
    let d = clamp(dir * 0.5 + 0.5, vec3<f32>(0.0), vec3<f32>(1.0));
    let qo = min(vec3<u32>(o * 32.0), vec3<u32>(31u));
    let qd = min(vec3<u32>(d * 32.0), vec3<u32>(31u));
    return (morton15(qo) << 15u) | morton15(qd);
}
