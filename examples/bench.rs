//! The paper's Table 1, remade: every scene at 1000x1000, 10 bounces, 1/10/100 spp, timing
//! the ray-tracing phase (GPU timestamps where the adapter has them), for every schedule and
//! reorder policy asked for. Prints a Markdown table of every run, the Table-1 pivot (one row
//! per scene and spp: each configuration's time, `auto`'s choice and how far it is from the
//! better of `on` and `off`), and for `on` the per-bounce `propagate`, sort and permute times
//! next to the unsorted wavefront's (where sorting pays); optionally writes JSON.
//!
//! ```text
//! cargo run --release --example bench -- --backend gpu \
//!     --schedule megakernel,wavefront --reorder off,on,auto --reorder-mode index,permute \
//!     scenes/*.toml scenes/living-room/scene.json
//! ```
//!
//! `off` runs once per schedule; `on` runs the wavefront once per reorder mode and key width
//! (whatever the schedule); `auto` runs once (its first candidate is the first schedule
//! listed, its sorted candidates use the first key width). Before
//! timing `auto` at a sample count, the bench renders until `auto` has decided (at most 30
//! renders: each exploring render measures one candidate, whole) and reports
//! those renders separately (`auto_exploring_s` in the JSON): the table times the decided
//! `auto`, as a user re-rendering a scene gets it.
//!
//! Each sample count starts with `--warmup-seconds` of untimed renders; each cell is the best
//! of `--repeat` renders per configuration (more for short cells, until
//! `--min-seconds` of renders per configuration, at most 30), taken in rounds that go through
//! every configuration once, so that a drift of the machine over the run touches all alike.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[path = "support/scene_name.rs"]
mod support;
use support::scene_name;

