// What both schedules share (stages.rs in cpu/ mirrors it): batch indexing, the camera path,
// writing a sample, and the per-workgroup statistics.

var<workgroup> wg_traced: atomic<u32>;
var<workgroup> wg_dropped: atomic<u32>;

// Linear thread index in a 2D dispatch (x at most MAX_WORKGROUPS_PER_DIMENSION).
fn thread_index(wg: vec3<u32>, nwg: vec3<u32>, local: u32) -> u32 {
    return (wg.y * nwg.x + wg.x) * WORKGROUP_SIZE + local;
}

// (pixel, sample) of ray `r` of the batch; consecutive rays are consecutive pixels.
fn batch_ray(r: u32) -> vec2<u32> {
    return vec2<u32>(scene.pixel_begin + r % scene.pixel_count, scene.sample_begin + r / scene.pixel_count);
}

// (pixel, sample) of megakernel thread r: batch_ray's samples with the whole image's pixels
// in PIXEL_TILE_WIDTH x PIXEL_TILE_HEIGHT tiles (stages.rs `tiled_ray` says how and why).
fn tiled_ray(r: u32) -> vec2<u32> {
    let w = scene.width;
    let h = scene.height;
    if (scene.pixel_begin != 0u || scene.pixel_count != w * h) {
        return batch_ray(r);
    }
    let i = r % scene.pixel_count;
    let band = i / (PIXEL_TILE_HEIGHT * w);
    let band_height = min(PIXEL_TILE_HEIGHT, h - band * PIXEL_TILE_HEIGHT);
    let j = i - band * PIXEL_TILE_HEIGHT * w;
    let blocks = (w + PIXEL_TILE_WIDTH - 1u) / PIXEL_TILE_WIDTH;
    let block = min(j / (PIXEL_TILE_WIDTH * band_height), blocks - 1u);
    let k = j - block * PIXEL_TILE_WIDTH * band_height;
    let block_width = min(PIXEL_TILE_WIDTH, w - block * PIXEL_TILE_WIDTH);
    let x = block * PIXEL_TILE_WIDTH + k % block_width;
    let y = band * PIXEL_TILE_HEIGHT + k / block_width;
    return vec2<u32>(y * w + x, scene.sample_begin + r / scene.pixel_count);
}

// The slot of a pixel sample of the batch: the inverse of batch_ray, so a ray whose state was
// moved (permute_rays) still writes its radiance where resolve looks for it.
fn sample_slot(pixel: u32, sample: u32) -> u32 {
    return (sample - scene.sample_begin) * scene.pixel_count + (pixel - scene.pixel_begin);
}

fn camera_path(pixel: u32, sample: u32) -> PathState {
    let jitter = path_rand4(pixel, sample, 0u, DIM_CAMERA).xy;
    let dir = generate_camera_ray(pixel, jitter);
    return PathState(scene.camera_origin, dir, vec3<f32>(1.0), vec3<f32>(0.0), true, 0.0);
}

struct PathResult {
    radiance: vec3<f32>,
    traced: u32,
}

// The whole path of one pixel sample, all bounces in a loop with the state in registers.
fn trace_path(pixel: u32, sample: u32) -> PathResult {
    var path = camera_path(pixel, sample);
    var traced = 0u;
    for (var depth = 0u; depth <= scene.max_bounces && path.alive; depth++) {
        trace_ray(&path, pixel, sample, depth, 0u);
        traced += 1u;
    }
    return PathResult(path.radiance, traced);
}

// Writes radiance to slot r; a non-finite or overflowing sample (sample_is_valid)
// is dropped (written as zero) and counted. Returns 1 when dropped.
fn write_sample(r: u32, radiance: vec3<f32>) -> u32 {
    let ok = sample_is_valid(radiance);
    let v = select(vec3<f32>(0.0), radiance, ok);
    sample_radiance[3u * r] = v.x;
    sample_radiance[3u * r + 1u] = v.y;
    sample_radiance[3u * r + 2u] = v.z;
    return select(1u, 0u, ok);
}

// Adds n rays to the batch's count (a carry-propagating 64-bit pair). The wavefront's
// propagate calls it from one thread per dispatch and counts its dropped samples with
// add_dropped: its kernels need no barrier for the stats.
fn count_traced(n: u32) {
    let i = 4u * scene.batch_index;
    if (n > 0u) {
        let old = atomicAdd(&batch_stats[i], n);
        if (old > 0xffffffffu - n) {
            atomicAdd(&batch_stats[i + 1u], 1u);
        }
    }
}

// One atomic per invocation that dropped samples (rare: write_sample).
fn add_dropped(dropped: u32) {
    if (dropped > 0u) {
        atomicAdd(&batch_stats[4u * scene.batch_index + 2u], dropped);
    }
}

// Adds this thread's counts to the workgroup's, then the workgroup's to the batch's with one
// atomic each (the ray count as a carry-propagating 64-bit pair). Call from uniform control
// flow: it contains a barrier.
fn flush_stats(local: u32, traced: u32, dropped: u32) {
    if (traced > 0u) {
        atomicAdd(&wg_traced, traced);
    }
    if (dropped > 0u) {
        atomicAdd(&wg_dropped, dropped);
    }
    workgroupBarrier();
    if (local == 0u) {
        count_traced(atomicLoad(&wg_traced));
        add_dropped(atomicLoad(&wg_dropped));
    }
}

// Sums each pixel's samples of this batch onto its running sum, in sample order, then
// scales (1/spp after the pixel's last batch). One thread per pixel of the batch.
@compute @workgroup_size(WORKGROUP_SIZE)
fn resolve(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = thread_index(wg, nwg, local);
    if (i >= scene.pixel_count) {
        return;
    }
    let p = 3u * (scene.pixel_begin + i);
    var sum = vec3<f32>(accumulation[p], accumulation[p + 1u], accumulation[p + 2u]);
    for (var s = 0u; s < scene.sample_count; s++) {
        let k = 3u * (s * scene.pixel_count + i);
        sum += vec3<f32>(sample_radiance[k], sample_radiance[k + 1u], sample_radiance[k + 2u]);
    }
    sum = sum * scene.resolve_scale;
    accumulation[p] = sum.x;
    accumulation[p + 1u] = sum.y;
    accumulation[p + 2u] = sum.z;
}
