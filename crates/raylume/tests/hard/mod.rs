//! Scenes built in code, render helpers and checks for `hard_cases.rs`.
//!
//! Every scene renders on the CPU and, when there is an adapter, on the GPU through one shared
//! [`Tracer`]; [`render_both`] also checks that the two backends traced the same paths.

use std::sync::{Mutex, OnceLock};

use glam::Vec3;
use raylume::{Backend, Render, Scene, Tracer};
use raylume_scene::{Camera, FovAxis, Material, RenderSettings, Sphere, Triangle};

/// Two triangles: corner, corner + u, corner + u + v, corner + v, facing along `u × v`.
pub fn quad(corner: Vec3, u: Vec3, v: Vec3, material: u32) -> [Triangle; 2] {
    let (p0, p1, p2, p3) = (corner, corner + u, corner + u + v, corner + v);
    [
        Triangle::flat([p0, p1, p2], material),
        Triangle::flat([p0, p2, p3], material),
    ]
}

/// An axis-aligned box `[lo, hi]`: 12 triangles sharing their edges and corners exactly,
/// wound so that every geometric normal points out of the box (what glass needs: a ray
/// meeting a face from behind its normal is leaving the glass).
pub fn cuboid(lo: Vec3, hi: Vec3, material: u32) -> Vec<Triangle> {
    let d = hi - lo;
    let (x, y, z) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    let faces = [
        (lo, y, x),     // -z
        (lo + z, x, y), // +z
        (lo, z, y),     // -x
        (lo + x, y, z), // +x
        (lo, x, z),     // -y
        (lo + y, z, x), // +y
    ];
    let t: Vec<Triangle> = faces
        .into_iter()
        .flat_map(|(c, u, v)| quad(c, u, v, material))
        .collect();
    let centre = (lo + hi) * 0.5;
    for tri in &t {
        let [a, b, c] = tri.positions;
        let outward = (b - a).cross(c - a).dot((a + b + c) / 3.0 - centre);
        debug_assert!(outward > 0.0, "cuboid winding");
    }
    t
}

/// A closed thin slab `[-1, 1] x [0, height] x [-1, 1]`, finely tessellated: its top and
/// bottom are `n x n` grids of quads whose inner vertices are jittered up and down (so every
/// triangle has its own plane and every edge is a crease), its four sides strips of `n`
/// quads. Neighbouring triangles share bit-identical vertices, so the mesh is closed.
pub fn jittered_slab(n: usize, height: f32, material: u32) -> Vec<Triangle> {
    // A deterministic jitter in [-1, 1].
    let jitter = |i: usize, j: usize, k: usize| {
        let h = (i * 73_856_093) ^ (j * 19_349_663) ^ (k * 83_492_791);
        ((h % 2001) as f32 / 1000.0) - 1.0
    };
    let coord = |i: usize| -1.0 + 2.0 * i as f32 / n as f32;
    let inner = |i: usize, j: usize| i > 0 && j > 0 && i < n && j < n;
    let vertex = |i: usize, j: usize, top: bool| {
        let amplitude = 0.2 * height;
        let y = match (top, inner(i, j)) {
            (false, false) => 0.0,
            (true, false) => height,
            (false, true) => amplitude * (1.0 + jitter(i, j, 0)) * 0.5,
            (true, true) => height - amplitude * (1.0 + jitter(i, j, 1)) * 0.5,
        };
        Vec3::new(coord(i), y, coord(j))
    };
    let mut t = Vec::new();
    for top in [false, true] {
        for i in 0..n {
            for j in 0..n {
                let (a, b) = (vertex(i, j, top), vertex(i + 1, j, top));
                let (c, d) = (vertex(i + 1, j + 1, top), vertex(i, j + 1, top));
                t.push(Triangle::flat([a, b, c], material));
                t.push(Triangle::flat([a, c, d], material));
            }
        }
    }
    // Sides: the boundary vertices of the two grids, joined.
    let boundary: Vec<(usize, usize)> = (0..n)
        .map(|i| (i, 0))
        .chain((0..n).map(|j| (n, j)))
        .chain((0..n).map(|i| (n - i, n)))
        .chain((0..n).map(|j| (0, n - j)))
        .collect();
    for k in 0..boundary.len() {
        let (p, q) = (boundary[k], boundary[(k + 1) % boundary.len()]);
        let (a, b) = (vertex(p.0, p.1, false), vertex(q.0, q.1, false));
        let (c, d) = (vertex(q.0, q.1, true), vertex(p.0, p.1, true));
        t.push(Triangle::flat([a, b, c], material));
        t.push(Triangle::flat([a, c, d], material));
    }
    t
}

