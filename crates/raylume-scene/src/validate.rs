//! Validation: every loader ends here, and [`Scene::validate`] is public for scenes built by
//! hand.
//!
//! Errors: NaN/Inf anywhere, out-of-range material/texture indices, zero or negative sizes,
//! vfov outside (0, 180), a degenerate camera, negative colours, empty scenes, counts past
//! [`crate::limits`], radiance above [`crate::limits::MAX_RADIANCE`] and bloom strength above
//! [`crate::limits::MAX_BLOOM_STRENGTH`]. Fixed with a warning by loaders (before validation): degenerate
//! triangles are dropped, albedo/tint above 1 are clamped to 1.

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{Location, SceneError};
use crate::limits::{
    MAX_BLOOM_RADIUS, MAX_BLOOM_STRENGTH, MAX_IMAGE_SIZE, MAX_MATERIALS, MAX_RADIANCE, MAX_SPHERES,
    MAX_TEXTURE_SIZE, MAX_TEXTURES, MAX_TRIANGLES,
};
use crate::model::{Environment, Scene, Texels, Texture, Triangle};

/// A triangle source: the first triangle index it produced and a label (a mesh file).
#[derive(Clone, Debug)]
pub(crate) struct Source {
    pub start: usize,
    pub label: String,
}

/// Where primitives came from, for messages.
pub(crate) struct Provenance<'a> {
    pub file: &'a str,
    pub sources: &'a [Source],
    pub sphere_labels: &'a [String],
}

impl Provenance<'_> {
    /// "triangle 12 of meshes/a.obj" (index within its source) or "triangle 12".
    fn triangle(&self, i: usize) -> Location {
        let k = self.sources.partition_point(|s| s.start <= i);
        match k.checked_sub(1).map(|k| &self.sources[k]) {
            Some(s) => Location::path(format!("triangle {} of {}", i - s.start, s.label)),
            None => Location::path(format!("triangle {i}")),
        }
    }

    fn sphere(&self, i: usize) -> Location {
        match self.sphere_labels.get(i) {
            Some(l) => Location::path(format!("sphere {i} ({l})")),
            None => Location::path(format!("sphere {i}")),
        }
    }
}

impl Scene {
    /// Checks every invariant the model documents (see the module docs of `validate`).
    /// Loaders call it before returning; call it on scenes built by hand.
    pub fn validate(&self) -> Result<(), SceneError> {
        validate_with(
            self,
            &Provenance {
                file: "<scene>",
                sources: &[],
                sphere_labels: &[],
            },
        )
    }
}

fn finite3(v: Vec3) -> bool {
    v.is_finite()
}

/// Zero area, or a normal that is not finite once normalised (finite positions assumed).
pub(crate) fn is_degenerate(t: &Triangle) -> bool {
    let [a, b, c] = t.positions;
    let n = (b - a).cross(c - a);
    let len = n.length();
    len.is_nan() || len <= 0.0 || !len.is_finite() || !(n / len).is_finite()
}

pub(crate) fn check_triangle_finite(
    t: &Triangle,
    prov: &Provenance,
    i: usize,
) -> Result<(), SceneError> {
    let bad = |what: &str| SceneError::NotFinite {
        file: prov.file.to_string(),
        at: prov.triangle(i),
        what: what.to_string(),
    };
    if !t.positions.iter().all(|p| finite3(*p)) {
        return Err(bad("a vertex position"));
    }
    if let Some(n) = &t.normals
        && !n.iter().all(|v| finite3(*v))
    {
        return Err(bad("a vertex normal"));
    }
    if let Some(uv) = &t.uvs
        && !uv.iter().all(|v| v.is_finite())
    {
        return Err(bad("a texture coordinate"));
    }
    Ok(())
}

fn too_large(file: &str, what: &str, count: usize, limit: usize) -> Result<(), SceneError> {
    if count > limit {
        return Err(SceneError::TooLarge {
            file: file.to_string(),
            at: Location::None,
            what: what.to_string(),
            count: count as u64,
            limit: limit as u64,
        });
    }
    Ok(())
}

