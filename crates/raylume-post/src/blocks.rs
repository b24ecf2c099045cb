//! Block statistics: how far the means of `n x n`-pixel blocks of a test image are from a
//! reference's, the measure behind "95 % of 8x8 blocks within 3 % of the reference".
//!
//! Per-pixel errors of two converged renders mix noise with bias; the mean of a block of 64
//! pixels has an eighth of a pixel's noise and keeps any bias (a lamp too bright, a camera
//! framed differently, a wrong material) at full size, so block means separate a renderer that
//! computes something else from one that is merely noisy. The blocks tile the image from its
//! top-left corner; where the size is not a multiple of `n`, the last column and row of blocks
//! are partial and average the pixels they hold (nothing is left out).
//!
//! **The error of a block** ([`block_errors`]): per channel `c`,
//! `(T_c - R_c) / max(R_c, floor * median_c)`, where `T_c`, `R_c` are the block means of test
//! and reference and `median_c` is the median of the reference's block means in that channel;
//! the block's error is the channel error of largest magnitude (signed: positive where the test
//! is brighter), so a wrong hue counts as much as a wrong brightness.
//!
//! **Why a floor.** A relative error is meaningless where the reference is near black: a block
//! of `R = 1e-4` and `T = 2e-4` is "100 % off" and invisible. Below `floor * median` the error
//! is the absolute difference in units of that level instead: with the default floor of 0.1
//! ([`BLOCK_FLOOR`]) a block more than ten times (3.3 stops) darker than the typical block may
//! be off by at most `tolerance * 0.1` of a typical block's brightness (0.3 % at a 3 %
//! tolerance). The median, not the image mean, sets the level because a bright emitter or
//! window in view can lift the mean far above what most of the picture shows.
//! [`BlockErrors::floored`] says which blocks the floor decided, so a reader can see whether it
//! mattered.

use crate::PostError;

/// The default floor of [`block_errors`], as a fraction of the median block mean: 0.1.
pub const BLOCK_FLOOR: f64 = 0.1;

/// The per-channel means of the `block x block`-pixel blocks of a `width x height` image,
/// row-major over `ceil(width / block) x ceil(height / block)` blocks (partial blocks at the
/// right and bottom average the pixels they hold), accumulated in f64.
pub fn block_means(
    img: &[[f32; 3]],
    width: u32,
    height: u32,
    block: u32,
) -> Result<Vec<[f64; 3]>, PostError> {
    crate::error::check_image("block-mean image", img.len(), width, height)?;
    if block == 0 {
        return Err(PostError::BadParam {
            what: "block size",
            value: "0".into(),
            requirement: "at least 1 pixel",
        });
    }
    let (w, b) = (width as usize, block as usize);
    let cols = w.div_ceil(b);
    let rows = (height as usize).div_ceil(b);
    let mut sums = vec![[0.0f64; 3]; cols * rows];
    let mut counts = vec![0u32; cols * rows];
    for (i, p) in img.iter().enumerate() {
        let k = (i / w / b) * cols + (i % w) / b;
        for c in 0..3 {
            sums[k][c] += f64::from(p[c]);
        }
        counts[k] += 1;
    }
    Ok(sums
        .iter()
        .zip(&counts)
        .map(|(s, &n)| s.map(|v| v / f64::from(n)))
        .collect())
}

/// The standard errors of the block means of an image whose pixels are independent, from its
/// per-pixel variances (`variance`, same layout as [`block_means`]): per channel,
/// `sqrt(sum of the block's pixel variances) / (pixels in the block)`. With two independent
/// halves `X1`, `X2` of a render, `((X1 - X2) / 2)^2` estimates the variance of their mean at
/// each pixel.
pub fn block_standard_errors(
    variance: &[[f32; 3]],
    width: u32,
    height: u32,
    block: u32,
) -> Result<Vec<[f64; 3]>, PostError> {
    let m = block_means(variance, width, height, block)?;
    let cols = width.div_ceil(block);
    Ok(m.iter()
        .enumerate()
        .map(|(k, v)| {
            let (bx, by) = (k as u32 % cols, k as u32 / cols);
            let n = f64::from((width - bx * block).min(block) * (height - by * block).min(block));
            v.map(|x| (x / n).sqrt())
        })
        .collect())
}

