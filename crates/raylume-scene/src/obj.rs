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
//! - `Ke` is the emission of any of them; `map_Kd` is the albedo texture (relative to the MTL
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
use crate::model::{Material, Triangle};

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

fn utf8(bytes: Vec<u8>, label: &str) -> Result<String, SceneError> {
    String::from_utf8(bytes).map_err(|e| {
        let line = line_of_offset(e.as_bytes(), e.utf8_error().valid_up_to());
        SceneError::Syntax {
            file: label.to_string(),
            at: Location::Line(line),
            message: "not valid UTF-8".into(),
        }
    })
}

/// What the pre-scan learned about an OBJ file.
#[derive(Debug)]
struct Scan {
    /// (line, name) of each `usemtl`.
    usemtl: Vec<(usize, String)>,
    /// (line, file) of each `mtllib`.
    mtllib: Vec<(usize, String)>,
    /// Number of `l` (line) elements, which are skipped.
    lines: usize,
}

fn floats_ok<'a>(words: impl Iterator<Item = &'a str>, n: usize) -> bool {
    words.take(n).filter(|w| w.parse::<f32>().is_ok()).count() == n
}

/// Resolves an OBJ index the way tobj does (1-based; negative = relative to `so_far`).
fn resolve(x: isize, so_far: usize) -> Option<usize> {
    if x < 0 {
        let r = so_far as isize + x;
        (r >= 0).then_some(r as usize)
    } else {
        (x > 0).then(|| x as usize - 1)
    }
}

/// Counts elements, checks every face index against the final counts (tobj's own check can
/// overflow), and collects `usemtl`/`mtllib` lines.
fn prescan(text: &str, label: &str) -> Result<Scan, SceneError> {
    let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
    for line in text.lines() {
        match line.split_whitespace().next() {
            Some("v") => nv += 1,
            Some("vt") => nvt += 1,
            Some("vn") => nvn += 1,
            _ => {}
        }
    }
    let mut scan = Scan {
        usemtl: Vec::new(),
        mtllib: Vec::new(),
        lines: 0,
    };
    let (mut sv, mut svt, mut svn) = (0usize, 0usize, 0usize);
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next();
        match key {
            Some("v") => sv += 1,
            Some("vt") => svt += 1,
            Some("vn") => svn += 1,
            Some("f") | Some("l") => {
                if key == Some("l") {
                    scan.lines += 1;
                }
                for token in words {
                    for (k, part) in token.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let (what, so_far, total) = match k {
                            0 => ("vertex", sv, nv),
                            1 => ("texture coordinate", svt, nvt),
                            2 => ("normal", svn, nvn),
                            _ => break, // tobj reports the malformed face itself
                        };
                        let Ok(x) = part.parse::<isize>() else {
                            return Err(SceneError::Syntax {
                                file: label.to_string(),
                                at: Location::Line(i + 1),
                                message: format!("bad face index `{part}`"),
                            });
                        };
                        match resolve(x, so_far) {
                            Some(r) if r < total => {}
                            _ => {
                                return Err(SceneError::IndexOutOfRange {
                                    file: label.to_string(),
                                    at: Location::Line(i + 1),
                                    what: what.to_string(),
                                    index: x as u64,
                                    len: total as u64,
                                });
                            }
                        }
                    }
                }
            }
            Some("usemtl") => {
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                scan.usemtl.push((i + 1, name.to_string()));
            }
            Some("mtllib") => {
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                scan.mtllib.push((i + 1, name.to_string()));
            }
            _ => {}
        }
    }
    Ok(scan)
}

/// The first line tobj would reject with `err` (tobj does not report lines).
fn locate_obj(text: &str, err: &tobj::LoadError) -> Location {
    use tobj::LoadError as E;
    for (i, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        let key = w.next();
        let bad = match (err, key) {
            (E::PositionParseError | E::ScalingByZeroError | E::ColorParseError, Some("v")) => {
                let rest: Vec<&str> = w.collect();
                !floats_ok(rest.iter().copied(), 3)
                    || !matches!(rest.len(), 3 | 4 | 6)
                    || (rest.len() == 4 && rest[3].parse::<f32>().map_or(true, |x| x == 0.0))
            }
            (E::NormalParseError, Some("vn")) => !floats_ok(w, 3),
            (E::TexcoordParseError, Some("vt")) => !floats_ok(w, 2),
            (E::MaterialParseError, Some("usemtl")) => {
                line.split_once(' ').unwrap_or_default().1.trim().is_empty()
            }
            (E::FaceParseError | E::InvalidPolygon, Some("f" | "l")) => {
                w.any(|t| t.split('/').count() > 3)
            }
            _ => false,
        };
        if bad {
            return Location::Line(i + 1);
        }
    }
    Location::None
}