use clap::Parser;
use raylume::{Backend, DepthSeconds, ReorderMode, ReorderPolicy, Scene, Schedule, Tracer};
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
    /// Comma-separated reorder policies to time (off, on, auto).
    #[arg(long, default_value = "off", value_delimiter = ',')]
    reorder: Vec<ReorderPolicy>,
    /// Comma-separated sorting modes `on` is timed with (index, permute).
    #[arg(long, default_value = "index", value_delimiter = ',', value_parser = parse_mode)]
    reorder_mode: Vec<ReorderMode>,
    /// Comma-separated key widths `on` is timed with (the top bits of the 30-bit key sorted:
    /// 30 = the paper's whole key, 4 radix passes; 16 = 2 passes). `auto` uses the first.
    #[arg(long, default_value = "30", value_delimiter = ',')]
    reorder_bits: Vec<u32>,
    /// Comma-separated schedules `off` is timed with (persistent, megakernel, wavefront);
    /// persistent when not given (the library's default chooses per render: bench always
    /// sets one).
    #[arg(long, default_value = "persistent", value_delimiter = ',')]
    schedule: Vec<Schedule>,
    /// Comma-separated BVH layouts every configuration is timed with (wide, binary); the
    /// library's default (wide) when not given.
    #[arg(long, value_delimiter = ',')]
    bvh: Vec<raylume::BvhLayout>,
    /// BVH build preset (fastest, fast or quality). Quality by default: the table times the trace, so
    /// it takes the tree that traces fastest (the library chooses by the work ahead).
    #[arg(long, default_value = "quality")]
    bvh_preset: raylume::BvhQuality,
    /// Comma-separated ways the GPU pipelines are specialised on the scene's features:
    /// composed (the library's default: absent features' code left out of the source),
    /// overrides (the full source, WGSL override constants), generic (every feature compiled
    /// in: the baseline). On the CPU, generic runs the mirror's variant with every feature,
    /// the others the smallest variant holding the scene's (`raylume_kernels::cpu::variant`).
    #[arg(long, default_value = "composed", value_delimiter = ',')]
    specialise: Vec<raylume::Specialisation>,
    /// Comma-separated features (diffuse, glass, spheres, ...): besides each configuration,
    /// one with that feature compiled into the pipelines although the scene lacks it (a
    /// ` +glass` column; a scene that has it runs the same pipeline twice): what a feature
    /// costs when present but unused.
    #[arg(long, value_delimiter = ',', value_parser = parse_feature)]
    extra_feature: Vec<raylume::Feature>,
    /// Samples per pixel per batch (the library's default: 32, fewer where the GPU's buffers
    /// cannot hold them; the paper used 20).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    batch_spp: Option<u32>,
    /// Estimator: plain (the paper's, the default here) or nee (next-event estimation with
    /// MIS). By default with independent random numbers and no Russian roulette, as the paper
    /// (`--sampler`, `--rr-depth` change that).
    #[arg(long, default_value = "plain")]
    estimator: raylume::Estimator,
    /// Random numbers: independent (the paper's, the default here), sobol or zsobol.
    #[arg(long, default_value = "independent")]
    sampler: raylume::Sampler,
    /// The wavefront's light samples in a `next_event` stage of their own (with NEE; see
    /// `Tracer::next_event_stage`).
    #[arg(long)]
    next_event_stage: bool,
    /// Comma-separated: the wavefront without (off, the default) and with (on) its walk stage
    /// (`Tracer::walk_stage`; wide BVH on an adapter with subgroups).
    #[arg(long, default_value = "off", value_delimiter = ',', value_parser = parse_on_off)]
    walk_stage: Vec<bool>,
    /// Comma-separated: with (on, the library's default) and without (off) the wavefront's
    /// shadow stage (`Tracer::shadow_stage`; it runs beside the walk stage with NEE, and
    /// columns without the walk stage or with the plain estimator are run once, without it).
    #[arg(long, default_value = "on", value_delimiter = ',', value_parser = parse_on_off)]
    shadow_stage: Vec<bool>,
    /// Russian roulette from this path segment on (Mitsuba 3's `path` starts at 5), or off
    /// (the paper's, the default here).
    #[arg(long, default_value = "off", value_parser = parse_rr_depth)]
    rr_depth: RrDepth,
    /// With --estimator nee, sample the environment by the learned guide (on) or by its
    /// radiance (off, the default here: Mitsuba's `path`).
    #[arg(long, default_value = "off", value_parser = parse_on_off, action = clap::ArgAction::Set)]
    environment_guide: bool,
    /// 8-bit textures decoded to floats for the GPU (on, the default here: the table times the
    /// trace, and decoded textures trace 1.3-2.8 % faster; the library decides by the work
    /// ahead) or kept as their sRGB codes (off).
    #[arg(long, default_value = "on", value_parser = parse_on_off, action = clap::ArgAction::Set)]
    decode_textures: bool,
    /// Best of at least this many runs per cell (see --min-seconds).
    #[arg(long, default_value_t = 3)]
    repeat: u32,
    /// Short cells repeat (beyond --repeat, up to 30 rounds) until each configuration's
    /// renders add up to this many seconds of `trace`: the best of 3 sub-millisecond renders
    /// varies by more than the few per cent being compared.
    #[arg(long, default_value_t = 0.05)]
    min_seconds: f64,
    /// Seconds of untimed renders (every fixed configuration in turn) before each sample
    /// count's timed renders.
    #[arg(long, default_value_t = 1.0)]
    warmup_seconds: f64,
    /// Write every measurement as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Save the last image of each scene and configuration into this folder (PNG).
    #[arg(long)]
    images: Option<PathBuf>,
}

/// `--rr-depth`: a segment number or `off`.
#[derive(Clone, Copy, Debug)]
struct RrDepth(Option<u32>);

fn parse_on_off(s: &str) -> Result<bool, String> {
    match s.trim() {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("`{s}`: on or off")),
    }
}

fn parse_rr_depth(s: &str) -> Result<RrDepth, String> {
    match s.trim() {
        "off" => Ok(RrDepth(None)),
        d => d
            .parse()
            .map(|d| RrDepth(Some(d)))
            .map_err(|_| format!("`{s}` is not a path segment number or `off`")),
    }
}

