//! Small dense symmetric positive (semi-)definite solves for the constraint system.
//!
//! In: `W` (n x n, column major, lower triangle read). Out: its Cholesky factor in place and the number of rows
//! dropped as linearly dependent.
//! Stays true: never NaN for a symmetric positive semi-definite input. A row whose pivot falls below
//! `DEPENDENT_PIVOT * W_ii` is dropped: its row and column of L are zeroed, its diagonal set to 1, and its unknown
//! solves to 0 (the constraint is redundant with the rows before it). Rows are visited in order, so the earlier of
//! two dependent rows is kept (deterministic).

use faer::dyn_stack::MemStack;
use faer::linalg::cholesky::llt::factor::{LltRegularization, cholesky_in_place};
use faer::{MatMut, Par, Spec};

/// Relative pivot below which a row counts as linearly dependent.
pub const DEPENDENT_PIVOT: f64 = 1e-10;

/// Reusable scratch of the dense factorization (grows, never shrinks).
#[derive(Default)]
pub struct DenseWorkspace {
    /// Rows found linearly dependent in the last factorization.
    pub dropped: Vec<bool>,
    diag: Vec<f64>,
    scratch: Option<(usize, faer::dyn_stack::MemBuffer)>,
}

impl std::fmt::Debug for DenseWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DenseWorkspace").field("rows", &self.diag.len()).finish()
    }
}

impl DenseWorkspace {
    /// Original diagonal of the last factored matrix.
    pub fn diagonal(&self) -> &[f64] {
        &self.diag
    }
}

/// Factors `w` (n x n, column major, full symmetric) into `l` (resized to n x n): `W = L L^T`, L in the lower
/// triangle. Marks dependent rows in `ws.dropped`; returns how many were dropped.
pub fn factor(w: &[f64], l: &mut Vec<f64>, n: usize, ws: &mut DenseWorkspace) -> usize {
    ws.diag.clear();
    ws.diag.extend((0..n).map(|i| w[i * n + i]));
    factor_impl(w, l, n, ws)
}

/// As [`factor`], with the dependent-row test relative to `reference_diag` instead of W's own diagonal (for a
/// Schur complement: the diagonal of the original rows).
pub fn factor_with_reference(w: &[f64], l: &mut Vec<f64>, n: usize, reference_diag: &[f64], ws: &mut DenseWorkspace) -> usize {
    ws.diag.clear();
    ws.diag.extend_from_slice(&reference_diag[..n]);
    factor_impl(w, l, n, ws)
}

fn factor_impl(w: &[f64], l: &mut Vec<f64>, n: usize, ws: &mut DenseWorkspace) -> usize {
    l.clear();
    l.extend_from_slice(&w[..n * n]);
    let w_orig = w;
    let w = &mut l[..];
    ws.dropped.clear();
    ws.dropped.resize(n, false);
    if n == 0 {
        return 0;
    }
    if ws.scratch.as_ref().is_none_or(|(cap, _)| *cap < n) {
        let req = faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Spec::default());
        ws.scratch = Some((n, faer::dyn_stack::MemBuffer::new(req)));
    }
    let ok = match ws.scratch.as_mut() {
        Some((_, buf)) => {
            let mat = MatMut::from_column_major_slice_mut(&mut w[..n * n], n, n);
            cholesky_in_place(mat, LltRegularization::default(), Par::Seq, MemStack::new(buf), Spec::default()).is_ok()
        }
        None => false,
    };
    // Fast path accepted when every pivot is healthy.
    if ok && (0..n).all(|i| {
        let l = w[i * n + i];
        l.is_finite() && l * l > DEPENDENT_PIVOT * ws.diag[i]
    }) {
        return 0;
    }
    w.copy_from_slice(&w_orig[..n * n]);
    factor_pivot_drop(w, n, &mut ws.dropped, &ws.diag)
}

