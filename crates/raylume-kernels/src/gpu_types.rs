//! Types shared by the WGSL kernels and their Rust mirror, byte for byte.
//!
//! Each type is `#[repr(C)]`, `Pod`, with its size and field offsets asserted below; the WGSL
//! struct of the same name in `gpu_types.wgsl` has the same fields in the same order (padding
//! spelled out as `_pad*` fields). The test `layout_matches_wgsl` parses the assembled shader
//! with naga and compares every struct's member names and offsets against these.
//!
//! The constants at the top are emitted into the shader by [`wgsl_constants`], so the WGSL
//! side cannot drift from them.

use bytemuck::{Pod, Zeroable};
use std::mem::{offset_of, size_of};

/// `GpuMaterial::kind`: Lambertian reflector.
pub const MATERIAL_DIFFUSE: u32 = 0;
/// `GpuMaterial::kind`: conductor (mirror at alpha 0, GGX above; Fresnel of `eta + i k`).
pub const MATERIAL_METAL: u32 = 1;
/// `GpuMaterial::kind`: dielectric (smooth at alpha 0, GGX above).
pub const MATERIAL_GLASS: u32 = 2;
/// `GpuMaterial::kind`: plastic, a diffuse base under a dielectric coat (smooth at alpha 0,
/// GGX above with the rough-coat table `GpuMaterial::table`).
pub const MATERIAL_PLASTIC: u32 = 3;

/// `GpuMaterial::table` of a material without a rough-plastic table.
pub const NO_TABLE: u32 = u32::MAX;

/// `GpuMaterial::flags`: the material emits from both faces (else from the front face only,
/// the side its geometric normal points to).
pub const MATERIAL_TWO_SIDED: u32 = 1;

/// `GpuMaterial::texture` when the material has no albedo texture.
pub const NO_TEXTURE: u32 = u32::MAX;

/// `TextureHeader::format`: a texel is three words, the bits of its linear R, G, B floats.
pub const TEXELS_LINEAR: u32 = 0;

/// `TextureHeader::format`: a texel is one word, its 8-bit sRGB codes R, G, B in bytes 0, 1,
/// 2 (`raylume_scene::Texels::Srgb8`), each decoded through the table at [`SRGB8_TABLE`].
pub const TEXELS_SRGB8: u32 = 1;

/// Where the texel buffer holds `raylume_scene::srgb8_table()` (256 words, the bits of each
/// code's linear f32) when any texture is [`TEXELS_SRGB8`]: its first word.
pub const SRGB8_TABLE: u32 = 0;

/// `SceneUniforms::environment_kind`: escaping rays carry nothing.
pub const ENVIRONMENT_BLACK: u32 = 0;
/// `SceneUniforms::environment_kind`: constant radiance `environment_color`.
pub const ENVIRONMENT_CONSTANT: u32 = 1;
/// `SceneUniforms::environment_kind`: equirectangular map times `environment_color`.
pub const ENVIRONMENT_MAP: u32 = 2;

/// `TriangleShading::flags`: the triangle has per-vertex shading normals.
pub const SHADING_HAS_NORMALS: u32 = 1;
/// `TriangleShading::flags`: the triangle has per-vertex texture coordinates.
pub const SHADING_HAS_UVS: u32 = 2;

/// The sort key of a dead ray (raylume-sort's): sorting by key also compacts the live rays
/// to the front. The WGSL constant comes from raylume-sort's `MORTON_WGSL`.
pub const DEAD_RAY_KEY: u32 = raylume_sort::DEAD_RAY_KEY;

/// The megakernel's threads take a batch's pixels in tiles of `PIXEL_TILE_WIDTH` x
/// `PIXEL_TILE_HEIGHT` (a 32-lane warp one tile) instead of scanlines, so that a warp's rays
/// start closer together ([`tiled_ray`](crate::cpu::stages::tiled_ray)). WGSL: the same names.
pub const PIXEL_TILE_WIDTH: u32 = 8;
/// See [`PIXEL_TILE_WIDTH`].
pub const PIXEL_TILE_HEIGHT: u32 = 4;

/// Random-number dimension (a group of 4 numbers) of the camera ray's pixel jitter. It uses x
/// and y only: under ZSobol its z and w are not drawn (0; `shade::path_rand4`).
pub const DIM_CAMERA: u32 = 0;
/// Random-number dimension of the scattering decision at a hit.
pub const DIM_SCATTER: u32 = 1;
/// Random-number dimension of next-event estimation at a hit: the light, then the point on it.
pub const DIM_LIGHT: u32 = 2;

