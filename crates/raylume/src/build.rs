//! [`SceneBuilder`]: a scene in code, validated exactly as a loaded file is.

use std::path::Path;

use glam::{Mat4, Vec3};
use raylume_scene::transform::Xform;
use raylume_scene::{
    Bloom, Camera, Environment, Material, RenderSettings, Scene, SceneError, Sphere, Triangle,
};

use crate::Error;

/// A material added to a [`SceneBuilder`]: its index in [`Scene::materials`], for the shapes
/// that use it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MaterialId(pub u32);

impl MaterialId {
    /// The index into [`Scene::materials`] (what [`Triangle::material`] and
    /// [`Sphere::material`] hold).
    pub fn index(self) -> u32 {
        self.0
    }
}

/// Where a mesh file goes: scale, then rotate (degrees about the fixed X, then Y, then Z
/// axes), then translate; the TOML `[[mesh]]` transform. The default is the identity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Per-axis scale (default `1, 1, 1`). A negative component mirrors the mesh; its
    /// triangles are rewound so that their front faces stay in front.
    pub scale: Vec3,
    /// Rotation in degrees about X, then Y, then Z (default `0, 0, 0`), exact at right angles.
    pub rotate: Vec3,
    /// Translation (default `0, 0, 0`).
    pub translate: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// No change.
    pub const IDENTITY: Transform = Transform {
        scale: Vec3::ONE,
        rotate: Vec3::ZERO,
        translate: Vec3::ZERO,
    };

    /// A translation only.
    pub fn translate(t: Vec3) -> Self {
        Self {
            translate: t,
            ..Self::IDENTITY
        }
    }

    /// This transform with a uniform scale `s`.
    pub fn with_scale(self, s: f32) -> Self {
        Self {
            scale: Vec3::splat(s),
            ..self
        }
    }

    /// This transform with a rotation of `degrees` about X, then Y, then Z.
    pub fn with_rotation(self, degrees: Vec3) -> Self {
        Self {
            rotate: degrees,
            ..self
        }
    }

    /// The matrix: `translate * rotate * scale` (raylume-scene's own `[[mesh]]` transform,
    /// [`Xform::from_srt`]).
    pub fn matrix(&self) -> Mat4 {
        self.xform().m
    }

    fn xform(&self) -> Xform {
        Xform::from_srt(self.scale, self.rotate, self.translate)
    }
}

/// Builds a [`Scene`] in code: the camera, materials, quads, boxes, spheres, triangles, meshes
/// from files and the environment, then [`SceneBuilder::build`] validates it as a loaded file
/// is ([`Scene::validate`]).
///
/// A new builder starts from [`Scene::default`]: [`Camera::default`] (at `(0, 0, 5)` looking
/// at the origin, `+y` up, a vertical field of view of 45 degrees),
/// [`RenderSettings::default`] (512x512, 16 spp, 10 bounces, seed 0), a black environment
/// ([`Environment::Black`]), no materials, no geometry, no bloom.
///
/// Emission leaves a surface's front face only (unless its material is
/// [`Material::two_sided`]): the side of `u x v` for [`SceneBuilder::quad`], the outside of a
/// [`SceneBuilder::cuboid`] or [`SceneBuilder::sphere`], the counter-clockwise side of a
/// [`SceneBuilder::triangle`]. Scattering is two-sided.
///
/// ```
/// use raylume::glam::Vec3;
/// use raylume::scene::Material;
/// use raylume::{Backend, SceneBuilder, Tracer};
///
/// let mut b = SceneBuilder::new();
/// b.look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 0.8, 0.0), 40.0)
///     .size(32, 24)
///     .spp(4);
/// let white = b.material(Material::diffuse("white", Vec3::splat(0.7)));
/// let lamp = b.material(Material::emissive("lamp", Vec3::splat(8.0)));
/// b.quad(Vec3::new(-2.0, 0.0, 2.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -4.0), white) // floor, facing up
///     .cuboid(Vec3::new(-0.4, 0.0, -0.4), Vec3::new(0.4, 0.8, 0.4), white)
///     .sphere(Vec3::new(0.0, 1.2, 0.0), 0.4, white)
///     // a lamp facing down: u x v = x x z = -y
///     .quad(Vec3::new(-0.5, 2.5, -0.5), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0), lamp);
/// let scene = b.build()?;
/// assert_eq!((scene.triangles.len(), scene.spheres.len()), (16, 1));
///
/// let render = Tracer::new(Backend::Cpu).render(&scene)?;
/// assert!(render.to_srgb8()?.iter().any(|p| p[0] > 0));
///
/// // Invalid input is the typed error a loaded file would give.
/// let mut bad = SceneBuilder::new();
/// let m = bad.material(Material::diffuse("m", Vec3::ONE));
/// bad.sphere(Vec3::ZERO, -1.0, m);
/// assert!(matches!(bad.build(), Err(raylume::Error::Scene(_))));
/// # Ok::<(), raylume::Error>(())
/// ```
#[derive(Clone, Debug, Default)]
pub struct SceneBuilder {
    scene: Scene,
}

