//! The FEM stage: linear tetrahedral elasticity solved exactly with enforced displacements, skull spheres and
//! reaction forces, in real time.
//!
//! In: a [`crate::mesh::TetMesh`] (m), materials per region, fixed nodes; each frame a list of [`Constraint`]s.
//! Out: per frame a [`FrameSolution`] (surface displacements, reactions per constraint and per owner); on demand
//! interior displacements and per-tet stress.
//! Stays true: `K_FF` is factored once ([`FemModel`], with [`crate::linalg`]); the surface compliance is
//! precomputed once ([`Compliance`], cached on disk); a frame is a gather, a small dense Cholesky and one dense
//! product (ARCHITECTURE.md, "One frame"). Phases, one file each: `element` -> `assembly` -> `model` ->
//! `compliance` -> `constrained` -> `stress`; `reference` is the direct solve the fast path is checked against.

pub mod assembly;
pub mod compliance;
pub mod constrained;
pub mod element;
pub mod error;
pub mod model;
pub mod reference;
pub mod stress;
pub mod tuning;

pub use compliance::{Compliance, ComplianceStats, ComplianceStorage, ComputeOptions, PROJECTIONS_PER_CALL, ProductWorkspace};
pub use constrained::{ConstrainedSolver, Constraint, ConstraintKind, ConstraintRow, FrameSolution, SurfaceWrites, Tether, TetherEnd};
pub use element::{Material, RegionMaterials};
pub use error::FemError;
pub use model::{BodyForce, FemModel, FemOptions, FemStats};
pub use stress::{ElementStress, element_stress, tet_stress};
