//! The compressed eight-wide layout ([`BvhLayout::Wide`](crate::BvhLayout::Wide)): obvhs'
//! converter (`cwbvh::bvh2_to_cwbvh`: the SAH-optimal collapse of a binary tree with one
//! primitive per leaf into nodes of up to eight children and leaves of up to three
//! primitives, children ordered for octant-ordered traversal, boxes quantised to 8 bits) over
//! raylume's binary build, with the leaf boxes made exact first; the tree's invariants
//! ([`GpuBvh::validate`] for this layout) and its stats.

use glam::DVec3;
use obvhs::{aabb::Aabb, bvh2::Bvh2};
use rayon::prelude::*;

use crate::bounds::{Source, primitive_aabb};
use crate::flatten::leaf_box;
use crate::stats::{SAH_NODE_COST, SAH_PRIMITIVE_COST};
use crate::wide_traverse::WIDE_QUANT_PAD;
use crate::{GpuBvh, PRIM_SPHERE, PRIM_TRIANGLE, Primitive, WIDE_STACK_SIZE, WideNode};

/// Most primitives in a wide leaf (the unary count has three bits).
pub(crate) const WIDE_MAX_LEAF: u32 = 3;

/// The wide tree and its primitives.
pub(crate) struct WideFlat {
    pub nodes: Vec<WideNode>,
    pub primitives: Vec<Primitive>,
    /// Nodes on the longest root-to-leaf path, the root counting 1.
    pub max_depth: usize,
}

/// A root with no children: the whole tree of a scene without primitives (its grid a unit
/// one, so that every node has a normal cell).
fn empty_root() -> WideNode {
    WideNode {
        e_imask: [127, 127, 127, 0],
        ..WideNode::default()
    }
}

/// Converts `bvh` (leaves of one primitive each, indexing `source` through
/// `primitive_indices`) to the wide layout.
///
/// Leaf boxes are first set as the binary flatten sets them (exact primitive bounds, or a
/// split piece's box widened for rounding; `flatten::leaf_box`) and the inner boxes refitted,
/// so that obvhs quantises boxes that contain what they must.
pub(crate) fn to_wide(mut bvh: Bvh2, source: Source) -> WideFlat {
    if bvh.nodes.is_empty() {
        return WideFlat {
            nodes: vec![empty_root()],
            primitives: Vec::new(),
            max_depth: 1,
        };
    }
    // Without spatial splits the leaves already hold their primitives' exact boxes (every
    // builder here gives a leaf of one primitive that primitive's box): nothing to change
    // and no refit. With them, a leaf of pieces gets its box from the pieces' triangle.
    let indices = &bvh.primitive_indices;
    let changed = bvh.uses_spatial_splits
        && bvh
            .nodes
            .par_iter_mut()
            .filter(|n| n.is_leaf())
            .map(|node| {
                let ids = &indices
                    [node.first_index as usize..(node.first_index + node.prim_count) as usize];
                let full = ids
                    .iter()
                    .fold(Aabb::empty(), |b, &p| b.union(&source.aabb(p)));
                let exact = leaf_box(node.aabb(), &full);
                let changed = exact != *node.aabb();
                node.set_aabb(exact);
                changed
            })
            .reduce(|| false, |a, b| a || b);
    if changed {
        refit(&mut bvh);
    }
    let cw = crate::wide_convert::convert(&bvh, WIDE_MAX_LEAF);
    drop(bvh); // before the primitives are gathered: a large scene's peak memory
    // obvhs' node and ours are the same 80 bytes: the allocation is reused when the
    // alignments agree too (no 40 MB copy at 3M triangles).
    let nodes: Vec<WideNode> = bytemuck::allocation::try_cast_vec(cw.nodes)
        .unwrap_or_else(|(_, nodes)| nodes.par_iter().map(|n| bytemuck::cast(*n)).collect());
    let primitives = cw
        .primitive_indices
        .par_iter()
        .map(|&p| source.get(p))
        .collect();
    let max_depth = wide_depth(&nodes);
    WideFlat {
        nodes,
        primitives,
        max_depth,
    }
}

