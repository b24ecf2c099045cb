//! raylume-bvh: bounding volume hierarchies built with [obvhs](https://docs.rs/obvhs),
//! flattened into the layout the WGSL kernels read, and traversed on the CPU in that same
//! layout.
//!
//! - [`GpuBvh::build`] / [`GpuBvh::from_scene`]: one BVH over a scene's triangles and spheres.
//!   Both [`BvhQuality`] presets build bottom-up with PLOC (Meister & Bittner, *Parallel
//!   Locally-Ordered Clustering for Bounding Volume Hierarchy Construction*, IEEE TVCG 2018)
//!   and improve the tree by SAH-driven parallel reinsertion (Meister & Bittner, *Parallel
//!   Reinsertion for Bounding Volume Hierarchy Optimization*, Eurographics 2018);
//!   [`BvhQuality::Quality`] adds spatial pre-splits of large triangles. The tree is then
//!   flattened to 64-byte [`BvhNode`]s that hold both children's boxes (Aila & Laine,
//!   *Understanding the Efficiency of Ray Traversal on GPUs*, HPG 2009), leaves folded into
//!   their parents, and the primitives copied out in leaf order as 48-byte [`Primitive`]s.
//! - [`GpuBvh::validate`]: every invariant the traversal relies on; tests call it after every
//!   build.
//! - [`traverse`]: the CPU traversal of that layout ([`trace_closest`], [`trace_any`]: explicit
//!   fixed-size stack, nearer child first), over the tests in [`intersect`]
//!   ([`intersect_aabb`], a NaN-safe, rounding-conservative slab test after Ize, JCGT 2013;
//!   [`intersect_triangle`], watertight after Woop, Benthin & Wald, JCGT 2013;
//!   [`intersect_sphere`]). They are the reference for [`TRAVERSE_WGSL`], the same functions
//!   in WGSL, bit-identical on lavapipe.
//!
//! ```
//! use glam::Vec3;
//! use raylume_bvh::{BvhQuality, GpuBvh, Ray};
//! use raylume_scene::{Sphere, Triangle};
//!
//! let floor = [
//!     Triangle::flat([Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0)], 0),
//!     Triangle::flat([Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(-1.0, 0.0, 1.0)], 0),
//! ];
//! let ball = [Sphere { center: Vec3::new(0.0, 0.5, 0.0), radius: 0.5, material: 0 }];
//! let bvh = GpuBvh::build(&floor, &ball, BvhQuality::Quality)?;
//! bvh.validate().unwrap();
//!
//! let down = Ray::new(Vec3::new(0.0, 2.0, 0.0), -Vec3::Y);
//! let hit = bvh.trace_closest(&down, 0.0, f32::INFINITY).expect("the ball is below");
//! assert_eq!(hit.t, 1.0);
//! assert_eq!(bvh.primitives[hit.prim as usize].kind(), raylume_bvh::PRIM_SPHERE);
//! let beside = Ray::new(Vec3::new(0.9, 2.0, 0.0), -Vec3::Y);
//! assert_eq!(bvh.trace_closest(&beside, 0.0, f32::INFINITY).unwrap().t, 2.0); // the floor
//! # Ok::<(), raylume_bvh::BvhError>(())
//! ```
//!
//! **Architecture invariant:** this crate knows nothing about wgpu. The WGSL it ships is a
//! string; the crates that run it own the bindings.

mod bounds;
mod builder;
mod error;
mod flatten;
mod gpu_bvh;
pub mod huge_pages;
pub mod lbvh;
mod median;
mod quality;
mod stats;
mod validate;
mod wide;
#[cfg(target_arch = "x86_64")]
mod wide_avx2;
#[cfg(target_arch = "x86_64")]
pub use wide_avx2::{FLAT_MAX_PRIMITIVES, FLAT_MAX_PRIMITIVES_AVX2};
mod wide_convert;

pub mod gpu_types;
pub mod intersect;
pub mod traverse;
pub mod wide_traverse;

#[doc(hidden)]
pub use builder::BuildProfile;
pub use error::BvhError;
pub use gpu_bvh::{CpuArrays, GpuBvh};
pub use gpu_types::{
    BvhLayout, BvhNode, INVALID_INDEX, MAX_STACK_DEPTH, PRIM_SPHERE, PRIM_TRIANGLE, Primitive,
    WIDE_STACK_SIZE, WideNode,
};
pub use huge_pages::HugePageArray;
pub use intersect::{
    AABB_T_FAR_SCALE, Ray, ShearedRay, T_MISS, intersect_aabb, intersect_primitive,
    intersect_sphere, intersect_triangle, shear_ray,
};
pub use quality::{BvhQuality, PRESET_BUILD_SECONDS, PRESET_TRACE_FACTOR};
pub use stats::{BvhStats, Fallback, SAH_NODE_COST, SAH_PRIMITIVE_COST};
pub use traverse::{Hit, T_MAX_LIMIT, trace_any, trace_closest};
pub use wide_traverse::{WIDE_ANY_OCT_FLIP, WIDE_INV_DIR_LIMIT, WIDE_QUANT_PAD, WIDE_T_FAR_SCALE};

