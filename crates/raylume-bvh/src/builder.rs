//! [`GpuBvh::build`]: input checks, obvhs' PLOC build (with spatial pre-splits of triangles
//! for [`BvhQuality::Quality`]), SAH reinsertion and leaf collapse, flattening, and the depth
//! fallback.

use std::borrow::Cow;
use std::time::{Duration, Instant};

use glam::Vec3A;
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::{Bvh2, leaf_collapser::collapse, reinsertion::ReinsertionOptimizer},
    ploc::PlocBuilder,
    splits::split_aabbs_preset,
    triangle::Triangle as ObvhsTriangle,
};
use raylume_scene::{Scene, Sphere, Triangle};
use rayon::prelude::*;

use crate::bounds::Source;
use crate::flatten::{Flat, flatten};
use crate::median::{LEAF_SIZE, build_median};
use crate::stats::{BvhStats, Fallback};
use crate::wide::{WideFlat, to_wide, wide_stats};
use crate::{
    BvhError, BvhLayout, BvhQuality, GpuBvh, INVALID_INDEX, MAX_STACK_DEPTH, Primitive,
    WIDE_STACK_SIZE,
};

/// The largest count a `u32` index may address: `u32::MAX` is [`INVALID_INDEX`].
const MAX_U32_COUNT: usize = INVALID_INDEX as usize;

impl GpuBvh {
    /// Builds one BVH over a scene's triangles and spheres.
    pub fn from_scene(scene: &Scene, quality: BvhQuality) -> Result<GpuBvh, BvhError> {
        GpuBvh::build(&scene.triangles, &scene.spheres, quality)
    }

    /// [`GpuBvh::from_scene`] in a chosen [`BvhLayout`].
    pub fn from_scene_with_layout(
        scene: &Scene,
        quality: BvhQuality,
        layout: BvhLayout,
    ) -> Result<GpuBvh, BvhError> {
        GpuBvh::build_with_layout(&scene.triangles, &scene.spheres, quality, layout)
    }

    /// Builds one BVH over `triangles` and `spheres` together and flattens it into the GPU
    /// layout.
    ///
    /// Primitive `i` of the result is a copy of `triangles[k]` or `spheres[k]` (its kind and
    /// `k` are stored in it); with [`BvhQuality::Quality`] a large triangle may be copied into
    /// several leaves. Zero primitives give a root with two empty slots; one primitive, a root
    /// whose left slot is a one-primitive leaf.
    ///
    /// Should the preset's tree be deeper than [`MAX_STACK_DEPTH`], or the input hold more
    /// than [`MAX_STACK_DEPTH`] coincident primitives (on which PLOC builds a chain, slowly),
    /// the builder falls back to balanced object-median splits and says so in
    /// [`BvhStats::fallback`].
    ///
    /// The tree is in [`BvhLayout::default`]; [`GpuBvh::build_with_layout`] chooses.
    pub fn build(
        triangles: &[Triangle],
        spheres: &[Sphere],
        quality: BvhQuality,
    ) -> Result<GpuBvh, BvhError> {
        GpuBvh::build_with_layout(triangles, spheres, quality, BvhLayout::default())
    }

    /// [`GpuBvh::build`] in a chosen [`BvhLayout`]. Both layouts come from the same build
    /// (PLOC, SAH reinsertion, pre-splits for `Quality`); [`BvhLayout::Binary`] then collapses
    /// leaves by SAH and reinserts again, [`BvhLayout::Wide`] hands the one-primitive-leaf
    /// tree to obvhs' eight-wide converter. A wide tree deeper than [`WIDE_STACK_SIZE`] falls
    /// back to the balanced median build as a binary one deeper than [`MAX_STACK_DEPTH`] does.
    pub fn build_with_layout(
        triangles: &[Triangle],
        spheres: &[Sphere],
        quality: BvhQuality,
        layout: BvhLayout,
    ) -> Result<GpuBvh, BvhError> {
        GpuBvh::build_profiled(triangles, spheres, quality, quality.params(), layout)
            .map(|(bvh, _)| bvh)
    }

    /// [`GpuBvh::build`] with any obvhs parameters, for measuring presets against each other
    /// (the crate's bench); `quality` only labels the stats.
    #[doc(hidden)]
    pub fn build_with_params(
        triangles: &[Triangle],
        spheres: &[Sphere],
        quality: BvhQuality,
        params: BvhBuildParams,
    ) -> Result<GpuBvh, BvhError> {
        GpuBvh::build_profiled(triangles, spheres, quality, params, BvhLayout::default())
            .map(|(bvh, _)| bvh)
    }

