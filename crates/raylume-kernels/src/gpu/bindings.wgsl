// The kernels' global bindings and specialisation constants (gpu/shader.rs assembles them).
//
// Group 0, the scene: uploaded once per scene; `scene` is rewritten before every batch.
// Group 1, the render's work buffers: allocated per render size; `bounce` is read at a
// dynamic offset, one entry per wavefront bounce.

@group(0) @binding(0) var<uniform> scene: SceneUniforms;
@group(0) @binding(1) var<storage, read> bvh_nodes: array<TraversalNode>;
@group(0) @binding(2) var<storage, read> bvh_primitives: array<Primitive>;
@group(0) @binding(3) var<storage, read> materials: array<GpuMaterial>;
@group(0) @binding(4) var<storage, read> prim_materials: array<u32>;
@group(0) @binding(5) var<storage, read> triangle_shading: array<TriangleShading>;
@group(0) @binding(6) var<storage, read> texture_headers: array<TextureHeader>;
@group(0) @binding(7) var<storage, read> texels: array<u32>;
// Emissive triangles for next-event estimation: the first `scene.light_count` (at least one
// entry, a placeholder when there is none).
@group(0) @binding(8) var<storage, read> lights: array<GpuLight>;
// Rough plastics' coat tables (GpuMaterial::table; one placeholder entry when there is none).
@group(0) @binding(9) var<storage, read> plastic_tables: array<RoughPlasticTable>;

@group(1) @binding(0) var<storage, read_write> ray_states: array<RayState>;
// Each sample's radiance, RGB triples, slot = sample_in_batch * pixel_count + pixel_in_batch.
@group(1) @binding(1) var<storage, read_write> sample_radiance: array<f32>;
// The ray queues (ray indices), double-buffered by depth parity as in pbrt-v4's wavefront:
// bounce d reads `ray_queue_in` and appends to `ray_queue_out`; the bind group of odd bounces
// swaps the two buffers. `scene.queue_capacity` entries each.
@group(1) @binding(2) var<storage, read_write> ray_queue_in: array<u32>;
@group(1) @binding(5) var<storage, read_write> ray_queue_out: array<u32>;
// Sort keys: when the next bounce is sorted (bounce.sort_next), per slot of the next queue,
// live rays only; the bounces before an unsorted one write none.
@group(1) @binding(3) var<storage, read_write> ray_keys: array<u32>;
// Lengths of the two queues: [d & 1] is bounce d's input, [1 - (d & 1)] its output.
// Then the walk stage's slots taken (WALK_STAGE_COUNTER), the persistent schedule's sample
// counter (3), the shadow stage's queue length and slots taken (SHADOW_QUEUE_COUNTER,
// SHADOW_STAGE_COUNTER).
@group(1) @binding(4) var<storage, read_write> queue_counts: array<atomic<u32>, 8>;
// The image: running sums, then the mean, RGB triples per pixel.
@group(1) @binding(6) var<storage, read_write> accumulation: array<f32>;
// Per batch: rays traced (low word, high word), samples dropped, unused.
@group(1) @binding(7) var<storage, read_write> batch_stats: array<atomic<u32>>;
@group(1) @binding(8) var<uniform> bounce: BounceUniforms;
// Next-event estimation deferred by `propagate` to `next_event`, per slot of the bounce's ray
// queue: each NeeRecord as NEE_RECORD_WORDS words of 16 bytes in a structure of arrays
// (shade.wgsl `store_nee_record`); a placeholder unless the render's wavefront samples lights.
@group(1) @binding(9) var<storage, read_write> nee_records: array<vec4<u32>>;
// The walk stage's closest hits (walk_stage.wgsl `trace_hits`), per slot of the bounce's ray
// queue, for `propagate` (HITS_TRACED): (t, primitive, u, v) as words; a placeholder unless
// the render's wavefront has a walk stage.
@group(1) @binding(10) var<storage, read_write> queue_hits: array<vec4<u32>>;

// Group 2, only in `prepare_propagate`'s layout: the indirect dispatch sizes of the next
// `propagate` (words 0-2) and of the walk stage's `trace_hits` (words 4-6) (a buffer used for
// an indirect dispatch must not be bound in that dispatch).
@group(2) @binding(0) var<storage, read_write> dispatch_args: array<u32, 8>;
// Group 2, only in `permute_rays`' layout: the other ray-state buffer, which it fills in key
// order.
@group(2) @binding(1) var<storage, read_write> permuted_states: array<RayState>;

// Scene features (raylume_scene::Features): code behind a false one is dead in the
// specialised pipeline. The defaults describe the unspecialised reference pipeline.
override HAS_DIFFUSE: bool = true;
override HAS_METAL: bool = true;
override HAS_ROUGH_METAL: bool = true;
override HAS_GLASS: bool = true;
override HAS_ROUGH_GLASS: bool = true;
override HAS_PLASTIC: bool = true;
override HAS_EMISSION: bool = true;
override HAS_SPHERES: bool = true;
override HAS_TEXTURES: bool = true;
override HAS_SHADING_NORMALS: bool = true;
override HAS_CONSTANT_ENVIRONMENT: bool = true;
override HAS_ENVIRONMENT_MAP: bool = true;
// Whether the render estimates with next-event estimation (crate::Estimator::Nee): false in
// the pipelines of plain renders, whose light sampling, shadow rays and MIS weights are then
// dead code (TracerPipelines compiles one pipeline per value; shade.rs decides the same by
// `light_count`, 0 in a plain render, and `mis_pdf`, then always 0).
override NEXT_EVENT: bool = true;
// True in `propagate`'s pipelines alone: trace_ray leaves a light sample in `nee_records` for
// the `next_event` stage instead of taking it (the light sampling, its shadow ray's traversal
// and the BSDF evaluation toward the light are then dead code there, and live in
// `next_event`'s pipeline, which the driver compiles beside it).
override DEFER_NEE: bool = false;
// True in the `propagate` pipeline of a wavefront's bounces with a walk stage (gpu/batch.rs
// `walk_stage_at`): trace_ray takes the path ray's closest hit from queue_hits
// (walk_stage.wgsl traced it) instead of walking the tree; a shadow ray is still walked there.
// The other bounces run `propagate` compiled without it.
override HITS_TRACED: bool = false;
// True in the `propagate` pipeline of the bounces with a walk stage when the render also runs
// the shadow stage (PathVariant::shadow_stage, NEE): trace_ray takes the light sample and
// evaluates it, but leaves its shadow ray, with the two terms of the vertex that wait on it,
// in `deferred_shadow` for propagate to queue; `trace_shadows` walks them and adds the terms.
override DEFER_SHADOW: bool = false;
// The walk stage refills a subgroup's idle lanes once this many wait (or all of them do):
// crate::walk_stage_refill(), set at pipeline creation (no default here: Rust's is the one).
override WALK_STAGE_REFILL: u32;
// A lane of the walk and shadow stages takes at most this many times its even share of the
// queue (0: no bound): crate::WALK_STAGE_SOFTWARE_SHARE on software adapters, whose loops end
// at an iteration limit, else 0 (set at pipeline creation, no default here).
override WALK_STAGE_SHARE: u32;
// The sampler the pipeline is compiled for (SAMPLER_INDEPENDENT, _ZSOBOL or _SOBOL; the
// others' code is then dead), or SAMPLER_FROM_SCENE: the uniforms' `sampler` decides.
// TracerPipelines compiles the path tracing pipelines per sampler; see `path_sampler`.
override SAMPLER: u32 = SAMPLER_FROM_SCENE;
