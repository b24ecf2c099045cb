//! glTF 2.0 (`.gltf` + buffers, or `.glb`) through the `gltf` crate.
//!
//! - Geometry: the default scene (else scene 0, else every root node), the full node hierarchy
//!   with each node's transform; primitives in triangle, strip and fan modes (points and lines
//!   are skipped with a warning). POSITION, NORMAL and the TEXCOORD set the base colour texture
//!   uses.
//! - Materials (metallic-roughness):
//!   `KHR_materials_transmission` factor > 0.5 -> glass (`ior` from `KHR_materials_ior`,
//!   default 1.5; tint = base colour; roughness = `roughnessFactor`, which is already
//!   perceptual: GGX alpha = roughness^2 in both); else `metallicFactor >= 0.5` -> metal
//!   (albedo = base colour at every angle, which is glTF's Schlick F0 held constant); else
//!   plastic: glTF's dielectric is a diffuse base colour under a GGX specular layer with
//!   F0 = 0.04, the Fresnel reflectance of ior 1.5 (`KHR_materials_ior` if given), which is
//!   raylume's plastic of that ior and roughness. A metallic factor strictly between 0 and 1
//!   picks the nearer of the two. Emission = `emissiveFactor` x
//!   `KHR_materials_emissive_strength`, from the front face only unless the material is
//!   `doubleSided`. `baseColorTexture` is the albedo texture. Other
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

use glam::{Mat4, Vec3};

use crate::builder::{MeshOptions, SceneBuilder, read_file};
use crate::error::{Location, SceneError};
use crate::image_io;
use crate::limits::MAX_NODE_DEPTH;
use crate::model::{Camera, Material};
use crate::transform::Xform;
use uri::{UriData, resolve_uri};

mod primitive;
mod uri;

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

pub(super) fn invalid(file: &str, at: impl Into<String>, message: impl Into<String>) -> SceneError {
    SceneError::InvalidValue {
        file: file.to_string(),
        at: Location::path(at),
        message: message.into(),
    }
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
        let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
        let mut out = if transmission > 0.5 {
            let mut glass = Material::glass(&name, m.ior().unwrap_or(1.5), base);
            glass.roughness = roughness;
            glass
        } else if pbr.metallic_factor() >= 0.5 {
            Material::metal(&name, base, roughness)
        } else {
            // glTF's dielectric: a diffuse base colour under a GGX specular layer of F0 = 0.04,
            // the reflectance of ior 1.5, which is raylume's plastic.
            Material::plastic(&name, base, m.ior().unwrap_or(1.5), roughness)
        };
        out.emission = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
        // glTF 2.0 §3.9.6: a single-sided material shows its front face only.
        out.two_sided = m.double_sided();
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
}

/// gltf 1.4's `Glb::from_slice` computes `header.length - 12` without a check (binary.rs), so
/// a GLB whose header declares fewer than 12 bytes overflows inside the parser (a panic with
/// overflow checks on, a huge length without). This rejects such headers first, and a header
/// whose declared length exceeds the file, with the numbers.
fn check_glb_header(bytes: &[u8], file: &str) -> Result<(), SceneError> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let Some(len) = bytes.get(8..12) else {
        return Err(syntax(
            file,
            Location::None,
            format!(
                "the GLB header is cut short: {} bytes of its 12",
                bytes.len()
            ),
        ));
    };
    let declared = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
    if declared < 12 {
        return Err(syntax(
            file,
            Location::None,
            format!(
                "the GLB header declares a total length of {declared} bytes, less than the header's own 12"
            ),
        ));
    }
    if declared > bytes.len() {
        return Err(syntax(
            file,
            Location::None,
            format!(
                "the GLB header declares {declared} bytes, but the file has {}",
                bytes.len()
            ),
        ));
    }
    Ok(())
}

/// gltf-json 1.4's validation looks up a primitive's `POSITION` accessor without a bounds
/// check (`primitive_validate_hook` in its mesh.rs), so a file whose `POSITION` index is past
/// the end of `accessors` panics inside `Gltf::from_slice`; `catch_unwind` turned that into an
/// error, but the panic message still reached stderr. This checks those indices on the
/// document exactly as gltf deserialised it, before its validation runs. (A check on the raw
/// JSON missed files that serde_json's `Value` rejects but gltf's reader accepts: an unknown
/// key holding invalid UTF-8 is skipped unread, and then `accessors` is simply absent.)
fn check_position_accessors(root: &::gltf::json::Root, file: &str) -> Result<(), SceneError> {
    use ::gltf::json::mesh::Semantic;
    use ::gltf::json::validation::Checked;
    let len = root.accessors.len() as u64;
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let Some(index) = primitive
                .attributes
                .get(&Checked::Valid(Semantic::Positions))
            else {
                continue;
            };
            let index = index.value() as u64;
            if index >= len {
                return Err(SceneError::IndexOutOfRange {
                    file: file.to_string(),
                    at: Location::path(format!("meshes[{m}].primitives[{p}].attributes.POSITION")),
                    what: "accessor".into(),
                    index,
                    len,
                });
            }
        }
    }
    Ok(())
}

/// `Gltf::from_slice` in two steps, so that [`check_position_accessors`] runs between reading
/// and validating (gltf's own `Document::validate` is private; this is its body).
fn parse_gltf(bytes: &[u8], file: &str) -> Result<::gltf::Gltf, SceneError> {
    use ::gltf::json::validation::Validate;
    let gltf =
        ::gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| map_gltf_error(file, e))?;
    let root = gltf.document.as_json();
    check_position_accessors(root, file)?;
    let mut errors = Vec::new();
    root.validate(root, ::gltf::json::Path::new, &mut |path, error| {
        errors.push((path(), error))
    });
    if errors.is_empty() {
        Ok(gltf)
    } else {
        Err(map_gltf_error(file, ::gltf::Error::Validation(errors)))
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
    check_glb_header(&bytes, &file)?;
    let gltf = std::panic::catch_unwind(|| parse_gltf(&bytes, &file)).map_err(|_| {
        syntax(
            &file,
            Location::None,
            "the glTF parser panicked on this file",
        )
    })??;
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
                            fov: p.yfov().to_degrees(),
                            fov_axis: crate::model::FovAxis::Vertical,
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
