// raylume-bvh: BVH traversal, the WGSL mirror of traverse.rs (same names, constants and
// operation order). The last part of TRAVERSE_WGSL, after gpu_types.wgsl, intersect.wgsl and
// hit.wgsl.
//
// Contract: this file declares no bindings. The including shader declares, at module scope
// and with bindings of its choosing,
//     var<storage, read> bvh_nodes: array<TraversalNode>;   // GpuBvh::nodes
//     var<storage, read> bvh_primitives: array<Primitive>;  // GpuBvh::primitives
// and must not define the names below. Node 0 is the root. Rays must have a non-zero
// direction; t_min must be below T_MISS.

// The node type the kernels bind as `bvh_nodes` (wide_traverse.wgsl binds WideNode).
alias TraversalNode = BvhNode;

// traverse.rs `intersect_leaf`: the closest hit of the leaf kept in `hit`; with any_hit,
// true at the first hit.
fn intersect_leaf(ray: ShearedRay, first: u32, count: u32, t_min: f32,
                  hit: ptr<function, Hit>, any_hit: bool) -> bool {
    for (var i = first; i < first + count; i += 1u) {
        let r = intersect_primitive(bvh_primitives[i], ray, t_min, (*hit).t);
        if r.x < (*hit).t {
            *hit = Hit(r.x, i, r.y, r.z);
            if any_hit {
                return true;
            }
        }
    }
    return false;
}

// traverse.rs `binary_walk`: the closest hit with t_min < t < t_max, or with any_hit the
// first found; a miss has prim == INVALID_INDEX and t == min(t_max, T_MAX_LIMIT).
fn binary_walk(ray: Ray, t_min: f32, t_max: f32, any_hit: bool) -> Hit {
    let inv_dir = 1.0 / ray.dir;
    let sheared = shear_ray(ray);
    var hit = Hit(min(t_max, T_MAX_LIMIT), INVALID_INDEX, 0.0, 0.0);
    var stack: array<u32, MAX_STACK_DEPTH>;
    var sp = 0u;
    var node_index = 0u;
    loop {
        let node = bvh_nodes[node_index];
        var t_left = intersect_aabb(node.left_min, node.left_max, ray.origin, inv_dir, t_min, hit.t);
        var t_right = intersect_aabb(node.right_min, node.right_max, ray.origin, inv_dir, t_min, hit.t);
        t_left = select(t_left, T_MISS, node.left_index == INVALID_INDEX);
        t_right = select(t_right, T_MISS, node.right_index == INVALID_INDEX);
        let swap = t_right < t_left;
        let t_near = select(t_left, t_right, swap);
        let near_index = select(node.left_index, node.right_index, swap);
        let near_count = select(node.left_count, node.right_count, swap);
        let t_far = select(t_right, t_left, swap);
        let far_index = select(node.right_index, node.left_index, swap);
        let far_count = select(node.right_count, node.left_count, swap);
        if near_count > 0u && t_near <= hit.t * AABB_T_FAR_SCALE {
            if intersect_leaf(sheared, near_index, near_count, t_min, &hit, any_hit) {
                return hit;
            }
        }
        if far_count > 0u && t_far <= hit.t * AABB_T_FAR_SCALE {
            if intersect_leaf(sheared, far_index, far_count, t_min, &hit, any_hit) {
                return hit;
            }
        }
        let go_near = near_count == 0u && t_near <= hit.t * AABB_T_FAR_SCALE;
        let go_far = far_count == 0u && t_far <= hit.t * AABB_T_FAR_SCALE;
        if go_near {
            if go_far {
                stack[sp] = far_index;
                sp += 1u;
            }
            node_index = near_index;
        } else if go_far {
            node_index = far_index;
        } else if sp > 0u {
            sp -= 1u;
            node_index = stack[sp];
        } else {
            break;
        }
    }
    return hit;
}

// Closest hit with t_min < t < t_max; a miss has prim == INVALID_INDEX and
// t == min(t_max, T_MAX_LIMIT).
fn trace_closest(ray: Ray, t_min: f32, t_max: f32) -> Hit {
    return binary_walk(ray, t_min, t_max, false);
}

// True if anything is hit with t_min < t < t_max (returns at the first hit).
fn trace_any(ray: Ray, t_min: f32, t_max: f32) -> bool {
    return binary_walk(ray, t_min, t_max, true).prim != INVALID_INDEX;
}

// The walk with the query's kind a value: shade.wgsl's trace_ray traces a path's ray and its
// shadow ray through one call.
fn trace_query(ray: Ray, t_min: f32, t_max: f32, any_hit: bool) -> Hit {
    return binary_walk(ray, t_min, t_max, any_hit);
}
