//! Bloom: bright pass, two box-blur passes, add back. The CPU mirror of `bloom.wgsl`.
//!
//! The effect of the paper (section *Bloom*): isolate the bright parts of the image, blur them
//! with a horizontal then a vertical box blur, and add them back. Precisely, for an image `p`
//! of packed RGB f32 triples (row-major, `width * height` pixels), per channel:
//!
//! 1. [`bloom_threshold`]: `bright = max(p - threshold, 0)`, per channel. (Per channel rather
//!    than on luminance: a saturated red light blooms red, and the analytic answers stay
//!    simple: one bright pixel `p` spreads `p - threshold` of light.)
//! 2. [`bloom_h`]: `tmp(x, y) = mean of bright(x', y)` over `x'` in `[x - r, x + r]` ∩ image.
//! 3. [`bloom_v`]: `blur(x, y) = mean of tmp(x, y')` over `y'` in `[y - r, y + r]` ∩ image.
//! 4. [`bloom_add`]: `p += strength * blur`.
//!
//! **Edges.** The window is clipped to the image and the sum is divided by the number of taps
//! inside it (`2r + 1` away from the edges, fewer near them). A flat region therefore stays flat
//! up to the border (no dark frame, as zero padding gives, and no over-weighted edge pixel, as
//! clamp-to-edge sampling gives), and no light is invented from outside the image. A radius
//! larger than the image is allowed: every window then covers the whole row or column. Radius 0
//! is the identity blur.
//!
//! **Summation order.** Each output is a direct sum over its window in ascending coordinate
//! order, then one division by the tap count: the same operations in the same order as the WGSL,
//! so CPU and GPU agree to a few ulps (all terms are >= 0, so there is no cancellation; the
//! GPU's division is within 2.5 ulp in Vulkan). The cost is `O(min(2r + 1, width))` per pixel
//! and pass. A running (sliding-window) sum would be `O(1)`, but it subtracts, so its error grows
//! along the row and depends on the order of the whole row, and on the GPU it runs one thread
//! per row (1000 threads for a 1000x1000 image, too few to fill a large GPU). Bloom radii are
//! small (the scene format's example uses 8), where the direct sum is cheap on both sides.
//!
//! Non-finite input (NaN, infinity) is not sanitised: on the CPU it follows `f32::max` and IEEE
//! arithmetic; on the GPU the result is unspecified, since WGSL lets implementations assume
//! finite floats. The tracer never produces such values; the tone mapper handles them.

use rayon::prelude::*;

use crate::PostError;
use crate::error::check_image;

/// Bloom parameters. `Copy`; checked by [`BloomParams::validate`] before every use.
///
/// Mirrors the scene file's `[post.bloom]` table (`raylume_scene::Bloom`), which the facade maps
/// onto this struct.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BloomParams {
    /// Radiance above which a channel contributes to the bloom. Finite, `>= 0`.
    pub threshold: f32,
    /// Box-blur half-width in pixels: the window is `2 * radius + 1` wide. 0 = no blur.
    /// Any value is allowed; windows are clipped to the image.
    pub radius: u32,
    /// Weight of the blurred bright pass added back. Finite, `>= 0`; 0 = the image unchanged.
    pub strength: f32,
}

impl BloomParams {
    /// The scene format's example: threshold 1, radius 8, strength 0.3.
    pub const fn scene_default() -> Self {
        Self {
            threshold: 1.0,
            radius: 8,
            strength: 0.3,
        }
    }

    /// Fails with [`PostError::BadParam`] unless threshold and strength are finite and `>= 0`.
    pub fn validate(&self) -> Result<(), PostError> {
        for (what, value) in [
            ("bloom threshold", self.threshold),
            ("bloom strength", self.strength),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(PostError::BadParam {
                    what,
                    value: value.to_string(),
                    requirement: "must be finite and >= 0",
                });
            }
        }
        Ok(())
    }

    /// True when bloom leaves every image unchanged (`strength == 0`): no pass needs to run.
    pub fn is_identity(&self) -> bool {
        self.strength == 0.0
    }
}

/// The window `[lo, hi]` of half-width `r` around `i`, clipped to `0..len`. Never overflows,
/// whatever `r` is. Same function in the WGSL.
#[inline]
pub fn box_window(i: u32, r: u32, len: u32) -> (u32, u32) {
    debug_assert!(i < len);
    (i - r.min(i), i + r.min(len - 1 - i))
}

/// Bright pass: `dst = max(src - threshold, 0)` per channel.
pub fn bloom_threshold(src: &[[f32; 3]], dst: &mut [[f32; 3]], threshold: f32) {
    debug_assert_eq!(src.len(), dst.len());
    dst.par_iter_mut().zip(src.par_iter()).for_each(|(d, s)| {
        *d = s.map(|v| (v - threshold).max(0.0));
    });
}

