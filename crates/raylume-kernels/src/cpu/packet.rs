//! The CPU path of scenes of diffuse triangles, several paths at a time ([`LANES`], or
//! [`LANES_AVX512`] on AVX-512 lanes), and of scenes of triangles that add other materials,
//! their diffuse hits on the lanes and their other hits one lane at a time.
//!
//! One path at a time, a segment of Bitterli's Cornell box costs about 2,000 instructions
//! (cachegrind, issue 15 in `docs/RESULTS.md`): some 1,000 in its two walks, ~250 in the sampler,
//! the rest in the shading and the light sample, scalar code whose every operation serves one path.
//! Mitsuba 3's LLVM backend runs those stages over 8 or 16 paths an instruction. This module does
//! so for the variant without any feature group ([`runs`]: diffuse triangles, emission, next-event
//! estimation, no sky, textures, spheres or other materials), and for the variant that adds the
//! other materials: there a lane whose hit is not diffuse finishes its segment alone through
//! [`shade_segment`] (the one-path code after its walk, from the segment's full numbers) while
//! the lanes shade the others. Bitterli's Cornell box with its two boxes made metal (a mirror
//! and a rough one): 500x500, 10 spp, 1.122 / 1.122 -> 0.842 / 0.847 s (min / median, three
//! rounds, session 44), the same image. Not with spheres (Cornell plus: within noise of one
//! path at a time, its walk, which tests primitives one at a time, takes most of its time),
//! nor with textures, shading normals or a sky: the living room so, its diffuse hits (54 %)
//! on lanes with shading normals and the sky's light sample, the others alone, rendered the
//! same image 9 % slower (2.27 -> 2.48 s at 400x400, 10 spp): the lanes' gains on cheap
//! diffuse hits do not repay the packets' cost on the rest. A chunk of the batch's paths is
//! traced `N` at a time (the lanes of a [`Lanes`]`<N>` type), each lane taking the chunk's next
//! path when its own ends. Per segment, the random numbers and the walks run lane by lane (the scalar functions:
//! [`wanted_pairs`] of `SegmentKeys::draw_pairs` or [`segment_rands`], the tree's walk; every
//! lane's numbers drawn before the first walk, so that the draws' chains of multiplies overlap the
//! walks, and under the `Sobol` sampler four lanes' at once, `Forms::draw_pairs4`: at x86-64-v4
//! `SegmentKeys::draw_pairs4_avx512`, sixteen lanes an instruction; a lane whose path escapes
//! takes the next one and walks again, so that the shading finds every lane with a hit), and
//! everything between them (the surface, the emission's weight, next-event estimation's light
//! sample, the scattered direction, Russian roulette) runs on all lanes at once, on a [`Lane`]
//! type: sixteen lanes in one AVX-512 register, their truths in a mask register, in `cpu::isa`'s
//! x86-64-v4 copy (`Avx512`, crate-private), eight in one AVX register in its x86-64-v3 copy
//! (`Avx`), eight as two glam `Vec4`s (SSE, which every x86-64 level has) at the build's level
//! ([`Sse`]); the paths are held a field's lanes side by side (`Paths`), and the AVX copies
//! draw the sampler's numbers and walk the tree in the AVX2 forms (the [`Forms`] that
//! [`trace_chunk`] takes:
//! `SegmentKeys::draw_pairs_avx2`, `GpuBvh::trace_closest_avx2`; at x86-64-v4
//! `GpuBvh::trace_closest_avx512`). Bitterli's Cornell box on the AMD EPYC dev VM: 400x400, 24 spp,
//! 1.70 -> 1.46 s (median) against one path at a time with the scalar draw, then 1.445 -> 1.365 s
//! with the AVX2 walks (`docs/RESULTS.md`, issue 15).
//!
//! **The same image bit for bit** as [`stages::trace_paths`](super::stages::trace_paths): every
//! lane computes what [`trace_ray_at`](crate::shade::trace_ray_at) computes for its path, the same
//! IEEE operations in the same order (each step below names the scalar function it mirrors; glam's
//! `min`/`max` are selects on `<`/`>`, as SSE's `minps`/`maxps`, `f32::min`/`max` keep their NaN
//! rule; the angle's sine and cosine are `math::sin_cos_turns`'s polynomial in lanes, this module's
//! `sin_cos_turns`). `tests/cpu_packet.rs` renders scenes of this variant both ways, at every
//! instruction-set level, and compares the images bit for bit (reassociating one sum of the
//! scattered direction fails it).

use std::mem::MaybeUninit;
use std::ops::{Add, Div, Mul, Neg, Sub};

use glam::{BVec4A, Vec3, Vec4};
use raylume_bvh::{GpuBvh, Hit, Ray};
use raylume_scene::Feature;

use super::stages::{batch_ray, camera_path_at, camera_path_from, write_sample};
use super::variant::{ALWAYS, Forms, GROUPS, has};
use crate::gpu_types::{
    LUMINANCE, MATERIAL_DIFFUSE, MATERIAL_TWO_SIDED, RR_MAX_SURVIVAL, SHADOW_T_SCALE, T_MAX,
};
use crate::math::{
    INV_PI, SIN_COS_C1, SIN_COS_C2, SIN_COS_C3, SIN_COS_ROUND, SIN_COS_S1, SIN_COS_S2, SIN_COS_S3,
};
use crate::shade::{
    PathState, choose_light, escape, sampler_pixel, segment_rands, shade_segment, table_keys,
    wanted_pairs,
};
use crate::sobol::{SegmentKeys, SegmentPairs, SobolPixel};
use crate::surface::{Globals, OFFSET_BACK_ULPS, OFFSET_HIT_ULPS, OFFSET_T_ULPS, UNIT_ROUNDOFF};

/// Paths traced together on [`Sse`] lanes and AVX lanes (`Avx`, crate-private: x86-64-v3).
pub const LANES: usize = 8;

/// Paths traced together on AVX-512 lanes (`Avx512`, crate-private: x86-64-v4): Bitterli's
/// Cornell box's render 5-6 % faster than eight lanes in an AVX register there (the Intel dev
/// VM, session 43); sixteen lanes as two AVX registers measured no faster than eight, and as
/// four SSE registers ~10 % slower (`docs/RESULTS.md`, issue 15).
pub const LANES_AVX512: usize = 16;

/// Whether variant `f` (`cpu::variant`) is traced by this module: the variant of no feature
/// group, [`ALWAYS`], and the one that adds the materials beyond diffuse (the first of
/// `cpu::variant::GROUPS`), whose lanes with a diffuse hit are shaded on the lanes and each
/// other lane finishes its segment alone through [`shade_segment`], the one-path code. Not
/// spheres, textures, shading normals or a sky (see the module docs: no gain measured).
pub const fn runs(f: u32) -> bool {
    f & !(ALWAYS | GROUPS[0]) == 0
}

/// Whether lane `j`'s hit (its walk's, in `found`) is shaded on the lanes in variant `F`: a
/// diffuse surface (the variants [`runs`] takes have triangles alone). Always in [`ALWAYS`].
#[inline(always)]
fn lane_shaded<const F: u32, const N: usize>(g: &Globals, found: &Found<N>, j: usize) -> bool {
    F == ALWAYS
        || g.materials[g.prim_materials[found.prim[j] as usize] as usize].kind == MATERIAL_DIFFUSE
}

/// The arithmetic of several numbers at once that the packets run on: [`Sse`] at every
/// level, `Avx` (crate-private) where the CPU has AVX2 (`cpu::isa`'s x86-64-v3 copy), `Avx512`
/// (crate-private) in the x86-64-v4 copy. Each operation is the IEEE one of `f32` lane by lane.
/// How many lanes, and the arrays they load and store, is [`Lanes`]'.
pub trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// A truth per lane.
    type M: Mask<Self>;
    fn splat(x: f32) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// `f32::max` (IEEE maxNum: a NaN operand gives the other).
    fn fmax(self, o: Self) -> Self;
    /// `f32::min` (IEEE minNum: a NaN operand gives the other).
    fn fmin(self, o: Self) -> Self;
    fn lt(self, o: Self) -> Self::M;
    fn gt(self, o: Self) -> Self::M;
    fn ge(self, o: Self) -> Self::M;
}

