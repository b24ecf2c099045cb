//! One path segment: trace the ray, add what it sees, scatter (`shade.wgsl` is the same code
//! in WGSL). These functions know nothing of the schedule: the megakernel calls
//! [`trace_ray`] in a loop with the path in registers, the wavefront calls it once per
//! `propagate` launch with the path loaded from and stored to a [`RayState`].
//!
//! The estimator is the paper's plain one unless the uniforms hold a light list
//! (`light_count > 0`, [`crate::Estimator::Nee`]): emission is collected where a path hits it
//! (on every material, from the front face unless the material is two-sided), escaping paths collect the environment, and each hit
//! scatters one new direction sampled from the material; Russian roulette only when the
//! uniforms ask for it (`rr_depth`, [`russian_roulette`]). With the light
//! list, a hit on a material [`samples_lights`] (diffuse, rough metal, plastic, rough glass)
//! also sends a shadow ray to a point on an emitter of the list ([`light_query`],
//! [`light_contribution`]): uniform on an emissive
//! triangle, or uniform in the cone of directions of an emissive sphere's visible cap
//! ([`crate::sampling::sample_sphere_cap`]), so that small bright spheres are found at a few
//! samples. The two estimates of the light an emitter sends there,
//! the shadow ray's and the scattered ray's if it hits one, are weighted by multiple
//! importance sampling (Veach's power heuristic, [`mis_weight`]): each wins where its pdf is
//! the larger (the shadow ray for small, far lights; the scattered ray close to a light,
//! where the shadow ray's 1/distance² would make fireflies). The environment is the list's
//! last entry when it shines: a constant sky is sampled uniformly on the sphere of directions
//! (as Mitsuba's `constant` emitter), a map by its luminance times `sin θ`
//! ([`crate::surface::sample_environment`]); a path that escapes after such a vertex weighs
//! the sky it sees the same way. Every random number comes from
//! [`path_rand4`]: the independent hash or ZSobol, as the uniforms say. Every material scatters on both faces (its normals are flipped towards the
//! incoming ray, decided by the geometric normal); a scattered direction on the wrong side of
//! the geometric surface (possible with shading normals) ends the path rather than leaking
//! light through it.

use glam::{Vec2, Vec3, Vec4};
use raylume_bvh::{GpuBvh, Hit, PRIM_SPHERE, PRIM_TRIANGLE, Ray};
use raylume_scene::Feature;

use crate::bsdf::{
    BsdfEval, BsdfSample, bsdf_absorbed, bsdf_eval_zero, eval_conductor, eval_plastic,
    eval_rough_dielectric, eval_rough_plastic, sample_conductor, sample_plastic,
    sample_rough_dielectric, sample_rough_plastic,
};
use crate::cpu::variant::{BuildForms, Forms, has};
use crate::gpu_types::{
    DIM_CAMERA, DIM_LIGHT, DIM_ROULETTE, DIM_SCATTER, DIMS_PER_BOUNCE, GpuMaterial,
    LIGHT_ENVIRONMENT, LIGHT_SPHERE, LUMINANCE, MATERIAL_DIFFUSE, MATERIAL_GLASS, MATERIAL_METAL,
    MATERIAL_PLASTIC, MATERIAL_TWO_SIDED, RAY_ALIVE, RR_MAX_SURVIVAL, RayState,
    SAMPLER_INDEPENDENT, SAMPLER_SOBOL, SHADOW_T_SCALE, SceneUniforms, T_MAX,
};
use crate::math::{INV_PI, PI};
use crate::rng::rand4;
use crate::sampling::{sample_diffuse, sample_sphere_cap, sphere_cap_pdf};
use crate::sobol::{SobolPixel, sobol_pixel, sobol2_at, sobol4_at};
use crate::surface::{
    Globals, SurfaceHit, environment_cell, environment_pdf, environment_radiance, material_at,
    offset_ray_origin, prefetch_texture, sample_environment, surface_at,
};

/// A path between two segments, as a thread holds it in registers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathState {
    pub origin: Vec3,
    pub dir: Vec3,
    pub throughput: Vec3,
    pub radiance: Vec3,
    pub alive: bool,
    /// The BSDF pdf (solid angle) of the current direction when the vertex that sampled it
    /// also sampled the lights; 0 when it did not (the emission it hits counts in full).
    pub mis_pdf: f32,
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
            mis_pdf: 0.0,
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
            mis_pdf: if r.alive > RAY_ALIVE {
                f32::from_bits(r.alive)
            } else {
                0.0
            },
        }
    }

    /// Writes the path back into its stored ray (pixel and sample stay).
    pub fn store(&self, r: &mut RayState, depth: u32) {
        r.origin = self.origin.into();
        r.dir = self.dir.into();
        r.throughput = self.throughput.into();
        r.radiance = self.radiance.into();
        r.depth = depth;
        r.alive = match (self.alive, self.mis_pdf > 0.0) {
            (false, _) => 0,
            (true, false) => RAY_ALIVE,
            (true, true) => self.mis_pdf.to_bits(),
        };
    }
}

/// What the surface's emission adds to the path arriving at `hit`: the emission times the
/// throughput and `emission_weight`, or zero (no emission, or the back of a one-sided
/// emitter). [`trace_ray`] adds it before [`shade_hit`] scatters the path.
#[inline(always)]
pub fn emitted<const F: u32>(
    path: &PathState,
    hit: &SurfaceHit,
    mat: &GpuMaterial,
    emission_weight: f32,
) -> Vec3 {
    let front = path.dir.dot(hit.geometric_normal) < 0.0;
    if has(F, Feature::Emission) && (front || mat.flags & MATERIAL_TWO_SIDED != 0) {
        return path.throughput * Vec3::from(mat.emission) * emission_weight;
    }
    Vec3::ZERO
}

