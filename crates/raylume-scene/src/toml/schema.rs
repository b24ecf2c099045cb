//! The serde schema of the TOML format (`deny_unknown_fields` everywhere, spans on every value
//! that later checks may point at) and the mapping of `toml` errors to [`SceneError`].

use std::collections::BTreeMap;
use std::fmt;

use ::toml::Spanned;
use glam::Vec3;
use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};

use crate::error::{Location, SceneError};

pub(super) type V3 = Spanned<[f32; 3]>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneToml {
    pub(super) camera: Option<Spanned<CameraToml>>,
    pub(super) render: Option<RenderToml>,
    pub(super) environment: Option<Spanned<EnvironmentToml>>,
    #[serde(default)]
    pub(super) materials: BTreeMap<Spanned<String>, Spanned<MaterialToml>>,
    #[serde(default)]
    pub(super) mesh: Vec<Spanned<MeshToml>>,
    #[serde(default)]
    pub(super) sphere: Vec<Spanned<SphereToml>>,
    #[serde(default)]
    pub(super) quad: Vec<Spanned<QuadToml>>,
    pub(super) post: Option<PostToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraToml {
    pub(super) position: V3,
    pub(super) look_at: V3,
    pub(super) up: Option<V3>,
    pub(super) vfov: Option<Spanned<f32>>,
    pub(super) hfov: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RenderToml {
    pub(super) width: Option<Spanned<u32>>,
    pub(super) height: Option<Spanned<u32>>,
    pub(super) spp: Option<Spanned<u32>>,
    pub(super) max_bounces: Option<u32>,
    pub(super) seed: Option<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EnvironmentToml {
    pub(super) radiance: Option<V3>,
    pub(super) map: Option<Spanned<String>>,
    pub(super) strength: Option<Spanned<f32>>,
    pub(super) rotation: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialToml {
    #[serde(rename = "type")]
    pub(super) kind: Spanned<String>,
    pub(super) albedo: Option<V3>,
    pub(super) emission: Option<V3>,
    pub(super) roughness: Option<Spanned<f32>>,
    pub(super) ior: Option<Spanned<f32>>,
    pub(super) tint: Option<V3>,
    pub(super) texture: Option<Spanned<String>>,
    pub(super) two_sided: Option<Spanned<bool>>,
    pub(super) conductor: Option<Spanned<String>>,
    pub(super) eta: Option<V3>,
    pub(super) k: Option<V3>,
}

/// `scale = 2.0` or `scale = [1, 2, 3]`.
pub(super) struct Scale(pub(super) Vec3);

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Scale;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Scale, A::Error> {
                let mut out = [0.0f32; 3];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<f32>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Scale(Vec3::from_array(out)))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshToml {
    pub(super) file: Spanned<String>,
    pub(super) material: Option<Spanned<String>>,
    pub(super) translate: Option<V3>,
    pub(super) rotate: Option<V3>,
    pub(super) scale: Option<Spanned<Scale>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SphereToml {
    pub(super) center: V3,
    pub(super) radius: Spanned<f32>,
    pub(super) material: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct QuadToml {
    pub(super) corner: V3,
    pub(super) u: V3,
    pub(super) v: V3,
    pub(super) material: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PostToml {
    pub(super) bloom: Option<Spanned<BloomToml>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BloomToml {
    pub(super) threshold: Spanned<f32>,
    pub(super) radius: Spanned<u32>,
    pub(super) strength: Spanned<f32>,
}

/// The text between the first pair of backquotes (serde names keys that way).
pub(super) fn quoted(msg: &str) -> Option<&str> {
    let a = msg.find('`')? + 1;
    let b = msg[a..].find('`')? + a;
    Some(&msg[a..b])
}

/// Sorts a `toml` error into the right variant.
pub(super) fn map_toml_error(text: &str, file: &str, e: &::toml::de::Error) -> SceneError {
    let at = e
        .span()
        .map_or(Location::None, |s| Location::from_offset(text, s.start));
    let msg = e.message().trim().to_string();
    let file = file.to_string();
    if msg.starts_with("unknown field") {
        let key = quoted(&msg).unwrap_or("?").to_string();
        let message = msg
            .split_once(", ")
            .map_or(msg.clone(), |(_, rest)| rest.to_string());
        SceneError::UnknownKey {
            file,
            at,
            key,
            message,
        }
    } else if msg.starts_with("missing field") {
        let key = quoted(&msg).unwrap_or("?").to_string();
        SceneError::MissingKey { file, at, key }
    } else if msg.starts_with("invalid type")
        || msg.starts_with("invalid length")
        || msg.starts_with("invalid value")
    {
        SceneError::WrongType {
            file,
            at,
            message: msg,
        }
    } else {
        SceneError::InvalidValue {
            file,
            at,
            message: msg,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoted_takes_the_first_backquoted_word() {
        assert_eq!(
            quoted("unknown field `wdth`, expected one of `width`"),
            Some("wdth")
        );
        assert_eq!(quoted("no quotes"), None);
    }
}
