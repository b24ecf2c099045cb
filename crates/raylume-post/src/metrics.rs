//! Image metrics for tests and accuracy-versus-time studies.
//!
//! Every metric compares a `test` image against a `reference` of the same size, over all three
//! channels of every pixel, accumulating in f64 in a fixed order (per chunk of pixels, then
//! over chunks), so results do not depend on the thread count. Non-finite input propagates to
//! a non-finite result rather than being hidden.
//!
//! - [`rmse`]: `sqrt(mean((t - r)^2))`.
//! - [`mae`]: `mean(|t - r|)`.
//! - [`relative_mse`]: `mean((t - r)^2 / (r^2 + eps))` with `eps = 1e-2`
//!   ([`RELATIVE_MSE_EPS`]), the relative MSE of the denoising literature (Rousselle, Knaus
//!   and Zwicker, *Adaptive Sampling and Reconstruction using Greedy Error Minimization*,
//!   SIGGRAPH Asia 2011; Bako et al., *Kernel-Predicting Convolutional Networks for Denoising
//!   Monte Carlo Renderings*, SIGGRAPH 2017). The epsilon keeps dark pixels from dominating.
//!   Not symmetric: the reference is the denominator.
//! - [`ssim`]: the structural similarity index (Wang, Bovik, Sheikh and Simoncelli, *Image
//!   Quality Assessment: From Error Visibility to Structural Similarity*, IEEE TIP 2004) on
//!   Rec. 709 luminance, with their constants: an 11x11 Gaussian window of sigma 1.5,
//!   `K1 = 0.01`, `K2 = 0.03`, dynamic range `L = 1`, averaged over the positions where the
//!   window lies inside the image (their reference code's `valid` filtering).
//!   It is meant for display-referred images in `[0, 1]`: tone-map HDR images first (e.g.
//!   sRGB-encoded output of [`crate::ToneMap`] divided by 255).
//!
//! Why SSIM written here rather than a crate: `nv-flip` (FLIP) takes 8-bit LDR images only and
//! compiles NVIDIA's C++ in every build; `dssim-core` is AGPL-3.0, incompatible with this
//! project's MIT/Apache licence; `image-compare` computes SSIM on 8-bit `image` buffers only.
//! SSIM on f32 data is 60 lines.

use rayon::prelude::*;

use crate::PostError;

/// The epsilon of [`relative_mse`]: `1e-2`, as in the denoising literature.
pub const RELATIVE_MSE_EPS: f64 = 1e-2;

/// SSIM's `K1` (Wang et al. 2004).
pub const SSIM_K1: f64 = 0.01;
/// SSIM's `K2` (Wang et al. 2004).
pub const SSIM_K2: f64 = 0.03;
/// SSIM window size (11x11 Gaussian).
pub const SSIM_WINDOW: usize = 11;
/// SSIM window standard deviation in pixels.
pub const SSIM_SIGMA: f64 = 1.5;

const CHUNK: usize = 4096;

