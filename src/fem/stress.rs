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

#[cfg(test)]
mod tests {
    use super::*;

    /// Against nalgebra's iterative eigen solver: random symmetric matrices of
    /// mixed scales, and degenerate spectra (double, triple, zero, rank one).
    #[test]
    fn largest_eigenvalue_matches_the_iterative_solver() {
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut cases: Vec<Matrix3<f64>> = Vec::new();
        for k in 0..2000 {
            let scale = 10f64.powi(k % 9 - 6);
            let m = Matrix3::from_fn(|_, _| next() * scale);
            cases.push((m + m.transpose()) * 0.5);
        }
        let v = Vec3::new(0.3, -0.5, 0.8).normalize();
        cases.push(Matrix3::zeros());
        cases.push(Matrix3::identity() * 2.5e-3);
        cases.push(Matrix3::from_diagonal(&Vec3::new(1e-3, 1e-3, -2e-3)));
        cases.push(Matrix3::from_diagonal(&Vec3::new(-1e-3, -1e-3, 2e-3)));
        cases.push(v * v.transpose() * 4e-3);
        cases.push(v * v.transpose() * -4e-3);
        cases.push(Matrix3::identity() * 1e-3 + v * v.transpose() * 1e-12);
        for a in &cases {
            let exact = a.symmetric_eigenvalues().iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
            let got = largest_symmetric_eigenvalue(a);
            let norm = a.abs().max();
            assert!((got - exact).abs() <= 1e-13 * norm.max(f64::MIN_POSITIVE), "{a}: {got} vs {exact}");
        }
        assert!(largest_symmetric_eigenvalue(&Matrix3::from_element(f64::NAN)).is_nan());
    }
}
