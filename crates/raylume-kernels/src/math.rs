//! Rust spellings of the WGSL builtins the kernels use, with WGSL's definitions, so that the
//! mirror performs the same operations in the same order.

use glam::Vec3;

/// WGSL `normalize`.
#[inline]
pub fn normalize(v: Vec3) -> Vec3 {
    v * (1.0 / v.dot(v).sqrt())
}

/// WGSL `reflect(e1, e2) = e1 - 2 * dot(e2, e1) * e2`.
#[inline]
pub fn reflect(e1: Vec3, e2: Vec3) -> Vec3 {
    e1 - e2 * (2.0 * e2.dot(e1))
}

/// True for a finite float, tested on its bits (as in WGSL, where there is no `isFinite`
/// and a fast-math compiler may fold `x == x`).
#[inline]
pub fn is_finite_f32(x: f32) -> bool {
    (x.to_bits() & 0x7f80_0000) != 0x7f80_0000
}

/// True when every component is finite.
#[inline]
pub fn is_finite3(v: Vec3) -> bool {
    is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z)
}

/// The brightest sample kept: 2^94 (about 1.98e28). A pixel sums up to `u32::MAX` samples in
/// `f32` before dividing by their count, and 2^32 samples of 2^94 sum to at most 2^126, below
/// `f32::MAX` (about 2^128): so finite samples can never add up to an infinite pixel.
pub const MAX_SAMPLE_RADIANCE: f32 = f32::from_bits((127 + 94) << 23);

/// True when a sample's radiance may be written: finite and at most [`MAX_SAMPLE_RADIANCE`].
/// Anything else is dropped and counted.
#[inline]
pub fn sample_is_valid(v: Vec3) -> bool {
    is_finite3(v) && v.x.max(v.y.max(v.z)) <= MAX_SAMPLE_RADIANCE
}

pub const PI: f32 = std::f32::consts::PI;
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
pub const INV_2PI: f32 = 0.5 * std::f32::consts::FRAC_1_PI;

/// The WGSL source of the helpers above (`is_finite3`, `PI`, ...).
pub const MATH_WGSL: &str = include_str!("math.wgsl");

/// `atan2(y, x)` in `[-π, π]` from a degree-15 odd minimax polynomial for `atan` on `[0, 1]`
/// (Hastings' coefficients; error below 4e-8 rad) and octant reduction: only `+ - * /` and
/// comparisons, so the CPU and every GPU agree to rounding, unlike the drivers' `atan2`
/// (Vulkan allows 4096 ULP). The coefficients are written as the exact `f32` values, so the
/// WGSL literals (parsed as f64, then rounded) are the same `f32`s.
#[inline]
#[allow(clippy::excessive_precision)]
pub fn atan2_poly(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let hi = ax.max(ay);
    let lo = ax.min(ay);
    let a = if hi > 0.0 { lo / hi } else { 0.0 };
    let s = a * a;
    let mut r = -0.004054057877510786;
    r = r * s + 0.021861229091882706;
    r = r * s - 0.055909886956214905;
    r = r * s + 0.0964200422167778;
    r = r * s - 0.1390853226184845;
    r = r * s + 0.19946536421775818;
    r = r * s - 0.33329856395721436;
    r = r * s + 0.9999993443489075;
    r *= a;
    if ay > ax {
        r = 0.5 * PI - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 { -r } else { r }
}

/// `1.5 * 2^23`: `(x + SIN_COS_ROUND) - SIN_COS_ROUND` is `x` rounded to the nearest integer
/// (ties to even) for `|x| < 2^22`, by two additions.
pub const SIN_COS_ROUND: f32 = 12_582_912.0;

/// `(sin 2πt, cos 2πt)` for `|t| < 2^20` turns, without branching on the angle's range: `4t` (exact) less its
/// nearest integer `q` (exact) is the quarter turn's fraction `r` in `[-1/2, 1/2]`, the angle
/// `a = r π/2` (one rounding) is given to Cephes' `sinf`/`cosf` minimax polynomials on
/// `[-π/4, π/4]` (each within about an ulp), and the quadrant `q mod 4` swaps and negates them.
/// The path's angles are all `2π u` of a random `u`: libm's `sinf`/`cosf` branched on the
/// angle's range (~13 % of Bitterli's Cornell box's mispredicted branches under cachegrind)
/// and ran one value at a time; this is the same arithmetic in `cpu::packet`'s lanes (its
/// `sin_cos_turns`), so eight paths take their angles at once, the same bits.
#[inline]
#[allow(clippy::excessive_precision)]
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    let x = 4.0 * t;
    let q = (x + SIN_COS_ROUND) - SIN_COS_ROUND;
    let a = (x - q) * std::f32::consts::FRAC_PI_2;
    let z = a * a;
    let s = ((SIN_COS_S3 * z + SIN_COS_S2) * z + SIN_COS_S1) * z * a + a;
    let c = ((SIN_COS_C3 * z + SIN_COS_C2) * z + SIN_COS_C1) * z * z - 0.5 * z + 1.0;
    let m = q as i32 & 3;
    // A quarter turn: (sin, cos) -> (cos, -sin); a half turn: both negated.
    let (s, c) = std::hint::select_unpredictable(m & 1 != 0, (c, -s), (s, c));
    std::hint::select_unpredictable(m & 2 != 0, (-s, -c), (s, c))
}

