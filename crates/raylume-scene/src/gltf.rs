//! glTF 2.0 (`.gltf` + buffers, or `.glb`) through the `gltf` crate.
//!
//! - Geometry: the default scene (else scene 0, else every root node), the full node hierarchy
//!   with each node's transform; primitives in triangle, strip and fan modes (points and lines
//!   are skipped with a warning). POSITION, NORMAL and the TEXCOORD set the base colour texture
//!   uses.
//! - Materials (metallic-roughness):
//!   `KHR_materials_transmission` factor > 0.5 -> glass (`ior` from `KHR_materials_ior`,
//!   default 1.5; tint = base colour); else `metallicFactor >= 0.5` -> metal (albedo = base
//!   colour, roughness = `roughnessFactor`, which is already perceptual: GGX alpha =
//!   roughness^2 in both); else diffuse (albedo = base colour). Emission = `emissiveFactor` x
//!   `KHR_materials_emissive_strength`. `baseColorTexture` is the albedo texture. Other
//!   textures (metallic-roughness, normal, emissive) are ignored with a warning. Primitives
//!   without a material get the grey default diffuse (not glTF's default, which is a rough
//!   metal).
//! - Camera: the first node (depth-first, in scene order) that has a perspective camera gives
//!   position, view direction (-z) and up (+y) from its world transform and vfov from `yfov`.
//!
//! Robustness: the `gltf` reader indexes buffers with unchecked arithmetic and debug
//! assertions; every accessor is therefore checked here first (type, stride, bounds, no sparse
//! storage), node hierarchies are checked for cycles and depth, and buffers/images are read by
//! this module (with the scene's error types and image size limits) rather than by
//! `::gltf::import`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::Mode;
use glam::{Mat4, Vec2, Vec3};

use crate::builder::{MeshOptions, SceneBuilder, ShadingNormals, read_file};
use crate::error::{Location, SceneError};
use crate::image_io;
use crate::limits::MAX_NODE_DEPTH;
use crate::model::{Camera, Material, Triangle};
use crate::transform::Xform;

/// A camera found in a glTF file.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GltfCamera {
    pub camera: Camera,
    /// Width / height, when the file gives it.
    pub aspect: Option<f32>,
}

fn syntax(file: &str, at: Location, message: impl Into<String>) -> SceneError {
    SceneError::Syntax {
        file: file.to_string(),
        at,
        message: message.into(),
    }
}

fn invalid(file: &str, at: impl Into<String>, message: impl Into<String>) -> SceneError {
    SceneError::InvalidValue {
        file: file.to_string(),
        at: Location::path(at),
        message: message.into(),
    }
}

/// Standard base64 (RFC 4648, padding optional) for `data:` URIs.
pub(crate) fn base64_decode(s: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

/// `%20` and friends in relative URIs.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Bytes of a `data:` URI, or the path of a relative one.
enum UriData {
    Bytes(Vec<u8>),
    File(PathBuf),
}

fn resolve_uri(uri: &str, dir: &Path, file: &str, at: &str) -> Result<UriData, SceneError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((meta, data)) = rest.split_once(',') else {
            return Err(invalid(file, at, "malformed data URI"));
        };
        if !meta.ends_with(";base64") {
            return Err(SceneError::Unsupported {
                file: file.into(),
                at: Location::path(at),
                message: "data URI that is not base64".into(),
            });
        }
        return base64_decode(data)
            .map(UriData::Bytes)
            .ok_or_else(|| invalid(file, at, "data URI is not valid base64"));
    }
    if uri.contains("://") {
        return Err(SceneError::Unsupported {
            file: file.into(),
            at: Location::path(at),
            message: format!("URI scheme of `{uri}` (only relative paths and data URIs)"),
        });
    }
    Ok(UriData::File(dir.join(percent_decode(uri))))
}

