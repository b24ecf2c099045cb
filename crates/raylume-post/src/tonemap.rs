//! Tone mapping for 8-bit output: exposure, a curve, sRGB encoding, quantisation.
//!
//! Per channel `v` of a linear HDR pixel:
//! 1. exposure: `v * 2^exposure` ([`ToneMap::exposure`] is in stops);
//! 2. a [`ToneCurve`] maps `[0, inf)` into `[0, 1]`;
//! 3. [`srgb_encode`]: the IEC 61966-2-1 transfer function;
//! 4. [`quantize`]: `round(255 * v)`.
//!
//! **Non-finite input** never panics: NaN becomes 0 (black, so a broken sample shows as a dark
//! speck rather than a bright one), `+inf` becomes 1 after the curve (white), and negative
//! values, `-inf` included, become 0.
//!
//! **CPU only, on purpose.** Tone mapping runs once per image and is a few dozen flops per
//! pixel (the sRGB power looked up: [`srgb8`]): a few milliseconds for 1M pixels with rayon,
//! less than copying the HDR image
//! back from the GPU, which has to happen anyway to save it. A kernel would add a pipeline and
//! a second (8-bit) read-back for no gain.

use rayon::prelude::*;

use crate::PostError;

/// The curve applied after exposure. Each maps `[0, inf)` monotonically into `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ToneCurve {
    /// No curve: `clamp(x, 0, 1)`. Everything above 1 clips to white.
    Clamp,
    /// Reinhard's simple global operator, `x / (1 + x)` per channel (E. Reinhard, M. Stark,
    /// P. Shirley, J. Ferwerda, *Photographic Tone Reproduction for Digital Images*,
    /// SIGGRAPH 2002, eq. 3). Never reaches white; keeps detail in highlights.
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve (K. Narkowicz, *ACES Filmic Tone Mapping
    /// Curve*, 2016): `clamp(x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), 0, 1)` per channel.
    /// Applied as published, without a pre-scale (the 0.6 pre-scale some engines use is an
    /// exposure of `log2(0.6)`, about -0.74 stops). Reaches white (1) at x ≈ 7.24.
    #[default]
    Aces,
}

impl ToneCurve {
    /// The curve at `x >= 0` (finite). Results are in `[0, 1]`. Evaluated in f64 and rounded
    /// once: in f32, `x / (1 + x)` steps down near 1 where `1 + x` rounds, and ACES's `x^2`
    /// overflows; in f64 `1 + x` is exact below 2^53 and nothing overflows.
    pub fn apply(self, x: f32) -> f32 {
        debug_assert!(x >= 0.0 && x.is_finite());
        let x = f64::from(x);
        let v = match self {
            ToneCurve::Clamp => x,
            ToneCurve::Reinhard => x / (1.0 + x),
            ToneCurve::Aces => {
                const A: f64 = 2.51;
                const B: f64 = 0.03;
                const C: f64 = 2.43;
                const D: f64 = 0.59;
                const E: f64 = 0.14;
                (x * (A * x + B)) / (x * (C * x + D) + E)
            }
        };
        v.clamp(0.0, 1.0) as f32
    }
}

/// Tone-mapping settings. `Copy`; checked by [`ToneMap::validate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToneMap {
    /// Exposure in stops: pixels are multiplied by `2^exposure` before the curve. Finite.
    pub exposure: f32,
    /// The curve.
    pub curve: ToneCurve,
}

impl Default for ToneMap {
    fn default() -> Self {
        Self::aces()
    }
}

impl ToneMap {
    /// No exposure change, no curve: values in `[0, 1]` are only sRGB-encoded and quantised.
    pub const fn clamp() -> Self {
        Self {
            exposure: 0.0,
            curve: ToneCurve::Clamp,
        }
    }

    /// Reinhard at exposure 0.
    pub const fn reinhard() -> Self {
        Self {
            exposure: 0.0,
            curve: ToneCurve::Reinhard,
        }
    }

