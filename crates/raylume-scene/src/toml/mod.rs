//! The raylume TOML scene format (the contract in `docs/SCENE_FORMAT.md`). Every key is parsed; unknown
//! keys, keys that do not apply to a material's type, wrong types and bad values are errors
//! with `file:line:column`.
//!
//! Defaults: `[camera] up = [0, 1, 0]` (`position`, `look_at` and one of `vfov` (vertical) or
//! `hfov` (horizontal field of view, degrees) are required; the camera keeps that axis when
//! the image size changes; without a `[camera]` table the camera frames the scene's bounding
//! box, as for a bare mesh);
//! `[render]` keys default to [`RenderSettings::default`](crate::RenderSettings); materials:
//! `albedo = [0.8, 0.8, 0.8]`, `emission = [0, 0, 0]`, `roughness = 0`, `ior = 1.5`,
//! `tint = [1, 1, 1]`; `[environment] strength = 1`, `rotation = 0`; `[[mesh]]` transform is
//! the identity. `[post.bloom]` needs all three keys. An emissive material emits from the
//! front faces of its surfaces only (a quad's `u x v` side, a mesh's counter-clockwise side, a
//! sphere's outside) unless it says `two_sided = true`.
//!
//! `texture = "file.png"` on a diffuse, metal or plastic material is an albedo texture
//! (png/jpg, sRGB; multiplied with `albedo`).
//!
//! Geometry conventions: a `[[quad]]` becomes the triangles (corner, corner+u, corner+u+v) and
//! (corner, corner+u+v, corner+v), so its front side is `u x v`; `[[mesh]]` `rotate` is in
//! degrees about X, then Y, then Z (fixed axes, `R = Rz Ry Rx`), exact at right angles; a
//! negative `scale` component mirrors the mesh (winding is swapped so fronts stay fronts), a
//! zero one is an error. Materials are numbered in file order.

use std::collections::HashMap;
use std::path::Path;

use ::toml::Spanned;
use glam::Vec3;

use crate::builder::{MeshOptions, SceneBuilder};
use crate::error::{Location, SceneError};
use crate::model::{
    Bloom, Camera, Environment, FovAxis, Material, MaterialKind, Scene, Sphere, Triangle,
};
use crate::transform::{Xform, frame_bounds};
use crate::validate::{check_camera_frame, check_vfov};
use schema::{MaterialToml, SceneToml, V3, map_toml_error};

mod schema;

/// Conversion state: the text (for spans), the label, the folder paths are relative to.
struct Ctx<'a> {
    text: &'a str,
    file: &'a str,
    dir: &'a Path,
}

