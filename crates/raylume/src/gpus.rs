//! [`Backend::Gpus`]: one render split by samples over several GPU devices, in threads, and
//! merged exactly as render parts are (`parts.rs`).

use std::time::Instant;

use raylume_bvh::{BvhQuality, GpuBvh};
use raylume_gpu::{AdapterChoice, ContextOptions, GpuContext};
use raylume_scene::Scene;
use serde::Serialize;

use crate::tracer::{BuiltBvh, BvhCacheEntry, GeometryKey};
use crate::{Backend, Error, GPU_RAYS_PER_SECOND, Render, SampleRange, Tracer};

/// What one device of a [`Backend::Gpus`] render did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct WorkerStats {
    /// The adapter, as `RenderStats::adapter` names it.
    pub adapter: String,
    /// The samples of every pixel it traced.
    pub samples: Option<SampleRange>,
    /// Its `trace` seconds and its whole render's.
    pub trace_seconds: f64,
    /// Its whole render's seconds (pipelines, upload, trace).
    pub total_seconds: f64,
    /// Rays it traced.
    pub rays_traced: u64,
}

/// Splits samples `range` between workers in proportion to `weights` (each worker with a
/// positive weight gets at least one sample while there are samples; ranges in worker order,
/// tiling `range`). Workers may get empty ranges when there are fewer samples than workers.
pub(crate) fn split(range: SampleRange, weights: &[f64]) -> Vec<SampleRange> {
    let n = weights.len();
    let total: f64 = weights.iter().map(|w| w.max(1e-9)).sum();
    let len = range.len();
    let mut out = Vec::with_capacity(n);
    let mut begin = range.begin;
    let mut acc = 0.0;
    for (i, w) in weights.iter().enumerate() {
        acc += w.max(1e-9);
        let mut end = if i + 1 == n {
            range.end
        } else {
            range.begin + ((acc / total) * f64::from(len)).round() as u32
        };
        // At least one sample each while samples last; never past the end.
        let left_after = (n - i - 1) as u32;
        end = end
            .max(begin + 1)
            .min(range.end.saturating_sub(left_after))
            .max(begin);
        out.push(SampleRange { begin, end });
        begin = end;
    }
    out
}

impl Tracer {
    /// Copies every setting that decides the samples (and how they are traced) to `w`.
    fn settings_into(&self, w: &mut Tracer) {
        w.batch_spp = self.batch_spp;
        w.seed = self.seed;
        w.reorder = self.reorder;
        w.reorder_mode = self.reorder_mode;
        w.reorder_key_bits = self.reorder_key_bits;
        w.schedule = self.schedule;
        w.wavefront_min_samples = self.wavefront_min_samples;
        w.next_event_stage = self.next_event_stage;
        w.walk_stage = self.walk_stage;
        w.shadow_stage = self.shadow_stage;
        w.estimator = self.estimator;
        w.sampler = self.sampler;
        w.environment_guide = self.environment_guide;
        w.decode_textures = self.decode_textures;
        w.russian_roulette = self.russian_roulette;
        w.bvh_layout = self.bvh_layout;
        w.specialisation = self.specialisation;
        w.extra_features = self.extra_features;
        w.target_error = None;
        w.bloom = false;
        w.tone = self.tone;
    }

