// Bloom: bright pass, horizontal and vertical box blur, add back.
// The Rust mirror is bloom.rs (same function names, same summation order); read its module
// docs for the exact definition, the edge rule and why the blur is a direct sum.
//
// Images are packed RGB f32 triples, row-major: pixel (x, y) is floats 3*(y*width + x) + 0..2.
// Every entry point reads `src` and writes `dst`; the host binds, per stage:
//   bloom_threshold: image  -> bright
//   bloom_h:         bright -> tmp
//   bloom_v:         tmp    -> bright
//   bloom_add:       bright -> image   (image += strength * bright)
// One thread per pixel; the dispatch is folded into 2D when it needs more than
// max_compute_workgroups_per_dimension workgroups, and threads past the last pixel return.

const WORKGROUP_SIZE: u32 = 256u;

struct BloomUniforms {
    width: u32,
    height: u32,
    radius: u32,
    threshold: f32,
    strength: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: BloomUniforms;
@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var<storage, read_write> dst: array<f32>;

fn pixel_index(wid: vec3<u32>, nwg: vec3<u32>, lid: vec3<u32>) -> u32 {
    return (wid.y * nwg.x + wid.x) * WORKGROUP_SIZE + lid.x;
}

fn load_rgb(i: u32) -> vec3<f32> {
    return vec3<f32>(src[3u * i], src[3u * i + 1u], src[3u * i + 2u]);
}

fn store_rgb(i: u32, v: vec3<f32>) {
    dst[3u * i] = v.x;
    dst[3u * i + 1u] = v.y;
    dst[3u * i + 2u] = v.z;
}

// The window [lo, hi] of half-width r around i, clipped to 0..len; never overflows.
fn box_window(i: u32, r: u32, len: u32) -> vec2<u32> {
    return vec2<u32>(i - min(r, i), i + min(r, len - 1u - i));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn bloom_threshold(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let i = pixel_index(wid, nwg, lid);
    if (i >= params.width * params.height) {
        return;
    }
    store_rgb(i, max(load_rgb(i) - vec3<f32>(params.threshold), vec3<f32>(0.0)));
}

// The mean of the pixels `first + k * stride` for `k` in the window `win` (inclusive), in
// order of `k`: a row's window (stride 1) or a column's (stride: the width).
fn box_mean(first: u32, stride: u32, win: vec2<u32>) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var k = win.x; k <= win.y; k++) {
        sum += load_rgb(first + k * stride);
    }
    return sum / f32(win.y - win.x + 1u);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn bloom_h(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let i = pixel_index(wid, nwg, lid);
    if (i >= params.width * params.height) {
        return;
    }
    let x = i % params.width;
    store_rgb(i, box_mean(i - x, 1u, box_window(x, params.radius, params.width)));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn bloom_v(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let i = pixel_index(wid, nwg, lid);
    if (i >= params.width * params.height) {
        return;
    }
    let x = i % params.width;
    let y = i / params.width;
    store_rgb(i, box_mean(x, params.width, box_window(y, params.radius, params.height)));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn bloom_add(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
) {
    let i = pixel_index(wid, nwg, lid);
    if (i >= params.width * params.height) {
        return;
    }
    let p = vec3<f32>(dst[3u * i], dst[3u * i + 1u], dst[3u * i + 2u]);
    store_rgb(i, p + params.strength * load_rgb(i));
}
