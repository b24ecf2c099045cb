//! What a ray sees: the surface at a hit (position, normals, uv, material), albedo textures,
//! the environment, and the origin of the next ray. `surface.wgsl` is the same code in WGSL,
//! reading the shader's global bindings where this takes a [`Globals`].
//!
//! Conventions, identical on both sides:
//! - Triangle barycentrics `(u, v)` weight vertices 1 and 2; the hit point is interpolated
//!   from the vertices (more accurate than `origin + t * dir`); the geometric normal is
//!   `normalize(cross(v1 - v0, v2 - v0))`; shading normals are flipped onto its side.
//! - Sphere hits are reprojected onto the sphere; the normal is analytic.
//! - Texture coordinates: `(0, 0)` is the top-left corner of the image (rows are stored top
//!   first), `u` to the right, `v` down; both wrap. Triangles without uvs use `(u, v)`;
//!   spheres use the equirectangular mapping of their normal.
//! - Environment maps are equirectangular: the image centre looks along -z, the top row along
//!   +y; `u = 0.5 + atan2(d.x, -d.z) / 2π + rotation`, `v = acos(d.y) / π`; bilinear
//!   filtering, wrapping in `u`, clamped in `v`.
//! - Secondary rays start at the hit point pushed off the surface along the geometric normal
//!   by Wächter & Binder's scale-aware integer-ULP offset (Ray Tracing Gems, ch. 6, "A Fast
//!   and Robust Method for Avoiding Self-Intersection", 2019) and are traced from t = 0.

use glam::{Vec2, Vec3};
use raylume_bvh::{Hit, PRIM_SPHERE, Primitive};

use crate::gpu_types::{
    ENVIRONMENT_CONSTANT, ENVIRONMENT_MAP, GpuMaterial, MATERIAL_GLASS, NO_TEXTURE,
    SHADING_HAS_NORMALS, SHADING_HAS_UVS, SceneUniforms, TextureHeader, TriangleShading,
};
use crate::math::{INV_2PI, INV_PI, acos_poly, atan2_poly, normalize};

/// The Rust mirror of the shader's global bindings: what the plain functions read.
#[derive(Clone, Copy)]
pub struct Globals<'a> {
    pub scene: &'a SceneUniforms,
    pub primitives: &'a [Primitive],
    pub materials: &'a [GpuMaterial],
    pub prim_materials: &'a [u32],
    /// Leaf-order shading data; empty when the scene has neither shading normals nor uvs.
    pub triangle_shading: &'a [TriangleShading],
    pub texture_headers: &'a [TextureHeader],
    pub texels: &'a [f32],
}

/// The surface a ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    pub position: Vec3,
    /// Unit geometric normal (triangle winding / sphere outward), for side decisions.
    pub geometric_normal: Vec3,
    /// Unit shading normal on the same side as `geometric_normal`.
    pub shading_normal: Vec3,
    pub uv: Vec2,
    /// Index into the material table.
    pub material: u32,
}

/// The equirectangular coordinates of a unit direction (no rotation).
#[inline]
pub fn direction_to_equirect(d: Vec3) -> Vec2 {
    let phi = atan2_poly(d.x, -d.z);
    Vec2::new(0.5 + phi * INV_2PI, acos_poly(d.y) * INV_PI)
}

/// The surface at `hit` of the ray `(origin, dir)`.
#[inline]
pub fn surface_at(g: &Globals, hit: &Hit, origin: Vec3, dir: Vec3) -> SurfaceHit {
    let prim = &g.primitives[hit.prim as usize];
    let material = g.prim_materials[hit.prim as usize];
    let a = Vec3::new(prim.a[0], prim.a[1], prim.a[2]);
    if prim.b[3].to_bits() == PRIM_SPHERE {
        let radius = prim.a[3];
        let p = origin + dir * hit.t;
        let from_center = p - a;
        let n = normalize(from_center);
        let position = a + n * radius;
        return SurfaceHit {
            position,
            geometric_normal: n,
            shading_normal: n,
            uv: direction_to_equirect(n),
            material,
        };
    }
    let b = Vec3::new(prim.b[0], prim.b[1], prim.b[2]);
    let c = Vec3::new(prim.c[0], prim.c[1], prim.c[2]);
    let w = 1.0 - hit.u - hit.v;
    let position = a * w + b * hit.u + c * hit.v;
    let ng = normalize((b - a).cross(c - a));
    let mut ns = ng;
    let mut uv = Vec2::new(hit.u, hit.v);
    if !g.triangle_shading.is_empty() {
        let sh = &g.triangle_shading[hit.prim as usize];
        if sh.flags & SHADING_HAS_NORMALS != 0 {
            let n = normalize(
                Vec3::from(sh.n0) * w + Vec3::from(sh.n1) * hit.u + Vec3::from(sh.n2) * hit.v,
            );
            ns = if n.dot(ng) < 0.0 { -n } else { n };
        }
        if sh.flags & SHADING_HAS_UVS != 0 {
            uv = Vec2::new(sh.u0, sh.v0) * w
                + Vec2::new(sh.u1, sh.v1) * hit.u
                + Vec2::new(sh.u2, sh.v2) * hit.v;
        }
    }
    SurfaceHit {
        position,
        geometric_normal: ng,
        shading_normal: ns,
        uv,
        material,
    }
}

/// Texel `(x, y)` of the texture starting at texel `offset` with row length `width`.
#[inline]
pub fn texel(g: &Globals, offset: u32, width: u32, x: u32, y: u32) -> Vec3 {
    let i = ((offset + y * width + x) * 3) as usize;
    Vec3::new(g.texels[i], g.texels[i + 1], g.texels[i + 2])
}

