// One path segment (shade.rs): trace the ray, add what it sees, scatter. Schedule-agnostic.

struct PathState {
    origin: vec3<f32>,
    dir: vec3<f32>,
    throughput: vec3<f32>,
    radiance: vec3<f32>,
    alive: bool,
    // The BSDF pdf of the current direction when the vertex that sampled it also sampled the
    // lights; 0 when it did not (shade.rs `PathState::mis_pdf`).
    mis_pdf: f32,
}

// shade.rs `emitted`.
fn emitted(path: PathState, hit: SurfaceHit, mat: GpuMaterial, emission_weight: f32) -> vec3<f32> {
//#if emission
    let front = dot(path.dir, hit.geometric_normal) < 0.0;
    if (HAS_EMISSION && (front || (mat.flags & MATERIAL_TWO_SIDED) != 0u)) {
        return path.throughput * mat.emission * emission_weight;
    }
//#endif
    return vec3<f32>(0.0);
}

fn shade_hit(path: ptr<function, PathState>, hit: SurfaceHit, mat: GpuMaterial, rnd: vec4<f32>, last: bool) -> f32 {
    let ng = hit.geometric_normal;
    let front = dot((*path).dir, ng) < 0.0;
    if (last) {
        (*path).alive = false;
        return 0.0;
    }
    let ng_facing = select(-ng, ng, front);
    let ns_facing = select(-hit.shading_normal, hit.shading_normal, front);
    // One branch per material kind (the kinds exclude each other); each is left out of the
    // composed source of a scene without that material (`//#if`, gpu/shader.rs `compose`).
    var s = bsdf_absorbed((*path).dir);
//#if diffuse
    if (HAS_DIFFUSE && mat.kind == MATERIAL_DIFFUSE) {
        let wi = sample_diffuse(ns_facing, rnd.xy);
        s = BsdfSample(wi, mat.color, max(dot(wi, ns_facing), 0.0) * INV_PI, false);
    }
//#endif
//#if metal|rough_metal
    if ((HAS_METAL || HAS_ROUGH_METAL) && mat.kind == MATERIAL_METAL) {
        var alpha = mat.alpha;
        if (!HAS_ROUGH_METAL) {
            alpha = 0.0;
        }
        s = sample_conductor((*path).dir, ns_facing, alpha, mat.color, mat.eta, mat.k, rnd.xy);
    }
//#endif
//#if glass|rough_glass
    if ((HAS_GLASS || HAS_ROUGH_GLASS) && mat.kind == MATERIAL_GLASS) {
        let eta = select(mat.ior, 1.0 / mat.ior, front);
        var alpha = mat.alpha;
        if (!HAS_ROUGH_GLASS) {
            alpha = 0.0;
        }
        s = sample_rough_dielectric((*path).dir, ns_facing, alpha, eta, mat.color, rnd.zxy);
    }
//#endif
//#if plastic
    if (HAS_PLASTIC && mat.kind == MATERIAL_PLASTIC) {
        if (mat.alpha > 0.0) {
            s = sample_rough_plastic((*path).dir, ns_facing, mat.alpha, mat.ior, mat.color, mat.table, rnd.zxy);
        } else {
            s = sample_plastic((*path).dir, ns_facing, mat.ior, mat.color, rnd.zxy);
        }
    }
//#endif
    let wi = s.dir;
    let cos_g = dot(wi, ng_facing);
    let right_side = select((cos_g > 0.0), (cos_g < 0.0), s.transmitted);
    (*path).throughput *= s.weight;
    let t = (*path).throughput;
    (*path).alive = right_side && max(t.x, max(t.y, t.z)) > 0.0;
    (*path).origin = offset_ray_origin(hit, (*path).dir, select(-ng_facing, ng_facing, cos_g > 0.0));
    (*path).dir = wi;
    return s.pdf;
}

// shade.rs `path_rand4`.
fn path_rand4(pixel: u32, sample: u32, bounce: u32, dim: u32) -> vec4<f32> {
    return path_rand4_at(sampler_pixel(pixel), pixel, sample, bounce, dim);
}

