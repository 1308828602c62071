//! BVH backend: a binary bounding-volume hierarchy over the deformed surface's
//! triangles, built once (binned surface-area heuristic over the rest positions,
//! `bvh/build.rs`) and REFIT every frame (topology never changes), traversed per
//! pair line NEAR-FIRST with our f64 watertight line test at the leaves.
//!
//! Why our own tree rather than parry's `Bvh` (the first version used it): a pair
//! line needs four nearest hits around the blade (behind and in front of each
//! face), and the query is cheap only if the boxes nearest the blade are opened
//! first, so that the interval where a hit could still matter shrinks at once and
//! prunes the rest of the line. parry's `traverse` visits children in a fixed order
//! and gave 4.4 ms for 500 nodes a face on a 20k-triangle sphere; near-first
//! traversal of this tree is several times faster (see `benches/collision.rs`).
//!
//! In: triangles (fixed), positions per frame, pair lines. Out: nearest hits per
//! line, bit for bit those of `reference`. Stays true: pruning is conservative. A
//! node is skipped only when the line misses its box grown by `margin`, or when the
//! line's parameter interval through that grown box lies outside the interval
//! where a hit could still change the result ([`LineAccumulator::needed_interval`],
//! itself widened by `margin`). `margin` is at least 1e-7 of the surface's
//! bounding-box diagonal (boxes are stored grown by it). Exact ties are kept (never pruned) and go to the lower triangle index
//! by [`LineAccumulator::offer`], whatever the visiting order. Lines are independent
//! and land in fixed output slots, so splitting them (and the refit) over rayon's
//! threads ([`BvhCaster::set_threads`], default min(pool, 2)) cannot change any answer.
//!
//! Cost per frame: the refit reads each leaf's distinct vertices once (about 2 per
//! triangle instead of 3) in one backward sweep, and only over the leaves of the
//! vertices that moved and their ancestors (a scene that holds the tissue away
//! from the blades moves a tenth of the fine brain's surface); a line costs about 50 node visits
//! on a 41k-triangle brain, each testing both children's boxes with a branch-free
//! slab test and pruning them against the needed interval before they are pushed.

mod build;


use super::{LineAccumulator, PairHits, PairLine, RayCaster, TriangleHit};
use crate::collision::{BackendKind, CollisionError};
use crate::geometry::LineQuery;
use crate::math::Vec3;

/// Relative size of the conservative margin (of the surface's AABB diagonal).
const MARGIN_RELATIVE: f64 = 1e-7;

/// Fewest pair lines worth splitting over threads.
const PARALLEL_MIN_LINES: usize = 64;
/// Fewest traversal steps (node visits and triangle tests, over all lines) of
/// the last cast for this one to be split over threads. Waking a second thread
/// costs tens of microseconds on a shared two-core machine: a shipped scene's
/// cast (300 lines, 250-6,000 steps, about 20 ns a step) took twice as long
/// split as on one thread, while 1,000 lines through a brain (some 66,000
/// steps) took a third less.
const PARALLEL_MIN_STEPS: u64 = 20_000;
/// Pair lines per parallel task (tasks are load-balanced by rayon; results land in
/// fixed slots, so the split never changes an answer).
const LINES_PER_TASK: usize = 32;
/// Fewest tree nodes worth refitting over threads.
const PARALLEL_MIN_NODES: usize = 4096;
/// The refit recomputes only the boxes over moved vertices while at most one
/// vertex in this many moved; above that, every box (the full sweep, split over
/// threads, costs less than marking most of the tree).
const SELECTIVE_REFIT_FRACTION: usize = 4;

thread_local! {
    /// Traversal stack of a worker thread, reused across frames.
    static STACK: std::cell::RefCell<Vec<Pending>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// A tree node: a box (stored grown by the margin) and either two children
/// (`count == 0`, children at `first` and `first + 1`) or a run of `count` triangles
/// at `order[first..]` whose distinct vertices are `leaf_vertices[vfirst..vfirst + vcount]`.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: [f64; 3],
    hi: [f64; 3],
    first: u32,
    count: u32,
    vfirst: u32,
    vcount: u32,
}

impl Node {
    const EMPTY: Self = Self { lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3], first: 0, count: 0, vfirst: 0, vcount: 0 };
}

