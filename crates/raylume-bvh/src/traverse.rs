//! CPU traversal of the GPU layout: the reference that `traverse.wgsl` mirrors function for
//! function. [`trace_closest`] and [`trace_any`] are iterative, with a fixed
//! `[u32; MAX_STACK_DEPTH]` stack, nearer child first, leaves intersected in place (Aila &
//! Laine, *Understanding the Efficiency of Ray Traversal on GPUs*, HPG 2009); the primitive
//! tests are in [`crate::intersect`].

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::intersect::{
    AABB_T_FAR_SCALE, Ray, ShearedRay, T_MISS, intersect_aabb, intersect_primitive, shear_ray,
};
use crate::{BvhLayout, BvhNode, GpuBvh, INVALID_INDEX, MAX_STACK_DEPTH, Primitive};

/// Traversal clamps `t_max` to this (2^127) so that `t_max * AABB_T_FAR_SCALE` stays finite
/// and below [`T_MISS`]. WGSL: `T_MAX_LIMIT`.
pub const T_MAX_LIMIT: f32 = f32::from_bits(0x7f00_0000);

/// The closest (or any) hit of a ray.
///
/// `repr(C)`, `Pod`, 16 bytes. WGSL: `Hit`.
///
/// `prim` indexes [`GpuBvh::primitives`] (leaf order; the scene index is in the primitive);
/// `u`, `v` are the barycentric weights of a triangle's v1 and v2 (the hit point is
/// `(1 - u - v) v0 + u v1 + v v2`), 0 for spheres. From the free functions a miss is
/// `prim == INVALID_INDEX` with `t == min(t_max, T_MAX_LIMIT)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

const _: () = assert!(size_of::<Hit>() == 16);
const _: () = assert!(std::mem::offset_of!(Hit, prim) == 4);
const _: () = assert!(std::mem::offset_of!(Hit, v) == 12);

/// Intersects `primitives[first .. first + count]`, keeping the closest hit in `hit`; with
/// `any_hit`, returns true at the first hit (then `hit` holds it).
#[inline(always)]
fn intersect_leaf<const SPHERES: bool>(
    primitives: &[Primitive],
    ray: &ShearedRay,
    first: u32,
    count: u32,
    t_min: f32,
    hit: &mut Hit,
    any_hit: bool,
) -> bool {
    for i in first..first + count {
        let r = intersect_primitive::<SPHERES>(&primitives[i as usize], ray, t_min, hit.t);
        if r.x < hit.t {
            *hit = Hit {
                t: r.x,
                prim: i,
                u: r.y,
                v: r.z,
            };
            if any_hit {
                return true;
            }
        }
    }
    false
}

/// Both child slots of `node` tested against the ray: `(t_near, near index, near count,
/// t_far, far index, far count)`, nearer first; a missed or empty slot has `t == T_MISS`.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn order_children(
    node: &BvhNode,
    origin: Vec3,
    inv_dir: Vec3,
    t_min: f32,
    t_max: f32,
) -> (f32, u32, u32, f32, u32, u32) {
    let mut t_left = intersect_aabb(
        node.left_min.into(),
        node.left_max.into(),
        origin,
        inv_dir,
        t_min,
        t_max,
    );
    let mut t_right = intersect_aabb(
        node.right_min.into(),
        node.right_max.into(),
        origin,
        inv_dir,
        t_min,
        t_max,
    );
    if node.left_index == INVALID_INDEX {
        t_left = T_MISS;
    }
    if node.right_index == INVALID_INDEX {
        t_right = T_MISS;
    }
    if t_right < t_left {
        (
            t_right,
            node.right_index,
            node.right_count,
            t_left,
            node.left_index,
            node.left_count,
        )
    } else {
        (
            t_left,
            node.left_index,
            node.left_count,
            t_right,
            node.right_index,
            node.right_count,
        )
    }
}

