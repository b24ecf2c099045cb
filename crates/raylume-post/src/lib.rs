//! raylume-post: what happens to the image after the tracer: bloom (GPU in WGSL, CPU mirror in
//! rayon), tone mapping to 8-bit sRGB, and image metrics.
//!
//! - [`bloom`]: the bloom of *Parallelising Ray Tracing on GPUs* (section *Bloom*): a bright
//!   pass, a horizontal and a vertical box blur, added back. [`bloom_cpu`] is the reference;
//!   [`GpuBloom`] records the same four kernels (`bloom.wgsl`: `bloom_threshold`, `bloom_h`,
//!   `bloom_v`, `bloom_add`) into the tracer's command encoder, on the radiance buffer it
//!   already has. The paper ran bloom on the GPU only and named a CPU version as future work:
//!   here both exist and agree to 1e-5 relative.
//! - [`tonemap`]: exposure, a curve ([`ToneCurve::Clamp`], [`ToneCurve::Reinhard`],
//!   [`ToneCurve::Aces`]), the sRGB transfer function and rounding to `u8`.
//! - [`metrics`]: RMSE, MAE, relative MSE and SSIM.
//! - [`blocks`]: errors of block means ("95 % of 8x8 blocks within 3 %").
//!
//! **Image format.** Everywhere in this crate an image is `width * height` packed RGB f32
//! triples, `[f32; 3]` per pixel (12 bytes), row-major: pixel `(x, y)` is element
//! `y * width + x`. On the GPU the same bytes are an `array<f32>` storage buffer.
//!
//! ```
//! use raylume_post::{BloomParams, ToneMap, bloom_cpu};
//!
//! // A 5x5 black image with one bright pixel in the middle.
//! let mut img = vec![[0.0f32; 3]; 25];
//! img[12] = [10.0, 10.0, 10.0];
//! let params = BloomParams { threshold: 1.0, radius: 1, strength: 0.9 };
//! bloom_cpu(&mut img, 5, 5, params)?;
//! // (10 - 1) * 0.9 / 3^2 = 0.9 lands on each of the 3x3 neighbours.
//! assert!((img[6][0] - 0.9).abs() < 1e-6);
//! assert_eq!(img[0], [0.0; 3]);
//!
//! let srgb = ToneMap::clamp().to_srgb8(&img)?;
//! assert_eq!(srgb[12], [255, 255, 255]);
//! # Ok::<(), raylume_post::PostError>(())
//! ```
//!
//! **Architecture invariant:** this crate knows nothing about scenes, rays or kernels; it takes
//! plain parameters ([`BloomParams`], [`ToneMap`]) that the facade fills from the scene.

pub mod blocks;
pub mod bloom;
mod bloom_gpu;
mod error;
pub mod gpu_types;
pub mod metrics;
pub mod tonemap;

pub use blocks::{BLOCK_FLOOR, BlockErrors, block_errors, block_means, block_standard_errors};
pub use bloom::{BloomParams, bloom_cpu};
pub use bloom_gpu::{BLOOM_STAGES, BLOOM_WGSL, GpuBloom, PIXEL_BYTES, bloom_gpu};
pub use error::PostError;
pub use metrics::{mae, relative_mse, rmse, ssim};
pub use tonemap::{ToneCurve, ToneMap, quantize, srgb_decode, srgb_encode, srgb8, srgb8_steps};
