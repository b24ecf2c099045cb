// raylume-bvh: the GPU layout of gpu_types.rs (same names, field order, sizes), the first
// part of TRAVERSE_WGSL.

const INVALID_INDEX: u32 = 0xffffffffu;
const MAX_STACK_DEPTH: u32 = 64u;
const WIDE_STACK_SIZE: u32 = 32u;
const PRIM_TRIANGLE: u32 = 0u;
const PRIM_SPHERE: u32 = 1u;

// 64 bytes: both children's boxes; per child count == 0 && index != INVALID_INDEX: inner
// node bvh_nodes[index]; count > 0: leaf bvh_primitives[index .. index + count];
// index == INVALID_INDEX: empty (only in the root).
struct BvhNode {
    left_min: vec3<f32>,
    left_index: u32,
    left_max: vec3<f32>,
    left_count: u32,
    right_min: vec3<f32>,
    right_index: u32,
    right_max: vec3<f32>,
    right_count: u32,
}

// 48 bytes. Triangle: vertices a.xyz, b.xyz, c.xyz. Sphere: centre a.xyz, radius a.w.
// b.w: kind (PRIM_TRIANGLE / PRIM_SPHERE) and c.w: scene index, both as u32 bits.
struct Primitive {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

// 80 bytes, gpu_types.rs `WideNode` (obvhs' CwBvhNode) read as words: e_imask = exponents
// of the grid cell per axis (bytes 0..3) and the inner-child mask (byte 3); child_meta = one byte
// per child slot; q_x = the slots' lower x cells (bytes 0..8) then upper x cells (8..16),
// likewise q_y, q_z.
struct WideNode {
    p: vec3<f32>,
    e_imask: u32,
    child_base: u32,
    prim_base: u32,
    child_meta: vec2<u32>,
    q_x: vec4<u32>,
    q_y: vec4<u32>,
    q_z: vec4<u32>,
}
