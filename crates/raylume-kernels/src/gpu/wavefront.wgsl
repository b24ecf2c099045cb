// The paper's wavefront schedule: `raygen` writes one ray per pixel sample of the batch;
// then, max_bounces + 1 times, `prepare_propagate` sizes the next launch from the live-ray
// count and `propagate` advances every live ray by one segment (traversal, intersection and
// shading in one kernel), stores it, writes its sort key and appends it to the next queue.
// Between two bounces the host may sort the next queue by key (raylume-sort) and, for
// ReorderMode::SortPermute, run `permute_rays`.

var<workgroup> wg_live: atomic<u32>;
var<workgroup> wg_base: u32;

@compute @workgroup_size(WORKGROUP_SIZE)
fn raygen(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let r = thread_index(wg, nwg, local);
    if (r >= scene.rays_in_batch) {
        return;
    }
    let ps = batch_ray(r);
    let path = camera_path(ps.x, ps.y);
    ray_states[r] = RayState(path.origin, ps.x, path.dir, ps.y, path.throughput, 0u, path.radiance, RAY_ALIVE);
    ray_queue_in[r] = r;
    if (r == 0u) {
        atomicStore(&queue_counts[0], scene.rays_in_batch);
    }
}

// `groups` workgroups as an indirect dispatch's (x, y) (at most
// MAX_WORKGROUPS_PER_DIMENSION along x; x * y >= groups) at word `at` of dispatch_args.
fn write_dispatch(at: u32, groups: u32) {
    let x = min(groups, MAX_WORKGROUPS_PER_DIMENSION);
    var y = 1u;
    if (x > 0u) {
        y = (groups + x - 1u) / x;
    }
    dispatch_args[at] = x;
    dispatch_args[at + 1u] = y;
    dispatch_args[at + 2u] = 1u;
}