/// The walk both queries share (obvhs' `traverse!` likewise takes the leaf test as a
/// parameter): the closest hit with `t_min < t < t_max` in the tree `nodes` over
/// `primitives`, or with `any_hit` the first one found; a miss has `prim == INVALID_INDEX` and
/// `t == min(t_max, T_MAX_LIMIT)`. `SPHERES`: as [`intersect_primitive`]'s.
///
/// At each node both child boxes are tested with the current closest `t`; hit leaves are
/// intersected at once (nearer first), and of the hit inner children the nearer is entered and
/// the farther pushed, each only if its entry distance is still within the (possibly shrunken)
/// closest `t`. The stack never holds more than `depth - 1` entries, which `validate` bounds by
/// `MAX_STACK_DEPTH`. (A box the slab test accepts has `t_near <= t_max * AABB_T_FAR_SCALE`,
/// a missed one `T_MISS`: for the any-hit walk, whose `t` stays `t_max` until it returns,
/// "within the closest `t`" is "not missed".)
#[inline(always)]
pub fn binary_walk<const SPHERES: bool>(
    nodes: &[BvhNode],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    any_hit: bool,
) -> Hit {
    let inv_dir = Vec3::ONE / ray.dir;
    let sheared = shear_ray(ray);
    let mut hit = Hit {
        t: t_max.min(T_MAX_LIMIT),
        prim: INVALID_INDEX,
        u: 0.0,
        v: 0.0,
    };
    let mut stack = [0u32; MAX_STACK_DEPTH];
    let mut sp = 0usize;
    let mut node_index = 0u32;
    loop {
        let node = &nodes[node_index as usize];
        let (t_near, near_index, near_count, t_far, far_index, far_count) =
            order_children(node, ray.origin, inv_dir, t_min, hit.t);
        if near_count > 0
            && t_near <= hit.t * AABB_T_FAR_SCALE
            && intersect_leaf::<SPHERES>(
                primitives, &sheared, near_index, near_count, t_min, &mut hit, any_hit,
            )
        {
            return hit;
        }
        if far_count > 0
            && t_far <= hit.t * AABB_T_FAR_SCALE
            && intersect_leaf::<SPHERES>(
                primitives, &sheared, far_index, far_count, t_min, &mut hit, any_hit,
            )
        {
            return hit;
        }
        let go_near = near_count == 0 && t_near <= hit.t * AABB_T_FAR_SCALE;
        let go_far = far_count == 0 && t_far <= hit.t * AABB_T_FAR_SCALE;
        if go_near {
            if go_far {
                debug_assert!(sp < MAX_STACK_DEPTH);
                stack[sp] = far_index;
                sp += 1;
            }
            node_index = near_index;
        } else if go_far {
            node_index = far_index;
        } else if sp > 0 {
            sp -= 1;
            node_index = stack[sp];
        } else {
            break;
        }
    }
    hit
}

/// The closest hit with `t_min < t < t_max` in the tree `nodes` over `primitives`, or a miss
/// (`prim == INVALID_INDEX`): [`binary_walk`].
pub fn trace_closest(
    nodes: &[BvhNode],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
) -> Hit {
    binary_walk::<true>(nodes, primitives, ray, t_min, t_max, false)
}

/// True if anything is hit with `t_min < t < t_max`: [`binary_walk`] returning at the first
/// primitive hit (a shadow ray).
pub fn trace_any(
    nodes: &[BvhNode],
    primitives: &[Primitive],
    ray: &Ray,
    t_min: f32,
    t_max: f32,
) -> bool {
    binary_walk::<true>(nodes, primitives, ray, t_min, t_max, true).prim != INVALID_INDEX
}

impl GpuBvh {
    /// The closest hit with `t_min < t < t_max`, if any, in whichever layout the tree has. See
    /// [`trace_closest`] and [`wide_traverse::trace_closest`](crate::wide_traverse::trace_closest).
    #[inline]
    pub fn trace_closest(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        self.trace_closest_for::<true>(ray, t_min, t_max)
    }

    /// True if anything is hit with `t_min < t < t_max`. See [`trace_any`] and
    /// [`wide_traverse::trace_any`](crate::wide_traverse::trace_any).
    #[inline]
    pub fn trace_any(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.trace_any_for::<true>(ray, t_min, t_max)
    }