/// One pending node of a traversal: its index and the line's parameter interval
/// through its (grown) box.
#[derive(Debug, Clone, Copy)]
struct Pending {
    node: u32,
    t0: f64,
    t1: f64,
}

/// The static layout of a [`BvhCaster`]'s tree (see [`BvhCaster::layout`]).
pub(crate) struct TreeLayout {
    pub topo: Vec<[u32; 4]>,
    pub leaf_triangles: Vec<[u32; 4]>,
    pub leaf_vertices: Vec<u32>,
    pub levels: Vec<Vec<u32>>,
    pub depth: usize,
}

/// Refit-per-frame BVH ray caster.
#[derive(Clone)]
pub struct BvhCaster {
    /// This frame's surface-vertex positions.
    positions: Vec<Vec3>,
    /// Every leaf's distinct vertices, leaf after leaf (a leaf's box needs each once).
    leaf_vertices: Vec<u32>,
    /// Original triangle indices in leaf order.
    order: Vec<u32>,
    /// Triangles (vertex indices) in leaf order: `leaf_triangles[i] = triangles[order[i]]`.
    leaf_triangles: Vec<[u32; 3]>,
    /// Nodes; every child has a larger index than its parent (refit runs backwards).
    nodes: Vec<Node>,
    /// Margin the boxes are grown by, metres: at least `MARGIN_RELATIVE` of the
    /// surface's bounding-box diagonal (set at construction, raised if the surface grows).
    margin: f64,
    stack: Vec<Pending>,
    /// Threads to split the work over (1: all on the calling thread).
    threads: usize,
    /// Traversal steps of the last cast (every line's node visits and triangle
    /// tests): whether the next one is worth splitting ([`PARALLEL_MIN_STEPS`]).
    last_steps: u64,
    /// Each node's parent (`u32::MAX` at the root).
    parent: Vec<u32>,
    /// The leaves holding each surface vertex, as CSR: vertex `v`'s are
    /// `vertex_leaves[vertex_leaf_start[v]..vertex_leaf_start[v + 1]]`.
    vertex_leaf_start: Vec<u32>,
    vertex_leaves: Vec<u32>,
    /// Marking scratch, one bit a node (a marked node's ancestors are marked
    /// too); zero between calls.
    dirty: Vec<u64>,
    /// The last refit grew every box in place: the next one recomputes all of them.
    refit_all: bool,
    /// Scratch: the vertices that moved since the last refit.
    moved: Vec<u32>,
    /// The nodes over `marked_for`'s vertices, descending (children first).
    marked: Vec<u32>,
    marked_for: Vec<u32>,
}

#[inline(always)]
fn min(a: f64, b: f64) -> f64 {
    if b < a { b } else { a }
}

#[inline(always)]
fn max(a: f64, b: f64) -> f64 {
    if b > a { b } else { a }
}

/// A line prepared for box tests: origin and reciprocal direction.
///
/// A zero direction component gives an infinite reciprocal, and the slab test then
/// needs no branch: outside the slab both bounds are +inf or both -inf (a miss),
/// inside they are -inf and +inf (no constraint). An origin exactly on a slab
/// boundary gives NaN, which [`min`] and [`max`] ignore, so that axis does not
/// constrain the interval: the test stays conservative.
#[derive(Clone, Copy)]
struct BoxQuery {
    o: [f64; 3],
    inv: [f64; 3],
}

impl BoxQuery {
    /// The line's parameter interval through box `n` (stored grown by the margin);
    /// empty (a miss) when `t0 > t1 + margin`.
    #[inline(always)]
    fn interval(&self, n: &Node) -> (f64, f64) {
        let mut t0 = f64::NEG_INFINITY;
        let mut t1 = f64::INFINITY;
        for a in 0..3 {
            let ta = (n.lo[a] - self.o[a]) * self.inv[a];
            let tb = (n.hi[a] - self.o[a]) * self.inv[a];
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        }
        (t0, t1)
    }
}

