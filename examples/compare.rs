//! Compares an image with a reference: RMSE, MAE and relative MSE of the linear radiance, SSIM
//! of the tone-mapped pictures, the ratio of the image means and the errors of 8x8-pixel block
//! means, with an estimate of how much of those errors is noise. The tool behind
//! accuracy-versus-time measurements and the agreement harness (`tools/agree/`).
//!
//! ```text
//! cargo run --release --example compare -- test.exr reference.exr
//! cargo run --release --example compare -- a1.exr ref1.exr --test2 a2.exr --reference2 ref2.exr \
//!     --blocks 8 --block-tolerance 0.03 --block-image blocks.png --json
//! ```
//!
//! **Halves and noise.** With `--test2` (an independent render of the test at the same spp,
//! another seed) the test is the mean of the two files; with `--reference2` likewise for the
//! reference; every metric then judges those means. The halves also give the noise: the null
//! image `N = (T1 - T2) / 2 - (R1 - R2) / 2` has the same noise as the difference of the means,
//! `(T1 + T2) / 2 - (R1 + R2) / 2`, but no bias, so the block errors of `R + N` against `R`
//! are what the block errors would be if the two renderers computed the same thing. When the
//! measured block errors are far above those of the null image, the mismatch is real and
//! converged; when they are alike, more samples are needed before judging. With only one
//! pair of halves the null image holds only that side's noise (and says so).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use raylume_post::{BLOCK_FLOOR, BlockErrors};
use serde_json::{Value, json};

#[derive(Parser, Debug)]
#[command(
    name = "compare",
    about = "Error of an image against a reference (.exr, .hdr, .png): RMSE, MAE, relative MSE, \
             SSIM, mean ratio, block-mean errors"
)]
struct Args {
    /// The image to judge.
    test: PathBuf,
    /// The reference (same size).
    reference: PathBuf,
    /// A second, independent render of the test (same spp, another seed): the test becomes the
    /// mean of the two, and their difference measures the test's noise.
    #[arg(long)]
    test2: Option<PathBuf>,
    /// A second, independent render of the reference (same spp, another seed): the reference
    /// becomes the mean of the two, and their difference measures the reference's noise.
    #[arg(long)]
    reference2: Option<PathBuf>,
    /// Block size in pixels for the block-mean statistics (0: none).
    #[arg(long, default_value_t = 8)]
    blocks: u32,
    /// A block is within when its relative error is at most this.
    #[arg(long, default_value_t = 0.03)]
    block_tolerance: f64,
    /// Relative errors of dark blocks are taken against this fraction of the median reference
    /// block mean (per channel) instead of their own mean.
    #[arg(long, default_value_t = BLOCK_FLOOR)]
    block_floor: f64,
    /// How many of the worst blocks to list.
    #[arg(long, default_value_t = 5)]
    worst: usize,
    /// Write a PNG: test | reference (tone-mapped like `render`'s PNGs) | block errors (red:
    /// test brighter, blue: darker; pale within the tolerance, saturated at 4x it).
    #[arg(long)]
    block_image: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Fail (exit status 1, after the report) unless every channel of every pixel is within
    /// `raylume::merge_bound(SPP)` of the reference, relative to it: the bound within which
    /// render parts, merged, or one render split over several GPUs (`--backend gpus`) equal
    /// one render of SPP samples per pixel.
    #[arg(long, value_name = "SPP")]
    merge_bound: Option<u32>,
}

type Image = Vec<[f32; 3]>;

fn load(path: &Path) -> Result<(u32, u32, Image), String> {
    let img = image::open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .into_rgb32f();
    let (w, h) = img.dimensions();
    Ok((w, h, img.pixels().map(|p| p.0).collect()))
}

