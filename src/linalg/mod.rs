//! The linear algebra the FEM rests on, with no knowledge of meshes or contact.
//!
//! In: a sparse symmetric positive definite matrix ([`LowerCsc`], its lower triangle) or dense blocks of one. Out:
//! factors and solves. `cholesky`: the supernodal sparse Cholesky of `K_FF` (faer) with solves pruned along the
//! elimination tree; `ordering`: its fill-reducing ordering (AMD or METIS nested dissection); `dense`: a dense
//! Cholesky that drops dependent rows; `kept_factor`: a dense factor kept across calls while its rows change.
//! Stays true: every factor and solve is deterministic (fixed order, one core), so answers repeat bit for bit.

pub mod cholesky;
pub mod dense;
pub mod kept_factor;
pub mod ordering;

pub use cholesky::SparseCholesky;
pub use ordering::FillOrdering;

/// Lower triangle of a sparse symmetric matrix in compressed sparse columns (the free-DOF stiffness `K_FF`).
#[derive(Debug, Clone)]
pub struct LowerCsc {
    /// Matrix dimension.
    pub dim: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    pub values: Vec<f64>,
}

impl LowerCsc {
    /// A faer view of the matrix (lower triangle stored).
    pub fn as_faer(&self) -> faer::sparse::SparseColMatRef<'_, usize, f64> {
        let sym = faer::sparse::SymbolicSparseColMatRef::new_checked(self.dim, self.dim, &self.col_ptr, None, &self.row_idx);
        faer::sparse::SparseColMatRef::new(sym, &self.values)
    }
}

/// What a factorization can meet; the FEM stage reports each as its [`crate::fem::FemError`] counterpart.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FactorError {
    /// A non-positive pivot at a DOF, named by the caller as (node, component).
    #[error("matrix is not positive definite: non-positive pivot at DOF {dof} (node {node}, component {component})")]
    NotPositiveDefinite { dof: usize, node: u32, component: usize },
    /// faer reported a failure other than a pivot.
    #[error("sparse factorization failed: {reason}")]
    Factorization { reason: String },
    /// A memory request could not be met.
    #[error("out of memory while allocating {what} ({bytes} bytes)")]
    OutOfMemory { what: &'static str, bytes: usize },
}

/// A stiffness-like test matrix with no mesh behind it: `bodies` uncoupled grids of `n` nodes, 3 DOFs a node
/// (node-major, as `K_FF` numbers them), each node coupled to its 26 neighbours: `L ⊗ B` with `L` the 27-point grid
/// Laplacian plus the identity and `B` = tridiag(1, 2, 1), both positive definite, so the product is.
#[cfg(test)]
pub(crate) fn grid_stiffness(n: [usize; 3], bodies: usize) -> LowerCsc {
    const B: [[f64; 3]; 3] = [[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]];
    let per_body = n[0] * n[1] * n[2];
    let node = |x: usize, y: usize, z: usize| x + n[0] * (y + n[1] * z);
    let (mut col_ptr, mut row_idx, mut values) = (vec![0], Vec::new(), Vec::new());
    for body in 0..bodies {
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    // Neighbours at or after this node, ascending (the lower triangle of a node-major column).
                    let mut after: Vec<(usize, f64)> = Vec::new();
                    for (dz, dy, dx) in (0..27).map(|k| (k / 9, k / 3 % 3, k % 3)) {
                        let (xx, yy, zz) = (x + dx, y + dy, z + dz);
                        if (1..=n[0]).contains(&xx) && (1..=n[1]).contains(&yy) && (1..=n[2]).contains(&zz) {
                            let j = node(xx - 1, yy - 1, zz - 1);
                            if j >= node(x, y, z) {
                                after.push((body * per_body + j, if j == node(x, y, z) { 27.0 } else { -1.0 }));
                            }
                        }
                    }
                    after.sort_by_key(|&(j, _)| j);
                    for a in 0..3 {
                        for &(j, l) in &after {
                            for b in 0..3 {
                                let (row, col) = (3 * j + b, 3 * (body * per_body + node(x, y, z)) + a);
                                if row >= col && B[a][b] != 0.0 {
                                    row_idx.push(row);
                                    values.push(l * B[a][b]);
                                }
                            }
                        }
                        col_ptr.push(row_idx.len());
                    }
                }
            }
        }
    }
    LowerCsc { dim: 3 * per_body * bodies, col_ptr, row_idx, values }
}
