// raylume-kernels: the environment guide's walks on the GPU, GUIDE_PROBES threads a walk: the WGSL mirror
// of env_guide.rs (`GuideParams`, `guide_walk`, `cell_index`, `EnvironmentGuide::bin_of`,
// `facing_normal`), same constants (from Rust) and operation order. Assembled by
// gpu/guide.rs after the traversal, gpu_types.wgsl, math.wgsl, rng.wgsl and sampling.wgsl.
// Every escape adds one to its counter: integer sums, the same in any order, so the counts
// are the CPU's wherever the two compute the same rays.

struct GuideParams {
    origin: vec3<f32>,
    extent: f32,
    forward: vec3<f32>,
    side: u32,
    right: vec3<f32>,
    walks: u32,
    up: vec3<f32>,
    _pad0: u32,
    scene_min: vec3<f32>,
    _pad1: u32,
    grid_scale: vec3<f32>,
    _pad2: u32,
    grid: vec3<u32>,
    _pad3: u32,
}

@group(0) @binding(0) var<storage, read> bvh_nodes: array<TraversalNode>;
@group(0) @binding(1) var<storage, read> bvh_primitives: array<Primitive>;
@group(0) @binding(2) var<uniform> guide: GuideParams;
// GUIDE_WIDTH x GUIDE_HEIGHT escape counts per cell (GuideParams::counter_count), zeroed.
@group(0) @binding(3) var<storage, read_write> guide_counts: array<atomic<u32>>;

// env_guide.rs `cell_index` over the guide's grid.
fn guide_cell_index(p: vec3<f32>) -> u32 {
    let q = (p - guide.scene_min) * guide.grid_scale;
    let top = vec3<f32>(guide.grid - vec3<u32>(1u));
    let c = vec3<u32>(min(max(q, vec3<f32>(0.0)), top));
    return (c.z * guide.grid.y + c.y) * guide.grid.x + c.x;
}

// env_guide.rs `EnvironmentGuide::bin_of`: the direction cell of equirectangular coordinates.
fn guide_bin_of(e: vec2<f32>) -> u32 {
    let u = e.x - floor(e.x);
    let x = min(u32(u * f32(GUIDE_WIDTH)), GUIDE_WIDTH - 1u);
    let y = min(u32(clamp(e.y, 0.0, 1.0) * f32(GUIDE_HEIGHT)), GUIDE_HEIGHT - 1u);
    return y * GUIDE_WIDTH + x;
}

// env_guide.rs `facing_normal`: the unit geometric normal of `prim` at `p`, against `dir`.
fn guide_facing_normal(prim: u32, p: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let q = bvh_primitives[prim];
    let a = q.a.xyz;
    var n: vec3<f32>;
    if bitcast<u32>(q.b.w) == PRIM_SPHERE {
        n = normalize(p - a);
    } else {
        n = normalize(cross(q.b.xyz - a, q.c.xyz - a));
    }
    return select(n, -n, dot(n, dir) > 0.0);
}

// env_guide.rs `guide_walk`'s counter of an escape in direction d from cell `cell`.
fn guide_escape(cell: u32, d: vec3<f32>) {
    atomicAdd(&guide_counts[cell * GUIDE_WIDTH * GUIDE_HEIGHT + guide_bin_of(direction_to_equirect(d))], 1u);
}

// env_guide.rs `guide_walk`, split into GUIDE_PROBES lanes (one thread each): every lane
// follows the walk (the same rays, so a warp's lanes of one walk run together) and traces
// probe `lane` at each vertex; lane 0 also counts the walk's own escape. The lanes together
// count what guide_walk counts, with eight times the threads to hide the traversal's latency.
fn guide_walk(walk: u32, lane: u32) {
    let side = guide.side;
    let x = walk % side;
    let y = walk / side;
    let h = pcg4d(vec4<u32>(walk, 0x5eed0001u, 0u, 0x9e3779b9u));
    let sx = 2.0 * ((f32(x) + rand_f32(h.x)) / f32(side)) - 1.0;
    let sy = 1.0 - 2.0 * ((f32(y) + rand_f32(h.y)) / f32(side));
    var o = guide.origin;
    var d = normalize(guide.forward + guide.right * sx + guide.up * sy);
    var cell = 0u;
    for (var vertex = 0u; vertex <= GUIDE_VERTICES; vertex++) {
        let hit = trace_closest(Ray(o, d), 0.0, T_MAX_LIMIT);
        if hit.prim == INVALID_INDEX {
            // The camera ray escaping says nothing about the light at surfaces.
            if vertex > 0u && lane == 0u {
                guide_escape(cell, d);
            }
            break;
        }
        if vertex == GUIDE_VERTICES {
            break;
        }
        let p = o + d * hit.t;
        let n = guide_facing_normal(hit.prim, p, d);
        let a = abs(p);
        o = p + n * (1e-5 * guide.extent + 1e-6 * max(a.x, max(a.y, a.z)));
        cell = guide_cell_index(o);
        let u = pcg4d(vec4<u32>(walk, vertex + 1u, lane, 0x5eed0002u));
        let dir = sample_diffuse(n, vec2<f32>(rand_f32(u.x), rand_f32(u.y)));
        if !trace_any(Ray(o, dir), 0.0, T_MAX_LIMIT) {
            guide_escape(cell, dir);
        }
        let next = pcg4d(vec4<u32>(walk, vertex + 1u, GUIDE_PROBES, 0x5eed0002u));
        d = sample_diffuse(n, vec2<f32>(rand_f32(next.x), rand_f32(next.y)));
    }
}

@compute @workgroup_size(GUIDE_WORKGROUP_SIZE)
fn learn_guide(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < guide.walks * GUIDE_PROBES {
        guide_walk(id.x / GUIDE_PROBES, id.x % GUIDE_PROBES);
    }
}
