//! Persistent Cholesky factor of the contact compliance `W = C K^-1 C^T` across frames.
//!
//! In: each frame the enforced (spatula) nodes, sorted; a function giving the 3x3 block `K^-1[p, q]`; per
//! active-set iteration the sphere rows. Out: a factor `W = L L^T` of the frame's rows and solves with it.
//!
//! Order rule (deterministic, a function of the frame history only): enforced nodes that persist from the previous
//! frame keep their relative order; new ones are appended in ascending node index. Then
//! - same set: W and L are reused (only the right-hand side changes);
//! - nodes only added: the new rows are gathered and L is extended by block Cholesky (`L21 = W21 L11^-T`,
//!   `L22 L22^T = W22 - L21 L21^T`);
//! - nodes removed: W is compacted; L's leading block before the first removed node is kept (its kept rows are
//!   unchanged) and the trailing block is refactored from `W22 - L21 L21^T`.
//! Sphere rows come after the enforced rows and are re-appended each active-set iteration the same way.
//! Dependent rows follow [`super::dense`]: a pivot below `DEPENDENT_PIVOT * W_ii` drops the row (earlier rows
//! kept). When a pivot fails in an incremental step, the whole enforced block is refactored with the
//! pivot-dropping kernel, so the result is that of a full factorization.
//! Stays true: no allocation once buffers have grown to the frame size; fixed iteration order.

use super::dense::{self, DEPENDENT_PIVOT, DenseWorkspace};
use crate::math::Matrix3;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltRegularization, cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::triangular::BlockStructure;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, MatMut, MatRef, Par, Spec};

/// What the last enforced update did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FactorUpdate {
    /// No enforced rows.
    #[default]
    Empty,
    /// Same node set: factor reused.
    Reused,
    /// Rows appended to the previous factor.
    Extended,
    /// Rows from the first changed position refactored.
    Trailing,
    /// Full refactorization (first frame, or a dependent row was found).
    Full,
}

/// Persistent factor of the enforced block plus the per-iteration sphere block.
#[derive(Default)]
pub struct ContactFactor {
    /// Enforced nodes in factor order.
    nodes: Vec<u32>,
    /// The same, ascending.
    nodes_sorted: Vec<u32>,
    /// Leading dimension of `w` and `l` (>= enforced rows).
    ld: usize,
    /// Enforced W, lower triangle, column major with stride `ld`.
    w: Vec<f64>,
    /// Its factor (lower triangle).
    l: Vec<f64>,
    /// Enforced rows dropped as dependent.
    dropped: Vec<bool>,
    any_dropped: bool,
    /// Sphere rows: `s` rows; `y = L_EE^-1 W_ES` (n x s, column major), `ls` the s x s factor.
    s: usize,
    w_es: Vec<f64>,
    w_ss: Vec<f64>,
    ls: Vec<f64>,
    sphere_dense: DenseWorkspace,
    sphere_diag: Vec<f64>,
    chol_scratch: Option<(usize, MemBuffer)>,
    full: Vec<f64>,
    full_l: Vec<f64>,
    full_dense: DenseWorkspace,
    compact_rows: Vec<usize>,
    last_update: FactorUpdate,
}

impl std::fmt::Debug for ContactFactor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContactFactor").field("enforced_nodes", &self.nodes.len()).field("sphere_rows", &self.s).finish()
    }
}

impl ContactFactor {
    /// Enforced rows.
    pub fn enforced_rows(&self) -> usize {
        3 * self.nodes.len()
    }

    /// All rows (enforced + sphere).
    pub fn rows(&self) -> usize {
        self.enforced_rows() + self.s
    }

    /// What the last enforced update did.
    pub fn last_update(&self) -> FactorUpdate {
        self.last_update
    }

    /// Forgets the factor (the next update is a full one).
    pub fn reset(&mut self) {
        self.nodes.clear();
        self.nodes_sorted.clear();
        self.s = 0;
    }

    /// The persistent order (see the module doc) for this frame's enforced nodes (`sorted`: ascending, distinct).
    pub fn order_for(&self, sorted: &[u32], out: &mut Vec<u32>) {
        out.clear();
        out.extend(self.nodes.iter().copied().filter(|n| sorted.binary_search(n).is_ok()));
        out.extend(sorted.iter().copied().filter(|n| self.nodes_sorted.binary_search(n).is_err()));
    }

