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
use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::builder::{MeshOptions, SceneBuilder, ShadingNormals, line_of_offset};
use crate::error::{Location, SceneError};
use crate::model::Triangle;
use mtl::{Mtl, convert, load_mtl};
use scan::{locate_obj, prescan};

mod fast;
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
    String::from_utf8(bytes)
        .map_err(|e| not_utf8(e.as_bytes(), e.utf8_error().valid_up_to(), label))
}

/// The error for `bytes` that are UTF-8 only up to `valid_up_to`.
fn not_utf8(bytes: &[u8], valid_up_to: usize, label: &str) -> SceneError {
    SceneError::Syntax {
        file: label.to_string(),
        at: Location::Line(line_of_offset(bytes, valid_up_to)),
        message: "not valid UTF-8".into(),
    }
}

/// An OBJ file's text, checked to be UTF-8: read into memory, or, from
/// [`MAP_FROM_BYTES`] on, mapped (the parser reads the page cache itself: the 3M-triangle
/// grid's 116 MB, read, were 28k page faults and a copy, ~0.1 s of its 0.8 s load on the
/// 2-core machine). A mapped file must not be truncated by another process while it loads.
enum ObjText {
    Read(String),
    Mapped(memmap2::Mmap),
}

/// Files from this size on are mapped rather than read.
const MAP_FROM_BYTES: u64 = 16 << 20;

impl ObjText {
    fn open(
        path: &Path,
        referenced_by: Option<&str>,
        label: &str,
        map_from: u64,
    ) -> Result<Self, SceneError> {
        let io = |e| SceneError::io(path.to_path_buf(), referenced_by.map(str::to_string), e);
        let mut file = std::fs::File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        // SAFETY: the map is read-only and private; it is undefined behaviour only if
        // another process changes or truncates the file while it is mapped, which
        // `Scene::load`'s documentation rules out (as every loader that maps its input must).
        let map =
            (len >= map_from).then(|| unsafe { memmap2::MmapOptions::new().populate().map(&file) });
        // A file too small to map, or one whose file system cannot map it, is read.
        let Some(Ok(map)) = map else {
            let mut bytes = Vec::new();
            bytes
                .try_reserve_exact(len as usize)
                .map_err(|e| io(std::io::Error::new(std::io::ErrorKind::OutOfMemory, e)))?;
            std::io::Read::read_to_end(&mut file, &mut bytes).map_err(io)?;
            return Ok(Self::Read(utf8(bytes, label)?));
        };
        if let Err(e) = std::str::from_utf8(&map) {
            return Err(not_utf8(&map, e.valid_up_to(), label));
        }
        Ok(Self::Mapped(map))
    }

    fn as_str(&self) -> &str {
        match self {
            Self::Read(s) => s,
            // SAFETY: checked to be UTF-8 in `open`.
            Self::Mapped(m) => unsafe { std::str::from_utf8_unchecked(m) },
        }
    }
}

/// An OBJ file read and parsed (its MTL files too, unless the material is overridden), not
/// yet added to a scene: [`parse`] needs no [`SceneBuilder`], so files can be parsed on several
/// threads and added in order ([`insert`]).
pub(crate) struct ParsedObj {
    label: String,
    dir: PathBuf,
    want_mtl: bool,
    scan: scan::Scan,
    geometry: Geometry,
    materials: Mtl,
}

/// The triangles of a parsed file: tobj's models, or the parallel parser's (`fast.rs`).
enum Geometry {
    Tobj(Vec<tobj::Model>),
    Fast {
        obj: fast::FastObj,
        models: fast::Models,
    },
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
    parse_with(path, want_mtl, referenced_by, true, MAP_FROM_BYTES)
}

/// [`parse`]; `try_fast`: false to go straight to tobj's path (the tests compare the two);
/// files from `map_from` bytes on are mapped.
fn parse_with(
    path: &Path,
    want_mtl: bool,
    referenced_by: Option<&str>,
    try_fast: bool,
    map_from: u64,
) -> Result<ParsedObj, SceneError> {
    let label = path.display().to_string();
    let text = ObjText::open(path, referenced_by, &label, map_from)?;
    let text = text.as_str();
    let dir = path.parent().unwrap_or(Path::new(""));
    // The parallel parser first; tobj's path for what it declines.
    if try_fast
        && let Some(obj) = fast::parse(text)
        && let Some(parsed) = parse_fast(obj, &label, dir, want_mtl)?
    {
        return Ok(parsed);
    }
    parse_tobj(text, label, dir, want_mtl)
}

