//! One path segment: trace the ray, add what it sees, scatter (`shade.wgsl` is the same code
//! in WGSL). These functions know nothing of the schedule: the megakernel calls
//! [`trace_ray`] in a loop with the path in registers, the wavefront calls it once per
//! `propagate` launch with the path loaded from and stored to a [`RayState`].
//!
//! The estimator is the paper's plain one: emission is collected where a path hits it
//! (two-sided, on every material), escaping paths collect the environment, and each hit
//! scatters one new direction sampled from the material; no light sampling, no Russian
//! roulette. Diffuse and metal surfaces are two-sided (their normals are flipped towards the
//! incoming ray, decided by the geometric normal); a scattered direction on the wrong side of
//! the geometric surface (possible with shading normals) ends the path rather than leaking
//! light through it.

use glam::{Vec2, Vec3, Vec4};
use raylume_bvh::{GpuBvh, Ray};

use crate::gpu_types::{
    DIM_SCATTER, GpuMaterial, MATERIAL_DIFFUSE, MATERIAL_GLASS, MATERIAL_METAL, RayState, T_MAX,
};
use crate::rng::rand4;
use crate::sampling::{sample_diffuse, sample_glass, sample_metal};
use crate::surface::{
    Globals, SurfaceHit, environment_radiance, material_at, offset_ray_origin, surface_at,
};

/// A path between two segments, as a thread holds it in registers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathState {
    pub origin: Vec3,
    pub dir: Vec3,
    pub throughput: Vec3,
    pub radiance: Vec3,
    pub alive: bool,
}

impl PathState {
    /// A camera path starting at `origin` along `dir`.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self {
            origin,
            dir,
            throughput: Vec3::ONE,
            radiance: Vec3::ZERO,
            alive: true,
        }
    }

    /// The path of a stored ray.
    pub fn load(r: &RayState) -> Self {
        Self {
            origin: r.origin.into(),
            dir: r.dir.into(),
            throughput: r.throughput.into(),
            radiance: r.radiance.into(),
            alive: r.alive != 0,
        }
    }

    /// Writes the path back into its stored ray (pixel and sample stay).
    pub fn store(&self, r: &mut RayState, depth: u32) {
        r.origin = self.origin.into();
        r.dir = self.dir.into();
        r.throughput = self.throughput.into();
        r.radiance = self.radiance.into();
        r.depth = depth;
        r.alive = u32::from(self.alive);
    }
}

/// Adds the surface's emission (times the throughput) to the path; then, unless this is the
/// path's `last` segment, samples the material with the random numbers `rnd` and sets up the
/// next ray, or ends the path when it is absorbed.
#[inline]
pub fn shade_hit(path: &mut PathState, hit: &SurfaceHit, mat: &GpuMaterial, rnd: Vec4, last: bool) {
    path.radiance += path.throughput * Vec3::from(mat.emission);
    if last {
        path.alive = false;
        return;
    }
    let ng = hit.geometric_normal;
    let front = path.dir.dot(ng) < 0.0;
    let ng_facing = if front { ng } else { -ng };
    let ns_facing = if front {
        hit.shading_normal
    } else {
        -hit.shading_normal
    };
    let color = Vec3::from(mat.color);
    let mut wi = path.dir;
    let mut weight = Vec3::ZERO;
    let mut reflected = true;
    if mat.kind == MATERIAL_DIFFUSE {
        wi = sample_diffuse(ns_facing, Vec2::new(rnd.x, rnd.y));
        weight = color;
    } else if mat.kind == MATERIAL_METAL {
        let s = sample_metal(path.dir, ns_facing, mat.alpha, Vec2::new(rnd.x, rnd.y));
        wi = s.dir;
        weight = color * s.weight;
    } else if mat.kind == MATERIAL_GLASS {
        let eta = if front { 1.0 / mat.ior } else { mat.ior };
        let s = sample_glass(path.dir, ns_facing, eta, rnd.x);
        wi = s.dir;
        reflected = !s.transmitted;
        weight = if s.transmitted { color } else { Vec3::ONE };
    }
    // The geometric surface decides the side: reflections stay in front, transmissions go
    // behind; anything else (shading normals bending a sample through) is absorbed.
    let cos_g = wi.dot(ng_facing);
    let right_side = if reflected { cos_g > 0.0 } else { cos_g < 0.0 };
    path.throughput *= weight;
    path.alive = right_side && path.throughput.max_element() > 0.0;
    path.origin = offset_ray_origin(
        hit,
        path.dir,
        if cos_g > 0.0 { ng_facing } else { -ng_facing },
    );
    path.dir = wi;
}

/// Traces the path's current ray (its segment number `depth`, 0 for the camera ray): adds
/// the environment when it escapes, else shades the hit. Every call traces exactly one ray.
#[inline]
pub fn trace_ray(
    g: &Globals,
    bvh: &GpuBvh,
    path: &mut PathState,
    pixel: u32,
    sample: u32,
    depth: u32,
) {
    let ray = Ray {
        origin: path.origin,
        dir: path.dir,
    };
    let Some(hit) = bvh.trace_closest(&ray, 0.0, T_MAX) else {
        path.radiance += path.throughput * environment_radiance(g, path.dir);
        path.alive = false;
        return;
    };
    let surface = surface_at(g, &hit, path.origin, path.dir);
    let mat = material_at(g, &surface);
    let rnd = rand4(g.scene.seed, pixel, sample, depth, DIM_SCATTER);
    shade_hit(path, &surface, &mat, rnd, depth >= g.scene.max_bounces);
}

/// The WGSL source of the functions above.
pub const SHADE_WGSL: &str = include_str!("shade.wgsl");
