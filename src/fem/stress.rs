//! Per-tet stress and strain on demand.
//!
//! In: the model (positions, tets, Lamé parameters per tet) and one displacement per node (m, e.g. from
//! `ConstrainedSolver::interior_displacements`). Out: per tet the von Mises stress (Pa) and the largest principal
//! strain. Stays true: constant within a tet (linear elements); zero for a rigid motion.

use super::FemError;
use super::element::{shape_gradients, strain, stress};
use super::model::FemModel;
use crate::math::{Matrix3, Vec3};

/// Stress measures of one tetrahedron.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ElementStress {
    /// von Mises equivalent stress, Pa.
    pub von_mises: f64,
    /// Largest principal strain (dimensionless; > 0 is stretch).
    pub max_principal_strain: f64,
}

/// Largest eigenvalue of a symmetric 3x3 matrix in closed form (the trigonometric solution of the characteristic
/// cubic, Smith 1961), within a few ulps of the largest entry, degenerate spectra included (tested against
/// nalgebra's iterative solver, which is several times slower; the stress pass runs over every tet each frame).
pub fn largest_symmetric_eigenvalue(a: &Matrix3<f64>) -> f64 {
    let off = a[(0, 1)] * a[(0, 1)] + a[(0, 2)] * a[(0, 2)] + a[(1, 2)] * a[(1, 2)];
    let q = a.trace() / 3.0;
    let (d0, d1, d2) = (a[(0, 0)] - q, a[(1, 1)] - q, a[(2, 2)] - q);
    let p2 = d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * off;
    if p2.is_nan() {
        return f64::NAN;
    }
    if p2 <= 0.0 {
        // a multiple of the identity
        return q;
    }
    let p = (p2 / 6.0).sqrt();
    // B = (A - qI) / p; r = det(B) / 2, in [-1, 1] up to rounding
    let b = (a - Matrix3::identity() * q) / p;
    let r = (b.determinant() * 0.5).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    q + 2.0 * p * phi.cos()
}

/// Computes [`ElementStress`] for every tet into `out` (resized).
pub fn element_stress(model: &FemModel, displacement: &[Vec3], out: &mut Vec<ElementStress>) -> Result<(), FemError> {
    tet_stress(model.mesh(), model.lame(), displacement, out)
}

/// [`element_stress`] from the mesh and the Lamé parameters per tet (what a background worker keeps of a model).
pub fn tet_stress(mesh: &crate::mesh::TetMesh, lame: &[(f64, f64)], displacement: &[Vec3], out: &mut Vec<ElementStress>) -> Result<(), FemError> {
    if lame.len() != mesh.tets.len() {
        return Err(FemError::LengthMismatch { what: "Lame parameters", expected: mesh.tets.len(), got: lame.len() });
    }
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
        let (lambda, mu) = lame[t];
        let s = stress(&e, lambda, mu);
        let dev = s - Matrix3::identity() * (s.trace() / 3.0);
        let von_mises = (1.5 * dev.component_mul(&dev).sum()).sqrt();
        let max_principal_strain = largest_symmetric_eigenvalue(&e);
        out.push(ElementStress { von_mises, max_principal_strain });
    }
    Ok(())
}
