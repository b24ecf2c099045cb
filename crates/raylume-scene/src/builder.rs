//! [`SceneBuilder`]: what every loader fills. It remembers where triangles came from (for
//! error messages), caches textures by path, enforces the size limits, and ends in
//! [`SceneBuilder::finish`], which drops degenerate triangles, clamps albedos and validates.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{Location, SceneError};
use crate::image_io;
use crate::limits::{MAX_MATERIALS, MAX_TEXTURES, MAX_TRIANGLES};
use crate::model::{Material, Scene, Texture, Triangle};
use crate::validate::{Provenance, Source, check_triangle_finite, is_degenerate, validate_with};

/// A scene under construction.
pub(crate) struct SceneBuilder {
    pub scene: Scene,
    /// Label of the top-level file (for scene-wide messages).
    pub file: String,
    /// Where each run of triangles came from, in triangle order.
    pub sources: Vec<Source>,
    /// One label per sphere (its place in the scene file).
    pub sphere_labels: Vec<String>,
    textures: HashMap<PathBuf, u32>,
    /// Textures decoded ahead of their first reference ([`SceneBuilder::prefetch_textures`]).
    prefetched: HashMap<PathBuf, Texture>,
    /// The prefetch still running on its thread.
    prefetch: Option<Prefetch>,
    /// Textures referenced while their prefetch ran, in reference order: their index (a
    /// placeholder until [`SceneBuilder::settle_textures`]), file and reference.
    pending: Vec<(u32, PathBuf, String)>,
    default_material: Option<u32>,
}

/// Image files being decoded on a thread of their own ([`SceneBuilder::prefetch_textures`]).
struct Prefetch {
    paths: std::collections::HashSet<PathBuf>,
    decoding: std::thread::JoinHandle<Vec<(PathBuf, Texture)>>,
}

/// Shading normals checked for use.
pub(crate) enum ShadingNormals {
    /// Normalised; use them.
    Unit([glam::Vec3; 3]),
    /// Finite but zero length: drop them (flat shading) and count it.
    Zero,
    /// NaN or infinite: keep them so that validation reports the triangle.
    NonFinite([glam::Vec3; 3]),
}

impl ShadingNormals {
    pub fn check(n: [Vec3; 3]) -> Self {
        if !n.iter().all(|v| v.is_finite()) {
            return ShadingNormals::NonFinite(n);
        }
        let mut out = n;
        for v in &mut out {
            let len = v.length();
            if len.is_nan() || len <= 0.0 || !len.is_finite() {
                return ShadingNormals::Zero;
            }
            *v /= len;
        }
        ShadingNormals::Unit(out)
    }
}

impl SceneBuilder {
    pub fn new(file: &str) -> Self {
        SceneBuilder {
            scene: Scene::default(),
            file: file.to_string(),
            sources: Vec::new(),
            sphere_labels: Vec::new(),
            textures: HashMap::new(),
            prefetched: HashMap::new(),
            prefetch: None,
            pending: Vec::new(),
            default_material: None,
        }
    }

    /// Triangles pushed from now on come from `label`.
    pub fn begin_source(&mut self, label: &str) {
        let start = self.scene.triangles.len();
        if let Some(last) = self.sources.last_mut()
            && last.start == start
        {
            last.label = label.to_string();
            return;
        }
        self.sources.push(Source {
            start,
            label: label.to_string(),
        });
    }

    /// Makes room for `n` more triangles, or fails past [`MAX_TRIANGLES`].
    pub fn reserve_triangles(
        &mut self,
        n: usize,
        file: &str,
        at: Location,
    ) -> Result<(), SceneError> {
        let total = self.scene.triangles.len().saturating_add(n);
        if total > MAX_TRIANGLES {
            return Err(SceneError::TooLarge {
                file: file.to_string(),
                at,
                what: "the triangle count".into(),
                count: total as u64,
                limit: MAX_TRIANGLES as u64,
            });
        }
        self.scene.triangles.reserve(n);
        Ok(())
    }

    pub fn push_triangle(&mut self, t: Triangle) {
        self.scene.triangles.push(t);
    }

