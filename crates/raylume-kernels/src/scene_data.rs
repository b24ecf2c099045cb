//! The scene flattened into the arrays both backends read: materials, per-primitive material
//! indices and shading data in the BVH's leaf order, textures in one texel buffer, and the
//! environment. Built once per scene; the GPU tracer uploads exactly these arrays, the CPU
//! tracer reads them in place, so both see the same numbers.

use std::collections::HashMap;

use glam::Vec3;
use raylume_bvh::{GpuBvh, PRIM_SPHERE, PRIM_TRIANGLE, Primitive};
use raylume_scene::{
    Camera, Environment, Features, MaterialKind, Scene, Texels, Texture, srgb8_table,
};
use rayon::prelude::*;

use crate::KernelError;
use crate::TraceSettings;
use crate::bsdf::RoughPlasticTable;
use crate::camera::camera_basis;
use crate::env_guide::{
    EnvironmentGuide, GUIDE_HEIGHT, GUIDE_WIDTH, GuideParams, cdf_from_weights,
    guided_constant_cdf, guided_map_cdf, learn_environment_guide_with,
};
use crate::gpu_types::LUMINANCE;
use crate::gpu_types::{
    ENVIRONMENT_BLACK, ENVIRONMENT_CONSTANT, ENVIRONMENT_MAP, GpuLight, GpuMaterial,
    LIGHT_ENVIRONMENT, LIGHT_SPHERE, LIGHT_TRIANGLE, MATERIAL_DIFFUSE, MATERIAL_GLASS,
    MATERIAL_METAL, MATERIAL_PLASTIC, MATERIAL_TWO_SIDED, NO_ROULETTE, NO_TABLE, NO_TEXTURE,
    SHADING_HAS_NORMALS, SHADING_HAS_UVS, SRGB8_TABLE, SceneUniforms, TEXELS_LINEAR, TEXELS_SRGB8,
    TextureHeader, TriangleShading,
};
use crate::{Estimator, Sampler};

/// The placeholder of an empty table buffer (bindings are never empty).
impl Default for RoughPlasticTable {
    fn default() -> Self {
        bytemuck::Zeroable::zeroed()
    }
}

/// The scene's data in the tracer's layout.
#[derive(Clone, Debug, Default)]
pub struct SceneData {
    /// The tracer's features of the scene ([`crate::tracer_features`]): the CPU mirror's
    /// variant is chosen by them (`cpu::variant`).
    pub features: Features,
    pub camera: Camera,
    /// The material table (at least one entry, so bindings are never empty).
    pub materials: Vec<GpuMaterial>,
    /// Material index per primitive, in leaf order (parallel to `GpuBvh::primitives`): the
    /// paper keeps them out of the primitives so intersection tests do not load them.
    pub prim_materials: Vec<u32>,
    /// Shading normals and uvs per primitive in leaf order; empty when no triangle has either.
    pub triangle_shading: Vec<TriangleShading>,
    pub texture_headers: Vec<TextureHeader>,
    /// 32-bit words: the sRGB table (at [`SRGB8_TABLE`], when a texture is 8-bit), all
    /// textures' texels, each texture at its header's offset in its format (three float
    /// words or one packed word a texel), the environment map (float words) and the
    /// environment's distributions (float words).
    pub texels: Vec<u32>,
    pub environment_kind: u32,
    pub environment_color: Vec3,
    /// Turns (degrees / 360).
    pub environment_rotation: f32,
    pub environment_width: u32,
    pub environment_height: u32,
    pub environment_offset: u32,
    /// An environment map's sampling distribution in `texels` (a float index; see
    /// `SceneUniforms::environment_cdf`), 0 without a map.
    pub environment_cdf: u32,
    /// The environment's selection probability in `lights` (0 when it is not there).
    pub environment_select: f32,
    /// The guided sampling distributions of the environment ([`crate::env_guide`]) in
    /// `texels`; `None` without an environment, without geometry, or when the walks found too
    /// few escapes.
    pub environment_guided_cdf: Option<GuidedCdf>,
    /// What the guide's walks found (`None` when no guide was learned).
    pub environment_guide_walks: Option<(u32, u64)>,
    /// Seconds the preparation waited for the guide's walks (all of them on the CPU; on the
    /// GPU what was left of them when it needed their counts); 0 when none ran.
    pub environment_guide_seconds: f64,
    /// Whether next-event estimation samples the environment by the guided distribution
    /// (when there is one; [`SceneData::uniforms`]).
    pub environment_guide: bool,
    pub scene_min: Vec3,
    pub scene_extent: Vec3,
    /// The emissive triangles, for next-event estimation (empty when none emits).
    pub lights: Vec<GpuLight>,
    /// Their total area times emitted luminance.
    pub light_power: f32,
    /// One coat table per distinct (roughness, ior) of the rough plastics
    /// (`GpuMaterial::table`); empty when there is none.
    pub plastic_tables: Vec<RoughPlasticTable>,
    /// Which estimator the uniforms ask for ([`SceneData::uniforms`]).
    pub estimator: Estimator,
    /// The first segment after whose hit Russian roulette may end a path; `None`: never.
    pub russian_roulette: Option<u32>,
    /// Where the paths' random numbers come from ([`SceneData::uniforms`]).
    pub sampler: Sampler,
    /// The samples of every pixel the next renders trace: all of them (`None`, the default,
    /// each pixel's mean), or a range (each pixel's sum over it: a render part).
    pub sample_range: Option<std::ops::Range<u32>>,
}

