//! raylume: GPU path tracing in Rust and WGSL, with a mirrored CPU path.
//!
//! This facade ties the workspace together: a [`Tracer`] takes a loaded
//! [`Scene`], builds its BVH (`raylume-bvh`), traces it in batches of rays
//! per pixel on the GPU (WGSL kernels through wgpu) or on the CPU (the same functions in Rust,
//! with rayon) (`raylume-kernels`), runs the scene's post effects (`raylume-post`), and returns
//! a [`Render`]: linear HDR pixels and honest [`RenderStats`].
//!
//! ```no_run
//! use raylume::{Backend, Tracer};
//! let mut tracer = Tracer::new(Backend::Auto);
//! // Optional, for the first image soonest: the GPU device opens on a thread of its own
//! // while the scene loads and its BVH is built.
//! tracer.start_backend();
//! let scene = raylume::Scene::load("scenes/cornell-box.toml")?;
//! tracer.prepare_scene(&scene)?;
//! let render = tracer.render(&scene)?;
//! eprintln!("{} on {}: {:.3} s", render.stats.backend, render.stats.adapter, render.stats.seconds.total);
//! render.save("cornell.png")?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A scene comes from a file ([`Scene::load`]: TOML, OBJ, glTF, Tungsten) or from code
//! ([`SceneBuilder`]: camera, materials, quads, boxes, spheres, meshes from files, environment;
//! validated as a loaded file is). The model types are in [`scene`], the `glam` they use is
//! [`glam`]. The fields can also be filled by hand, then checked by [`Scene::validate`] (which
//! [`Tracer::render`] runs first):
//!
//! ```
//! use raylume::glam::Vec3;
//! use raylume::scene::{Camera, Material, Scene, Sphere, Triangle};
//! use raylume::{Backend, Tracer};
//!
//! let mut scene = Scene::default(); // black environment, RenderSettings::default()
//! scene.camera = Camera::looking_at(Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 0.5, 0.0), 40.0);
//! scene.render.width = 32;
//! scene.render.height = 24;
//! scene.render.spp = 4;
//! scene.materials = vec![
//!     Material::diffuse("white", Vec3::splat(0.7)),
//!     Material::emissive("lamp", Vec3::splat(10.0)),
//! ];
//! scene.spheres.push(Sphere { center: Vec3::new(0.0, 0.5, 0.0), radius: 0.5, material: 0 });
//! // A lamp quad facing down (emission leaves the side its winding's normal points to).
//! let (a, b, c, d) = (
//!     Vec3::new(-0.5, 2.0, -0.5), Vec3::new(0.5, 2.0, -0.5),
//!     Vec3::new(0.5, 2.0, 0.5), Vec3::new(-0.5, 2.0, 0.5),
//! );
//! scene.triangles.push(Triangle::flat([a, b, c], 1));
//! scene.triangles.push(Triangle::flat([a, c, d], 1));
//!
//! let render = Tracer::new(Backend::Cpu).render(&scene)?; // validates the scene first
//! let path = std::env::temp_dir().join("raylume-doc-quickstart.png");
//! render.save(&path)?;
//! let rgb8: Vec<[u8; 3]> = render.to_srgb8()?; // row-major, top row first
//! assert_eq!(rgb8.len(), 32 * 24);
//! assert!(rgb8.iter().any(|p| p[0] > 0), "the lamp lights the sphere");
//! let image = render.to_image()?; // an image::RgbImage
//! assert_eq!(image.dimensions(), (32, 24));
//! # std::fs::remove_file(&path)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! It implements, and goes past, *Parallelising Ray Tracing on GPUs* (Chandler, Cutfield,
//! Dangwal): the paper's ray generation / propagation / accumulation kernels, its batches of
//! 20 rays per pixel, its Morton-key ray reordering and its bloom.
//!
//! **Architecture invariant:** the facade owns policy (which backend, batch sizes, what to
//! time, where files go), never kernels: every ray computation lives in `raylume-kernels`.

#![warn(missing_docs)]

mod auto;
mod build;
mod error;
mod gpus;
mod output;
mod parts;
mod prepared;
mod stats;
mod target;
pub mod timeline;
mod tracer;

pub use auto::AutoDecision;
pub use build::{MaterialId, SceneBuilder, Transform};
pub use error::Error;
pub use gpus::WorkerStats;
pub use output::{ImageFormat, save_exr, save_png};
pub use parts::{
    Part, PartHeader, SampleRange, join, merge, merge_bound, worst_relative_difference,
};
pub use stats::{DepthSeconds, LightStats, NO_LIGHT_WARNING, RenderStats, StageSeconds};
pub use timeline::{Timeline, TimelineMark};
pub use tracer::{
    BVH_BUILD_THREADS, Backend, BvhBuilder, CPU_FASTEST_BUILD_SECONDS,
    CPU_RAYS_PER_SECOND_PER_THREAD, GPU_BUILD_FIXED_SECONDS, GPU_BUILD_SECONDS,
    GPU_BUILD_TRACE_FACTOR, GPU_RAYS_PER_SECOND, Progress, ROULETTE_TAIL_SEGMENTS, Render,
    ReorderPolicy, Tracer, WALK_STAGE_MIN_PRIMITIVES, WAVEFRONT_MIN_SAMPLES, prepare_materials,
};

pub use raylume_bvh::{BvhLayout, BvhQuality};
pub use raylume_kernels::{
    BatchPlan, CpuIsa, Estimator, Reorder, ReorderMode, Sampler, Schedule, Specialisation,
};
pub use raylume_scene::{Feature, Features, RenderSettings, Scene};

/// Advice for a program that renders on the CPU about how to build raylume; always `None`
/// now. It said to build with `RUSTFLAGS="-C target-cpu=native"` where the build targeted the
/// baseline x86-64 on a CPU with AVX2; the CPU path now picks the CPU's instruction set when
/// it runs ([`CpuIsa`]: AVX2 or AVX-512 from a default build, the same image), which gives a
/// default build the speed of a native one (`docs/RESULTS.md`, issue 15).
#[deprecated(
    since = "0.1.0",
    note = "the CPU path picks the CPU's instruction set at run time (`CpuIsa`): no build advice is needed"
)]
pub fn cpu_build_advice() -> Option<&'static str> {
    None
}

/// The scene model and its loaders (`raylume-scene`, re-exported): [`scene::Camera`],
/// [`scene::Material`], [`scene::Triangle`], [`scene::Sphere`], [`scene::Environment`], ...
/// so that building a scene in code needs no second crate.
pub mod scene {
    pub use raylume_scene::*;
}

/// The `glam` version raylume's scene model uses (`Vec3`, `Vec2`): use it through this path
/// to avoid "multiple different versions of crate `glam`".
pub use glam;
/// The `image` version [`Render::to_image`] returns.
pub use image;
/// Tone mapping for 8-bit output ([`Render::tone`]): exposure, curve, sRGB encoding.
pub use raylume_post::ToneMap;
