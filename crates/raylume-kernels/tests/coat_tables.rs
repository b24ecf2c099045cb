//! The rough plastics' coat tables asked for by several threads at once (as a render does:
//! one thread as soon as the scene is loaded, another beside the BVH build, the scene's
//! preparation a third time): every call returns.
//!
//! An earlier cache computed each table inside `OnceLock::get_or_init` within a parallel
//! iterator; a rayon worker waiting in a nested join could steal a job that waited on the
//! table its own stack was computing, and the process hung (seen on two cores). This test
//! hung with it (checked by putting it back): it runs the calls on threads of their own and
//! fails after a timeout instead of hanging.

use std::sync::mpsc;
use std::time::Duration;

use glam::Vec3;
use raylume_kernels::scene_data::prepare_plastic_tables_for;
use raylume_scene::Material;

#[test]
fn concurrent_requests_for_the_same_tables_all_return() {
    // Fresh keys each round (the cache lives as long as the process).
    for round in 0..6 {
        let materials: Vec<Material> = (0..3)
            .map(|i| {
                let roughness = 0.05 + 0.01 * (round * 3 + i) as f32;
                Material::plastic("coat", Vec3::splat(0.5), 1.5, roughness)
            })
            .collect();
        let (done, finished) = mpsc::channel();
        for _ in 0..3 {
            let (materials, done) = (materials.clone(), done.clone());
            std::thread::spawn(move || {
                prepare_plastic_tables_for(&materials);
                done.send(()).ok();
            });
        }
        for caller in 0..3 {
            finished
                .recv_timeout(Duration::from_secs(120))
                .unwrap_or_else(|_| panic!("round {round}: caller {caller} of 3 never returned"));
        }
    }
}
