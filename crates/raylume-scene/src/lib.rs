//! Scenes for raylume: the model, its loaders (TOML, OBJ, glTF, Tungsten `scene.json`),
//! validation, and [`Scene::features`], the set of effects a scene calls for.
//!
//! **Architecture invariant:** this crate knows nothing about GPUs, BVHs or rays.
//!
//! # Entry points
//! - [`Scene::load`]: by extension — `.toml` (raylume's format, `docs/SCENE_FORMAT.md`), `.obj`
//!   (+ `.mtl`), `.gltf` / `.glb`, `.json` (Tungsten). Paths inside a file are relative to it.
//! - [`Scene::from_toml_str`]: a TOML scene held in memory.
//! - [`Scene::validate`]: the checks every loader runs before returning.
//!
//! Every failure is a [`SceneError`] naming the file and the place (`scene.toml:12:5`,
//! `scene.json: primitives[3].transform`, `model.glb: nodes[2] mesh 0 primitive 1 accessor 4`,
//! `scene.toml: triangle 7 of meshes/a.obj`). What a loader had to approximate or drop is in
//! [`Scene::warnings`], never silent.
//!
//! ```
//! use raylume_scene::{MaterialKind, Scene};
//!
//! let text = r#"
//!     [camera]
//!     position = [0.0, 1.0, 5.0]
//!     look_at = [0.0, 1.0, 0.0]
//!     vfov = 40.0
//!
//!     [materials.white]
//!     type = "diffuse"
//!     albedo = [0.7, 0.7, 0.7]
//!
//!     [materials.lamp]
//!     type = "diffuse"
//!     emission = [4.0, 4.0, 4.0]
//!
//!     [[sphere]]
//!     center = [0.0, 1.0, 0.0]
//!     radius = 0.5
//!     material = "white"
//!
//!     [[quad]]
//!     corner = [-0.5, 2.0, -0.5]
//!     u = [1.0, 0.0, 0.0]
//!     v = [0.0, 0.0, 1.0]
//!     material = "lamp"
//! "#;
//! let scene = Scene::from_toml_str(text, std::path::Path::new("."), "inline.toml")?;
//! assert_eq!(scene.spheres.len(), 1);
//! assert_eq!(scene.triangles.len(), 2);
//! assert_eq!(scene.materials[0].kind, MaterialKind::Diffuse);
//! assert_eq!(scene.features().names(), ["diffuse", "emission", "spheres", "triangles"]);
//!
//! // A typo is an error with file, line and column.
//! let err = Scene::from_toml_str("[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfv = 40\n",
//!     std::path::Path::new("."), "typo.toml").unwrap_err();
//! assert!(err.to_string().starts_with("typo.toml:4:1: unknown key `vfv`"), "{err}");
//! # Ok::<(), raylume_scene::SceneError>(())
//! ```
//!
//! # Material mappings
//!
//! | source | raylume diffuse | raylume metal | raylume glass |
//! | --- | --- | --- | --- |
//! | TOML | `type = "diffuse"` | `type = "metal"` | `type = "glass"` |
//! | MTL | otherwise (`Kd`) | `Ks > 0` and (`illum 3` or `max Ks > max Kd`); roughness `(2/(Ns+2))^(1/4)` | `illum` 4/6/7, or `Ni` with `d < 1` |
//! | glTF | `metallicFactor < 0.5` | `metallicFactor >= 0.5` (roughness as is) | transmission > 0.5 (`KHR_materials_ior`) |
//! | Tungsten | `lambert`; approx.: `oren_nayar`, `plastic`, `rough_plastic`, `phong`, `null` (black) | `mirror`; approx.: `conductor`, `rough_conductor` (RGB F0 table) | `dielectric`; approx.: `rough_dielectric`, `thinsheet` |
//!
//! Emission: TOML `emission`, MTL `Ke`, glTF `emissiveFactor` x
//! `KHR_materials_emissive_strength`, Tungsten `emission` / `power` on primitives. Albedo
//! textures: TOML `texture`, MTL `map_Kd`, glTF `baseColorTexture`, Tungsten `albedo` as a
//! path. Texture coordinates put (0, 0) at the top-left texel (glTF's convention; OBJ's v is
//! flipped on load). Details in the `obj`, `gltf` and `tungsten` module docs.
//!
//! A bare mesh file loads as a scene: its own materials, the glTF camera if it has one, else a
//! camera on +z looking down -z at the bounding box (vfov 40 degrees, the bounding sphere
//! fitting the view), a black environment, [`RenderSettings::default`].

pub mod conductors;
pub mod error;
pub mod features;
pub mod grid;
pub mod limits;
pub mod model;

mod builder;
mod gltf;
mod image_io;
mod obj;
mod toml;
pub mod transform;
mod tungsten;
mod validate;

use std::path::Path;

pub use conductors::{CONDUCTORS, ConductorIor, conductor_ior, conductor_names};
pub use error::{Location, SceneError};
pub use features::{Feature, Features};
pub use model::{
    Bloom, Bounds, Camera, Environment, FovAxis, Material, MaterialKind, PostSettings,
    RenderSettings, Scene, Sphere, Texels, Texture, Triangle, srgb8_table,
};