impl Ctx<'_> {
    fn at<T>(&self, s: &Spanned<T>) -> Location {
        Location::from_offset(self.text, s.span().start)
    }

    /// "file:line:col" of a span, for `referenced_by`.
    fn place<T>(&self, s: &Spanned<T>) -> String {
        format!("{}{}", self.file, self.at(s))
    }

    fn finite(&self, v: &V3, what: &str) -> Result<Vec3, SceneError> {
        let x = Vec3::from_array(*v.get_ref());
        if !x.is_finite() {
            return Err(SceneError::NotFinite {
                file: self.file.into(),
                at: self.at(v),
                what: what.into(),
            });
        }
        Ok(x)
    }

    fn finite1(&self, v: &Spanned<f32>, what: &str) -> Result<f32, SceneError> {
        let x = *v.get_ref();
        if !x.is_finite() {
            return Err(SceneError::NotFinite {
                file: self.file.into(),
                at: self.at(v),
                what: what.into(),
            });
        }
        Ok(x)
    }

    fn non_negative(&self, v: &V3, what: &str) -> Result<Vec3, SceneError> {
        let x = self.finite(v, what)?;
        if x.min_element() < 0.0 {
            return Err(SceneError::Negative {
                file: self.file.into(),
                at: self.at(v),
                what: what.into(),
                value: x.min_element() as f64,
            });
        }
        Ok(x)
    }

    fn positive_u32(&self, v: &Spanned<u32>, what: &str) -> Result<u32, SceneError> {
        if *v.get_ref() == 0 {
            return Err(SceneError::NonPositive {
                file: self.file.into(),
                at: self.at(v),
                what: what.into(),
                value: 0.0,
            });
        }
        Ok(*v.get_ref())
    }

    fn material(
        &self,
        b: &mut SceneBuilder,
        name: &str,
        m: &Spanned<MaterialToml>,
    ) -> Result<Material, SceneError> {
        let mt = m.get_ref();
        let kind = match mt.kind.get_ref().as_str() {
            "diffuse" => MaterialKind::Diffuse,
            "metal" => MaterialKind::Metal,
            "glass" => MaterialKind::Glass,
            "plastic" => MaterialKind::Plastic,
            other => {
                return Err(SceneError::InvalidValue {
                    file: self.file.into(),
                    at: self.at(&mt.kind),
                    message: format!(
                        "material type `{other}`, expected `diffuse`, `metal`, `glass` or \
                         `plastic`"
                    ),
                });
            }
        };
        // Keys that do not apply to this type are errors (typo protection).
        let applies: &[&str] = match kind {
            MaterialKind::Diffuse => &["albedo", "texture"],
            MaterialKind::Metal => &["albedo", "texture", "roughness", "conductor", "eta", "k"],
            MaterialKind::Glass => &["roughness", "ior", "tint"],
            MaterialKind::Plastic => &["albedo", "texture", "roughness", "ior"],
        };
        let given = [
            ("albedo", mt.albedo.as_ref().map(|s| self.at(s))),
            ("texture", mt.texture.as_ref().map(|s| self.at(s))),
            ("roughness", mt.roughness.as_ref().map(|s| self.at(s))),
            ("ior", mt.ior.as_ref().map(|s| self.at(s))),
            ("tint", mt.tint.as_ref().map(|s| self.at(s))),
            ("conductor", mt.conductor.as_ref().map(|s| self.at(s))),
            ("eta", mt.eta.as_ref().map(|s| self.at(s))),
            ("k", mt.k.as_ref().map(|s| self.at(s))),
        ];
        for (key, at) in given {
            if let (Some(at), false) = (at, applies.contains(&key)) {
                return Err(SceneError::UnknownKey {
                    file: self.file.into(),
                    at,
                    key: key.into(),
                    message: format!("does not apply to a {} material", mt.kind.get_ref()),
                });
            }
        }
        let mut out = Material::diffuse(name, Vec3::splat(0.8));
        out.kind = kind;
        out.roughness = if kind == MaterialKind::Diffuse {
            1.0
        } else {
            0.0
        };
        match (&mt.conductor, &mt.eta, &mt.k) {
            (None, None, None) => {}
            (Some(c), None, None) => {
                let (eta, k) =
                    crate::conductor_ior(c.get_ref()).ok_or_else(|| SceneError::InvalidValue {
                        file: self.file.into(),
                        at: self.at(c),
                        message: format!(
                            "unknown conductor `{}`, expected one of {}",
                            c.get_ref(),
                            crate::conductors::conductor_names_list()
                        ),
                    })?;
                (out.conductor_eta, out.conductor_k) = (eta, k);
            }
            (None, Some(eta), Some(k)) => {
                out.conductor_eta = self.non_negative(eta, "eta")?;
                out.conductor_k = self.non_negative(k, "k")?;
            }
            (Some(c), _, _) => {
                return Err(SceneError::InvalidValue {
                    file: self.file.into(),
                    at: self.at(c),
                    message: "a metal takes `conductor` or `eta` and `k`, not both".into(),
                });
            }
            (None, Some(e), None) => {
                return Err(SceneError::MissingKey {
                    file: self.file.into(),
                    at: self.at(e),
                    key: "k".into(),
                });
            }
            (None, None, Some(k)) => {
                return Err(SceneError::MissingKey {
                    file: self.file.into(),
                    at: self.at(k),
                    key: "eta".into(),
                });
            }
        }
        if let Some(a) = &mt.albedo {
            out.albedo = self.non_negative(a, "albedo")?;
        }
        if let Some(e) = &mt.emission {
            out.emission = self.non_negative(e, "emission")?;
        }
        if let Some(t) = &mt.two_sided {
            if !out.is_emissive() {
                return Err(SceneError::InvalidValue {
                    file: self.file.into(),
                    at: self.at(t),
                    message: "`two_sided` says which faces emit: it needs a nonzero `emission`"
                        .into(),
                });
            }
            out.two_sided = *t.get_ref();
        }
        if let Some(t) = &mt.tint {
            out.tint = self.non_negative(t, "tint")?;
        }
        if let Some(r) = &mt.roughness {
            let x = self.finite1(r, "roughness")?;
            if !(0.0..=1.0).contains(&x) {
                return Err(SceneError::InvalidValue {
                    file: self.file.into(),
                    at: self.at(r),
                    message: format!("roughness {x} is outside [0, 1]"),
                });
            }
            out.roughness = x;
        }
        if let Some(i) = &mt.ior {
            let x = self.finite1(i, "ior")?;
            crate::validate::positive(self.file, &self.at(i), "ior", x as f64)?;
            out.ior = x;
        }
        if let Some(t) = &mt.texture {
            let path = self.dir.join(t.get_ref());
            out.albedo_texture = Some(b.texture(&path, &self.place(t))?);
        }
        Ok(out)
    }

    fn lookup(&self, names: &HashMap<String, u32>, s: &Spanned<String>) -> Result<u32, SceneError> {
        names
            .get(s.get_ref())
            .copied()
            .ok_or_else(|| SceneError::UnknownMaterial {
                file: self.file.into(),
                at: self.at(s),
                name: s.get_ref().clone(),
            })
    }
}

