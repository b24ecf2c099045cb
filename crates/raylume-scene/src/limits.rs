//! Sanity limits on input sizes. Past them a loader returns [`crate::SceneError::TooLarge`]
//! instead of trying to allocate gigabytes for a corrupt or hostile file.

/// Most triangles in one scene (2^28, about 268 million: the BVH's 32-bit indices and GPU
/// buffer sizes run out long before).
pub const MAX_TRIANGLES: usize = 1 << 28;
/// Most analytic spheres in one scene.
pub const MAX_SPHERES: usize = 1 << 24;
/// Most materials in one scene.
pub const MAX_MATERIALS: usize = 1 << 20;
/// Most textures (including the environment map) in one scene.
pub const MAX_TEXTURES: usize = 1 << 12;
/// Largest texture or environment map side, in texels.
pub const MAX_TEXTURE_SIZE: u32 = 16384;
/// Largest image side for rendering (`[render] width/height`).
pub const MAX_IMAGE_SIZE: u32 = 32768;
/// Largest bloom radius in pixels.
pub const MAX_BLOOM_RADIUS: u32 = 4096;
/// Brightest radiance accepted anywhere (emission, constant environment, environment map
/// texel times strength): 1e20. A path collects at most `max_bounces + 1 <= 1025` such terms
/// with throughputs at most 1, about 1e23, well below the 2^94 (2e28) above which a renderer
/// must drop a sample so that summing a pixel's samples in `f32` cannot overflow. Brighter
/// input is a mistake (or a value that overflowed on its way in), not a light.
pub const MAX_RADIANCE: f32 = 1e20;
/// Largest bloom strength: 1e6. Bloom adds `strength` times a blur of the image to it, so a
/// larger factor could overflow `f32` on bright pixels; the paper used 0.3.
pub const MAX_BLOOM_STRENGTH: f32 = 1e6;
/// Largest scene description file (TOML, Tungsten JSON, glTF JSON) in bytes; meshes (OBJ,
/// GLB, buffers) are bounded by [`MAX_TRIANGLES`] instead.
pub const MAX_DESCRIPTION_BYTES: u64 = 256 << 20;
/// Deepest glTF node hierarchy.
pub const MAX_NODE_DEPTH: usize = 1024;
