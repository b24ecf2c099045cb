//! GPU radix sort of `(u32 key, u32 value)` pairs: LSD, stable, reduce-then-scan.
//!
//! Per pass of `radix_bits` bits, three kernels over tiles of `workgroup_size *
//! items_per_thread` keys (Merrill & Grimshaw's reduce-then-scan; the tile ranking is Onesweep's
//! warp-level multi-split, Adinets & Merrill 2022):
//! 1. `sort_upsweep`: each tile's digit histogram, stored digit-major `[digit][tile]`;
//! 2. `sort_scan`: one workgroup per digit scans its row over the tiles (exclusive) and writes
//!    the digit's total;
//! 3. `sort_downsweep`: each tile ranks its keys stably within their digit (subgroup ballots,
//!    or shared-memory binary splits without subgroups), adds the digit's global offset (an
//!    exclusive scan of the totals, recomputed per workgroup) and its tiles-before count, and
//!    scatters keys and values through shared memory so that writes are coalesced.
//!
//! A one-thread `sort_setup` kernel first reads the element count from a GPU buffer and writes
//! the tile grid's indirect dispatch arguments, so that a count computed on the GPU (the live
//! rays) needs no read-back. No kernel waits on another workgroup (no decoupled look-back), so
//! the sort cannot dead-lock on adapters without forward-progress guarantees.

mod encode;
mod gpu_types;
mod options;
mod shader;
mod sorter;

pub use gpu_types::{SortParams, SortPass};
pub use options::{SortOptions, SortPlan};
pub use shader::{LANE_MASK_WGSL, Stage};
pub use sorter::RadixSorter;

use raylume_gpu::GpuContext;

use crate::SortError;

/// How many pairs [`RadixSorter::encode`] sorts.
#[derive(Clone, Copy, Debug)]
pub enum SortLen<'a> {
    /// A count known on the CPU (at most the sorter's `max_len`).
    Fixed(u32),
    /// A count the GPU wrote: the `u32` at byte `offset` of `count_buffer` (which needs
    /// `BufferUsages::COPY_SRC`; `offset` a multiple of 4). It is read when the commands run
    /// and clamped to the sorter's `max_len`.
    Indirect {
        count_buffer: &'a wgpu::Buffer,
        offset: u64,
    },
}

/// Sorts `(key, value)` pairs by the low 30 bits of the key on the GPU ([`SortOptions::ray_keys`]),
/// stably; a convenience for tests that builds a sorter for this one call.
pub fn sort_pairs(
    ctx: &GpuContext,
    keys: &[u32],
    values: &[u32],
) -> Result<(Vec<u32>, Vec<u32>), SortError> {
    sort_pairs_with(ctx, keys, values, SortOptions::ray_keys())
}

/// [`sort_pairs`] with chosen options.
pub fn sort_pairs_with(
    ctx: &GpuContext,
    keys: &[u32],
    values: &[u32],
    opts: SortOptions,
) -> Result<(Vec<u32>, Vec<u32>), SortError> {
    let len = u32::try_from(keys.len()).map_err(|_| SortError::TooLong {
        len: keys.len() as u64,
        max_len: u32::MAX,
    })?;
    let sorter = RadixSorter::new(ctx, len, opts)?;
    sorter.sort_pairs(ctx, keys, values)
}
