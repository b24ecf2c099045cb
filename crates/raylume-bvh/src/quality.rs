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
/// where `Quality`'s build (extrapolated, ~n log n: 5 s at 1M here) starts to show.
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

    /// `Quality` up to a million primitives, `Fast` beyond (see the table above).
    pub const fn for_primitive_count(primitives: usize) -> BvhQuality {
        if primitives <= 1_000_000 {
            BvhQuality::Quality
        } else {
            BvhQuality::Fast
        }
    }

    /// The preset that finishes a render of `rays` ray segments over `primitives` primitives
    /// sooner, build and trace together: `Quality` when its longer build is repaid by its
    /// faster rays, else `Fast`.
    ///
    /// `Quality` builds longer by [`QUALITY_EXTRA_BUILD_SECONDS`] per primitive and thread
    /// and traces [`QUALITY_TRACE_GAIN`] faster; it pays when
    /// `QUALITY_TRACE_GAIN * rays / rays_per_second > QUALITY_EXTRA_BUILD_SECONDS * primitives
    /// / build_threads`. `rays_per_second` is the backend's rate (a few million on a CPU core,
    /// billions on a GPU: the caller's estimate); `build_threads` the threads the build runs on.
    /// An estimate from the measured constants, not a measurement of this scene: on the 2-core
    /// machine a 128x128, 4-spp CPU render of a million triangles chooses `Fast` (0.6 s of
    /// build instead of 2 s), a 1000x1000, 100-spp one `Quality`.
    pub fn for_work(
        primitives: usize,
        rays: f64,
        rays_per_second: f64,
        build_threads: usize,
    ) -> BvhQuality {
        let extra_build =
            QUALITY_EXTRA_BUILD_SECONDS * primitives as f64 / build_threads.max(1) as f64;
        let saved = QUALITY_TRACE_GAIN * rays / rays_per_second.max(1.0);
        if saved > extra_build {
            BvhQuality::Quality
        } else {
            BvhQuality::Fast
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

impl std::str::FromStr for BvhQuality {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "fast" => Ok(BvhQuality::Fast),
            "quality" => Ok(BvhQuality::Quality),
            other => Err(format!(
                "unknown BVH preset '{other}' (expected fast or quality)"
            )),
        }
    }
}

/// What `Quality`'s build costs beyond `Fast`'s, seconds per primitive on one thread: the
/// eight-wide build of the 1M-triangle grid of `benches/build.rs` on the 2-core machine
/// (2026-12-02), 2.06 s against 0.63 s on 2 threads, so (2.06 - 0.63) x 2 / 10^6 (the
/// 100k grid and the living room measure 1.6–3 us; reinsertion grows a little faster
/// than linearly).
pub const QUALITY_EXTRA_BUILD_SECONDS: f64 = 2.9e-6;

/// How much faster `Quality`'s rays are than `Fast`'s, as a fraction of the trace time: the
/// table above measured 8–15 % on incoherent rays (one CPU thread, binary layout); 0.1 is
/// taken for every backend and layout.
pub const QUALITY_TRACE_GAIN: f64 = 0.1;

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
        // A million primitives on 2 threads: Quality costs ~1.45 s more. At 4 Mrays/s it needs
        // 1.45 / 0.1 * 4e6 = 58 M rays to pay.
        let choose = |rays: f64| BvhQuality::for_work(1_000_000, rays, 4e6, 2);
        assert_eq!(choose(128.0 * 128.0 * 4.0 * 11.0), BvhQuality::Fast);
        assert_eq!(choose(50e6), BvhQuality::Fast);
        assert_eq!(choose(70e6), BvhQuality::Quality);
        // More build threads make Quality cheaper; a faster backend makes it pay later.
        assert_eq!(
            BvhQuality::for_work(1_000_000, 50e6, 4e6, 4),
            BvhQuality::Quality
        );
        assert_eq!(
            BvhQuality::for_work(1_000_000, 70e6, 4e9, 2),
            BvhQuality::Fast
        );
        // No primitives: nothing to build, Quality is free.
        assert_eq!(BvhQuality::for_work(0, 1.0, 4e6, 2), BvhQuality::Quality);
        // No rays: Fast (a non-empty scene), and nonsense rates do not divide by zero.
        assert_eq!(BvhQuality::for_work(10, 0.0, 0.0, 0), BvhQuality::Fast);
    }
}