/// Recomputes every inner box as the union of its children's (obvhs' `refit_all` sizes its
/// stack by the tree's recorded depth bound; this walk needs none).
fn refit(bvh: &mut Bvh2) {
    let mut order = Vec::with_capacity(bvh.nodes.len());
    let mut stack = vec![0u32];
    while let Some(id) = stack.pop() {
        order.push(id);
        let n = &bvh.nodes[id as usize];
        if !n.is_leaf() {
            stack.push(n.first_index);
            stack.push(n.first_index + 1);
        }
    }
    for &id in order.iter().rev() {
        let n = bvh.nodes[id as usize];
        if !n.is_leaf() {
            let a = *bvh.nodes[n.first_index as usize].aabb();
            let b = *bvh.nodes[n.first_index as usize + 1].aabb();
            bvh.nodes[id as usize].set_aabb(a.union(&b));
        }
    }
}

/// The node index of inner slot `slot` of `node`.
fn child_node(node: &WideNode, slot: usize) -> usize {
    let below = u32::from(node.imask()) & ((1u32 << slot) - 1);
    (node.child_base + below.count_ones()) as usize
}

/// `(first primitive, count)` of leaf slot `slot` of `node`.
fn leaf_range(node: &WideNode, slot: usize) -> (usize, u32) {
    let meta = node.child_meta[slot];
    (
        node.prim_base as usize + usize::from(meta & 0b1_1111),
        u32::from(meta >> 5).count_ones(),
    )
}

/// Slot `slot`'s box as the traversal sees it (padded by [`WIDE_QUANT_PAD`] cells), in f64.
pub(crate) fn slot_box(node: &WideNode, slot: usize) -> (DVec3, DVec3) {
    let cell = DVec3::from(node.cell().map(f64::from));
    let p = DVec3::from(node.p.map(f64::from));
    let pad = f64::from(WIDE_QUANT_PAD);
    let q = |i: usize| DVec3::from([0, 1, 2].map(|k| f64::from(node.q_all(k)[i])));
    let lo = q(slot) - pad;
    let hi = q(8 + slot) + pad;
    (p + lo * cell, p + hi * cell)
}

