//! The error-versus-time study (issue 20, item 5): for each knob that trades accuracy for time,
//! the relative MSE ([`raylume_post::metrics::relative_mse`]) of renders against a converged
//! reference versus the seconds they took, with Mitsuba 3's points on the same axes.
//!
//! ```text
//! # raylume: a reference (rounds of 1024 spp) and every knob of the standard study
//! cargo run --release --example study -- run scene.json --size 128x128 --bounces 10 \
//!     --make-reference 4096 --reference ref.exr --spp 4,16,64,256 --backend cpu --out results.jsonl
//! # Mitsuba: series.py's (or tools/study/mitsuba_series.py's) EXRs and times, scored against
//! # a reference (Mitsuba's own and raylume's: run twice), into the same results file
//! cargo run --release --example study -- mitsuba series.json --exr-dir DIR --reference ref.exr \
//!     --reference-kind own --scene-name bitterli-cornell-box --out results.jsonl
//! # one SVG per knob per scene, and the table (with "what halving the error costs")
//! cargo run --release --example study -- plot results.jsonl --out-dir plots
//! ```
//!
//! **What a point is.** One configuration (a setting of every knob) at one spp, rendered
//! `--repeats` times (3) with the same seed by one [`raylume::Tracer`] (the repeats come in
//! passes over all points, so that on a shared machine a point's best-of-3 samples moments
//! minutes apart); its time is the fastest `Tracer::render` call's wall seconds (BVH build included only where it was not cached: the
//! tracer keeps the BVH of the last geometry, so only the very first render of a scene builds
//! it, and a warm-up render happens before the first timed one; GPU pipelines are created in
//! every call and count). Its error is the relative MSE of that image against the reference,
//! `mean((x - r)^2 / (r^2 + 1e-2))` over all channels. Every configuration uses the same seed
//! (common random numbers: the difference between two knob settings is less noisy than either).
//!
//! **The reference** (`--make-reference SPP`) is rendered in rounds of `--reference-round` spp
//! with seeds far from the test renders', averaged in f64 (memory stays that of one round), with
//! next-event estimation, the independent sampler and no Russian roulette, at the study's
//! bounce count: an unbiased estimate of the same integral every configuration estimates
//! (except the `bounces` knob's, which are biased against it on purpose).
//!
//! **Knobs** (`--knobs`, all by default): `spp` (the baseline alone), `bounces` (bias),
//! `estimator` (plain vs nee), `rr` (Russian roulette start), `sampler` (sobol vs zsobol vs independent),
//! `batch` (samples per batch) and `reorder` (ray sorting, GPU only): each varies one knob of
//! the baseline (`--baseline`, default nee, sobol, rr 5, the tracer's batch size, reorder
//! off), the baseline itself in every plot. `--config NAME:KNOB:key=value,...` adds more.

use std::collections::{BTreeMap, BTreeSet};
use std::fs::{self, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use clap::{Parser, Subcommand};
use plotters::prelude::*;
use raylume::{Backend, Estimator, ReorderPolicy, Sampler, Scene, Tracer};
use serde_json::{Value, json};

#[derive(Parser, Debug)]
#[command(
    name = "study",
    about = "Error versus time: relative MSE against a converged reference versus seconds, per knob"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Renders a scene for every configuration x spp and appends the points to a results file.
    Run(Box<RunArgs>),
    /// Scores Mitsuba 3's EXRs (series.py's) against a reference, with series.py's times.
    Mitsuba(MitsubaArgs),
    /// Draws one log-log SVG per knob per scene from results files and prints the table.
    Plot(PlotArgs),
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    /// The scene (any file Scene::load reads: raylume TOML, glTF, OBJ, Tungsten scene.json).
    scene: PathBuf,
    /// The scene's name in the results (default: the folder name of a `scene.json`, else the
    /// file stem).
    #[arg(long)]
    name: Option<String>,
    /// Image size as WIDTHxHEIGHT (default: the scene's).
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Maximum bounces of the baseline and of the reference (default: the scene's).
    #[arg(long)]
    bounces: Option<u32>,
    /// The reference EXR: read it, or, with --make-reference, write it.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Render a reference of this many spp (in rounds) instead of reading one.
    #[arg(long)]
    make_reference: Option<u32>,
    /// Samples per pixel per reference round.
    #[arg(long, default_value_t = 1024)]
    reference_round: u32,
    /// The spp values of every configuration.
    #[arg(long, value_delimiter = ',', default_value = "4,16,64,256")]
    spp: Vec<u32>,
    /// The standard knobs to study (each varies one knob of the baseline).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "spp,bounces,estimator,rr,sampler,batch,reorder"
    )]
    knobs: Vec<String>,
    /// The baseline's settings, `key=value,...` (keys: estimator, sampler, rr, bounces, batch,
    /// reorder), over nee, sobol, rr 5, the tracer's default batch, reorder off.
    #[arg(long, default_value = "")]
    baseline: String,
    /// Bounce counts of the `bounces` knob (the baseline's is added).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3,5")]
    bounces_list: Vec<u32>,
    /// Russian-roulette starts of the `rr` knob (`off` or a segment number).
    #[arg(long, value_delimiter = ',', default_value = "off,2,8")]
    rr_list: Vec<String>,
    /// Samples per batch of the `batch` knob.
    #[arg(long, value_delimiter = ',', default_value = "1,5,64")]
    batch_list: Vec<u32>,
    /// More configurations: `NAME:KNOB:key=value,...` over the baseline (repeatable).
    #[arg(long = "config")]
    configs: Vec<String>,
    /// auto, gpu or cpu.
    #[arg(long, default_value = "auto")]
    backend: Backend,
    /// Renders per point; the fastest counts.
    #[arg(long, default_value_t = 3)]
    repeats: u32,
    /// The seed of every test render.
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Results, one JSON object a line (appended).
    #[arg(long)]
    out: PathBuf,
    /// The same points as CSV (appended; a header when new).
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Write small PNGs here: the reference and the baseline at each spp.
    #[arg(long)]
    pictures: Option<PathBuf>,
    /// A configuration whose render took longer than this (seconds) is not run at higher spp.
    #[arg(long)]
    max_render_s: Option<f64>,
    /// Start no configuration after this many seconds (from the start of the command).
    #[arg(long)]
    budget_s: Option<f64>,
    /// The raylume commit, for the records (default: $STUDY_COMMIT, else "unknown").
    #[arg(long)]
    commit: Option<String>,
}