impl BvhCaster {
    /// Builds the tree once over the triangles at `positions` (indices validated by the caller).
    pub fn new(triangles: &[[u32; 3]], positions: &[Vec3]) -> Self {
        let boxes: Vec<([f64; 3], [f64; 3])> = triangles.iter().map(|t| triangle_box(positions, t)).collect();
        let centroids: Vec<[f64; 3]> = triangles
            .iter()
            .map(|t| {
                let c = t.map(|i| positions[i as usize]).iter().sum::<Vec3>() / 3.0;
                [c.x, c.y, c.z]
            })
            .collect();
        let (mut nodes, order) = build::build(&boxes, &centroids);
        let mut leaf_vertices = Vec::with_capacity(triangles.len() * 3 / 2);
        let mut distinct = Vec::with_capacity(3 * build::MAX_LEAF);
        for n in nodes.iter_mut().filter(|n| n.count > 0) {
            distinct.clear();
            distinct.extend(order[n.first as usize..(n.first + n.count) as usize].iter().flat_map(|&t| triangles[t as usize]));
            distinct.sort_unstable();
            distinct.dedup();
            n.vfirst = leaf_vertices.len() as u32;
            n.vcount = distinct.len() as u32;
            leaf_vertices.extend_from_slice(&distinct);
        }
        let leaf_triangles = order.iter().map(|&t| triangles[t as usize]).collect();
        let mut parent = vec![u32::MAX; nodes.len()];
        for (k, n) in nodes.iter().enumerate().filter(|(_, n)| n.count == 0 && n.first > 0) {
            parent[n.first as usize] = k as u32;
            parent[n.first as usize + 1] = k as u32;
        }
        let (vertex_leaf_start, vertex_leaves) = crate::mesh::group_by_key(positions.len(), || {
            nodes.iter().enumerate().filter(|(_, n)| n.count > 0).flat_map(|(k, n)| {
                leaf_vertices[n.vfirst as usize..(n.vfirst + n.vcount) as usize].iter().map(move |&v| (v, k as u32))
            })
        });
        let words = nodes.len().div_ceil(64);
        let mut s = Self {
            positions: positions.to_vec(),
            leaf_vertices,
            order,
            leaf_triangles,
            nodes,
            margin: 0.0,
            stack: Vec::with_capacity(128),
            threads: default_threads(),
            last_steps: 0,
            parent,
            vertex_leaf_start,
            vertex_leaves,
            dirty: vec![0; words],
            refit_all: false,
            moved: Vec::new(),
            marked: Vec::new(),
            marked_for: Vec::new(),
        };
        s.refit();
        s
    }

    /// Marks leaf `k` and its ancestors for the next refit (stops at the first
    /// ancestor already marked: its own ancestors are).
    fn mark_dirty(&mut self, mut k: u32) {
        while k != u32::MAX {
            let (w, b) = (k as usize / 64, 1u64 << (k % 64));
            if self.dirty[w] & b != 0 {
                return;
            }
            self.dirty[w] |= b;
            k = self.parent[k as usize];
        }
    }

    /// Recomputes only the boxes in `marked`, children before parents (descending
    /// node index), each exactly as [`Self::refit`] would: a box depends only
    /// on its leaf's vertices or its children's boxes, so an unmarked node's
    /// box is already what a full refit would give it. Then the margin rule of
    /// the full refit.
    fn refit_marked(&mut self) {
        let (positions, leaf_vertices, m) = (&self.positions, &self.leaf_vertices, self.margin);
        for &k in &self.marked {
            let nodes = &self.nodes;
            let (lo, hi) = fitted_box(&nodes[k as usize], |c| nodes[c], positions, leaf_vertices, m);
            self.nodes[k as usize].lo = lo;
            self.nodes[k as usize].hi = hi;
        }
        self.grow_margin();
    }

    /// Sets `marked` to the leaves of the vertices in `moved` and their
    /// ancestors, descending. A blade pressing the same tissue moves the same
    /// vertices sub-step after sub-step: the list of the last set is kept.
    fn mark_moved(&mut self) {
        if self.moved == self.marked_for {
            return;
        }
        for k in 0..self.moved.len() {
            let v = self.moved[k] as usize;
            for i in self.vertex_leaf_start[v]..self.vertex_leaf_start[v + 1] {
                self.mark_dirty(self.vertex_leaves[i as usize]);
            }
        }
        self.marked.clear();
        for w in (0..self.dirty.len()).rev() {
            let mut bits = std::mem::take(&mut self.dirty[w]);
            while bits != 0 {
                let b = 63 - bits.leading_zeros();
                bits &= !(1u64 << b);
                self.marked.push(w as u32 * 64 + b);
            }
        }
        self.marked_for.clone_from(&self.moved);
    }

