// raylume-sort radix sort, stage `sort_copy`: after an odd number of passes the sorted pairs
// sit in the sorter's scratch buffers; this copies the first `len` back to the caller's.

@group(0) @binding(0) var<uniform> params: SortParams;
@group(0) @binding(2) var<storage, read> keys_in: array<u32>;
@group(0) @binding(3) var<storage, read> vals_in: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> vals_out: array<u32>;

@compute @workgroup_size(WG)
fn sort_copy(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
             @builtin(local_invocation_index) local_index: u32) {
    let tile = tile_index(wg, nwg);
    if (tile >= params.num_tiles) {
        return;
    }
    let start = tile * TILE;
    let valid = min(TILE, params.len - start);
    //#unroll i ITEMS
    if ({i}u * WG + local_index < valid) {
        keys_out[start + {i}u * WG + local_index] = keys_in[start + {i}u * WG + local_index];
        vals_out[start + {i}u * WG + local_index] = vals_in[start + {i}u * WG + local_index];
    }
    //#end
}
