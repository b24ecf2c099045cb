//! The scene model every loader produces and every backend consumes.
//!
//! Plain data: world-space triangles and spheres, a material table, textures, a camera,
//! render settings, an environment and post effects. Loaders (`toml`, `obj`, `gltf`,
//! `tungsten`) fill it; [`Scene::validate`] checks it; [`Scene::features`] says what it uses.

use glam::{Vec2, Vec3};

/// The image axis a camera's field of view spans.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FovAxis {
    /// Top to bottom (TOML `vfov`, glTF `yfov`): a wider `--size` shows more at the sides.
    #[default]
    Vertical,
    /// Left to right (TOML `hfov`, Tungsten's `fov`, Mitsuba's `fov_axis = "x"`): a taller
    /// `--size` shows more above and below.
    Horizontal,
}

/// A pinhole camera.
///
/// The field of view keeps the axis its file gave, so that changing the image size changes
/// the image's aspect, never the angle the file said (the other axis follows from the aspect).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    /// Up hint; need not be orthogonal to the view direction, must not be parallel to it.
    pub up: Vec3,
    /// Field of view in degrees along [`Camera::fov_axis`], in (0, 180).
    pub fov: f32,
    pub fov_axis: FovAxis,
}

impl Default for Camera {
    /// At `(0, 0, 5)` looking at the origin, `+y` up, a vertical field of view of 45 degrees.
    fn default() -> Self {
        Self {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov: 45.0,
            fov_axis: FovAxis::Vertical,
        }
    }
}

impl Camera {
    /// A camera at `position` looking at `look_at` with `+y` up and a vertical field of view
    /// of `vfov` degrees.
    pub fn looking_at(position: Vec3, look_at: Vec3, vfov: f32) -> Self {
        Self {
            position,
            look_at,
            up: Vec3::Y,
            fov: vfov,
            fov_axis: FovAxis::Vertical,
        }
    }

    /// `tan` of half the field of view along the image's height and width, for an image of
    /// `width x height` pixels: the image plane at distance 1 spans `[-x, x] x [-y, y]`.
    pub fn half_extent(&self, width: u32, height: u32) -> (f32, f32) {
        let t = (self.fov.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        match self.fov_axis {
            FovAxis::Vertical => (t * aspect, t),
            FovAxis::Horizontal => (t, t / aspect),
        }
    }

    /// The vertical field of view in degrees for an image of `width x height` pixels.
    pub fn vfov(&self, width: u32, height: u32) -> f32 {
        2.0 * self.half_extent(width, height).1.atan().to_degrees()
    }
}

/// Image size and sampling. Command-line flags override the scene's values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples (camera rays) per pixel.
    pub spp: u32,
    /// Bounces after the camera ray: 10 means a path has at most 11 segments.
    pub max_bounces: u32,
    pub seed: u32,
}

impl RenderSettings {
    /// The paper's setting: 1000x1000, 10 bounces (spp varies: 1, 10, 100).
    pub const fn paper(spp: u32) -> Self {
        Self {
            width: 1000,
            height: 1000,
            spp,
            max_bounces: 10,
            seed: 0,
        }
    }

    /// A small, fast preview (tests, lavapipe).
    pub const fn preview() -> Self {
        Self {
            width: 64,
            height: 64,
            spp: 4,
            max_bounces: 4,
            seed: 0,
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 512,
            height: 512,
            spp: 16,
            max_bounces: 10,
            seed: 0,
        }
    }
}

/// How a surface scatters light. Every kind scatters on both faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MaterialKind {
    /// Lambertian, cosine-weighted sampling.
    Diffuse,
    /// Conductor: a perfect mirror at roughness 0, GGX microfacets above, with the Fresnel
    /// reflectance of its complex index of refraction ([`Material::conductor_eta`],
    /// [`Material::conductor_k`]; `eta = 0` reflects everything) times `albedo`.
    Metal,
    /// Dielectric: Fresnel reflection and refraction, tinted transmission; smooth at
    /// roughness 0, GGX microfacets above (Walter et al. 2007).
    Glass,
    /// A diffuse base (`albedo`) under a dielectric coat of index `ior`: Fresnel-weighted
    /// specular reflection, smooth at roughness 0 or GGX above; what enters the coat is
    /// reflected diffusely (Mitsuba's `plastic` / `roughplastic`, linear model).
    Plastic,
}