// The render's sampler: the pipeline's SAMPLER override, which TracerPipelines sets to the
// uniforms' `sampler` (shade.rs reads `scene.sampler`), so that the other samplers' code is
// dead; the uniforms' value when the pipeline is compiled for any (SAMPLER_FROM_SCENE).
fn path_sampler() -> u32 {
    return select(SAMPLER, scene.sampler, SAMPLER == SAMPLER_FROM_SCENE);
}

// shade.rs `sampler_pixel`.
fn sampler_pixel(pixel: u32) -> SobolPixel {
    if (path_sampler() == SAMPLER_INDEPENDENT) {
        return SobolPixel(0u, 0u, 0u);
    }
    let xy = vec2<u32>(pixel % scene.width, pixel / scene.width);
    return sobol_pixel(scene.seed, xy, scene.spp);
}

// shade.rs `path_rand4_at`.
fn path_rand4_at(sp: SobolPixel, pixel: u32, sample: u32, bounce: u32, dim: u32) -> vec4<f32> {
    let sampler = path_sampler();
    if (sampler != SAMPLER_INDEPENDENT) {
        let shuffled = select(0u, 1u, sampler == SAMPLER_SOBOL);
        let group = bounce * DIMS_PER_BOUNCE + dim;
        if (dim == DIM_CAMERA || dim == DIM_ROULETTE) {
            let v = sobol2_at(shuffled, sp, sample, group);
            return vec4<f32>(v.x, v.y, 0.0, 0.0);
        }
        return sobol4_at(shuffled, sp, sample, group);
    }
    return rand4(scene.seed, pixel, sample, bounce, dim);
}