fn parse_mode(s: &str) -> Result<ReorderMode, String> {
    match s {
        "index" | "sort-index" => Ok(ReorderMode::SortIndex),
        "permute" | "sort-permute" => Ok(ReorderMode::SortPermute),
        _ => Err(format!("unknown reorder mode `{s}`: use index or permute")),
    }
}

/// One configuration of the tracer the bench times.
#[derive(Clone, Copy, Debug)]
struct Config {
    schedule: Schedule,
    reorder: ReorderPolicy,
    mode: ReorderMode,
    key_bits: u32,
    layout: raylume::BvhLayout,
    /// How the GPU pipelines are specialised (`--specialise`).
    specialisation: raylume::Specialisation,
    /// A feature compiled in although the scene lacks it (`--extra-feature`).
    extra: Option<raylume::Feature>,
    /// The wavefront's walk stage (`--walk-stage`).
    walk_stage: bool,
    /// The wavefront's shadow stage (`--shadow-stage`).
    shadow_stage: bool,
}

impl Config {
    /// Column name: `megakernel`, `wavefront`, `on sort-index`, `on sort-index/16`, `auto`,
    /// with ` wide` after it for the wide BVH layout, ` generic` or ` overrides` when the
    /// pipelines are not specialised the library's default way, ` +walk` with the walk
    /// stage and ` +shadow` with the shadow stage.
    fn name(&self) -> String {
        let bits = if self.key_bits == 30 {
            String::new()
        } else {
            format!("/{}", self.key_bits)
        };
        let base = match self.reorder {
            ReorderPolicy::Off => self.schedule.name().to_string(),
            ReorderPolicy::On => format!("on {}{bits}", self.mode.name()),
            ReorderPolicy::Auto => format!("auto{bits}"),
        };
        let base = match self.layout {
            raylume::BvhLayout::Binary => base,
            raylume::BvhLayout::Wide => format!("{base} wide"),
        };
        let base = if self.specialisation == raylume::Specialisation::default() {
            base
        } else {
            format!("{base} {}", self.specialisation.name())
        };
        let base = match self.extra {
            Some(f) => format!("{base} +{}", f.name()),
            None => base,
        };
        let base = if self.walk_stage {
            format!("{base} +walk")
        } else {
            base
        };
        if self.shadow_stage {
            format!("{base} +shadow")
        } else {
            base
        }
    }
}

#[derive(Serialize)]
struct Row {
    scene: String,
    primitives: usize,
    backend: String,
    adapter: String,
    /// The configuration: `megakernel`, `wavefront`, `on sort-index`, `on sort-permute`, `auto`.
    config: String,
    /// What ran (`RenderStats::schedule`).
    schedule: String,
    /// What the policy did (`RenderStats::reorder`).
    reorder: String,
    /// The key width `on` and `auto` sorted by (0 for `off`).
    key_bits: u32,
    /// The features the GPU pipelines were compiled for (`RenderStats::pipeline_features`):
    /// the scene's, or all of them for `--specialise generic`.
    pipeline_features: Vec<&'static str>,
    /// How they were specialised (`RenderStats::specialisation`).
    specialisation: String,
    /// Seconds the warm-up render of this configuration spent compiling its pipelines for
    /// this scene (0 when another configuration had compiled the same ones; the driver's
    /// shader cache may have made it short).
    pipelines_s: f64,
    spp: u32,
    width: u32,
    height: u32,
    bounces: u32,
    /// Best `trace` seconds (the paper's ray-tracing phase).
    trace_s: f64,
    /// Sorting seconds of that run (`seconds.sort`).
    sort_s: f64,
    /// `total` seconds of that same run (BVH build, upload, trace, post; no loading).
    total_s: f64,
    rays_traced: u64,
    mrays_per_s: f64,
    all_trace_s: Vec<f64>,
    /// `auto` only: the `trace` seconds of the renders before it had decided.
    auto_exploring_s: Vec<f64>,
    /// Per bounce depth of the best run (wavefront batches).
    depths: Vec<DepthSeconds>,
    /// The best run's seconds per GPU pass or CPU stage (`RenderStats::kernel_seconds`: e.g.
    /// the wavefront's `trace_hits`, `propagate`, `trace_shadows`).
    kernel_seconds: Vec<(String, f64)>,
}