/// One entry of the material table. Every material may emit.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the scene file (for error messages and warnings).
    pub name: String,
    pub kind: MaterialKind,
    /// Reflectance (diffuse, metal). Linear RGB in [0, 1].
    pub albedo: Vec3,
    /// Emitted radiance, linear RGB, >= 0.
    pub emission: Vec3,
    /// Roughness of metal, glass and plastic, in [0, 1] (GGX alpha = roughness^2); 0 is
    /// smooth (a perfect mirror, smooth glass, a smooth coat). Unused by diffuse.
    pub roughness: f32,
    /// Index of refraction of glass and of a plastic's coat, > 0.
    pub ior: f32,
    /// Glass transmission tint, linear RGB in [0, 1].
    pub tint: Vec3,
    /// Metal: the real part of the complex index of refraction `eta + i k`, per RGB channel
    /// (named presets: [`crate::conductor_ior`]). The default `eta = 0, k = 1` is a lossless
    /// conductor whose Fresnel reflectance is 1 at every angle, so `albedo` alone is the
    /// reflectance.
    pub conductor_eta: Vec3,
    /// Metal: the imaginary part `k` of the complex index of refraction.
    pub conductor_k: Vec3,
    /// Albedo texture (index into [`Scene::textures`]), multiplied with `albedo`.
    pub albedo_texture: Option<u32>,
    /// Whether the emission leaves both faces. By default (`false`) a surface emits from its
    /// front face only, as in Tungsten, Mitsuba and pbrt: the side its geometric normal
    /// points to (`u x v` for a TOML quad, the counter-clockwise winding for meshes, outward
    /// for spheres). Scattering is two-sided either way.
    pub two_sided: bool,
}

impl Material {
    pub fn diffuse(name: &str, albedo: Vec3) -> Self {
        Self {
            name: name.to_string(),
            kind: MaterialKind::Diffuse,
            albedo,
            emission: Vec3::ZERO,
            roughness: 1.0,
            ior: 1.5,
            tint: Vec3::ONE,
            conductor_eta: Vec3::ZERO,
            conductor_k: Vec3::ONE,
            albedo_texture: None,
            two_sided: false,
        }
    }

    /// A metal reflecting `albedo` at every angle (Fresnel 1), smooth at roughness 0.
    pub fn metal(name: &str, albedo: Vec3, roughness: f32) -> Self {
        Self {
            kind: MaterialKind::Metal,
            roughness,
            ..Self::diffuse(name, albedo)
        }
    }

    /// A metal with the complex index of refraction `eta + i k` (per RGB channel), its
    /// Fresnel reflectance scaled by `albedo`.
    pub fn conductor(name: &str, eta: Vec3, k: Vec3, albedo: Vec3, roughness: f32) -> Self {
        Self {
            conductor_eta: eta,
            conductor_k: k,
            ..Self::metal(name, albedo, roughness)
        }
    }

    /// Smooth glass of index `ior`, its transmission tinted by `tint`.
    pub fn glass(name: &str, ior: f32, tint: Vec3) -> Self {
        Self {
            kind: MaterialKind::Glass,
            ior,
            tint,
            roughness: 0.0,
            ..Self::diffuse(name, Vec3::ONE)
        }
    }

    /// A diffuse `albedo` under a dielectric coat of index `ior`, smooth at roughness 0.
    pub fn plastic(name: &str, albedo: Vec3, ior: f32, roughness: f32) -> Self {
        Self {
            kind: MaterialKind::Plastic,
            ior,
            roughness,
            ..Self::diffuse(name, albedo)
        }
    }

    /// A black surface emitting `emission` from its front face.
    pub fn emissive(name: &str, emission: Vec3) -> Self {
        Self {
            emission,
            ..Self::diffuse(name, Vec3::ZERO)
        }
    }

    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// An RGB texture (alpha is dropped on load).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Source file, for messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first, `width * height` texels.
    pub texels: Texels,
}

/// A texture's texels, in the precision of their file.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// Linear RGB floats: float images (`.hdr`, `.exr`), 16-bit images (sRGB-decoded on
    /// load), environment maps.
    Linear(Vec<[f32; 3]>),
    /// 8-bit sRGB-encoded RGB as in the file (png, jpg): a quarter of the memory of floats on
    /// the GPU, a third on the CPU. Both backends decode a channel `c` on lookup as
    /// [`srgb8_table`]`()[c]`, the value the loader would have stored as a float: the same
    /// numbers either way.
    Srgb8(Vec<[u8; 3]>),
}

