//! Compares an image with a reference: RMSE, MAE and relative MSE of the linear radiance, and
//! SSIM of the tone-mapped pictures. The tool behind accuracy-versus-time measurements.
//!
//! ```text
//! cargo run --release --example compare -- test.exr reference.exr
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    name = "compare",
    about = "Error of an image against a reference (.exr, .hdr, .png)"
)]
struct Args {
    /// The image to judge.
    test: PathBuf,
    /// The reference (same size).
    reference: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

fn load(path: &PathBuf) -> Result<(u32, u32, Vec<[f32; 3]>), String> {
    let img = image::open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .into_rgb32f();
    let (w, h) = img.dimensions();
    Ok((w, h, img.pixels().map(|p| p.0).collect()))
}

fn run(a: Args) -> Result<(), String> {
    let (w, h, test) = load(&a.test)?;
    let (rw, rh, reference) = load(&a.reference)?;
    if (w, h) != (rw, rh) {
        return Err(format!("sizes differ: {w}x{h} vs {rw}x{rh}"));
    }
    let e = |r: Result<f64, raylume_post::PostError>| r.map_err(|e| e.to_string());
    let rmse = e(raylume_post::rmse(&test, &reference))?;
    let mae = e(raylume_post::mae(&test, &reference))?;
    let rel = e(raylume_post::relative_mse(&test, &reference))?;
    // SSIM compares what a person sees: both tone-mapped the way `render` writes a PNG.
    let tone = raylume_post::ToneMap::default();
    let display = |px: &[[f32; 3]]| -> Result<Vec<[f32; 3]>, String> {
        Ok(tone
            .to_srgb8(px)
            .map_err(|e| e.to_string())?
            .into_iter()
            .map(|p| p.map(|c| f32::from(c) / 255.0))
            .collect())
    };
    let ssim = e(raylume_post::ssim(
        &display(&test)?,
        &display(&reference)?,
        w,
        h,
    ))?;
    if a.json {
        println!(
            "{{\"rmse\": {rmse}, \"mae\": {mae}, \"relative_mse\": {rel}, \"ssim\": {ssim}, \"width\": {w}, \"height\": {h}}}"
        );
    } else {
        println!(
            "{}x{}: RMSE {rmse:.6}, MAE {mae:.6}, relative MSE {rel:.6}, SSIM {ssim:.5}",
            w, h
        );
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
