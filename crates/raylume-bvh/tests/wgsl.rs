//! `TRAVERSE_WGSL` and `WIDE_TRAVERSE_WGSL` without a GPU: each parses and validates with naga
//! (the compiler wgpu uses) inside a shader that declares the two globals it expects, its
//! structs have the Rust layouts, its constants the Rust values, and it has every function
//! the Rust side names.

use std::mem::{offset_of, size_of};

use raylume_bvh::{
    AABB_T_FAR_SCALE, BvhNode, Hit, INVALID_INDEX, MAX_STACK_DEPTH, PRIM_SPHERE, PRIM_TRIANGLE,
    Primitive, T_MAX_LIMIT, T_MISS, TRAVERSE_WGSL, WIDE_ANY_OCT_FLIP, WIDE_INV_DIR_LIMIT,
    WIDE_QUANT_PAD, WIDE_STACK_SIZE, WIDE_T_FAR_SCALE, WIDE_TRAVERSE_WGSL, WideNode,
};
use raylume_gpu::wgpu::naga;

/// The smallest shader that includes `TRAVERSE_WGSL` as its contract asks.
const KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> bvh_nodes: array<TraversalNode>;
@group(0) @binding(1) var<storage, read> bvh_primitives: array<Primitive>;
@group(0) @binding(2) var<storage, read_write> out: array<Hit>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let ray = Ray(vec3<f32>(f32(id.x), 0.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
    var hit = trace_closest(ray, 0.0, 1e30);
    if trace_any(ray, 0.0, 1e30) {
        hit.u += 1.0;
    }
    out[id.x] = hit;
}
"#;

fn parse() -> (naga::Module, String) {
    parse_with(TRAVERSE_WGSL)
}

fn parse_with(traverse: &str) -> (naga::Module, String) {
    let src = format!("{traverse}\n{KERNEL}");
    match naga::front::wgsl::parse_str(&src) {
        Ok(m) => (m, src),
        Err(e) => panic!("{}", e.emit_to_string(&src)),
    }
}

/// Parses `traverse` inside the kernel, validates it, and checks that it defines every
/// function of `functions` and no global of its own (only the kernel's three exist).
fn check_module(traverse: &str, what: &str, functions: &[&str]) -> naga::Module {
    let (module, src) = parse_with(traverse);
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
    for f in functions {
        assert!(
            module
                .functions
                .iter()
                .any(|(_, g)| g.name.as_deref() == Some(*f)),
            "{what} has no function {f}"
        );
    }
    let mut globals: Vec<_> = module
        .global_variables
        .iter()
        .filter_map(|(_, g)| g.name.clone())
        .collect();
    globals.sort();
    assert_eq!(globals, ["bvh_nodes", "bvh_primitives", "out"], "{what}");
    module
}

#[test]
fn wide_traverse_wgsl_validates_inside_a_kernel() {
    // The same names as wide_traverse.rs.
    let module = check_module(
        WIDE_TRAVERSE_WGSL,
        "WIDE_TRAVERSE_WGSL",
        &[
            "intersect_primitive",
            "wide_ray",
            "wide_overlap4",
            "intersect_wide_node",
            "wide_child_index",
            "wide_walk",
            "trace_closest",
            "trace_any",
        ],
    );
    // The wide layout's struct and constants as Rust has them.
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    raylume_gpu::testing::check_wgsl_struct(
        &module,
        &layouter,
        "WideNode",
        size_of::<WideNode>(),
        &[
            ("p", offset_of!(WideNode, p)),
            ("e_imask", offset_of!(WideNode, e_imask)),
            ("child_base", offset_of!(WideNode, child_base)),
            ("prim_base", offset_of!(WideNode, prim_base)),
            ("child_meta", offset_of!(WideNode, child_meta)),
            ("q_x", offset_of!(WideNode, q_x)),
            ("q_y", offset_of!(WideNode, q_y)),
            ("q_z", offset_of!(WideNode, q_z)),
        ],
    );
    let value = |name: &str| constant(&module, name);
    assert_eq!(
        value("WIDE_STACK_SIZE"),
        naga::Literal::U32(WIDE_STACK_SIZE as u32)
    );
    assert_eq!(value("WIDE_QUANT_PAD"), naga::Literal::F32(WIDE_QUANT_PAD));
    assert_eq!(
        value("WIDE_T_FAR_SCALE"),
        naga::Literal::F32(WIDE_T_FAR_SCALE)
    );
    assert_eq!(
        value("WIDE_INV_DIR_LIMIT"),
        naga::Literal::F32(WIDE_INV_DIR_LIMIT)
    );
    assert_eq!(
        value("WIDE_ANY_OCT_FLIP"),
        naga::Literal::U32(WIDE_ANY_OCT_FLIP)
    );
    assert_eq!(value("T_MAX_LIMIT"), naga::Literal::F32(T_MAX_LIMIT));
}

/// The literal value of WGSL constant `name`.
fn constant(module: &naga::Module, name: &str) -> naga::Literal {
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("WGSL has no constant {name}"));
    match module.global_expressions[c.init] {
        naga::Expression::Literal(l) => l,
        ref e => panic!("{name} is not a literal: {e:?}"),
    }
}

