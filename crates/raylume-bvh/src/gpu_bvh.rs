//! [`GpuBvh`]: the flattened tree and its primitives, ready to upload.

use std::sync::OnceLock;

use crate::huge_pages::HugePageArray;
use crate::intersect::TriangleBlock;
use crate::stats::BvhStats;
use crate::wide_traverse::{WideBoxes, triangle_blocks, wide_boxes};
use crate::{BvhLayout, BvhNode, Primitive, WideNode};

/// A BVH over a scene's triangles and spheres in the layout the WGSL kernels read.
///
/// Upload [`GpuBvh::node_bytes`] and `primitives` unchanged as the storage buffers
/// `bvh_nodes` and `bvh_primitives` that [`GpuBvh::traverse_wgsl`] (for the tree's
/// [`layout`](GpuBvh::layout)) expects.
#[derive(Clone, Debug)]
pub struct GpuBvh {
    /// Which of the two node arrays below holds the tree.
    pub layout: BvhLayout,
    /// [`BvhLayout::Binary`]: inner nodes in depth-first order; node 0 is the root. Never
    /// empty in that layout, empty in the other.
    pub nodes: Vec<BvhNode>,
    /// [`BvhLayout::Wide`]: the compressed eight-wide nodes; node 0 is the root. Never empty
    /// in that layout, empty in the other.
    pub wide_nodes: Vec<WideNode>,
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
    /// The arrays the CPU's wide walk reads instead of `wide_nodes` and `primitives`
    /// ([`GpuBvh::wide_boxes`], [`GpuBvh::triangle_blocks`]), made on the first CPU
    /// traversal (`Default::default()` when building a `GpuBvh` by hand).
    pub cpu_arrays: CpuArrays,
}

/// What the CPU's wide walk reads instead of the GPU's arrays, made from them on first use
/// ([`GpuBvh::wide_boxes`], [`GpuBvh::triangle_blocks`]): the nodes' [`WideBoxes`] (224
/// bytes a node) and their leaves' triangles in [`TriangleBlock`]s (144 bytes per four, about
/// 40 bytes a primitive), which a GPU-only render never makes. Made once; a tree whose `wide_nodes` or `primitives` are
/// changed after a CPU traversal needs [`CpuArrays::default`] again.
#[derive(Clone, Default)]
pub struct CpuArrays(OnceLock<CpuWalkArrays>);

/// What [`CpuArrays`] holds once made.
#[derive(Clone)]
pub(crate) struct CpuWalkArrays {
    /// A node's float boxes ([`WideBoxes`]), by node. (Both arrays in huge pages where
    /// [`GpuBvh::prepare_cpu_walks`] asked for them: [`HugePageArray`].)
    pub(crate) boxes: HugePageArray<WideBoxes>,
    /// The nodes' leaf triangles four a block ([`TriangleBlock`]).
    pub(crate) blocks: HugePageArray<TriangleBlock>,
    /// A small tree's triangles, all of them, sixteen a block grouped by where they lie, each
    /// block with its box (the AVX-512 walks test them all instead of walking, a block only
    /// where the ray enters its box before the closest hit so far: `wide_avx2::flat_hit16`);
    /// empty for a tree of more than `FLAT_MAX_PRIMITIVES` primitives or one with a sphere.
    /// x86-64 only, as the walks that read it.
    #[cfg(target_arch = "x86_64")]
    pub(crate) flat: crate::wide_avx2::FlatSet,
    /// The triangles of `flat` a segment between two points of the scene may meet (all but
    /// the hull's faces), as `flat` groups them, for the AVX-512 walks' any-hit tests of such
    /// segments ([`GpuBvh::trace_any_between_avx512`]).
    #[cfg(target_arch = "x86_64")]
    pub(crate) flat_between16: crate::wide_avx2::FlatSet,
    /// The tree's triangles sixteen a block in the tree's order (`wide_avx2::flat_blocks`)
    /// for the AVX2 walks (`wide_avx2::flat_hit`, eight lanes at a time) if the tree has at
    /// most `FLAT_MAX_PRIMITIVES_AVX2` primitives, else empty. (An array of its own, not a
    /// flag or the count checked in the walk: either made LLVM lay out `flat_hit` otherwise,
    /// its closest hits 20-30 % slower on the Intel dev VM.)
    #[cfg(target_arch = "x86_64")]
    pub(crate) flat_avx2: Vec<crate::wide_avx2::FlatBlock>,
    /// The triangles of `flat_avx2` a segment between two points of the scene may meet (all
    /// but the hull's faces: `wide_avx2::flat_between_blocks`), tested by the AVX2 walks'
    /// any-hit tests of such segments ([`GpuBvh::trace_any_between_avx2`]), and how many.
    #[cfg(target_arch = "x86_64")]
    pub(crate) flat_between: (Vec<crate::wide_avx2::FlatBlock>, usize),
}

impl std::fmt::Debug for CpuArrays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0.get() {
            Some(a) => write!(f, "CpuArrays({} nodes)", a.boxes.len()),
            None => write!(f, "CpuArrays(not made)"),
        }
    }
}

impl GpuBvh {
    /// The tree's nodes as bytes, to upload as `bvh_nodes`.
    pub fn node_bytes(&self) -> &[u8] {
        match self.layout {
            BvhLayout::Binary => bytemuck::cast_slice(&self.nodes),
            BvhLayout::Wide => bytemuck::cast_slice(&self.wide_nodes),
        }
    }

