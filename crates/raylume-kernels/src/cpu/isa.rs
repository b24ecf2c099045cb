//! The instruction set the CPU path's per-path kernel runs with, picked when it runs.
//!
//! Cargo's default target is the baseline x86-64 (SSE2), which every x86-64 CPU runs; the
//! CPUs that render have AVX2 and often AVX-512, whose wider registers, three-operand forms,
//! bit instructions (`lzcnt`, `popcnt`, ...) and, with AVX-512, twice the vector registers
//! make the same arithmetic faster. So that a dependent's plain `cargo build --release` gets
//! them without `-C target-cpu=native` (which makes a binary that runs only on CPUs like the
//! build machine's), [`stages::trace_paths`] is compiled three times over: as the build
//! targets, for x86-64-v3 (AVX2, FMA, BMI1/2, LZCNT, POPCNT) and for x86-64-v4 (those and
//! AVX-512 F/BW/CD/DQ/VL), each copy a `#[target_feature]` function into which the whole
//! path is inlined (the per-bounce functions it calls are `#[inline(always)]` for that: a
//! function left out of line would run at the build's level: the disassembly of a release
//! build's `call_v4` copies should call nothing but the panics and
//! `GpuBvh::cpu_walk_arrays`, no libm function since the angles' `math::sin_cos_turns`
//! (c6c5093); at bf09b4f `sample_environment` had dropped out of line, and was marked).
//! [`CpuIsa::best`] is the highest level the running CPU has; the tracer runs that one unless
//! told otherwise ([`crate::CpuTracer::set_isa`]). The x86-64-v3 and v4 copies also take
//! the AVX2 forms of [`Forms`](super::variant::Forms): the `Sobol` sampler's segments drawn
//! with `SegmentKeys::draw_avx2` (the same numbers, in AVX2 intrinsics), and the wide walk
//! with a node's eight boxes in one AVX register and two triangle blocks at once
//! (`GpuBvh::trace_closest_avx2`, the same hits); [`trace_chunk`] runs [`super::packet`]'s
//! paths on AVX lanes there. The x86-64-v4 copies take the AVX-512 forms (`Avx512Forms`):
//! the AVX2 ones, but a tree of at most `raylume_bvh::FLAT_MAX_PRIMITIVES` triangles tested
//! sixteen at a time (`GpuBvh::trace_closest_avx512`, the same hits; Bitterli's Cornell box
//! ~10 % faster on the Intel dev VM); their [`trace_chunk`] runs sixteen paths at a time on
//! AVX-512 lanes (another 6 % there).
//!
//! **The same image bit for bit** at every level: Rust never fuses `a * b + c` on its own
//! (only `mul_add`, which is exactly rounded on every level: an instruction or libm's `fmaf`),
//! nor reorders float arithmetic, so the wider instructions compute the same values
//! (`tests/cpu_isa.rs` renders a scene of every feature group at each level the CPU has and
//! compares the images bit for bit). Only the persistent and megakernel schedules dispatch
//! (the CPU's default); the wavefront's stages, a reference for the GPU's, run as the build
//! targets.
//!
//! On the AMD EPYC development VM (AVX-512), a default build: Bitterli's Cornell box 14 %
//! faster at x86-64-v4 than at the build's level, the living room 9-10 %; at x86-64-v3 7 %
//! and 0-2 %; a build with `-C target-cpu=native` no faster than x86-64-v4 from the default
//! one (`docs/RESULTS.md`, issue 15).

use raylume_bvh::GpuBvh;

use crate::surface::Globals;

use super::stages;

/// An instruction-set level of the CPU path's kernel ([`self`](crate::cpu::isa)): ordered,
/// each one a superset of those below it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CpuIsa {
    /// What the build targets (Cargo's default: the baseline x86-64; on other architectures,
    /// the only level).
    #[default]
    Build,
    /// x86-64-v3: AVX2, FMA, BMI1, BMI2, LZCNT, POPCNT, F16C, MOVBE.
    X86_64V3,
    /// x86-64-v4: x86-64-v3 and AVX-512 F, BW, CD, DQ, VL.
    X86_64V4,
}

impl CpuIsa {
    /// Every level, lowest first.
    pub const ALL: [CpuIsa; 3] = [CpuIsa::Build, CpuIsa::X86_64V3, CpuIsa::X86_64V4];