fn configs(args: &Args) -> Vec<Config> {
    let layouts = if args.bvh.is_empty() {
        vec![raylume::BvhLayout::default()]
    } else {
        args.bvh.clone()
    };
    let kinds = args.specialise.clone();
    layouts
        .into_iter()
        .flat_map(|layout| {
            configs_of_layout(args)
                .into_iter()
                .map(move |c| Config { layout, ..c })
        })
        .flat_map(|c| {
            kinds.iter().map(move |&specialisation| Config {
                specialisation,
                ..c
            })
        })
        .flat_map(|c| {
            std::iter::once(None)
                .chain(args.extra_feature.iter().map(|f| Some(*f)))
                .map(move |extra| Config { extra, ..c })
        })
        .flat_map(|c| {
            args.walk_stage
                .iter()
                .map(move |&walk_stage| Config { walk_stage, ..c })
        })
        .flat_map(|c| {
            // The shadow stage runs only beside the walk stage and with NEE: elsewhere one
            // column, marked without it, whatever --shadow-stage says.
            let applies = c.walk_stage && args.estimator != raylume::Estimator::Plain;
            let stages = if applies {
                args.shadow_stage.clone()
            } else {
                vec![false]
            };
            stages
                .into_iter()
                .map(move |shadow_stage| Config { shadow_stage, ..c })
        })
        .collect()
}

/// The configurations of `--reorder`, `--schedule`, `--reorder-mode` and `--reorder-bits`
/// (in the default layout; [`configs`] sets each layout).
fn configs_of_layout(args: &Args) -> Vec<Config> {
    let layout = raylume::BvhLayout::default();
    let first = args.schedule.first().copied().unwrap_or_default();
    let first_bits = args.reorder_bits.first().copied().unwrap_or(30);
    let mut out = Vec::new();
    for &reorder in &args.reorder {
        match reorder {
            ReorderPolicy::Off => out.extend(args.schedule.iter().map(|&schedule| Config {
                schedule,
                reorder,
                mode: ReorderMode::Off,
                key_bits: 30,
                layout,
                specialisation: raylume::Specialisation::default(),
                extra: None,
                walk_stage: false,
                shadow_stage: false,
            })),
            ReorderPolicy::On => {
                for &key_bits in &args.reorder_bits {
                    out.extend(args.reorder_mode.iter().map(|&mode| Config {
                        schedule: Schedule::Wavefront,
                        reorder,
                        mode,
                        key_bits,
                        layout,
                        specialisation: raylume::Specialisation::default(),
                        extra: None,
                        walk_stage: false,
                        shadow_stage: false,
                    }))
                }
            }
            ReorderPolicy::Auto => out.push(Config {
                schedule: first,
                reorder,
                mode: ReorderMode::SortIndex,
                key_bits: first_bits,
                layout,
                specialisation: raylume::Specialisation::default(),
                extra: None,
                walk_stage: false,
                shadow_stage: false,
            }),
        }
    }
    out
}

fn parse_feature(s: &str) -> Result<raylume::Feature, String> {
    raylume::Feature::ALL
        .into_iter()
        .find(|f| f.name() == s)
        .ok_or_else(|| format!("unknown feature '{s}'"))
}

/// The most rounds of renders a cell runs to reach `--min-seconds`.
const MAX_ROUNDS: u32 = 30;

