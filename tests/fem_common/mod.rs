//! Shared code of the `fem_*` integration tests: small structured meshes,
//! materials, and relative error measures.
#![allow(dead_code)]

use fissure::mesh::fixtures::{box_mesh, linspace};
use fissure::fem::{Compliance, Material, RegionMaterials};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

pub const BRAIN: Material = Material { young_modulus: 3.0e3, poisson_ratio: 0.45 };

pub fn uniform(m: Material) -> RegionMaterials {
    RegionMaterials::uniform(m)
}

/// A 60 x 40 x 30 mm block with `nx, ny, nz` cells.
pub fn block(nx: usize, ny: usize, nz: usize) -> TetMesh {
    box_mesh(&linspace(0.0, 0.06, nx), &linspace(0.0, 0.04, ny), &linspace(0.0, 0.03, nz)).expect("valid block")
}

/// Nodes on the bottom face z = 0 are fixed.
pub fn bottom_fixed(mesh: &TetMesh) -> Vec<bool> {
    mesh.positions.iter().map(|p| p.z.abs() < 1e-12).collect()
}

pub fn max_norm(v: &[Vec3]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.norm()))
}

/// max |a - b| / max |b|
pub fn rel_error(a: &[Vec3], b: &[Vec3]) -> f64 {
    assert_eq!(a.len(), b.len(), "compared fields differ in length");
    let diff = a.iter().zip(b).fold(0.0_f64, |m, (x, y)| m.max((x - y).norm()));
    diff / max_norm(b).max(f64::MIN_POSITIVE)
}

/// Every stored block of a compliance (column by column, every row), as bits: two compliances compare equal only
/// when every entry is the same bit pattern (0.0 and -0.0 differ, NaN equals itself).
pub fn all_block_bits(c: &Compliance) -> Vec<u64> {
    let mut v = Vec::new();
    for col in 0..c.column_count() {
        for row in 0..c.row_nodes().len() {
            v.extend(c.block(row, col).iter().map(|x| x.to_bits()));
        }
    }
    v
}
