// The persistent / megakernel schedule: one thread per pixel sample of the batch follows its
// whole path with the state in registers, then writes its radiance to its own slot.

@compute @workgroup_size(WORKGROUP_SIZE)
fn trace_paths(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let r = thread_index(wg, nwg, local);
    var traced = 0u;
    var dropped = 0u;
    if (r < scene.rays_in_batch) {
        let ps = batch_ray(r);
        let result = trace_path(ps.x, ps.y);
        traced = result.traced;
        dropped = write_sample(r, result.radiance);
    }
    flush_stats(local, traced, dropped);
}
