//! The kernels' entry points in Rust, one function per WGSL entry point (same names), each
//! the body of one GPU thread. [`super::CpuTracer`] runs them with rayon.

use glam::{Vec2, Vec3};
use raylume_bvh::{GpuBvh, Hit};

use super::variant::{BuildForms, Forms};
use crate::camera::generate_camera_ray;
use crate::gpu_types::{
    DIM_CAMERA, PIXEL_TILE_HEIGHT, PIXEL_TILE_WIDTH, RayState, SAMPLER_SOBOL, SceneUniforms,
};
use crate::math::sample_is_valid;
use crate::shade::{
    PathState, SegmentRands, sampler_pixel, shade_segment, trace_ray, trace_ray_at, walk_segment,
};
use crate::shade::{path_rand4, path_rand4_at};
use crate::sobol::SobolPixel;
use crate::surface::{Globals, prefetch_hit};

/// (pixel, sample) of ray `r` of the batch; consecutive rays are consecutive pixels.
#[inline]
pub fn batch_ray(scene: &SceneUniforms, r: u32) -> (u32, u32) {
    (
        scene.pixel_begin + r % scene.pixel_count,
        scene.sample_begin + r / scene.pixel_count,
    )
}

/// (pixel, sample) of thread `r` of the GPU's megakernel (WGSL `tiled_ray`): [`batch_ray`]'s
/// samples in another order. When the batch covers the whole image, its pixels are taken in
/// bands of [`PIXEL_TILE_HEIGHT`] rows, each band in blocks of [`PIXEL_TILE_WIDTH`] columns
/// (the last band and block narrower where the image is), row by row inside a block: a
/// 32-lane warp's camera rays leave from an 8x4 tile, not a 32x1 strip, and its first bounces
/// stay closer together (H200, 100 spp: the living room's megakernel 1.5-2 % faster, the
/// teapots' 4-7 %; docs/study/h200-a3d7590-pixel-tiles.md). A batch of part of the image
/// keeps scanlines. Each thread writes its sample to [`sample_slot`], so the image is the
/// same. The CPU runs its samples in slot order and does not call this twin of the WGSL.
#[inline]
pub fn tiled_ray(scene: &SceneUniforms, r: u32) -> (u32, u32) {
    let (w, h) = (scene.width, scene.height);
    if scene.pixel_begin != 0 || scene.pixel_count != w * h {
        return batch_ray(scene, r);
    }
    let i = r % scene.pixel_count;
    let band = i / (PIXEL_TILE_HEIGHT * w);
    let band_height = PIXEL_TILE_HEIGHT.min(h - band * PIXEL_TILE_HEIGHT);
    let j = i - band * PIXEL_TILE_HEIGHT * w;
    let blocks = w.div_ceil(PIXEL_TILE_WIDTH);
    let block = (j / (PIXEL_TILE_WIDTH * band_height)).min(blocks - 1);
    let k = j - block * PIXEL_TILE_WIDTH * band_height;
    let block_width = PIXEL_TILE_WIDTH.min(w - block * PIXEL_TILE_WIDTH);
    let x = block * PIXEL_TILE_WIDTH + k % block_width;
    let y = band * PIXEL_TILE_HEIGHT + k / block_width;
    (y * w + x, scene.sample_begin + r / scene.pixel_count)
}

/// The slot of a pixel sample of the batch: the inverse of [`batch_ray`]. (The GPU's
/// `propagate` writes a finished sample there, wherever its state was moved by sorting.)
#[inline]
pub fn sample_slot(scene: &SceneUniforms, pixel: u32, sample: u32) -> u32 {
    (sample - scene.sample_begin) * scene.pixel_count + (pixel - scene.pixel_begin)
}

/// [`camera_path`] with the pixel's [`sampler_pixel`] `sp` given: under the `Sobol` sampler
/// its two numbers from the render's table of segment 0's hashes
/// ([`SegmentKeys::draw_camera`](crate::sobol::SegmentKeys::draw_camera); the same numbers).
#[inline(always)]
pub fn camera_path_at(g: &Globals, sp: SobolPixel, pixel: u32, sample: u32) -> PathState {
    let scene = g.scene;
    let j = match g.sobol_segments.first() {
        Some(keys) if keys.seed() == sp.seed && scene.sampler == SAMPLER_SOBOL => {
            keys.draw_camera(sp, sample)
        }
        _ => {
            let j = path_rand4_at(scene, sp, pixel, sample, 0, DIM_CAMERA);
            Vec2::new(j.x, j.y)
        }
    };
    camera_path_from(scene, pixel, j)
}