impl From<Scene> for SceneBuilder {
    /// Starts from an existing (for example loaded) scene, to add to it.
    fn from(scene: Scene) -> Self {
        Self { scene }
    }
}

impl SceneBuilder {
    /// An empty scene with the defaults of [`SceneBuilder`]'s docs.
    pub fn new() -> Self {
        Self::default()
    }

    /// The scene so far (not yet validated).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Sets the camera (default [`Camera::default`]).
    pub fn camera(&mut self, camera: Camera) -> &mut Self {
        self.scene.camera = camera;
        self
    }

    /// A camera at `position` looking at `target`, `+y` up, a vertical field of view of `vfov`
    /// degrees ([`Camera::looking_at`]).
    pub fn look_at(&mut self, position: Vec3, target: Vec3, vfov: f32) -> &mut Self {
        self.camera(Camera::looking_at(position, target, vfov))
    }

    /// Sets all render settings (default [`RenderSettings::default`]: 512x512, 16 spp, 10
    /// bounces, seed 0).
    pub fn render_settings(&mut self, settings: RenderSettings) -> &mut Self {
        self.scene.render = settings;
        self
    }

    /// Image size in pixels (default 512x512).
    pub fn size(&mut self, width: u32, height: u32) -> &mut Self {
        self.scene.render.width = width;
        self.scene.render.height = height;
        self
    }

    /// Samples per pixel (default 16).
    pub fn spp(&mut self, spp: u32) -> &mut Self {
        self.scene.render.spp = spp;
        self
    }

    /// Bounces after the camera ray (default 10).
    pub fn max_bounces(&mut self, bounces: u32) -> &mut Self {
        self.scene.render.max_bounces = bounces;
        self
    }

    /// The random seed (default 0).
    pub fn seed(&mut self, seed: u32) -> &mut Self {
        self.scene.render.seed = seed;
        self
    }

    /// Adds a material ([`Material::diffuse`], [`Material::metal`], [`Material::glass`],
    /// [`Material::plastic`], [`Material::emissive`], ... or a literal) and returns its id.
    pub fn material(&mut self, material: Material) -> MaterialId {
        self.scene.materials.push(material);
        MaterialId(self.scene.materials.len() as u32 - 1)
    }

    /// One triangle, front face on the side from which `positions` run counter-clockwise.
    pub fn triangle(&mut self, positions: [Vec3; 3], material: MaterialId) -> &mut Self {
        self.scene
            .triangles
            .push(Triangle::flat(positions, material.0));
        self
    }

    /// A parallelogram `corner, corner + u, corner + u + v, corner + v` as two triangles, its
    /// front face towards `u x v` (the TOML `[[quad]]`).
    pub fn quad(&mut self, corner: Vec3, u: Vec3, v: Vec3, material: MaterialId) -> &mut Self {
        let (a, b, c, d) = (corner, corner + u, corner + u + v, corner + v);
        self.triangle([a, b, c], material)
            .triangle([a, c, d], material)
    }

    /// An axis-aligned box between the corners `min` and `max` (12 triangles), its faces'
    /// fronts outside. (The corners may come in any order; a flat box has degenerate
    /// triangles, which [`SceneBuilder::build`] rejects.)
    pub fn cuboid(&mut self, min: Vec3, max: Vec3, material: MaterialId) -> &mut Self {
        let (min, max) = (min.min(max), min.max(max));
        let e = max - min;
        let (x, y, z) = (
            Vec3::new(e.x, 0.0, 0.0),
            Vec3::new(0.0, e.y, 0.0),
            Vec3::new(0.0, 0.0, e.z),
        );
        self.quad(min, y, x, material) // -z
            .quad(min + z, x, y, material) // +z
            .quad(min, z, y, material) // -x
            .quad(min + x, y, z, material) // +x
            .quad(min, x, z, material) // -y
            .quad(min + y, z, x, material) // +y
    }

    /// An analytic sphere (emitting, if its material does, from the outside).
    pub fn sphere(&mut self, center: Vec3, radius: f32, material: MaterialId) -> &mut Self {
        self.scene.spheres.push(Sphere {
            center,
            radius,
            material: material.0,
        });
        self
    }

