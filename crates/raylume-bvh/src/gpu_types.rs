//! The flattened BVH layout read unchanged by the WGSL kernels (`traverse.wgsl`, included by
//! `raylume-kernels` through [`TRAVERSE_WGSL`](crate::TRAVERSE_WGSL), declares the same
//! structs with the same names and field order) and by the CPU traversal in this crate.

use bytemuck::{Pod, Zeroable};

/// `child_index` of an empty child slot (only in a root whose tree has fewer than two leaves).
pub const INVALID_INDEX: u32 = u32::MAX;

/// Primitive kind tag stored in [`Primitive::b`]`[3]` (as `u32` bits).
pub const PRIM_TRIANGLE: u32 = 0;
/// Primitive kind tag stored in [`Primitive::b`]`[3]` (as `u32` bits).
pub const PRIM_SPHERE: u32 = 1;

/// Maximum traversal stack depth the kernels allocate; builds deeper than this are rejected
/// (or rebuilt) by the builder, so traversal never overflows.
pub const MAX_STACK_DEPTH: usize = 64;

/// A BVH2 node holding the boxes of both of its children, so that one 64-byte load gives a
/// ray everything it needs to pick the nearer child (Aila & Laine 2009's layout).
///
/// `repr(C)`, `Pod`, 64 bytes. WGSL: `BvhNode`.
///
/// Per child: `*_count == 0` and `*_index != INVALID_INDEX`: an inner node at
/// `nodes[*_index]`; `*_count > 0`: a leaf holding primitives
/// `primitives[*_index .. *_index + *_count]` (leaf order); `*_index == INVALID_INDEX`: empty.
/// Node 0 is the root.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub left_min: [f32; 3],
    pub left_index: u32,
    pub left_max: [f32; 3],
    pub left_count: u32,
    pub right_min: [f32; 3],
    pub right_index: u32,
    pub right_max: [f32; 3],
    pub right_count: u32,
}

/// One primitive in leaf order, triangle or sphere.
///
/// `repr(C)`, `Pod`, 48 bytes. WGSL: `Primitive`.
///
/// - triangle: `a.xyz`, `b.xyz`, `c.xyz` = vertices v0, v1, v2 (world space, exactly as
///   loaded: neighbouring triangles share bit-identical vertices); `a[3]` = 0.0.
/// - sphere: `a.xyz` = centre, `a[3]` = radius; `b.xyz`, `c.xyz` = 0.
/// - both: `b[3]` = kind ([`PRIM_TRIANGLE`] / [`PRIM_SPHERE`]) and `c[3]` = the primitive's
///   index in the scene's `triangles` or `spheres`, stored as `u32` bits (`f32::from_bits`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Primitive {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

impl Primitive {
    pub fn triangle(v: [[f32; 3]; 3], scene_index: u32) -> Self {
        Self {
            a: [v[0][0], v[0][1], v[0][2], 0.0],
            b: [v[1][0], v[1][1], v[1][2], f32::from_bits(PRIM_TRIANGLE)],
            c: [v[2][0], v[2][1], v[2][2], f32::from_bits(scene_index)],
        }
    }

    pub fn sphere(center: [f32; 3], radius: f32, scene_index: u32) -> Self {
        Self {
            a: [center[0], center[1], center[2], radius],
            b: [0.0, 0.0, 0.0, f32::from_bits(PRIM_SPHERE)],
            c: [0.0, 0.0, 0.0, f32::from_bits(scene_index)],
        }
    }

    pub fn kind(&self) -> u32 {
        self.b[3].to_bits()
    }

    pub fn scene_index(&self) -> u32 {
        self.c[3].to_bits()
    }
}

/// Depth of the wide traversal's stack of node groups ([`WideNode`]s): wide trees deeper than
/// this are never handed to the kernels (the builder falls back to a balanced tree). An
/// eight-wide tree of a binary one [`MAX_STACK_DEPTH`] deep is at most that deep, and
/// ordinary scenes' wide trees are 5 to 12 deep.
pub const WIDE_STACK_SIZE: usize = 32;

