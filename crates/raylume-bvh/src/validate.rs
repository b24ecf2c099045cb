//! [`GpuBvh::validate`]: the flattened tree's invariants, checked from the stored data alone.

use glam::Vec3A;
use obvhs::aabb::Aabb;

use crate::bounds::{contains, primitive_aabb};
use crate::{
    BvhLayout, GpuBvh, INVALID_INDEX, MAX_STACK_DEPTH, PRIM_SPHERE, PRIM_TRIANGLE, Primitive,
};

/// Barycentric grid resolution of the coverage check for split triangles.
const COVERAGE_STEPS: u32 = 8;

impl GpuBvh {
    /// Checks every invariant the traversal relies on; tests call it after every build.
    ///
    /// - node 0 is the root; every other node is the child of exactly one slot; no node is
    ///   unreachable; indices are in range; the tree is at most [`MAX_STACK_DEPTH`] deep;
    /// - empty slots appear only in the root, and only as `(INVALID_INDEX, 0)`; a tree with
    ///   primitives has a non-empty left root slot;
    /// - leaf ranges are in bounds and together cover `primitives` exactly once;
    /// - every primitive is finite, of a known kind, with a scene index in range, and every
    ///   scene triangle and sphere appears in at least one leaf;
    /// - every child slot's box contains its child node's two slot boxes, and every leaf box
    ///   contains its primitives' bounds; a triangle copied into several leaves by spatial
    ///   splits need only be covered by the union of its leaves' boxes (checked on its
    ///   vertices and a barycentric grid of points).
    ///
    /// A tree of [`BvhLayout::Wide`] is checked by its own rules (`wide.rs`, `validate_wide`).
    pub fn validate(&self) -> Result<(), String> {
        if self.layout == BvhLayout::Wide {
            return self.validate_wide();
        }
        if !self.wide_nodes.is_empty() {
            return Err("a binary tree holds wide nodes too".into());
        }
        let n_nodes = self.nodes.len();
        let n_prims = self.primitives.len();
        if n_nodes == 0 {
            return Err("no root node".into());
        }
        crate::wide::check_primitives(self)?;
        // Some copy of each triangle, for the coverage check below.
        let mut copy_of = vec![0usize; self.triangle_count as usize];
        for (i, p) in self.primitives.iter().enumerate() {
            if p.kind() == PRIM_TRIANGLE {
                copy_of[p.scene_index() as usize] = i;
            }
        }

        let mut visited = vec![false; n_nodes];
        let mut covered = vec![0u32; n_prims];
        let mut found_tri = vec![false; self.triangle_count as usize];
        let mut found_sphere = vec![false; self.sphere_count as usize];
        // Per triangle: fully inside one of its leaves, or the boxes of its partial leaves.
        let mut whole = vec![false; self.triangle_count as usize];
        let mut pieces: Vec<Vec<Aabb>> = vec![Vec::new(); self.triangle_count as usize];

        visited[0] = true;
        let mut stack: Vec<(usize, usize, Option<Aabb>)> = vec![(0, 1, None)];
        while let Some((id, depth, parent_box)) = stack.pop() {
            if depth > MAX_STACK_DEPTH {
                return Err(format!(
                    "node {id} is at depth {depth}, deeper than MAX_STACK_DEPTH = {MAX_STACK_DEPTH}"
                ));
            }
            let n = &self.nodes[id];
            let slots = [
                ("left", n.left_min, n.left_max, n.left_index, n.left_count),
                (
                    "right",
                    n.right_min,
                    n.right_max,
                    n.right_index,
                    n.right_count,
                ),
            ];
            for (side, min, max, index, count) in slots {
                let here = format!("node {id} {side} slot");
                if index == INVALID_INDEX {
                    if count != 0 || id != 0 {
                        return Err(format!(
                            "{here}: empty (INVALID_INDEX) with count {count}; empty slots \
                             belong only to the root, with count 0"
                        ));
                    }
                    continue;
                }
                let b = Aabb::new(min.into(), max.into());
                if !(b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all()) {
                    return Err(format!("{here}: invalid box {b:?}"));
                }
                if let Some(pb) = parent_box
                    && !contains(&pb, &b)
                {
                    return Err(format!(
                        "{here}: box {b:?} pokes out of the parent's box {pb:?}"
                    ));
                }
                if count > 0 {
                    let end = index as usize + count as usize;
                    if end > n_prims {
                        return Err(format!(
                            "{here}: leaf range {index}..{end} past {n_prims} primitives"
                        ));
                    }
                    let range = index as usize..end;
                    for (k, p) in range.clone().zip(&self.primitives[range]) {
                        covered[k] += 1;
                        let scene = p.scene_index() as usize;
                        let inside = contains(&b, &primitive_aabb(p));
                        if p.kind() == PRIM_SPHERE {
                            found_sphere[scene] = true;
                            if !inside {
                                return Err(format!(
                                    "{here}: sphere {scene} (primitive {k}) pokes out of its \
                                     leaf box {b:?}"
                                ));
                            }
                        } else {
                            found_tri[scene] = true;
                            if inside {
                                whole[scene] = true;
                            } else {
                                pieces[scene].push(b);
                            }
                        }
                    }
                } else {
                    let child = index as usize;
                    if child == 0 || child >= n_nodes {
                        return Err(format!("{here}: child index {child} out of 1..{n_nodes}"));
                    }
                    if visited[child] {
                        return Err(format!("{here}: node {child} has two parents"));
                    }
                    visited[child] = true;
                    stack.push((child, depth + 1, Some(b)));
                }
            }
        }

        if let Some(i) = visited.iter().position(|v| !v) {
            return Err(format!("node {i} is unreachable from the root"));
        }
        if let Some(k) = covered.iter().position(|&c| c != 1) {
            return Err(format!(
                "primitive {k} lies in {} leaf ranges instead of exactly 1",
                covered[k]
            ));
        }
        if let Some(i) = found_tri.iter().position(|f| !f) {
            return Err(format!("triangle {i} is in no leaf"));
        }
        if let Some(i) = found_sphere.iter().position(|f| !f) {
            return Err(format!("sphere {i} is in no leaf"));
        }
        if n_prims > 0 && self.nodes[0].left_index == INVALID_INDEX {
            return Err("the root's left slot is empty but the tree has primitives".into());
        }
        for (scene, boxes) in pieces.iter().enumerate() {
            if whole[scene] || boxes.is_empty() {
                continue;
            }
            let p = &self.primitives[copy_of[scene]];
            check_split_coverage(p, scene, boxes.len(), |point| {
                boxes.iter().any(|bx| bx.contains_point(point))
            })?;
        }
        Ok(())
    }
}

/// Checks that a triangle split over `leaves` leaves is covered: `covered` must hold for its
/// vertices and a barycentric grid of [`COVERAGE_STEPS`] steps (`p` is one of its copies).
pub(crate) fn check_split_coverage(
    p: &Primitive,
    scene: usize,
    leaves: usize,
    covered: impl Fn(Vec3A) -> bool,
) -> Result<(), String> {
    let v = [p.a, p.b, p.c].map(|x| Vec3A::new(x[0], x[1], x[2]));
    let steps = COVERAGE_STEPS;
    // The exact point lies in the triangle's box; rounding may push the computed one out
    // (e.g. off an axis-aligned triangle's plane).
    let full = primitive_aabb(p);
    for i in 0..=steps {
        for j in 0..=steps - i {
            let (a, b) = (i as f32 / steps as f32, j as f32 / steps as f32);
            let point = (v[0] * (1.0 - a - b) + v[1] * a + v[2] * b).clamp(full.min, full.max);
            if !covered(point) {
                return Err(format!(
                    "triangle {scene} is split over {leaves} leaves whose boxes miss its \
                     point {point} (barycentrics {a}, {b})"
                ));
            }
        }
    }
    Ok(())
}