    /// Updates the enforced factor to `order` (from [`Self::order_for`]); `block(p, q)` returns `K^-1[p, q]`.
    pub fn update_enforced(&mut self, order: &[u32], block: &dyn Fn(u32, u32) -> Matrix3<f64>) {
        self.s = 0;
        let m = order.len();
        let n = 3 * m;
        // kept prefix: order[..kept] are previous nodes, in previous order
        let kept = order.iter().take_while(|x| self.nodes_sorted.binary_search(x).is_ok()).count();
        let mut first_removed = self.nodes.len();
        for (i, &p) in self.nodes.iter().enumerate() {
            if i >= kept || order[i] != p {
                first_removed = i;
                break;
            }
        }
        if kept == self.nodes.len() && m == kept && m > 0 {
            self.last_update = FactorUpdate::Reused;
            return;
        }
        let q = if self.any_dropped { 0 } else { 3 * first_removed.min(kept) };
        self.compact(&order[..kept], q, n);
        self.gather_new(order, kept, block);
        self.nodes.clear();
        self.nodes.extend_from_slice(order);
        self.nodes_sorted.clear();
        self.nodes_sorted.extend_from_slice(order);
        self.nodes_sorted.sort_unstable();
        self.dropped.clear();
        self.dropped.resize(n, false);
        self.any_dropped = false;
        if n == 0 {
            self.last_update = FactorUpdate::Empty;
            return;
        }
        let new_start = 3 * kept;
        let ok = self.refactor_from(q, new_start, n);
        let ld = self.ld;
        let healthy = ok
            && (q..n).all(|i| {
                let d = self.l[i * ld + i];
                d.is_finite() && d * d > DEPENDENT_PIVOT * self.w[i * ld + i]
            });
        self.last_update = if q == 0 {
            FactorUpdate::Full
        } else if q == new_start {
            FactorUpdate::Extended
        } else {
            FactorUpdate::Trailing
        };
        if !healthy {
            self.refactor_with_pivot_drop(n);
            self.last_update = FactorUpdate::Full;
        }
    }

    /// Moves the kept nodes' rows of W (and of L in its first `q` columns) to their new places (`kept`: in new
    /// order, a subsequence of the old), growing the storage to `n` rows if needed.
    fn compact(&mut self, kept: &[u32], q: usize, n: usize) {
        // row map of the kept rows (new row -> old row)
        self.compact_rows.clear();
        {
            let mut old = 0;
            for &p in kept {
                while self.nodes[old] != p {
                    old += 1;
                }
                for r in 0..3 {
                    self.compact_rows.push(3 * old + r);
                }
                old += 1;
            }
        }
        if n > self.ld {
            let ld = n.max(2 * self.ld).max(48);
            let mut w = vec![0.0; ld * ld];
            let mut l = vec![0.0; ld * ld];
            for (jn, &jo) in self.compact_rows.iter().enumerate() {
                for (in_, &io) in self.compact_rows.iter().enumerate().skip(jn) {
                    w[jn * ld + in_] = self.w[jo * self.ld + io];
                    if jn < q {
                        l[jn * ld + in_] = self.l[jo * self.ld + io];
                    }
                }
            }
            self.w = w;
            self.l = l;
            self.ld = ld;
        } else {
            let ld = self.ld;
            // in place: destination index <= source index, visited ascending
            for jn in 0..self.compact_rows.len() {
                let jo = self.compact_rows[jn];
                for in_ in jn..self.compact_rows.len() {
                    let io = self.compact_rows[in_];
                    self.w[jn * ld + in_] = self.w[jo * ld + io];
                    if jn < q {
                        self.l[jn * ld + in_] = self.l[jo * ld + io];
                    }
                }
            }
        }
    }

    /// Gathers the rows of W of the new nodes `order[kept..]` against every node up to themselves.
    fn gather_new(&mut self, order: &[u32], kept: usize, block: &dyn Fn(u32, u32) -> Matrix3<f64>) {
        let ld = self.ld;
        for a in kept..order.len() {
            for b in 0..=a {
                let blk = block(order[a], order[b]);
                for c in 0..3 {
                    for r in 0..3 {
                        self.w[(3 * b + c) * ld + 3 * a + r] = blk[(r, c)];
                    }
                }
            }
        }
    }