/// A [`Lane`] type of `N` lanes (at most 32: its [`Mask`]'s bits): the packets trace `N` paths
/// at a time on it ([`trace_chunk`]).
pub trait Lanes<const N: usize>: Lane {
    fn from_array(a: [f32; N]) -> Self;
    fn to_array(self) -> [f32; N];

    /// `N` four-word records' words side by side: result `k`'s lane `j` is `rows[j][k]` (a
    /// record's x, y, z and w: the gathers of the lanes' triangles, materials and lights).
    #[inline(always)]
    fn transpose(rows: [&[f32; 4]; N]) -> [Self; 4] {
        let mut a = [[0.0; N]; 4];
        for (j, row) in rows.iter().enumerate() {
            for k in 0..4 {
                a[k][j] = row[k];
            }
        }
        a.map(Self::from_array)
    }
}

/// `a.map(f)` as a plain loop: the array's `map` (`try_map`) was compiled out of line, a call
/// from `cpu::isa`'s AVX copies for each gather.
#[inline(always)]
fn each<T: Copy, U: Copy, const N: usize>(a: [T; N], f: impl Fn(T) -> U) -> [U; N] {
    let mut out = [const { MaybeUninit::<U>::uninit() }; N];
    for j in 0..N {
        out[j] = MaybeUninit::new(f(a[j]));
    }
    // SAFETY: every element was written above; `[MaybeUninit<U>; N]` and `[U; N]` have the
    // same layout.
    unsafe { std::mem::transmute_copy(&out) }
}

/// Words `4 * i..4 * i + 4` of `record` (a GPU record of four-word groups) as four `f32`s.
#[inline(always)]
fn quad<T: bytemuck::Pod>(record: &T, i: usize) -> &[f32; 4] {
    bytemuck::from_bytes(&bytemuck::bytes_of(record)[16 * i..16 * i + 16])
}

/// A truth per lane of [`Lane`] `L`.
pub trait Mask<L: Lane>: Copy {
    /// Lane `i` true where bit `i` of `bits` is set.
    fn from_bits(bits: u32) -> Self;
    fn and(self, o: Self) -> Self;
    fn or(self, o: Self) -> Self;
    fn not(self) -> Self;
    /// Lane `i`'s truth in bit `i`.
    fn bits(self) -> u32;
    /// `a` where true, else `b`.
    fn pick(self, a: L, b: L) -> L;

    #[inline(always)]
    fn pick3(self, a: V3<L>, b: V3<L>) -> V3<L> {
        V3 {
            x: self.pick(a.x, b.x),
            y: self.pick(a.y, b.y),
            z: self.pick(a.z, b.z),
        }
    }
}

/// [`LANES`] numbers as two glam `Vec4`s, whose SSE arithmetic every x86-64 level has.
#[derive(Clone, Copy, Debug)]
pub struct Sse([Vec4; 2]);

/// [`Sse`]'s truths.
#[derive(Clone, Copy, Debug)]
pub struct SseMask([BVec4A; 2]);

impl Lanes<LANES> for Sse {
    #[inline(always)]
    fn from_array(a: [f32; LANES]) -> Sse {
        Sse([Vec4::from_slice(&a[..4]), Vec4::from_slice(&a[4..])])
    }

    #[inline(always)]
    fn to_array(self) -> [f32; LANES] {
        let mut a = [0.0; LANES];
        self.0[0].write_to_slice(&mut a[..4]);
        self.0[1].write_to_slice(&mut a[4..]);
        a
    }
}

impl Lane for Sse {
    type M = SseMask;

    #[inline(always)]
    fn splat(x: f32) -> Sse {
        Sse([Vec4::splat(x); 2])
    }

    #[inline(always)]
    fn sqrt(self) -> Sse {
        Sse(self.0.map(Vec4::sqrt))
    }

    #[inline(always)]
    fn abs(self) -> Sse {
        Sse(self.0.map(Vec4::abs))
    }

    #[inline(always)]
    fn fmax(self, o: Sse) -> Sse {
        // x86's lowering of `f32::max`: `a` NaN gives `b`, else `b > a ? b : a` (so `b`
        // NaN gives `a`).
        self.zip(o, |a, b| {
            Vec4::select(a.is_nan_mask(), b, Vec4::select(b.cmpgt(a), b, a))
        })
    }

    #[inline(always)]
    fn fmin(self, o: Sse) -> Sse {
        self.zip(o, |a, b| {
            Vec4::select(a.is_nan_mask(), b, Vec4::select(b.cmplt(a), b, a))
        })
    }

    #[inline(always)]
    fn lt(self, o: Sse) -> SseMask {
        self.test(o, Vec4::cmplt)
    }

    #[inline(always)]
    fn gt(self, o: Sse) -> SseMask {
        self.test(o, Vec4::cmpgt)
    }

    #[inline(always)]
    fn ge(self, o: Sse) -> SseMask {
        self.test(o, Vec4::cmpge)
    }
}

