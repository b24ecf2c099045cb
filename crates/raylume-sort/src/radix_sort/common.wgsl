// raylume-sort radix sort: types and helpers shared by every stage.
//
// The generated prelude (src/radix_sort/shader.rs) defines before this text:
//   WG (threads per workgroup), ITEMS (keys per thread), TILE = WG * ITEMS,
//   RADIX_BITS, RADIX = 1 << RADIX_BITS, DIGITS_PER_THREAD = ceil(RADIX / WG),
//   SCAN_ITEMS (tile counts per thread in `sort_scan`), MAX_SG (most subgroups in a workgroup),
//   MAX_LEN (the sorter's capacity), MAX_GRID_X (workgroups per grid row).

/// The length of this sort and its tile grid; written by `sort_setup`, read as a uniform by the
/// other stages. Mirror of `SortParams` in gpu_types.rs (16 bytes).
struct SortParams {
    len: u32,
    num_tiles: u32,
    grid_x: u32,
    grid_y: u32,
}

/// One radix pass: the digit is `(key >> shift) & mask`. Mirror of `SortPass` (16 bytes).
struct SortPass {
    shift: u32,
    mask: u32,
    index: u32,
    _pad: u32,
}

/// Tiles are numbered row by row over a 2D grid of at most MAX_GRID_X workgroups per row.
fn tile_index(wg: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wg.x + wg.y * nwg.x;
}