    /// Recomputes every box bottom-up from `self.positions`, grown by the margin, in
    /// one backward sweep (children come after their parents). With two threads the
    /// root's two subtrees, each a contiguous run of the node array (depth-first
    /// layout), are swept at the same time, then the top three nodes.
    fn refit(&mut self) {
        let (positions, leaf_vertices, m) = (&self.positions, &self.leaf_vertices, self.margin);
        // Sweeps `nodes` (global indices `base..`) backwards; every child of a node in
        // the run must lie in the run.
        let sweep = |nodes: &mut [Node], base: usize| {
            for k in (0..nodes.len()).rev() {
                let (lo, hi) = fitted_box(&nodes[k], |c| nodes[c - base], positions, leaf_vertices, m);
                nodes[k].lo = lo;
                nodes[k].hi = hi;
            }
        };
        let len = self.nodes.len();
        if self.threads > 1 && len >= PARALLEL_MIN_NODES && self.nodes[0].count == 0 {
            // Root 0, children 1 and 2; node 1's descendants are 3..x, node 2's are x..len.
            let x = if self.nodes[2].count == 0 { self.nodes[2].first as usize } else { len };
            let (top, rest) = self.nodes.split_at_mut(3);
            let (left, right) = rest.split_at_mut(x - 3);
            rayon::join(|| sweep(left, 3), || sweep(right, x));
            let mut top_and_children = |k: usize| sweep_one(top, k, &*left, &*right, x, positions, leaf_vertices, m);
            top_and_children(2);
            top_and_children(1);
            (top[0].lo, top[0].hi) = union_box(&top[1], &top[2]);
        } else {
            sweep(&mut self.nodes, 0);
        }
        self.refit_all = false;
        self.grow_margin();
    }

    /// The margin must stay at least MARGIN_RELATIVE of the diagonal: when the surface
    /// has grown past that (or on the first fit), grow every box by the difference
    /// (in place, so the next refit recomputes every box).
    fn grow_margin(&mut self) {
        let Some(root) = self.nodes.first() else { return };
        let d = Vec3::new(root.hi[0] - root.lo[0], root.hi[1] - root.lo[1], root.hi[2] - root.lo[2]);
        let wanted = MARGIN_RELATIVE * d.norm().max(f64::MIN_POSITIVE);
        if wanted > self.margin && wanted.is_finite() {
            let extra = 2.0 * wanted - self.margin; // headroom: no second pass while the surface stays this size
            for n in &mut self.nodes {
                for i in 0..3 {
                    n.lo[i] -= extra;
                    n.hi[i] += extra;
                }
            }
            self.margin += extra;
            self.refit_all = true;
        }
    }

    /// The tree's static layout, for the GPU backend (which refits and walks the same
    /// tree on the device): per node (first, count, vfirst, vcount), the leaf-order
    /// triangles with their original index in the fourth entry, every leaf's distinct
    /// vertices, the node indices grouped by height above the leaves (leaves first),
    /// and the depth (edges from the root to the deepest leaf).
    pub(crate) fn layout(&self) -> TreeLayout {
        let n = self.nodes.len();
        let mut height = vec![0u32; n];
        for k in (0..n).rev() {
            let node = &self.nodes[k];
            if node.count == 0 {
                let c = node.first as usize;
                height[k] = 1 + height[c].max(height[c + 1]);
            }
        }
        let mut depth = vec![0u32; n];
        for k in 0..n {
            let node = &self.nodes[k];
            if node.count == 0 {
                let c = node.first as usize;
                depth[c] = depth[k] + 1;
                depth[c + 1] = depth[k] + 1;
            }
        }
        let top = height.iter().copied().max().unwrap_or(0) as usize;
        let mut levels = vec![Vec::new(); if n == 0 { 0 } else { top + 1 }];
        for (k, &h) in height.iter().enumerate() {
            levels[h as usize].push(k as u32);
        }
        TreeLayout {
            topo: self.nodes.iter().map(|x| [x.first, x.count, x.vfirst, x.vcount]).collect(),
            leaf_triangles: self.leaf_triangles.iter().zip(&self.order).map(|(t, &o)| [t[0], t[1], t[2], o]).collect(),
            leaf_vertices: self.leaf_vertices.clone(),
            levels,
            depth: depth.iter().copied().max().unwrap_or(0) as usize,
        }
    }

