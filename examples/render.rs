//! Renders a scene file to an image: the command a user runs.
//!
//! ```text
//! cargo run --release --example render -- scenes/cornell-box.toml -o cornell.png
//! ```
//! GPU if a hardware adapter is present, else the CPU (it says which). Flags override the
//! scene's `[render]` values. On any error: a message, a non-zero exit, no output file.
//!
//! What it prints, all to stderr: the loader's and the render's warnings (`warning: ...`,
//! among them a scene that nothing lights), then one line with the settings (`raylume:
//! backend CPU (...), size 1000x1000, spp 100, ...`) before the first batch, an estimate of
//! the trace time after the first batch, progress (a bar on a terminal; with stderr piped or
//! redirected a plain line every 5 seconds, or every `RAYLUME_PROGRESS_SECS`), and a summary.
//! `-q` drops the progress and the estimate.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Parser;
use raylume::{Backend, Estimator, ReorderPolicy, Sampler, Scene, Schedule, Tracer};

#[derive(Parser, Debug)]
#[command(
    name = "render",
    version,
    about = "Render a raylume scene (.toml, .obj, .gltf/.glb, Tungsten scene.json) to .png or .exr"
)]
struct Args {
    /// Scene file: .toml, .obj, .gltf, .glb or a Tungsten scene.json (or the folder holding it).
    scene: PathBuf,
    /// Output image: .png (tone-mapped sRGB) or .exr (linear radiance).
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
    /// auto (hardware GPU, else CPU), gpu (any adapter, software included), gpus (every
    /// hardware GPU at once, the samples split between them) or cpu.
    #[arg(long, default_value = "auto")]
    backend: Backend,
    /// Samples per pixel (with --target-error: the most it may trace).
    #[arg(long)]
    spp: Option<u32>,
    /// Trace batches until the relative MSE estimated from their spread is below E (e.g.
    /// 1e-3), then stop; the scene's or --spp's samples per pixel are the cap. Needs at least
    /// 2 batches of --batch-spp samples under the cap to estimate anything.
    #[arg(long, value_name = "E")]
    target_error: Option<f32>,
    /// Render part I of N (1-based, e.g. 2/4): the I-th of N equal ranges of every pixel's
    /// samples, written as an .exr of per-pixel sums with a header; `merge` joins the parts
    /// into the image of one render of all the samples (render farms, Slurm arrays: see
    /// README). No bloom on a part.
    #[arg(long, value_parser = parse_part)]
    part: Option<(u32, u32)>,
    /// Maximum bounces per path.
    #[arg(long)]
    bounces: Option<u32>,
    /// Image size as WIDTHxHEIGHT, e.g. 1000x1000.
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Random seed.
    #[arg(long)]
    seed: Option<u32>,
    /// Samples per pixel per batch (default 32, fewer where the GPU's buffers cannot hold
    /// them; the paper used 20). The image does not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    batch_spp: Option<u32>,
    /// Ray reordering between bounces: off, on or auto. (`auto` decides over repeated renders
    /// of a scene in one process, as a library user or `bench` renders; this command renders
    /// once, so with `auto` it runs what `off` runs and says so.)
    #[arg(long, default_value = "off")]
    reorder: ReorderPolicy,
    /// GPU schedule: persistent (bounces in registers, a thread starting the next sample when
    /// its path ends), megakernel (a thread a sample) or wavefront (the paper's kernels).
    /// Default: chosen per render, the wavefront with its stages where the walk stage runs
    /// (scenes of 10,000 primitives or more), the estimator is NEE and the render traces at
    /// least 2^26 pixel samples (about 64 spp at 1024x1024), else persistent; the stats line
    /// says which ran.
    #[arg(long)]
    schedule: Option<Schedule>,
    /// BVH node layout: wide (eight children a node, compressed; the default) or binary.
    #[arg(long)]
    bvh: Option<raylume::BvhLayout>,
    /// BVH build preset: auto (the default: the one whose build the render's rays repay:
    /// fastest for a quick look at a large scene, quality for a long render), fastest, fast
    /// or quality.
    #[arg(long, default_value = "auto", value_parser = parse_preset)]
    bvh_preset: Preset,
    /// Where the BVH is built: auto (the default: on the GPU for a large scene rendered
    /// briefly, where the CPU's build would take longer than its better tree saves), cpu, or
    /// gpu (a binary linear BVH built in WGSL; triangles only).
    #[arg(long, default_value = "auto")]
    bvh_builder: raylume::BvhBuilder,
    /// Estimator: nee (the default: next-event estimation with multiple importance sampling,
    /// a shadow ray to an emitter at every reflecting hit; far less noise per sample under
    /// small lights) or plain (the paper's).
    #[arg(long, default_value = "nee")]
    estimator: Estimator,
    /// Random numbers: sobol (the default: scrambled Sobol' points, each pixel's a net),
    /// zsobol (pbrt-v4's: the same nets with blue noise across pixels, ~1.3x slower on the
    /// GPU) or independent (the paper's).
    #[arg(long, default_value = "sobol")]
    sampler: Sampler,
    /// With `--schedule wavefront` and NEE: take the light samples in a stage of their own
    /// after each bounce, two pipelines the driver compiles side by side (a cold first run's
    /// wait is shorter; a small scene traces slower). See `Tracer::next_event_stage`.
    #[arg(long)]
    next_event_stage: bool,
    /// With `--schedule wavefront`: walk each bounce's rays in a stage of their own, whose
    /// threads take the next ray when theirs ends: on, off, or auto (the default: on for
    /// scenes of at least 10,000 primitives). Faster on large scenes whose rays are not sorted
    /// (the living room's plain paths 0.486 -> 0.383 s on the H200), slower on small ones; a
    /// sorted bounce is walked as without it. Wide BVH on a GPU with subgroups. See
    /// `Tracer::walk_stage`.
    #[arg(long, default_value = "auto", value_parser = parse_on_off_auto, action = clap::ArgAction::Set)]
    walk_stage: OnOffAuto,
    /// With the walk stage and NEE: walk the shadow rays in a stage of their own after each
    /// bounce's shading, whose threads take the next ray when theirs ends: on (the default)
    /// or off; the same image (the living room's NEE paths 0.376 -> 0.302 s on the H200). See
    /// `Tracer::shadow_stage`.
    #[arg(long, value_parser = parse_on_off)]
    shadow_stage: Option<bool>,
    /// Russian roulette from this path segment on (segments count from 0, the camera ray's;
    /// default 5), or off. Mitsuba 3's `path` at its default rr_depth 5 counts hits from 1:
    /// its roulette is `--rr-depth 4` here.
    #[arg(long, default_value = "5", value_parser = parse_rr_depth)]
    rr_depth: RrDepth,
    /// Environment sampling for nee: on (shadow rays toward the sky go where short diffuse
    /// walks from the camera found it visible, learned per region of the scene before
    /// rendering), off (by the sky's radiance alone, as Mitsuba 3) or auto (the default: on
    /// when the render's rays repay the walks, e.g. not for a thumbnail).
    #[arg(long, default_value = "auto", value_parser = parse_on_off_auto, action = clap::ArgAction::Set)]
    environment_guide: OnOffAuto,
    /// The highest instruction-set level the CPU path may run at: x86-64-v4 (the default:
    /// AVX-512 where the CPU has it, else the highest it has), x86-64-v3 (AVX2) or build (what
    /// this binary was built for). The same image at every level; the stats line says which
    /// ran.
    #[arg(long, default_value = "x86-64-v4", value_parser = parse_cpu_isa)]
    cpu_isa: raylume::CpuIsa,
    /// Whether the CPU path traces scenes of triangles without textures, shading normals or sky
    /// eight paths at a time (sixteen on AVX-512), their diffuse hits' shading in vector
    /// instructions (on, the default), or one at a time (off). The same image; the stats line
    /// says `packets` when they ran.
    #[arg(long, default_value = "on", value_parser = parse_on_off, action = clap::ArgAction::Set)]
    cpu_packets: bool,
    /// Whether the CPU path traces the other scenes two paths at a time, a segment of each in
    /// turn, a hit's records fetched while the other path's segment runs (on), one at a time
    /// (off), or in pairs where those records exceed a core's L2 cache (auto, the default).
    /// The same image; the stats line says `paths in pairs` when they ran.
    #[arg(long, default_value = "auto", value_parser = parse_on_off_auto, action = clap::ArgAction::Set)]
    cpu_pairs: OnOffAuto,
    /// Whether the CPU path places the arrays it reads at random (its walks' arrays, a copy of
    /// the primitives, shading records and texels) in memory backed by 2 MiB pages before it
    /// traces (on), reads them in ordinary pages (off), or places them there where they are
    /// large and the render long (auto, the default). The same image; the stats line says
    /// `records in huge pages` when it ran; the copy's time is part of `upload`.
    #[arg(long, default_value = "auto", value_parser = parse_on_off_auto, action = clap::ArgAction::Set)]
    cpu_huge_pages: OnOffAuto,
    /// Skip the scene's bloom pass.
    #[arg(long)]
    no_bloom: bool,
    /// Write render statistics as JSON to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Exposure in stops for .png output (-64 to 64).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_exposure)]
    exposure: f32,
    /// No progress bar, progress lines or time estimate.
    #[arg(long, short = 'q')]
    quiet: bool,
    /// Print the render's milestones (the scene loaded, the BVH built, the GPU device open,
    /// its pipelines compiled, the upload, the trace, the file written), in seconds from the
    /// process's start, to find what the image waited for. `--stats` writes them anyway.
    #[arg(long)]
    timeline: bool,
}

