//! Errors of the FEM stage.
//!
//! In: nothing. Out: [`FemError`], whose variants carry the data a user needs to find the cause (region, node,
//! component, pivot, file). Stays true: no variant comes from a panic path; every fallible public function of
//! `crate::fem` returns one.

use std::path::PathBuf;

/// What can go wrong while building, precomputing or solving the FEM model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FemError {
    /// A material parameter is out of its valid range. `region` is `None` for the default material.
    #[error("material of {} has {field} = {value}, {reason}", .region.map_or("the default material".into(), |r| format!("region {r}")))]
    InvalidMaterial { region: Option<u32>, field: &'static str, value: f64, reason: &'static str },
    /// The `fixed` slice does not have one entry per node.
    #[error("`fixed` has {got} entries but the mesh has {expected} nodes")]
    FixedLength { expected: usize, got: usize },
    /// A connected component of the mesh has no fixed node: its stiffness is singular.
    #[error("mesh component {component} ({nodes} nodes, lowest node {first_node}) has no fixed node; fix some of its nodes")]
    UnfixedComponent { component: usize, nodes: usize, first_node: u32 },
    /// Every node is fixed (or unused): there is nothing to solve.
    #[error("the model has no free degree of freedom")]
    NoFreeDofs,
    /// The sparse Cholesky factorization met a non-positive pivot.
    #[error("stiffness matrix is not positive definite: non-positive pivot at free DOF {dof} (node {node}, component {component})")]
    NotPositiveDefinite { dof: usize, node: u32, component: usize },
    /// faer reported a failure other than a pivot (e.g. out of memory).
    #[error("sparse factorization failed: {reason}")]
    Factorization { reason: String },
    /// An option is out of range.
    #[error("option `{field}` = {value} is invalid: {reason}")]
    InvalidOption { field: &'static str, value: f64, reason: &'static str },
    /// A node index is out of range.
    #[error("{what} refers to node {node}, but the mesh has {count} nodes")]
    NodeOutOfRange { what: &'static str, node: u32, count: usize },
    /// A constraint carries a non-finite or invalid value.
    #[error("constraint {index} (node {node}) is invalid: {reason}")]
    InvalidConstraint { index: usize, node: u32, reason: &'static str },
    /// The unilateral active-set loop (blade contacts, barrier rows, skull spheres) did not settle.
    #[error("contact active set (blade faces and skull spheres) did not converge in {iterations} iterations (largest violation {max_violation:e} m, most adhesive force {min_force:e} N)")]
    ActiveSetNotConverged { iterations: usize, max_violation: f64, min_force: f64 },
    /// A field of the per-frame input does not match the model.
    #[error("{what}: expected length {expected}, got {got}")]
    LengthMismatch { what: &'static str, expected: usize, got: usize },
    /// Writing the compliance cache failed (reading failures rebuild instead).
    #[error("compliance cache {path}: {reason}")]
    Cache { path: PathBuf, reason: String },
    /// The compliance for the requested region would not fit in memory (checked before allocating it).
    #[error(
        "the compliance for a region of interest of {cols} nodes ({rows} stored rows, {storage}) needs {need_mb} MB with the precompute's working space, more than the {available_mb} MB this machine has available; choose a smaller region of interest (region_of_interest: Auto, a smaller radius, or fewer nodes) or the smaller storage (F32)"
    )]
    RegionTooLarge { cols: usize, rows: usize, storage: String, need_mb: u64, available_mb: u64 },
    /// A memory request could not be met.
    #[error("out of memory while allocating {what} ({bytes} bytes)")]
    OutOfMemory { what: &'static str, bytes: usize },
    /// Background-filled compliance columns could not be completed; a frame that needed one stops with this.
    #[error("the compliance columns being computed in the background are not available: {reason}")]
    ComplianceIncomplete { reason: String },
    /// A background thread could not be started.
    #[error("{what} thread did not start: {reason}")]
    ThreadStart { what: &'static str, reason: String },
}

impl From<crate::linalg::FactorError> for FemError {
    fn from(e: crate::linalg::FactorError) -> Self {
        use crate::linalg::FactorError as F;
        match e {
            F::NotPositiveDefinite { dof, node, component } => FemError::NotPositiveDefinite { dof, node, component },
            F::Factorization { reason } => FemError::Factorization { reason },
            F::OutOfMemory { what, bytes } => FemError::OutOfMemory { what, bytes },
        }
    }
}