    pub fn add_material(
        &mut self,
        m: Material,
        file: &str,
        at: Location,
    ) -> Result<u32, SceneError> {
        if self.scene.materials.len() >= MAX_MATERIALS {
            return Err(SceneError::TooLarge {
                file: file.to_string(),
                at,
                what: "the material count".into(),
                count: self.scene.materials.len() as u64 + 1,
                limit: MAX_MATERIALS as u64,
            });
        }
        self.scene.materials.push(m);
        Ok(self.scene.materials.len() as u32 - 1)
    }

    /// The grey diffuse material (albedo 0.8) for geometry that names none.
    pub fn default_material(&mut self) -> u32 {
        if let Some(m) = self.default_material {
            return m;
        }
        self.scene
            .materials
            .push(Material::diffuse("default", Vec3::splat(0.8)));
        let m = self.scene.materials.len() as u32 - 1;
        self.default_material = Some(m);
        m
    }

    fn check_texture_count(&self, file: &str) -> Result<(), SceneError> {
        if self.scene.textures.len() >= MAX_TEXTURES {
            return Err(SceneError::TooLarge {
                file: file.to_string(),
                at: Location::None,
                what: "the texture count".into(),
                count: self.scene.textures.len() as u64 + 1,
                limit: MAX_TEXTURES as u64,
            });
        }
        Ok(())
    }

    /// The texture at `path` (loaded once, then shared), as an index into `scene.textures`.
    pub fn texture(&mut self, path: &Path, referenced_by: &str) -> Result<u32, SceneError> {
        if let Some(&i) = self.textures.get(path) {
            return Ok(i);
        }
        self.check_texture_count(referenced_by)?;
        if self
            .prefetch
            .as_ref()
            .is_some_and(|p| p.paths.contains(path))
        {
            // Still decoding: a placeholder now, the texture at settle_textures.
            let i = self.push_texture(Texture {
                name: path.display().to_string(),
                width: 0,
                height: 0,
                texels: Vec::<[f32; 3]>::new().into(),
            });
            self.pending
                .push((i, path.to_path_buf(), referenced_by.to_string()));
            self.textures.insert(path.to_path_buf(), i);
            return Ok(i);
        }
        let tex = match self.prefetched.remove(path) {
            Some(tex) => tex,
            None => image_io::load_texture(path, referenced_by)?,
        };
        let i = self.push_texture(tex);
        self.textures.insert(path.to_path_buf(), i);
        Ok(i)
    }

    /// Starts decoding the image files at `paths` (on every core, from a thread of its own)
    /// ahead of the [`SceneBuilder::texture`] calls that will reference them, and returns:
    /// the import goes on meanwhile (the living room's progressive 2048x910 JPEG alone takes
    /// ~80 ms, longer than its 65 meshes parse on 16 cores). A texture referenced before its
    /// file is decoded gets its index and a placeholder, filled by
    /// [`SceneBuilder::settle_textures`] (which [`SceneBuilder::finish`] calls). Only what
    /// decodes is kept: a file that fails is decoded again at its first reference's turn, so
    /// that its error names that reference, as without the prefetch; one never referenced is
    /// dropped.
    pub fn prefetch_textures(&mut self, paths: &[PathBuf]) {
        let mut paths: Vec<PathBuf> = paths
            .iter()
            .filter(|p| !self.textures.contains_key(*p) && !self.prefetched.contains_key(*p))
            .cloned()
            .collect();
        paths.sort();
        paths.dedup();
        if paths.is_empty() {
            return;
        }
        let set = paths.iter().cloned().collect();
        // On threads of their own, not rayon's: a rayon worker waiting inside the meshes'
        // parallel parse would steal a decode and hold its mesh until the image is done (on
        // the H200's host the meshes finished only after the progressive JPEG, every time).
        let decode = move || -> Vec<(PathBuf, Texture)> {
            let threads = std::thread::available_parallelism()
                .map_or(1, usize::from)
                .min(paths.len());
            let next = std::sync::atomic::AtomicUsize::new(0);
            let mut out: Vec<Option<Texture>> = Vec::new();
            out.resize_with(paths.len(), || None);
            let slots: Vec<std::sync::Mutex<Option<Texture>>> =
                out.into_iter().map(std::sync::Mutex::new).collect();
            std::thread::scope(|scope| {
                for _ in 0..threads {
                    scope.spawn(|| {
                        loop {
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(p) = paths.get(i) else { break };
                            let t = image_io::load_texture(p, "").ok();
                            *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = t;
                        }
                    });
                }
            });
            paths
                .into_iter()
                .zip(slots)
                .filter_map(|(p, t)| Some((p, t.into_inner().unwrap_or_else(|e| e.into_inner())?)))
                .collect()
        };
        // Without a thread to be had, the textures decode at their references.
        if let Ok(decoding) = std::thread::Builder::new()
            .name("raylume texture prefetch".into())
            .spawn(decode)
        {
            self.settle_prefetch();
            self.prefetch = Some(Prefetch {
                paths: set,
                decoding,
            });
        }
    }

