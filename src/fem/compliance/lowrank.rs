//! Block-low-rank (BLR) storage of the compliance.
//!
//! In: the compliance's row nodes (ROI nodes first, Morton order, then the
//! other free surface nodes, Morton order), the number of ROI columns, the
//! model (its factor gives the columns) and a tolerance `10^-digits`.
//! Out: a [`BlockLowRank`] that returns any 3x3 block `K^-1[row, col]` and
//! accumulates `u_rows += K^-1[rows, cols] F` for a few nodal forces at a cost
//! that grows with the rank of the blocks, not with rows x forced columns.
//!
//! Layout: the ROI rows `[0, n_cols)` and the other rows `[n_cols, n_rows)` are
//! each cut into contiguous clusters of at most [`CLUSTER_NODES`] nodes: octree
//! cells of the Morton codes the rows are sorted by, consecutive cells packed
//! together (row clusters `0..nc` are the column clusters). Only blocks (row cluster I,
//! column cluster J) with `I >= J` are stored, column cluster after column
//! cluster; a ROI block with `I < J` is the transpose of block (J, I). A block
//! is *admissible* when `dist(box_I, box_J) >= ETA * max(diam_I, diam_J)`;
//! admissible blocks are compressed to `U V^T` (U: 3|I| x r, V: 3|J| x r,
//! column-major f64) by adaptive cross approximation with full pivoting on the
//! explicit block (no SVD recompression: see [`compress`]); the others, and any block whose rank would not save memory, are
//! stored dense (3|I| x 3|J|, column-major f64). Diagonal blocks (I == J) are
//! dense and made exactly symmetric (every entry above the diagonal is a copy
//! of its lower twin; the dense symmetric storage does the same for node
//! blocks and keeps the 3x3 diagonal blocks as solved).
//!
//! Stays true: every stored block satisfies `||A - U V^T||_F <= 10^-digits
//! ||A||_F` (the cross approximation stops there; dense blocks are exact); `block(p, q)` and `block(q, p)^T`
//! are bitwise equal for ROI nodes p, q; the build is sequential and uses no
//! randomness, so the same inputs give the same bits; the per-frame product
//! allocates nothing beyond the grow-only scratch it is given.
//!
//! Why f64 factors: at `digits >= 7` a rounding to f32 (relative 6e-8 per
//! entry) would exceed the stated tolerance; the factors are small (the
//! per-frame product reads a few MB), so f64 costs little.

use super::super::FemError;
use super::super::model::FemModel;
use crate::math::{Matrix3, Vec3};

/// Target nodes per cluster (rows and columns). Set when this storage was
/// introduced; no comparison of cluster sizes is on record. With 64 the
/// paper-12k compliance's blocks have mean rank 21.7, and at 8 digits it takes
/// 811 MB against f32's 1,102 MB (`FEM_BENCH_STORAGE=lowrank8 cargo bench
/// --bench fem -- paper`; docs/design-notes.md).
pub(super) const CLUSTER_NODES: usize = 64;
/// Admissibility parameter: a block is compressed when the distance of the two
/// cluster boxes is at least `ETA` times the larger box diagonal.
pub(super) const ETA: f64 = 0.5;
/// Rank marker of a block stored dense.
const DENSE: u32 = u32::MAX;

/// The BLR compliance (see the module documentation).
#[derive(Debug, Clone)]
pub(super) struct BlockLowRank {
    digits: u8,
    n_rows: usize,
    n_cols: usize,
    /// Row cluster starts (`clusters + 1` entries); clusters `0..nc` tile `[0, n_cols)`.
    starts: Vec<u32>,
    nc: usize,
    /// Cluster of every row.
    row_cluster: Vec<u32>,
    /// Per stored block (column cluster J, row clusters I >= J): rank or [`DENSE`].
    ranks: Vec<u32>,
    /// Offset of every stored block in `values` (`ranks.len() + 1` entries).
    offsets: Vec<usize>,
    values: Vec<f64>,
    max_rank: usize,
}

/// Counts of the stored blocks.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct BlockCounts {
    pub compressed: usize,
    pub dense: usize,
    pub mean_rank: f64,
    pub max_rank: usize,
}

