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
