//! The composed tracer shader (issue 14): for any feature set the source composed for it
//! (`gpu::compose`, the `//#if` blocks of absent features left out) parses and validates, and
//! the functions and branches of an absent feature are not in it at all.

use raylume_bvh::BvhLayout;
use raylume_gpu::wgpu::naga;
use raylume_kernels::gpu::{
    PathVariant, TracerPipelines, compose, entry_constants, tracer_source_for, walk_stage_source,
};
use raylume_kernels::{Estimator, Sampler, Schedule};
use raylume_scene::{Feature, Features};

/// The composed source without its comments.
fn code(features: Features) -> String {
    tracer_source_for(65535, BvhLayout::Wide, features)
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The module `TracerPipelines` builds for `features` over `layout`, validated; with
/// `walk_stage`, as on an adapter with subgroups (the walk stage appended: wide BVH only).
fn validate_module(features: Features, layout: BvhLayout, walk_stage: bool) -> naga::Module {
    let mut src = tracer_source_for(65535, layout, features);
    if walk_stage {
        src += &walk_stage_source();
    }
    let module = naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{features}: {}", e.emit_to_string(&src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{features}: {}", e.emit_to_string(&src)));
    module
}

fn validate(features: Features, layout: BvhLayout) -> naga::Module {
    validate_module(features, layout, false)
}

/// A deterministic pseudo-random feature set.
fn subset(state: &mut u64) -> Features {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    Features::from_bits((*state >> 33) as u32)
}

/// Every feature set a scene may have composes into a valid module: all of them, none, each
/// feature alone, all but each one, and 64 pseudo-random sets, in both BVH layouts.
#[test]
fn every_feature_set_composes_into_a_valid_module() {
    let mut sets = vec![Features::all(), Features::NONE];
    for f in Feature::ALL {
        sets.push(Features::NONE.with(f));
        let mut all_but = Features::all();
        all_but.remove(f);
        sets.push(all_but);
    }
    let mut s = 7;
    sets.extend((0..64).map(|_| subset(&mut s)));
    for features in sets {
        for layout in [BvhLayout::Binary, BvhLayout::Wide] {
            validate(features, layout);
        }
        // The module of adapters with subgroups: the walk stage beside every feature set.
        let module = validate_module(features, BvhLayout::Wide, true);
        assert!(
            module.entry_points.iter().any(|e| e.name == "trace_hits"),
            "{features}: no trace_hits"
        );
    }
}

/// The functions only a feature (or a group of features) needs, as written in the WGSL.
const ONLY_FOR: [(&[Feature], &[&str]); 5] = [
    (
        &[Feature::Glass, Feature::RoughGlass],
        &["sample_rough_dielectric", "eval_rough_dielectric"],
    ),
    (
        &[Feature::Metal, Feature::RoughMetal],
        &["sample_conductor", "eval_conductor", "fresnel_conductor"],
    ),
    (
        &[Feature::Plastic],
        &[
            "sample_plastic",
            "eval_plastic",
            "sample_rough_plastic",
            "eval_rough_plastic",
        ],
    ),
    (
        &[Feature::Spheres],
        &["sample_sphere_cap", "sphere_cap_pdf"],
    ),
    // A constant sky samples its guide's distributions with them too (env_guide).
    (
        &[Feature::EnvironmentMap, Feature::ConstantEnvironment],
        &["cdf_search", "cdf_step", "environment_cdf_base"],
    ),
];

/// Without a feature, its functions are absent from the module (naga's function list) and
/// their names from the composed source; with it, present. Textures and environment maps
/// share the texel fetch: it is absent only when both are.
#[test]
fn absent_features_leave_no_code() {
    for (features, functions) in ONLY_FOR {
        let mut without = Features::all();
        for &f in features {
            without.remove(f);
        }
        let module = validate(without, BvhLayout::Wide);
        let src = code(without);
        for name in functions {
            assert!(
                !module
                    .functions
                    .iter()
                    .any(|(_, f)| f.name.as_deref() == Some(*name)),
                "without {features:?}: `{name}` is still in the module"
            );
            assert!(
                !src.contains(name),
                "without {features:?}: `{name}` in the source"
            );
        }
        let with = validate(Features::NONE.with(features[0]), BvhLayout::Wide);
        for name in functions {
            assert!(
                with.functions
                    .iter()
                    .any(|(_, f)| f.name.as_deref() == Some(*name)),
                "with {:?}: `{name}` missing",
                features[0]
            );
        }
    }
    let mut neither = Features::all();
    neither.remove(Feature::Textures);
    neither.remove(Feature::EnvironmentMap);
    assert!(!code(neither).contains("texture_bilinear"));
    let mut no_shading = neither;
    no_shading.remove(Feature::ShadingNormals);
    assert!(
        !code(no_shading).contains("triangle_shading[hit.prim]"),
        "shading data read without textures or normals"
    );
    assert!(code(Features::all()).contains("triangle_shading[hit.prim]"));
}

