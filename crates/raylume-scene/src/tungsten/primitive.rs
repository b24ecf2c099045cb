//! Tungsten primitives (quad, cube, sphere, mesh, environment emitters) and the camera.

use std::collections::HashMap;
use std::path::PathBuf;

use glam::{DMat4, DVec3, Vec3};

use super::geometry::{area, cube_triangles, quad_triangles, transform};
use super::json::J;
use super::{TUNGSTEN_ENV_ROTATION, Tungsten};
use crate::builder::{MeshOptions, SceneBuilder};
use crate::error::{Location, SceneError};
use crate::image_io;
use crate::model::{Camera, Environment, FovAxis, Material, Sphere, Triangle};
use crate::transform::Xform;

/// Keys the importer reads on primitives (others are reported in one warning).
const PRIMITIVE_KEYS: [&str; 10] = [
    "type",
    "transform",
    "bsdf",
    "emission",
    "power",
    "file",
    "smooth",
    "recompute_normals",
    "name",
    "backface_culling",
];

impl<'a> Tungsten<'a> {
    /// The emitted radiance of a primitive (`emission`, or `power` over `area`).
    fn emission(&self, p: J, area: impl Fn() -> f32) -> Result<Option<Vec3>, SceneError> {
        if let Some(e) = p.key("emission") {
            if e.v.is_string() || e.v.is_object() {
                return Err(e.j().unsupported("textured emission on a primitive"));
            }
            return Ok(Some(e.j().vec3()?));
        }
        if let Some(pw) = p.key("power") {
            if pw.v.is_string() || pw.v.is_object() {
                return Err(pw.j().unsupported("textured power on a primitive"));
            }
            let a = area();
            if a.is_nan() || a <= 0.0 {
                return Err(SceneError::NonPositive {
                    file: self.file.into(),
                    at: pw.j().at(),
                    what: "the area of an emitter given by power".into(),
                    value: a as f64,
                });
            }
            return Ok(Some(pw.j().vec3()? / (a * std::f32::consts::PI)));
        }
        Ok(None)
    }

    /// The environment from an `infinite_sphere`/`envmap` emitter: a map file or a colour.
    pub(super) fn environment(
        &self,
        b: &mut SceneBuilder,
        e: J,
    ) -> Result<Environment, SceneError> {
        if let Some(f) = e.v.as_str() {
            let path = self.dir.join(f);
            let (image, negatives) =
                image_io::load_environment(&path, &format!("{}: {}", self.file, e.path))?;
            if negatives > 0 {
                b.warn(format!(
                    "{}: {negatives} negative texels clamped to 0",
                    path.display()
                ));
            }
            return Ok(Environment::Map {
                image,
                strength: 1.0,
                rotation: TUNGSTEN_ENV_ROTATION,
            });
        }
        if e.v.is_object() {
            return Err(e.unsupported("a texture object as environment emission"));
        }
        Ok(Environment::Constant(e.vec3()?))
    }

    pub(super) fn set_environment(&self, b: &mut SceneBuilder, env: Environment, at: &str) {
        if !matches!(b.scene.environment, Environment::Black) {
            b.warn(format!(
                "{}: {at}: a second environment emitter replaces the first",
                self.file
            ));
        }
        b.scene.environment = env;
    }

    /// The OBJ file of a `mesh` primitive and who references it (for a missing file's
    /// error), as [`Tungsten::primitive`] reads them; `None` for any other primitive, or a
    /// mesh whose file `primitive` will reject (it reports that error in its turn).
    pub(super) fn mesh_file(&self, p: J) -> Option<(PathBuf, String)> {
        if p.key("type")?.v.as_str()? != "mesh" {
            return None;
        }
        let file_node = p.key("file")?;
        let path = self.dir.join(file_node.v.as_str()?);
        let obj = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        obj.then(|| (path, format!("{}: {}", self.file, file_node.path)))
    }

