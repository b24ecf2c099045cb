//! obvhs' binary-to-eight-wide converter (`cwbvh::bvh2_to_cwbvh`, after Ylitie et al. 2017
//! and Jan van Bergen's GPU-Raytracer), remade to run on every core and in a sixth of the
//! memory, giving **the same nodes and primitive order, bit for bit** (`tests` below compare
//! the two on many trees).
//!
//! obvhs' converter is two recursions over the binary tree, each on one thread: the SAH cost
//! table (for every node and every `i` in 0..7, the cheapest way to turn its subtree into at
//! most `i + 1` wide children: a leaf, an inner wide node, or a split of `i + 1` between its
//! two children), kept as 7 eight-byte decisions per binary node (336 MB for 3M triangles),
//! then the emission of the wide nodes, depth first. On the 2-core machine it took 1.1–1.8 s
//! of the 3M-triangle grid's 1.9 s `Fast` build.
//!
//! Here the cost recursion returns each subtree's seven costs by value (the parent needs only
//! its children's) and keeps of every decision only what the emission reads, a byte (kind,
//! left and right split), seven to a node; sibling subtrees run on different threads. A second
//! pass counts the wide nodes and primitives under each wide node, so the emission knows where
//! each subtree's nodes and primitives go in obvhs' depth-first order, and fills disjoint
//! slices of the output from different threads.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use glam::{UVec3, Vec3A, vec3a};
use obvhs::{
    PerComponent,
    aabb::Aabb,
    bvh2::Bvh2,
    cwbvh::{bvh2_to_cwbvh::bvh2_to_cwbvh, node::CwBvhNode},
};

/// obvhs' `DENOM`: one step of the 8-bit grid, 1/255 of the node's extent.
const DENOM: f32 = 1.0 / 255.0;
/// obvhs' primitive cost against a node's 1.
const PRIM_COST: f32 = 0.3;
/// Subtrees with at least this many primitives are split between threads (the counting
/// and emission passes; the cost pass, which learns the sizes, forks by depth).
const PARALLEL_PRIMS: u32 = 4096;
/// The cost recursion (which does not know subtree sizes yet) forks above this depth.
const PARALLEL_DEPTH: u32 = 14;

const LEAF: u8 = 0;
const INTERNAL: u8 = 1;
const DISTRIBUTE: u8 = 2;

/// One decision as the emission reads it: kind in bits 0-1, left split in 2-4, right in 5-7.
fn pack(kind: u8, left: u8, right: u8) -> u8 {
    kind | (left << 2) | (right << 5)
}

fn kind(d: u8) -> u8 {
    d & 3
}

fn left(d: u8) -> usize {
    usize::from((d >> 2) & 7)
}

fn right(d: u8) -> usize {
    usize::from(d >> 5)
}

/// The converter's state: the binary tree and, per binary node, its seven decisions (a byte
/// each, in one word) and, for nodes that become wide nodes, (wide nodes, primitives) below.
struct Converter<'a> {
    bvh: &'a Bvh2,
    decisions: Vec<AtomicU64>,
    counts: Vec<AtomicU64>,
    max_prims_per_leaf: u32,
}

/// The wide tree: obvhs' nodes and primitive indices.
pub(crate) struct Converted {
    pub nodes: Vec<CwBvhNode>,
    pub primitive_indices: Vec<u32>,
}

