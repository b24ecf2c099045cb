//! [`BvhQuality`]: build-time against trace-time presets, mapped onto obvhs' build parameters.

use obvhs::BvhBuildParams;

/// How much time the builder spends to make rays faster.
///
/// obvhs (the builder underneath) has no top-down binned-SAH builder. Both presets build
/// bottom-up with PLOC, *Parallel Locally-Ordered Clustering* (Meister & Bittner, IEEE TVCG
/// 2018, <https://meistdan.github.io/publications/ploc/paper.pdf>): primitives sorted along a
/// Morton curve are merged pairwise with their nearest neighbour (smallest union box) within a
/// search radius. The tree is then improved by SAH-driven *parallel reinsertion* (Meister &
/// Bittner, *Parallel Reinsertion for Bounding Volume Hierarchy Optimization*, Eurographics
/// 2018, <https://meistdan.github.io/publications/prbvh/paper.pdf>), which moves subtrees to
/// where they lower the SAH cost, and leaves are formed by an SAH-driven collapse of subtrees
/// (at most 8 primitives per leaf).
///
/// The SAH costs and trace rates behind the choice of presets and of [`Default`] are in the
/// crate's bench (`benches/bvh.rs`) and quoted in `docs/RESULTS.md`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BvhQuality {
    /// PLOC with a short search radius, a little reinsertion, SAH leaf collapse, no splits:
    /// obvhs' `fast_build()`. For scenes rebuilt often or so large that build time shows.
    Fast,
    /// PLOC with a long search radius, many SAH reinsertion passes before and after the leaf
    /// collapse, 128-bit Morton codes, and spatial pre-splits of large triangles (their boxes
    /// are cut along the longest axis into tighter pieces, so one triangle may sit in several
    /// leaves; spheres are never split): obvhs' `very_slow_build()`.
    #[default]
    Quality,
}

impl BvhQuality {
    /// The obvhs build parameters of this preset.
    pub const fn params(self) -> BvhBuildParams {
        match self {
            BvhQuality::Fast => BvhBuildParams::fast_build(),
            BvhQuality::Quality => BvhBuildParams::very_slow_build(),
        }
    }

    /// Lower-case name for logs and stats ("fast", "quality").
    pub const fn name(self) -> &'static str {
        match self {
            BvhQuality::Fast => "fast",
            BvhQuality::Quality => "quality",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_differ_where_documented() {
        let fast = BvhQuality::Fast.params();
        let quality = BvhQuality::Quality.params();
        assert!(!fast.pre_split);
        assert!(quality.pre_split);
        assert!(quality.reinsertion_batch_ratio > fast.reinsertion_batch_ratio);
        assert_eq!(fast.max_prims_per_leaf, 8);
        assert_eq!(quality.max_prims_per_leaf, 8);
    }
}