/// [`parse`] through the parallel parser: the MTL files loaded as tobj loads them, when
/// their `mtllib` is met. `Ok(None)`: an MTL file tobj's path would treat otherwise.
fn parse_fast(
    obj: fast::FastObj,
    label: &str,
    dir: &Path,
    want_mtl: bool,
) -> Result<Option<ParsedObj>, SceneError> {
    let mut scan = scan::Scan {
        usemtl: Vec::new(),
        mtllib: Vec::new(),
        lines: 0,
    };
    for (_, line, e) in &obj.events {
        match e {
            fast::Event::Usemtl(n) => scan.usemtl.push((*line, n.clone())),
            fast::Event::Mtllib(f) => scan.mtllib.push((*line, f.clone())),
            fast::Event::Group => {}
        }
    }
    let (mut materials, mut mtl_paths) = (Vec::new(), Vec::new());
    let models = fast::models(&obj, |file, _| {
        if !want_mtl {
            return Ok(HashMap::new());
        }
        let full = dir.join(file);
        let line = scan
            .mtllib
            .iter()
            .find(|(_, f)| Path::new(f) == Path::new(file))
            .map_or(0, |(l, _)| *l);
        match load_mtl(&full, &format!("{label}:{line}")) {
            Ok(Ok((mats, map))) => {
                let offset = materials.len();
                mtl_paths.extend(std::iter::repeat_n(full, mats.len()));
                materials.extend(mats);
                Ok(map.into_iter().map(|(k, v)| (k, v + offset)).collect())
            }
            Ok(Err(_)) => Err(None),
            Err(e) => Err(Some(e)),
        }
    });
    let models = match models {
        Ok(m) => m,
        Err(None) => return Ok(None),
        Err(Some(e)) => return Err(e),
    };
    Ok(Some(ParsedObj {
        label: label.to_string(),
        dir: dir.to_path_buf(),
        want_mtl,
        scan,
        geometry: Geometry::Fast { obj, models },
        materials: (materials, mtl_paths),
    }))
}

