//! Boundary surface extraction: the faces that belong to exactly one tetrahedron.
//!
//! In: a [`TetMesh`]. Out: [`BoundarySurface`] with triangles in *surface-vertex*
//! indices (compact, what collision and the GPU use), oriented so that their
//! normals point out of the body, plus the maps between surface vertices and
//! mesh nodes. Stays true: `vertices` is sorted ascending; the order of triangles
//! is deterministic (by owning tet, then local face).

use super::TetMesh;
use crate::math::Vec3;

/// Marks a node that is not on the boundary in [`BoundarySurface::node_to_vertex`].
pub const NOT_ON_SURFACE: u32 = u32::MAX;

/// The outward-oriented boundary of a tetrahedral mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundarySurface {
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Surface vertex k is mesh node `vertices[k]` (ascending).
    pub vertices: Vec<u32>,
    /// Mesh node -> surface vertex, or [`NOT_ON_SURFACE`].
    pub node_to_vertex: Vec<u32>,
    /// The tetrahedron each triangle is a face of.
    pub triangle_tet: Vec<u32>,
}

/// Local faces of a positively oriented tet (0,1,2,3), each listed so that its
/// right-hand normal points out of the tet.
const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// The faces (tet, local face) that no other tet shares, in any order. A
/// face is one `u128`, its sorted nodes (32 bits each) over its tet, so the
/// sort moves and compares single integers (on the fine brain's 1.2 M faces
/// about twice as fast as sorting tuples); the local face is the one that
/// leaves out the tet's node not in the triple.
fn boundary_faces(mesh: &TetMesh) -> Vec<(u32, u8)> {
    let mut keyed: Vec<u128> = Vec::with_capacity(mesh.tets.len() * 4);
    for (t, tet) in mesh.tets.iter().enumerate() {
        for face in FACES {
            let mut key = face.map(|k| tet[k]);
            key.sort_unstable();
            keyed.push((u128::from(key[0]) << 96) | (u128::from(key[1]) << 64) | (u128::from(key[2]) << 32) | t as u128);
        }
    }
    keyed.sort_unstable();
    let mut boundary = Vec::new();
    for group in keyed.chunk_by(|a, b| a >> 32 == b >> 32) {
        if let [x] = group {
            let t = *x as u32;
            let nodes = [(*x >> 96) as u32, (*x >> 64) as u32, (*x >> 32) as u32];
            // FACES[f] leaves out local node f.
            if let Some(f) = mesh.tets[t as usize].iter().position(|n| !nodes.contains(n)) {
                boundary.push((t, f as u8));
            }
        }
    }
    boundary
}

impl BoundarySurface {
    /// Extracts the boundary of `mesh`.
    pub fn of(mesh: &TetMesh) -> Self {
        // Sort faces by their sorted node triple; a face seen once is boundary.
        let mut boundary = boundary_faces(mesh);
        boundary.sort_unstable();
        let mut node_to_vertex = vec![NOT_ON_SURFACE; mesh.node_count()];
        for &(t, f) in &boundary {
            for k in FACES[f as usize] {
                node_to_vertex[mesh.tets[t as usize][k] as usize] = 0;
            }
        }
        let mut vertices = Vec::new();
        for (n, slot) in node_to_vertex.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = vertices.len() as u32;
                vertices.push(n as u32);
            }
        }
        let triangles = boundary
            .iter()
            .map(|&(t, f)| FACES[f as usize].map(|k| node_to_vertex[mesh.tets[t as usize][k] as usize]))
            .collect();
        let triangle_tet = boundary.iter().map(|&(t, _)| t).collect();
        Self { triangles, vertices, node_to_vertex, triangle_tet }
    }

    /// Positions of the surface vertices, gathered from the mesh's nodes.
    pub fn gather_positions(&self, node_positions: &[Vec3]) -> Vec<Vec3> {
        self.vertices.iter().map(|&n| node_positions[n as usize]).collect()
    }

    /// Sum of area vectors (zero for a closed surface) and the enclosed volume by
    /// the divergence theorem, given surface-vertex positions.
    pub fn area_vector_and_volume(&self, positions: &[Vec3]) -> (Vec3, f64) {
        let mut area = Vec3::zeros();
        let mut volume = 0.0;
        for t in &self.triangles {
            let [a, b, c] = t.map(|k| positions[k as usize]);
            let n = (b - a).cross(&(c - a)) * 0.5;
            area += n;
            volume += a.dot(&(b - a).cross(&(c - a))) / 6.0;
        }
        (area, volume)
    }
}

/// Per-surface-vertex areas (a third of each adjacent rest triangle), m^2, for
/// turning reaction forces into pressures.
pub fn vertex_areas(rest: &[crate::math::Vec3], triangles: &[[u32; 3]]) -> Vec<f64> {
    let mut areas = vec![0.0; rest.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| rest.get(i as usize).copied().unwrap_or_else(crate::math::Vec3::zeros));
        let third = (b - a).cross(&(c - a)).norm() / 6.0;
        for &i in t {
            if let Some(slot) = areas.get_mut(i as usize) {
                *slot += third;
            }
        }
    }
    areas
}

#[cfg(test)]
mod tests {
    use crate::mesh::tests::cube;

    #[test]
    fn cube_boundary_is_closed_and_outward() {
        let m = cube();
        let s = m.boundary();
        assert_eq!(s.triangles.len(), 12);
        assert_eq!(s.vertices.len(), 8);
        let pos = s.gather_positions(&m.positions);
        let (area, volume) = s.area_vector_and_volume(&pos);
        assert!(area.norm() < 1e-14, "closed surface area vectors sum to zero, got {area}");
        assert!((volume - m.volume()).abs() < 1e-14, "outward orientation gives +volume, got {volume}");
    }
}
