//! A linear BVH (Karras, *Maximizing Parallelism in the Construction of BVHs, Octrees, and
//! k-d Trees*, HPG 2012): primitives sorted along a 63-bit Morton curve of their box centres,
//! and the binary radix tree over the sorted codes, every inner node found independently of
//! the others. Two uses:
//!
//! - [`BvhQuality::Fastest`](crate::BvhQuality::Fastest) on the CPU (`build_lbvh`): one
//!   primitive a leaf, as an obvhs `Bvh2` with each node's children side by side, which the
//!   reinsertion and the eight-wide converter then take as a PLOC tree (obvhs' PLOC, the
//!   other presets' builder, hardly uses the cores: 351 of 654 ms of the 3M grid's build on
//!   16 cores). Its SAH cost is higher than PLOC's (the Morton order alone decides the
//!   splits): the preset for renders of few rays over many primitives.
//! - The build on the GPU (`raylume_kernels::gpu::LbvhBuilder`, the WGSL of [`LBVH_WGSL`]):
//!   [`lbvh_binary`] is its reference, function for function ([`LbvhParams`],
//!   [`morton_code`], [`lbvh_delta`], [`lbvh_node`]), and writes the same [`BvhNode`]s in
//!   the same places: inner node `i` of the radix tree is node `i` (the root 0), a leaf is
//!   the slot of its parent that holds sorted primitive `k`.
//!
//! [`LBVH_WGSL`]: crate::LBVH_WGSL

use bytemuck::{Pod, Zeroable};
use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::{Bvh2, node::Bvh2Node};
use rayon::prelude::*;

use crate::bounds::primitive_aabb;
use crate::{BvhNode, INVALID_INDEX, PRIM_TRIANGLE, Primitive};

/// Subtrees of at least this many leaves are emitted on two threads.
const PARALLEL_LEAVES: u32 = 4096;

/// Bits of each axis in a [`morton_code`] (three axes: 63 bits).
pub const LBVH_AXIS_BITS: u32 = 21;

/// What every kernel of the GPU build reads (WGSL `LbvhParams`): the grid the Morton codes
/// quantise the box centres to, the primitive count, and the refit pass.
///
/// `repr(C)`, `Pod`, 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LbvhParams {
    /// The smallest box centre, per axis.
    pub centre_min: [f32; 3],
    /// Primitives.
    pub count: u32,
    /// `(2^21 - 1) / extent` per axis (the extent at least 1e-30): a centre's grid cell is
    /// `(centre - centre_min) * scale`, truncated.
    pub scale: [f32; 3],
    /// The refit pass this dispatch runs (1, 2, ...; the GPU build's `lbvh_refit`).
    pub pass_index: u32,
}

impl LbvhParams {
    /// The grid of the centres of `boxes` (finite).
    pub(crate) fn of_boxes(boxes: &[Aabb]) -> Self {
        let (lo, hi) = centre_bounds(boxes.par_iter().map(|b| b.center()));
        Self::of_centre_bounds(lo, hi, boxes.len())
    }

    /// The grid over box centres from `lo` to `hi` (each the least or greatest over all
    /// `count` centres, finite).
    pub fn of_centre_bounds(lo: Vec3A, hi: Vec3A, count: usize) -> Self {
        let scale =
            (hi - lo).max(Vec3A::splat(1e-30)).recip() * ((1u64 << LBVH_AXIS_BITS) - 1) as f32;
        Self {
            centre_min: lo.to_array(),
            count: count as u32,
            scale: scale.to_array(),
            pass_index: 0,
        }
    }

    /// The grid of `primitives`' box centres (finite), as the GPU build uses it.
    pub fn of_primitives(primitives: &[Primitive]) -> Self {
        let (lo, hi) = centre_bounds(primitives.par_iter().map(primitive_centre));
        Self::of_centre_bounds(lo, hi, primitives.len())
    }
}

/// The least and greatest of `centres`, per axis (`(inf, -inf)` for none), on every core.
pub fn centre_bounds(centres: impl ParallelIterator<Item = Vec3A>) -> (Vec3A, Vec3A) {
    centres
        .fold(
            || (Vec3A::INFINITY, Vec3A::NEG_INFINITY),
            |(lo, hi), c| (lo.min(c), hi.max(c)),
        )
        .reduce(
            || (Vec3A::INFINITY, Vec3A::NEG_INFINITY),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        )
}

/// The centre of `p`'s box (WGSL: `(lbvh_box_max(p) + lbvh_box_min(p)) * 0.5`), the point
/// its Morton code quantises.
pub fn primitive_centre(p: &Primitive) -> Vec3A {
    primitive_aabb(p).center()
}