fn check_pair(test: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<(), PostError> {
    if test.len() != reference.len() {
        return Err(PostError::LengthMismatch {
            a: test.len(),
            b: reference.len(),
        });
    }
    if test.is_empty() {
        return Err(PostError::ZeroSize {
            what: "compared image",
            width: 0,
            height: 0,
        });
    }
    Ok(())
}

/// Mean over all channels of `f(test, reference)`, summed deterministically.
fn channel_mean(
    test: &[[f32; 3]],
    reference: &[[f32; 3]],
    f: impl Fn(f64, f64) -> f64 + Sync,
) -> Result<f64, PostError> {
    check_pair(test, reference)?;
    let partial: Vec<f64> = test
        .par_chunks(CHUNK)
        .zip(reference.par_chunks(CHUNK))
        .map(|(t, r)| {
            let mut s = 0.0f64;
            for (pt, pr) in t.iter().zip(r) {
                for c in 0..3 {
                    s += f(f64::from(pt[c]), f64::from(pr[c]));
                }
            }
            s
        })
        .collect();
    Ok(partial.iter().sum::<f64>() / (3 * test.len()) as f64)
}

/// Root-mean-square error over all channels.
pub fn rmse(test: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<f64, PostError> {
    Ok(channel_mean(test, reference, |t, r| (t - r) * (t - r))?.sqrt())
}

/// Mean absolute error over all channels.
pub fn mae(test: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<f64, PostError> {
    channel_mean(test, reference, |t, r| (t - r).abs())
}

/// Relative mean squared error over all channels: `mean((t - r)^2 / (r^2 + 1e-2))`.
pub fn relative_mse(test: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<f64, PostError> {
    channel_mean(test, reference, |t, r| {
        (t - r) * (t - r) / (r * r + RELATIVE_MSE_EPS)
    })
}

/// Rec. 709 / sRGB luminance of a linear RGB pixel: `0.2126 R + 0.7152 G + 0.0722 B`.
pub fn luminance(p: [f32; 3]) -> f64 {
    0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2])
}

/// The normalised 11-tap Gaussian of SSIM.
fn ssim_kernel() -> [f64; SSIM_WINDOW] {
    let mut k = [0.0; SSIM_WINDOW];
    let c = (SSIM_WINDOW / 2) as f64;
    for (i, v) in k.iter_mut().enumerate() {
        let d = i as f64 - c;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let s: f64 = k.iter().sum();
    k.map(|v| v / s)
}

/// Mean SSIM of the luminance of `test` against `reference` (`width x height`, at least 11x11).
/// 1 for identical images, symmetric in its arguments, lower for less similar images.
pub fn ssim(
    test: &[[f32; 3]],
    reference: &[[f32; 3]],
    width: u32,
    height: u32,
) -> Result<f64, PostError> {
    check_pair(test, reference)?;
    crate::error::check_image("SSIM test image", test.len(), width, height)?;
    let n = SSIM_WINDOW as u32;
    if width < n || height < n {
        return Err(PostError::TooSmall {
            what: "SSIM (11x11 Gaussian window)",
            min: n,
            width,
            height,
        });
    }
    let (w, h) = (width as usize, height as usize);
    let (ow, oh) = (w - SSIM_WINDOW + 1, h - SSIM_WINDOW + 1);
    let k = ssim_kernel();
    let lum = |img: &[[f32; 3]]| -> Vec<f64> { img.par_iter().map(|&p| luminance(p)).collect() };
    let (x, y) = (lum(test), lum(reference));

    // Horizontal pass of the five moments (x, y, x^2, y^2, xy): h rows of ow values each.
    let horizontal: Vec<[f64; 5]> = (0..h)
        .into_par_iter()
        .flat_map_iter(|row| {
            let (xr, yr) = (&x[row * w..(row + 1) * w], &y[row * w..(row + 1) * w]);
            (0..ow).map(move |ox| {
                let mut m = [0.0f64; 5];
                for (j, kj) in k.iter().enumerate() {
                    let (a, b) = (xr[ox + j], yr[ox + j]);
                    m[0] += kj * a;
                    m[1] += kj * b;
                    m[2] += kj * a * a;
                    m[3] += kj * b * b;
                    m[4] += kj * a * b;
                }
                m
            })
        })
        .collect();

    let c1 = (SSIM_K1 * 1.0) * (SSIM_K1 * 1.0);
    let c2 = (SSIM_K2 * 1.0) * (SSIM_K2 * 1.0);
    let row_sums: Vec<f64> = (0..oh)
        .into_par_iter()
        .map(|oy| {
            let mut s = 0.0;
            for ox in 0..ow {
                let mut m = [0.0f64; 5];
                for (j, kj) in k.iter().enumerate() {
                    let hm = &horizontal[(oy + j) * ow + ox];
                    for q in 0..5 {
                        m[q] += kj * hm[q];
                    }
                }
                let (mx, my) = (m[0], m[1]);
                let vx = m[2] - mx * mx;
                let vy = m[3] - my * my;
                let cxy = m[4] - mx * my;
                s += ((2.0 * mx * my + c1) * (2.0 * cxy + c2))
                    / ((mx * mx + my * my + c1) * (vx + vy + c2));
            }
            s
        })
        .collect();
    Ok(row_sums.iter().sum::<f64>() / (ow * oh) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn analytic_values_on_a_tiny_image() {
        let r = [[1.0f32, 2.0, 0.0], [0.0, 0.5, 4.0]];
        let t = [[1.5f32, 2.0, 1.0], [0.0, 0.0, 4.0]];
        // Differences: 0.5, 0, 1, 0, -0.5, 0 over 6 channels.
        assert!(close(mae(&t, &r).unwrap(), 2.0 / 6.0));
        assert!(close(rmse(&t, &r).unwrap(), (1.5f64 / 6.0).sqrt()));
        // relMSE: 0.25/1.01 + 1/0.01 + 0.25/0.26, over 6.
        let want = (0.25 / 1.01 + 1.0 / 0.01 + 0.25 / 0.26) / 6.0;
        assert!(close(relative_mse(&t, &r).unwrap(), want));
        assert_eq!(rmse(&r, &r).unwrap(), 0.0);
        assert_eq!(relative_mse(&r, &r).unwrap(), 0.0);
    }

    #[test]
    fn size_errors() {
        let a = [[0.0f32; 3]; 4];
        let b = [[0.0f32; 3]; 5];
        assert!(matches!(
            rmse(&a, &b),
            Err(PostError::LengthMismatch { a: 4, b: 5 })
        ));
        assert!(matches!(mae(&[], &[]), Err(PostError::ZeroSize { .. })));
        assert!(matches!(
            ssim(&a, &a, 2, 2),
            Err(PostError::TooSmall { min: 11, .. })
        ));
        assert!(matches!(
            ssim(&a, &a, 3, 2),
            Err(PostError::SizeMismatch { .. })
        ));
    }

    #[test]
    fn chunked_sums_cover_every_pixel() {
        // More than one chunk: a difference of 1 in channel 0 of every pixel.
        let n = 3 * CHUNK + 17;
        let r = vec![[0.5f32; 3]; n];
        let t: Vec<[f32; 3]> = r.iter().map(|p| [p[0] + 1.0, p[1], p[2]]).collect();
        assert!(close(mae(&t, &r).unwrap(), 1.0 / 3.0));
    }

    /// A tiny deterministic generator for test noise (splitmix64).
    fn noise(seed: u64, i: usize) -> f32 {
        let mut z = seed.wrapping_add((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }

    fn pattern(w: usize, h: usize) -> Vec<[f32; 3]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let v = 0.5 + 0.3 * (x * 0.4).sin() * (y * 0.3).cos();
                [v, v * 0.8, 0.2]
            })
            .collect()
    }

    #[test]
    fn ssim_identical_is_one_and_symmetric() {
        let (w, h) = (32u32, 24u32);
        let a = pattern(32, 24);
        assert!((ssim(&a, &a, w, h).unwrap() - 1.0).abs() < 1e-12);
        let b: Vec<[f32; 3]> = a
            .iter()
            .enumerate()
            .map(|(i, p)| p.map(|v| v + 0.1 * noise(7, i)))
            .collect();
        let ab = ssim(&a, &b, w, h).unwrap();
        let ba = ssim(&b, &a, w, h).unwrap();
        assert!((ab - ba).abs() < 1e-12, "{ab} vs {ba}");
        assert!(ab < 1.0);
    }

    #[test]
    fn ssim_decreases_with_noise() {
        let (w, h) = (40u32, 40u32);
        let a = pattern(40, 40);
        let mut prev = 1.0;
        for amp in [0.01f32, 0.05, 0.1, 0.3, 4.0] {
            let b: Vec<[f32; 3]> = a
                .iter()
                .enumerate()
                .map(|(i, p)| p.map(|v| v + amp * noise(3, i)))
                .collect();
            let s = ssim(&a, &b, w, h).unwrap();
            assert!(s < prev, "amplitude {amp}: {s} !< {prev}");
            prev = s;
        }
        // Noise of amplitude 4 (variance 16/12 = 1.33) drowns the pattern (variance <= 0.09 / 2):
        // the contrast-structure term is at most about 2 * 0.045 / 1.4 = 0.065 and the window
        // covariance of independent noise averages out, so SSIM is near 0.
        assert!(
            prev < 0.1,
            "noise 4x the signal should score near 0, got {prev}"
        );
    }

    /// Two constant images have zero variance: SSIM reduces to its luminance term
    /// `(2 a b + C1) / (a^2 + b^2 + C1)` everywhere.
    #[test]
    fn ssim_of_constant_images_is_the_luminance_term() {
        let (a, b) = (0.3f32, 0.6f32);
        let ia = vec![[a; 3]; 144];
        let ib = vec![[b; 3]; 144];
        let (la, lb) = (luminance([a; 3]), luminance([b; 3]));
        let c1 = SSIM_K1 * SSIM_K1;
        let want = (2.0 * la * lb + c1) / (la * la + lb * lb + c1);
        let got = ssim(&ia, &ib, 12, 12).unwrap();
        // The moments of a constant under a normalised window carry ~1e-16 rounding; the
        // variance terms (~1e-17) are negligible against C2 = 9e-4.
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
}
