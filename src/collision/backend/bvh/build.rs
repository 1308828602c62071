//! BVH build (once, at construction): binned surface-area-heuristic splits over the
//! triangles' boxes at the rest positions.
//!
//! In: triangle boxes and centroids. Out: a node array in which every inner node's two
//! children are adjacent and come after it (so a backward sweep refits bottom-up),
//! and the triangle order of the leaves. Stays true: every triangle lies in exactly
//! one leaf; no leaf holds more than [`MAX_LEAF`] triangles; the build is
//! deterministic (fixed bin arithmetic, stable partitions, ties by index).

use super::Node;

/// Most triangles in a leaf.
pub(super) const MAX_LEAF: usize = 8;
/// Bins per axis of the binned SAH.
const BINS: usize = 16;
/// Cost of visiting an inner node relative to one triangle test.
const TRAVERSAL_COST: f64 = 0.7;

#[derive(Clone, Copy)]
struct Aabb {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Aabb {
    const EMPTY: Self = Self { lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] };
    fn grow(&mut self, o: &Aabb) {
        for i in 0..3 {
            self.lo[i] = self.lo[i].min(o.lo[i]);
            self.hi[i] = self.hi[i].max(o.hi[i]);
        }
    }
    fn grow_point(&mut self, p: &[f64; 3]) {
        for i in 0..3 {
            self.lo[i] = self.lo[i].min(p[i]);
            self.hi[i] = self.hi[i].max(p[i]);
        }
    }
    /// Half the surface area (0 for an empty box).
    fn half_area(&self) -> f64 {
        let d = [self.hi[0] - self.lo[0], self.hi[1] - self.lo[1], self.hi[2] - self.lo[2]];
        if d.iter().any(|&x| !(x >= 0.0)) {
            return 0.0;
        }
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

/// Builds the tree over `boxes` (per triangle `(lo, hi)`) and `centroids`. Returns the
/// nodes (boxes left empty; the caller refits) and the triangle order of the leaves.
pub(super) fn build(boxes: &[([f64; 3], [f64; 3])], centroids: &[[f64; 3]]) -> (Vec<Node>, Vec<u32>) {
    let n = boxes.len();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut nodes = Vec::with_capacity(2 * n.div_ceil(2) + 1);
    if n == 0 {
        return (nodes, order);
    }
    let boxes: Vec<Aabb> = boxes.iter().map(|&(lo, hi)| Aabb { lo, hi }).collect();
    let mut scratch = vec![0u32; n];
    nodes.push(Node::EMPTY);
    // Explicit work list (node, start, end) instead of recursion: a pathological
    // surface cannot overflow the call stack.
    let mut work = vec![(0usize, 0usize, n)];
    while let Some((node, start, end)) = work.pop() {
        match split(&boxes, centroids, &mut order[start..end], &mut scratch[start..end]) {
            None => nodes[node] = Node { first: start as u32, count: (end - start) as u32, ..Node::EMPTY },
            Some(mid) => {
                let left = nodes.len();
                nodes.push(Node::EMPTY);
                nodes.push(Node::EMPTY);
                nodes[node] = Node { first: left as u32, count: 0, ..Node::EMPTY };
                // Pushed right first so the left subtree is laid out next (depth-first order).
                work.push((left + 1, start + mid, end));
                work.push((left, start, start + mid));
            }
        }
    }
    (nodes, order)
}

/// Chooses a split of `order` and partitions it in place; returns the size of the
/// left part, or None when the range becomes a leaf.
fn split(boxes: &[Aabb], centroids: &[[f64; 3]], order: &mut [u32], scratch: &mut [u32]) -> Option<usize> {
    let n = order.len();
    if n <= 2 {
        return None;
    }
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for &t in order.iter() {
        bounds.grow(&boxes[t as usize]);
        cbounds.grow_point(&centroids[t as usize]);
    }
    let parent_area = bounds.half_area();
    let leaf_cost = n as f64;
    // Best (cost, axis, last bin of the left side).
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        let (lo, hi) = (cbounds.lo[axis], cbounds.hi[axis]);
        let extent = hi - lo;
        if !(extent > 0.0) {
            continue;
        }
        let scale = BINS as f64 / extent;
        let mut counts = [0usize; BINS];
        let mut bin_boxes = [Aabb::EMPTY; BINS];
        for &t in order.iter() {
            let b = bin_of(centroids[t as usize][axis], lo, scale);
            counts[b] += 1;
            bin_boxes[b].grow(&boxes[t as usize]);
        }
        // Sweep from the right: area and count of bins b..BINS.
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in (1..BINS).rev() {
            acc.grow(&bin_boxes[b]);
            cnt += counts[b];
            right_area[b] = acc.half_area();
            right_count[b] = cnt;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in 0..BINS - 1 {
            acc.grow(&bin_boxes[b]);
            cnt += counts[b];
            let (nl, nr) = (cnt, right_count[b + 1]);
            if nl == 0 || nr == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + if parent_area > 0.0 {
                    (acc.half_area() * nl as f64 + right_area[b + 1] * nr as f64) / parent_area
                } else {
                    n as f64
                };
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    match best {
        Some((cost, axis, last)) if cost < leaf_cost || n > MAX_LEAF => {
            let (lo, hi) = (cbounds.lo[axis], cbounds.hi[axis]);
            let scale = BINS as f64 / (hi - lo);
            // Stable partition: keeps the relative order of both sides.
            let mut nl = 0;
            let mut nr = 0;
            for &t in order.iter() {
                if bin_of(centroids[t as usize][axis], lo, scale) > last {
                    scratch[nr] = t;
                    nr += 1;
                }
            }
            for i in 0..n {
                let t = order[i];
                if bin_of(centroids[t as usize][axis], lo, scale) <= last {
                    order[nl] = t;
                    nl += 1;
                }
            }
            order[nl..].copy_from_slice(&scratch[..nr]);
            Some(nl)
        }
        Some(_) => None,
        None if n <= MAX_LEAF => None,
        None => {
            // Every centroid coincides (or is non-finite): split by index.
            order.sort_unstable();
            Some(n / 2)
        }
    }
}

#[inline]
fn bin_of(c: f64, lo: f64, scale: f64) -> usize {
    let b = ((c - lo) * scale) as usize; // saturating cast: NaN -> 0
    b.min(BINS - 1)
}
