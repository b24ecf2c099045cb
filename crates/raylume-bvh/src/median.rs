//! The fallback builder: object-median splits, used only when the preset's tree is deeper than
//! [`MAX_STACK_DEPTH`](crate::MAX_STACK_DEPTH) (pathological inputs such as thousands of
//! coincident triangles, where clustering by proximity has nothing to go on).
//!
//! Every split halves the primitive count, so the tree is at most
//! `ceil(log2(n / LEAF_SIZE)) + 1` nodes deep whatever the geometry: 31 for 2^32 primitives.
//! Its SAH cost is worse than the presets' on ordinary scenes, which is why it is a fallback.

use obvhs::{
    aabb::Aabb,
    bvh2::{Bvh2, node::Bvh2Node},
};

/// Primitives per leaf of the binary layout's fallback (the wide layout's converter wants one
/// per leaf and merges them itself).
pub(crate) const LEAF_SIZE: usize = 4;

/// A `Bvh2` in obvhs' layout (root at 0, children in adjacent pairs) over `aabbs`, whose
/// `primitive_indices` index `aabbs`.
pub(crate) fn build_median(aabbs: &[Aabb], leaf_size: usize) -> Bvh2 {
    let n = aabbs.len();
    let mut indices: Vec<u32> = (0..n as u32).collect();
    if n == 0 {
        return Bvh2::default();
    }
    let centre = |i: u32, axis: usize| {
        let b = &aabbs[i as usize];
        b.min[axis] + b.max[axis]
    };
    let mut nodes = vec![Bvh2Node::default()];
    let mut work = vec![(0usize, 0usize, n)];
    while let Some((id, start, end)) = work.pop() {
        let mut bounds = Aabb::empty();
        let mut centres = Aabb::empty();
        for &i in &indices[start..end] {
            bounds = bounds.union(&aabbs[i as usize]);
            centres.extend(aabbs[i as usize].center());
        }
        if end - start <= leaf_size.max(1) {
            nodes[id] = Bvh2Node::new(bounds, (end - start) as u32, start as u32);
            continue;
        }
        let axis = centres.largest_axis();
        let mid = start + (end - start) / 2;
        // Ties (coincident centres) are broken by index, so the split is always a true half.
        indices[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centre(a, axis).total_cmp(&centre(b, axis)).then(a.cmp(&b))
        });
        let first = nodes.len();
        nodes.push(Bvh2Node::default());
        nodes.push(Bvh2Node::default());
        nodes[id] = Bvh2Node::new(bounds, 0, first as u32);
        work.push((first, start, mid));
        work.push((first + 1, mid, end));
    }
    Bvh2 {
        nodes,
        primitive_indices: indices,
        ..Bvh2::default()
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::*;

    fn depth(bvh: &Bvh2, id: usize) -> usize {
        let n = &bvh.nodes[id];
        if n.is_leaf() {
            1
        } else {
            1 + depth(bvh, n.first_index as usize).max(depth(bvh, n.first_index as usize + 1))
        }
    }

    #[test]
    fn coincident_boxes_give_a_balanced_tree() {
        let b = Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        let bvh = build_median(&vec![b; 10_000], LEAF_SIZE);
        // 10_000 / 4 = 2500 leaves: 12 levels of inner nodes above them, 13 in obvhs' count.
        assert_eq!(depth(&bvh, 0), 13);
        let mut seen: Vec<u32> = bvh.primitive_indices.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..10_000).collect::<Vec<u32>>());
    }
}