    /// ACES (Narkowicz) at exposure 0. The default.
    pub const fn aces() -> Self {
        Self {
            exposure: 0.0,
            curve: ToneCurve::Aces,
        }
    }

    /// Fails unless the exposure is finite.
    pub fn validate(&self) -> Result<(), PostError> {
        if !self.exposure.is_finite() {
            return Err(PostError::BadParam {
                what: "exposure",
                value: self.exposure.to_string(),
                requirement: "must be finite (stops)",
            });
        }
        Ok(())
    }

    /// One linear channel to its display value in `[0, 1]` (before sRGB encoding): exposure,
    /// then the curve, with non-finite values handled as the module docs say.
    pub fn map_channel(&self, v: f32) -> f32 {
        self.map_scaled(v, self.exposure.exp2())
    }

    /// [`ToneMap::map_channel`] with `2^exposure` given (`scale`): computed once per image,
    /// not per channel.
    #[inline]
    fn map_scaled(&self, v: f32, scale: f32) -> f32 {
        if v.is_nan() || v <= 0.0 {
            return 0.0;
        }
        let x = v * scale;
        if x.is_infinite() {
            return 1.0;
        }
        if x.is_nan() {
            return 0.0;
        }
        self.curve.apply(x)
    }

    /// One linear pixel to 8-bit sRGB.
    pub fn pixel_to_srgb8(&self, p: [f32; 3]) -> [u8; 3] {
        let scale = self.exposure.exp2();
        p.map(|v| srgb8(self.map_scaled(v, scale)))
    }

    /// Linear HDR pixels to 8-bit sRGB, in parallel (rayon). Fails only on a non-finite exposure.
    pub fn to_srgb8(&self, pixels: &[[f32; 3]]) -> Result<Vec<[u8; 3]>, PostError> {
        self.validate()?;
        let scale = self.exposure.exp2();
        Ok(pixels
            .par_iter()
            .map(|&p| p.map(|v| srgb8(self.map_scaled(v, scale))))
            .collect())
    }
}

/// The sRGB transfer function (IEC 61966-2-1:1999): `12.92 x` for `x <= 0.0031308`, else
/// `1.055 x^(1/2.4) - 0.055`. Input is clamped to `[0, 1]`; NaN gives 0.
pub fn srgb_encode(linear: f32) -> f32 {
    if linear.is_nan() || linear <= 0.0 {
        return 0.0;
    }
    // In f64, rounded once: in f32, 1.055 - 0.055 is 0.99999994, not 1.
    let x = f64::from(linear.min(1.0));
    let v = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    v as f32
}

/// `quantize(srgb_encode(v))`, the 8-bit sRGB code of `v`: the number of the 255 values where
/// the code steps up ([`srgb8_steps`]) at or below `v`, counted from the code at the start of
/// `v`'s bucket of 2^16 bit patterns (a table of 16,256 bytes; at most one step falls in a
/// bucket), instead of a power in f64 per channel or a binary search whose branches the CPU
/// cannot predict (the tone map of a 1280x720 image on the 2-core machine: 0.033 s by the
/// search, 0.00x s by the buckets). The same code for every `f32`, NaN included (tested).
#[inline]
pub fn srgb8(v: f32) -> u8 {
    // NaN, zero and below: 0, as quantize gives; 1 and above: 255 (the last step is 1 or less).
    if v.is_nan() || v <= 0.0 {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    let steps = srgb8_steps();
    let mut c = srgb8_buckets()[(v.to_bits() >> 16) as usize];
    while c < 255 && steps[usize::from(c)] <= v {
        c += 1;
    }
    c
}

/// For each bucket of bit patterns `[i << 16, (i + 1) << 16)` below 1.0, the code of its first
/// value (see [`srgb8`]).
fn srgb8_buckets() -> &'static [u8] {
    static BUCKETS: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BUCKETS.get_or_init(|| {
        let steps = srgb8_steps();
        (0..1.0f32.to_bits() >> 16)
            .map(|i| steps.partition_point(|&s| s <= f32::from_bits(i << 16)) as u8)
            .collect()
    })
}