    /// Adds primitive `p`. A mesh's OBJ file comes parsed in `parsed` when the caller parsed
    /// it ahead ([`Tungsten::mesh_file`]); otherwise it is parsed here.
    pub(super) fn primitive(
        &self,
        b: &mut SceneBuilder,
        p: J,
        materials: &mut HashMap<(String, [u32; 3]), u32>,
        ignored: &mut Vec<String>,
        parsed: Option<Result<crate::obj::ParsedObj, SceneError>>,
    ) -> Result<(), SceneError> {
        let obj = p.object()?;
        for k in obj.keys() {
            if !PRIMITIVE_KEYS.contains(&k.as_str()) {
                ignored.push(format!("{}.{k}", p.path));
            }
        }
        if p.key("backface_culling")
            .is_some_and(|v| v.v.as_bool() == Some(true))
        {
            ignored.push(format!("{}.backface_culling = true", p.path));
        }
        let ty_node = p.key("type").ok_or_else(|| SceneError::MissingKey {
            file: self.file.into(),
            at: p.at(),
            key: "type".into(),
        })?;
        let ty = ty_node.j().str()?;
        let m = match p.key("transform") {
            Some(t) => transform(t.j())?,
            None => DMat4::IDENTITY,
        };
        if !m.is_finite() {
            return Err(SceneError::NotFinite {
                file: self.file.into(),
                at: Location::path(format!("{}.transform", p.path)),
                what: "the transform".into(),
            });
        }
        match ty {
            "infinite_sphere" | "skydome" => {
                let env = if ty == "skydome" {
                    let i = match p.key("intensity") {
                        Some(v) => v.j().f32()?,
                        None => 2.0,
                    };
                    b.warn(format!(
                        "{}: {}: Tungsten 'skydome' (procedural sky) approximated as a constant environment {i}",
                        self.file, p.path
                    ));
                    Environment::Constant(Vec3::splat(i))
                } else {
                    match p.key("emission") {
                        Some(e) => self.environment(b, e.j())?,
                        None => return Err(p.invalid("infinite_sphere without `emission`")),
                    }
                };
                if m != DMat4::IDENTITY {
                    ignored.push(format!(
                        "{}.transform (environments are not rotated)",
                        p.path
                    ));
                }
                self.set_environment(b, env, p.path);
                return Ok(());
            }
            "quad" | "cube" | "mesh" | "sphere" => {}
            other => {
                return Err(ty_node
                    .j()
                    .unsupported(format!("Tungsten primitive type '{other}'")));
            }
        }

        // Geometry first (mesh areas are needed for `power`), then the material.
        let start = b.scene.triangles.len();
        let mut sphere = None;
        let prim_area: f32;
        match ty {
            "quad" => {
                let tris = quad_triangles(&m);
                prim_area = area(&tris);
                b.begin_source(&format!("{} {}", self.file, p.path));
                b.reserve_triangles(2, self.file, p.at())?;
                for t in tris {
                    b.push_triangle(Triangle::flat(t, 0));
                }
            }
            "cube" => {
                let tris = cube_triangles(&m);
                prim_area = area(&tris);
                b.begin_source(&format!("{} {}", self.file, p.path));
                b.reserve_triangles(12, self.file, p.at())?;
                for t in tris {
                    b.push_triangle(Triangle::flat(t, 0));
                }
            }
            "sphere" => {
                let center = m.transform_point3(DVec3::ZERO).as_vec3();
                let radius = (0..3)
                    .map(|i| m.col(i).truncate().length())
                    .fold(0.0f64, f64::max) as f32;
                prim_area = 4.0 * std::f32::consts::PI * radius * radius;
                sphere = Some(Sphere {
                    center,
                    radius,
                    material: 0,
                });
            }
            _ => {
                let file_node = p.key("file").ok_or_else(|| SceneError::MissingKey {
                    file: self.file.into(),
                    at: p.at(),
                    key: "file".into(),
                })?;
                let rel = file_node.j().str()?;
                let path = self.dir.join(rel);
                let referenced_by = format!("{}: {}", self.file, file_node.path);
                let ext = path
                    .extension()
                    .and_then(|e| e.to_str())
                    .map(str::to_ascii_lowercase);
                if ext.as_deref() != Some("obj") {
                    return Err(SceneError::UnsupportedExtension {
                        path,
                        referenced_by: Some(referenced_by),
                        expected: ".obj (Tungsten's .wo3 is not supported)",
                    });
                }
                // Placeholder material 0; set below once the area is known.
                let opts = MeshOptions {
                    xform: Xform::from_mat4(m.as_mat4()),
                    material: Some(0),
                    referenced_by: Some(referenced_by),
                };
                let obj = match parsed {
                    Some(done) => done?,
                    None => crate::obj::parse(&path, false, opts.referenced_by.as_deref())?,
                };
                crate::obj::insert(b, obj, &opts)?;
                let smooth = match p.key("smooth") {
                    Some(s) => s.j().bool()?,
                    None => false,
                };
                if p.key("recompute_normals")
                    .is_some_and(|v| v.v.as_bool() == Some(true))
                {
                    ignored.push(format!(
                        "{}.recompute_normals = true (the file's normals are used)",
                        p.path
                    ));
                }
                if !smooth {
                    for t in &mut b.scene.triangles[start..] {
                        t.normals = None;
                    }
                }
                prim_area = b.scene.triangles[start..]
                    .iter()
                    .map(|t| 0.5 * t.double_area())
                    .filter(|a| a.is_finite())
                    .sum();
            }
        }

        let emission = self.emission(p, || prim_area)?;
        let key_name = match p.key("bsdf") {
            Some(r) => match r.v.as_str() {
                Some(n) => n.to_string(),
                None => format!("{}.bsdf", p.path),
            },
            None => String::new(),
        };
        let bits = emission.unwrap_or(Vec3::ZERO).to_array().map(f32::to_bits);
        let material = match materials.get(&(key_name.clone(), bits)) {
            Some(&i) => i,
            None => {
                let mut mat = match p.key("bsdf") {
                    Some(r) => self.bsdf_ref(b, r.j(), 0)?,
                    None => {
                        b.warn(format!(
                            "{}: {}: no bsdf: the default grey diffuse is used",
                            self.file, p.path
                        ));
                        Material::diffuse("default", Vec3::splat(0.8))
                    }
                };
                let mut emits = false;
                if let Some(e) = emission
                    && (e.max_element() > 0.0 || e.min_element() < 0.0)
                {
                    mat.emission = e;
                    emits = true;
                }
                // The same BSDF may be used with several emissions: keep names apart.
                if materials.keys().any(|(n, _)| *n == key_name) {
                    let role = if emits { " emitter" } else { "" };
                    mat.name = format!("{} ({}{role})", mat.name, p.path);
                }
                let i = b.add_material(mat, self.file, p.at())?;
                materials.insert((key_name, bits), i);
                i
            }
        };
        for t in &mut b.scene.triangles[start..] {
            t.material = material;
        }
        if let Some(mut s) = sphere {
            s.material = material;
            b.scene.spheres.push(s);
            b.sphere_labels.push(format!("{} {}", self.file, p.path));
        }
        Ok(())
    }

