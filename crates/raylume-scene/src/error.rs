//! [`SceneError`], the one error type of this crate, and [`Location`], the place in a file an
//! error points at.
//!
//! Every message names the file and the place: `scene.toml:12:5: unknown key ...`,
//! `scene.json: primitives[3].transform: ...`, `scene.toml: triangle 12 (from bunny.obj): ...`.

use std::fmt;
use std::path::PathBuf;

/// Where in a file an error is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Location {
    /// The file as a whole.
    None,
    /// A 1-based line and column (TOML, JSON syntax errors).
    LineCol { line: usize, column: usize },
    /// A 1-based line (OBJ, MTL).
    Line(usize),
    /// A path inside the document: a JSON path such as `primitives[3].transform`, a glTF
    /// `mesh 2 primitive 0 accessor 5`, or a validation place such as `triangle 12`.
    Path(String),
}

impl Location {
    /// A path location.
    pub fn path(p: impl Into<String>) -> Self {
        Location::Path(p.into())
    }

    /// The line/column of byte `offset` in `text` (1-based; columns count characters).
    pub fn from_offset(text: &str, offset: usize) -> Self {
        let offset = offset.min(text.len());
        // Step back to a char boundary so that slicing cannot panic.
        let mut o = offset;
        while !text.is_char_boundary(o) {
            o -= 1;
        }
        let before = &text[..o];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() + 1;
        Location::LineCol { line, column }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::None => Ok(()),
            Location::LineCol { line, column } => write!(f, ":{line}:{column}"),
            Location::Line(line) => write!(f, ":{line}"),
            Location::Path(p) => write!(f, ": {p}"),
        }
    }
}

/// " (referenced by X)" or nothing.
fn by(referenced_by: &Option<String>) -> String {
    match referenced_by {
        Some(r) => format!(" (referenced by {r})"),
        None => String::new(),
    }
}

/// Everything that can go wrong while loading or validating a scene.
///
/// `file` is the file's label as the user gave it (or as joined to the scene's folder);
/// `at` is the place inside it.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file that the scene needs does not exist.
    #[error("{}: file not found{}", path.display(), by(referenced_by))]
    MissingFile {
        path: PathBuf,
        referenced_by: Option<String>,
    },
    /// Any other I/O failure.
    #[error("{}: cannot read{}: {source}", path.display(), by(referenced_by))]
    Io {
        path: PathBuf,
        referenced_by: Option<String>,
        #[source]
        source: std::io::Error,
    },
    /// The file's extension says a format this crate does not read.
    #[error("{}: unsupported file extension{} (expected {expected})", path.display(), by(referenced_by))]
    UnsupportedExtension {
        path: PathBuf,
        referenced_by: Option<String>,
        expected: &'static str,
    },
    /// A folder given where a scene file was expected, and not a Tungsten scene's folder
    /// (one holding `scene.json`, which [`Scene::load`](crate::Scene::load) takes).
    #[error("{}: a folder, not a scene file (a folder is read as a Tungsten scene when it holds scene.json)", path.display())]
    Folder { path: PathBuf },
    /// The file is not well-formed (TOML, JSON, OBJ, MTL, glTF syntax).
    #[error("{file}{at}: syntax error: {message}")]
    Syntax {
        file: String,
        at: Location,
        message: String,
    },
    /// A key the format does not have (typo protection).
    #[error("{file}{at}: unknown key `{key}`: {message}")]
    UnknownKey {
        file: String,
        at: Location,
        key: String,
        message: String,
    },
    /// A required key is absent.
    #[error("{file}{at}: missing key `{key}`")]
    MissingKey {
        file: String,
        at: Location,
        key: String,
    },
    /// A value of the wrong type (a string where a number belongs, 2 numbers for a vector...).
    #[error("{file}{at}: wrong type: {message}")]
    WrongType {
        file: String,
        at: Location,
        message: String,
    },
    /// A material name that the scene does not define.
    #[error("{file}{at}: unknown material `{name}`")]
    UnknownMaterial {
        file: String,
        at: Location,
        name: String,
    },
    /// An index (material, texture, vertex, node, ...) past the end of its table.
    #[error("{file}{at}: {what} index {index} is out of range (there are {len})")]
    IndexOutOfRange {
        file: String,
        at: Location,
        what: String,
        index: u64,
        len: u64,
    },
    /// NaN or infinity where a finite number belongs.
    #[error("{file}{at}: {what} is not finite (NaN or infinity)")]
    NotFinite {
        file: String,
        at: Location,
        what: String,
    },
    /// A size that must be positive is zero or negative (image size, spp, radius, scale,
    /// quad area, ...).
    #[error("{file}{at}: {what} must be positive, got {value}")]
    NonPositive {
        file: String,
        at: Location,
        what: String,
        value: f64,
    },
    /// A value that must not be negative is (emission, albedo, strength, ...).
    #[error("{file}{at}: {what} must not be negative, got {value}")]
    Negative {
        file: String,
        at: Location,
        what: String,
        value: f64,
    },
    /// A camera's vertical field of view outside (0, 180) degrees.
    #[error("{file}{at}: vfov {vfov} degrees is outside (0, 180)")]
    Vfov {
        file: String,
        at: Location,
        vfov: f64,
    },
    /// The camera cannot form a view: position equals look_at, or up is parallel to the view
    /// direction.
    #[error("{file}{at}: degenerate camera: {reason}")]
    DegenerateCamera {
        file: String,
        at: Location,
        reason: &'static str,
    },
    /// No triangles and no spheres (after dropping degenerate triangles).
    #[error("{file}: the scene is empty: it has no triangles and no spheres")]
    EmptyScene { file: String },
    /// A value of the right type that is not allowed (an unknown material type, a roughness
    /// above 1, radiance and map both given, ...).
    #[error("{file}{at}: invalid value: {message}")]
    InvalidValue {
        file: String,
        at: Location,
        message: String,
    },
    /// Something the format allows that raylume cannot represent (a Tungsten primitive type
    /// without a raylume equivalent, sparse glTF accessors, ...).
    #[error("{file}{at}: unsupported: {message}")]
    Unsupported {
        file: String,
        at: Location,
        message: String,
    },
    /// An image (texture, environment map) that cannot be decoded.
    #[error("{}: cannot decode image{}: {message}", path.display(), by(referenced_by))]
    Image {
        path: PathBuf,
        referenced_by: Option<String>,
        message: String,
    },
    /// Input past one of the limits in [`crate::limits`].
    #[error("{file}{at}: too large: {what} is {count}, the limit is {limit}")]
    TooLarge {
        file: String,
        at: Location,
        what: String,
        count: u64,
        limit: u64,
    },
}

