//! raylume-sort: the ray sorting of *Parallelising Ray Tracing on GPUs* (Chandler, Cutfield,
//! Dangwal), which used CUB's radix sort on 30-bit origin-direction Morton keys, rebuilt in
//! Rust + WGSL.
//!
//! - [`morton`]: the 30-bit key of a ray ([`ray_sort_key`]), in Rust and in WGSL
//!   ([`MORTON_WGSL`], `src/morton.wgsl`, for the tracer's `propagate` kernel), bit-identical.
//!   Dead rays get [`DEAD_RAY_KEY`] and sort after every live ray, so sorting also compacts.
//! - [`RadixSorter`]: a stable LSD radix sort of `(u32 key, u32 value)` pairs in WGSL
//!   (reduce-then-scan, Merrill & Grimshaw 2011, *High performance and scalable radix sorting*;
//!   tile ranking by subgroup ballots as in Adinets & Merrill 2022, *Onesweep*), recorded into
//!   the caller's command encoder, sorting a length known on the CPU or one read from a GPU
//!   buffer ([`SortLen::Indirect`]).
//! - [`sort_pairs_cpu`]: the reference it is tested against.
//!
//! ```
//! use raylume_sort::{sort_pairs_cpu, ray_sort_key, DEAD_RAY_KEY};
//! use glam::Vec3;
//! let (lo, ext) = (Vec3::ZERO, Vec3::ONE);
//! let keys = [
//!     DEAD_RAY_KEY,
//!     ray_sort_key(Vec3::splat(0.9), Vec3::X, lo, ext),
//!     ray_sort_key(Vec3::splat(0.1), Vec3::X, lo, ext),
//! ];
//! let (sorted, rays) = sort_pairs_cpu(&keys, &[0, 1, 2], 30);
//! assert_eq!(rays, vec![2, 1, 0]); // the dead ray 0 goes last
//! assert_eq!(sorted[2], DEAD_RAY_KEY);
//! ```
//!
//! ## Design choices (numbers from `benches/sort.rs` on an NVIDIA H100, Vulkan, 2026-11-23)
//! - **8-bit digits, 4 passes** for 30-bit keys by default (`radix_bits` 4..=10 is an option):
//!   16M pairs in 1.14 ms (14.7 G pairs/s, ~1.2 TB/s counting 20 bytes per pair and pass);
//!   1M in 0.13 ms, 4M in 0.35 ms, the adapter's maximum of 536,870,911 in 34 ms.
//!   10-bit digits save a pass but took 3.7 ms: a tile scatters into 1024 buckets (a few keys,
//!   a fraction of a 32-byte sector, per bucket), needs 4x the tile counters, and its
//!   per-subgroup counters do not fit 48 KiB of workgroup memory at 256 threads; 9-bit digits
//!   (still 4 passes) took 2.1 ms, 7-bit (5 passes) 1.4 ms. On lavapipe 8 bits were also the
//!   fastest (1M pairs: 0.42 s against 0.61 s for 10 bits, 0.88 s without subgroups). An even pass count also leaves the
//!   result in the caller's buffers without a copy.
//! - **Tiles of 256 threads x 12 keys.** Per-key state is kept in unrolled scalars: the WGSL
//!   is generated with `//#unroll` blocks expanded ([`Stage`] lists the kernels), because
//!   loops over private arrays put them in local memory on NVIDIA's compiler (4.9 ms before).
//! - **Reduce-then-scan**, not decoupled look-back: no workgroup ever waits for another, so the
//!   sort is safe where WGSL gives no forward-progress guarantee. The price is one extra read
//!   of the keys per pass (the upsweep, ~20% of the time).
//! - **Subgroups when present** (ballots for ranking, subgroup scans), any subgroup size up to
//!   128, no assumption on how invocations map to subgroups; a shared-memory path (binary-split
//!   local sort, 2.7 ms for 16M on the H100) when absent or disabled.
//! - **Lengths from the GPU**: `sort_setup` turns a count in a buffer into indirect dispatch
//!   arguments. wgpu validates indirect dispatches by default (`VALIDATION_INDIRECT_CALL`),
//!   which cost ~40 us per sort on the H100; `sort_setup` already clamps to the limits.
//!
//! **Architecture invariant:** this crate knows nothing about scenes, rays' other state or the
//! tracer's kernels; it sorts `u32` pairs and computes keys from vectors.

mod cpu;
mod error;
pub mod morton;
mod radix_sort;

pub use cpu::{key_mask, sort_pairs_cpu};
pub use error::SortError;
pub use morton::{DEAD_RAY_KEY, LIVE_RAY_KEY_MAX, MORTON_WGSL, RAY_KEY_BITS, ray_sort_key};
pub use radix_sort::{
    LANE_MASK_WGSL, RadixSorter, SortLen, SortOptions, SortParams, SortPass, SortPlan, Stage,
    sort_pairs, sort_pairs_with,
};