    /// The name `--cpu-isa` takes and the stats print: `build`, `x86-64-v3`, `x86-64-v4`.
    pub fn name(self) -> &'static str {
        match self {
            CpuIsa::Build => "build",
            CpuIsa::X86_64V3 => "x86-64-v3",
            CpuIsa::X86_64V4 => "x86-64-v4",
        }
    }

    /// The level named `name` ([`CpuIsa::name`]), if any.
    pub fn parse(name: &str) -> Option<CpuIsa> {
        CpuIsa::ALL.into_iter().find(|i| i.name() == name)
    }

    /// Whether the running CPU executes this level's instructions ([`CpuIsa::Build`]
    /// always: the program runs). One load once detected ([`CpuIsa::best`]).
    pub fn available(self) -> bool {
        self <= CpuIsa::best()
    }

    /// The CPU's features, tested (levels are cumulative: [`CpuIsa::best`] asks each only if
    /// the one below has them).
    fn detect(self) -> bool {
        // Every feature named, detected (the std macro takes literal tokens only). The lists
        // are the `#[target_feature]` attributes' of `call_v3` and (both together) `call_v4`
        // below: keep them equal.
        #[cfg(target_arch = "x86_64")]
        macro_rules! all_detected {
            ($($f:tt),+) => { $(std::arch::is_x86_feature_detected!($f))&&+ };
        }
        match self {
            CpuIsa::Build => true,
            #[cfg(target_arch = "x86_64")]
            CpuIsa::X86_64V3 => {
                all_detected!(
                    "avx2", "fma", "bmi1", "bmi2", "lzcnt", "popcnt", "f16c", "movbe"
                )
            }
            #[cfg(target_arch = "x86_64")]
            CpuIsa::X86_64V4 => {
                all_detected!("avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The highest level the running CPU executes: what the tracer runs by default (detected
    /// once a process).
    pub fn best() -> CpuIsa {
        static BEST: std::sync::OnceLock<CpuIsa> = std::sync::OnceLock::new();
        *BEST.get_or_init(|| {
            CpuIsa::ALL
                .into_iter()
                .take_while(|i| i.detect())
                .last()
                .unwrap_or(CpuIsa::Build)
        })
    }

    /// The highest level at most `limit` that the running CPU executes.
    pub fn best_up_to(limit: CpuIsa) -> CpuIsa {
        limit.min(CpuIsa::best())
    }
}

/// `f()` compiled for x86-64-v3 (see the module docs): what it inlines runs with AVX2. Not
/// compiled where the build already targets AVX2: there [`CpuIsa::Build`] is at least this.
#[cfg(all(target_arch = "x86_64", not(target_feature = "avx2")))]
#[target_feature(enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt,f16c,movbe")]
fn call_v3<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// `f()` compiled for x86-64-v4 (see the module docs). Not compiled where the build already
/// targets AVX-512.
#[cfg(all(target_arch = "x86_64", not(target_feature = "avx512f")))]
#[target_feature(
    enable = "avx,avx2,fma,bmi1,bmi2,lzcnt,popcnt,f16c,movbe,avx512f,avx512bw,avx512cd,avx512dq,avx512vl"
)]
fn call_v4<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// `f()` at level `isa`, which must be [`CpuIsa::available`] (the tracer checks it when it is
/// set: [`crate::CpuTracer::set_isa`]): a copy of `f` and of everything it inlines compiled
/// for that level (a level the build already targets runs the build's). For a hot loop's
/// body, e.g. one path ([`trace_paths`]) or one ray of a walk (`trace_rate --backend cpu`);
/// mark the closure `#[inline(always)]`, or it may stay out of line at the build's level.
///
/// # Panics
/// If the CPU lacks `isa` (running its instructions would be undefined behaviour): take the
/// level from [`CpuIsa::best`] or [`CpuIsa::best_up_to`].
#[inline(always)]
pub fn with_isa<R>(isa: CpuIsa, f: impl FnOnce() -> R) -> R {
    assert!(isa.available(), "{isa:?} is not available on this CPU");
    match isa {
        #[cfg(all(target_arch = "x86_64", not(target_feature = "avx512f")))]
        // SAFETY: the CPU has x86-64-v4's features (asserted above).
        CpuIsa::X86_64V4 => unsafe { call_v4(f) },
        #[cfg(all(target_arch = "x86_64", not(target_feature = "avx2")))]
        // SAFETY: the CPU has x86-64-v3's features (asserted above).
        CpuIsa::X86_64V3 => unsafe { call_v3(f) },
        _ => f(),
    }
}

/// Whether the path at level `isa` runs the AVX-512 forms (`Avx512Forms`): where `with_isa`
/// runs x86-64-v4 (asserting the CPU has it), or the build's own target has AVX-512.
#[cfg(target_arch = "x86_64")]
fn avx512_forms(isa: CpuIsa) -> bool {
    isa >= CpuIsa::X86_64V4 || cfg!(target_feature = "avx512f")
}

/// Whether the path at level `isa` runs at least the AVX2 forms (`Avx2Forms`; the packets on
/// AVX lanes, or AVX-512 lanes where [`avx512_forms`]):
/// where `with_isa` runs x86-64-v3 or v4, or the build's own target has AVX2.
#[cfg(target_arch = "x86_64")]
fn avx2_forms(isa: CpuIsa) -> bool {
    avx512_forms(isa) || isa >= CpuIsa::X86_64V3 || cfg!(target_feature = "avx2")
}

/// Whether the walks of the path at level `isa` ([`trace_paths`], [`trace_chunk`]) test
/// `bvh` flat, every triangle against every ray (`GpuBvh::cpu_walks_flat`: a small tree, with
/// the forms this level runs).
pub fn walks_flat(isa: CpuIsa, bvh: &GpuBvh) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let (avx2, avx512) = (avx2_forms(isa), avx512_forms(isa));
        avx2 && bvh.cpu_walks_flat(avx512)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (isa, bvh);
        false
    }
}