/// What a render chooses that [`SceneData`] carries besides the scene: the estimator, Russian
/// roulette, the sampler, the environment guide's use and the sample range (the fields of the
/// same names; [`SceneData::uniforms_with`] reads them from here instead).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderChoices {
    pub estimator: Estimator,
    pub russian_roulette: Option<u32>,
    pub sampler: Sampler,
    pub environment_guide: bool,
    pub sample_range: Option<std::ops::Range<u32>>,
}

/// What a tracer prepares for a scene beyond its own data (`CpuTracer::with_options`,
/// `GpuTracer::with_options`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneOptions {
    /// Learn where the environment is visible from ([`crate::env_guide`]: diffuse walks from
    /// the camera, a fraction of a second on large scenes) and sample it by that; off by
    /// default (the kernels' defaults are the paper's). A tracer made with it can still turn
    /// it off (`set_environment_guide`).
    pub environment_guide: bool,
    /// Store 8-bit textures decoded, as three float words a texel, instead of their sRGB codes
    /// (one word a texel, decoded on lookup through a table): four times the texture memory
    /// and upload (the living room: 58 MB against 19.5 MB), and lookups without the table's
    /// second load (the living room's 100-spp render 1.3-2.8 % faster on the H200). The same
    /// numbers either way.
    pub decode_textures: bool,
}

/// Where the guided environment distributions are and how they are laid out (the uniforms'
/// `environment_cdf*` and `environment_grid*` fields).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuidedCdf {
    /// Float index in `texels` of the first cell's distribution.
    pub offset: u32,
    /// Direction grid: columns, rows.
    pub width: u32,
    pub height: u32,
    /// Spatial cells along x, y, z and per unit of scene coordinate.
    pub grid: [u32; 3],
    pub grid_scale: Vec3,
}

/// Every emitter that next-event estimation samples, with its selection probability
/// proportional to its area times its emitted luminance ([`LUMINANCE`]) as a running sum, and
/// the total of area times luminance; empty when nothing emits. Emissive triangles
/// ([`LIGHT_TRIANGLE`]) first, then emissive spheres ([`LIGHT_SPHERE`], area `4 pi r^2`),
/// then the environment ([`LIGHT_ENVIRONMENT`]) when `environment_power` (its selection
/// weight, in the same units) is positive. Also returns the environment's probability.
fn light_list(scene: &Scene, environment_power: f32) -> (Vec<GpuLight>, f32, f32) {
    let mut lights = Vec::new();
    let mut total = 0.0f64;
    let mut push = |area: f32, m: &raylume_scene::Material, mut light: GpuLight| {
        let luminance = m.emission.dot(Vec3::from(LUMINANCE));
        if !(area > 0.0 && luminance > 0.0 && area.is_finite()) {
            return;
        }
        total += f64::from(area) * f64::from(luminance);
        light.cdf = total as f32; // the running sum, normalised below
        light.area = area;
        light.two_sided = u32::from(m.two_sided);
        light.emission = m.emission.into();
        lights.push(light);
    };
    // The emitting triangles, found on every core (a large scene emits from few), in order.
    let emits: Vec<bool> = scene
        .materials
        .iter()
        .map(|m| m.emission.dot(Vec3::from(LUMINANCE)) > 0.0)
        .collect();
    let emitting: Vec<&raylume_scene::Triangle> = scene
        .triangles
        .par_iter()
        .filter(|t| emits.get(t.material as usize).copied().unwrap_or(false))
        .collect();
    for t in emitting {
        let Some(m) = scene.materials.get(t.material as usize) else {
            continue;
        };
        let [p0, p1, p2] = t.positions;
        let (e1, e2) = (p1 - p0, p2 - p0);
        let light = GpuLight {
            p0: p0.into(),
            e1: e1.into(),
            e2: e2.into(),
            kind: LIGHT_TRIANGLE,
            ..Default::default()
        };
        push(0.5 * e1.cross(e2).length(), m, light);
    }
    for sp in &scene.spheres {
        let Some(m) = scene.materials.get(sp.material as usize) else {
            continue;
        };
        let light = GpuLight {
            p0: sp.center.into(),
            e1: [sp.radius, 0.0, 0.0],
            kind: LIGHT_SPHERE,
            ..Default::default()
        };
        push(4.0 * std::f32::consts::PI * sp.radius * sp.radius, m, light);
    }
    let before_environment = total;
    if environment_power > 0.0 && environment_power.is_finite() {
        total += f64::from(environment_power);
        lights.push(GpuLight {
            cdf: total as f32,
            kind: LIGHT_ENVIRONMENT,
            ..Default::default()
        });
    }
    for l in &mut lights {
        l.cdf = (f64::from(l.cdf) / total) as f32;
    }
    if let Some(last) = lights.last_mut() {
        last.cdf = 1.0;
    }
    let environment_select = match lights.last() {
        Some(l) if l.kind == LIGHT_ENVIRONMENT => 1.0 - (before_environment / total) as f32,
        _ => 0.0,
    };
    (lights, total as f32, environment_select)
}

/// The sampling distribution of an environment map, in the layout
/// `SceneUniforms::environment_cdf` describes: texel `(x, y)` is chosen with probability
/// proportional to `(luminance + floor) sin θ_y` (θ at the row's centre: the solid angle of
/// its texels), `floor` a thousandth of the mean luminance so that every direction can be
/// drawn. Returns the CDFs and the map's mean luminance over the sphere of directions
/// (solid-angle weighted, before `strength`).
pub fn environment_distribution(image: &Texture) -> (Vec<f32>, f32) {
    let (weights, mean) = environment_weights(image);
    (
        cdf_from_weights(image.width as usize, image.height as usize, &weights),
        mean,
    )
}