use builder::{MeshOptions, SceneBuilder};

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// Loads a mesh file (OBJ or glTF) into a scene under construction.
pub(crate) fn load_mesh_into(
    b: &mut SceneBuilder,
    path: &Path,
    opts: &MeshOptions,
) -> Result<Option<gltf::GltfCamera>, SceneError> {
    match extension(path).as_deref() {
        Some("obj") => obj::load_into(b, path, opts).map(|()| None),
        Some("gltf" | "glb") => gltf::load_into(b, path, opts),
        _ => Err(SceneError::UnsupportedExtension {
            path: path.to_path_buf(),
            referenced_by: opts.referenced_by.clone(),
            expected: ".obj, .gltf or .glb",
        }),
    }
}

impl Scene {
    /// Loads a scene file, by extension: `.toml`, `.obj`, `.gltf`, `.glb`, `.json` (Tungsten);
    /// a folder holding a `scene.json` is that Tungsten scene (as Tungsten and Bitterli's
    /// scene archives lay them out). The result is validated; see [`Scene::warnings`] for
    /// what had to be approximated.
    ///
    /// OBJ files of 16 MiB and more (the file itself or one a scene references) are mapped
    /// into memory while they are parsed, not read: no other process may change or truncate
    /// them during the load.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        Self::load_with(path, |_| {})
    }

    /// [`Scene::load`], calling `geometry_ready` with the scene as soon as everything but its
    /// textures' texels is final (triangles, spheres, materials, camera, settings: sanitised,
    /// degenerate triangles dropped), while image files may still decode on other threads:
    /// the caller can start work on the geometry then (raylume's `Tracer::prepare_geometry`
    /// builds the BVH beside the living room's 0.06-0.15 s progressive JPEG). The scene's
    /// textures may be empty placeholders then; what the hook changes in the scene is kept
    /// and validated with the rest. Tungsten files overlap this way; for the other formats the
    /// hook runs once the scene is loaded, before it is returned. Not called when loading
    /// fails first; the errors are `load`'s.
    pub fn load_with(
        path: impl AsRef<Path>,
        geometry_ready: impl FnOnce(&mut Scene),
    ) -> Result<Scene, SceneError> {
        let mut hook = Some(geometry_ready);
        let mut once = |s: &mut Scene| {
            if let Some(f) = hook.take() {
                f(s);
            }
        };
        let path = path.as_ref();
        let mut scene = Self::load_calling(path, &mut once)?;
        // The formats that do not call it on the way.
        once(&mut scene);
        Ok(scene)
    }

    /// [`Scene::load_with`]'s loading: the loaders that can call `geometry_ready` before
    /// their textures are in do.
    fn load_calling(
        path: &Path,
        geometry_ready: &mut dyn FnMut(&mut Scene),
    ) -> Result<Scene, SceneError> {
        if path.is_dir() {
            let scene = path.join("scene.json");
            if !scene.is_file() {
                return Err(SceneError::Folder {
                    path: path.to_path_buf(),
                });
            }
            return tungsten::load_with(&scene, geometry_ready);
        }
        match extension(path).as_deref() {
            Some("toml") => {
                let bytes = builder::read_description(path, None)?;
                let label = path.display().to_string();
                let text = String::from_utf8(bytes).map_err(|e| SceneError::Syntax {
                    file: label.clone(),
                    at: Location::Line(builder::line_of_offset(
                        e.as_bytes(),
                        e.utf8_error().valid_up_to(),
                    )),
                    message: "not valid UTF-8".into(),
                })?;
                let dir = path.parent().unwrap_or(Path::new(""));
                toml::parse(&text, dir, &label)
            }
            Some("json") => tungsten::load_with(path, geometry_ready),
            Some("obj" | "gltf" | "glb") => {
                let label = path.display().to_string();
                let mut b = SceneBuilder::new(&label);
                let camera = load_mesh_into(&mut b, path, &MeshOptions::bare())?;
                match camera {
                    Some(c) => {
                        b.scene.camera = c.camera;
                        if let Some(aspect) = c.aspect.filter(|a| a.is_finite() && *a > 0.0) {
                            let h = b.scene.render.height as f32;
                            b.scene.render.width =
                                ((h * aspect).round() as u32).clamp(1, limits::MAX_IMAGE_SIZE);
                        }
                    }
                    None => b.scene.camera = transform::frame_bounds(b.scene.bounds()),
                }
                b.finish()
            }
            _ => Err(SceneError::UnsupportedExtension {
                path: path.to_path_buf(),
                referenced_by: None,
                expected: ".toml, .obj, .gltf, .glb or .json (Tungsten)",
            }),
        }
    }

    /// Parses a TOML scene held in memory. `base_dir`: where the paths in it start;
    /// `file_label`: the name used in messages.
    pub fn from_toml_str(
        text: &str,
        base_dir: &Path,
        file_label: &str,
    ) -> Result<Scene, SceneError> {
        toml::parse(text, base_dir, file_label)
    }
}