/// Horizontal box blur: the mean over the in-image part of each pixel's `2r + 1` window, summed
/// left to right.
///
/// Pixels whose window lies inside the row are summed together, tap by tap (`acc[x] +=
/// row[x - r + k]` for k = 0..=2r over all of them at once), which vectorises and still adds
/// each pixel's taps in ascending order, as the GPU does; the few pixels near the ends are
/// summed one by one.
pub fn bloom_h(src: &[[f32; 3]], dst: &mut [[f32; 3]], width: u32, height: u32, radius: u32) {
    debug_assert_eq!(src.len(), (width as usize) * (height as usize));
    debug_assert_eq!(dst.len(), src.len());
    let w = width as usize;
    // Interior pixels x in [a, b): their whole window is inside the row.
    let (a, b) = if 2 * u64::from(radius) < u64::from(width) {
        (radius as usize, w - radius as usize)
    } else {
        (w, w)
    };
    dst.par_chunks_mut(w)
        .zip(src.par_chunks(w))
        .for_each(|(out, row)| {
            for x in (0..a.min(w)).chain(b.max(a)..w) {
                let (lo, hi) = box_window(x as u32, radius, width);
                let mut sum = [0.0f32; 3];
                for s in &row[lo as usize..=hi as usize] {
                    for c in 0..3 {
                        sum[c] += s[c];
                    }
                }
                let n = (hi - lo + 1) as f32;
                out[x] = sum.map(|v| v / n);
            }
            if a < b {
                let r = radius as usize;
                let acc: &mut [f32] = bytemuck::cast_slice_mut(&mut out[a..b]);
                let flat: &[f32] = bytemuck::cast_slice(row);
                acc.fill(0.0);
                for k in 0..=2 * r {
                    let taps = &flat[3 * (a - r + k)..3 * (b - r + k)];
                    for (o, t) in acc.iter_mut().zip(taps) {
                        *o += t;
                    }
                }
                let n = (2 * r + 1) as f32;
                for o in acc.iter_mut() {
                    *o /= n;
                }
            }
        });
}

/// Vertical box blur: the mean over the in-image part of each pixel's `2r + 1` window, summed
/// top to bottom. Accumulates whole rows so that memory is read row by row and the adds
/// vectorise; each pixel still sums its own column in ascending order, as the GPU does.
pub fn bloom_v(src: &[[f32; 3]], dst: &mut [[f32; 3]], width: u32, height: u32, radius: u32) {
    debug_assert_eq!(src.len(), (width as usize) * (height as usize));
    debug_assert_eq!(dst.len(), src.len());
    let w = width as usize;
    let flat: &[f32] = bytemuck::cast_slice(src);
    dst.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let (lo, hi) = box_window(y as u32, radius, height);
        let acc: &mut [f32] = bytemuck::cast_slice_mut(out);
        acc.fill(0.0);
        for yy in lo as usize..=hi as usize {
            for (o, s) in acc.iter_mut().zip(&flat[3 * yy * w..3 * (yy + 1) * w]) {
                *o += s;
            }
        }
        let n = (hi - lo + 1) as f32;
        for o in acc.iter_mut() {
            *o /= n;
        }
    });
}

/// Add back: `image += strength * blurred`, per channel.
pub fn bloom_add(image: &mut [[f32; 3]], blurred: &[[f32; 3]], strength: f32) {
    debug_assert_eq!(image.len(), blurred.len());
    image
        .par_iter_mut()
        .zip(blurred.par_iter())
        .for_each(|(p, b)| {
            for c in 0..3 {
                p[c] += strength * b[c];
            }
        });
}