/// Cephes' `sinf` coefficients (`x + x z (S1 + z (S2 + z S3))`, `z = x²`).
#[allow(clippy::excessive_precision)]
pub const SIN_COS_S1: f32 = -1.6666654611e-1;
#[allow(clippy::excessive_precision)]
pub const SIN_COS_S2: f32 = 8.3321608736e-3;
#[allow(clippy::excessive_precision)]
pub const SIN_COS_S3: f32 = -1.9515295891e-4;
/// Cephes' `cosf` coefficients (`1 - z/2 + z² (C1 + z (C2 + z C3))`).
#[allow(clippy::excessive_precision)]
pub const SIN_COS_C1: f32 = 4.166664568298827e-2;
#[allow(clippy::excessive_precision)]
pub const SIN_COS_C2: f32 = -1.388731625493765e-3;
#[allow(clippy::excessive_precision)]
pub const SIN_COS_C3: f32 = 2.443315711809948e-5;

/// `acos(x)` for `x` in `[-1, 1]` (clamped) through [`atan2_poly`].
#[inline]
pub fn acos_poly(x: f32) -> f32 {
    let c = x.clamp(-1.0, 1.0);
    atan2_poly((1.0 - c * c).max(0.0).sqrt(), c)
}

/// The equirectangular coordinates of a unit direction (no rotation): `u = 0.5 + φ / 2π`
/// with `φ = atan2(x, -z)`, `v = θ / π` from +y (math.wgsl's `direction_to_equirect`).
#[inline(always)]
pub fn direction_to_equirect(d: Vec3) -> glam::Vec2 {
    let phi = atan2_poly(d.x, -d.z);
    glam::Vec2::new(0.5 + phi * INV_2PI, acos_poly(d.y) * INV_PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One unit in the last place of `x` (its distance to the next float away from zero).
    fn ulp(x: f32) -> f64 {
        let a = x.abs();
        f64::from(f32::from_bits(a.to_bits() + 1) - a)
    }

    /// `sin_cos_turns(t)` against `f64`'s `sin`/`cos` of `2πt` (`t` exact), over a dense sweep
    /// of `[-1.5, 1.5]` (the environment map's angles reach -1.5 turns) and the quarter
    /// turns' neighbours: within 1.5e-7 absolute (the angle's own rounding, `a = r π/2`, is
    /// up to half an ulp of π/4, 3e-8, and each polynomial about an ulp of its result).
    #[test]
    fn sin_cos_turns_matches_f64() {
        let mut worst = 0.0f64;
        // Each quarter turn and the 64 floats on either side of it.
        let quarters = (-6..=6).flat_map(|k| {
            let q = k as f32 * 0.25;
            let (mut up, mut down) = (q, q);
            (0..64).flat_map(move |_| {
                (up, down) = (up.next_up(), down.next_down());
                [up, down]
            })
        });
        for t in (0..=3_000_000)
            .map(|i| i as f32 / 1_000_000.0 - 1.5)
            .chain(quarters)
        {
            assert!(t.is_finite());
            if t.abs() > 1.5 {
                continue;
            }
            let (s, c) = sin_cos_turns(t);
            let angle = std::f64::consts::TAU * f64::from(t);
            let (es, ec) = (
                (f64::from(s) - angle.sin()).abs(),
                (f64::from(c) - angle.cos()).abs(),
            );
            worst = worst.max(es).max(ec);
            assert!(
                es <= 1.5e-7 && ec <= 1.5e-7,
                "t {t}: sin {s} cos {c} off by {es:e} / {ec:e}"
            );
            assert!(s.abs() <= 1.0 && c.abs() <= 1.0, "t {t}: {s} {c}");
        }
        assert!(worst > 1e-8, "the sweep compared something ({worst:e})");
    }

    /// The WGSL's `sin_cos_turns` coefficients are the Rust constants, the same `f32`s.
    #[test]
    fn wgsl_sin_cos_coefficients_are_the_rust_ones() {
        for (name, value) in [
            ("SIN_COS_S1", SIN_COS_S1),
            ("SIN_COS_S2", SIN_COS_S2),
            ("SIN_COS_S3", SIN_COS_S3),
            ("SIN_COS_C1", SIN_COS_C1),
            ("SIN_COS_C2", SIN_COS_C2),
            ("SIN_COS_C3", SIN_COS_C3),
        ] {
            let prefix = format!("const {name}: f32 = ");
            let line = MATH_WGSL
                .lines()
                .find(|l| l.starts_with(&prefix))
                .unwrap_or_else(|| panic!("the WGSL declares {name}"));
            let literal = line.trim_end_matches(';').rsplit(' ').next().unwrap();
            assert_eq!(literal.parse::<f32>().unwrap(), value, "{name}");
        }
    }

    /// Against `f64` references, within what the documentation and the rounding allow:
    ///
    /// - `atan2_poly(y, x)`: the polynomial's 4e-8 rad (its documentation) plus 2 ulps of the
    ///   result for the rounding of the reduction (`lo / hi`, Horner's steps, `π/2 - r`,
    ///   `π - r`). Measured over this sweep: 3.4e-8 beyond the 2 ulps.
    /// - `acos_poly(c) = atan2_poly(sqrt(1 - c²), c)`: the same, plus the rounding of its
    ///   first argument. `c²` is rounded by at most 2^-25 (half an ulp below 1) and `1 - c²` is
    ///   then exact (Sterbenz) or rounded by as little, so `s = sqrt(1 - c²)` is off by at most
    ///   2^-26 / s + ulp(s) / 2 ≤ 2^-26 / s + 2^-25, and the angle by |c| ≤ 1 times that.
    ///   Allowed: twice that first-order bound. The sweep reaches c within 1 ulp of ±1, where
    ///   it dominates (measured 8.1e-7 at c = 0.99983, s = 0.0186; 96 % of the single bound).
    #[test]
    fn polynomial_atan2_and_acos_match_the_library() {
        for i in 0..=36_000 {
            let t = (i as f32 / 36_000.0 - 0.5) * 2.0 * PI;
            for r in [1e-3f32, 1.0, 7.5e4] {
                let (y, x) = (r * t.sin(), r * t.cos());
                let want = f64::from(y).atan2(f64::from(x));
                let e = (f64::from(atan2_poly(y, x)) - want).abs();
                let bound = 4e-8 + 2.0 * ulp(want as f32);
                assert!(e <= bound, "atan2({y}, {x}) off by {e:e} (bound {bound:e})");
            }
        }
        let near_one = (0..100_000u32).map(|k| f32::from_bits(1f32.to_bits() - k));
        let cs: Vec<f32> = (0..=200_000)
            .map(|i| i as f32 / 100_000.0 - 1.0)
            .chain(near_one.clone())
            .chain(near_one.map(|c| -c))
            .collect();
        for c in cs {
            let s = (1.0 - c * c).max(0.0).sqrt();
            let want = f64::from(c).acos();
            let e = (f64::from(acos_poly(c)) - want).abs();
            let sqrt_rounding = if s > 0.0 {
                2f64.powi(-26) / f64::from(s) + 2f64.powi(-25)
            } else {
                0.0
            };
            let bound = 4e-8 + 2.0 * ulp(want as f32) + 2.0 * sqrt_rounding;
            assert!(e <= bound, "acos({c}) off by {e:e} (bound {bound:e})");
        }
        assert_eq!(atan2_poly(0.0, 0.0), 0.0);
        assert_eq!(atan2_poly(0.0, -1.0), PI);
        assert_eq!(acos_poly(-1.0), PI);
        assert_eq!(acos_poly(1.0), 0.0);
    }

    /// Regression test: samples of radiance near `f32::MAX` (an emitter of 3e38 is finite and
    /// was accepted) are each finite, so they used to be kept, and their sum in `resolve`
    /// overflowed to an infinite pixel with no sample counted as dropped.
    #[test]
    fn kept_samples_cannot_sum_to_infinity() {
        assert_eq!(MAX_SAMPLE_RADIANCE, 2f32.powi(94));
        // The worst case: u32::MAX samples of the largest kept radiance, summed in f32.
        assert!((MAX_SAMPLE_RADIANCE * u32::MAX as f32).is_finite());
        assert!(sample_is_valid(Vec3::new(0.0, MAX_SAMPLE_RADIANCE, 1.0)));
        for bad in [f32::MAX, f32::INFINITY, f32::NAN, 2f32.powi(95)] {
            assert!(!sample_is_valid(Vec3::new(1.0, bad, 1.0)), "{bad}");
        }
        // The WGSL constant is the same f32.
        let line = MATH_WGSL
            .lines()
            .find(|l| l.starts_with("const MAX_SAMPLE_RADIANCE: f32 = "))
            .expect("the WGSL declares it");
        let literal = line.trim_end_matches(';').rsplit(' ').next().unwrap();
        assert_eq!(literal.parse::<f32>().unwrap(), MAX_SAMPLE_RADIANCE);
    }
}