/// `texels.len()` as the index of what is appended next, or an error past 2^32 words.
fn texel_index(texels: &[u32]) -> Result<u32, KernelError> {
    u32::try_from(texels.len()).map_err(|_| {
        KernelError::InvalidScene(
            "the textures and the environment's distributions hold more than 2^32 words".into(),
        )
    })
}

/// Appends floats to the texel buffer as their bits.
fn extend_floats(texels: &mut Vec<u32>, floats: impl IntoIterator<Item = f32>) {
    texels.extend(floats.into_iter().map(f32::to_bits));
}

/// The texel weights of [`environment_distribution`] (`(luminance + floor) sin θ_y`,
/// row-major) and the map's mean luminance.
pub fn environment_weights(image: &Texture) -> (Vec<f64>, f32) {
    let (w, h) = (image.width as usize, image.height as usize);
    let lum = |t: &[f32; 3]| f64::from(Vec3::from(*t).dot(Vec3::from(LUMINANCE)).max(0.0));
    let plain_mean = (0..w * h)
        .map(|i| lum(&image.texels.linear(i)))
        .sum::<f64>()
        / (w * h).max(1) as f64;
    let floor = if plain_mean > 0.0 {
        1e-3 * plain_mean
    } else {
        1.0
    };
    let mut weights = vec![0.0f64; w * h];
    let (mut weighted, mut solid) = (0.0f64, 0.0f64);
    for y in 0..h {
        let sin = ((y as f64 + 0.5) / h as f64 * std::f64::consts::PI).sin();
        for x in 0..w {
            let l = lum(&image.texels.linear(y * w + x));
            weighted += l * sin;
            solid += sin;
            weights[y * w + x] = (l + floor) * sin;
        }
    }
    (weights, (weighted / solid) as f32)
}

/// Each rough plastic's table key ([`table_key`]) to its index in the table buffer.
type TableIndex = HashMap<Option<(u32, u32)>, u32>;

/// The coat table key of a rough plastic: its GGX alpha and ior, as bits; `None` for any
/// other material.
fn table_key(m: &raylume_scene::Material) -> Option<(u32, u32)> {
    let alpha = m.roughness * m.roughness;
    (m.kind == MaterialKind::Plastic && alpha > 0.0).then(|| (alpha.to_bits(), m.ior.to_bits()))
}

/// Computes (and keeps for the process) the coat tables of `scene`'s rough plastics, so that
/// preparing the scene later ([`SceneData::with_options`]) finds them: they depend on the
/// materials alone, so a caller can compute them while it builds the BVH (the facade does).
pub fn prepare_plastic_tables(scene: &Scene) {
    prepare_plastic_tables_for(&scene.materials);
}

/// [`prepare_plastic_tables`] for these materials (e.g. a scene's, on a thread of their own
/// as soon as it is loaded). A table being computed by another thread is waited for, not
/// computed twice.
pub fn prepare_plastic_tables_for(materials: &[raylume_scene::Material]) {
    tables_of(materials);
}

/// The coat tables of the rough plastics among `materials`, by key, in key order.
///
/// The process keeps every table it computed. A key no one has asked for is marked pending
/// and computed by this call (its tables on every core, outside any lock); a key pending in
/// another call is waited for, not computed twice, except by a rayon worker, which computes
/// it again rather than wait. No rayon job ever waits here: an earlier
/// form computed each table inside `OnceLock::get_or_init` within a parallel iterator, and a
/// worker waiting in a nested join could steal a job waiting on a table its own stack was
/// computing: a deadlock (seen on two cores: `prepare_plastic_tables` beside the BVH build
/// and `prepare_plastic_tables_for` on the loading thread, both asking for the living
/// room's tables).
fn tables_of(materials: &[raylume_scene::Material]) -> (Vec<(u32, u32)>, Vec<RoughPlasticTable>) {
    use rayon::prelude::*;
    use std::sync::{Condvar, Mutex, MutexGuard, OnceLock};
    type Cache = HashMap<(u32, u32), Option<RoughPlasticTable>>;
    static CACHE: OnceLock<(Mutex<Cache>, Condvar)> = OnceLock::new();
    let (cache, ready) = CACHE.get_or_init(Default::default);
    let lock = || cache.lock().unwrap_or_else(|e| e.into_inner());
    let mut keys: Vec<(u32, u32)> = materials.iter().filter_map(table_key).collect();
    keys.sort_unstable();
    keys.dedup();
    // Claim the keys no one has: `None` marks a table in the making.
    let mine: Vec<(u32, u32)> = {
        let mut c = lock();
        let mut mine = Vec::new();
        for k in &keys {
            if !c.contains_key(k) {
                c.insert(*k, None);
                mine.push(*k);
            }
        }
        mine
    };
    if !mine.is_empty() {
        // Should the computation panic, its keys are released (and the waiters woken, to
        // claim them) rather than left pending for ever.
        struct Release<'a>(&'a [(u32, u32)], &'a Mutex<Cache>, &'a Condvar);
        impl Drop for Release<'_> {
            fn drop(&mut self) {
                let mut c = self.1.lock().unwrap_or_else(|e| e.into_inner());
                for k in self.0 {
                    if c.get(k).is_some_and(Option::is_none) {
                        c.remove(k);
                    }
                }
                self.2.notify_all();
            }
        }
        let release = Release(&mine, cache, ready);
        let tables: Vec<RoughPlasticTable> = mine
            .par_iter()
            .map(|k| RoughPlasticTable::new(f32::from_bits(k.0), f32::from_bits(k.1)))
            .collect();
        let mut c = lock();
        for (k, t) in mine.iter().zip(tables) {
            c.insert(*k, Some(t));
        }
        drop(c);
        drop(release);
    }
    // Every key is now ready or in another call's making: wait for those (a thread outside
    // the rayon pool; a worker computes them itself), or claim a key a failed call released.
    let mut c: MutexGuard<'_, Cache> = lock();
    loop {
        let missing: Vec<(u32, u32)> = keys
            .iter()
            .filter(|k| !c.get(k).is_some_and(Option::is_some))
            .copied()
            .collect();
        if missing.is_empty() {
            let tables = keys.iter().map(|k| c[k].expect("ready")).collect();
            return (keys, tables);
        }
        if missing.iter().any(|k| !c.contains_key(k)) {
            // Released by a call that failed: start over, claiming it.
            drop(c);
            return tables_of(materials);
        }
        if rayon::current_thread_index().is_some() {
            // A rayon worker never waits for another call's tables (that call may be a job
            // further down its own stack, which cannot go on until this one returns): it
            // computes them itself, the same numbers, and keeps whichever lands first.
            drop(c);
            let tables: Vec<RoughPlasticTable> = missing
                .par_iter()
                .map(|k| RoughPlasticTable::new(f32::from_bits(k.0), f32::from_bits(k.1)))
                .collect();
            c = lock();
            for (k, t) in missing.iter().zip(tables) {
                c.entry(*k).or_insert(None).get_or_insert(t);
            }
            ready.notify_all();
        } else {
            c = ready.wait(c).unwrap_or_else(|e| e.into_inner());
        }
    }
}

