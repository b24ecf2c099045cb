// One path segment (shade.rs): trace the ray, add what it sees, scatter. Schedule-agnostic.

struct PathState {
    origin: vec3<f32>,
    dir: vec3<f32>,
    throughput: vec3<f32>,
    radiance: vec3<f32>,
    alive: bool,
}

fn shade_hit(path: ptr<function, PathState>, hit: SurfaceHit, mat: GpuMaterial, rnd: vec4<f32>, last: bool) {
    if (HAS_EMISSION) {
        (*path).radiance += (*path).throughput * mat.emission;
    }
    if (last) {
        (*path).alive = false;
        return;
    }
    let ng = hit.geometric_normal;
    let front = dot((*path).dir, ng) < 0.0;
    let ng_facing = select(-ng, ng, front);
    let ns_facing = select(-hit.shading_normal, hit.shading_normal, front);
    var wi = (*path).dir;
    var weight = vec3<f32>(0.0);
    var reflected = true;
    if (HAS_DIFFUSE && mat.kind == MATERIAL_DIFFUSE) {
        wi = sample_diffuse(ns_facing, rnd.xy);
        weight = mat.color;
    } else if ((HAS_METAL || HAS_ROUGH_METAL) && mat.kind == MATERIAL_METAL) {
        var alpha = mat.alpha;
        if (!HAS_ROUGH_METAL) {
            alpha = 0.0;
        }
        let s = sample_metal((*path).dir, ns_facing, alpha, rnd.xy);
        wi = s.dir;
        weight = mat.color * s.weight;
    } else if (HAS_GLASS && mat.kind == MATERIAL_GLASS) {
        let eta = select(mat.ior, 1.0 / mat.ior, front);
        let s = sample_glass((*path).dir, ns_facing, eta, rnd.x);
        wi = s.dir;
        reflected = !s.transmitted;
        weight = select(vec3<f32>(1.0), mat.color, s.transmitted);
    }
    let cos_g = dot(wi, ng_facing);
    let right_side = select((cos_g < 0.0), (cos_g > 0.0), reflected);
    (*path).throughput *= weight;
    let t = (*path).throughput;
    (*path).alive = right_side && max(t.x, max(t.y, t.z)) > 0.0;
    (*path).origin = offset_ray_origin(hit, (*path).dir, select(-ng_facing, ng_facing, cos_g > 0.0));
    (*path).dir = wi;
}

fn trace_ray(path: ptr<function, PathState>, pixel: u32, sample: u32, depth: u32) {
    let hit = trace_closest(Ray((*path).origin, (*path).dir), 0.0, T_MAX);
    if (hit.prim == INVALID_INDEX) {
        (*path).radiance += (*path).throughput * environment_radiance((*path).dir);
        (*path).alive = false;
        return;
    }
    let surface = surface_at(hit, (*path).origin, (*path).dir);
    let mat = material_at(surface);
    let rnd = rand4(scene.seed, pixel, sample, depth, DIM_SCATTER);
    shade_hit(path, surface, mat, rnd, depth >= scene.max_bounces);
}