/// Whether tobj's MTL parser accepts this line (to find the line of an MTL error).
fn mtl_line_ok(line: &str) -> bool {
    let trimmed = line.trim();
    let mut w = trimmed.split_whitespace();
    match w.next() {
        Some("newmtl") => !trimmed[6..].trim().is_empty(),
        Some("Ka" | "Kd" | "Ks" | "Ke") => floats_ok(w, 3),
        Some("Ns" | "Ni" | "d") => floats_ok(w, 1),
        Some("illum") => w.next().is_some_and(|x| x.parse::<u8>().is_ok()),
        Some(k) if k.starts_with("map_") || k == "bump" => w.next().is_some(),
        _ => true,
    }
}

/// Expands one-value colours (`Kd 0.5` means `Kd 0.5 0.5 0.5` in the MTL spec; tobj panics on
/// it) and rejects two-value colours. Keeps the line count.
fn normalize_mtl(text: &str, label: &str) -> Result<String, SceneError> {
    let mut out = String::with_capacity(text.len() + 64);
    for (i, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        let key = w.next();
        let vals: Vec<&str> = w.collect();
        if matches!(key, Some("Ka" | "Kd" | "Ks" | "Ke")) && vals.len() < 3 {
            if vals.len() == 1 && vals[0].parse::<f32>().is_ok() {
                let v = vals[0];
                out.push_str(&format!("{} {v} {v} {v}\n", key.unwrap_or_default()));
                continue;
            }
            return Err(SceneError::Syntax {
                file: label.to_string(),
                at: Location::Line(i + 1),
                message: format!("colour `{}` needs 1 or 3 numbers", line.trim()),
            });
        }
        out.push_str(line);
        out.push('\n');
    }
    Ok(out)
}

type Mtl = (Vec<tobj::Material>, Vec<PathBuf>);

/// Parses one MTL file; the second vector holds each material's MTL path.
fn load_mtl(path: &Path, referenced_by: &str) -> Result<tobj::MTLLoadResult, SceneError> {
    let label = path.display().to_string();
    let text = utf8(read_file(path, Some(referenced_by))?, &label)?;
    let normalized = normalize_mtl(&text, &label)?;
    let result = catch_unwind(AssertUnwindSafe(|| {
        tobj::load_mtl_buf(&mut normalized.as_bytes())
    }))
    .map_err(|_| SceneError::Syntax {
        file: label.clone(),
        at: Location::None,
        message: "the MTL parser (tobj) panicked on this file".into(),
    })?;
    if let Err(e) = &result {
        let at = text
            .lines()
            .position(|l| !mtl_line_ok(l))
            .map_or(Location::None, |i| Location::Line(i + 1));
        return Err(SceneError::Syntax {
            file: label,
            at,
            message: e.to_string(),
        });
    }
    Ok(result)
}

/// Parses "r g b" or "r" (an MTL colour in an unknown-parameter string).
fn parse_color(s: &str) -> Option<Vec3> {
    let v: Vec<f32> = s
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .ok()?;
    match v.as_slice() {
        [r] => Some(Vec3::splat(*r)),
        [r, g, b] => Some(Vec3::new(*r, *g, *b)),
        _ => None,
    }
}

/// `(2 / (Ns + 2))^(1/4)`, see the module docs.
pub(crate) fn roughness_from_ns(ns: Option<f32>) -> f32 {
    match ns {
        None => 0.0,
        Some(ns) if ns.is_finite() => (2.0 / (ns.max(0.0) + 2.0)).sqrt().sqrt().clamp(0.0, 1.0),
        Some(ns) => ns, // NaN/Inf: validation reports the material
    }
}