/// For each code `c` in `1..=255`, at index `c - 1`, the smallest `f32` whose
/// `quantize(srgb_encode(v))` is at least `c`: found once by bisecting the bit patterns of
/// `[0, 1]` with those two functions (both non-decreasing), so the table cannot disagree with
/// them.
pub fn srgb8_steps() -> &'static [f32; 255] {
    static STEPS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    STEPS.get_or_init(|| {
        let code = |bits: u32| quantize(srgb_encode(f32::from_bits(bits)));
        std::array::from_fn(|i| {
            let c = i as u8 + 1;
            // The smallest bit pattern in [0, 1.0] whose code is >= c (1.0 gives 255).
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if code(mid) >= c {
                    hi = mid
                } else {
                    lo = mid + 1
                }
            }
            f32::from_bits(lo)
        })
    })
}

/// The inverse of [`srgb_encode`]: `x / 12.92` for `x <= 0.04045`, else
/// `((x + 0.055) / 1.055)^2.4`. Input is clamped to `[0, 1]`; NaN gives 0.
pub fn srgb_decode(encoded: f32) -> f32 {
    if encoded.is_nan() || encoded <= 0.0 {
        return 0.0;
    }
    let x = f64::from(encoded.min(1.0));
    let v = if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    };
    v as f32
}

