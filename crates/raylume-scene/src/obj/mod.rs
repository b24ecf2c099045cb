//! Wavefront OBJ + MTL through `tobj` (triangulated, single index; per-vertex normals and uvs
//! kept when every vertex of a mesh has them).
//!
//! MTL -> raylume:
//! - glass when `illum` is 4, 6 or 7, or when `Ni` is given and `d` (or `1 - Tr`) is below 1:
//!   `ior = Ni` (1.5 if absent), `tint = Tf` (white if absent);
//! - else metal when `Ks` is non-zero and either `illum 3` or `max(Ks) > max(Kd)`:
//!   `albedo = Ks`, `roughness = (2 / (Ns + 2))^(1/4)` (the Phong exponent's Beckmann-equivalent
//!   `alpha = sqrt(2 / (Ns + 2))`, and raylume's `alpha = roughness^2`), 0 when `Ns` is absent;
//! - else diffuse with `albedo = Kd` (0.8 grey if absent);
//! - `Ke` is the emission of any of them (from the front, counter-clockwise face only); `map_Kd` is the albedo texture (relative to the MTL
//!   file; multiplied with `Kd` as MTL prescribes).
//!
//! Texture coordinates: OBJ puts v = 0 at the bottom of the image, raylume at the top, so v is
//! flipped on load.
//!
//! Robustness: tobj would panic (integer overflow) on some out-of-range face indices and on a
//! colour with fewer than three values (`Kd 0.5`); both are caught by a pre-scan before tobj
//! sees the text: face indices are checked (an error with the line), and one-value colours are
//! expanded to three (the MTL spec's meaning). As a last resort the tobj calls run under
//! `catch_unwind`, so a panic inside tobj becomes a syntax error, never a crash.

use std::cell::RefCell;
use std::collections::HashSet;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use crate::builder::{MeshOptions, SceneBuilder, ShadingNormals, line_of_offset, read_file};
use crate::error::{Location, SceneError};
use crate::model::Triangle;
use mtl::{Mtl, convert, load_mtl};
use scan::{locate_obj, prescan};

mod mtl;
mod scan;

#[allow(clippy::needless_update)]
fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        // Further fields exist when tobj's `merging` / `reordering` features are on.
        ..Default::default()
    }
}

pub(super) fn utf8(bytes: Vec<u8>, label: &str) -> Result<String, SceneError> {
    String::from_utf8(bytes).map_err(|e| {
        let line = line_of_offset(e.as_bytes(), e.utf8_error().valid_up_to());
        SceneError::Syntax {
            file: label.to_string(),
            at: Location::Line(line),
            message: "not valid UTF-8".into(),
        }
    })
}

/// An OBJ file read and parsed (its MTL files too, unless the material is overridden), not
/// yet added to a scene: [`parse`] needs no [`SceneBuilder`], so files can be parsed on several
/// threads and added in order ([`insert`]).
pub(crate) struct ParsedObj {
    label: String,
    dir: PathBuf,
    want_mtl: bool,
    scan: scan::Scan,
    models: Vec<tobj::Model>,
    materials: Mtl,
}

/// Loads an OBJ file's triangles (and, unless overridden, its MTL materials) into `b`.
pub(crate) fn load_into(
    b: &mut SceneBuilder,
    path: &Path,
    opts: &MeshOptions,
) -> Result<(), SceneError> {
    let parsed = parse(path, opts.material.is_none(), opts.referenced_by.as_deref())?;
    insert(b, parsed, opts)
}

/// Reads and parses `path` (and its MTL files when `want_mtl`); `referenced_by` names who
/// referenced it, for a missing file's error.
pub(crate) fn parse(
    path: &Path,
    want_mtl: bool,
    referenced_by: Option<&str>,
) -> Result<ParsedObj, SceneError> {
    let label = path.display().to_string();
    let text = utf8(read_file(path, referenced_by)?, &label)?;
    let scan = prescan(&text, &label)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let failure: RefCell<Option<SceneError>> = RefCell::new(None);
    let mtl_paths: RefCell<Vec<PathBuf>> = RefCell::new(Vec::new());
    let result = catch_unwind(AssertUnwindSafe(|| {
        tobj::load_obj_buf(
            &mut text.as_bytes(),
            &load_options(),
            |mtl: &Path| -> tobj::MTLLoadResult {
                if !want_mtl {
                    return Ok((Vec::new(), Default::default()));
                }
                let full = dir.join(mtl);
                let line = scan
                    .mtllib
                    .iter()
                    .find(|(_, f)| Path::new(f) == mtl)
                    .map_or(0, |(l, _)| *l);
                match load_mtl(&full, &format!("{label}:{line}")) {
                    Ok(Ok(r)) => {
                        mtl_paths
                            .borrow_mut()
                            .extend(std::iter::repeat_n(full, r.0.len()));
                        Ok(r)
                    }
                    Ok(Err(e)) => Err(e),
                    Err(e) => {
                        failure.borrow_mut().get_or_insert(e);
                        Err(tobj::LoadError::OpenFileFailed)
                    }
                }
            },
        )
    }))
    .map_err(|_| SceneError::Syntax {
        file: label.clone(),
        at: Location::None,
        message: "the OBJ parser (tobj) panicked on this file".into(),
    })?;
    if let Some(e) = failure.into_inner() {
        return Err(e);
    }
    let (models, materials) = result.map_err(|e| SceneError::Syntax {
        file: label.clone(),
        at: locate_obj(&text, &e),
        message: e.to_string(),
    })?;
    let materials: Mtl = (materials.unwrap_or_default(), mtl_paths.into_inner());
    Ok(ParsedObj {
        label,
        dir: dir.to_path_buf(),
        want_mtl,
        scan,
        models,
        materials,
    })
}