impl Sse {
    #[inline(always)]
    fn zip(self, o: Sse, f: impl Fn(Vec4, Vec4) -> Vec4) -> Sse {
        Sse([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
    }

    #[inline(always)]
    fn test(self, o: Sse, f: impl Fn(Vec4, Vec4) -> BVec4A) -> SseMask {
        SseMask([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
    }
}

macro_rules! sse_op {
    ($trait:ident, $f:ident, $op:tt) => {
        impl $trait for Sse {
            type Output = Sse;
            #[inline(always)]
            fn $f(self, o: Sse) -> Sse {
                self.zip(o, |a, b| a $op b)
            }
        }
    };
}
sse_op!(Add, add, +);
sse_op!(Sub, sub, -);
sse_op!(Mul, mul, *);
sse_op!(Div, div, /);

impl Neg for Sse {
    type Output = Sse;
    #[inline(always)]
    fn neg(self) -> Sse {
        Sse(self.0.map(|a| -a))
    }
}

impl Mask<Sse> for SseMask {
    #[inline(always)]
    fn from_bits(bits: u32) -> SseMask {
        let b = |j: u32| bits >> j & 1 != 0;
        SseMask([
            BVec4A::new(b(0), b(1), b(2), b(3)),
            BVec4A::new(b(4), b(5), b(6), b(7)),
        ])
    }

    #[inline(always)]
    fn and(self, o: SseMask) -> SseMask {
        SseMask([self.0[0] & o.0[0], self.0[1] & o.0[1]])
    }

    #[inline(always)]
    fn or(self, o: SseMask) -> SseMask {
        SseMask([self.0[0] | o.0[0], self.0[1] | o.0[1]])
    }

    #[inline(always)]
    fn not(self) -> SseMask {
        SseMask([!self.0[0], !self.0[1]])
    }

    #[inline(always)]
    fn bits(self) -> u32 {
        self.0[0].bitmask() | self.0[1].bitmask() << 4
    }

    #[inline(always)]
    fn pick(self, a: Sse, b: Sse) -> Sse {
        Sse([
            Vec4::select(self.0[0], a.0[0], b.0[0]),
            Vec4::select(self.0[1], a.0[1], b.0[1]),
        ])
    }
}

/// [`Lane`]'s comparisons and `f32::max`/`min` lane by lane, for the x86 lane types, from
/// their `cmp::<P>` (an AVX comparison predicate, `_CMP_*`): `fmax`/`fmin` pick the other
/// operand where `self` is NaN, else by `>`/`<`, as x86 lowers `f32::max`/`min`.
#[cfg(target_arch = "x86_64")]
macro_rules! compare_ops {
    ($t:ty, $m:ty) => {
        #[inline(always)]
        fn fmax(self, o: $t) -> $t {
            let bigger = o.gt(self).pick(o, self);
            self.cmp::<_CMP_UNORD_Q>(self).pick(o, bigger)
        }

        #[inline(always)]
        fn fmin(self, o: $t) -> $t {
            let smaller = o.lt(self).pick(o, self);
            self.cmp::<_CMP_UNORD_Q>(self).pick(o, smaller)
        }

        #[inline(always)]
        fn lt(self, o: $t) -> $m {
            self.cmp::<_CMP_LT_OQ>(o)
        }

        #[inline(always)]
        fn gt(self, o: $t) -> $m {
            self.cmp::<_CMP_GT_OQ>(o)
        }

        #[inline(always)]
        fn ge(self, o: $t) -> $m {
            self.cmp::<_CMP_GE_OQ>(o)
        }
    };
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::Avx;

/// [`LANES`] numbers in one AVX register, for the x86-64-v3 copy of `cpu::isa` (the v4 copy
/// runs [`Avx512`]).
///
/// The intrinsics are `unsafe` to call where the CPU may lack AVX; these lanes are built only
/// in [`trace_chunk`]'s instances that `cpu::isa::trace_chunk` runs inside its v3 copy, which
/// runs only on CPUs with that level (`with_isa` asserts it), or in a build whose target has
/// AVX2. That is the safety argument of every `unsafe` block here.
#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    use super::{LANES, Lane, Lanes, Mask};

    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx(__m256);

    /// [`Avx`]'s truths: all-ones or zero lanes.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct AvxMask(__m256);

    macro_rules! avx_op {
        ($trait:ident, $f:ident, $intrinsic:ident) => {
            impl $trait for Avx {
                type Output = Avx;
                #[inline(always)]
                fn $f(self, o: Avx) -> Avx {
                    // SAFETY: see the module's docs.
                    Avx(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    avx_op!(Add, add, _mm256_add_ps);
    avx_op!(Sub, sub, _mm256_sub_ps);
    avx_op!(Mul, mul, _mm256_mul_ps);
    avx_op!(Div, div, _mm256_div_ps);

    impl Neg for Avx {
        type Output = Avx;
        #[inline(always)]
        fn neg(self) -> Avx {
            // SAFETY: see the module's docs.
            Avx(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
    }

    impl Avx {
        #[inline(always)]
        fn cmp<const P: i32>(self, o: Avx) -> AvxMask {
            // SAFETY: see the module's docs.
            AvxMask(unsafe { _mm256_cmp_ps::<P>(self.0, o.0) })
        }
    }

    impl Lane for Avx {
        type M = AvxMask;

        #[inline(always)]
        fn splat(x: f32) -> Avx {
            // SAFETY: see the module's docs.
            Avx(unsafe { _mm256_set1_ps(x) })
        }

        #[inline(always)]
        fn sqrt(self) -> Avx {
            // SAFETY: see the module's docs.
            Avx(unsafe { _mm256_sqrt_ps(self.0) })
        }

        #[inline(always)]
        fn abs(self) -> Avx {
            // SAFETY: see the module's docs.
            Avx(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }

        compare_ops!(Avx, AvxMask);
    }

    impl Lanes<LANES> for Avx {
        #[inline(always)]
        fn from_array(a: [f32; LANES]) -> Avx {
            // SAFETY: see the module's docs; `a` holds 8 floats.
            Avx(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }

        #[inline(always)]
        fn to_array(self) -> [f32; LANES] {
            let mut a = [0.0; LANES];
            // SAFETY: see the module's docs; `a` holds 8 floats.
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }

        #[inline(always)]
        fn transpose(rows: [&[f32; 4]; LANES]) -> [Avx; 4] {
            // SAFETY: see the module's docs; each row is four floats, read unaligned.
            unsafe {
                // Rows j and j + 4 in the two halves, then the 4x4 transpose of each half.
                // (No closures or array maps here: they may be compiled out of line,
                // without AVX, with every intrinsic a call.)
                macro_rules! pair {
                    ($j:expr) => {
                        _mm256_insertf128_ps::<1>(
                            _mm256_castps128_ps256(_mm_loadu_ps(rows[$j].as_ptr())),
                            _mm_loadu_ps(rows[$j + 4].as_ptr()),
                        )
                    };
                }
                let r = [pair!(0), pair!(1), pair!(2), pair!(3)];
                let (t0, t1) = (
                    _mm256_unpacklo_ps(r[0], r[1]),
                    _mm256_unpackhi_ps(r[0], r[1]),
                );
                let (t2, t3) = (
                    _mm256_unpacklo_ps(r[2], r[3]),
                    _mm256_unpackhi_ps(r[2], r[3]),
                );
                [
                    Avx(_mm256_shuffle_ps::<0b01_00_01_00>(t0, t2)),
                    Avx(_mm256_shuffle_ps::<0b11_10_11_10>(t0, t2)),
                    Avx(_mm256_shuffle_ps::<0b01_00_01_00>(t1, t3)),
                    Avx(_mm256_shuffle_ps::<0b11_10_11_10>(t1, t3)),
                ]
            }
        }
    }

    impl Mask<Avx> for AvxMask {
        #[inline(always)]
        fn from_bits(bits: u32) -> AvxMask {
            // SAFETY: see the module's docs (AVX2).
            unsafe {
                let lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                let set = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane_bit);
                AvxMask(_mm256_castsi256_ps(_mm256_cmpeq_epi32(set, lane_bit)))
            }
        }

        #[inline(always)]
        fn and(self, o: AvxMask) -> AvxMask {
            // SAFETY: see the module's docs.
            AvxMask(unsafe { _mm256_and_ps(self.0, o.0) })
        }

        #[inline(always)]
        fn or(self, o: AvxMask) -> AvxMask {
            // SAFETY: see the module's docs.
            AvxMask(unsafe { _mm256_or_ps(self.0, o.0) })
        }

        #[inline(always)]
        fn not(self) -> AvxMask {
            // SAFETY: see the module's docs.
            AvxMask(unsafe { _mm256_xor_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(-1))) })
        }

        #[inline(always)]
        fn bits(self) -> u32 {
            // SAFETY: see the module's docs.
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }

        #[inline(always)]
        fn pick(self, a: Avx, b: Avx) -> Avx {
            // SAFETY: see the module's docs.
            Avx(unsafe { _mm256_blendv_ps(b.0, a.0, self.0) })
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::Avx512;

/// [`LANES_AVX512`] numbers in one AVX-512 register and their truths in a mask register, for
/// the x86-64-v4 copy of `cpu::isa`.
///
/// The intrinsics are `unsafe` to call where the CPU may lack AVX-512; these lanes are built
/// only in [`trace_chunk`]'s instances that `cpu::isa::trace_chunk` runs inside its v4 copy,
/// which runs only on CPUs with that level (`with_isa` asserts it), or in a build whose target
/// has AVX-512 F. That is the safety argument of every `unsafe` block here.
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    use super::{LANES_AVX512, Lane, Lanes, Mask};

    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx512(__m512);

    /// [`Avx512`]'s truths: a bit a lane.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx512Mask(__mmask16);

    macro_rules! avx512_op {
        ($trait:ident, $f:ident, $intrinsic:ident) => {
            impl $trait for Avx512 {
                type Output = Avx512;
                #[inline(always)]
                fn $f(self, o: Avx512) -> Avx512 {
                    // SAFETY: see the module's docs.
                    Avx512(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    avx512_op!(Add, add, _mm512_add_ps);
    avx512_op!(Sub, sub, _mm512_sub_ps);
    avx512_op!(Mul, mul, _mm512_mul_ps);
    avx512_op!(Div, div, _mm512_div_ps);

    impl Neg for Avx512 {
        type Output = Avx512;
        #[inline(always)]
        fn neg(self) -> Avx512 {
            // The sign bit flipped as an integer (AVX-512 F's `xor`; the float one is DQ's).
            // SAFETY: see the module's docs.
            Avx512(unsafe {
                let a = _mm512_castps_si512(self.0);
                _mm512_castsi512_ps(_mm512_xor_si512(a, _mm512_set1_epi32(i32::MIN)))
            })
        }
    }

    impl Avx512 {
        #[inline(always)]
        fn cmp<const P: i32>(self, o: Avx512) -> Avx512Mask {
            // SAFETY: see the module's docs.
            Avx512Mask(unsafe { _mm512_cmp_ps_mask::<P>(self.0, o.0) })
        }
    }

    impl Lane for Avx512 {
        type M = Avx512Mask;

        #[inline(always)]
        fn splat(x: f32) -> Avx512 {
            // SAFETY: see the module's docs.
            Avx512(unsafe { _mm512_set1_ps(x) })
        }

        #[inline(always)]
        fn sqrt(self) -> Avx512 {
            // SAFETY: see the module's docs.
            Avx512(unsafe { _mm512_sqrt_ps(self.0) })
        }

        #[inline(always)]
        fn abs(self) -> Avx512 {
            // The sign bit cleared as an integer (as `neg`).
            // SAFETY: see the module's docs.
            Avx512(unsafe {
                let a = _mm512_castps_si512(self.0);
                _mm512_castsi512_ps(_mm512_and_si512(a, _mm512_set1_epi32(i32::MAX)))
            })
        }

        compare_ops!(Avx512, Avx512Mask);
    }

    impl Lanes<LANES_AVX512> for Avx512 {
        #[inline(always)]
        fn from_array(a: [f32; LANES_AVX512]) -> Avx512 {
            // SAFETY: see the module's docs; `a` holds 16 floats.
            Avx512(unsafe { _mm512_loadu_ps(a.as_ptr()) })
        }

        #[inline(always)]
        fn to_array(self) -> [f32; LANES_AVX512] {
            let mut a = [0.0; LANES_AVX512];
            // SAFETY: see the module's docs; `a` holds 16 floats.
            unsafe { _mm512_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }

        #[inline(always)]
        fn transpose(rows: [&[f32; 4]; LANES_AVX512]) -> [Avx512; 4] {
            // SAFETY: see the module's docs; each row is four floats, read unaligned.
            unsafe {
                // Rows j, j + 4, j + 8 and j + 12 in the four quarters, then the 4x4
                // transpose of each quarter (as `Avx`'s halves; no closures: see there).
                macro_rules! four {
                    ($j:expr) => {{
                        let v = _mm512_castps128_ps512(_mm_loadu_ps(rows[$j].as_ptr()));
                        let v = _mm512_insertf32x4::<1>(v, _mm_loadu_ps(rows[$j + 4].as_ptr()));
                        let v = _mm512_insertf32x4::<2>(v, _mm_loadu_ps(rows[$j + 8].as_ptr()));
                        _mm512_insertf32x4::<3>(v, _mm_loadu_ps(rows[$j + 12].as_ptr()))
                    }};
                }
                let r = [four!(0), four!(1), four!(2), four!(3)];
                let (t0, t1) = (
                    _mm512_unpacklo_ps(r[0], r[1]),
                    _mm512_unpackhi_ps(r[0], r[1]),
                );
                let (t2, t3) = (
                    _mm512_unpacklo_ps(r[2], r[3]),
                    _mm512_unpackhi_ps(r[2], r[3]),
                );
                [
                    Avx512(_mm512_shuffle_ps::<0b01_00_01_00>(t0, t2)),
                    Avx512(_mm512_shuffle_ps::<0b11_10_11_10>(t0, t2)),
                    Avx512(_mm512_shuffle_ps::<0b01_00_01_00>(t1, t3)),
                    Avx512(_mm512_shuffle_ps::<0b11_10_11_10>(t1, t3)),
                ]
            }
        }
    }

    impl Mask<Avx512> for Avx512Mask {
        #[inline(always)]
        fn from_bits(bits: u32) -> Avx512Mask {
            Avx512Mask(bits as __mmask16)
        }

        #[inline(always)]
        fn and(self, o: Avx512Mask) -> Avx512Mask {
            Avx512Mask(self.0 & o.0)
        }

        #[inline(always)]
        fn or(self, o: Avx512Mask) -> Avx512Mask {
            Avx512Mask(self.0 | o.0)
        }

        #[inline(always)]
        fn not(self) -> Avx512Mask {
            Avx512Mask(!self.0)
        }

        #[inline(always)]
        fn bits(self) -> u32 {
            u32::from(self.0)
        }

        #[inline(always)]
        fn pick(self, a: Avx512, b: Avx512) -> Avx512 {
            // SAFETY: see the module's docs.
            Avx512(unsafe { _mm512_mask_blend_ps(self.0, b.0, a.0) })
        }
    }
}

/// A `Vec3` per lane, with glam's `Vec3` arithmetic (the same operations in the same order).
#[derive(Clone, Copy, Debug)]
pub struct V3<L> {
    x: L,
    y: L,
    z: L,
}

impl<L: Lane> V3<L> {
    #[inline(always)]
    fn from_arrays<const N: usize>(v: &[[f32; N]; 3]) -> V3<L>
    where
        L: Lanes<N>,
    {
        V3 {
            x: L::from_array(v[0]),
            y: L::from_array(v[1]),
            z: L::from_array(v[2]),
        }
    }

    #[inline(always)]
    fn to_arrays<const N: usize>(self) -> [[f32; N]; 3]
    where
        L: Lanes<N>,
    {
        [self.x.to_array(), self.y.to_array(), self.z.to_array()]
    }

    #[inline(always)]
    fn zero() -> V3<L> {
        V3::splat([0.0; 3])
    }

    #[inline(always)]
    fn splat(v: [f32; 3]) -> V3<L> {
        V3 {
            x: L::splat(v[0]),
            y: L::splat(v[1]),
            z: L::splat(v[2]),
        }
    }

    /// `f` of each component.
    #[inline(always)]
    fn map(self, f: impl Fn(L) -> L) -> V3<L> {
        V3 {
            x: f(self.x),
            y: f(self.y),
            z: f(self.z),
        }
    }

    /// `f` of each pair of components.
    #[inline(always)]
    fn zip(self, o: V3<L>, f: impl Fn(L, L) -> L) -> V3<L> {
        V3 {
            x: f(self.x, o.x),
            y: f(self.y, o.y),
            z: f(self.z, o.z),
        }
    }

    /// `Vec3 * f32`.
    #[inline(always)]
    fn scale(self, s: L) -> V3<L> {
        self.map(|c| c * s)
    }

    /// `Vec3 / f32`.
    #[inline(always)]
    fn div(self, s: L) -> V3<L> {
        self.map(|c| c / s)
    }

    /// `Vec3 * Vec3`.
    #[inline(always)]
    fn mul(self, o: V3<L>) -> V3<L> {
        self.zip(o, |a, b| a * b)
    }

    #[inline(always)]
    fn dot(self, o: V3<L>) -> L {
        (self.x * o.x) + (self.y * o.y) + (self.z * o.z)
    }

    #[inline(always)]
    fn cross(self, o: V3<L>) -> V3<L> {
        V3 {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    #[inline(always)]
    fn length(self) -> L {
        self.dot(self).sqrt()
    }

    #[inline(always)]
    fn abs(self) -> V3<L> {
        self.map(L::abs)
    }

    /// glam's `Vec3::min`: `if a < b { a } else { b }`.
    #[inline(always)]
    fn min(self, o: V3<L>) -> V3<L> {
        self.zip(o, |a, b| a.lt(b).pick(a, b))
    }

    /// glam's `Vec3::max`: `if a > b { a } else { b }`.
    #[inline(always)]
    fn max(self, o: V3<L>) -> V3<L> {
        self.zip(o, |a, b| a.gt(b).pick(a, b))
    }

    /// glam's `Vec3::max_element`: `max(max(x, y), z)` with `if a > b { a } else { b }`.
    #[inline(always)]
    fn max_element(self) -> L {
        let m = self.x.gt(self.y).pick(self.x, self.y);
        m.gt(self.z).pick(m, self.z)
    }
}

impl<L: Lane> Add for V3<L> {
    type Output = V3<L>;
    #[inline(always)]
    fn add(self, o: V3<L>) -> V3<L> {
        self.zip(o, |a, b| a + b)
    }
}

impl<L: Lane> Sub for V3<L> {
    type Output = V3<L>;
    #[inline(always)]
    fn sub(self, o: V3<L>) -> V3<L> {
        self.zip(o, |a, b| a - b)
    }
}

impl<L: Lane> Neg for V3<L> {
    type Output = V3<L>;
    #[inline(always)]
    fn neg(self) -> V3<L> {
        self.map(|c| -c)
    }
}

/// The `N` lanes' paths, a field's lanes side by side (what [`PathState`] holds per path).
#[derive(Clone, Copy)]
struct Paths<const N: usize> {
    origin: [[f32; N]; 3],
    dir: [[f32; N]; 3],
    throughput: [[f32; N]; 3],
    radiance: [[f32; N]; 3],
    mis_pdf: [f32; N],
    alive: [bool; N],
}

impl<const N: usize> Paths<N> {
    #[inline(always)]
    fn get(&self, j: usize) -> PathState {
        let v = |a: &[[f32; N]; 3]| Vec3::new(a[0][j], a[1][j], a[2][j]);
        PathState {
            origin: v(&self.origin),
            dir: v(&self.dir),
            throughput: v(&self.throughput),
            radiance: v(&self.radiance),
            alive: self.alive[j],
            mis_pdf: self.mis_pdf[j],
        }
    }

    #[inline(always)]
    fn set(&mut self, j: usize, p: &PathState) {
        for k in 0..3 {
            self.origin[k][j] = p.origin[k];
            self.dir[k][j] = p.dir[k];
            self.throughput[k][j] = p.throughput[k];
            self.radiance[k][j] = p.radiance[k];
        }
        (self.alive[j], self.mis_pdf[j]) = (p.alive, p.mis_pdf);
    }
}

/// What each of `N` lanes' walks found and the numbers its shading draws from.
#[derive(Clone, Copy)]
struct Found<const N: usize> {
    prim: [u32; N],
    t: [f32; N],
    u: [f32; N],
    v: [f32; N],
    /// The light's x and y, the scattered direction's x and y, the roulette's.
    light_x: [f32; N],
    light_y: [f32; N],
    scatter_x: [f32; N],
    scatter_y: [f32; N],
    roulette: [f32; N],
}

impl<const N: usize> Default for Found<N> {
    fn default() -> Self {
        Found {
            prim: [0; N],
            t: [0.0; N],
            u: [0.0; N],
            v: [0.0; N],
            light_x: [0.0; N],
            light_y: [0.0; N],
            scatter_x: [0.0; N],
            scatter_y: [0.0; N],
            roulette: [0.0; N],
        }
    }
}

/// `math::sin_cos_turns` lane by lane, the same operations: the quadrant `q mod 4` by float
/// arithmetic (`q - 4 round((q - 3/2) / 4)`, exact for these small integers) where the scalar
/// form converts to an integer, and picked the same values.
#[inline(always)]
fn sin_cos_turns<L: Lane>(t: L) -> (L, L) {
    let round = |x: L| (x + L::splat(SIN_COS_ROUND)) - L::splat(SIN_COS_ROUND);
    let x = L::splat(4.0) * t;
    let q = round(x);
    let a = (x - q) * L::splat(std::f32::consts::FRAC_PI_2);
    let z = a * a;
    let s =
        ((L::splat(SIN_COS_S3) * z + L::splat(SIN_COS_S2)) * z + L::splat(SIN_COS_S1)) * z * a + a;
    let c = ((L::splat(SIN_COS_C3) * z + L::splat(SIN_COS_C2)) * z + L::splat(SIN_COS_C1)) * z * z
        - L::splat(0.5) * z
        + L::splat(1.0);
    let m = q - L::splat(4.0) * round((q - L::splat(1.5)) * L::splat(0.25));
    // m is 0, 1, 2 or 3: odd for 1 and 3, high for 2 and 3.
    let odd = m
        .ge(L::splat(0.5))
        .and(m.lt(L::splat(1.5)))
        .or(m.ge(L::splat(2.5)));
    let high = m.ge(L::splat(1.5));
    let (s, c) = (odd.pick(c, s), odd.pick(-s, c));
    (high.pick(-s, s), high.pick(-c, c))
}

/// `mis_weight`: Veach's power heuristic.
#[inline(always)]
fn mis_weight<L: Lane>(a: L, b: L) -> L {
    let (a2, b2) = (a * a, b * b);
    (a2 + b2)
        .gt(L::splat(0.0))
        .pick(a2 / (a2 + b2), L::splat(0.0))
}

/// `light_pdf`: the solid-angle pdf of a light's point.
#[inline(always)]
fn light_pdf<L: Lane>(g: &Globals, emission: V3<L>, dist2: L, cos_l: L) -> L {
    emission.dot(V3::splat(LUMINANCE)) * dist2 / (L::splat(g.scene.light_power) * cos_l)
}

/// The surface of the lanes' hits (`surface_at` for triangles without shading data).
#[derive(Clone, Copy)]
struct Surface<L> {
    position: V3<L>,
    /// Geometric normal, which is also the shading normal here.
    ng: V3<L>,
    offset: L,
    back_offset: L,
}

/// `offset_ray_origin`.
#[inline(always)]
fn offset_ray_origin<L: Lane>(s: &Surface<L>, dir_in: V3<L>, n: V3<L>) -> V3<L> {
    let ng = s.ng;
    let back = dir_in
        .dot(n)
        .lt(L::splat(0.0))
        .pick3(dir_in, dir_in - ng.scale(dir_in.dot(ng)));
    s.position - back.scale(s.back_offset) + n.scale(s.offset)
}

/// Traces the paths `r0..r0 + slots.len()` of the batch, writing each one's slot value as
/// [`stages::trace_paths`](super::stages::trace_paths) does; returns the segments traced and
/// the samples dropped, on lanes `L`, drawing and walking in the forms `K` (the same numbers
/// and hits in each). Only for a variant that [`runs`].
#[inline(always)]
pub fn trace_chunk<const F: u32, const N: usize, L: Lanes<N>, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    r0: u32,
    slots: &mut [[f32; 3]],
) -> (u64, u64) {
    debug_assert!(runs(F));
    let scene = g.scene;
    let mut paths = Paths {
        origin: [[0.0; N]; 3],
        dir: [[0.0; N]; 3],
        throughput: [[0.0; N]; 3],
        radiance: [[0.0; N]; 3],
        mis_pdf: [0.0; N],
        alive: [false; N],
    };
    // The slot each lane traces (`usize::MAX`: none), its pixel, sample, sampler setup and
    // segment number.
    let mut slot = [usize::MAX; N];
    let mut pixel = [0u32; N];
    let mut sample = [0u32; N];
    let mut sp = [SobolPixel::default(); N];
    let mut depth = [0u32; N];
    let mut next = 0usize;
    let (mut rays, mut dropped) = (0u64, 0u64);
    let mut found = Found::<N>::default();
    loop {
        // Every lane walks until its path hits something: a path that escapes ends there,
        // and the lane takes the chunk's next path, so that the shading below finds every
        // lane busy but at the chunk's end. All the lanes' numbers are drawn before their
        // walks, so that the draws' long chains of multiplies run beside the walks.
        let mut hit = [false; N];
        let mut todo = u32::MAX >> (32 - N); // every lane (N <= 32)
        while todo != 0 {
            // The lanes' paths: a lane without one takes the chunk's next.
            let (mut live, mut fresh) = (0u32, 0u32);
            let mut m = todo;
            while m != 0 {
                let j = m.trailing_zeros() as usize;
                m &= m - 1;
                if slot[j] == usize::MAX {
                    if next == slots.len() {
                        continue;
                    }
                    let (p, s) = batch_ray(scene, r0 + next as u32);
                    sp[j] = sampler_pixel(scene, p);
                    (pixel[j], sample[j], depth[j]) = (p, s, 0);
                    slot[j] = next;
                    next += 1;
                    fresh |= 1 << j;
                }
                live |= 1 << j;
            }
            // The segment's numbers: under the `Sobol` sampler from the render's table, four
            // lanes at a time (`Forms::draw_pairs4`), then `wanted_pairs`.
            let drawn = table_pairs::<K, N>(g, &sp, &sample, &depth, live);
            let mut m = live;
            while m != 0 {
                let j = m.trailing_zeros() as usize;
                m &= m - 1;
                let fresh = fresh & (1 << j) != 0;
                // A new path's camera ray (from the same draw under the `Sobol` sampler).
                let (rl, rs, rr) = match drawn[j] {
                    Some(d) => {
                        let d = wanted_pairs(g, d, depth[j]);
                        if fresh {
                            paths.set(j, &camera_path_from(scene, pixel[j], d.camera));
                        }
                        (d.light, d.scatter, d.roulette)
                    }
                    None => {
                        if fresh {
                            paths.set(j, &camera_path_at(g, sp[j], pixel[j], sample[j]));
                        }
                        let (rl, rs, rr) =
                            segment_rands::<K>(g, sp[j], pixel[j], sample[j], depth[j]);
                        (rl.truncate().truncate(), rs.truncate().truncate(), rr)
                    }
                };
                (found.light_x[j], found.light_y[j]) = (rl.x, rl.y);
                (found.scatter_x[j], found.scatter_y[j], found.roulette[j]) = (rs.x, rs.y, rr);
            }
            let mut missed = 0u32;
            let mut m = live;
            while m != 0 {
                let j = m.trailing_zeros() as usize;
                m &= m - 1;
                let (o, d) = (&paths.origin, &paths.dir);
                let ray = Ray {
                    origin: Vec3::new(o[0][j], o[1][j], o[2][j]),
                    dir: Vec3::new(d[0][j], d[1][j], d[2][j]),
                };
                rays += 1;
                let h = K::trace_closest::<F>(bvh, &ray, 0.0, T_MAX);
                hit[j] = h.is_some();
                missed |= u32::from(h.is_none()) << j;
                let h = h.unwrap_or_default();
                (found.prim[j], found.t[j], found.u[j], found.v[j]) = (h.prim, h.t, h.u, h.v);
            }
            todo = missed;
            while missed != 0 {
                let j = missed.trailing_zeros() as usize;
                missed &= missed - 1;
                let mut path = paths.get(j);
                escape::<F>(g, &mut path);
                let (v, d) = write_sample(path.radiance);
                slots[slot[j]] = v;
                dropped += u64::from(d);
                slot[j] = usize::MAX;
            }
        }
        if !hit.iter().any(|&h| h) {
            return (rays, dropped);
        }
        // The lanes the packet's shading serves; each other one finishes its segment alone
        // through the one-path code, from the segment's full numbers (the pairs drawn above
        // are theirs too: the same numbers).
        let mut lanes = hit;
        if F != ALWAYS {
            for j in 0..N {
                if !hit[j] || lane_shaded::<F, N>(g, &found, j) {
                    continue;
                }
                lanes[j] = false;
                let mut path = paths.get(j);
                let rnd = segment_rands::<K>(g, sp[j], pixel[j], sample[j], depth[j]);
                let h = Hit {
                    t: found.t[j],
                    prim: found.prim[j],
                    u: found.u[j],
                    v: found.v[j],
                };
                shade_segment::<F, K>(g, bvh, &mut path, h, rnd, depth[j]);
                paths.set(j, &path);
            }
        }
        if lanes.iter().any(|&l| l) {
            shade::<F, N, L, K>(g, bvh, &mut paths, &lanes, &found, &depth);
        }
        for j in 0..N {
            if !hit[j] {
                continue;
            }
            depth[j] += 1;
            if !(depth[j] <= scene.max_bounces && paths.alive[j]) {
                let r = &paths.radiance;
                let (v, d) = write_sample(Vec3::new(r[0][j], r[1][j], r[2][j]));
                slots[slot[j]] = v;
                dropped += u64::from(d);
                slot[j] = usize::MAX;
            }
        }
    }
}

/// The pairs ([`SegmentKeys::draw_pairs`]) of the lanes of `live` whose segment the render's
/// table serves ([`table_keys`]), four lanes at a time by [`Forms::draw_pairs4`] where the
/// form draws four for less than four one-lane draws ([`Forms::DRAWS_FOUR`]; the last two or
/// three lanes padded to four), else a lane at a time by [`Forms::draw_pairs`]; `None` for
/// the other lanes.
#[inline(always)]
fn table_pairs<K: Forms, const N: usize>(
    g: &Globals,
    sp: &[SobolPixel; N],
    sample: &[u32; N],
    depth: &[u32; N],
    live: u32,
) -> [Option<SegmentPairs>; N] {
    let mut drawn = [None; N];
    let mut keys: [Option<&SegmentKeys>; N] = [None; N];
    // The lanes the table serves, in order.
    let (mut lanes, mut n) = ([0usize; N], 0usize);
    let mut m = live;
    while m != 0 {
        let j = m.trailing_zeros() as usize;
        m &= m - 1;
        keys[j] = table_keys(g, sp[j], depth[j]);
        if keys[j].is_some() {
            lanes[n] = j;
            n += 1;
        }
    }
    let mut at = 0;
    while at < n {
        if n - at == 1 || !K::DRAWS_FOUR {
            let j = lanes[at];
            if let Some(k) = keys[j] {
                drawn[j] = Some(K::draw_pairs(k, sp[j], sample[j]));
            }
            at += 1;
            continue;
        }
        // Lanes past the last drawn again (their numbers dropped).
        let lane = |i: usize| lanes[(at + i).min(n - 1)];
        let four = [lane(0), lane(1), lane(2), lane(3)];
        let k = |j: usize| keys[j].expect("a lane the table serves");
        let d = K::draw_pairs4(
            [k(four[0]), k(four[1]), k(four[2]), k(four[3])],
            [sp[four[0]], sp[four[1]], sp[four[2]], sp[four[3]]],
            [
                sample[four[0]],
                sample[four[1]],
                sample[four[2]],
                sample[four[3]],
            ],
        );
        for i in 0..4.min(n - at) {
            drawn[four[i]] = Some(d[i]);
        }
        at += 4;
    }
    drawn
}

/// The rest of `trace_ray_at` for the lanes `hit` marks, all at once: the surface, the
/// emission's weight, the light sample, the scattered direction and the roulette, then the
/// shadow rays lane by lane, then the radiance.
#[inline(always)]
fn shade<const F: u32, const N: usize, L: Lanes<N>, K: Forms>(
    g: &Globals,
    bvh: &GpuBvh,
    paths: &mut Paths<N>,
    hit: &[bool; N],
    found: &Found<N>,
    depth: &[u32; N],
) {
    let scene = g.scene;
    // Gathered: the hit's triangle and material (a lane without a hit reads the first hit
    // lane's triangle, and its results are not stored), four-word groups of eight records
    // transposed into lanes (`Lane::transpose`); the flags as bits.
    let first = (0..N).find(|&j| hit[j]).unwrap_or(0);
    let prims: [usize; N] =
        std::array::from_fn(|j| found.prim[if hit[j] { j } else { first }] as usize);
    let tris = each(prims, |i| &g.primitives[i]);
    let mats = each(prims, |i| &g.materials[g.prim_materials[i] as usize]);
    let (mut two_sided, mut hit_bits, mut last, mut roulette) = (0u32, 0u32, 0u32, 0u32);
    for j in 0..N {
        let bit = |b: bool| u32::from(b) << j;
        two_sided |= bit(mats[j].flags & MATERIAL_TWO_SIDED != 0);
        hit_bits |= bit(hit[j]);
        last |= bit(depth[j] >= scene.max_bounces);
        roulette |= bit(depth[j] >= scene.rr_depth);
    }
    debug_assert!(
        (0..N).all(|j| !hit[j] || mats[j].kind == MATERIAL_DIFFUSE),
        "a variant of diffuse surfaces"
    );
    let xyz = |rows: [&[f32; 4]; N]| {
        let [x, y, z, _] = L::transpose(rows);
        V3 { x, y, z }
    };
    let (a, b, c) = (
        xyz(each(tris, |p| &p.a)),
        xyz(each(tris, |p| &p.b)),
        xyz(each(tris, |p| &p.c)),
    );
    let (origin, dir) = (V3::from_arrays(&paths.origin), V3::from_arrays(&paths.dir));
    let throughput = V3::from_arrays(&paths.throughput);
    let radiance = V3::from_arrays(&paths.radiance);
    // GpuMaterial's words 0..4: color, kind; 4..8: emission, alpha.
    let (color, emission) = (
        xyz(each(mats, |m| quad(m, 0))),
        xyz(each(mats, |m| quad(m, 1))),
    );
    let (t, u, v) = (
        L::from_array(found.t),
        L::from_array(found.u),
        L::from_array(found.v),
    );
    let mis_pdf = L::from_array(paths.mis_pdf);
    let rl_y = L::from_array(found.light_y);
    let (rs_x, rs_y) = (
        L::from_array(found.scatter_x),
        L::from_array(found.scatter_y),
    );
    let rr = L::from_array(found.roulette);
    let hit_mask = L::M::from_bits(hit_bits);
    let (two_sided, last, roulette) = (
        L::M::from_bits(two_sided),
        L::M::from_bits(last),
        L::M::from_bits(roulette),
    );
    let zero = L::splat(0.0);
    let one = L::splat(1.0);

    // surface_at, a triangle.
    let w = one - u - v;
    let position = a.scale(w) + b.scale(u) + c.scale(v);
    let cr = (b - a).cross(c - a);
    let cr_length = cr.dot(cr).sqrt();
    let ng = cr.scale(one / cr_length);
    let extent = (a.max(b).max(c) - a.min(b).min(c)).max_element();
    let magnitude = a.abs().max(b.abs()).max(c.abs());
    let aspect = extent * extent / cr_length;
    let offset = L::splat(OFFSET_HIT_ULPS * UNIT_ROUNDOFF) * ng.abs().dot(magnitude)
        + L::splat(OFFSET_T_ULPS * UNIT_ROUNDOFF) * extent * aspect.fmax(one);
    let back_offset = (L::splat(OFFSET_BACK_ULPS * UNIT_ROUNDOFF) * magnitude.max_element())
        .fmin(L::splat(0.5) * t);
    let surface = Surface {
        position,
        ng,
        offset,
        back_offset,
    };

    // The emission's weight against the light sample of the vertex before.
    let lit = has(F, Feature::Emission) && has(F, Feature::Diffuse);
    let emission_weight = if lit {
        let cos_l = cr.dot(dir).abs() / cr.length();
        mis_pdf.gt(zero).pick(
            mis_weight(mis_pdf, light_pdf(g, emission, t * t, cos_l)),
            one,
        )
    } else {
        one
    };
    let sample_here = if lit && scene.light_count > 0 {
        // Every hit lane's surface is diffuse (the variant's).
        last.not()
    } else {
        L::M::from_bits(0)
    }
    .and(hit_mask);

    // light_query, a triangle light.
    let front = dir.dot(ng).lt(zero);
    let ng_facing = front.pick3(ng, -ng);
    let ns_facing = ng_facing;
    // The lanes' lights (a lane that samples none reads light 0, or zeros in a scene
    // without lights; its results are unused: its `p_select` is 0, so `query` is false).
    let (mut light_index, mut fp_select, mut fx) = ([0usize; N], [0.0f32; N], [0.0f32; N]);
    let mut light_two_sided = 0u32;
    let sample_bits = sample_here.bits();
    for j in 0..N {
        if sample_bits >> j & 1 == 0 {
            continue;
        }
        let (lo, ps, x) = choose_light(g, found.light_x[j]);
        (fp_select[j], fx[j]) = (ps, x);
        let light = &g.lights[lo as usize];
        light_index[j] = lo as usize;
        light_two_sided |= u32::from(light.two_sided != 0) << j;
    }
    let none = <crate::gpu_types::GpuLight as bytemuck::Zeroable>::zeroed();
    let lights = each(light_index, |i| g.lights.get(i).unwrap_or(&none));
    // GpuLight's words: p0, cdf; e1, area; e2, two_sided; emission, kind.
    let [e1x, e1y, e1z, area] = L::transpose(each(lights, |l| quad(l, 1)));
    let (p0, e1, e2) = (
        xyz(each(lights, |l| quad(l, 0))),
        V3 {
            x: e1x,
            y: e1y,
            z: e1z,
        },
        xyz(each(lights, |l| quad(l, 2))),
    );
    let light_emission = xyz(each(lights, |l| quad(l, 3)));
    let (p_select, x) = (L::from_array(fp_select), L::from_array(fx));
    let light_two_sided = L::M::from_bits(light_two_sided);
    let shadow_origin = offset_ray_origin(&surface, dir, ng_facing);
    let su = x.sqrt();
    let point = p0 + e1.scale(su * (one - rl_y)) + e2.scale(su * rl_y);
    let to = point - shadow_origin;
    let dist2 = to.dot(to);
    let dist = dist2.sqrt();
    let wi = to.div(dist);
    let t_max = dist * L::splat(SHADOW_T_SCALE);
    let side = ns_facing.dot(wi).gt(zero).and(ng_facing.dot(wi).gt(zero));
    let nl = e1.cross(e2);
    let cos_front = -nl.dot(wi) / nl.length();
    let cos_l = light_two_sided.pick(cos_front.abs(), cos_front);
    let query = sample_here
        .and(p_select.gt(zero))
        .and(dist2.gt(zero))
        .and(side)
        .and(cos_l.gt(zero));

    // light_contribution, a diffuse surface.
    let f_pdf = ns_facing.dot(wi).fmax(zero) * L::splat(INV_PI);
    let f_value = color.scale(f_pdf);
    let light_weight = mis_weight(light_pdf(g, light_emission, dist2, cos_l), f_pdf);
    let light_in = f_value
        .mul(light_emission)
        .scale(cos_l * area / (dist2 * p_select) * light_weight);

    // emitted.
    let emitted = front.or(two_sided).pick3(
        throughput.mul(emission).scale(emission_weight),
        V3::<L>::zero(),
    );
    let throughput_in = throughput;

    // shade_hit, a diffuse surface not at the last segment (sample_diffuse).
    let r = rs_x.sqrt();
    let (sin_phi, cos_phi) = sin_cos_turns(rs_y);
    let local = V3 {
        x: r * cos_phi,
        y: r * sin_phi,
        z: (one - rs_x).fmax(zero).sqrt(),
    };
    let n = ns_facing;
    let sign = n.z.ge(zero).pick(one, -one);
    let ob_a = L::splat(-1.0) / (sign + n.z);
    let ob_b = n.x * n.y * ob_a;
    let tangent = V3 {
        x: one + sign * n.x * n.x * ob_a,
        y: sign * ob_b,
        z: -sign * n.x,
    };
    let bitangent = V3 {
        x: ob_b,
        y: sign + n.y * n.y * ob_a,
        z: -n.y,
    };
    let scattered = tangent.scale(local.x) + bitangent.scale(local.y) + n.scale(local.z);
    let pdf = scattered.dot(ns_facing).fmax(zero) * L::splat(INV_PI);
    let cos_g = scattered.dot(ng_facing);
    let right_side = cos_g.gt(zero);
    let scattered_throughput = throughput.mul(color);
    let survives = right_side.and(scattered_throughput.max_element().gt(zero));
    let next_origin = offset_ray_origin(&surface, dir, right_side.pick3(ng_facing, -ng_facing));
    let go_on = last.not();
    let mut throughput = go_on.pick3(scattered_throughput, throughput);
    let mut alive = survives.and(go_on);
    let origin = go_on.pick3(next_origin, origin);
    let dir = go_on.pick3(scattered, dir);
    let pdf = go_on.pick(pdf, zero);
    let mis_pdf = sample_here.pick(pdf, zero);

    // russian_roulette.
    let spin = alive.and(roulette);
    let q = throughput.max_element().fmin(L::splat(RR_MAX_SURVIVAL));
    let keep = rr.lt(q);
    throughput = spin.and(keep).pick3(throughput.div(q), throughput);
    alive = alive.and(spin.and(keep.not()).not());

    // The shadow rays, lane by lane.
    let mut open = 0u32;
    let (query_bits, so, sd, t_max) = (
        query.bits(),
        shadow_origin.to_arrays(),
        wi.to_arrays(),
        t_max.to_array(),
    );
    // Over the set bits (whether a lane has a shadow ray, e.g. a light behind its surface,
    // is a coin toss: one mispredicted branch a lane where the loop tested each).
    let mut bits = query_bits;
    while bits != 0 {
        let j = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let ray = Ray {
            origin: Vec3::new(so[0][j], so[1][j], so[2][j]),
            dir: Vec3::new(sd[0][j], sd[1][j], sd[2][j]),
        };
        // Toward a point of a lamp (this variant has no sky): `shade::shadowed`'s test.
        open |= u32::from(!K::trace_any_between::<F>(bvh, &ray, 0.0, t_max[j])) << j;
    }
    let open = L::M::from_bits(open);
    let arrived = query.and(open).pick3(light_in, V3::<L>::zero());
    let radiance = sample_here.pick3(radiance + throughput_in.mul(arrived), radiance) + emitted;

    // Stored for the lanes with a hit (the others hold no path here: the chunk is done).
    let keep = hit_mask;
    paths.origin = keep
        .pick3(origin, V3::from_arrays(&paths.origin))
        .to_arrays();
    paths.dir = keep.pick3(dir, V3::from_arrays(&paths.dir)).to_arrays();
    paths.throughput = keep
        .pick3(throughput, V3::from_arrays(&paths.throughput))
        .to_arrays();
    paths.radiance = keep
        .pick3(radiance, V3::from_arrays(&paths.radiance))
        .to_arrays();
    paths.mis_pdf = keep.pick(mis_pdf, L::from_array(paths.mis_pdf)).to_array();
    let alive = alive.bits();
    for (j, (stored, &h)) in paths.alive.iter_mut().zip(hit).enumerate() {
        if h {
            *stored = alive >> j & 1 != 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `fmax`/`fmin` are `f32::max`/`min` lane by lane where an operand is NaN (the other
    /// comes back) and wherever the two differ (zeros of both signs, equal to each other,
    /// are left out: which of them `f32::max` returns is the compiler's choice).
    fn min_max_follow_f32<const N: usize, L: Lanes<N>>() {
        let values = [
            f32::NAN,
            -1.5,
            0.25,
            3.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            7.0,
            -0.5,
        ];
        for shift in 0..N {
            let a: [f32; N] = std::array::from_fn(|i| values[i % values.len()]);
            let b: [f32; N] = std::array::from_fn(|i| values[(i + shift) % values.len()]);
            let (max, min) = (
                L::from_array(a).fmax(L::from_array(b)).to_array(),
                L::from_array(a).fmin(L::from_array(b)).to_array(),
            );
            for i in 0..N {
                let (x, y) = (a[i], b[i]);
                assert_eq!(max[i].to_bits(), x.max(y).to_bits(), "max({x}, {y})");
                assert_eq!(min[i].to_bits(), x.min(y).to_bits(), "min({x}, {y})");
            }
        }
    }

    /// `transpose`'s lane `j` of result `k` is word `k` of row `j`.
    fn transpose_puts_row_j_in_lane_j<const N: usize, L: Lanes<N>>() {
        let rows: [[f32; 4]; N] =
            std::array::from_fn(|j| std::array::from_fn(|k| (10 * j + k) as f32));
        let t = L::transpose(std::array::from_fn(|j| &rows[j]));
        for (k, lanes) in t.iter().enumerate() {
            assert_eq!(
                lanes.to_array(),
                std::array::from_fn(|j| rows[j][k]),
                "word {k}"
            );
        }
    }

    #[test]
    fn sse_transpose_puts_row_j_in_lane_j() {
        transpose_puts_row_j_in_lane_j::<LANES, Sse>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx_transpose_puts_row_j_in_lane_j() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        #[target_feature(enable = "avx2")]
        fn with_avx() {
            transpose_puts_row_j_in_lane_j::<LANES, Avx>();
        }
        // SAFETY: AVX2 detected above.
        unsafe { with_avx() };
    }

    #[test]
    fn sse_min_max_follow_f32() {
        min_max_follow_f32::<LANES, Sse>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx_min_max_follow_f32() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        // The lanes' intrinsics run inside a function compiled for AVX2.
        #[target_feature(enable = "avx2")]
        fn with_avx() {
            min_max_follow_f32::<LANES, Avx>();
        }
        // SAFETY: AVX2 detected above.
        unsafe { with_avx() };
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_transpose_puts_row_j_in_lane_j() {
        if !std::arch::is_x86_feature_detected!("avx512f") {
            return;
        }
        #[target_feature(enable = "avx512f")]
        fn with_avx512() {
            transpose_puts_row_j_in_lane_j::<LANES_AVX512, Avx512>();
        }
        // SAFETY: AVX-512 F detected above.
        unsafe { with_avx512() };
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_min_max_follow_f32() {
        if !std::arch::is_x86_feature_detected!("avx512f") {
            return;
        }
        #[target_feature(enable = "avx512f")]
        fn with_avx512() {
            min_max_follow_f32::<LANES_AVX512, Avx512>();
        }
        // SAFETY: AVX-512 F detected above.
        unsafe { with_avx512() };
    }

    /// The masks' bits and picks, lane by lane: `from_bits` then `bits` gives the bits back,
    /// `pick` takes `a` exactly where the bit is set, and `and`, `or`, `not` are the bits'.
    fn masks_follow_their_bits<const N: usize, L: Lanes<N>>() {
        let a: [f32; N] = std::array::from_fn(|i| i as f32 + 0.5);
        let b: [f32; N] = std::array::from_fn(|i| -(i as f32) - 0.25);
        let all = if N == 32 { u32::MAX } else { (1u32 << N) - 1 };
        for (x, y) in [
            (0u32, 0u32),
            (all, 0),
            (0xa5a5_a5a5 & all, 0x0ff0_0ff0 & all),
            (1, 1 << (N - 1)),
        ] {
            let (mx, my) = (L::M::from_bits(x), L::M::from_bits(y));
            assert_eq!(mx.bits(), x);
            assert_eq!(mx.and(my).bits(), x & y);
            assert_eq!(mx.or(my).bits(), x | y);
            assert_eq!(mx.not().bits(), !x & all);
            let picked = mx.pick(L::from_array(a), L::from_array(b)).to_array();
            for i in 0..N {
                let want = if x >> i & 1 == 1 { a[i] } else { b[i] };
                assert_eq!(picked[i].to_bits(), want.to_bits(), "lane {i} of {x:#x}");
            }
            // A comparison's truths land in the lane's bit.
            assert_eq!(L::from_array(a).gt(L::splat(7.0)).bits(), all & !0x7f);
        }
    }

    #[test]
    fn sse_masks_follow_their_bits() {
        masks_follow_their_bits::<LANES, Sse>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx_masks_follow_their_bits() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        #[target_feature(enable = "avx2")]
        fn with_avx() {
            masks_follow_their_bits::<LANES, Avx>();
        }
        // SAFETY: AVX2 detected above.
        unsafe { with_avx() };
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_masks_follow_their_bits() {
        if !std::arch::is_x86_feature_detected!("avx512f") {
            return;
        }
        #[target_feature(enable = "avx512f")]
        fn with_avx512() {
            masks_follow_their_bits::<LANES_AVX512, Avx512>();
        }
        // SAFETY: AVX-512 F detected above.
        unsafe { with_avx512() };
    }
}