impl Texels {
    /// The number of texels.
    pub fn len(&self) -> usize {
        match self {
            Texels::Linear(t) => t.len(),
            Texels::Srgb8(t) => t.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether these are 8-bit sRGB codes ([`Texels::Srgb8`]).
    pub fn is_srgb8(&self) -> bool {
        matches!(self, Texels::Srgb8(_))
    }

    /// Texel `i`, linear RGB.
    pub fn linear(&self, i: usize) -> [f32; 3] {
        match self {
            Texels::Linear(t) => t[i],
            Texels::Srgb8(t) => t[i].map(|c| srgb8_table()[c as usize]),
        }
    }

    /// Every texel, linear RGB (a copy).
    pub fn to_linear(&self) -> Vec<[f32; 3]> {
        match self {
            Texels::Linear(t) => t.clone(),
            Texels::Srgb8(t) => t
                .iter()
                .map(|c| c.map(|c| srgb8_table()[c as usize]))
                .collect(),
        }
    }
}

/// Linear texels.
impl From<Vec<[f32; 3]>> for Texels {
    fn from(t: Vec<[f32; 3]>) -> Self {
        Texels::Linear(t)
    }
}

/// 8-bit sRGB texels.
impl From<Vec<[u8; 3]>> for Texels {
    fn from(t: Vec<[u8; 3]>) -> Self {
        Texels::Srgb8(t)
    }
}

/// Linear texels.
impl FromIterator<[f32; 3]> for Texels {
    fn from_iter<I: IntoIterator<Item = [f32; 3]>>(iter: I) -> Self {
        Texels::Linear(iter.into_iter().collect())
    }
}

/// 8-bit sRGB texels.
impl FromIterator<[u8; 3]> for Texels {
    fn from_iter<I: IntoIterator<Item = [u8; 3]>>(iter: I) -> Self {
        Texels::Srgb8(iter.into_iter().collect())
    }
}

/// The linear value of each 8-bit sRGB code: the exact sRGB transfer function of `c / 255`,
/// in f32 (what [`Texels::Srgb8`] texels mean).
pub fn srgb8_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| crate::image_io::srgb_to_linear(i as f32 / 255.0)))
}

/// One world-space triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub positions: [Vec3; 3],
    /// Per-vertex shading normals (unit length), if the source had them.
    pub normals: Option<[Vec3; 3]>,
    /// Per-vertex texture coordinates, if the source had them. `(0, 0)` is the top-left
    /// texel, `v` grows downwards (glTF's convention; the OBJ loader flips OBJ's `v`).
    pub uvs: Option<[Vec2; 3]>,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// A triangle with no shading normals and no uvs.
    pub fn flat(positions: [Vec3; 3], material: u32) -> Self {
        Self {
            positions,
            normals: None,
            uvs: None,
            material,
        }
    }

    /// Twice the area (length of the geometric normal before normalising).
    pub fn double_area(&self) -> f32 {
        let [a, b, c] = self.positions;
        (b - a).cross(c - a).length()
    }
}

/// An analytic sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
    pub material: u32,
}

/// Light from infinitely far away.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Environment {
    /// Nothing: escaping rays carry no light.
    #[default]
    Black,
    /// The same radiance in every direction.
    Constant(Vec3),
    /// An equirectangular map (longitude along x, +y up at the top row).
    Map {
        image: Texture,
        /// Multiplier on the map's radiance.
        strength: f32,
        /// Rotation about +y, degrees.
        rotation: f32,
    },
}

/// Bloom, the paper's post effect: pixels above `threshold` are blurred by two box passes of
/// half-width `radius` and added back times `strength`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bloom {
    pub threshold: f32,
    pub radius: u32,
    pub strength: f32,
}

/// Post effects. Absent effects run no pass at all.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PostSettings {
    pub bloom: Option<Bloom>,
}

/// A loaded, validated scene.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub camera: Camera,
    pub render: RenderSettings,
    pub environment: Environment,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub triangles: Vec<Triangle>,
    pub spheres: Vec<Sphere>,
    pub post: PostSettings,
    /// What the loaders had to approximate or drop (unknown material types mapped to the
    /// nearest one, degenerate triangles dropped, ...). Never silent: the `render` command
    /// prints them.
    pub warnings: Vec<String>,
}

/// Axis-aligned bounds of the scene's geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }
}

impl Scene {
    /// Bounds of all triangles and spheres.
    pub fn bounds(&self) -> Bounds {
        use rayon::prelude::*;
        let (lo, hi) = self
            .triangles
            .par_iter()
            .fold(
                || (Vec3::INFINITY, Vec3::NEG_INFINITY),
                |(lo, hi), t| {
                    let [a, b, c] = t.positions;
                    (lo.min(a).min(b).min(c), hi.max(a).max(b).max(c))
                },
            )
            .reduce(
                || (Vec3::INFINITY, Vec3::NEG_INFINITY),
                |x, y| (x.0.min(y.0), x.1.max(y.1)),
            );
        let mut b = Bounds { min: lo, max: hi };
        for s in &self.spheres {
            b.grow(s.center - Vec3::splat(s.radius));
            b.grow(s.center + Vec3::splat(s.radius));
        }
        b
    }

    /// Number of primitives (triangles + spheres).
    pub fn primitive_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }
}