    /// [`GpuBvh::build_with_params`], also returning the wall time of each stage (the
    /// crate's `benches/build.rs`).
    #[doc(hidden)]
    pub fn build_profiled(
        triangles: &[Triangle],
        spheres: &[Sphere],
        quality: BvhQuality,
        params: BvhBuildParams,
        layout: BvhLayout,
    ) -> Result<(GpuBvh, BuildProfile), BvhError> {
        let start = Instant::now();
        let mut profile = BuildProfile::default();
        let mut lap = Lap(Instant::now());
        check_input(triangles, spheres)?;
        let source = Source { triangles, spheres };
        // The linear BVH reads each box where it needs it (no 96 MB array at 3M triangles);
        // PLOC, the pre-splits and the coincident check read them as one slice.
        let lbvh = builds_lbvh(quality, params);
        let aabbs: Vec<Aabb> = if lbvh { Vec::new() } else { source.aabbs() };
        for k in 0..spheres.len() {
            let b = source.aabb((triangles.len() + k) as u32);
            if !(b.min.is_finite() && b.max.is_finite()) {
                return Err(BvhError::NonFinite {
                    kind: "sphere",
                    index: k,
                    detail: format!("its bounds {:?}..{:?} overflow f32", b.min, b.max),
                });
            }
        }

        profile.prepare = lap.next();

        // The linear BVH breaks ties between equal Morton codes by index, so coincident boxes
        // give it a balanced subtree, not PLOC's chain: it needs no check (3M triangles: a
        // 24 MB sort skipped); the depth checks after the build still stand.
        let coincident = if lbvh {
            0
        } else {
            largest_coincident_group(&aabbs)
        };
        profile.coincident_check = lap.next();
        if layout == BvhLayout::Wide {
            return build_wide(
                source, aabbs, coincident, quality, params, profile, lap, start,
            );
        }
        let mut fallback = None;
        let mut flat = if coincident > MAX_COINCIDENT {
            fallback = Some(Fallback::CoincidentBoxes { count: coincident });
            flatten(&build_median(&aabbs, LEAF_SIZE), source)
        } else {
            match build_obvhs(
                source,
                &aabbs,
                params,
                quality,
                true,
                &mut profile,
                &mut lap,
            )? {
                Ok(bvh2) => {
                    let flat = flatten(&bvh2, source);
                    profile.flatten = lap.next();
                    flat
                }
                Err(depth) => {
                    fallback = Some(Fallback::TooDeep { depth });
                    flatten(&build_median(&source.boxes(&aabbs), LEAF_SIZE), source)
                }
            }
        };
        if fallback.is_none() && flat.max_depth > MAX_STACK_DEPTH {
            fallback = Some(Fallback::TooDeep {
                depth: flat.max_depth,
            });
            flat = flatten(&build_median(&source.boxes(&aabbs), LEAF_SIZE), source);
        }
        BvhError::check_depth(flat.max_depth)?;
        check_output(&flat)?;

        let Flat {
            nodes,
            primitives,
            max_depth,
        } = flat;
        let mut bvh = GpuBvh {
            layout: BvhLayout::Binary,
            nodes,
            wide_nodes: Vec::new(),
            primitives,
            triangle_count: triangles.len() as u32,
            sphere_count: spheres.len() as u32,
            stats: BvhStats::default(),
            cpu_arrays: Default::default(),
        };
        lap.next();
        bvh.stats = BvhStats::measure(&bvh, quality, max_depth, fallback, start);
        profile.stats = lap.next();
        Ok((bvh, profile))
    }
}

