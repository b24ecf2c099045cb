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

const _: () = assert!(size_of::<BvhNode>() == 64);
const _: () = assert!(std::mem::offset_of!(BvhNode, left_index) == 12);
const _: () = assert!(std::mem::offset_of!(BvhNode, left_count) == 28);
const _: () = assert!(std::mem::offset_of!(BvhNode, right_min) == 32);
const _: () = assert!(std::mem::offset_of!(BvhNode, right_count) == 60);
const _: () = assert!(size_of::<Primitive>() == 48);
const _: () = assert!(std::mem::offset_of!(Primitive, b) == 16);
const _: () = assert!(std::mem::offset_of!(Primitive, c) == 32);