/// The WGSL of [`traverse`]: the structs [`BvhNode`], [`Primitive`], `Hit`, `Ray`, the
/// constants (`INVALID_INDEX`, `MAX_STACK_DEPTH`, `PRIM_TRIANGLE`, `PRIM_SPHERE`, `T_MISS`,
/// `T_MAX_LIMIT`, `AABB_T_FAR_SCALE`) and the functions `intersect_aabb`,
/// `intersect_triangle`, `intersect_sphere`, `intersect_primitive`, `trace_closest`,
/// `trace_any` (plus helpers `bvh_dot`, `shear_ray`, `intersect_leaf` and `binary_walk`, the
/// one walk of both queries).
///
/// It declares no bindings. Concatenate it with a shader that declares, at module scope,
///
/// ```wgsl
/// @group(0) @binding(0) var<storage, read> bvh_nodes: array<BvhNode>;
/// @group(0) @binding(1) var<storage, read> bvh_primitives: array<Primitive>;
/// ```
///
/// (any group and binding numbers), filled with [`GpuBvh::nodes`] and [`GpuBvh::primitives`].
/// `trace_closest(ray, t_min, t_max) -> Hit` reports a miss as `prim == INVALID_INDEX`.
pub const TRAVERSE_WGSL: &str = concat!(
    include_str!("gpu_types.wgsl"),
    "\n",
    include_str!("intersect.wgsl"),
    "\n",
    include_str!("hit.wgsl"),
    "\n",
    include_str!("traverse.wgsl"),
);

/// The WGSL of [`wide_traverse`]: as [`TRAVERSE_WGSL`], with `trace_closest` and `trace_any`
/// over [`WideNode`]s (`bvh_nodes: array<TraversalNode>`, `TraversalNode` being `WideNode`
/// here), filled with [`GpuBvh::wide_nodes`] of a tree built with [`BvhLayout::Wide`].
pub const WIDE_TRAVERSE_WGSL: &str = concat!(
    include_str!("gpu_types.wgsl"),
    "\n",
    include_str!("intersect.wgsl"),
    "\n",
    include_str!("hit.wgsl"),
    "\n",
    include_str!("wide_traverse.wgsl"),
);

/// The WGSL of [`gpu_types`]: `BvhNode`, `Primitive`, `WideNode` and the constants of the
/// layout (the first part of [`TRAVERSE_WGSL`]), for shaders that write trees rather than
/// traverse them.
pub const BVH_TYPES_WGSL: &str = include_str!("gpu_types.wgsl");

/// The WGSL of [`lbvh`]'s GPU half: `LbvhParams`, `LbvhInner`, `lbvh_box_min`,
/// `lbvh_box_max`, `morton_code`, `lbvh_delta`, `lbvh_node` (and helpers `lbvh_spread`,
/// `lbvh_clz64`), the same arithmetic as the Rust functions of those names. It needs
/// [`BVH_TYPES_WGSL`]'s `Primitive`, the constant `LBVH_AXIS_BITS`
/// ([`lbvh::LBVH_AXIS_BITS`]) and, at module scope, `lbvh_params: LbvhParams` and
/// `lbvh_codes: array<vec2<u32>>` (the sorted codes, low word first); it declares no
/// bindings.
pub const LBVH_WGSL: &str = include_str!("lbvh.wgsl");

/// [`TRAVERSE_WGSL`] or [`WIDE_TRAVERSE_WGSL`], by layout.
pub const fn traverse_wgsl(layout: BvhLayout) -> &'static str {
    match layout {
        BvhLayout::Binary => TRAVERSE_WGSL,
        BvhLayout::Wide => WIDE_TRAVERSE_WGSL,
    }
}

/// A deterministic pseudo-random number in [0, 1) (a 64-bit LCG's top bits), for the unit
/// tests' random soups and rays.
#[cfg(test)]
pub(crate) fn test_rand(state: &mut u64) -> f32 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 40) as f32 / (1u64 << 24) as f32
}