fn parse_cpu_isa(s: &str) -> Result<raylume::CpuIsa, String> {
    raylume::CpuIsa::parse(s.trim()).ok_or_else(|| format!("`{s}`: x86-64-v4, x86-64-v3 or build"))
}

/// `--rr-depth`: a segment number or `off`.
#[derive(Clone, Copy, Debug)]
struct RrDepth(Option<u32>);

fn parse_rr_depth(s: &str) -> Result<RrDepth, String> {
    if s.trim() == "off" {
        return Ok(RrDepth(None));
    }
    s.trim()
        .parse()
        .map(|d| RrDepth(Some(d)))
        .map_err(|_| format!("`{s}` is not a path segment number or `off`"))
}

fn parse_on_off(s: &str) -> Result<bool, String> {
    match s.trim() {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("`{s}`: on or off")),
    }
}

/// `--environment-guide`, `--walk-stage`: `on`, `off` or `auto` (`None`: the library decides). A newtype:
/// clap takes a bare `Option` field for an optional flag.
#[derive(Clone, Copy, Debug)]
struct OnOffAuto(Option<bool>);

fn parse_on_off_auto(s: &str) -> Result<OnOffAuto, String> {
    match s.trim() {
        "auto" => Ok(OnOffAuto(None)),
        other => parse_on_off(other)
            .map(|b| OnOffAuto(Some(b)))
            .map_err(|_| format!("`{s}`: on, off or auto")),
    }
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WIDTHxHEIGHT (e.g. 1000x1000)"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in `{s}`"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in `{s}`"))?;
    Ok((w, h))
}