/// Random-number dimension of the Russian-roulette decision after a hit (x only; under ZSobol
/// z and w are 0, as for [`DIM_CAMERA`]).
pub const DIM_ROULETTE: u32 = 3;

/// `GpuLight::kind`: an emissive triangle.
pub const LIGHT_TRIANGLE: u32 = 0;
/// `GpuLight::kind`: an emissive sphere (its outside; also its inside when two-sided).
pub const LIGHT_SPHERE: u32 = 1;
/// `GpuLight::kind`: the environment (constant, or a map sampled by its luminance).
pub const LIGHT_ENVIRONMENT: u32 = 2;
/// `SceneUniforms::sampler`: independent numbers, `rand4`.
pub const SAMPLER_INDEPENDENT: u32 = 0;
/// `SceneUniforms::sampler`: ZSobol, `sobol4`.
pub const SAMPLER_ZSOBOL: u32 = 1;
/// `SceneUniforms::sampler`: ZSobol with Burley's shuffle, `shuffled_sobol4`.
pub const SAMPLER_SOBOL: u32 = 2;
/// The tracer's `SAMPLER` override when a pipeline is not compiled for one sampler: the
/// uniforms' `sampler` decides at run time (every sampler's code in the pipeline).
pub const SAMPLER_FROM_SCENE: u32 = 0xffff_ffff;
/// Random-number dimensions (groups of four) a path segment may draw: `DIM_CAMERA` ..
/// `DIM_ROULETTE`. ZSobol numbers segment `b`'s dimension `d` as pair group
/// `b * DIMS_PER_BOUNCE + d`.
pub const DIMS_PER_BOUNCE: u32 = 4;
/// `SceneUniforms::rr_depth` when Russian roulette is off.
pub const NO_ROULETTE: u32 = u32::MAX;

/// Russian roulette keeps a path with probability `min(max throughput, RR_MAX_SURVIVAL)`
/// (Mitsuba's `path`: 0.95), dividing the throughput of the survivors by it.
pub const RR_MAX_SURVIVAL: f32 = 0.95;

/// `RayState::alive` of a live ray whose last vertex did not sample the lights; any other
/// nonzero value is the `f32` bits of the BSDF pdf of a live ray's last direction, sampled at a
/// vertex that also sampled the lights (the multiple-importance weight of the emission it hits
/// next needs it). The bits of 1 are a denormal no such pdf takes.
pub const RAY_ALIVE: u32 = 1;

/// Rec. 709 luminance weights: the light list chooses lights by area times the luminance of
/// their emission.
pub const LUMINANCE: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// A shadow ray toward a point on a light ends this fraction of the way there, so that it
/// does not find the light's own triangle (the watertight test's `t` is exact to ~1e-6).
pub const SHADOW_T_SCALE: f32 = 0.9999;

/// The far end of every ray: the largest finite `f32` (WGSL has no infinity literal).
pub const T_MAX: f32 = f32::MAX;