    /// The pinhole camera and the resolution.
    pub(super) fn camera(&self, b: &mut SceneBuilder, c: J) -> Result<(), SceneError> {
        match c.key("type").map(|t| t.j().str()).transpose()? {
            Some("pinhole") | None => {}
            Some("thinlens") => b.warn(format!(
                "{}: camera: thin lens approximated as pinhole (no depth of field)",
                self.file
            )),
            Some(other) => return Err(c.unsupported(format!("Tungsten camera type '{other}'"))),
        }
        if let Some(r) = c.key("resolution") {
            let j = r.j();
            let (w, h) = match j.v.as_array() {
                Some(a) if a.len() == 2 => (J { v: &a[0], ..j }.f32()?, J { v: &a[1], ..j }.f32()?),
                _ if j.v.is_number() => (j.f32()?, j.f32()?),
                _ => return Err(j.wrong("a number or [width, height]")),
            };
            if !(w >= 1.0
                && h >= 1.0
                && w.fract() == 0.0
                && h.fract() == 0.0
                && w <= u32::MAX as f32
                && h <= u32::MAX as f32)
            {
                return Err(SceneError::NonPositive {
                    file: self.file.into(),
                    at: j.at(),
                    what: "the resolution (whole pixels)".into(),
                    value: w.min(h) as f64,
                });
            }
            b.scene.render.width = w as u32;
            b.scene.render.height = h as u32;
        }
        let fov = match c.key("fov") {
            Some(f) => f.j().f32()?,
            None => 60.0,
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(SceneError::Vfov {
                file: self.file.into(),
                at: Location::path(format!("{}.fov", c.path)),
                vfov: fov as f64,
            });
        }
        // Tungsten's fov spans the image's width whatever its size (PinholeCamera.cpp).
        let mut cam = Camera {
            fov,
            fov_axis: FovAxis::Horizontal,
            ..Camera::default()
        };
        if let Some(t) = c.key("transform") {
            let m = transform(t.j())?;
            let position = m.transform_point3(DVec3::ZERO);
            cam.position = position.as_vec3();
            cam.look_at = (position + m.z_axis.truncate()).as_vec3();
            cam.up = m.y_axis.truncate().as_vec3();
            if let Some(u) = t.j().key("up") {
                cam.up = u.j().vec3()?;
            }
            if let Some(l) = t.j().key("look_at") {
                cam.look_at = l.j().vec3()?;
            }
        }
        crate::validate::check_camera_frame(
            self.file,
            &Location::path(c.path),
            cam.position,
            cam.look_at,
            cam.up,
        )?;
        b.scene.camera = cam;
        Ok(())
    }
}