impl SceneError {
    /// The file label or path the error names.
    pub fn file(&self) -> String {
        match self {
            SceneError::MissingFile { path, .. }
            | SceneError::Io { path, .. }
            | SceneError::UnsupportedExtension { path, .. }
            | SceneError::Folder { path }
            | SceneError::Image { path, .. } => path.display().to_string(),
            SceneError::Syntax { file, .. }
            | SceneError::UnknownKey { file, .. }
            | SceneError::MissingKey { file, .. }
            | SceneError::WrongType { file, .. }
            | SceneError::UnknownMaterial { file, .. }
            | SceneError::IndexOutOfRange { file, .. }
            | SceneError::NotFinite { file, .. }
            | SceneError::NonPositive { file, .. }
            | SceneError::Negative { file, .. }
            | SceneError::Vfov { file, .. }
            | SceneError::DegenerateCamera { file, .. }
            | SceneError::EmptyScene { file }
            | SceneError::InvalidValue { file, .. }
            | SceneError::Unsupported { file, .. }
            | SceneError::TooLarge { file, .. } => file.clone(),
        }
    }

    /// The place inside the file, where the variant has one.
    pub fn location(&self) -> Option<&Location> {
        match self {
            SceneError::Syntax { at, .. }
            | SceneError::UnknownKey { at, .. }
            | SceneError::MissingKey { at, .. }
            | SceneError::WrongType { at, .. }
            | SceneError::UnknownMaterial { at, .. }
            | SceneError::IndexOutOfRange { at, .. }
            | SceneError::NotFinite { at, .. }
            | SceneError::NonPositive { at, .. }
            | SceneError::Negative { at, .. }
            | SceneError::Vfov { at, .. }
            | SceneError::DegenerateCamera { at, .. }
            | SceneError::InvalidValue { at, .. }
            | SceneError::Unsupported { at, .. }
            | SceneError::TooLarge { at, .. } => Some(at),
            _ => None,
        }
    }

    /// An I/O error on `path`: [`SceneError::MissingFile`] when it does not exist.
    pub(crate) fn io(path: PathBuf, referenced_by: Option<String>, e: std::io::Error) -> Self {
        if e.kind() == std::io::ErrorKind::NotFound {
            SceneError::MissingFile {
                path,
                referenced_by,
            }
        } else {
            SceneError::Io {
                path,
                referenced_by,
                source: e,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_become_lines_and_columns() {
        let text = "a = 1\nbé = 2\n\nc";
        assert_eq!(
            Location::from_offset(text, 0),
            Location::LineCol { line: 1, column: 1 }
        );
        // 'b' starts line 2; '=' after "bé " is the 4th character (é is 2 bytes).
        let eq = text.find("= 2").unwrap();
        assert_eq!(
            Location::from_offset(text, eq),
            Location::LineCol { line: 2, column: 4 }
        );
        assert_eq!(
            Location::from_offset(text, text.len()),
            Location::LineCol { line: 4, column: 2 }
        );
        // Inside a multi-byte character: snaps back, never panics.
        let e = text.find('é').unwrap() + 1;
        assert_eq!(
            Location::from_offset(text, e),
            Location::LineCol { line: 2, column: 2 }
        );
    }

    #[test]
    fn messages_name_file_and_place() {
        let e = SceneError::UnknownKey {
            file: "a.toml".into(),
            at: Location::LineCol { line: 3, column: 1 },
            key: "wdth".into(),
            message: "expected one of `width`, `height`".into(),
        };
        assert_eq!(
            e.to_string(),
            "a.toml:3:1: unknown key `wdth`: expected one of `width`, `height`"
        );
        let e = SceneError::MissingFile {
            path: "m/x.obj".into(),
            referenced_by: Some("a.toml:9:8".into()),
        };
        assert_eq!(
            e.to_string(),
            "m/x.obj: file not found (referenced by a.toml:9:8)"
        );
        let e = SceneError::NotFinite {
            file: "s.json".into(),
            at: Location::path("primitives[3].transform.position"),
            what: "position".into(),
        };
        assert_eq!(
            e.to_string(),
            "s.json: primitives[3].transform.position: position is not finite (NaN or infinity)"
        );
    }
}
