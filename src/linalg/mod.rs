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

pub use cholesky::{SparseCholesky, UnitColumns, UnitScratch};
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

