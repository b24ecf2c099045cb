//! The radix sort's GPU-visible structs; the WGSL twins are in `common.wgsl`, same names and
//! field order.

use bytemuck::{Pod, Zeroable};

/// The length of one sort and its tile grid, written on the GPU by `sort_setup` and read as a
/// uniform by the other stages. `repr(C)`, Pod, 16 bytes; WGSL `SortParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SortParams {
    /// Number of pairs sorted (the requested count clamped to the sorter's capacity).
    pub len: u32,
    /// Tiles of `TILE` pairs: `ceil(len / TILE)`.
    pub num_tiles: u32,
    /// Workgroups per row of the tile grid (at most the adapter's dispatch limit).
    pub grid_x: u32,
    /// Rows of the tile grid.
    pub grid_y: u32,
}
const _: () = assert!(std::mem::size_of::<SortParams>() == 16);
const _: () = assert!(std::mem::offset_of!(SortParams, num_tiles) == 4);
const _: () = assert!(std::mem::offset_of!(SortParams, grid_x) == 8);
const _: () = assert!(std::mem::offset_of!(SortParams, grid_y) == 12);

/// One radix pass: the digit of a key is `(key >> shift) & mask`. `repr(C)`, Pod, 16 bytes;
/// WGSL `SortPass`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SortPass {
    pub shift: u32,
    pub mask: u32,
    /// 0-based pass number (even passes read the caller's buffers).
    pub index: u32,
    pub _pad: u32,
}
const _: () = assert!(std::mem::size_of::<SortPass>() == 16);
const _: () = assert!(std::mem::offset_of!(SortPass, mask) == 4);
const _: () = assert!(std::mem::offset_of!(SortPass, index) == 8);
