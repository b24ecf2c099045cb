//! [`BvhQuality`]: build-time against trace-time presets, mapped onto obvhs' build parameters.

use obvhs::BvhBuildParams;

/// How much time the builder spends to make rays faster.
///
/// obvhs (the builder underneath) has no top-down binned-SAH builder. All presets build
/// bottom-up with PLOC, *Parallel Locally-Ordered Clustering* (Meister & Bittner, IEEE TVCG
/// 2018, <https://meistdan.github.io/publications/ploc/paper.pdf>): primitives sorted along a
/// Morton curve are merged pairwise with their nearest neighbour (smallest union box) within a
/// search radius. The tree is then improved by SAH-driven *parallel reinsertion* (Meister &
/// Bittner, *Parallel Reinsertion for Bounding Volume Hierarchy Optimization*, Eurographics
/// 2018, <https://meistdan.github.io/publications/prbvh/paper.pdf>), which moves subtrees to
/// where they lower the SAH cost, and leaves are formed by an SAH-driven collapse of subtrees
/// (at most 8 primitives per leaf).
///
/// Measured with the crate's bench (`benches/bvh.rs`, `RAYLUME_BVH_PRESETS=1`; release build,
/// one thread of a shared 2-core x86 machine), obvhs' four presets on the project's scenes:
///
/// | scene (primitives) | preset | build | SAH | primary / secondary Mrays/s |
/// | --- | --- | --- | --- | --- |
/// | teapot (123,554) | `very_fast_build` | 48 ms | 7.27 | 3.01 / 1.23 |
/// | | `fast_build` = **Fast** | 54 ms | 6.70 | 3.04 / 1.38 |
/// | | `slow_build` | 146 ms | 6.57 | 3.29 / 1.41 |
/// | | `very_slow_build` = **Quality** | 391 ms | 6.32 | 3.31 / 1.52 |
/// | living room (142,973) | `very_fast_build` | 54 ms | 42.2 | 1.31 / 0.99 |
/// | | `fast_build` = **Fast** | 66 ms | 39.1 | 1.29 / 1.08 |
/// | | `slow_build` | 218 ms | 37.6 | 1.45 / 1.02 |
/// | | `very_slow_build` = **Quality** | 552 ms | 36.2 | 1.45 / 1.17 |
///
/// `fast_build` costs 10–20 % more build time than `very_fast_build` for an 8 % lower SAH cost
/// and 9–12 % faster incoherent (secondary) rays; `very_slow_build` 2.5x the build time of
/// `slow_build` for 4 % lower SAH and 8–15 % faster secondary rays. A render traces ~10^9
/// rays, so half a second of build is repaid many times: [`Default`] is `Quality`, and
/// [`BvhQuality::for_primitive_count`] switches to `Fast` only past a million primitives,
/// where `Quality`'s build (extrapolated, ~n log n: 5 s at 1M here) starts to show. A render
/// of few rays over many primitives does not repay even `Fast`'s: [`BvhQuality::for_work`]
/// weighs build against trace (the facade's choice when the preset is not set).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BvhQuality {
    /// A linear BVH (Karras 2012: the binary radix tree over the primitives' Morton codes,
    /// `lbvh.rs`, built on every core), then obvhs' `very_fast_build()` passes (the least
    /// reinsertion, SAH leaf collapse, no splits). For a quick look at a large scene (a few
    /// rays per primitive): the 3M-triangle grid's eight-wide tree in 1.01 s against `Fast`'s
    /// 1.24 s on the 2-core machine (SAH 17 % higher); on the H200 host's 16 cores obvhs' PLOC
    /// hardly scales (351 of 654 ms with PLOC in this preset), the radix tree does.
    Fastest,
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
            // The tree itself is the LBVH (`lbvh.rs`); these are the passes after it.
            BvhQuality::Fastest => BvhBuildParams::very_fast_build(),
            BvhQuality::Fast => BvhBuildParams::fast_build(),
            BvhQuality::Quality => BvhBuildParams::very_slow_build(),
        }
    }

    /// Every preset, fastest build first.
    pub const ALL: [BvhQuality; 3] = [BvhQuality::Fastest, BvhQuality::Fast, BvhQuality::Quality];

    /// `Quality` up to a million primitives, `Fast` beyond (see the table above).
    pub const fn for_primitive_count(primitives: usize) -> BvhQuality {
        if primitives <= 1_000_000 {
            BvhQuality::Quality
        } else {
            BvhQuality::Fast
        }
    }

    /// The preset that finishes a render of `rays` ray segments over `primitives` primitives
    /// soonest, build and trace together: the one of least
    /// `BUILD_SECONDS[p] * primitives / build_threads + TRACE_FACTOR[p] * rays / rays_per_second`
    /// ([`PRESET_BUILD_SECONDS`], [`PRESET_TRACE_FACTOR`]: the extra build per primitive and
    /// thread over `Fastest`'s, and the trace time relative to `Fastest`'s).
    /// `rays_per_second` is the backend's rate with a `Fastest` tree (a few million on a CPU
    /// core, billions on a GPU: the caller's estimate); `build_threads` the threads the build
    /// runs on. An estimate from the measured constants, not a measurement of this scene: on
    /// the 2-core machine a 128x128, 4-spp CPU render of a million triangles chooses
    /// `Fastest`, a 1000x1000, 100-spp one `Quality`.
    pub fn for_work(
        primitives: usize,
        rays: f64,
        rays_per_second: f64,
        build_threads: usize,
    ) -> BvhQuality {
        let threads = build_threads.max(1) as f64;
        let trace = rays / rays_per_second.max(1.0);
        let cost = |i: usize| {
            PRESET_BUILD_SECONDS[i] * primitives as f64 / threads + PRESET_TRACE_FACTOR[i] * trace
        };
        // The last of equal costs: with nothing to build, the better tree.
        let best = (0..3).fold(0, |b, i| if cost(i) <= cost(b) { i } else { b });
        BvhQuality::ALL[best]
    }

    /// Lower-case name for logs and stats ("fastest", "fast", "quality").
    pub const fn name(self) -> &'static str {
        match self {
            BvhQuality::Fastest => "fastest",
            BvhQuality::Fast => "fast",
            BvhQuality::Quality => "quality",
        }
    }
}