/// Nodes on the longest root-to-leaf path of a wide tree (indices assumed valid).
fn wide_depth(nodes: &[WideNode]) -> usize {
    let mut deepest = 1;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((id, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        let n = &nodes[id];
        for slot in 0..8 {
            if n.imask() & (1 << slot) != 0 {
                stack.push((child_node(n, slot), depth + 1));
            }
        }
    }
    deepest
}

/// What [`GpuBvh::stats`](crate::GpuBvh::stats) reports of a wide tree: (leaf slots, most
/// primitives in a leaf, SAH cost). The SAH cost weighs each node [`SAH_NODE_COST`] and each
/// leaf its count times [`SAH_PRIMITIVE_COST`], by the area of its (quantised) box over the
/// root's: comparable between wide builds of one scene, not with the binary layout's (a wide
/// node tests eight boxes).
pub(crate) fn wide_stats(nodes: &[WideNode]) -> (usize, usize, f32) {
    let area = |(lo, hi): (DVec3, DVec3)| {
        let d = (hi - lo).max(DVec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    };
    let (mut leaves, mut max_leaf) = (0usize, 0usize);
    let (mut node_area, mut leaf_area) = (0.0f64, 0.0f64);
    let mut root_area = 0.0f64;
    for (i, n) in nodes.iter().enumerate() {
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for slot in 0..8 {
            if n.child_meta[slot] == 0 {
                continue;
            }
            let b = slot_box(n, slot);
            lo = lo.min(b.0);
            hi = hi.max(b.1);
            if n.imask() & (1 << slot) == 0 {
                let (_, count) = leaf_range(n, slot);
                leaves += 1;
                max_leaf = max_leaf.max(count as usize);
                leaf_area += area(b) * f64::from(count);
            }
        }
        let a = if lo.x <= hi.x { area((lo, hi)) } else { 0.0 };
        if i == 0 {
            root_area = a;
        }
        node_area += a;
    }
    let sah = if root_area > 0.0 {
        (f64::from(SAH_NODE_COST) * node_area + f64::from(SAH_PRIMITIVE_COST) * leaf_area)
            / root_area
    } else {
        f64::from(SAH_NODE_COST) * nodes.len() as f64
    };
    (leaves, max_leaf, sah as f32)
}

impl GpuBvh {
    /// [`GpuBvh::validate`] for the wide layout:
    ///
    /// - node 0 is the root; every other node is the child of exactly one inner slot; indices
    ///   are in range; the tree is at most [`WIDE_STACK_SIZE`] deep; every node's cell
    ///   exponents are normal (a non-zero, finite cell);
    /// - every slot's meta byte is empty (0), an inner child's (`0b001_11sss` with `sss` the
    ///   slot, and its imask bit set), or a leaf's (a unary count of 1 to 3 and an offset whose
    ///   primitives lie within `prim_base .. prim_base + 24`, imask bit clear); the node's
    ///   leaves cover `prim_base ..` without gaps, and all leaves cover `primitives` exactly
    ///   once;
    /// - every primitive is finite, of a known kind, with a scene index in range, and every
    ///   scene triangle and sphere appears in some leaf;
    /// - what the traversal can reach of a leaf is the intersection of its own padded box and
    ///   every ancestor slot's: each primitive's bounds must lie in that intersection, or,
    ///   for a triangle split over several leaves, its vertices and a barycentric grid must
    ///   lie in the union of those intersections (as the binary layout's check, in f64).
    pub(crate) fn validate_wide(&self) -> Result<(), String> {
        let nodes = &self.wide_nodes;
        let n_prims = self.primitives.len();
        if nodes.is_empty() {
            return Err("no root node".into());
        }
        if !self.nodes.is_empty() {
            return Err("a wide tree holds binary nodes too".into());
        }
        check_primitives(self)?;
        let mut visited = vec![false; nodes.len()];
        let mut covered = vec![0u32; n_prims];
        let mut found_tri = vec![false; self.triangle_count as usize];
        let mut found_sphere = vec![false; self.sphere_count as usize];
        // Per triangle: reachable boxes of the leaves holding it (when not wholly inside one).
        let mut whole = vec![false; self.triangle_count as usize];
        let mut pieces: Vec<Vec<(DVec3, DVec3)>> = vec![Vec::new(); self.triangle_count as usize];
        visited[0] = true;
        let everything = (DVec3::NEG_INFINITY, DVec3::INFINITY);
        let mut stack = vec![(0usize, 1usize, everything)];
        while let Some((id, depth, reach)) = stack.pop() {
            if depth > WIDE_STACK_SIZE {
                return Err(format!(
                    "node {id} is at depth {depth}, deeper than WIDE_STACK_SIZE = {WIDE_STACK_SIZE}"
                ));
            }
            let n = &nodes[id];
            if n.e_imask[..3].iter().any(|&e| e == 0 || e == 255) {
                return Err(format!("node {id}: cell exponents {:?}", &n.e_imask[..3]));
            }
            let mut leaf_prims = 0u32;
            let mut leaf_slots = 0u32;
            for slot in 0..8 {
                let meta = n.child_meta[slot];
                let inner = n.imask() & (1 << slot) != 0;
                let here = format!("node {id} slot {slot}");
                if meta == 0 {
                    if inner {
                        return Err(format!("{here}: empty but marked inner"));
                    }
                    continue;
                }
                let (lo, hi) = slot_box(n, slot);
                for k in 0..3 {
                    let (a, b) = (n.q_all(k)[slot], n.q_all(k)[8 + slot]);
                    if a > b {
                        return Err(format!("{here}: axis {k} cells {a}..{b} inverted"));
                    }
                }
                let reach_here = (lo.max(reach.0), hi.min(reach.1));
                if inner {
                    if meta != 0b0010_0000 | (24 + slot as u8) {
                        return Err(format!("{here}: inner child with meta {meta:#010b}"));
                    }
                    let child = child_node(n, slot);
                    if child == 0 || child >= nodes.len() {
                        return Err(format!("{here}: child {child} out of 1..{}", nodes.len()));
                    }
                    if visited[child] {
                        return Err(format!("{here}: node {child} has two parents"));
                    }
                    visited[child] = true;
                    stack.push((child, depth + 1, reach_here));
                    continue;
                }
                let count = meta >> 5;
                if !matches!(count, 0b001 | 0b011 | 0b111) || (meta & 0b1_1111) >= 24 {
                    return Err(format!("{here}: leaf meta {meta:#010b}"));
                }
                let (first, count) = leaf_range(n, slot);
                let end = first + count as usize;
                if end > n_prims || end > n.prim_base as usize + 24 {
                    return Err(format!(
                        "{here}: leaf range {first}..{end} past {n_prims} primitives or the \
                         node's 24"
                    ));
                }
                leaf_prims += count;
                leaf_slots |= ((1u32 << count) - 1) << (first - n.prim_base as usize);
                for (k, p) in (first..end).zip(&self.primitives[first..end]) {
                    covered[k] += 1;
                    let scene = p.scene_index() as usize;
                    let b = primitive_aabb(p);
                    let (bmin, bmax) = (b.min.as_dvec3(), b.max.as_dvec3());
                    let inside = reach_here.0.cmple(bmin).all() && reach_here.1.cmpge(bmax).all();
                    if p.kind() == PRIM_SPHERE {
                        found_sphere[scene] = true;
                        if !inside {
                            return Err(format!(
                                "{here}: sphere {scene} (primitive {k}) pokes out of what the \
                                 traversal reaches of its leaf, {reach_here:?}"
                            ));
                        }
                    } else {
                        found_tri[scene] = true;
                        if inside {
                            whole[scene] = true;
                        } else {
                            pieces[scene].push(reach_here);
                        }
                    }
                }
            }
            // The node's leaves hold prim_base .. prim_base + leaf_prims, each once.
            if leaf_slots != (1u32 << leaf_prims) - 1 {
                return Err(format!(
                    "node {id}: its leaves cover offsets {leaf_slots:#b}, not 0..{leaf_prims}"
                ));
            }
        }
        if let Some(i) = visited.iter().position(|v| !v) {
            return Err(format!("node {i} is unreachable from the root"));
        }
        if let Some(k) = covered.iter().position(|&c| c != 1) {
            return Err(format!(
                "primitive {k} lies in {} leaves instead of exactly 1",
                covered[k]
            ));
        }
        if let Some(i) = found_tri.iter().position(|f| !f) {
            return Err(format!("triangle {i} is in no leaf"));
        }
        if let Some(i) = found_sphere.iter().position(|f| !f) {
            return Err(format!("sphere {i} is in no leaf"));
        }
        for (scene, boxes) in pieces.iter().enumerate() {
            if whole[scene] || boxes.is_empty() {
                continue;
            }
            let p = self
                .primitives
                .iter()
                .find(|p| p.kind() == PRIM_TRIANGLE && p.scene_index() as usize == scene)
                .expect("found above");
            crate::validate::check_split_coverage(p, scene, boxes.len(), |point| {
                let q = point.as_dvec3();
                boxes
                    .iter()
                    .any(|(lo, hi)| lo.cmple(q).all() && hi.cmpge(q).all())
            })?;
        }
        Ok(())
    }
}

impl WideNode {
    /// The 16 cell bytes of axis `k` (lower cells of slots 0..8, then upper).
    fn q_all(&self, k: usize) -> &[u8; 16] {
        match k {
            0 => &self.q_x,
            1 => &self.q_y,
            _ => &self.q_z,
        }
    }
}

/// Every primitive finite, of a known kind, with a scene index in range (both layouts'
/// `validate`).
pub(crate) fn check_primitives(bvh: &GpuBvh) -> Result<(), String> {
    for (i, p) in bvh.primitives.iter().enumerate() {
        let (kind, scene) = (p.kind(), p.scene_index() as usize);
        let count = match kind {
            PRIM_TRIANGLE => bvh.triangle_count as usize,
            PRIM_SPHERE => bvh.sphere_count as usize,
            _ => return Err(format!("primitive {i} has unknown kind {kind}")),
        };
        if scene >= count {
            return Err(format!(
                "primitive {i} refers to scene primitive {scene} of {count}"
            ));
        }
        let b = primitive_aabb(p);
        if !(b.min.is_finite() && b.max.is_finite()) {
            return Err(format!("primitive {i} is not finite: {p:?}"));
        }
    }
    Ok(())
}
