//! raylume: GPU path tracing in Rust and WGSL, with a mirrored CPU path.
//!
//! This facade ties the workspace together: a [`Tracer`] takes a loaded
//! [`Scene`](raylume_scene::Scene), builds its BVH (`raylume-bvh`), traces it in batches of rays
//! per pixel on the GPU (WGSL kernels through wgpu) or on the CPU (the same functions in Rust,
//! with rayon) (`raylume-kernels`), runs the scene's post effects (`raylume-post`), and returns
//! a [`Render`]: linear HDR pixels and honest [`RenderStats`].
//!
//! ```no_run
//! use raylume::{Backend, Tracer};
//! let scene = raylume::Scene::load("scenes/cornell-box.toml")?;
//! let mut tracer = Tracer::new(Backend::Auto);
//! let render = tracer.render(&scene)?;
//! eprintln!("{} on {}: {:.3} s", render.stats.backend, render.stats.adapter, render.stats.seconds.total);
//! render.save("cornell.png")?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! It implements, and goes past, *Parallelising Ray Tracing on GPUs* (Chandler, Cutfield,
//! Dangwal): the paper's ray generation / propagation / accumulation kernels, its batches of
//! 20 rays per pixel, its Morton-key ray reordering and its bloom.
//!
//! **Architecture invariant:** the facade owns policy (which backend, batch sizes, what to
//! time, where files go), never kernels: every ray computation lives in `raylume-kernels`.

mod auto;
mod error;
mod output;
mod stats;
mod tracer;

pub use auto::AutoDecision;
pub use error::Error;
pub use output::{ImageFormat, save_exr, save_png};
pub use stats::{DepthSeconds, RenderStats, StageSeconds};
pub use tracer::{Backend, Progress, Render, ReorderPolicy, Tracer};

pub use raylume_bvh::BvhQuality;
pub use raylume_kernels::{BatchPlan, Estimator, Reorder, ReorderMode, Schedule};
pub use raylume_scene::{Feature, Features, RenderSettings, Scene};