#[derive(clap::Args, Debug)]
struct MitsubaArgs {
    /// series.py's JSON (`NAME-mi-series.json`: scene, size, sampler, depth, times by spp).
    series: PathBuf,
    /// The folder of its EXRs (`NAME-mi-SAMPLER-SPP.exr`; default: the JSON's folder).
    #[arg(long)]
    exr_dir: Option<PathBuf>,
    /// The reference to score against.
    #[arg(long)]
    reference: PathBuf,
    /// `own` (Mitsuba's reference) or `raylume` (raylume's): kept in the records.
    #[arg(long, default_value = "own")]
    reference_kind: String,
    /// The scene's name in the results (default: the JSON's `scene`).
    #[arg(long)]
    scene_name: Option<String>,
    /// Results file (appended).
    #[arg(long)]
    out: PathBuf,
    /// CSV (appended).
    #[arg(long)]
    csv: Option<PathBuf>,
    /// What ran it, for the records (e.g. "cuda_ad_rgb on NVIDIA H200").
    #[arg(long)]
    adapter: Option<String>,
}

#[derive(clap::Args, Debug)]
struct PlotArgs {
    /// Results files (JSON lines from `run` and `mitsuba`).
    results: Vec<PathBuf>,
    /// Where the SVGs go (`SCENE-KNOB.svg`).
    #[arg(long)]
    out_dir: PathBuf,
    /// Which of Mitsuba's references its lines are scored against: own or raylume.
    #[arg(long, default_value = "own")]
    mitsuba_reference: String,
    /// Text added to every title (device, date, commit are added from the records).
    #[arg(long, default_value = "")]
    note: String,
    /// The table as Markdown here too.
    #[arg(long)]
    table: Option<PathBuf>,
    /// The time axis: `wall` (seconds of the render call) or `cpu` (CPU seconds of all the
    /// process's threads over the call: steadier than wall time on a machine shared with other
    /// work; raylume's CPU backend only, so Mitsuba's points are left out).
    #[arg(long, default_value = "wall")]
    time: String,
    /// "What halving the error costs" starts from the error at this spp (else the middle point).
    #[arg(long, default_value_t = 256)]
    halve_at: u32,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size `{s}`: use WIDTHxHEIGHT"))?;
    let w: u32 = w.parse().map_err(|_| format!("size `{s}`: bad width"))?;
    let h: u32 = h.parse().map_err(|_| format!("size `{s}`: bad height"))?;
    if w == 0 || h == 0 {
        return Err(format!("size `{s}`: must be at least 1x1"));
    }
    Ok((w, h))
}

// ---------------------------------------------------------------------------------------------
// Knobs
// ---------------------------------------------------------------------------------------------

/// One setting of every knob.
#[derive(Clone, Debug, PartialEq)]
struct Knobs {
    estimator: Estimator,
    sampler: Sampler,
    /// Russian roulette from this path segment on; None: off.
    rr: Option<u32>,
    bounces: u32,
    batch: u32,
    reorder: ReorderPolicy,
    /// NEE toward the environment guided by the learned visibility (`Tracer::environment_guide`).
    guide: bool,
}

fn reorder_name(r: ReorderPolicy) -> &'static str {
    match r {
        ReorderPolicy::Off => "off",
        ReorderPolicy::On => "on",
        ReorderPolicy::Auto => "auto",
    }
}

fn rr_name(rr: Option<u32>) -> String {
    rr.map_or_else(|| "off".into(), |s| s.to_string())
}

impl Knobs {
    fn set(&mut self, key: &str, value: &str) -> Result<(), String> {
        match key {
            "estimator" => self.estimator = value.parse()?,
            "sampler" => self.sampler = value.parse()?,
            "rr" => {
                self.rr = if value == "off" {
                    None
                } else {
                    Some(
                        value
                            .parse()
                            .map_err(|_| format!("rr `{value}`: off or a segment number"))?,
                    )
                }
            }
            "bounces" => {
                self.bounces = value
                    .parse()
                    .map_err(|_| format!("bounces `{value}`: a number"))?
            }
            "batch" => {
                self.batch = value
                    .parse()
                    .map_err(|_| format!("batch `{value}`: a number"))?
            }
            "reorder" => self.reorder = value.parse()?,
            "guide" => {
                self.guide = match value {
                    "on" => true,
                    "off" => false,
                    _ => return Err(format!("guide `{value}`: on or off")),
                }
            }
            _ => {
                return Err(format!(
                    "unknown knob `{key}`: estimator, sampler, rr, bounces, batch, reorder, guide"
                ));
            }
        }
        Ok(())
    }

    fn apply(&mut self, spec: &str) -> Result<(), String> {
        for kv in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| format!("`{kv}`: use key=value"))?;
            self.set(k.trim(), v.trim())?;
        }
        Ok(())
    }

    fn to_json(&self) -> Value {
        json!({
            "estimator": self.estimator.name(),
            "sampler": self.sampler.name(),
            "rr": rr_name(self.rr),
            "bounces": self.bounces,
            "batch": self.batch,
            "reorder": reorder_name(self.reorder),
            "guide": if self.guide { "on" } else { "off" },
        })
    }

    /// The value of `knob` as a short label.
    fn label(&self, knob: &str) -> String {
        match knob {
            "estimator" => format!("estimator {}", self.estimator.name()),
            "sampler" => format!("sampler {}", self.sampler.name()),
            "rr" => format!("rr {}", rr_name(self.rr)),
            "bounces" if self.bounces == 1 => "1 bounce".into(),
            "bounces" => format!("{} bounces", self.bounces),
            "batch" => format!("batch {}", self.batch),
            "reorder" => format!("reorder {}", reorder_name(self.reorder)),
            "guide" => format!("guide {}", if self.guide { "on" } else { "off" }),
            _ => format!(
                "{}, {}, rr {}, {} bounces, batch {}",
                self.estimator.name(),
                self.sampler.name(),
                rr_name(self.rr),
                self.bounces,
                self.batch
            ),
        }
    }

    /// Sets the tracer's knobs (the image size, spp and bounces go on the scene).
    fn configure(&self, tracer: &mut Tracer) -> Result<(), String> {
        tracer.estimator = self.estimator;
        tracer.batch_spp = self.batch;
        tracer.reorder = self.reorder;
        tracer.sampler = self.sampler;
        tracer.russian_roulette = self.rr;
        // Explicit either way (not the library's `None`, which decides by the render's size):
        // every spp of a curve samples the sky alike.
        tracer.environment_guide = Some(self.guide);
        Ok(())
    }
}

