//! Tungsten `scene.json` (Benedikt Bitterli's renderer; the format of his "Rendering
//! resources").
//!
//! Conventions, read from Tungsten's source (`src/core/io/JsonPtr.cpp`,
//! `src/core/math/Mat4f.cpp`, `src/core/primitives/{Quad,Cube,Sphere}.cpp`,
//! `src/core/cameras/PinholeCamera.cpp`):
//! - A transform object is `T * R * S`: `scale` (number or vector) scales the axes, then
//!   `rotation` (degrees) applies `Mat4f::rotYXZ`, which is `Ry(-y) * Rx(x) * Rz(z)` (Z first,
//!   and Tungsten's Y angle turns the other way from the right-hand rule), then `position`
//!   translates. A 16-number array is a row-major matrix.
//! - `quad` is the unit square in the xz plane, centred at the origin, corners (+-0.5, 0, +-0.5);
//!   its front (emitting) side is `edge1 x edge0 = z x x = +y` before transforming. raylume's
//!   triangles are wound so that `(p1 - p0) x (p2 - p0)` points to that front side.
//! - `cube` is the unit cube [-0.5, 0.5]^3 with outward faces, triangulated as Tungsten's
//!   `TriangleMesh::makeCube`; `sphere` has radius = the
//!   largest axis scale, centre = the position.
//! - `mesh` loads an OBJ with the primitive's `bsdf` (the OBJ's materials are not used);
//!   `smooth: false` (the default) means flat shading, so the file's normals are dropped.
//! - The pinhole `fov` is horizontal: the image plane spans x in [-1, 1] and
//!   y in [-h/w, h/w] at distance 1/tan(fov/2), whatever the image size: the camera keeps
//!   [`FovAxis::Horizontal`](crate::FovAxis), so a render at another aspect shows the same
//!   width of the scene (as Mitsuba's `fov_axis = "x"`).
//! - `power` on an emitter becomes radiance = power / (area * pi). Emitters emit from their
//!   front side only (Tungsten's `Quad::evalDirect` and `TriangleMesh::evalDirect` are 0 behind).
//! - `infinite_sphere` and `skydome` primitives, and the top-level `emissions` list (the
//!   111116/toyray-scenes variant, `{"type": "envmap", "radiance": "sky.exr"}`), become the
//!   environment (a map gets [`TUNGSTEN_ENV_ROTATION`] so that it is oriented as in Tungsten).
//!   A missing map file is an error. `skydome` (a procedural sky) becomes a
//!   constant environment of its `intensity`, with a warning.
//! - Render settings: `camera.resolution`, `renderer.spp`, `integrator.max_bounces` are
//!   taken as they are.
//!
//! BSDFs are mapped by [`bsdf`]; keys this importer does not read are listed in a warning.

mod bsdf;
mod geometry;
mod json;
mod primitive;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde_json::Value;

use crate::builder::{SceneBuilder, read_description};
use crate::error::{Location, SceneError};
use crate::model::Scene;
use json::{J, Owned};

/// Rotation (degrees about +y) that makes raylume's equirectangular lookup (`raylume-kernels`:
/// `u = 0.5 + atan2(d.x, -d.z) / 2 pi + rotation / 360`) read the texel Tungsten's
/// `InfiniteSphere` reads (`u = 0.5 + atan2(d.z, d.x) / 2 pi`): the two angles differ by a
/// quarter turn, `atan2(x, -z) = atan2(z, x) + pi / 2`. Both put the top row at +y.
pub(crate) const TUNGSTEN_ENV_ROTATION: f32 = -90.0;

/// The document being imported.
pub(crate) struct Tungsten<'a> {
    file: &'a str,
    dir: PathBuf,
    bsdfs: &'a [Value],
    bsdf_names: HashMap<&'a str, usize>,
}

