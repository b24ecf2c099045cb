// raylume-sort radix sort: thread numbering and workgroup scans WITH subgroup operations.
// Variant of lanes_shared.wgsl (same function names). No assumption on the subgroup size
// (mask32.wgsl or mask128.wgsl, chosen from the adapter's largest subgroup size, define
// `LaneMask` and the ballot helpers) nor on how the driver maps invocations to subgroups:
// threads are numbered by (subgroup id, rank among the active lanes of their subgroup).
// The `num_subgroups` builtin is not used: lavapipe reports floor(WG / 8) for a workgroup whose
// last subgroup is partial (1 for 12 threads in subgroups of 8 and 4); the count is taken as
// 1 + the largest subgroup id instead.

struct LaneIds {
    @builtin(local_invocation_index) local_index: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(subgroup_invocation_id) sg_invocation: u32,
    @builtin(subgroup_id) sg_id: u32,
}

/// This thread's rank in the workgroup, 0..WG, in subgroup order.
var<private> lin: u32;
var<private> sg_id: u32;
var<private> num_sg: u32;
/// Rank among the active lanes of this subgroup, and their count.
var<private> sg_rank: u32;
var<private> sg_lanes: u32;
/// Lanes in the subgroups before this one.
var<private> sg_base: u32;
/// Ballot mask of the lanes with a smaller invocation id.
var<private> lt_mask: LaneMask;

var<workgroup> s_sg_sum: array<u32, MAX_SG>;
var<workgroup> s_num_sg: atomic<u32>;

/// Call first, in uniform control flow, from every stage that uses `lin` or the scans.
fn lanes_init(ids: LaneIds) {
    sg_id = ids.sg_id;
    sg_rank = subgroupExclusiveAdd(1u);
    sg_lanes = subgroupAdd(1u);
    lt_mask = lanes_below_mask(ids.sg_invocation);
    if (ids.local_index == 0u) {
        atomicStore(&s_num_sg, 0u);
    }
    workgroupBarrier();
    if (sg_rank == 0u) {
        s_sg_sum[sg_id] = sg_lanes;
        atomicMax(&s_num_sg, sg_id + 1u);
    }
    workgroupBarrier();
    num_sg = atomicLoad(&s_num_sg);
    var base = 0u;
    for (var s = 0u; s < sg_id; s++) {
        base += s_sg_sum[s];
    }
    workgroupBarrier();
    sg_base = base;
    lin = base + sg_rank;
}

/// Exclusive prefix sum of `x` over the workgroup in `lin` order: (sum before me, total).
/// Uniform control flow only (barriers).
fn wg_exclusive_scan(x: u32) -> vec2<u32> {
    let incl = subgroupInclusiveAdd(x);
    if (sg_rank == sg_lanes - 1u) {
        s_sg_sum[sg_id] = incl;
    }
    workgroupBarrier();
    var before = 0u;
    var total = 0u;
    for (var s = 0u; s < num_sg; s++) {
        let v = s_sg_sum[s];
        before += select(0u, v, s < sg_id);
        total += v;
    }
    workgroupBarrier();
    return vec2<u32>(before + incl - x, total);
}

/// True when every active lane of this subgroup holds the same `v`. Uniform control flow only.
fn lanes_agree(v: u32) -> bool {
    return subgroupAll(subgroupBroadcastFirst(v) == v);
}

/// True for one lane of each subgroup.
fn lane_leads() -> bool {
    return sg_rank == 0u;
}

/// Active lanes in this subgroup.
fn lanes_active() -> u32 {
    return sg_lanes;
}
