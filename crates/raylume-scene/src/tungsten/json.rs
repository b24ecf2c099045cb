//! A JSON value with its path (`primitives[3].transform.scale`), for typed errors.

use glam::{DVec3, Vec3};
use serde_json::Value;

use crate::error::{Location, SceneError};

/// A value and where it sits in the document.
#[derive(Clone, Copy)]
pub(crate) struct J<'v, 'p> {
    pub v: &'v Value,
    pub path: &'p str,
    pub file: &'v str,
}

/// An owned path, so that children can borrow it.
pub(crate) struct Owned<'a> {
    pub v: &'a Value,
    pub path: String,
    pub file: &'a str,
}

impl<'a> Owned<'a> {
    pub fn j(&self) -> J<'a, '_> {
        J {
            v: self.v,
            path: &self.path,
            file: self.file,
        }
    }
}

impl<'a> J<'a, '_> {
    pub fn at(&self) -> Location {
        Location::path(self.path)
    }

    pub fn wrong(&self, expected: &str) -> SceneError {
        SceneError::WrongType {
            file: self.file.to_string(),
            at: self.at(),
            message: format!("expected {expected}, found {}", kind(self.v)),
        }
    }

    pub fn invalid(&self, message: impl Into<String>) -> SceneError {
        SceneError::InvalidValue {
            file: self.file.to_string(),
            at: self.at(),
            message: message.into(),
        }
    }

    pub fn unsupported(&self, message: impl Into<String>) -> SceneError {
        SceneError::Unsupported {
            file: self.file.to_string(),
            at: self.at(),
            message: message.into(),
        }
    }

    /// The member `key` of an object (None when absent or when `self` is not an object).
    pub fn key(&self, key: &str) -> Option<Owned<'a>> {
        self.v.get(key).map(|v| Owned {
            v,
            path: if self.path.is_empty() {
                key.to_string()
            } else {
                format!("{}.{key}", self.path)
            },
            file: self.file,
        })
    }

    pub fn index(&self, i: usize) -> Option<Owned<'a>> {
        self.v.get(i).map(|v| Owned {
            v,
            path: format!("{}[{i}]", self.path),
            file: self.file,
        })
    }

    pub fn str(&self) -> Result<&'a str, SceneError> {
        self.v.as_str().ok_or_else(|| self.wrong("a string"))
    }

    pub fn bool(&self) -> Result<bool, SceneError> {
        self.v.as_bool().ok_or_else(|| self.wrong("true or false"))
    }

    pub fn array(&self) -> Result<&'a Vec<Value>, SceneError> {
        self.v.as_array().ok_or_else(|| self.wrong("an array"))
    }

    pub fn object(&self) -> Result<&'a serde_json::Map<String, Value>, SceneError> {
        self.v.as_object().ok_or_else(|| self.wrong("an object"))
    }

    /// A finite f32.
    pub fn f32(&self) -> Result<f32, SceneError> {
        let x = self.v.as_f64().ok_or_else(|| self.wrong("a number"))? as f32;
        if !x.is_finite() {
            return Err(SceneError::NotFinite {
                file: self.file.to_string(),
                at: self.at(),
                what: "the number".into(),
            });
        }
        Ok(x)
    }

    /// A finite f64 (transforms are computed in double precision).
    pub fn f64(&self) -> Result<f64, SceneError> {
        let x = self.v.as_f64().ok_or_else(|| self.wrong("a number"))?;
        if !x.is_finite() || !(x as f32).is_finite() {
            return Err(SceneError::NotFinite {
                file: self.file.to_string(),
                at: self.at(),
                what: "the number".into(),
            });
        }
        Ok(x)
    }

    /// [`J::vec3`] in double precision.
    pub fn dvec3(&self) -> Result<DVec3, SceneError> {
        if self.v.is_number() {
            return Ok(DVec3::splat(self.f64()?));
        }
        let a = self
            .v
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| self.wrong("a number or an array of 3 numbers"))?;
        let mut out = [0.0f64; 3];
        for (i, v) in a.iter().enumerate() {
            out[i] = J { v, ..*self }.f64()?;
        }
        Ok(DVec3::from_array(out))
    }

    /// A vector: `[x, y, z]`, or one number for all three (Tungsten's shorthand).
    pub fn vec3(&self) -> Result<Vec3, SceneError> {
        if self.v.is_number() {
            return Ok(Vec3::splat(self.f32()?));
        }
        let a = self
            .v
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| self.wrong("a number or an array of 3 numbers"))?;
        let mut out = [0.0f32; 3];
        for (i, v) in a.iter().enumerate() {
            out[i] = J { v, ..*self }.f32()?;
        }
        Ok(Vec3::from_array(out))
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}