/// A finite exposure within ±64 stops (2^64 already saturates any radiance a render holds),
/// checked before rendering rather than when the image is written.
fn parse_exposure(s: &str) -> Result<f32, String> {
    let stops: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number of stops"))?;
    if !(-64.0..=64.0).contains(&stops) {
        return Err(format!("exposure {s} stops: use a value from -64 to 64"));
    }
    Ok(stops)
}

/// Fails early, before any rendering, if an output path cannot be written.
fn check_output_path(path: &Path, what: &str, allowed: &[&str]) -> Result<(), String> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !allowed.contains(&ext.as_str()) {
        return Err(format!(
            "{what} {}: use a file name ending in {}",
            path.display(),
            allowed
                .iter()
                .map(|e| format!(".{e}"))
                .collect::<Vec<_>>()
                .join(" or ")
        ));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!(
            "{what} {}: the folder {} does not exist",
            path.display(),
            dir.display()
        ));
    }
    let meta = std::fs::metadata(dir).map_err(|e| format!("{what} {}: {e}", path.display()))?;
    if meta.permissions().readonly() {
        return Err(format!(
            "{what} {}: the folder {} is read-only",
            path.display(),
            dir.display()
        ));
    }
    Ok(())
}

fn run(args: Args, timeline: raylume::Timeline) -> Result<(), String> {
    check_output_path(&args.output, "output", &["png", "exr"])?;
    if args.part.is_some()
        && !args
            .output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        return Err(format!(
            "{}: a part holds sums of samples, to be merged: write it as .exr",
            args.output.display()
        ));
    }
    if let Some(s) = &args.stats {
        check_output_path(s, "stats file", &["json"])?;
    }

    let t_start = Instant::now();
    let mut tracer = Tracer::new(args.backend);
    tracer.timeline = Some(timeline.clone());
    tracer.seed = args.seed;
    tracer.reorder = args.reorder;
    tracer.bloom = !args.no_bloom;
    tracer.tone.exposure = args.exposure;
    if let Some(b) = args.batch_spp {
        tracer.batch_spp = b;
    }
    tracer.estimator = args.estimator;
    tracer.sampler = args.sampler;
    tracer.next_event_stage = args.next_event_stage;
    tracer.walk_stage = args.walk_stage.0;
    if let Some(on) = args.shadow_stage {
        tracer.shadow_stage = on;
    }
    tracer.russian_roulette = args.rr_depth.0;
    tracer.environment_guide = args.environment_guide.0;
    tracer.cpu_isa = args.cpu_isa;
    tracer.cpu_packets = args.cpu_packets;
    tracer.cpu_pairs = args.cpu_pairs.0;
    tracer.cpu_huge_pages = args.cpu_huge_pages.0;
    tracer.target_error = args.target_error;
    tracer.schedule = args.schedule;
    if let Some(l) = args.bvh {
        tracer.bvh_layout = l;
    }
    tracer.bvh_quality = args.bvh_preset.0;
    tracer.bvh_builder = args.bvh_builder;

    // The GPU device opens on a thread of its own (0.14-0.16 s on the H200) while the scene
    // loads and its BVH is built (docs/RESULTS.md, time to the first image).
    tracer.start_backend();
    let overrides = |scene: &mut Scene| {
        if let Some((w, h)) = args.size {
            scene.render.width = w;
            scene.render.height = h;
        }
        if let Some(spp) = args.spp {
            scene.render.spp = spp;
        }
        if let Some(b) = args.bounces {
            scene.render.max_bounces = b;
        }
    };
    let t_load = Instant::now();
    // The BVH is built (and the coat tables integrated) as soon as the geometry is known,
    // while the scene's images may still decode (the living room's progressive JPEG takes
    // 0.06-0.15 s on the H200's host). A part's render plans its own tree.
    let mut geometry_s = 0.0;
    let mut scene = Scene::load_with(&args.scene, |scene| {
        timeline.mark("load: geometry final");
        overrides(scene);
        if args.part.is_none() {
            let t = Instant::now();
            // Errors come again, and are reported, from `prepare_scene` and the render.
            let _ = tracer.prepare_geometry(scene);
            geometry_s = t.elapsed().as_secs_f64();
        }
    })
    .map_err(|e| e.to_string())?;
    timeline.mark("load: done");
    // The build is the `bvh` stage's (the render reports it), not the load's.
    let load_s = t_load.elapsed().as_secs_f64() - geometry_s;
    overrides(&mut scene);
    if let Some((i, n)) = args.part {
        let range =
            raylume::SampleRange::part(i, n, scene.render.spp).map_err(|e| e.to_string())?;
        tracer.samples = Some(range);
    }
    tracer.prepare_scene(&scene).map_err(|e| e.to_string())?;
    timeline.mark("prepare_scene: done");
    // A bar on a terminal; plain lines (no escape codes) when stderr is piped or redirected.
    let terminal = std::io::stderr().is_terminal();
    let bar = if args.quiet || !terminal {
        indicatif::ProgressBar::hidden()
    } else {
        let bar = indicatif::ProgressBar::new(u64::from(scene.render.spp));
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp ({eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    };
    let scene_name = args.scene.display().to_string();
    let capped = args.target_error.is_some();
    tracer.on_start(move |s| {
        for w in &s.warnings {
            eprintln!("warning: {w}");
        }
        eprintln!("raylume: {}", settings_line(&scene_name, s, capped));
    });
    let bar_cb = bar.clone();
    let interval = progress_interval();
    let last_line = Arc::new(Mutex::new(None::<Duration>));
    let quiet = args.quiet;
    tracer.on_progress(move |p| {
        bar_cb.set_length(u64::from(p.total_spp));
        bar_cb.set_position(u64::from(p.done_spp));
        if quiet || p.done_spp == 0 {
            return;
        }
        let mut last = last_line.lock().unwrap_or_else(|e| e.into_inner());
        let secs = p.elapsed.as_secs_f64();
        let estimate = secs * f64::from(p.total_spp) / f64::from(p.done_spp);
        match *last {
            // One batch is the whole render: nothing to estimate.
            None if p.done_spp >= p.total_spp => *last = Some(p.elapsed),
            None => {
                // After the first batch: what the whole trace will cost.
                let line = format!(
                    "raylume: first batch: {} of {} spp in {secs:.2} s; estimated trace time \
                     {}{estimate:.1} s",
                    p.done_spp,
                    p.total_spp,
                    if capped { "at most " } else { "" },
                );
                bar_cb.suspend(|| eprintln!("{line}"));
                *last = Some(p.elapsed);
            }
            Some(t) if !terminal && p.elapsed.saturating_sub(t) >= interval => {
                eprintln!(
                    "raylume: progress {}/{} spp, {secs:.1} s, about {:.1} s left",
                    p.done_spp,
                    p.total_spp,
                    (estimate - secs).max(0.0)
                );
                *last = Some(p.elapsed);
            }
            Some(_) => {}
        }
    });
    let mut render = tracer.render(&scene).map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    render.stats.seconds.load = load_s;
    let t_save = Instant::now();
    render.save(&args.output).map_err(|e| e.to_string())?;
    render.stats.seconds.save = t_save.elapsed().as_secs_f64();
    render.stats.seconds.total = t_start.elapsed().as_secs_f64();
    timeline.mark("saved");
    render.stats.timeline = timeline.marks();

    let s = &render.stats;
    let roulette = match s.russian_roulette {
        Some(d) => format!("roulette from {d}"),
        None => "roulette off".into(),
    };
    eprintln!(
        "raylume: rendered {} ({}x{}, {} spp, {} bounces; estimator {}, sampler {}, {roulette}, \
         environment {}, textures {}, texel buffer {:.1} MB) on {} [{}]: {} (reorder {})",
        args.scene.display(),
        s.width,
        s.height,
        s.spp,
        s.max_bounces,
        s.estimator,
        s.sampler,
        s.environment_guide,
        s.textures,
        s.texel_bytes as f64 / 1e6,
        s.backend.to_uppercase(),
        s.adapter,
        s.backend_reason,
        s.reorder
    );
    eprintln!(
        "raylume: trace {:.3} s, {:.1} Mrays/s, total {:.3} s from the file to the image (load {:.3} \
         and device {:.3} together, bvh {:.3} {} {}{} ({}) and pipelines {:.3}{} together, upload \
         {:.3} (guide {:.3}), prepare {:.3}, post {:.3}, save {:.3})",
        s.seconds.trace,
        s.mrays_per_s,
        s.seconds.total,
        s.seconds.load,
        s.seconds.device,
        s.seconds.bvh,
        s.bvh_preset,
        s.bvh_layout,
        match (s.bvh_cached, s.prepared_ahead) {
            (true, _) => " cached",
            (false, true) => " ahead",
            _ => "",
        },
        s.bvh_builder,
        s.seconds.pipelines,
        match (s.pipelines_cached, s.pipelines_ahead) {
            (true, _) => " cached",
            (false, true) => " ahead",
            _ => "",
        },
        s.seconds.upload,
        s.seconds.guide,
        s.seconds.prepare,
        s.seconds.post,
        s.seconds.save
    );
    if let Some(target) = s.target_error {
        eprintln!("raylume: {}", describe_target(s, target));
    }
    if args.timeline {
        for m in &s.timeline {
            eprintln!("raylume: timeline {:8.4} s  {}", m.seconds, m.event);
        }
    }
    if s.dropped_samples > 0 {
        eprintln!(
            "warning: {} samples had non-finite or overflowing radiance and were dropped",
            s.dropped_samples
        );
    }

    if let Some(path) = &args.stats
        && let Err(e) = std::fs::write(path, render.stats.to_json())
    {
        let _ = std::fs::remove_file(&args.output);
        return Err(format!("cannot write stats file {}: {e}", path.display()));
    }
    if args.next_event_stage && !render.stats.schedule.contains("next_event") {
        eprintln!(
            "raylume: --next-event-stage did nothing: it applies to the GPU's wavefront schedule \
             with next-event estimation (`--schedule wavefront`, `--estimator nee`)"
        );
    }
    if args.walk_stage.0 == Some(true) && !render.stats.schedule.contains("walk stage") {
        eprintln!(
            "raylume: --walk-stage did nothing: it applies to the GPU's wavefront schedule \
             (`--schedule wavefront`) over the wide BVH, on a GPU with subgroups"
        );
    }
    if args.shadow_stage == Some(true) && !render.stats.schedule.contains("shadow stage") {
        eprintln!(
            "raylume: --shadow-stage did nothing: it applies where the walk stage runs, with \
             next-event estimation (`--schedule wavefront --walk-stage on --estimator nee`)"
        );
    }
    eprintln!("raylume: wrote {}", args.output.display());
    Ok(())
}

/// The line printed before the first batch: what the render will do, each value labelled.
fn settings_line(scene: &str, s: &raylume::RenderStats, capped: bool) -> String {
    let roulette = match s.russian_roulette {
        Some(d) => format!("from segment {d}"),
        None => "off".into(),
    };
    format!(
        "rendering {scene}: backend {} ({}; {}), size {}x{}, spp {}{}, bounces {}, batch {} spp, \
         estimator {}, sampler {}, roulette {roulette}, reorder {}, schedule {}, bvh {} {}, \
         lights {}",
        s.backend.to_uppercase(),
        s.adapter,
        s.backend_reason,
        s.width,
        s.height,
        if capped { "at most " } else { "" },
        s.spp,
        s.max_bounces,
        s.batch_spp,
        s.estimator,
        s.sampler,
        s.reorder,
        s.schedule,
        if s.bvh_preset_chosen {
            format!("{} (chosen for the work)", s.bvh_preset)
        } else {
            s.bvh_preset.clone()
        },
        s.bvh_layout,
        s.lights.describe(),
    )
}

/// `--part I/N`.
fn parse_part(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("--part wants I/N with 1 <= I <= N (e.g. 2/4), not `{s}`");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.trim().parse::<u32>().map_err(|_| bad())?,
        n.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if i == 0 || i > n {
        return Err(bad());
    }
    Ok((i, n))
}

/// `--bvh-preset`: `None` for auto.
#[derive(Clone, Copy, Debug)]
struct Preset(Option<raylume::BvhQuality>);

fn parse_preset(s: &str) -> Result<Preset, String> {
    match s {
        "auto" => Ok(Preset(None)),
        other => other
            .parse::<raylume::BvhQuality>()
            .map(|q| Preset(Some(q)))
            .map_err(|e| e.replace("fastest, fast or quality", "auto, fastest, fast or quality")),
    }
}

/// How often piped progress prints a line: 5 s, or `RAYLUME_PROGRESS_SECS` (the tests use a
/// short one).
fn progress_interval() -> Duration {
    std::env::var("RAYLUME_PROGRESS_SECS")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|v| v.is_finite() && *v >= 0.0)
        .map_or(Duration::from_secs(5), Duration::from_secs_f64)
}

