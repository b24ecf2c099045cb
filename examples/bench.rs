//! The paper's Table 1, remade: every scene at 1000x1000, 10 bounces, 1/10/100 spp, timing
//! the ray-tracing phase (GPU timestamps where the adapter has them). Prints a Markdown table
//! and optionally writes JSON.
//!
//! ```text
//! cargo run --release --example bench -- --backend gpu scenes/*.toml scenes/living-room/scene.json
//! ```

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use raylume::{Backend, ReorderPolicy, Scene, Schedule, Tracer};
use serde::Serialize;

#[derive(Parser, Debug)]
#[command(
    name = "bench",
    about = "Time raylume renders the way the paper's Table 1 does"
)]
struct Args {
    /// Scene files.
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// auto, gpu or cpu.
    #[arg(long, default_value = "auto")]
    backend: Backend,
    /// Comma-separated samples per pixel.
    #[arg(long, default_value = "1,10,100", value_delimiter = ',')]
    spp: Vec<u32>,
    /// Image size.
    #[arg(long, default_value = "1000x1000")]
    size: String,
    /// Bounces.
    #[arg(long, default_value_t = 10)]
    bounces: u32,
    /// Comma-separated reorder policies to time.
    #[arg(long, default_value = "off", value_delimiter = ',')]
    reorder: Vec<ReorderPolicy>,
    /// Comma-separated schedules to time (megakernel, wavefront).
    #[arg(long, default_value = "megakernel", value_delimiter = ',')]
    schedule: Vec<String>,
    /// Samples per pixel per batch.
    #[arg(long)]
    batch_spp: Option<u32>,
    /// Best of this many runs per cell.
    #[arg(long, default_value_t = 3)]
    repeat: u32,
    /// Write every measurement as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Save the last image of each scene into this folder (PNG).
    #[arg(long)]
    images: Option<PathBuf>,
}

#[derive(Serialize)]
struct Row {
    scene: String,
    primitives: usize,
    backend: String,
    adapter: String,
    schedule: String,
    reorder: String,
    spp: u32,
    width: u32,
    height: u32,
    bounces: u32,
    /// Best `trace` seconds (the paper's ray-tracing phase).
    trace_s: f64,
    /// `total` seconds of that same run (BVH build, upload, trace, post; no loading).
    total_s: f64,
    rays_traced: u64,
    mrays_per_s: f64,
    all_trace_s: Vec<f64>,
}

fn run(args: Args) -> Result<(), String> {
    let (w, h) = args
        .size
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .ok_or_else(|| format!("bad --size {}", args.size))?;
    let mut rows = Vec::new();
    let mut tracer = Tracer::new(args.backend);
    if let Some(b) = args.batch_spp {
        tracer.batch_spp = b;
    }
    for path in &args.scenes {
        let t = Instant::now();
        let mut scene = Scene::load(path).map_err(|e| e.to_string())?;
        eprintln!(
            "{}: {} triangles, {} spheres, loaded in {:.2} s",
            path.display(),
            scene.triangles.len(),
            scene.spheres.len(),
            t.elapsed().as_secs_f64()
        );
        scene.render.width = w;
        scene.render.height = h;
        scene.render.max_bounces = args.bounces;
        for sched in &args.schedule {
            tracer.schedule = match sched.as_str() {
                "megakernel" => Schedule::Megakernel,
                "wavefront" => Schedule::Wavefront,
                s => return Err(format!("unknown schedule {s}")),
            };
            for &reorder in &args.reorder {
                tracer.reorder = reorder;
                // Warm-up: compiles pipelines, touches every buffer once.
                scene.render.spp = 1;
                tracer.render(&scene).map_err(|e| e.to_string())?;
                for &spp in &args.spp {
                    scene.render.spp = spp;
                    let mut best: Option<raylume::Render> = None;
                    let mut all = Vec::new();
                    for _ in 0..args.repeat.max(1) {
                        let r = tracer.render(&scene).map_err(|e| e.to_string())?;
                        all.push(r.stats.seconds.trace);
                        if best
                            .as_ref()
                            .is_none_or(|b| r.stats.seconds.trace < b.stats.seconds.trace)
                        {
                            best = Some(r);
                        }
                    }
                    let best = best.expect("repeat >= 1");
                    let s = &best.stats;
                    eprintln!(
                        "  {} {} reorder={} spp={spp}: trace {:.4} s, total {:.4} s, {:.0} Mrays/s",
                        s.backend,
                        s.schedule,
                        s.reorder,
                        s.seconds.trace,
                        s.seconds.total,
                        s.mrays_per_s
                    );
                    rows.push(Row {
                        scene: path.display().to_string(),
                        primitives: scene.primitive_count(),
                        backend: s.backend.clone(),
                        adapter: s.adapter.clone(),
                        schedule: s.schedule.clone(),
                        reorder: s.reorder.clone(),
                        spp,
                        width: w,
                        height: h,
                        bounces: args.bounces,
                        trace_s: s.seconds.trace,
                        total_s: s.seconds.total,
                        rays_traced: s.rays_traced,
                        mrays_per_s: s.mrays_per_s,
                        all_trace_s: all,
                    });
                    if let Some(dir) = &args.images {
                        let stem = path
                            .file_stem()
                            .map(|s| s.to_string_lossy().to_string())
                            .unwrap_or_default();
                        let stem = if stem == "scene" {
                            path.parent()
                                .and_then(|p| p.file_name())
                                .map(|s| s.to_string_lossy().to_string())
                                .unwrap_or(stem)
                        } else {
                            stem
                        };
                        let out = dir.join(format!("{stem}-{}-{spp}spp.png", s.backend));
                        best.save(&out).map_err(|e| e.to_string())?;
                    }
                }
            }
        }
    }
    println!(
        "| scene | prims | backend | schedule | reorder | spp | trace s | total s | Mrays/s |"
    );
    println!("|---|---:|---|---|---|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.4} | {:.4} | {:.0} |",
            r.scene,
            r.primitives,
            r.backend,
            r.schedule,
            r.reorder,
            r.spp,
            r.trace_s,
            r.total_s,
            r.mrays_per_s
        );
    }
    if let Some(p) = &args.json {
        std::fs::write(
            p,
            serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?,
        )
        .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    }
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