/// Adds a parsed OBJ file's triangles (and, unless overridden, its materials) to `b`.
pub(crate) fn insert(
    b: &mut SceneBuilder,
    parsed: ParsedObj,
    opts: &MeshOptions,
) -> Result<(), SceneError> {
    let ParsedObj {
        label,
        dir,
        want_mtl,
        scan,
        models,
        materials,
    } = parsed;
    let dir = dir.as_path();

    // Every `usemtl` must name a material of the MTL files (unless overridden).
    if want_mtl {
        let known: HashSet<&str> = materials.0.iter().map(|m| m.name.as_str()).collect();
        let mut unresolved = 0;
        for (line, name) in &scan.usemtl {
            if !known.contains(name.as_str()) {
                if !scan.mtllib.is_empty() {
                    return Err(SceneError::UnknownMaterial {
                        file: label,
                        at: Location::Line(*line),
                        name: name.clone(),
                    });
                }
                unresolved += 1;
            }
        }
        if unresolved > 0 {
            b.warn(format!(
                "{label}: {unresolved} `usemtl` lines but no `mtllib`: the default grey diffuse material is used"
            ));
        }
    }
    if scan.lines > 0 {
        b.warn(format!(
            "{label}: {} line elements (`l`) ignored",
            scan.lines
        ));
    }

    let count: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    b.reserve_triangles(count, &label, Location::None)?;
    b.begin_source(&label);
    let mut converted: Vec<Option<u32>> = vec![None; materials.0.len()];
    let (mut zero_normals, mut partial) = (0usize, 0usize);
    for model in &models {
        let mesh = &model.mesh;
        let material = match (opts.material, mesh.material_id) {
            (Some(m), _) => m,
            (None, Some(i)) if i < materials.0.len() => match converted[i] {
                Some(m) => m,
                None => {
                    let mtl_path = materials
                        .1
                        .get(i)
                        .cloned()
                        .unwrap_or_else(|| dir.to_path_buf());
                    let m = convert(b, &materials.0[i], &mtl_path)?;
                    let at = Location::path(format!("material `{}`", materials.0[i].name));
                    let idx = b.add_material(m, &mtl_path.display().to_string(), at)?;
                    converted[i] = Some(idx);
                    idx
                }
            },
            _ => b.default_material(),
        };
        let p = &mesh.positions;
        let nv = p.len() / 3;
        let has_n = mesh.normals.len() == p.len();
        let has_uv = mesh.texcoords.len() == nv * 2;
        if (!has_n && !mesh.normals.is_empty()) || (!has_uv && !mesh.texcoords.is_empty()) {
            partial += 1;
        }
        let pos = |i: usize| Vec3::new(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
        let nrm = |i: usize| {
            Vec3::new(
                mesh.normals[3 * i],
                mesh.normals[3 * i + 1],
                mesh.normals[3 * i + 2],
            )
        };
        let uv = |i: usize| Vec2::new(mesh.texcoords[2 * i], 1.0 - mesh.texcoords[2 * i + 1]);
        for tri in mesh.indices.chunks_exact(3) {
            let [a, bb, c] = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
            let normals = if has_n {
                match ShadingNormals::check([nrm(a), nrm(bb), nrm(c)]) {
                    ShadingNormals::Unit(n) | ShadingNormals::NonFinite(n) => Some(n),
                    ShadingNormals::Zero => {
                        zero_normals += 1;
                        None
                    }
                }
            } else {
                None
            };
            let mut t = Triangle {
                positions: [pos(a), pos(bb), pos(c)],
                normals,
                uvs: has_uv.then(|| [uv(a), uv(bb), uv(c)]),
                material,
            };
            opts.xform.apply(&mut t);
            b.push_triangle(t);
        }
    }
    if zero_normals > 0 {
        b.warn(format!(
            "{label}: {zero_normals} triangles have zero-length normals: flat shading used for them"
        ));
    }
    if partial > 0 {
        b.warn(format!(
            "{label}: {partial} objects give normals or uvs for only some vertices: those attributes are dropped there"
        ));
    }
    Ok(())
}
