//! Merges render parts (`render --part I/N -o part-I.exr`) into the image of one render of all
//! their samples.
//!
//! ```text
//! cargo run --release --example merge -- -o OUT.(exr|png) part-1.exr part-2.exr ...
//! ```
//!
//! The parts must be of one render (the same scene, size, samples per pixel, bounces, seed,
//! estimator, sampler and roulette: their headers say) and their sample ranges must tile
//! every pixel's samples without gap or overlap; otherwise a message says which part is wrong
//! and nothing is written. The merged image equals one render of all the samples within the
//! float-rounding bound of `raylume::merge_bound` (bit for bit for a single part of all of
//! them). `.png` output is tone-mapped as `render`'s (`--exposure`). With `--part`, parts that
//! follow each other are joined into one part instead (a part resumed with more samples).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

#[derive(Parser, Debug)]
#[command(about = "Merge raylume render parts (render --part I/N) into one image")]
struct Args {
    /// The merged image: .exr (linear radiance) or .png (tone-mapped sRGB).
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
    /// Exposure in stops for .png output.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// Write the joined parts as one part (.exr of sums with a header) instead of the image:
    /// the parts need only follow each other, not cover every sample. A part resumed with
    /// more samples: `merge --part -o p.exr p.exr more.exr`.
    #[arg(long)]
    part: bool,
    /// The parts (.exr files written by `render --part`).
    #[arg(required = true)]
    parts: Vec<PathBuf>,
}

fn run(args: &Args) -> Result<String, String> {
    let mut parts = Vec::with_capacity(args.parts.len());
    for p in &args.parts {
        parts.push(raylume::Part::load(p).map_err(|e| e.to_string())?);
    }
    let names: Vec<String> = args.parts.iter().map(|p| p.display().to_string()).collect();
    if args.part {
        let joined = raylume::join(&parts, &names).map_err(|e| e.to_string())?;
        joined.save(&args.output).map_err(|e| e.to_string())?;
        let r = joined.header.samples;
        return Ok(format!(
            "joined {} parts into {} (samples {}..{} of {})",
            parts.len(),
            args.output.display(),
            r.begin,
            r.end,
            joined.header.spp
        ));
    }
    let (header, pixels) = raylume::merge(&parts, &names).map_err(|e| e.to_string())?;
    let render = raylume::Render {
        width: header.width,
        height: header.height,
        pixels,
        stats: raylume::RenderStats::default(),
        tone: raylume_post::ToneMap {
            exposure: args.exposure,
            ..Default::default()
        },
        part: None,
    };
    render.save(&args.output).map_err(|e| e.to_string())?;
    Ok(format!(
        "merged {} parts ({}x{}, {} spp) into {}",
        parts.len(),
        header.width,
        header.height,
        header.spp,
        args.output.display()
    ))
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(msg) => {
            eprintln!("raylume: {msg}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("merge: {e}");
            ExitCode::FAILURE
        }
    }
}