// Returns true when the vertex's light sample was left for `next_event` (DEFER_NEE) in
// nee_records at queue slot `slot` (wavefront.wgsl `store_nee_record`). `slot` is also where
// the walk stage left the path ray's hit (HITS_TRACED); it is unused otherwise.
fn trace_ray(path: ptr<function, PathState>, pixel: u32, sample: u32, depth: u32, slot: u32) -> bool {
    // The path's ray and then, where the lights are sampled, the shadow ray go through one
    // call of the walk (the driver inlines each call: one copy of the traversal, where two
    // calls compiled slower and, with the shading's state live across the second, traced
    // slower). The hit is shaded before the shadow ray is traced (as shade.rs): the light
    // sample's contribution, the emission and the scattered ray; only the two terms wait
    // across the walk, to be added in the order of the next_event stage's sums (the light's,
    // if its ray is not blocked, then the emission).
    var ray = Ray((*path).origin, (*path).dir);
    var t_max = T_MAX;
    var shadow = false;
    var occluded = false;
    var sample_here = false;
    var throughput_in = vec3<f32>(0.0);
    var light_in = vec3<f32>(0.0);
    var emission = vec3<f32>(0.0);
    loop {
        // With a walk stage (HITS_TRACED: the propagate of the bounces that run it) the path
        // ray's hit is already traced, at this ray's queue slot; the shadow ray is walked here.
        var hit: Hit;
        if (HITS_TRACED && !shadow) {
            hit = load_queue_hit(slot);
        } else {
            hit = trace_query(ray, 0.0, t_max, shadow);
        }
        if (shadow) {
            occluded = hit.prim != INVALID_INDEX;
            break;
        }
        if (hit.prim == INVALID_INDEX) {
            // shade.rs: weighed against the shadow ray toward the environment.
            var w_env = 1.0;
            if (NEXT_EVENT && (*path).mis_pdf > 0.0 && scene.environment_select > 0.0) {
                w_env = mis_weight((*path).mis_pdf, scene.environment_select * environment_pdf((*path).dir, environment_cell((*path).origin)));
            }
            (*path).radiance += (*path).throughput * environment_radiance((*path).dir) * w_env;
            (*path).alive = false;
            return false;
        }
        let surface = surface_at(hit, (*path).origin, (*path).dir);
        let mat = material_at(surface);
        let last = depth >= scene.max_bounces;
        let sp = sampler_pixel(pixel);
        // An emissive triangle hit by a direction sampled where the lights were sampled too:
        // weigh the scattered ray's estimate against the shadow ray's (shade.rs).
        var emission_weight = 1.0;
        var lq: LightQuery;
//#if emission|constant_environment|environment_map
        // A plain render's pipelines (NEXT_EVENT false, gpu::PathVariant) hold none of this:
        // its own `if`, which the override makes constant (tests/compose.rs follows it).
        if (NEXT_EVENT) {
            if ((HAS_EMISSION || HAS_CONSTANT_ENVIRONMENT || HAS_ENVIRONMENT_MAP) && (HAS_DIFFUSE || HAS_PLASTIC || HAS_ROUGH_METAL || HAS_ROUGH_GLASS)) {
                let prim = bvh_primitives[hit.prim];
                if ((*path).mis_pdf > 0.0 && bitcast<u32>(prim.b.w) == PRIM_TRIANGLE) {
                    let n = cross(prim.b.xyz - prim.a.xyz, prim.c.xyz - prim.a.xyz);
                    let cos_l = abs(dot(n, (*path).dir)) / length(n);
                    emission_weight = mis_weight((*path).mis_pdf, light_pdf(mat.emission, hit.t * hit.t, cos_l));
                }
//#if spheres
                if (HAS_SPHERES && (*path).mis_pdf > 0.0 && bitcast<u32>(prim.b.w) == PRIM_SPHERE) {
                    let cap_pdf = sphere_cap_pdf(prim.a.xyz, prim.a.w, (*path).origin);
                    emission_weight = mis_weight((*path).mis_pdf, sphere_light_pdf(mat.emission, prim.a.w, cap_pdf));
                }
//#endif
                sample_here = scene.light_count > 0u && samples_lights(mat) && !last;
                if (sample_here) {
                    let rnd_light = path_rand4_at(sp, pixel, sample, depth, DIM_LIGHT);
                    if (!DEFER_NEE) {
                        throughput_in = (*path).throughput;
                        lq = light_query(surface, mat, (*path).dir, rnd_light);
                        if (lq.valid) {
                            light_in = light_contribution(lq, mat, (*path).dir);
                        }
                    } else {
                        // next_event adds the light sample, then the emission (below), to the
                        // radiance as it is now: the sums of the other schedules, in their order.
                        store_nee_record(slot, NeeRecord(surface.position, surface.offset, surface.geometric_normal,
                            surface.back_offset, surface.shading_normal, surface.material, mat.color, NEE_PENDING,
                            (*path).dir, 0u, (*path).throughput, 0u, rnd_light,
                            emitted(*path, surface, mat, emission_weight), 0u));
                    }
                }
            }
        }
//#endif
        if (!(DEFER_NEE && sample_here)) {
            emission = emitted(*path, surface, mat, emission_weight);
        }
        let rnd = path_rand4_at(sp, pixel, sample, depth, DIM_SCATTER);
        let pdf = shade_hit(path, surface, mat, rnd, last);
        (*path).mis_pdf = select(0.0, pdf, sample_here);
        if ((*path).alive && depth >= scene.rr_depth) {
            russian_roulette(path, path_rand4_at(sp, pixel, sample, depth, DIM_ROULETTE).x);
        }
        if (lq.valid) {
            if (DEFER_SHADOW) {
                // The shadow stage walks the ray, then adds the two terms in the order below
                // (gpu/wavefront.wgsl queues them, gpu/walk_stage.wgsl `trace_shadows`).
                deferred_shadow = DeferredShadow(lq.ray, lq.t_max, throughput_in, light_in, emission);
                return true;
            }
            ray = lq.ray;
            t_max = lq.t_max;
            shadow = true;
            continue;
        }
        break;
    }
    if (sample_here && !DEFER_NEE) {
        (*path).radiance += throughput_in * select(light_in, vec3<f32>(0.0), occluded);
    }
    if (!(DEFER_NEE && sample_here)) {
        (*path).radiance += emission;
    }
    return sample_here && DEFER_NEE;
}


// shade.rs `russian_roulette`.
fn russian_roulette(path: ptr<function, PathState>, u: f32) {
    let t = (*path).throughput;
    let q = min(max(t.x, max(t.y, t.z)), RR_MAX_SURVIVAL);
    if (u < q) {
        (*path).throughput = t / q;
    } else {
        (*path).alive = false;
    }
}

