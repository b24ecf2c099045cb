// The wavefront's walk stage (PathVariant::walk_stage; wide BVH and subgroups only): before
// `propagate`, the closest hit of every ray of the bounce's queue, into queue_hits at its queue
// slot, for `propagate` to shade (HITS_TRACED). A fixed number of threads walk the queue: a
// lane whose ray is done takes the next one (Aila & Laine 2009, "replacing terminated rays")
// once WALK_STAGE_REFILL lanes of its subgroup wait for one, or all of them do, so that the
// lanes of a subgroup stay busy while its longest walk goes on instead of idling until it
// ends. Each ray's walk is wide_walk's, step for step (the same nodes, primitives and hit:
// tests/schedules.rs), so images do not change; only which lane takes which step does.
// Appended to the tracer's module, after raylume-sort's LANE_MASK_WGSL (its ballot masks),
// only with the wide BVH on adapters with subgroups (gpu/pipelines.rs).

// The most rays a lane takes in a stage of `threads` threads over a queue of `n` (all of them
// but for WALK_STAGE_SHARE): the threads can take every ray between them, and on a software
// adapter no lane runs past its loop limit (crate::WALK_STAGE_SOFTWARE_SHARE).
fn lane_rays_at_most(n: u32, nwg: vec3<u32>) -> u32 {
    let threads = nwg.x * nwg.y * WORKGROUP_SIZE;
    return select(0xffffffffu, WALK_STAGE_SHARE * ((n + threads - 1u) / threads), WALK_STAGE_SHARE != 0u);
}

// A lane of the walk or shadow stage that waits for a ray, and one that leaves the loop.
const LANE_WAITS: u32 = 0xffffffffu;
const LANE_LEAVES: u32 = 0xfffffffeu;

