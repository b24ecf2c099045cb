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

/// How a pipeline is specialised on a scene's features.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Specialisation {
    /// Every feature compiled in: the baseline the others are measured against.
    Generic,
    /// The generic source, with the features as WGSL override constants at pipeline creation
    /// (`HAS_GLASS = false`): the driver's compiler sees the dead branches and may drop them.
    Overrides,
    /// The source composed for the features ([`compose`]: an absent feature's functions and
    /// branches are not in it at all), and the override constants as well.
    #[default]
    Composed,
}

impl Specialisation {
    /// Every kind, the baseline first.
    pub const ALL: [Specialisation; 3] = [
        Specialisation::Generic,
        Specialisation::Overrides,
        Specialisation::Composed,
    ];

    /// Lower-case name for stats and flags.
    pub const fn name(self) -> &'static str {
        match self {
            Specialisation::Generic => "generic",
            Specialisation::Overrides => "overrides",
            Specialisation::Composed => "composed",
        }
    }

    /// The features a pipeline for a scene with `features` is compiled with: all of them
    /// for [`Specialisation::Generic`].
    pub fn features(self, features: Features) -> Features {
        match self {
            Specialisation::Generic => Features::all(),
            _ => features,
        }
    }
}

impl std::str::FromStr for Specialisation {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Specialisation::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                format!("unknown specialisation '{s}' (expected generic, overrides or composed)")
            })
    }
}

/// The tracer's WGSL composed for `features`: the lines of every `//#if a|b` block (up to its
/// `//#else` or `//#endif`; blocks nest) whose named features (`Feature::name`) are all
/// absent become empty lines, as do those of an `//#else` block when one of them is present,
/// and the marker lines themselves; the line count stays, so a compiler's line numbers still
/// point into the files. Panics on an unknown feature name or unbalanced markers (the
/// crate's tests compose every source for many feature sets).
pub fn compose(source: &str, features: Features) -> String {
    let mut out = String::with_capacity(source.len());
    // Per open block: (the block's condition holds, we are in its `//#else` part).
    let mut stack: Vec<(bool, bool)> = Vec::new();
    for (i, line) in source.lines().enumerate() {
        let t = line.trim();
        let keep = stack.iter().all(|&(cond, in_else)| cond != in_else);
        if let Some(names) = t.strip_prefix("//#if ") {
            let cond = names.split('|').map(str::trim).any(|n| {
                let f = Feature::ALL
                    .into_iter()
                    .find(|f| f.name() == n)
                    .unwrap_or_else(|| panic!("line {}: unknown feature `{n}` in `{t}`", i + 1));
                features.contains(f)
            });
            stack.push((cond, false));
        } else if t == "//#else" {
            let top = stack
                .last_mut()
                .unwrap_or_else(|| panic!("line {}: `//#else` without `//#if`", i + 1));
            assert!(!top.1, "line {}: a second `//#else`", i + 1);
            top.1 = true;
        } else if t == "//#endif" {
            stack
                .pop()
                .unwrap_or_else(|| panic!("line {}: `//#endif` without `//#if`", i + 1));
        } else if keep {
            out += line;
        }
        out.push('\n');
    }
    assert!(stack.is_empty(), "{} `//#if` blocks left open", stack.len());
    out
}

/// The complete shader source for a device whose dispatches may have at most
/// `max_workgroups_per_dimension` workgroups along x, over a BVH of `layout`, with every
/// feature's code in it ([`compose`]d for all features).
pub fn tracer_source(max_workgroups_per_dimension: u32, layout: BvhLayout) -> String {
    tracer_source_for(max_workgroups_per_dimension, layout, Features::all())
}

/// [`tracer_source`] [`compose`]d for `features`: without the code of absent features.
pub fn tracer_source_for(
    max_workgroups_per_dimension: u32,
    layout: BvhLayout,
    features: Features,
) -> String {
    compose(
        &tracer_source_uncomposed(max_workgroups_per_dimension, layout),
        features,
    )
}

/// The tracer's WGSL before [`compose`]: every feature's code, inside its `//#if` markers
/// (what `tracer_source_for` composes; `examples/shader_stats.rs --write-source` writes it
/// for variants to be compiled without a rebuild).
pub fn tracer_source_uncomposed(max_workgroups_per_dimension: u32, layout: BvhLayout) -> String {
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
