//! Local refinement where the blades touch: longest-edge bisection of the
//! boundary edges inside given volumes.
//!
//! In: a [`TetMesh`], a target edge length `h` (m), a test "is this point in
//! the refined volume", a cap on the node count. Out: a refined [`TetMesh`]
//! whose first nodes are the input's (same indices, same positions), new
//! nodes appended, and [`RefineStats`]. Every boundary edge whose midpoint is
//! inside is split until it is no longer than `h`.
//!
//! How: an edge is split at its midpoint in every tetrahedron around it at
//! once (each becomes two, the halves of the same edge), so the mesh stays
//! conforming after every split. An edge is split only when it is the longest
//! edge of every tetrahedron around it; otherwise the longer edge is split
//! first (Rivara's longest-edge propagation path), which keeps the shapes of
//! the new tetrahedra within a bounded number of classes, so refinement never
//! makes slivers. Boundary edges wait in a heap, longest first; the order is
//! a function of the mesh alone (ties broken by node ids), so the result is
//! deterministic.
//!
//! Stays true: total volume unchanged (to round-off), every tetrahedron
//! positively oriented, region ids inherited, the boundary surface is the
//! same surface (new boundary nodes lie on the old boundary triangles).

use super::{MeshError, TetMesh};
use crate::math::Vec3;
use std::collections::{BinaryHeap, HashSet};

/// Why a refinement could not be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RefineError {
    #[error("the target edge length must be positive and finite (got {0} m)")]
    EdgeLength(f64),
    #[error(
        "refining to {edge_mm} mm edges would pass {limit} nodes (the mesh has {nodes}); give a larger edge length or a smaller volume"
    )]
    TooManyNodes { edge_mm: f64, nodes: usize, limit: usize },
    #[error("the refined mesh is invalid: {0}")]
    Mesh(#[from] MeshError),
}

/// What a refinement did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RefineStats {
    /// Edges split (= nodes added).
    pub splits: usize,
    /// Of those, boundary edges (= boundary nodes added).
    pub boundary_splits: usize,
    /// Tetrahedra added.
    pub tets_added: usize,
}

type Edge = (u32, u32);

fn edge(a: u32, b: u32) -> Edge {
    if a < b { (a, b) } else { (b, a) }
}

fn face(mut f: [u32; 3]) -> [u32; 3] {
    f.sort_unstable();
    f
}

/// The six edges of a tet, as local node pairs.
const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// An edge's place in the split order: longer first, ties by node ids.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Key {
    len2: f64,
    edge: Edge,
}

impl Eq for Key {}

impl Ord for Key {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.len2.total_cmp(&other.len2).then(self.edge.cmp(&other.edge))
    }
}

impl PartialOrd for Key {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

struct Work {
    positions: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    regions: Vec<u32>,
    /// Node -> the tets holding it, in the order each was last made or
    /// changed (the order the path's choices follow, so it is kept exactly);
    /// the tets around an edge are its first node's that hold the second (a
    /// node's list is short: 20-30 on the brains).
    node_tets: Vec<Vec<u32>>,
    /// Boundary faces (sorted node triples).
    boundary: HashSet<[u32; 3]>,
}

impl Work {
    fn key(&self, e: Edge) -> Key {
        Key { len2: (self.positions[e.0 as usize] - self.positions[e.1 as usize]).norm_squared(), edge: e }
    }

    fn longest(&self, t: u32) -> Edge {
        let tet = self.tets[t as usize];
        EDGES.iter().map(|&(i, j)| self.key(edge(tet[i], tet[j]))).max().map(|k| k.edge).unwrap_or((0, 0))
    }

    /// The tets around `e` into `out` (empty: no such edge).
    fn around(&self, e: Edge, out: &mut Vec<u32>) {
        out.clear();
        out.extend(self.node_tets[e.0 as usize].iter().copied().filter(|&t| self.tets[t as usize].contains(&e.1)));
    }

    fn exists(&self, e: Edge) -> bool {
        self.node_tets[e.0 as usize].iter().any(|&t| self.tets[t as usize].contains(&e.1))
    }

    fn link(&mut self, t: u32) {
        for n in self.tets[t as usize] {
            self.node_tets[n as usize].push(t);
        }
    }

    fn unlink(&mut self, t: u32) {
        for n in self.tets[t as usize] {
            self.node_tets[n as usize].retain(|&x| x != t);
        }
    }

