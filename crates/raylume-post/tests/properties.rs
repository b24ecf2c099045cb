//! Properties of the CPU bloom and the metrics on arbitrary small inputs.

use proptest::prelude::*;
use raylume_post::{BloomParams, bloom_cpu, mae, relative_mse, rmse};

fn image(max_side: u32) -> impl Strategy<Value = (u32, u32, Vec<[f32; 3]>)> {
    (1..=max_side, 1..=max_side).prop_flat_map(|(w, h)| {
        let px = prop::array::uniform3(0.0f32..100.0);
        (
            Just(w),
            Just(h),
            prop::collection::vec(px, (w * h) as usize),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Bloom only adds light, and adds none where nothing exceeds the threshold.
    #[test]
    fn bloom_only_adds_light(
        (w, h, img) in image(12),
        threshold in 0.0f32..120.0,
        radius in 0u32..20,
        strength in 0.0f32..2.0,
    ) {
        let p = BloomParams { threshold, radius, strength };
        let mut out = img.clone();
        bloom_cpu(&mut out, w, h, p).unwrap();
        let any_bright = img.iter().flatten().any(|&v| v > threshold);
        for (o, i) in out.iter().zip(&img) {
            for c in 0..3 {
                prop_assert!(o[c] >= i[c]);
                if !any_bright {
                    prop_assert_eq!(o[c], i[c]);
                }
            }
        }
    }

    /// A radius reaching across the image blurs every pixel to the mean of the bright pass
    /// (each window is a whole row, then a whole column of row means).
    #[test]
    fn radius_across_the_image_adds_the_mean(
        (w, h, img) in image(9),
        threshold in 0.0f32..50.0,
        strength in 0.0f32..2.0,
    ) {
        let p = BloomParams { threshold, radius: w.max(h), strength };
        let mut out = img.clone();
        bloom_cpu(&mut out, w, h, p).unwrap();
        for c in 0..3 {
            let mean = img.iter().map(|q| f64::from((q[c] - threshold).max(0.0))).sum::<f64>()
                / img.len() as f64;
            for (o, i) in out.iter().zip(&img) {
                let want = f64::from(i[c]) + f64::from(strength) * mean;
                // f32 sums of at most 9 + 9 terms below 100: a few 1e-6 relative.
                prop_assert!((f64::from(o[c]) - want).abs() <= 1e-5 * want.max(1.0),
                    "{} vs {}", o[c], want);
            }
        }
    }

    /// The metrics are zero on identical images, RMSE >= MAE (power means), and RMSE and MAE
    /// are symmetric.
    #[test]
    fn metric_identities((_, _, a) in image(6), shift in -1.0f32..1.0) {
        let b: Vec<[f32; 3]> = a.iter().enumerate()
            .map(|(i, p)| p.map(|v| v + shift * (i % 3) as f32))
            .collect();
        prop_assert_eq!(rmse(&a, &a).unwrap(), 0.0);
        prop_assert_eq!(relative_mse(&a, &a).unwrap(), 0.0);
        let (r, m) = (rmse(&a, &b).unwrap(), mae(&a, &b).unwrap());
        prop_assert!(r + 1e-12 >= m, "rmse {} < mae {}", r, m);
        prop_assert_eq!(r, rmse(&b, &a).unwrap());
        prop_assert_eq!(m, mae(&b, &a).unwrap());
    }
}