/// Cluster starts over the ROI rows then the other rows, given the Morton
/// codes the rows are sorted by: each range is split recursively at its
/// highest differing code bit (octree cells) down to [`CLUSTER_NODES`] nodes,
/// then consecutive cells are packed while they fit in [`CLUSTER_NODES`].
/// Returns (starts with the row count last, number of ROI clusters).
pub(super) fn cluster_starts(roi_codes: &[u64], other_codes: &[u64]) -> (Vec<u32>, usize) {
    fn split(codes: &[u64], offset: usize, cells: &mut Vec<(usize, usize)>) {
        if codes.is_empty() {
            return;
        }
        if codes.len() <= CLUSTER_NODES {
            cells.push((offset, codes.len()));
            return;
        }
        let diff = codes[0] ^ codes[codes.len() - 1];
        let s = if diff == 0 {
            codes.len() / 2
        } else {
            let bit = 63 - diff.leading_zeros();
            codes.partition_point(|&c| (c >> bit) & 1 == 0)
        };
        split(&codes[..s], offset, cells);
        split(&codes[s..], offset + s, cells);
    }
    fn pack(codes: &[u64], offset: usize, starts: &mut Vec<u32>) {
        let mut cells = Vec::new();
        split(codes, offset, &mut cells);
        let mut size = CLUSTER_NODES;
        for (start, len) in cells {
            if size + len > CLUSTER_NODES {
                starts.push(start as u32);
                size = 0;
            }
            size += len;
        }
    }
    let mut starts = Vec::new();
    pack(roi_codes, 0, &mut starts);
    let nc = starts.len();
    pack(other_codes, roi_codes.len(), &mut starts);
    starts.push((roi_codes.len() + other_codes.len()) as u32);
    (starts, nc)
}

/// Index of stored block (I, J), `I >= J`, among `nr` row clusters.
#[inline]
fn block_index(i: usize, j: usize, nr: usize) -> usize {
    j * nr - j * j.saturating_sub(1) / 2 + (i - j)
}

/// Stored blocks for `nr` row and `nc <= nr` column clusters.
#[inline]
fn block_count(nr: usize, nc: usize) -> usize {
    if nc == 0 { 0 } else { block_index(nr - 1, nc - 1, nr) + 1 }
}

/// Entries of a block with `rank` (or dense) and `m x n` entries.
#[inline]
fn block_len(rank: u32, m: usize, n: usize) -> usize {
    if rank == DENSE { m * n } else { rank as usize * (m + n) }
}

/// Axis-aligned box of a cluster's rest positions.
fn cluster_box(rows: &[u32], positions: &[Vec3]) -> (Vec3, Vec3) {
    let mut lo = Vec3::repeat(f64::INFINITY);
    let mut hi = Vec3::repeat(f64::NEG_INFINITY);
    for &n in rows {
        lo = lo.inf(&positions[n as usize]);
        hi = hi.sup(&positions[n as usize]);
    }
    (lo, hi)
}

fn admissible(a: &(Vec3, Vec3), b: &(Vec3, Vec3)) -> bool {
    let gap = Vec3::from_fn(|k, _| (b.0[k] - a.1[k]).max(a.0[k] - b.1[k]).max(0.0));
    let diam = (a.1 - a.0).norm().max((b.1 - b.0).norm());
    gap.norm() >= ETA * diam
}

/// Scratch of the block compression, reused between blocks.
#[derive(Default)]
struct CompressWork {
    residual: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
}