/// A named configuration and the knob it studies (`baseline`: every plot's reference line).
#[derive(Clone, Debug)]
struct Config {
    name: String,
    knob: String,
    knobs: Knobs,
}

const KNOBS: [&str; 8] = [
    "spp",
    "bounces",
    "estimator",
    "rr",
    "sampler",
    "batch",
    "reorder",
    "guide",
];

fn standard_configs(args: &RunArgs, base: &Knobs) -> Result<Vec<Config>, String> {
    let mut out = vec![Config {
        name: "baseline".into(),
        knob: "baseline".into(),
        knobs: base.clone(),
    }];
    let mut push = |knob: &str, key: &str, value: &str| -> Result<(), String> {
        let mut k = base.clone();
        k.set(key, value)?;
        if k != *base {
            out.push(Config {
                name: format!("{knob}-{value}"),
                knob: knob.into(),
                knobs: k,
            });
        }
        Ok(())
    };
    for knob in &args.knobs {
        match knob.as_str() {
            "spp" => {}
            "bounces" => {
                for b in &args.bounces_list {
                    push("bounces", "bounces", &b.to_string())?;
                }
            }
            "estimator" => {
                let other = if base.estimator == Estimator::Nee {
                    "plain"
                } else {
                    "nee"
                };
                push("estimator", "estimator", other)?;
            }
            "rr" => {
                for r in &args.rr_list {
                    push("rr", "rr", r)?;
                }
            }
            "sampler" => {
                for other in [Sampler::Sobol, Sampler::ZSobol, Sampler::Independent] {
                    if other != base.sampler {
                        push("sampler", "sampler", other.name())?;
                    }
                }
            }
            "batch" => {
                for b in &args.batch_list {
                    push("batch", "batch", &b.to_string())?;
                }
            }
            "reorder" => push("reorder", "reorder", "on")?,
            "guide" => push("guide", "guide", if base.guide { "off" } else { "on" })?,
            other => {
                return Err(format!("unknown knob `{other}`: use {}", KNOBS.join(", ")));
            }
        }
    }
    for spec in &args.configs {
        let mut parts = spec.splitn(3, ':');
        let (Some(name), Some(knob)) = (parts.next(), parts.next()) else {
            return Err(format!("--config `{spec}`: use NAME:KNOB:key=value,..."));
        };
        let mut k = base.clone();
        k.apply(parts.next().unwrap_or(""))?;
        out.push(Config {
            name: name.into(),
            knob: knob.into(),
            knobs: k,
        });
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Records
// ---------------------------------------------------------------------------------------------

/// Today's date and time in UTC, `YYYY-MM-DD HH:MM`.
fn utc_now() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}",
        rem / 3600,
        (rem % 3600) / 60
    )
}

const CSV_COLUMNS: [&str; 20] = [
    "kind",
    "scene",
    "renderer",
    "config",
    "knob",
    "setting",
    "estimator",
    "sampler",
    "rr",
    "bounces",
    "batch",
    "reorder",
    "spp",
    "seconds",
    "rel_mse",
    "mean_ratio",
    "reference",
    "backend",
    "adapter",
    "commit",
];

/// Appends one record to the JSON-lines file and, if given, a row to the CSV.
fn append(out: &Path, csv: Option<&Path>, rec: &Value) -> Result<(), String> {
    let mut f = OpenOptions::new()
        .create(true)
        .append(true)
        .open(out)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    writeln!(f, "{rec}").map_err(|e| format!("{}: {e}", out.display()))?;
    if let Some(csv) = csv {
        let new = !csv.exists();
        let mut f = OpenOptions::new()
            .create(true)
            .append(true)
            .open(csv)
            .map_err(|e| format!("{}: {e}", csv.display()))?;
        if new {
            writeln!(f, "{}", CSV_COLUMNS.join(",")).map_err(|e| e.to_string())?;
        }
        let field = |k: &str| -> String {
            let v = rec.get(k).or_else(|| rec["knobs"].get(k));
            match v {
                None | Some(Value::Null) => String::new(),
                Some(Value::String(s)) if s.contains([',', '"']) => {
                    format!("\"{}\"", s.replace('"', "\"\""))
                }
                Some(Value::String(s)) => s.clone(),
                Some(v) => v.to_string(),
            }
        };
        let row: Vec<String> = CSV_COLUMNS.iter().map(|k| field(k)).collect();
        writeln!(f, "{}", row.join(",")).map_err(|e| e.to_string())?;
    }
    Ok(())
}

type Image = Vec<[f32; 3]>;

fn load_exr(path: &Path) -> Result<(u32, u32, Image), String> {
    let img = image::open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .into_rgb32f();
    let (w, h) = img.dimensions();
    Ok((w, h, img.pixels().map(|p| p.0).collect()))
}

fn mean(img: &[[f32; 3]]) -> f64 {
    img.iter()
        .map(|p| f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2]))
        .sum::<f64>()
        / (3 * img.len().max(1)) as f64
}