/// The block errors of a test image against a reference (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockErrors {
    /// Block size in pixels.
    pub block: u32,
    /// Blocks per row (`ceil(width / block)`).
    pub columns: u32,
    /// Blocks per column (`ceil(height / block)`).
    pub rows: u32,
    /// The signed relative error of each block, row-major (positive: the test is brighter).
    pub errors: Vec<f64>,
    /// The channel (0, 1, 2) that set each block's error.
    pub channel: Vec<u8>,
    /// Whether the floor, not the reference's own block mean, was the denominator of the
    /// channel that set the block's error.
    pub floored: Vec<bool>,
    /// The denominators' floor per channel: `floor * median` of the reference's block means.
    pub floor_level: [f64; 3],
    /// The block means of the test, row-major.
    pub test_means: Vec<[f64; 3]>,
    /// The block means of the reference, row-major.
    pub reference_means: Vec<[f64; 3]>,
}

impl BlockErrors {
    /// The fraction of blocks whose error magnitude is at most `tolerance` (NaN is never within).
    pub fn fraction_within(&self, tolerance: f64) -> f64 {
        let n = self.errors.iter().filter(|e| e.abs() <= tolerance).count();
        n as f64 / self.errors.len() as f64
    }

    /// The `p`-th percentile (`0 < p <= 1`) of the error magnitudes, nearest rank: the smallest
    /// value that at least a fraction `p` of the blocks do not exceed. So
    /// `percentile(0.95) <= tol` exactly when `fraction_within(tol) >= 0.95`.
    pub fn percentile(&self, p: f64) -> f64 {
        let mut m: Vec<f64> = self.errors.iter().map(|e| e.abs()).collect();
        m.sort_by(f64::total_cmp);
        let rank = (p * m.len() as f64).ceil().max(1.0) as usize;
        m[rank.min(m.len()) - 1]
    }

    /// Indices of the `k` blocks of largest error magnitude, largest first.
    pub fn worst(&self, k: usize) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.errors.len()).collect();
        idx.sort_by(|&a, &b| self.errors[b].abs().total_cmp(&self.errors[a].abs()));
        idx.truncate(k);
        idx
    }
}

