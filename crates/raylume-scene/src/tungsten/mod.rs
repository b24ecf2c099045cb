//! Tungsten `scene.json` (Benedikt Bitterli's renderer; the format of his "Rendering
//! resources").
//!
//! Conventions, read from Tungsten's source (`src/core/io/JsonPtr.cpp`,
//! `src/core/math/Mat4f.cpp`, `src/core/primitives/{Quad,Cube,Sphere}.cpp`,
//! `src/core/cameras/PinholeCamera.cpp`):
//! - A transform object is `T * R * S`: `scale` (number or vector) scales the axes, then
//!   `rotation` (degrees) applies `Mat4f::rotYXZ`, which is `Ry(-y) * Rx(x) * Rz(z)` (Z first,
//!   and Tungsten's Y angle turns the other way from the right-hand rule), then `position`
//!   translates. A 16-number array is a row-major matrix.
//! - `quad` is the unit square in the xz plane, centred at the origin, corners (+-0.5, 0, +-0.5);
//!   its front (emitting) side is `edge1 x edge0 = z x x = +y` before transforming. raylume's
//!   triangles are wound so that `(p1 - p0) x (p2 - p0)` points to that front side.
//! - `cube` is the unit cube [-0.5, 0.5]^3 with outward faces, triangulated as Tungsten's
//!   `TriangleMesh::makeCube`; `sphere` has radius = the
//!   largest axis scale, centre = the position.
//! - `mesh` loads an OBJ with the primitive's `bsdf` (the OBJ's materials are not used);
//!   `smooth: false` (the default) means flat shading, so the file's normals are dropped.
//! - The pinhole `fov` is horizontal: the image plane spans x in [-1, 1] and
//!   y in [-h/w, h/w] at distance 1/tan(fov/2). raylume's vfov = 2 atan(tan(fov/2) h/w).
//! - `power` on an emitter becomes radiance = power / (area * pi).
//! - `infinite_sphere` and `skydome` primitives, and the top-level `emissions` list (the
//!   111116/toyray-scenes variant, `{"type": "envmap", "radiance": "sky.exr"}`), become the
//!   environment (a map gets [`TUNGSTEN_ENV_ROTATION`] so that it is oriented as in Tungsten).
//!   A missing map file is an error. `skydome` (a procedural sky) becomes a
//!   constant environment of its `intensity`, with a warning.
//! - Render settings: `camera.resolution`, `renderer.spp`, `integrator.max_bounces` are
//!   taken as they are.
//!
//! BSDFs are mapped by [`bsdf`]; keys this importer does not read are listed in a warning.

mod bsdf;
mod json;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DMat4, DVec3, Vec3};
use serde_json::Value;

use crate::builder::{MeshOptions, SceneBuilder, read_description};
use crate::error::{Location, SceneError};
use crate::image_io;
use crate::model::{Camera, Environment, Material, Scene, Sphere, Triangle};
use crate::transform::{Xform, sin_cos_deg};
use json::{J, Owned};

/// Rotation (degrees about +y) that makes raylume's equirectangular lookup (`raylume-kernels`:
/// `u = 0.5 + atan2(d.x, -d.z) / 2 pi + rotation / 360`) read the texel Tungsten's
/// `InfiniteSphere` reads (`u = 0.5 + atan2(d.z, d.x) / 2 pi`): the two angles differ by a
/// quarter turn, `atan2(x, -z) = atan2(z, x) + pi / 2`. Both put the top row at +y.
pub(crate) const TUNGSTEN_ENV_ROTATION: f32 = -90.0;

/// The document being imported.
pub(crate) struct Tungsten<'a> {
    file: &'a str,
    dir: PathBuf,
    bsdfs: &'a [Value],
    bsdf_names: HashMap<&'a str, usize>,
}

/// Tungsten's `Mat4f::rotYXZ`, copied term by term (degrees), in double precision with exact
/// right angles.
pub(crate) fn rot_yxz(rot: DVec3) -> DMat3 {
    let (sx, cx) = sin_cos_deg(rot.x);
    let (sy, cy) = sin_cos_deg(rot.y);
    let (sz, cz) = sin_cos_deg(rot.z);
    let (c, s) = ([cx, cy, cz], [sx, sy, sz]);
    // Rows as written in Tungsten; glam takes columns, hence the transpose.
    DMat3::from_cols(
        DVec3::new(
            c[1] * c[2] - s[1] * s[0] * s[2],
            -c[1] * s[2] - s[1] * s[0] * c[2],
            -s[1] * c[0],
        ),
        DVec3::new(c[0] * s[2], c[0] * c[2], -s[0]),
        DVec3::new(
            s[1] * c[2] + c[1] * s[0] * s[2],
            -s[1] * s[2] + c[1] * s[0] * c[2],
            c[1] * c[0],
        ),
    )
    .transpose()
}