#[inline]
fn wrap_index(i: i32, n: i32) -> i32 {
    ((i % n) + n) % n
}

/// Bilinear lookup at `uv` in a `width x height` texture starting at texel `offset`; `u`
/// wraps, `v` wraps when `wrap_v` and is clamped otherwise.
#[inline]
pub fn texture_bilinear(
    g: &Globals,
    offset: u32,
    width: u32,
    height: u32,
    uv: Vec2,
    wrap_v: bool,
) -> Vec3 {
    let w = width as i32;
    let h = height as i32;
    let u = uv.x - uv.x.floor();
    let v = if wrap_v {
        uv.y - uv.y.floor()
    } else {
        uv.y.clamp(0.0, 1.0)
    };
    let x = u * width as f32 - 0.5;
    let y = v * height as f32 - 0.5;
    let x0f = x.floor();
    let y0f = y.floor();
    let fx = x - x0f;
    let fy = y - y0f;
    let x0 = x0f as i32;
    let y0 = y0f as i32;
    let ix0 = wrap_index(x0, w) as u32;
    let ix1 = wrap_index(x0 + 1, w) as u32;
    let (iy0, iy1) = if wrap_v {
        (wrap_index(y0, h) as u32, wrap_index(y0 + 1, h) as u32)
    } else {
        (
            y0.max(0).min(h - 1) as u32,
            (y0 + 1).max(0).min(h - 1) as u32,
        )
    };
    let t00 = texel(g, offset, width, ix0, iy0);
    let t10 = texel(g, offset, width, ix1, iy0);
    let t01 = texel(g, offset, width, ix0, iy1);
    let t11 = texel(g, offset, width, ix1, iy1);
    let top = t00 * (1.0 - fx) + t10 * fx;
    let bottom = t01 * (1.0 - fx) + t11 * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The material at a surface, its colour multiplied by its albedo texture (never on glass).
#[inline]
pub fn material_at(g: &Globals, surface: &SurfaceHit) -> GpuMaterial {
    let mut m = g.materials[surface.material as usize];
    if m.texture != NO_TEXTURE && m.kind != MATERIAL_GLASS {
        let h = g.texture_headers[m.texture as usize];
        let t = texture_bilinear(g, h.offset, h.width, h.height, surface.uv, true);
        m.color = (Vec3::from(m.color) * t).into();
    }
    m
}

/// Radiance arriving from the environment along the unit direction `dir`.
#[inline]
pub fn environment_radiance(g: &Globals, dir: Vec3) -> Vec3 {
    let s = g.scene;
    if s.environment_kind == ENVIRONMENT_CONSTANT {
        return Vec3::from(s.environment_color);
    }
    if s.environment_kind == ENVIRONMENT_MAP {
        let e = direction_to_equirect(dir);
        let uv = Vec2::new(e.x + s.environment_rotation, e.y);
        let l = texture_bilinear(
            g,
            s.environment_offset,
            s.environment_width,
            s.environment_height,
            uv,
            false,
        );
        return l * Vec3::from(s.environment_color);
    }
    Vec3::ZERO
}

/// Wächter & Binder's constants (Ray Tracing Gems, ch. 6): below `ORIGIN` in magnitude a
/// coordinate is offset by `FLOAT_SCALE * n`, above it by `INT_SCALE * n` units in the last
/// place, so the offset scales with the coordinate's own rounding error.
pub const OFFSET_ORIGIN: f32 = 1.0 / 32.0;
pub const OFFSET_FLOAT_SCALE: f32 = 1.0 / 65536.0;
pub const OFFSET_INT_SCALE: f32 = 256.0;

#[inline]
fn offset_component(p: f32, n: f32) -> f32 {
    let of_i = (OFFSET_INT_SCALE * n) as i32;
    let p_i = f32::from_bits(
        (p.to_bits() as i32).wrapping_add(if p < 0.0 { -of_i } else { of_i }) as u32,
    );
    if p.abs() < OFFSET_ORIGIN {
        p + OFFSET_FLOAT_SCALE * n
    } else {
        p_i
    }
}

/// The origin of a ray leaving the surface point `p` to the side of the unit normal `n`.
#[inline]
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    Vec3::new(
        offset_component(p.x, n.x),
        offset_component(p.y, n.y),
        offset_component(p.z, n.z),
    )
}

/// The WGSL source of the functions above.
pub const SURFACE_WGSL: &str = include_str!("surface.wgsl");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_off_the_plane_by_a_few_ulps_and_to_the_right_side() {
        for p in [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, -2.0, 3.0),
            Vec3::new(-1000.0, 5e-3, 1e4),
        ] {
            for n in [Vec3::X, Vec3::NEG_Y, Vec3::new(0.6, 0.0, -0.8)] {
                let q = offset_ray_origin(p, n);
                let d = (q - p).dot(n);
                assert!(d > 0.0, "{p} {n} -> {q}");
                // Never more than 256 ulps of the largest coordinate (or 2^-16 near 0).
                let scale = p.abs().max_element().max(1.0);
                assert!(d < scale * 256.0 * f32::EPSILON * 2.0, "{p} {n} moved {d}");
            }
        }
    }

    #[test]
    fn equirect_centre_is_minus_z_and_top_is_up() {
        let e = direction_to_equirect(Vec3::NEG_Z);
        assert!((e - Vec2::new(0.5, 0.5)).length() < 1e-6);
        let e = direction_to_equirect(Vec3::Y);
        assert!(e.y.abs() < 1e-6);
        let e = direction_to_equirect(Vec3::X);
        assert!((e - Vec2::new(0.75, 0.5)).length() < 1e-6);
    }
}
