//! raylume's wgpu plumbing, shared by every crate that runs WGSL: `raylume-kernels`,
//! `raylume-sort`, `raylume-post` and the `raylume` facade.
//!
//! - [`GpuContext`]: picks an adapter (discrete GPU first, Vulkan over GL), asks for the
//!   adapter's own limits (lavapipe: 128 MiB per storage binding; an H100: 2 GiB) and the
//!   optional features raylume uses (timestamps, subgroups), and records what it got.
//! - [`GpuError`]: every GPU failure as a typed error a user can act on: no adapter, a
//!   buffer larger than the adapter allows, validation errors, out-of-memory, device loss.
//! - [`GpuContext::scoped`]: runs GPU work under error scopes so that wgpu's errors come back
//!   as `Err` instead of a panic in its default handler.
//! - [`GpuContext::read_buffer`]: copies a storage buffer back to the CPU.
//! - [`Timestamps`]: named GPU timestamps around compute passes.
//! - [`testing::context_or_skip`]: what every GPU test calls first: a context, or a visible
//!   skip message (a failure when `RAYLUME_REQUIRE_GPU=1`).
//!
//! ```no_run
//! let ctx = raylume_gpu::GpuContext::new(&raylume_gpu::ContextOptions::default())?;
//! println!("{}", ctx.describe());
//! # Ok::<(), raylume_gpu::GpuError>(())
//! ```
//!
//! **Architecture invariant:** this crate knows nothing about scenes, rays or images.

mod context;
mod error;
mod timestamps;

pub mod testing;

pub use context::{AdapterChoice, ContextOptions, GpuContext, GpuInfo};
pub use error::GpuError;
pub use timestamps::Timestamps;

/// Re-exported so that dependants name one wgpu version.
pub use wgpu;