/// Checks a colour: finite and not negative.
fn color(file: &str, at: &Location, what: &str, c: Vec3) -> Result<(), SceneError> {
    if !c.is_finite() {
        return Err(SceneError::NotFinite {
            file: file.to_string(),
            at: at.clone(),
            what: what.to_string(),
        });
    }
    if c.min_element() < 0.0 {
        return Err(SceneError::Negative {
            file: file.to_string(),
            at: at.clone(),
            what: what.to_string(),
            value: c.min_element() as f64,
        });
    }
    Ok(())
}

/// A radiance (already checked finite and not negative) must not exceed [`MAX_RADIANCE`].
fn radiance(file: &str, at: &Location, what: &str, value: f32) -> Result<(), SceneError> {
    if value > MAX_RADIANCE {
        return Err(SceneError::InvalidValue {
            file: file.to_string(),
            at: at.clone(),
            message: format!(
                "{what} {value:e} is above {MAX_RADIANCE:e}, the brightest radiance raylume \
                 accepts (summing such samples would overflow 32-bit floats)"
            ),
        });
    }
    Ok(())
}

/// `what` must be finite and > 0.
pub(crate) fn positive(file: &str, at: &Location, what: &str, v: f64) -> Result<(), SceneError> {
    if !v.is_finite() {
        return Err(SceneError::NotFinite {
            file: file.to_string(),
            at: at.clone(),
            what: what.to_string(),
        });
    }
    if v <= 0.0 {
        return Err(SceneError::NonPositive {
            file: file.to_string(),
            at: at.clone(),
            what: what.to_string(),
            value: v,
        });
    }
    Ok(())
}

fn texture(file: &str, at: &Location, t: &Texture) -> Result<(), SceneError> {
    positive(file, at, "texture width", t.width as f64)?;
    positive(file, at, "texture height", t.height as f64)?;
    too_large(
        file,
        "texture width",
        t.width as usize,
        MAX_TEXTURE_SIZE as usize,
    )?;
    too_large(
        file,
        "texture height",
        t.height as usize,
        MAX_TEXTURE_SIZE as usize,
    )?;
    if t.texels.len() != t.width as usize * t.height as usize {
        return Err(SceneError::InvalidValue {
            file: file.to_string(),
            at: at.clone(),
            message: format!(
                "texture `{}` has {} texels, {}x{} needs {}",
                t.name,
                t.texels.len(),
                t.width,
                t.height,
                t.width as usize * t.height as usize
            ),
        });
    }
    // The first bad texel (finite and not negative: `0 <= x < inf`, false for NaN), found on
    // every core in runs of 64k texels: a render validates its scene each time, and the
    // living room's textures are 4.9 M texels (12 ms on one core).
    // 8-bit sRGB codes are all valid colours.
    const RUN: usize = 1 << 16;
    let ok = |c: &[f32; 3]| c.iter().all(|&x| (0.0..f32::INFINITY).contains(&x));
    let bad = match &t.texels {
        Texels::Linear(texels) => texels
            .par_chunks(RUN)
            .enumerate()
            .find_map_first(|(r, run)| run.iter().position(|c| !ok(c)).map(|i| r * RUN + i)),
        Texels::Srgb8(_) => None,
    };
    if let Some(i) = bad {
        let c = Vec3::from_array(t.texels.linear(i));
        {
            let at = Location::path(format!(
                "{} texel ({}, {})",
                match at {
                    Location::Path(p) => p.as_str(),
                    _ => "",
                },
                i % t.width as usize,
                i / t.width as usize
            ));
            color(file, &at, &format!("texture `{}`", t.name), c)?;
        }
    }
    Ok(())
}

