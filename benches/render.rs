//! End-to-end criterion benches: a whole render (`Tracer::render`: BVH from the tracer's
//! cache, upload, pipelines from its cache, batches, read-back) of each of the project's scenes
//! at a small size, per backend and estimator, so that a regression anywhere in the pipeline
//! shows as a number. The paper's Table 1 at full size is `examples/bench.rs`; these are the
//! quick, always-runnable kind.
//!
//! ```text
//! cargo bench -p raylume --bench render                  # every scene, CPU and GPU
//! RAYLUME_BENCH_QUICK=1 cargo bench -p raylume --bench render   # CI-sized: 32x32, 2 spp
//! ```
//!
//! Without a GPU adapter the GPU cases are left out, saying so; on lavapipe they run (slowly:
//! use the quick form there).

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use raylume::{Backend, Estimator, Scene, Tracer};

fn quick() -> bool {
    std::env::var("RAYLUME_BENCH_QUICK").is_ok_and(|v| v == "1")
}

/// The scenes, loaded once, at the bench's size.
fn scenes() -> Vec<(String, Scene)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let (size, spp, bounces) = if quick() { (32, 2, 4) } else { (128, 8, 10) };
    let files: &[&str] = if quick() {
        &["cornell-box.toml", "spheres.toml"]
    } else {
        &[
            "cornell-box.toml",
            "cornell-plus.toml",
            "spheres.toml",
            "teapot.toml",
            "glass-teapot.toml",
            "living-room/scene.json",
        ]
    };
    files
        .iter()
        .map(|f| {
            let mut scene =
                Scene::load(root.join(f)).unwrap_or_else(|e| panic!("loading {f}: {e}"));
            scene.render.width = size;
            scene.render.height = size;
            scene.render.spp = spp;
            scene.render.max_bounces = bounces;
            (
                f.trim_end_matches(".toml").replace("/scene.json", ""),
                scene,
            )
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let scenes = scenes();
    for backend in [Backend::Cpu, Backend::Gpu] {
        for estimator in [Estimator::Nee, Estimator::Plain] {
            let mut tracer = Tracer::new(backend);
            tracer.estimator = estimator;
            if let Err(e) = tracer.prepare_backend() {
                eprintln!("render bench: {backend:?} left out: {e}");
                break;
            }
            let mut group = c.benchmark_group(format!(
                "render/{}/{}",
                format!("{backend:?}").to_lowercase(),
                estimator.name()
            ));
            group.sample_size(10);
            group.warm_up_time(Duration::from_millis(if quick() { 200 } else { 1000 }));
            group.measurement_time(Duration::from_secs(if quick() { 1 } else { 5 }));
            for (name, scene) in &scenes {
                group.bench_function(name.as_str(), |b| {
                    b.iter(|| tracer.render(scene).expect("the scene renders"))
                });
            }
            group.finish();
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