    /// Refactors the enforced block from column `q` on (`q` = 0: in full): the new nodes' rows (from `new_start`) in
    /// the kept leading columns, `L21 = W21 L11^-T`, then the trailing block. False when its Cholesky fails.
    fn refactor_from(&mut self, q: usize, new_start: usize, n: usize) -> bool {
        let ld = self.ld;
        // rows of new nodes in the kept leading columns: L21 = W21 L11^-T
        for j in 0..q {
            for i in new_start..n {
                self.l[j * ld + i] = self.w[j * ld + i];
            }
        }
        // trailing block: W22 (lower)
        for j in q..n {
            for i in j..n {
                self.l[j * ld + i] = self.w[j * ld + i];
            }
        }
        {
            let lm = MatMut::from_column_major_slice_with_stride_mut(&mut self.l[..], ld, ld, ld);
            let lm = lm.submatrix_mut(0, 0, n, n);
            let (mut left, mut right) = lm.split_at_col_mut(q);
            if q > 0 && new_start < n {
                let (top, bottom) = left.rb_mut().split_at_row_mut(q);
                let l11 = top.rb();
                let x = bottom.submatrix_mut(new_start - q, 0, n - new_start, q);
                faer::linalg::triangular_solve::solve_lower_triangular_in_place(l11, x.transpose_mut(), Par::Seq);
            }
            if q > 0 {
                let l21 = left.rb().submatrix(q, 0, n - q, q);
                let dst = right.rb_mut().submatrix_mut(q, 0, n - q, n - q);
                faer::linalg::matmul::triangular::matmul(
                    dst,
                    BlockStructure::TriangularLower,
                    Accum::Add,
                    l21,
                    BlockStructure::Rectangular,
                    l21.transpose(),
                    BlockStructure::Rectangular,
                    -1.0,
                    Par::Seq,
                );
            }
            let t = n - q;
            if self.chol_scratch.as_ref().is_none_or(|(cap, _)| *cap < t) {
                let req = cholesky_in_place_scratch::<f64>(t.max(self.ld), Par::Seq, Spec::default());
                self.chol_scratch = Some((t.max(self.ld), MemBuffer::new(req)));
            }
            match self.chol_scratch.as_mut() {
                Some((_, buf)) => {
                    let s = right.submatrix_mut(q, 0, t, t);
                    cholesky_in_place(s, LltRegularization::default(), Par::Seq, MemStack::new(buf), Spec::default()).is_ok()
                }
                None => false,
            }
        }
    }

    /// Full factorization of the enforced block with the pivot-dropping kernel.
    fn refactor_with_pivot_drop(&mut self, n: usize) {
        let ld = self.ld;
        self.full.clear();
        self.full.resize(n * n, 0.0);
        for j in 0..n {
            for i in j..n {
                let v = self.w[j * ld + i];
                self.full[j * n + i] = v;
                self.full[i * n + j] = v;
            }
        }
        dense::factor(&self.full, &mut self.full_l, n, &mut self.full_dense);
        for j in 0..n {
            for i in 0..n {
                self.l[j * ld + i] = if i >= j { self.full_l[j * n + i] } else { 0.0 };
            }
        }
        self.dropped.clear();
        self.dropped.extend_from_slice(&self.full_dense.dropped);
        self.any_dropped = self.dropped.iter().any(|d| *d);
    }

    /// Appends `s` sphere rows: `w_es` (enforced rows x s, column major: column t holds `W[enforced, sphere t]`) and
    /// `w_ss` (s x s, column major, full symmetric). Factors `S = W_SS - Y^T Y`, `Y = L_EE^-1 W_ES`, dropping
    /// dependent rows relative to the diagonal of `W_SS`.
    pub fn set_sphere_rows(&mut self, s: usize, w_es: &[f64], w_ss: &[f64]) {
        let n = self.enforced_rows();
        self.s = s;
        self.w_es.clear();
        self.w_es.extend_from_slice(&w_es[..n * s]);
        if n > 0 && s > 0 {
            let l = MatRef::from_column_major_slice_with_stride(&self.l[..], self.ld, n, self.ld).submatrix(0, 0, n, n);
            let y = MatMut::from_column_major_slice_mut(&mut self.w_es[..n * s], n, s);
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(l, y, Par::Seq);
            for t in 0..s {
                for (i, d) in self.dropped.iter().enumerate() {
                    if *d {
                        self.w_es[t * n + i] = 0.0;
                    }
                }
            }
        }
        self.w_ss.clear();
        self.w_ss.extend_from_slice(&w_ss[..s * s]);
        // S = W_SS - Y^T Y (symmetric: each dot once, the same sum for both halves)
        for a in 0..s {
            let ya = &self.w_es[a * n..a * n + n];
            for b in 0..=a {
                let yb = &self.w_es[b * n..b * n + n];
                let dot: f64 = ya.iter().zip(yb).map(|(x, y)| x * y).sum();
                self.w_ss[b * s + a] -= dot;
                if b != a {
                    self.w_ss[a * s + b] -= dot;
                }
            }
        }
        self.sphere_diag.clear();
        self.sphere_diag.extend((0..s).map(|i| w_ss[i * s + i]));
        dense::factor_with_reference(&self.w_ss, &mut self.ls, s, &self.sphere_diag, &mut self.sphere_dense);
    }