    /// Waits for a running prefetch and keeps what it decoded.
    fn settle_prefetch(&mut self) {
        if let Some(p) = self.prefetch.take() {
            let decoded = p
                .decoding
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            self.prefetched.extend(decoded);
        }
    }

    /// Waits for the prefetch ([`SceneBuilder::prefetch_textures`]) and puts the textures
    /// referenced meanwhile in their places; a file that did not decode is decoded again
    /// here, and the first such failure, in reference order, is the error (naming its
    /// reference). An importer calls it before anything that may fail after those references,
    /// so that errors come in the order of the file.
    pub fn settle_textures(&mut self) -> Result<(), SceneError> {
        self.settle_prefetch();
        for (i, path, by) in std::mem::take(&mut self.pending) {
            let tex = match self.prefetched.remove(&path) {
                Some(t) => t,
                None => image_io::load_texture(&path, &by)?,
            };
            self.scene.textures[i as usize] = tex;
        }
        Ok(())
    }

    /// Adds an already decoded texture (glTF embedded images).
    pub fn add_texture(&mut self, tex: Texture, file: &str) -> Result<u32, SceneError> {
        self.check_texture_count(file)?;
        Ok(self.push_texture(tex))
    }

    fn push_texture(&mut self, tex: Texture) -> u32 {
        self.scene.textures.push(tex);
        self.scene.textures.len() as u32 - 1
    }

    pub fn warn(&mut self, message: String) {
        self.scene.warnings.push(message);
    }

    /// Drops degenerate triangles (with a warning per source), clamps albedos above 1 (with a
    /// warning per material), then validates. NaN/Inf are errors, found before anything is
    /// dropped so that the index in the message is the index in the source file.
    pub fn finish(self) -> Result<Scene, SceneError> {
        self.finish_with(&mut |_| {})
    }

    /// [`SceneBuilder::finish`], calling `geometry_ready` once the geometry, materials,
    /// camera and settings are final (sanitised), before waiting for the textures still
    /// decoding ([`SceneBuilder::prefetch_textures`]): a caller can build the BVH meanwhile.
    /// Errors come as from `finish`: a texture that fails, referenced before the data that
    /// fails sanitising, is the error.
    pub fn finish_with(
        mut self,
        geometry_ready: &mut dyn FnMut(&mut Scene),
    ) -> Result<Scene, SceneError> {
        if let Err(e) = sanitize(&mut self) {
            self.settle_textures()?;
            return Err(e);
        }
        geometry_ready(&mut self.scene);
        self.settle_textures()?;
        validate_with(
            &self.scene,
            &Provenance {
                file: &self.file,
                sources: &self.sources,
                sphere_labels: &self.sphere_labels,
            },
        )?;
        Ok(self.scene)
    }
}

/// How a mesh file is placed into a scene.
#[derive(Clone, Debug)]
pub(crate) struct MeshOptions {
    pub xform: crate::transform::Xform,
    /// Material index overriding the file's own materials.
    pub material: Option<u32>,
    /// The place that named the file ("scene.toml:12:8"), for messages.
    pub referenced_by: Option<String>,
}

impl MeshOptions {
    /// A bare mesh file loaded as a scene: identity transform, the file's materials.
    pub fn bare() -> Self {
        MeshOptions {
            xform: crate::transform::Xform::IDENTITY,
            material: None,
            referenced_by: None,
        }
    }
}