#[test]
fn traverse_wgsl_validates_inside_a_kernel() {
    check_module(
        TRAVERSE_WGSL,
        "TRAVERSE_WGSL",
        &[
            "intersect_aabb",
            "shear_ray",
            "intersect_triangle",
            "intersect_sphere",
            "intersect_primitive",
            "intersect_leaf",
            "binary_walk",
            "trace_closest",
            "trace_any",
        ],
    );
}

#[test]
fn structs_have_the_rust_layouts() {
    let (module, _) = parse();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    raylume_gpu::testing::check_wgsl_struct(
        &module,
        &layouter,
        "BvhNode",
        size_of::<BvhNode>(),
        &[
            ("left_min", offset_of!(BvhNode, left_min)),
            ("left_index", offset_of!(BvhNode, left_index)),
            ("left_max", offset_of!(BvhNode, left_max)),
            ("left_count", offset_of!(BvhNode, left_count)),
            ("right_min", offset_of!(BvhNode, right_min)),
            ("right_index", offset_of!(BvhNode, right_index)),
            ("right_max", offset_of!(BvhNode, right_max)),
            ("right_count", offset_of!(BvhNode, right_count)),
        ],
    );
    raylume_gpu::testing::check_wgsl_struct(
        &module,
        &layouter,
        "Primitive",
        size_of::<Primitive>(),
        &[
            ("a", offset_of!(Primitive, a)),
            ("b", offset_of!(Primitive, b)),
            ("c", offset_of!(Primitive, c)),
        ],
    );
    raylume_gpu::testing::check_wgsl_struct(
        &module,
        &layouter,
        "Hit",
        size_of::<Hit>(),
        &[
            ("t", offset_of!(Hit, t)),
            ("prim", offset_of!(Hit, prim)),
            ("u", offset_of!(Hit, u)),
            ("v", offset_of!(Hit, v)),
        ],
    );
}

#[test]
fn constants_have_the_rust_values() {
    let (module, _) = parse();
    let value = |name: &str| constant(&module, name);
    assert_eq!(value("INVALID_INDEX"), naga::Literal::U32(INVALID_INDEX));
    assert_eq!(
        value("MAX_STACK_DEPTH"),
        naga::Literal::U32(MAX_STACK_DEPTH as u32)
    );
    assert_eq!(value("PRIM_TRIANGLE"), naga::Literal::U32(PRIM_TRIANGLE));
    assert_eq!(value("PRIM_SPHERE"), naga::Literal::U32(PRIM_SPHERE));
    assert_eq!(value("T_MISS"), naga::Literal::F32(T_MISS));
    assert_eq!(value("T_MAX_LIMIT"), naga::Literal::F32(T_MAX_LIMIT));
    assert_eq!(
        value("AABB_T_FAR_SCALE"),
        naga::Literal::F32(AABB_T_FAR_SCALE)
    );
}
