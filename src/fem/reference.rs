//! Direct reference solver: prescribed DOFs eliminated, `K_FF` factored anew.
//!
//! In: a mesh, per-tet Lamé parameters, prescribed values per global DOF (`3 * node + component`, m) and optional
//! nodal forces (N). Out: all nodal displacements and the reaction (N) at every prescribed DOF. The accuracy
//! reference for the fast path, and the vehicle of the closed-form verification tests (which need roller
//! conditions the node-level `fixed` set cannot express). Not for per-frame use.
//! Stays true: exact up to round-off; a singular system is a typed error.

use super::FemError;
use super::assembly::assemble_full_triplets;
use crate::linalg::{FillOrdering, LowerCsc, SparseCholesky};
use crate::math::Vec3;
use crate::mesh::TetMesh;

/// Displacements and reactions of a direct solve.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectSolution {
    /// Per node, m.
    pub displacement: Vec<Vec3>,
    /// Per prescribed DOF (input order): `(K u - f)` at that DOF, the force ON the tissue, N.
    pub reactions: Vec<f64>,
}

/// Solves `K u = f` with `u[dof] = value` for every `(dof, value)` in `prescribed` (a repeated DOF keeps its first).
pub fn solve_direct(mesh: &TetMesh, lame: &[(f64, f64)], prescribed: &[(usize, f64)], forces: &[Vec3]) -> Result<DirectSolution, FemError> {
    let n = 3 * mesh.node_count();
    let mut fixed_value: Vec<Option<f64>> = vec![None; n];
    for &(d, v) in prescribed {
        if d >= n {
            return Err(FemError::NodeOutOfRange { what: "prescribed DOF", node: (d / 3) as u32, count: mesh.node_count() });
        }
        if fixed_value[d].is_none() {
            fixed_value[d] = Some(v);
        }
    }
    let trip = assemble_full_triplets(mesh, lame);
    // Free numbering of DOFs that are not prescribed and belong to some tet.
    let mut used = vec![false; n];
    for &(r, _, _) in &trip {
        used[r] = true;
    }
    let mut free = vec![usize::MAX; n];
    let mut free_dofs = Vec::new();
    for d in 0..n {
        if used[d] && fixed_value[d].is_none() {
            free[d] = free_dofs.len();
            free_dofs.push(d);
        }
    }
    let nf = free_dofs.len();
    let mut rhs = vec![0.0; nf];
    for (node, f) in forces.iter().enumerate() {
        for c in 0..3 {
            let d = 3 * node + c;
            if d < n && free[d] != usize::MAX {
                rhs[free[d]] += f[c];
            }
        }
    }
    // triplets are sorted by (col, row): the free lower part is already CSC ordered
    let mut col_ptr = vec![0usize; nf + 1];
    let mut row_idx = Vec::new();
    let mut values = Vec::new();
    for &(r, c, v) in &trip {
        let (fr, fc) = (free[r], free[c]);
        if fc != usize::MAX && fr == usize::MAX {
            if let Some(g) = fixed_value[r] {
                rhs[fc] -= v * g;
            }
        }
        if fr != usize::MAX && fc != usize::MAX && fr >= fc {
            col_ptr[fc + 1] += 1;
            row_idx.push(fr);
            values.push(v);
        }
    }
    for j in 0..nf {
        col_ptr[j + 1] += col_ptr[j];
    }
    let k = LowerCsc { dim: nf, col_ptr, row_idx, values };
    let chol = SparseCholesky::new(&k, FillOrdering::Amd, &|dof| ((free_dofs[dof] / 3) as u32, free_dofs[dof] % 3))?;
    let mut scratch = chol.scratch(1)?;
    chol.solve_vec_in_place(&mut rhs, &mut scratch);
    let mut u = vec![0.0; n];
    for d in 0..n {
        u[d] = if free[d] != usize::MAX { rhs[free[d]] } else { fixed_value[d].unwrap_or(0.0) };
    }
    // reactions: (K u)[dof] - f[dof]
    let mut ku = vec![0.0; n];
    for &(r, c, v) in &trip {
        ku[r] += v * u[c];
    }
    let reactions = prescribed
        .iter()
        .map(|&(d, _)| ku[d] - forces.get(d / 3).map(|f| f[d % 3]).unwrap_or(0.0))
        .collect();
    let displacement = (0..mesh.node_count()).map(|i| Vec3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2])).collect();
    Ok(DirectSolution { displacement, reactions })
}