/// 21 bits spread to every third bit.
fn spread3(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// The 63-bit Morton code of a box centre on `params`' grid: x in bits 0, 3, 6, ..., y in
/// 1, 4, ..., z in 2, 5, ... (WGSL `morton_code`, the code as two words, low first).
pub fn morton_code(centre: Vec3A, params: &LbvhParams) -> u64 {
    let lo = Vec3A::from_array(params.centre_min);
    let scale = Vec3A::from_array(params.scale);
    let q = ((centre - lo) * scale).max(Vec3A::ZERO);
    spread3(q.x as u64) | (spread3(q.y as u64) << 1) | (spread3(q.z as u64) << 2)
}

/// Karras' δ over sorted `codes`: the length of the common prefix of keys `i` and `j` (the
/// key of leaf `i` being `(codes[i], i)`: the index breaks ties between equal codes), -1
/// outside the leaves (WGSL `lbvh_delta`).
pub fn lbvh_delta(codes: &[u64], i: i64, j: i64) -> i64 {
    delta_by(codes.len(), |k| codes[k], i, j)
}

/// [`lbvh_delta`] over `n` sorted codes read through `code`.
fn delta_by(n: usize, code: impl Fn(usize) -> u64, i: i64, j: i64) -> i64 {
    if j < 0 || j >= n as i64 {
        return -1;
    }
    let (a, b) = (code(i as usize), code(j as usize));
    if a == b {
        64 + i64::from((i as u64 ^ j as u64).leading_zeros())
    } else {
        i64::from((a ^ b).leading_zeros())
    }
}

/// Inner node `i` of the radix tree over sorted `codes` (WGSL `lbvh_node`): its children and
/// the leaves it covers (Karras' Figure 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LbvhInner {
    /// The children: `(index, is a leaf)`; a leaf's index is its sorted position, an inner
    /// child's its node.
    pub children: [(u32, bool); 2],
    /// The first and last leaves (sorted positions) under the node.
    pub range: (u32, u32),
}

/// [`LbvhInner`] of inner node `i` (`0 <= i < codes.len() - 1`).
pub fn lbvh_node(codes: &[u64], i: i64) -> LbvhInner {
    node_by(codes.len(), |k| codes[k], i)
}

/// [`lbvh_node`] over `n` sorted codes read through `code`.
fn node_by(n: usize, code: impl Fn(usize) -> u64 + Copy, i: i64) -> LbvhInner {
    let delta = |j: i64| delta_by(n, code, i, j);
    let d: i64 = if delta(i + 1) > delta(i - 1) { 1 } else { -1 };
    let d_min = delta(i - d);
    let mut l_max = 2i64;
    while delta(i + l_max * d) > d_min {
        l_max *= 2;
    }
    let mut l = 0i64;
    let mut t = l_max / 2;
    while t >= 1 {
        if delta(i + (l + t) * d) > d_min {
            l += t;
        }
        t /= 2;
    }
    let j = i + l * d;
    let d_node = delta(j);
    let mut s = 0i64;
    let mut t = l;
    loop {
        t = (t + 1) / 2;
        if delta(i + (s + t) * d) > d_node {
            s += t;
        }
        if t <= 1 {
            break;
        }
    }
    let gamma = i + s * d + d.min(0);
    let (first, last) = (i.min(j), i.max(j));
    LbvhInner {
        children: [
            (gamma as u32, first == gamma),
            (gamma as u32 + 1, last == gamma + 1),
        ],
        range: (first as u32, last as u32),
    }
}

/// The `n` primitives' (Morton code of their box centre, index), sorted; `box_of(i)` is
/// primitive `i`'s box.
fn sorted_keys(
    n: usize,
    box_of: impl Fn(u32) -> Aabb + Sync,
    params: &LbvhParams,
) -> Vec<(u64, u32)> {
    let mut keys: Vec<(u64, u32)> = (0..n as u32)
        .into_par_iter()
        .map(|i| (morton_code(box_of(i).center(), params), i))
        .collect();
    keys.par_sort_unstable();
    keys
}

/// The tree the GPU build writes ([`lbvh_binary`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LbvhTree {
    /// Inner node `i` of the radix tree at `nodes[i]` (the root at 0): `n - 1` nodes for `n`
    /// primitives, each slot a leaf of one primitive (count 1, index its sorted position) or an
    /// inner node (count 0). One primitive: a root with one leaf slot and an empty one.
    pub nodes: Vec<BvhNode>,
    /// The primitives' sorted order: sorted position `k` holds `primitives[order[k]]`.
    pub order: Vec<u32>,
    /// Nodes on the longest root-to-leaf path, the root counting 1 (what the GPU build's
    /// refit pass count reaches).
    pub max_depth: usize,
}