    /// Splits refit and casting over `threads` threads of rayon's pool (at least 1;
    /// 1 keeps everything on the calling thread). Answers do not depend on it.
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = threads.max(1);
    }

    /// Threads the work is split over.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Nearest hits of one pair line.
    pub fn cast_one(&mut self, line: &PairLine) -> PairHits {
        let mut stack = std::mem::take(&mut self.stack);
        let hits = self.cast_with(line, &mut stack, &mut 0);
        self.stack = stack;
        hits
    }

    /// Nearest hits of one pair line, with `stack` as scratch; adds its traversal steps to `steps`.
    fn cast_with(&self, line: &PairLine, stack: &mut Vec<Pending>, steps: &mut u64) -> PairHits {
        let mut best = LineAccumulator::new(line.thickness);
        let Some(query) = LineQuery::new(line.origin, line.direction) else {
            return best.finish();
        };
        let Some(root) = self.nodes.first() else {
            return best.finish();
        };
        let d = [line.direction.x, line.direction.y, line.direction.z];
        let bq = BoxQuery { o: [line.origin.x, line.origin.y, line.origin.z], inv: d.map(|c| 1.0 / c) };
        // Distance of an interval from the blade's mid-plane (line parameter -h/2).
        let centre = -0.5 * line.thickness;
        let gap = |t0: f64, t1: f64| {
            if t0 > centre {
                t0 - centre
            } else if t1 < centre {
                centre - t1
            } else {
                0.0
            }
        };
        let m = self.margin;
        let (mut need_lo, mut need_hi) = (f64::NEG_INFINITY, f64::INFINITY);
        stack.clear();
        let (t0, t1) = bq.interval(root);
        if t0 <= t1 + m {
            stack.push(Pending { node: 0, t0, t1 });
        }
        while let Some(Pending { node, t0, t1 }) = stack.pop() {
            // The needed interval may have shrunk since the push.
            if t1 < need_lo || t0 > need_hi {
                continue;
            }
            let n = &self.nodes[node as usize];
            *steps += 1 + u64::from(n.count);
            if n.count > 0 {
                let range = n.first as usize..(n.first + n.count) as usize;
                for (tri, &t) in self.leaf_triangles[range.clone()].iter().zip(&self.order[range]) {
                    let [a, b, c] = tri.map(|i| &self.positions[i as usize]);
                    if let Some(h) = query.intersect(a, b, c) {
                        best.offer(TriangleHit { triangle: t, t: h.t, u: h.u, v: h.v });
                    }
                }
                (need_lo, need_hi) = best.needed_interval(m);
                continue;
            }
            let (l, r) = (n.first, n.first + 1);
            let (a0, a1) = bq.interval(&self.nodes[l as usize]);
            let (b0, b1) = bq.interval(&self.nodes[r as usize]);
            // A child is kept when the line meets its box and the interval still matters there.
            let keep_l = a0 <= a1 + m && a1 >= need_lo && a0 <= need_hi;
            let keep_r = b0 <= b1 + m && b1 >= need_lo && b0 <= need_hi;
            let (left, right) = (Pending { node: l, t0: a0, t1: a1 }, Pending { node: r, t0: b0, t1: b1 });
            // Push the farther child first so the nearer one is opened next.
            match (keep_l, keep_r) {
                (true, true) => {
                    if gap(a0, a1) <= gap(b0, b1) {
                        stack.extend([right, left]);
                    } else {
                        stack.extend([left, right]);
                    }
                }
                (true, false) => stack.push(left),
                (false, true) => stack.push(right),
                (false, false) => {}
            }
        }
        best.finish()
    }
}