/// The wide layout's half of [`GpuBvh::build_profiled`]: the binary build without its leaf
/// collapse, converted; the median fallback (one primitive a leaf) for coincident boxes, a
/// PLOC chain, or a wide tree deeper than [`WIDE_STACK_SIZE`].
#[allow(clippy::too_many_arguments)]
fn build_wide(
    source: Source,
    aabbs: Vec<Aabb>,
    coincident: usize,
    quality: BvhQuality,
    params: BvhBuildParams,
    mut profile: BuildProfile,
    mut lap: Lap,
    start: Instant,
) -> Result<(GpuBvh, BuildProfile), BvhError> {
    // The boxes are dropped as soon as the tree is built (a large scene's peak memory is the
    // conversion's); the median fallback after a too-deep conversion makes them again.
    let median = |aabbs: &[Aabb]| to_wide(build_median(&source.boxes(aabbs), 1), source);
    let mut fallback = None;
    let mut flat = if coincident > MAX_COINCIDENT {
        fallback = Some(Fallback::CoincidentBoxes { count: coincident });
        median(&aabbs)
    } else {
        match build_obvhs(
            source,
            &aabbs,
            params,
            quality,
            false,
            &mut profile,
            &mut lap,
        )? {
            Ok(bvh2) => {
                drop(aabbs);
                let flat = to_wide(bvh2, source);
                profile.flatten = lap.next();
                flat
            }
            Err(depth) => {
                fallback = Some(Fallback::TooDeep { depth });
                median(&aabbs)
            }
        }
    };
    if fallback.is_none() && flat.max_depth > WIDE_STACK_SIZE {
        fallback = Some(Fallback::TooDeep {
            depth: flat.max_depth,
        });
        flat = median(&[]);
    }
    if flat.max_depth > WIDE_STACK_SIZE {
        return Err(BvhError::TooDeep {
            depth: flat.max_depth,
            max: WIDE_STACK_SIZE,
        });
    }
    let WideFlat {
        nodes,
        primitives,
        max_depth,
    } = flat;
    for (what, count) in [
        ("primitives (after spatial splits)", primitives.len()),
        ("nodes", nodes.len()),
    ] {
        if count > MAX_U32_COUNT {
            return Err(BvhError::TooManyPrimitives {
                what,
                count,
                limit: MAX_U32_COUNT,
            });
        }
    }
    lap.next();
    let (leaf_count, max_leaf_size, sah_cost) = wide_stats(&nodes);
    let stats = BvhStats {
        quality,
        fallback,
        node_count: nodes.len(),
        leaf_count,
        max_depth,
        max_leaf_size,
        primitive_refs: primitives.len(),
        sah_cost,
        build_time: start.elapsed(),
    };
    profile.stats = lap.next();
    Ok((
        GpuBvh {
            layout: BvhLayout::Wide,
            nodes: Vec::new(),
            wide_nodes: nodes,
            primitives,
            triangle_count: source.triangles.len() as u32,
            sphere_count: source.spheres.len() as u32,
            stats,
            cpu_arrays: Default::default(),
        },
        profile,
    ))
}

/// Wall time of each stage of one [`GpuBvh::build_profiled`]; stages that did not run are
/// zero. The median fallback is in no stage (only in the total, [`BvhStats::build_time`]).
#[doc(hidden)]
#[derive(Clone, Copy, Debug, Default)]
pub struct BuildProfile {
    /// Input checks, primitive copies, their boxes.
    pub prepare: Duration,
    /// The sort for coincident boxes.
    pub coincident_check: Duration,
    /// Spatial pre-splits (Quality only), with the copies they need.
    pub pre_split: Duration,
    /// obvhs' PLOC build.
    pub ploc: Duration,
    /// The PLOC tree's depth check.
    pub depth_check: Duration,
    /// SAH reinsertion before the leaf collapse.
    pub reinsertion: Duration,
    /// SAH leaf collapse.
    pub collapse: Duration,
    /// SAH reinsertion after the leaf collapse.
    pub reinsertion_after_collapse: Duration,
    /// obvhs' `Bvh2` to the GPU layout.
    pub flatten: Duration,
    /// [`BvhStats::measure`] (SAH cost and counts).
    pub stats: Duration,
}

/// Successive laps of a stopwatch.
struct Lap(Instant);

impl Lap {
    /// Time since the last call (or the start).
    fn next(&mut self) -> Duration {
        let now = Instant::now();
        let d = now - self.0;
        self.0 = now;
        d
    }
}