/// [`parse`] through tobj, after the pre-scan that checks what tobj would panic on.
fn parse_tobj(
    text: &str,
    label: String,
    dir: &Path,
    want_mtl: bool,
) -> Result<ParsedObj, SceneError> {
    let scan = prescan(text, &label)?;
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
        at: locate_obj(text, &e),
        message: e.to_string(),
    })?;
    let materials: Mtl = (materials.unwrap_or_default(), mtl_paths.into_inner());
    Ok(ParsedObj {
        label,
        dir: dir.to_path_buf(),
        want_mtl,
        scan,
        geometry: Geometry::Tobj(models),
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
        geometry,
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

    let count = match &geometry {
        Geometry::Tobj(models) => models.iter().map(|m| m.mesh.indices.len() / 3).sum(),
        Geometry::Fast { obj, .. } => obj.triangle_count(),
    };
    b.reserve_triangles(count, &label, Location::None)?;
    b.begin_source(&label);
    let mut converted: Vec<Option<u32>> = vec![None; materials.0.len()];
    // The scene material of a model whose MTL material is `id`.
    let mut material_of = |b: &mut SceneBuilder, id: Option<usize>| -> Result<u32, SceneError> {
        Ok(match (opts.material, id) {
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
        })
    };
    let (mut zero_normals, mut partial) = (0usize, 0usize);
    match &geometry {
        Geometry::Tobj(models) => {
            for model in models {
                let material = material_of(b, model.mesh.material_id)?;
                let (z, p) = insert_tobj_mesh(b, &model.mesh, material, opts);
                zero_normals += z;
                partial += usize::from(p);
            }
        }
        Geometry::Fast { obj, models } => {
            for (range, id) in models {
                let material = material_of(b, *id)?;
                let (z, p) = insert_fast_model(b, obj, range.clone(), material, opts);
                zero_normals += z;
                partial += usize::from(p);
            }
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

/// A normal triple as the scene takes it: normalised, `None` when one is zero (flat shading;
/// counted by the caller), kept raw when not finite (validation reports the triangle).
fn shading_normals(n: [Vec3; 3]) -> Option<[Vec3; 3]> {
    match ShadingNormals::check(n) {
        ShadingNormals::Unit(n) | ShadingNormals::NonFinite(n) => Some(n),
        ShadingNormals::Zero => None,
    }
}

/// Adds one tobj mesh's triangles; returns (triangles whose normals were dropped as zero,
/// whether the mesh gives normals or uvs for only some vertices).
fn insert_tobj_mesh(
    b: &mut SceneBuilder,
    mesh: &tobj::Mesh,
    material: u32,
    opts: &MeshOptions,
) -> (usize, bool) {
    let p = &mesh.positions;
    let nv = p.len() / 3;
    let has_n = mesh.normals.len() == p.len();
    let has_uv = mesh.texcoords.len() == nv * 2;
    let partial = (!has_n && !mesh.normals.is_empty()) || (!has_uv && !mesh.texcoords.is_empty());
    let pos = |i: usize| Vec3::new(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    let nrm = |i: usize| {
        Vec3::new(
            mesh.normals[3 * i],
            mesh.normals[3 * i + 1],
            mesh.normals[3 * i + 2],
        )
    };
    let uv = |i: usize| Vec2::new(mesh.texcoords[2 * i], 1.0 - mesh.texcoords[2 * i + 1]);
    let mut zero_normals = 0;
    for tri in mesh.indices.chunks_exact(3) {
        let [a, bb, c] = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
        let normals = if has_n {
            let n = shading_normals([nrm(a), nrm(bb), nrm(c)]);
            zero_normals += usize::from(n.is_none());
            n
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
    (zero_normals, partial)
}

/// [`insert_tobj_mesh`] for one of the parallel parser's models (triangles `range` of the
/// file), its triangles made on every core. The same rules: normals (uvs) are kept when every
/// corner of the model has one.
fn insert_fast_model(
    b: &mut SceneBuilder,
    obj: &fast::FastObj,
    range: Range<usize>,
    material: u32,
    opts: &MeshOptions,
) -> (usize, bool) {
    let slices = obj.slices(range);
    // (every corner has a normal, some corner has one, the same for uvs)
    let flags = |f: &[fast::Corner; 3]| {
        let n = f.iter().filter(|c| c.vn != fast::MISSING).count();
        let t = f.iter().filter(|c| c.vt != fast::MISSING).count();
        (n == 3, n > 0, t == 3, t > 0)
    };
    let join = |a: (bool, bool, bool, bool), b: (bool, bool, bool, bool)| {
        (a.0 && b.0, a.1 || b.1, a.2 && b.2, a.3 || b.3)
    };
    let (has_n, any_n, has_uv, any_uv) = slices
        .par_iter()
        .flat_map(|s| s.par_iter())
        .map(flags)
        .reduce(|| (true, false, true, false), join);
    let partial = (!has_n && any_n) || (!has_uv && any_uv);
    let pos = |i: u32| Vec3::from(obj.positions[i as usize]);
    let nrm = |i: u32| Vec3::from(obj.normals[i as usize]);
    let uv = |i: u32| {
        let t = obj.texcoords[i as usize];
        Vec2::new(t[0], 1.0 - t[1])
    };
    let make = |f: &[fast::Corner; 3]| {
        let mut t = Triangle {
            positions: f.map(|c| pos(c.v)),
            normals: if has_n {
                shading_normals(f.map(|c| nrm(c.vn)))
            } else {
                None
            },
            uvs: has_uv.then(|| f.map(|c| uv(c.vt))),
            material,
        };
        opts.xform.apply(&mut t);
        t
    };
    let first = b.scene.triangles.len();
    for s in slices {
        b.scene.triangles.par_extend(s.par_iter().map(make));
    }
    let zero_normals = if has_n {
        b.scene.triangles[first..]
            .par_iter()
            .filter(|t| t.normals.is_none())
            .count()
    } else {
        0
    };
    (zero_normals, partial)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// One OBJ statement, rendered against the counts so far by [`render`].
    #[derive(Clone, Debug)]
    enum Stmt {
        V(f32, f32, f32),
        Vt(f32, f32),
        Vn(f32, f32, f32),
        /// Corner selectors (index = selector mod count; negative form when `rel`), the form
        /// (0: v, 1: v/vt, 2: v//vn, 3: v/vt/vn), and per corner a form override.
        F(Vec<(u16, bool, Option<u8>)>, u8),
        Group(bool),
        Usemtl(u8),
        Mtllib(bool),
        Comment,
        Smooth,
        /// Something the parallel parser declines (tobj's path must then give the same).
        Odd(u8),
    }

    fn stmt() -> impl Strategy<Value = Stmt> {
        let f = -2.0f32..2.0;
        prop_oneof![
            6 => (f.clone(), f.clone(), f.clone()).prop_map(|(a, b, c)| Stmt::V(a, b, c)),
            2 => (f.clone(), f.clone()).prop_map(|(a, b)| Stmt::Vt(a, b)),
            2 => (f.clone(), f.clone(), f).prop_map(|(a, b, c)| Stmt::Vn(a, b, c)),
            8 => (
                prop::collection::vec(
                    (any::<u16>(), any::<bool>(), prop::option::weighted(0.05, 0u8..4)),
                    3..6
                ),
                0u8..4
            )
                .prop_map(|(c, form)| Stmt::F(c, form)),
            1 => any::<bool>().prop_map(Stmt::Group),
            1 => (0u8..4).prop_map(Stmt::Usemtl),
            1 => prop::bool::weighted(0.9).prop_map(Stmt::Mtllib),
            1 => Just(Stmt::Comment),
            1 => Just(Stmt::Smooth),
            1 => (0u8..40).prop_map(Stmt::Odd),
        ]
    }

    fn render(stmts: &[Stmt]) -> String {
        let mut out = String::new();
        let (mut v, mut vt, mut vn) = (0usize, 0usize, 0usize);
        let pick = |sel: u16, rel: bool, n: usize| -> String {
            if n == 0 {
                return "1".into(); // out of range: both paths must fail alike
            }
            let i = sel as usize % n;
            if rel {
                format!("-{}", n - i)
            } else {
                format!("{}", i + 1)
            }
        };
        for s in stmts {
            match s {
                Stmt::V(a, b, c) => {
                    v += 1;
                    out += &format!("v {a} {b} {c}\n");
                }
                Stmt::Vt(a, b) => {
                    vt += 1;
                    out += &format!("vt {a} {b}\n");
                }
                Stmt::Vn(a, b, c) => {
                    vn += 1;
                    out += &format!("vn {a} {b} {c}\n");
                }
                Stmt::F(corners, form) => {
                    out += "f";
                    for (sel, rel, own) in corners {
                        let p = pick(*sel, *rel, v);
                        let t = pick(sel.rotate_left(5), *rel, vt);
                        let n = pick(sel.rotate_left(11), *rel, vn);
                        out += &match own.unwrap_or(*form) {
                            0 => format!(" {p}"),
                            1 => format!(" {p}/{t}"),
                            2 => format!(" {p}//{n}"),
                            _ => format!(" {p}/{t}/{n}"),
                        };
                    }
                    out += "\n";
                }
                Stmt::Group(o) => out += if *o { "o thing\n" } else { "g part\n" },
                Stmt::Usemtl(m) => {
                    out += &format!("usemtl {}\n", ["red", "gold", "glass", "red"][*m as usize])
                }
                Stmt::Mtllib(ok) => {
                    out += if *ok {
                        "mtllib m.mtl\n"
                    } else {
                        "mtllib gone.mtl\n"
                    }
                }
                Stmt::Comment => out += "# a comment\n\n",
                Stmt::Smooth => out += "s 1\n",
                Stmt::Odd(k) => {
                    out += match k {
                        0 => "l 1 2\n",
                        1 => "v 1 2 3 0.5\n",
                        2 => "f 1 2\n",
                        3 => "usemtl\n",
                        4 => "vt 0.5\n",
                        5 => "f 0 1 2\n",
                        6 => "v 1 2 3 0.1 0.2 0.3\n",
                        7 => "f 1/1/1/1 1 1\n",
                        8 => "vp 0.5 0.5\n",
                        9 => "  usemtl gold\n",
                        _ => "\r\n",
                    }
                }
            }
        }
        out
    }

    const MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl gold\nKs 0.9 0.7 0.2\nKd 0.1 0.1 0.1\nillum 3\nNs 50\nnewmtl glass\nillum 7\nNi 1.5\n";

    /// What loading `text` gives: the scene's triangles, materials and warnings, or the error.
    fn load(
        dir: &Path,
        text: &str,
        fast: bool,
        material: Option<u32>,
    ) -> Result<(Vec<Triangle>, usize, Vec<String>), String> {
        let path = dir.join(if fast { "fast.obj" } else { "tobj.obj" });
        std::fs::write(&path, text).unwrap();
        let mut b = SceneBuilder::new("test");
        let opts = MeshOptions {
            material,
            ..MeshOptions::bare()
        };
        let material_given = material.is_some();
        let label = path.display().to_string();
        let r = parse_with(&path, !material_given, None, fast, MAP_FROM_BYTES)
            .and_then(|p| insert(&mut b, p, &opts));
        let clean = |s: String| s.replace(&label, "FILE");
        match r {
            Ok(()) => Ok((
                b.scene.triangles,
                b.scene.materials.len(),
                b.scene.warnings.into_iter().map(clean).collect(),
            )),
            Err(e) => Err(clean(format!("{e:?}"))),
        }
    }

    fn temp_dir() -> PathBuf {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let d = std::env::temp_dir().join(format!(
            "raylume-obj-fast-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("m.mtl"), MTL).unwrap();
        d
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// The parallel parser and tobj's path give the same triangles (positions, normals,
        /// uvs, materials), the same materials and warnings, or the same error, on random
        /// files of positions, normals, uvs, faces of 3 to 5 corners in every index form
        /// (absolute and relative), groups, materials and a few things the parallel parser
        /// declines.
        #[test]
        fn parallel_parser_equals_tobj(stmts in prop::collection::vec(stmt(), 0..60), override_material in any::<bool>()) {
            let text = render(&stmts);
            let dir = temp_dir();
            let material = override_material.then_some(0);
            let fast = load(&dir, &text, true, material);
            let slow = load(&dir, &text, false, material);
            std::fs::remove_dir_all(&dir).ok();
            prop_assert_eq!(fast, slow, "{}", text);
        }
    }

    /// A mapped file loads as the same file read, and its errors are the same (bad UTF-8 with
    /// its line, a face index out of range).
    #[test]
    fn a_mapped_file_loads_as_the_file_read() {
        let dir = temp_dir();
        let mut text = String::from("mtllib m.mtl\nusemtl gold\n");
        for i in 0..2000 {
            let (x, y) = ((i % 50) as f32, (i / 50) as f32);
            text += &format!(
                "v {x} {y} 0.5\nv {} {y} 0\nv {x} {} 1\nf -3 -2 -1\n",
                x + 1.0,
                y + 1.0
            );
        }
        let mut bad = text.clone().into_bytes();
        bad.extend_from_slice(b"v 1 2 3\nv \xff 1 1\n");
        let mut out_of_range = text.clone();
        out_of_range += "f 1 2 99999\n";
        let load = |bytes: &[u8], map_from: u64| {
            let path = dir.join(format!("m{map_from}.obj"));
            std::fs::write(&path, bytes).unwrap();
            let mut b = SceneBuilder::new("test");
            let r = parse_with(&path, true, None, true, map_from)
                .and_then(|p| insert(&mut b, p, &MeshOptions::bare()));
            let label = path.display().to_string();
            match r {
                Ok(()) => Ok((b.scene.triangles, b.scene.materials.len())),
                Err(e) => Err(format!("{e:?}").replace(&label, "FILE")),
            }
        };
        let mapped = load(text.as_bytes(), 0).unwrap();
        assert_eq!(mapped.0.len(), 2000);
        assert_eq!(mapped, load(text.as_bytes(), u64::MAX).unwrap());
        for bytes in [bad, out_of_range.into_bytes()] {
            let (read, mapped) = (load(&bytes, u64::MAX), load(&bytes, 0));
            assert!(read.is_err(), "{read:?}");
            assert_eq!(mapped, read);
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A file its file system cannot map (procfs has no mmap) is read instead: the same
    /// outcome as reading it, not an I/O error.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_file_that_cannot_be_mapped_is_read() {
        let path = Path::new("/proc/version");
        let outcome = |map_from: u64| {
            let mut b = SceneBuilder::new("test");
            parse_with(path, false, None, true, map_from)
                .and_then(|p| insert(&mut b, p, &MeshOptions::bare()))
                .map(|()| b.scene.triangles.len())
                .map_err(|e| format!("{e:?}"))
        };
        let read = outcome(u64::MAX);
        assert!(!format!("{read:?}").contains("Io"), "{read:?}");
        assert_eq!(outcome(0), read);
    }

    /// A large file cut into many pieces: relative indices across piece borders, and the
    /// parallel parser really used (it declines nothing here).
    #[test]
    fn pieces_resolve_relative_indices_across_borders() {
        let mut text = String::from("mtllib m.mtl\nusemtl gold\n");
        for i in 0..30_000 {
            let x = i as f32 * 0.001;
            text += &format!(
                "v {x} 0 0\nv {x} 1 0\nvn 0 0 1\nvt {x} 0.5\nf -2/-1/-1 -1/-1/-1 {}/1/1\n",
                2 * i + 1
            );
            if i % 7000 == 0 {
                text += "g more\nusemtl red\n";
            }
        }
        assert!(text.len() > 8 * MIN_PIECE_FOR_TESTS);
        assert!(
            fast::parse(&text).is_some(),
            "the parallel parser declined it"
        );
        let dir = temp_dir();
        let fast = load(&dir, &text, true, None);
        let slow = load(&dir, &text, false, None);
        std::fs::remove_dir_all(&dir).ok();
        let (tris, materials, _) = fast.clone().unwrap();
        assert_eq!(tris.len(), 30_000);
        assert_eq!(materials, 2);
        assert_eq!(fast, slow);
    }

    const MIN_PIECE_FOR_TESTS: usize = 1 << 16;
}
