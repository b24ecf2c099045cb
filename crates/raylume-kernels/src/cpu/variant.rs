//! The CPU mirror specialised on a scene's features, as the GPU's pipelines are.
//!
//! The per-bounce functions (`shade::trace_ray`, `shade_hit`, `light_query`,
//! `surface::surface_at`, ...) take the feature set as a const generic `F` (the bits of
//! [`Features`]) and test [`has`] where the WGSL tests its `HAS_*` override constants, so that
//! the variant compiled for a scene without a feature holds none of its code: the compiler
//! folds the test to `false` and drops the branch. A render picks its variant once
//! ([`variant_of`], by [`Specialisation`]); [`GENERIC`] has every feature.
//!
//! Compiling a variant per feature set (2^14) is out of the question, so the features are
//! compiled in or out by group ([`GROUPS`]: the materials beyond diffuse, spheres, textures and
//! shading normals, the environment), diffuse surfaces, emission and triangles always in:
//! sixteen variants, each a superset of the features of the scenes it serves. On the 2-core
//! machine the Cornell box (diffuse and emission only) traced 5 % faster with every other
//! group's branches removed by hand (docs/RESULTS.md).

use glam::Vec4;
use raylume_bvh::{GpuBvh, Hit, Ray};
use raylume_scene::{Feature, Features};

use crate::Specialisation;
use crate::sobol::{SegmentKeys, SegmentPairs, SobolPixel};

/// Whether the feature set `f` (a variant's bits) holds `feature`: the Rust side of a WGSL
/// `HAS_*` constant.
#[inline(always)]
pub const fn has(f: u32, feature: Feature) -> bool {
    f & feature as u32 != 0
}

/// `bvh.trace_closest` in variant `F`: the traversal's sphere test compiled in only when `F`
/// holds spheres (the tracer's WGSL drops it by the `//#if spheres` block of raylume-bvh's
/// `intersect_primitive`).
#[inline(always)]
pub fn trace_closest<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
    if has(F, Feature::Spheres) {
        bvh.trace_closest_for::<true>(ray, t_min, t_max)
    } else {
        bvh.trace_closest_for::<false>(ray, t_min, t_max)
    }
}

/// `bvh.trace_any` in variant `F` (see [`trace_closest`]).
#[inline(always)]
pub fn trace_any<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
    if has(F, Feature::Spheres) {
        bvh.trace_any_for::<true>(ray, t_min, t_max)
    } else {
        bvh.trace_any_for::<false>(ray, t_min, t_max)
    }
}

/// What the CPU path computes in more than one form, one per instruction-set level (the
/// same numbers and hits in each): the `Sobol` sampler's segment draw and the tree's walks.
/// The per-bounce functions take it as a type (`K`), so that `cpu::isa`'s AVX2 copies of the
/// path inline the AVX2 forms and the others the build's: [`BuildForms`] everywhere,
/// `Avx2Forms` (crate-private: it runs AVX2 instructions) in those copies.
pub trait Forms {
    /// The `Sobol` sampler's three groups of a segment ([`SegmentKeys::draw`]).
    #[inline(always)]
    fn draw(keys: &SegmentKeys, p: SobolPixel, sample: u32) -> (Vec4, Vec4, f32) {
        keys.draw(p, sample)
    }

    /// The pairs a segment of diffuse surfaces draws ([`SegmentKeys::draw_pairs`]).
    #[inline(always)]
    fn draw_pairs(keys: &SegmentKeys, p: SobolPixel, sample: u32) -> SegmentPairs {
        keys.draw_pairs(p, sample)
    }

    /// Whether [`Forms::draw_pairs4`] draws four paths for less than four
    /// [`Forms::draw_pairs`] (so that a caller with two or three paths pads them to four).
    const DRAWS_FOUR: bool = false;

    /// [`Forms::draw_pairs`] of four paths, path `k` under `keys[k]` (its segment's).
    #[inline(always)]
    fn draw_pairs4(
        keys: [&SegmentKeys; 4],
        p: [SobolPixel; 4],
        sample: [u32; 4],
    ) -> [SegmentPairs; 4] {
        [
            Self::draw_pairs(keys[0], p[0], sample[0]),
            Self::draw_pairs(keys[1], p[1], sample[1]),
            Self::draw_pairs(keys[2], p[2], sample[2]),
            Self::draw_pairs(keys[3], p[3], sample[3]),
        ]
    }