/// Without `XDG_RUNTIME_DIR` the Vulkan loader prints `error: XDG_RUNTIME_DIR is invalid or
/// not set` (twice) when the GPU instance is created, with the same `error:` prefix as real
/// errors. It only wants a private folder for runtime files, so when the variable is unset
/// (or names no folder) the command points it at one of its own: `<tmp>/raylume-runtime-<user>`,
/// created with mode 0700.
fn ensure_runtime_dir() {
    let set = std::env::var_os("XDG_RUNTIME_DIR")
        .is_some_and(|d| !d.is_empty() && Path::new(&d).is_dir());
    if set {
        return;
    }
    let user = std::env::var("USER").unwrap_or_else(|_| "user".into());
    let dir = std::env::temp_dir().join(format!("raylume-runtime-{user}"));
    if std::fs::create_dir_all(&dir).is_err() {
        return;
    }
    #[cfg(unix)]
    {
        // Fails unless this user owns the folder: then leave the variable alone.
        use std::os::unix::fs::PermissionsExt;
        if std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).is_err() {
            return;
        }
    }
    // SAFETY: called first thing in `main`, before any other thread exists, so nothing reads
    // the environment concurrently.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
}

/// The summary of a render with a target error: where it stopped and why.
fn describe_target(s: &raylume::RenderStats, target: f32) -> String {
    let cap = s.spp_cap.unwrap_or(s.spp);
    let batches = s.batches.unwrap_or(0);
    let estimate = match s.estimated_error {
        Some(e) => format!("estimated relative MSE {e:.3e}"),
        None => format!(
            "no estimate: an estimate needs at least 2 batches, and the cap of {cap} spp holds \
             {batches} of {} spp (raise --spp or lower --batch-spp)",
            s.batch_spp
        ),
    };
    if s.target_reached == Some(true) {
        format!(
            "target error {target:.3e}: reached at {} of at most {cap} spp ({batches} batches of \
             {} spp), {estimate}",
            s.spp, s.batch_spp
        )
    } else {
        format!(
            "target error {target:.3e}: not reached, stopped at the cap of {cap} spp ({batches} \
             batches of {} spp), {estimate}",
            s.batch_spp
        )
    }
}

fn main() -> ExitCode {
    let timeline = raylume::Timeline::new();
    ensure_runtime_dir();
    let args = Args::parse();
    match run(args, timeline) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
