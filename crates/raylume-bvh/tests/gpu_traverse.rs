//! `TRAVERSE_WGSL` and `WIDE_TRAVERSE_WGSL` on the GPU (lavapipe in CI) against the CPU
//! traversal of the same tree: ~50,000 queries of the brute-force test's five kinds on a scene
//! of triangles and spheres, in each layout.

mod support;

use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh, Hit, INVALID_INDEX, Primitive, wide_traverse};
use raylume_gpu::{GpuContext, GpuError, testing::context_or_skip, wgpu};

/// One query as the test kernel reads it. `repr(C)`, `Pod`, 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuQuery {
    origin: [f32; 3],
    t_min: f32,
    dir: [f32; 3],
    t_max: f32,
}

const KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> bvh_nodes: array<TraversalNode>;
@group(0) @binding(1) var<storage, read> bvh_primitives: array<Primitive>;

struct GpuQuery {
    origin: vec3<f32>,
    t_min: f32,
    dir: vec3<f32>,
    t_max: f32,
}
@group(0) @binding(2) var<storage, read> queries: array<GpuQuery>;
@group(0) @binding(3) var<storage, read_write> hits: array<Hit>;
@group(0) @binding(4) var<storage, read_write> any_hits: array<u32>;

@compute @workgroup_size(64)
fn trace_test(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= arrayLength(&queries) {
        return;
    }
    let q = queries[i];
    let ray = Ray(q.origin, q.dir);
    hits[i] = trace_closest(ray, q.t_min, q.t_max);
    any_hits[i] = select(0u, 1u, trace_any(ray, q.t_min, q.t_max));
}
"#;

/// Runs the kernel over `queries`: each query's closest hit and any-hit flag.
fn trace_on_gpu(
    ctx: &GpuContext,
    bvh: &GpuBvh,
    queries: &[GpuQuery],
) -> Result<(Vec<Hit>, Vec<u32>), GpuError> {
    let source = format!("{}\n{KERNEL}", bvh.traverse_wgsl());
    let module = ctx.scoped("compiling traverse_test", || {
        ctx.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("traverse_test"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
    })?;
    let pipeline = ctx.scoped("creating the trace_test pipeline", || {
        ctx.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("trace_test"),
                layout: None,
                module: &module,
                entry_point: Some("trace_test"),
                compilation_options: Default::default(),
                cache: None,
            })
    })?;
    let none = wgpu::BufferUsages::empty();
    let nodes = ctx.storage_buffer("bvh_nodes", bvh.node_bytes(), none)?;
    let primitives = ctx.storage_buffer("bvh_primitives", &bvh.primitives, none)?;
    let query_buf = ctx.storage_buffer("queries", queries, none)?;
    let n = queries.len();
    let hits = ctx.storage_buffer_zeroed(
        "hits",
        (n * size_of::<Hit>()) as u64,
        wgpu::BufferUsages::COPY_SRC,
    )?;
    let any =
        ctx.storage_buffer_zeroed("any_hits", (n * 4) as u64, wgpu::BufferUsages::COPY_SRC)?;
    ctx.scoped("dispatching trace_test", || {
        let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace_test"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                (0, &nodes),
                (1, &primitives),
                (2, &query_buf),
                (3, &hits),
                (4, &any),
            ]
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }),
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("trace_test"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups((n as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
    })?;
    Ok((ctx.read_buffer(&hits, n)?, ctx.read_buffer(&any, n)?))
}

fn scene_of(bvh: &GpuBvh, hit: &Hit) -> Option<(u32, u32)> {
    (hit.prim != INVALID_INDEX).then(|| {
        let p: &Primitive = &bvh.primitives[hit.prim as usize];
        (p.kind(), p.scene_index())
    })
}