/// Applies bloom in place on the CPU (rayon): the four stages above, in order. The reference
/// for [`crate::GpuBloom`]. Does nothing when `params.strength == 0`.
pub fn bloom_cpu(
    pixels: &mut [[f32; 3]],
    width: u32,
    height: u32,
    params: BloomParams,
) -> Result<(), PostError> {
    params.validate()?;
    check_image("bloom image", pixels.len(), width, height)?;
    if params.is_identity() {
        return Ok(());
    }
    let mut bright = vec![[0.0f32; 3]; pixels.len()];
    let mut tmp = vec![[0.0f32; 3]; pixels.len()];
    bloom_threshold(pixels, &mut bright, params.threshold);
    bloom_h(&bright, &mut tmp, width, height, params.radius);
    bloom_v(&tmp, &mut bright, width, height, params.radius);
    bloom_add(pixels, &bright, params.strength);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(threshold: f32, radius: u32, strength: f32) -> BloomParams {
        BloomParams {
            threshold,
            radius,
            strength,
        }
    }

    #[test]
    fn windows_clip_without_overflow() {
        assert_eq!(box_window(0, 0, 1), (0, 0));
        assert_eq!(box_window(5, 2, 10), (3, 7));
        assert_eq!(box_window(1, 2, 10), (0, 3));
        assert_eq!(box_window(8, 2, 10), (6, 9));
        assert_eq!(box_window(3, u32::MAX, 7), (0, 6));
    }

    #[test]
    fn bad_params_are_typed_errors() {
        for p in [
            params(-1.0, 1, 1.0),
            params(f32::NAN, 1, 1.0),
            params(1.0, 1, f32::INFINITY),
            params(1.0, 1, -0.5),
        ] {
            let mut img = vec![[1.0; 3]; 4];
            let err = bloom_cpu(&mut img, 2, 2, p).unwrap_err();
            assert!(matches!(err, PostError::BadParam { .. }), "{p:?}: {err}");
        }
        assert!(params(0.0, 0, 0.0).validate().is_ok());
    }

    #[test]
    fn bad_sizes_are_typed_errors() {
        let p = BloomParams::scene_default();
        let mut img = vec![[1.0; 3]; 6];
        assert!(matches!(
            bloom_cpu(&mut img, 0, 6, p),
            Err(PostError::ZeroSize { .. })
        ));
        assert!(matches!(
            bloom_cpu(&mut img, 2, 2, p),
            Err(PostError::SizeMismatch {
                got: 6,
                expected: 4,
                ..
            })
        ));
    }

    /// One bright pixel `b` far from the edges spreads to a (2r+1)^2 box of
    /// `(b - t) * s / (2r+1)^2` on top of the image; everything else is unchanged.
    #[test]
    fn single_pixel_spreads_to_a_box() {
        let (w, h, r) = (15u32, 13u32, 2u32);
        let (t, s, b, bg) = (1.0f32, 0.5f32, 10.0f32, 0.25f32);
        let (px, py) = (7u32, 6u32);
        let mut img = vec![[bg; 3]; (w * h) as usize];
        img[(py * w + px) as usize] = [b, 2.0 * b, 0.5];
        bloom_cpu(&mut img, w, h, params(t, r, s)).unwrap();
        let n = ((2 * r + 1) * (2 * r + 1)) as f32;
        for y in 0..h {
            for x in 0..w {
                let inside = x.abs_diff(px) <= r && y.abs_diff(py) <= r;
                let centre = x == px && y == py;
                let base = if centre { [b, 2.0 * b, 0.5] } else { [bg; 3] };
                let add = if inside {
                    [(b - t) * s / n, (2.0 * b - t) * s / n, 0.0]
                } else {
                    [0.0; 3]
                };
                for c in 0..3 {
                    let want = base[c] + add[c];
                    let got = img[(y * w + x) as usize][c];
                    // Sums of a handful of exact terms and one division: a few ulps.
                    assert!(
                        (got - want).abs() <= 1e-6 * want.abs(),
                        "({x},{y})[{c}]: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// A bright pixel in the corner: windows are clipped and divided by their in-image tap
    /// count. With r = 1 the horizontal pass gives b/2 at x = 0 (taps 0..=1) and b/3 at x = 1
    /// (taps 0..=2); the vertical pass divides by 2 again at y = 0 and by 3 at y = 1.
    #[test]
    fn corner_pixel_uses_in_image_tap_counts() {
        let (w, h) = (4u32, 4u32);
        let b = 36.0f32;
        let mut img = vec![[0.0; 3]; 16];
        img[0] = [b; 3];
        bloom_cpu(&mut img, w, h, params(0.0, 1, 1.0)).unwrap();
        let want = |x: u32, y: u32| -> f32 {
            let base = if x == 0 && y == 0 { b } else { 0.0 };
            let hx = [b / 2.0, b / 3.0, 0.0, 0.0][x as usize];
            let vy = [1.0 / 2.0, 1.0 / 3.0, 0.0, 0.0][y as usize];
            base + hx * vy
        };
        for y in 0..h {
            for x in 0..w {
                let got = img[(y * w + x) as usize][1];
                assert!((got - want(x, y)).abs() <= 1e-5, "({x},{y}): {got}");
            }
        }
    }

    /// Radius 0 is the identity blur: with threshold 0 and strength 1 every pixel doubles.
    #[test]
    fn radius_zero_threshold_zero_doubles() {
        let mut img: Vec<[f32; 3]> = (0..35)
            .map(|i| [i as f32 * 0.37, 1.5, (i % 4) as f32])
            .collect();
        let orig = img.clone();
        bloom_cpu(&mut img, 7, 5, params(0.0, 0, 1.0)).unwrap();
        for (g, o) in img.iter().zip(&orig) {
            // p + 1 * (p / 1): exact in binary floating point.
            assert_eq!(*g, o.map(|v| 2.0 * v));
        }
    }

    /// A constant image stays constant everywhere, borders included: every window's mean is the
    /// constant, whatever its tap count.
    #[test]
    fn constant_image_stays_constant() {
        let (w, h) = (9u32, 6u32);
        for r in [0, 1, 3, 50] {
            let mut img = vec![[3.0f32, 1.5, 0.5]; (w * h) as usize];
            bloom_cpu(&mut img, w, h, params(1.0, r, 0.5)).unwrap();
            for p in &img {
                // 3 + 0.5 * 2 = 4, 1.5 + 0.5 * 0.5 = 1.75, 0.5 + 0 = 0.5; sums of equal terms
                // divided by their count are within an ulp or two of the term.
                assert!((p[0] - 4.0).abs() < 1e-5, "r={r} {p:?}");
                assert!((p[1] - 1.75).abs() < 1e-5, "r={r} {p:?}");
                assert_eq!(p[2], 0.5, "r={r}");
            }
        }
    }

    /// With a radius covering the whole image, every window is a whole row then a whole column,
    /// so the blur is the global mean of the bright pass.
    #[test]
    fn huge_radius_adds_the_global_mean() {
        let (w, h) = (5u32, 3u32);
        let orig: Vec<[f32; 3]> = (0..15).map(|i| [i as f32, 0.0, 2.0]).collect();
        let mut img = orig.clone();
        bloom_cpu(&mut img, w, h, params(4.0, 1000, 2.0)).unwrap();
        // Bright pass of channel 0: max(i - 4, 0) for i in 0..15 sums to 1 + 2 + ... + 10 = 55.
        let mean = 55.0f32 / 15.0;
        for (g, o) in img.iter().zip(&orig) {
            assert!((g[0] - (o[0] + 2.0 * mean)).abs() < 1e-5, "{g:?}");
            assert_eq!(g[1], 0.0);
            assert_eq!(g[2], 2.0);
        }
    }

    #[test]
    fn zero_strength_is_identity() {
        let orig: Vec<[f32; 3]> = (0..12).map(|i| [i as f32 * 5.0; 3]).collect();
        let mut img = orig.clone();
        bloom_cpu(&mut img, 4, 3, params(0.0, 3, 0.0)).unwrap();
        assert_eq!(img, orig);
    }

    /// The definition, one pixel at a time: what the vectorised passes must reproduce bit for
    /// bit (same taps, same order).
    fn naive_blur(src: &[[f32; 3]], w: u32, h: u32, r: u32, horizontal: bool) -> Vec<[f32; 3]> {
        let mut out = vec![[0.0f32; 3]; src.len()];
        for y in 0..h {
            for x in 0..w {
                let (i, len) = if horizontal { (x, w) } else { (y, h) };
                let (lo, hi) = box_window(i, r, len);
                let mut sum = [0.0f32; 3];
                for t in lo..=hi {
                    let (tx, ty) = if horizontal { (t, y) } else { (x, t) };
                    let p = src[(ty * w + tx) as usize];
                    for c in 0..3 {
                        sum[c] += p[c];
                    }
                }
                out[(y * w + x) as usize] = sum.map(|v| v / (hi - lo + 1) as f32);
            }
        }
        out
    }

    #[test]
    fn fast_passes_equal_the_definition_bitwise() {
        for (w, h) in [(1u32, 1u32), (2, 5), (7, 3), (16, 9), (33, 4)] {
            let src: Vec<[f32; 3]> = (0..w * h)
                .map(|i| {
                    let v = ((i.wrapping_mul(2_654_435_761) >> 8) % 1000) as f32 * 0.137;
                    [v, v * 0.3 + 1.0, (i % 7) as f32 * 11.1]
                })
                .collect();
            for r in [0, 1, 2, 3, 7, 8, 16, 17, 40] {
                let mut out = vec![[0.0f32; 3]; src.len()];
                bloom_h(&src, &mut out, w, h, r);
                assert_eq!(out, naive_blur(&src, w, h, r, true), "h {w}x{h} r={r}");
                bloom_v(&src, &mut out, w, h, r);
                assert_eq!(out, naive_blur(&src, w, h, r, false), "v {w}x{h} r={r}");
            }
        }
    }
}
