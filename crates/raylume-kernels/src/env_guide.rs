//! Environment sampling guided by where the environment is seen from: a learned proposal for
//! next-event estimation toward the sky.
//!
//! Next-event estimation samples a constant environment uniformly over the sphere and a map by
//! its luminance; neither knows which directions the scene leaves open. In a room lit through
//! its windows almost every such shadow ray hits a wall (the living room: NEE lowered the error
//! at equal spp only 1.2x). Before rendering, [`learn_environment_guide`] sends cheap diffuse
//! random walks from the camera into the scene and counts the directions in which they escape.
//! A walk's vertex samples a cosine-weighted direction about its geometric normal, so the
//! escape directions are distributed as `V(x, ω) cos θ` averaged over the vertices the walks
//! visit: the shape of the direct sky light at those vertices, which is the density NEE should
//! sample (times the environment's radiance, for a map).
//!
//! The guide becomes an equirectangular distribution in the same layout as an environment
//! map's ([`crate::surface::sample_environment`] draws from it; [`crate::surface::environment_pdf`]
//! gives its pdf, used by MIS), mixed with the unguided one ([`GUIDE_UNIFORM_SHARE`] of the
//! probability) so that every direction keeps a pdf of at least a quarter of the unguided one:
//! the estimator stays unbiased whatever the walks found, and a direction they missed costs at
//! most 4x its unguided variance. The walks are deterministic (a hash of their index), integer
//! counts summed in any order: the same scene and BVH give the same distribution on every
//! machine, so the CPU and the GPU draw the same samples.

use glam::{Vec2, Vec3};
use raylume_bvh::{GpuBvh, PRIM_SPHERE, Ray};
use raylume_scene::Camera;
use rayon::prelude::*;

use crate::camera::camera_basis;
use crate::math::{direction_to_equirect, normalize};
use crate::rng::{pcg4d, rand_f32};
use crate::sampling::sample_diffuse;

/// Columns of each cell's equirectangular direction grid (in `u`, the azimuth).
pub const GUIDE_WIDTH: u32 = 32;
/// Rows of each cell's direction grid (in `v`, from +y down).
pub const GUIDE_HEIGHT: u32 = 16;
/// Cells along the scene's longest axis; the other axes get as many of the same size (at
/// least one).
pub const GUIDE_CELLS_LONGEST: u32 = 8;
/// Walks per side of the camera grid they start from: `GUIDE_WALKS_PER_SIDE²` walks.
pub const GUIDE_WALKS_PER_SIDE: u32 = 160;
/// Vertices a walk visits at most (the camera ray's hit and the bounces after it).
pub const GUIDE_VERTICES: u32 = 4;
/// Probe rays per vertex (besides the walk's own next ray, which counts too when it escapes).
pub const GUIDE_PROBES: u32 = 8;
/// The most rays the walks trace: every walk's vertices, each with its probes.
pub const GUIDE_MAX_RAYS: u64 =
    (GUIDE_WALKS_PER_SIDE as u64).pow(2) * GUIDE_VERTICES as u64 * (1 + GUIDE_PROBES as u64);
/// The share of the probability the unguided distribution keeps (defensive sampling): every
/// direction's pdf is at least this times its unguided pdf.
pub const GUIDE_UNIFORM_SHARE: f64 = 0.25;
/// How many (blurred) escapes the distribution of all cells together is worth in a cell's:
/// a cell with far fewer follows all cells', one with far more its own.
pub const GUIDE_PRIOR_ESCAPES: f64 = 64.0;
/// Fewer escapes than this in all and the counts are noise: no guide (the unguided
/// distribution).
pub const GUIDE_MIN_ESCAPES: u64 = 256;

/// What the walks found: escape counts per cell and direction.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentGuide {
    /// Cells along x, y, z over the scene's bounds.
    pub grid: [u32; 3],
    /// `grid` over the scene's extent per axis (0 along an axis of one cell).
    pub grid_scale: Vec3,
    /// Per cell (x fastest, then y, then z), `GUIDE_WIDTH x GUIDE_HEIGHT` counts in direction
    /// space (no map rotation; row-major, top row first).
    pub counts: Vec<u32>,
    /// Walks started (camera rays sent).
    pub walks: u32,
    /// Probe and walk rays that escaped (the sum of `counts`).
    pub escapes: u64,
}

/// Direction cells of one spatial cell.
const BINS: usize = (GUIDE_WIDTH * GUIDE_HEIGHT) as usize;

