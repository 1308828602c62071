//! Tetrahedral meshes: the body the FEM deforms and whose boundary the spatulas touch.
//!
//! In: node positions (metres, f64), tetrahedra (u32 node indices), an optional
//! region id per tet. Out: a validated [`TetMesh`] in which every tet is positively
//! oriented (reversed ones are reordered and counted, zero-volume ones rejected)
//! and its [`BoundarySurface`] with outward-oriented triangles.
//! Stays true: indices are in range, coordinates are finite, volumes are > 0.

pub mod brain;
pub mod fixtures;
pub mod io;
pub mod phantom;
pub mod quality;
pub mod refine;
pub mod surface;
pub mod tetrahedralize;
pub mod trisurface;

pub use surface::BoundarySurface;
pub use trisurface::TriSurface;

use crate::math::{Vec3, is_finite3};

/// Items grouped by key as compressed rows: key `k`'s items are
/// `items[start[k]..start[k + 1]]`, in the order `entries` yields them (it is
/// called twice: to count, then to fill). Every key must be below `keys`.
/// Used for the triangles around each surface vertex and the BVH leaves over
/// each vertex.
pub fn group_by_key<I: Iterator<Item = (u32, u32)>>(keys: usize, entries: impl Fn() -> I) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; keys + 1];
    for (k, _) in entries() {
        start[k as usize + 1] += 1;
    }
    for k in 0..keys {
        start[k + 1] += start[k];
    }
    let mut next = start[..keys].to_vec();
    let mut items = vec![0u32; start[keys] as usize];
    for (k, item) in entries() {
        items[next[k as usize] as usize] = item;
        next[k as usize] += 1;
    }
    (start, items)
}

/// The triangles around each vertex of `vertex_count`, ascending: vertex `v`'s
/// are `around[start[v]..start[v + 1]]` (the returned pair is `(start, around)`).
pub fn triangles_around_vertices(vertex_count: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    group_by_key(vertex_count, || triangles.iter().enumerate().flat_map(|(t, tri)| tri.iter().map(move |&v| (v, t as u32))))
}

/// Errors in building or validating a mesh. File parsers wrap these with the path.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    #[error("the mesh has no nodes or no tetrahedra")]
    Empty,
    #[error("node {node} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFiniteNode { node: usize, x: f64, y: f64, z: f64 },
    #[error("tetrahedron {tet} refers to node {node}, but the mesh has {count} nodes")]
    IndexOutOfRange { tet: usize, node: u64, count: usize },
    #[error("tetrahedron {tet} uses node {node} twice")]
    RepeatedNode { tet: usize, node: u32 },
    #[error("tetrahedron {tet} has zero volume ({volume:e} m^3, relative {relative:e})")]
    ZeroVolume { tet: usize, volume: f64, relative: f64 },
    #[error("{tets} tetrahedra but {regions} region ids")]
    RegionCount { tets: usize, regions: usize },
}

/// A validated linear tetrahedral mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    /// Node positions in metres.
    pub positions: Vec<Vec3>,
    /// Tetrahedra as node indices, each positively oriented:
    /// `(p1 - p0) . ((p2 - p0) x (p3 - p0)) > 0`.
    pub tets: Vec<[u32; 4]>,
    /// Region id per tetrahedron (Gmsh physical volume; 0 when the file has none).
    pub regions: Vec<u32>,
    /// How many tetrahedra arrived negatively oriented and were reordered.
    pub reoriented: usize,
}

/// Signed volume of the tetrahedron (a, b, c, d): positive for positive orientation.
#[inline]
pub fn signed_volume(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

/// Axis-aligned bounding box (min, max) of `points`; (+inf, -inf) when empty.
pub fn bounding_box(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(lo, hi), p| (lo.inf(p), hi.sup(p)))
}

/// Multiplies every point by `factor`.
pub fn scale_points(points: &mut [Vec3], factor: f64) {
    for p in points {
        *p *= factor;
    }
}