/// Unless this is the path's `last` segment (where the path ends), samples the material with
/// the random numbers `rnd` and sets up the next ray, or ends the path when it is absorbed.
/// Returns the solid-angle pdf of the scattered direction (0 for a delta lobe: a smooth
/// mirror, glass or coat).
#[inline(always)]
pub fn shade_hit<const F: u32>(
    g: &Globals,
    path: &mut PathState,
    hit: &SurfaceHit,
    mat: &GpuMaterial,
    rnd: Vec4,
    last: bool,
) -> f32 {
    let ng = hit.geometric_normal;
    let front = path.dir.dot(ng) < 0.0;
    if last {
        path.alive = false;
        return 0.0;
    }
    let ng_facing = if front { ng } else { -ng };
    let ns_facing = if front {
        hit.shading_normal
    } else {
        -hit.shading_normal
    };
    let color = Vec3::from(mat.color);
    let mut s = bsdf_absorbed(path.dir);
    // One branch per material kind, each compiled only into the variants that hold it
    // (`cpu::variant`; the WGSL's `HAS_*`).
    if has(F, Feature::Diffuse) && mat.kind == MATERIAL_DIFFUSE {
        let wi = sample_diffuse(ns_facing, Vec2::new(rnd.x, rnd.y));
        s = BsdfSample {
            dir: wi,
            weight: color,
            pdf: wi.dot(ns_facing).max(0.0) * INV_PI,
            transmitted: false,
        };
    } else if (has(F, Feature::Metal) || has(F, Feature::RoughMetal)) && mat.kind == MATERIAL_METAL
    {
        let (eta, k) = (Vec3::from(mat.eta), Vec3::from(mat.k));
        let alpha = if has(F, Feature::RoughMetal) {
            mat.alpha
        } else {
            0.0
        };
        s = sample_conductor(
            path.dir,
            ns_facing,
            alpha,
            color,
            eta,
            k,
            Vec2::new(rnd.x, rnd.y),
        );
    } else if (has(F, Feature::Glass) || has(F, Feature::RoughGlass)) && mat.kind == MATERIAL_GLASS
    {
        let eta = if front { 1.0 / mat.ior } else { mat.ior };
        let alpha = if has(F, Feature::RoughGlass) {
            mat.alpha
        } else {
            0.0
        };
        s = sample_rough_dielectric(path.dir, ns_facing, alpha, eta, color, lobe_first(rnd));
    } else if has(F, Feature::Plastic) && mat.kind == MATERIAL_PLASTIC {
        s = if mat.alpha > 0.0 {
            let table = &g.plastic_tables[mat.table as usize];
            sample_rough_plastic(
                path.dir,
                ns_facing,
                mat.alpha,
                mat.ior,
                color,
                table,
                lobe_first(rnd),
            )
        } else {
            sample_plastic(path.dir, ns_facing, mat.ior, color, lobe_first(rnd))
        };
    }
    let wi = s.dir;
    // The geometric surface decides the side: reflections stay in front, transmissions go
    // behind; anything else (shading normals bending a sample through) is absorbed.
    let cos_g = wi.dot(ng_facing);
    let right_side = if s.transmitted {
        cos_g < 0.0
    } else {
        cos_g > 0.0
    };
    path.throughput *= s.weight;
    path.alive = right_side && path.throughput.max_element() > 0.0;
    path.origin = offset_ray_origin(
        hit,
        path.dir,
        if cos_g > 0.0 { ng_facing } else { -ng_facing },
    );
    path.dir = wi;
    s.pdf
}

/// The numbers a BSDF sampler takes (`u.x` the lobe, `(u.y, u.z)` the direction: `bsdf`) from
/// a segment's four: the direction from `(rnd.x, rnd.y)`, the first pair, which the Sobol'
/// samplers make a (0, 2)-net over a pixel's samples, and the lobe from `rnd.z` (the next
/// pair's first number). `(rnd.y, rnd.z)` would pair numbers of two nets, stratified each on
/// its own axis but not together. Light sampling draws from the first pair alone
/// ([`light_query`]: the light from `rnd.x`, which then places the point or direction with
/// `rnd.y`).
#[inline]
pub fn lobe_first(rnd: Vec4) -> Vec3 {
    Vec3::new(rnd.z, rnd.x, rnd.y)
}

/// The four random numbers of dimension `dim` (a `DIM_*` constant) at segment `bounce` of
/// sample `sample` of pixel `pixel` (row-major), from the sampler the uniforms name:
/// [`rand4`] (independent), or [`sobol4_at`] (ZSobol, shuffled for `SAMPLER_SOBOL`) with pair group
/// `bounce * DIMS_PER_BOUNCE + dim`, the pixel's (x, y) and the render's spp. Every random
/// number of a path comes from here, so both samplers serve every estimator.
#[inline(always)]
pub fn path_rand4(scene: &SceneUniforms, pixel: u32, sample: u32, bounce: u32, dim: u32) -> Vec4 {
    path_rand4_at(
        scene,
        sampler_pixel(scene, pixel),
        pixel,
        sample,
        bounce,
        dim,
    )
}

/// What the Sobol' samplers share between the random numbers of one pixel sample
/// ([`SobolPixel`]; all zero for the independent one, which needs none of it): a segment
/// computes it once for its light, scattering and roulette numbers. (The WGSL reads the
/// sampler through `path_sampler`: its pipeline's `SAMPLER` override, compiled equal to
/// `scene.sampler`, so that the other samplers' code is dead there.)
#[inline]
pub fn sampler_pixel(scene: &SceneUniforms, pixel: u32) -> SobolPixel {
    if scene.sampler == SAMPLER_INDEPENDENT {
        return SobolPixel::default();
    }
    let xy = glam::UVec2::new(pixel % scene.width, pixel / scene.width);
    sobol_pixel(scene.seed, xy, scene.spp)
}

