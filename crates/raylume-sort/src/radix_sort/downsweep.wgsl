// raylume-sort radix sort, stage `sort_downsweep` (one workgroup per tile): ranks each key of
// the tile among the keys of its digit, stably (rank_subgroup.wgsl or rank_split.wgsl), and
// scatters keys and values to
//   dest = (keys of smaller digits, all tiles) + (keys of this digit in earlier tiles)
//        + (keys of this digit earlier in this tile).
// Keys and values go through shared memory in digit order first, so that consecutive threads
// write consecutive addresses within each digit's run.

@group(0) @binding(0) var<uniform> params: SortParams;
@group(0) @binding(1) var<uniform> pass_info: SortPass;
@group(0) @binding(2) var<storage, read> keys_in: array<u32>;
@group(0) @binding(3) var<storage, read> vals_in: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> vals_out: array<u32>;
@group(0) @binding(6) var<storage, read> tile_hist: array<u32>;
@group(0) @binding(7) var<storage, read> digit_total: array<u32>;

/// Global position of this tile's first key of each digit (later minus the digit's first
/// position inside the tile, so that dest = s_base[d] + position in the digit-sorted tile).
var<workgroup> s_base: array<u32, RADIX>;

fn digit_of(key: u32) -> u32 {
    return (key >> pass_info.shift) & pass_info.mask;
}

/// s_base[d] = (keys of digits < d over all tiles) + (keys of digit d in tiles before `tile`).
fn load_digit_bases(tile: u32) {
    let d0 = lin * DIGITS_PER_THREAD;
    var sum = 0u;
    for (var j = 0u; j < DIGITS_PER_THREAD; j++) {
        if (d0 + j < RADIX) {
            sum += digit_total[d0 + j];
        }
    }
    var run = wg_exclusive_scan(sum).x;
    for (var j = 0u; j < DIGITS_PER_THREAD; j++) {
        let d = d0 + j;
        if (d < RADIX) {
            s_base[d] = run + tile_hist[d * params.num_tiles + tile];
            run += digit_total[d];
        }
    }
}

@compute @workgroup_size(WG)
fn sort_downsweep(ids: LaneIds) {
    let tile = tile_index(ids.wg, ids.nwg);
    if (tile >= params.num_tiles) {
        return;
    }
    lanes_init(ids);
    let start = tile * TILE;
    let valid = min(TILE, params.len - start);
    load_digit_bases(tile);
    rank_and_scatter(start, valid);
}