/// Adaptive cross approximation with full pivoting on the explicit `m x n`
/// block `a` (column-major): stops when `||R||_F <= tol ||A||_F`. Returns the
/// rank (factors in `work.u` (m x k) and `work.v` (n x k)) and `||A||_F^2`,
/// or `None` when the rank would exceed `max_rank` or an entry is not finite.
fn cross_approximation(a: &[f64], m: usize, n: usize, tol: f64, max_rank: usize, work: &mut CompressWork) -> Option<(usize, f64)> {
    let r = &mut work.residual;
    r.clear();
    r.extend_from_slice(a);
    work.u.clear();
    work.v.clear();
    let mut norm2 = 0.0;
    for &x in r.iter() {
        norm2 += x * x;
    }
    if !norm2.is_finite() {
        return None;
    }
    let target = tol * tol * norm2;
    let mut res2 = norm2;
    let mut k = 0;
    while res2 > target {
        if k >= max_rank {
            return None;
        }
        // Pivot: the largest residual entry, first in column-major order on ties.
        let (mut idx, mut mag) = (0usize, 0.0f64);
        for (e, &x) in r.iter().enumerate() {
            if x.abs() > mag {
                mag = x.abs();
                idx = e;
            }
        }
        if !(mag > 0.0) {
            break;
        }
        let (pi, pj) = (idx % m, idx / m);
        let pivot = r[idx];
        work.u.extend_from_slice(&r[pj * m..(pj + 1) * m]);
        for c in 0..n {
            work.v.push(r[c * m + pi] / pivot);
        }
        let uk = &work.u[k * m..(k + 1) * m];
        let vk = &work.v[k * n..(k + 1) * n];
        res2 = 0.0;
        for (col, &vc) in r.chunks_exact_mut(m).zip(vk) {
            let mut s = 0.0;
            for (x, &ur) in col.iter_mut().zip(uk) {
                *x -= ur * vc;
                s += *x * *x;
            }
            res2 += s;
        }
        k += 1;
    }
    Some((k, norm2))
}

/// Compresses one `m x n` block (column-major) to `U V^T` within `tol`
/// (relative Frobenius) by cross approximation. Returns `U` then `V`
/// (column-major, `rank (m + n)` entries) appended to `out` and the rank, or
/// `None` when dense is smaller.
///
/// No SVD recompression of the factors: one was tried (QR of both factors, SVD
/// of the small core, truncation at half the tolerance) and on the real brain
/// it broke the tolerance on a few blocks (relative errors up to 2e-3 at
/// digits 8, against 3e-8 for the cross approximation alone); it saved 11 % of
/// the memory.
fn compress(a: &[f64], m: usize, n: usize, tol: f64, work: &mut CompressWork, out: &mut Vec<f64>) -> Option<usize> {
    // Only worth it while rank (m + n) < m n.
    let max_rank = (m * n).saturating_sub(1) / (m + n);
    let (k, _) = cross_approximation(a, m, n, tol, max_rank, work)?;
    out.extend_from_slice(&work.u);
    out.extend_from_slice(&work.v);
    Some(k)
}

/// Reserves `extra` more entries or reports the memory request.
fn reserve(values: &mut Vec<f64>, extra: usize) -> Result<(), FemError> {
    values.try_reserve(extra).map_err(|_| FemError::OutOfMemory { what: "low-rank compliance", bytes: (values.len() + extra) * 8 })
}