/// Every check, in a fixed order; the first failure is returned.
pub(crate) fn validate_with(s: &Scene, prov: &Provenance) -> Result<(), SceneError> {
    let file = prov.file;
    too_large(file, "the triangle count", s.triangles.len(), MAX_TRIANGLES)?;
    too_large(file, "the sphere count", s.spheres.len(), MAX_SPHERES)?;
    too_large(file, "the material count", s.materials.len(), MAX_MATERIALS)?;
    too_large(file, "the texture count", s.textures.len(), MAX_TEXTURES)?;

    // Camera.
    let at = Location::path("camera");
    let c = &s.camera;
    for (what, v) in [
        ("camera position", c.position),
        ("camera look_at", c.look_at),
        ("camera up", c.up),
    ] {
        if !v.is_finite() {
            return Err(SceneError::NotFinite {
                file: file.into(),
                at: at.clone(),
                what: what.into(),
            });
        }
    }
    check_vfov(file, &at, c.fov)?;
    check_camera_frame(file, &at, c.position, c.look_at, c.up)?;

    // Render settings.
    let at = Location::path("render");
    let r = &s.render;
    for (what, v) in [
        ("render width", r.width),
        ("render height", r.height),
        ("render spp", r.spp),
    ] {
        if v == 0 {
            return Err(SceneError::NonPositive {
                file: file.into(),
                at: at.clone(),
                what: what.into(),
                value: 0.0,
            });
        }
    }
    too_large(
        file,
        "render width",
        r.width as usize,
        MAX_IMAGE_SIZE as usize,
    )?;
    too_large(
        file,
        "render height",
        r.height as usize,
        MAX_IMAGE_SIZE as usize,
    )?;

    // Environment.
    let at = Location::path("environment");
    match &s.environment {
        Environment::Black => {}
        Environment::Constant(c) => {
            color(file, &at, "environment radiance", *c)?;
            radiance(file, &at, "environment radiance", c.max_element())?;
        }
        Environment::Map {
            image,
            strength,
            rotation,
        } => {
            texture(file, &at, image)?;
            if !strength.is_finite() || !rotation.is_finite() {
                return Err(SceneError::NotFinite {
                    file: file.into(),
                    at,
                    what: "environment strength/rotation".into(),
                });
            }
            if *strength < 0.0 {
                return Err(SceneError::Negative {
                    file: file.into(),
                    at,
                    what: "environment strength".into(),
                    value: *strength as f64,
                });
            }
            let brightest = (0..image.texels.len())
                .map(|i| image.texels.linear(i))
                .fold(0.0f32, |m, t| m.max(t[0]).max(t[1]).max(t[2]));
            radiance(
                file,
                &at,
                "environment map radiance (brightest texel times strength)",
                brightest * strength,
            )?;
        }
    }

    // Textures.
    for (i, t) in s.textures.iter().enumerate() {
        texture(
            file,
            &Location::path(format!("texture {i} `{}`", t.name)),
            t,
        )?;
    }

    // Materials.
    for (i, m) in s.materials.iter().enumerate() {
        let at = Location::path(format!("material {i} `{}`", m.name));
        color(file, &at, "albedo", m.albedo)?;
        color(file, &at, "emission", m.emission)?;
        radiance(file, &at, "emission", m.emission.max_element())?;
        color(file, &at, "tint", m.tint)?;
        // A conductor's complex index of refraction: finite, not negative (eta = 0 is the
        // lossless conductor). Large values are fine: the Fresnel term tends to 1.
        color(file, &at, "conductor eta", m.conductor_eta)?;
        color(file, &at, "conductor k", m.conductor_k)?;
        for (what, c) in [("albedo", m.albedo), ("tint", m.tint)] {
            if c.max_element() > 1.0 {
                return Err(SceneError::InvalidValue {
                    file: file.into(),
                    at,
                    message: format!(
                        "{what} {:?} is above 1 (loaders clamp it with a warning)",
                        c.to_array()
                    ),
                });
            }
        }
        if !m.roughness.is_finite() || !m.ior.is_finite() {
            return Err(SceneError::NotFinite {
                file: file.into(),
                at,
                what: "roughness or ior".into(),
            });
        }
        if !(0.0..=1.0).contains(&m.roughness) {
            return Err(SceneError::InvalidValue {
                file: file.into(),
                at,
                message: format!("roughness {} is outside [0, 1]", m.roughness),
            });
        }
        positive(file, &at, "ior", m.ior as f64)?;
        if let Some(t) = m.albedo_texture
            && t as usize >= s.textures.len()
        {
            return Err(SceneError::IndexOutOfRange {
                file: file.into(),
                at,
                what: "texture".into(),
                index: t as u64,
                len: s.textures.len() as u64,
            });
        }
    }

    // Triangles, on every core; the error is the first triangle's, as a loop would find.
    let check = |i: usize, t: &Triangle| -> Result<(), SceneError> {
        check_triangle_finite(t, prov, i)?;
        if t.material as usize >= s.materials.len() {
            return Err(SceneError::IndexOutOfRange {
                file: file.into(),
                at: prov.triangle(i),
                what: "material".into(),
                index: t.material as u64,
                len: s.materials.len() as u64,
            });
        }
        if let Some(ns) = &t.normals
            && ns.iter().any(|n| (n.length() - 1.0).abs() > 1e-3)
        {
            return Err(SceneError::InvalidValue {
                file: file.into(),
                at: prov.triangle(i),
                message: "shading normals must have unit length".into(),
            });
        }
        if is_degenerate(t) {
            return Err(SceneError::InvalidValue {
                file: file.into(),
                at: prov.triangle(i),
                message: "zero area or non-finite normal (loaders drop such triangles)".into(),
            });
        }
        Ok(())
    };
    if let Some(e) = s
        .triangles
        .par_iter()
        .enumerate()
        .find_map_first(|(i, t)| check(i, t).err())
    {
        return Err(e);
    }

    // Spheres.
    for (i, sp) in s.spheres.iter().enumerate() {
        let at = prov.sphere(i);
        if !sp.center.is_finite() {
            return Err(SceneError::NotFinite {
                file: file.into(),
                at,
                what: "sphere center".into(),
            });
        }
        positive(file, &at, "sphere radius", sp.radius as f64)?;
        if sp.material as usize >= s.materials.len() {
            return Err(SceneError::IndexOutOfRange {
                file: file.into(),
                at,
                what: "material".into(),
                index: sp.material as u64,
                len: s.materials.len() as u64,
            });
        }
    }

    // Post.
    if let Some(bloom) = &s.post.bloom {
        let at = Location::path("post.bloom");
        for (what, v) in [
            ("bloom threshold", bloom.threshold),
            ("bloom strength", bloom.strength),
        ] {
            color(file, &at, what, Vec3::splat(v))?;
        }
        positive(file, &at, "bloom radius", bloom.radius as f64)?;
        if bloom.strength > MAX_BLOOM_STRENGTH {
            return Err(SceneError::InvalidValue {
                file: file.into(),
                at,
                message: format!(
                    "bloom strength {:e} is above {MAX_BLOOM_STRENGTH:e} (bloom adds strength \
                     times the blurred image, which would overflow)",
                    bloom.strength
                ),
            });
        }
        too_large(
            file,
            "bloom radius",
            bloom.radius as usize,
            MAX_BLOOM_RADIUS as usize,
        )?;
    }

    if s.primitive_count() == 0 {
        return Err(SceneError::EmptyScene { file: file.into() });
    }
    Ok(())
}