/// The guide's grid over a scene of `extent`: [`GUIDE_CELLS_LONGEST`] cells along the longest
/// axis, cubes as near as the others allow, and the cells per unit along each axis.
pub fn guide_grid(extent: Vec3) -> ([u32; 3], Vec3) {
    let longest = extent.max_element();
    if !(longest.is_finite() && longest > 0.0) {
        return ([1, 1, 1], Vec3::ZERO);
    }
    let size = longest / GUIDE_CELLS_LONGEST as f32;
    let mut grid = [1u32; 3];
    let mut scale = Vec3::ZERO;
    for axis in 0..3 {
        let n = ((extent[axis] / size).ceil() as u32).clamp(1, GUIDE_CELLS_LONGEST);
        grid[axis] = n;
        if n > 1 {
            scale[axis] = n as f32 / extent[axis];
        }
    }
    (grid, scale)
}

/// The cell of point `p` in a grid of `grid` cells, `scale` per unit, from `scene_min`
/// ([`crate::surface::environment_cell`] is this on the uniforms).
#[inline]
pub fn cell_index(p: Vec3, scene_min: Vec3, scale: Vec3, grid: [u32; 3]) -> u32 {
    let q = (p - scene_min) * scale;
    let c = |v: f32, n: u32| v.max(0.0).min((n - 1) as f32) as u32;
    let (x, y, z) = (c(q.x, grid[0]), c(q.y, grid[1]), c(q.z, grid[2]));
    (z * grid[1] + y) * grid[0] + x
}

impl EnvironmentGuide {
    /// Whether the counts are worth guiding by ([`GUIDE_MIN_ESCAPES`]).
    pub fn is_useful(&self) -> bool {
        self.escapes >= GUIDE_MIN_ESCAPES
    }

    /// Cells in the grid.
    pub fn cell_count(&self) -> usize {
        self.grid.iter().map(|&n| n as usize).product()
    }

    /// The direction cell holding the direction with equirectangular coordinates `e` (no
    /// rotation).
    pub fn bin_of(e: Vec2) -> usize {
        let u = e.x - e.x.floor();
        let x = ((u * GUIDE_WIDTH as f32) as u32).min(GUIDE_WIDTH - 1);
        let y = ((e.y.clamp(0.0, 1.0) * GUIDE_HEIGHT as f32) as u32).min(GUIDE_HEIGHT - 1);
        (y * GUIDE_WIDTH + x) as usize
    }

    /// Per spatial cell, each direction cell's probability under the guide before the
    /// uniform share is mixed in: the cell's counts blurred over the 3x3 neighbourhood of
    /// directions (wrapping in `u`, clamped in `v`: directions next to the ones found keep
    /// some weight) plus [`GUIDE_PRIOR_ESCAPES`] times all cells' blurred distribution,
    /// normalised; and all cells' distribution itself.
    pub fn cell_probabilities(&self) -> GuideProbabilities {
        let cells = self.cell_count();
        let blurred: Vec<Vec<f64>> = (0..cells)
            .into_par_iter()
            .map(|c| blur(&self.counts[c * BINS..(c + 1) * BINS]))
            .collect();
        let mut global = vec![0.0f64; BINS];
        for b in &blurred {
            for (g, x) in global.iter_mut().zip(b) {
                *g += x;
            }
        }
        let total: f64 = global.iter().sum();
        let solid = cell_solid_angles();
        if total > 0.0 {
            global.iter_mut().for_each(|g| *g /= total);
        } else {
            global.clone_from(
                &solid
                    .iter()
                    .map(|s| s / (4.0 * std::f64::consts::PI))
                    .collect(),
            );
        }
        let cells: Vec<Vec<f64>> = blurred
            .into_par_iter()
            .map(|b| {
                let n: f64 = b.iter().sum();
                b.iter()
                    .zip(&global)
                    .map(|(x, g)| (x + GUIDE_PRIOR_ESCAPES * g) / (n + GUIDE_PRIOR_ESCAPES))
                    .collect()
            })
            .collect();
        GuideProbabilities { cells, all: global }
    }
}

/// [`EnvironmentGuide::cell_probabilities`]: per spatial cell and for all cells together,
/// each direction cell's probability (row-major on the guide's direction grid).
#[derive(Clone, Debug, PartialEq)]
pub struct GuideProbabilities {
    pub cells: Vec<Vec<f64>>,
    pub all: Vec<f64>,
}

