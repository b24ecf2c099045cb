//! The assembled tracer shader parses and validates, and every struct shared with Rust has
//! the same members at the same offsets and the same size on both sides (naga's layouter
//! computes the WGSL side, `offset_of!` the Rust side).

use std::mem::{offset_of, size_of};

use raylume_bvh::BvhLayout;
use raylume_gpu::wgpu::naga;
use raylume_kernels::gpu::tracer_source;
use raylume_kernels::gpu_types::*;

macro_rules! rust_layout {
    ($t:ty; $($f:ident),* $(,)?) => {
        (stringify!($t), size_of::<$t>(), vec![$((stringify!($f), offset_of!($t, $f))),*])
    };
}

fn parse() -> naga::Module {
    parse_layout(BvhLayout::Binary)
}

fn parse_layout(layout: BvhLayout) -> naga::Module {
    let src = tracer_source(65535, layout);
    match naga::front::wgsl::parse_str(&src) {
        Ok(m) => m,
        Err(e) => panic!("{}", e.emit_to_string(&src)),
    }
}

#[test]
fn tracer_shader_validates() {
    for layout in [BvhLayout::Binary, BvhLayout::Wide] {
        validate_tracer(layout);
    }
}

fn validate_tracer(layout: BvhLayout) {
    let module = parse_layout(layout);
    let src = tracer_source(65535, layout);
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&src)));
    for entry in [
        "raygen",
        "prepare_propagate",
        "propagate",
        "resolve",
        "trace_paths",
    ] {
        assert!(
            module.entry_points.iter().any(|e| e.name == entry),
            "missing entry point {entry}"
        );
    }
}

#[test]
fn layout_matches_wgsl() {
    let module = parse();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let expected = [
        rust_layout!(SceneUniforms; camera_origin, width, camera_forward, height, camera_right, spp,
            camera_up, max_bounces, environment_color, environment_kind, scene_min, seed,
            scene_extent, light_count, environment_rotation, environment_width, environment_height,
            environment_offset, sample_begin, sample_count, pixel_begin, pixel_count, batch_index,
            resolve_scale, rays_in_batch, queue_capacity, primitive_count, material_count,
            texture_count, light_power, rr_depth, sampler, environment_select, environment_cdf,
            environment_grid_scale, environment_cdf_width, environment_grid, environment_cdf_height),
        rust_layout!(GpuMaterial; color, kind, emission, alpha, ior, texture, flags, table, eta, _pad0, k, _pad1),
        rust_layout!(TriangleShading; n0, u0, n1, v0, n2, u1, v1, u2, v2, flags),
        rust_layout!(TextureHeader; offset, width, height, format),
        rust_layout!(GpuLight; p0, cdf, e1, area, e2, two_sided, emission, kind),
        rust_layout!(RayState; origin, pixel, dir, sample, throughput, depth, radiance, alive),
        rust_layout!(NeeRecord; position, offset, geometric_normal, back_offset, shading_normal,
            material, color, state, dir_in, _pad0, throughput, _pad1, rnd, emitted, _pad2),
        rust_layout!(BounceUniforms; depth, sort_next, sort_shift, walk_groups),
    ];
    for (name, size, fields) in expected {
        raylume_gpu::testing::check_wgsl_struct(&module, &layouter, name, size, &fields);
    }
}

#[test]
fn shared_constants_reach_the_shader() {
    let src = tracer_source(65535, BvhLayout::Binary);
    for line in [
        format!("const MATERIAL_GLASS: u32 = {MATERIAL_GLASS}u;"),
        format!("const NO_TEXTURE: u32 = {NO_TEXTURE}u;"),
        format!("const DIM_SCATTER: u32 = {DIM_SCATTER}u;"),
        format!(
            "const WORKGROUP_SIZE: u32 = {}u;",
            raylume_kernels::WORKGROUP_SIZE
        ),
        format!(
            "const MEGAKERNEL_WORKGROUP_SIZE: u32 = {}u;",
            raylume_kernels::MEGAKERNEL_WORKGROUP_SIZE
        ),
    ] {
        assert!(src.contains(&line), "{line}");
    }
    // T_MAX parses back to the same f32.
    let module = parse();
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some("T_MAX"))
        .expect("T_MAX");
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::F32(v)) => assert_eq!(v, T_MAX),
        ref other => panic!("T_MAX is {other:?}"),
    }
}

/// Each rough plastic points at the coat table of its own (alpha, ior); plastics that share
/// both share one table; smooth plastics and other materials have none.
#[test]
fn rough_plastics_get_the_table_of_their_roughness_and_ior() {
    use raylume_kernels::bsdf::RoughPlasticTable;
    use raylume_kernels::gpu_types::NO_TABLE;
    use raylume_kernels::scene_data::SceneData;
    use raylume_scene::{Material, Scene, Sphere};
    let g = glam::Vec3::splat(0.5);
    let materials = vec![
        Material::plastic("a", g, 1.5, 0.3),
        Material::plastic("b", g, 1.5, 0.0),
        Material::plastic("c", g, 1.4, 0.3),
        Material::plastic("d", g, 1.5, 0.3),
        Material::plastic("e", g, 1.5, 0.5),
        Material::diffuse("f", g),
    ];
    let spheres = (0..materials.len() as u32)
        .map(|i| Sphere {
            center: glam::Vec3::new(3.0 * i as f32, 0.0, 0.0),
            radius: 1.0,
            material: i,
        })
        .collect();
    let scene = Scene {
        materials,
        spheres,
        ..Default::default()
    };
    let bvh = raylume_bvh::GpuBvh::from_scene(&scene, raylume_bvh::BvhQuality::Fast).unwrap();
    let data = SceneData::new(&scene, &bvh).unwrap();
    assert_eq!(
        data.plastic_tables.len(),
        3,
        "(0.09, 1.5), (0.09, 1.4), (0.25, 1.5)"
    );
    let t = |i: usize| data.materials[i].table;
    assert_eq!((t(1), t(5)), (NO_TABLE, NO_TABLE));
    assert_eq!(t(0), t(3));
    for i in [0, 2, 4] {
        let m = &scene.materials[i];
        let want = RoughPlasticTable::new(m.roughness * m.roughness, m.ior);
        assert_eq!(data.plastic_tables[t(i) as usize], want, "material {i}");
    }
    // A second flattening (the process-wide cache) gives the same tables.
    assert_eq!(
        SceneData::new(&scene, &bvh).unwrap().plastic_tables,
        data.plastic_tables
    );
}