/// vfov finite and in (0, 180).
pub(crate) fn check_vfov(file: &str, at: &Location, vfov: f32) -> Result<(), SceneError> {
    if !vfov.is_finite() {
        return Err(SceneError::NotFinite {
            file: file.into(),
            at: at.clone(),
            what: "vfov".into(),
        });
    }
    if !(vfov > 0.0 && vfov < 180.0) {
        return Err(SceneError::Vfov {
            file: file.into(),
            at: at.clone(),
            vfov: vfov as f64,
        });
    }
    Ok(())
}

/// position != look_at, and up not parallel to the view direction.
pub(crate) fn check_camera_frame(
    file: &str,
    at: &Location,
    position: Vec3,
    look_at: Vec3,
    up: Vec3,
) -> Result<(), SceneError> {
    let dir = look_at - position;
    let len = dir.length();
    if len.is_nan() || len <= 0.0 || !len.is_finite() {
        return Err(SceneError::DegenerateCamera {
            file: file.into(),
            at: at.clone(),
            reason: "position equals look_at (no view direction)",
        });
    }
    let up_len = up.length();
    // sin(angle between up and dir) below 1e-6: parallel (or up is zero).
    if up_len.is_nan() || up_len <= 0.0 || dir.cross(up).length() <= 1e-6 * len * up_len {
        return Err(SceneError::DegenerateCamera {
            file: file.into(),
            at: at.clone(),
            reason: "up is zero or parallel to the view direction",
        });
    }
    Ok(())
}