/// `counts` (one spatial cell's directions) summed over each direction's 3x3 neighbourhood.
fn blur(counts: &[u32]) -> Vec<f64> {
    let (w, h) = (GUIDE_WIDTH as usize, GUIDE_HEIGHT as usize);
    let mut out = vec![0.0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut sum = 0u32;
            for dy in -1i32..=1 {
                let yy = (y as i32 + dy).clamp(0, h as i32 - 1) as usize;
                for dx in -1i32..=1 {
                    let xx = (x as i32 + dx).rem_euclid(w as i32) as usize;
                    sum += counts[yy * w + xx];
                }
            }
            out[y * w + x] = f64::from(sum);
        }
    }
    out
}

/// The solid angle of each direction cell (row-major).
fn cell_solid_angles() -> Vec<f64> {
    let (w, h) = (GUIDE_WIDTH as usize, GUIDE_HEIGHT as usize);
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let t0 = y as f64 / h as f64 * std::f64::consts::PI;
        let t1 = (y + 1) as f64 / h as f64 * std::f64::consts::PI;
        let s = (t0.cos() - t1.cos()) * 2.0 * std::f64::consts::PI / w as f64;
        out.extend(std::iter::repeat_n(s, w));
    }
    out
}

/// A unit geometric normal of primitive `prim` at `p`, facing against `dir`.
fn facing_normal(bvh: &GpuBvh, prim: u32, p: Vec3, dir: Vec3) -> Vec3 {
    let q = &bvh.primitives[prim as usize];
    let a = Vec3::new(q.a[0], q.a[1], q.a[2]);
    let n = if q.kind() == PRIM_SPHERE {
        normalize(p - a)
    } else {
        let b = Vec3::new(q.b[0], q.b[1], q.b[2]);
        let c = Vec3::new(q.c[0], q.c[1], q.c[2]);
        normalize((b - a).cross(c - a))
    };
    if n.dot(dir) > 0.0 { -n } else { n }
}

/// Walks per parallel task of [`learn_environment_guide`].
const WALKS_PER_TASK: u32 = 512;

/// What every walk of [`learn_environment_guide`] reads: the camera grid's basis, the scene's
/// bounds and the guide's grid over them. `repr(C)`, `Pod`, 112 bytes: env_guide.wgsl's
/// `GuideParams` (a uniform of the GPU's walks, `crate::gpu::GuideLearner`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GuideParams {
    /// The camera's position (`camera_basis` of a `side x side` image).
    pub origin: [f32; 3],
    /// The scene's largest extent (1 when it has none): the walks' ray offsets scale by it.
    pub extent: f32,
    pub forward: [f32; 3],
    /// Walks per side of the camera grid ([`GUIDE_WALKS_PER_SIDE`]).
    pub side: u32,
    pub right: [f32; 3],
    /// Walks in all (`side²`).
    pub walks: u32,
    pub up: [f32; 3],
    pub _pad0: u32,
    /// The scene's bounds' minimum corner.
    pub scene_min: [f32; 3],
    pub _pad1: u32,
    /// Cells per unit along each axis ([`guide_grid`]).
    pub grid_scale: [f32; 3],
    pub _pad2: u32,
    /// Cells along each axis ([`guide_grid`]).
    pub grid: [u32; 3],
    pub _pad3: u32,
}

const _: () = {
    assert!(size_of::<GuideParams>() == 112);
    assert!(std::mem::offset_of!(GuideParams, forward) == 16);
    assert!(std::mem::offset_of!(GuideParams, right) == 32);
    assert!(std::mem::offset_of!(GuideParams, up) == 48);
    assert!(std::mem::offset_of!(GuideParams, scene_min) == 64);
    assert!(std::mem::offset_of!(GuideParams, grid_scale) == 80);
    assert!(std::mem::offset_of!(GuideParams, grid) == 96);
};

impl GuideParams {
    /// The walks' parameters for `camera` over a scene of bounds `scene_min + [0, scene_extent]`.
    pub fn new(camera: &Camera, scene_min: Vec3, scene_extent: Vec3) -> Self {
        let side = GUIDE_WALKS_PER_SIDE;
        let [origin, forward, right, up] = camera_basis(camera, side, side);
        let extent = match scene_extent.max_element() {
            e if e.is_finite() && e > 0.0 => e,
            _ => 1.0,
        };
        let (grid, grid_scale) = guide_grid(scene_extent);
        Self {
            origin: origin.into(),
            extent,
            forward: forward.into(),
            side,
            right: right.into(),
            walks: side * side,
            up: up.into(),
            scene_min: scene_min.into(),
            grid_scale: grid_scale.into(),
            grid,
            ..Self::default()
        }
    }

    /// Cells in the grid.
    pub fn cell_count(&self) -> usize {
        self.grid.iter().map(|&n| n as usize).product()
    }

