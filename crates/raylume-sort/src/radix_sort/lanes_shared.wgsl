// raylume-sort radix sort: thread numbering and workgroup scans WITHOUT subgroup operations
// (shared memory only). Variant of lanes_subgroup.wgsl (same function names).

struct LaneIds {
    @builtin(local_invocation_index) local_index: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
}

/// This thread's rank in the workgroup, 0..WG.
var<private> lin: u32;

var<workgroup> s_scan: array<u32, WG>;

fn lanes_init(ids: LaneIds) {
    lin = ids.local_index;
}

/// Exclusive prefix sum of `x` over the workgroup in `lin` order: (sum before me, total).
/// Hillis-Steele in shared memory. Uniform control flow only (barriers).
fn wg_exclusive_scan(x: u32) -> vec2<u32> {
    s_scan[lin] = x;
    for (var off = 1u; off < WG; off <<= 1u) {
        workgroupBarrier();
        var v = 0u;
        if (lin >= off) {
            v = s_scan[lin - off];
        }
        workgroupBarrier();
        s_scan[lin] += v;
    }
    workgroupBarrier();
    let incl = s_scan[lin];
    let total = s_scan[WG - 1u];
    workgroupBarrier();
    return vec2<u32>(incl - x, total);
}

/// Without subgroups every thread is its own group: never "agreeing" with others.
fn lanes_agree(v: u32) -> bool {
    return false;
}

fn lane_leads() -> bool {
    return true;
}

fn lanes_active() -> u32 {
    return 1u;
}