/// The errors of the `block x block` means of `test` against `reference` (both
/// `width x height`), relative to `max(reference block mean, floor * median reference block
/// mean)` per channel (see the [module docs](self); [`BLOCK_FLOOR`] is the usual `floor`).
pub fn block_errors(
    test: &[[f32; 3]],
    reference: &[[f32; 3]],
    width: u32,
    height: u32,
    block: u32,
    floor: f64,
) -> Result<BlockErrors, PostError> {
    if test.len() != reference.len() {
        return Err(PostError::LengthMismatch {
            a: test.len(),
            b: reference.len(),
        });
    }
    if !(floor.is_finite() && floor >= 0.0) {
        return Err(PostError::BadParam {
            what: "block error floor",
            value: floor.to_string(),
            requirement: "finite and >= 0",
        });
    }
    let t = block_means(test, width, height, block)?;
    let r = block_means(reference, width, height, block)?;
    let mut floor_level = [0.0f64; 3];
    for (c, level) in floor_level.iter_mut().enumerate() {
        let mut v: Vec<f64> = r.iter().map(|m| m[c]).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        *level = floor * median;
    }
    let n = t.len();
    let (mut errors, mut channel, mut floored) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for (tb, rb) in t.iter().zip(&r) {
        let (mut worst, mut worst_c, mut was_floored) = (0.0f64, 0u8, false);
        for c in 0..3 {
            let denom = rb[c].max(floor_level[c]);
            let diff = tb[c] - rb[c];
            let e = if denom > 0.0 {
                diff / denom
            } else if diff == 0.0 {
                0.0
            } else {
                diff * f64::INFINITY
            };
            // A NaN (from non-finite input) wins and stays, so it is never hidden.
            if c == 0 || e.is_nan() || (!worst.is_nan() && e.abs() > worst.abs()) {
                worst = e;
                worst_c = c as u8;
                was_floored = rb[c] < floor_level[c];
            }
        }
        errors.push(worst);
        channel.push(worst_c);
        floored.push(was_floored);
    }
    let (w, h, b) = (width as usize, height as usize, block as usize);
    Ok(BlockErrors {
        block,
        columns: w.div_ceil(b) as u32,
        rows: h.div_ceil(b) as u32,
        errors,
        channel,
        floored,
        floor_level,
        test_means: t,
        reference_means: r,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth, strictly positive picture with colour.
    fn pattern(w: usize, h: usize) -> Vec<[f32; 3]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let v = 0.5 + 0.3 * (x * 0.4).sin() * (y * 0.3).cos();
                [v, v * 0.8, 0.2 + 0.01 * x]
            })
            .collect()
    }

    /// splitmix64 in [-0.5, 0.5).
    fn noise(seed: u64, i: usize) -> f32 {
        let mut z = seed.wrapping_add((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }

    #[test]
    fn block_means_average_each_tile_and_partial_edges() {
        // 10x9 in blocks of 4: 3x3 blocks, the last column 2 wide, the last row 1 high.
        let (w, h) = (10usize, 9usize);
        let img: Vec<[f32; 3]> = (0..w * h)
            .map(|i| [(i % w) as f32, (i / w) as f32, 1.0])
            .collect();
        let m = block_means(&img, 10, 9, 4).unwrap();
        assert_eq!(m.len(), 9);
        assert_eq!(m[0], [1.5, 1.5, 1.0]); // x 0..4, y 0..4
        assert_eq!(m[2], [8.5, 1.5, 1.0]); // x 8..10
        assert_eq!(m[7], [5.5, 8.0, 1.0]); // x 4..8, y 8
        assert_eq!(m[8], [8.5, 8.0, 1.0]);
        assert!(matches!(
            block_means(&img, 10, 9, 0),
            Err(PostError::BadParam { .. })
        ));
        assert!(matches!(
            block_means(&img, 10, 8, 4),
            Err(PostError::SizeMismatch { .. })
        ));
    }

    #[test]
    fn one_block_off_by_five_percent() {
        // 32x24 in 8x8 blocks: 4x3 = 12 blocks. Block (column 1, row 2) is 5 % brighter.
        let (w, h) = (32usize, 24usize);
        let r = pattern(w, h);
        let mut t = r.clone();
        for (i, p) in t.iter_mut().enumerate() {
            if (i % w) / 8 == 1 && (i / w) / 8 == 2 {
                *p = p.map(|v| v * 1.05);
            }
        }
        let e = block_errors(&t, &r, 32, 24, 8, BLOCK_FLOOR).unwrap();
        assert_eq!((e.columns, e.rows, e.errors.len()), (4, 3, 12));
        let k = 2 * 4 + 1;
        assert!((e.errors[k] - 0.05).abs() < 1e-6, "{}", e.errors[k]);
        for (i, &v) in e.errors.iter().enumerate() {
            if i != k {
                assert_eq!(v, 0.0, "block {i}");
            }
        }
        assert_eq!(e.fraction_within(0.03), 11.0 / 12.0);
        assert_eq!(e.fraction_within(0.06), 1.0);
        // Nearest rank: 95 % of 12 is 11.4, the 12th value, the bad block; 90 % is the 11th.
        assert!((e.percentile(0.95) - 0.05).abs() < 1e-6);
        assert_eq!(e.percentile(0.90), 0.0);
        assert_eq!(e.worst(1), vec![k]);
        // 5 % darker gives the same magnitude with the sign of the test.
        let t2: Vec<[f32; 3]> = t
            .iter()
            .zip(&r)
            .map(|(a, b)| [0, 1, 2].map(|c| 2.0 * b[c] - a[c]))
            .collect();
        let e2 = block_errors(&t2, &r, 32, 24, 8, BLOCK_FLOOR).unwrap();
        assert!((e2.errors[k] + 0.05).abs() < 1e-6, "{}", e2.errors[k]);
    }

    #[test]
    fn noise_below_the_tolerance_keeps_every_block_within() {
        // Every pixel within +-2.5 % of the reference (independent per channel): every block
        // mean is within 2.5 % too, whatever the noise does.
        let (w, h) = (64usize, 40usize);
        let r = pattern(w, h);
        let t: Vec<[f32; 3]> = r
            .iter()
            .enumerate()
            .map(|(i, p)| [0, 1, 2].map(|c| p[c] * (1.0 + 0.05 * noise(c as u64 + 1, i))))
            .collect();
        let e = block_errors(&t, &r, 64, 40, 8, BLOCK_FLOOR).unwrap();
        assert_eq!(e.fraction_within(0.03), 1.0);
        assert!(e.percentile(0.95) < 0.025);
        assert!(e.percentile(1.0) > 0.0);
        assert!(e.floored.iter().all(|&f| !f));
        // Noise of +-25 % puts some blocks past 3 % (block noise ~0.25 / sqrt(12 * 64) = 0.9 %
        // per channel, the worst of three channels over 40 blocks).
        let t: Vec<[f32; 3]> = r
            .iter()
            .enumerate()
            .map(|(i, p)| [0, 1, 2].map(|c| p[c] * (1.0 + 0.5 * noise(c as u64 + 1, i))))
            .collect();
        let e = block_errors(&t, &r, 64, 40, 8, BLOCK_FLOOR).unwrap();
        assert!(e.fraction_within(0.03) < 1.0);
    }

    #[test]
    fn dark_blocks_are_measured_against_the_floor() {
        // 16x8 in 8x8 blocks: a grey block of 0.5 and a black one. The median of the two block
        // means is 0.25, so the floor level is 0.025; a test of 0.001 in the black block is
        // 0.001 / 0.025 = 4 % off, not infinitely.
        let r: Vec<[f32; 3]> = (0..128)
            .map(|i| if i % 16 < 8 { [0.5; 3] } else { [0.0; 3] })
            .collect();
        let t: Vec<[f32; 3]> = r
            .iter()
            .map(|p| if p[0] == 0.0 { [0.001; 3] } else { *p })
            .collect();
        let e = block_errors(&t, &r, 16, 8, 8, BLOCK_FLOOR).unwrap();
        assert_eq!(e.floor_level, [0.025; 3]);
        assert_eq!(e.errors[0], 0.0);
        assert!((e.errors[1] - 0.04).abs() < 1e-6, "{}", e.errors[1]);
        assert_eq!(e.floored, vec![false, true]);
        // Without a floor the black block is infinitely off; equal black blocks are not.
        let e = block_errors(&t, &r, 16, 8, 8, 0.0).unwrap();
        assert_eq!(e.errors[1], f64::INFINITY);
        assert_eq!(
            block_errors(&r, &r, 16, 8, 8, 0.0).unwrap().errors,
            [0.0; 2]
        );
        assert!(matches!(
            block_errors(&t, &r, 16, 8, 8, -1.0),
            Err(PostError::BadParam { .. })
        ));
    }

    #[test]
    fn standard_errors_from_halves_match_the_spread_of_block_errors() {
        // 10x9 in blocks of 4 with a constant variance of 0.16: full blocks sqrt(0.16 * 16) / 16
        // = 0.1, the 2x4 edge block sqrt(0.16 * 8) / 8, the 2x1 corner sqrt(0.16 * 2) / 2.
        let v = vec![[0.16f32; 3]; 90];
        let se = block_standard_errors(&v, 10, 9, 4).unwrap();
        assert!((se[0][0] - 0.1).abs() < 1e-7, "{}", se[0][0]);
        assert!((se[2][1] - (0.16f64 * 8.0).sqrt() / 8.0).abs() < 1e-7);
        assert!((se[8][2] - (0.16f64 * 2.0).sqrt() / 2.0).abs() < 1e-7);
        // Two noisy halves of a known picture: the errors of their mean's blocks, divided by
        // the standard errors estimated from the halves alone, spread with unit variance.
        let (w, h) = (128usize, 128usize);
        let r = pattern(w, h);
        let half = |seed: u64| -> Vec<[f32; 3]> {
            r.iter()
                .enumerate()
                .map(|(i, p)| [0, 1, 2].map(|c| p[c] * (1.0 + 0.6 * noise(seed + c as u64, i))))
                .collect()
        };
        let (a, b) = (half(10), half(20));
        let mean: Vec<[f32; 3]> = a
            .iter()
            .zip(&b)
            .map(|(x, y)| [0, 1, 2].map(|c| 0.5 * (x[c] + y[c])))
            .collect();
        let var: Vec<[f32; 3]> = a
            .iter()
            .zip(&b)
            .map(|(x, y)| [0, 1, 2].map(|c| (0.5 * (x[c] - y[c])).powi(2)))
            .collect();
        let se = block_standard_errors(&var, 128, 128, 8).unwrap();
        let tm = block_means(&mean, 128, 128, 8).unwrap();
        let rm = block_means(&r, 128, 128, 8).unwrap();
        let mut z2 = 0.0;
        for k in 0..tm.len() {
            for c in 0..3 {
                z2 += ((tm[k][c] - rm[k][c]) / se[k][c]).powi(2);
            }
        }
        let z_rms = (z2 / (3 * tm.len()) as f64).sqrt();
        assert!((z_rms - 1.0).abs() < 0.1, "z rms {z_rms}");
    }

    #[test]
    fn a_wrong_hue_counts_like_a_wrong_brightness() {
        // Only the blue channel is 10 % low: the block error is -10 %.
        let r = pattern(16, 16);
        let t: Vec<[f32; 3]> = r.iter().map(|p| [p[0], p[1], p[2] * 0.9]).collect();
        let e = block_errors(&t, &r, 16, 16, 8, BLOCK_FLOOR).unwrap();
        for v in &e.errors {
            assert!((v + 0.1).abs() < 1e-6, "{v}");
        }
        assert!(e.channel.iter().all(|&c| c == 2));
        let mut bad = t.clone();
        bad[0] = [f32::NAN; 3];
        assert!(
            block_errors(&bad, &r, 16, 16, 8, BLOCK_FLOOR)
                .unwrap()
                .errors[0]
                .is_nan()
        );
    }
}
