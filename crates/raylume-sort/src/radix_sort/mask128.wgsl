// raylume-sort radix sort: ballot masks for subgroups of up to 128 lanes (the most WGSL
// allows): all four words of a ballot. Variant of mask32.wgsl (same names).

alias LaneMask = vec4<u32>;

fn ballot(p: bool) -> LaneMask {
    return subgroupBallot(p);
}

fn mask_count(m: LaneMask) -> u32 {
    let c = countOneBits(m);
    return c.x + c.y + c.z + c.w;
}

/// Invocation id of the lowest lane set in `m` (m must not be empty).
fn first_lane(m: LaneMask) -> u32 {
    if (m.x != 0u) {
        return countTrailingZeros(m.x);
    }
    if (m.y != 0u) {
        return 32u + countTrailingZeros(m.y);
    }
    if (m.z != 0u) {
        return 64u + countTrailingZeros(m.z);
    }
    return 96u + countTrailingZeros(m.w);
}

/// The lanes with an invocation id below `id`.
fn lanes_below_mask(id: u32) -> LaneMask {
    var m = vec4<u32>(0u);
    for (var w = 0u; w < 4u; w++) {
        let lo = 32u * w;
        if (id >= lo + 32u) {
            m[w] = 0xFFFFFFFFu;
        } else if (id > lo) {
            m[w] = (1u << (id - lo)) - 1u;
        }
    }
    return m;
}