#[test]
fn wgsl_traversal_matches_the_cpu_traversal() {
    let Some(ctx) = context_or_skip("wgsl_traversal_matches_the_cpu_traversal") else {
        return;
    };
    for layout in [BvhLayout::Binary, BvhLayout::Wide] {
        check_scene(
            ctx,
            support::spheres_and_triangles(),
            BvhQuality::Quality,
            layout,
            21,
        );
        check_scene(
            ctx,
            support::icosphere_on_plane(),
            BvhQuality::Fast,
            layout,
            22,
        );
    }
}

/// The CPU traversal of `bvh`'s layout: (closest hit, any hit).
fn trace_on_cpu(bvh: &GpuBvh, q: &support::Query) -> (Hit, bool) {
    let (r, t0, t1) = (&q.ray, q.t_min, q.t_max);
    match bvh.layout {
        BvhLayout::Binary => (
            raylume_bvh::trace_closest(&bvh.nodes, &bvh.primitives, r, t0, t1),
            raylume_bvh::trace_any(&bvh.nodes, &bvh.primitives, r, t0, t1),
        ),
        BvhLayout::Wide => (
            wide_traverse::trace_closest(&bvh.wide_nodes, &bvh.primitives, r, t0, t1),
            wide_traverse::trace_any(&bvh.wide_nodes, &bvh.primitives, r, t0, t1),
        ),
    }
}

