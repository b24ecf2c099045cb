// Scattering directions (sampling.rs): Lambertian cosine sampling, GGX visible-normal sampling
// (Heitz 2018) with the Smith G2/G1 weight, smooth dielectric Fresnel. Same code as Rust.

// Duff et al. 2017, "Building an Orthonormal Basis, Revisited".
struct Basis {
    t: vec3<f32>,
    b: vec3<f32>,
}

fn orthonormal_basis(n: vec3<f32>) -> Basis {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return Basis(
        vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        vec3<f32>(b, sign + n.y * n.y * a, -n.y),
    );
}

fn to_world(v: vec3<f32>, t: vec3<f32>, b: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return t * v.x + b * v.y + n * v.z;
}

fn to_local(v: vec3<f32>, t: vec3<f32>, b: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, t), dot(v, b), dot(v, n));
}

fn sample_diffuse(n: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let r = sqrt(u.x);
    let sc = sin_cos_turns(u.y);
    let local = vec3<f32>(r * sc.y, r * sc.x, sqrt(max(1.0 - u.x, 0.0)));
    let basis = orthonormal_basis(n);
    return to_world(local, basis.t, basis.b, n);
}

//#if spheres
// sampling.rs `sphere_cone_one_minus_cos`: 1 - cos θmax as sin²/(1 + cos).
fn sphere_cone_one_minus_cos(r: f32, d2: f32) -> f32 {
    let sin2 = min(r * r / d2, 1.0);
    let c = sqrt(max(1.0 - sin2, 0.0));
    return sin2 / (1.0 + c);
}
//#endif

//#if spheres
// sampling.rs `sphere_cap_pdf`.
fn sphere_cap_pdf(center: vec3<f32>, r: f32, p: vec3<f32>) -> f32 {
    let to_c = center - p;
    let d2 = dot(to_c, to_c);
    if (!(d2 > r * r)) {
        return 0.0;
    }
    return 1.0 / (2.0 * PI * sphere_cone_one_minus_cos(r, d2));
}
//#endif

// sampling.rs `sample_sphere_cap` (pbrt-v4 Sphere::Sample(ctx, u)); `valid` false on or
// inside the sphere.
struct CapSample {
    point: vec3<f32>,
    valid: bool,
}

//#if spheres
fn sample_sphere_cap(center: vec3<f32>, r: f32, p: vec3<f32>, u: vec2<f32>) -> CapSample {
    let to_c = center - p;
    let d2 = dot(to_c, to_c);
    if (!(d2 > r * r)) {
        return CapSample(vec3<f32>(0.0), false);
    }
    let sin2_max = r * r / d2;
    let sin_max = sqrt(sin2_max);
    let one_minus_cos = u.x * sphere_cone_one_minus_cos(r, d2);
    let cos_theta = 1.0 - one_minus_cos;
    let sin2_theta = one_minus_cos * (2.0 - one_minus_cos);
    let cos_alpha = sin2_theta / sin_max + cos_theta * sqrt(max(1.0 - sin2_theta / sin2_max, 0.0));
    let sin_alpha = sqrt(max(1.0 - cos_alpha * cos_alpha, 0.0));
    let sc = sin_cos_turns(u.y);
    let w = to_c / sqrt(d2);
    let basis = orthonormal_basis(w);
    let n = -to_world(vec3<f32>(sin_alpha * sc.y, sin_alpha * sc.x, cos_alpha), basis.t, basis.b, w);
    return CapSample(center + n * r, true);
}
//#endif

fn smith_lambda(w: vec3<f32>, alpha: f32) -> f32 {
    let a2_tan2 = alpha * alpha * (w.x * w.x + w.y * w.y) / (w.z * w.z);
    return 0.5 * (sqrt(1.0 + a2_tan2) - 1.0);
}

// Heitz 2018, listing 1: a GGX normal visible from wo (wo.z > 0); u.x radius, u.y angle.
fn sample_ggx_vndf(wo: vec3<f32>, alpha: f32, u: vec2<f32>) -> vec3<f32> {
    let vh = normalize(vec3<f32>(alpha * wo.x, alpha * wo.y, wo.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3<f32>(1.0, 0.0, 0.0);
    if (lensq > 0.0) {
        t1 = vec3<f32>(-vh.y, vh.x, 0.0) * (1.0 / sqrt(lensq));
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let sc = sin_cos_turns(u.y);
    let p1 = r * sc.y;
    let p2_disk = r * sc.x;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2_disk;
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 0.0)));
}

struct MetalSample {
    dir: vec3<f32>,
    weight: f32,
}

fn sample_metal(dir: vec3<f32>, n: vec3<f32>, alpha: f32, u: vec2<f32>) -> MetalSample {
    if (alpha <= 0.0) {
        return MetalSample(reflect(dir, n), 1.0);
    }
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    if (wo.z <= 0.0) {
        return MetalSample(dir, 0.0);
    }
    let m = sample_ggx_vndf(wo, alpha, u);
    let wi = reflect(-wo, m);
    if (wi.z <= 0.0) {
        return MetalSample(dir, 0.0);
    }
    let lambda_o = smith_lambda(wo, alpha);
    let lambda_i = smith_lambda(wi, alpha);
    return MetalSample(
        to_world(wi, basis.t, basis.b, n),
        (1.0 + lambda_o) / (1.0 + lambda_o + lambda_i),
    );
}

fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let sin2_t = eta * eta * max(1.0 - cos_i * cos_i, 0.0);
    if (sin2_t >= 1.0) {
        return 1.0;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    let r_s = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_p = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_s * r_s + r_p * r_p);
}

struct GlassSample {
    dir: vec3<f32>,
    transmitted: bool,
}

fn sample_glass(dir: vec3<f32>, n: vec3<f32>, eta: f32, u: f32) -> GlassSample {
    let cos_i = min(max(-dot(dir, n), 0.0), 1.0);
    let sin2_t = eta * eta * max(1.0 - cos_i * cos_i, 0.0);
    let f = fresnel_dielectric(cos_i, eta);
    if (u < f) {
        return GlassSample(reflect(dir, n), false);
    }
    let cos_t = sqrt(1.0 - sin2_t);
    return GlassSample(normalize(dir * eta + n * (eta * cos_i - cos_t)), true);
}
