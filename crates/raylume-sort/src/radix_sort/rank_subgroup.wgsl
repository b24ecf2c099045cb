// raylume-sort radix sort: the downsweep's ranking WITH subgroups (Onesweep's warp-level
// multi-split). Each subgroup owns a contiguous run of sg_lanes * ITEMS keys of the tile and
// walks it ITEMS times sg_lanes keys at a time; `match_peers` finds the lanes holding the same
// digit; the lowest of them adds their count to the subgroup's counter for that digit
// (a workgroup atomic whose old value is shuffled to the peers), so each key learns how many
// keys of its digit precede it in its subgroup's run. An exclusive scan over subgroups and
// then over digits turns that into the key's position in the stably digit-sorted tile.

/// Per subgroup and digit: count, then exclusive prefix over earlier subgroups.
var<workgroup> s_sg_hist: array<atomic<u32>, MAX_SG * RADIX>;
/// The tile's keys, then values, in digit order.
var<workgroup> s_stage: array<u32, TILE>;
/// Per digit: the tile's count, then the digit's first position in the sorted tile.
var<workgroup> s_count: array<u32, RADIX>;

fn rank_and_scatter(start: u32, valid: u32) {
    for (var i = lin; i < num_sg * RADIX; i += WG) {
        atomicStore(&s_sg_hist[i], 0u);
    }
    workgroupBarrier();

    var keys: array<u32, ITEMS>;
    // digit << 16 | rank within the subgroup's run; later the position in the tile.
    var rank: array<u32, ITEMS>;
    let first = sg_base * ITEMS + sg_rank;
    let hist_row = sg_id * RADIX;
    for (var i = 0u; i < ITEMS; i++) {
        let idx = first + i * sg_lanes;
        // Past the end: the largest digit; such keys have the largest indices of the tile,
        // so they land after every real key and are never written out.
        var key = 0xFFFFFFFFu;
        var d = RADIX - 1u;
        if (idx < valid) {
            key = keys_in[start + idx];
            d = digit_of(key);
        }
        keys[i] = key;
        let peers = match_peers(d, RADIX_BITS);
        let below = mask_count(peers & lt_mask);
        var old = 0u;
        if (below == 0u) {
            old = atomicAdd(&s_sg_hist[hist_row + d], mask_count(peers));
        }
        old = subgroupShuffle(old, first_lane(peers));
        rank[i] = (d << 16u) | (old + below);
    }
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

    for (var i = 0u; i < ITEMS; i++) {
        let d = rank[i] >> 16u;
        let p = s_count[d] + atomicLoad(&s_sg_hist[hist_row + d]) + (rank[i] & 0xFFFFu);
        rank[i] = p;
        s_stage[p] = keys[i];
    }
    workgroupBarrier();

    var dest: array<u32, ITEMS>;
    for (var j = 0u; j < ITEMS; j++) {
        let q = j * WG + lin;
        if (q < valid) {
            let k = s_stage[q];
            let dst = s_base[digit_of(k)] + q;
            keys_out[dst] = k;
            dest[j] = dst;
        }
    }
    workgroupBarrier();
    for (var i = 0u; i < ITEMS; i++) {
        let idx = first + i * sg_lanes;
        if (idx < valid) {
            s_stage[rank[i]] = vals_in[start + idx];
        }
    }
    workgroupBarrier();
    for (var j = 0u; j < ITEMS; j++) {
        let q = j * WG + lin;
        if (q < valid) {
            vals_out[dest[j]] = s_stage[q];
        }
    }
}
