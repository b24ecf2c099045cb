//! Rays per second through a scene's BVH alone, on the GPU and on the CPU: what traversal
//! costs without shading, to set beside the path tracer's segments per second (`bench`).
//!
//! ```text
//! cargo run --release --example trace_rate -- scenes/living-room/scene.json [--size 1000x1000]
//!     [--bvh wide,binary] [--backend gpu,cpu] [--repeat 5]
//! ```
//!
//! Two sets of rays per scene, one per pixel of a `--size` image: **primary** (through each
//! pixel's centre from the camera: coherent) and **diffuse** (from each primary hit, leaving
//! the surface in a cosine-distributed direction about its geometric normal: incoherent, what
//! the later bounces of a path trace). Each set is traced as closest-hit queries and as
//! any-hit queries (shadow rays) over the whole set, best of `--repeat` runs; the GPU time is
//! the wall clock of `--passes` dispatches over the set in one submission and their
//! completion (one dispatch of a million rays takes well under a millisecond on a large GPU:
//! the passes keep the submission's fixed cost out of the rate), the CPU's of a `rayon` loop
//! over every core. Both backends count the rays that hit, and closest-hit and any-hit
//! queries must agree on that count.
//!
//! `--dump DIR` also writes, per scene, the scene's triangles and both ray sets to
//! `DIR/<scene>/` (`mesh.ply`, `primary.f32`, `diffuse.f32`, `hits.json`), so that another
//! renderer can trace the very same rays through the very same triangles:
//! `tools/peers/mitsuba_trace_rate.py` times Mitsuba 3's (Embree's on the CPU, OptiX's on
//! the GPU) traversal of them and checks its hit counts against raylume's.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use raylume::Scene;
use raylume::glam::{Vec2, Vec3};
use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh, Hit, Primitive, Ray};
use raylume_gpu::{AdapterChoice, ContextOptions, GpuContext, GpuError, wgpu};
use raylume_kernels::CpuIsa;
use raylume_kernels::cpu::isa::with_isa;
use rayon::prelude::*;

#[path = "support/scene_name.rs"]
mod support;
use support::scene_name;

#[derive(Parser, Debug)]
#[command(name = "trace_rate", about = "Rays per second through the BVH alone")]
struct Args {
    /// Scene files.
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Rays per set: one per pixel of this image.
    #[arg(long, default_value = "1000x1000")]
    size: String,
    /// Comma-separated BVH layouts (wide, binary).
    #[arg(long, default_value = "wide,binary", value_delimiter = ',')]
    bvh: Vec<BvhLayout>,
    /// Comma-separated backends (gpu, cpu).
    #[arg(long, default_value = "gpu,cpu", value_delimiter = ',')]
    backend: Vec<String>,
    /// Best of this many runs per cell.
    #[arg(long, default_value_t = 5)]
    repeat: u32,
    /// GPU dispatches over the set per timed submission.
    #[arg(long, default_value_t = 10)]
    passes: u32,
    /// Write each scene's triangles and ray sets here (see the module docs).
    #[arg(long)]
    dump: Option<PathBuf>,
    /// The highest instruction-set level the CPU walks run at (x86-64-v4, x86-64-v3 or build),
    /// as the renders' `--cpu-isa`: by default the CPU's best, what the renders run.
    #[arg(long, default_value = "x86-64-v4", value_parser = parse_cpu_isa)]
    cpu_isa: CpuIsa,
}

fn parse_cpu_isa(s: &str) -> Result<CpuIsa, String> {
    CpuIsa::parse(s.trim()).ok_or_else(|| format!("`{s}`: x86-64-v4, x86-64-v3 or build"))
}

/// One query as the kernel reads it (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Query {
    origin: [f32; 3],
    t_min: f32,
    dir: [f32; 3],
    t_max: f32,
}

const KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> bvh_nodes: array<TraversalNode>;
@group(0) @binding(1) var<storage, read> bvh_primitives: array<Primitive>;
struct Query {
    origin: vec3<f32>,
    t_min: f32,
    dir: vec3<f32>,
    t_max: f32,
}
@group(0) @binding(2) var<storage, read> queries: array<Query>;
// Per query, 1 when it hit (a plain store: no atomics to contend on).
@group(0) @binding(3) var<storage, read_write> hit: array<u32>;

@compute @workgroup_size(64)
fn closest(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&queries) {
        return;
    }
    let q = queries[id.x];
    let h = trace_closest(Ray(q.origin, q.dir), q.t_min, q.t_max);
    hit[id.x] = select(0u, 1u, h.prim != INVALID_INDEX);
}

@compute @workgroup_size(64)
fn any(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&queries) {
        return;
    }
    let q = queries[id.x];
    hit[id.x] = select(0u, 1u, trace_any(Ray(q.origin, q.dir), q.t_min, q.t_max));
}
"#;

