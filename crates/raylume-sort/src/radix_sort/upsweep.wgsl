// raylume-sort radix sort, stage `sort_upsweep` (one workgroup per tile of TILE keys): the
// tile's histogram of this pass's digit, stored digit-major: tile_hist[digit * num_tiles + tile].

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
    workgroupBarrier();
    let start = tile * TILE;
    let valid = min(TILE, params.len - start);
    for (var i = 0u; i < ITEMS; i++) {
        let idx = i * WG + lin;
        var d = RADIX; // no key
        if (idx < valid) {
            d = (keys_in[start + idx] >> pass_info.shift) & pass_info.mask;
        }
        let c = digit_leader_count(d);
        if (c != 0u && d < RADIX) {
            atomicAdd(&s_hist[d], c);
        }
    }
    workgroupBarrier();
    for (var d = lin; d < RADIX; d += WG) {
        tile_hist[d * params.num_tiles + tile] = atomicLoad(&s_hist[d]);
    }
}
