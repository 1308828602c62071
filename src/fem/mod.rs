//! The FEM stage: linear tetrahedral elasticity solved exactly with enforced displacements, skull spheres and
//! reaction forces, in real time.
//!
//! In: a [`crate::mesh::TetMesh`] (m), materials per region, fixed nodes; each frame a list of [`Constraint`]s.
//! Out: per frame a [`FrameSolution`] (surface displacements, reactions per constraint and per owner); on demand
//! interior displacements and per-tet stress.
//! Stays true: `K_FF` is factored once ([`FemModel`]); the surface compliance is precomputed once ([`Compliance`],
//! cached on disk); a frame is a gather, a small dense Cholesky and one dense product (ARCHITECTURE.md, "One
//! frame"). Phases, one file each: `element` (tet stiffness) -> `assembly` -> `factor` -> `model` -> `compliance`
//! -> `constrained` (+ `dense`, skull rows inside) -> `stress`, `contact`.

pub mod assembly;
pub mod background_stress;
pub mod compliance;
pub mod constrained;
pub mod contact;
pub mod dense;
pub mod element;
pub mod error;
pub mod factor;
pub mod model;
pub mod ordering;
pub mod reference;
pub mod stress;
pub mod tuning;
pub mod wfactor;

pub use compliance::{Compliance, ComplianceStats, ComplianceStorage, ComputeOptions, ProductWorkspace};
pub use constrained::{ConstrainedSolver, Constraint, ConstraintKind, ConstraintRow, FrameSolution};
pub use contact::{ContactPatch, ContactScratch, PA_PER_MMHG, RETRACTION_DANGER_PA, contact_patches};
pub use element::{Material, RegionMaterials};
pub use error::FemError;
pub use model::{BodyForce, FemModel, FemOptions, FemStats};
pub use background_stress::StressWorker;
pub use stress::{ElementStress, element_stress, tet_stress};
