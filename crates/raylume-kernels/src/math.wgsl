// Helpers shared by the kernels (math.rs).

const PI: f32 = 3.14159265358979323846;
const INV_PI: f32 = 0.31830988618379067154;
const INV_2PI: f32 = 0.15915494309189533577;

// Finite test on the bits: WGSL has no isFinite, and fast-math may fold `x == x`.
fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn is_finite3(v: vec3<f32>) -> bool {
    return is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z);
}

// 2^94: 2^32 samples of it still sum to a finite f32 (math.rs).
const MAX_SAMPLE_RADIANCE: f32 = 1.9807040628566084e28;

fn sample_is_valid(v: vec3<f32>) -> bool {
    return is_finite3(v) && max(v.x, max(v.y, v.z)) <= MAX_SAMPLE_RADIANCE;
}

// (sin 2πt, cos 2πt) for |t| < 2^20 turns (math.rs's sin_cos_turns): 4t less its nearest
// integer q (both exact) is the quarter turn's fraction, a = r π/2 goes to Cephes' sinf/cosf
// polynomials on [-π/4, π/4], and q mod 4 swaps and negates them: the CPU mirror's values to
// rounding (Vulkan lets a driver's sin and cos be 2^-11 off), without its branches.
const SIN_COS_S1: f32 = -1.6666654611e-1;
const SIN_COS_S2: f32 = 8.3321608736e-3;
const SIN_COS_S3: f32 = -1.9515295891e-4;
const SIN_COS_C1: f32 = 4.166664568298827e-2;
const SIN_COS_C2: f32 = -1.388731625493765e-3;
const SIN_COS_C3: f32 = 2.443315711809948e-5;

fn sin_cos_turns(t: f32) -> vec2<f32> {
    let x = 4.0 * t;
    // WGSL's round is to the nearest, ties to even, as the mirror's two additions.
    let q = round(x);
    let a = (x - q) * (0.5 * PI);
    let z = a * a;
    let s = ((SIN_COS_S3 * z + SIN_COS_S2) * z + SIN_COS_S1) * z * a + a;
    let c = ((SIN_COS_C3 * z + SIN_COS_C2) * z + SIN_COS_C1) * z * z - 0.5 * z + 1.0;
    let m = i32(q) & 3;
    var sc = select(vec2<f32>(s, c), vec2<f32>(c, -s), (m & 1) != 0);
    return select(sc, -sc, (m & 2) != 0);
}

// atan2 from a degree-15 odd minimax polynomial on [0, 1] (Hastings; error < 4e-8 rad) with
// octant reduction: only + - * / and compares, so every device agrees with the Rust mirror to
// rounding (Vulkan lets a driver's atan be 4096 ULP off). Coefficients: exact f32 values.
fn atan2_poly(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let hi = max(ax, ay);
    let lo = min(ax, ay);
    var a = 0.0;
    if (hi > 0.0) {
        a = lo / hi;
    }
    let s = a * a;
    var r = -0.004054057877510786;
    r = r * s + 0.021861229091882706;
    r = r * s - 0.055909886956214905;
    r = r * s + 0.0964200422167778;
    r = r * s - 0.1390853226184845;
    r = r * s + 0.19946536421775818;
    r = r * s - 0.33329856395721436;
    r = r * s + 0.9999993443489075;
    r *= a;
    if (ay > ax) {
        r = 0.5 * PI - r;
    }
    if (x < 0.0) {
        r = PI - r;
    }
    return select(r, -r, y < 0.0);
}

fn acos_poly(x: f32) -> f32 {
    let c = clamp(x, -1.0, 1.0);
    return atan2_poly(sqrt(max(1.0 - c * c, 0.0)), c);
}

// The equirectangular coordinates of a unit direction (no rotation): math.rs.
fn direction_to_equirect(d: vec3<f32>) -> vec2<f32> {
    let phi = atan2_poly(d.x, -d.z);
    return vec2<f32>(0.5 + phi * INV_2PI, acos_poly(d.y) * INV_PI);
}