fn score(test: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<(f64, f64), String> {
    let e = raylume_post::metrics::relative_mse(test, reference).map_err(|e| e.to_string())?;
    Ok((e, mean(test) / mean(reference)))
}

/// A small PNG of linear radiance, tone-mapped as `render` writes PNGs.
fn save_picture(path: &Path, pixels: &[[f32; 3]], w: u32, h: u32) -> Result<(), String> {
    raylume::save_png(path, pixels, w, h, &raylume::ToneMap::default()).map_err(|e| e.to_string())
}

// ---------------------------------------------------------------------------------------------
// run
// ---------------------------------------------------------------------------------------------

/// CPU time of this process so far, in seconds: the sum over its threads of the time they ran
/// (`/proc/self/task/*/schedstat`, nanoseconds; Linux only, else None). Threads that have ended
/// are not counted: rayon's pool threads live as long as the process.
fn process_cpu_seconds() -> Option<f64> {
    let mut ns = 0u64;
    for t in fs::read_dir("/proc/self/task").ok()? {
        let path = t.ok()?.path().join("schedstat");
        let text = fs::read_to_string(path).ok()?;
        ns += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(ns as f64 * 1e-9)
}

/// One point of the study, measured once or more.
struct Pending {
    config: usize,
    spp: u32,
    times: Vec<f64>,
    /// CPU seconds of the same renders (every thread of the process), where known.
    cpu_times: Vec<f64>,
    rel_mse: f64,
    mean_ratio: f64,
    stats: raylume::RenderStats,
}

/// Renders `scene` at `spp` with `cfg`'s bounces (the tracer already configured); returns the
/// `Tracer::render` call's wall seconds, the process's CPU seconds over the call, and the render.
fn render_point(
    tracer: &mut Tracer,
    scene: &Scene,
    cfg: &Config,
    spp: u32,
) -> Result<(f64, Option<f64>, raylume::Render), String> {
    let mut s = scene.clone();
    s.render.spp = spp;
    s.render.max_bounces = cfg.knobs.bounces;
    let cpu0 = process_cpu_seconds();
    let t = Instant::now();
    let r = tracer
        .render(&s)
        .map_err(|e| format!("{}: {e}", cfg.name))?;
    let wall = t.elapsed().as_secs_f64();
    let cpu = cpu0.zip(process_cpu_seconds()).map(|(a, b)| b - a);
    Ok((wall, cpu, r))
}

fn scene_name(path: &Path) -> String {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
    if stem == "scene"
        && let Some(dir) = path
            .canonicalize()
            .ok()
            .and_then(|p| p.parent().and_then(|d| d.file_name()).map(|d| d.to_owned()))
    {
        return dir.to_string_lossy().into_owned();
    }
    stem.to_string()
}

fn run(args: &RunArgs) -> Result<(), String> {
    let start = Instant::now();
    let mut scene = Scene::load(&args.scene).map_err(|e| e.to_string())?;
    if let Some((w, h)) = args.size {
        scene.render.width = w;
        scene.render.height = h;
    }
    if let Some(b) = args.bounces {
        scene.render.max_bounces = b;
    }
    let (w, h) = (scene.render.width, scene.render.height);
    let name = args.name.clone().unwrap_or_else(|| scene_name(&args.scene));
    let commit = args
        .commit
        .clone()
        .or_else(|| std::env::var("STUDY_COMMIT").ok())
        .unwrap_or_else(|| "unknown".into());
    let date = utc_now();
    let mut base = Knobs {
        estimator: Estimator::Nee,
        sampler: Sampler::Sobol,
        rr: Some(5),
        bounces: scene.render.max_bounces,
        batch: Tracer::DEFAULT_BATCH_SPP,
        reorder: ReorderPolicy::Off,
        guide: true,
    };
    base.apply(&args.baseline)?;
    let configs = standard_configs(args, &base)?;
    if let Some(dir) = &args.pictures {
        fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }

    let mut tracer = Tracer::new(args.backend);
    tracer.bloom = false;
    // One tree for every point (the library would choose a cheaper preset for the few-spp
    // points, and their times would then mix BVH qualities): Quality, built once and cached.
    tracer.bvh_quality = Some(raylume::BvhQuality::Quality);

    // The reference: read, or rendered in rounds (and saved where --reference says).
    let reference: Image = match args.make_reference {
        Some(total) => {
            let round = args.reference_round.clamp(1, total.max(1));
            let rounds = total.div_ceil(round);
            let knobs = Knobs {
                estimator: Estimator::Nee,
                sampler: Sampler::Independent,
                rr: None,
                ..base.clone()
            };
            knobs.configure(&mut tracer)?;
            let mut acc = vec![[0.0f64; 3]; (w * h) as usize];
            let mut s = scene.clone();
            s.render.spp = round;
            s.render.max_bounces = base.bounces;
            let t = Instant::now();
            let mut adapter = String::new();
            for i in 0..rounds {
                tracer.seed = Some(1_000_003 + 7919 * i);
                let r = tracer.render(&s).map_err(|e| e.to_string())?;
                for (a, p) in acc.iter_mut().zip(&r.pixels) {
                    for c in 0..3 {
                        a[c] += f64::from(p[c]);
                    }
                }
                adapter = r.stats.adapter.clone();
                eprintln!(
                    "reference {name}: round {}/{rounds} ({round} spp) done, {:.1} s",
                    i + 1,
                    t.elapsed().as_secs_f64()
                );
            }
            let img: Image = acc
                .iter()
                .map(|a| a.map(|v| (v / f64::from(rounds)) as f32))
                .collect();
            let seconds = t.elapsed().as_secs_f64();
            if let Some(p) = &args.reference {
                raylume::save_exr(p, &img, w, h).map_err(|e| e.to_string())?;
                eprintln!("reference written to {}", p.display());
            } else {
                eprintln!("reference not saved (no --reference path)");
            }
            append(
                &args.out,
                None,
                &json!({
                    "kind": "reference", "scene": name, "renderer": "raylume",
                    "width": w, "height": h, "spp": rounds * round, "round_spp": round,
                    "seconds": seconds, "knobs": knobs.to_json(), "backend": format!("{:?}", args.backend).to_lowercase(),
                    "adapter": adapter, "commit": commit, "date": date,
                }),
            )?;
            img
        }
        None => {
            let p = args
                .reference
                .as_ref()
                .ok_or("give --reference PATH, or --make-reference SPP")?;
            let (rw, rh, img) = load_exr(p)?;
            if (rw, rh) != (w, h) {
                return Err(format!(
                    "the reference {} is {rw}x{rh}, the renders {w}x{h}",
                    p.display()
                ));
            }
            img
        }
    };
    if let Some(dir) = &args.pictures {
        save_picture(&dir.join(format!("{name}-reference.png")), &reference, w, h)?;
    }

    // A warm-up render (BVH build, GPU context, pipelines' first compilation): not timed.
    {
        if let Err(e) = base.configure(&mut tracer) {
            eprintln!("warm-up with the reference's knobs: {e}");
        }
        let mut s = scene.clone();
        s.render.spp = 1;
        tracer.seed = Some(args.seed);
        tracer.render(&s).map_err(|e| e.to_string())?;
    }

    let mut spps = args.spp.clone();
    spps.sort_unstable();
    spps.dedup();
    let past_budget = || {
        args.budget_s
            .is_some_and(|b| start.elapsed().as_secs_f64() > b)
    };
    // First pass: every configuration x spp once, scored (the image is the same in every
    // repeat: same seed). Then the repeats, pass after pass over all the points, so that a
    // point's best-of-N samples several moments of a shared machine's load.
    let mut points: Vec<Pending> = Vec::new();
    for (ci, cfg) in configs.iter().enumerate() {
        if past_budget() {
            eprintln!(
                "SKIPPED {name} {}: past --budget-s ({:.0} s)",
                cfg.name,
                start.elapsed().as_secs_f64()
            );
            continue;
        }
        if let Err(e) = cfg.knobs.configure(&mut tracer) {
            eprintln!("SKIPPED {name} {}: {e}", cfg.name);
            continue;
        }
        tracer.seed = Some(args.seed);
        for &spp in &spps {
            let (secs, cpu, r) = render_point(&mut tracer, &scene, cfg, spp)?;
            let (rel_mse, mean_ratio) = score(&r.pixels, &reference)?;
            println!(
                "{name} {:<20} {spp:>6} spp {secs:>9.4} s  rel MSE {rel_mse:.4e}  mean x{mean_ratio:.4}  (repeat 1)",
                cfg.name
            );
            if let (Some(dir), "baseline") = (&args.pictures, cfg.name.as_str()) {
                save_picture(
                    &dir.join(format!("{name}-baseline-{spp}spp.png")),
                    &r.pixels,
                    w,
                    h,
                )?;
            }
            points.push(Pending {
                config: ci,
                spp,
                times: vec![secs],
                cpu_times: cpu.into_iter().collect(),
                rel_mse,
                mean_ratio,
                stats: r.stats,
            });
            if args.max_render_s.is_some_and(|m| secs > m) {
                eprintln!(
                    "{name} {}: {secs:.1} s at {spp} spp, past --max-render-s: no higher spp",
                    cfg.name
                );
                break;
            }
        }
    }
    'repeats: for rep in 1..args.repeats.max(1) {
        let mut current = None;
        for p in points.iter_mut() {
            if past_budget() {
                eprintln!("{name}: past --budget-s: repeat {} cut short", rep + 1);
                break 'repeats;
            }
            let cfg = &configs[p.config];
            if current != Some(p.config) {
                cfg.knobs.configure(&mut tracer)?;
                tracer.seed = Some(args.seed);
                current = Some(p.config);
            }
            let (secs, cpu, _) = render_point(&mut tracer, &scene, cfg, p.spp)?;
            p.times.push(secs);
            p.cpu_times.extend(cpu);
        }
        eprintln!(
            "{name}: repeat {} of every point done ({:.0} s)",
            rep + 1,
            start.elapsed().as_secs_f64()
        );
    }
    for p in &points {
        let cfg = &configs[p.config];
        let seconds = p.times.iter().copied().fold(f64::INFINITY, f64::min);
        let cpu_s = (p.cpu_times.len() == p.times.len())
            .then(|| p.cpu_times.iter().copied().fold(f64::INFINITY, f64::min));
        let st = &p.stats;
        let rec = json!({
            "kind": "point", "scene": name, "renderer": "raylume",
            "config": cfg.name, "knob": cfg.knob, "setting": cfg.knobs.label(&cfg.knob),
            "knobs": cfg.knobs.to_json(), "spp": p.spp, "seconds": seconds, "times": p.times, "cpu_s": cpu_s, "cpu_times": p.cpu_times,
            "rel_mse": p.rel_mse, "mean_ratio": p.mean_ratio, "reference": "own",
            "width": w, "height": h, "backend": st.backend, "adapter": st.adapter,
            "trace_s": st.seconds.trace, "upload_s": st.seconds.upload, "bvh_s": st.seconds.bvh,
            "stages": st.seconds, "bvh_cached": st.bvh_cached, "scene_cached": st.scene_cached, "schedule": st.schedule, "reorder_run": st.reorder,
            "batch_run": st.batch_spp, "rays": st.rays_traced, "commit": commit, "date": date,
        });
        append(&args.out, args.csv.as_deref(), &rec)?;
        println!(
            "{name} {:<20} {:>6} spp {seconds:>9.4} s (best of {})  rel MSE {:.4e}",
            cfg.name,
            p.spp,
            p.times.len(),
            p.rel_mse
        );
    }
    eprintln!(
        "{name}: done in {:.1} s (results in {})",
        start.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// mitsuba
// ---------------------------------------------------------------------------------------------

fn mitsuba(args: &MitsubaArgs) -> Result<(), String> {
    let text =
        fs::read_to_string(&args.series).map_err(|e| format!("{}: {e}", args.series.display()))?;
    let series: Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", args.series.display()))?;
    let src_scene = series["scene"]
        .as_str()
        .ok_or("series JSON: no `scene`")?
        .to_string();
    let sampler = series["sampler"]
        .as_str()
        .unwrap_or("independent")
        .to_string();
    let depth = series["depth"].as_u64().unwrap_or(11);
    let name = args.scene_name.clone().unwrap_or_else(|| src_scene.clone());
    let dir = args.exr_dir.clone().unwrap_or_else(|| {
        args.series
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
    });
    let (rw, rh, reference) = load_exr(&args.reference)?;
    let times = series["times"]
        .as_object()
        .ok_or("series JSON: no `times`")?;
    let mut points: Vec<(u32, f64)> = times
        .iter()
        .filter_map(|(k, v)| Some((k.parse().ok()?, v.as_f64()?)))
        .collect();
    points.sort_by_key(|p| p.0);
    let adapter = args
        .adapter
        .clone()
        .or_else(|| series["variant"].as_str().map(String::from))
        .unwrap_or_else(|| "mitsuba".into());
    let date = utc_now();
    for (spp, seconds) in points {
        let exr = dir.join(format!("{src_scene}-mi-{sampler}-{spp}.exr"));
        let (w, h, img) = load_exr(&exr)?;
        if (w, h) != (rw, rh) {
            return Err(format!(
                "{} is {w}x{h}, the reference {rw}x{rh}",
                exr.display()
            ));
        }
        let (rel_mse, mean_ratio) = score(&img, &reference)?;
        let rec = json!({
            "kind": "point", "scene": name, "renderer": "mitsuba",
            "config": format!("mitsuba-{sampler}"), "knob": "mitsuba",
            "setting": format!("Mitsuba 3 {sampler}"),
            "knobs": {"sampler": sampler, "bounces": depth.saturating_sub(1), "estimator": "path (nee, mis, rr 5)"},
            "spp": spp, "seconds": seconds, "rel_mse": rel_mse, "mean_ratio": mean_ratio,
            "reference": args.reference_kind, "reference_file": args.reference.file_name().map(|f| f.to_string_lossy().into_owned()),
            "width": w, "height": h, "backend": "mitsuba", "adapter": adapter,
            "commit": "", "date": date,
        });
        append(&args.out, args.csv.as_deref(), &rec)?;
        println!(
            "{name} mitsuba-{sampler:<12} {spp:>6} spp {seconds:>9.4} s  rel MSE {rel_mse:.4e}  mean x{mean_ratio:.4}  (vs {} reference)",
            args.reference_kind
        );
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// plot
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Debug)]
struct Point {
    spp: u32,
    seconds: f64,
    rel_mse: f64,
}

#[derive(Clone, Debug)]
struct Line {
    renderer: String,
    config: String,
    knob: String,
    setting: String,
    points: Vec<Point>,
}

/// Per scene: its lines, by (renderer, config, reference), and what ran them.
#[derive(Default, Debug)]
struct SceneData {
    lines: BTreeMap<(String, String, String), Line>,
    adapters: BTreeSet<String>,
    commits: BTreeSet<String>,
    dates: BTreeSet<String>,
    size: String,
    reference_spp: Option<u64>,
}

/// Reads the points of `paths`, with their time from `time_key` (`seconds` or `cpu_s`: points
/// without it are left out).
fn read_results(paths: &[PathBuf], time_key: &str) -> Result<BTreeMap<String, SceneData>, String> {
    let mut scenes: BTreeMap<String, SceneData> = BTreeMap::new();
    for p in paths {
        let text = fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let v: Value = serde_json::from_str(line)
                .map_err(|e| format!("{}:{}: {e}", p.display(), i + 1))?;
            let s = |k: &str| v[k].as_str().unwrap_or("").to_string();
            let sd = scenes.entry(s("scene")).or_default();
            if v["kind"] == "reference" {
                sd.reference_spp = v["spp"].as_u64();
                continue;
            }
            if v["kind"] != "point" {
                continue;
            }
            let (Some(spp), Some(seconds), Some(rel_mse)) = (
                v["spp"].as_u64(),
                v[time_key].as_f64(),
                v["rel_mse"].as_f64(),
            ) else {
                continue;
            };
            let renderer = s("renderer");
            if renderer == "raylume" {
                sd.adapters.insert(s("adapter"));
                if !s("commit").is_empty() {
                    sd.commits.insert(s("commit"));
                }
                sd.size = format!("{}x{}", v["width"], v["height"]);
            } else {
                sd.adapters.insert(format!("Mitsuba {}", s("adapter")));
            }
            if let Some(d) = v["date"].as_str() {
                sd.dates.insert(d.get(..10).unwrap_or(d).to_string());
            }
            let key = (renderer.clone(), s("config"), s("reference"));
            let l = sd.lines.entry(key).or_insert_with(|| Line {
                renderer,
                config: s("config"),
                knob: s("knob"),
                setting: match s("setting").as_str() {
                    "1 bounces" => "1 bounce".into(),
                    other => other.into(),
                },
                points: Vec::new(),
            });
            // A later record of the same point replaces an earlier one.
            l.points.retain(|q| u64::from(q.spp) != spp);
            l.points.push(Point {
                spp: spp as u32,
                seconds,
                rel_mse,
            });
        }
    }
    for sd in scenes.values_mut() {
        for l in sd.lines.values_mut() {
            l.points.sort_by_key(|p| p.spp);
        }
    }
    Ok(scenes)
}

/// Seconds at which the curve (sorted by spp) reaches `target`, interpolated linearly in
/// log-log between the points around it, or extrapolated from the last two points' slope
/// (`true`: extrapolated).
fn time_at(points: &[Point], target: f64) -> Option<(f64, bool)> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.seconds > 0.0 && p.rel_mse > 0.0)
        .map(|p| (p.seconds.ln(), p.rel_mse.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let y = target.ln();
    for win in pts.windows(2) {
        let ((x0, y0), (x1, y1)) = (win[0], win[1]);
        if (y0 >= y && y >= y1) || (y0 <= y && y <= y1) {
            if (y1 - y0).abs() < 1e-12 {
                return Some((x0.exp(), false));
            }
            return Some(((x0 + (y - y0) * (x1 - x0) / (y1 - y0)).exp(), false));
        }
    }
    let ((x0, y0), (x1, y1)) = if y < pts[pts.len() - 1].1 {
        (pts[pts.len() - 2], pts[pts.len() - 1])
    } else {
        (pts[0], pts[1])
    };
    if (y1 - y0).abs() < 1e-12 || (y1 - y0) * (x1 - x0) >= 0.0 {
        return None; // the error does not fall with time there
    }
    Some(((x0 + (y - y0) * (x1 - x0) / (y1 - y0)).exp(), true))
}

/// The log-log slope d ln(rel MSE) / d ln(seconds) of the last two points.
fn last_slope(points: &[Point]) -> Option<f64> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let (a, b) = (&points[n - 2], &points[n - 1]);
    let dx = (b.seconds / a.seconds).ln();
    (dx.abs() > 1e-12).then(|| (b.rel_mse / a.rel_mse).ln() / dx)
}

/// What halving the error costs along a line: the time ratio t(e/2) / t(e), where e is the
/// error of the point at `at_spp` (else the middle point).
fn halving(points: &[Point], at_spp: u32) -> Option<(f64, f64, u32, bool)> {
    let p = points
        .iter()
        .find(|p| p.spp == at_spp)
        .or_else(|| points.get(points.len() / 2))?;
    let (t0, x0) = time_at(points, p.rel_mse)?;
    let (t1, x1) = time_at(points, p.rel_mse / 2.0)?;
    Some((t1 / t0, p.rel_mse, p.spp, x0 || x1))
}

/// Tick values for a log axis over `lo..hi`: 1-2-5 per decade when the axis spans at most four
/// decades, else the powers of ten.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let steps: &[f64] = if b - a <= 4 { &[1.0, 2.0, 5.0] } else { &[1.0] };
    (a..=b)
        .flat_map(|e| steps.iter().map(move |m| m * 10f64.powi(e)))
        .filter(|v| *v >= lo && *v <= hi)
        .collect()
}