/// [`path_rand4`] with the pixel's [`sampler_pixel`] given.
#[inline(always)]
pub fn path_rand4_at(
    scene: &SceneUniforms,
    sp: SobolPixel,
    pixel: u32,
    sample: u32,
    bounce: u32,
    dim: u32,
) -> Vec4 {
    if scene.sampler != SAMPLER_INDEPENDENT {
        let shuffled = scene.sampler == SAMPLER_SOBOL;
        let group = bounce * DIMS_PER_BOUNCE + dim;
        if dim == DIM_CAMERA || dim == DIM_ROULETTE {
            // These use x and y only (`DIM_CAMERA`, `DIM_ROULETTE`): their second pair is not
            // computed, and z, w are 0.
            let v = sobol2_at(shuffled, sp, sample, group);
            return Vec4::new(v.x, v.y, 0.0, 0.0);
        }
        return sobol4_at(shuffled, sp, sample, group);
    }
    rand4(scene.seed, pixel, sample, bounce, dim)
}

/// Traces the path's current ray (its segment number `depth`, 0 for the camera ray): adds
/// the environment when it escapes, else shades the hit. Every call traces exactly one ray.
#[inline]
pub fn trace_ray<const F: u32>(
    g: &Globals,
    bvh: &GpuBvh,
    path: &mut PathState,
    pixel: u32,
    sample: u32,
    depth: u32,
) {
    trace_ray_at::<F, BuildForms>(
        g,
        bvh,
        path,
        pixel,
        sampler_pixel(g.scene, pixel),
        sample,
        depth,
    );
}

/// [`trace_ray`] with the pixel's [`sampler_pixel`] given (the CPU's path loop computes it
/// once a path, not once a segment), the `Sobol` sampler's groups drawn and the walks taken
/// in the forms `K` ([`BuildForms`], or the AVX2 ones in `cpu::isa`'s AVX2 copies: the same
/// numbers and hits).
#[inline(always)]
pub fn trace_ray_at<const F: u32, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    path: &mut PathState,
    pixel: u32,
    sp: SobolPixel,
    sample: u32,
    depth: u32,
) {
    if let Some((hit, rnd)) = walk_segment::<F, K>(g, bvh, path, pixel, sp, sample, depth) {
        shade_segment::<F, K>(g, bvh, path, hit, rnd, depth);
    }
}

/// The numbers a segment draws before its walk, [`segment_rands`]'s: the light's four, the
/// scattered direction's four and the roulette's.
pub type SegmentRands = (Vec4, Vec4, f32);

/// The first half of [`trace_ray_at`]: the segment's random numbers and its walk. A ray that
/// escapes takes the environment ([`escape`], which ends the path) and gives `None`; a hit
/// comes back with the numbers [`shade_segment`] finishes the segment with.
/// `cpu::stages::trace_paths_in_pairs` runs the two halves of two paths' segments in turn.
#[inline(always)]
pub fn walk_segment<const F: u32, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    path: &mut PathState,
    pixel: u32,
    sp: SobolPixel,
    sample: u32,
    depth: u32,
) -> Option<(Hit, SegmentRands)> {
    let ray = Ray {
        origin: path.origin,
        dir: path.dir,
    };
    // The segment's random numbers (pure functions of the pixel, sample and segment) are
    // drawn before its walk, so that the core computes them while the walk waits on memory
    // (Bitterli's Cornell box 8-10 % faster than drawing each where it is used, the living
    // room 3 %: `docs/RESULTS.md`, issue 15); the WGSL draws them where it uses them, which
    // keeps them out of the registers the walk needs. The light's only where a hit could
    // sample the lights (not in a plain render, whose `light_count` is 0, nor at the last
    // segment); it and the roulette's are wasted when the ray escapes or the hit's material
    // does not sample the lights. With the `Sobol` sampler the three groups are drawn at once
    // from the render's table of their hashes (`Globals::sobol_segments`; the same numbers,
    // eight lanes at a time, with `sampler_pixel` once a path in `trace_path`: the Cornell
    // box 10-12 % faster in the default build, 5-10 % built native, the living room 2-5 %;
    // `docs/RESULTS.md`, issue 15).
    let rnd = segment_rands::<K>(g, sp, pixel, sample, depth);
    let Some(hit) = K::trace_closest::<F>(bvh, &ray, 0.0, T_MAX) else {
        escape::<F>(g, path);
        return None;
    };
    Some((hit, rnd))
}

