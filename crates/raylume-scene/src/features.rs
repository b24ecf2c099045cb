//! The set of effects a scene calls for. Kernels are specialised on it: code for an effect
//! the scene does not use is not compiled into its pipeline, and passes it does not need do not
//! run.

use rayon::prelude::*;

use crate::model::{Environment, MaterialKind, Scene};

/// A set of [`Feature`]s, stored as bits (the same bits the WGSL kernels receive as pipeline
/// override constants).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Features(u32);

/// One effect a scene may call for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Feature {
    /// Diffuse surfaces.
    Diffuse = 1 << 0,
    /// Perfect mirrors (metal, roughness 0).
    Metal = 1 << 1,
    /// Rough metal (GGX, roughness > 0).
    RoughMetal = 1 << 2,
    /// Glass (Fresnel, refraction).
    Glass = 1 << 3,
    /// Some material emits.
    Emission = 1 << 4,
    /// Analytic spheres.
    Spheres = 1 << 5,
    /// Albedo textures.
    Textures = 1 << 6,
    /// A constant environment.
    ConstantEnvironment = 1 << 7,
    /// An equirectangular environment map.
    EnvironmentMap = 1 << 8,
    /// The bloom post pass.
    Bloom = 1 << 9,
    /// Triangles (almost always).
    Triangles = 1 << 10,
    /// Interpolated shading normals on some triangles.
    ShadingNormals = 1 << 11,
    /// Plastic (a diffuse base under a dielectric coat), smooth or rough.
    Plastic = 1 << 12,
    /// Rough glass (GGX microfacets, roughness > 0).
    RoughGlass = 1 << 13,
}

impl Feature {
    /// Every feature, in bit order.
    pub const ALL: [Feature; 14] = [
        Feature::Diffuse,
        Feature::Metal,
        Feature::RoughMetal,
        Feature::Glass,
        Feature::Emission,
        Feature::Spheres,
        Feature::Textures,
        Feature::ConstantEnvironment,
        Feature::EnvironmentMap,
        Feature::Bloom,
        Feature::Triangles,
        Feature::ShadingNormals,
        Feature::Plastic,
        Feature::RoughGlass,
    ];

    /// snake_case name used in stats JSON and logs.
    pub const fn name(self) -> &'static str {
        match self {
            Feature::Diffuse => "diffuse",
            Feature::Metal => "metal",
            Feature::RoughMetal => "rough_metal",
            Feature::Glass => "glass",
            Feature::Emission => "emission",
            Feature::Spheres => "spheres",
            Feature::Textures => "textures",
            Feature::ConstantEnvironment => "constant_environment",
            Feature::EnvironmentMap => "environment_map",
            Feature::Bloom => "bloom",
            Feature::Triangles => "triangles",
            Feature::ShadingNormals => "shading_normals",
            Feature::Plastic => "plastic",
            Feature::RoughGlass => "rough_glass",
        }
    }
}

impl Features {
    pub const NONE: Features = Features(0);

    /// All features: the unspecialised kernel.
    pub const fn all() -> Self {
        let mut bits = 0;
        let mut i = 0;
        while i < Feature::ALL.len() {
            bits |= Feature::ALL[i] as u32;
            i += 1;
        }
        Features(bits)
    }

    pub const fn bits(self) -> u32 {
        self.0
    }

    pub const fn from_bits(bits: u32) -> Self {
        Features(bits & Self::all().0)
    }

    pub const fn contains(self, f: Feature) -> bool {
        self.0 & f as u32 != 0
    }

    pub fn insert(&mut self, f: Feature) {
        self.0 |= f as u32;
    }

    pub fn remove(&mut self, f: Feature) {
        self.0 &= !(f as u32);
    }

    pub fn with(mut self, f: Feature) -> Self {
        self.insert(f);
        self
    }

    /// The features present, in bit order.
    pub fn iter(self) -> impl Iterator<Item = Feature> {
        Feature::ALL.into_iter().filter(move |f| self.contains(*f))
    }

    /// Names of the features present, e.g. `["diffuse", "emission"]`.
    pub fn names(self) -> Vec<&'static str> {
        self.iter().map(Feature::name).collect()
    }
}

impl std::fmt::Display for Features {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.names().join(", "))
    }
}

impl Scene {
    /// The effects this scene calls for. Only materials that some primitive uses count: an
    /// unused glass material in the table does not pull glass code into the kernel.
    pub fn features(&self) -> Features {
        let mut f = Features::NONE;
        // The triangles on every core: a render asks several times, and a large scene's
        // triangles are read whole each time (324 MB for 3M triangles; 30-60 ms a pass on
        // one core of the 2-core machine).
        let materials = self.materials.len();
        let (mut used, normals) = self
            .triangles
            .par_iter()
            .with_min_len(1 << 14)
            .fold(
                || (vec![false; materials], false),
                |(mut used, normals), t| {
                    if let Some(u) = used.get_mut(t.material as usize) {
                        *u = true;
                    }
                    (used, normals || t.normals.is_some())
                },
            )
            .reduce(
                || (vec![false; materials], false),
                |(mut a, an), (b, bn)| {
                    a.iter_mut().zip(b).for_each(|(a, b)| *a |= b);
                    (a, an || bn)
                },
            );
        if normals {
            f.insert(Feature::ShadingNormals);
        }
        for s in &self.spheres {
            if let Some(u) = used.get_mut(s.material as usize) {
                *u = true;
            }
        }
        if !self.triangles.is_empty() {
            f.insert(Feature::Triangles);
        }
        if !self.spheres.is_empty() {
            f.insert(Feature::Spheres);
        }
        for (m, _) in self.materials.iter().zip(&used).filter(|(_, u)| **u) {
            match m.kind {
                MaterialKind::Diffuse => f.insert(Feature::Diffuse),
                MaterialKind::Metal if m.roughness > 0.0 => f.insert(Feature::RoughMetal),
                MaterialKind::Metal => f.insert(Feature::Metal),
                MaterialKind::Glass if m.roughness > 0.0 => f.insert(Feature::RoughGlass),
                MaterialKind::Glass => f.insert(Feature::Glass),
                MaterialKind::Plastic => f.insert(Feature::Plastic),
            }
            if m.is_emissive() {
                f.insert(Feature::Emission);
            }
            if m.albedo_texture.is_some() && m.kind != MaterialKind::Glass {
                f.insert(Feature::Textures);
            }
        }
        match &self.environment {
            Environment::Black => {}
            Environment::Constant(c) if c.max_element() > 0.0 => {
                f.insert(Feature::ConstantEnvironment)
            }
            Environment::Constant(_) => {}
            Environment::Map { .. } => f.insert(Feature::EnvironmentMap),
        }
        if self.post.bloom.is_some() {
            f.insert(Feature::Bloom);
        }
        f
    }
}