fn map_gltf_error(file: &str, e: ::gltf::Error) -> SceneError {
    match e {
        ::gltf::Error::Deserialize(j) => syntax(
            file,
            Location::LineCol {
                line: j.line(),
                column: j.column(),
            },
            j.to_string(),
        ),
        ::gltf::Error::Validation(errs) => match errs.first() {
            Some((path, err)) => invalid(file, path.to_string(), err.to_string()),
            None => invalid(file, "document", "validation failed"),
        },
        ::gltf::Error::Binary(b) => syntax(file, Location::None, format!("GLB: {b}")),
        other => syntax(file, Location::None, other.to_string()),
    }
}

/// Checks an accessor so that the `gltf` reader cannot panic on it. `Ok(false)`: empty.
fn check_accessor(
    acc: &::gltf::Accessor,
    buffers: &[Vec<u8>],
    types: &[DataType],
    dims: Dimensions,
    file: &str,
    at: &str,
) -> Result<bool, SceneError> {
    let at = format!("{at} accessor {}", acc.index());
    if acc.sparse().is_some() {
        return Err(SceneError::Unsupported {
            file: file.into(),
            at: Location::path(at),
            message: "sparse accessors".into(),
        });
    }
    if !types.contains(&acc.data_type()) || acc.dimensions() != dims {
        return Err(SceneError::WrongType {
            file: file.into(),
            at: Location::path(at),
            message: format!(
                "{:?} {:?}, expected {dims:?} of {types:?}",
                acc.dimensions(),
                acc.data_type()
            ),
        });
    }
    if acc.count() == 0 {
        return Ok(false);
    }
    let Some(view) = acc.view() else {
        return Err(SceneError::Unsupported {
            file: file.into(),
            at: Location::path(at),
            message: "accessors without a buffer view".into(),
        });
    };
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(invalid(
            file,
            at,
            format!("byteStride {stride} is smaller than an element ({elem} bytes)"),
        ));
    }
    let end = stride
        .checked_mul(acc.count() - 1)
        .and_then(|x| x.checked_add(elem))
        .and_then(|x| x.checked_add(acc.offset()));
    if end.is_none_or(|e| e > view.length()) {
        return Err(invalid(
            file,
            at,
            format!("reads past the end of buffer view {}", view.index()),
        ));
    }
    let buf_len = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|e| e > buf_len)
    {
        return Err(invalid(
            file,
            format!("bufferViews[{}]", view.index()),
            format!(
                "reaches past the end of buffer {} ({buf_len} bytes)",
                view.buffer().index()
            ),
        ));
    }
    Ok(true)
}

struct Loader<'a> {
    file: String,
    dir: PathBuf,
    buffers: Vec<Vec<u8>>,
    opts: &'a MeshOptions,
    materials: HashMap<usize, u32>,
    images: HashMap<usize, u32>,
    camera: Option<GltfCamera>,
    zero_normals: usize,
}

