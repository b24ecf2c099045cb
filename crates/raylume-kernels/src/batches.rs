//! Splitting a render into batches: `batch_spp` samples of every pixel at a time (the paper's
//! 20), fewer when the per-ray buffers would not fit one storage binding, and a range of the
//! pixels at a time when even one sample of every pixel does not fit.

use crate::gpu_types::SceneUniforms;

/// One batch: samples `sample_begin .. sample_begin + sample_count` of pixels
/// `pixel_begin .. pixel_begin + pixel_count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Batch {
    pub pixel_begin: u32,
    pub pixel_count: u32,
    pub sample_begin: u32,
    pub sample_count: u32,
    /// True when this batch holds the last samples of its pixels (`resolve` then divides).
    pub last_for_pixels: bool,
}

impl Batch {
    /// Rays (pixel samples) in the batch.
    pub fn rays(&self) -> u32 {
        self.pixel_count * self.sample_count
    }

    /// The render's uniforms `base` with this batch's fields filled in: batch `index` of a
    /// render of `spp` samples per pixel, its ray queues `queue_capacity` long. The GPU
    /// writes exactly these before each batch; the CPU mirror computes with them.
    pub fn uniforms(
        &self,
        base: &SceneUniforms,
        index: u32,
        spp: u32,
        queue_capacity: u32,
    ) -> SceneUniforms {
        SceneUniforms {
            sample_begin: self.sample_begin,
            sample_count: self.sample_count,
            pixel_begin: self.pixel_begin,
            pixel_count: self.pixel_count,
            batch_index: index,
            resolve_scale: if self.last_for_pixels {
                1.0 / spp as f32
            } else {
                1.0
            },
            rays_in_batch: self.rays(),
            queue_capacity,
            ..*base
        }
    }
}

/// The batches of a `pixels`-pixel, `spp`-sample render with at most `batch_spp` samples per
/// batch and at most `max_rays` rays per batch (both at least 1), pixel ranges outermost.
pub fn plan_batches(pixels: u32, spp: u32, batch_spp: u32, max_rays: u64) -> Vec<Batch> {
    plan_sample_range(pixels, 0..spp, batch_spp, max_rays, true)
}

/// [`plan_batches`] over samples `samples` of every pixel only (a render *part*). With
/// `mean`, the last batch of each pixel range divides by `samples.end` (a whole render);
/// without, no batch divides and the image holds each pixel's *sum* over the range, to be
/// added to other parts' sums and divided by the total count.
pub fn plan_sample_range(
    pixels: u32,
    samples: std::ops::Range<u32>,
    batch_spp: u32,
    max_rays: u64,
    mean: bool,
) -> Vec<Batch> {
    let spp = samples.end.saturating_sub(samples.start);
    let max_rays = max_rays.clamp(1, u64::from(u32::MAX));
    let batch_spp = batch_spp.clamp(1, spp.max(1));
    let (pixels_per_batch, samples_per_batch) =
        if u64::from(pixels) * u64::from(batch_spp) <= max_rays {
            (pixels, batch_spp)
        } else if u64::from(pixels) <= max_rays {
            (pixels, (max_rays / u64::from(pixels)) as u32)
        } else {
            (max_rays as u32, 1)
        };
    let mut out = Vec::new();
    let mut p = 0;
    while p < pixels {
        let pc = pixels_per_batch.min(pixels - p);
        let mut s = samples.start;
        while s < samples.end {
            let sc = samples_per_batch.min(samples.end - s);
            out.push(Batch {
                pixel_begin: p,
                pixel_count: pc,
                sample_begin: s,
                sample_count: sc,
                last_for_pixels: mean && s + sc == samples.end,
            });
            s += sc;
        }
        p += pc;
    }
    out
}

/// The batches of a render with `settings`: all its samples (each pixel's mean), or only
/// `range` of them (each pixel's sum over it; [`plan_sample_range`]). A range must be
/// non-empty and within `0..settings.spp`.
pub fn plan_render(
    pixels: u32,
    settings: &crate::TraceSettings,
    range: Option<&std::ops::Range<u32>>,
    max_rays: u64,
) -> Result<Vec<Batch>, crate::KernelError> {
    match range {
        None => Ok(plan_batches(
            pixels,
            settings.spp,
            settings.batch_spp,
            max_rays,
        )),
        Some(r) if r.start < r.end && r.end <= settings.spp => Ok(plan_sample_range(
            pixels,
            r.clone(),
            settings.batch_spp,
            max_rays,
            false,
        )),
        Some(r) => Err(crate::KernelError::InvalidSettings(format!(
            "sample range {}..{} is not a non-empty range within the render's {} samples per pixel",
            r.start, r.end, settings.spp
        ))),
    }
}

/// What a batch hook ([`crate::CpuTracer::render_with_hook`],
/// `GpuTracer::render_with_policy_and_hook`) sees after each **round**: the batches that
/// together add the same range of samples to every pixel (one batch, or one per pixel range
/// when the image is split).
#[derive(Clone, Copy, Debug)]
pub struct RoundSums<'a> {
    /// Rounds finished, this one included (1, 2, ...).
    pub round: u32,
    /// Samples per pixel traced so far: `sums` holds samples `0..samples_done` of each pixel.
    pub samples_done: u32,
    /// Samples per pixel this round added.
    pub round_samples: u32,
    /// Per pixel (row-major, top row first), the sum of its samples so far, in the fixed
    /// order `resolve` adds them: not yet divided by `samples_done`.
    pub sums: &'a [[f32; 3]],
}