/// Tungsten's Gram-Schmidt (`JsonPtr.cpp`): `a` normalised, `b` and `c` made orthonormal to
/// what precedes them (falling back to an arbitrary orthogonal vector / a cross product).
fn gram_schmidt(a: &mut DVec3, b: &mut DVec3, c: &mut DVec3) {
    *a = a.normalize_or(DVec3::Z);
    *b -= *a * a.dot(*b);
    *b = if b.length_squared() < 1e-5 {
        a.any_orthonormal_vector()
    } else {
        b.normalize()
    };
    *c -= *a * a.dot(*c);
    *c -= *b * b.dot(*c);
    *c = if c.length_squared() < 1e-5 {
        a.cross(*b)
    } else {
        c.normalize()
    };
}

/// A Tungsten transform (object or 16-number row-major array), as `JsonPtr::get(Mat4f&)`.
pub(crate) fn transform(t: J) -> Result<DMat4, SceneError> {
    if let Some(a) = t.v.as_array() {
        if a.len() != 16 {
            return Err(t.wrong("an object or an array of 16 numbers"));
        }
        let mut m = [0.0f64; 16];
        for (i, v) in a.iter().enumerate() {
            m[i] = J { v, ..t }.f64()?;
        }
        return Ok(DMat4::from_cols_array(&m).transpose());
    }
    t.object()?;
    let get = |k: &str| -> Result<Option<DVec3>, SceneError> {
        t.key(k).map(|v| v.j().dvec3()).transpose()
    };
    let pos = get("position")?.unwrap_or(DVec3::ZERO);
    let (mut x, mut y, mut z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let look_at = get("look_at")?;
    let up = get("up")?;
    let (xa, ya, za) = (get("x_axis")?, get("y_axis")?, get("z_axis")?);
    let ex = xa.is_some();
    let ey = up.is_some() || ya.is_some();
    let ez = look_at.is_some() || za.is_some();
    if let Some(l) = look_at {
        z = l - pos;
    }
    if let Some(u) = up {
        y = u;
    }
    if let Some(v) = xa {
        x = v;
    }
    if let Some(v) = ya {
        y = v;
    }
    if let Some(v) = za {
        z = v;
    }
    if ex || ey || ez {
        match (ez, ey, ex) {
            (false, false, true) => gram_schmidt(&mut x, &mut z, &mut y),
            (false, true, false) => gram_schmidt(&mut y, &mut z, &mut x),
            (false, true, true) => gram_schmidt(&mut y, &mut x, &mut z),
            (true, false, true) => gram_schmidt(&mut z, &mut x, &mut y),
            _ => gram_schmidt(&mut z, &mut y, &mut x),
        }
        if x.cross(y).dot(z) < 0.0 {
            if !ex {
                x = -x;
            } else if !ey {
                y = -y;
            } else {
                z = -z;
            }
        }
    }
    if let Some(s) = get("scale")? {
        x *= s.x;
        y *= s.y;
        z *= s.z;
    }
    if let Some(r) = get("rotation")? {
        let m = rot_yxz(r);
        x = m * x;
        y = m * y;
        z = m * z;
    }
    Ok(DMat4::from_cols(
        x.extend(0.0),
        y.extend(0.0),
        z.extend(0.0),
        pos.extend(1.0),
    ))
}

/// The unit quad's two triangles, front side = Tungsten's `edge1 x edge0`.
pub(crate) fn quad_triangles(m: &DMat4) -> [[Vec3; 3]; 2] {
    let base = m.transform_point3(DVec3::new(-0.5, 0.0, -0.5));
    let e0 = m.transform_vector3(DVec3::X);
    let e1 = m.transform_vector3(DVec3::Z);
    let (p0, p1, p2, p3) = (
        base.as_vec3(),
        (base + e1).as_vec3(),
        (base + e0 + e1).as_vec3(),
        (base + e0).as_vec3(),
    );
    [[p0, p1, p2], [p0, p2, p3]]
}

/// The unit cube's 12 triangles, outward facing: Tungsten's `TriangleMesh::makeCube`, corner
/// for corner and in its triangle order, so that the diagonals match Tungsten's.
pub(crate) fn cube_triangles(m: &DMat4) -> Vec<[Vec3; 3]> {
    const H: f64 = 0.5;
    const FACES: [[[f64; 3]; 4]; 6] = [
        [[-H, -H, -H], [-H, -H, H], [H, -H, H], [H, -H, -H]],
        [[-H, H, H], [-H, H, -H], [H, H, -H], [H, H, H]],
        [[-H, H, -H], [-H, -H, -H], [H, -H, -H], [H, H, -H]],
        [[H, H, H], [H, -H, H], [-H, -H, H], [-H, H, H]],
        [[-H, H, H], [-H, -H, H], [-H, -H, -H], [-H, H, -H]],
        [[H, H, -H], [H, -H, -H], [H, -H, H], [H, H, H]],
    ];
    let mut out = Vec::with_capacity(12);
    for face in &FACES {
        let p = face.map(|c| m.transform_point3(DVec3::from_array(c)).as_vec3());
        out.push([p[0], p[2], p[1]]);
        out.push([p[0], p[3], p[2]]);
    }
    out
}

fn area(tris: &[[Vec3; 3]]) -> f32 {
    tris.iter()
        .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
        .sum()
}

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
    fn environment(&self, b: &mut SceneBuilder, e: J) -> Result<Environment, SceneError> {
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

    fn set_environment(&self, b: &mut SceneBuilder, env: Environment, at: &str) {
        if !matches!(b.scene.environment, Environment::Black) {
            b.warn(format!(
                "{}: {at}: a second environment emitter replaces the first",
                self.file
            ));
        }
        b.scene.environment = env;
    }

    fn primitive(
        &self,
        b: &mut SceneBuilder,
        p: J,
        materials: &mut HashMap<(String, [u32; 3]), u32>,
        ignored: &mut Vec<String>,
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
                crate::obj::load_into(b, &path, &opts)?;
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
                if let Some(e) = emission {
                    if e.max_element() > 0.0 || e.min_element() < 0.0 {
                        mat.emission = e;
                        emits = true;
                    }
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
    fn camera(&self, b: &mut SceneBuilder, c: J) -> Result<(), SceneError> {
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
        let aspect = b.scene.render.height as f32 / b.scene.render.width as f32;
        let vfov = 2.0
            * ((fov.to_radians() * 0.5).tan() * aspect)
                .atan()
                .to_degrees();
        let mut cam = Camera {
            vfov,
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

/// Loads a Tungsten `scene.json`.
pub(crate) fn load(path: &Path) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = read_description(path, None)?;
    let doc: Value = serde_json::from_slice(&bytes).map_err(|e| SceneError::Syntax {
        file: file.clone(),
        at: Location::LineCol {
            line: e.line(),
            column: e.column(),
        },
        message: e.to_string(),
    })?;
    let root = J {
        v: &doc,
        path: "",
        file: &file,
    };
    root.object()?;
    let no_bsdfs = Vec::new();
    let bsdfs: &[Value] = match doc.get("bsdfs") {
        Some(v) => v.as_array().ok_or_else(|| {
            J {
                v,
                path: "bsdfs",
                file: &file,
            }
            .wrong("an array")
        })?,
        None => &no_bsdfs,
    };
    let mut bsdf_names = HashMap::new();
    for (i, v) in bsdfs.iter().enumerate() {
        let path = format!("bsdfs[{i}]");
        let j = J {
            v,
            path: &path,
            file: &file,
        };
        let name = j.key("name").ok_or_else(|| SceneError::MissingKey {
            file: file.clone(),
            at: j.at(),
            key: "name".into(),
        })?;
        let n = name.j().str()?;
        if bsdf_names.insert(n, i).is_some() {
            return Err(name.j().invalid(format!("a second BSDF named '{n}'")));
        }
    }
    let t = Tungsten {
        file: &file,
        dir: path.parent().unwrap_or(Path::new("")).to_path_buf(),
        bsdfs,
        bsdf_names,
    };
    let mut b = SceneBuilder::new(&file);
    b.scene.render = crate::model::RenderSettings::default();
    let mut ignored = Vec::new();

    if let Some(r) = root.key("renderer") {
        if let Some(spp) = r.j().key("spp") {
            b.scene.render.spp = whole(spp.j())?;
        }
    }
    if let Some(i) = root.key("integrator") {
        if let Some(mb) = i.j().key("max_bounces") {
            b.scene.render.max_bounces = whole(mb.j())?;
        }
    }
    let mut have_camera = false;
    if let Some(c) = root.key("camera") {
        t.camera(&mut b, c.j())?;
        have_camera = true;
    }
    if let Some(m) = root.key("media") {
        if m.v.as_array().is_some_and(|a| !a.is_empty()) {
            ignored.push("media (participating media)".to_string());
        }
    }
    let mut materials = HashMap::new();
    if let Some(prims) = root.key("primitives") {
        let list = prims.j().array()?;
        for i in 0..list.len() {
            let p: Owned = prims.j().index(i).expect("index within the array");
            t.primitive(&mut b, p.j(), &mut materials, &mut ignored)?;
        }
    }
    if let Some(em) = root.key("emissions") {
        let list = em.j().array()?;
        for i in 0..list.len() {
            let e = em.j().index(i).expect("index within the array");
            let e = e.j();
            let ty = e
                .key("type")
                .map(|t| t.j().str().map(str::to_string))
                .transpose()?;
            match ty.as_deref() {
                Some("envmap" | "infinite_sphere") => {
                    let r = e
                        .key("radiance")
                        .or_else(|| e.key("emission"))
                        .ok_or_else(|| e.invalid("environment emitter without `radiance`"))?;
                    let env = t.environment(&mut b, r.j())?;
                    t.set_environment(&mut b, env, e.path);
                }
                _ => return Err(e.unsupported(format!("emission type {ty:?}"))),
            }
        }
    }
    if !ignored.is_empty() {
        b.warn(format!("{file}: ignored: {}", ignored.join(", ")));
    }
    if !have_camera {
        b.scene.camera = crate::transform::frame_bounds(b.scene.bounds());
    }
    b.finish()
}

/// A whole, non-negative number that fits u32.
fn whole(j: J) -> Result<u32, SceneError> {
    let x = j.v.as_u64().ok_or_else(|| j.wrong("a whole number >= 0"))?;
    u32::try_from(x).map_err(|_| SceneError::TooLarge {
        file: j.file.into(),
        at: j.at(),
        what: "the number".into(),
        count: x,
        limit: u32::MAX as u64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn rot_yxz_is_ry_minus_y_rx_rz() {
        // Tungsten's term-by-term matrix equals the composition Ry(-y) Rx(x) Rz(z) built from
        // glam's own rotations, for a generic angle triple.
        let r = DVec3::new(20.0, 35.0, -50.0);
        let want = DMat3::from_rotation_y(-r.y.to_radians())
            * DMat3::from_rotation_x(r.x.to_radians())
            * DMat3::from_rotation_z(r.z.to_radians());
        assert!(rot_yxz(r).abs_diff_eq(want, 1e-12));
    }

    #[test]
    fn unit_quad_faces_plus_y_and_has_unit_area() {
        let tris = quad_triangles(&DMat4::IDENTITY);
        for [a, b, c] in tris {
            let n = (b - a).cross(c - a);
            assert!(n.normalize().abs_diff_eq(Vec3::Y, 1e-6), "{n}");
        }
        assert!((area(&tris) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn unit_cube_faces_point_outward() {
        let tris = cube_triangles(&DMat4::IDENTITY);
        assert_eq!(tris.len(), 12);
        for [a, b, c] in &tris {
            let n = (*b - *a).cross(*c - *a).normalize();
            let centroid = (*a + *b + *c) / 3.0;
            assert!(n.dot(centroid) > 0.0, "inward face {n} at {centroid}");
        }
        assert!((area(&tris) - 6.0).abs() < 1e-5);
    }

    #[test]
    fn camera_style_transform_is_orthonormal_and_right_handed() {
        let v = serde_json::json!({"position": [0, 1, 6.8], "look_at": [0, 1, 0], "up": [0, 1, 0]});
        let m = transform(J {
            v: &v,
            path: "t",
            file: "f",
        })
        .unwrap();
        let c = |v: glam::DVec4| v.truncate().as_vec3();
        assert!(close(c(m.z_axis), -Vec3::Z));
        assert!(close(c(m.y_axis), Vec3::Y));
        assert!(close(c(m.x_axis), Vec3::Y.cross(-Vec3::Z)));
        assert!(close(c(m.w_axis), Vec3::new(0.0, 1.0, 6.8)));
    }
}
