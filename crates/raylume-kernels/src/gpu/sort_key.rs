//! A local stand-in for raylume-sort's ray key (`sort_key.wgsl`), written by `propagate`
//! until that crate's `MORTON_WGSL` replaces it: the paper's 30-bit origin-direction Morton
//! key. The CPU never sorts; this mirror exists for the test of the keys the GPU writes.

use glam::{UVec3, Vec3};

fn spread_bits_5(x: u32) -> u32 {
    (0..5).fold(0, |r, i| r | (((x >> i) & 1) << (3 * i)))
}

fn morton15(q: UVec3) -> u32 {
    (spread_bits_5(q.x) << 2) | (spread_bits_5(q.y) << 1) | spread_bits_5(q.z)
}

/// The 30-bit key of a ray: origin Morton code (bits 29..15) over direction Morton code.
pub fn local_ray_sort_key(origin: Vec3, dir: Vec3, scene_min: Vec3, scene_extent: Vec3) -> u32 {
    let o =
        ((origin - scene_min) / scene_extent.max(Vec3::splat(1e-30))).clamp(Vec3::ZERO, Vec3::ONE);
    let d = (dir * 0.5 + 0.5).clamp(Vec3::ZERO, Vec3::ONE);
    let qo = (o * 32.0).as_uvec3().min(UVec3::splat(31));
    let qd = (d * 32.0).as_uvec3().min(UVec3::splat(31));
    (morton15(qo) << 15) | morton15(qd)
}

/// The WGSL source of [`local_ray_sort_key`].
pub const SORT_KEY_WGSL: &str = include_str!("sort_key.wgsl");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_order_origins_then_directions() {
        let (min, ext) = (Vec3::ZERO, Vec3::ONE);
        // Origin cell (0, 0, 0); direction -x quantises to (0, 16, 16): y's bit 4 lands at
        // bit 13, z's at bit 12.
        let k0 = local_ray_sort_key(Vec3::ZERO, Vec3::NEG_X, min, ext);
        assert_eq!(k0, (1 << 13) | (1 << 12));
        let k1 = local_ray_sort_key(Vec3::ONE, Vec3::ONE.normalize(), min, ext);
        assert_eq!(k1 >> 15, (1 << 15) - 1);
        assert!(k1 < 1 << 30);
        // Same origin cell: the direction decides.
        let a = local_ray_sort_key(Vec3::splat(0.5), Vec3::X, min, ext);
        let b = local_ray_sort_key(Vec3::splat(0.5), Vec3::NEG_X, min, ext);
        assert_eq!(a >> 15, b >> 15);
        assert_ne!(a, b);
    }
}