/// Converts one MTL material (see the module docs for the mapping).
fn convert(
    b: &mut SceneBuilder,
    m: &tobj::Material,
    mtl_path: &Path,
) -> Result<Material, SceneError> {
    let v3 = |c: Option<[f32; 3]>, d: f32| c.map_or(Vec3::splat(d), Vec3::from_array);
    let kd = v3(m.diffuse, 0.8);
    let ks = v3(m.specular, 0.0);
    let ke = v3(m.emissive, 0.0);
    let dissolve = m.dissolve.or_else(|| {
        m.unknown_param
            .get("Tr")
            .and_then(|t| t.trim().parse::<f32>().ok())
            .map(|t| 1.0 - t)
    });
    let illum = m.illumination_model;
    let glass = matches!(illum, Some(4 | 6 | 7))
        || (m.optical_density.is_some() && dissolve.is_some_and(|d| d < 1.0));
    let metal = !glass
        && ks.max_element() > 0.0
        && (illum == Some(3) || ks.max_element() > kd.max_element());
    let mut out = if glass {
        let tint = match m.unknown_param.get("Tf") {
            Some(tf) => match parse_color(tf) {
                Some(c) => c,
                None => {
                    b.warn(format!(
                        "material '{}' in {}: Tf `{tf}` not understood, white tint used",
                        m.name,
                        mtl_path.display()
                    ));
                    Vec3::ONE
                }
            },
            None => Vec3::ONE,
        };
        Material::glass(&m.name, m.optical_density.unwrap_or(1.5), tint)
    } else if metal {
        Material::metal(&m.name, ks, roughness_from_ns(m.shininess))
    } else {
        Material::diffuse(&m.name, kd)
    };
    out.emission = ke;
    if let Some(map) = &m.diffuse_texture {
        if glass {
            b.warn(format!("material '{}': map_Kd ignored on glass", m.name));
        } else {
            // Options such as `-s 1 1 1 file.png` precede the file name: keep the last word.
            let file = if map.trim_start().starts_with('-') {
                b.warn(format!(
                    "material '{}': map_Kd options in `{map}` ignored",
                    m.name
                ));
                map.split_whitespace().last().unwrap_or(map)
            } else {
                map.trim()
            };
            let dir = mtl_path.parent().unwrap_or(Path::new(""));
            let referenced_by = format!("{}: material `{}` map_Kd", mtl_path.display(), m.name);
            out.albedo_texture = Some(b.texture(&dir.join(file), &referenced_by)?);
        }
    }
    Ok(out)
}

/// Loads an OBJ file's triangles (and, unless overridden, its MTL materials) into `b`.
pub(crate) fn load_into(
    b: &mut SceneBuilder,
    path: &Path,
    opts: &MeshOptions,
) -> Result<(), SceneError> {
    let label = path.display().to_string();
    let text = utf8(read_file(path, opts.referenced_by.as_deref())?, &label)?;
    let scan = prescan(&text, &label)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let want_mtl = opts.material.is_none();
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_and_absolute_indices_resolve_like_tobj() {
        assert_eq!(resolve(1, 5), Some(0));
        assert_eq!(resolve(-1, 5), Some(4));
        assert_eq!(resolve(-6, 5), None);
        assert_eq!(resolve(0, 5), None);
    }

    #[test]
    fn prescan_names_the_line_of_a_bad_index() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1/-7 2/1 3/1\n";
        let e = prescan(text, "m.obj").unwrap_err();
        assert!(
            matches!(&e, SceneError::IndexOutOfRange { at: Location::Line(6), what, index, len: 1, .. } if what == "texture coordinate" && *index as i64 == -7),
            "{e:?}"
        );
        // Index 0 does not exist in OBJ.
        let e = prescan("v 0 0 0\nf 0 1 1\n", "m.obj").unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::IndexOutOfRange {
                    at: Location::Line(2),
                    ..
                }
            ),
            "{e:?}"
        );
    }

    #[test]
    fn one_value_colours_expand_and_two_values_fail() {
        let n = normalize_mtl("newmtl a\nKd 0.5\nKs 1 1 1\n", "a.mtl").unwrap();
        assert_eq!(n, "newmtl a\nKd 0.5 0.5 0.5\nKs 1 1 1\n");
        let e = normalize_mtl("newmtl a\n\nKe 1 2\n", "a.mtl").unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::Syntax {
                    at: Location::Line(3),
                    ..
                }
            ),
            "{e:?}"
        );
    }

    #[test]
    fn ns_maps_to_roughness() {
        assert_eq!(roughness_from_ns(None), 0.0);
        // Ns = 0: alpha = 1, roughness = 1.
        assert!((roughness_from_ns(Some(0.0)) - 1.0).abs() < 1e-6);
        // Ns = 198: alpha = sqrt(2/200) = 0.1, roughness = sqrt(0.1).
        assert!((roughness_from_ns(Some(198.0)) - 0.1f32.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn tobj_errors_are_located() {
        let text = "v 0 0 0\nv 1 x 0\nf 1 2 3\n";
        assert_eq!(
            locate_obj(text, &tobj::LoadError::PositionParseError),
            Location::Line(2)
        );
        let text = "v 0 0 0\nvn 0 1\n";
        assert_eq!(
            locate_obj(text, &tobj::LoadError::NormalParseError),
            Location::Line(2)
        );
    }
}
