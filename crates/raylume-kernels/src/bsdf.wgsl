// Microfacet materials after Mitsuba 3's plugins (bsdf.rs, whose module notes give the
// conventions): conductor / roughconductor, plastic, roughplastic, roughdielectric; GGX with
// separable Smith masking and visible-normal sampling. Same names, arguments and constants as
// the Rust mirror. Needs math.wgsl (PI, INV_PI) and sampling.wgsl (basis, VNDF, Fresnel).

const GGX_MIN_ALPHA: f32 = 1e-4;
const ROUGH_TRANSMITTANCE_RES: u32 = 64u;

struct BsdfSample {
    dir: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
    transmitted: bool,
}

struct BsdfEval {
    value: vec3<f32>,
    pdf: f32,
}

fn bsdf_absorbed(dir: vec3<f32>) -> BsdfSample {
    return BsdfSample(dir, vec3<f32>(0.0), 0.0, false);
}

fn bsdf_eval_zero() -> BsdfEval {
    return BsdfEval(vec3<f32>(0.0), 0.0);
}

//#if metal|rough_metal|glass|rough_glass|plastic
fn ggx_d(m: vec3<f32>, alpha: f32) -> f32 {
    let x = m.x / alpha;
    let y = m.y / alpha;
    let s = x * x + y * y + m.z * m.z;
    let d = 1.0 / (PI * alpha * alpha * (s * s));
    return select(0.0, d, d * m.z > 1e-20);
}
//#endif

//#if metal|rough_metal|glass|rough_glass|plastic
fn smith_g1(v: vec3<f32>, m: vec3<f32>, alpha: f32) -> f32 {
    let xy_alpha_2 = (alpha * v.x) * (alpha * v.x) + (alpha * v.y) * (alpha * v.y);
    let tan_theta_alpha_2 = xy_alpha_2 / (v.z * v.z);
    var g = 2.0 / (1.0 + sqrt(1.0 + tan_theta_alpha_2));
    if (xy_alpha_2 == 0.0) {
        g = 1.0;
    }
    if (dot(v, m) * v.z <= 0.0) {
        g = 0.0;
    }
    return g;
}
//#endif

//#if metal|rough_metal
fn sqrt3(v: vec3<f32>) -> vec3<f32> {
    return sqrt(v);
}
//#endif

//#if metal|rough_metal
// Exact conductor Fresnel (Mitsuba's fresnel_conductor); eta == 0 channels reflect exactly 1.
fn fresnel_conductor(cos_i: f32, eta: vec3<f32>, k: vec3<f32>) -> vec3<f32> {
    let cos_i_2 = cos_i * cos_i;
    let sin_i_2 = 1.0 - cos_i_2;
    let sin_i_4 = sin_i_2 * sin_i_2;
    let temp_1 = eta * eta - k * k - vec3<f32>(sin_i_2);
    let a_2_pb_2 = sqrt3(max(temp_1 * temp_1 + 4.0 * k * k * eta * eta, vec3<f32>(0.0)));
    let a = sqrt3(max(0.5 * (a_2_pb_2 + temp_1), vec3<f32>(0.0)));
    let term_1 = a_2_pb_2 + vec3<f32>(cos_i_2);
    let term_2 = 2.0 * cos_i * a;
    let r_s = (term_1 - term_2) / (term_1 + term_2);
    let term_3 = a_2_pb_2 * cos_i_2 + vec3<f32>(sin_i_4);
    let term_4 = term_2 * sin_i_2;
    let r_p = r_s * (term_3 - term_4) / (term_3 + term_4);
    let f = 0.5 * (r_s + r_p);
    return select(f, vec3<f32>(1.0), eta == vec3<f32>(0.0));
}
//#endif

fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv_eta = 1.0 / eta;
    if (eta < 1.0) {
        return 0.0636 * inv_eta + (eta * (eta * -1.4399 + 0.7099) + 0.6681);
    }
    let x = inv_eta;
    return 0.919317 + x * (-3.4793 + x * (6.75335 + x * (-7.80989 + x * (4.98554 + x * -1.36881))));
}

fn sample_cosine_local(u: vec2<f32>) -> vec3<f32> {
    let r = sqrt(u.x);
    let sc = sin_cos_turns(u.y);
    return vec3<f32>(r * sc.y, r * sc.x, sqrt(max(1.0 - u.x, 0.0)));
}

// ---- conductor / roughconductor ----