/// Loads `first` and, if given, `second` of the same size; returns their mean and half their
/// difference (the second is `None` without a second file).
fn load_pair(
    first: &Path,
    second: Option<&PathBuf>,
    size: Option<(u32, u32)>,
) -> Result<(u32, u32, Image, Option<Image>), String> {
    let (w, h, a) = load(first)?;
    let same = |(w2, h2): (u32, u32), what: &Path| -> Result<(), String> {
        if (w, h) != (w2, h2) {
            return Err(format!(
                "sizes differ: {w}x{h} ({}) vs {w2}x{h2} ({})",
                first.display(),
                what.display()
            ));
        }
        Ok(())
    };
    if let Some(s) = size {
        // The size of the images already loaded (the test's).
        if s != (w, h) {
            return Err(format!(
                "sizes differ: {}x{} vs {w}x{h} ({})",
                s.0,
                s.1,
                first.display()
            ));
        }
    }
    let Some(p2) = second else {
        return Ok((w, h, a, None));
    };
    let (w2, h2, b) = load(p2)?;
    same((w2, h2), p2)?;
    let mean = a
        .iter()
        .zip(&b)
        .map(|(x, y)| [0, 1, 2].map(|c| 0.5 * (x[c] + y[c])))
        .collect();
    let half_diff = a
        .iter()
        .zip(&b)
        .map(|(x, y)| [0, 1, 2].map(|c| 0.5 * (x[c] - y[c])))
        .collect();
    Ok((w, h, mean, Some(half_diff)))
}

fn channel_means(img: &[[f32; 3]]) -> [f64; 3] {
    let mut s = [0.0f64; 3];
    for p in img {
        for c in 0..3 {
            s[c] += f64::from(p[c]);
        }
    }
    s.map(|v| v / img.len() as f64)
}

/// Summary of one set of block errors.
fn block_summary(e: &BlockErrors, tol: f64) -> Value {
    json!({
        "within": e.fraction_within(tol),
        "p50": e.percentile(0.5),
        "p95": e.percentile(0.95),
        "max": e.percentile(1.0),
    })
}

/// The variance of the compared difference `T - R` at each pixel, from the halves: for the
/// mean of two independent halves, `E[((X1 - X2) / 2)^2] = Var((X1 + X2) / 2)`, so it is
/// `dT^2 + dR^2` (`d`: half the difference of the halves; a side without halves adds 0).
/// The fourth value is that of the pixel's mean over the channels.
fn pixel_variance(dt: Option<&Image>, dr: Option<&Image>, n: usize) -> Vec<[f64; 4]> {
    (0..n)
        .map(|i| {
            let mut v = [0.0f64; 4];
            for d in [dt, dr].into_iter().flatten() {
                let p = d[i].map(f64::from);
                for c in 0..3 {
                    v[c] += p[c] * p[c];
                }
                let all = (p[0] + p[1] + p[2]) / 3.0;
                v[3] += all * all;
            }
            v
        })
        .collect()
}

/// The standard error of the mean ratio, per channel and over all channels: pixels are
/// independent, so the variance of the image mean of `T - R` is the sum of the pixel variances
/// over the pixel count squared.
fn ratio_noise(var: &[[f64; 4]], reference_mean: [f64; 3]) -> [f64; 4] {
    let mut s = [0.0f64; 4];
    for v in var {
        for c in 0..4 {
            s[c] += v[c];
        }
    }
    let n = var.len() as f64;
    let all_mean = reference_mean.iter().sum::<f64>() / 3.0;
    let means = [
        reference_mean[0],
        reference_mean[1],
        reference_mean[2],
        all_mean,
    ];
    [0, 1, 2, 3].map(|c| s[c].sqrt() / n / means[c])
}

/// The standard error of each block's relative error (in the channel that set it), from the
/// pixel variances ([`raylume_post::block_standard_errors`]), relative to the error's
/// denominator.
fn block_sigma(var: &[[f64; 4]], w: u32, h: u32, e: &BlockErrors) -> Vec<f64> {
    let v3: Vec<[f32; 3]> = var
        .iter()
        .map(|v| [v[0], v[1], v[2]].map(|x| x as f32))
        .collect();
    let se = raylume_post::block_standard_errors(&v3, w, h, e.block).expect("checked sizes");
    se.iter()
        .enumerate()
        .map(|(k, s)| {
            let c = usize::from(e.channel[k]);
            s[c] / e.reference_means[k][c].max(e.floor_level[c])
        })
        .collect()
}