    /// Splits `e` at its midpoint in every tet around it; returns the new
    /// node and the boundary edges the split made.
    fn split(&mut self, e: Edge, around: &[u32], new_boundary: &mut Vec<Edge>) -> u32 {
        let (a, b) = e;
        let m = self.positions.len() as u32;
        self.positions.push((self.positions[a as usize] + self.positions[b as usize]) * 0.5);
        self.node_tets.push(Vec::new());
        let mut on_boundary = false;
        for &t in around {
            let tet = self.tets[t as usize];
            self.unlink(t);
            // The two faces of this tet that hold the edge.
            for &c in tet.iter().filter(|&&n| n != a && n != b) {
                if self.boundary.remove(&face([a, b, c])) {
                    on_boundary = true;
                    self.boundary.insert(face([a, m, c]));
                    self.boundary.insert(face([m, b, c]));
                    new_boundary.push(edge(m, c));
                }
            }
            // Replacing one end by a point inside the edge keeps the orientation.
            let first = tet.map(|n| if n == b { m } else { n });
            let second = tet.map(|n| if n == a { m } else { n });
            self.tets[t as usize] = first;
            self.link(t);
            let s = self.tets.len() as u32;
            self.tets.push(second);
            self.regions.push(self.regions[t as usize]);
            self.link(s);
        }
        if on_boundary {
            new_boundary.push(edge(a, m));
            new_boundary.push(edge(m, b));
        }
        m
    }

    fn is_boundary_edge(&self, e: Edge, around: &[u32]) -> bool {
        around.iter().any(|&t| {
            self.tets[t as usize].iter().any(|&c| c != e.0 && c != e.1 && self.boundary.contains(&face([e.0, e.1, c])))
        })
    }
}

/// Refines `mesh` so that every boundary edge whose midpoint satisfies
/// `inside` is at most `h` long (m), splitting interior edges only where the
/// longest-edge rule needs it. Fails, before the node count passes
/// `max_nodes`, with [`RefineError::TooManyNodes`].
pub fn refine_boundary(
    mesh: &TetMesh,
    h: f64,
    inside: impl Fn(&Vec3) -> bool,
    max_nodes: usize,
) -> Result<(TetMesh, RefineStats), RefineError> {
    if !(h > 0.0 && h.is_finite()) {
        return Err(RefineError::EdgeLength(h));
    }
    let surface = mesh.boundary();
    let mut work = Work {
        positions: mesh.positions.clone(),
        tets: mesh.tets.clone(),
        regions: mesh.regions.clone(),
        node_tets: vec![Vec::new(); mesh.node_count()],
        boundary: surface.triangles.iter().map(|t| face(t.map(|v| surface.vertices[v as usize]))).collect(),
    };
    for t in 0..work.tets.len() as u32 {
        work.link(t);
    }
    let h2 = h * h;
    let wanted = |work: &Work, e: Edge| {
        let (p, q) = (work.positions[e.0 as usize], work.positions[e.1 as usize]);
        (p - q).norm_squared() > h2 && inside(&((p + q) * 0.5))
    };
    let mut heap: BinaryHeap<Key> = BinaryHeap::new();
    let mut seen: HashSet<Edge> = HashSet::new();
    for tri in &work.boundary {
        for (i, j) in [(0, 1), (1, 2), (0, 2)] {
            let e = edge(tri[i], tri[j]);
            if seen.insert(e) && wanted(&work, e) {
                heap.push(work.key(e));
            }
        }
    }
    drop(seen);
    let mut stats = RefineStats::default();
    let tets_before = work.tets.len();
    let mut new_boundary = Vec::new();
    let mut path: Vec<Edge> = Vec::new();
    let mut around: Vec<u32> = Vec::new();
    while let Some(Key { edge: target, .. }) = heap.pop() {
        if !work.exists(target) {
            continue; // split already, as part of another edge's path
        }
        path.clear();
        path.push(target);
        while let Some(&e) = path.last() {
            work.around(e, &mut around);
            if around.is_empty() {
                path.pop();
                continue;
            }
            // Each pushed edge is longer (in `Key` order) than the one under
            // it, so the path ends.
            if let Some(longer) = around.iter().map(|&t| work.longest(t)).find(|&l| l != e) {
                path.push(longer);
                continue;
            }
            if work.positions.len() >= max_nodes {
                return Err(RefineError::TooManyNodes { edge_mm: h * 1e3, nodes: mesh.node_count(), limit: max_nodes });
            }
            let was_boundary = work.is_boundary_edge(e, &around);
            new_boundary.clear();
            work.split(e, &around, &mut new_boundary);
            stats.splits += 1;
            stats.boundary_splits += usize::from(was_boundary);
            for &nb in &new_boundary {
                if wanted(&work, nb) {
                    heap.push(work.key(nb));
                }
            }
            path.pop();
        }
    }
    stats.tets_added = work.tets.len() - tets_before;
    let refined = TetMesh::new(work.positions, work.tets, work.regions)?;
    Ok((refined, stats))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::tests::cube;
    use std::collections::HashMap;

    fn surface_edges(m: &TetMesh) -> Vec<(Vec3, Vec3)> {
        let s = m.boundary();
        let mut out = Vec::new();
        for t in &s.triangles {
            for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                out.push((m.positions[s.vertices[t[i] as usize] as usize], m.positions[s.vertices[t[j] as usize] as usize]));
            }
        }
        out
    }

