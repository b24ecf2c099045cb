//! Tungsten BSDFs -> raylume materials. The mapping (a warning is pushed for every row that is
//! not exact):
//!
//! | Tungsten | raylume | exact? |
//! | --- | --- | --- |
//! | `lambert` | diffuse | yes |
//! | `oren_nayar`, `phong`, `lambertian_fiber`, `diffuse_transmission` | diffuse (albedo) | no |
//! | `plastic`, `rough_plastic` | plastic (albedo, `ior`, roughness = sqrt(Tungsten's alpha)) | as Mitsuba's `plastic` / `roughplastic` (a `thickness` with nonzero `sigma_a` is dropped with a warning) |
//! | `smooth_coat`, `rough_coat` | the substrate, mapped (coat dropped) | no |
//! | `mirror` | metal, roughness 0 (Fresnel 1) | yes |
//! | `conductor`, `rough_conductor` | metal with the complex IOR of `material` (default `Cu`; [`crate::conductor_ior`], Mitsuba's RGB values) or of `eta`/`k`, albedo scaling its Fresnel term, roughness = sqrt(alpha) | yes (RGB) |
//! | `dielectric`, `rough_dielectric` | glass (ior, tint = albedo, roughness = sqrt(alpha)) | yes |
//! | `thinsheet` | smooth glass (thin-sheet optics dropped) | no |
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

/// Tungsten's roughness is the GGX alpha itself; raylume's is `sqrt(alpha)`.
fn roughness_of_alpha(alpha: f32) -> f32 {
    alpha.max(0.0).sqrt().min(1.0)
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
        if j.key("distribution")
            .is_some_and(|d| d.v.as_str().is_some_and(|d| d != "ggx"))
        {
            Self::approx(b, name, "microfacet distribution other than ggx", "GGX");
        }
        let mut m = match ty {
            "plastic" | "rough_plastic" => {
                if j.key("sigma_a").is_some_and(|s| {
                    s.j().vec3().is_ok_and(|v| v.max_element() > 0.0)
                        || s.v.as_f64().is_some_and(|v| v > 0.0)
                }) {
                    Self::approx(
                        b,
                        name,
                        "plastic with an absorbing coat (sigma_a)",
                        "a clear coat",
                    );
                }
                let (albedo, tex) = self.albedo(b, j, name)?;
                let roughness = if ty == "rough_plastic" {
                    roughness_of_alpha(f32_or("roughness", 0.1)?)
                } else {
                    0.0
                };
                let mut m = Material::plastic(name, albedo, f32_or("ior", 1.5)?, roughness);
                m.albedo_texture = tex;
                m
            }
            "lambert" | "oren_nayar" | "phong" | "lambertian_fiber" | "diffuse_transmission" => {
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
                        let (eta, k) =
                            crate::conductor_ior("Cu").unwrap_or((Vec3::ZERO, Vec3::ONE));
                        Material::conductor(name, eta, k, Vec3::ONE, roughness_of_alpha(0.1))
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
                let (eta, k) = match (j.key("eta"), j.key("k")) {
                    (Some(eta), Some(k)) => (eta.j().vec3()?, k.j().vec3()?),
                    _ => {
                        let metal = match j.key("material") {
                            Some(n) => n.j().str()?.to_string(),
                            None => "Cu".to_string(),
                        };
                        match crate::conductor_ior(&metal) {
                            Some(ior) => ior,
                            None => {
                                b.warn(format!(
                                    "material '{name}': conductor '{metal}' is not one of the named \
                                     conductors ({}): Fresnel 1 used",
                                    crate::conductors::conductor_names_list()
                                ));
                                (Vec3::ZERO, Vec3::ONE)
                            }
                        }
                    }
                };
                let alpha = if ty == "rough_conductor" {
                    f32_or("roughness", 0.1)?
                } else {
                    0.0
                };
                let (albedo, tex) = self.albedo(b, j, name)?;
                let mut m = Material::conductor(name, eta, k, albedo, roughness_of_alpha(alpha));
                m.albedo_texture = tex;
                m
            }
            "dielectric" | "rough_dielectric" | "thinsheet" => {
                if ty == "thinsheet" {
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
                let mut m = Material::glass(name, f32_or("ior", 1.5)?, tint);
                if ty == "rough_dielectric" {
                    m.roughness = roughness_of_alpha(f32_or("roughness", 0.1)?);
                }
                m
            }
            "transparency" => {
                Self::approx(b, name, ty, "its base BSDF (alpha dropped)");
                if let Some(alpha) = j.key("alpha")
                    && let Some(f) = alpha.v.as_str()
                {
                    let p = self.dir.join(f);
                    if !p.exists() {
                        return Err(SceneError::MissingFile {
                            path: p,
                            referenced_by: Some(format!("{}: {}", self.file, alpha.path)),
                        });
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
    fn tungsten_roughness_is_alpha() {
        // raylume's alpha = roughness^2, so Tungsten's alpha 0.15 is raylume roughness 0.387.
        assert!((roughness_of_alpha(0.15).powi(2) - 0.15).abs() < 1e-7);
        assert_eq!(roughness_of_alpha(-1.0), 0.0);
        assert_eq!(roughness_of_alpha(4.0), 1.0);
    }
}
