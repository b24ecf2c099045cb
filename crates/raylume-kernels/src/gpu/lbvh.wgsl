// raylume-kernels: the linear BVH built on the GPU (gpu/lbvh.rs), over raylume-bvh's
// LBVH_WGSL (the mirror of raylume_bvh::lbvh): Morton codes, two stable radix sorts (low
// words, then high), the primitives gathered in sorted order, the radix tree's inner nodes,
// then one refit pass per level. Bindings as gpu/lbvh.rs `LbvhBuilder` lays them out.

@group(0) @binding(0) var<storage, read> lbvh_source: array<Primitive>;
@group(0) @binding(1) var<storage, read_write> lbvh_unsorted: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read_write> lbvh_keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> lbvh_values: array<u32>;
@group(0) @binding(4) var<storage, read_write> lbvh_codes: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read_write> bvh_primitives: array<Primitive>;
@group(0) @binding(6) var<storage, read_write> bvh_nodes: array<BvhNode>;
@group(0) @binding(7) var<storage, read_write> lbvh_state: array<u32>;
@group(0) @binding(8) var<uniform> lbvh_params: LbvhParams;

// The thread's index in a grid of LBVH_WORKGROUP_SIZE-thread groups, rows of nwg.x groups.
fn lbvh_thread(wg: vec3<u32>, nwg: vec3<u32>, local: u32) -> u32 {
    return (wg.y * nwg.x + wg.x) * LBVH_WORKGROUP_SIZE + local;
}

// Each primitive's code; the pairs (low word, index) for the first sort.
@compute @workgroup_size(LBVH_WORKGROUP_SIZE)
fn lbvh_encode(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = lbvh_thread(wg, nwg, local);
    if (i >= lbvh_params.count) {
        return;
    }
    let p = lbvh_source[i];
    let code = morton_code((lbvh_box_max(p) + lbvh_box_min(p)) * 0.5);
    lbvh_unsorted[i] = code;
    lbvh_keys[i] = code.x;
    lbvh_values[i] = i;
}

// The high words in the first sort's order, for the second (stable: equal high words keep
// the low words' order, and equal codes the indices').
@compute @workgroup_size(LBVH_WORKGROUP_SIZE)
fn lbvh_high_keys(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = lbvh_thread(wg, nwg, local);
    if (i >= lbvh_params.count) {
        return;
    }
    lbvh_keys[i] = lbvh_unsorted[lbvh_values[i]].y;
}

// Codes and primitives in sorted order.
@compute @workgroup_size(LBVH_WORKGROUP_SIZE)
fn lbvh_gather(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let k = lbvh_thread(wg, nwg, local);
    if (k >= lbvh_params.count) {
        return;
    }
    let s = lbvh_values[k];
    lbvh_codes[k] = lbvh_unsorted[s];
    bvh_primitives[k] = lbvh_source[s];
}

// Inner node i's children into bvh_nodes[i] (their boxes come with the refit).
@compute @workgroup_size(LBVH_WORKGROUP_SIZE)
fn lbvh_inner(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = lbvh_thread(wg, nwg, local);
    if (i + 1u >= lbvh_params.count) {
        return;
    }
    let node = lbvh_node(i32(i));
    bvh_nodes[i].left_index = node.left;
    bvh_nodes[i].left_count = select(0u, 1u, node.left_leaf);
    bvh_nodes[i].right_index = node.right;
    bvh_nodes[i].right_count = select(0u, 1u, node.right_leaf);
    lbvh_state[i] = 0u;
}

// A child slot's box: a leaf's primitive, or the union of an inner node's slots.
fn lbvh_child_box(index: u32, count: u32) -> array<vec3<f32>, 2> {
    if (count > 0u) {
        let p = bvh_primitives[index];
        return array<vec3<f32>, 2>(lbvh_box_min(p), lbvh_box_max(p));
    }
    let c = bvh_nodes[index];
    return array<vec3<f32>, 2>(min(c.left_min, c.right_min), max(c.left_max, c.right_max));
}

// Pass `pass_index` (1, 2, ...): every node whose inner children were finished by earlier
// passes takes its boxes and is finished at this pass, which is its height (leaves' parents
// at 1). A child finished in this same pass is left for the next: its boxes may not be
// visible yet.
@compute @workgroup_size(LBVH_WORKGROUP_SIZE)
fn lbvh_refit(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let i = lbvh_thread(wg, nwg, local);
    if (i + 1u >= lbvh_params.count || lbvh_state[i] != 0u) {
        return;
    }
    let pass_index = lbvh_params.pass_index;
    let node = bvh_nodes[i];
    if (node.left_count == 0u) {
        let s = lbvh_state[node.left_index];
        if (s == 0u || s >= pass_index) {
            return;
        }
    }
    if (node.right_count == 0u) {
        let s = lbvh_state[node.right_index];
        if (s == 0u || s >= pass_index) {
            return;
        }
    }
    let l = lbvh_child_box(node.left_index, node.left_count);
    let r = lbvh_child_box(node.right_index, node.right_count);
    bvh_nodes[i].left_min = l[0];
    bvh_nodes[i].left_max = l[1];
    bvh_nodes[i].right_min = r[0];
    bvh_nodes[i].right_max = r[1];
    lbvh_state[i] = pass_index;
}