/// The composer itself: nesting, `//#else`, alternatives, line count kept.
#[test]
fn compose_keeps_lines_and_nests() {
    let src = "a\n//#if glass\nb\n//#if spheres\nc\n//#else\nd\n//#endif\n//#else\ne\n//#endif\nf\n//#if plastic|spheres\ng\n//#endif\n";
    let glass = Features::NONE.with(Feature::Glass);
    assert_eq!(compose(src, glass), "a\n\nb\n\n\n\nd\n\n\n\n\nf\n\n\n\n");
    let spheres = Features::NONE.with(Feature::Spheres);
    assert_eq!(compose(src, spheres), "a\n\n\n\n\n\n\n\n\ne\n\nf\n\ng\n\n");
    assert_eq!(
        compose(src, Features::all()).lines().count(),
        src.lines().count()
    );
}

#[test]
#[should_panic(expected = "unknown feature")]
fn compose_rejects_unknown_features() {
    compose("//#if glas\nx\n//#endif\n", Features::all());
}

#[test]
#[should_panic(expected = "left open")]
fn compose_rejects_open_blocks() {
    compose("//#if glass\nx\n", Features::all());
}

/// The functions `entry` can reach once the overrides are set to `constants`: [`calls`]'
/// names.
fn reachable(
    module: &naga::Module,
    constants: &[(&str, f64)],
    entry: &str,
) -> std::collections::BTreeSet<String> {
    calls(module, constants, entry).into_keys().collect()
}

/// How many times each function is called from `entry` once the overrides are set to
/// `constants` (naga's own processing, as wgpu does it at pipeline creation), counted along
/// every chain of calls: the copies a driver that inlines every call compiles. Calls in the
/// branches of an `if` whose condition the overrides make a constant are followed into the
/// taken branch only. (A condition combined with run-time values by `&&` is lowered through a
/// local variable and counts as unknown: the WGSL gives `NEXT_EVENT` an `if` of its own.)
fn calls(
    module: &naga::Module,
    constants: &[(&str, f64)],
    entry: &str,
) -> std::collections::BTreeMap<String, usize> {
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(module)
    .unwrap();
    let constants: naga::back::PipelineConstants =
        constants.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    let (module, _) = naga::back::pipeline_constants::process_overrides(
        module,
        &info,
        Some((naga::ShaderStage::Compute, entry)),
        &constants,
    )
    .unwrap();
    let known = |f: &naga::Function, e: naga::Handle<naga::Expression>| -> Option<bool> {
        let literal = |l: &naga::Literal| match l {
            naga::Literal::Bool(b) => Some(*b),
            _ => None,
        };
        match &f.expressions[e] {
            naga::Expression::Literal(l) => literal(l),
            naga::Expression::Constant(c) => {
                match &module.global_expressions[module.constants[*c].init] {
                    naga::Expression::Literal(l) => literal(l),
                    _ => None,
                }
            }
            _ => None,
        }
    };
    fn walk(
        module: &naga::Module,
        f: &naga::Function,
        block: &naga::Block,
        known: &dyn Fn(&naga::Function, naga::Handle<naga::Expression>) -> Option<bool>,
        seen: &mut std::collections::BTreeMap<String, usize>,
    ) {
        for s in block.iter() {
            match s {
                naga::Statement::Block(b) => walk(module, f, b, known, seen),
                naga::Statement::If {
                    condition,
                    accept,
                    reject,
                } => match known(f, *condition) {
                    Some(true) => walk(module, f, accept, known, seen),
                    Some(false) => walk(module, f, reject, known, seen),
                    None => {
                        walk(module, f, accept, known, seen);
                        walk(module, f, reject, known, seen);
                    }
                },
                naga::Statement::Switch { cases, .. } => {
                    for c in cases {
                        walk(module, f, &c.body, known, seen);
                    }
                }
                naga::Statement::Loop {
                    body, continuing, ..
                } => {
                    walk(module, f, body, known, seen);
                    walk(module, f, continuing, known, seen);
                }
                naga::Statement::Call { function, .. } => {
                    let g = &module.functions[*function];
                    *seen.entry(g.name.clone().unwrap_or_default()).or_default() += 1;
                    walk(module, g, &g.body, known, seen);
                }
                _ => {}
            }
        }
    }
    let ep = module
        .entry_points
        .iter()
        .find(|ep| ep.name == entry)
        .unwrap();
    let mut seen = std::collections::BTreeMap::new();
    walk(&module, &ep.function, &ep.function.body, &known, &mut seen);
    seen
}

