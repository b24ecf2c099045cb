//! BVH build time (Fast vs Quality) and CPU traversal rate (closest hit, one thread and a
//! rayon pool of two) on the project's real scenes, `scenes/teapot.toml` (123,554 triangles)
//! and `scenes/living-room/scene.json` (142,973); a level-6 icosphere (81,920 triangles)
//! stands in when neither is there.
//!
//! Rays: 256 x 256 camera rays through the scene's own camera ("primary"), and from each
//! primary hit one ray in a uniformly random direction ("secondary", incoherent like diffuse
//! bounces). Run: `cargo bench -p raylume-bvh` (add `-- --quick` for a short run).
//!
//! With `RAYLUME_BVH_PRESETS=1` it first prints, per scene, build time, SAH cost and
//! single-threaded primary/secondary trace rates for four obvhs presets (`very_fast_build`,
//! `fast_build`, `slow_build`, `very_slow_build`): the measurement behind [`BvhQuality`]'s
//! choice of presets.

#[path = "../tests/support/mod.rs"]
mod support;

use std::path::PathBuf;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use raylume_bvh::{BvhLayout, BvhQuality, GpuBvh, Ray};
use raylume_scene::{Camera, FovAxis, Scene, Sphere, Triangle};
use rayon::prelude::*;

const QUALITIES: [BvhQuality; 2] = [BvhQuality::Fast, BvhQuality::Quality];
const IMAGE: u32 = 256;

struct BenchScene {
    name: &'static str,
    triangles: Vec<Triangle>,
    spheres: Vec<Sphere>,
    camera: Camera,
}

fn scenes() -> Vec<BenchScene> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut out = Vec::new();
    for (name, file) in [
        ("teapot", "teapot.toml"),
        ("living_room", "living-room/scene.json"),
    ] {
        let path = dir.join(file);
        match Scene::load(&path) {
            Ok(s) => out.push(BenchScene {
                name,
                triangles: s.triangles,
                spheres: s.spheres,
                camera: s.camera,
            }),
            Err(e) => eprintln!("SKIPPED {name}: {} does not load: {e}", path.display()),
        }
    }
    if out.is_empty() {
        eprintln!(
            "no scene in {} loads; benchmarking an icosphere",
            dir.display()
        );
        out.push(BenchScene {
            name: "icosphere_81920",
            triangles: support::icosphere(6, Vec3::ZERO, 1.0),
            spheres: Vec::new(),
            camera: Camera {
                position: Vec3::new(0.0, 0.5, 3.0),
                look_at: Vec3::ZERO,
                up: Vec3::Y,
                fov: 45.0,
                fov_axis: FovAxis::Vertical,
            },
        });
    }
    out
}

/// `IMAGE x IMAGE` pinhole camera rays through pixel centres.
fn camera_rays(c: &Camera) -> Vec<Ray> {
    let forward = (c.look_at - c.position).normalize();
    let right = forward.cross(c.up).normalize();
    let up = right.cross(forward);
    let tan = (c.fov.to_radians() / 2.0).tan(); // square images: either axis
    let mut rays = Vec::with_capacity((IMAGE * IMAGE) as usize);
    for j in 0..IMAGE {
        for i in 0..IMAGE {
            let u = (2.0 * (i as f32 + 0.5) / IMAGE as f32 - 1.0) * tan;
            let v = (1.0 - 2.0 * (j as f32 + 0.5) / IMAGE as f32) * tan;
            rays.push(Ray::new(
                c.position,
                (forward + right * u + up * v).normalize(),
            ));
        }
    }
    rays
}

/// One random-direction ray from every primary hit.
fn secondary_rays(bvh: &GpuBvh, primary: &[Ray], seed: u64) -> Vec<Ray> {
    let mut rng = support::Rng::new(seed);
    primary
        .iter()
        .filter_map(|r| bvh.trace_closest(r, 0.0, f32::INFINITY).map(|h| (r, h)))
        .map(|(r, h)| Ray::new(r.origin + r.dir * h.t, rng.direction()))
        .collect()
}

/// Rays per second of closest-hit traversal over `rays`, single-threaded, best of 3.
fn rate(bvh: &GpuBvh, rays: &[Ray], t_min: f32) -> f64 {
    (0..3)
        .map(|_| {
            let start = std::time::Instant::now();
            let hits = rays
                .iter()
                .filter(|r| bvh.trace_closest(r, t_min, f32::INFINITY).is_some())
                .count();
            std::hint::black_box(hits);
            rays.len() as f64 / start.elapsed().as_secs_f64()
        })
        .fold(0.0, f64::max)
}