    /// Every interior face has two tets, every boundary face one; no face three.
    fn assert_conforming(m: &TetMesh) {
        let mut count: HashMap<[u32; 3], u32> = HashMap::new();
        for t in &m.tets {
            for f in [[t[1], t[2], t[3]], [t[0], t[2], t[3]], [t[0], t[1], t[3]], [t[0], t[1], t[2]]] {
                *count.entry(face(f)).or_default() += 1;
            }
        }
        assert!(count.values().all(|&c| c <= 2), "a face shared by three tets");
        // A hanging node would leave boundary faces inside the body: the
        // boundary's area equals the cube's.
        let s = m.boundary();
        let area: f64 = s
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| m.positions[s.vertices[v as usize] as usize]);
                0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()
            })
            .sum();
        assert!((area - 6.0).abs() < 1e-9, "boundary area {area}, a unit cube has 6");
    }

    #[test]
    fn refined_where_asked_conforming_same_volume_and_deterministic() {
        let m = cube();
        let inside = |p: &Vec3| p.z > 0.75; // the top face and the rim of the sides
        let (r, stats) = refine_boundary(&m, 0.2, inside, 100_000).expect("refines");
        assert!((r.volume() - 1.0).abs() < 1e-12, "volume {}", r.volume());
        assert!(r.tets.iter().all(|t| r.tet_volume(t) > 0.0));
        assert_eq!(r.positions[..m.node_count()], m.positions[..], "the input's nodes keep their indices");
        assert_eq!(stats.splits, r.node_count() - m.node_count());
        assert!(stats.boundary_splits > 0 && stats.boundary_splits <= stats.splits);
        assert_conforming(&r);
        for (p, q) in surface_edges(&r) {
            if (p.z + q.z) * 0.5 > 0.75 {
                assert!((p - q).norm() <= 0.2 + 1e-12, "edge {p:?}-{q:?} inside and still long");
            }
        }
        // Away from the volume the mesh is coarse still.
        assert!(surface_edges(&r).iter().any(|(p, q)| (p - q).norm() > 0.5 && (p.z + q.z) < 0.5));
        let (again, _) = refine_boundary(&m, 0.2, inside, 100_000).expect("refines");
        assert_eq!(again, r, "the same input gives the same mesh");
        // The quality of the worst tet stays within a bound of the input's:
        // longest-edge bisection does not make slivers.
        let worst = |m: &TetMesh| crate::mesh::quality::QualityReport::of(m).min_mean_ratio;
        assert!(worst(&r) > 0.25 * worst(&m), "worst mean ratio {} from {}", worst(&r), worst(&m));
    }

    #[test]
    fn nothing_inside_changes_nothing_and_limits_are_errors() {
        let m = cube();
        let (r, stats) = refine_boundary(&m, 0.1, |p| p.x > 5.0, 1000).expect("nothing to do");
        assert_eq!((r.positions.len(), r.tets.len(), stats.splits), (m.positions.len(), m.tets.len(), 0));
        assert_eq!(refine_boundary(&m, 0.0, |_| true, 1000).unwrap_err(), RefineError::EdgeLength(0.0));
        assert!(refine_boundary(&m, f64::NAN, |_| true, 1000).is_err());
        let err = refine_boundary(&m, 0.01, |_| true, 500).unwrap_err();
        assert!(matches!(err, RefineError::TooManyNodes { limit: 500, .. }), "{err}");
    }
}
