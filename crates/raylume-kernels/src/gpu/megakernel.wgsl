// The persistent / megakernel schedule: one thread per pixel sample of the batch follows its
// whole path with the state in registers, then writes its radiance to its sample's slot.

// Its own workgroup size (MEGAKERNEL_WORKGROUP_SIZE, lib.rs): faster than the other kernels'.
@compute @workgroup_size(MEGAKERNEL_WORKGROUP_SIZE)
fn trace_paths(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let r = (wg.y * nwg.x + wg.x) * MEGAKERNEL_WORKGROUP_SIZE + local;
    var traced = 0u;
    var dropped = 0u;
    if (r < scene.rays_in_batch) {
        let ps = tiled_ray(r);
        let result = trace_path(ps.x, ps.y);
        traced = result.traced;
        dropped = write_sample(sample_slot(ps.x, ps.y), result.radiance);
    }
    flush_stats(local, traced, dropped);
}

// The persistent schedule (path regeneration): at most PERSISTENT_THREADS threads, each
// taking pixel samples of the batch from a counter (queue_counts[3], zeroed before the
// dispatch) one bounce at a time: a thread whose path has ended starts the next sample at the
// top of the loop, so the lanes of a warp keep tracing while their paths end at different
// depths, where trace_paths' lanes idle until the longest path of the warp ends. Each sample
// is the same function calls in the same order as in trace_paths (trace_path's loop, unrolled
// into the outer one) and lands in its own slot: the same image, bit for bit.
@compute @workgroup_size(WORKGROUP_SIZE)
fn trace_paths_persistent(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    // The first sample is the thread's own index, the next ones come from the counter. The
    // loop carries only the path, its sample index and depth (pixel and sample are derived
    // from r at every bounce): the megakernel's state plus two words.
    var r = thread_index(wg, nwg, local);
    var depth = 0u;
    var traced = 0u;
    var dropped = 0u;
    var path = PathState(vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0), vec3<f32>(0.0), false, 0.0);
    loop {
        if (r >= scene.rays_in_batch) {
            break;
        }
        let ps = batch_ray(r);
        if (depth == 0u) {
            path = camera_path(ps.x, ps.y);
        }
        trace_ray(&path, ps.x, ps.y, depth, 0u);
        traced += 1u;
        depth += 1u;
        if (!path.alive || depth > scene.max_bounces) {
            dropped += write_sample(r, path.radiance);
            depth = 0u;
            r = nwg.x * nwg.y * WORKGROUP_SIZE + atomicAdd(&queue_counts[3], 1u);
        }
    }
    flush_stats(local, traced, dropped);
}