/// Scene-constant data and the current batch, in a uniform buffer.
///
/// `repr(C)`, `Pod`, 224 bytes. WGSL: `SceneUniforms`.
///
/// The camera is a pinhole: a pixel's ray is
/// `normalize(camera_forward + sx * camera_right + sy * camera_up)` with `sx, sy` in
/// `[-1, 1]` across the image; `camera_right` and `camera_up` are pre-scaled by the field of
/// view and aspect ratio.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SceneUniforms {
    pub camera_origin: [f32; 3],
    pub width: u32,
    pub camera_forward: [f32; 3],
    pub height: u32,
    pub camera_right: [f32; 3],
    /// Samples per pixel of the whole render.
    pub spp: u32,
    pub camera_up: [f32; 3],
    /// Bounces after the camera ray (a path has at most `max_bounces + 1` segments).
    pub max_bounces: u32,
    /// Constant radiance, or the map's multiplier (`strength` in all three channels).
    pub environment_color: [f32; 3],
    /// [`ENVIRONMENT_BLACK`], [`ENVIRONMENT_CONSTANT`] or [`ENVIRONMENT_MAP`].
    pub environment_kind: u32,
    /// Scene bounds, for the rays' sort keys.
    pub scene_min: [f32; 3],
    pub seed: u32,
    pub scene_extent: [f32; 3],
    /// Emissive triangles in the light list that next-event estimation samples; 0 for the
    /// paper's plain estimator.
    pub light_count: u32,
    /// Map rotation about +y, in turns (degrees / 360).
    pub environment_rotation: f32,
    pub environment_width: u32,
    pub environment_height: u32,
    /// Index of the map's first texel in the texel buffer (texels, not floats).
    pub environment_offset: u32,
    /// First sample index of this batch.
    pub sample_begin: u32,
    /// Samples per pixel in this batch.
    pub sample_count: u32,
    /// First pixel of this batch (row-major index).
    pub pixel_begin: u32,
    /// Pixels in this batch.
    pub pixel_count: u32,
    /// Index of this batch's statistics slot.
    pub batch_index: u32,
    /// Multiplier `resolve` applies after summing: `1 / spp` on a pixel's last batch, else 1.
    pub resolve_scale: f32,
    /// `sample_count * pixel_count`.
    pub rays_in_batch: u32,
    /// Capacity of one wavefront ray queue (the largest `rays_in_batch` of the render).
    pub queue_capacity: u32,
    pub primitive_count: u32,
    pub material_count: u32,
    pub texture_count: u32,
    /// The sum of area times emitted luminance over the light list (next-event estimation's
    /// light-selection pdf of a light is its share).
    pub light_power: f32,
    /// Russian roulette decides after every hit of a segment `>= rr_depth` whether the path
    /// goes on ([`NO_ROULETTE`]: never).
    pub rr_depth: u32,
    /// [`SAMPLER_INDEPENDENT`], [`SAMPLER_ZSOBOL`] or [`SAMPLER_SOBOL`]: where the path's
    /// random numbers come from.
    pub sampler: u32,
    /// The environment's selection probability in the light list (its share of
    /// `light_power`); 0 when next-event estimation does not sample it (then an escaping path
    /// counts it in full).
    pub environment_select: f32,
    /// An environment map's sampling distribution ([`crate::surface::sample_environment`]):
    /// the index in `texels` (floats, not texels) of its row CDF (`environment_height`
    /// floats), followed by each row's column CDF (`environment_width` floats per row).
    pub environment_cdf: u32,
    /// The guide's cells per unit of scene coordinate along each axis (`environment_grid` over
    /// `scene_extent`; 0 along an axis of one cell): a point's cell is
    /// [`crate::surface::environment_cell`]. Zero without a spatial guide.
    pub environment_grid_scale: [f32; 3],
    /// Columns of the grid(s) that `environment_cdf` describes; 0: no distribution (a
    /// constant environment sampled uniformly over the sphere). A map's own size when sampled
    /// by radiance; a guide's grid ([`crate::env_guide`]) otherwise.
    pub environment_cdf_width: u32,
    /// Cells of the guide along x, y, z over the scene's bounds (`[1, 1, 1]`, or zeros,
    /// without a spatial guide): each cell has its own distribution, `environment_cdf_height +
    /// environment_cdf_width * environment_cdf_height` floats after the previous cell's.
    pub environment_grid: [u32; 3],
    /// Rows of the grid(s) that `environment_cdf` describes.
    pub environment_cdf_height: u32,
}

/// One material.
///
/// `repr(C)`, `Pod`, 80 bytes. WGSL: `GpuMaterial`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    /// Reflectance (diffuse, plastic base, metal's Fresnel scale) or transmission tint
    /// (glass), linear RGB.
    pub color: [f32; 3],
    /// [`MATERIAL_DIFFUSE`], [`MATERIAL_METAL`], [`MATERIAL_GLASS`] or [`MATERIAL_PLASTIC`].
    pub kind: u32,
    /// Emitted radiance, linear RGB, from the front face (both with [`MATERIAL_TWO_SIDED`]).
    pub emission: [f32; 3],
    /// GGX alpha = roughness² (metal, glass, plastic); 0 is smooth.
    pub alpha: f32,
    /// Index of refraction (glass, plastic's coat).
    pub ior: f32,
    /// Albedo texture index, or [`NO_TEXTURE`].
    pub texture: u32,
    /// [`MATERIAL_TWO_SIDED`] or 0.
    pub flags: u32,
    /// A rough plastic's coat table: index into the plastic-table buffer, or [`NO_TABLE`].
    pub table: u32,
    /// Metal: real part of the complex index of refraction (0: Fresnel 1).
    pub eta: [f32; 3],
    pub _pad0: u32,
    /// Metal: imaginary part of the complex index of refraction.
    pub k: [f32; 3],
    pub _pad1: u32,
}

