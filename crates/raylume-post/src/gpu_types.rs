//! Types shared by the Rust side and the WGSL kernels. Each has the same name, field order and
//! layout as its WGSL struct.

use bytemuck::{Pod, Zeroable};

/// Threads per workgroup of every bloom kernel; `WORKGROUP_SIZE` in `bloom.wgsl`.
pub const WORKGROUP_SIZE: u32 = 256;

/// Per-dispatch bloom constants, a uniform buffer: `BloomUniforms` in `bloom.wgsl`.
/// repr(C), Pod, 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BloomUniforms {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Box-blur half-width.
    pub radius: u32,
    /// Bright-pass threshold.
    pub threshold: f32,
    /// Add-back weight.
    pub strength: f32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

const _: () = assert!(size_of::<BloomUniforms>() == 32);
const _: () = assert!(std::mem::offset_of!(BloomUniforms, width) == 0);
const _: () = assert!(std::mem::offset_of!(BloomUniforms, height) == 4);
const _: () = assert!(std::mem::offset_of!(BloomUniforms, radius) == 8);
const _: () = assert!(std::mem::offset_of!(BloomUniforms, threshold) == 12);
const _: () = assert!(std::mem::offset_of!(BloomUniforms, strength) == 16);
const _: () = assert!(std::mem::offset_of!(BloomUniforms, _pad0) == 20);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BLOOM_WGSL;

    /// The WGSL declares the same constant and the same struct, fields in the same order.
    #[test]
    fn wgsl_mirrors_the_rust_types() {
        assert!(
            BLOOM_WGSL.contains(&format!("const WORKGROUP_SIZE: u32 = {WORKGROUP_SIZE}u;")),
            "WORKGROUP_SIZE differs between Rust and bloom.wgsl"
        );
        let start = BLOOM_WGSL
            .find("struct BloomUniforms {")
            .expect("struct in WGSL");
        let body = &BLOOM_WGSL[start..start + BLOOM_WGSL[start..].find('}').unwrap()];
        let fields: Vec<&str> = body
            .lines()
            .skip(1)
            .filter_map(|l| l.trim().split(':').next())
            .filter(|f| !f.is_empty())
            .collect();
        assert_eq!(
            fields,
            [
                "width",
                "height",
                "radius",
                "threshold",
                "strength",
                "_pad0",
                "_pad1",
                "_pad2"
            ]
        );
    }

    /// Every stage is a WGSL entry point and a Rust mirror function of the same name.
    #[test]
    fn stages_are_entry_points() {
        for stage in crate::BLOOM_STAGES {
            assert!(
                BLOOM_WGSL.contains(&format!(
                    "@compute @workgroup_size(WORKGROUP_SIZE)\nfn {stage}("
                )),
                "{stage} is not an entry point of bloom.wgsl"
            );
        }
        // The Rust mirror: these paths fail to compile if a name drifts.
        let _ = (
            crate::bloom::bloom_threshold,
            crate::bloom::bloom_h,
            crate::bloom::bloom_v,
            crate::bloom::bloom_add,
        );
    }
}