impl std::str::FromStr for BvhQuality {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "fastest" => Ok(BvhQuality::Fastest),
            "fast" => Ok(BvhQuality::Fast),
            "quality" => Ok(BvhQuality::Quality),
            other => Err(format!(
                "unknown BVH preset '{other}' (expected fastest, fast or quality)"
            )),
        }
    }
}

/// What each preset's build costs beyond `Fastest`'s, seconds per primitive on one thread
/// ([`BvhQuality::ALL`]'s order), from the eight-wide builds of `benches/build.rs`'s grids on
/// the 2-core machine (2026-12-02, best of 3, 2 threads): at 3M triangles `Fast` 1.24–1.56 s
/// against `Fastest`'s 1.01–1.26 s (obvhs' PLOC then, the LBVH now), so 0.15–0.2 us; at 1M
/// `Quality` 2.06 s against `Fast`'s 0.63 s, 1.43 x 2 / 1e6 = 2.9 us more (the 100k grid and
/// the living room measure 1.6–3 us; reinsertion grows a little faster than linearly).
pub const PRESET_BUILD_SECONDS: [f64; 3] = [0.0, 0.2e-6, 3.1e-6];

/// Each preset's trace time relative to `Fastest`'s ([`BvhQuality::ALL`]'s order): the
/// table above measured `Fast`'s incoherent rays 9–12 % faster than `Fastest`'s and
/// `Quality`'s 8–15 % faster than `Fast`'s (one CPU thread, binary layout); 10 % a step is
/// taken for every backend and layout.
pub const PRESET_TRACE_FACTOR: [f64; 3] = [1.0, 0.9, 0.81];

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
        assert_eq!(BvhQuality::default(), BvhQuality::Quality);
        assert_eq!(
            BvhQuality::for_primitive_count(143_000),
            BvhQuality::Quality
        );
        assert_eq!(BvhQuality::for_primitive_count(5_000_000), BvhQuality::Fast);
    }

    #[test]
    fn work_decides_the_preset() {
        // A million primitives on 2 threads at 4 Mrays/s: Fast's build costs 0.1 s more than
        // Fastest's and saves 10 % of the trace, so it pays from 0.1 / 0.1 * 4e6 = 4 M rays;
        // Quality's costs 1.45 s more than Fast's and saves 0.09 of Fastest's trace time, so
        // it pays from 1.45 / 0.09 * 4e6 = 64 M rays.
        let choose = |rays: f64| BvhQuality::for_work(1_000_000, rays, 4e6, 2);
        assert_eq!(choose(128.0 * 128.0 * 4.0 * 11.0), BvhQuality::Fastest);
        assert_eq!(choose(3.5e6), BvhQuality::Fastest);
        assert_eq!(choose(4.5e6), BvhQuality::Fast);
        assert_eq!(choose(60e6), BvhQuality::Fast);
        assert_eq!(choose(70e6), BvhQuality::Quality);
        // More build threads make the better builds cheaper; a faster backend makes them pay
        // later.
        assert_eq!(
            BvhQuality::for_work(1_000_000, 60e6, 4e6, 4),
            BvhQuality::Quality
        );
        assert_eq!(
            BvhQuality::for_work(1_000_000, 70e6, 4e9, 2),
            BvhQuality::Fastest
        );
        // No primitives: nothing to build, Quality is free.
        assert_eq!(BvhQuality::for_work(0, 1.0, 4e6, 2), BvhQuality::Quality);
        // No rays: Fastest (a non-empty scene), and nonsense rates do not divide by zero.
        assert_eq!(BvhQuality::for_work(10, 0.0, 0.0, 0), BvhQuality::Fastest);
        for q in BvhQuality::ALL {
            assert_eq!(q.name().parse::<BvhQuality>(), Ok(q));
        }
    }
}