/// Per-triangle shading data in leaf order (parallel to the BVH's primitives): per-vertex
/// normals and texture coordinates, interpolated with the hit's barycentrics.
///
/// `repr(C)`, `Pod`, 64 bytes. WGSL: `TriangleShading`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TriangleShading {
    pub n0: [f32; 3],
    pub u0: f32,
    pub n1: [f32; 3],
    pub v0: f32,
    pub n2: [f32; 3],
    pub u1: f32,
    pub v1: f32,
    pub u2: f32,
    pub v2: f32,
    /// [`SHADING_HAS_NORMALS`] | [`SHADING_HAS_UVS`].
    pub flags: u32,
}

/// Where one texture's texels start in the shared texel buffer, their format, and its size.
///
/// `repr(C)`, `Pod`, 16 bytes. WGSL: `TextureHeader`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TextureHeader {
    /// Index of the texture's first word in the texel buffer (a buffer of 32-bit words).
    pub offset: u32,
    pub width: u32,
    pub height: u32,
    /// [`TEXELS_LINEAR`] (three f32 words a texel) or [`TEXELS_SRGB8`] (one word a texel).
    pub format: u32,
}

/// An emitter of the light list that next-event estimation samples, chosen with probability
/// `cdf - previous cdf` (proportional to area times emitted luminance): an emissive triangle
/// ([`LIGHT_TRIANGLE`]: a point `p0 + u e1 + v e2`), an emissive sphere ([`LIGHT_SPHERE`]:
/// centre `p0`, radius `e1.x`; a point of the cap seen from the shading point) or the
/// environment ([`LIGHT_ENVIRONMENT`], last; a direction, other fields unused).
///
/// `repr(C)`, `Pod`, 64 bytes. WGSL: `GpuLight`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    pub p0: [f32; 3],
    /// The running sum of selection probabilities up to and including this light.
    pub cdf: f32,
    pub e1: [f32; 3],
    pub area: f32,
    pub e2: [f32; 3],
    /// 1 when the triangle emits from both faces; 0: only toward `e1 x e2`.
    pub two_sided: u32,
    pub emission: [f32; 3],
    /// [`LIGHT_TRIANGLE`] or [`LIGHT_SPHERE`].
    pub kind: u32,
}

/// One ray of the wavefront, between two `propagate` launches.
///
/// `repr(C)`, `Pod`, 64 bytes. WGSL: `RayState`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RayState {
    pub origin: [f32; 3],
    /// Row-major pixel index.
    pub pixel: u32,
    pub dir: [f32; 3],
    /// Sample index within the pixel (global, not batch-relative).
    pub sample: u32,
    pub throughput: [f32; 3],
    /// Segments traced so far (0 for a camera ray).
    pub depth: u32,
    pub radiance: [f32; 3],
    /// 0 once the path has ended; else [`RAY_ALIVE`], or the bits of the BSDF pdf of its
    /// direction when its last vertex sampled the lights (see [`RAY_ALIVE`]).
    pub alive: u32,
}

/// `NeeRecord::state`: no light sample waits for this ray.
pub const NEE_NONE: u32 = 0;
/// `NeeRecord::state`: a light sample waits, the path goes on.
pub const NEE_PENDING: u32 = 1;
/// `NeeRecord::state`: a light sample waits, the path ended at this vertex (`next_event`
/// writes its sample once the sample's contribution is in).
pub const NEE_ENDED: u32 = 2;

/// Next-event estimation at one vertex of a wavefront ray, deferred by `propagate` to the
/// `next_event` stage that runs after it (its own pipeline, compiled beside `propagate`'s):
/// what `light_query` reads of the hit (`SurfaceHit` without its uv), the material's
/// textured color, the incoming direction, the throughput before the vertex scatters and the
/// light's random numbers, and the vertex's emission term, which the stage adds after the
/// light sample (the order of the other schedules' sums). One per slot of the bounce's ray queue.
///
/// `repr(C)`, `Pod`, 128 bytes. WGSL: `NeeRecord`, stored as its eight 16-byte words in a
/// structure of arrays by slot of the bounce's ray queue (word `k` of slot `t` at
/// `k * queue_capacity + t`: `store_nee_record`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct NeeRecord {
    pub position: [f32; 3],
    pub offset: f32,
    pub geometric_normal: [f32; 3],
    pub back_offset: f32,
    pub shading_normal: [f32; 3],
    pub material: u32,
    /// The material's color at the hit (textured).
    pub color: [f32; 3],
    /// [`NEE_NONE`], [`NEE_PENDING`] or [`NEE_ENDED`].
    pub state: u32,
    pub dir_in: [f32; 3],
    pub _pad0: u32,
    pub throughput: [f32; 3],
    pub _pad1: u32,
    pub rnd: [f32; 4],
    /// The vertex's emission term (`shade::emitted`), added after the light sample.
    pub emitted: [f32; 3],
    pub _pad2: u32,
}

