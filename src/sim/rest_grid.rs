//! The surface vertices near a box, found without reading the whole surface.
//!
//! In: the surface's rest positions (binned once into a uniform grid), a box,
//! and a bound on every displacement. Out: the vertices whose current position
//! may lie in the box, ascending. Stays true: a vertex at `rest + u` with every
//! component of `u` within `bound` lies outside the box whenever its rest
//! position lies outside the box grown by `bound`, so a caller that runs its
//! exact test on the vertices returned, in the order returned, gets what a pass
//! over the whole surface gets, bit for bit. A query that would read most of the
//! grid, or a box that is not finite, answers "every vertex" instead.
//!
//! Why: a blade inserted into a fissure moves in sub-steps with no contact yet.
//! Each sub-step's barrier rows and tunnelling monitor only concern the few
//! hundred vertices around the blades, but a pass over a brain's 21,533 surface
//! vertices per blade, sub-step and stage cost more than the rest of the sub-step.

use crate::math::Vec3;

/// Slack added to every query (m): above the rounding of `rest + u` and of a
/// pose transform (about 1e-16 m at brain scale), far below anything measured.
const QUERY_SLACK_M: f64 = 1e-9;

/// At most this many cells a side (a flat or degenerate surface keeps a small grid).
const MAX_CELLS_PER_AXIS: f64 = 128.0;

/// Surface vertices binned by their rest positions.
#[derive(Debug, Clone, Default)]
pub struct RestGrid {
    /// The rest positions' lowest and highest corners.
    lo: Vec3,
    hi: Vec3,
    /// One over the cell's edge, 1/m.
    inv_cell: f64,
    dims: [usize; 3],
    /// Cell `c`'s vertices are `vertices[start[c]..start[c + 1]]`, ascending.
    start: Vec<u32>,
    vertices: Vec<u32>,
}

/// A query's answer, and its scratch (kept between queries: no allocation per frame).
#[derive(Debug, Clone, Default)]
pub struct Near {
    /// Whether the last query answered every vertex (the list is then empty).
    pub all: bool,
    /// The last query's vertices, ascending (when not `all`).
    pub list: Vec<u32>,
    /// One bit a vertex; zero between queries.
    marks: Vec<u64>,
}

impl Near {
    /// Calls `f` with every vertex of the last query's answer, ascending (`0..n` when it was every vertex).
    pub fn for_each(&self, n: usize, mut f: impl FnMut(usize)) {
        if self.all {
            (0..n).for_each(f);
        } else {
            self.list.iter().for_each(|&v| f(v as usize));
        }
    }
}

/// The largest component of any `positions[v] - rest[v]`: a bound for
/// [`RestGrid::near`]; infinity for mismatched slices or a NaN.
pub fn displacement_bound(positions: &[Vec3], rest: &[Vec3]) -> f64 {
    if positions.len() != rest.len() {
        return f64::INFINITY;
    }
    let mut bound = [0u64; 3];
    for (p, r) in positions.iter().zip(rest) {
        add_to_bound(&mut bound, p, r);
    }
    finish_bound(bound)
}

/// Takes `p - rest` into a running [`displacement_bound`] (start from zeros,
/// end with [`finish_bound`]). The bits of a non-negative float order as the
/// float does, and those of a NaN's absolute value above infinity's: an
/// integer max, one chain an axis, is branch-free and short (a float max that
/// handles NaN is a chain of six dependent operations a component).
#[inline(always)]
pub fn add_to_bound(bound: &mut [u64; 3], p: &Vec3, rest: &Vec3) {
    for i in 0..3 {
        bound[i] = bound[i].max((p[i] - rest[i]).abs().to_bits());
    }
}

/// The bound that [`add_to_bound`] ran up.
pub fn finish_bound(bound: [u64; 3]) -> f64 {
    let b = f64::from_bits(bound[0].max(bound[1]).max(bound[2]));
    if b.is_nan() { f64::INFINITY } else { b }
}