/// A closed box `[lo, hi]` whose faces are cut into needles: `m` points along each face's
/// diagonal `c0 -> c2`, joined to the two other corners, give `2 m` triangles per face of
/// aspect ratio about `m`. The face edges stay whole (no T-junctions), so neighbouring faces
/// share bit-identical edges and the box is closed.
pub fn sliver_box(lo: Vec3, hi: Vec3, m: usize, material: u32) -> Vec<Triangle> {
    let d = hi - lo;
    let (x, y, z) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    let faces = [
        (lo, y, x),
        (lo + z, x, y),
        (lo, z, y),
        (lo + x, y, z),
        (lo, x, z),
        (lo + y, z, x),
    ];
    let mut t = Vec::new();
    for (c0, u, v) in faces {
        let (c1, c2, c3) = (c0 + u, c0 + u + v, c0 + v);
        let q: Vec<Vec3> = (0..=m)
            .map(|k| match k {
                0 => c0,
                k if k == m => c2,
                k => c0 + (c2 - c0) * (k as f32 / m as f32),
            })
            .collect();
        for k in 0..m {
            t.push(Triangle::flat([c1, q[k + 1], q[k]], material));
            t.push(Triangle::flat([c3, q[k], q[k + 1]], material));
        }
    }
    t
}

pub fn camera(position: Vec3, look_at: Vec3, vfov: f32) -> Camera {
    Camera {
        position,
        look_at,
        up: Vec3::Y,
        fov: vfov,
        fov_axis: FovAxis::Vertical,
    }
}

pub fn settings(width: u32, height: u32, spp: u32, max_bounces: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp,
        max_bounces,
        seed: 11,
    }
}

pub fn sphere(center: Vec3, radius: f32, material: u32) -> Sphere {
    Sphere {
        center,
        radius,
        material,
    }
}

/// A diffuse material of albedo `a` that also emits `e`, from both faces (so that the walls of
/// a closed glowing box light its inside whichever way they are wound: a furnace).
pub fn glowing(name: &str, a: f32, e: Vec3) -> Material {
    Material {
        emission: e,
        two_sided: true,
        ..Material::diffuse(name, Vec3::splat(a))
    }
}

/// The scene with every point `p` moved to `p * scale + offset` (camera included).
pub fn transformed(scene: &Scene, scale: f32, offset: Vec3) -> Scene {
    let f = |p: Vec3| p * scale + offset;
    let mut s = scene.clone();
    for t in &mut s.triangles {
        t.positions = t.positions.map(f);
    }
    for sp in &mut s.spheres {
        sp.center = f(sp.center);
        sp.radius *= scale;
    }
    s.camera.position = f(s.camera.position);
    s.camera.look_at = f(s.camera.look_at);
    s
}

/// The radiance every path collects inside a closed surface of albedo `a` emitting `e`, with
/// `n` bounces after the camera ray: cosine sampling makes each bounce's weight exactly `a`,
/// so segment `k` adds `a^k e`, and `Σ_{k=0..n} a^k e = e (1 - a^(n+1)) / (1 - a)`.
pub fn furnace_series(a: f32, e: Vec3, n: u32) -> Vec3 {
    let a = f64::from(a);
    let s = (1.0 - a.powi(n as i32 + 1)) / (1.0 - a);
    (e.as_dvec3() * s).as_vec3()
}

/// The GPU tracer all tests of this binary share (one device, pipelines created once per
/// feature set), or `None` after `context_or_skip`'s visible SKIPPED line.
fn gpu_tracer(test: &str) -> Option<&'static Mutex<Tracer>> {
    raylume_gpu::testing::context_or_skip(test)?;
    static GPU: OnceLock<Mutex<Tracer>> = OnceLock::new();
    Some(GPU.get_or_init(|| Mutex::new(paper_tracer(Backend::Gpu))))
}

/// A tracer with the paper's estimator (plain, independent numbers, no Russian roulette):
/// the answers here are exact per sample and every path runs its full length only under it
/// (next-event estimation and roulette make each sample random, unbiased but not exact).
pub fn paper_tracer(backend: Backend) -> Tracer {
    let mut t = Tracer::new(backend);
    t.paper_estimator();
    t
}

/// One backend's render of a case.
pub struct Rendered {
    pub backend: &'static str,
    pub render: Render,
}

