//! raylume-bvh: BVHs built with obvhs, flattened into the layout the WGSL kernels read, and
//! traversed on the CPU in that same layout.
//!
//! **Architecture invariant:** this crate knows nothing about wgpu.

pub mod gpu_types;

pub use gpu_types::{
    BvhNode, INVALID_INDEX, MAX_STACK_DEPTH, PRIM_SPHERE, PRIM_TRIANGLE, Primitive,
};