impl BlockLowRank {
    /// Computes the BLR compliance over `row_nodes` x the first `n_cols` of them.
    pub(super) fn build(
        model: &FemModel,
        row_nodes: &[u32],
        n_cols: usize,
        (starts, nc): (Vec<u32>, usize),
        digits: u8,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Self, FemError> {
        let n_rows = row_nodes.len();
        let nr = starts.len() - 1;
        let range = |c: usize| starts[c] as usize..starts[c + 1] as usize;
        let positions = &model.mesh.positions;
        let boxes: Vec<(Vec3, Vec3)> = (0..nr).map(|c| cluster_box(&row_nodes[range(c)], positions)).collect();
        let tol = 10f64.powi(-(digits as i32));
        let n_free = model.dofs.dof_count();
        let row_dofs: Vec<usize> = row_nodes.iter().map(|&n| model.dofs.dof(n).unwrap_or(0)).collect();
        let widest = (0..nc).map(|c| range(c).len()).max().unwrap_or(0);
        let mut rhs = faer::Mat::<f64>::zeros(n_free, 3 * widest);
        let chol = model.chol.get()?;
        let mut scratch = chol.scratch(3 * widest.max(1))?;
        let n_blocks = block_count(nr, nc);
        let mut ranks: Vec<u32> = Vec::with_capacity(n_blocks);
        let mut offsets: Vec<usize> = Vec::with_capacity(n_blocks + 1);
        let mut values: Vec<f64> = Vec::new();
        let mut block: Vec<f64> = Vec::new();
        let mut work = CompressWork::default();
        progress(0, n_cols);
        for j in 0..nc {
            let cols = range(j);
            let nb = cols.len();
            rhs.fill(0.0);
            for (b, &d) in row_dofs[cols.clone()].iter().enumerate() {
                for c in 0..3 {
                    rhs[(d + c, 3 * b + c)] = 1.0;
                }
            }
            chol.solve_in_place(rhs.as_mut().subcols_mut(0, 3 * nb), &mut scratch);
            let n = 3 * nb;
            for i in j..nr {
                let rows = range(i);
                let m = 3 * rows.len();
                block.clear();
                block.resize(m * n, 0.0);
                for (c, out) in block.chunks_exact_mut(m).enumerate() {
                    let col = rhs.col(c).try_as_col_major().map(|c| c.as_slice()).unwrap_or(&[]);
                    for (p, &d) in row_dofs[rows.clone()].iter().enumerate() {
                        out[3 * p..3 * p + 3].copy_from_slice(&col[d..d + 3]);
                    }
                }
                offsets.push(values.len());
                if i == j {
                    // Exact symmetry: every entry above the diagonal mirrors its lower twin
                    // (node blocks above the diagonal and the upper half of the 3x3 diagonal blocks).
                    for c in 0..m {
                        for r in 0..c {
                            block[c * m + r] = block[r * m + c];
                        }
                    }
                }
                let start = values.len();
                let rank = if i != j && admissible(&boxes[i], &boxes[j]) {
                    reserve(&mut values, m * n)?;
                    compress(&block, m, n, tol, &mut work, &mut values)
                } else {
                    None
                };
                match rank {
                    Some(r) => ranks.push(r as u32),
                    None => {
                        values.truncate(start);
                        reserve(&mut values, m * n)?;
                        values.extend_from_slice(&block);
                        ranks.push(DENSE);
                    }
                }
            }
            progress(cols.end, n_cols);
        }
        offsets.push(values.len());
        values.shrink_to_fit();
        Ok(Self::assemble(digits, n_rows, n_cols, starts, nc, ranks, offsets, values))
    }

    #[allow(clippy::too_many_arguments)]
    fn assemble(digits: u8, n_rows: usize, n_cols: usize, starts: Vec<u32>, nc: usize, ranks: Vec<u32>, offsets: Vec<usize>, values: Vec<f64>) -> Self {
        let mut row_cluster = vec![0u32; n_rows];
        for c in 0..starts.len() - 1 {
            row_cluster[starts[c] as usize..starts[c + 1] as usize].fill(c as u32);
        }
        let max_rank = ranks.iter().filter(|&&r| r != DENSE).max().copied().unwrap_or(0) as usize;
        Self { digits, n_rows, n_cols, starts, nc, row_cluster, ranks, offsets, values, max_rank }
    }

    /// Decimal digits of the per-block tolerance.
    pub(super) fn digits(&self) -> u8 {
        self.digits
    }

    /// Row cluster starts and the number of column clusters.
    pub(super) fn clusters(&self) -> (&[u32], usize) {
        (&self.starts, self.nc)
    }

    /// Bytes of stored entries (factors and dense blocks) and the block table.
    pub(super) fn bytes(&self) -> usize {
        self.values.len() * 8 + self.ranks.len() * 4 + self.starts.len() * 4
    }

    /// Compressed and dense block counts and ranks.
    pub(super) fn counts(&self) -> BlockCounts {
        let mut c = BlockCounts::default();
        let mut sum = 0usize;
        for &r in &self.ranks {
            if r == DENSE {
                c.dense += 1;
            } else {
                c.compressed += 1;
                sum += r as usize;
            }
        }
        c.max_rank = self.max_rank;
        c.mean_rank = if c.compressed > 0 { sum as f64 / c.compressed as f64 } else { 0.0 };
        c
    }

    #[inline]
    fn size(&self, c: usize) -> usize {
        (self.starts[c + 1] - self.starts[c]) as usize
    }

    /// `K^-1[row node, col node]` (`col < n_cols`).
    #[inline]
    pub(super) fn block(&self, row: usize, col: usize) -> Matrix3<f64> {
        let ci = self.row_cluster[row] as usize;
        let cj = self.row_cluster[col] as usize;
        let p = row - self.starts[ci] as usize;
        let q = col - self.starts[cj] as usize;
        if ci >= cj { self.stored(ci, cj, p, q) } else { self.stored(cj, ci, q, p).transpose() }
    }

    #[inline]
    fn stored(&self, i: usize, j: usize, p: usize, q: usize) -> Matrix3<f64> {
        let b = block_index(i, j, self.starts.len() - 1);
        let (m, n) = (3 * self.size(i), 3 * self.size(j));
        let data = &self.values[self.offsets[b]..self.offsets[b + 1]];
        let rank = self.ranks[b];
        if rank == DENSE {
            return Matrix3::from_fn(|a, c| data[(3 * q + c) * m + 3 * p + a]);
        }
        let (u, v) = data.split_at(rank as usize * m);
        Matrix3::from_fn(|a, c| {
            let mut s = 0.0;
            for k in 0..rank as usize {
                s += u[k * m + 3 * p + a] * v[k * n + 3 * q + c];
            }
            s
        })
    }

    /// `u[row] += sum_k K^-1[row, col_k] F_k` over every row, for forces sorted
    /// by ascending column. `scratch` grows to `3 n_rows + max rank` f64 once.
    pub(super) fn accumulate(&self, forces: &[(usize, Vec3)], u: &mut [Vec3], scratch: &mut Vec<f64>) {
        let need = 3 * self.n_rows + self.max_rank;
        if scratch.len() < need {
            scratch.resize(need, 0.0);
        }
        let (acc, t) = scratch.split_at_mut(3 * self.n_rows);
        acc.fill(0.0);
        let nr = self.starts.len() - 1;
        let mut k0 = 0;
        while k0 < forces.len() && forces[k0].0 < self.n_cols {
            let j = self.row_cluster[forces[k0].0] as usize;
            let (j0, j1) = (self.starts[j] as usize, self.starts[j + 1] as usize);
            let mut k1 = k0;
            while k1 < forces.len() && forces[k1].0 < j1 {
                k1 += 1;
            }
            let fj = &forces[k0..k1];
            for i in 0..nr {
                let (i0, i1) = (self.starts[i] as usize, self.starts[i + 1] as usize);
                let out = &mut acc[3 * i0..3 * i1];
                if i >= j {
                    let b = block_index(i, j, nr);
                    let data = &self.values[self.offsets[b]..self.offsets[b + 1]];
                    let (m, n) = (3 * (i1 - i0), 3 * (j1 - j0));
                    match self.ranks[b] {
                        DENSE => dense_times(data, m, fj, j0, out),
                        r => {
                            let (uf, vf) = data.split_at(r as usize * m);
                            low_rank_times(uf, vf, m, n, r as usize, fj, j0, &mut t[..r as usize], out);
                        }
                    }
                } else {
                    // ROI block above the diagonal: the transpose of stored (j, i).
                    let b = block_index(j, i, nr);
                    let data = &self.values[self.offsets[b]..self.offsets[b + 1]];
                    let (m, n) = (3 * (j1 - j0), 3 * (i1 - i0));
                    match self.ranks[b] {
                        DENSE => dense_transpose_times(data, m, fj, j0, out),
                        r => {
                            let (uf, vf) = data.split_at(r as usize * m);
                            low_rank_times(vf, uf, n, m, r as usize, fj, j0, &mut t[..r as usize], out);
                        }
                    }
                }
            }
            k0 = k1;
        }
        for (ui, a) in u.iter_mut().zip(acc.chunks_exact(3)) {
            *ui += Vec3::new(a[0], a[1], a[2]);
        }
    }
}

/// `out += D f` for a dense `m x n` block (column-major) and forces at local columns `c - j0`.
#[inline]
fn dense_times(d: &[f64], m: usize, forces: &[(usize, Vec3)], j0: usize, out: &mut [f64]) {
    for &(c, f) in forces {
        let q = c - j0;
        for comp in 0..3 {
            let fc = f[comp];
            let col = &d[(3 * q + comp) * m..(3 * q + comp + 1) * m];
            for (o, &x) in out.iter_mut().zip(col) {
                *o += x * fc;
            }
        }
    }
}

/// `out += D^T f` for a dense `m x n` block (column-major), forces at local rows `c - j0`.
#[inline]
fn dense_transpose_times(d: &[f64], m: usize, forces: &[(usize, Vec3)], j0: usize, out: &mut [f64]) {
    for (o, col) in out.iter_mut().zip(d.chunks_exact(m)) {
        let mut s = 0.0;
        for &(c, f) in forces {
            let q = 3 * (c - j0);
            s += col[q] * f.x + col[q + 1] * f.y + col[q + 2] * f.z;
        }
        *o += s;
    }
}

/// `out += A (B^T f)` with `A` (m x r) and `B` (n x r) column-major, forces at
/// local rows `c - j0` of `B`; `t` holds the r intermediate values.
#[allow(clippy::too_many_arguments)]
#[inline]
fn low_rank_times(a: &[f64], b: &[f64], m: usize, n: usize, r: usize, forces: &[(usize, Vec3)], j0: usize, t: &mut [f64], out: &mut [f64]) {
    for (k, tk) in t.iter_mut().enumerate().take(r) {
        let col = &b[k * n..(k + 1) * n];
        let mut s = 0.0;
        for &(c, f) in forces {
            let q = 3 * (c - j0);
            s += col[q] * f.x + col[q + 1] * f.y + col[q + 2] * f.z;
        }
        *tk = s;
    }
    for (k, &tk) in t.iter().enumerate().take(r) {
        let col = &a[k * m..(k + 1) * m];
        for (o, &x) in out.iter_mut().zip(col) {
            *o += x * tk;
        }
    }
}

// ------------------------------------------------------------------ cache

impl BlockLowRank {
    /// The three counts written before the arrays: row clusters, column clusters, values.
    pub(super) fn meta(&self) -> [u64; 3] {
        [(self.starts.len() - 1) as u64, self.nc as u64, self.values.len() as u64]
    }

