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

@compute @workgroup_size(1)
fn prepare_propagate() {
    let q = bounce.depth & 1u;
    let n = atomicLoad(&queue_counts[q]);
    let groups = (n + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    let x = min(groups, MAX_WORKGROUPS_PER_DIMENSION);
    var y = 1u;
    if (x > 0u) {
        y = (groups + x - 1u) / x;
    }
    dispatch_args[0] = x;
    dispatch_args[1] = y;
    dispatch_args[2] = 1u;
    atomicStore(&queue_counts[1u - q], 0u);
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
    var traced = 0u;
    var dropped = 0u;
    var live = false;
    var r = 0u;
    var key = DEAD_RAY_KEY;
    if (t < n) {
        r = ray_queue_in[t];
        var ray = ray_states[r];
        var path = PathState(ray.origin, ray.dir, ray.throughput, ray.radiance, true, select(0.0, bitcast<f32>(ray.alive), ray.alive > RAY_ALIVE));
        // A light sample left for next_event goes to this queue slot's record: the stage
        // reads it at the same slot, so both access the records in queue order.
        let deferred = trace_ray(&path, ray.pixel, ray.sample, bounce.depth, t);
        traced = 1u;
        live = path.alive;
        ray.origin = path.origin;
        ray.dir = path.dir;
        ray.throughput = path.throughput;
        ray.radiance = path.radiance;
        ray.depth = bounce.depth + 1u;
        ray.alive = select(0u, select(RAY_ALIVE, bitcast<u32>(path.mis_pdf), path.mis_pdf > 0.0), live);
        ray_states[r] = ray;
        if (live) {
            // SORT KEY (raylume-sort's MORTON_WGSL): the paper's 30-bit origin-direction key.
            key = ray_sort_key(path.origin, path.dir, scene.scene_min, scene.scene_extent);
        } else if (deferred) {
            // next_event adds the vertex's light sample, then writes the sample.
            set_nee_record_state(t, NEE_ENDED);
        } else {
            // The sample's own slot, not `r`: permute_rays may have moved its state.
            dropped = write_sample(sample_slot(ray.pixel, ray.sample), path.radiance);
        }
        if (bounce.sort_next == 0u) {
            // Indexed by queue slot, so that (ray_keys, queue) pairs can be sorted.
            ray_keys[t] = key;
        }
    }
    // Compaction: the live rays of this workgroup take consecutive slots of the next queue.
    var slot = 0u;
    if (live) {
        slot = atomicAdd(&wg_live, 1u);
    }
    workgroupBarrier();
    if (local == 0u) {
        let count = atomicLoad(&wg_live);
        if (count > 0u) {
            wg_base = atomicAdd(&queue_counts[1u - q], count);
        }
    }
    flush_stats(local, traced, dropped);
    workgroupBarrier();
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
    flush_stats(local, 0u, dropped);
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