/// The camera path of `pixel` through its point `jitter` (the camera group's first pair).
#[inline(always)]
pub fn camera_path_from(scene: &SceneUniforms, pixel: u32, jitter: Vec2) -> PathState {
    let dir = generate_camera_ray(scene, pixel, jitter);
    PathState::new(Vec3::from(scene.camera_origin), dir)
}

/// The camera path of a pixel sample.
#[inline(always)]
pub fn camera_path(scene: &SceneUniforms, pixel: u32, sample: u32) -> PathState {
    let j = path_rand4(scene, pixel, sample, 0, DIM_CAMERA);
    let dir = generate_camera_ray(scene, pixel, Vec2::new(j.x, j.y));
    PathState::new(Vec3::from(scene.camera_origin), dir)
}

/// The value a finished sample writes to its slot: its radiance, or zero when it is not
/// finite or too bright to sum safely (then `true`: the sample is dropped and counted; see
/// [`crate::math::sample_is_valid`]).
#[inline]
pub fn write_sample(radiance: Vec3) -> ([f32; 3], bool) {
    if sample_is_valid(radiance) {
        (radiance.into(), false)
    } else {
        ([0.0; 3], true)
    }
}

/// `raygen`: the stored camera ray of ray `r` of the batch.
#[inline]
pub fn raygen(scene: &SceneUniforms, r: u32) -> RayState {
    let (pixel, sample) = batch_ray(scene, r);
    let path = camera_path(scene, pixel, sample);
    let mut ray = RayState {
        pixel,
        sample,
        ..Default::default()
    };
    path.store(&mut ray, 0);
    ray
}

/// `propagate` at segment `depth`: advances a live stored ray by one segment. Returns the
/// sample to write when the path ended (`Some((value, dropped))`).
#[inline]
pub fn propagate<const F: u32>(
    g: &Globals,
    bvh: &GpuBvh,
    ray: &mut RayState,
    depth: u32,
) -> Option<([f32; 3], bool)> {
    let mut path = PathState::load(ray);
    path.alive = true;
    trace_ray::<F>(g, bvh, &mut path, ray.pixel, ray.sample, depth);
    path.store(ray, depth + 1);
    (!path.alive).then(|| write_sample(path.radiance))
}

/// The whole path of one pixel sample, all bounces in a loop: its radiance and the rays it
/// traced.
#[inline(always)]
pub fn trace_path<const F: u32>(g: &Globals, bvh: &GpuBvh, pixel: u32, sample: u32) -> (Vec3, u32) {
    trace_path_by::<F, BuildForms>(g, bvh, pixel, sample)
}

/// [`trace_path`] with the forms `K` of the sampler's draw and the walks
/// ([`crate::shade::trace_ray_at`]).
#[inline(always)]
pub fn trace_path_by<const F: u32, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    pixel: u32,
    sample: u32,
) -> (Vec3, u32) {
    let scene = g.scene;
    let sp = sampler_pixel(scene, pixel);
    let mut path = camera_path_at(g, sp, pixel, sample);
    let mut traced = 0;
    let mut depth = 0;
    while depth <= scene.max_bounces && path.alive {
        trace_ray_at::<F, K>(g, bvh, &mut path, pixel, sp, sample, depth);
        traced += 1;
        depth += 1;
    }
    (path.radiance, traced)
}

/// `trace_paths`: the whole path of ray `r` of the batch; returns its slot value, whether
/// it was dropped, and the rays traced.
#[inline(always)]
pub fn trace_paths<const F: u32>(g: &Globals, bvh: &GpuBvh, r: u32) -> ([f32; 3], bool, u32) {
    trace_paths_by::<F, BuildForms>(g, bvh, r)
}

/// [`trace_paths`] with the forms `K` of the sampler's draw and the walks
/// ([`crate::shade::trace_ray_at`]).
#[inline(always)]
pub fn trace_paths_by<const F: u32, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    r: u32,
) -> ([f32; 3], bool, u32) {
    let (pixel, sample) = batch_ray(g.scene, r);
    let (radiance, traced) = trace_path_by::<F, K>(g, bvh, pixel, sample);
    let (value, dropped) = write_sample(radiance);
    (value, dropped, traced)
}