//#if metal|rough_metal
fn sample_conductor(
    dir: vec3<f32>,
    n: vec3<f32>,
    alpha: f32,
    reflectance: vec3<f32>,
    eta: vec3<f32>,
    k: vec3<f32>,
    u: vec2<f32>,
) -> BsdfSample {
    if (alpha <= 0.0) {
        let cos_i = -dot(dir, n);
        if (cos_i <= 0.0) {
            return bsdf_absorbed(dir);
        }
        return BsdfSample(
            reflect(dir, n),
            reflectance * fresnel_conductor(min(cos_i, 1.0), eta, k),
            0.0,
            false,
        );
    }
    let a = max(alpha, GGX_MIN_ALPHA);
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    if (wo.z <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let m = sample_ggx_vndf(wo, a, u);
    let wl = reflect(-wo, m);
    if (wl.z <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let pdf = ggx_d(m, a) * smith_g1(wo, m, a) / (4.0 * wo.z);
    if (!(pdf > 0.0)) {
        return bsdf_absorbed(dir);
    }
    let f = fresnel_conductor(clamp(dot(wo, m), 0.0, 1.0), eta, k);
    return BsdfSample(
        to_world(wl, basis.t, basis.b, n),
        reflectance * f * smith_g1(wl, m, a),
        pdf,
        false,
    );
}
//#endif

//#if metal|rough_metal
fn eval_conductor(
    dir: vec3<f32>,
    n: vec3<f32>,
    wi: vec3<f32>,
    alpha: f32,
    reflectance: vec3<f32>,
    eta: vec3<f32>,
    k: vec3<f32>,
) -> BsdfEval {
    if (alpha <= 0.0) {
        return bsdf_eval_zero();
    }
    let a = max(alpha, GGX_MIN_ALPHA);
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    let wl = to_local(wi, basis.t, basis.b, n);
    if (wo.z <= 0.0 || wl.z <= 0.0) {
        return bsdf_eval_zero();
    }
    let h = normalize(wo + wl);
    let cos_oh = dot(wo, h);
    if (cos_oh <= 0.0 || dot(wl, h) <= 0.0) {
        return bsdf_eval_zero();
    }
    let d = ggx_d(h, a);
    let g1o = smith_g1(wo, h, a);
    let pdf = d * g1o / (4.0 * wo.z);
    let f = fresnel_conductor(min(cos_oh, 1.0), eta, k);
    return BsdfEval(reflectance * f * (pdf * smith_g1(wl, h, a)), pdf);
}
//#endif

// ---- plastic (smooth coat) ----

//#if plastic
fn plastic_specular_weight(albedo: vec3<f32>) -> f32 {
    let d_mean = (albedo.x + albedo.y + albedo.z) * (1.0 / 3.0);
    return 1.0 / (d_mean + 1.0);
}
//#endif

//#if plastic
fn plastic_specular_probability(f_i: f32, w: f32) -> f32 {
    let ps = f_i * w;
    let pd = (1.0 - f_i) * (1.0 - w);
    if (ps + pd > 0.0) {
        return ps / (ps + pd);
    }
    return 1.0;
}
//#endif

//#if plastic
fn plastic_diffuse_local(wo: vec3<f32>, wl: vec3<f32>, ior: f32, albedo: vec3<f32>) -> BsdfEval {
    let inv_ior = 1.0 / ior;
    let f_i = fresnel_dielectric(min(wo.z, 1.0), inv_ior);
    let f_o = fresnel_dielectric(min(wl.z, 1.0), inv_ior);
    let fdr_int = fresnel_diffuse_reflectance(inv_ior);
    let p_spec = plastic_specular_probability(f_i, plastic_specular_weight(albedo));
    let cos_pdf = wl.z * INV_PI;
    let scale = inv_ior * inv_ior * (1.0 - f_i) * (1.0 - f_o) / (1.0 - fdr_int);
    return BsdfEval(albedo * (scale * cos_pdf), (1.0 - p_spec) * cos_pdf);
}
//#endif

//#if plastic
fn sample_plastic(dir: vec3<f32>, n: vec3<f32>, ior: f32, albedo: vec3<f32>, u: vec3<f32>) -> BsdfSample {
    let cos_i = -dot(dir, n);
    if (cos_i <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let f_i = fresnel_dielectric(min(cos_i, 1.0), 1.0 / ior);
    let p_spec = plastic_specular_probability(f_i, plastic_specular_weight(albedo));
    if (u.x < p_spec) {
        return BsdfSample(reflect(dir, n), vec3<f32>(f_i / p_spec), 0.0, false);
    }
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    let wl = sample_cosine_local(vec2<f32>(u.y, u.z));
    if (wo.z <= 0.0 || wl.z <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let e = plastic_diffuse_local(wo, wl, ior, albedo);
    if (!(e.pdf > 0.0)) {
        return bsdf_absorbed(dir);
    }
    return BsdfSample(to_world(wl, basis.t, basis.b, n), e.value / e.pdf, e.pdf, false);
}
//#endif

//#if plastic
fn eval_plastic(dir: vec3<f32>, n: vec3<f32>, wi: vec3<f32>, ior: f32, albedo: vec3<f32>) -> BsdfEval {
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    let wl = to_local(wi, basis.t, basis.b, n);
    if (wo.z <= 0.0 || wl.z <= 0.0) {
        return bsdf_eval_zero();
    }
    return plastic_diffuse_local(wo, wl, ior, albedo);
}
//#endif

// ---- roughplastic ----

// Built by RoughPlasticTable::new (Rust) per (alpha, ior); 272 bytes. The functions below take
// its index in the `plastic_tables` storage array (declared with the module's bindings) and
// read the two entries they interpolate from there: a copy into a function-space `var` (272
// bytes a thread, indexed dynamically: local memory) cost every rough plastic hit 68 loads and
// stores and the driver's compiler a larger kernel.
struct RoughPlasticTable {
    transmittance: array<f32, 64>,
    internal_reflectance: f32,
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

//#if plastic
fn rough_transmittance(table: u32, cos_i: f32) -> f32 {
    let x = cos_i * f32(ROUGH_TRANSMITTANCE_RES - 1u);
    let i = min(u32(x), ROUGH_TRANSMITTANCE_RES - 2u);
    let v0 = plastic_tables[table].transmittance[i];
    let v1 = plastic_tables[table].transmittance[i + 1u];
    let t = x - f32(i);
    return v0 + (v1 - v0) * t;
}
//#endif

//#if plastic
fn rough_plastic_local(
    wo: vec3<f32>,
    wl: vec3<f32>,
    alpha: f32,
    ior: f32,
    albedo: vec3<f32>,
    table: u32,
) -> BsdfEval {
    let inv_ior = 1.0 / ior;
    let t_i = rough_transmittance(table, min(wo.z, 1.0));
    let t_o = rough_transmittance(table, min(wl.z, 1.0));
    let p_spec = plastic_specular_probability(1.0 - t_i, plastic_specular_weight(albedo));
    let h = normalize(wo + wl);
    let cos_oh = clamp(dot(wo, h), 0.0, 1.0);
    let d = ggx_d(h, alpha);
    let spec_pdf = d * smith_g1(wo, h, alpha) / (4.0 * wo.z);
    let spec = fresnel_dielectric(cos_oh, inv_ior) * spec_pdf * smith_g1(wl, h, alpha);
    let cos_pdf = wl.z * INV_PI;
    let scale = inv_ior * inv_ior * t_i * t_o / (1.0 - plastic_tables[table].internal_reflectance);
    return BsdfEval(
        albedo * (scale * cos_pdf) + vec3<f32>(spec),
        p_spec * spec_pdf + (1.0 - p_spec) * cos_pdf,
    );
}
//#endif

//#if plastic
fn sample_rough_plastic(
    dir: vec3<f32>,
    n: vec3<f32>,
    alpha: f32,
    ior: f32,
    albedo: vec3<f32>,
    table: u32,
    u: vec3<f32>,
) -> BsdfSample {
    let a = max(alpha, GGX_MIN_ALPHA);
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    if (wo.z <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let t_i = rough_transmittance(table, min(wo.z, 1.0));
    let p_spec = plastic_specular_probability(1.0 - t_i, plastic_specular_weight(albedo));
    let u2 = vec2<f32>(u.y, u.z);
    var wl: vec3<f32>;
    if (u.x < p_spec) {
        wl = reflect(-wo, sample_ggx_vndf(wo, a, u2));
    } else {
        wl = sample_cosine_local(u2);
    }
    if (wl.z <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let e = rough_plastic_local(wo, wl, a, ior, albedo, table);
    if (!(e.pdf > 0.0)) {
        return bsdf_absorbed(dir);
    }
    return BsdfSample(to_world(wl, basis.t, basis.b, n), e.value / e.pdf, e.pdf, false);
}
//#endif

//#if plastic
fn eval_rough_plastic(
    dir: vec3<f32>,
    n: vec3<f32>,
    wi: vec3<f32>,
    alpha: f32,
    ior: f32,
    albedo: vec3<f32>,
    table: u32,
) -> BsdfEval {
    let a = max(alpha, GGX_MIN_ALPHA);
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    let wl = to_local(wi, basis.t, basis.b, n);
    if (wo.z <= 0.0 || wl.z <= 0.0) {
        return bsdf_eval_zero();
    }
    return rough_plastic_local(wo, wl, a, ior, albedo, table);
}
//#endif

// ---- roughdielectric ----

//#if glass|rough_glass
fn sample_rough_dielectric(
    dir: vec3<f32>,
    n: vec3<f32>,
    alpha: f32,
    eta: f32,
    tint: vec3<f32>,
    u: vec3<f32>,
) -> BsdfSample {
    if (alpha <= 0.0) {
        let g = sample_glass(dir, n, eta, u.x);
        return BsdfSample(g.dir, select(vec3<f32>(1.0), tint * (eta * eta), g.transmitted), 0.0, g.transmitted);
    }
    let a = max(alpha, GGX_MIN_ALPHA);
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    if (wo.z <= 0.0) {
        return bsdf_absorbed(dir);
    }
    let m = sample_ggx_vndf(wo, a, vec2<f32>(u.y, u.z));
    let cos_om = clamp(dot(wo, m), 0.0, 1.0);
    let f = fresnel_dielectric(cos_om, eta);
    let vis = ggx_d(m, a) * smith_g1(wo, m, a) / wo.z;
    if (u.x < f) {
        let wl = reflect(-wo, m);
        let pdf = vis * f * 0.25;
        if (wl.z <= 0.0 || !(pdf > 0.0)) {
            return bsdf_absorbed(dir);
        }
        return BsdfSample(to_world(wl, basis.t, basis.b, n), vec3<f32>(smith_g1(wl, m, a)), pdf, false);
    }
    let sin2_t = eta * eta * max(1.0 - cos_om * cos_om, 0.0);
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    let wl = normalize(-wo * eta + m * (eta * cos_om - cos_t));
    if (wl.z >= 0.0) {
        return bsdf_absorbed(dir);
    }
    let cos_lm = dot(wl, m);
    let denom = eta * cos_om + cos_lm;
    let pdf = vis * cos_om * (1.0 - f) * abs(cos_lm) / (denom * denom);
    if (!(pdf > 0.0)) {
        return bsdf_absorbed(dir);
    }
    return BsdfSample(to_world(wl, basis.t, basis.b, n), tint * (smith_g1(wl, m, a) * eta * eta), pdf, true);
}
//#endif

//#if glass|rough_glass
fn eval_rough_dielectric(
    dir: vec3<f32>,
    n: vec3<f32>,
    wi: vec3<f32>,
    alpha: f32,
    eta: f32,
    tint: vec3<f32>,
) -> BsdfEval {
    if (alpha <= 0.0) {
        return bsdf_eval_zero();
    }
    let a = max(alpha, GGX_MIN_ALPHA);
    let basis = orthonormal_basis(n);
    let wo = to_local(-dir, basis.t, basis.b, n);
    let wl = to_local(wi, basis.t, basis.b, n);
    if (wo.z <= 0.0 || wl.z == 0.0) {
        return bsdf_eval_zero();
    }
    let reflected = wl.z > 0.0;
    var h: vec3<f32>;
    if (reflected) {
        h = normalize(wo + wl);
    } else {
        h = normalize(wo + wl * (1.0 / eta));
    }
    if (h.z < 0.0) {
        h = -h;
    }
    let cos_oh = dot(wo, h);
    let cos_lh = dot(wl, h);
    if (!(cos_oh > 0.0) || !(cos_lh * wl.z > 0.0)) {
        return bsdf_eval_zero();
    }
    let d = ggx_d(h, a);
    let f = fresnel_dielectric(min(cos_oh, 1.0), eta);
    let g1o = smith_g1(wo, h, a);
    let g1l = smith_g1(wl, h, a);
    if (reflected) {
        let pdf = f * d * g1o / (4.0 * wo.z);
        return BsdfEval(vec3<f32>(pdf * g1l), pdf);
    }
    let denom = eta * cos_oh + cos_lh;
    let pdf = (1.0 - f) * d * g1o * cos_oh * abs(cos_lh) / (wo.z * denom * denom);
    return BsdfEval(tint * (pdf * g1l * eta * eta), pdf);
}
//#endif
