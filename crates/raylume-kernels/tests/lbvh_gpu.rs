//! The BVH built on the GPU (`raylume_kernels::gpu::LbvhBuilder`, `gpu/lbvh.wgsl`) is its CPU
//! reference (`raylume_bvh::lbvh::lbvh_binary`) node for node: the same sorted order, the same
//! children, the same boxes bit for bit (a box is a min/max of the triangles' own coordinates:
//! no rounding), the same depth; the primitives left on the GPU are the read-back tree's, and
//! the tree passes every invariant the traversal relies on (`GpuBvh::validate`; the reference
//! is checked against brute-force ray queries in raylume-bvh's `brute_force.rs`).

use glam::Vec3;
use raylume_bvh::lbvh::lbvh_binary;
use raylume_bvh::{BvhError, GpuBvh, Primitive};
use raylume_kernels::KernelError;
use raylume_kernels::gpu::{GpuScene, LbvhBuilder};
use raylume_scene::Triangle;

fn lcg(seed: &mut u64) -> f32 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*seed >> 40) as f32 / (1u64 << 24) as f32
}

/// `n` small random triangles in a 10-unit cube; every seventh a copy of the first (equal
/// Morton codes: the index breaks the tie).
fn soup(n: usize, seed: u64) -> Vec<Triangle> {
    let mut s = seed;
    let v = |s: &mut u64| Vec3::new(lcg(s), lcg(s), lcg(s));
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        if i % 7 == 6 {
            out.push(out[0]);
            continue;
        }
        let c = v(&mut s) * 10.0;
        out.push(Triangle::flat(
            [c, c + v(&mut s) * 0.3, c + v(&mut s) * 0.3],
            0,
        ));
    }
    out
}

/// Issue 19's height field, `k` x `k` quads (`raylume_scene::grid`).
fn grid(k: usize) -> Vec<Triangle> {
    raylume_scene::grid::height_field(k)
}

fn check(builder: &mut LbvhBuilder, ctx: &raylume_gpu::GpuContext, name: &str, t: &[Triangle]) {
    let source = GpuBvh::lbvh_input(t).unwrap();
    let reference = lbvh_binary(&source);
    let expected =
        GpuBvh::from_lbvh(reference.clone(), &source, std::time::Instant::now()).unwrap();
    // From primitives, and from the scene's triangles written straight into the upload.
    let resident = builder.build(ctx, &source).unwrap();
    let from_triangles = builder.build_triangles(ctx, t).unwrap();
    for (how, r) in [("primitives", &resident), ("triangles", &from_triangles)] {
        assert_eq!(
            r.node_count(),
            reference.nodes.len(),
            "{name} ({how}): nodes"
        );
        assert_eq!(r.max_depth(), reference.max_depth, "{name} ({how}): depth");
        assert_eq!(r.order(), reference.order, "{name} ({how}): sorted order");
        let built = r.read_back(ctx).unwrap();
        assert_eq!(
            built.primitives, expected.primitives,
            "{name} ({how}): leaves"
        );
        if let Some(i) = (0..reference.nodes.len()).find(|&i| built.nodes[i] != reference.nodes[i])
        {
            panic!(
                "{name} ({how}): node {i} differs:\nGPU {:?}\nCPU {:?}",
                built.nodes[i], reference.nodes[i]
            );
        }
    }
    let built = resident.read_back(ctx).unwrap();
    assert_eq!(built.stats.max_depth, reference.max_depth, "{name}: depth");
    built.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
    // What the tracer reads is what was read back.
    let scene = raylume_scene::Scene {
        triangles: t.to_vec(),
        materials: vec![raylume_scene::Material::diffuse("grey", Vec3::splat(0.5))],
        ..Default::default()
    };
    let uploaded =
        GpuScene::upload_resident(ctx, &scene, &resident, &Default::default(), None).unwrap();
    let (nodes, primitives) = uploaded.tree_buffers();
    let on_gpu = ctx
        .read_buffer::<Primitive>(primitives, source.len())
        .unwrap();
    assert_eq!(on_gpu, built.primitives, "{name}: the GPU's primitives");
    let on_gpu = ctx
        .read_buffer::<raylume_bvh::BvhNode>(nodes, built.nodes.len())
        .unwrap();
    assert_eq!(on_gpu, built.nodes, "{name}: the GPU's nodes");
    eprintln!(
        "{name}: {} triangles, {} nodes, depth {}",
        source.len(),
        built.nodes.len(),
        reference.max_depth
    );
}