/// At most this many rays a set: one dispatch of 65,535 workgroups of 64 (`gpu_rate`).
const MAX_RAYS: u64 = 65_535 * 64;

/// `--size WxH`: both at least 1, at most [`MAX_RAYS`] together.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("--size {s}: expected WxH of 1 to {MAX_RAYS} rays, e.g. 500x500");
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let (w, h): (u32, u32) = (w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_RAYS {
        return Err(bad());
    }
    Ok((w, h))
}

/// The unit geometric normal of leaf primitive `p` at `point`.
fn normal(p: &Primitive, point: Vec3) -> Vec3 {
    let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
    if p.kind() == raylume_bvh::PRIM_SPHERE {
        (point - v(p.a)).normalize()
    } else {
        (v(p.b) - v(p.a)).cross(v(p.c) - v(p.a)).normalize()
    }
}

/// A cheap hash to [0, 1)² per index.
fn hash2(i: u32) -> Vec2 {
    let h = raylume_kernels::rng::pcg4d([i, 0x7261_7465, 17, 3]);
    Vec2::new(
        (h[0] >> 8) as f32 / 16_777_216.0,
        (h[1] >> 8) as f32 / 16_777_216.0,
    )
}

/// Primary rays through every pixel centre, and the diffuse rays leaving their hits.
fn rays(scene: &Scene, bvh: &GpuBvh, w: u32, h: u32) -> (Vec<Query>, Vec<Query>) {
    let [origin, forward, right, up] = raylume_kernels::camera::camera_basis(&scene.camera, w, h);
    let primary: Vec<Query> = (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (x, y) = (p % w, p / w);
            let sx = 2.0 * ((x as f32 + 0.5) / w as f32) - 1.0;
            let sy = 1.0 - 2.0 * ((y as f32 + 0.5) / h as f32);
            let dir = (forward + right * sx + up * sy).normalize();
            Query {
                origin: origin.into(),
                t_min: 0.0,
                dir: dir.into(),
                t_max: f32::INFINITY,
            }
        })
        .collect();
    let diffuse: Vec<Query> = primary
        .par_iter()
        .enumerate()
        .filter_map(|(i, q)| {
            let ray = Ray {
                origin: Vec3::from(q.origin),
                dir: Vec3::from(q.dir),
            };
            let hit: Hit = bvh.trace_closest(&ray, 0.0, f32::INFINITY)?;
            let p = ray.origin + ray.dir * hit.t;
            let mut n = normal(&bvh.primitives[hit.prim as usize], p);
            if n.dot(ray.dir) > 0.0 {
                n = -n;
            }
            let dir = raylume_kernels::sampling::sample_diffuse(n, hash2(i as u32));
            Some(Query {
                origin: (p + n * 1e-4 * (1.0 + p.abs().max_element())).into(),
                t_min: 0.0,
                dir: dir.into(),
                t_max: f32::INFINITY,
            })
        })
        .collect();
    (primary, diffuse)
}

/// Writes the scene's triangles (a binary PLY in world space, each once; their number is
/// returned), both ray sets (per ray eight little-endian `f32`s: origin, `t_min`,
/// direction, `t_max`) and their closest-hit counts to `dir`. Fails on a scene with
/// spheres: another renderer would not trace the same primitives.
fn dump(
    dir: &Path,
    bvh: &GpuBvh,
    sets: [(&str, &[Query]); 2],
) -> Result<usize, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    if bvh
        .primitives
        .iter()
        .any(|p| p.kind() == raylume_bvh::PRIM_SPHERE)
    {
        return Err("the scene has spheres; only triangles can be written as a mesh".into());
    }
    // Each scene triangle once: the BVH's spatial splits give a split triangle a copy per
    // leaf it lies in, which the other renderer's own build would not have.
    let mut seen = std::collections::HashSet::new();
    let triangles: Vec<&Primitive> = bvh
        .primitives
        .iter()
        .filter(|p| seen.insert(p.scene_index()))
        .collect();
    let n = triangles.len();
    let mut ply = std::io::BufWriter::new(std::fs::File::create(dir.join("mesh.ply"))?);
    write!(
        ply,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {n}\n\
         property list uchar int vertex_indices\nend_header\n",
        3 * n
    )?;
    for p in &triangles {
        for v in [p.a, p.b, p.c] {
            ply.write_all(bytemuck::cast_slice(&v[..3]))?;
        }
    }
    for i in 0..n as i32 {
        ply.write_all(&[3])?;
        ply.write_all(bytemuck::cast_slice(&[3 * i, 3 * i + 1, 3 * i + 2]))?;
    }
    ply.flush()?;
    let mut hits = Vec::new();
    for (kind, qs) in sets {
        std::fs::write(dir.join(format!("{kind}.f32")), bytemuck::cast_slice(qs))?;
        let hit = cpu_rate(bvh, qs, false, 1, CpuIsa::Build).1;
        hits.push(format!(
            "\"{kind}\": {{\"rays\": {}, \"hit\": {hit}}}",
            qs.len()
        ));
    }
    std::fs::write(dir.join("hits.json"), format!("{{{}}}\n", hits.join(", ")))?;
    Ok(n)
}

