//! MTL files: parsed by tobj (after [`normalize_mtl`]), mapped to raylume materials as the
//! module docs of `obj` describe.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::scan::{mtl_line_ok, normalize_mtl};
use super::utf8;
use crate::builder::{SceneBuilder, read_file};
use crate::error::{Location, SceneError};
use crate::model::Material;

pub(super) type Mtl = (Vec<tobj::Material>, Vec<PathBuf>);

/// Parses one MTL file; the second vector holds each material's MTL path.
pub(super) fn load_mtl(
    path: &Path,
    referenced_by: &str,
) -> Result<tobj::MTLLoadResult, SceneError> {
    let label = path.display().to_string();
    let text = utf8(read_file(path, Some(referenced_by))?, &label)?;
    let normalized = normalize_mtl(&text, &label)?;
    let result = catch_unwind(AssertUnwindSafe(|| {
        tobj::load_mtl_buf(&mut normalized.as_bytes())
    }))
    .map_err(|_| SceneError::Syntax {
        file: label.clone(),
        at: Location::None,
        message: "the MTL parser (tobj) panicked on this file".into(),
    })?;
    if let Err(e) = &result {
        let at = text
            .lines()
            .position(|l| !mtl_line_ok(l))
            .map_or(Location::None, |i| Location::Line(i + 1));
        return Err(SceneError::Syntax {
            file: label,
            at,
            message: e.to_string(),
        });
    }
    Ok(result)
}

/// Parses "r g b" or "r" (an MTL colour in an unknown-parameter string).
pub(super) fn parse_color(s: &str) -> Option<Vec3> {
    let v: Vec<f32> = s
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .ok()?;
    match v.as_slice() {
        [r] => Some(Vec3::splat(*r)),
        [r, g, b] => Some(Vec3::new(*r, *g, *b)),
        _ => None,
    }
}

/// `(2 / (Ns + 2))^(1/4)`, see the module docs.
pub(crate) fn roughness_from_ns(ns: Option<f32>) -> f32 {
    match ns {
        None => 0.0,
        Some(ns) if ns.is_finite() => (2.0 / (ns.max(0.0) + 2.0)).sqrt().sqrt().clamp(0.0, 1.0),
        Some(ns) => ns, // NaN/Inf: validation reports the material
    }
}

/// Converts one MTL material (see the module docs for the mapping).
pub(super) fn convert(
    b: &mut SceneBuilder,
    m: &tobj::Material,
    mtl_path: &Path,
) -> Result<Material, SceneError> {
    let v3 = |c: Option<[f32; 3]>, d: f32| c.map_or(Vec3::splat(d), Vec3::from_array);
    let kd = v3(m.diffuse, 0.8);
    let ks = v3(m.specular, 0.0);
    let ke = v3(m.emissive, 0.0);
    let dissolve = m.dissolve.or_else(|| {
        m.unknown_param
            .get("Tr")
            .and_then(|t| t.trim().parse::<f32>().ok())
            .map(|t| 1.0 - t)
    });
    let illum = m.illumination_model;
    let glass = matches!(illum, Some(4 | 6 | 7))
        || (m.optical_density.is_some() && dissolve.is_some_and(|d| d < 1.0));
    let metal = !glass
        && ks.max_element() > 0.0
        && (illum == Some(3) || ks.max_element() > kd.max_element());
    let mut out = if glass {
        let tint = match m.unknown_param.get("Tf") {
            Some(tf) => match parse_color(tf) {
                Some(c) => c,
                None => {
                    b.warn(format!(
                        "material '{}' in {}: Tf `{tf}` not understood, white tint used",
                        m.name,
                        mtl_path.display()
                    ));
                    Vec3::ONE
                }
            },
            None => Vec3::ONE,
        };
        Material::glass(&m.name, m.optical_density.unwrap_or(1.5), tint)
    } else if metal {
        Material::metal(&m.name, ks, roughness_from_ns(m.shininess))
    } else {
        Material::diffuse(&m.name, kd)
    };
    out.emission = ke;
    if let Some(map) = &m.diffuse_texture {
        if glass {
            b.warn(format!("material '{}': map_Kd ignored on glass", m.name));
        } else {
            // Options such as `-s 1 1 1 file.png` precede the file name: keep the last word.
            let file = if map.trim_start().starts_with('-') {
                b.warn(format!(
                    "material '{}': map_Kd options in `{map}` ignored",
                    m.name
                ));
                map.split_whitespace().last().unwrap_or(map)
            } else {
                map.trim()
            };
            let dir = mtl_path.parent().unwrap_or(Path::new(""));
            let referenced_by = format!("{}: material `{}` map_Kd", mtl_path.display(), m.name);
            out.albedo_texture = Some(b.texture(&dir.join(file), &referenced_by)?);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ns_maps_to_roughness() {
        assert_eq!(roughness_from_ns(None), 0.0);
        // Ns = 0: alpha = 1, roughness = 1.
        assert!((roughness_from_ns(Some(0.0)) - 1.0).abs() < 1e-6);
        // Ns = 198: alpha = sqrt(2/200) = 0.1, roughness = sqrt(0.1).
        assert!((roughness_from_ns(Some(198.0)) - 0.1f32.sqrt()).abs() < 1e-6);
    }
}