/// The rest of [`trace_ray_at`]'s segment `depth` once its walk found `hit`: the surface, the
/// light sample and its shadow ray, the emission, the scattered ray and the roulette, from the
/// segment's numbers `rnd` ([`segment_rands`]'s). `cpu::packet` finishes through it the
/// segments of the lanes it does not shade on lanes (other materials than diffuse), so that
/// one code computes them either way.
#[inline(always)]
pub fn shade_segment<const F: u32, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    path: &mut PathState,
    hit: Hit,
    rnd: SegmentRands,
    depth: u32,
) {
    let (rnd_light, rnd_scatter, rnd_roulette) = rnd;
    let surface = surface_at::<F>(g, &hit, path.origin, path.dir);
    // The material's record, untextured: what the light sample and the emission's weight
    // read. Its texels are asked for now, and read by `material_at` below.
    let record = &g.materials[surface.material as usize];
    prefetch_texture::<F>(g, record, surface.uv);
    let last = depth >= g.scene.max_bounces;
    // An emissive triangle hit by a direction sampled where the lights were sampled too: the
    // shadow ray there could have found this point; weigh the two estimates.
    // Lights to sample (emitters or a sky) and materials that sample them, or neither. (The
    // WGSL also tests its `NEXT_EVENT` override, false in a plain render's pipelines, so that
    // the driver drops this part there; here a plain render's `light_count` of 0 and `mis_pdf`
    // of 0 take the same branches.)
    let lit = (has(F, Feature::Emission)
        || has(F, Feature::ConstantEnvironment)
        || has(F, Feature::EnvironmentMap))
        && (has(F, Feature::Diffuse)
            || has(F, Feature::Plastic)
            || has(F, Feature::RoughMetal)
            || has(F, Feature::RoughGlass));
    let prim = g.primitives[hit.prim as usize];
    let emission_weight = if !lit {
        1.0
    } else if path.mis_pdf > 0.0 && prim.kind() == PRIM_TRIANGLE {
        let [a, b, c] = [prim.a, prim.b, prim.c].map(|v| Vec3::new(v[0], v[1], v[2]));
        let n = (b - a).cross(c - a);
        let cos_l = n.dot(path.dir).abs() / n.length();
        mis_weight(
            path.mis_pdf,
            light_pdf(g, Vec3::from(record.emission), hit.t * hit.t, cos_l),
        )
    } else if has(F, Feature::Spheres) && path.mis_pdf > 0.0 && prim.kind() == PRIM_SPHERE {
        let (center, r) = (Vec3::new(prim.a[0], prim.a[1], prim.a[2]), prim.a[3]);
        let cap_pdf = sphere_cap_pdf(center, r, path.origin);
        mis_weight(
            path.mis_pdf,
            sphere_light_pdf(g, Vec3::from(record.emission), r, cap_pdf),
        )
    } else {
        1.0
    };
    let sample_here = lit && g.scene.light_count > 0 && samples_lights::<F>(record) && !last;
    // The light sample first, which reads the material's record alone; then the textured
    // material, the light's contribution, the emission and the scattered ray; the light's
    // term and the emission are added in the order of the `next_event` stage's sums. Where
    // the variant has textures, the shadow ray is walked before the texels are read (asked
    // for above), so that the walk hides their latency (the living room at 1000x1000, 10
    // spp, 4 % faster by the best of three; `docs/RESULTS.md`, issue 15); elsewhere after
    // the shading, where the next segment's start overlaps it (the Cornell box ~1 % faster
    // so). The WGSL shades the hit first and walks the path's ray and the shadow ray through
    // one call of the walk: the values are the same in any order.
    let query = if sample_here {
        light_query::<F>(g, &surface, record, path.dir, rnd_light)
    } else {
        None
    };
    let early = has(F, Feature::Textures) && shadowed::<F, K>(bvh, &query);
    let mat = material_at::<F>(g, &surface);
    let throughput_in = path.throughput;
    // A sample whose shadow ray was walked first and found blocked adds zero whatever its
    // contribution: that (the BSDF's value toward the light, its pdf, the weight) is not
    // computed. The living room's sky samples are 97 % blocked (a counter, session 45): its
    // render's instructions -2.9 % (cachegrind). The same values (the sum below adds
    // `throughput_in * 0` as before).
    let light_in = match &query {
        Some(q) if !early => light_contribution::<F>(g, q, &mat, path.dir),
        _ => Vec3::ZERO,
    };
    let emission = emitted::<F>(path, &surface, &mat, emission_weight);
    let pdf = shade_hit::<F>(g, path, &surface, &mat, rnd_scatter, last);
    path.mis_pdf = if sample_here { pdf } else { 0.0 };
    if path.alive && depth >= g.scene.rr_depth {
        russian_roulette(path, rnd_roulette);
    }
    if sample_here {
        let occluded = if has(F, Feature::Textures) {
            early
        } else {
            shadowed::<F, K>(bvh, &query)
        };
        path.radiance += throughput_in * if occluded { Vec3::ZERO } else { light_in };
    }
    path.radiance += emission;
}

/// Where light `lo`'s share of `[0, 1)` begins: the cdf of the light before it, 0 for the
/// first. Both read, then one taken by `select_unpredictable` (which light a sample takes is
/// a coin toss: Bitterli's Cornell box, two triangles, where `if lo > 0` around the read was
/// ~12 % of its mispredicted branches under cachegrind; x86 may still compile a float select
/// as a short branch, but this measured faster).
#[inline(always)]
pub fn cdf_before(g: &Globals, lo: u32) -> f32 {
    let below = g.lights[lo.saturating_sub(1) as usize].cdf;
    std::hint::select_unpredictable(lo > 0, below, 0.0)
}