/// Best-of-`repeat` seconds and hit count of `entry` over `queries` on the GPU.
fn gpu_rate(
    ctx: &GpuContext,
    bvh: &GpuBvh,
    queries: &[Query],
    entry: &str,
    repeat: u32,
    passes: u32,
) -> Result<(f64, u32), String> {
    let source = format!("{}\n{KERNEL}", bvh.traverse_wgsl());
    // As the renders' kernels are made (`GpuContext::shader_module`: on Vulkan without naga's
    // bounds checks and loop bounding), so that the rate is the traversal they run.
    let module = ctx.shader_module("trace_rate", &source);
    let pipeline = ctx
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: None,
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
    let none = wgpu::BufferUsages::empty();
    let gpu = |e: GpuError| format!("GPU: {e}");
    let nodes = ctx
        .storage_buffer("bvh_nodes", bvh.node_bytes(), none)
        .map_err(gpu)?;
    let prims = ctx
        .storage_buffer("bvh_primitives", &bvh.primitives, none)
        .map_err(gpu)?;
    let qbuf = ctx.storage_buffer("queries", queries, none).map_err(gpu)?;
    let n = queries.len();
    let count = ctx
        .storage_buffer_zeroed("hit", 4 * n as u64, wgpu::BufferUsages::COPY_SRC)
        .map_err(gpu)?;
    let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("trace_rate"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[(0, &nodes), (1, &prims), (2, &qbuf), (3, &count)].map(|(binding, b)| {
            wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }
        }),
    });
    let mut best = f64::INFINITY;
    let mut hits = 0;
    // One untimed run first (pipeline creation, caches).
    for run in 0..=repeat {
        let t = Instant::now();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            // Dispatches of at most 65,535 workgroups (4.2 M rays) each.
            let groups = (queries.len() as u32).div_ceil(64);
            debug_assert!(groups <= 65_535, "parse_size allows at most MAX_RAYS");
            for _ in 0..passes {
                pass.dispatch_workgroups(groups, 1, 1);
            }
        }
        ctx.queue.submit([enc.finish()]);
        ctx.wait("tracing").map_err(gpu)?;
        let secs = t.elapsed().as_secs_f64() / f64::from(passes);
        if run > 0 {
            best = best.min(secs);
        }
        hits = ctx.read_buffer::<u32>(&count, n).map_err(gpu)?.iter().sum();
    }
    Ok((best, hits))
}

/// Best-of-`repeat` seconds and hit count of `queries` on the CPU (every core), each walk as
/// the renders' paths take it: at level `isa` (`with_isa`), with the wide walk's AVX2 node
/// and triangle tests at x86-64-v3/v4 (`GpuBvh::trace_closest_avx2`), and the
/// triangles-only walk (`SPHERES` false: four or eight triangles a test) where the tree has
/// no spheres.
fn cpu_rate(bvh: &GpuBvh, queries: &[Query], any: bool, repeat: u32, isa: CpuIsa) -> (f64, u32) {
    let spheres = bvh
        .primitives
        .iter()
        .any(|p| p.kind() == raylume_bvh::PRIM_SPHERE);
    if spheres {
        cpu_rate_for::<true>(bvh, queries, any, repeat, isa)
    } else {
        cpu_rate_for::<false>(bvh, queries, any, repeat, isa)
    }
}