    /// Byte sections written after the meta: cluster starts, ranks, values.
    pub(super) fn sections(&self) -> [&[u8]; 3] {
        [bytemuck::cast_slice(&self.starts), bytemuck::cast_slice(&self.ranks), bytemuck::cast_slice(&self.values)]
    }

    /// Rebuilds the storage from cached sections; `read(bytes)` fills a buffer
    /// from the file (hashing it). Everything is checked against the layout
    /// this compliance would build; any mismatch is an `Err(reason)`.
    pub(super) fn read(
        digits: u8,
        n_rows: usize,
        n_cols: usize,
        (want_starts, nc): (Vec<u32>, usize),
        meta: [u64; 3],
        remaining: usize,
        read: &mut dyn FnMut(&mut [u8]) -> Result<(), String>,
    ) -> Result<Self, String> {
        let nr = want_starts.len() - 1;
        if meta[0] != nr as u64 || meta[1] != nc as u64 {
            return Err(format!("cluster counts {} x {}, expected {nr} x {nc}", meta[0], meta[1]));
        }
        let expected = usize::try_from(meta[2])
            .ok()
            .and_then(|nv| nv.checked_mul(8))
            .and_then(|b| b.checked_add(4 * (nr + 1) + 4 * block_count(nr, nc)));
        if expected != Some(remaining) {
            return Err(format!("{remaining} bytes of blocks, expected {expected:?}"));
        }
        let mut starts = vec![0u32; nr + 1];
        read(bytemuck::cast_slice_mut(&mut starts))?;
        if starts != want_starts {
            return Err("cluster starts mismatch".into());
        }
        let n_blocks = block_count(nr, nc);
        let mut ranks = vec![0u32; n_blocks];
        read(bytemuck::cast_slice_mut(&mut ranks))?;
        let size = |c: usize| (want_starts[c + 1] - want_starts[c]) as usize;
        let mut offsets = Vec::with_capacity(n_blocks + 1);
        let mut total = 0usize;
        for j in 0..nc {
            for i in j..nr {
                let (m, n) = (3 * size(i), 3 * size(j));
                let r = ranks[block_index(i, j, nr)];
                if r != DENSE && (r as usize) * (m + n) >= m * n {
                    return Err(format!("block ({i}, {j}) has rank {r}, above the dense break-even"));
                }
                offsets.push(total);
                total += block_len(r, m, n);
            }
        }
        offsets.push(total);
        if total as u64 != meta[2] {
            return Err(format!("block table needs {total} values, file has {}", meta[2]));
        }
        let mut values: Vec<f64> = Vec::new();
        values.try_reserve_exact(total).map_err(|_| "out of memory".to_string())?;
        values.resize(total, 0.0);
        read(bytemuck::cast_slice_mut(&mut values))?;
        Ok(Self::assemble(digits, n_rows, n_cols, starts, nc, ranks, offsets, values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clusters_tile_rows_and_columns_separately() {
        for (rows, cols) in [(1000usize, 300usize), (64, 64), (65, 1), (500, 129), (10, 0)] {
            // Sorted pseudo-random codes with runs of equal values.
            let codes: Vec<u64> = (0..rows as u64).map(|i| (i * 2654435761 % 1000) / 3).collect();
            let (mut a, mut b) = (codes[..cols].to_vec(), codes[cols..].to_vec());
            a.sort_unstable();
            b.sort_unstable();
            let (s, nc) = cluster_starts(&a, &b);
            assert_eq!(s[0], 0);
            assert_eq!(*s.last().unwrap() as usize, rows);
            assert_eq!(s[nc] as usize, cols, "column clusters must end exactly at the ROI end ({rows}, {cols})");
            for w in s.windows(2) {
                let len = (w[1] - w[0]) as usize;
                assert!(len >= 1 && len <= CLUSTER_NODES, "cluster of {len} nodes out of 1..={CLUSTER_NODES}");
            }
        }
    }

    #[test]
    fn block_index_enumerates_the_lower_block_triangle_in_order() {
        let (nr, nc) = (7, 4);
        let mut k = 0;
        for j in 0..nc {
            for i in j..nr {
                assert_eq!(block_index(i, j, nr), k, "block ({i}, {j})");
                k += 1;
            }
        }
    }

    /// The kernel 1/|x - y| between two separated point clouds is numerically low rank.
    #[test]
    fn compression_meets_the_tolerance_with_a_small_rank() {
        let (m, n) = (90, 60);
        let x: Vec<Vec3> = (0..m).map(|i| Vec3::new((i % 9) as f64 * 0.1, (i / 9) as f64 * 0.1, 0.0)).collect();
        let y: Vec<Vec3> = (0..n).map(|i| Vec3::new(3.0 + (i % 6) as f64 * 0.1, (i / 6) as f64 * 0.1, 0.5)).collect();
        let mut a = vec![0.0; m * n];
        for c in 0..n {
            for r in 0..m {
                a[c * m + r] = 1.0 / (x[r] - y[c]).norm();
            }
        }
        let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
        for digits in [4, 8, 12] {
            let tol = 10f64.powi(-digits);
            let mut work = CompressWork::default();
            let mut out = Vec::new();
            let r = compress(&a, m, n, tol, &mut work, &mut out).expect("this kernel block is compressible");
            assert_eq!(out.len(), r * (m + n));
            let (u, v) = out.split_at(r * m);
            let mut err = 0.0;
            for c in 0..n {
                for row in 0..m {
                    let approx: f64 = (0..r).map(|k| u[k * m + row] * v[k * n + c]).sum();
                    err += (a[c * m + row] - approx).powi(2);
                }
            }
            let rel = err.sqrt() / norm;
            assert!(rel <= tol, "digits {digits}: relative Frobenius error {rel:e} above {tol:e} (rank {r})");
            // Cross approximation alone (no SVD recompression) gives a few more than the SVD rank
            // (25 at 12 digits here); dense would be 35.
            assert!(r <= 28, "digits {digits}: rank {r} is not low for a well-separated kernel block");
        }
    }

    #[test]
    fn incompressible_blocks_stay_dense() {
        // The identity has full rank: no U V^T is smaller than it.
        let m = 12;
        let a: Vec<f64> = (0..m * m).map(|e| if e % (m + 1) == 0 { 1.0 } else { 0.0 }).collect();
        let mut out = Vec::new();
        assert!(compress(&a, m, m, 1e-6, &mut CompressWork::default(), &mut out).is_none(), "the identity must stay dense");
        let zero = vec![0.0; m * m];
        assert_eq!(compress(&zero, m, m, 1e-6, &mut CompressWork::default(), &mut out), Some(0), "a zero block has rank 0");
    }
}
