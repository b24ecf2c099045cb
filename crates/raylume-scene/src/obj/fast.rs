//! The parallel OBJ parser: the statements large meshes are made of (`v`, `vt`, `vn`, `f`,
//! `o`, `g`, `usemtl`, `mtllib`, comments and keywords tobj ignores), parsed on every core
//! without a per-line allocation, with exactly tobj's meaning (what [`super::parse`] gives
//! through tobj: the same triangles, materials, groups and warnings).
//!
//! It declines a file ([`parse`] returns `None`, and the caller uses tobj) at the first thing
//! outside that subset or anything tobj would reject: a `v` with other than three numbers, a
//! `vt` or `vn` with too few, a face of fewer than three corners or with a malformed, zero or
//! out-of-range index, a line element (`l`), an empty `usemtl`. Errors are therefore always
//! tobj's path's, with its line numbers.
//!
//! How: the text is cut at line ends into pieces, several per thread. A first pass counts the
//! `v`, `vt`, `vn` of each piece, so that the second, which parses them, knows how many come
//! before and resolves relative (negative) indices at once. Structure statements (`o`, `g`,
//! `usemtl`, `mtllib`) are rare: they are recorded with their place and replayed in order
//! afterwards, as tobj meets them, to cut the faces into tobj's models (a new model at `o` or
//! `g` after faces, and at a change of material after faces) and to load the MTL files.

use std::collections::HashMap;
use std::ops::Range;

use rayon::prelude::*;

/// A face corner's absent texture coordinate or normal.
pub(super) const MISSING: u32 = u32::MAX;

/// One corner of a triangle: 0-based indices into the positions, texture coordinates and
/// normals ([`MISSING`] when absent).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Corner {
    pub v: u32,
    pub vt: u32,
    pub vn: u32,
}

/// A structure statement and where it was met.
#[derive(Debug)]
pub(super) enum Event {
    /// `o` or `g`: a new model once the current one has faces.
    Group,
    /// `usemtl NAME` (tobj's reading: after the first space, trimmed).
    Usemtl(String),
    /// `mtllib FILE` (the same reading).
    Mtllib(String),
}

/// The geometry of an OBJ file, parsed, in pieces of the text (each piece's faces in order).
#[derive(Debug)]
pub(super) struct FastObj {
    pub positions: Vec<[f32; 3]>,
    pub texcoords: Vec<[f32; 2]>,
    pub normals: Vec<[f32; 3]>,
    /// The triangles of each piece of the text (polygons fanned as tobj fans them).
    pub faces: Vec<Vec<[Corner; 3]>>,
    /// (triangles before it in the file, 1-based line, statement), in file order.
    pub events: Vec<(usize, usize, Event)>,
}

impl FastObj {
    /// All triangles, in file order.
    pub fn triangle_count(&self) -> usize {
        self.faces.iter().map(Vec::len).sum()
    }

    /// The triangles `range` (file order) as slices of the pieces.
    pub fn slices(&self, range: Range<usize>) -> Vec<&[[Corner; 3]]> {
        let mut out = Vec::new();
        let mut start = 0;
        for piece in &self.faces {
            let end = start + piece.len();
            let (a, b) = (range.start.max(start), range.end.min(end));
            if a < b {
                out.push(&piece[a - start..b - start]);
            }
            start = end;
        }
        out
    }
}

/// tobj's models: the triangles of each (file order) and its material.
pub(super) type Models = Vec<(Range<usize>, Option<usize>)>;

/// Bytes of text per piece at least (smaller files are one piece).
const MIN_PIECE: usize = 1 << 16;

/// Cuts `text` after line ends into about `n` pieces.
fn pieces(text: &str, n: usize) -> Vec<&str> {
    let target = (text.len() / n.max(1)).max(MIN_PIECE);
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut start = 0;
    while start < text.len() {
        let mut end = (start + target).min(text.len());
        while end < text.len() && bytes[end - 1] != b'\n' {
            end += 1;
        }
        out.push(&text[start..end]);
        start = end;
    }
    out
}

/// `(v, vt, vn)` statements in `piece`.
fn count(piece: &str) -> [usize; 3] {
    let mut c = [0; 3];
    for line in piece.lines() {
        match line.split_whitespace().next() {
            Some("v") => c[0] += 1,
            Some("vt") => c[1] += 1,
            Some("vn") => c[2] += 1,
            _ => {}
        }
    }
    c
}

/// What the second pass makes of a piece.
#[derive(Default)]
struct Piece {
    positions: Vec<[f32; 3]>,
    texcoords: Vec<[f32; 2]>,
    normals: Vec<[f32; 3]>,
    faces: Vec<[Corner; 3]>,
    /// (triangles before it in this piece, 0-based line in this piece, statement).
    events: Vec<(usize, usize, Event)>,
    lines: usize,
}

/// `n` floats from `words` (tobj's `parse_floatn`: the first `n`, the rest ignored).
fn floats<const N: usize>(words: &mut std::str::SplitWhitespace) -> Option<[f32; N]> {
    let mut out = [0.0; N];
    for x in &mut out {
        *x = words.next()?.parse().ok()?;
    }
    Some(out)
}

/// tobj's index rule: 1-based, or negative counting back from the elements so far; `None`
/// when it resolves outside `0..so_far`. (An index to an element defined later in the file
/// is valid for tobj only if that element comes before the end of the face's model: such
/// files go to tobj's path.)
fn index(part: &str, so_far: usize) -> Option<u32> {
    let x: isize = part.parse().ok()?;
    let r = if x < 0 { so_far as isize + x } else { x - 1 };
    (r >= 0 && (r as usize) < so_far).then_some(r as u32)
}

