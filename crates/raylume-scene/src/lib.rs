//! Scenes for raylume: the model, its loaders (TOML, OBJ, glTF, Tungsten `scene.json`),
//! validation, and [`Scene::features`], the set of effects a scene calls for.
//!
//! **Architecture invariant:** this crate knows nothing about GPUs, BVHs or rays.

pub mod features;
pub mod model;

pub use features::{Feature, Features};
pub use model::{
    Bloom, Bounds, Camera, Environment, Material, MaterialKind, PostSettings, RenderSettings,
    Scene, Sphere, Texture, Triangle,
};