/// [`obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh`]`(bvh, max_prims_per_leaf, true, false)`,
/// on every core. `bvh` must have one primitive per leaf and finite boxes; where a cost
/// comes out not finite (no split cheaper than infinity) obvhs' own converter is used, so the
/// result is always obvhs'.
pub(crate) fn convert(bvh: &Bvh2, max_prims_per_leaf: u32) -> Converted {
    let obvhs = || {
        let cw = bvh2_to_cwbvh(bvh, max_prims_per_leaf, true, false);
        Converted {
            nodes: cw.nodes,
            primitive_indices: cw.primitive_indices,
        }
    };
    if bvh.nodes.is_empty() {
        return obvhs();
    }
    let n = bvh.nodes.len();
    // Zeroed pages from the allocator, touched first by the passes that write them.
    let zeros = || bytemuck::zeroed_vec::<AtomicU64>(n);
    let c = Converter {
        bvh,
        decisions: zeros(),
        counts: zeros(),
        max_prims_per_leaf,
    };
    let Some((_, prims)) = c.cost(0, 0) else {
        return obvhs();
    };
    let (wide, counted) = c.count(0);
    debug_assert_eq!(counted, prims);
    // Zeroed pages from the allocator (a node's default is all zeros), filled by the
    // emission on every core.
    let mut nodes: Vec<CwBvhNode> = bytemuck::zeroed_vec(wide as usize);
    let mut primitive_indices = vec![0u32; prims as usize];
    let (root, rest) = nodes.split_at_mut(1);
    c.emit(0, &mut root[0], rest, 1, &mut primitive_indices, 0);
    Converted {
        nodes,
        primitive_indices,
    }
}