// The refill of the walk and shadow stages, first in every iteration of their loops: the queue
// slot (of the `n` counted in queue_counts[counter]) that the lane walks now. Its own `slot`
// while it walks one; where it waits, the next slot of the queue (the subgroup's waiting lanes
// take the next ones with one atomic, once WALK_STAGE_REFILL of them wait or all those still
// in the loop do: one ballot an iteration decides, the same in every lane), LANE_WAITS, or
// LANE_LEAVES once the queue has no more or (WALK_STAGE_SHARE) the lane has taken `most`
// rays. `in_loop` (the subgroup's lanes still in the loop, the same in every lane) and
// `taken` (the rays this lane took) follow.
fn next_slot(
    slot: u32,
    lane: u32,
    below: LaneMask,
    n: u32,
    most: u32,
    counter: u32,
    in_loop: ptr<function, u32>,
    taken: ptr<function, u32>,
) -> u32 {
    if WALK_STAGE_SHARE != 0u {
        let done = slot == LANE_WAITS && *taken >= most;
        *in_loop -= mask_count(ballot(done));
        if done {
            return LANE_LEAVES;
        }
    }
    let waiting = slot == LANE_WAITS;
    let waiting_lanes = ballot(waiting);
    let want = mask_count(waiting_lanes);
    if want < min(WALK_STAGE_REFILL, *in_loop) {
        return slot;
    }
    let rank = mask_count(waiting_lanes & below);
    let first = first_lane(waiting_lanes);
    var base = 0u;
    if lane == first {
        base = atomicAdd(&queue_counts[counter], want);
    }
    base = subgroupShuffle(base, first);
    // The lanes whose slot is past the queue's end leave.
    *in_loop -= want - min(want, n - min(n, base));
    if !waiting {
        return slot;
    }
    if base + rank >= n {
        return LANE_LEAVES;
    }
    *taken += 1u;
    return base + rank;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn trace_hits(
    @builtin(subgroup_invocation_id) lane: u32,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let n = atomicLoad(&queue_counts[bounce.depth & 1u]);
    let most = lane_rays_at_most(n, nwg);
    var taken = 0u;
    // The lanes of the subgroup below this one, as ballot words.
    let below = lanes_below_mask(lane);
    // The subgroup's lanes still in the loop (the same in every lane: lanes leave only where
    // every lane sees it, next_slot).
    var in_loop = subgroupAdd(1u);
    var slot = LANE_WAITS;
    var wr: WideRay;
    var sheared: ShearedRay;
    var hit = Hit(0.0, INVALID_INDEX, 0.0, 0.0);
    var stack: array<vec2<u32>, WIDE_STACK_SIZE>;
    var sp = 0u;
    var group = vec2<u32>(0u, 0u);
    loop {
        let next = next_slot(slot, lane, below, n, most, WALK_STAGE_COUNTER, &in_loop, &taken);
        if next == LANE_LEAVES {
            break;
        }
        if next != slot {
            slot = next;
            let state = ray_states[ray_queue_in[slot]];
            let ray = Ray(state.origin, state.dir);
            wr = wide_ray(ray);
            sheared = shear_ray(ray);
            hit = Hit(min(T_MAX, T_MAX_LIMIT), INVALID_INDEX, 0.0, 0.0);
            sp = 0u;
            // The root as the only child of a group.
            group = vec2<u32>(0u, 0x80000000u);
        }
        if slot == LANE_WAITS {
            continue;
        }
        // One iteration of wide_walk's loop (closest hit, t_min 0).
        if (group.y & 0xff000000u) != 0u {
            let bit = firstLeadingBit(group.y);
            let index = wide_child_index(group, bit, wr.oct_inv4);
            group.y &= ~(1u << bit);
            if (group.y & 0xff000000u) != 0u {
                stack[sp] = group;
                sp += 1u;
            }
            let node = bvh_nodes[index];
            let mask = intersect_wide_node(node, wr, 0.0, hit.t);
            group = vec2<u32>(node.child_base, (mask & 0xff000000u) | (node.e_imask >> 24u));
            var prims = mask & 0x00ffffffu;
            while prims != 0u {
                let k = firstLeadingBit(prims);
                prims &= ~(1u << k);
                let i = node.prim_base + k;
                let r = intersect_primitive(bvh_primitives[i], sheared, 0.0, hit.t);
                if r.x < hit.t {
                    hit = Hit(r.x, i, r.y, r.z);
                }
            }
        }
        if (group.y & 0xff000000u) == 0u {
            if sp == 0u {
                store_queue_hit(slot, hit);
                slot = LANE_WAITS;
            } else {
                sp -= 1u;
                group = stack[sp];
            }
        }
    }
}

// The shadow stage (PathVariant::shadow_stage, NEE; after the `propagate` of a bounce with a
// walk stage, compiled with DEFER_SHADOW): the shadow rays that propagate's trace_ray left in
// the shadow queue (nee_records, store_shadow_record), walked as trace_hits walks path rays (a
// lane takes the next one as soon as its own walk ends), each as trace_any would (any hit
// with 0 < t < t_max: the same answer), then the vertex's two terms added to its path's
// radiance in trace_ray's order, the light's if nothing blocks it, then the emission, so that
// images do not change (tests/schedules.rs); a path that ended at the vertex has its sample
// written here.
@compute @workgroup_size(WORKGROUP_SIZE)
fn trace_shadows(
    @builtin(subgroup_invocation_id) lane: u32,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    let n = atomicLoad(&queue_counts[SHADOW_QUEUE_COUNTER]);
    let most = lane_rays_at_most(n, nwg);
    var taken = 0u;
    let below = lanes_below_mask(lane);
    var in_loop = subgroupAdd(1u);
    var slot = LANE_WAITS;
    var wr: WideRay;
    var sheared: ShearedRay;
    var t_max = 0.0;
    var occluded = false;
    var stack: array<vec2<u32>, WIDE_STACK_SIZE>;
    var sp = 0u;
    var group = vec2<u32>(0u, 0u);
    var dropped = 0u;
    loop {
        // trace_hits' refill, over the shadow queue.
        let next = next_slot(slot, lane, below, n, most, SHADOW_STAGE_COUNTER, &in_loop, &taken);
        if next == LANE_LEAVES {
            break;
        }
        if next != slot {
            slot = next;
            let w0 = nee_records[nee_word(0u, slot)];
            let w1 = nee_records[nee_word(1u, slot)];
            let ray = Ray(bitcast<vec3<f32>>(w0.xyz), bitcast<vec3<f32>>(w1.xyz));
            wr = wide_ray(ray);
            // wide_walk's any-hit order.
            wr.oct_inv4 ^= WIDE_ANY_OCT_FLIP;
            sheared = shear_ray(ray);
            // wide_walk's bound: a hit counts below it.
            t_max = min(bitcast<f32>(w0.w), T_MAX_LIMIT);
            occluded = false;
            sp = 0u;
            group = vec2<u32>(0u, 0x80000000u);
        }
        if slot == LANE_WAITS {
            continue;
        }
        // One iteration of wide_walk's loop (any hit, t_min 0).
        if (group.y & 0xff000000u) != 0u {
            let bit = firstLeadingBit(group.y);
            let index = wide_child_index(group, bit, wr.oct_inv4);
            group.y &= ~(1u << bit);
            if (group.y & 0xff000000u) != 0u {
                stack[sp] = group;
                sp += 1u;
            }
            let node = bvh_nodes[index];
            let mask = intersect_wide_node(node, wr, 0.0, t_max);
            group = vec2<u32>(node.child_base, (mask & 0xff000000u) | (node.e_imask >> 24u));
            var prims = mask & 0x00ffffffu;
            while prims != 0u {
                let k = firstLeadingBit(prims);
                prims &= ~(1u << k);
                let r = intersect_primitive(bvh_primitives[node.prim_base + k], sheared, 0.0, t_max);
                if r.x < t_max {
                    occluded = true;
                    break;
                }
            }
        }
        if occluded || (group.y & 0xff000000u) == 0u {
            if occluded || sp == 0u {
                dropped += add_shadow_terms(slot, occluded);
                slot = LANE_WAITS;
            } else {
                sp -= 1u;
                group = stack[sp];
            }
        }
    }
    // Dropped samples are rare: one atomic per lane that dropped any (flush_stats' barrier
    // would need every lane to leave the loop together).
    add_dropped(dropped);
}

// The terms of shadow queue slot `slot` added to its path's radiance as trace_ray adds them
// (the light's, unless `occluded`, then the emission); the sample written when the path ended
// there. Returns 1 when that sample was dropped (write_sample). The light's word is read only
// for a ray not blocked (`throughput * 0` as trace_ray's `select` makes it otherwise), the
// emission's only where the record has one (else the zero trace_ray would add).
fn add_shadow_terms(slot: u32, occluded: bool) -> u32 {
    let w1 = nee_records[nee_word(1u, slot)];
    let w2 = nee_records[nee_word(2u, slot)];
    let throughput_in = bitcast<vec3<f32>>(w2.xyz);
    var light_in = vec3<f32>(0.0);
    if (!occluded) {
        light_in = bitcast<vec3<f32>>(nee_records[nee_word(3u, slot)].xyz);
    }
    var emission = vec3<f32>(0.0);
    if ((w2.w & SHADOW_HAS_EMISSION) != 0u) {
        emission = bitcast<vec3<f32>>(nee_records[nee_word(4u, slot)].xyz);
    }
    let r = w1.w;
    var radiance = ray_states[r].radiance;
    radiance += throughput_in * light_in;
    radiance += emission;
    if ((w2.w & ~SHADOW_HAS_EMISSION) == NEE_ENDED) {
        return write_sample(sample_slot(ray_states[r].pixel, ray_states[r].sample), radiance);
    }
    ray_states[r].radiance = radiance;
    return 0u;
}