/// The linear BVH over `primitives` (triangles; none empty) in the layout the GPU build
/// (`raylume_kernels::gpu::LbvhBuilder`) writes: its reference, node for node.
pub fn lbvh_binary(primitives: &[Primitive]) -> LbvhTree {
    let n = primitives.len();
    let boxes: Vec<Aabb> = primitives.par_iter().map(primitive_aabb).collect();
    let slot = |b: &Aabb| (b.min.to_array(), b.max.to_array());
    if n <= 1 {
        let mut root = BvhNode {
            left_index: INVALID_INDEX,
            right_index: INVALID_INDEX,
            ..Default::default()
        };
        if let Some(b) = boxes.first() {
            (root.left_min, root.left_max) = slot(b);
            (root.left_index, root.left_count) = (0, 1);
        }
        return LbvhTree {
            nodes: vec![root],
            order: (0..n as u32).collect(),
            max_depth: 1,
        };
    }
    let params = LbvhParams::of_boxes(&boxes);
    let (codes, order): (Vec<u64>, Vec<u32>) = sorted_keys(n, |i| boxes[i as usize], &params)
        .into_par_iter()
        .unzip();
    let inner: Vec<LbvhInner> = (0..n as i64 - 1)
        .into_par_iter()
        .map(|i| lbvh_node(&codes, i))
        .collect();
    // Boxes and heights bottom-up: an inner node after its inner children (its height is
    // one more than theirs), as the GPU's refit passes find them, pass by pass.
    let mut nodes = vec![BvhNode::default(); n - 1];
    let mut height = vec![0usize; n - 1];
    let mut stack = vec![(0u32, false)];
    while let Some((i, children_done)) = stack.pop() {
        let node = inner[i as usize];
        if !children_done {
            stack.push((i, true));
            for (c, leaf) in node.children {
                if !leaf {
                    stack.push((c, false));
                }
            }
            continue;
        }
        let mut out = BvhNode::default();
        let mut h = 0;
        for (side, (c, leaf)) in node.children.into_iter().enumerate() {
            let (b, count) = if leaf {
                (boxes[order[c as usize] as usize], 1)
            } else {
                let k = nodes[c as usize];
                h = h.max(height[c as usize]);
                let b = Aabb::new(k.left_min.into(), k.left_max.into())
                    .union(&Aabb::new(k.right_min.into(), k.right_max.into()));
                (b, 0)
            };
            let (min, max) = slot(&b);
            if side == 0 {
                (out.left_min, out.left_max, out.left_index, out.left_count) = (min, max, c, count);
            } else {
                (
                    out.right_min,
                    out.right_max,
                    out.right_index,
                    out.right_count,
                ) = (min, max, c, count);
            }
        }
        nodes[i as usize] = out;
        height[i as usize] = h + 1;
    }
    LbvhTree {
        nodes,
        order,
        max_depth: height[0],
    }
}

/// Whether `p` is a primitive the GPU build takes: a triangle.
pub fn lbvh_takes(p: &Primitive) -> bool {
    p.kind() == PRIM_TRIANGLE
}

/// The LBVH over `aabbs` (finite), as an obvhs tree with one primitive a leaf.
#[cfg(test)]
pub(crate) fn build_lbvh(aabbs: &[Aabb]) -> Bvh2 {
    build_lbvh_with(aabbs.len(), |i| aabbs[i as usize])
}

/// The LBVH over `n` primitives whose boxes (finite) `box_of` gives, as an obvhs tree with
/// one primitive a leaf. Each box is asked for three times (its centre's bounds, its code,
/// its leaf), never kept in an array.
pub(crate) fn build_lbvh_with(n: usize, box_of: impl Fn(u32) -> Aabb + Sync) -> Bvh2 {
    let mut bvh = Bvh2::default();
    if n == 0 {
        return bvh;
    }
    if n == 1 {
        bvh.nodes = vec![Bvh2Node::new(box_of(0), 1, 0)];
        bvh.primitive_indices = vec![0];
        bvh.max_depth = 1;
        return bvh;
    }
    let (lo, hi) = centre_bounds((0..n as u32).into_par_iter().map(|i| box_of(i).center()));
    let params = LbvhParams::of_centre_bounds(lo, hi, n);
    // The sorted (code, primitive) pairs stay as they are: the δ searches read their codes
    // in place and the leaves their primitives (no two further arrays of 3M entries).
    let keys = sorted_keys(n, &box_of, &params);

    // Nodes in a depth-first layout with each node's children side by side: the root at 0,
    // then for an inner node its children's pair, the left child's subtree, the right's.
    // Zeroed pages from the allocator (a node's default is all zeros): the emission below
    // writes every node, on every core, so nothing is written twice (3M triangles: 6M
    // nodes, 288 MB, which `vec![default; n]` wrote on one core first). Each inner node of
    // the radix tree is found where its parent is emitted, not kept in a table.
    let mut nodes: Vec<Bvh2Node> = bytemuck::zeroed_vec(2 * n - 1);
    let (root, rest) = nodes.split_at_mut(1);
    let e = Emit {
        keys: &keys,
        box_of: &box_of,
    };
    let (root_box, depth) = e.emit(e.node(0), rest, 1);
    root[0] = Bvh2Node::new(root_box, 0, 1);
    bvh.nodes = nodes;
    bvh.primitive_indices = keys.into_par_iter().map(|(_, p)| p).collect();
    bvh.max_depth = depth + 1;
    bvh
}

