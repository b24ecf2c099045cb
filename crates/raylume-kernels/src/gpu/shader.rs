//! The tracer's WGSL module: the shared functions (each `.wgsl` beside its Rust mirror), the
//! BVH traversal from raylume-bvh, the ray sort key from raylume-sort, the bindings, and the two schedules' entry points, in one
//! source; and the pipeline-override constants that specialise it on a scene's features.

use raylume_bvh::BvhLayout;
use raylume_scene::{Feature, Features};

use crate::gpu_types::{GPU_TYPES_WGSL, wgsl_constants};

/// WGSL sources in the order they are concatenated (WGSL declarations are order-independent;
/// the order only helps reading the assembled shader).
const PARTS: [(&str, &str); 13] = [
    ("gpu_types.wgsl", GPU_TYPES_WGSL),
    ("math.wgsl", crate::math::MATH_WGSL),
    ("rng.wgsl", crate::rng::RNG_WGSL),
    ("sobol.wgsl", crate::sobol::SOBOL_WGSL),
    ("gpu/bindings.wgsl", include_str!("bindings.wgsl")),
    ("camera.wgsl", crate::camera::CAMERA_WGSL),
    ("sampling.wgsl", crate::sampling::SAMPLING_WGSL),
    ("bsdf.wgsl", crate::bsdf::BSDF_WGSL),
    ("surface.wgsl", crate::surface::SURFACE_WGSL),
    ("shade.wgsl", crate::shade::SHADE_WGSL),
    ("gpu/common.wgsl", include_str!("common.wgsl")),
    ("gpu/megakernel.wgsl", include_str!("megakernel.wgsl")),
    ("gpu/wavefront.wgsl", include_str!("wavefront.wgsl")),
];

/// The complete shader source for a device whose dispatches may have at most
/// `max_workgroups_per_dimension` workgroups along x, over a BVH of `layout`.
pub fn tracer_source(max_workgroups_per_dimension: u32, layout: BvhLayout) -> String {
    let mut s = String::from("// raylume-kernels: the tracer (assembled by gpu/shader.rs)\n");
    s += &wgsl_constants();
    s += &format!("const MAX_WORKGROUPS_PER_DIMENSION: u32 = {max_workgroups_per_dimension}u;\n");
    s += &format!(
        "\n// ---- raylume-bvh: the traversal of the {} layout ----\n",
        layout.name()
    );
    s += raylume_bvh::traverse_wgsl(layout);
    s += "\n// ---- raylume-sort: MORTON_WGSL ----\n";
    s += raylume_sort::MORTON_WGSL;
    for (name, src) in PARTS {
        s += &format!("\n// ---- {name} ----\n");
        s += src;
    }
    s
}

/// The override constants of a pipeline specialised on `features`.
pub fn pipeline_constants(features: Features) -> Vec<(&'static str, f64)> {
    let b = |f: Feature| if features.contains(f) { 1.0 } else { 0.0 };
    vec![
        ("HAS_DIFFUSE", b(Feature::Diffuse)),
        ("HAS_METAL", b(Feature::Metal)),
        ("HAS_ROUGH_METAL", b(Feature::RoughMetal)),
        ("HAS_GLASS", b(Feature::Glass)),
        ("HAS_ROUGH_GLASS", b(Feature::RoughGlass)),
        ("HAS_PLASTIC", b(Feature::Plastic)),
        ("HAS_EMISSION", b(Feature::Emission)),
        ("HAS_SPHERES", b(Feature::Spheres)),
        ("HAS_TEXTURES", b(Feature::Textures)),
        ("HAS_SHADING_NORMALS", b(Feature::ShadingNormals)),
        ("HAS_CONSTANT_ENVIRONMENT", b(Feature::ConstantEnvironment)),
        ("HAS_ENVIRONMENT_MAP", b(Feature::EnvironmentMap)),
    ]
}
