//! [`GpuBvh`]: the flattened tree and its primitives, ready to upload.

use crate::stats::BvhStats;
use crate::{BvhNode, Primitive};

/// A BVH over a scene's triangles and spheres in the layout the WGSL kernels read.
///
/// Upload `nodes` and `primitives` unchanged (`bytemuck::cast_slice`) as the storage buffers
/// `bvh_nodes` and `bvh_primitives` that [`TRAVERSE_WGSL`](crate::TRAVERSE_WGSL) expects.
#[derive(Clone, Debug)]
pub struct GpuBvh {
    /// Inner nodes in depth-first order; node 0 is the root. Never empty.
    pub nodes: Vec<BvhNode>,
    /// Primitives in leaf order: `primitives[i]` is the i-th primitive met leaf by leaf. With
    /// spatial splits one scene triangle may have copies in several leaves; each copy carries
    /// its kind and scene index.
    pub primitives: Vec<Primitive>,
    /// Length of the scene's `triangles` the tree was built over.
    pub triangle_count: u32,
    /// Length of the scene's `spheres` the tree was built over.
    pub sphere_count: u32,
    /// What the build produced and cost.
    pub stats: BvhStats,
}