/// The wavefront's per-bounce uniforms: one entry per bounce, each read at its own dynamic
/// offset, so that one submission can run every bounce.
///
/// `repr(C)`, `Pod`, 16 bytes. WGSL: `BounceUniforms`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BounceUniforms {
    /// The segment `propagate` traces (0: camera rays).
    pub depth: u32,
    /// 1 when the rays are sorted before the next segment: `propagate` then writes each live
    /// ray's sort key at its slot of the next queue (so that only live rays are sorted);
    /// 0: it computes no key.
    pub sort_next: u32,
    /// With `sort_next`: how far the 30-bit key is shifted right, so that a sort of the low
    /// `30 - sort_shift` bits sorts by the key's top bits (`Reorder::key_bits`).
    pub sort_shift: u32,
    /// The walk stage's workgroups at most (`prepare_propagate` sizes its dispatch to the
    /// bounce's rays within it): [`crate::walk_stage_groups`] on a hardware adapter, no bound
    /// on a software one; 0 at the bounces without the stage (the sorted ones).
    pub walk_groups: u32,
}

const _: () = assert!(size_of::<BounceUniforms>() == 16);
const _: () = assert!(size_of::<NeeRecord>() == 128);
const _: () = assert!(offset_of!(NeeRecord, color) == 48);
const _: () = assert!(offset_of!(NeeRecord, state) == 60);
const _: () = assert!(offset_of!(NeeRecord, rnd) == 96);
const _: () = assert!(offset_of!(NeeRecord, emitted) == 112);
const _: () = assert!(size_of::<SceneUniforms>() == 224);
const _: () = assert!(offset_of!(SceneUniforms, environment_grid_scale) == 192);
const _: () = assert!(offset_of!(SceneUniforms, environment_grid) == 208);
const _: () = assert!(offset_of!(SceneUniforms, rr_depth) == 176);
const _: () = assert!(offset_of!(SceneUniforms, sampler) == 180);
const _: () = assert!(offset_of!(SceneUniforms, width) == 12);
const _: () = assert!(offset_of!(SceneUniforms, camera_forward) == 16);
const _: () = assert!(offset_of!(SceneUniforms, environment_color) == 64);
const _: () = assert!(offset_of!(SceneUniforms, scene_min) == 80);
const _: () = assert!(offset_of!(SceneUniforms, environment_rotation) == 112);
const _: () = assert!(offset_of!(SceneUniforms, sample_begin) == 128);
const _: () = assert!(offset_of!(SceneUniforms, batch_index) == 144);
const _: () = assert!(offset_of!(SceneUniforms, light_power) == 172);
const _: () = assert!(size_of::<GpuMaterial>() == 80);
const _: () = assert!(offset_of!(GpuMaterial, emission) == 16);
const _: () = assert!(offset_of!(GpuMaterial, ior) == 32);
const _: () = assert!(offset_of!(GpuMaterial, flags) == 40);
const _: () = assert!(offset_of!(GpuMaterial, table) == 44);
const _: () = assert!(offset_of!(GpuMaterial, eta) == 48);
const _: () = assert!(offset_of!(GpuMaterial, k) == 64);
const _: () = assert!(size_of::<TriangleShading>() == 64);
const _: () = assert!(offset_of!(TriangleShading, n1) == 16);
const _: () = assert!(offset_of!(TriangleShading, v1) == 48);
const _: () = assert!(offset_of!(TriangleShading, flags) == 60);
const _: () = assert!(size_of::<TextureHeader>() == 16);
const _: () = assert!(size_of::<GpuLight>() == 64);
const _: () = assert!(offset_of!(GpuLight, e1) == 16);
const _: () = assert!(offset_of!(GpuLight, e2) == 32);
const _: () = assert!(offset_of!(GpuLight, two_sided) == 44);
const _: () = assert!(offset_of!(GpuLight, emission) == 48);
const _: () = assert!(size_of::<RayState>() == 64);
const _: () = assert!(offset_of!(RayState, dir) == 16);
const _: () = assert!(offset_of!(RayState, throughput) == 32);
const _: () = assert!(offset_of!(RayState, radiance) == 48);
const _: () = assert!(offset_of!(RayState, alive) == 60);