/// [`light_query`]'s choice of light by `u` (its `rnd.x`): the first light whose running
/// probability exceeds `u`, its selection probability, and where `u` falls in its share of
/// `[0, 1)`, rescaled to `[0, 1)` (below 1: `u` may reach the last light's cdf by rounding; 0
/// for a light never chosen, `p_select` 0, which the caller rejects). `cpu::packet` chooses
/// its lanes' lights through it too.
#[inline(always)]
pub fn choose_light(g: &Globals, u: f32) -> (u32, f32, f32) {
    let mut lo = 0u32;
    let mut hi = g.scene.light_count - 1;
    while lo < hi {
        let mid = (lo + hi) / 2;
        if g.lights[mid as usize].cdf > u {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let before = cdf_before(g, lo);
    let p_select = g.lights[lo as usize].cdf - before;
    let x = if p_select > 0.0 {
        ((u - before) / p_select).min(crate::sobol::SOBOL_ONE_MINUS_EPSILON)
    } else {
        0.0
    };
    (lo, p_select, x)
}

/// The random numbers of a path's segment `depth`: the light's four (zero where no light can
/// be sampled: a plain render, or the last segment), the scattered direction's four, and the
/// roulette's (zero before `rr_depth`), as [`trace_ray_at`] draws them; the `Sobol`
/// sampler's groups drawn by `K::draw` ([`SegmentKeys::draw`](crate::sobol::SegmentKeys::draw)
/// or another form of it, the same numbers: `SegmentKeys::draw_avx2`).
#[inline(always)]
pub fn segment_rands<K: Forms>(
    g: &Globals,
    sp: SobolPixel,
    pixel: u32,
    sample: u32,
    depth: u32,
) -> (Vec4, Vec4, f32) {
    let (wants_light, wants_roulette) = segment_wants(g, depth);
    match table_keys(g, sp, depth) {
        // The `Sobol` sampler's three groups at once, their hashes from the render's table
        // (the same numbers: `SegmentKeys::draw`).
        Some(keys) => {
            let (light, scatter, roulette) = K::draw(keys, sp, sample);
            // Selects, not branches: whether a path is past `rr_depth` varies from path
            // to path.
            (
                std::hint::select_unpredictable(wants_light, light, Vec4::ZERO),
                scatter,
                std::hint::select_unpredictable(wants_roulette, roulette, 0.0),
            )
        }
        _ => (
            if wants_light {
                path_rand4_at(g.scene, sp, pixel, sample, depth, DIM_LIGHT)
            } else {
                Vec4::ZERO
            },
            path_rand4_at(g.scene, sp, pixel, sample, depth, DIM_SCATTER),
            if wants_roulette {
                path_rand4_at(g.scene, sp, pixel, sample, depth, DIM_ROULETTE).x
            } else {
                0.0
            },
        ),
    }
}

/// Whether segment `depth` draws its light sample's numbers (a light to sample, not the
/// last segment) and its roulette's (from `rr_depth` on): [`segment_rands`] gives zeros for
/// those it does not.
#[inline(always)]
pub fn segment_wants(g: &Globals, depth: u32) -> (bool, bool) {
    (
        g.scene.light_count > 0 && depth < g.scene.max_bounces,
        depth >= g.scene.rr_depth,
    )
}

/// A segment's numbers as [`segment_rands`] draws them under the `Sobol` sampler, for the
/// paths of diffuse surfaces (`cpu::packet`), which use the first pair of its light and
/// scatter groups and, at segment 0, the camera's pair: the pairs `d` drawn for segment
/// `depth` ([`SegmentKeys::draw_pairs`] under `table_keys`' keys), the light and roulette
/// numbers zeroed where the segment does not use them, as [`segment_rands`] zeroes them.
///
/// [`SegmentKeys::draw_pairs`]: crate::sobol::SegmentKeys::draw_pairs
#[inline(always)]
pub fn wanted_pairs(
    g: &Globals,
    d: crate::sobol::SegmentPairs,
    depth: u32,
) -> crate::sobol::SegmentPairs {
    let (wants_light, wants_roulette) = segment_wants(g, depth);
    crate::sobol::SegmentPairs {
        light: std::hint::select_unpredictable(wants_light, d.light, glam::Vec2::ZERO),
        roulette: std::hint::select_unpredictable(wants_roulette, d.roulette, 0.0),
        ..d
    }
}

/// Segment `depth`'s hashes from the render's table (`Globals::sobol_segments`) where the
/// `Sobol` sampler draws from it: the pixel's seed the table's (not a tile of its own) and
/// the segment within the table (else `None`: another sampler, a tile's seed or a segment
/// past the table). `cpu::packet` draws four lanes' pairs from them at once.
#[inline(always)]
pub(crate) fn table_keys<'a>(
    g: &Globals<'a>,
    sp: SobolPixel,
    depth: u32,
) -> Option<&'a crate::sobol::SegmentKeys> {
    match g.sobol_segments.get(depth as usize) {
        Some(keys) if keys.seed() == sp.seed && g.scene.sampler == SAMPLER_SOBOL => Some(keys),
        _ => None,
    }
}

/// A path whose ray escaped the scene: adds the environment it sees (weighed against the
/// light sample of the vertex it left, when that sampled the lights) and ends it.
#[inline(always)]
pub fn escape<const F: u32>(g: &Globals, path: &mut PathState) {
    // Escaped from a vertex that sampled the lights, the environment among them: weigh the
    // scattered ray's estimate against the shadow ray's.
    let w = if path.mis_pdf > 0.0 && g.scene.environment_select > 0.0 {
        mis_weight(
            path.mis_pdf,
            g.scene.environment_select
                * environment_pdf::<F>(g, path.dir, environment_cell(g, path.origin)),
        )
    } else {
        1.0
    };
    path.radiance += path.throughput * environment_radiance::<F>(g, path.dir) * w;
    path.alive = false;
}

/// Whether the light sample `query`'s shadow ray is blocked (false without a sample): toward
/// the sky [`Forms::trace_any`], toward a point of a lamp [`Forms::trace_any_between`] (a
/// segment between two points of the scene; the same answer but for a rounding artifact at
/// an origin in a corner).
/// A function, not a closure in [`trace_ray_at`]: one the compiler left out of line would run
/// at the build's instruction level, not the one `cpu::isa` compiled the path for.
#[inline(always)]
fn shadowed<const F: u32, K: Forms>(bvh: &GpuBvh, query: &Option<LightQuery>) -> bool {
    match query {
        Some(q) if q.is_env => K::trace_any::<F>(bvh, &q.ray, 0.0, q.t_max),
        Some(q) => K::trace_any_between::<F>(bvh, &q.ray, 0.0, q.t_max),
        None => false,
    }
}