/// [`cpu_rate`] with the walk's sphere test compiled in or not.
fn cpu_rate_for<const SPHERES: bool>(
    bvh: &GpuBvh,
    queries: &[Query],
    any: bool,
    repeat: u32,
    isa: CpuIsa,
) -> (f64, u32) {
    let avx2 = cfg!(target_arch = "x86_64") && isa >= CpuIsa::X86_64V3;
    let avx512 = cfg!(target_arch = "x86_64") && isa >= CpuIsa::X86_64V4;
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeat {
        let t = Instant::now();
        // Each chunk of rays walked inside one `with_isa` call, as a render's paths are
        // (entering the level's copy once a ray cost a third of the Cornell box's rate).
        hits = queries
            .par_chunks(1024)
            .map(|chunk| {
                with_isa(
                    isa,
                    #[inline(always)]
                    || {
                        let mut n = 0u32;
                        for q in chunk {
                            let ray = Ray {
                                origin: Vec3::from(q.origin),
                                dir: Vec3::from(q.dir),
                            };
                            n += u32::from(cpu_walk::<SPHERES>(bvh, &ray, q, any, avx2, avx512));
                        }
                        n
                    },
                )
            })
            .sum();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (best, hits)
}

/// Whether `ray` hits (any hit, or a closest one) with the wide walk's AVX2 tests where
/// `avx2` (only inside `with_isa`'s x86-64-v3/v4 copies), its AVX-512 ones where `avx512`
/// (only in the v4 copy), else the build's.
#[inline(always)]
fn cpu_walk<const SPHERES: bool>(
    bvh: &GpuBvh,
    ray: &Ray,
    q: &Query,
    any: bool,
    avx2: bool,
    avx512: bool,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    if avx512 {
        // SAFETY: `with_isa` runs x86-64-v4 only on a CPU that has it (it asserts so).
        return unsafe {
            if any {
                bvh.trace_any_avx512::<SPHERES>(ray, q.t_min, q.t_max)
            } else {
                bvh.trace_closest_avx512::<SPHERES>(ray, q.t_min, q.t_max)
                    .is_some()
            }
        };
    }
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `with_isa` runs x86-64-v3 or v4 only on a CPU that has it (it asserts so),
        // and both have AVX2.
        return unsafe {
            if any {
                bvh.trace_any_avx2::<SPHERES>(ray, q.t_min, q.t_max)
            } else {
                bvh.trace_closest_avx2::<SPHERES>(ray, q.t_min, q.t_max)
                    .is_some()
            }
        };
    }
    if any {
        bvh.trace_any_for::<SPHERES>(ray, q.t_min, q.t_max)
    } else {
        bvh.trace_closest_for::<SPHERES>(ray, q.t_min, q.t_max)
            .is_some()
    }
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("trace_rate: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<(), String> {
    let (w, h) = parse_size(&args.size)?;
    let ctx = if args.backend.iter().any(|b| b == "gpu") {
        let options = ContextOptions {
            choice: AdapterChoice::Any,
            adapter_name: None,
        };
        Some(GpuContext::new(&options).map_err(|e| {
            format!("--backend gpu: {e} (lavapipe counts: see README.md; or --backend cpu)")
        })?)
    } else {
        None
    };
    if let Some(ctx) = &ctx {
        println!("GPU: {}", ctx.describe());
    }
    let isa = CpuIsa::best_up_to(args.cpu_isa);
    println!(
        "CPU: {} threads, {}; {w}x{h} rays per set, best of {}",
        rayon::current_num_threads(),
        isa.name(),
        args.repeat
    );
    println!();
    println!("| scene | prims | layout | backend | rays | closest Mrays/s | any Mrays/s | hit |");
    println!("|---|---:|---|---|---|---:|---:|---:|");
    for path in &args.scenes {
        let scene = Scene::load(path).map_err(|e| format!("{}: {e}", path.display()))?;
        for &layout in &args.bvh {
            let bvh = GpuBvh::from_scene_with_layout(&scene, BvhQuality::Quality, layout)
                .map_err(|e| format!("{}: the BVH: {e}", path.display()))?;
            // The CPU walk's float node boxes, made before the parallel loops.
            bvh.wide_boxes();
            let (primary, diffuse) = rays(&scene, &bvh, w, h);
            if let (Some(root), true) = (&args.dump, layout == args.bvh[0]) {
                let dir = root.join(scene_name(path));
                let n = dump(&dir, &bvh, [("primary", &primary), ("diffuse", &diffuse)])
                    .map_err(|e| format!("writing {}: {e}", dir.display()))?;
                println!("wrote {} ({n} triangles)", dir.display());
            }
            for (kind, qs) in [("primary", &primary), ("diffuse", &diffuse)] {
                for backend in &args.backend {
                    let ((tc, hc), (ta, ha)) = match (backend.as_str(), &ctx) {
                        ("gpu", Some(ctx)) => (
                            gpu_rate(ctx, &bvh, qs, "closest", args.repeat, args.passes)?,
                            gpu_rate(ctx, &bvh, qs, "any", args.repeat, args.passes)?,
                        ),
                        _ => (
                            cpu_rate(&bvh, qs, false, args.repeat, isa),
                            cpu_rate(&bvh, qs, true, args.repeat, isa),
                        ),
                    };
                    assert_eq!(hc, ha, "closest and any-hit disagree on what is hit");
                    println!(
                        "| {} | {} | {} | {backend} | {kind} ({}) | {:.1} | {:.1} | {:.1} % |",
                        path.display(),
                        bvh.primitives.len(),
                        layout.name(),
                        qs.len(),
                        qs.len() as f64 / tc / 1e6,
                        qs.len() as f64 / ta / 1e6,
                        100.0 * hc as f64 / qs.len().max(1) as f64
                    );
                }
            }
        }
    }
    Ok(())
}
