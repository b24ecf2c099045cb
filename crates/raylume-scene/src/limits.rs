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
/// Largest scene description file (TOML, Tungsten JSON, glTF JSON) in bytes; meshes (OBJ,
/// GLB, buffers) are bounded by [`MAX_TRIANGLES`] instead.
pub const MAX_DESCRIPTION_BYTES: u64 = 256 << 20;
/// Deepest glTF node hierarchy.
pub const MAX_NODE_DEPTH: usize = 1024;