#[test]
fn the_gpu_build_is_its_cpu_reference_node_for_node() {
    let Some(ctx) =
        raylume_gpu::testing::context_or_skip("the_gpu_build_is_its_cpu_reference_node_for_node")
    else {
        return;
    };
    let mut builder = LbvhBuilder::new(ctx).unwrap();
    let one = soup(1, 1);
    check(&mut builder, ctx, "one triangle", &one);
    for n in [2usize, 3, 5, 100] {
        check(
            &mut builder,
            ctx,
            &format!("soup of {n}"),
            &soup(n, n as u64),
        );
    }
    check(&mut builder, ctx, "grid 40x40", &grid(40));
    // A larger input than the sorter was made for: it grows.
    check(&mut builder, ctx, "soup of 20000", &soup(20_000, 7));
    // Every triangle the same: the codes tie everywhere, the index orders them.
    check(&mut builder, ctx, "coincident", &vec![soup(1, 3)[0]; 300]);
}

/// Triangles whose Morton codes make the radix tree a chain: one point per leading-bit
/// position of the 63-bit code (a cell of 2^k - 1 along one axis), plus copies of the origin.
fn chain() -> Vec<Triangle> {
    let tiny = |c: Vec3| Triangle::flat([c, c, c], 0);
    let mut out = vec![tiny(Vec3::ZERO); 8];
    for axis in 0..3 {
        for k in 0..21 {
            let mut c = Vec3::ZERO;
            c[axis] = 1.5 * (1u32 << k) as f32 / (1u32 << 21) as f32;
            out.push(tiny(c));
        }
    }
    out
}

#[test]
fn a_tree_deeper_than_the_stack_is_an_error_not_a_wrong_tree() {
    let Some(ctx) = raylume_gpu::testing::context_or_skip(
        "a_tree_deeper_than_the_stack_is_an_error_not_a_wrong_tree",
    ) else {
        return;
    };
    let mut builder = LbvhBuilder::new(ctx).unwrap();
    let source = GpuBvh::lbvh_input(&chain()).unwrap();
    let reference = lbvh_binary(&source);
    assert!(
        reference.max_depth > raylume_bvh::MAX_STACK_DEPTH,
        "the chain is {} deep: not past the stack",
        reference.max_depth
    );
    match builder.build(ctx, &source) {
        Err(KernelError::Bvh(BvhError::TooDeep { .. })) => {}
        other => panic!("expected TooDeep, got {other:?}"),
    }
    // Spheres are the CPU builders' (their boxes carry a slack the GPU would round otherwise).
    let ball = Primitive::sphere([0.0; 3], 1.0, 0);
    assert!(matches!(
        builder.build(ctx, &[source[0], ball]),
        Err(KernelError::InvalidScene(_))
    ));
}

/// The builder's shader validates, `LbvhParams` has the same members at the same offsets on
/// both sides, and the constants come from Rust.
#[test]
fn the_build_shader_and_its_rust_mirror_share_their_layout() {
    use raylume_bvh::lbvh::{LBVH_AXIS_BITS, LbvhParams};
    use raylume_gpu::wgpu::naga;
    use std::mem::{offset_of, size_of};
    let src = raylume_kernels::gpu::lbvh_source();
    let module =
        naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let fields = [
        ("centre_min", offset_of!(LbvhParams, centre_min)),
        ("count", offset_of!(LbvhParams, count)),
        ("scale", offset_of!(LbvhParams, scale)),
        ("pass_index", offset_of!(LbvhParams, pass_index)),
    ];
    raylume_gpu::testing::check_wgsl_struct(
        &module,
        &layouter,
        "LbvhParams",
        size_of::<LbvhParams>(),
        &fields,
    );
    assert_eq!(size_of::<LbvhParams>(), 32);
    assert!(src.contains(&format!("const LBVH_AXIS_BITS: u32 = {LBVH_AXIS_BITS}u;")));
    assert!(src.contains(&format!(
        "const LBVH_WORKGROUP_SIZE: u32 = {}u;",
        raylume_kernels::gpu::LBVH_WORKGROUP_SIZE
    )));
}
