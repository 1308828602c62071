//! Per-tet stress and strain on demand.
//!
//! In: the model (positions, tets, Lamé parameters per tet) and one displacement
//! per node (m, e.g. from `ConstrainedSolver::interior_displacements`).
//! Out: per tet the von Mises stress (Pa) and the largest principal strain.
//! Stays true: constant within a tet (linear elements); zero for a rigid motion.

use super::FemError;
use super::element::{shape_gradients, strain, stress};
use super::model::FemModel;
use crate::math::Vec3;

/// Stress measures of one tetrahedron.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ElementStress {
    /// von Mises equivalent stress, Pa.
    pub von_mises: f64,
    /// Largest principal strain (dimensionless; > 0 is stretch).
    pub max_principal_strain: f64,
}

/// Computes [`ElementStress`] for every tet into `out` (resized).
pub fn element_stress(model: &FemModel, displacement: &[Vec3], out: &mut Vec<ElementStress>) -> Result<(), FemError> {
    let mesh = model.mesh();
    if displacement.len() != mesh.node_count() {
        return Err(FemError::LengthMismatch { what: "nodal displacements", expected: mesh.node_count(), got: displacement.len() });
    }
    out.clear();
    out.reserve(mesh.tets.len());
    for (t, tet) in mesh.tets.iter().enumerate() {
        let p = tet.map(|n| mesh.positions[n as usize]);
        let u = tet.map(|n| displacement[n as usize]);
        let (g, _) = shape_gradients(&p);
        let e = strain(&g, &u);
        let (lambda, mu) = model.lame()[t];
        let s = stress(&e, lambda, mu);
        let dev = s - crate::math::Matrix3::identity() * (s.trace() / 3.0);
        let von_mises = (1.5 * dev.component_mul(&dev).sum()).sqrt();
        let eig = e.symmetric_eigenvalues();
        let max_principal_strain = eig.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        out.push(ElementStress { von_mises, max_principal_strain });
    }
    Ok(())
}