/// Reads a whole file, mapping failures to [`SceneError::MissingFile`] / [`SceneError::Io`].
pub(crate) fn read_file(path: &Path, referenced_by: Option<&str>) -> Result<Vec<u8>, SceneError> {
    std::fs::read(path)
        .map_err(|e| SceneError::io(path.to_path_buf(), referenced_by.map(str::to_string), e))
}

/// Reads a scene description file, bounded by [`crate::limits::MAX_DESCRIPTION_BYTES`].
pub(crate) fn read_description(
    path: &Path,
    referenced_by: Option<&str>,
) -> Result<Vec<u8>, SceneError> {
    let limit = crate::limits::MAX_DESCRIPTION_BYTES;
    if let Ok(meta) = std::fs::metadata(path)
        && meta.len() > limit
    {
        return Err(SceneError::TooLarge {
            file: path.display().to_string(),
            at: Location::None,
            what: "the file size in bytes".into(),
            count: meta.len(),
            limit,
        });
    }
    read_file(path, referenced_by)
}

/// The 1-based line of byte `offset` in `bytes`.
pub(crate) fn line_of_offset(bytes: &[u8], offset: usize) -> usize {
    bytes[..offset.min(bytes.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Drops degenerate triangles, with a warning per source that had some.
fn drop_degenerate(b: &mut SceneBuilder) {
    let n = b.scene.triangles.len();
    let sources = std::mem::take(&mut b.sources);
    let mut runs: Vec<(usize, usize, String)> = Vec::with_capacity(sources.len() + 1);
    let first = sources.first().map_or(n, |s| s.start);
    if first > 0 {
        runs.push((0, first, b.file.clone()));
    }
    for (k, s) in sources.iter().enumerate() {
        let end = sources.get(k + 1).map_or(n, |next| next.start);
        runs.push((s.start, end, s.label.clone()));
    }
    let mut kept: Vec<Triangle> = Vec::with_capacity(n);
    for (start, end, label) in runs {
        let new_start = kept.len();
        let mut dropped = 0usize;
        for t in &b.scene.triangles[start..end] {
            if is_degenerate(t) {
                dropped += 1;
            } else {
                kept.push(*t);
            }
        }
        if dropped > 0 {
            b.scene.warnings.push(format!(
                "dropped {dropped} degenerate triangles from {label}"
            ));
        }
        b.sources.push(Source {
            start: new_start,
            label,
        });
    }
    b.scene.triangles = kept;
}

/// The loaders' sanitising (see [`SceneBuilder::finish_with`]): NaN/Inf errors, degenerate
/// triangles dropped, albedo/tint clamped; [`validate_with`] follows once the textures are in.
fn sanitize(b: &mut SceneBuilder) -> Result<(), SceneError> {
    let prov = Provenance {
        file: &b.file,
        sources: &b.sources,
        sphere_labels: &b.sphere_labels,
    };
    // 1. Non-finite data is an error, reported with the index it has in its source file (the
    //    first such triangle's, found on every core).
    if let Some(e) = b
        .scene
        .triangles
        .par_iter()
        .enumerate()
        .find_map_first(|(i, t)| check_triangle_finite(t, &prov, i).err())
    {
        return Err(e);
    }
    // 2. Degenerate triangles go, counted per source (nothing is copied when there are none).
    if b.scene.triangles.par_iter().any(is_degenerate) {
        drop_degenerate(b);
    } else if b
        .sources
        .first()
        .map_or(b.scene.triangles.len(), |s| s.start)
        > 0
    {
        // Triangles before the first source belong to the scene file (as drop_degenerate says).
        b.sources.insert(
            0,
            Source {
                start: 0,
                label: b.file.clone(),
            },
        );
    }
    // 3. Albedo and tint above 1 are clamped (negative stays an error below).
    for m in &mut b.scene.materials {
        for (what, c) in [("albedo", &mut m.albedo), ("tint", &mut m.tint)] {
            if c.is_finite() && c.max_element() > 1.0 {
                b.scene.warnings.push(format!(
                    "material '{}': {what} {:?} clamped to [0, 1]",
                    m.name,
                    c.to_array()
                ));
                *c = c.min(Vec3::ONE);
            }
        }
    }
    Ok(())
}
