//! Structured tetrahedral meshes for verification tests and benchmarks.
//!
//! In: grid coordinates (m). Out: a validated [`TetMesh`]: a box (each hex of a tensor grid split into 6 tets, Kuhn
//! split, conforming) or a hollow sphere shell (cube-sphere: the lattice on a cube's surface projected radially,
//! layered between two radii). Stays true: node numbering is deterministic; every tet has positive volume.

use crate::math::Vec3;
use crate::mesh::{MeshError, TetMesh};

/// The 6 tets of the Kuhn split of a hex whose corner `b` is at local (b & 1, (b >> 1) & 1, (b >> 2) & 1).
const KUHN: [[usize; 4]; 6] = [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];

/// A box on the tensor grid `xs x ys x zs` (each ascending, m); node `i + nx (j + ny k)` is at `(xs[i], ys[j], zs[k])`.
pub fn box_mesh(xs: &[f64], ys: &[f64], zs: &[f64]) -> Result<TetMesh, MeshError> {
    let (nx, ny, nz) = (xs.len(), ys.len(), zs.len());
    let mut positions = Vec::with_capacity(nx * ny * nz);
    for &z in zs {
        for &y in ys {
            for &x in xs {
                positions.push(Vec3::new(x, y, z));
            }
        }
    }
    let id = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
    let mut tets = Vec::new();
    for k in 0..nz.saturating_sub(1) {
        for j in 0..ny.saturating_sub(1) {
            for i in 0..nx.saturating_sub(1) {
                let corner = |b: usize| id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
                for t in KUHN {
                    tets.push(t.map(corner));
                }
            }
        }
    }
    TetMesh::new(positions, tets, vec![])
}

/// Uniform coordinates `n + 1` points from `a` to `b`.
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|i| a + (b - a) * i as f64 / n as f64).collect()
}

/// A hollow sphere shell centred at the origin, radii `inner < outer` (m), `n` cells along each cube edge and
/// `layers` uniform cells through the thickness. Node `l * m + s` is surface-lattice point s on layer l.
pub fn sphere_shell(inner: f64, outer: f64, n: usize, layers: usize) -> Result<TetMesh, MeshError> {
    // Lattice points on the surface of the cube [0, n]^3, numbered in (k, j, i) order.
    let side = n + 1;
    let mut lattice = vec![u32::MAX; side * side * side];
    let mut dirs: Vec<Vec3> = Vec::new();
    for k in 0..side {
        for j in 0..side {
            for i in 0..side {
                if i == 0 || j == 0 || k == 0 || i == n || j == n || k == n {
                    lattice[i + side * (j + side * k)] = dirs.len() as u32;
                    let p = Vec3::new(i as f64, j as f64, k as f64) * (2.0 / n as f64) - Vec3::repeat(1.0);
                    dirs.push(p.normalize());
                }
            }
        }
    }
    let m = dirs.len();
    let mut positions = Vec::with_capacity(m * (layers + 1));
    for l in 0..=layers {
        let r = inner + (outer - inner) * l as f64 / layers as f64;
        positions.extend(dirs.iter().map(|d| d * r));
    }
    let mut tets = Vec::new();
    // Faces of the cube: fixed axis a at value 0 or n; in-face axes (p, q) in ascending axis order.
    for a in 0..3 {
        let (p, q) = match a {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        for value in [0, n] {
            for u in 0..n {
                for v in 0..n {
                    let point = |du: usize, dv: usize| {
                        let mut c = [0usize; 3];
                        c[a] = value;
                        c[p] = u + du;
                        c[q] = v + dv;
                        lattice[c[0] + side * (c[1] + side * c[2])]
                    };
                    for l in 0..layers {
                        let corner = |b: usize| point(b & 1, (b >> 1) & 1) + ((l + ((b >> 2) & 1)) * m) as u32;
                        for t in KUHN {
                            tets.push(t.map(corner));
                        }
                    }
                }
            }
        }
    }
    TetMesh::new(positions, tets, vec![])
}

/// Clamps each connected piece of `mesh` at its bottom: the nodes within `depth` (m) of the piece's lowest z (the
/// benchmarks' boundary condition on a brain whose hemispheres are stored apart).
pub fn fix_bottom_of_each_component(mesh: &TetMesh, depth: f64) -> Vec<bool> {
    let comps = crate::mesh::quality::components(mesh);
    let mut min_z = vec![f64::INFINITY; comps.count];
    for (p, &c) in mesh.positions.iter().zip(&comps.node_component) {
        if let Some(m) = min_z.get_mut(c as usize) {
            *m = m.min(p.z);
        }
    }
    // a node no tet uses is its own piece: clamped
    mesh.positions.iter().zip(&comps.node_component).map(|(p, &c)| min_z.get(c as usize).is_none_or(|m| p.z <= m + depth)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_volume_and_closed_boundary() {
        let m = box_mesh(&linspace(0.0, 2.0, 3), &linspace(0.0, 1.0, 2), &linspace(0.0, 1.0, 4)).expect("valid box");
        assert_eq!(m.tets.len(), 6 * 3 * 2 * 4);
        assert!((m.volume() - 2.0).abs() < 1e-12, "box volume {}", m.volume());
        let s = m.boundary();
        let (area, vol) = s.area_vector_and_volume(&s.gather_positions(&m.positions));
        assert!(area.norm() < 1e-12 && (vol - 2.0).abs() < 1e-12, "boundary closed and outward, got {area} {vol}");
    }

    #[test]
    fn shell_is_conforming() {
        let m = sphere_shell(1.0, 2.0, 4, 2).expect("valid shell");
        let s = m.boundary();
        // A conforming shell has exactly two boundary sheets: 6 n^2 quads (12 n^2 triangles) each.
        assert_eq!(s.triangles.len(), 2 * 12 * 16, "non-conforming faces would show up as extra boundary");
        let (area, vol) = s.area_vector_and_volume(&s.gather_positions(&m.positions));
        assert!(area.norm() < 1e-12);
        assert!((vol - m.volume()).abs() < 1e-9 * vol, "outward boundary encloses the tet volume");
    }
}