/// Sets the tracer up to run `config`.
fn apply(tracer: &mut Tracer, config: &Config) {
    tracer.schedule = Some(config.schedule);
    tracer.reorder = config.reorder;
    if config.reorder == ReorderPolicy::On {
        tracer.reorder_mode = config.mode;
    }
    tracer.reorder_key_bits = config.key_bits;
    tracer.bvh_layout = config.layout;
    tracer.specialisation = config.specialisation;
    tracer.extra_features = raylume::Features::NONE;
    if let Some(f) = config.extra {
        tracer.extra_features.insert(f);
    }
    tracer.walk_stage = Some(config.walk_stage);
    tracer.shadow_stage = config.shadow_stage;
}

fn run(args: Args) -> Result<(), String> {
    let (w, h) = args
        .size
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .ok_or_else(|| format!("bad --size {}", args.size))?;
    let configs = configs(&args);
    let mut rows = Vec::new();
    let mut tracer = Tracer::new(args.backend);
    // The paper's estimator (plain, independent numbers, no Russian roulette), not the
    // library's defaults: Table 1 compares with the paper. `--estimator`, `--sampler` and
    // `--rr-depth` change one part each (Mitsuba's `path`: nee, independent, 4: its default
    // rr_depth 5 counts hits from 1, this segments from 0).
    tracer.paper_estimator();
    tracer.estimator = args.estimator;
    tracer.sampler = args.sampler;
    tracer.next_event_stage = args.next_event_stage;
    tracer.russian_roulette = args.rr_depth.0;
    tracer.environment_guide = Some(args.environment_guide);
    tracer.decode_textures = Some(args.decode_textures);
    tracer.bvh_quality = Some(args.bvh_preset);
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
        // Warm-up, per configuration: compiles pipelines (their seconds kept for the rows),
        // touches every buffer once.
        let mut compiled: Vec<f64> = Vec::with_capacity(configs.len());
        for config in &configs {
            apply(&mut tracer, config);
            scene.render.spp = 1;
            let r = tracer.render(&scene).map_err(|e| e.to_string())?;
            compiled.push(if r.stats.pipelines_cached {
                0.0
            } else {
                r.stats.seconds.pipelines
            });
        }
        for &spp in &args.spp {
            scene.render.spp = spp;
            // Warm-up at this size: rounds of untimed renders of every fixed configuration
            // for --warmup-seconds (on the H100, renders right after a change of render size
            // often ran slow for a while). `auto` is left out: its exploring renders are its warm-up.
            let t_warm = Instant::now();
            // (Not on the CPU, whose renders take seconds and have nothing to settle.)
            let warmup = if args.backend == Backend::Cpu {
                0.0
            } else {
                args.warmup_seconds
            };
            while t_warm.elapsed().as_secs_f64() < warmup {
                for config in configs.iter().filter(|c| c.reorder != ReorderPolicy::Auto) {
                    apply(&mut tracer, config);
                    tracer.render(&scene).map_err(|e| e.to_string())?;
                }
            }
            let mut exploring = vec![Vec::new(); configs.len()];
            for (config, exploring) in configs.iter().zip(&mut exploring) {
                if config.reorder != ReorderPolicy::Auto {
                    continue;
                }
                apply(&mut tracer, config);
                while tracer.auto_decision(&scene).is_none() && exploring.len() < 30 {
                    let r = tracer.render(&scene).map_err(|e| e.to_string())?;
                    exploring.push(r.stats.seconds.trace);
                    if r.stats.backend == "cpu" {
                        break; // the CPU never reorders: nothing to decide
                    }
                }
                match tracer.auto_decision(&scene) {
                    Some(d) => eprintln!(
                        "  auto at {spp} spp decided after {} renders ({}): {}",
                        exploring.len(),
                        exploring
                            .iter()
                            .map(|s| format!("{s:.4}"))
                            .collect::<Vec<_>>()
                            .join(", "),
                        d.summary
                    ),
                    None => eprintln!(
                        "  auto at {spp} spp: no decision after {} renders (the CPU backend \
                         never reorders; on a GPU, more renders would be needed)",
                        exploring.len()
                    ),
                }
            }
            // The repeats go round the configurations (one render of each, then the next
            // round), so that a drift of the machine (clocks, temperature) over the run
            // touches every configuration alike instead of the last one timed.
            let mut best: Vec<Option<raylume::Render>> = configs.iter().map(|_| None).collect();
            let mut all: Vec<Vec<f64>> = vec![Vec::new(); configs.len()];
            let first_pipelines = &compiled;
            let mut rounds = 0;
            while rounds < args.repeat.max(1)
                || (rounds < MAX_ROUNDS
                    && all.iter().any(|a| a.iter().sum::<f64>() < args.min_seconds))
            {
                rounds += 1;
                for (ci, config) in configs.iter().enumerate() {
                    apply(&mut tracer, config);
                    let r = tracer.render(&scene).map_err(|e| e.to_string())?;
                    all[ci].push(r.stats.seconds.trace);
                    if best[ci]
                        .as_ref()
                        .is_none_or(|b| r.stats.seconds.trace < b.stats.seconds.trace)
                    {
                        best[ci] = Some(r);
                    }
                }
            }
            for (ci, config) in configs.iter().enumerate() {
                let best = best[ci].take().expect("repeat >= 1");
                let s = &best.stats;
                eprintln!(
                    "  {} [{}] spp={spp}: trace {:.4} s (sort {:.4} s), total {:.4} s, {:.0} Mrays/s; {}",
                    s.backend,
                    config.name(),
                    s.seconds.trace,
                    s.seconds.sort,
                    s.seconds.total,
                    s.mrays_per_s,
                    s.reorder
                );
                rows.push(Row {
                    scene: path.display().to_string(),
                    primitives: scene.primitive_count(),
                    backend: s.backend.clone(),
                    adapter: s.adapter.clone(),
                    config: config.name(),
                    schedule: s.schedule.clone(),
                    reorder: s.reorder.clone(),
                    key_bits: if config.reorder == ReorderPolicy::Off {
                        0
                    } else {
                        config.key_bits
                    },
                    pipeline_features: s.pipeline_features.clone(),
                    specialisation: s.specialisation.clone(),
                    pipelines_s: first_pipelines[ci],
                    spp,
                    width: w,
                    height: h,
                    bounces: args.bounces,
                    trace_s: s.seconds.trace,
                    sort_s: s.seconds.sort,
                    total_s: s.seconds.total,
                    rays_traced: s.rays_traced,
                    mrays_per_s: s.mrays_per_s,
                    all_trace_s: std::mem::take(&mut all[ci]),
                    auto_exploring_s: std::mem::take(&mut exploring[ci]),
                    depths: s.depth_seconds.clone(),
                    kernel_seconds: s.kernel_seconds.clone(),
                });
                if let Some(dir) = &args.images {
                    let tag = config.name().replace(' ', "-");
                    let out = dir.join(format!(
                        "{}-{}-{tag}-{spp}spp.png",
                        scene_name(path),
                        s.backend
                    ));
                    best.save(&out).map_err(|e| e.to_string())?;
                }
            }
        }
    }
    print_runs(&rows);
    print_pivot(&rows, &configs);
    print_depths(&rows);
    if let Some(p) = &args.json {
        std::fs::write(
            p,
            serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?,
        )
        .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
    }
    Ok(())
}

