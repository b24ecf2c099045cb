//! [`BvhStats`]: what a build produced and what it cost.

use std::time::{Duration, Instant};

use obvhs::aabb::Aabb;

use crate::bounds::half_area;
use crate::{BvhQuality, GpuBvh, INVALID_INDEX};

/// Cost of fetching one node and testing its two child boxes, in the SAH cost below.
pub const SAH_NODE_COST: f32 = 1.0;
/// Cost of one primitive test, in the SAH cost below.
pub const SAH_PRIMITIVE_COST: f32 = 1.0;

/// Why a build used the median-split fallback instead of the preset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fallback {
    /// The preset's tree was `depth` nodes deep, more than
    /// [`MAX_STACK_DEPTH`](crate::MAX_STACK_DEPTH). (For a PLOC tree abandoned before its SAH
    /// passes, counted as obvhs does, leaves as nodes.)
    TooDeep { depth: usize },
    /// `count` primitives had bit-identical boxes, more than
    /// [`MAX_STACK_DEPTH`](crate::MAX_STACK_DEPTH); PLOC would have chained them. (Never
    /// for the linear BVH, [`BvhQuality::Fastest`](crate::BvhQuality::Fastest) without
    /// pre-splits: it splits equal boxes by index, into a balanced subtree.)
    CoincidentBoxes { count: usize },
}

/// Measurements of one build.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// The preset asked for.
    pub quality: BvhQuality,
    /// `Some` when the preset's tree was replaced by the balanced median-split fallback, and
    /// why.
    pub fallback: Option<Fallback>,
    /// [`BvhNode`](crate::BvhNode)s (inner nodes; leaves live in their parents' slots).
    pub node_count: usize,
    /// Non-empty leaf slots.
    pub leaf_count: usize,
    /// Nodes on the longest root-to-leaf path, the root counting 1. Traversal pushes at most
    /// `max_depth - 1` entries.
    pub max_depth: usize,
    /// Most primitives in one leaf.
    pub max_leaf_size: usize,
    /// Entries of `primitives`: the scene's primitive count plus the copies made by spatial
    /// splits.
    pub primitive_refs: usize,
    /// Expected cost of a random ray that hits the root box, by the surface area heuristic
    /// (MacDonald & Booth 1990): every node weighs [`SAH_NODE_COST`] and every leaf
    /// `count * SAH_PRIMITIVE_COST`, each times its box's area over the root's. Comparable
    /// between builds of one scene, not between scenes.
    pub sah_cost: f32,
    /// Wall time of [`GpuBvh::build`], from input checks to the flattened tree.
    pub build_time: Duration,
}

fn slot_area(min: [f32; 3], max: [f32; 3]) -> f32 {
    half_area(&Aabb::new(min.into(), max.into()))
}

impl BvhStats {
    /// The stats of a binary LBVH (`GpuBvh::from_lbvh`, or one built on the GPU and read
    /// back) `max_depth` deep, whose build began at `start`.
    pub fn of_lbvh(bvh: &GpuBvh, max_depth: usize, start: Instant) -> BvhStats {
        Self::measure(bvh, BvhQuality::Fastest, max_depth, None, start)
    }

    pub(crate) fn measure(
        bvh: &GpuBvh,
        quality: BvhQuality,
        max_depth: usize,
        fallback: Option<Fallback>,
        start: Instant,
    ) -> BvhStats {
        let mut root_area = 0.0f32;
        let mut leaves: Vec<(f32, u32)> = Vec::new();
        // Area of each node's own box (the union of its slots).
        let mut node_area = 0.0f64;
        for (i, n) in bvh.nodes.iter().enumerate() {
            let mut b = Aabb::empty();
            for (min, max, index, count) in [
                (n.left_min, n.left_max, n.left_index, n.left_count),
                (n.right_min, n.right_max, n.right_index, n.right_count),
            ] {
                if index == INVALID_INDEX {
                    continue;
                }
                b = b.union(&Aabb::new(min.into(), max.into()));
                if count > 0 {
                    leaves.push((slot_area(min, max), count));
                }
            }
            let a = half_area(&b);
            if i == 0 {
                root_area = a;
            }
            node_area += f64::from(a);
        }
        let leaf_area: f64 = leaves
            .iter()
            .map(|&(a, c)| f64::from(a) * f64::from(c))
            .sum();
        let sah_cost = if root_area > 0.0 {
            ((f64::from(SAH_NODE_COST) * node_area + f64::from(SAH_PRIMITIVE_COST) * leaf_area)
                / f64::from(root_area)) as f32
        } else {
            // A flat or point-like scene: every ray that meets it visits everything.
            SAH_NODE_COST * bvh.nodes.len() as f32
                + SAH_PRIMITIVE_COST * bvh.primitives.len() as f32
        };
        BvhStats {
            quality,
            fallback,
            node_count: bvh.nodes.len(),
            leaf_count: leaves.len(),
            max_depth,
            max_leaf_size: leaves.iter().map(|&(_, c)| c as usize).max().unwrap_or(0),
            primitive_refs: bvh.primitives.len(),
            sah_cost,
            build_time: start.elapsed(),
        }
    }
}