/// The paths of slots `r0..r0 + slots.len()` of the batch, each slot's value written as
/// [`trace_paths`] writes it; returns the segments traced and the samples dropped. The CPU's
/// schedule of [`trace_paths`] for large scenes the packets do not take
/// ([`CpuTracer::pairs`](super::CpuTracer::pairs)): two paths at a time, a segment of each in
/// turn. After a path's walk ([`walk_segment`]) the
/// records its hit's surface reads are asked for ([`prefetch_hit`]); the other path's
/// segment runs; then the hit is shaded ([`shade_segment`]), its records in the cache by
/// then instead of on the shading's chain of loads. Each path runs the functions of
/// [`trace_path_by`] on its own numbers, in its own order: the same image bit for bit
/// (`tests/cpu_isa.rs` against the wavefront schedule's one segment at a time). Bitterli's
/// living room (textured, shading normals, a sky; the AMD EPYC dev VM, 10 spp alternating
/// with one path at a time): 3-5 % faster (geometric means of the rounds' ratios 0.948-0.972
/// over five series, 500x500 to 1000x1000; `docs/study/cpu-2fe0ab8-paths-in-pairs.md`); the
/// interleave without the prefetches gains nothing. Two in turn, not three or four: those
/// measured no better.
#[inline(always)]
pub fn trace_paths_in_pairs<const F: u32, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    r0: u32,
    slots: &mut [[f32; 3]],
) -> (u64, u64) {
    /// One of the two paths in flight: its state, its pixel sample and segment, the slot it
    /// writes, and the hit its last walk found, still to shade.
    #[derive(Clone, Copy)]
    struct InFlight {
        path: PathState,
        pixel: u32,
        sample: u32,
        sp: SobolPixel,
        depth: u32,
        slot: usize,
        hit: Option<(Hit, SegmentRands)>,
    }
    let scene = g.scene;
    let mut flights: [Option<InFlight>; 2] = [None; 2];
    let (mut next, mut rays, mut dropped) = (0usize, 0u64, 0u64);
    loop {
        let mut busy = false;
        for flight in flights.iter_mut() {
            // The hit walked a turn ago: shade it, then end the path or go on (as
            // `trace_path_by`'s loop: `depth <= max_bounces && alive`).
            if let Some(f) = flight {
                if let Some((hit, rnd)) = f.hit.take() {
                    shade_segment::<F, K>(g, bvh, &mut f.path, hit, rnd, f.depth);
                    f.depth += 1;
                }
                if !(f.depth <= scene.max_bounces && f.path.alive) {
                    let (value, d) = write_sample(f.path.radiance);
                    slots[f.slot] = value;
                    dropped += u64::from(d);
                    *flight = None;
                }
            }
            // A free place takes the chunk's next path.
            if flight.is_none() && next < slots.len() {
                let (pixel, sample) = batch_ray(scene, r0 + next as u32);
                let sp = sampler_pixel(scene, pixel);
                *flight = Some(InFlight {
                    path: camera_path_at(g, sp, pixel, sample),
                    pixel,
                    sample,
                    sp,
                    depth: 0,
                    slot: next,
                    hit: None,
                });
                next += 1;
            }
            let Some(f) = flight else { continue };
            busy = true;
            rays += 1;
            f.hit = walk_segment::<F, K>(g, bvh, &mut f.path, f.pixel, f.sp, f.sample, f.depth);
            match &f.hit {
                Some((hit, _)) => prefetch_hit::<F>(g, hit.prim),
                // Escaped: the environment taken, the path ended.
                None => f.depth += 1,
            }
        }
        if !busy {
            return (rays, dropped);
        }
    }
}

/// `resolve` for pixel `i` of the batch: its running sum plus this batch's samples in sample
/// order, times `resolve_scale`.
#[inline]
pub fn resolve(
    scene: &SceneUniforms,
    accumulated: [f32; 3],
    sample_radiance: &[[f32; 3]],
    i: u32,
) -> [f32; 3] {
    let mut sum = Vec3::from(accumulated);
    for s in 0..scene.sample_count {
        sum += Vec3::from(sample_radiance[(s * scene.pixel_count + i) as usize]);
    }
    (sum * scene.resolve_scale).into()
}