/// Every run.
fn print_runs(rows: &[Row]) {
    println!(
        "| scene | prims | backend | config | ran | reorder | spp | trace s | sort s | total s | Mrays/s |"
    );
    println!("|---|---:|---|---|---|---|---:|---:|---:|---:|---:|");
    for r in rows {
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {:.0} |",
            r.scene,
            r.primitives,
            r.backend,
            r.config,
            r.schedule,
            r.reorder,
            r.spp,
            r.trace_s,
            r.sort_s,
            r.total_s,
            r.mrays_per_s
        );
    }
    println!();
}

/// Table 1's shape: one row per scene and spp, a column per configuration, then `auto`
/// against the better of `on` and `off` (the `on` runs of auto's key width: the candidates
/// `auto` measures).
fn print_pivot(rows: &[Row], configs: &[Config]) {
    let names: Vec<String> = configs.iter().map(Config::name).collect();
    let mut head = String::from("| scene | prims | spp |");
    let mut rule = String::from("|---|---:|---:|");
    for n in &names {
        head += &format!(" {n} s |");
        rule += "---:|";
    }
    let has_auto = configs.iter().any(|c| c.reorder == ReorderPolicy::Auto);
    if has_auto {
        head += " best of on/off | auto vs best | auto chose |";
        rule += "---|---:|---|";
    }
    println!("{head}");
    println!("{rule}");
    let mut keys: Vec<(&str, u32)> = Vec::new();
    for r in rows {
        if !keys.contains(&(r.scene.as_str(), r.spp)) {
            keys.push((r.scene.as_str(), r.spp));
        }
    }
    for (scene, spp) in keys {
        let of = |name: &str| {
            rows.iter()
                .find(|r| r.scene == scene && r.spp == spp && r.config == name)
        };
        let prims = rows
            .iter()
            .find(|r| r.scene == scene)
            .map_or(0, |r| r.primitives);
        let mut line = format!("| {scene} | {prims} | {spp} |");
        for n in &names {
            line += &match of(n) {
                Some(r) => format!(" {:.4} |", r.trace_s),
                None => " - |".into(),
            };
        }
        if has_auto {
            let auto = rows
                .iter()
                .find(|r| r.scene == scene && r.spp == spp && r.config.starts_with("auto"));
            let best = rows
                .iter()
                .filter(|r| r.scene == scene && r.spp == spp && !r.config.starts_with("auto"))
                .filter(|r| r.key_bits == 0 || auto.is_none_or(|a| a.key_bits == r.key_bits))
                .min_by(|a, b| a.trace_s.total_cmp(&b.trace_s));
            match (best, auto) {
                (Some(b), Some(a)) => {
                    let chose = a
                        .reorder
                        .strip_prefix("auto: ")
                        .unwrap_or(&a.reorder)
                        .split(" (")
                        .next()
                        .unwrap_or("");
                    line += &format!(
                        " {} {:.4} | {:+.1} % | {chose} |",
                        b.config,
                        b.trace_s,
                        (a.trace_s / b.trace_s - 1.0) * 100.0
                    );
                }
                _ => line += " - | - | - |",
            }
        }
        println!("{line}");
    }
    println!();
}