    /// The closest hit of `ray` in variant `F` ([`trace_closest`]).
    #[inline(always)]
    fn trace_closest<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        trace_closest::<F>(bvh, ray, t_min, t_max)
    }

    /// Whether `ray` hits anything in variant `F` ([`trace_any`]).
    #[inline(always)]
    fn trace_any<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        trace_any::<F>(bvh, ray, t_min, t_max)
    }

    /// [`Forms::trace_any`] for a shadow ray toward a point of a lamp (a segment between two
    /// points of the scene): the AVX forms leave out the faces of the scene's hull where
    /// they test a small tree flat (`GpuBvh::trace_any_between_avx512`: the same answer but
    /// where the full test meets a wall within rounding of the ray's origin).
    #[inline(always)]
    fn trace_any_between<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        Self::trace_any::<F>(bvh, ray, t_min, t_max)
    }
}

/// The forms every level runs: the build's instructions.
#[derive(Clone, Copy, Debug, Default)]
pub struct BuildForms;

impl Forms for BuildForms {}

/// The AVX2 forms: `SegmentKeys::draw_avx2` and the wide walk's eight-lane node and
/// triangle tests (`GpuBvh::trace_closest_avx2`). Only `cpu::isa` names it, in the copies it
/// runs where the CPU has AVX2 (its methods are safe to call there only).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Avx2Forms;

#[cfg(target_arch = "x86_64")]
impl Forms for Avx2Forms {
    #[inline(always)]
    fn draw(keys: &SegmentKeys, p: SobolPixel, sample: u32) -> (Vec4, Vec4, f32) {
        // SAFETY: used only where the CPU has AVX2 (`cpu::isa` checks it).
        unsafe { keys.draw_avx2(p, sample) }
    }

    #[inline(always)]
    fn draw_pairs(keys: &SegmentKeys, p: SobolPixel, sample: u32) -> SegmentPairs {
        // SAFETY: as `draw`.
        unsafe { keys.draw_pairs_avx2(p, sample) }
    }

    #[inline(always)]
    fn trace_closest<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        // SAFETY: as `draw`.
        unsafe {
            if has(F, Feature::Spheres) {
                bvh.trace_closest_avx2::<true>(ray, t_min, t_max)
            } else {
                bvh.trace_closest_avx2::<false>(ray, t_min, t_max)
            }
        }
    }

    #[inline(always)]
    fn trace_any<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        // SAFETY: as `draw`.
        unsafe {
            if has(F, Feature::Spheres) {
                bvh.trace_any_avx2::<true>(ray, t_min, t_max)
            } else {
                bvh.trace_any_avx2::<false>(ray, t_min, t_max)
            }
        }
    }

    #[inline(always)]
    fn trace_any_between<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        // SAFETY: as `draw`.
        unsafe {
            if has(F, Feature::Spheres) {
                bvh.trace_any_between_avx2::<true>(ray, t_min, t_max)
            } else {
                bvh.trace_any_between_avx2::<false>(ray, t_min, t_max)
            }
        }
    }
}

/// The x86-64-v4 forms: [`Avx2Forms`]' with a small tree's triangles tested sixteen at a
/// time instead of eight (`GpuBvh::trace_closest_avx512`, the same hits). Only `cpu::isa`
/// names it, in the copies it runs where the CPU has AVX-512.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Avx512Forms;

#[cfg(target_arch = "x86_64")]
impl Forms for Avx512Forms {
    const DRAWS_FOUR: bool = true;

    #[inline(always)]
    fn draw(keys: &SegmentKeys, p: SobolPixel, sample: u32) -> (Vec4, Vec4, f32) {
        Avx2Forms::draw(keys, p, sample)
    }

    #[inline(always)]
    fn draw_pairs(keys: &SegmentKeys, p: SobolPixel, sample: u32) -> SegmentPairs {
        Avx2Forms::draw_pairs(keys, p, sample)
    }

    #[inline(always)]
    fn draw_pairs4(
        keys: [&SegmentKeys; 4],
        p: [SobolPixel; 4],
        sample: [u32; 4],
    ) -> [SegmentPairs; 4] {
        // SAFETY: used only where the CPU has x86-64-v4 (`cpu::isa` checks it).
        unsafe { SegmentKeys::draw_pairs4_avx512(keys, p, sample) }
    }

    #[inline(always)]
    fn trace_closest<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        // SAFETY: used only where the CPU has x86-64-v4 (`cpu::isa` checks it).
        unsafe {
            if has(F, Feature::Spheres) {
                bvh.trace_closest_avx512::<true>(ray, t_min, t_max)
            } else {
                bvh.trace_closest_avx512::<false>(ray, t_min, t_max)
            }
        }
    }

    #[inline(always)]
    fn trace_any<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        // SAFETY: as `trace_closest`.
        unsafe {
            if has(F, Feature::Spheres) {
                bvh.trace_any_avx512::<true>(ray, t_min, t_max)
            } else {
                bvh.trace_any_avx512::<false>(ray, t_min, t_max)
            }
        }
    }

    #[inline(always)]
    fn trace_any_between<const F: u32>(bvh: &GpuBvh, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        // SAFETY: as `trace_closest`.
        unsafe {
            if has(F, Feature::Spheres) {
                bvh.trace_any_between_avx512::<true>(ray, t_min, t_max)
            } else {
                bvh.trace_any_between_avx512::<false>(ray, t_min, t_max)
            }
        }
    }
}