/// [`stages::trace_paths`] at level `isa` ([`with_isa`]).
#[inline(always)]
pub fn trace_paths<const F: u32>(
    isa: CpuIsa,
    g: &Globals,
    bvh: &GpuBvh,
    r: u32,
) -> ([f32; 3], bool, u32) {
    #[cfg(target_arch = "x86_64")]
    if avx512_forms(isa) {
        // As below, a small tree's flat test sixteen lanes at a time where the level has
        // AVX-512.
        return with_isa(
            isa,
            #[inline(always)]
            || stages::trace_paths_by::<F, super::variant::Avx512Forms>(g, bvh, r),
        );
    }
    #[cfg(target_arch = "x86_64")]
    if avx2_forms(isa) {
        // The Sobol' draws in AVX2 where `with_isa` runs a level with it (asserting the CPU
        // has it), or the build's own target has it.
        return with_isa(
            isa,
            #[inline(always)]
            // The AVX2 forms only here, where the CPU has AVX2 (above).
            || stages::trace_paths_by::<F, super::variant::Avx2Forms>(g, bvh, r),
        );
    }
    with_isa(
        isa,
        #[inline(always)]
        || stages::trace_paths::<F>(g, bvh, r),
    )
}

/// [`stages::trace_paths_in_pairs`] at level `isa` ([`with_isa`]), the draws and walks in
/// the level's forms as [`trace_paths`].
#[inline(always)]
pub fn trace_paths_in_pairs<const F: u32>(
    isa: CpuIsa,
    g: &Globals,
    bvh: &GpuBvh,
    r0: u32,
    slots: &mut [[f32; 3]],
) -> (u64, u64) {
    #[cfg(target_arch = "x86_64")]
    if avx512_forms(isa) {
        return with_isa(
            isa,
            #[inline(always)]
            || stages::trace_paths_in_pairs::<F, super::variant::Avx512Forms>(g, bvh, r0, slots),
        );
    }
    #[cfg(target_arch = "x86_64")]
    if avx2_forms(isa) {
        return with_isa(
            isa,
            #[inline(always)]
            || stages::trace_paths_in_pairs::<F, super::variant::Avx2Forms>(g, bvh, r0, slots),
        );
    }
    with_isa(
        isa,
        #[inline(always)]
        || stages::trace_paths_in_pairs::<F, super::variant::BuildForms>(g, bvh, r0, slots),
    )
}

/// [`packet::trace_chunk`](super::packet::trace_chunk) at instruction-set level `isa`: sixteen
/// paths at a time on AVX-512 lanes (the crate's `packet::Avx512`) at x86-64-v4, eight on AVX
/// lanes (`packet::Avx`) at x86-64-v3, eight on SSE lanes at the build's level (unless the
/// build targets AVX2 or AVX-512 itself).
#[inline(always)]
pub fn trace_chunk<const F: u32>(
    isa: CpuIsa,
    g: &Globals,
    bvh: &GpuBvh,
    r0: u32,
    slots: &mut [[f32; 3]],
) -> (u64, u64) {
    use super::packet;
    #[cfg(target_arch = "x86_64")]
    if avx512_forms(isa) {
        // AVX-512 lanes (sixteen paths at a time), and the AVX-512 forms.
        return with_isa(
            isa,
            #[inline(always)]
            || {
                packet::trace_chunk::<
                    F,
                    { packet::LANES_AVX512 },
                    packet::Avx512,
                    super::variant::Avx512Forms,
                >(g, bvh, r0, slots)
            },
        );
    }
    #[cfg(target_arch = "x86_64")]
    if avx2_forms(isa) {
        // AVX lanes only where `with_isa` runs a level with AVX (it asserts the CPU has it),
        // or the build's own target has it.
        return with_isa(
            isa,
            #[inline(always)]
            || {
                packet::trace_chunk::<F, { packet::LANES }, packet::Avx, super::variant::Avx2Forms>(
                    g, bvh, r0, slots,
                )
            },
        );
    }
    with_isa(
        isa,
        #[inline(always)]
        || {
            packet::trace_chunk::<F, { packet::LANES }, packet::Sse, super::variant::BuildForms>(
                g, bvh, r0, slots,
            )
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_round_trip_their_names_and_best_is_available() {
        for isa in CpuIsa::ALL {
            assert_eq!(CpuIsa::parse(isa.name()), Some(isa));
        }
        assert_eq!(CpuIsa::parse("native"), None);
        assert!(CpuIsa::best().available());
        assert_eq!(CpuIsa::best_up_to(CpuIsa::Build), CpuIsa::Build);
        // Levels are cumulative: the best one's features and every one's below it are there.
        for isa in CpuIsa::ALL {
            assert_eq!(isa.available(), isa <= CpuIsa::best(), "{isa:?}");
            if isa.available() {
                assert!(isa.detect(), "{isa:?}");
            }
        }
    }
}
