// raylume-sort radix sort: the downsweep's ranking WITH subgroups (Onesweep's warp-level
// multi-split). Each subgroup owns a contiguous run of sg_lanes * ITEMS keys of the tile and
// walks it ITEMS times sg_lanes keys at a time; `match_peers` finds the lanes holding the same
// digit; the lowest of them adds their count to the subgroup's counter for that digit
// (a workgroup atomic whose old value is shuffled to the peers), so each key learns how many
// keys of its digit precede it in its subgroup's run. An exclusive scan over subgroups and
// then over digits turns that into the key's position in the stably digit-sorted tile.
// Per-key state lives in unrolled scalars (key_0, rank_0, ...), never in indexed arrays.

/// Per subgroup and digit: count, then exclusive prefix over earlier subgroups.
var<workgroup> s_sg_hist: array<atomic<u32>, MAX_SG * RADIX>;
/// The tile's keys, then values, in digit order.
var<workgroup> s_stage: array<u32, TILE>;
/// Per digit: the tile's count, then the digit's first position in the sorted tile.
var<workgroup> s_count: array<u32, RADIX>;

/// The lanes of this subgroup whose digit equals mine (one ballot per digit bit).
/// Uniform control flow only.
fn match_peers(d: u32) -> LaneMask {
    var peers = ballot(true);
    //#unroll b RADIX_BITS
    {
        let bit = ((d >> {b}u) & 1u) == 1u;
        let bal = ballot(bit);
        peers &= select(~bal, bal, bit);
    }
    //#end
    return peers;
}

fn rank_and_scatter(start: u32, valid: u32) {
    for (var i = lin; i < num_sg * RADIX; i += WG) {
        atomicStore(&s_sg_hist[i], 0u);
    }
    let first = sg_base * ITEMS + sg_rank;
    let hist_row = sg_id * RADIX;
    // Loads first, all in flight together. Past the end: the largest digit; such keys have
    // the largest indices of the tile, so they sort after every real key and are never written.
    //#unroll i ITEMS
    var key_{i} = 0xFFFFFFFFu;
    var rank_{i} = RADIX - 1u;
    if (first + {i}u * sg_lanes < valid) {
        key_{i} = keys_in[start + first + {i}u * sg_lanes];
        rank_{i} = digit_of(key_{i});
    }
    //#end
    workgroupBarrier();

    // rank_i: digit, then digit << 16 | keys of that digit before it in the subgroup's run.
    //#unroll i ITEMS
    {
        let d = rank_{i};
        let peers = match_peers(d);
        let below = mask_count(peers & lt_mask);
        var old = 0u;
        if (below == 0u) {
            old = atomicAdd(&s_sg_hist[hist_row + d], mask_count(peers));
        }
        old = subgroupShuffle(old, first_lane(peers));
        rank_{i} = (d << 16u) | (old + below);
    }
    //#end
    workgroupBarrier();

    // Per digit: exclusive prefix over subgroups, and the tile's count.
    for (var d = lin; d < RADIX; d += WG) {
        var run = 0u;
        for (var s = 0u; s < num_sg; s++) {
            let c = atomicLoad(&s_sg_hist[s * RADIX + d]);
            atomicStore(&s_sg_hist[s * RADIX + d], run);
            run += c;
        }
        s_count[d] = run;
    }
    workgroupBarrier();

    // Exclusive prefix over digits: first position of each digit in the sorted tile.
    let d0 = lin * DIGITS_PER_THREAD;
    var sum = 0u;
    for (var j = 0u; j < DIGITS_PER_THREAD; j++) {
        if (d0 + j < RADIX) {
            sum += s_count[d0 + j];
        }
    }
    var run = wg_exclusive_scan(sum).x;
    for (var j = 0u; j < DIGITS_PER_THREAD; j++) {
        let d = d0 + j;
        if (d < RADIX) {
            let c = s_count[d];
            s_count[d] = run;
            s_base[d] -= run;
            run += c;
        }
    }
    workgroupBarrier();

    // rank_i: position in the sorted tile.
    //#unroll i ITEMS
    {
        let d = rank_{i} >> 16u;
        rank_{i} = s_count[d] + atomicLoad(&s_sg_hist[hist_row + d]) + (rank_{i} & 0xFFFFu);
        s_stage[rank_{i}] = key_{i};
    }
    //#end
    workgroupBarrier();

    // Keys out in sorted order: consecutive threads, consecutive addresses within a digit.
    //#unroll j ITEMS
    var dest_{j} = 0u;
    if ({j}u * WG + lin < valid) {
        let k = s_stage[{j}u * WG + lin];
        dest_{j} = s_base[digit_of(k)] + {j}u * WG + lin;
        keys_out[dest_{j}] = k;
    }
    //#end
    // Values: loaded (all in flight), staged in sorted order, written like the keys.
    //#unroll i ITEMS
    var val_{i} = 0u;
    if (first + {i}u * sg_lanes < valid) {
        val_{i} = vals_in[start + first + {i}u * sg_lanes];
    }
    //#end
    workgroupBarrier();
    //#unroll i ITEMS
    s_stage[rank_{i}] = val_{i};
    //#end
    workgroupBarrier();
    //#unroll j ITEMS
    if ({j}u * WG + lin < valid) {
        vals_out[dest_{j}] = s_stage[{j}u * WG + lin];
    }
    //#end
}