/// Parses a TOML scene (see the module docs). `base_dir`: where relative paths start;
/// `file`: the label used in messages.
pub(crate) fn parse(text: &str, base_dir: &Path, file: &str) -> Result<Scene, SceneError> {
    if text.len() as u64 > crate::limits::MAX_DESCRIPTION_BYTES {
        return Err(SceneError::TooLarge {
            file: file.into(),
            at: Location::None,
            what: "the file size in bytes".into(),
            count: text.len() as u64,
            limit: crate::limits::MAX_DESCRIPTION_BYTES,
        });
    }
    // Syntax first, so that a syntax error is never reported as a type error.
    if let Err(e) = text.parse::<::toml::Table>() {
        return Err(SceneError::Syntax {
            file: file.into(),
            at: e
                .span()
                .map_or(Location::None, |s| Location::from_offset(text, s.start)),
            message: e.message().trim().to_string(),
        });
    }
    let doc: SceneToml = ::toml::from_str(text).map_err(|e| map_toml_error(text, file, &e))?;
    let cx = Ctx {
        text,
        file,
        dir: base_dir,
    };
    let mut b = SceneBuilder::new(file);

    // Materials, in file order.
    let mut entries: Vec<_> = doc.materials.iter().collect();
    entries.sort_by_key(|(k, _)| k.span().start);
    let mut names = HashMap::new();
    for (name, m) in entries {
        let mat = cx.material(&mut b, name.get_ref(), m)?;
        let i = b.add_material(mat, file, cx.at(name))?;
        names.insert(name.get_ref().clone(), i);
    }

    if let Some(r) = &doc.render {
        if let Some(w) = &r.width {
            b.scene.render.width = cx.positive_u32(w, "width")?;
        }
        if let Some(h) = &r.height {
            b.scene.render.height = cx.positive_u32(h, "height")?;
        }
        if let Some(s) = &r.spp {
            b.scene.render.spp = cx.positive_u32(s, "spp")?;
        }
        if let Some(m) = r.max_bounces {
            b.scene.render.max_bounces = m;
        }
        if let Some(s) = r.seed {
            b.scene.render.seed = s;
        }
    }

    if let Some(env) = &doc.environment {
        let e = env.get_ref();
        let strength = match &e.strength {
            Some(s) => {
                let x = cx.finite1(s, "strength")?;
                if x < 0.0 {
                    return Err(SceneError::Negative {
                        file: file.into(),
                        at: cx.at(s),
                        what: "strength".into(),
                        value: x as f64,
                    });
                }
                x
            }
            None => 1.0,
        };
        let rotation = match &e.rotation {
            Some(r) => cx.finite1(r, "rotation")?,
            None => 0.0,
        };
        b.scene.environment = match (&e.radiance, &e.map) {
            (Some(_), Some(m)) => {
                return Err(SceneError::InvalidValue {
                    file: file.into(),
                    at: cx.at(m),
                    message: "[environment] takes `radiance` or `map`, not both".into(),
                });
            }
            (None, None) => {
                return Err(SceneError::MissingKey {
                    file: file.into(),
                    at: cx.at(env),
                    key: "radiance` or `map".into(),
                });
            }
            (Some(r), None) => Environment::Constant(cx.non_negative(r, "radiance")? * strength),
            (None, Some(m)) => {
                let path = base_dir.join(m.get_ref());
                let (image, negatives) = crate::image_io::load_environment(&path, &cx.place(m))?;
                if negatives > 0 {
                    b.warn(format!(
                        "{}: {negatives} negative texels clamped to 0",
                        path.display()
                    ));
                }
                Environment::Map {
                    image,
                    strength,
                    rotation,
                }
            }
        };
    }

    for mesh in &doc.mesh {
        let m = mesh.get_ref();
        let translate = m
            .translate
            .as_ref()
            .map(|t| cx.finite(t, "translate"))
            .transpose()?
            .unwrap_or(Vec3::ZERO);
        let rotate = m
            .rotate
            .as_ref()
            .map(|r| cx.finite(r, "rotate"))
            .transpose()?
            .unwrap_or(Vec3::ZERO);
        let scale = match &m.scale {
            Some(s) => {
                let v = s.get_ref().0;
                if !v.is_finite() {
                    return Err(SceneError::NotFinite {
                        file: file.into(),
                        at: cx.at(s),
                        what: "scale".into(),
                    });
                }
                if v.cmpeq(Vec3::ZERO).any() {
                    return Err(SceneError::NonPositive {
                        file: file.into(),
                        at: cx.at(s),
                        what: "scale (a zero factor flattens the mesh)".into(),
                        value: 0.0,
                    });
                }
                v
            }
            None => Vec3::ONE,
        };
        let material = m
            .material
            .as_ref()
            .map(|s| cx.lookup(&names, s))
            .transpose()?;
        let path = base_dir.join(m.file.get_ref());
        let opts = MeshOptions {
            xform: Xform::from_srt(scale, rotate, translate),
            material,
            referenced_by: Some(cx.place(&m.file)),
        };
        crate::load_mesh_into(&mut b, &path, &opts)?;
    }

    for s in &doc.sphere {
        let sp = s.get_ref();
        let center = cx.finite(&sp.center, "center")?;
        let radius = cx.finite1(&sp.radius, "radius")?;
        crate::validate::positive(file, &cx.at(&sp.radius), "radius", radius as f64)?;
        let material = cx.lookup(&names, &sp.material)?;
        if b.scene.spheres.len() >= crate::limits::MAX_SPHERES {
            return Err(SceneError::TooLarge {
                file: file.into(),
                at: cx.at(s),
                what: "the sphere count".into(),
                count: b.scene.spheres.len() as u64 + 1,
                limit: crate::limits::MAX_SPHERES as u64,
            });
        }
        b.scene.spheres.push(Sphere {
            center,
            radius,
            material,
        });
        b.sphere_labels.push(cx.place(s));
    }

    for q in &doc.quad {
        let qt = q.get_ref();
        let corner = cx.finite(&qt.corner, "corner")?;
        let u = cx.finite(&qt.u, "u")?;
        let v = cx.finite(&qt.v, "v")?;
        let area = u.cross(v).length();
        crate::validate::positive(file, &cx.at(q), "quad area |u x v|", area as f64)?;
        let material = cx.lookup(&names, &qt.material)?;
        b.begin_source(&format!("[[quad]] at {}", cx.place(q)));
        b.reserve_triangles(2, file, cx.at(q))?;
        b.push_triangle(Triangle::flat(
            [corner, corner + u, corner + u + v],
            material,
        ));
        b.push_triangle(Triangle::flat(
            [corner, corner + u + v, corner + v],
            material,
        ));
    }

    if let Some(post) = &doc.post
        && let Some(bl) = &post.bloom
    {
        let bt = bl.get_ref();
        let threshold = cx.finite1(&bt.threshold, "threshold")?;
        let strength = cx.finite1(&bt.strength, "strength")?;
        for (x, s, what) in [
            (threshold, &bt.threshold, "threshold"),
            (strength, &bt.strength, "strength"),
        ] {
            if x < 0.0 {
                return Err(SceneError::Negative {
                    file: file.into(),
                    at: cx.at(s),
                    what: what.into(),
                    value: x as f64,
                });
            }
        }
        let radius = cx.positive_u32(&bt.radius, "radius")?;
        b.scene.post.bloom = Some(Bloom {
            threshold,
            radius,
            strength,
        });
    }

    b.scene.camera = match &doc.camera {
        Some(c) => {
            let ct = c.get_ref();
            let position = cx.finite(&ct.position, "position")?;
            let look_at = cx.finite(&ct.look_at, "look_at")?;
            let up = ct
                .up
                .as_ref()
                .map(|u| cx.finite(u, "up"))
                .transpose()?
                .unwrap_or(Vec3::Y);
            let (key, fov, fov_axis) = match (&ct.vfov, &ct.hfov) {
                (Some(v), None) => ("vfov", v, FovAxis::Vertical),
                (None, Some(h)) => ("hfov", h, FovAxis::Horizontal),
                (Some(_), Some(h)) => {
                    return Err(SceneError::InvalidValue {
                        file: file.into(),
                        at: cx.at(h),
                        message: "[camera] takes `vfov` or `hfov`, not both".into(),
                    });
                }
                (None, None) => {
                    return Err(SceneError::MissingKey {
                        file: file.into(),
                        at: cx.at(c),
                        key: "vfov` or `hfov".into(),
                    });
                }
            };
            let at_fov = cx.at(fov);
            let fov = cx.finite1(fov, key)?;
            check_vfov(file, &at_fov, fov)?;
            let at = ct.up.as_ref().map_or_else(|| cx.at(c), |u| cx.at(u));
            check_camera_frame(file, &at, position, look_at, up)?;
            Camera {
                position,
                look_at,
                up,
                fov,
                fov_axis,
            }
        }
        None => frame_bounds(b.scene.bounds()),
    };
    b.finish()
}