// shade.rs `samples_lights`: the materials whose reflection next-event estimation evaluates.
fn samples_lights(mat: GpuMaterial) -> bool {
    return (HAS_DIFFUSE && mat.kind == MATERIAL_DIFFUSE)
        || (HAS_PLASTIC && mat.kind == MATERIAL_PLASTIC)
        || (HAS_ROUGH_METAL && mat.kind == MATERIAL_METAL && mat.alpha > 0.0)
        || (HAS_ROUGH_GLASS && mat.kind == MATERIAL_GLASS && mat.alpha > 0.0);
}

// shade.rs `light_side`: 1 in front, -1 behind (rough glass), 0 neither.
fn light_side(mat: GpuMaterial, ns_facing: vec3<f32>, ng_facing: vec3<f32>, wi: vec3<f32>) -> f32 {
    let s = dot(ns_facing, wi);
    let g = dot(ng_facing, wi);
    if (s > 0.0 && g > 0.0) {
        return 1.0;
    }
    if (HAS_ROUGH_GLASS && mat.kind == MATERIAL_GLASS && s < 0.0 && g < 0.0) {
        return -1.0;
    }
    return 0.0;
}

// shade.rs `eval_material`: f cos and the sampling pdf of `mat` from dir_in into wi.
fn eval_material(mat: GpuMaterial, dir_in: vec3<f32>, n: vec3<f32>, wi: vec3<f32>, front: bool) -> BsdfEval {
    if (HAS_DIFFUSE && mat.kind == MATERIAL_DIFFUSE) {
        let pdf = max(dot(n, wi), 0.0) * INV_PI;
        return BsdfEval(mat.color * pdf, pdf);
    }
//#if rough_metal
    if (HAS_ROUGH_METAL && mat.kind == MATERIAL_METAL) {
        return eval_conductor(dir_in, n, wi, mat.alpha, mat.color, mat.eta, mat.k);
    }
//#endif
//#if plastic
    if (HAS_PLASTIC && mat.kind == MATERIAL_PLASTIC) {
        if (mat.alpha > 0.0) {
            return eval_rough_plastic(dir_in, n, wi, mat.alpha, mat.ior, mat.color, mat.table);
        }
        return eval_plastic(dir_in, n, wi, mat.ior, mat.color);
    }
//#endif
//#if rough_glass
    if (HAS_ROUGH_GLASS && mat.kind == MATERIAL_GLASS) {
        let eta = select(mat.ior, 1.0 / mat.ior, front);
        return eval_rough_dielectric(dir_in, n, wi, mat.alpha, eta, mat.color);
    }
//#endif
    return bsdf_eval_zero();
}

fn light_pdf(emission: vec3<f32>, dist2: f32, cos_l: f32) -> f32 {
    return dot(emission, LUMINANCE) * dist2 / (scene.light_power * cos_l);
}

// shade.rs `sphere_light_pdf`.
fn sphere_light_pdf(emission: vec3<f32>, r: f32, cap_pdf: f32) -> f32 {
    return dot(emission, LUMINANCE) * (4.0 * PI * r * r) / scene.light_power * cap_pdf;
}

fn mis_weight(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    if (a2 + b2 > 0.0) {
        return a2 / (a2 + b2);
    }
    return 0.0;
}

// shade.rs `LightQuery`: a light sample's shadow ray and what its contribution needs besides
// the ray's verdict; `valid` false where shade.rs has `None`.
struct LightQuery {
    valid: bool,
    ray: Ray,
    t_max: f32,
    wi: vec3<f32>,
    ns_facing: vec3<f32>,
    front: bool,
    is_env: bool,
    is_sphere: bool,
    light: u32,
    cell: u32,
    origin: vec3<f32>,
    env_pdf: f32,
    dist2: f32,
    cos_l: f32,
    p_select: f32,
}

fn no_light_query() -> LightQuery {
    return LightQuery(false, Ray(vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0)), 0.0, vec3<f32>(0.0), vec3<f32>(0.0),
        false, false, false, 0u, 0u, vec3<f32>(0.0), 0.0, 0.0, 0.0, 0.0);
}