impl TetMesh {
    /// Validates and orients a mesh. `regions` may be empty (all 0).
    ///
    /// A tet whose |volume| is below `1e-12 * L^3` (L: its longest edge) is
    /// rejected as zero-volume; a negative one is reordered (swap of its last two
    /// nodes) and counted in [`TetMesh::reoriented`].
    pub fn new(positions: Vec<Vec3>, mut tets: Vec<[u32; 4]>, regions: Vec<u32>) -> Result<Self, MeshError> {
        if positions.is_empty() || tets.is_empty() {
            return Err(MeshError::Empty);
        }
        for (node, p) in positions.iter().enumerate() {
            if !is_finite3(p) {
                return Err(MeshError::NonFiniteNode { node, x: p.x, y: p.y, z: p.z });
            }
        }
        let regions = if regions.is_empty() { vec![0; tets.len()] } else { regions };
        if regions.len() != tets.len() {
            return Err(MeshError::RegionCount { tets: tets.len(), regions: regions.len() });
        }
        let count = positions.len();
        let mut reoriented = 0;
        for (t, tet) in tets.iter_mut().enumerate() {
            for (k, &n) in tet.iter().enumerate() {
                if n as usize >= count {
                    return Err(MeshError::IndexOutOfRange { tet: t, node: n as u64, count });
                }
                if tet[..k].contains(&n) {
                    return Err(MeshError::RepeatedNode { tet: t, node: n });
                }
            }
            let [a, b, c, d] = tet.map(|n| positions[n as usize]);
            let volume = signed_volume(&a, &b, &c, &d);
            let longest = [b - a, c - a, d - a, c - b, d - b, d - c]
                .iter()
                .map(|e| e.norm())
                .fold(0.0_f64, f64::max);
            let relative = volume.abs() / longest.powi(3).max(f64::MIN_POSITIVE);
            if !(relative > 1e-12) {
                return Err(MeshError::ZeroVolume { tet: t, volume, relative });
            }
            if volume < 0.0 {
                tet.swap(2, 3);
                reoriented += 1;
            }
        }
        Ok(Self { positions, tets, regions, reoriented })
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.positions.len()
    }

    /// Sum of the tetrahedra's volumes, m^3.
    pub fn volume(&self) -> f64 {
        self.tets.iter().map(|t| self.tet_volume(t)).sum()
    }

    /// Signed volume of one tetrahedron of this mesh, m^3.
    pub fn tet_volume(&self, t: &[u32; 4]) -> f64 {
        let [a, b, c, d] = t.map(|n| self.positions[n as usize]);
        signed_volume(&a, &b, &c, &d)
    }

    /// Axis-aligned bounding box (min, max), metres.
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        bounding_box(&self.positions)
    }

    /// Multiplies every coordinate by `factor` (e.g. 1e-3 for a file in mm).
    pub fn scale(&mut self, factor: f64) {
        scale_points(&mut self.positions, factor);
    }

    /// The boundary surface (faces used by exactly one tet), outward oriented.
    pub fn boundary(&self) -> BoundarySurface {
        BoundarySurface::of(self)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn grouping_by_key_keeps_each_keys_items_in_order_and_leaves_empty_keys_empty() {
        let entries = [(2u32, 10u32), (0, 11), (2, 12), (3, 13), (0, 14)];
        let (start, items) = group_by_key(5, || entries.iter().copied());
        assert_eq!(start, vec![0, 2, 2, 4, 5, 5]);
        assert_eq!(items, vec![11, 14, 10, 12, 13]);
        let (start, around) = triangles_around_vertices(4, &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!((start, around), (vec![0, 2, 3, 5, 6], vec![0, 1, 0, 0, 1, 1]));
    }

    /// A unit cube split into 6 positively oriented tets (Kuhn triangulation).
    pub fn cube() -> TetMesh {
        let mut p = Vec::new();
        for i in 0..8u32 {
            p.push(Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64));
        }
        let tets = vec![[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];
        TetMesh::new(p, tets, vec![]).expect("cube is valid")
    }

    #[test]
    fn cube_is_oriented_and_has_unit_volume() {
        let m = cube();
        assert!(m.tets.iter().all(|t| m.tet_volume(t) > 0.0));
        assert!((m.volume() - 1.0).abs() < 1e-14);
        assert!(m.reoriented > 0, "the Kuhn list mixes orientations; some must be reordered");
    }

    #[test]
    fn rejects_bad_input() {
        let p = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        assert_eq!(TetMesh::new(vec![], vec![], vec![]), Err(MeshError::Empty));
        assert!(matches!(TetMesh::new(p.clone(), vec![[0, 1, 2, 9]], vec![]), Err(MeshError::IndexOutOfRange { .. })));
        assert!(matches!(TetMesh::new(p.clone(), vec![[0, 1, 1, 3]], vec![]), Err(MeshError::RepeatedNode { .. })));
        let flat = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::new(1.0, 1.0, 0.0)];
        assert!(matches!(TetMesh::new(flat, vec![[0, 1, 2, 3]], vec![]), Err(MeshError::ZeroVolume { .. })));
        let mut nan = p.clone();
        nan[2].y = f64::NAN;
        assert!(matches!(TetMesh::new(nan, vec![[0, 1, 2, 3]], vec![]), Err(MeshError::NonFiniteNode { node: 2, .. })));
    }
}
