//! Tungsten BSDFs -> raylume materials. The mapping (a warning is pushed for every row that is
//! not exact):
//!
//! | Tungsten | raylume | exact? |
//! | --- | --- | --- |
//! | `lambert` | diffuse | yes |
//! | `oren_nayar`, `phong`, `lambertian_fiber`, `diffuse_transmission` | diffuse (albedo) | no |
//! | `plastic`, `rough_plastic` | diffuse (albedo; the clear coat is dropped) | no |
//! | `smooth_coat`, `rough_coat` | the substrate, mapped (coat dropped) | no |
//! | `mirror` | metal, roughness 0 | yes |
//! | `conductor` | metal, roughness 0, albedo x RGB F0 of `material` (or of `eta`/`k`) | no |
//! | `rough_conductor` | metal, roughness = sqrt(Tungsten's alpha), albedo x F0 | no |
//! | `dielectric` | glass (ior, tint = albedo) | yes |
//! | `rough_dielectric`, `thinsheet` | glass (roughness / thin-sheet optics dropped) | no |
//! | `transparency` | its `base` (alpha dropped; the alpha file must still exist) | no |
//! | `mixed` | `bsdf0` when `ratio >= 0.5`, else `bsdf1` | no |
//! | `null`, `forward` | black diffuse (only emission remains visible) | no |
//!
//! Albedo: a number, `[r, g, b]`, a texture path (albedo 1 x texture), or a texture object
//! (`{"type": "bitmap", "file": ...}` or `{"type": "constant", "value": ...}`).

use glam::Vec3;

use super::Tungsten;
use super::json::J;
use crate::builder::SceneBuilder;
use crate::error::SceneError;
use crate::model::Material;

/// Normal-incidence reflectance (F0) of metals in linear RGB, from Naty Hoffman, "Physics and
/// Math of Shading" (SIGGRAPH 2013 course notes), table of metal F0 values.
const METAL_F0: [(&str, [f32; 3]); 13] = [
    ("Ag", [0.972, 0.960, 0.915]),
    ("Al", [0.913, 0.922, 0.924]),
    ("Au", [1.000, 0.782, 0.344]),
    ("Cu", [0.955, 0.638, 0.538]),
    ("Cr", [0.549, 0.556, 0.554]),
    ("Fe", [0.562, 0.565, 0.578]),
    ("Ni", [0.660, 0.609, 0.526]),
    ("Ni_palik", [0.660, 0.609, 0.526]),
    ("Pt", [0.673, 0.637, 0.585]),
    ("Ti", [0.542, 0.497, 0.449]),
    ("Zn", [0.664, 0.824, 0.850]),
    ("Pd", [0.733, 0.697, 0.652]),
    ("Hg", [0.781, 0.780, 0.778]),
];

/// F0 of a metal by Tungsten's name for it.
pub(crate) fn metal_f0(name: &str) -> Option<Vec3> {
    METAL_F0
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, c)| Vec3::from_array(*c))
}

/// F0 from a complex index of refraction: ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2).
pub(crate) fn f0_from_eta_k(eta: Vec3, k: Vec3) -> Vec3 {
    let k2 = k * k;
    ((eta - 1.0) * (eta - 1.0) + k2) / ((eta + 1.0) * (eta + 1.0) + k2)
}

/// Deepest nesting of BSDFs (transparency of mixed of ...), against reference cycles.
const MAX_DEPTH: usize = 16;