/// The preset comparison behind `BvhQuality` (see the crate docs above).
fn compare_presets(s: &BenchScene, primary: &[Ray]) {
    use obvhs::BvhBuildParams as P;
    for (name, params) in [
        ("very_fast_build", P::very_fast_build()),
        ("fast_build", P::fast_build()),
        ("slow_build", P::slow_build()),
        ("very_slow_build", P::very_slow_build()),
    ] {
        let build = |_| {
            GpuBvh::build_with_params(&s.triangles, &s.spheres, BvhQuality::Fast, params).unwrap()
        };
        let builds: Vec<GpuBvh> = (0..3).map(build).collect();
        let best = builds.iter().map(|b| b.stats.build_time).min().unwrap();
        let bvh = &builds[0];
        let secondary = secondary_rays(bvh, primary, 7);
        eprintln!(
            "preset {} {name}: build {:.1} ms, SAH {:.2}, {} refs, depth {}, primary {:.2} Mrays/s, \
             secondary {:.2} Mrays/s (1 thread)",
            s.name,
            best.as_secs_f64() * 1e3,
            bvh.stats.sah_cost,
            bvh.stats.primitive_refs,
            bvh.stats.max_depth,
            rate(bvh, primary, 0.0) / 1e6,
            rate(bvh, &secondary, 1e-4) / 1e6,
        );
    }
}

fn bench(c: &mut Criterion) {
    if std::env::var("RAYLUME_BVH_PRESETS").is_ok_and(|v| v == "1") {
        for s in scenes() {
            compare_presets(&s, &camera_rays(&s.camera));
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a rayon pool");
    for s in scenes() {
        let mut group = c.benchmark_group(format!("build/{}", s.name));
        group.sample_size(10);
        group.measurement_time(Duration::from_secs(8));
        group.throughput(Throughput::Elements(
            (s.triangles.len() + s.spheres.len()) as u64,
        ));
        for q in QUALITIES {
            group.bench_function(q.name(), |b| {
                b.iter(|| GpuBvh::build(&s.triangles, &s.spheres, q).unwrap())
            });
        }
        group.finish();

        let primary = camera_rays(&s.camera);
        for (q, layout) in QUALITIES
            .into_iter()
            .flat_map(|q| [(q, BvhLayout::Binary), (q, BvhLayout::Wide)])
        {
            let bvh = GpuBvh::build_with_layout(&s.triangles, &s.spheres, q, layout).unwrap();
            let st = bvh.stats;
            eprintln!(
                "{} {} {}: {} primitives -> {} refs, {} nodes, {} leaves, depth {}, max leaf {}, \
                 SAH {:.2}, built in {:.1} ms",
                s.name,
                q.name(),
                layout.name(),
                s.triangles.len() + s.spheres.len(),
                st.primitive_refs,
                st.node_count,
                st.leaf_count,
                st.max_depth,
                st.max_leaf_size,
                st.sah_cost,
                st.build_time.as_secs_f64() * 1e3
            );
            let secondary = secondary_rays(&bvh, &primary, 7);
            let mut group = c.benchmark_group(format!(
                "trace_closest/{}/{}/{}",
                s.name,
                q.name(),
                layout.name()
            ));
            group.sample_size(10);
            group.measurement_time(Duration::from_secs(5));
            for (kind, rays, t_min) in [("primary", &primary, 0.0), ("secondary", &secondary, 1e-4)]
            {
                group.throughput(Throughput::Elements(rays.len() as u64));
                group.bench_with_input(BenchmarkId::new(kind, "1_thread"), rays, |b, rays| {
                    b.iter(|| {
                        rays.iter()
                            .filter(|r| bvh.trace_closest(r, t_min, f32::INFINITY).is_some())
                            .count()
                    })
                });
                group.bench_with_input(BenchmarkId::new(kind, "rayon_2"), rays, |b, rays| {
                    b.iter(|| {
                        pool.install(|| {
                            rays.par_iter()
                                .filter(|r| bvh.trace_closest(r, t_min, f32::INFINITY).is_some())
                                .count()
                        })
                    })
                });
            }
            group.finish();
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