/// One coat table per distinct (alpha, ior) of the scene's rough plastics, and the index of
/// each. A table is a numerical integration (~0.1 s on one core): the distinct ones are
/// computed in parallel, and kept for the life of the process, so that repeated renders of a
/// scene (benches, `--reorder auto`'s trials, an interactive tool) pay for them once.
fn plastic_tables(scene: &Scene) -> (Vec<RoughPlasticTable>, TableIndex) {
    let (keys, tables) = tables_of(&scene.materials);
    let index = keys
        .iter()
        .enumerate()
        .map(|(i, k)| (Some(*k), i as u32))
        .collect();
    (tables, index)
}

/// Appends texture `t` to the texel buffer in its own format (`linear`: as floats whatever
/// its format, for environment maps); returns its header's offset and format.
fn append_texture(
    texels: &mut Vec<u32>,
    t: &Texture,
    what: &str,
    linear: bool,
) -> Result<(u32, u32), KernelError> {
    let n = u64::from(t.width) * u64::from(t.height);
    if n == 0 || t.texels.len() as u64 != n {
        return Err(KernelError::InvalidScene(format!(
            "{what} `{}` is {}x{} but holds {} texels",
            t.name,
            t.width,
            t.height,
            t.texels.len()
        )));
    }
    let offset = texels.len() as u64;
    let srgb8 = t.texels.is_srgb8() && !linear;
    let words = if srgb8 { n } else { 3 * n };
    // Word indices must stay within u32 in the kernels.
    if offset + words > u64::from(u32::MAX) {
        return Err(KernelError::InvalidScene(format!(
            "textures hold more than 2^32 words in total (at {what} `{}`)",
            t.name
        )));
    }
    // On every core: the living room's 4.9 M texels took 12-16 ms on one.
    match &t.texels {
        Texels::Srgb8(codes) if srgb8 => {
            texels.par_extend(
                codes
                    .par_iter()
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], 0])),
            );
        }
        Texels::Linear(floats) => {
            texels.par_extend(floats.par_iter().flat_map_iter(|c| c.map(f32::to_bits)))
        }
        Texels::Srgb8(codes) => {
            let table = srgb8_table();
            texels.par_extend(
                codes
                    .par_iter()
                    .flat_map_iter(|c| c.map(|c| table[c as usize].to_bits())),
            );
        }
    }
    Ok((
        offset as u32,
        if srgb8 { TEXELS_SRGB8 } else { TEXELS_LINEAR },
    ))
}