/// Traces 50,000 queries on `f` on the GPU and the CPU and compares them.
fn check_scene(
    ctx: &GpuContext,
    f: support::Fixture,
    quality: BvhQuality,
    layout: BvhLayout,
    seed: u64,
) {
    let bvh = GpuBvh::build_with_layout(&f.triangles, &f.spheres, quality, layout).unwrap();
    bvh.validate().unwrap();
    let queries = support::queries(&f, 50_000, seed);
    let gpu_queries: Vec<GpuQuery> = queries
        .iter()
        .map(|q| GpuQuery {
            origin: q.ray.origin.to_array(),
            t_min: q.t_min,
            dir: q.ray.dir.to_array(),
            t_max: q.t_max,
        })
        .collect();
    let (gpu_hits, gpu_any) = trace_on_gpu(ctx, &bvh, &gpu_queries).unwrap();

    let (lo, hi) = f.bounds();
    let size = (hi - lo).max_element();
    let (mut identical, mut same, mut ties, mut hits) = (0usize, 0usize, 0usize, 0usize);
    // Beyond ties: the same primitive with t further apart, another primitive at another t, a
    // hit against a miss, a different any-hit answer.
    let (mut t_apart, mut other_prim, mut hit_vs_miss, mut any_differs) = (0, 0, 0, 0);
    let (mut disagreements, mut not_identical) = (Vec::new(), Vec::new());
    for (i, q) in queries.iter().enumerate() {
        let (cpu, cpu_any) = trace_on_cpu(&bvh, q);
        let gpu = gpu_hits[i];
        let any_ok = cpu_any == (gpu_any[i] == 1);
        hits += usize::from(cpu.prim != INVALID_INDEX);
        if bytemuck::bytes_of(&cpu) == bytemuck::bytes_of(&gpu) && any_ok {
            identical += 1;
        } else if not_identical.len() < 4 {
            not_identical.push(format!(
                "query {i}: cpu {cpu:?} any {cpu_any}, gpu {gpu:?} any {}",
                gpu_any[i]
            ));
        }
        // Rounding moves t by ulps of the coordinates involved, not of t: for a hit just
        // past a ray's origin on a surface, 1e-5 of t is less than one ulp of the scene. So
        // t agrees when within 1e-5 of max(t, scene size / |dir|).
        let scale = cpu.t.abs().max(size / q.ray.dir.length());
        let (same_prim, tie) = match (scene_of(&bvh, &cpu), scene_of(&bvh, &gpu)) {
            (None, None) => (true, false),
            (Some(a), Some(b)) if a == b => {
                let close = (cpu.t - gpu.t).abs() <= 1e-5 * scale;
                t_apart += usize::from(!close);
                (close, false)
            }
            (Some(_), Some(_)) => {
                let tie = (cpu.t - gpu.t).abs() <= support::TIE_RELATIVE * scale;
                other_prim += usize::from(!tie);
                (false, tie)
            }
            _ => {
                hit_vs_miss += 1;
                (false, false)
            }
        };
        any_differs += usize::from(!any_ok);
        same += usize::from(same_prim && any_ok);
        ties += usize::from(tie && any_ok);
        if !((same_prim || tie) && any_ok) && disagreements.len() < 8 {
            disagreements.push(format!(
                "query {i} {q:?}: cpu {cpu:?} any {cpu_any}, gpu {gpu:?} any {}",
                gpu_any[i]
            ));
        }
    }
    let n = queries.len();
    eprintln!(
        "{} on {} ({quality:?}, {layout:?}): of {n} queries {identical} bit-identical, {same} same \
         primitive with t within 1e-5 of max(t, size), {ties} ties (another primitive at the \
         same t), {hits} hit; beyond ties: {t_apart} same primitive with t further apart, \
         {other_prim} another primitive, {hit_vs_miss} a hit against a miss, {any_differs} \
         another any-hit answer",
        f.name,
        ctx.describe(),
    );
    for d in &disagreements {
        eprintln!("  differs: {d}");
    }
    assert!(
        hits > queries.len() / 5,
        "the query set hits too little: {hits}"
    );
    // The WGSL evaluates the same expressions in the same order as the Rust. A software
    // adapter (lavapipe: LLVM without fast-math contraction) then computes the same f32
    // operations: every result bit-identical, required.
    if ctx.info.is_software {
        assert_eq!(
            identical,
            n,
            "{} of {n} queries not bit-identical on a software adapter, e.g.:\n{}",
            n - identical,
            not_identical.join("\n")
        );
        return;
    }
    // A GPU compiler may contract a multiply and an add into one fused multiply-add (WGSL
    // allows it and cannot forbid it) and divide less exactly than IEEE (Vulkan allows 2.5 ulp
    // for 1 / x); the H100 and H200 do both, and a quarter of their results differ from the
    // CPU's in the last bits. That changes the outcome only for a ray within rounding of an
    // edge or a vertex, where two primitives meet at the same t: the two sides may then report
    // different ones of them, a tie as in the brute-force tests. A fifth of these queries run
    // parallel to an axis, half of those exactly through vertices, so ties are common here
    // (732 of the icosphere's 50,000 on the H100). Beyond ties, the H100 and the H200 differed
    // on 3 of these 100,000 queries (2026-12-01), all of them the same triangle hit by a
    // grazing ray from 20 scene units away, t apart by 1.5e-5 (ill-conditioned barycentrics
    // amplify the ulp differences), none a hit against a miss, another primitive or another
    // any-hit answer. Required: those kinds never; t apart for at most
    // HARDWARE_T_APART_PER_SCENE queries of a scene (a few times the measured rate).
    assert_eq!(
        (other_prim, hit_vs_miss, any_differs),
        (0, 0, 0),
        "{}: GPU and CPU disagree on the primitive, hit or any-hit, e.g.:\n{}",
        f.name,
        disagreements.join("\n")
    );
    assert!(
        t_apart <= HARDWARE_T_APART_PER_SCENE,
        "{}: {t_apart} of {n} queries hit the same primitive at t further apart than 1e-5, \
         e.g.:\n{}",
        f.name,
        disagreements.join("\n")
    );
    assert_eq!(same + ties + t_apart, n);
}

/// On a hardware adapter, the queries of one scene (50,000) that may find the same primitive
/// as the CPU with t further apart than 1e-5 of max(t, size): the H100 and H200 measured 3 in
/// both scenes together, and allowing 8 a scene keeps the bound near that rate while leaving
/// room for another driver's contractions.
const HARDWARE_T_APART_PER_SCENE: usize = 8;
