//! obvhs' `Bvh2` (one node per box, children at `first_index` and `first_index + 1`) to the
//! GPU layout: one [`BvhNode`] per inner node holding both children's boxes, leaves folded into
//! their parent's child slots, primitives copied out in leaf order.

use glam::Vec3A;
use obvhs::{aabb::Aabb, bvh2::Bvh2};

use crate::bounds::{Source, contains, half_area, primitive_aabb};
use crate::{BvhNode, INVALID_INDEX, Primitive};

/// The flattened tree.
pub(crate) struct Flat {
    pub nodes: Vec<BvhNode>,
    pub primitives: Vec<Primitive>,
    /// Nodes on the longest root-to-leaf path, the root counting 1.
    pub max_depth: usize,
}

#[derive(Clone, Copy)]
enum Side {
    Left,
    Right,
}

/// A root whose two slots are empty: the whole tree of a scene without primitives.
fn empty_node() -> BvhNode {
    BvhNode {
        left_index: INVALID_INDEX,
        right_index: INVALID_INDEX,
        ..BvhNode::default()
    }
}

fn set_slot(node: &mut BvhNode, side: Side, b: &Aabb, index: u32, count: u32) {
    let (min, max) = (b.min.to_array(), b.max.to_array());
    match side {
        Side::Left => {
            node.left_min = min;
            node.left_max = max;
            node.left_index = index;
            node.left_count = count;
        }
        Side::Right => {
            node.right_min = min;
            node.right_max = max;
            node.right_index = index;
            node.right_count = count;
        }
    }
}

fn slot_box(node: &BvhNode, side: Side) -> Aabb {
    match side {
        Side::Left => Aabb::new(node.left_min.into(), node.left_max.into()),
        Side::Right => Aabb::new(node.right_min.into(), node.right_max.into()),
    }
}

/// Flattens `bvh`, whose leaves index `source` through `bvh.primitive_indices`.
///
/// - Nodes are in depth-first pre-order, and of two inner children the one with the larger
///   box (the likelier to be visited) comes right after its parent, so that a descent usually
///   reads the next 64 bytes. Primitives are in the order their leaves are met.
/// - Leaf boxes are recomputed from the primitives (exact vertex bounds). A leaf holding
///   pieces of spatially split triangles keeps obvhs' tighter piece box, widened by 8 ulp of
///   the vertex magnitudes (the clipped polygon's vertices carry rounding error) and clipped
///   to the primitives' full bounds. Copies of one triangle inside one leaf are merged.
/// - Inner boxes are recomputed bottom-up as unions of their children, so every box encloses
///   its subtree exactly as stored.
pub(crate) fn flatten(bvh: &Bvh2, source: Source) -> Flat {
    let mut out = Flat {
        nodes: Vec::with_capacity(bvh.nodes.len() / 2 + 1),
        primitives: Vec::with_capacity(source.len()),
        max_depth: 1,
    };
    if bvh.nodes.is_empty() {
        out.nodes.push(empty_node());
        return out;
    }
    let root = &bvh.nodes[0];
    if root.is_leaf() {
        let mut node = empty_node();
        let (b, index, count) = emit_leaf(bvh, 0, source, &mut out.primitives);
        set_slot(&mut node, Side::Left, &b, index, count);
        out.nodes.push(node);
        return out;
    }

    // (parent node, which slot) of every output node; the root has none.
    let mut parents: Vec<(u32, Side)> = Vec::with_capacity(bvh.nodes.len() / 2 + 1);
    // Work: (obvhs node, parent output node or INVALID_INDEX, slot, depth).
    let mut stack: Vec<(usize, u32, Side, usize)> = vec![(0, INVALID_INDEX, Side::Left, 1)];
    while let Some((id, parent, side, depth)) = stack.pop() {
        let me = out.nodes.len() as u32;
        out.nodes.push(empty_node());
        parents.push((parent, side));
        if parent != INVALID_INDEX {
            set_slot(&mut out.nodes[parent as usize], side, &Aabb::empty(), me, 0);
        }
        out.max_depth = out.max_depth.max(depth);

        let a = bvh.nodes[id].first_index as usize;
        let (first, second) =
            if half_area(bvh.nodes[a].aabb()) >= half_area(bvh.nodes[a + 1].aabb()) {
                (a, a + 1)
            } else {
                (a + 1, a)
            };
        for (side, child) in [(Side::Left, first), (Side::Right, second)] {
            if bvh.nodes[child].is_leaf() {
                let (b, index, count) = emit_leaf(bvh, child, source, &mut out.primitives);
                set_slot(&mut out.nodes[me as usize], side, &b, index, count);
            }
        }
        // Pushed last, popped first: `first` lands right after this node.
        if !bvh.nodes[second].is_leaf() {
            stack.push((second, me, Side::Right, depth + 1));
        }
        if !bvh.nodes[first].is_leaf() {
            stack.push((first, me, Side::Left, depth + 1));
        }
    }

    // Children follow their parents, so a reverse sweep sees every node after its subtree.
    for i in (1..out.nodes.len()).rev() {
        let node = &out.nodes[i];
        let b = slot_box(node, Side::Left).union(&slot_box(node, Side::Right));
        let (parent, side) = parents[i];
        set_slot(&mut out.nodes[parent as usize], side, &b, i as u32, 0);
    }
    out
}

/// Copies leaf `id`'s primitives to the end of `primitives`; returns its box, first index and
/// count.
fn emit_leaf(
    bvh: &Bvh2,
    id: usize,
    source: Source,
    primitives: &mut Vec<Primitive>,
) -> (Aabb, u32, u32) {
    let leaf = &bvh.nodes[id];
    let start = primitives.len();
    let mut full = Aabb::empty();
    let ids = &bvh.primitive_indices
        [leaf.first_index as usize..(leaf.first_index + leaf.prim_count) as usize];
    for (k, &p) in ids.iter().enumerate() {
        // A second copy of one triangle (spatial splits) is merged into the first.
        if ids[..k].contains(&p) {
            continue;
        }
        let prim = source.get(p);
        full = full.union(&primitive_aabb(&prim));
        primitives.push(prim);
    }
    let b = leaf_box(leaf.aabb(), &full);
    let count = (primitives.len() - start) as u32;
    debug_assert!(count > 0);
    (b, start as u32, count)
}

/// The box a leaf of obvhs' box `built` over primitives whose bounds are `full` gets: `full`
/// when `built` contains it; for pieces of split triangles, `built` widened for the rounding
/// of the clipped polygon, never past `full`.
pub(crate) fn leaf_box(built: &Aabb, full: &Aabb) -> Aabb {
    if contains(built, full) {
        *full
    } else {
        let slack = split_slack(full);
        let widened = Aabb::new(built.min - slack, built.max + slack);
        let b = widened.intersection(full);
        debug_assert!(b.min.cmple(b.max).all(), "split leaf box is empty");
        b
    }
}

/// How far a split leaf's box is widened: 8 ulp of the largest vertex magnitude per axis.
fn split_slack(full: &Aabb) -> Vec3A {
    full.min.abs().max(full.max.abs()) * (8.0 * f32::EPSILON)
}