/// Counts that fit `u32` indices, finite coordinates, positive radii.
fn check_input(triangles: &[Triangle], spheres: &[Sphere]) -> Result<(), BvhError> {
    for (what, count) in [("triangles", triangles.len()), ("spheres", spheres.len())] {
        if count > MAX_U32_COUNT {
            return Err(BvhError::TooManyPrimitives {
                what,
                count,
                limit: MAX_U32_COUNT,
            });
        }
    }
    let total = triangles.len() + spheres.len();
    if total > MAX_U32_COUNT {
        return Err(BvhError::TooManyPrimitives {
            what: "primitives",
            count: total,
            limit: MAX_U32_COUNT,
        });
    }
    // The first bad triangle, found on every core.
    if let Some((index, v)) = triangles.par_iter().enumerate().find_map_first(|(i, t)| {
        t.positions
            .iter()
            .position(|p| !p.is_finite())
            .map(|v| (i, v))
    }) {
        return Err(BvhError::NonFinite {
            kind: "triangle",
            index,
            detail: format!("vertex {v} is {}", triangles[index].positions[v]),
        });
    }
    for (index, s) in spheres.iter().enumerate() {
        if !(s.center.is_finite() && s.radius.is_finite()) {
            return Err(BvhError::NonFinite {
                kind: "sphere",
                index,
                detail: format!("centre {}, radius {}", s.center, s.radius),
            });
        }
        if s.radius <= 0.0 {
            return Err(BvhError::BadRadius {
                index,
                radius: s.radius,
            });
        }
    }
    Ok(())
}

impl GpuBvh {
    /// The input of a build on the GPU ([`crate::lbvh`]; `raylume_kernels::gpu::LbvhBuilder`):
    /// `triangles` checked as [`GpuBvh::build`] checks them, as [`Primitive`]s in scene order.
    pub fn lbvh_input(triangles: &[Triangle]) -> Result<Vec<Primitive>, BvhError> {
        Self::check_triangles(triangles)?;
        let mut source = Vec::with_capacity(triangles.len());
        source.par_extend(
            triangles
                .par_iter()
                .enumerate()
                .map(|(i, t)| Primitive::triangle(t.positions.map(|p| p.to_array()), i as u32)),
        );
        Ok(source)
    }

    /// The checks [`GpuBvh::build`] runs on `triangles` (a scene of no spheres): at most
    /// `u32::MAX - 1`, every vertex finite.
    pub fn check_triangles(triangles: &[Triangle]) -> Result<(), BvhError> {
        check_input(triangles, &[])
    }

    /// The binary tree of an LBVH ([`crate::lbvh::lbvh_binary`], or the GPU build's read
    /// back) over `source` (scene-order triangles, [`GpuBvh::lbvh_input`]), its primitives put
    /// in leaf order; the build began at `start`. A tree deeper than the traversal's stack is
    /// [`BvhError::TooDeep`].
    pub fn from_lbvh(
        tree: crate::lbvh::LbvhTree,
        source: &[Primitive],
        start: Instant,
    ) -> Result<GpuBvh, BvhError> {
        BvhError::check_depth(tree.max_depth)?;
        let mut bvh = GpuBvh {
            nodes: tree.nodes,
            ..GpuBvh::lbvh_leaves(&tree.order, source)?
        };
        bvh.stats = BvhStats::of_lbvh(&bvh, tree.max_depth, start);
        Ok(bvh)
    }

    /// `source` (scene-order triangles) in an LBVH's leaf `order`, as a binary-layout
    /// [`GpuBvh`] without nodes yet.
    fn lbvh_leaves(order: &[u32], source: &[Primitive]) -> Result<GpuBvh, BvhError> {
        if order.len() != source.len() {
            return Err(BvhError::Inconsistent(format!(
                "an LBVH order of {} primitives over {}",
                order.len(),
                source.len()
            )));
        }
        if let Some(&i) = order.par_iter().find_any(|&&i| i as usize >= source.len()) {
            return Err(BvhError::Inconsistent(format!(
                "an LBVH order naming primitive {i} of {}",
                source.len()
            )));
        }
        let mut primitives = Vec::with_capacity(source.len());
        primitives.par_extend(order.par_iter().map(|&i| source[i as usize]));
        Ok(GpuBvh {
            layout: BvhLayout::Binary,
            nodes: Vec::new(),
            wide_nodes: Vec::new(),
            primitives,
            triangle_count: source.len() as u32,
            sphere_count: 0,
            stats: BvhStats::default(),
            cpu_arrays: Default::default(),
        })
    }
}

