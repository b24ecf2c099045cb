// raylume-sort radix sort: the downsweep's ranking WITHOUT subgroups. The tile is sorted by the
// digit in shared memory with RADIX_BITS stable binary splits (each a workgroup prefix sum of
// "bit is 0" counts, Blelloch's split primitive as in Satish, Harris & Garland 2009) over
// entries (digit << 16 | index in tile); the sorted entry at position q then goes to
// s_base[digit] + q - (first position of its digit in the tile), gathering its key and value
// from the tile in global memory. Per-entry state lives in unrolled scalars.

var<workgroup> s_stage: array<u32, TILE>;
/// First position of each digit present in the sorted tile.
var<workgroup> s_first: array<u32, RADIX>;

fn rank_and_scatter(start: u32, valid: u32) {
    //#unroll i ITEMS
    {
        let idx = {i}u * WG + lin;
        // Past the end: the largest digit and the largest indices, so these sort last.
        var d = RADIX - 1u;
        if (idx < valid) {
            d = digit_of(keys_in[start + idx]);
        }
        s_stage[idx] = (d << 16u) | idx;
    }
    //#end
    workgroupBarrier();

    // Each thread holds ITEMS consecutive entries of the current order.
    let mine = lin * ITEMS;
    //#unroll j ITEMS
    var item_{j} = s_stage[mine + {j}u];
    //#end
    for (var b = 16u; b < 16u + RADIX_BITS; b++) {
        var zeros = 0u;
        //#unroll j ITEMS
        zeros += 1u - ((item_{j} >> b) & 1u);
        //#end
        // Barriers inside: every thread has read s_stage before anyone writes it below.
        let sc = wg_exclusive_scan(zeros);
        var z = sc.x;
        var o = sc.y + mine - sc.x;
        //#unroll j ITEMS
        if (((item_{j} >> b) & 1u) == 0u) {
            s_stage[z] = item_{j};
            z++;
        } else {
            s_stage[o] = item_{j};
            o++;
        }
        //#end
        workgroupBarrier();
        //#unroll j ITEMS
        item_{j} = s_stage[mine + {j}u];
        //#end
    }

    //#unroll j ITEMS
    {
        let q = {j}u * WG + lin;
        let d = s_stage[q] >> 16u;
        if (q == 0u || (s_stage[q - 1u] >> 16u) != d) {
            s_first[d] = q;
        }
    }
    //#end
    workgroupBarrier();
    //#unroll j ITEMS
    {
        let q = {j}u * WG + lin;
        if (q < valid) {
            let e = s_stage[q];
            let d = e >> 16u;
            let src = start + (e & 0xFFFFu);
            let dst = s_base[d] + q - s_first[d];
            keys_out[dst] = keys_in[src];
            vals_out[dst] = vals_in[src];
        }
    }
    //#end
}