/// Every path tracing pipeline holds one traversal: `trace_ray` sends the path's ray and the
/// shadow ray through one call of the walk, and a driver inlines each call (on the H200, with
/// a second copy for the shadow ray and the hit's state live across it, the living room's NEE
/// paths traced 8-46 % slower: megakernel 0.485 against 0.448 s, persistent 0.776 against
/// 0.417 s at 100 spp). The next_event stage's one call is its shadow ray's; with the walk
/// stage, `propagate`'s is its shadow ray's too (the path ray's hit is read from the stage).
#[test]
fn each_path_tracing_pipeline_inlines_one_walk() {
    for (layout, walk) in [
        (BvhLayout::Wide, "wide_walk"),
        (BvhLayout::Binary, "binary_walk"),
    ] {
        let module = validate(Features::all(), layout);
        for estimator in [Estimator::Plain, Estimator::Nee] {
            for (stage, walk_stage) in [(false, false), (true, false), (false, true), (true, true)]
            {
                let variant = PathVariant::of(estimator, Sampler::Sobol)
                    .with_next_event_stage(stage)
                    .with_walk_stage(walk_stage);
                for entry in TracerPipelines::entries(Schedule::Wavefront, variant)
                    .iter()
                    .chain(&["trace_paths", "trace_paths_persistent"])
                    .filter(|e| {
                        ["propagate", "next_event"].contains(e) || e.starts_with("trace_paths")
                    })
                {
                    let n = calls(
                        &module,
                        &entry_constants(Features::all(), entry, variant, false),
                        entry,
                    )
                    .get(walk)
                    .copied()
                    .unwrap_or(0);
                    assert_eq!(
                        n, 1,
                        "{layout:?} {entry} for {variant:?}: {n} copies of `{walk}`"
                    );
                }
            }
        }
    }
}

/// A plain render's path tracing pipelines (`NEXT_EVENT` false: `gpu::PathVariant`) cannot
/// reach next-event estimation's functions once their overrides are set (as `TracerPipelines`
/// sets them: `entry_constants`), and a NEE render's megakernels can: the code the driver
/// compiles for a plain render holds no light sampling.
#[test]
fn plain_pipelines_reach_no_light_sampling() {
    let module = validate(Features::all(), BvhLayout::Wide);
    for entry in ["trace_paths", "trace_paths_persistent", "propagate"] {
        for (estimator, want, stage) in [
            (Estimator::Plain, false, false),
            (Estimator::Nee, true, false),
            (Estimator::Nee, true, true),
        ] {
            let variant = PathVariant::of(estimator, Sampler::Sobol).with_next_event_stage(stage);
            let constants = entry_constants(Features::all(), entry, variant, false);
            let seen = reachable(&module, &constants, entry);
            assert!(seen.contains("shade_hit"), "{entry}: {seen:?}");
            // With the next_event stage the wavefront's propagate leaves the light samples to
            // it (below); the MIS weight of the emission it hits stays.
            let deferred = entry == "propagate" && stage;
            for f in ["light_query", "light_contribution", "eval_material"] {
                assert_eq!(
                    seen.contains(f),
                    want && !deferred,
                    "{entry} for {variant:?}: `{f}` reachable: {seen:?}"
                );
            }
            assert_eq!(seen.contains("light_pdf"), want, "{entry}: {seen:?}");
        }
    }
}

/// The wavefront's two halves of a NEE render with the `next_event` stage (`PathVariant::
/// next_event_stage`): `propagate` (its pipeline's `DEFER_NEE`)
/// reaches the closest-hit walk and the materials' sampling but no light sampling, shadow ray
/// or BSDF evaluation; `next_event` reaches those and no path tracing: the driver compiles
/// them as two pipelines, side by side.
#[test]
fn the_wavefront_compiles_light_sampling_apart() {
    let module = validate(Features::all(), BvhLayout::Wide);
    let variant = PathVariant::of(Estimator::Nee, Sampler::Sobol).with_next_event_stage(true);
    let entries = TracerPipelines::entries(Schedule::Wavefront, variant);
    assert!(entries.contains(&"next_event"), "{entries:?}");
    for (v, why) in [
        (
            PathVariant::of(Estimator::Plain, Sampler::Sobol).with_next_event_stage(true),
            "a plain render",
        ),
        (
            PathVariant::of(Estimator::Nee, Sampler::Sobol),
            "the default",
        ),
    ] {
        assert!(
            !TracerPipelines::entries(Schedule::Wavefront, v).contains(&"next_event"),
            "{why} runs no next_event stage"
        );
    }
    let seen = |entry| {
        reachable(
            &module,
            &entry_constants(Features::all(), entry, variant, false),
            entry,
        )
    };
    let (propagate, next_event) = (seen("propagate"), seen("next_event"));
    for f in ["trace_query", "shade_hit", "sample_rough_plastic"] {
        assert!(propagate.contains(f), "propagate: `{f}`: {propagate:?}");
        assert!(!next_event.contains(f), "next_event: `{f}`: {next_event:?}");
    }
    for f in [
        "light_query",
        "light_contribution",
        "trace_any",
        "eval_material",
        "eval_rough_plastic",
    ] {
        assert!(next_event.contains(f), "next_event: `{f}`: {next_event:?}");
        assert!(!propagate.contains(f), "propagate: `{f}`: {propagate:?}");
    }
}
