// raylume-sort radix sort, stage `sort_setup` (one thread): reads the element count that the
// sorter copied into `count`, clamps it to MAX_LEN, and writes the parameters every later
// stage reads plus the indirect dispatch arguments of the tile grid.

@group(0) @binding(0) var<storage, read> count: array<u32>;
@group(0) @binding(1) var<storage, read_write> params_out: SortParams;
@group(0) @binding(2) var<storage, read_write> dispatch_args: array<u32>;

@compute @workgroup_size(1)
fn sort_setup() {
    let n = min(count[0], MAX_LEN);
    let tiles = (n + (TILE - 1u)) / TILE;
    let gx = min(tiles, MAX_GRID_X);
    var gy = 0u;
    if (gx > 0u) {
        gy = (tiles + gx - 1u) / gx;
    }
    params_out = SortParams(n, tiles, gx, gy);
    dispatch_args[0] = gx;
    dispatch_args[1] = gy;
    dispatch_args[2] = 1u;
}
