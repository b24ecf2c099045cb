// raylume-sort radix sort, stage `sort_scan` (one workgroup per digit): exclusive prefix sum of
// the digit's row of tile counts, in place, and the digit's total over all tiles.
// After it, tile_hist[d * num_tiles + t] = number of keys with digit d in tiles before t.

@group(0) @binding(0) var<uniform> params: SortParams;
@group(0) @binding(3) var<storage, read_write> tile_hist: array<u32>;
@group(0) @binding(4) var<storage, read_write> digit_total: array<u32>;

@compute @workgroup_size(WG)
fn sort_scan(ids: LaneIds) {
    lanes_init(ids);
    let d = ids.wg.x;
    let n = params.num_tiles;
    let row = d * n;
    var carry = 0u;
    for (var base = 0u; base < n; base += WG * SCAN_ITEMS) {
        let first = base + lin * SCAN_ITEMS;
        var sum = 0u;
        //#unroll k SCAN_ITEMS
        var v_{k} = 0u;
        if (first + {k}u < n) {
            v_{k} = tile_hist[row + first + {k}u];
        }
        sum += v_{k};
        //#end
        let sc = wg_exclusive_scan(sum);
        var run = carry + sc.x;
        //#unroll k SCAN_ITEMS
        if (first + {k}u < n) {
            tile_hist[row + first + {k}u] = run;
        }
        run += v_{k};
        //#end
        carry += sc.y;
    }
    if (lin == 0u) {
        digit_total[d] = carry;
    }
}