impl Tungsten<'_> {
    /// The albedo of a BSDF (default 1, as in Tungsten) and its texture, if any.
    fn albedo(
        &self,
        b: &mut SceneBuilder,
        bsdf: J,
        name: &str,
    ) -> Result<(Vec3, Option<u32>), SceneError> {
        let Some(a) = bsdf.key("albedo") else {
            return Ok((Vec3::ONE, None));
        };
        let a = a.j();
        if let Some(file) = a.v.as_str() {
            let t = b.texture(&self.dir.join(file), &format!("{}: {}", self.file, a.path))?;
            return Ok((Vec3::ONE, Some(t)));
        }
        if a.v.is_object() {
            let ty = a
                .key("type")
                .ok_or_else(|| a.invalid("texture object without `type`"))?;
            return match ty.j().str()? {
                "bitmap" => {
                    let f = a
                        .key("file")
                        .ok_or_else(|| a.invalid("bitmap texture without `file`"))?;
                    if a.key("gamma_correct")
                        .is_some_and(|g| g.v.as_bool() == Some(false))
                    {
                        b.warn(format!(
                            "material '{name}': {}: gamma_correct = false ignored (8-bit textures are always sRGB-decoded)",
                            a.path
                        ));
                    }
                    let t = b.texture(
                        &self.dir.join(f.j().str()?),
                        &format!("{}: {}", self.file, f.path),
                    )?;
                    Ok((Vec3::ONE, Some(t)))
                }
                "constant" => {
                    let v = a
                        .key("value")
                        .ok_or_else(|| a.invalid("constant texture without `value`"))?;
                    Ok((v.j().vec3()?, None))
                }
                other => Err(a.unsupported(format!("texture type '{other}' as an albedo"))),
            };
        }
        Ok((a.vec3()?, None))
    }

    /// Warns that `ty` of material `name` became `to`.
    fn approx(b: &mut SceneBuilder, name: &str, ty: &str, to: &str) {
        b.warn(format!(
            "material '{name}': Tungsten '{ty}' approximated as {to}"
        ));
    }

    /// A BSDF given by name (a string) or inline (an object).
    pub(super) fn bsdf_ref(
        &self,
        b: &mut SceneBuilder,
        r: J,
        depth: usize,
    ) -> Result<Material, SceneError> {
        match r.v {
            serde_json::Value::String(n) => {
                let Some(&i) = self.bsdf_names.get(n.as_str()) else {
                    return Err(SceneError::UnknownMaterial {
                        file: self.file.to_string(),
                        at: r.at(),
                        name: n.clone(),
                    });
                };
                let path = format!("bsdfs[{i}]");
                let j = J {
                    v: &self.bsdfs[i],
                    path: &path,
                    file: self.file,
                };
                self.bsdf(b, j, n, depth + 1)
            }
            serde_json::Value::Object(_) => {
                let name =
                    r.v.get("name")
                        .and_then(|n| n.as_str())
                        .unwrap_or(r.path)
                        .to_string();
                self.bsdf(b, r, &name, depth + 1)
            }
            _ => Err(r.wrong("a BSDF name or object")),
        }
    }

    /// Maps one BSDF object (see the module table).
    pub(super) fn bsdf(
        &self,
        b: &mut SceneBuilder,
        j: J,
        name: &str,
        depth: usize,
    ) -> Result<Material, SceneError> {
        if depth > MAX_DEPTH {
            return Err(j.invalid("BSDFs nested too deeply (a reference cycle?)"));
        }
        j.object()?;
        let ty_node = j.key("type").ok_or_else(|| SceneError::MissingKey {
            file: self.file.to_string(),
            at: j.at(),
            key: "type".into(),
        })?;
        let ty = ty_node.j().str()?;
        let f32_or = |key: &str, d: f32| -> Result<f32, SceneError> {
            match j.key(key) {
                Some(v) if v.v.is_string() || v.v.is_object() => {
                    Err(v.j().unsupported(format!("a texture for `{key}`")))
                }
                Some(v) => v.j().f32(),
                None => Ok(d),
            }
        };
        if j.key("bump").is_some() {
            b.warn(format!("material '{name}': bump map ignored"));
        }
        let mut m = match ty {
            "lambert"
            | "oren_nayar"
            | "phong"
            | "lambertian_fiber"
            | "diffuse_transmission"
            | "plastic"
            | "rough_plastic" => {
                if ty != "lambert" {
                    Self::approx(b, name, ty, "diffuse");
                }
                let (albedo, tex) = self.albedo(b, j, name)?;
                let mut m = Material::diffuse(name, albedo);
                m.albedo_texture = tex;
                m
            }
            "smooth_coat" | "rough_coat" => {
                Self::approx(b, name, ty, "its substrate (coat dropped)");
                match j.key("substrate") {
                    Some(s) => self.bsdf_ref(b, s.j(), depth)?,
                    // Tungsten's default substrate is a rough conductor (Cu).
                    None => {
                        Material::metal(name, metal_f0("Cu").unwrap_or(Vec3::ONE), 0.1f32.sqrt())
                    }
                }
            }
            "mirror" => {
                let (albedo, tex) = self.albedo(b, j, name)?;
                let mut m = Material::metal(name, albedo, 0.0);
                m.albedo_texture = tex;
                m
            }
            "conductor" | "rough_conductor" => {
                let f0 = match (j.key("eta"), j.key("k")) {
                    (Some(eta), Some(k)) => f0_from_eta_k(eta.j().vec3()?, k.j().vec3()?),
                    _ => {
                        let metal = match j.key("material") {
                            Some(n) => n.j().str()?.to_string(),
                            None => "Cu".to_string(),
                        };
                        match metal_f0(&metal) {
                            Some(f0) => f0,
                            None => {
                                b.warn(format!(
                                    "material '{name}': conductor '{metal}' not in the RGB table: neutral F0 0.9 used"
                                ));
                                Vec3::splat(0.9)
                            }
                        }
                    }
                };
                let alpha = if ty == "rough_conductor" {
                    f32_or("roughness", 0.1)?
                } else {
                    0.0
                };
                Self::approx(b, name, ty, "metal with an RGB albedo x F0 table value");
                let (albedo, tex) = self.albedo(b, j, name)?;
                let mut m = Material::metal(name, albedo * f0, alpha.max(0.0).sqrt().min(1.0));
                m.albedo_texture = tex;
                m
            }
            "dielectric" | "rough_dielectric" | "thinsheet" => {
                if ty != "dielectric" {
                    Self::approx(b, name, ty, "smooth glass");
                }
                if j.key("enable_refraction")
                    .is_some_and(|e| e.v.as_bool() == Some(false))
                {
                    Self::approx(b, name, "dielectric without refraction", "glass");
                }
                let (tint, tex) = self.albedo(b, j, name)?;
                if tex.is_some() {
                    b.warn(format!(
                        "material '{name}': albedo texture ignored on glass"
                    ));
                }
                Material::glass(name, f32_or("ior", 1.5)?, tint)
            }
            "transparency" => {
                Self::approx(b, name, ty, "its base BSDF (alpha dropped)");
                if let Some(alpha) = j.key("alpha") {
                    if let Some(f) = alpha.v.as_str() {
                        let p = self.dir.join(f);
                        if !p.exists() {
                            return Err(SceneError::MissingFile {
                                path: p,
                                referenced_by: Some(format!("{}: {}", self.file, alpha.path)),
                            });
                        }
                    }
                }
                let base = j.key("base").ok_or_else(|| SceneError::MissingKey {
                    file: self.file.to_string(),
                    at: j.at(),
                    key: "base".into(),
                })?;
                self.bsdf_ref(b, base.j(), depth)?
            }
            "mixed" => {
                let ratio = f32_or("ratio", 0.5)?;
                let key = if ratio >= 0.5 { "bsdf0" } else { "bsdf1" };
                Self::approx(
                    b,
                    name,
                    ty,
                    &format!("its heavier component `{key}` (ratio {ratio})"),
                );
                let sub = j.key(key).ok_or_else(|| SceneError::MissingKey {
                    file: self.file.to_string(),
                    at: j.at(),
                    key: key.into(),
                })?;
                self.bsdf_ref(b, sub.j(), depth)?
            }
            "null" | "forward" => {
                Self::approx(b, name, ty, "black diffuse");
                Material::diffuse(name, Vec3::ZERO)
            }
            other => {
                return Err(ty_node
                    .j()
                    .unsupported(format!("Tungsten BSDF type '{other}'")));
            }
        };
        m.name = name.to_string();
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f0_formula_matches_a_known_dielectric_and_the_table() {
        // eta = 1.5, k = 0: F0 = (0.5/2.5)^2 = 0.04.
        let f = f0_from_eta_k(Vec3::splat(1.5), Vec3::ZERO);
        assert!((f - Vec3::splat(0.04)).abs().max_element() < 1e-6);
        // Aluminium at ~550 nm: eta ~ 0.96, k ~ 6.69 gives F0 ~ 0.91; the table says 0.922.
        let al = f0_from_eta_k(Vec3::splat(0.96), Vec3::splat(6.69));
        assert!((al.y - metal_f0("Al").unwrap().y).abs() < 0.02, "{al}");
    }
}