// Next-event estimation's light sample at a hit (shade.rs `light_query`): the light chosen by
// rnd.x, a point on it from (rnd.x rescaled within the light's share, rnd.y), and the shadow ray
// toward it. The BSDF samplers get rnd.zxy (shade.rs `lobe_first`).
fn light_query(hit: SurfaceHit, mat: GpuMaterial, dir_in: vec3<f32>, rnd: vec4<f32>) -> LightQuery {
    var lo = 0u;
    var hi = scene.light_count - 1u;
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        if (lights[mid].cdf > rnd.x) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    let light = lights[lo];
    var before = 0.0;
    if (lo > 0u) {
        before = lights[lo - 1u].cdf;
    }
    let p_select = light.cdf - before;
    var x = 0.0;
    if (p_select > 0.0) {
        x = min((rnd.x - before) / p_select, SOBOL_ONE_MINUS_EPSILON);
    }
    let ng = hit.geometric_normal;
    let front = dot(dir_in, ng) < 0.0;
    let ng_facing = select(-ng, ng, front);
    let ns_facing = select(-hit.shading_normal, hit.shading_normal, front);
    let origin = offset_ray_origin(hit, dir_in, ng_facing);
    let cell = environment_cell(origin);
    let is_env = (HAS_CONSTANT_ENVIRONMENT || HAS_ENVIRONMENT_MAP) && light.kind == LIGHT_ENVIRONMENT;
    let is_sphere = HAS_SPHERES && light.kind == LIGHT_SPHERE;
    var wi: vec3<f32>;
    var t_max = T_MAX;
    var side: f32;
    var env_pdf = 0.0;
    var dist2 = 0.0;
    var cos_l = 1.0;
    if (is_env) {
        let es = sample_environment(vec2<f32>(x, rnd.y), cell);
        wi = es.dir;
        env_pdf = es.pdf;
        side = light_side(mat, ns_facing, ng_facing, wi);
        if (!(env_pdf > 0.0 && p_select > 0.0 && side != 0.0)) {
            return no_light_query();
        }
    } else {
        let su = sqrt(x);
        var point = light.p0 + light.e1 * (su * (1.0 - rnd.y)) + light.e2 * (su * rnd.y);
//#if spheres
        if (is_sphere) {
            let cap = sample_sphere_cap(light.p0, light.e1.x, origin, vec2<f32>(x, rnd.y));
            if (!cap.valid) {
                return no_light_query();
            }
            point = cap.point;
        }
//#endif
        let to = point - origin;
        dist2 = dot(to, to);
        if (!(p_select > 0.0 && dist2 > 0.0)) {
            return no_light_query();
        }
        let dist = sqrt(dist2);
        wi = to / dist;
        t_max = dist * SHADOW_T_SCALE;
        side = light_side(mat, ns_facing, ng_facing, wi);
        if (!is_sphere) {
            let nl = cross(light.e1, light.e2);
            let cos_front = -dot(nl, wi) / length(nl);
            cos_l = select(cos_front, abs(cos_front), light.two_sided != 0u);
        }
        if (!(side != 0.0 && cos_l > 0.0)) {
            return no_light_query();
        }
    }
    var shadow_from = origin;
    if (side < 0.0) {
        shadow_from = offset_ray_origin(hit, dir_in, -ng_facing);
    }
    return LightQuery(true, Ray(shadow_from, wi), t_max, wi, ns_facing, front, is_env, is_sphere, lo, cell,
        origin, env_pdf, dist2, cos_l, p_select);
}

// shade.rs `light_contribution`: the reflected radiance the sample carries if its shadow ray
// is not blocked, times its MIS weight.
fn light_contribution(q: LightQuery, mat: GpuMaterial, dir_in: vec3<f32>) -> vec3<f32> {
    let f = eval_material(mat, dir_in, q.ns_facing, q.wi, q.front);
    if (q.is_env) {
        let we = mis_weight(scene.environment_select * environment_pdf(q.wi, q.cell), f.pdf);
        return f.value * environment_radiance(q.wi) * (we / (q.p_select * q.env_pdf));
    }
    let light = lights[q.light];
//#if spheres
    if (q.is_sphere) {
        let cap_pdf = sphere_cap_pdf(light.p0, light.e1.x, q.origin);
        let ws = mis_weight(sphere_light_pdf(light.emission, light.e1.x, cap_pdf), f.pdf);
        return f.value * light.emission * (ws / (q.p_select * cap_pdf));
    }
//#endif
    let w = mis_weight(light_pdf(light.emission, q.dist2, q.cos_l), f.pdf);
    return f.value * light.emission * (q.cos_l * light.area / (q.dist2 * q.p_select) * w);
}