struct Emit<'a, F: Fn(u32) -> Aabb + Sync> {
    /// Sorted (Morton code, primitive); the key of leaf `k` is `(keys[k].0, k)`.
    keys: &'a [(u64, u32)],
    box_of: &'a F,
}

impl<F: Fn(u32) -> Aabb + Sync> Emit<'_, F> {
    /// Inner node `i` of the radix tree.
    fn node(&self, i: u32) -> LbvhInner {
        node_by(self.keys.len(), |k| self.keys[k].0, i64::from(i))
    }

    /// Writes inner node `node`'s children pair into `region[0..2]` (global index `start`)
    /// and their subtrees after it; returns the node's box and the depth below it.
    fn emit(&self, node: LbvhInner, region: &mut [Bvh2Node], start: u32) -> (Aabb, usize) {
        let (pair, rest) = region.split_at_mut(2);
        let child = |(c, leaf): (u32, bool)| (!leaf).then(|| self.node(c));
        let (left, right) = (child(node.children[0]), child(node.children[1]));
        let size = left.map_or(0, |l| 2 * (l.range.1 - l.range.0) as usize);
        let (left_rest, right_rest) = rest.split_at_mut(size);
        let left_start = start + 2;
        let right_start = left_start + left_rest.len() as u32;
        let big = node.range.1 - node.range.0 + 1 >= PARALLEL_LEAVES;
        let one =
            |c: u32, inner: Option<LbvhInner>, sub: &mut [Bvh2Node], sub_start: u32| match inner {
                None => {
                    let p = self.keys[c as usize].1;
                    (Bvh2Node::new((self.box_of)(p), 1, c), 0)
                }
                Some(inner) => {
                    let (b, d) = self.emit(inner, sub, sub_start);
                    (Bvh2Node::new(b, 0, sub_start), d)
                }
            };
        let (l_id, r_id) = (node.children[0].0, node.children[1].0);
        let ((l, dl), (r, dr)) = if big {
            rayon::join(
                || one(l_id, left, left_rest, left_start),
                || one(r_id, right, right_rest, right_start),
            )
        } else {
            (
                one(l_id, left, left_rest, left_start),
                one(r_id, right, right_rest, right_start),
            )
        };
        let b = l.aabb().union(r.aabb());
        pair[0] = l;
        pair[1] = r;
        (b, 1 + dl.max(dr))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut s = seed;
        let mut r = || crate::test_rand(&mut s);
        (0..n)
            .map(|i| {
                let c = glam::Vec3A::new(r(), r(), r()) * 10.0;
                let c = if i % 31 == 0 {
                    glam::Vec3A::splat(3.0)
                } else {
                    c
                };
                Aabb::new(c - 0.01, c + 0.02)
            })
            .collect()
    }

    /// Every primitive in exactly one leaf, every inner box the union of its children's,
    /// children side by side, every node reached once.
    #[test]
    fn the_tree_is_well_formed() {
        for n in [1usize, 2, 3, 7, 100, 5000, 20_000] {
            let aabbs = boxes(n, n as u64);
            let bvh = build_lbvh(&aabbs);
            assert_eq!(bvh.nodes.len(), 2 * n - 1);
            let mut seen = vec![0u32; n];
            let mut visited = 0;
            let mut stack = vec![(0usize, 1usize)];
            let mut deepest = 0;
            while let Some((k, depth)) = stack.pop() {
                visited += 1;
                deepest = deepest.max(depth);
                let node = &bvh.nodes[k];
                if node.is_leaf() {
                    assert_eq!(node.prim_count, 1);
                    let p = bvh.primitive_indices[node.first_index as usize] as usize;
                    seen[p] += 1;
                    assert_eq!(*node.aabb(), aabbs[p], "a leaf holds its primitive's box");
                } else {
                    let (a, b) = (node.first_index as usize, node.first_index as usize + 1);
                    let u = bvh.nodes[a].aabb().union(bvh.nodes[b].aabb());
                    assert_eq!(*node.aabb(), u, "node {k} of {n}");
                    stack.push((a, depth + 1));
                    stack.push((b, depth + 1));
                }
            }
            assert_eq!(visited, 2 * n - 1, "{n}: every node reached once");
            assert!(seen.iter().all(|&c| c == 1), "{n}: every primitive once");
            assert_eq!(bvh.max_depth, deepest, "{n}: the depth it records");
        }
    }
}