/// The two BVH layouts the kernels traverse; both over the same [`Primitive`] records, and
/// both find the same hits (ties between primitives at one distance aside).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BvhLayout {
    /// Two children per node, both boxes in full precision: [`BvhNode`], 64 bytes
    /// (Aila & Laine 2009). The reference layout.
    Binary,
    /// Up to eight children per node, boxes quantised to 8 bits against the node's own grid:
    /// [`WideNode`], 80 bytes (Ylitie, Karras & Laine, *Efficient Incoherent Ray Traversal on
    /// GPUs Through Compressed Wide BVHs*, HPG 2017). Leaves of up to three primitives.
    /// The default: on the H200 it traced every scene of Table 1 faster than the binary
    /// layout (1.1-1.9x at 100 spp, `docs/RESULTS.md`), on lavapipe too.
    #[default]
    Wide,
}

impl BvhLayout {
    /// Lower-case name for logs, flags and stats ("binary", "wide").
    pub const fn name(self) -> &'static str {
        match self {
            BvhLayout::Binary => "binary",
            BvhLayout::Wide => "wide",
        }
    }
}

impl std::str::FromStr for BvhLayout {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "binary" => Ok(BvhLayout::Binary),
            "wide" => Ok(BvhLayout::Wide),
            other => Err(format!(
                "unknown BVH layout '{other}' (expected binary or wide)"
            )),
        }
    }
}

/// A compressed eight-wide BVH node (Ylitie, Karras & Laine 2017), byte for byte obvhs'
/// `CwBvhNode`, so that obvhs' converter builds it.
///
/// `repr(C)`, `Pod`, 80 bytes. WGSL: `WideNode` (the byte arrays read there as `u32`
/// words, little-endian: `child_meta` as a `vec2<u32>`, each `q_*` as a `vec4<u32>`).
///
/// - `p`: the node's grid origin (the minimum corner of its box); `e_imask[0..3]`: the
///   exponents of the grid's cell size per axis (the cell is `f32::from_bits(e << 23)`, a
///   power of two); `e_imask[3]`: bit `i` set when child slot `i` is an inner node.
/// - Child slot `i` spans cells `q_x[i] ..= q_x[8 + i]` on x (likewise y, z): the box
///   `p + q * cell`, rounded outward by the builder.
/// - `child_meta[i]`: 0 for an empty slot; for an inner child `0b001_11sss` (`24 + i` in the low
///   five bits), the node being `nodes[child_base + r]` with `r` the number of inner slots
///   before `i`; for a leaf the number of its primitives in unary in the high three bits
///   (`0b001`, `0b011`, `0b111`) and their offset from `prim_base` in the low five.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct WideNode {
    pub p: [f32; 3],
    pub e_imask: [u8; 4],
    pub child_base: u32,
    pub prim_base: u32,
    pub child_meta: [u8; 8],
    pub q_x: [u8; 16],
    pub q_y: [u8; 16],
    pub q_z: [u8; 16],
}

impl WideNode {
    /// Bit `i` set when child slot `i` is an inner node.
    pub fn imask(&self) -> u8 {
        self.e_imask[3]
    }

    /// The grid's cell size per axis (a power of two each).
    #[inline]
    pub fn cell(&self) -> [f32; 3] {
        [0, 1, 2].map(|k| f32::from_bits(u32::from(self.e_imask[k]) << 23))
    }
}

const _: () = assert!(size_of::<WideNode>() == 80);
const _: () = assert!(std::mem::offset_of!(WideNode, e_imask) == 12);
const _: () = assert!(std::mem::offset_of!(WideNode, child_base) == 16);
const _: () = assert!(std::mem::offset_of!(WideNode, prim_base) == 20);
const _: () = assert!(std::mem::offset_of!(WideNode, child_meta) == 24);
const _: () = assert!(std::mem::offset_of!(WideNode, q_x) == 32);
const _: () = assert!(std::mem::offset_of!(WideNode, q_y) == 48);
const _: () = assert!(std::mem::offset_of!(WideNode, q_z) == 64);
const _: () = assert!(size_of::<obvhs::cwbvh::node::CwBvhNode>() == size_of::<WideNode>());

const _: () = assert!(size_of::<BvhNode>() == 64);
const _: () = assert!(std::mem::offset_of!(BvhNode, left_index) == 12);
const _: () = assert!(std::mem::offset_of!(BvhNode, left_count) == 28);
const _: () = assert!(std::mem::offset_of!(BvhNode, right_min) == 32);
const _: () = assert!(std::mem::offset_of!(BvhNode, right_count) == 60);
const _: () = assert!(size_of::<Primitive>() == 48);
const _: () = assert!(std::mem::offset_of!(Primitive, b) == 16);
const _: () = assert!(std::mem::offset_of!(Primitive, c) == 32);
