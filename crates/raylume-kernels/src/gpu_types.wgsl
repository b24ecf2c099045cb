// Types shared with Rust (gpu_types.rs): same names, same fields, same order, same offsets.
// The constants they use (MATERIAL_*, ENVIRONMENT_*, ...) are emitted from Rust.

struct SceneUniforms {
    camera_origin: vec3<f32>,
    width: u32,
    camera_forward: vec3<f32>,
    height: u32,
    camera_right: vec3<f32>,
    spp: u32,
    camera_up: vec3<f32>,
    max_bounces: u32,
    environment_color: vec3<f32>,
    environment_kind: u32,
    scene_min: vec3<f32>,
    seed: u32,
    scene_extent: vec3<f32>,
    light_count: u32,
    environment_rotation: f32,
    environment_width: u32,
    environment_height: u32,
    environment_offset: u32,
    sample_begin: u32,
    sample_count: u32,
    pixel_begin: u32,
    pixel_count: u32,
    batch_index: u32,
    resolve_scale: f32,
    rays_in_batch: u32,
    queue_capacity: u32,
    primitive_count: u32,
    material_count: u32,
    texture_count: u32,
    light_power: f32,
    rr_depth: u32,
    sampler: u32,
    environment_select: f32,
    environment_cdf: u32,
    environment_grid_scale: vec3<f32>,
    environment_cdf_width: u32,
    environment_grid: vec3<u32>,
    environment_cdf_height: u32,
}

struct GpuMaterial {
    color: vec3<f32>,
    kind: u32,
    emission: vec3<f32>,
    alpha: f32,
    ior: f32,
    texture: u32,
    flags: u32,
    table: u32,
    eta: vec3<f32>,
    _pad0: u32,
    k: vec3<f32>,
    _pad1: u32,
}

struct TriangleShading {
    n0: vec3<f32>,
    u0: f32,
    n1: vec3<f32>,
    v0: f32,
    n2: vec3<f32>,
    u1: f32,
    v1: f32,
    u2: f32,
    v2: f32,
    flags: u32,
}

struct TextureHeader {
    offset: u32,
    width: u32,
    height: u32,
    format: u32,
}

struct GpuLight {
    p0: vec3<f32>,
    cdf: f32,
    e1: vec3<f32>,
    area: f32,
    e2: vec3<f32>,
    two_sided: u32,
    emission: vec3<f32>,
    kind: u32,
}

struct RayState {
    origin: vec3<f32>,
    pixel: u32,
    dir: vec3<f32>,
    sample: u32,
    throughput: vec3<f32>,
    depth: u32,
    radiance: vec3<f32>,
    alive: u32,
}

struct NeeRecord {
    position: vec3<f32>,
    offset: f32,
    geometric_normal: vec3<f32>,
    back_offset: f32,
    shading_normal: vec3<f32>,
    material: u32,
    color: vec3<f32>,
    state: u32,
    dir_in: vec3<f32>,
    _pad0: u32,
    throughput: vec3<f32>,
    _pad1: u32,
    rnd: vec4<f32>,
    emitted: vec3<f32>,
    _pad2: u32,
}

struct BounceUniforms {
    depth: u32,
    sort_next: u32,
    sort_shift: u32,
    walk_groups: u32,
}
