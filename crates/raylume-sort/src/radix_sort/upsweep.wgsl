// raylume-sort radix sort, stage `sort_upsweep` (one workgroup per tile of TILE keys): the
// tile's histogram of this pass's digit, stored digit-major: tile_hist[digit * num_tiles + tile].
// Counting is one workgroup atomic per key, except that a subgroup whose keys all share a digit
// (sorted or coherent input) adds its count once, so coherent keys cost no contention.

@group(0) @binding(0) var<uniform> params: SortParams;
@group(0) @binding(1) var<uniform> pass_info: SortPass;
@group(0) @binding(2) var<storage, read> keys_in: array<u32>;
@group(0) @binding(3) var<storage, read_write> tile_hist: array<u32>;

var<workgroup> s_hist: array<atomic<u32>, RADIX>;

@compute @workgroup_size(WG)
fn sort_upsweep(ids: LaneIds) {
    let tile = tile_index(ids.wg, ids.nwg);
    if (tile >= params.num_tiles) {
        return;
    }
    lanes_init(ids);
    for (var d = lin; d < RADIX; d += WG) {
        atomicStore(&s_hist[d], 0u);
    }
    let start = tile * TILE;
    let valid = min(TILE, params.len - start);
    // Loads first, all in flight together.
    //#unroll i ITEMS
    var d_{i} = RADIX; // no key
    if ({i}u * WG + lin < valid) {
        d_{i} = (keys_in[start + {i}u * WG + lin] >> pass_info.shift) & pass_info.mask;
    }
    //#end
    workgroupBarrier();
    //#unroll i ITEMS
    if (lanes_agree(d_{i})) {
        if (lane_leads() && d_{i} < RADIX) {
            atomicAdd(&s_hist[d_{i}], lanes_active());
        }
    } else if (d_{i} < RADIX) {
        atomicAdd(&s_hist[d_{i}], 1u);
    }
    //#end
    workgroupBarrier();
    for (var d = lin; d < RADIX; d += WG) {
        tile_hist[d * params.num_tiles + tile] = atomicLoad(&s_hist[d]);
    }
}
