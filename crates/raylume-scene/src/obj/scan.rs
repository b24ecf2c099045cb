//! The pre-scan of OBJ text before tobj sees it (face indices checked, `usemtl`/`mtllib`
//! collected), MTL normalisation, and the lines of tobj's errors (tobj reports none).

use crate::error::{Location, SceneError};

/// What the pre-scan learned about an OBJ file.
#[derive(Debug)]
pub(super) struct Scan {
    /// (line, name) of each `usemtl`.
    pub(super) usemtl: Vec<(usize, String)>,
    /// (line, file) of each `mtllib`.
    pub(super) mtllib: Vec<(usize, String)>,
    /// Number of `l` (line) elements, which are skipped.
    pub(super) lines: usize,
}

pub(super) fn floats_ok<'a>(words: impl Iterator<Item = &'a str>, n: usize) -> bool {
    words.take(n).filter(|w| w.parse::<f32>().is_ok()).count() == n
}

/// Resolves an OBJ index the way tobj does (1-based; negative = relative to `so_far`).
pub(super) fn resolve(x: isize, so_far: usize) -> Option<usize> {
    if x < 0 {
        let r = so_far as isize + x;
        (r >= 0).then_some(r as usize)
    } else {
        (x > 0).then(|| x as usize - 1)
    }
}

/// Counts elements, checks every face index against the final counts (tobj's own check can
/// overflow), and collects `usemtl`/`mtllib` lines.
pub(super) fn prescan(text: &str, label: &str) -> Result<Scan, SceneError> {
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
pub(super) fn locate_obj(text: &str, err: &tobj::LoadError) -> Location {
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
pub(super) fn mtl_line_ok(line: &str) -> bool {
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
pub(super) fn normalize_mtl(text: &str, label: &str) -> Result<String, SceneError> {
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
