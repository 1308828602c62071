//! Constant-strain tetrahedra and isotropic linear elastic materials.
//!
//! In: four node positions (m) and a [`Material`] (E in Pa, nu). Out: the 12x12 element stiffness `V * B^T D B`
//! (N/m), the shape-function gradients, the element strain of a displacement field.
//! Stays true: the element stiffness is symmetric, positive semi-definite with exactly the six rigid-body modes in
//! its kernel when the tet has volume > 0.

use super::FemError;
use crate::math::{Matrix3, Vec3};

/// Isotropic linear elastic material.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    /// Young's modulus, Pa, > 0 (brain tissue: about 1e3 to 1e4 Pa).
    pub young_modulus: f64,
    /// Poisson's ratio, dimensionless, in (-1, 0.5) (brain: 0.45 to 0.499).
    pub poisson_ratio: f64,
}

impl Material {
    /// Checks the ranges; `region` names the region in the error.
    pub fn validate(&self, region: Option<u32>) -> Result<(), FemError> {
        let e = self.young_modulus;
        if !(e.is_finite() && e > 0.0) {
            return Err(FemError::InvalidMaterial { region, field: "young_modulus", value: e, reason: "must be finite and > 0 Pa" });
        }
        let nu = self.poisson_ratio;
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(FemError::InvalidMaterial { region, field: "poisson_ratio", value: nu, reason: "must lie in (-1, 0.5)" });
        }
        Ok(())
    }

    /// Lamé parameters (lambda, mu), Pa.
    pub fn lame(&self) -> (f64, f64) {
        let (e, nu) = (self.young_modulus, self.poisson_ratio);
        let mu = e / (2.0 * (1.0 + nu));
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        (lambda, mu)
    }
}

/// Materials per region id, with a default for regions not listed.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegionMaterials {
    /// Material of every region not listed in `by_region`.
    pub default: Material,
    /// (region id, material); a region listed twice is an error at model build.
    pub by_region: Vec<(u32, Material)>,
}

impl RegionMaterials {
    /// One material everywhere.
    pub fn uniform(material: Material) -> Self {
        Self { default: material, by_region: Vec::new() }
    }

    /// Validates every material and returns a lookup sorted by region.
    pub(crate) fn validated(&self) -> Result<Vec<(u32, Material)>, FemError> {
        self.default.validate(None)?;
        let mut sorted = self.by_region.clone();
        sorted.sort_by_key(|(r, _)| *r);
        for w in sorted.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(FemError::InvalidMaterial {
                    region: Some(w[0].0),
                    field: "region",
                    value: w[0].0 as f64,
                    reason: "is listed twice",
                });
            }
        }
        for (r, m) in &sorted {
            m.validate(Some(*r))?;
        }
        Ok(sorted)
    }

    /// The material of `region`, from a list returned by `validated`.
    pub(crate) fn lookup(sorted: &[(u32, Material)], default: Material, region: u32) -> Material {
        match sorted.binary_search_by_key(&region, |(r, _)| *r) {
            Ok(i) => sorted[i].1,
            Err(_) => default,
        }
    }
}

/// Gradients of the four barycentric shape functions (1/m) and the volume (m^3).
pub fn shape_gradients(p: &[Vec3; 4]) -> ([Vec3; 4], f64) {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let e3 = p[3] - p[0];
    let det = e1.dot(&e2.cross(&e3));
    let volume = det / 6.0;
    let inv = 1.0 / det;
    let g1 = e2.cross(&e3) * inv;
    let g2 = e3.cross(&e1) * inv;
    let g3 = e1.cross(&e2) * inv;
    let g0 = -(g1 + g2 + g3);
    ([g0, g1, g2, g3], volume)
}

/// Element stiffness (N/m), row/column `3 * local_node + component`:
/// `K_ab = V (lambda g_a g_b^T + mu g_b g_a^T + mu (g_a . g_b) I)`.
pub fn tet_stiffness(p: &[Vec3; 4], lambda: f64, mu: f64) -> [[f64; 12]; 12] {
    let (g, v) = shape_gradients(p);
    let mut k = [[0.0; 12]; 12];
    for a in 0..4 {
        for b in 0..4 {
            let dot = g[a].dot(&g[b]);
            for i in 0..3 {
                for j in 0..3 {
                    let mut val = lambda * g[a][i] * g[b][j] + mu * g[a][j] * g[b][i];
                    if i == j {
                        val += mu * dot;
                    }
                    k[3 * a + i][3 * b + j] = v * val;
                }
            }
        }
    }
    k
}

/// Small-strain tensor of a tet from its shape gradients and nodal displacements.
pub fn strain(gradients: &[Vec3; 4], u: &[Vec3; 4]) -> Matrix3<f64> {
    let mut grad_u = Matrix3::zeros();
    for a in 0..4 {
        grad_u += u[a] * gradients[a].transpose();
    }
    (grad_u + grad_u.transpose()) * 0.5
}

/// Cauchy stress (Pa) of a small strain for Lamé parameters (lambda, mu).
pub fn stress(strain: &Matrix3<f64>, lambda: f64, mu: f64) -> Matrix3<f64> {
    Matrix3::identity() * (lambda * strain.trace()) + strain * (2.0 * mu)
}