/// Nearest-rank percentile of non-negative values.
fn percentile(v: &[f64], p: f64) -> f64 {
    let mut m = v.to_vec();
    m.sort_by(f64::total_cmp);
    let rank = (p * m.len() as f64).ceil().max(1.0) as usize;
    m[rank.min(m.len()) - 1]
}

/// The colour of a block error in the block image.
fn error_colour(e: f64, tol: f64) -> [u8; 3] {
    if !e.is_finite() {
        return [0, 0, 0];
    }
    let hue = if e > 0.0 {
        [0.85, 0.08, 0.08]
    } else {
        [0.08, 0.25, 0.9]
    };
    let m = e.abs();
    let t = if m <= tol {
        0.3 * m / tol
    } else {
        0.5 + 0.5 * ((m - tol) / (3.0 * tol)).min(1.0)
    };
    hue.map(|h: f64| ((1.0 - t + t * h) * 255.0).round() as u8)
}

fn write_block_image(
    path: &Path,
    test: &[[f32; 3]],
    reference: &[[f32; 3]],
    w: u32,
    h: u32,
    e: &BlockErrors,
    tol: f64,
) -> Result<(), String> {
    let tone = raylume_post::ToneMap::default();
    let t8 = tone.to_srgb8(test).map_err(|e| e.to_string())?;
    let r8 = tone.to_srgb8(reference).map_err(|e| e.to_string())?;
    // Small images are scaled up (nearest) to at least 256 pixels on their longer side.
    let s = 256u32.div_ceil(w.max(h)).max(1);
    let gap = 4u32;
    let (pw, ph) = (w * s, h * s);
    let mut out = image::RgbImage::from_pixel(3 * pw + 2 * gap, ph, image::Rgb([255, 255, 255]));
    for y in 0..ph {
        for x in 0..pw {
            let (sx, sy) = (x / s, y / s);
            let i = (sy * w + sx) as usize;
            let k = ((sy / e.block) * e.columns + sx / e.block) as usize;
            out.put_pixel(x, y, image::Rgb(t8[i]));
            out.put_pixel(pw + gap + x, y, image::Rgb(r8[i]));
            out.put_pixel(
                2 * (pw + gap) + x,
                y,
                image::Rgb(error_colour(e.errors[k], tol)),
            );
        }
    }
    out.save(path)
        .map_err(|err| format!("{}: {err}", path.display()))
}

/// `println!` that ends the program quietly when stdout is closed (`compare ... | head -1`)
/// instead of panicking, and returns any other write error from `run`.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            return Err(format!("writing to stdout: {e}"));
        }
    }};
}