impl Rendered {
    pub fn pixels(&self) -> &[[f32; 3]] {
        &self.render.pixels
    }
}

/// Renders `scene` on the CPU and, with an adapter, on the GPU; checks that neither dropped a
/// sample unless `drops_allowed`, that every pixel is finite, and that the backends agree
/// (see [`assert_backends_agree`], `max_flipped` pixels may differ).
pub fn render_both(
    test: &str,
    scene: &Scene,
    drops_allowed: bool,
    max_flipped: usize,
) -> Vec<Rendered> {
    let cpu = paper_tracer(Backend::Cpu)
        .render(scene)
        .unwrap_or_else(|e| panic!("{test}: CPU render failed: {e}"));
    let mut out = vec![Rendered {
        backend: "cpu",
        render: cpu,
    }];
    if let Some(gpu) = gpu_tracer(test) {
        let render = gpu
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .render(scene)
            .unwrap_or_else(|e| panic!("{test}: GPU render failed: {e}"));
        assert_eq!(render.stats.backend, "gpu");
        out.push(Rendered {
            backend: "gpu",
            render,
        });
    }
    for r in &out {
        assert!(
            r.pixels().iter().flatten().all(|c| c.is_finite()),
            "{test} ({}): a non-finite pixel was written",
            r.backend
        );
        if !drops_allowed {
            assert_eq!(
                r.render.stats.dropped_samples, 0,
                "{test} ({}): samples dropped",
                r.backend
            );
        }
    }
    if out.len() == 2 {
        assert_backends_agree(test, &out[0].render, &out[1].render, max_flipped);
    }
    out
}

/// The CPU and the GPU trace the same paths with the same random numbers; their images differ
/// by float rounding (the GPU may fuse multiply-adds: a few units in the last place, 1e-4
/// relative is far above that), except where rounding sends a ray to the other side of an
/// edge and the path changes: at most `max_flipped` pixels, justified by each caller.
pub fn assert_backends_agree(test: &str, cpu: &Render, gpu: &Render, max_flipped: usize) {
    let mean = mean(&cpu.pixels).iter().sum::<f64>() as f32 / 3.0;
    let flipped: Vec<usize> = (0..cpu.pixels.len())
        .filter(|&i| {
            let (c, g) = (Vec3::from(cpu.pixels[i]), Vec3::from(gpu.pixels[i]));
            (c - g).abs().max_element() > 1e-4 * (c.max_element().max(g.max_element()) + mean)
        })
        .collect();
    eprintln!(
        "{test}: CPU and GPU differ in {} pixels ({max_flipped} allowed)",
        flipped.len()
    );
    assert!(
        flipped.len() <= max_flipped,
        "{test}: CPU and GPU differ in {} pixels (at most {max_flipped} allowed), e.g. {:?}",
        flipped.len(),
        flipped
            .iter()
            .take(4)
            .map(|&i| (i, cpu.pixels[i], gpu.pixels[i]))
            .collect::<Vec<_>>()
    );
    if max_flipped == 0 {
        assert_eq!(
            cpu.stats.rays_traced, gpu.stats.rays_traced,
            "{test}: the same paths, ray for ray"
        );
    }
}

/// Per-channel mean.
pub fn mean(img: &[[f32; 3]]) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for p in img {
        for c in 0..3 {
            m[c] += f64::from(p[c]);
        }
    }
    m.map(|x| x / img.len() as f64)
}

/// Asserts that every pixel of every render is `expected` within `rel` (relative to its
/// largest component).
pub fn assert_every_pixel(test: &str, renders: &[Rendered], expected: Vec3, rel: f32) {
    for r in renders {
        for (i, p) in r.pixels().iter().enumerate() {
            let d = (Vec3::from(*p) - expected).abs().max_element();
            assert!(
                d <= rel * expected.max_element(),
                "{test} ({}): pixel {i} is {p:?}, expected {expected}",
                r.backend
            );
        }
    }
}

/// Asserts that no path ended before its last bounce: `pixels * spp * (max_bounces + 1)` rays.
pub fn assert_full_paths(test: &str, renders: &[Rendered], scene: &Scene) {
    let r = scene.render;
    let full = u64::from(r.width * r.height * r.spp) * u64::from(r.max_bounces + 1);
    for x in renders {
        assert_eq!(
            x.render.stats.rays_traced,
            full,
            "{test} ({}): {} paths' worth of rays missing (escaped or ended early)",
            x.backend,
            (full - x.render.stats.rays_traced.min(full)) as f64 / f64::from(r.max_bounces + 1)
        );
    }
}
