//! The counter-based random numbers every path draws, identical in WGSL (`rng.wgsl`) and Rust.
//!
//! A random number is a pure function of (seed, pixel, sample, bounce, dimension): no
//! generator state travels with a ray, so the CPU and the GPU, and the megakernel and the
//! wavefront, draw the same numbers for the same path vertex whatever order they run in.
//!
//! The hash is `pcg4d` from Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 9(3),
//! 2020: four rounds of multiply-add and xor-shift on a `vec4<u32>`, all wrapping `u32`
//! arithmetic, so both sides agree bit for bit. One call yields four numbers; a *dimension*
//! names such a group of four (see [`crate::gpu_types::DIM_CAMERA`] and friends).

use glam::Vec4;

/// The pcg4d hash (Jarzynski & Olano 2020, listing "pcg4d").
#[inline]
pub fn pcg4d(v: [u32; 4]) -> [u32; 4] {
    let mut v = v.map(|x| x.wrapping_mul(1664525).wrapping_add(1013904223));
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[3]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v[3] = v[3].wrapping_add(v[1].wrapping_mul(v[2]));
    v = v.map(|x| x ^ (x >> 16));
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[3]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v[3] = v[3].wrapping_add(v[1].wrapping_mul(v[2]));
    v
}

/// The hash input for one group of four numbers. `dim` must be below 16.
#[inline]
pub fn rng_key(seed: u32, pixel: u32, sample: u32, bounce: u32, dim: u32) -> [u32; 4] {
    debug_assert!(dim < 16);
    [pixel, sample, (bounce << 4) | (dim & 15), seed]
}

/// A float in `[0, 1)` from the top 24 bits of `x` (exactly representable, so identical on
/// every device).
#[inline]
pub fn rand_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Four uniform floats in `[0, 1)` for (seed, pixel, sample, bounce, dimension).
#[inline]
pub fn rand4(seed: u32, pixel: u32, sample: u32, bounce: u32, dim: u32) -> Vec4 {
    let h = pcg4d(rng_key(seed, pixel, sample, bounce, dim));
    Vec4::new(
        rand_f32(h[0]),
        rand_f32(h[1]),
        rand_f32(h[2]),
        rand_f32(h[3]),
    )
}

/// The WGSL source of the functions above.
pub const RNG_WGSL: &str = include_str!("rng.wgsl");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rand_f32_covers_the_unit_interval_and_never_reaches_one() {
        assert_eq!(rand_f32(0), 0.0);
        assert!(rand_f32(u32::MAX) < 1.0);
        assert_eq!(rand_f32(u32::MAX), 1.0 - 1.0 / 16_777_216.0);
    }

    #[test]
    fn neighbouring_keys_give_uncorrelated_uniform_numbers() {
        // Mean and variance of 4 * 65536 numbers from consecutive pixels: uniform [0,1) has
        // mean 1/2 and variance 1/12; with n = 262144 the standard error of the mean is
        // sqrt(1/12/n) ~ 5.6e-4, so 3e-3 is > 5 sigma.
        let mut sum = 0.0f64;
        let mut sum2 = 0.0f64;
        let mut lag = 0.0f64;
        let mut prev = 0.5f64;
        let n = 65536u32;
        for p in 0..n {
            let r = rand4(7, p, 3, 2, 1);
            for x in r.to_array() {
                let x = f64::from(x);
                sum += x;
                sum2 += x * x;
                lag += (x - 0.5) * (prev - 0.5);
                prev = x;
            }
        }
        let m = f64::from(n * 4);
        let mean = sum / m;
        let var = sum2 / m - mean * mean;
        assert!((mean - 0.5).abs() < 3e-3, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 3e-3, "variance {var}");
        // Lag-1 autocovariance: 0 for independent numbers, standard error (1/12)/sqrt(m).
        assert!((lag / m).abs() < 1e-3, "lag-1 covariance {}", lag / m);
    }

    #[test]
    fn every_key_component_changes_the_numbers() {
        let base = rand4(1, 2, 3, 4, 5);
        for other in [
            rand4(9, 2, 3, 4, 5),
            rand4(1, 9, 3, 4, 5),
            rand4(1, 2, 9, 4, 5),
            rand4(1, 2, 3, 9, 5),
            rand4(1, 2, 3, 4, 9),
        ] {
            assert_ne!(base, other);
        }
    }
}