    /// [`Tracer::render`] for [`Backend::Gpus`].
    pub(crate) fn render_gpus(&mut self, scene: &Scene, t_total: Instant) -> Result<Render, Error> {
        if self.target_error.is_some() {
            return Err(Error::Settings(
                "a target error with several GPUs is not supported: use one GPU".into(),
            ));
        }
        let r = scene.render;
        let whole = SampleRange {
            begin: 0,
            end: r.spp,
        };
        let range = self.samples.unwrap_or(whole);
        if range.is_empty() || range.end > r.spp {
            return Err(Error::Settings(format!(
                "samples {}..{} are not a non-empty range within the render's 0..{}",
                range.begin, range.end, r.spp
            )));
        }
        let t_device = Instant::now();
        self.open_gpu_workers()?;
        let device_seconds = t_device.elapsed().as_secs_f64();
        let n = self.gpu_workers.len();
        if self.worker_speeds.len() != n {
            self.worker_speeds = vec![1.0; n];
        }

        // One BVH for every device, built here (or found in this tracer's cache).
        let t_bvh = Instant::now();
        let quality = self.bvh_quality.unwrap_or_else(|| {
            BvhQuality::for_work(
                scene.triangles.len() + scene.spheres.len(),
                self.estimated_rays(&r, range.len()),
                GPU_RAYS_PER_SECOND * n as f64,
                crate::tracer::bvh_build_threads(),
            )
        });
        let key = GeometryKey::of(scene, quality, self.bvh_layout);
        let bvh = match self.bvh_cache.iter().find(|c| c.key == key) {
            Some(c) => c.bvh.clone(),
            None => {
                let bvh = BuiltBvh::Cpu(std::sync::Arc::new(GpuBvh::from_scene_with_layout(
                    scene,
                    quality,
                    self.bvh_layout,
                )?));
                self.bvh_cache.insert(
                    0,
                    BvhCacheEntry {
                        key,
                        bvh: bvh.clone(),
                        prepared: Default::default(),
                        ahead: None,
                    },
                );
                self.bvh_cache.truncate(2);
                bvh
            }
        };
        let bvh_seconds = t_bvh.elapsed().as_secs_f64();

        let ranges = split(range, &self.worker_speeds);
        let mut workers = std::mem::take(&mut self.gpu_workers);
        for w in &mut workers {
            self.settings_into(w);
            w.bvh_quality = Some(quality);
            // The one tree built here (on the CPU), shared: no worker builds its own.
            w.bvh_builder = crate::BvhBuilder::Cpu;
            if !w.bvh_cache.iter().any(|c| c.key == key) {
                w.bvh_cache.insert(
                    0,
                    BvhCacheEntry {
                        key,
                        bvh: bvh.clone(),
                        prepared: Default::default(),
                        ahead: None,
                    },
                );
                w.bvh_cache.truncate(2);
            }
        }
        let results: Vec<Option<Result<Render, Error>>> = std::thread::scope(|threads| {
            let handles: Vec<_> = workers
                .iter_mut()
                .zip(&ranges)
                .map(|(w, &part)| {
                    (!part.is_empty()).then(|| {
                        threads.spawn(move || {
                            w.samples = Some(part);
                            let out = w.render(scene);
                            w.samples = None;
                            out
                        })
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p))))
                .collect()
        });
        self.gpu_workers = workers;

        // Sums in sample order, then the mean (or the sums, for a part), as `merge` does.
        let pixels_n = (r.width as usize) * (r.height as usize);
        let mut sums = vec![[0.0f32; 3]; pixels_n];
        let mut stats = None;
        let mut worker_stats = Vec::with_capacity(n);
        for (i, res) in results.into_iter().enumerate() {
            let Some(res) = res else {
                worker_stats.push(WorkerStats {
                    adapter: self.gpu_workers[i].gpu_adapter().unwrap_or_default(),
                    ..Default::default()
                });
                continue;
            };
            let render = res?;
            for (o, s) in sums.iter_mut().zip(&render.pixels) {
                for k in 0..3 {
                    o[k] += s[k];
                }
            }
            let s = &render.stats;
            worker_stats.push(WorkerStats {
                adapter: s.adapter.clone(),
                samples: s.samples,
                trace_seconds: s.seconds.trace,
                total_seconds: s.seconds.total,
                rays_traced: s.rays_traced,
            });
            if s.seconds.trace > 0.0 {
                self.worker_speeds[i] = f64::from(ranges[i].len()) / s.seconds.trace;
            }
            if stats.is_none() {
                stats = Some(render.stats.clone());
            }
        }
        let mut stats = stats.expect("at least one worker had samples");
        let part = self.samples.is_some();
        let mut pixels = sums;
        if !part {
            let scale = 1.0 / range.len() as f32;
            for p in &mut pixels {
                for v in p.iter_mut() {
                    *v *= scale;
                }
            }
        }
        stats.post_passes = Vec::new();
        let t_post = Instant::now();
        if !part
            && self.bloom
            && let Some(b) = scene.post.bloom
        {
            let params = raylume_post::BloomParams {
                threshold: b.threshold,
                radius: b.radius,
                strength: b.strength,
            };
            raylume_post::bloom_cpu(&mut pixels, r.width, r.height, params)?;
            stats.post_passes = raylume_post::BLOOM_STAGES.to_vec();
        }
        stats.backend = "gpus".into();
        stats.backend_reason = format!("requested: {} devices", n);
        stats.adapter = worker_stats
            .iter()
            .map(|w| w.adapter.as_str())
            .collect::<Vec<_>>()
            .join(" + ");
        stats.spp = r.spp;
        stats.seconds.device = device_seconds;
        stats.seconds.bvh = bvh_seconds;
        stats.seconds.post = t_post.elapsed().as_secs_f64();
        stats.seconds.trace = worker_stats
            .iter()
            .map(|w| w.trace_seconds)
            .fold(0.0, f64::max);
        stats.rays_traced = worker_stats.iter().map(|w| w.rays_traced).sum();
        stats.bvh_preset = quality.name().into();
        stats.bvh_preset_chosen = self.bvh_quality.is_none();
        stats.seconds.total = t_total.elapsed().as_secs_f64();
        stats.mrays_per_s = if stats.seconds.trace > 0.0 {
            stats.rays_traced as f64 / stats.seconds.trace / 1e6
        } else {
            0.0
        };
        stats.workers = worker_stats;
        Ok(self.make_render(scene, pixels, stats))
    }

    /// One worker per hardware adapter, unless there are workers already.
    pub(crate) fn open_gpu_workers(&mut self) -> Result<(), Error> {
        if self.gpu_workers.is_empty() {
            let contexts = GpuContext::all(&ContextOptions {
                choice: AdapterChoice::HardwareOnly,
                adapter_name: None,
            })?;
            self.gpu_workers = contexts
                .into_iter()
                .map(|c| Tracer::new(Backend::Gpu).with_gpu_context(c))
                .collect();
        }
        Ok(())
    }

    /// The adapter this tracer's GPU context is on, if it has one.
    pub(crate) fn gpu_adapter(&self) -> Option<String> {
        self.gpu.as_ref().map(GpuContext::describe)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_follow_the_weights_and_tile_the_range() {
        let r = SampleRange { begin: 0, end: 100 };
        let s = split(r, &[1.0, 1.0]);
        assert_eq!(
            s,
            [
                SampleRange { begin: 0, end: 50 },
                SampleRange {
                    begin: 50,
                    end: 100
                }
            ]
        );
        let s = split(r, &[3.0, 1.0]);
        assert_eq!(s[0], SampleRange { begin: 0, end: 75 });
        // A very slow device still gets a sample; three devices, two samples: one gets none.
        let s = split(r, &[1e6, 1.0]);
        assert_eq!(s[1].len(), 1);
        let s = split(SampleRange { begin: 4, end: 6 }, &[1.0, 1.0, 1.0]);
        assert_eq!(s.iter().map(SampleRange::len).sum::<u32>(), 2);
        assert_eq!(s[0].begin, 4);
        assert_eq!(s[2].end, 6);
        for (a, b) in s.iter().zip(s.iter().skip(1)) {
            assert_eq!(a.end, b.begin);
        }
    }
}