/// A batch hook's answer after a round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoundFlow {
    /// Trace the next round (if the render has one).
    Continue,
    /// Stop here: the image becomes `sums / samples_done`.
    Stop,
}

/// A hook called after every round of a render; see [`RoundSums`].
pub type RoundHook<'h> = dyn FnMut(&RoundSums<'_>) -> RoundFlow + 'h;

/// Puts `batches` (from [`plan_batches`]) in round order: each range of samples over every
/// pixel range before the next range of samples. A pixel's samples are still summed in the
/// same order (its batches keep their order), so the image is the same bit for bit; only a
/// hooked render needs it (it sees whole images between rounds).
pub fn into_rounds(batches: &mut [Batch]) {
    batches.sort_by_key(|b| (b.sample_begin, b.pixel_begin));
}

/// True when `b` ends a round of a `pixels`-pixel render in round order ([`into_rounds`]).
pub fn ends_round(b: &Batch, pixels: u32) -> bool {
    b.pixel_begin + b.pixel_count == pixels
}

/// A pixel's mean from its running sum after `spp` samples: `sum * (1 / spp)`, the very
/// arithmetic of `resolve` on a pixel's last batch, so that a render stopped after `spp`
/// samples equals an `spp`-sample render bit for bit.
pub fn mean_of_sum(sum: [f32; 3], spp: u32) -> [f32; 3] {
    let scale = 1.0 / spp as f32;
    (glam::Vec3::from(sum) * scale).into()
}

/// Workgroup counts `(x, y)` covering `threads` threads with `x` at most `max_per_dim`.
pub fn dispatch_size(threads: u32, workgroup_size: u32, max_per_dim: u32) -> (u32, u32) {
    let groups = threads.div_ceil(workgroup_size);
    if groups == 0 {
        return (0, 1);
    }
    let x = groups.min(max_per_dim);
    (x, groups.div_ceil(x))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(pixels: u32, spp: u32, batch_spp: u32, max_rays: u64) {
        let batches = plan_batches(pixels, spp, batch_spp, max_rays);
        // Every (pixel, sample) exactly once, each batch within the limit.
        let mut seen = vec![0u8; (pixels * spp) as usize];
        for b in &batches {
            assert!(u64::from(b.rays()) <= max_rays.max(1), "{b:?}");
            assert!(b.sample_count <= batch_spp.max(1), "{b:?}");
            for p in b.pixel_begin..b.pixel_begin + b.pixel_count {
                for s in b.sample_begin..b.sample_begin + b.sample_count {
                    seen[(p * spp + s) as usize] += 1;
                }
            }
            assert_eq!(b.last_for_pixels, b.sample_begin + b.sample_count == spp);
        }
        assert!(
            seen.iter().all(|&c| c == 1),
            "{pixels} {spp} {batch_spp} {max_rays}"
        );
    }

    #[test]
    fn batches_cover_every_sample_once_within_the_limit() {
        check(100, 7, 3, 1_000_000); // batch_spp rules
        check(100, 45, 20, 1_000); // reduced to 10 spp per batch
        check(100, 5, 20, 30); // pixel ranges of 30, one sample each
        check(1, 1, 1, 1);
        check(64 * 64, 4, 20, 64 * 64 * 4);
    }

    #[test]
    fn the_paper_setting_fits_an_h100_in_batches_of_20() {
        // 1000x1000 pixels, 64-byte ray states, 2 GiB bindings: 33 M rays per batch.
        let max_rays = 2_147_483_644 / 64;
        let b = plan_batches(1_000_000, 100, 20, max_rays);
        assert_eq!(b.len(), 5);
        assert!(
            b.iter()
                .all(|b| b.sample_count == 20 && b.pixel_count == 1_000_000)
        );
    }

    #[test]
    fn round_order_keeps_each_pixels_batches_in_order_and_ends_rounds_at_the_last_pixel() {
        let mut b = plan_batches(100, 5, 20, 30); // pixel ranges of 30 (10 last), 1 spp each
        let before = b.clone();
        into_rounds(&mut b);
        assert_eq!(b.len(), before.len());
        let rounds: Vec<u32> = b
            .iter()
            .filter(|x| ends_round(x, 100))
            .map(|x| x.sample_begin + x.sample_count)
            .collect();
        assert_eq!(rounds, vec![1, 2, 3, 4, 5]);
        for p in [0, 30, 60, 90] {
            let of = |v: &[Batch]| -> Vec<u32> {
                v.iter()
                    .filter(|x| x.pixel_begin == p)
                    .map(|x| x.sample_begin)
                    .collect()
            };
            assert_eq!(of(&b), of(&before), "pixel range {p}");
        }
        // Every round covers every pixel once before the next begins.
        let mut covered = 0;
        for x in &b {
            covered += x.pixel_count;
            if ends_round(x, 100) {
                assert_eq!(covered, 100);
                covered = 0;
            }
        }
    }

    #[test]
    fn dispatches_stay_within_the_per_dimension_limit() {
        assert_eq!(dispatch_size(0, 64, 65535), (0, 1));
        assert_eq!(dispatch_size(1, 64, 65535), (1, 1));
        assert_eq!(dispatch_size(64 * 65535, 64, 65535), (65535, 1));
        let (x, y) = dispatch_size(20_000_000, 64, 65535);
        assert!(x <= 65535 && u64::from(x) * u64::from(y) * 64 >= 20_000_000);
    }
}