impl RestGrid {
    /// Bins `rest`: about one cell a vertex over the rest positions' box, at most
    /// [`MAX_CELLS_PER_AXIS`] a side.
    pub fn new(rest: &[Vec3]) -> Self {
        let n = rest.len();
        if n == 0 || !rest.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            return Self::default();
        }
        let lo = rest.iter().fold(Vec3::repeat(f64::INFINITY), |m, p| m.inf(p));
        let hi = rest.iter().fold(Vec3::repeat(f64::NEG_INFINITY), |m, p| m.sup(p));
        let extent = hi - lo;
        let longest = extent.max();
        let volume = extent.x.max(1e-12) * extent.y.max(1e-12) * extent.z.max(1e-12);
        let cell = (volume / n as f64).cbrt().max(longest / MAX_CELLS_PER_AXIS).max(1e-9);
        let inv_cell = 1.0 / cell;
        let dims = [0, 1, 2].map(|i| ((extent[i] * inv_cell).floor() as usize + 1).max(1));
        let mut grid = Self { lo, hi, inv_cell, dims, start: vec![0; dims[0] * dims[1] * dims[2] + 1], vertices: vec![0; n] };
        let cells: Vec<usize> = rest.iter().map(|p| grid.cell_of(p)).collect();
        for &c in &cells {
            grid.start[c + 1] += 1;
        }
        for c in 1..grid.start.len() {
            grid.start[c] += grid.start[c - 1];
        }
        let mut next = grid.start.clone();
        for (v, &c) in cells.iter().enumerate() {
            grid.vertices[next[c] as usize] = v as u32;
            next[c] += 1;
        }
        grid
    }

    /// Vertices binned.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// Whether no vertex is binned.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// Index along axis `i` of coordinate `x`, clamped to the grid (monotone in `x`).
    #[inline]
    fn index(&self, i: usize, x: f64) -> usize {
        ((x - self.lo[i]) * self.inv_cell).floor().clamp(0.0, (self.dims[i] - 1) as f64) as usize
    }

    fn cell_of(&self, p: &Vec3) -> usize {
        let [i, j, k] = [0, 1, 2].map(|a| self.index(a, p[a]));
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    /// The vertices whose position may lie in the box `[lo, hi]` when every
    /// displacement component is within `bound` ([`displacement_bound`]), into
    /// `near`: ascending, or `near.all` when the box is not finite or covers
    /// more than half the grid's cells.
    pub fn near(&self, lo: &Vec3, hi: &Vec3, bound: f64, near: &mut Near) {
        near.list.clear();
        near.all = true;
        let grow = bound + QUERY_SLACK_M;
        if self.is_empty() || !grow.is_finite() || !(lo.iter().chain(hi.iter()).all(|c| c.is_finite())) {
            return;
        }
        let (qlo, qhi) = (lo.add_scalar(-grow), hi.add_scalar(grow));
        near.all = false;
        if (0..3).any(|i| qhi[i] < self.lo[i] || qlo[i] > self.hi[i] || qlo[i] > qhi[i]) {
            return;
        }
        let [a, b] = [qlo, qhi].map(|q| [0, 1, 2].map(|i| self.index(i, q[i])));
        let cells: usize = (0..3).map(|i| b[i] - a[i] + 1).product();
        if 2 * cells > self.start.len() - 1 {
            near.all = true;
            return;
        }
        let words = self.vertices.len().div_ceil(64);
        if near.marks.len() != words {
            near.marks.clear();
            near.marks.resize(words, 0);
        }
        let (mut first, mut last) = (usize::MAX, 0);
        for k in a[2]..=b[2] {
            for j in a[1]..=b[1] {
                let row = (k * self.dims[1] + j) * self.dims[0];
                let (s, e) = (self.start[row + a[0]] as usize, self.start[row + b[0] + 1] as usize);
                for &v in &self.vertices[s..e] {
                    let w = v as usize / 64;
                    near.marks[w] |= 1 << (v % 64);
                    first = first.min(w);
                    last = last.max(w);
                }
            }
        }
        if first == usize::MAX {
            return;
        }
        for w in first..=last {
            let mut bits = std::mem::take(&mut near.marks[w]);
            while bits != 0 {
                near.list.push((w * 64) as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every vertex inside a box (at its displaced position) is returned, the answer is ascending, and a small box
    /// returns few vertices.
    #[test]
    fn near_holds_every_vertex_in_the_box_and_few_others() {
        let mut next = crate::math::test_rng::uniform(0x2545f4914f6cdd1d);
        let rest: Vec<Vec3> = (0..5000).map(|_| Vec3::new(next(), next(), 0.5 * next()) * 0.15).collect();
        let grid = RestGrid::new(&rest);
        let mut near = Near::default();
        let mut small = 0;
        for round in 0..200 {
            let amp = if round % 3 == 0 { 0.0 } else { 0.004 * next() };
            let positions: Vec<Vec3> = rest.iter().map(|r| r + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * (2.0 * amp)).collect();
            let bound = displacement_bound(&positions, &rest);
            assert!(bound <= amp);
            let c = Vec3::new(next(), next(), next()) * 0.15;
            let half = Vec3::new(next(), next(), next()) * 0.02;
            let (lo, hi) = (c - half, c + half);
            grid.near(&lo, &hi, bound, &mut near);
            let inside: Vec<u32> = (0..rest.len() as u32).filter(|&v| (0..3).all(|i| positions[v as usize][i] >= lo[i] && positions[v as usize][i] <= hi[i])).collect();
            let mut got = Vec::new();
            near.for_each(rest.len(), |v| got.push(v as u32));
            assert!(got.windows(2).all(|w| w[0] < w[1]), "ascending");
            assert!(inside.iter().all(|v| got.binary_search(v).is_ok()), "round {round}: a vertex in the box is missing");
            if !near.all && got.len() < rest.len() / 4 {
                small += 1;
            }
        }
        assert!(small > 150, "most boxes are small and must not read the whole surface: {small}");
        assert!(near.marks.iter().all(|&w| w == 0), "the marks are cleared");
    }

    /// A box beyond the surface finds nothing; a box that is not finite, or covers the surface, is every vertex.
    #[test]
    fn far_boxes_are_empty_and_unbounded_ones_are_everything() {
        let rest: Vec<Vec3> = (0..1000).map(|k| Vec3::new((k % 10) as f64, ((k / 10) % 10) as f64, (k / 100) as f64) * 0.01).collect();
        let grid = RestGrid::new(&rest);
        let mut near = Near::default();
        grid.near(&Vec3::repeat(1.0), &Vec3::repeat(2.0), 0.0, &mut near);
        assert!(!near.all && near.list.is_empty());
        grid.near(&Vec3::repeat(-1.0), &Vec3::repeat(2.0), 0.0, &mut near);
        assert!(near.all);
        grid.near(&Vec3::zeros(), &Vec3::repeat(0.001), f64::INFINITY, &mut near);
        assert!(near.all);
        grid.near(&Vec3::new(f64::NAN, 0.0, 0.0), &Vec3::repeat(0.001), 0.0, &mut near);
        assert!(near.all);
        // a bound grows the box: the vertex at the origin is 1 mm from this box
        grid.near(&Vec3::repeat(-0.002), &Vec3::repeat(-0.001), 0.0, &mut near);
        assert!(!near.all && near.list.is_empty());
        grid.near(&Vec3::repeat(-0.002), &Vec3::repeat(-0.001), 0.001, &mut near);
        assert_eq!(near.list, [0]);
        assert_eq!(displacement_bound(&[Vec3::new(f64::NAN, 0.0, 0.0)], &[Vec3::zeros()]), f64::INFINITY);
        // a flat surface keeps a small grid
        let flat: Vec<Vec3> = (0..400).map(|k| Vec3::new((k % 20) as f64, (k / 20) as f64, 0.0) * 0.01).collect();
        assert!(RestGrid::new(&flat).start.len() <= 129 * 129 + 1);
    }
}