/// Every feature of the tracer (all but bloom, a post pass): the generic variant, the
/// baseline.
pub const GENERIC: u32 = Features::all().bits() & !(Feature::Bloom as u32);

/// What every variant holds: diffuse surfaces, emission, triangles.
pub const ALWAYS: u32 =
    Feature::Diffuse as u32 | Feature::Emission as u32 | Feature::Triangles as u32;

/// The groups of features a variant holds or lacks as a whole.
pub const GROUPS: [u32; 4] = [
    Feature::Metal as u32
        | Feature::RoughMetal as u32
        | Feature::Glass as u32
        | Feature::RoughGlass as u32
        | Feature::Plastic as u32,
    Feature::Spheres as u32,
    Feature::Textures as u32 | Feature::ShadingNormals as u32,
    Feature::ConstantEnvironment as u32 | Feature::EnvironmentMap as u32,
];

/// The variants compiled, by index: bit `i` of the index holds group `i`.
pub const VARIANTS: usize = 1 << GROUPS.len();

/// The feature bits of variant `index` ([`ALWAYS`] and its groups).
pub const fn variant(index: usize) -> u32 {
    let mut f = ALWAYS;
    let mut i = 0;
    while i < GROUPS.len() {
        if index & (1 << i) != 0 {
            f |= GROUPS[i];
        }
        i += 1;
    }
    f
}

/// The index of the smallest variant holding `features`.
pub fn variant_index(features: Features) -> usize {
    GROUPS
        .iter()
        .enumerate()
        .filter(|(_, g)| features.bits() & **g != 0)
        .map(|(i, _)| 1 << i)
        .sum()
}

/// The variant a render of a scene of `features` runs: the smallest holding them, or every
/// feature for [`Specialisation::Generic`]. (`Overrides` and `Composed`, which differ on the
/// GPU in how the absent code is dropped, are the same here.)
pub fn variant_of(features: Features, specialisation: Specialisation) -> usize {
    match specialisation {
        Specialisation::Generic => VARIANTS - 1,
        Specialisation::Overrides | Specialisation::Composed => variant_index(features),
    }
}

/// Code generic over a variant, run by [`run_variant`] with the one chosen at run time.
pub trait ForVariant {
    /// What the code returns.
    type Out;
    /// Runs the code compiled for the feature set `F`.
    fn run<const F: u32>(self) -> Self::Out;
}

/// Runs `code` compiled for variant `index` (< [`VARIANTS`]).
pub fn run_variant<T: ForVariant>(index: usize, code: T) -> T::Out {
    match index {
        0 => code.run::<{ variant(0) }>(),
        1 => code.run::<{ variant(1) }>(),
        2 => code.run::<{ variant(2) }>(),
        3 => code.run::<{ variant(3) }>(),
        4 => code.run::<{ variant(4) }>(),
        5 => code.run::<{ variant(5) }>(),
        6 => code.run::<{ variant(6) }>(),
        7 => code.run::<{ variant(7) }>(),
        8 => code.run::<{ variant(8) }>(),
        9 => code.run::<{ variant(9) }>(),
        10 => code.run::<{ variant(10) }>(),
        11 => code.run::<{ variant(11) }>(),
        12 => code.run::<{ variant(12) }>(),
        13 => code.run::<{ variant(13) }>(),
        14 => code.run::<{ variant(14) }>(),
        _ => code.run::<{ variant(15) }>(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_feature_set_runs_a_variant_that_holds_it() {
        assert_eq!(VARIANTS, 16, "run_variant's arms");
        assert_eq!(
            variant(VARIANTS - 1),
            GENERIC,
            "the last variant is the generic one"
        );
        let all: u32 = GROUPS.iter().fold(ALWAYS, |a, g| a | g);
        assert_eq!(all, GENERIC, "every feature is in a group or always in");
        for bits in (0..=GENERIC).filter(|b| b & !GENERIC == 0) {
            let f = Features::from_bits(bits);
            let v = variant(variant_of(f, Specialisation::Composed));
            assert_eq!(v & bits, bits, "variant {v:#x} lacks features of {bits:#x}");
            // And it is the smallest: each of its groups is needed.
            for g in GROUPS {
                if v & g != 0 {
                    assert_ne!(bits & g, 0, "variant {v:#x} holds a group {bits:#x} lacks");
                }
            }
            assert_eq!(variant_of(f, Specialisation::Generic), VARIANTS - 1);
        }
    }
}