/// Loads a Tungsten `scene.json`, calling `geometry_ready` as [`SceneBuilder::finish_with`]
/// does: with the geometry final while the image files may still decode.
pub(crate) fn load_with(
    path: &Path,
    geometry_ready: &mut dyn FnMut(&mut Scene),
) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = read_description(path, None)?;
    let doc: Value = serde_json::from_slice(&bytes).map_err(|e| SceneError::Syntax {
        file: file.clone(),
        at: Location::LineCol {
            line: e.line(),
            column: e.column(),
        },
        message: e.to_string(),
    })?;
    let root = J {
        v: &doc,
        path: "",
        file: &file,
    };
    root.object()?;
    let no_bsdfs = Vec::new();
    let bsdfs: &[Value] = match doc.get("bsdfs") {
        Some(v) => v.as_array().ok_or_else(|| {
            J {
                v,
                path: "bsdfs",
                file: &file,
            }
            .wrong("an array")
        })?,
        None => &no_bsdfs,
    };
    let mut bsdf_names = HashMap::new();
    for (i, v) in bsdfs.iter().enumerate() {
        let path = format!("bsdfs[{i}]");
        let j = J {
            v,
            path: &path,
            file: &file,
        };
        let name = j.key("name").ok_or_else(|| SceneError::MissingKey {
            file: file.clone(),
            at: j.at(),
            key: "name".into(),
        })?;
        let n = name.j().str()?;
        if bsdf_names.insert(n, i).is_some() {
            return Err(name.j().invalid(format!("a second BSDF named '{n}'")));
        }
    }
    let t = Tungsten {
        file: &file,
        dir: path.parent().unwrap_or(Path::new("")).to_path_buf(),
        bsdfs,
        bsdf_names,
    };
    let mut b = SceneBuilder::new(&file);
    b.scene.render = crate::model::RenderSettings::default();
    let mut ignored = Vec::new();

    if let Some(r) = root.key("renderer")
        && let Some(spp) = r.j().key("spp")
    {
        b.scene.render.spp = whole(spp.j())?;
    }
    if let Some(i) = root.key("integrator")
        && let Some(mb) = i.j().key("max_bounces")
    {
        b.scene.render.max_bounces = whole(mb.j())?;
    }
    let mut have_camera = false;
    if let Some(c) = root.key("camera") {
        t.camera(&mut b, c.j())?;
        have_camera = true;
    }
    if let Some(m) = root.key("media")
        && m.v.as_array().is_some_and(|a| !a.is_empty())
    {
        ignored.push("media (participating media)".to_string());
    }
    let mut materials = HashMap::new();
    if let Some(prims) = root.key("primitives") {
        let list = prims.j().array()?;
        // The meshes' OBJ files are read and parsed on every core first (the living room's 65
        // files took 0.46 s on one core of the H200's host), then added in order: the same
        // scene, and the same first error, as one by one.
        let files: Vec<Option<(PathBuf, String)>> = (0..list.len())
            .map(|i| {
                let p: Owned = prims.j().index(i).expect("index within the array");
                t.mesh_file(p.j())
            })
            .collect();
        // The BSDFs' image files decode on a thread of their own while the meshes parse and
        // are added (the living room's progressive JPEG alone takes longer than its meshes
        // on 16 cores).
        let mut images = Vec::new();
        bitmap_files(&doc["bsdfs"], &t.dir, &mut images);
        for p in list {
            bitmap_files(&p["bsdf"], &t.dir, &mut images);
        }
        b.prefetch_textures(&images);
        let mut parsed: Vec<_> = files
            .par_iter()
            .map(|f| {
                f.as_ref()
                    .map(|(path, by)| crate::obj::parse(path, false, Some(by)))
            })
            .collect();
        // The meshes are added while the images may still decode; a texture's failure,
        // referenced before a mesh's, is the error (the order of the file).
        for (i, parsed) in parsed.iter_mut().enumerate() {
            let p: Owned = prims.j().index(i).expect("index within the array");
            if let Err(e) = t.primitive(&mut b, p.j(), &mut materials, &mut ignored, parsed.take())
            {
                b.settle_textures()?;
                return Err(e);
            }
        }
    }
    // The images may still decode (until `finish_with`): an error from here on is reported
    // after theirs, as the file orders them.
    if let Err(e) = t.emissions(&mut b, root) {
        b.settle_textures()?;
        return Err(e);
    }
    if !ignored.is_empty() {
        b.warn(format!("{file}: ignored: {}", ignored.join(", ")));
    }
    if !have_camera {
        b.scene.camera = crate::transform::frame_bounds(b.scene.bounds());
    }
    b.finish_with(geometry_ready)
}

impl Tungsten<'_> {
    /// The `emissions` array: environment emitters.
    fn emissions(&self, b: &mut SceneBuilder, root: J<'_, '_>) -> Result<(), SceneError> {
        let t = self;
        if let Some(em) = root.key("emissions") {
            let list = em.j().array()?;
            for i in 0..list.len() {
                let e = em.j().index(i).expect("index within the array");
                let e = e.j();
                let ty = e
                    .key("type")
                    .map(|t| t.j().str().map(str::to_string))
                    .transpose()?;
                match ty.as_deref() {
                    Some("envmap" | "infinite_sphere") => {
                        let r = e
                            .key("radiance")
                            .or_else(|| e.key("emission"))
                            .ok_or_else(|| e.invalid("environment emitter without `radiance`"))?;
                        let env = t.environment(b, r.j())?;
                        t.set_environment(b, env, e.path);
                    }
                    _ => return Err(e.unsupported(format!("emission type {ty:?}"))),
                }
            }
        }
        Ok(())
    }
}

/// The image files a BSDF (or an array or nesting of them) may read as textures: every
/// `albedo` given as a file name and every `bitmap` texture's `file`, relative to `dir`. More
/// than the import will read is harmless (a prefetch: [`SceneBuilder::prefetch_textures`]).
fn bitmap_files(v: &Value, dir: &Path, out: &mut Vec<PathBuf>) {
    match v {
        Value::Array(a) => a.iter().for_each(|x| bitmap_files(x, dir, out)),
        Value::Object(o) => {
            if let Some(Value::String(f)) = o.get("albedo") {
                out.push(dir.join(f));
            }
            if o.get("type").and_then(Value::as_str) == Some("bitmap")
                && let Some(Value::String(f)) = o.get("file")
            {
                out.push(dir.join(f));
            }
            o.values().for_each(|x| bitmap_files(x, dir, out));
        }
        _ => {}
    }
}

/// A whole, non-negative number that fits u32.
fn whole(j: J) -> Result<u32, SceneError> {
    let x = j.v.as_u64().ok_or_else(|| j.wrong("a whole number >= 0"))?;
    u32::try_from(x).map_err(|_| SceneError::TooLarge {
        file: j.file.into(),
        at: j.at(),
        what: "the number".into(),
        count: x,
        limit: u32::MAX as u64,
    })
}
