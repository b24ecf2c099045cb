//! Primitives: accessors checked, then read into world-space triangles.

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::Mode;
use glam::{Vec2, Vec3};

use super::{Loader, invalid};
use crate::builder::{SceneBuilder, ShadingNormals};
use crate::error::{Location, SceneError};
use crate::model::Triangle;
use crate::transform::Xform;

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

impl Loader<'_> {
    pub(super) fn primitive(
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
        if let Some(a) = &index_acc
            && !check_accessor(
                a,
                &self.buffers,
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
                &file,
                at,
            )?
        {
            return Ok(());
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