/// Primitive copies and nodes must stay addressable by `u32`.
fn check_output(flat: &Flat) -> Result<(), BvhError> {
    if flat.primitives.len() > MAX_U32_COUNT {
        return Err(BvhError::TooManyPrimitives {
            what: "primitives (after spatial splits)",
            count: flat.primitives.len(),
            limit: MAX_U32_COUNT,
        });
    }
    if flat.nodes.len() > MAX_U32_COUNT {
        return Err(BvhError::TooManyPrimitives {
            what: "nodes",
            count: flat.nodes.len(),
            limit: MAX_U32_COUNT,
        });
    }
    Ok(())
}

/// A PLOC tree deeper than this (in obvhs' count, leaves included) is abandoned before the
/// SAH passes: collapsing leaves removes at most 3 levels and reinsertion optimises cost, not
/// depth, so it would end far past [`MAX_STACK_DEPTH`], and reinsertion over a chain of
/// thousands of nodes is quadratic (seconds for 5000 coincident triangles).
const ABANDON_PLOC_DEPTH: usize = 2 * MAX_STACK_DEPTH;

/// obvhs' `build_bvh2_from_tris`, generalised to triangles followed by spheres: `aabbs[i]`
/// bounds primitive `i`, the first `triangles.len()` of them triangles. Only triangles are
/// pre-split (the splitter clips a triangle's polygon; a sphere has none). Calls the stages
/// directly rather than through `build_bvh2`, whose debug-build self-check panics where this
/// crate wants typed errors and its own `validate`.
///
/// The inner `Err(depth)`: the PLOC tree is `depth` deep, past [`ABANDON_PLOC_DEPTH`].
fn build_obvhs(
    source: Source,
    aabbs: &[Aabb],
    params: BvhBuildParams,
    quality: BvhQuality,
    collapse_leaves: bool,
    profile: &mut BuildProfile,
    lap: &mut Lap,
) -> Result<Result<Bvh2, usize>, BvhError> {
    // `Fastest` builds the linear BVH (`lbvh.rs`), which runs on every core and reads the
    // boxes from `source` (`aabbs` is empty then); the other presets obvhs' PLOC.
    let mut bvh2 = if builds_lbvh(quality, params) {
        profile.pre_split = lap.next();
        crate::lbvh::build_lbvh_with(source.len(), |i| source.aabb(i))
    } else {
        ploc(source.triangles, aabbs, params, profile, lap)?
    };
    bvh2.uses_spatial_splits = params.pre_split;
    profile.ploc = lap.next();
    // obvhs records a bound on the PLOC tree's depth (its merge rounds plus one, at least
    // 96: `Bvh2::max_depth`); walk the tree only when that bound is past the threshold.
    if bvh2.max_depth > ABANDON_PLOC_DEPTH {
        let depth = tree_depth(&bvh2);
        if depth > ABANDON_PLOC_DEPTH {
            return Ok(Err(depth));
        }
    }
    profile.depth_check = lap.next();
    let mut reinsertion = ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh2, params.reinsertion_batch_ratio, None);
    profile.reinsertion = lap.next();
    if !collapse_leaves {
        return Ok(Ok(bvh2));
    }
    collapse(
        &mut bvh2,
        params.max_prims_per_leaf.clamp(1, 255),
        params.collapse_traversal_cost,
    );
    profile.collapse = lap.next();
    reinsertion.run(
        &mut bvh2,
        params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
        None,
    );
    profile.reinsertion_after_collapse = lap.next();
    Ok(Ok(bvh2))
}