/// Right-looking Cholesky that drops dependent rows (see the module doc).
fn factor_pivot_drop(w: &mut [f64], n: usize, dropped: &mut [bool], diag: &[f64]) -> usize {
    let mut count = 0;
    for j in 0..n {
        let pivot = w[j * n + j];
        if !(pivot > DEPENDENT_PIVOT * diag[j]) || !pivot.is_finite() {
            dropped[j] = true;
            count += 1;
            for i in j..n {
                w[j * n + i] = 0.0;
            }
            // its row in earlier columns too: the row is decoupled from the rest
            for k in 0..j {
                w[k * n + j] = 0.0;
            }
            w[j * n + j] = 1.0;
            continue;
        }
        let l = pivot.sqrt();
        w[j * n + j] = l;
        for i in j + 1..n {
            w[j * n + i] /= l;
        }
        for k in j + 1..n {
            let lkj = w[j * n + k];
            if lkj == 0.0 {
                continue;
            }
            for i in k..n {
                w[k * n + i] -= w[j * n + i] * lkj;
            }
        }
    }
    count
}

/// Solves `L L^T x = b` in place with the factor from [`factor`]; dropped rows get x = 0.
pub fn solve_in_place(l: &[f64], n: usize, dropped: &[bool], b: &mut [f64]) {
    for (i, d) in dropped.iter().enumerate() {
        if *d {
            b[i] = 0.0;
        }
    }
    // forward: L y = b (column oriented)
    for j in 0..n {
        let y = b[j] / l[j * n + j];
        b[j] = y;
        if y != 0.0 {
            let col = &l[j * n + j + 1..j * n + n];
            for (bi, lij) in b[j + 1..n].iter_mut().zip(col) {
                *bi -= lij * y;
            }
        }
    }
    // backward: L^T x = y (row j of L^T is column j of L)
    for j in (0..n).rev() {
        let col = &l[j * n + j + 1..j * n + n];
        let s: f64 = col.iter().zip(&b[j + 1..n]).map(|(a, x)| a * x).sum();
        b[j] = (b[j] - s) / l[j * n + j];
    }
    for (i, d) in dropped.iter().enumerate() {
        if *d {
            b[i] = 0.0;
        }
    }
}

/// Cheap estimate of cond_2(W) from its factor, a lower bound: `(max L_ii / min L_ii)^2` over kept rows.
pub fn conditioning_estimate(l: &[f64], n: usize, dropped: &[bool]) -> f64 {
    let mut lo = f64::INFINITY;
    let mut hi: f64 = 0.0;
    for i in 0..n {
        if !dropped[i] {
            let d = l[i * n + i].abs();
            lo = lo.min(d);
            hi = hi.max(d);
        }
    }
    if hi == 0.0 { 1.0 } else { (hi / lo).powi(2) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dependent_row_is_dropped_and_solution_stays_finite() {
        // rows 0 and 2 equal: W = A A^T with A = [[1,0],[0,1],[1,0]]
        let n = 3;
        let a = [[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]];
        let mut w = vec![0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                w[j * n + i] = a[i][0] * a[j][0] + a[i][1] * a[j][1];
            }
        }
        let mut ws = DenseWorkspace::default();
        let orig = w.clone();
        let count = factor(&orig, &mut w, n, &mut ws);
        let dropped = ws.dropped.clone();
        assert_eq!(count, 1, "one of the two equal rows must be dropped");
        assert_eq!(dropped, vec![false, false, true], "the later duplicate is dropped");
        let mut b = vec![2.0, 3.0, 2.0];
        solve_in_place(&w, n, &dropped, &mut b);
        assert!(b.iter().all(|x| x.is_finite()));
        assert!((b[0] - 2.0).abs() < 1e-12 && (b[1] - 3.0).abs() < 1e-12 && b[2] == 0.0, "got {b:?}");
    }

    #[test]
    fn spd_solve_matches_product() {
        let n = 4;
        let mut w = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                w[j * n + i] = 1.0 / (1.0 + (i as f64 - j as f64).abs()) + if i == j { 1.0 } else { 0.0 };
            }
        }
        let orig = w.clone();
        let mut ws = DenseWorkspace::default();
        assert_eq!(factor(&orig, &mut w, n, &mut ws), 0);
        let dropped = ws.dropped.clone();
        let x_true = [1.0, -2.0, 0.5, 3.0];
        let mut b: Vec<f64> = (0..n).map(|i| (0..n).map(|j| orig[j * n + i] * x_true[j]).sum()).collect();
        solve_in_place(&w, n, &dropped, &mut b);
        for i in 0..n {
            assert!((b[i] - x_true[i]).abs() < 1e-12, "x[{i}] = {} vs {}", b[i], x_true[i]);
        }
    }
}
