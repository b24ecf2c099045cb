//! The scene prepared for tracing, kept between renders of the same scene.
//!
//! Before its first batch a render prepares its scene beside the BVH: the material table, the
//! primitives' materials and shading data, the textures, the light list, the rough plastics'
//! coat tables and the environment guide's walks (`raylume_kernels::SceneData`), then, on
//! the GPU, uploads it all (`raylume_kernels::GpuScene`). On the living room that is a tenth
//! of a second, as long as 40 samples per pixel of a 500x500 image on the H200: a user
//! rendering one scene many times (other spp, sizes, seeds; a benchmark's repeats; a study's
//! error-versus-time curve) should pay it once, as Mitsuba 3 does when its scene is loaded.
//!
//! What was prepared is kept with the BVH it was prepared for (`BvhCacheEntry`; the last
//! two scenes per tree), each under a [`SceneKey`]: a hash of everything the preparation reads of the scene besides the
//! geometry the BVH's key already covers, and the options. A render whose key differs
//! prepares again; the test `tests/tracer.rs::prepared_scene_is_reused_only_for_the_same_scene`
//! changes each of those inputs in turn.

use std::hash::{Hash, Hasher};
use std::sync::Arc;

use rayon::prelude::*;

use raylume_kernels::scene_data::SceneData;
use raylume_kernels::{GpuScene, SceneOptions};
use raylume_scene::{Environment, Scene, Texels};

/// The last scenes prepared over one BVH (at most [`PREPARED_ENTRIES`], the latest first).
#[derive(Default)]
pub(crate) struct Prepared {
    scenes: Vec<PreparedScene>,
}

/// Scenes kept per BVH: two, so that a study or benchmark alternating a preparation option
/// (the environment guide on and off) or two materials prepares each once.
const PREPARED_ENTRIES: usize = 2;

/// What a render prepared for one scene, per backend.
pub(crate) struct PreparedScene {
    pub(crate) key: SceneKey,
    /// The CPU backend's data (texels included).
    pub(crate) cpu: Option<Arc<SceneData>>,
    /// The GPU backend's upload (to the tracer's one context; dropped with it).
    pub(crate) gpu: Option<Arc<GpuScene>>,
    /// Data `Tracer::prepare_scene` prepared for a GPU render still to come (before the
    /// device was open), and the seconds it took: the render uploads it (moved, not copied).
    pub(crate) ahead: Option<(SceneData, f64)>,
}

impl Prepared {
    /// The preparation of `key`'s scene, moved to the front; a new, empty one (the oldest
    /// dropped) when there is none.
    pub(crate) fn of(&mut self, key: SceneKey) -> &mut PreparedScene {
        let entry = match self.scenes.iter().position(|s| s.key == key) {
            Some(i) => self.scenes.remove(i),
            None => PreparedScene {
                key,
                cpu: None,
                gpu: None,
                ahead: None,
            },
        };
        self.scenes.insert(0, entry);
        self.scenes.truncate(PREPARED_ENTRIES);
        &mut self.scenes[0]
    }

    /// Forgets the GPU uploads (their device is gone).
    pub(crate) fn forget_gpu(&mut self) {
        for s in &mut self.scenes {
            s.gpu = None;
        }
    }
}

/// What `SceneData::with_options` reads of a scene, except the triangles' positions and the
/// spheres' centres and radii (the BVH's `GeometryKey`): the camera (the environment guide's
/// walks start there), the materials, the textures' texels, the environment (a map's texels
/// too), each triangle's material, normals and uvs, each sphere's material; and the options.
/// Render settings (size, spp, bounces, seed) are not read by it, so renders that differ only
/// in them share one preparation.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) struct SceneKey {
    hash: u64,
    options: SceneOptions,
}

/// FxHash's multiply-rotate step over 32-bit words (as `GeometryKey`).
fn step(h: u64, w: u32) -> u64 {
    (h.rotate_left(5) ^ u64::from(w)).wrapping_mul(0x517c_c1b7_2722_0a95)
}

const SEED: u64 = 0x243f_6a88_85a3_08d3;

/// The hash of `words`, on every core in runs of 65,536 values.
fn hash_words<T: Sync>(items: &[T], words: impl Fn(&T, &mut dyn FnMut(u32)) + Sync) -> u64 {
    let runs: Vec<u64> = items
        .par_chunks(1 << 16)
        .map(|run| {
            let mut h = SEED;
            for item in run {
                words(item, &mut |w| h = step(h, w));
            }
            h
        })
        .collect();
    runs.into_iter()
        .fold(step(SEED, items.len() as u32), |h, r| {
            step(step(h, r as u32), (r >> 32) as u32)
        })
}

fn texels_hash(texels: &Texels) -> u64 {
    match texels {
        Texels::Linear(t) => hash_words(t, |t, eat| t.iter().for_each(|c| eat(c.to_bits()))),
        // The format is part of the hash: a code and a float of the same bits differ.
        Texels::Srgb8(t) => step(
            hash_words(t, |t, eat| eat(u32::from_le_bytes([t[0], t[1], t[2], 0]))),
            1,
        ),
    }
}

impl SceneKey {
    pub(crate) fn of(scene: &Scene, options: SceneOptions) -> Self {
        // The small parts through their `Debug` text (every field, including any added
        // later), the large ones word by word.
        let mut small = std::collections::hash_map::DefaultHasher::new();
        format!("{:?}", scene.camera).hash(&mut small);
        format!("{:?}", scene.materials).hash(&mut small);
        let mut h = step(SEED, small.finish() as u32);
        h = step(h, (small.finish() >> 32) as u32);
        let mut eat64 = |v: u64| h = step(step(h, v as u32), (v >> 32) as u32);
        for t in &scene.textures {
            let mut s = std::collections::hash_map::DefaultHasher::new();
            (&t.name, t.width, t.height).hash(&mut s);
            eat64(s.finish());
            eat64(texels_hash(&t.texels));
        }
        match &scene.environment {
            Environment::Map {
                image,
                strength,
                rotation,
            } => {
                let mut s = std::collections::hash_map::DefaultHasher::new();
                (&image.name, image.width, image.height).hash(&mut s);
                (strength.to_bits(), rotation.to_bits()).hash(&mut s);
                eat64(s.finish());
                eat64(texels_hash(&image.texels));
            }
            other => {
                let mut s = std::collections::hash_map::DefaultHasher::new();
                format!("{other:?}").hash(&mut s);
                eat64(s.finish());
            }
        }
        eat64(hash_words(&scene.triangles, |t, eat| {
            eat(t.material);
            match t.normals {
                Some(n) => {
                    for c in n.iter().flat_map(|v| v.to_array()) {
                        eat(c.to_bits());
                    }
                }
                None => eat(0xffff_fff1),
            }
            match t.uvs {
                Some(uv) => {
                    for c in uv.iter().flat_map(|v| v.to_array()) {
                        eat(c.to_bits());
                    }
                }
                None => eat(0xffff_fff2),
            }
        }));
        eat64(hash_words(&scene.spheres, |s, eat| eat(s.material)));
        Self { hash: h, options }
    }
}