/// Russian roulette: the path goes on with probability `q = min(max throughput,
/// RR_MAX_SURVIVAL)` (when `u < q`), its throughput divided by `q` so that the estimate stays
/// unbiased; otherwise it ends.
#[inline]
pub fn russian_roulette(path: &mut PathState, u: f32) {
    let q = path.throughput.max_element().min(RR_MAX_SURVIVAL);
    if u < q {
        path.throughput /= q;
    } else {
        path.alive = false;
    }
}

/// Whether next-event estimation samples the lights at a hit on `mat`: every material whose
/// scattering can be evaluated for a given direction (diffuse, rough metal, plastic, whose
/// smooth coat's delta lobe is left to the scattered ray, rough glass on both sides, the
/// shadow ray leaving from behind for transmission: [`light_side`]). Not smooth metal or
/// smooth glass (deltas).
#[inline]
pub fn samples_lights<const F: u32>(mat: &GpuMaterial) -> bool {
    (has(F, Feature::Diffuse) && mat.kind == MATERIAL_DIFFUSE)
        || (has(F, Feature::Plastic) && mat.kind == MATERIAL_PLASTIC)
        || (has(F, Feature::RoughMetal) && mat.kind == MATERIAL_METAL && mat.alpha > 0.0)
        || (has(F, Feature::RoughGlass) && mat.kind == MATERIAL_GLASS && mat.alpha > 0.0)
}

/// Where a light direction `wi` lies for a hit on `mat` whose normals face the incoming ray:
/// 1 in front (both the shading and the geometric normal agree), -1 behind (both agree) for
/// rough glass, which transmits; 0 where they disagree or the material cannot transmit.
#[inline]
pub fn light_side<const F: u32>(
    mat: &GpuMaterial,
    ns_facing: Vec3,
    ng_facing: Vec3,
    wi: Vec3,
) -> f32 {
    let (s, g) = (ns_facing.dot(wi), ng_facing.dot(wi));
    if s > 0.0 && g > 0.0 {
        return 1.0;
    }
    if has(F, Feature::RoughGlass) && mat.kind == MATERIAL_GLASS && s < 0.0 && g < 0.0 {
        return -1.0;
    }
    0.0
}

/// The reflection of `mat` from the incoming `dir_in` into `wi` about the unit shading normal
/// `n` facing `dir_in`: `f · cos θ` and the pdf with which [`shade_hit`] samples `wi` (the
/// same pdf, so that multiple importance sampling weighs the two strategies consistently).
/// Zero for materials [`samples_lights`] excludes. `front`: the ray meets the geometric
/// front face (glass: it enters).
#[inline(always)]
pub fn eval_material<const F: u32>(
    g: &Globals,
    mat: &GpuMaterial,
    dir_in: Vec3,
    n: Vec3,
    wi: Vec3,
    front: bool,
) -> BsdfEval {
    let color = Vec3::from(mat.color);
    if has(F, Feature::Diffuse) && mat.kind == MATERIAL_DIFFUSE {
        let pdf = n.dot(wi).max(0.0) * INV_PI;
        return BsdfEval {
            value: color * pdf,
            pdf,
        };
    }
    if has(F, Feature::RoughMetal) && mat.kind == MATERIAL_METAL {
        let (eta, k) = (Vec3::from(mat.eta), Vec3::from(mat.k));
        return eval_conductor(dir_in, n, wi, mat.alpha, color, eta, k);
    }
    if has(F, Feature::Plastic) && mat.kind == MATERIAL_PLASTIC {
        if mat.alpha > 0.0 {
            let table = &g.plastic_tables[mat.table as usize];
            return eval_rough_plastic(dir_in, n, wi, mat.alpha, mat.ior, color, table);
        }
        return eval_plastic(dir_in, n, wi, mat.ior, color);
    }
    if has(F, Feature::RoughGlass) && mat.kind == MATERIAL_GLASS {
        // Entering when the ray meets the geometric front face (as in shade_hit).
        let eta = if front { 1.0 / mat.ior } else { mat.ior };
        return eval_rough_dielectric(dir_in, n, wi, mat.alpha, eta, color);
    }
    bsdf_eval_zero()
}

/// The solid-angle pdf with which [`light_query`] picks a direction toward a point of a light
/// emitting `emission`, `dist2` away, seen at `cos_l` to its normal: its selection probability
/// (area times luminance over the list's total) over its area, converted to solid angle. The
/// area cancels.
#[inline]
pub fn light_pdf(g: &Globals, emission: Vec3, dist2: f32, cos_l: f32) -> f32 {
    emission.dot(Vec3::from(LUMINANCE)) * dist2 / (g.scene.light_power * cos_l)
}

/// The solid-angle pdf with which [`light_query`] picks a direction toward a point of an
/// emissive sphere of radius `r` emitting `emission`, seen from a point where the sphere's
/// cone has pdf `cap_pdf` ([`sphere_cap_pdf`], 0 inside the sphere): its selection
/// probability (`4 π r²` times luminance over the list's total) times `cap_pdf`.
#[inline]
pub fn sphere_light_pdf(g: &Globals, emission: Vec3, r: f32, cap_pdf: f32) -> f32 {
    emission.dot(Vec3::from(LUMINANCE)) * (4.0 * PI * r * r) / g.scene.light_power * cap_pdf
}