    /// Escape counters the walks fill: [`GUIDE_WIDTH`] x [`GUIDE_HEIGHT`] per cell.
    pub fn counter_count(&self) -> usize {
        self.cell_count() * BINS
    }
}

/// Walk `walk` of the guide's walks (env_guide.wgsl's `guide_walk`, on the GPU split into one thread per probe):
/// from the camera through its cell of the `side x side` grid (jittered), into the scene of
/// `bvh`, up to [`GUIDE_VERTICES`] vertices; at each, [`GUIDE_PROBES`] cosine-distributed
/// probes and the walk's next direction; `escape(counter)` for every probe that leaves the
/// scene, and for the walk's own ray when it leaves after its first vertex (the counter
/// `cell * GUIDE_WIDTH * GUIDE_HEIGHT + direction cell`). Surfaces are treated as opaque and
/// diffuse (as a shadow ray sees them); a vertex's rays start `1e-5` of the scene's largest
/// extent plus `1e-6` of the point's largest coordinate off the surface (a proposal's rounding
/// does not matter: the guide only shapes a pdf that is evaluated exactly).
pub fn guide_walk(walk: u32, g: &GuideParams, bvh: &GpuBvh, mut escape: impl FnMut(u32)) {
    let (origin, forward, right, up) = (
        Vec3::from(g.origin),
        Vec3::from(g.forward),
        Vec3::from(g.right),
        Vec3::from(g.up),
    );
    let (scene_min, grid_scale) = (Vec3::from(g.scene_min), Vec3::from(g.grid_scale));
    let side = g.side;
    let (x, y) = (walk % side, walk / side);
    let h = pcg4d([walk, 0x5eed_0001, 0, 0x9e37_79b9]);
    let sx = 2.0 * ((x as f32 + rand_f32(h[0])) / side as f32) - 1.0;
    let sy = 1.0 - 2.0 * ((y as f32 + rand_f32(h[1])) / side as f32);
    let mut o = origin;
    let mut d = normalize(forward + right * sx + up * sy);
    let mut cell = 0;
    let counter = |cell: u32, d: Vec3| {
        cell * BINS as u32 + EnvironmentGuide::bin_of(direction_to_equirect(d)) as u32
    };
    for vertex in 0..=GUIDE_VERTICES {
        let Some(hit) = bvh.trace_closest(&Ray::new(o, d), 0.0, f32::INFINITY) else {
            // The camera ray escaping says nothing about the light at surfaces.
            if vertex > 0 {
                escape(counter(cell, d));
            }
            break;
        };
        if vertex == GUIDE_VERTICES {
            break;
        }
        let p = o + d * hit.t;
        let n = facing_normal(bvh, hit.prim, p, d);
        o = p + n * (1e-5 * g.extent + 1e-6 * p.abs().max_element());
        cell = cell_index(o, scene_min, grid_scale, g.grid);
        for probe in 0..=GUIDE_PROBES {
            let u = pcg4d([walk, vertex + 1, probe, 0x5eed_0002]);
            let dir = sample_diffuse(n, Vec2::new(rand_f32(u[0]), rand_f32(u[1])));
            if probe == GUIDE_PROBES {
                d = dir;
            } else if !bvh.trace_any(&Ray::new(o, dir), 0.0, f32::INFINITY) {
                escape(counter(cell, dir));
            }
        }
    }
}

/// Sends `GUIDE_WALKS_PER_SIDE²` diffuse random walks ([`guide_walk`]) from `camera` (through
/// a square grid over its view, jittered) into the scene of `bvh` (bounds `scene_min +
/// [0, scene_extent]`) and counts where their probes escape. On every core; deterministic.
/// The GPU's walks ([`crate::gpu::GuideLearner`]) count the same.
pub fn learn_environment_guide(
    camera: &Camera,
    bvh: &GpuBvh,
    scene_min: Vec3,
    scene_extent: Vec3,
) -> EnvironmentGuide {
    learn_environment_guide_with(&GuideParams::new(camera, scene_min, scene_extent), bvh)
}

/// [`learn_environment_guide`] of the walks `g` over `bvh`, on every core.
pub fn learn_environment_guide_with(g: &GuideParams, bvh: &GpuBvh) -> EnvironmentGuide {
    let tasks: Vec<Vec<u32>> = (0..g.walks.div_ceil(WALKS_PER_TASK))
        .into_par_iter()
        .map(|task| {
            let mut events = Vec::new();
            let first = task * WALKS_PER_TASK;
            for walk in first..(first + WALKS_PER_TASK).min(g.walks) {
                guide_walk(walk, g, bvh, |counter| events.push(counter));
            }
            events
        })
        .collect();
    let mut counts = vec![0u32; g.counter_count()];
    for &counter in tasks.iter().flatten() {
        counts[counter as usize] += 1;
    }
    EnvironmentGuide::from_counts(g, counts)
}