impl Converter<'_> {
    fn decision(&self, node: usize, i: usize) -> u8 {
        (self.decisions[node].load(Relaxed) >> (8 * i)) as u8
    }

    /// The cost table of `node`'s subtree (its seven costs; its decisions and primitive count
    /// stored) (obvhs' `calculate_cost_impl`, the same float
    /// operations in the same order) and its primitive count; `None` when a slot-0 decision
    /// found no finite split (obvhs then reads past its table: its own converter is used).
    fn cost(&self, node: usize, depth: u32) -> Option<([f32; 7], u32)> {
        let n = &self.bvh.nodes[node];
        let half_area = n.aabb().half_area();
        if n.prim_count != 0 {
            assert_eq!(
                n.prim_count, 1,
                "the wide converter needs one primitive a leaf"
            );
            let leaf = half_area * PRIM_COST;
            self.decisions[node].store(0, Relaxed); // LEAF in every slot
            self.counts[node].store(1 << 32, Relaxed);
            return Some(([leaf; 7], 1));
        }
        let first = n.first_index as usize;
        let (a, b) = if depth < PARALLEL_DEPTH {
            rayon::join(
                || self.cost(first, depth + 1),
                || self.cost(first + 1, depth + 1),
            )
        } else {
            (self.cost(first, depth + 1), self.cost(first + 1, depth + 1))
        };
        let ((lc, lp), (rc, rp)) = (a?, b?);
        let num = lp + rp;
        let mut costs = [0.0f32; 7];
        let mut packed = [0u8; 7];

        let cost_leaf = if num <= self.max_prims_per_leaf {
            (num as f32) * half_area * PRIM_COST
        } else {
            f32::INFINITY
        };
        let mut cost_distribute = f32::INFINITY;
        let (mut dl, mut dr) = (u8::MAX, u8::MAX);
        for k in 0..7 {
            let c = lc[k] + rc[6 - k];
            if c < cost_distribute {
                cost_distribute = c;
                dl = k as u8;
                dr = 6 - k as u8;
            }
        }
        if dl == u8::MAX {
            return None;
        }
        let cost_internal = cost_distribute + half_area;
        if cost_leaf < cost_internal {
            costs[0] = cost_leaf;
            packed[0] = pack(LEAF, dl, dr);
        } else {
            costs[0] = cost_internal;
            packed[0] = pack(INTERNAL, dl, dr);
        }
        for i in 1..7 {
            let mut cost_distribute = costs[i - 1];
            let (mut dl, mut dr) = (u8::MAX, u8::MAX);
            for k in 0..i {
                let c = lc[k] + rc[i - k - 1];
                if c < cost_distribute {
                    cost_distribute = c;
                    dl = k as u8;
                    dr = (i - k - 1) as u8;
                }
            }
            if dl != u8::MAX {
                costs[i] = cost_distribute;
                packed[i] = pack(DISTRIBUTE, dl, dr);
            } else {
                costs[i] = costs[i - 1];
                packed[i] = packed[i - 1];
            }
        }
        let word = packed
            .iter()
            .enumerate()
            .fold(0u64, |w, (i, &d)| w | (u64::from(d) << (8 * i)));
        self.decisions[node].store(word, Relaxed);
        self.counts[node].store(u64::from(num) << 32, Relaxed);
        Some((costs, num))
    }

    /// obvhs' `get_children`: the binary nodes that become `node`'s wide children, given
    /// `node`'s decision `i`.
    fn children(&self, node: usize, out: &mut [u32; 8], count: &mut usize, i: usize) {
        let n = &self.bvh.nodes[node];
        if n.is_leaf() {
            out[*count] = node as u32;
            *count += 1;
            return;
        }
        let d = self.decision(node, i);
        let first = n.first_index as usize;
        for (child, slot) in [(first, left(d)), (first + 1, right(d))] {
            if kind(self.decision(child, slot)) == DISTRIBUTE {
                self.children(child, out, count, slot);
            } else {
                out[*count] = child as u32;
                *count += 1;
            }
        }
    }

    /// Primitives under binary node `node` (its leaves), as the cost pass stored them.
    fn prims_under(&self, node: usize) -> u32 {
        (self.counts[node].load(Relaxed) >> 32) as u32
    }

    /// (wide nodes, primitives) of the wide subtree rooted at binary node `node`, stored for
    /// the emission.
    fn count(&self, node: usize) -> (u32, u32) {
        let mut children = [u32::MAX; 8];
        let mut k = 0;
        self.children(node, &mut children, &mut k, 0);
        let mut wide = 1u32;
        let mut prims = 0u32;
        let mut inner = Vec::new();
        for &c in &children[..k] {
            if kind(self.decision(c as usize, 0)) == LEAF {
                prims += self.prims_under(c as usize);
            } else {
                inner.push(c as usize);
            }
        }
        let sub: Vec<(u32, u32)> = if inner.len() > 1 && self.big(node) {
            use rayon::prelude::*;
            inner.par_iter().map(|&c| self.count(c)).collect()
        } else {
            inner.iter().map(|&c| self.count(c)).collect()
        };
        for (w, p) in sub {
            wide += w;
            prims += p;
        }
        self.counts[node].store(u64::from(wide) | (u64::from(prims) << 32), Relaxed);
        (wide, prims)
    }

    /// Whether the subtree is worth splitting between threads.
    fn big(&self, node: usize) -> bool {
        self.prims_under(node) >= PARALLEL_PRIMS
    }

    fn counted(&self, node: usize) -> (u32, u32) {
        let w = self.counts[node].load(Relaxed);
        (w as u32, (w >> 32) as u32)
    }

    /// Pushes the primitives under binary node `node`, leaves left to right, into `out` from
    /// `*at` (obvhs' `count_primitives`).
    fn write_prims(&self, node: usize, out: &mut [u32], at: &mut usize) {
        let n = &self.bvh.nodes[node];
        if n.is_leaf() {
            out[*at] = self.bvh.primitive_indices[n.first_index as usize];
            *at += 1;
            return;
        }
        let first = n.first_index as usize;
        self.write_prims(first, out, at);
        self.write_prims(first + 1, out, at);
    }

    /// obvhs' `order_children`: children assigned to the eight octant slots greedily, by
    /// the dot product of their centre offsets with the octant directions.
    fn order_children(&self, node: usize, children: &mut [u32; 8], count: usize) {
        let p = self.bvh.nodes[node].aabb().center();
        let mut cost = [[f32::MAX; 8]; 8];
        for (s, row) in (0..8).map(|s| (s, direction(s))) {
            for c in 0..count {
                let v = self.bvh.nodes[children[c] as usize].aabb().center() - p;
                cost[c][s] = row.dot(v);
            }
        }
        let mut assignment = [usize::MAX; 8];
        let mut slot_filled = [false; 8];
        loop {
            let mut min_cost = f32::MAX;
            let (mut min_slot, mut min_index) = (usize::MAX, usize::MAX);
            for c in 0..count {
                if assignment[c] == usize::MAX {
                    for (s, &filled) in slot_filled.iter().enumerate() {
                        if !filled && cost[c][s] < min_cost {
                            min_cost = cost[c][s];
                            min_slot = s;
                            min_index = c;
                        }
                    }
                }
            }
            if min_slot == usize::MAX {
                break;
            }
            slot_filled[min_slot] = true;
            assignment[min_index] = min_slot;
        }
        let original = std::mem::replace(children, [u32::MAX; 8]);
        for i in 0..count {
            children[assignment[i]] = original[i];
        }
    }

    /// Writes the wide node of binary node `node` into `me`; `region` holds its children's
    /// block and then every node below it (global index `region_start` on), `prims` every
    /// primitive below it (from global index `prim_start`). obvhs' `convert_to_cwbvh_impl`.
    fn emit(
        &self,
        node: usize,
        me: &mut CwBvhNode,
        region: &mut [CwBvhNode],
        region_start: u32,
        prims: &mut [u32],
        prim_start: u32,
    ) {
        let aabb: &Aabb = self.bvh.nodes[node].aabb();
        let mut out = CwBvhNode {
            p: aabb.min.into(),
            ..CwBvhNode::default()
        };
        let e = ((aabb.max - aabb.min).max(Vec3A::splat(1e-20)) * DENOM)
            .log2()
            .ceil()
            .exp2();
        let rcp_e = 1.0 / e;
        let e: UVec3 = e.per_comp(|c: f32| c.to_bits() >> 23);
        out.e = [e.x as u8, e.y as u8, e.z as u8];

        let mut children = [u32::MAX; 8];
        let mut count = 0;
        self.children(node, &mut children, &mut count, 0);
        self.order_children(node, &mut children, count);

        out.imask = 0;
        out.primitive_base_idx = prim_start;
        out.child_base_idx = region_start;
        let mut inner: Vec<usize> = Vec::with_capacity(8);
        let mut num_prims = 0usize;
        for (i, &child) in children.iter().enumerate() {
            if child == u32::MAX {
                continue;
            }
            let b = self.bvh.nodes[child as usize].aabb();
            let lo = ((b.min - aabb.min) * rcp_e)
                .floor()
                .clamp(Vec3A::ZERO, Vec3A::splat(255.0));
            let hi = ((b.max - aabb.min) * rcp_e)
                .ceil()
                .clamp(Vec3A::ZERO, Vec3A::splat(255.0));
            out.child_min_x[i] = lo.x as u8;
            out.child_min_y[i] = lo.y as u8;
            out.child_min_z[i] = lo.z as u8;
            out.child_max_x[i] = hi.x as u8;
            out.child_max_y[i] = hi.y as u8;
            out.child_max_z[i] = hi.z as u8;
            if kind(self.decision(child as usize, 0)) == LEAF {
                let before = num_prims;
                self.write_prims(child as usize, prims, &mut num_prims);
                out.child_meta[i] = before as u8
                    | match num_prims - before {
                        1 => 0b0010_0000,
                        2 => 0b0110_0000,
                        3 => 0b1110_0000,
                        n => panic!("a wide leaf of {n} primitives"),
                    };
            } else {
                out.imask |= 1 << i;
                out.child_meta[i] = (24 + i as u8) | 0b0010_0000;
                inner.push(child as usize);
            }
        }
        *me = out;

        // The children's block, then each inner child's nodes and primitives, in slot order.
        let (block, mut rest) = region.split_at_mut(inner.len());
        let mut prims_rest = &mut prims[num_prims..];
        let mut next_node = region_start + inner.len() as u32;
        let mut next_prim = prim_start + num_prims as u32;
        let mut jobs = Vec::with_capacity(inner.len());
        for (slot, &child) in block.iter_mut().zip(&inner) {
            let (wide, nprims) = self.counted(child);
            let (r, tail) = std::mem::take(&mut rest).split_at_mut(wide as usize - 1);
            rest = tail;
            let (p, ptail) = std::mem::take(&mut prims_rest).split_at_mut(nprims as usize);
            prims_rest = ptail;
            jobs.push((child, slot, r, next_node, p, next_prim));
            next_node += wide - 1;
            next_prim += nprims;
        }
        let total: u32 = jobs.iter().map(|j| j.4.len() as u32).sum();
        if jobs.len() > 1 && total >= PARALLEL_PRIMS {
            use rayon::prelude::*;
            jobs.into_par_iter()
                .for_each(|(child, slot, r, rs, p, ps)| self.emit(child, slot, r, rs, p, ps));
        } else {
            for (child, slot, r, rs, p, ps) in jobs {
                self.emit(child, slot, r, rs, p, ps);
            }
        }
    }
}

