// raylume-sort radix sort: ballot masks for subgroups of at most 32 lanes (NVIDIA, lavapipe,
// RDNA in wave32, Intel): one u32. Variant of mask128.wgsl (same names).

alias LaneMask = u32;

fn ballot(p: bool) -> LaneMask {
    return subgroupBallot(p).x;
}

fn mask_count(m: LaneMask) -> u32 {
    return countOneBits(m);
}

/// Invocation id of the lowest lane set in `m` (m must not be empty).
fn first_lane(m: LaneMask) -> u32 {
    return countTrailingZeros(m);
}

/// The lanes with an invocation id below `id`.
fn lanes_below_mask(id: u32) -> LaneMask {
    if (id >= 32u) {
        return 0xFFFFFFFFu;
    }
    return (1u << id) - 1u;
}