impl EnvironmentGuide {
    /// The guide of walks of parameters `g` that counted `counts` (per cell, per direction
    /// cell: [`GuideParams::counter_count`] of them).
    pub fn from_counts(g: &GuideParams, counts: Vec<u32>) -> Self {
        debug_assert_eq!(counts.len(), g.counter_count());
        let escapes = counts.iter().map(|&c| u64::from(c)).sum();
        EnvironmentGuide {
            grid: g.grid,
            grid_scale: Vec3::from(g.grid_scale),
            counts,
            walks: g.walks,
            escapes,
        }
    }
}

/// Builds the two-level CDF of [`crate::surface::sample_environment`] from per-cell
/// probabilities (any positive scale; row-major `w x h`): the row CDF (`h` floats), then each
/// row's column CDF (`w` floats per row), in f64 and stored as f32 with every last entry 1.
pub fn cdf_from_weights(w: usize, h: usize, weights: &[f64]) -> Vec<f32> {
    assert_eq!(weights.len(), w * h);
    let mut rows = vec![0.0f64; h];
    let mut columns = vec![0.0f32; w * h];
    for y in 0..h {
        let mut run = 0.0f64;
        let mut cum = vec![0.0f64; w];
        for x in 0..w {
            run += weights[y * w + x];
            cum[x] = run;
        }
        for x in 0..w {
            columns[y * w + x] = if run > 0.0 {
                (cum[x] / run) as f32
            } else {
                (x + 1) as f32 / w as f32
            };
        }
        columns[y * w + w - 1] = 1.0;
        rows[y] = run;
    }
    let total: f64 = rows.iter().sum();
    let mut cdf = Vec::with_capacity(h + w * h);
    let mut run = 0.0f64;
    for r in &rows {
        run += r;
        cdf.push((run / total) as f32);
    }
    cdf[h - 1] = 1.0;
    cdf.extend(columns);
    cdf
}

/// The guided distributions of a constant environment, one per spatial cell on the guide's
/// direction grid, back to back: each direction cell's probability is
/// `(1 - GUIDE_UNIFORM_SHARE)` times the cell's guide ([`EnvironmentGuide::cell_probabilities`])
/// plus `GUIDE_UNIFORM_SHARE` times its solid angle's share (uniform over the sphere).
pub fn guided_constant_cdf(guide: &EnvironmentGuide) -> Vec<f32> {
    let solid = cell_solid_angles();
    let four_pi = 4.0 * std::f64::consts::PI;
    guide
        .cell_probabilities()
        .cells
        .par_iter()
        .map(|p| {
            let weights: Vec<f64> = p
                .iter()
                .zip(&solid)
                .map(|(p, s)| (1.0 - GUIDE_UNIFORM_SHARE) * p + GUIDE_UNIFORM_SHARE * s / four_pi)
                .collect();
            cdf_from_weights(GUIDE_WIDTH as usize, GUIDE_HEIGHT as usize, &weights)
        })
        .flatten()
        .collect()
}

/// The guided distribution of a `w x h` environment map turned by `rotation` (turns), for
/// all cells together: texel weights `radiance_weights` (the unguided ones, `(luminance +
/// floor) sin θ`) times `(1 - GUIDE_UNIFORM_SHARE) g + GUIDE_UNIFORM_SHARE`, `g` the density
/// of all cells' guide relative to uniform at the texel centre's direction.
pub fn guided_map_cdf(
    guide: &EnvironmentGuide,
    w: usize,
    h: usize,
    rotation: f32,
    radiance_weights: &[f64],
) -> Vec<f32> {
    let global = guide.cell_probabilities().all;
    let solid = cell_solid_angles();
    let density: Vec<f64> = global
        .iter()
        .zip(&solid)
        .map(|(p, s)| p / s * 4.0 * std::f64::consts::PI)
        .collect();
    let weights: Vec<f64> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            // The texel's direction in direction space: map u minus the rotation.
            let e = Vec2::new(
                (x as f32 + 0.5) / w as f32 - rotation,
                (y as f32 + 0.5) / h as f32,
            );
            let g = density[EnvironmentGuide::bin_of(e)];
            radiance_weights[i] * ((1.0 - GUIDE_UNIFORM_SHARE) * g + GUIDE_UNIFORM_SHARE)
        })
        .collect();
    cdf_from_weights(w, h, &weights)
}