impl Loader<'_> {
    fn image(&mut self, b: &mut SceneBuilder, img: ::gltf::Image) -> Result<u32, SceneError> {
        if let Some(&t) = self.images.get(&img.index()) {
            return Ok(t);
        }
        let at = format!("images[{}]", img.index());
        let referenced_by = format!("{}: {at}", self.file);
        let name = PathBuf::from(format!("{}#{at}", self.file));
        let t = match img.source() {
            ::gltf::image::Source::View { view, .. } => {
                let buf = self
                    .buffers
                    .get(view.buffer().index())
                    .map_or(&[][..], Vec::as_slice);
                let bytes = view
                    .offset()
                    .checked_add(view.length())
                    .and_then(|end| buf.get(view.offset()..end))
                    .ok_or_else(|| {
                        invalid(
                            &self.file,
                            format!("bufferViews[{}]", view.index()),
                            "past the end of its buffer",
                        )
                    })?;
                let tex = image_io::decode_texture(bytes, &name, &referenced_by)?;
                b.add_texture(tex, &self.file)?
            }
            ::gltf::image::Source::Uri { uri, .. } => {
                match resolve_uri(uri, &self.dir, &self.file, &at)? {
                    UriData::Bytes(bytes) => {
                        let tex = image_io::decode_texture(&bytes, &name, &referenced_by)?;
                        b.add_texture(tex, &self.file)?
                    }
                    UriData::File(path) => b.texture(&path, &referenced_by)?,
                }
            }
        };
        self.images.insert(img.index(), t);
        Ok(t)
    }

    /// The raylume material for a glTF material (see the module docs).
    fn material(&mut self, b: &mut SceneBuilder, m: &::gltf::Material) -> Result<u32, SceneError> {
        let Some(index) = m.index() else {
            return Ok(b.default_material());
        };
        if let Some(&i) = self.materials.get(&index) {
            return Ok(i);
        }
        let name = m
            .name()
            .map_or_else(|| format!("materials[{index}]"), str::to_string);
        let pbr = m.pbr_metallic_roughness();
        let [r, g, bl, _] = pbr.base_color_factor();
        let base = Vec3::new(r, g, bl);
        let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
        let mut out = if transmission > 0.5 {
            Material::glass(&name, m.ior().unwrap_or(1.5), base)
        } else if pbr.metallic_factor() >= 0.5 {
            Material::metal(&name, base, pbr.roughness_factor())
        } else {
            Material::diffuse(&name, base)
        };
        out.emission = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
        if let Some(info) = pbr.base_color_texture() {
            if transmission > 0.5 {
                b.warn(format!(
                    "{}: material '{name}': base colour texture ignored on glass",
                    self.file
                ));
            } else {
                out.albedo_texture = Some(self.image(b, info.texture().source())?);
            }
        }
        let mut ignored = Vec::new();
        if pbr.metallic_roughness_texture().is_some() {
            ignored.push("metallicRoughnessTexture");
        }
        if m.normal_texture().is_some() {
            ignored.push("normalTexture");
        }
        if m.emissive_texture().is_some() {
            ignored.push("emissiveTexture");
        }
        if m.alpha_mode() != ::gltf::material::AlphaMode::Opaque {
            ignored.push("alphaMode (treated as opaque)");
        }
        if !ignored.is_empty() {
            b.warn(format!(
                "{}: material '{name}': ignored {}",
                self.file,
                ignored.join(", ")
            ));
        }
        let i = b.add_material(
            out,
            &self.file,
            Location::path(format!("materials[{index}]")),
        )?;
        self.materials.insert(index, i);
        Ok(i)
    }

    fn primitive(
        &mut self,
        b: &mut SceneBuilder,
        prim: &::gltf::Primitive,
        xform: &Xform,
        at: &str,
    ) -> Result<(), SceneError> {
        let file = self.file.clone();
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            b.warn(format!(
                "{file}: {at}: {mode:?} primitive skipped (only triangles are rendered)"
            ));
            return Ok(());
        }
        let Some(pos_acc) = prim.get(&::gltf::Semantic::Positions) else {
            return Err(SceneError::MissingKey {
                file,
                at: Location::path(at),
                key: "POSITION".into(),
            });
        };
        if !check_accessor(
            &pos_acc,
            &self.buffers,
            &[DataType::F32],
            Dimensions::Vec3,
            &file,
            at,
        )? {
            return Ok(());
        }
        let material = match self.opts.material {
            Some(m) => m,
            None => self.material(b, &prim.material())?,
        };
        let uv_set = if self.opts.material.is_none() {
            prim.material()
                .pbr_metallic_roughness()
                .base_color_texture()
                .map_or(0, |i| i.tex_coord())
        } else {
            0
        };
        let normals_acc = prim.get(&::gltf::Semantic::Normals);
        let has_normals = match &normals_acc {
            Some(a) => check_accessor(
                a,
                &self.buffers,
                &[DataType::F32],
                Dimensions::Vec3,
                &file,
                at,
            )?,
            None => false,
        };
        let uv_acc = prim.get(&::gltf::Semantic::TexCoords(uv_set));
        let has_uvs = match &uv_acc {
            Some(a) => check_accessor(
                a,
                &self.buffers,
                &[DataType::F32, DataType::U8, DataType::U16],
                Dimensions::Vec2,
                &file,
                at,
            )?,
            None => false,
        };
        let index_acc = prim.indices();
        if let Some(a) = &index_acc {
            if !check_accessor(
                a,
                &self.buffers,
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
                &file,
                at,
            )? {
                return Ok(());
            }
        }
        let buffers = &self.buffers;
        let reader = prim.reader(|buf| buffers.get(buf.index()).map(Vec::as_slice));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .map(|it| it.map(Vec3::from).collect())
            .unwrap_or_default();
        let n = positions.len();
        let normals: Option<Vec<Vec3>> = if has_normals {
            reader.read_normals().map(|it| it.map(Vec3::from).collect())
        } else {
            None
        };
        let uvs: Option<Vec<Vec2>> = if has_uvs {
            reader
                .read_tex_coords(uv_set)
                .map(|it| it.into_f32().map(Vec2::from).collect())
        } else {
            None
        };
        let normals = normals.filter(|v| v.len() == n);
        let uvs = uvs.filter(|v| v.len() == n);
        let indices: Vec<u32> = match index_acc {
            Some(_) => reader
                .read_indices()
                .map(|r| r.into_u32().collect())
                .unwrap_or_default(),
            None => (0..n as u32).collect(),
        };
        if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(SceneError::IndexOutOfRange {
                file,
                at: Location::path(format!("{at} indices")),
                what: "vertex".into(),
                index: u64::from(*bad),
                len: n as u64,
            });
        }
        if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
            b.warn(format!(
                "{file}: {at}: {} indices is not a multiple of 3: the last {} ignored",
                indices.len(),
                indices.len() % 3
            ));
        }
        let tris: Vec<[u32; 3]> = match mode {
            Mode::Triangles => indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
            Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
                .map(|i| {
                    if i % 2 == 0 {
                        [indices[i], indices[i + 1], indices[i + 2]]
                    } else {
                        [indices[i + 1], indices[i], indices[i + 2]]
                    }
                })
                .collect(),
            _ => (1..indices.len().saturating_sub(1))
                .map(|i| [indices[0], indices[i], indices[i + 1]])
                .collect(),
        };
        b.reserve_triangles(tris.len(), &file, Location::path(at))?;
        for [i0, i1, i2] in tris {
            let idx = [i0 as usize, i1 as usize, i2 as usize];
            let normals = match &normals {
                Some(ns) => match ShadingNormals::check(idx.map(|i| ns[i])) {
                    ShadingNormals::Unit(v) | ShadingNormals::NonFinite(v) => Some(v),
                    ShadingNormals::Zero => {
                        self.zero_normals += 1;
                        None
                    }
                },
                None => None,
            };
            let mut t = Triangle {
                positions: idx.map(|i| positions[i]),
                normals,
                uvs: uvs.as_ref().map(|u| idx.map(|i| u[i])),
                material,
            };
            xform.apply(&mut t);
            b.push_triangle(t);
        }
        Ok(())
    }
}