/// For every `on` run at each scene's largest spp: per depth, the unsorted wavefront's
/// `propagate` (with `next_event`, when the render samples lights) against the sorted one
/// plus its sort (and permute): where sorting pays.
fn print_depths(rows: &[Row]) {
    let on: Vec<&Row> = rows
        .iter()
        .filter(|r| r.config.starts_with("on "))
        .collect();
    if on.is_empty() {
        return;
    }
    println!(
        "| scene | spp | config | depth | propagate unsorted s | propagate sorted s | sort s | permute s | saved s |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|");
    for r in on {
        let max_spp = rows
            .iter()
            .filter(|x| x.scene == r.scene)
            .map(|x| x.spp)
            .max()
            .unwrap_or(0);
        if r.spp != max_spp {
            continue;
        }
        let unsorted = rows
            .iter()
            .find(|x| x.scene == r.scene && x.spp == r.spp && x.config == "wavefront");
        for d in &r.depths {
            let off = unsorted
                .and_then(|u| u.depths.iter().find(|x| x.depth == d.depth))
                .map(|x| x.propagate + x.next_event);
            let (off_s, saved) = match off {
                Some(o) => (
                    format!("{o:.5}"),
                    format!(
                        "{:+.5}",
                        o - (d.propagate + d.next_event + d.sort + d.permute)
                    ),
                ),
                None => ("-".into(), "-".into()),
            };
            println!(
                "| {} | {} | {} | {} | {off_s} | {:.5} | {:.5} | {:.5} | {saved} |",
                r.scene,
                r.spp,
                r.config,
                d.depth,
                d.propagate + d.next_event,
                d.sort,
                d.permute
            );
        }
    }
    println!();
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
