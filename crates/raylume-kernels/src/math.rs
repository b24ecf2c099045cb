//! Rust spellings of the WGSL builtins the kernels use, with WGSL's definitions, so that the
//! mirror performs the same operations in the same order.

use glam::Vec3;

/// WGSL `normalize`.
#[inline]
pub fn normalize(v: Vec3) -> Vec3 {
    v * (1.0 / v.dot(v).sqrt())
}

/// WGSL `reflect(e1, e2) = e1 - 2 * dot(e2, e1) * e2`.
#[inline]
pub fn reflect(e1: Vec3, e2: Vec3) -> Vec3 {
    e1 - e2 * (2.0 * e2.dot(e1))
}

/// True for a finite float, tested on its bits (as in WGSL, where there is no `isFinite`
/// and a fast-math compiler may fold `x == x`).
#[inline]
pub fn is_finite_f32(x: f32) -> bool {
    (x.to_bits() & 0x7f80_0000) != 0x7f80_0000
}

/// True when every component is finite.
#[inline]
pub fn is_finite3(v: Vec3) -> bool {
    is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z)
}

pub const PI: f32 = std::f32::consts::PI;
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
pub const INV_2PI: f32 = 0.5 * std::f32::consts::FRAC_1_PI;

/// The WGSL source of the helpers above (`is_finite3`, `PI`, ...).
pub const MATH_WGSL: &str = include_str!("math.wgsl");