    /// Adds the triangles of a mesh file (`.obj` with its `.mtl`, `.gltf`, `.glb`), loaded by
    /// the same loader as [`Scene::load`] (its warnings join [`Scene::warnings`]), placed by
    /// `transform`. With `material: None` the file's own materials (and their textures) are
    /// added; `Some(id)` gives every triangle that material instead (the TOML `[[mesh]]`
    /// `material` key). Fails with the loader's [`SceneError`].
    pub fn mesh(
        &mut self,
        path: impl AsRef<Path>,
        transform: Transform,
        material: Option<MaterialId>,
    ) -> Result<&mut Self, Error> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if !matches!(ext.as_deref(), Some("obj" | "gltf" | "glb")) {
            return Err(SceneError::UnsupportedExtension {
                path: path.to_path_buf(),
                referenced_by: None,
                expected: ".obj, .gltf or .glb",
            }
            .into());
        }
        let mesh = Scene::load(path)?;
        let (material_base, texture_base) = (
            self.scene.materials.len() as u32,
            self.scene.textures.len() as u32,
        );
        if material.is_none() {
            self.scene
                .materials
                .extend(mesh.materials.into_iter().map(|mut m| {
                    m.albedo_texture = m.albedo_texture.map(|t| t + texture_base);
                    m
                }));
            self.scene.textures.extend(mesh.textures);
        }
        let xform = transform.xform();
        self.scene.triangles.reserve(mesh.triangles.len());
        for mut t in mesh.triangles {
            xform.apply(&mut t);
            t.material = match material {
                Some(id) => id.0,
                None => t.material + material_base,
            };
            self.scene.triangles.push(t);
        }
        self.scene.warnings.extend(mesh.warnings);
        Ok(self)
    }

    /// Sets the environment: [`Environment::Black`] (the default), a constant radiance, or a
    /// map already decoded.
    pub fn environment(&mut self, environment: Environment) -> &mut Self {
        self.scene.environment = environment;
        self
    }

    /// A constant environment radiance (linear RGB, not negative).
    pub fn environment_radiance(&mut self, radiance: Vec3) -> &mut Self {
        self.environment(Environment::Constant(radiance))
    }

    /// An equirectangular `.hdr` or `.exr` environment map, loaded as the TOML `[environment]
    /// map` is (same decoder, limits and warnings), times `strength` (the TOML default is 1),
    /// rotated by `rotation` degrees about `+y` (default 0).
    pub fn environment_map(
        &mut self,
        path: impl AsRef<Path>,
        strength: f32,
        rotation: f32,
    ) -> Result<&mut Self, Error> {
        let path = path.as_ref();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| !n.contains(['\'', '\n', '\r']))
            .ok_or_else(|| SceneError::InvalidValue {
                file: path.display().to_string(),
                at: raylume_scene::Location::None,
                message: "an environment map's file name must be UTF-8 without quotes or \
                          line breaks"
                    .into(),
            })?;
        for (what, v) in [("strength", strength), ("rotation", rotation)] {
            if !v.is_finite() {
                return Err(SceneError::InvalidValue {
                    file: path.display().to_string(),
                    at: raylume_scene::Location::None,
                    message: format!("environment map {what} {v} is not finite"),
                }
                .into());
            }
        }
        // The TOML loader's own environment path, on a minimal scene around it.
        let text = format!(
            "[camera]\nposition = [0.0, 0.0, 1.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 45.0\n\
             [materials.m]\ntype = \"diffuse\"\n\
             [[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 0.5\nmaterial = \"m\"\n\
             [environment]\nmap = '{name}'\nstrength = {strength:?}\nrotation = {rotation:?}\n"
        );
        let dir = path.parent().unwrap_or(Path::new(""));
        let loaded = Scene::from_toml_str(&text, dir, &path.display().to_string())?;
        self.scene.environment = loaded.environment;
        self.scene.warnings.extend(loaded.warnings);
        Ok(self)
    }

    /// The paper's bloom post effect (default none: no pass runs).
    pub fn bloom(&mut self, bloom: Bloom) -> &mut Self {
        self.scene.post.bloom = Some(bloom);
        self
    }

    /// Validates the scene ([`Scene::validate`], the checks every loader runs: finite numbers,
    /// indices in range, positive sizes, no degenerate triangle, at least one primitive, the
    /// limits) and returns it, or the [`SceneError`] a loaded file with the same content
    /// would give (as [`Error::Scene`]).
    pub fn build(&self) -> Result<Scene, Error> {
        self.scene.validate()?;
        Ok(self.scene.clone())
    }

    /// [`SceneBuilder::build`] without the copy.
    pub fn into_scene(self) -> Result<Scene, Error> {
        self.scene.validate()?;
        Ok(self.scene)
    }
}