    /// The traversal WGSL for this tree's layout: [`TRAVERSE_WGSL`](crate::TRAVERSE_WGSL) or
    /// [`WIDE_TRAVERSE_WGSL`](crate::WIDE_TRAVERSE_WGSL). Both define `TraversalNode` (the
    /// element type of `bvh_nodes`), `Hit`, `trace_closest` and `trace_any`.
    pub fn traverse_wgsl(&self) -> &'static str {
        crate::traverse_wgsl(self.layout)
    }

    /// The float boxes of [`GpuBvh::wide_nodes`] that the CPU's traversal tests
    /// ([`WideBoxes`]), made on the first call and kept (about 0.1 us a node, on the calling
    /// thread: a `rayon` loop here could, while it waits, take up another ray's trace on this
    /// same thread and re-enter this initialisation). Call it before tracing in parallel to
    /// keep that first call out of the loop, as the CPU tracer does.
    pub fn wide_boxes(&self) -> &[WideBoxes] {
        &self.cpu_walk_arrays().boxes
    }

    /// The wide nodes' leaf triangles four a block, for the CPU's wide walk's four-at-once
    /// triangle tests ([`TriangleBlock`]; a node's first is its [`WideBoxes::block_base`]);
    /// made with [`GpuBvh::wide_boxes`].
    pub fn triangle_blocks(&self) -> &[TriangleBlock] {
        &self.cpu_walk_arrays().blocks
    }

    /// Whether the CPU's AVX walks test this tree flat, every triangle against every ray,
    /// instead of walking it: with `avx512` the x86-64-v4 ones
    /// ([`GpuBvh::trace_closest_avx512`], a wide tree of at most
    /// [`FLAT_MAX_PRIMITIVES`](crate::FLAT_MAX_PRIMITIVES) triangles), else the AVX2 ones
    /// ([`GpuBvh::trace_closest_avx2`], at most
    /// [`FLAT_MAX_PRIMITIVES_AVX2`](crate::FLAT_MAX_PRIMITIVES_AVX2)). The same hits either
    /// way; a render's stats say which. Makes the CPU arrays ([`GpuBvh::wide_boxes`]).
    #[cfg(target_arch = "x86_64")]
    pub fn cpu_walks_flat(&self, avx512: bool) -> bool {
        let arrays = self.cpu_walk_arrays();
        let flat = if avx512 {
            !arrays.flat.is_empty()
        } else {
            !arrays.flat_avx2.is_empty()
        };
        self.layout == crate::BvhLayout::Wide && flat
    }

    /// Makes the CPU walks' arrays ([`GpuBvh::wide_boxes`]) if no walk has yet, their node
    /// boxes and triangle blocks in 2 MiB pages where `huge_pages` asks for them and they
    /// are large enough ([`HugePageArray`]: fewer page-table walks for a large tree's random
    /// reads, at the price of the kernel gathering free huge pages when they are first
    /// written; the CPU tracer asks for them for long renders). The first call decides: a
    /// walk makes them in ordinary pages. Returns whether they are in huge pages.
    pub fn prepare_cpu_walks(&self, huge_pages: bool) -> bool {
        let arrays = self.cpu_walk_arrays_in(huge_pages);
        arrays.boxes.advised() || arrays.blocks.advised()
    }

    /// The bytes [`GpuBvh::prepare_cpu_walks`] would place in huge pages: the node boxes and
    /// triangle blocks, as many as the tree's nodes and about a quarter of its primitives.
    pub fn cpu_walk_bytes(&self) -> usize {
        self.wide_nodes.len() * size_of::<WideBoxes>()
            + self.primitives.len().div_ceil(4) * size_of::<TriangleBlock>()
    }

    pub(crate) fn cpu_walk_arrays(&self) -> &CpuWalkArrays {
        self.cpu_walk_arrays_in(false)
    }

    fn cpu_walk_arrays_in(&self, huge_pages: bool) -> &CpuWalkArrays {
        self.cpu_arrays.0.get_or_init(|| {
            let mut boxes: Vec<WideBoxes> = self.wide_nodes.iter().map(wide_boxes).collect();
            let blocks = triangle_blocks(&self.wide_nodes, &mut boxes, &self.primitives);
            #[cfg(target_arch = "x86_64")]
            let (flat, flat_between16) = crate::wide_avx2::flat_sets(&self.primitives);
            #[cfg(target_arch = "x86_64")]
            let flat_avx2 = if self.primitives.len() <= crate::wide_avx2::FLAT_MAX_PRIMITIVES_AVX2 {
                crate::wide_avx2::flat_blocks(&self.primitives)
            } else {
                Vec::new()
            };
            #[cfg(target_arch = "x86_64")]
            let flat_between = crate::wide_avx2::flat_between_blocks(&self.primitives, &flat_avx2);
            CpuWalkArrays {
                boxes: HugePageArray::from_vec(boxes, huge_pages),
                blocks: HugePageArray::from_vec(blocks, huge_pages),
                #[cfg(target_arch = "x86_64")]
                flat,
                #[cfg(target_arch = "x86_64")]
                flat_between16,
                #[cfg(target_arch = "x86_64")]
                flat_avx2,
                #[cfg(target_arch = "x86_64")]
                flat_between,
            }
        })
    }
}