/// obvhs' octant directions: bit 2 negates x, bit 1 y, bit 0 z.
fn direction(s: usize) -> Vec3A {
    vec3a(
        if s & 0b100 != 0 { -1.0 } else { 1.0 },
        if s & 0b010 != 0 { -1.0 } else { 1.0 },
        if s & 0b001 != 0 { -1.0 } else { 1.0 },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::{BvhBuildParams, bvh2::reinsertion::ReinsertionOptimizer, ploc::PlocBuilder};

    use crate::test_rand as rand;

    /// `n` boxes: small ones scattered in clusters, some large, some coincident.
    fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut s = seed;
        (0..n)
            .map(|i| {
                let c = Vec3A::new(rand(&mut s), rand(&mut s), rand(&mut s)) * 10.0;
                let size = if i % 97 == 0 {
                    3.0
                } else {
                    0.05 * rand(&mut s)
                };
                let c = if i % 53 == 0 { Vec3A::splat(5.0) } else { c };
                Aabb::new(c - size, c + Vec3A::new(size, 0.3 * size, size))
            })
            .collect()
    }

    /// obvhs' PLOC tree (one primitive a leaf) with the Fast preset's parameters, or the
    /// Quality preset's and its reinsertion.
    fn tree(aabbs: &[Aabb], quality: bool) -> Bvh2 {
        let p = if quality {
            BvhBuildParams::very_slow_build()
        } else {
            BvhBuildParams::fast_build()
        };
        let mut bvh = PlocBuilder::with_capacity(aabbs.len()).build(
            p.ploc_search_distance,
            aabbs,
            (0..aabbs.len() as u32).collect(),
            p.sort_precision,
            p.search_depth_threshold,
        );
        if quality {
            ReinsertionOptimizer::default().run(&mut bvh, p.reinsertion_batch_ratio, None);
        }
        bvh
    }

    fn bytes(nodes: &[CwBvhNode]) -> Vec<u8> {
        nodes
            .iter()
            .flat_map(|n| bytemuck::bytes_of(n).to_vec())
            .collect()
    }

    /// The converter and the LBVH allocate their nodes zeroed (`bytemuck::zeroed_vec`) where
    /// they wrote `vec![Node::default(); n]`: the same only while obvhs' defaults are all
    /// zero bits.
    #[test]
    fn the_nodes_default_is_all_zeros() {
        let cw = CwBvhNode::default();
        assert!(bytemuck::bytes_of(&cw).iter().all(|&b| b == 0));
        let b2 = obvhs::bvh2::node::Bvh2Node::default();
        assert!(bytemuck::bytes_of(&b2).iter().all(|&b| b == 0));
    }

    /// The same nodes, byte for byte, and the same primitive order as obvhs' converter, on
    /// trees from 1 to 60,000 primitives (past the thread split), with and without
    /// reinsertion, for every leaf size the wide layout allows.
    #[test]
    fn equals_obvhs_converter() {
        for (n, seed) in [
            (1, 1),
            (2, 2),
            (3, 3),
            (4, 4),
            (9, 5),
            (100, 6),
            (5_000, 7),
            (60_000, 8),
        ] {
            let aabbs = boxes(n, seed);
            for reinsert in [false, true] {
                let bvh = tree(&aabbs, reinsert);
                for leaf in 1..=3 {
                    let ours = convert(&bvh, leaf);
                    let theirs = bvh2_to_cwbvh(&bvh, leaf, true, false);
                    assert_eq!(
                        ours.nodes.len(),
                        theirs.nodes.len(),
                        "{n} boxes, leaf {leaf}"
                    );
                    assert!(
                        bytes(&ours.nodes) == bytes(&theirs.nodes),
                        "{n} boxes, leaf {leaf}: nodes differ"
                    );
                    assert_eq!(
                        ours.primitive_indices, theirs.primitive_indices,
                        "{n} boxes, leaf {leaf}"
                    );
                }
            }
        }
    }
}