/// One `f` token (`v`, `v/vt`, `v//vn`, `v/vt/vn`).
fn corner(token: &str, so_far: [usize; 3]) -> Option<Corner> {
    let mut c = [MISSING; 3];
    let mut parts = token.split('/');
    for (k, slot) in c.iter_mut().enumerate() {
        match parts.next() {
            Some("") if k > 0 => {}
            Some(p) => *slot = index(p, so_far[k])?,
            None => break,
        }
    }
    if parts.next().is_some() {
        return None;
    }
    Some(Corner {
        v: c[0],
        vt: c[1],
        vn: c[2],
    })
}

/// Parses one piece; `before`: the `v`, `vt`, `vn` of the pieces before it. `None`: outside
/// the subset (see the module's docs).
fn parse_piece(piece: &str, before: [usize; 3]) -> Option<Piece> {
    let mut out = Piece::default();
    let mut corners: Vec<Corner> = Vec::with_capacity(8);
    for (i, line) in piece.lines().enumerate() {
        out.lines = i + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let p = floats::<3>(&mut words)?;
                if words.next().is_some() {
                    return None; // w or vertex colours: tobj's path
                }
                out.positions.push(p);
            }
            Some("vt") => out.texcoords.push(floats::<2>(&mut words)?),
            Some("vn") => out.normals.push(floats::<3>(&mut words)?),
            Some("f") => {
                let so_far = [
                    before[0] + out.positions.len(),
                    before[1] + out.texcoords.len(),
                    before[2] + out.normals.len(),
                ];
                corners.clear();
                for token in words {
                    corners.push(corner(token, so_far)?);
                }
                if corners.len() < 3 {
                    return None;
                }
                // tobj's triangulation: a fan around the first corner.
                for k in 2..corners.len() {
                    out.faces.push([corners[0], corners[k - 1], corners[k]]);
                }
            }
            Some("o" | "g") => out.events.push((out.faces.len(), i, Event::Group)),
            Some(key @ ("usemtl" | "mtllib")) => {
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                if name.is_empty() && key == "usemtl" {
                    return None;
                }
                let e = if key == "usemtl" {
                    Event::Usemtl(name.to_string())
                } else {
                    Event::Mtllib(name.to_string())
                };
                out.events.push((out.faces.len(), i, e));
            }
            Some("l") => return None,
            // Comments, `s` and every keyword tobj ignores.
            _ => {}
        }
    }
    Some(out)
}

/// Parses `text` on the current rayon pool; `None` when it is outside the subset this parser
/// handles exactly as tobj (the caller then uses tobj).
pub(super) fn parse(text: &str) -> Option<FastObj> {
    let pieces = pieces(text, rayon::current_num_threads() * 8);
    let counts: Vec<[usize; 3]> = pieces.par_iter().map(|p| count(p)).collect();
    let mut before = Vec::with_capacity(counts.len());
    let mut totals = [0usize; 3];
    for c in &counts {
        before.push(totals);
        for k in 0..3 {
            totals[k] += c[k];
        }
    }
    if totals.iter().any(|&t| t >= MISSING as usize) {
        return None;
    }
    let parsed: Vec<Piece> = pieces
        .par_iter()
        .zip(before.par_iter())
        .map(|(p, b)| parse_piece(p, *b))
        .collect::<Option<Vec<Piece>>>()?;

    let mut positions = Vec::with_capacity(totals[0]);
    let mut texcoords = Vec::with_capacity(totals[1]);
    let mut normals = Vec::with_capacity(totals[2]);
    let mut faces = Vec::with_capacity(parsed.len());
    let mut events = Vec::new();
    let (mut faces_before, mut lines_before) = (0usize, 0usize);
    for p in parsed {
        positions.extend_from_slice(&p.positions);
        texcoords.extend_from_slice(&p.texcoords);
        normals.extend_from_slice(&p.normals);
        for (f, line, e) in p.events {
            events.push((faces_before + f, lines_before + line + 1, e));
        }
        faces_before += p.faces.len();
        lines_before += p.lines;
        faces.push(p.faces);
    }
    Some(FastObj {
        positions,
        texcoords,
        normals,
        faces,
        events,
    })
}

/// tobj's models, replayed: `(triangles, material)` of each, in file order, the last one
/// always there (tobj pushes the model in progress at the end of the file, faces or not).
/// `material(name)`: the material index a `usemtl` name resolves to with the MTL files loaded
/// so far; `load(file, line)`: loads an `mtllib` file when it is met, returning the name ->
/// index map of its materials, already offset (tobj's merge).
pub(super) fn models<E>(
    obj: &FastObj,
    mut load: impl FnMut(&str, usize) -> Result<HashMap<String, usize>, E>,
) -> Result<Models, E> {
    let mut known: HashMap<String, usize> = HashMap::new();
    let mut out = Vec::new();
    let (mut start, mut material) = (0usize, None);
    for (at, line, e) in &obj.events {
        match e {
            Event::Group => {
                if *at > start {
                    out.push((start..*at, material));
                    start = *at;
                }
            }
            Event::Usemtl(name) => {
                let new = known.get(name).copied();
                if material != new && *at > start {
                    out.push((start..*at, material));
                    start = *at;
                }
                material = new;
            }
            Event::Mtllib(file) => known.extend(load(file, *line)?),
        }
    }
    out.push((start..obj.triangle_count(), material));
    Ok(out)
}