fn run(a: Args) -> Result<(), String> {
    let (w, h, test, test_half_diff) = load_pair(&a.test, a.test2.as_ref(), None)?;
    let (_, _, reference, ref_half_diff) =
        load_pair(&a.reference, a.reference2.as_ref(), Some((w, h)))?;
    let e = |r: Result<f64, raylume_post::PostError>| r.map_err(|e| e.to_string());
    let rmse = e(raylume_post::rmse(&test, &reference))?;
    let mae = e(raylume_post::mae(&test, &reference))?;
    let rel = e(raylume_post::relative_mse(&test, &reference))?;
    let worst = raylume::worst_relative_difference(&test, &reference);
    let bound = a.merge_bound.map(raylume::merge_bound);
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
    // Images below SSIM's 11x11 window get none (`null` in JSON); the other metrics stand.
    let ssim = match raylume_post::ssim(&display(&test)?, &display(&reference)?, w, h) {
        Ok(v) => Some(v),
        Err(raylume_post::PostError::TooSmall { .. }) => None,
        Err(err) => return Err(err.to_string()),
    };
    let ssim_text = ssim.map_or("n/a (below 11x11 pixels)".to_string(), |v| {
        format!("{v:.5}")
    });

    // Image means.
    let tm = channel_means(&test);
    let rm = channel_means(&reference);
    let ratio = [
        tm[0] / rm[0],
        tm[1] / rm[1],
        tm[2] / rm[2],
        tm.iter().sum::<f64>() / rm.iter().sum::<f64>(),
    ];

    // The null image (see the module docs): the noise of the comparison without its bias.
    let noise_sources = match (&test_half_diff, &ref_half_diff) {
        (Some(_), Some(_)) => Some("test and reference halves"),
        (Some(_), None) => Some("test halves only (the reference's noise is not included)"),
        (None, Some(_)) => Some("reference halves only (the test's noise is not included)"),
        (None, None) => None,
    };
    let null: Option<Image> = noise_sources.map(|_| {
        (0..test.len())
            .map(|i| {
                [0, 1, 2].map(|c| {
                    test_half_diff.as_ref().map_or(0.0, |d| d[i][c])
                        - ref_half_diff.as_ref().map_or(0.0, |d| d[i][c])
                })
            })
            .collect()
    });
    let variance = noise_sources
        .map(|_| pixel_variance(test_half_diff.as_ref(), ref_half_diff.as_ref(), test.len()));
    let ratio_sigma = variance.as_ref().map(|v| ratio_noise(v, rm));

    // Block statistics.
    let tol = a.block_tolerance;
    let blocks = if a.blocks == 0 {
        None
    } else {
        let be = raylume_post::block_errors(&test, &reference, w, h, a.blocks, a.block_floor)
            .map_err(|e| e.to_string())?;
        let noise = match &null {
            Some(n) => {
                let pseudo: Image = reference
                    .iter()
                    .zip(n)
                    .map(|(r, d)| [0, 1, 2].map(|c| r[c] + d[c]))
                    .collect();
                Some(
                    raylume_post::block_errors(&pseudo, &reference, w, h, a.blocks, a.block_floor)
                        .map_err(|e| e.to_string())?,
                )
            }
            None => None,
        };
        let sigma = variance.as_ref().map(|v| block_sigma(v, w, h, &be));
        Some((be, noise, sigma))
    };
    if let (Some(path), Some((be, _, _))) = (&a.block_image, &blocks) {
        write_block_image(path, &test, &reference, w, h, be, tol)?;
    }

    // Per-block noise: the standard errors' p50 / p95, and the blocks outside the tolerance by
    // more than three standard errors (a miss that noise does not explain).
    let sigma_summary = |be: &BlockErrors, sg: &[f64]| {
        let beyond = be
            .errors
            .iter()
            .zip(sg)
            .filter(|(e, s)| e.abs() > tol + 3.0 * **s)
            .count();
        (
            percentile(sg, 0.5),
            percentile(sg, 0.95),
            beyond as f64 / sg.len() as f64,
        )
    };
    let block_rect = |be: &BlockErrors, k: usize| {
        let b = be.block;
        let (x0, y0) = ((k as u32 % be.columns) * b, (k as u32 / be.columns) * b);
        (x0, y0, (x0 + b).min(w), (y0 + b).min(h))
    };

    if a.json {
        let mut out = json!({
            "rmse": rmse, "mae": mae, "relative_mse": rel, "ssim": ssim,
            "worst_relative_difference": worst, "merge_bound": bound,
            "width": w, "height": h,
            "test_mean": tm, "reference_mean": rm,
            "mean_ratio": {"r": ratio[0], "g": ratio[1], "b": ratio[2], "all": ratio[3]},
            "mean_ratio_noise": ratio_sigma.map(|s| json!({"r": s[0], "g": s[1], "b": s[2], "all": s[3]})),
            "noise_sources": noise_sources,
        });
        if let Some((be, noise, sigma)) = &blocks {
            let worst: Vec<Value> = be
                .worst(a.worst)
                .into_iter()
                .map(|k| {
                    let (x0, y0, x1, y1) = block_rect(be, k);
                    json!({"x0": x0, "y0": y0, "x1": x1, "y1": y1, "error": be.errors[k],
                           "sigma": sigma.as_ref().map(|s| s[k]),
                           "channel": be.channel[k],
                           "test": be.test_means[k], "reference": be.reference_means[k],
                           "floored": be.floored[k]})
                })
                .collect();
            let sg = sigma.as_ref().map(|s| sigma_summary(be, s));
            let mut bj = block_summary(be, tol);
            let extra = json!({
                "size": be.block, "columns": be.columns, "rows": be.rows,
                "count": be.errors.len(), "tolerance": tol, "floor": a.block_floor,
                "floor_level": be.floor_level,
                "floored": be.floored.iter().filter(|&&f| f).count(),
                "worst": worst,
                "noise": noise.as_ref().map(|n| block_summary(n, tol)),
                "sigma_p50": sg.map(|x| x.0),
                "sigma_p95": sg.map(|x| x.1),
                "outside_beyond_noise": sg.map(|x| x.2),
            });
            if let (Value::Object(m), Value::Object(x)) = (&mut bj, extra) {
                m.extend(x);
            }
            out["blocks"] = bj;
        } else {
            out["blocks"] = Value::Null;
        }
        outln!("{out}");
    } else {
        outln!(
            "{}x{}: RMSE {rmse:.6}, MAE {mae:.6}, relative MSE {rel:.6}, SSIM {ssim_text}",
            w,
            h
        );
        outln!(
            "worst relative difference of a channel: {worst:.3e}{}",
            bound.map_or(String::new(), |b| format!(
                " ({} the merge bound {b:.3e} of {} spp)",
                if worst <= b { "within" } else { "OUTSIDE" },
                a.merge_bound.unwrap_or(0)
            ))
        );
        let sigma = |i: usize| ratio_sigma.map_or(String::new(), |s| format!(" ± {:.4}", s[i]));
        outln!(
            "mean ratio (test / reference): {:.4}{} (R {:.4}, G {:.4}, B {:.4}); means: test \
             [{:.4}, {:.4}, {:.4}], reference [{:.4}, {:.4}, {:.4}]",
            ratio[3],
            sigma(3),
            ratio[0],
            ratio[1],
            ratio[2],
            tm[0],
            tm[1],
            tm[2],
            rm[0],
            rm[1],
            rm[2]
        );
        if let Some((be, noise, sigma)) = &blocks {
            let floored = be.floored.iter().filter(|&&f| f).count();
            outln!(
                "{b}x{b} blocks ({n}; floor {f} x median, {floored} floored): {:.1} % within \
                 {:.1} %, p50 {:.2} %, p95 {:.2} %, max {:.2} %",
                100.0 * be.fraction_within(tol),
                100.0 * tol,
                100.0 * be.percentile(0.5),
                100.0 * be.percentile(0.95),
                100.0 * be.percentile(1.0),
                b = be.block,
                n = be.errors.len(),
                f = a.block_floor,
            );
            if let (Some(n), Some(src)) = (noise, noise_sources) {
                outln!(
                    "noise alone ({src}): {:.1} % within, p50 {:.2} %, p95 {:.2} %, max {:.2} %",
                    100.0 * n.fraction_within(tol),
                    100.0 * n.percentile(0.5),
                    100.0 * n.percentile(0.95),
                    100.0 * n.percentile(1.0),
                );
            }
            if let Some(sg) = sigma {
                let (p50, p95, beyond) = sigma_summary(be, sg);
                outln!(
                    "block standard errors (from the halves' pixels): p50 {:.2} %, p95 {:.2} %; \
                     {:.1} % of the blocks are outside {:.1} % by more than 3 standard errors",
                    100.0 * p50,
                    100.0 * p95,
                    100.0 * beyond,
                    100.0 * tol
                );
            }
            for k in be.worst(a.worst) {
                let (x0, y0, x1, y1) = block_rect(be, k);
                let (t, r) = (be.test_means[k], be.reference_means[k]);
                let sd = sigma
                    .as_ref()
                    .map_or(String::new(), |s| format!(" ± {:.2} %", 100.0 * s[k]));
                outln!(
                    "  block x {x0}..{x1}, y {y0}..{y1}: {:+.2} %{sd}{} in {} (test [{:.4}, {:.4}, \
                     {:.4}], reference [{:.4}, {:.4}, {:.4}])",
                    100.0 * be.errors[k],
                    if be.floored[k] { " of the floor" } else { "" },
                    ["R", "G", "B"][usize::from(be.channel[k])],
                    t[0],
                    t[1],
                    t[2],
                    r[0],
                    r[1],
                    r[2]
                );
            }
        }
    }
    match bound {
        Some(b) if worst > b => Err(format!(
            "the images differ by {worst:.3e} (relative, worst channel), past the merge bound \
             {b:.3e}"
        )),
        _ => Ok(()),
    }
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