/// Veach's power heuristic: the weight of a sample drawn with pdf `a` when pdf `b` could have
/// drawn it too.
#[inline]
pub fn mis_weight(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

/// A light sample's shadow ray and what its contribution needs besides the ray's verdict
/// ([`light_query`]'s result; [`light_contribution`] reads it). A value type, not a buffer
/// layout: the WGSL's `LightQuery` has the same fields and a `valid` flag where this is an
/// `Option`.
#[derive(Clone, Copy, Debug)]
pub struct LightQuery {
    /// The shadow ray, from the surface toward the sampled point or direction.
    pub ray: Ray,
    /// The shadow ray's reach: the light's distance times [`SHADOW_T_SCALE`], or [`T_MAX`]
    /// toward the sky.
    pub t_max: f32,
    /// The direction toward the light.
    pub wi: Vec3,
    /// The shading normal on the incoming ray's side.
    pub ns_facing: Vec3,
    /// Whether the incoming ray meets the geometric normal's front.
    pub front: bool,
    /// The environment was chosen.
    pub is_env: bool,
    /// An emissive sphere was chosen.
    pub is_sphere: bool,
    /// The chosen light's index in the list.
    pub light: u32,
    /// The environment's guide cell of `origin` ([`environment_cell`]).
    pub cell: u32,
    /// Where a reflected ray leaves the surface ([`offset_ray_origin`]).
    pub origin: Vec3,
    /// The environment sample's pdf (0 for the other kinds).
    pub env_pdf: f32,
    /// The squared distance to the light's point (0 toward the sky).
    pub dist2: f32,
    /// The cosine at the light's point (1 for the sky and spheres).
    pub cos_l: f32,
    /// The chosen light's selection probability.
    pub p_select: f32,
}

/// Next-event estimation's light sample at a hit reached along `dir_in` on a material that
/// [`samples_lights`]: the light of the list chosen by `rnd.x` (with probability `cdf -
/// previous cdf`), a uniform point on it from `(x', rnd.y)`, `x'` where `rnd.x` falls in the
/// light's share of `[0, 1)` rescaled to `[0, 1)`, and the shadow ray toward it; `None` when nothing can arrive (the point behind the surface,
/// geometric or shading normal, the surface behind a one-sided light, an empty selection).
/// [`trace_ray`] traces the ray after the hit's shading (the WGSL through one call of the walk
/// for both its rays), and [`light_contribution`] says what arrives if it is not blocked.
#[inline(always)]
pub fn light_query<const F: u32>(
    g: &Globals,
    hit: &SurfaceHit,
    mat: &GpuMaterial,
    dir_in: Vec3,
    rnd: Vec4,
) -> Option<LightQuery> {
    // The first light whose running probability exceeds rnd.x; where rnd.x falls in that
    // light's share, rescaled to [0, 1), and rnd.y then place the point, as Mitsuba 3 reuses
    // its emitter sample: (rnd.x, rnd.y), the segment's 2D net under the Sobol' samplers, stays
    // one net over all the lights together (a quad light's two triangles are sampled as one
    // quad), where choosing by rnd.z gave each light a random subset of the net (Bitterli's
    // Cornell box at 128x128, 64 spp: relative MSE 3.5 % lower over seven seeds;
    // `docs/RESULTS.md`, issue 15). A light's share of [0, 1) is at least its probability's
    // float spacing, so the rescaled number keeps fewer bits where thousands of lights share
    // the range: their points then fall on a coarser grid along one axis of each triangle.
    let (lo, p_select, x) = choose_light(g, rnd.x);
    let light = g.lights[lo as usize];
    let ng = hit.geometric_normal;
    let front = dir_in.dot(ng) < 0.0;
    let ng_facing = if front { ng } else { -ng };
    let ns_facing = if front {
        hit.shading_normal
    } else {
        -hit.shading_normal
    };
    let origin = offset_ray_origin(hit, dir_in, ng_facing);
    // The environment's guide cell: that of the origin a reflected ray leaves from, the same
    // point whose cell weighs such a ray if it escapes (`trace_ray`).
    let cell = environment_cell(g, origin);
    // The light's direction, the shadow ray's reach and the side it leaves from, per kind;
    // then one shadow ray and one BSDF evaluation whatever the kind (as the WGSL, where that
    // means one material switch instead of two).
    let is_env = (has(F, Feature::ConstantEnvironment) || has(F, Feature::EnvironmentMap))
        && light.kind == LIGHT_ENVIRONMENT;
    let is_sphere = has(F, Feature::Spheres) && light.kind == LIGHT_SPHERE;
    let (wi, t_max, side, env_pdf, dist2, cos_l);
    if is_env {
        // A direction toward the sky; the shadow ray must escape the scene.
        let (dir, pdf) = sample_environment::<F>(g, Vec2::new(x, rnd.y), cell);
        wi = dir;
        env_pdf = pdf;
        side = light_side::<F>(mat, ns_facing, ng_facing, wi);
        if !(env_pdf > 0.0 && p_select > 0.0 && side != 0.0) {
            return None;
        }
        (t_max, dist2, cos_l) = (T_MAX, 0.0, 1.0);
    } else {
        env_pdf = 0.0;
        let point = if is_sphere {
            // A point of the cap seen from the origin: it faces the origin (cos_l = 1).
            let center = Vec3::from(light.p0);
            // Inside the sphere: only the scattered ray finds it.
            sample_sphere_cap(center, light.e1[0], origin, Vec2::new(x, rnd.y))?
        } else {
            // Uniform on the triangle (the square-root parameterisation).
            let su = x.sqrt();
            let (e1, e2) = (Vec3::from(light.e1), Vec3::from(light.e2));
            Vec3::from(light.p0) + e1 * (su * (1.0 - rnd.y)) + e2 * (su * rnd.y)
        };
        let to = point - origin;
        dist2 = to.length_squared();
        if !(p_select > 0.0 && dist2 > 0.0) {
            return None;
        }
        let dist = dist2.sqrt();
        wi = to / dist;
        t_max = dist * SHADOW_T_SCALE;
        side = light_side::<F>(mat, ns_facing, ng_facing, wi);
        cos_l = if is_sphere {
            1.0
        } else {
            // The light's front face looks along e1 x e2: a one-sided light sends nothing
            // backwards.
            let nl = Vec3::from(light.e1).cross(Vec3::from(light.e2));
            let cos_front = -nl.dot(wi) / nl.length();
            if light.two_sided != 0 {
                cos_front.abs()
            } else {
                cos_front
            }
        };
        if !(side != 0.0 && cos_l > 0.0) {
            return None;
        }
    }
    // Through rough glass the shadow ray leaves from behind the surface (the distance to the
    // light differs by the offset alone, which SHADOW_T_SCALE covers).
    let from = if side > 0.0 {
        origin
    } else {
        offset_ray_origin(hit, dir_in, -ng_facing)
    };
    Some(LightQuery {
        ray: Ray {
            origin: from,
            dir: wi,
        },
        t_max,
        wi,
        ns_facing,
        front,
        is_env,
        is_sphere,
        light: lo,
        cell,
        origin,
        env_pdf,
        dist2,
        cos_l,
        p_select,
    })
}

/// The reflected radiance a light sample ([`light_query`]) carries if its shadow ray is not
/// blocked: `f cos θ_surface · L_e · cos θ_light · area / (distance² · p_select)`
/// ([`eval_material`]; for the sky and spheres their own densities), times its
/// multiple-importance weight against the material's own sampling.
#[inline(always)]
pub fn light_contribution<const F: u32>(
    g: &Globals,
    q: &LightQuery,
    mat: &GpuMaterial,
    dir_in: Vec3,
) -> Vec3 {
    let f = eval_material::<F>(g, mat, dir_in, q.ns_facing, q.wi, q.front);
    if q.is_env {
        let w = mis_weight(
            g.scene.environment_select * environment_pdf::<F>(g, q.wi, q.cell),
            f.pdf,
        );
        return f.value * environment_radiance::<F>(g, q.wi) * (w / (q.p_select * q.env_pdf));
    }
    let light = g.lights[q.light as usize];
    let emission = Vec3::from(light.emission);
    if q.is_sphere {
        let r = light.e1[0];
        let cap_pdf = sphere_cap_pdf(Vec3::from(light.p0), r, q.origin);
        let w = mis_weight(sphere_light_pdf(g, emission, r, cap_pdf), f.pdf);
        return f.value * emission * (w / (q.p_select * cap_pdf));
    }
    let w = mis_weight(light_pdf(g, emission, q.dist2, q.cos_l), f.pdf);
    f.value * emission * (q.cos_l * light.area / (q.dist2 * q.p_select) * w)
}

/// The WGSL source of the functions above.
pub const SHADE_WGSL: &str = include_str!("shade.wgsl");

#[cfg(test)]
mod tests {
    use super::*;

    /// True when the `2^k` points have exactly one in every elementary interval of area
    /// `2^-k` (a (0, k, 2)-net in base 2).
    fn is_net(pts: &[Vec2], k: u32) -> bool {
        (0..=k).all(|a| {
            let b = k - a;
            let mut count = vec![0u32; 1 << k];
            for p in pts {
                let cx = (p.x * (1u32 << a) as f32) as u32;
                let cy = (p.y * (1u32 << b) as f32) as u32;
                count[((cy << a) | cx) as usize] += 1;
            }
            count.iter().all(|&c| c == 1)
        })
    }

    #[test]
    fn two_dimensional_samples_come_from_one_net() {
        // Under the Sobol' samplers, what a BSDF sampler takes as its direction, (u.y, u.z) of
        // `lobe_first`, and what light sampling takes as its light and point, (rnd.x, rnd.y),
        // are over a pixel's 64 samples a (0, 6, 2)-net, at every segment: one pair of one
        // net. The number of the next pair (rnd.z) only chooses a BSDF's lobe. (Taking (rnd.y, rnd.z), as before,
        // pairs two nets: no net.)
        for sampler in [SAMPLER_SOBOL, crate::gpu_types::SAMPLER_ZSOBOL] {
            let scene = SceneUniforms {
                sampler,
                width: 37,
                height: 11,
                spp: 64,
                seed: 5,
                ..Default::default()
            };
            for (pixel, bounce) in [(0, 0), (200, 3), (406, 7)] {
                for dim in [DIM_SCATTER, DIM_LIGHT] {
                    let rnd: Vec<Vec4> = (0..64)
                        .map(|s| path_rand4(&scene, pixel, s, bounce, dim))
                        .collect();
                    let direction: Vec<Vec2> = rnd
                        .iter()
                        .map(|&r| {
                            let u = lobe_first(r);
                            Vec2::new(u.y, u.z)
                        })
                        .collect();
                    assert!(is_net(&direction, 6), "BSDF direction, pixel {pixel}");
                    let point: Vec<Vec2> = rnd.iter().map(|r| Vec2::new(r.x, r.y)).collect();
                    assert!(is_net(&point, 6), "light point, pixel {pixel}");
                    let mixed: Vec<Vec2> = rnd.iter().map(|r| Vec2::new(r.y, r.z)).collect();
                    assert!(
                        !is_net(&mixed, 6),
                        "two nets' numbers paired, pixel {pixel}"
                    );
                }
            }
        }
    }
}