/// The leaves a preparation looks up, in leaf order: each one's kind and scene index.
#[derive(Clone, Copy, Debug)]
pub enum Leaves<'a> {
    /// A tree's primitive records ([`GpuBvh::primitives`]).
    Primitives(&'a [Primitive]),
    /// A tree over the scene's triangles only, leaf `k` holding triangle `order[k]` (a tree
    /// built on the GPU: `crate::gpu::ResidentBvh`).
    Triangles(&'a [u32]),
}

impl Leaves<'_> {
    /// How many leaves.
    pub fn len(&self) -> usize {
        match self {
            Leaves::Primitives(p) => p.len(),
            Leaves::Triangles(o) => o.len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Leaf `k`'s kind ([`PRIM_TRIANGLE`], [`PRIM_SPHERE`]) and index in the scene's list.
    pub fn get(&self, k: usize) -> (u32, u32) {
        match self {
            Leaves::Primitives(p) => (p[k].kind(), p[k].scene_index()),
            Leaves::Triangles(o) => (PRIM_TRIANGLE, o[k]),
        }
    }
}

impl SceneData {
    /// Whether this data was prepared over a tree of `bvh`'s primitive count (data kept from
    /// an earlier render handed to a tracer: `CpuTracer::with_data`, `GpuScene::upload_data`).
    pub fn check_bvh(&self, bvh: &GpuBvh) -> Result<(), KernelError> {
        if self.prim_materials.len() != bvh.primitives.len() {
            return Err(KernelError::InvalidScene(format!(
                "scene data for {} primitives given a BVH of {}",
                self.prim_materials.len(),
                bvh.primitives.len()
            )));
        }
        Ok(())
    }

    /// Flattens `scene` for the primitives of `bvh` (which must have been built from it).
    pub fn new(scene: &Scene, bvh: &GpuBvh) -> Result<Self, KernelError> {
        Self::with_options(scene, bvh, &SceneOptions::default())
    }

    /// [`SceneData::new`], also preparing what `options` asks for (the environment guide's
    /// walks on every core: [`crate::env_guide::learn_environment_guide`]).
    pub fn with_options(
        scene: &Scene,
        bvh: &GpuBvh,
        options: &SceneOptions,
    ) -> Result<Self, KernelError> {
        Self::with_guide_walks(scene, bvh, options, &mut |g| {
            Ok(learn_environment_guide_with(g, bvh))
        })
    }

    /// [`SceneData::with_options`], the environment guide learned by `walk` (given the walks'
    /// parameters, it returns what [`crate::env_guide::learn_environment_guide`] would: the
    /// GPU's walks, `crate::gpu::GuideLearner`). Called at most once, only when the guide is
    /// learned; its error is returned.
    pub fn with_guide_walks(
        scene: &Scene,
        bvh: &GpuBvh,
        options: &SceneOptions,
        walk: &mut dyn FnMut(&GuideParams) -> Result<EnvironmentGuide, KernelError>,
    ) -> Result<Self, KernelError> {
        Self::check_counts(scene, bvh)?;
        Self::with_leaves(scene, Leaves::Primitives(&bvh.primitives), options, walk)
    }

    /// [`SceneData::with_guide_walks`] for the leaves `leaves` of a tree built over `scene`
    /// (the guide's walks, if any, by `walk`: there may be no tree on the CPU to walk).
    pub fn with_leaves(
        scene: &Scene,
        leaves: Leaves<'_>,
        options: &SceneOptions,
        walk: &mut dyn FnMut(&GuideParams) -> Result<EnvironmentGuide, KernelError>,
    ) -> Result<Self, KernelError> {
        let mut data = Self::before_guide(scene, leaves, options)?;
        if let Some(g) = data.pending_guide() {
            let start = std::time::Instant::now();
            let guide = walk(&g)?;
            data.add_guide(scene, guide, start.elapsed().as_secs_f64())?;
        }
        Ok(data)
    }

    /// [`SceneData::with_guide_walks`] without the walks: everything but the environment
    /// guide, which [`SceneData::pending_guide`] then asks for (when `options` wants one and
    /// the scene has a sky and geometry) and [`SceneData::add_guide`] adds. What a GPU render
    /// prepares before its device is open: the data is uploaded while the device compiles
    /// the walks (`crate::gpu::GpuScene::upload_before_guide`). The texel buffer's layout is
    /// the same as with the guide, whose distributions come last.
    pub fn before_guide_walks(
        scene: &Scene,
        bvh: &GpuBvh,
        options: &SceneOptions,
    ) -> Result<Self, KernelError> {
        Self::check_counts(scene, bvh)?;
        Self::before_guide(scene, Leaves::Primitives(&bvh.primitives), options)
    }

    /// The walks' parameters when the data wants a guide not learned yet: the data is then
    /// incomplete, and [`SceneData::add_guide`] completes it.
    pub fn pending_guide(&self) -> Option<GuideParams> {
        (self.environment_guide && self.environment_guide_walks.is_none())
            .then(|| GuideParams::new(&self.camera, self.scene_min, self.scene_extent))
    }

    /// Fails when a guide is pending ([`SceneData::pending_guide`]): such data would render
    /// as if it had no guide (the unguided distribution) while asking for one.
    pub fn check_complete(&self) -> Result<(), KernelError> {
        match self.pending_guide() {
            Some(_) => Err(KernelError::InvalidSettings(
                "scene data with its environment guide still to learn (SceneData::add_guide, \
                 learn_pending_guide, or GpuScene::upload_before_guide and PendingScene::finish)"
                    .into(),
            )),
            None => Ok(()),
        }
    }

    /// Words the guide's distributions will take at the end of `texels` should the walks
    /// find enough escapes (0 when no guide is pending): a constant sky's
    /// [`guided_constant_cdf`] per cell of the guide's grid, or a map's
    /// [`guided_map_cdf`].
    pub fn pending_guide_words(&self) -> usize {
        if self.pending_guide().is_none() {
            return 0;
        }
        let rows_and_columns = |w: usize, h: usize| h + w * h;
        match self.environment_kind {
            ENVIRONMENT_MAP => rows_and_columns(
                self.environment_width as usize,
                self.environment_height as usize,
            ),
            _ => {
                let (grid, _) = crate::env_guide::guide_grid(self.scene_extent);
                grid.iter().map(|&n| n as usize).product::<usize>()
                    * rows_and_columns(GUIDE_WIDTH as usize, GUIDE_HEIGHT as usize)
            }
        }
    }

    /// The guide's distributions for `guide` and where they go: at float index `offset` of
    /// the texel buffer (its length before them). `None` when the walks found too few
    /// escapes (the unguided distribution is sampled then).
    fn guide_distributions(
        &self,
        scene: &Scene,
        guide: &EnvironmentGuide,
        offset: u32,
    ) -> Option<(Vec<f32>, GuidedCdf)> {
        if !guide.is_useful() {
            return None;
        }
        Some(match &scene.environment {
            Environment::Map {
                image, rotation, ..
            } => {
                let (weights, _) = environment_weights(image);
                let (w, h) = (image.width as usize, image.height as usize);
                (
                    guided_map_cdf(guide, w, h, rotation / 360.0, &weights),
                    GuidedCdf {
                        offset,
                        width: image.width,
                        height: image.height,
                        grid: [1, 1, 1],
                        grid_scale: Vec3::ZERO,
                    },
                )
            }
            _ => (
                guided_constant_cdf(guide),
                GuidedCdf {
                    offset,
                    width: GUIDE_WIDTH,
                    height: GUIDE_HEIGHT,
                    grid: guide.grid,
                    grid_scale: guide.grid_scale,
                },
            ),
        })
    }

    /// Completes data with a guide pending ([`SceneData::pending_guide`]) with what the walks
    /// found (`seconds`: how long the preparation waited for them): their distributions are
    /// appended to `texels` when useful. An error when no guide is pending.
    pub fn add_guide(
        &mut self,
        scene: &Scene,
        guide: EnvironmentGuide,
        seconds: f64,
    ) -> Result<(), KernelError> {
        let offset = texel_index(&self.texels)?;
        if let Some(cdf) = self.take_guide(scene, &guide, seconds, offset)? {
            extend_floats(&mut self.texels, cdf);
            // The buffer must stay addressable with u32 float indices.
            texel_index(&self.texels)?;
        }
        Ok(())
    }

    /// [`SceneData::add_guide`] for data whose texels are elsewhere (uploaded): records what
    /// the walks found and returns the distributions to place at float index `offset` of the
    /// texel buffer (`None`: too few escapes, nothing to place).
    pub fn take_guide(
        &mut self,
        scene: &Scene,
        guide: &EnvironmentGuide,
        seconds: f64,
        offset: u32,
    ) -> Result<Option<Vec<f32>>, KernelError> {
        if self.pending_guide().is_none() {
            return Err(KernelError::InvalidSettings(
                "an environment guide added to scene data that asked for none".into(),
            ));
        }
        self.environment_guide_seconds = seconds;
        self.environment_guide_walks = Some((guide.walks, guide.escapes));
        Ok(self
            .guide_distributions(scene, guide, offset)
            .map(|(cdf, at)| {
                self.environment_guided_cdf = Some(at);
                cdf
            }))
    }

    /// Completes a pending guide ([`SceneData::pending_guide`]) by walks on the CPU over
    /// `bvh` (the tree the data was prepared over): data prepared for a GPU render that
    /// renders on the CPU. Nothing to do when no guide is pending.
    pub fn learn_pending_guide(&mut self, scene: &Scene, bvh: &GpuBvh) -> Result<(), KernelError> {
        if let Some(g) = self.pending_guide() {
            let start = std::time::Instant::now();
            let guide = learn_environment_guide_with(&g, bvh);
            self.add_guide(scene, guide, start.elapsed().as_secs_f64())?;
        }
        Ok(())
    }

    /// Fails unless `bvh` was built over as many triangles and spheres as `scene` has.
    fn check_counts(scene: &Scene, bvh: &GpuBvh) -> Result<(), KernelError> {
        if bvh.triangle_count as usize != scene.triangles.len()
            || bvh.sphere_count as usize != scene.spheres.len()
        {
            return Err(KernelError::InvalidScene(format!(
                "the BVH was built over {} triangles and {} spheres, but the scene has {} and {}",
                bvh.triangle_count,
                bvh.sphere_count,
                scene.triangles.len(),
                scene.spheres.len()
            )));
        }
        Ok(())
    }

    /// Everything of [`SceneData::with_leaves`] but the guide's walks and distributions.
    fn before_guide(
        scene: &Scene,
        leaves: Leaves<'_>,
        options: &SceneOptions,
    ) -> Result<Self, KernelError> {
        if let Leaves::Triangles(order) = leaves
            && order.len() != scene.triangles.len()
        {
            return Err(KernelError::InvalidScene(format!(
                "a tree of {} triangles, but the scene has {}",
                order.len(),
                scene.triangles.len()
            )));
        }
        let decode = options.decode_textures;
        // The words every texture takes (as `append_texture` lays them out), reserved at once:
        // growing the buffer texture by texture copied it each time.
        let words: usize = scene
            .textures
            .iter()
            .map(|t| t.texels.len() * if t.texels.is_srgb8() && !decode { 1 } else { 3 })
            .sum();
        let mut texels = Vec::with_capacity(256 + words);
        if !decode && scene.textures.iter().any(|t| t.texels.is_srgb8()) {
            debug_assert_eq!(SRGB8_TABLE, 0, "the table comes first");
            extend_floats(&mut texels, srgb8_table().iter().copied());
        }
        let mut texture_headers = Vec::with_capacity(scene.textures.len());
        for t in &scene.textures {
            let (offset, format) = append_texture(&mut texels, t, "texture", decode)?;
            texture_headers.push(TextureHeader {
                offset,
                width: t.width,
                height: t.height,
                format,
            });
        }

        let mut materials = Vec::with_capacity(scene.materials.len().max(1));
        let (plastic_tables, table_of) = plastic_tables(scene);
        for (i, m) in scene.materials.iter().enumerate() {
            let texture = match (m.kind, m.albedo_texture) {
                (MaterialKind::Glass, _) | (_, None) => NO_TEXTURE,
                (_, Some(t)) if (t as usize) < scene.textures.len() => t,
                (_, Some(t)) => {
                    return Err(KernelError::InvalidScene(format!(
                        "material {i} `{}` uses texture {t}, but the scene has {} textures",
                        m.name,
                        scene.textures.len()
                    )));
                }
            };
            let alpha = m.roughness * m.roughness;
            let (kind, color) = match m.kind {
                MaterialKind::Diffuse => (MATERIAL_DIFFUSE, m.albedo),
                MaterialKind::Metal => (MATERIAL_METAL, m.albedo),
                MaterialKind::Glass => (MATERIAL_GLASS, m.tint),
                MaterialKind::Plastic => (MATERIAL_PLASTIC, m.albedo),
            };
            let table = table_of.get(&table_key(m)).copied().unwrap_or(NO_TABLE);
            materials.push(GpuMaterial {
                color: color.into(),
                kind,
                emission: m.emission.into(),
                alpha: if m.kind == MaterialKind::Diffuse {
                    0.0
                } else {
                    alpha
                },
                ior: m.ior,
                texture,
                flags: if m.two_sided { MATERIAL_TWO_SIDED } else { 0 },
                table,
                eta: m.conductor_eta.into(),
                _pad0: 0,
                k: m.conductor_k.into(),
                _pad1: 0,
            });
        }
        if materials.is_empty() {
            materials.push(GpuMaterial::default());
        }

        let has_shading = scene
            .triangles
            .par_iter()
            .any(|t| t.normals.is_some() || t.uvs.is_some());
        // Each leaf primitive's material and shading data, on every core.
        let lookup = |leaf: usize,
                      (kind, index): (u32, u32)|
         -> Result<(u32, TriangleShading), KernelError> {
            let index = index as usize;
            let (material, shading) = match kind {
                PRIM_TRIANGLE => {
                    let t = scene.triangles.get(index).ok_or_else(|| {
                        KernelError::InvalidScene(format!(
                            "BVH primitive {leaf} refers to triangle {index}, but the scene has \
                             {} triangles (was the BVH built from another scene?)",
                            scene.triangles.len()
                        ))
                    })?;
                    let mut s = TriangleShading::default();
                    if let Some([n0, n1, n2]) = t.normals {
                        s.n0 = n0.into();
                        s.n1 = n1.into();
                        s.n2 = n2.into();
                        s.flags |= SHADING_HAS_NORMALS;
                    }
                    if let Some([a, b, c]) = t.uvs {
                        (s.u0, s.v0, s.u1, s.v1, s.u2, s.v2) = (a.x, a.y, b.x, b.y, c.x, c.y);
                        s.flags |= SHADING_HAS_UVS;
                    }
                    (t.material, s)
                }
                PRIM_SPHERE => {
                    let s = scene.spheres.get(index).ok_or_else(|| {
                        KernelError::InvalidScene(format!(
                            "BVH primitive {leaf} refers to sphere {index}, but the scene has {} \
                             spheres (was the BVH built from another scene?)",
                            scene.spheres.len()
                        ))
                    })?;
                    (s.material, TriangleShading::default())
                }
                k => {
                    return Err(KernelError::InvalidScene(format!(
                        "BVH primitive {leaf} has unknown kind {k}"
                    )));
                }
            };
            if material as usize >= scene.materials.len() {
                return Err(KernelError::InvalidScene(format!(
                    "BVH primitive {leaf} uses material {material}, but the scene has {} materials",
                    scene.materials.len()
                )));
            }
            Ok((material, shading))
        };
        // One pass on every core; only when a primitive failed, a second for the first bad
        // one's error, as a loop would report it.
        let failed = std::sync::atomic::AtomicBool::new(false);
        let looked_up = |leaf: usize| {
            lookup(leaf, leaves.get(leaf)).unwrap_or_else(|_| {
                failed.store(true, std::sync::atomic::Ordering::Relaxed);
                Default::default()
            })
        };
        let mut prim_materials: Vec<u32> = Vec::new();
        let mut triangle_shading: Vec<TriangleShading> = Vec::new();
        if has_shading {
            (0..leaves.len())
                .into_par_iter()
                .map(looked_up)
                .unzip_into_vecs(&mut prim_materials, &mut triangle_shading);
        } else {
            (0..leaves.len())
                .into_par_iter()
                .map(|leaf| looked_up(leaf).0)
                .collect_into_vec(&mut prim_materials);
        }
        if failed.into_inner()
            && let Some(e) = (0..leaves.len())
                .into_par_iter()
                .find_map_first(|leaf| lookup(leaf, leaves.get(leaf)).err())
        {
            return Err(e);
        }

        let mut data = SceneData {
            features: crate::tracer_features(scene),
            camera: scene.camera,
            materials,
            prim_materials,
            triangle_shading,
            texture_headers,
            texels: Vec::new(),
            environment_kind: ENVIRONMENT_BLACK,
            environment_color: Vec3::ZERO,
            environment_rotation: 0.0,
            environment_width: 0,
            environment_height: 0,
            environment_offset: 0,
            environment_cdf: 0,
            environment_select: 0.0,
            environment_guided_cdf: None,
            environment_guide_walks: None,
            environment_guide_seconds: 0.0,
            environment_guide: false,
            scene_min: Vec3::ZERO,
            scene_extent: Vec3::ZERO,
            lights: Vec::new(),
            light_power: 0.0,
            plastic_tables,
            estimator: Estimator::Plain,
            russian_roulette: None,
            sampler: Sampler::Independent,
            sample_range: None,
        };
        match &scene.environment {
            Environment::Black => {}
            Environment::Constant(c) => {
                if c.max_element() > 0.0 {
                    data.environment_kind = ENVIRONMENT_CONSTANT;
                    data.environment_color = *c;
                }
            }
            Environment::Map {
                image,
                strength,
                rotation,
            } => {
                (data.environment_offset, _) =
                    append_texture(&mut texels, image, "environment map", true)?;
                data.environment_kind = ENVIRONMENT_MAP;
                data.environment_color = Vec3::splat(*strength);
                data.environment_rotation = rotation / 360.0;
                data.environment_width = image.width;
                data.environment_height = image.height;
            }
        }
        // The environment's mean radiance over directions (luminance), for its share of the
        // light list.
        let mut environment_luminance = 0.0f32;
        match &scene.environment {
            Environment::Constant(c) if c.max_element() > 0.0 => {
                environment_luminance = c.dot(Vec3::from(LUMINANCE));
            }
            Environment::Map {
                image, strength, ..
            } => {
                let (weights, mean) = environment_weights(image);
                data.environment_cdf = texel_index(&texels)?;
                extend_floats(
                    &mut texels,
                    cdf_from_weights(image.width as usize, image.height as usize, &weights),
                );
                environment_luminance = mean * strength;
            }
            _ => {}
        }
        let bounds = scene.bounds();
        if !bounds.is_empty() {
            data.scene_min = bounds.min;
            data.scene_extent = bounds.extent();
        }
        // The guide is learned after (`pending_guide`, `add_guide`): its distributions come
        // last in the texel buffer.
        data.environment_guide =
            options.environment_guide && environment_luminance > 0.0 && !leaves.is_empty();
        data.texels = texels;
        // pbrt's estimate of an infinite light's power: its radiance over a disc of the
        // scene's bounding radius.
        let radius = if bounds.is_empty() {
            1.0
        } else {
            (0.5 * bounds.extent().length()).max(f32::MIN_POSITIVE)
        };
        let environment_power = std::f32::consts::PI * radius * radius * environment_luminance;
        (data.lights, data.light_power, data.environment_select) =
            light_list(scene, environment_power);
        Ok(data)
    }

    /// The choices of the next renders this data holds (its estimator, roulette, sampler,
    /// guide use and sample range).
    pub fn choices(&self) -> RenderChoices {
        RenderChoices {
            estimator: self.estimator,
            russian_roulette: self.russian_roulette,
            sampler: self.sampler,
            environment_guide: self.environment_guide,
            sample_range: self.sample_range.clone(),
        }
    }

    /// The uniforms of a render with `settings`; the batch fields are left for the caller.
    pub fn uniforms(&self, settings: &TraceSettings) -> SceneUniforms {
        self.uniforms_with(settings, &self.choices())
    }

    /// [`SceneData::uniforms`] with `choices` in place of the data's own (a tracer sharing
    /// the data with others: `CpuTracer::with_shared`).
    pub fn uniforms_with(
        &self,
        settings: &TraceSettings,
        choices: &RenderChoices,
    ) -> SceneUniforms {
        let [origin, forward, right, up] =
            camera_basis(&self.camera, settings.width, settings.height);
        // The distribution NEE samples the environment by: the guided ones when asked for and
        // learned, else a map's by radiance, else uniform over the sphere (no grid).
        let cdf = match self.environment_guided_cdf {
            Some(guided) if choices.environment_guide => guided,
            _ if self.environment_kind == ENVIRONMENT_MAP => GuidedCdf {
                offset: self.environment_cdf,
                width: self.environment_width,
                height: self.environment_height,
                grid: [1, 1, 1],
                grid_scale: Vec3::ZERO,
            },
            _ => GuidedCdf {
                offset: 0,
                width: 0,
                height: 0,
                grid: [1, 1, 1],
                grid_scale: Vec3::ZERO,
            },
        };
        SceneUniforms {
            camera_origin: origin.into(),
            width: settings.width,
            camera_forward: forward.into(),
            height: settings.height,
            camera_right: right.into(),
            spp: settings.spp,
            camera_up: up.into(),
            max_bounces: settings.max_bounces,
            environment_color: self.environment_color.into(),
            environment_kind: self.environment_kind,
            scene_min: self.scene_min.into(),
            seed: settings.seed,
            scene_extent: self.scene_extent.into(),
            environment_rotation: self.environment_rotation,
            environment_width: self.environment_width,
            environment_height: self.environment_height,
            environment_offset: self.environment_offset,
            primitive_count: self.prim_materials.len() as u32,
            material_count: self.materials.len() as u32,
            texture_count: self.texture_headers.len() as u32,
            light_count: match choices.estimator {
                Estimator::Plain => 0,
                Estimator::Nee => self.lights.len() as u32,
            },
            light_power: self.light_power,
            rr_depth: choices.russian_roulette.unwrap_or(NO_ROULETTE),
            sampler: choices.sampler.uniform(),
            environment_select: match choices.estimator {
                Estimator::Plain => 0.0,
                Estimator::Nee => self.environment_select,
            },
            environment_cdf: cdf.offset,
            environment_cdf_width: cdf.width,
            environment_cdf_height: cdf.height,
            environment_grid: cdf.grid,
            environment_grid_scale: cdf.grid_scale.into(),
            ..Default::default()
        }
    }
}