/// Loads a glTF/GLB file's triangles (and, unless overridden, materials) into `b`; returns
/// the file's first perspective camera, in world space.
pub(crate) fn load_into(
    b: &mut SceneBuilder,
    path: &Path,
    opts: &MeshOptions,
) -> Result<Option<GltfCamera>, SceneError> {
    let file = path.display().to_string();
    let bytes = read_file(path, opts.referenced_by.as_deref())?;
    let gltf = std::panic::catch_unwind(|| ::gltf::Gltf::from_slice(&bytes))
        .map_err(|_| {
            syntax(
                &file,
                Location::None,
                "the glTF parser panicked on this file",
            )
        })?
        .map_err(|e| map_gltf_error(&file, e))?;
    let doc = gltf.document;
    let mut blob = gltf.blob;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();

    // Buffers.
    let mut buffers = Vec::new();
    for buffer in doc.buffers() {
        let at = format!("buffers[{}]", buffer.index());
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                invalid(
                    &file,
                    &at,
                    "refers to the GLB binary chunk, which is missing",
                )
            })?,
            ::gltf::buffer::Source::Uri(uri) => match resolve_uri(uri, &dir, &file, &at)? {
                UriData::Bytes(v) => v,
                UriData::File(p) => read_file(&p, Some(&format!("{file}: {at}")))?,
            },
        };
        if data.len() < buffer.length() {
            return Err(invalid(
                &file,
                &at,
                format!(
                    "byteLength is {} but the data has {} bytes",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        buffers.push(data);
    }

    let mut loader = Loader {
        file: file.clone(),
        dir,
        buffers,
        opts,
        materials: HashMap::new(),
        images: HashMap::new(),
        camera: None,
        zero_normals: 0,
    };
    b.begin_source(&file);

    // Roots: the default scene, else scene 0, else every node that is nobody's child.
    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    let mut visited = vec![false; doc.nodes().len()];
    let mut stack: Vec<(::gltf::Node, Mat4, usize)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY, 0))
        .collect();
    let mut skinned = 0usize;
    while let Some((node, parent, depth)) = stack.pop() {
        let at = format!("nodes[{}]", node.index());
        if std::mem::replace(&mut visited[node.index()], true) {
            return Err(invalid(
                &file,
                &at,
                "appears twice in the node hierarchy (a cycle or a shared child)",
            ));
        }
        if depth > MAX_NODE_DEPTH {
            return Err(SceneError::TooLarge {
                file: file.clone(),
                at: Location::path(at),
                what: "the node hierarchy depth".into(),
                count: depth as u64,
                limit: MAX_NODE_DEPTH as u64,
            });
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if !world.is_finite() {
            return Err(SceneError::NotFinite {
                file: file.clone(),
                at: Location::path(at),
                what: "the node's world transform".into(),
            });
        }
        if let (None, Some(cam)) = (loader.camera, node.camera()) {
            match cam.projection() {
                ::gltf::camera::Projection::Perspective(p) => {
                    let m = opts.xform.m * world;
                    let position = m.transform_point3(Vec3::ZERO);
                    let forward = m.transform_vector3(-Vec3::Z).normalize_or_zero();
                    loader.camera = Some(GltfCamera {
                        camera: Camera {
                            position,
                            look_at: position + forward,
                            up: m.transform_vector3(Vec3::Y),
                            vfov: p.yfov().to_degrees(),
                        },
                        aspect: p.aspect_ratio(),
                    });
                }
                ::gltf::camera::Projection::Orthographic(_) => {
                    b.warn(format!("{file}: {at}: orthographic camera ignored"));
                }
            }
        }
        if node.skin().is_some() {
            skinned += 1;
        }
        if let Some(mesh) = node.mesh() {
            let xform = Xform::from_mat4(opts.xform.m * world);
            for prim in mesh.primitives() {
                let pat = format!("{at} mesh {} primitive {}", mesh.index(), prim.index());
                loader.primitive(b, &prim, &xform, &pat)?;
            }
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
    }
    if skinned > 0 {
        b.warn(format!(
            "{file}: {skinned} skinned nodes: skins ignored, meshes placed by their node transforms"
        ));
    }
    if loader.zero_normals > 0 {
        b.warn(format!(
            "{file}: {} triangles have zero-length normals: flat shading used for them",
            loader.zero_normals
        ));
    }
    Ok(loader.camera)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_vectors() {
        // RFC 4648 test vectors.
        assert_eq!(base64_decode("").unwrap(), b"");
        assert_eq!(base64_decode("Zg==").unwrap(), b"f");
        assert_eq!(base64_decode("Zm8=").unwrap(), b"fo");
        assert_eq!(base64_decode("Zm9v").unwrap(), b"foo");
        assert_eq!(base64_decode("Zm9vYmFy").unwrap(), b"foobar");
        assert!(base64_decode("Zm9v!").is_none());
    }

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("a%20b.bin"), "a b.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("x%2"), "x%2");
    }
}