/// `[0, 1]` to `0..=255`, rounding to nearest (halves up). Out-of-range input clamps; NaN gives 0.
pub fn quantize(v: f32) -> u8 {
    if v.is_nan() {
        return 0;
    }
    (v.clamp(0.0, 1.0) * 255.0 + 0.5).floor() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_known_points() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert_eq!(srgb_encode(1.0), 1.0);
        assert_eq!(quantize(srgb_encode(0.0)), 0);
        assert_eq!(quantize(srgb_encode(1.0)), 255);
        // 1.055 * 0.5^(1/2.4) - 0.055 = 0.735357, * 255 = 187.52.
        assert!((srgb_encode(0.5) - 0.735_357).abs() < 1e-5);
        assert_eq!(quantize(srgb_encode(0.5)), 188);
        // 0.18 (mid grey): 1.055 * 0.18^(1/2.4) - 0.055 = 0.461356, * 255 = 117.65.
        assert_eq!(quantize(srgb_encode(0.18)), 118);
        // The boundary: the linear segment gives 12.92 * 0.0031308 = 0.040450; the power
        // segment is continuous there to within 1e-6 (the standard's constants are rounded).
        let b = 0.003_130_8f32;
        assert!((srgb_encode(b) - 0.040_45).abs() < 1e-6);
        let above = 1.055 * (b * (1.0 + 1e-6)).powf(1.0 / 2.4) - 0.055;
        assert!((srgb_encode(b * (1.0 + 1e-6)) - above).abs() < 1e-7);
        assert!((above - 0.040_45).abs() < 1e-5);
        // Linear segment slope.
        assert!((srgb_encode(0.001) - 0.012_92).abs() < 1e-7);
    }

    #[test]
    fn srgb_round_trips_every_code() {
        for code in 0..=255u8 {
            let lin = srgb_decode(f32::from(code) / 255.0);
            assert_eq!(quantize(srgb_encode(lin)), code);
        }
    }

    /// `srgb8` is `quantize(srgb_encode(v))` for every `f32`: at each step and the float
    /// below it (which, both functions being non-decreasing, pins the table down exactly),
    /// over the whole of `[0, 1]` in strides, and outside it.
    #[test]
    fn srgb8_is_the_encoding_quantised() {
        let want = |v: f32| quantize(srgb_encode(v));
        for (i, &step) in srgb8_steps().iter().enumerate() {
            let below = f32::from_bits(step.to_bits() - 1);
            assert_eq!(want(step), i as u8 + 1, "step {i}: {step}");
            assert_eq!(want(below), i as u8, "below step {i}: {below}");
            assert_eq!(srgb8(step), want(step));
            assert_eq!(srgb8(below), want(below));
        }
        let one = 1.0f32.to_bits();
        for bits in (0..=one).step_by(997) {
            let v = f32::from_bits(bits);
            assert_eq!(srgb8(v), want(v), "{v}");
        }
        // Every bucket's first and last bit pattern, where the bucket table could go wrong.
        for i in 0..=one >> 16 {
            for bits in [i << 16, ((i + 1) << 16) - 1] {
                let v = f32::from_bits(bits);
                assert_eq!(srgb8(v), want(v), "{v} ({bits:#x})");
            }
        }
        for v in [
            -0.0,
            -1.0,
            1.5,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
        ] {
            assert_eq!(srgb8(v), want(v), "{v}");
        }
    }

    #[test]
    fn quantize_rounds_to_nearest() {
        assert_eq!(quantize(0.5 / 255.0 - 1e-6), 0);
        assert_eq!(quantize(0.5 / 255.0 + 1e-6), 1);
        assert_eq!(quantize(-3.0), 0);
        assert_eq!(quantize(7.0), 255);
        assert_eq!(quantize(f32::NAN), 0);
    }

    #[test]
    fn curves_are_monotonic_and_bounded() {
        for curve in [ToneCurve::Clamp, ToneCurve::Reinhard, ToneCurve::Aces] {
            let mut prev = curve.apply(0.0);
            assert!(prev.abs() < 1e-6, "{curve:?}(0) = {prev}");
            let mut x = 1e-4f32;
            while x < 1e30 {
                let v = curve.apply(x);
                assert!((0.0..=1.0).contains(&v), "{curve:?}({x}) = {v}");
                assert!(v >= prev, "{curve:?} decreases at {x}: {prev} -> {v}");
                prev = v;
                x *= 1.05;
            }
            assert!(curve.apply(f32::MAX) <= 1.0);
        }
        assert_eq!(ToneCurve::Reinhard.apply(1.0), 0.5);
        assert_eq!(ToneCurve::Clamp.apply(0.25), 0.25);
        // ACES at 1: (2.51 + 0.03) / (2.43 + 0.59 + 0.14) = 2.54 / 3.16.
        assert!((ToneCurve::Aces.apply(1.0) - 2.54 / 3.16).abs() < 1e-6);
        assert_eq!(ToneCurve::Aces.apply(f32::MAX), 1.0);
    }

    #[test]
    fn exposure_is_in_stops() {
        let tm = ToneMap {
            exposure: 1.0,
            curve: ToneCurve::Reinhard,
        };
        // 0.5 * 2 = 1 -> 1 / 2.
        assert_eq!(tm.map_channel(0.5), 0.5);
        let tm = ToneMap {
            exposure: -2.0,
            curve: ToneCurve::Clamp,
        };
        assert_eq!(tm.map_channel(2.0), 0.5);
    }

    #[test]
    fn non_finite_pixels_are_defined() {
        let tm = ToneMap::aces();
        assert_eq!(
            tm.pixel_to_srgb8([f32::NAN, f32::INFINITY, f32::NEG_INFINITY]),
            [0, 255, 0]
        );
        assert_eq!(tm.pixel_to_srgb8([-1.0, 0.0, 1e38]), [0, 0, 255]);
        // Exposure that overflows a finite value to infinity still gives white.
        let bright = ToneMap {
            exposure: 100.0,
            curve: ToneCurve::Reinhard,
        };
        assert_eq!(bright.pixel_to_srgb8([1e10; 3]), [255; 3]);
        let bad = ToneMap {
            exposure: f32::NAN,
            curve: ToneCurve::Clamp,
        };
        assert!(matches!(
            bad.to_srgb8(&[[0.5; 3]]),
            Err(PostError::BadParam { .. })
        ));
    }

    #[test]
    fn clamp_curve_is_plain_srgb() {
        let tm = ToneMap::clamp();
        let px = [[0.0, 0.5, 1.0], [2.0, 0.18, 0.001]];
        let out = tm.to_srgb8(&px).unwrap();
        assert_eq!(out, vec![[0, 188, 255], [255, 118, 3]]);
    }
}