/// Refits node `k` (1 or 2) of `top` (nodes 0..3) from its children, which lie in
/// `left` (global 3..x) or `right` (global x..), or from its triangles if it is a leaf.
#[allow(clippy::too_many_arguments)]
fn sweep_one(top: &mut [Node], k: usize, left: &[Node], right: &[Node], x: usize, positions: &[Vec3], leaf_vertices: &[u32], m: f64) {
    let child = |c: usize| if c >= x { right[c - x] } else { left[c - 3] };
    let (lo, hi) = fitted_box(&top[k], child, positions, leaf_vertices, m);
    top[k].lo = lo;
    top[k].hi = hi;
}

/// The box of node `n`: its leaf's vertices grown by the margin `m`, or the
/// union of its children's boxes (`child(i)` is node `i`). Every refit path
/// computes boxes here, so they agree bit for bit.
#[inline(always)]
fn fitted_box(n: &Node, child: impl Fn(usize) -> Node, positions: &[Vec3], leaf_vertices: &[u32], m: f64) -> ([f64; 3], [f64; 3]) {
    if n.count > 0 {
        return leaf_box(n, positions, leaf_vertices, m);
    }
    let c = n.first as usize;
    union_box(&child(c), &child(c + 1))
}

/// The smallest box holding boxes `a` and `b`.
#[inline(always)]
fn union_box(a: &Node, b: &Node) -> ([f64; 3], [f64; 3]) {
    let (mut lo, mut hi) = ([0.0; 3], [0.0; 3]);
    for i in 0..3 {
        lo[i] = min(a.lo[i], b.lo[i]);
        hi[i] = max(a.hi[i], b.hi[i]);
    }
    (lo, hi)
}

/// Box of a leaf's triangle vertices, grown by the margin `m`.
#[inline]
fn leaf_box(n: &Node, positions: &[Vec3], leaf_vertices: &[u32], m: f64) -> ([f64; 3], [f64; 3]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &v in &leaf_vertices[n.vfirst as usize..(n.vfirst + n.vcount) as usize] {
        let q = &positions[v as usize];
        for i in 0..3 {
            lo[i] = min(lo[i], q[i]);
            hi[i] = max(hi[i], q[i]);
        }
    }
    (lo.map(|x| x - m), hi.map(|x| x + m))
}

/// Default thread count: the pool's size, at most 2 (the machines we target).
fn default_threads() -> usize {
    rayon::current_num_threads().clamp(1, 2)
}

fn triangle_box(positions: &[Vec3], t: &[u32; 3]) -> ([f64; 3], [f64; 3]) {
    let [a, b, c] = t.map(|i| positions[i as usize]);
    let lo = a.inf(&b).inf(&c);
    let hi = a.sup(&b).sup(&c);
    ([lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z])
}

impl RayCaster for BvhCaster {
    fn kind(&self) -> BackendKind {
        BackendKind::Bvh
    }

    fn set_threads(&mut self, threads: usize) {
        BvhCaster::set_threads(self, threads);
    }

    fn update_surface(&mut self, positions: &[Vec3]) -> Result<(), CollisionError> {
        if positions.len() != self.positions.len() {
            return Err(CollisionError::VertexCount { expected: self.positions.len(), got: positions.len() });
        }
        // Only the boxes over moved vertices (compared bit for bit) change: an
        // unmoved surface (blades away from the tissue, a held frame) keeps
        // every box, and on a scene holding the tissue away from the blades a
        // tenth of the surface moves. Each moved vertex marks its leaves and
        // their ancestors, and the refit recomputes those boxes alone, giving
        // every box the bits of a full refit. When most of the surface moves,
        // the full sweep (on two threads) is cheaper.
        self.moved.clear();
        for (v, (p, q)) in positions.iter().zip(self.positions.iter_mut()).enumerate() {
            if p.x.to_bits() != q.x.to_bits() || p.y.to_bits() != q.y.to_bits() || p.z.to_bits() != q.z.to_bits() {
                *q = *p;
                self.moved.push(v as u32);
            }
        }
        if self.moved.is_empty() {
            return Ok(());
        }
        if self.refit_all || self.moved.len() * SELECTIVE_REFIT_FRACTION > positions.len() {
            self.refit();
        } else {
            self.mark_moved();
            self.refit_marked();
        }
        Ok(())
    }