/// The shared constants as WGSL `const` declarations, prepended to every shader.
pub fn wgsl_constants() -> String {
    let u = |name: &str, v: u32| format!("const {name}: u32 = {v}u;\n");
    let mut s = String::new();
    s += &u("MATERIAL_DIFFUSE", MATERIAL_DIFFUSE);
    s += &u("MATERIAL_METAL", MATERIAL_METAL);
    s += &u("MATERIAL_GLASS", MATERIAL_GLASS);
    s += &u("MATERIAL_PLASTIC", MATERIAL_PLASTIC);
    s += &u("NO_TABLE", NO_TABLE);
    s += &u("MATERIAL_TWO_SIDED", MATERIAL_TWO_SIDED);
    s += &u("NO_TEXTURE", NO_TEXTURE);
    s += &u("TEXELS_LINEAR", TEXELS_LINEAR);
    s += &u("TEXELS_SRGB8", TEXELS_SRGB8);
    s += &u("SRGB8_TABLE", SRGB8_TABLE);
    s += &u("ENVIRONMENT_BLACK", ENVIRONMENT_BLACK);
    s += &u("ENVIRONMENT_CONSTANT", ENVIRONMENT_CONSTANT);
    s += &u("ENVIRONMENT_MAP", ENVIRONMENT_MAP);
    s += &u("SHADING_HAS_NORMALS", SHADING_HAS_NORMALS);
    s += &u("SHADING_HAS_UVS", SHADING_HAS_UVS);
    s += &u("PIXEL_TILE_WIDTH", PIXEL_TILE_WIDTH);
    s += &u("PIXEL_TILE_HEIGHT", PIXEL_TILE_HEIGHT);
    s += &u("DIM_CAMERA", DIM_CAMERA);
    s += &u("DIM_SCATTER", DIM_SCATTER);
    s += &u("DIM_LIGHT", DIM_LIGHT);
    s += &u("DIM_ROULETTE", DIM_ROULETTE);
    s += &u("DIMS_PER_BOUNCE", DIMS_PER_BOUNCE);
    s += &u("LIGHT_TRIANGLE", LIGHT_TRIANGLE);
    s += &u("LIGHT_SPHERE", LIGHT_SPHERE);
    s += &u("LIGHT_ENVIRONMENT", LIGHT_ENVIRONMENT);
    s += &u("SAMPLER_INDEPENDENT", SAMPLER_INDEPENDENT);
    s += &u("SAMPLER_ZSOBOL", SAMPLER_ZSOBOL);
    s += &u("SAMPLER_SOBOL", SAMPLER_SOBOL);
    s += &u("SAMPLER_FROM_SCENE", SAMPLER_FROM_SCENE);
    s += &u("NO_ROULETTE", NO_ROULETTE);
    s += &u("RAY_ALIVE", RAY_ALIVE);
    s += &u("NEE_NONE", NEE_NONE);
    s += &u("NEE_PENDING", NEE_PENDING);
    s += &u("NEE_ENDED", NEE_ENDED);
    s += &u("WORKGROUP_SIZE", crate::workgroup_size());
    s += &u("WALK_STAGE_COUNTER", crate::WALK_STAGE_COUNTER);
    s += &u("SHADOW_QUEUE_COUNTER", crate::SHADOW_QUEUE_COUNTER);
    s += &u("SHADOW_STAGE_COUNTER", crate::SHADOW_STAGE_COUNTER);
    s += &u("SHADOW_HAS_EMISSION", crate::SHADOW_HAS_EMISSION);
    s += &u(
        "MEGAKERNEL_WORKGROUP_SIZE",
        crate::megakernel_workgroup_size(),
    );
    // `{:e}` prints the shortest representation that round-trips, so the WGSL literal is the
    // same f32.
    s += &format!("const SHADOW_T_SCALE: f32 = {:e};\n", SHADOW_T_SCALE);
    s += &format!("const RR_MAX_SURVIVAL: f32 = {:e};\n", RR_MAX_SURVIVAL);
    s += &format!(
        "const LUMINANCE: vec3<f32> = vec3<f32>({:e}, {:e}, {:e});\n",
        LUMINANCE[0], LUMINANCE[1], LUMINANCE[2]
    );
    s += &format!("const T_MAX: f32 = {:e};\n", T_MAX);
    s
}

/// The WGSL declarations of the types above.
pub const GPU_TYPES_WGSL: &str = include_str!("gpu_types.wgsl");