    /// [`GpuBvh::trace_closest`] with the sphere test compiled in only when `SPHERES` (see
    /// [`intersect_primitive`]): `false` only for a tree without spheres.
    #[inline(always)]
    pub fn trace_closest_for<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        // SAFETY: without AVX2 the walk runs on any CPU.
        let hit = unsafe { self.walk::<SPHERES, false, false>(ray, t_min, t_max, false, false) };
        (hit.prim != INVALID_INDEX).then_some(hit)
    }

    /// [`GpuBvh::trace_any`] with the sphere test compiled in only when `SPHERES`.
    #[inline(always)]
    pub fn trace_any_for<const SPHERES: bool>(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        // SAFETY: without AVX2 the walk runs on any CPU.
        unsafe { self.walk::<SPHERES, false, false>(ray, t_min, t_max, true, false) }.prim
            != INVALID_INDEX
    }

    /// The walk of the tree's layout ([`binary_walk`] or the wide one, `GpuBvh::wide_walk`),
    /// with `AVX2` the wide one's node and triangle tests in AVX registers, with `AVX512` a
    /// small tree's flat test sixteen lanes at a time.
    ///
    /// # Safety
    /// With `AVX2`, the CPU must have AVX2, with `AVX512` AVX-512 F too (without, none).
    #[inline(always)]
    unsafe fn walk<const SPHERES: bool, const AVX2: bool, const AVX512: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        any_hit: bool,
        between: bool,
    ) -> Hit {
        match self.layout {
            BvhLayout::Binary => {
                binary_walk::<SPHERES>(&self.nodes, &self.primitives, ray, t_min, t_max, any_hit)
            }
            // SAFETY: the caller's CPU has AVX2 where `AVX2` is set.
            BvhLayout::Wide => unsafe {
                self.wide_walk::<SPHERES, AVX2, AVX512>(ray, t_min, t_max, any_hit, between)
            },
        }
    }

    /// [`GpuBvh::trace_closest_for`] with a wide tree's node and triangle tests eight lanes at
    /// a time in AVX registers (the crate's `wide_avx2` module); the same hit, bit for bit (a binary
    /// tree walks as there). Fast where inlined into a function compiled with AVX2 (e.g.
    /// raylume-kernels' x86-64-v3/v4 copies of its CPU path).
    ///
    /// # Safety
    /// The CPU must have AVX2 (`is_x86_feature_detected!("avx2")`).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn trace_closest_avx2<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        // SAFETY: the caller's CPU has AVX2.
        let hit = unsafe { self.walk::<SPHERES, true, false>(ray, t_min, t_max, false, false) };
        (hit.prim != INVALID_INDEX).then_some(hit)
    }

    /// [`GpuBvh::trace_any_for`] as [`GpuBvh::trace_closest_avx2`] walks: the same answer.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn trace_any_avx2<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> bool {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { self.walk::<SPHERES, true, false>(ray, t_min, t_max, true, false) }.prim
            != INVALID_INDEX
    }

    /// [`GpuBvh::trace_closest_avx2`] where the CPU has AVX-512 too: a tree of at most
    /// [`FLAT_MAX_PRIMITIVES`](crate::FLAT_MAX_PRIMITIVES) triangles tested sixteen at a
    /// time instead of eight, in blocks grouped by where they lie, a block passed over where
    /// the ray enters its box beyond the closest hit found so far; the same hit, bit for bit. Fast where inlined into a function
    /// compiled with AVX-512 (raylume-kernels' x86-64-v4 copies of its CPU path).
    ///
    /// # Safety
    /// The CPU must have AVX2 and AVX-512 F (`is_x86_feature_detected!("avx512f")`).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn trace_closest_avx512<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        // SAFETY: the caller's CPU has AVX2 and AVX-512 F.
        let hit = unsafe { self.walk::<SPHERES, true, true>(ray, t_min, t_max, false, false) };
        (hit.prim != INVALID_INDEX).then_some(hit)
    }

    /// [`GpuBvh::trace_any_avx2`] for a segment between two points of the tree's primitives
    /// (a shadow ray from a surface toward a point of a lamp: `ray.at(t_max)` and the origin
    /// each within the convex hull of the primitives' vertices, up to the rounding of a
    /// surface point's offset and of `t_max`'s margin): where the tree is tested flat, the
    /// faces of that hull (triangles with every vertex on one side of their plane: walls of a
    /// room, a box's bottom on its floor) are left out, since such a segment meets their
    /// plane at an end only. The same answer as [`GpuBvh::trace_any_avx2`] except where that
    /// finds a hull face within rounding of the segment's origin (an origin in a corner, on
    /// another wall's plane): a rounding artifact at `t <= 0`, the kind of self-intersection
    /// the origin's offset exists to prevent, which this answer leaves out (1 of the 40,000
    /// segments of `flat_between_answers_the_any_hit_test`, a third of them from within 1e-5
    /// of an edge; none in a render of Bitterli's Cornell box, 1000x1000 10 spp, whose PNG is
    /// the same).
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn trace_any_between_avx2<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> bool {
        // SAFETY: the caller's CPU has AVX2.
        unsafe { self.walk::<SPHERES, true, false>(ray, t_min, t_max, true, true) }.prim
            != INVALID_INDEX
    }

    /// [`GpuBvh::trace_any_between_avx2`] as [`GpuBvh::trace_closest_avx512`] walks: the same
    /// answers (both leave out the same faces).
    ///
    /// # Safety
    /// The CPU must have AVX2 and AVX-512 F.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn trace_any_between_avx512<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> bool {
        // SAFETY: the caller's CPU has AVX2 and AVX-512 F.
        unsafe { self.walk::<SPHERES, true, true>(ray, t_min, t_max, true, true) }.prim
            != INVALID_INDEX
    }

    /// [`GpuBvh::trace_any_avx2`] as [`GpuBvh::trace_closest_avx512`] walks: the same answer.
    ///
    /// # Safety
    /// The CPU must have AVX2 and AVX-512 F.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub unsafe fn trace_any_avx512<const SPHERES: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> bool {
        // SAFETY: the caller's CPU has AVX2 and AVX-512 F.
        unsafe { self.walk::<SPHERES, true, true>(ray, t_min, t_max, true, false) }.prim
            != INVALID_INDEX
    }
}