    /// Rows dropped as dependent (enforced then sphere).
    pub fn dropped(&self) -> impl Iterator<Item = bool> + '_ {
        self.dropped.iter().copied().chain(self.sphere_dense.dropped.iter().take(self.s).copied())
    }

    /// Solves `W x = b` in place (`b` has [`Self::rows`] entries); dropped rows get 0.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let n = self.enforced_rows();
        let s = self.s;
        let (be, bs) = b.split_at_mut(n);
        let bs = &mut bs[..s];
        for (i, d) in self.dropped.iter().enumerate() {
            if *d {
                be[i] = 0.0;
            }
        }
        if n > 0 {
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(self.l_ref(), MatMut::from_column_major_slice_mut(be, n, 1), Par::Seq);
            for (i, d) in self.dropped.iter().enumerate() {
                if *d {
                    be[i] = 0.0;
                }
            }
        }
        if s > 0 {
            for t in 0..s {
                let y = &self.w_es[t * n..t * n + n];
                bs[t] -= y.iter().zip(be.iter()).map(|(a, x)| a * x).sum::<f64>();
            }
            dense::solve_in_place(&self.ls, s, &self.sphere_dense.dropped, bs);
            for t in 0..s {
                let y = &self.w_es[t * n..t * n + n];
                let xt = bs[t];
                if xt != 0.0 {
                    for (bi, a) in be.iter_mut().zip(y) {
                        *bi -= a * xt;
                    }
                }
            }
        }
        if n > 0 {
            faer::linalg::triangular_solve::solve_upper_triangular_in_place(
                self.l_ref().transpose(),
                MatMut::from_column_major_slice_mut(be, n, 1),
                Par::Seq,
            );
            for (i, d) in self.dropped.iter().enumerate() {
                if *d {
                    be[i] = 0.0;
                }
            }
        }
    }

    /// Cheap conditioning estimate `(max L_ii / min L_ii)^2` over kept rows (the sphere block's from its Schur factor).
    pub fn conditioning_estimate(&self) -> f64 {
        let n = self.enforced_rows();
        let mut lo = f64::INFINITY;
        let mut hi: f64 = 0.0;
        for i in 0..n {
            if !self.dropped[i] {
                let d = self.l[i * self.ld + i].abs();
                lo = lo.min(d);
                hi = hi.max(d);
            }
        }
        for i in 0..self.s {
            if !self.sphere_dense.dropped[i] {
                let d = self.ls[i * self.s + i].abs();
                lo = lo.min(d);
                hi = hi.max(d);
            }
        }
        if hi == 0.0 { 1.0 } else { (hi / lo).powi(2) }
    }

    /// The enforced factor `L_EE` (n x n view, n > 0).
    fn l_ref(&self) -> MatRef<'_, f64> {
        let n = self.enforced_rows();
        MatRef::from_column_major_slice_with_stride(&self.l[..], self.ld, n, self.ld).submatrix(0, 0, n, n)
    }

    /// Copies W's enforced block (full symmetric) into `out`, column major with leading dimension `t` (>= its rows).
    pub fn copy_enforced_w(&self, out: &mut [f64], t: usize) {
        let n = self.enforced_rows();
        for j in 0..n {
            for i in j..n {
                let v = self.w[j * self.ld + i];
                out[j * t + i] = v;
                out[i * t + j] = v;
            }
        }
    }
}