    fn cast(&mut self, lines: &[PairLine], out: &mut Vec<PairHits>) -> Result<(), CollisionError> {
        out.clear();
        if self.threads > 1 && lines.len() >= PARALLEL_MIN_LINES && self.last_steps >= PARALLEL_MIN_STEPS {
            use rayon::prelude::*;
            out.resize(lines.len(), PairHits::default());
            let this = &*self;
            let steps = std::sync::atomic::AtomicU64::new(0);
            out.par_chunks_mut(LINES_PER_TASK).zip(lines.par_chunks(LINES_PER_TASK)).for_each(|(o, l)| {
                let mut task_steps = 0;
                STACK.with_borrow_mut(|stack| {
                    for (o, l) in o.iter_mut().zip(l) {
                        *o = this.cast_with(l, stack, &mut task_steps);
                    }
                });
                steps.fetch_add(task_steps, std::sync::atomic::Ordering::Relaxed);
            });
            self.last_steps = steps.into_inner();
        } else {
            let mut stack = std::mem::take(&mut self.stack);
            let mut steps = 0;
            out.extend(lines.iter().map(|l| self.cast_with(l, &mut stack, &mut steps)));
            self.stack = stack;
            self.last_steps = steps;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::backend::reference::ReferenceCaster;

    /// Deterministic pseudo-random numbers in [0, 1).
    fn rng(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Lines through a unit-scale scene: random directions, axis-aligned ones (exact
    /// zero components: the branch-free slab test's infinite reciprocals), and origins
    /// exactly on vertex coordinates (slab boundaries before the margin).
    fn lines(positions: &[Vec3], n: usize, seed: u64) -> Vec<PairLine> {
        let mut s = seed;
        (0..n)
            .map(|k| {
                let p = positions[(rng(&mut s) * positions.len() as f64) as usize];
                let direction = match k % 3 {
                    0 => Vec3::new(rng(&mut s) - 0.5, rng(&mut s) - 0.5, rng(&mut s) - 0.5).normalize(),
                    1 => [Vec3::x(), -Vec3::y(), Vec3::z()][k % 9 / 3],
                    _ => Vec3::new(rng(&mut s) - 0.5, 0.0, rng(&mut s) - 0.5).normalize(),
                };
                let origin = if k % 2 == 0 { p } else { p * (0.5 + rng(&mut s)) };
                PairLine { origin, direction, thickness: 0.01 + 0.05 * rng(&mut s) }
            })
            .collect()
    }

    #[test]
    fn one_and_two_threads_agree_with_the_reference_bit_for_bit() {
        let (tris, rest) = crate::collision::scenes::icosphere(Vec3::zeros(), 1.0, 4);
        let mut s = 7;
        // A deformed surface (the tree was built on `rest` and is refit, not rebuilt).
        let moved: Vec<Vec3> = rest.iter().map(|p| p * (1.0 + 0.2 * (rng(&mut s) - 0.5))).collect();
        let lines = lines(&moved, 600, 11);
        let mut reference = ReferenceCaster::new(&tris, &rest);
        reference.update_surface(&moved).unwrap();
        let mut expected = Vec::new();
        reference.cast(&lines, &mut expected).unwrap();
        assert!(expected.iter().filter(|h| h.face0.behind.is_some()).count() > 100, "the scene must produce hits");
        for threads in [1, 2] {
            let mut bvh = BvhCaster::new(&tris, &rest);
            bvh.set_threads(threads);
            bvh.update_surface(&moved).unwrap();
            let mut got = Vec::new();
            bvh.cast(&lines, &mut got).unwrap();
            for (k, (g, e)) in got.iter().zip(&expected).enumerate() {
                assert_eq!(g, e, "{threads} thread(s), line {k} ({:?}): bvh differs from reference", lines[k]);
            }
        }
    }

    #[test]
    fn a_surface_grown_tenfold_raises_the_margin_and_keeps_answers() {
        // Guards the margin rule: it must follow the deformed surface's size, not only the rest size.
        let (tris, rest) = crate::collision::scenes::icosphere(Vec3::zeros(), 1.0, 3);
        let grown: Vec<Vec3> = rest.iter().map(|p| p * 10.0).collect();
        let mut bvh = BvhCaster::new(&tris, &rest);
        let m0 = bvh.margin;
        bvh.update_surface(&grown).unwrap();
        assert!(bvh.margin >= MARGIN_RELATIVE * 20.0 * 3f64.sqrt(), "margin {} (was {m0}) must cover the grown diagonal", bvh.margin);
        let lines = lines(&grown, 300, 5);
        let (mut got, mut expected) = (Vec::new(), Vec::new());
        bvh.cast(&lines, &mut got).unwrap();
        ReferenceCaster::new(&tris, &grown).cast(&lines, &mut expected).unwrap();
        assert_eq!(got, expected, "bvh on the grown surface differs from reference");
    }

    /// Every box, bitwise, of a tree refit over the moved vertices only against
    /// a tree built on the same surface and refit in full.
    fn assert_boxes_equal(got: &BvhCaster, full: &BvhCaster, what: &str) {
        assert_eq!(got.margin.to_bits(), full.margin.to_bits(), "{what}: margin");
        for (k, (a, b)) in got.nodes.iter().zip(&full.nodes).enumerate() {
            let bits = |n: &Node| (n.lo.map(f64::to_bits), n.hi.map(f64::to_bits));
            assert_eq!(bits(a), bits(b), "{what}: node {k}'s box");
        }
    }

    #[test]
    fn refitting_only_over_moved_vertices_gives_every_box_of_a_full_refit() {
        let (tris, rest) = crate::collision::scenes::icosphere(Vec3::zeros(), 1.0, 4);
        let mut s = 3;
        let mut bvh = BvhCaster::new(&tris, &rest);
        let mut full = BvhCaster::new(&tris, &rest);
        full.set_threads(1);
        let mut moved = rest.clone();
        // frames moving a patch, a scattered few, nothing, everything, and a
        // growth past the margin (which grows every box in place)
        for frame in 0..8 {
            for (v, p) in moved.iter_mut().enumerate() {
                let pick = match frame {
                    0 | 1 => rest[v].z > 0.6,
                    2 => v % 97 == 5,
                    3 => false,
                    5 => true,
                    _ => rest[v].x < -0.6,
                };
                if pick {
                    *p += Vec3::new(rng(&mut s) - 0.5, rng(&mut s) - 0.5, rng(&mut s) - 0.5) * 0.05;
                }
            }
            if frame == 4 {
                for p in &mut moved {
                    *p *= 30.0;
                }
            }
            bvh.update_surface(&moved).unwrap();
            full.positions.copy_from_slice(&moved);
            full.refit();
            assert_boxes_equal(&bvh, &full, &format!("frame {frame}"));
            let lines = lines(&moved, 200, frame);
            let (mut got, mut expected) = (Vec::new(), Vec::new());
            bvh.cast(&lines, &mut got).unwrap();
            ReferenceCaster::new(&tris, &moved).cast(&lines, &mut expected).unwrap();
            assert_eq!(got, expected, "frame {frame}: bvh differs from reference");
        }
    }

    #[test]
    fn a_wrong_vertex_count_is_an_error_not_a_panic() {
        let (tris, rest) = crate::collision::scenes::icosphere(Vec3::zeros(), 1.0, 1);
        let mut bvh = BvhCaster::new(&tris, &rest);
        let err = bvh.update_surface(&rest[1..]).unwrap_err();
        assert_eq!(err, CollisionError::VertexCount { expected: rest.len(), got: rest.len() - 1 });
    }

    #[test]
    fn children_follow_parents_so_backward_refit_is_bottom_up() {
        let (tris, pos) = crate::collision::scenes::icosphere(Vec3::zeros(), 1.0, 3);
        let b = BvhCaster::new(&tris, &pos);
        for (k, n) in b.nodes.iter().enumerate() {
            if n.count == 0 {
                assert!(n.first as usize > k, "child {} of node {k} must come after it", n.first);
            }
        }
        let mut seen = vec![0; tris.len()];
        for n in b.nodes.iter().filter(|n| n.count > 0) {
            assert!(n.count as usize <= build::MAX_LEAF, "leaf of {} triangles exceeds MAX_LEAF", n.count);
            for &t in &b.order[n.first as usize..(n.first + n.count) as usize] {
                seen[t as usize] += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1), "every triangle in exactly one leaf");
    }
}