@compute @workgroup_size(1)
fn prepare_propagate() {
    let q = bounce.depth & 1u;
    let n = atomicLoad(&queue_counts[q]);
    let groups = (n + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    write_dispatch(0u, groups);
    // The walk stage's threads: as many as the rays, at most bounce.walk_groups workgroups
    // (they take the queue's rays in turn).
    write_dispatch(4u, min(groups, bounce.walk_groups));
    atomicStore(&queue_counts[1u - q], 0u);
    // The walk stage's count of the queue slots taken (it runs after this, before propagate).
    atomicStore(&queue_counts[WALK_STAGE_COUNTER], 0u);
    // The shadow stage's queue, filled by propagate, and its count of the slots taken.
    atomicStore(&queue_counts[SHADOW_QUEUE_COUNTER], 0u);
    atomicStore(&queue_counts[SHADOW_STAGE_COUNTER], 0u);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn propagate(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let t = thread_index(wg, nwg, local);
    let q = bounce.depth & 1u;
    let n = atomicLoad(&queue_counts[q]);
    // This dispatch advances each of the n rays by one segment: the batch's ray count, added
    // once (one atomic, where each workgroup added its own after a barrier).
    if (t == 0u) {
        count_traced(n);
    }
    var dropped = 0u;
    var live = false;
    var shadow = false;
    var r = 0u;
    var key = DEAD_RAY_KEY;
    if (t < n) {
        r = ray_queue_in[t];
        var ray = ray_states[r];
        var path = PathState(ray.origin, ray.dir, ray.throughput, ray.radiance, true, select(0.0, bitcast<f32>(ray.alive), ray.alive > RAY_ALIVE));
        // A light sample left for next_event goes to this queue slot's record: the stage
        // reads it at the same slot, so both access the records in queue order.
        let deferred = trace_ray(&path, ray.pixel, ray.sample, bounce.depth, t);
        live = path.alive;
        shadow = DEFER_SHADOW && deferred;
        ray.origin = path.origin;
        ray.dir = path.dir;
        ray.throughput = path.throughput;
        ray.radiance = path.radiance;
        ray.depth = bounce.depth + 1u;
        ray.alive = select(0u, select(RAY_ALIVE, bitcast<u32>(path.mis_pdf), path.mis_pdf > 0.0), live);
        ray_states[r] = ray;
        if (live) {
            if (bounce.sort_next != 0u) {
                // SORT KEY (raylume-sort's MORTON_WGSL): the paper's 30-bit origin-direction
                // key, for the sort before the next bounce (none for an unsorted one).
                key = ray_sort_key(path.origin, path.dir, scene.scene_min, scene.scene_extent);
            }
        } else if (deferred) {
            // next_event (or, DEFER_SHADOW, trace_shadows) adds the vertex's light sample,
            // then writes the sample.
            if (DEFER_NEE) {
                set_nee_record_state(t, NEE_ENDED);
            }
        } else {
            // The sample's own slot, not `r`: permute_rays may have moved its state.
            dropped = write_sample(sample_slot(ray.pixel, ray.sample), path.radiance);
        }
    }
    // Compaction: the live rays of this workgroup take consecutive slots of the next queue.
    var slot = 0u;
    if (live) {
        slot = atomicAdd(&wg_live, 1u);
    }
    // Likewise the shadow rays left to the shadow stage, in its queue.
    var shadow_slot = 0u;
    if (shadow) {
        shadow_slot = atomicAdd(&wg_shadows, 1u);
    }
    workgroupBarrier();
    if (local == 0u) {
        let count = atomicLoad(&wg_live);
        if (count > 0u) {
            wg_base = atomicAdd(&queue_counts[1u - q], count);
        }
        if (DEFER_SHADOW) {
            let shadows = atomicLoad(&wg_shadows);
            if (shadows > 0u) {
                wg_shadow_base = atomicAdd(&queue_counts[SHADOW_QUEUE_COUNTER], shadows);
            }
        }
    }
    add_dropped(dropped);
    workgroupBarrier();
    if (shadow) {
        store_shadow_record(wg_shadow_base + shadow_slot, r, live);
    }
    if (live) {
        let out = wg_base + slot;
        ray_queue_out[out] = r;
        if (bounce.sort_next != 0u) {
            // The next bounce is sorted: keys beside the compacted queue, live rays only, by
            // their top 30 - sort_shift bits.
            ray_keys[out] = key >> bounce.sort_shift;
        }
    }
}

// The shadow stage (PathVariant::shadow_stage; DEFER_SHADOW in the propagate of the bounces
// with a walk stage): the light sample trace_ray took, whose shadow ray it left unwalked, and
// the vertex's two terms that wait on that ray (the light's, then the emission).
struct DeferredShadow {
    ray: Ray,
    t_max: f32,
    throughput: vec3<f32>,
    light: vec3<f32>,
    emission: vec3<f32>,
}

var<private> deferred_shadow: DeferredShadow;
var<workgroup> wg_shadows: atomic<u32>;
var<workgroup> wg_shadow_base: u32;

// deferred_shadow as the record of shadow queue slot `i`, for path ray `r`, which goes on
// (`live`) or ended at this vertex (trace_shadows then writes its sample). SHADOW_RECORD_WORDS
// words in nee_records' structure of arrays (nee_word); the emission's only where it is not
// zero (SHADOW_HAS_EMISSION in the state word says so).
fn store_shadow_record(i: u32, r: u32, live: bool) {
    let d = deferred_shadow;
    let emission = bitcast<vec3<u32>>(d.emission);
    let emits = any(emission != vec3<u32>(0u));
    nee_records[nee_word(0u, i)] = vec4<u32>(bitcast<vec3<u32>>(d.ray.origin), bitcast<u32>(d.t_max));
    nee_records[nee_word(1u, i)] = vec4<u32>(bitcast<vec3<u32>>(d.ray.dir), r);
    nee_records[nee_word(2u, i)] = vec4<u32>(bitcast<vec3<u32>>(d.throughput),
        select(NEE_ENDED, NEE_PENDING, live) | select(0u, SHADOW_HAS_EMISSION, emits));
    nee_records[nee_word(3u, i)] = vec4<u32>(bitcast<vec3<u32>>(d.light), 0u);
    if (emits) {
        nee_records[nee_word(4u, i)] = vec4<u32>(emission, 0u);
    }
}

// The walk stage's closest hit of queue slot `slot` (walk_stage.wgsl), and what propagate's
// trace_ray reads of it (HITS_TRACED).
fn store_queue_hit(slot: u32, hit: Hit) {
    queue_hits[slot] = vec4<u32>(bitcast<u32>(hit.t), hit.prim, bitcast<u32>(hit.u), bitcast<u32>(hit.v));
}

fn load_queue_hit(slot: u32) -> Hit {
    let w = queue_hits[slot];
    return Hit(bitcast<f32>(w.x), w.y, bitcast<f32>(w.z), bitcast<f32>(w.w));
}

// Word k of the NeeRecord of queue slot `slot` in nee_records: the records are a structure of
// arrays indexed by queue slot, so that a warp's stores of one word are contiguous whatever
// order the queue's rays are in (a 128-byte struct per ray made each of its 4-byte fields a
// transaction of its own: on the H200 the Cornell box's camera rays took 3x as long in
// propagate; indexed by ray, a sorted queue scattered them).
fn nee_word(k: u32, slot: u32) -> u32 {
    return k * scene.queue_capacity + slot;
}

fn store_nee_record(slot: u32, r: NeeRecord) {
    nee_records[nee_word(0u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.position), bitcast<u32>(r.offset));
    nee_records[nee_word(1u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.geometric_normal), bitcast<u32>(r.back_offset));
    nee_records[nee_word(2u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.shading_normal), r.material);
    nee_records[nee_word(3u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.color), r.state);
    nee_records[nee_word(4u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.dir_in), r._pad0);
    nee_records[nee_word(5u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.throughput), r._pad1);
    nee_records[nee_word(6u, slot)] = bitcast<vec4<u32>>(r.rnd);
    nee_records[nee_word(7u, slot)] = vec4<u32>(bitcast<vec3<u32>>(r.emitted), r._pad2);
}

fn load_nee_record(slot: u32) -> NeeRecord {
    let w0 = nee_records[nee_word(0u, slot)];
    let w1 = nee_records[nee_word(1u, slot)];
    let w2 = nee_records[nee_word(2u, slot)];
    let w3 = nee_records[nee_word(3u, slot)];
    let w4 = nee_records[nee_word(4u, slot)];
    let w5 = nee_records[nee_word(5u, slot)];
    let w6 = nee_records[nee_word(6u, slot)];
    let w7 = nee_records[nee_word(7u, slot)];
    return NeeRecord(bitcast<vec3<f32>>(w0.xyz), bitcast<f32>(w0.w), bitcast<vec3<f32>>(w1.xyz),
                     bitcast<f32>(w1.w), bitcast<vec3<f32>>(w2.xyz), w2.w, bitcast<vec3<f32>>(w3.xyz), w3.w,
                     bitcast<vec3<f32>>(w4.xyz), w4.w, bitcast<vec3<f32>>(w5.xyz), w5.w, bitcast<vec4<f32>>(w6),
                     bitcast<vec3<f32>>(w7.xyz), w7.w);
}

// NeeRecord::state alone (NEE_NONE, NEE_PENDING or NEE_ENDED).
fn nee_record_state(slot: u32) -> u32 {
    return nee_records[nee_word(3u, slot)].w;
}

fn set_nee_record_state(slot: u32, state: u32) {
    nee_records[nee_word(3u, slot)].w = state;
}

// The `next_event` stage's part: the light sample trace_ray left in
// nee_records[slot] at a vertex, taken as trace_ray takes it in the other schedules (the
// contribution evaluated before the shadow ray, which then decides whether it counts).
// Returns the throughput at the vertex times it; the caller adds that, then `rec.emitted`.
fn deferred_light_sample(rec: NeeRecord) -> vec3<f32> {
    let surface = SurfaceHit(rec.position, rec.geometric_normal, rec.shading_normal, vec2<f32>(0.0),
                             rec.material, rec.offset, rec.back_offset);
    var mat = materials[rec.material];
    mat.color = rec.color;
    let q = light_query(surface, mat, rec.dir_in, rec.rnd);
    var light_in = vec3<f32>(0.0);
    if (q.valid) {
        light_in = light_contribution(q, mat, rec.dir_in);
    }
    let occluded = q.valid && trace_any(q.ray, 0.0, q.t_max);
    return rec.throughput * select(light_in, vec3<f32>(0.0), occluded);
}

// Next-event estimation of bounce `bounce.depth`, after its `propagate` (whose pipeline
// defers it: DEFER_NEE): each ray of the bounce's queue that left a light sample in
// nee_records gets its contribution, then the vertex's emission, added to its radiance, in the
// order trace_ray adds them in the other schedules; a path that ended there has its sample
// written. Dispatched by the same dispatch size as that `propagate`.
@compute @workgroup_size(WORKGROUP_SIZE)
fn next_event(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let t = thread_index(wg, nwg, local);
    let n = atomicLoad(&queue_counts[bounce.depth & 1u]);
    var dropped = 0u;
    if (t < n) {
        let state = nee_record_state(t);
        if (state != NEE_NONE) {
            set_nee_record_state(t, NEE_NONE);
            let rec = load_nee_record(t);
            let r = ray_queue_in[t];
            let radiance = (ray_states[r].radiance + deferred_light_sample(rec)) + rec.emitted;
            if (state == NEE_ENDED) {
                let ray = ray_states[r];
                dropped = write_sample(sample_slot(ray.pixel, ray.sample), radiance);
            } else {
                ray_states[r].radiance = radiance;
            }
        }
    }
    add_dropped(dropped);
}

// After the sort before bounce `bounce.depth` (ReorderMode::SortPermute): gathers the states
// of the queue's rays into key order in the other state buffer and makes the queue the
// identity, so that `propagate` reads and writes the states contiguously. Dispatched over the
// live rays by the dispatch size `prepare_propagate` wrote for this bounce.
@compute @workgroup_size(WORKGROUP_SIZE)
fn permute_rays(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let t = thread_index(wg, nwg, local);
    let n = atomicLoad(&queue_counts[bounce.depth & 1u]);
    if (t < n) {
        permuted_states[t] = ray_states[ray_queue_in[t]];
        ray_queue_in[t] = t;
    }
}