/// obvhs' PLOC over `aabbs` (the triangles' boxes, then the spheres'), after spatial
/// pre-splits of the triangles when `params` ask for them.
fn ploc(
    triangles: &[Triangle],
    aabbs: &[Aabb],
    params: BvhBuildParams,
    profile: &mut BuildProfile,
    lap: &mut Lap,
) -> Result<Bvh2, BvhError> {
    let n_tri = triangles.len();
    let (boxes, indices) = if params.pre_split && n_tri > 0 {
        let tris: Vec<ObvhsTriangle> = triangles
            .iter()
            .map(|t| ObvhsTriangle {
                v0: Vec3A::from(t.positions[0]),
                v1: Vec3A::from(t.positions[1]),
                v2: Vec3A::from(t.positions[2]),
            })
            .collect();
        let (mut largest, mut sum) = (0.0f32, 0.0f64);
        for b in &aabbs[..n_tri] {
            let a = b.half_area();
            largest = largest.max(a);
            sum += f64::from(a);
        }
        let average = (sum / n_tri as f64) as f32;
        // The splitter looks every box up in `tris`, so it gets the triangles' boxes alone;
        // the pieces it appends go after the spheres. obvhs needs `indices[i] == i` for every
        // primitive (PLOC leaves store the primitive id where collapse later reads a slot).
        let mut boxes = Vec::with_capacity(aabbs.len());
        boxes.extend_from_slice(&aabbs[..n_tri]);
        let mut indices: Vec<u32> = (0..n_tri as u32).collect();
        split_aabbs_preset(&mut boxes, &mut indices, &tris, average, largest);
        if aabbs.len() > n_tri {
            let pieces = boxes.split_off(n_tri);
            let piece_indices = indices.split_off(n_tri);
            boxes.extend_from_slice(&aabbs[n_tri..]);
            indices.extend(n_tri as u32..aabbs.len() as u32);
            boxes.extend_from_slice(&pieces);
            indices.extend_from_slice(&piece_indices);
        }
        (Cow::Owned(boxes), indices)
    } else {
        (Cow::Borrowed(aabbs), (0..aabbs.len() as u32).collect())
    };
    profile.pre_split = lap.next();
    if boxes.len() > MAX_U32_COUNT {
        return Err(BvhError::TooManyPrimitives {
            what: "primitives (after spatial splits)",
            count: boxes.len(),
            limit: MAX_U32_COUNT,
        });
    }

    Ok(PlocBuilder::with_capacity(boxes.len()).build(
        params.ploc_search_distance,
        &boxes,
        indices,
        params.sort_precision,
        params.search_depth_threshold,
    ))
}

/// Whether the build is the linear BVH's (`Fastest` without pre-splits) rather than PLOC's.
fn builds_lbvh(quality: BvhQuality, params: BvhBuildParams) -> bool {
    quality == BvhQuality::Fastest && !params.pre_split
}

/// More bit-identical primitive boxes than this and the builder goes straight to the median
/// fallback. PLOC pairs each cluster with its nearest neighbour, and among equal boxes every
/// distance ties: measured, n coincident triangles cluster into a chain n deep, in time
/// quadratic in n (0.4 s for 5000, 9 s for 20,000 with the Fast preset), and the chain is
/// deeper than the stack anyway once n passes [`MAX_STACK_DEPTH`].
const MAX_COINCIDENT: usize = MAX_STACK_DEPTH;

/// The size of the largest group of bit-identical boxes, exact when it is past
/// [`MAX_COINCIDENT`]; at most [`MAX_COINCIDENT`], an upper bound of it.
///
/// Groups are first counted by a 64-bit hash of the box (one sort of `u64`s: 65 ms at 3M
/// triangles on the 2-core machine, where sorting the boxes' 24 bytes took 200 ms); equal
/// boxes hash alike, so no group is missed, and only when a hash group is past
/// [`MAX_COINCIDENT`] are the boxes themselves sorted and compared.
fn largest_coincident_group(aabbs: &[Aabb]) -> usize {
    let bits = |b: &Aabb| {
        let (lo, hi) = (b.min.to_array(), b.max.to_array());
        [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits)
    };
    let mut hashes: Vec<u64> = aabbs
        .par_iter()
        .map(|b| {
            let h = bits(b).iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
                (h ^ u64::from(x)).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            });
            h ^ (h >> 29)
        })
        .collect();
    hashes.par_sort_unstable();
    let bound = hashes
        .chunk_by(|a, b| a == b)
        .map(<[_]>::len)
        .max()
        .unwrap_or(0);
    drop(hashes);
    if bound <= MAX_COINCIDENT {
        return bound;
    }
    let mut keys: Vec<[u32; 6]> = aabbs.iter().map(bits).collect();
    keys.sort_unstable();
    keys.chunk_by(|a, b| a == b)
        .map(<[_]>::len)
        .max()
        .unwrap_or(0)
}

/// Nodes on the longest root-to-leaf path of an obvhs tree (0 for an empty one).
fn tree_depth(bvh: &Bvh2) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((id, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        let n = &bvh.nodes[id];
        if !n.is_leaf() {
            stack.push((n.first_index as usize, depth + 1));
            stack.push((n.first_index as usize + 1, depth + 1));
        }
    }
    deepest
}