/// An axis label in seconds: 0.002, 0.05, 0.3, 1, 20.
fn seconds_label(v: f64) -> String {
    if v >= 1.0 {
        format!("{v:.0}")
    } else {
        let digits = (-v.log10().floor()) as usize;
        format!("{v:.digits$}")
    }
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
];
const MITSUBA_COLOURS: [RGBColor; 3] = [
    RGBColor(60, 60, 60),
    RGBColor(150, 150, 150),
    RGBColor(188, 189, 34),
];

fn draw_plot(
    path: &Path,
    title: &str,
    x_desc: &str,
    lines: &[(&Line, bool)], // (line, is Mitsuba)
) -> Result<(), String> {
    let all: Vec<&Point> = lines.iter().flat_map(|(l, _)| &l.points).collect();
    let xs = all.iter().map(|p| p.seconds).filter(|v| *v > 0.0);
    let ys = all.iter().map(|p| p.rel_mse).filter(|v| *v > 0.0);
    let (xmin, xmax) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (ymin, ymax) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if !xmin.is_finite() || !ymin.is_finite() {
        return Err(format!("{}: no positive points", path.display()));
    }
    let root = SVGBackend::new(path, (900, 620)).into_drawing_area();
    let e = |e: DrawingAreaErrorKind<_>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 17))
        .margin(14)
        .x_label_area_size(48)
        .y_label_area_size(78)
        .build_cartesian_2d(
            (xmin / 1.5..xmax * 1.5)
                .log_scale()
                .with_key_points(ticks(xmin / 1.5, xmax * 1.5))
                .with_light_points(Vec::new()),
            (ymin / 2.0..ymax * 2.0)
                .log_scale()
                .with_key_points(ticks(ymin / 2.0, ymax * 2.0))
                .with_light_points(Vec::new()),
        )
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("relative MSE vs converged reference")
        .x_label_formatter(&|v| seconds_label(*v))
        .y_label_formatter(&|v| {
            if (1.0..10.0).contains(v) {
                format!("{v:.0}")
            } else {
                format!("{v:.0e}")
            }
        })
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(246, 246, 246))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()
        .map_err(e)?;
    let (mut ci, mut mi) = (0, 0);
    for (l, is_mitsuba) in lines {
        let pts: Vec<(f64, f64)> = l
            .points
            .iter()
            .filter(|p| p.seconds > 0.0 && p.rel_mse > 0.0)
            .map(|p| (p.seconds, p.rel_mse))
            .collect();
        let label = if *is_mitsuba {
            l.setting.clone()
        } else if l.knob == "baseline" {
            format!("raylume {} (baseline)", l.setting)
        } else {
            format!("raylume {}", l.setting)
        };
        if *is_mitsuba {
            let c = MITSUBA_COLOURS[mi % MITSUBA_COLOURS.len()];
            mi += 1;
            let style = c.stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new(pts.clone(), 7, 4, style))
                .map_err(e)?
                .label(label)
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (7, 0)], c.stroke_width(2))
                        + PathElement::new(vec![(11, 0), (18, 0)], c.stroke_width(2))
                });
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(x, y)| TriangleMarker::new((x, y), 4, c.filled())),
                )
                .map_err(e)?;
        } else {
            let c = COLOURS[ci % COLOURS.len()];
            ci += 1;
            let width = if l.knob == "baseline" { 3 } else { 2 };
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(width)))
                .map_err(e)?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(width))
                });
            chart
                .draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 3, c.filled())))
                .map_err(e)?;
        }
        // spp beside the points of the baseline and of Mitsuba's first line.
        if l.knob == "baseline" || (*is_mitsuba && mi == 1) {
            let c = if *is_mitsuba {
                MITSUBA_COLOURS[0]
            } else {
                COLOURS[0]
            };
            chart
                .draw_series(
                    l.points
                        .iter()
                        .filter(|p| p.seconds > 0.0 && p.rel_mse > 0.0)
                        .map(|p| {
                            EmptyElement::at((p.seconds, p.rel_mse))
                                + Text::new(
                                    format!("{} spp", p.spp),
                                    (6, 2),
                                    ("sans-serif", 11).into_font().color(&c),
                                )
                        }),
                )
                .map_err(e)?;
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

fn plot(args: &PlotArgs) -> Result<(), String> {
    let (time_key, x_desc) = match args.time.as_str() {
        "wall" => (
            "seconds",
            "seconds (wall time of one render call, best of 3)",
        ),
        "cpu" => (
            "cpu_s",
            "CPU seconds of one render call (all threads; best of 3)",
        ),
        t => return Err(format!("--time {t}: use wall or cpu")),
    };
    let scenes = read_results(&args.results, time_key)?;
    fs::create_dir_all(&args.out_dir).map_err(|e| format!("{}: {e}", args.out_dir.display()))?;
    let mut table = String::new();
    let mut files = Vec::new();
    for (scene, sd) in &scenes {
        let raylume: Vec<&Line> = sd
            .lines
            .iter()
            .filter(|((r, _, refk), _)| r == "raylume" && refk == "own")
            .map(|(_, l)| l)
            .collect();
        let mitsuba: Vec<&Line> = sd
            .lines
            .iter()
            .filter(|((r, _, refk), _)| r == "mitsuba" && *refk == args.mitsuba_reference)
            .map(|(_, l)| l)
            .collect();
        let Some(baseline) = raylume.iter().find(|l| l.knob == "baseline").copied() else {
            eprintln!("{scene}: no baseline configuration: no plots");
            continue;
        };
        let adapters: Vec<&str> = sd.adapters.iter().map(String::as_str).collect();
        let raylume_adapter = adapters
            .iter()
            .find(|a| !a.starts_with("Mitsuba"))
            .copied()
            .unwrap_or("?");
        let commits: Vec<&str> = sd.commits.iter().map(String::as_str).collect();
        let dates: Vec<&str> = sd.dates.iter().map(String::as_str).collect();
        let subtitle = format!(
            "{} | {} | {} | raylume {}{}",
            sd.size,
            raylume_adapter,
            dates.join(", "),
            commits.join(", "),
            if args.note.is_empty() {
                String::new()
            } else {
                format!(" | {}", args.note)
            }
        );
        for knob in KNOBS {
            let mut lines: Vec<(&Line, bool)> = vec![(baseline, false)];
            lines.extend(
                raylume
                    .iter()
                    .filter(|l| l.knob == knob && knob != "spp")
                    .map(|l| (*l, false)),
            );
            if knob != "spp" && lines.len() == 1 {
                continue; // this knob was not run here
            }
            lines.extend(mitsuba.iter().map(|l| (*l, true)));
            let suffix = if args.time == "cpu" { "-cpu" } else { "" };
            let path = args.out_dir.join(format!("{scene}-{knob}{suffix}.svg"));
            let title = format!("{scene}: {knob}  ({subtitle})");
            draw_plot(&path, &title, x_desc, &lines)?;
            files.push(path);
        }

        // The table.
        use std::fmt::Write as _;
        let _ = writeln!(
            table,
            "\n### {scene} ({}; raylume on {raylume_adapter}; reference {} spp; {}; commit {})\n",
            sd.size,
            sd.reference_spp
                .map_or_else(|| "?".into(), |s| s.to_string()),
            dates.join(", "),
            commits.join(", ")
        );
        let _ = writeln!(table, "Time: {x_desc}.\n");
        let _ = writeln!(
            table,
            "| renderer | config | setting | spp | seconds | relative MSE | MSE x seconds |"
        );
        let _ = writeln!(table, "|---|---|---|---:|---:|---:|---:|");
        let mut ordered: Vec<&Line> = vec![baseline];
        ordered.extend(raylume.iter().filter(|l| l.knob != "baseline"));
        ordered.extend(mitsuba.iter());
        for l in &ordered {
            for p in &l.points {
                let _ = writeln!(
                    table,
                    "| {} | {} | {} | {} | {:.4} | {:.3e} | {:.3e} |",
                    l.renderer,
                    l.config,
                    l.setting,
                    p.spp,
                    p.seconds,
                    p.rel_mse,
                    p.rel_mse * p.seconds
                );
            }
        }
        let _ = writeln!(
            table,
            "\n**What halving the error costs** (time ratio t(e/2) / t(e), interpolated in \
             log-log along each spp curve from the error e at {} spp; slope = d ln(rel MSE) / \
             d ln(seconds) over the last two points, -1 for pure Monte Carlo):\n",
            args.halve_at
        );
        let _ = writeln!(
            table,
            "| line | e (at spp) | time for e/2 / time for e | slope |"
        );
        let _ = writeln!(table, "|---|---:|---:|---:|");
        for l in std::iter::once(&baseline).chain(mitsuba.iter()) {
            let h = halving(&l.points, args.halve_at);
            let slope = last_slope(&l.points);
            let _ = writeln!(
                table,
                "| {} {} | {} | {} | {} |",
                l.renderer,
                l.setting,
                h.map_or("-".into(), |(_, e, spp, _)| format!("{e:.3e} ({spp})")),
                h.map_or("-".into(), |(r, _, _, x)| format!(
                    "{r:.2}x{}",
                    if x { " (extrapolated)" } else { "" }
                )),
                slope.map_or("-".into(), |s| format!("{s:.2}"))
            );
        }
        // Equal-error time against Mitsuba's lines at 256 spp (issue 20's criterion).
        for m in &mitsuba {
            if let Some(p) = m.points.iter().find(|p| p.spp == 256)
                && let Some((t, x)) = time_at(&baseline.points, p.rel_mse)
            {
                let _ = writeln!(
                    table,
                    "\nraylume's baseline reaches {}'s 256-spp error ({:.3e}, {:.4} s) in \
                         {t:.4} s{}: {:.2}x Mitsuba's time.",
                    m.setting,
                    p.rel_mse,
                    p.seconds,
                    if x { " (extrapolated)" } else { "" },
                    t / p.seconds
                );
            }
        }
        // Mitsuba against the other reference, and the two references against each other.
        let others: Vec<&Line> = sd
            .lines
            .iter()
            .filter(|((r, _, refk), _)| r == "mitsuba" && *refk != args.mitsuba_reference)
            .map(|(_, l)| l)
            .collect();
        if !others.is_empty() {
            let _ = writeln!(
                table,
                "\nMitsuba's renders scored against the other reference (not plotted):\n"
            );
            let _ = writeln!(table, "| line | against | spp | seconds | relative MSE |");
            let _ = writeln!(table, "|---|---|---:|---:|---:|");
            for ((_, _, refk), l) in sd
                .lines
                .iter()
                .filter(|((r, _, refk), _)| r == "mitsuba" && *refk != args.mitsuba_reference)
            {
                for p in &l.points {
                    let _ = writeln!(
                        table,
                        "| {} | {refk} | {} | {:.4} | {:.3e} |",
                        l.setting, p.spp, p.seconds, p.rel_mse
                    );
                }
            }
        }
    }
    println!("{table}");
    if let Some(t) = &args.table {
        fs::write(t, &table).map_err(|e| format!("{}: {e}", t.display()))?;
    }
    for f in &files {
        eprintln!("wrote {}", f.display());
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match &cli.cmd {
        Cmd::Run(a) => run(a),
        Cmd::Mitsuba(a) => mitsuba(a),
        Cmd::Plot(a) => plot(a),
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("study: {e}");
            ExitCode::FAILURE
        }
    }
}
