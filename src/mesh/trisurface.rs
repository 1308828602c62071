//! Triangle surfaces (OBJ/STL input, tetrahedralization input) and their checks.
//!
//! In: positions and triangles. Out: a [`TriSurface`] and checks that a surface
//! bounds a solid: [`TriSurface::validate`] (non-empty, finite, indices in range,
//! no zero-area triangle), [`TriSurface::check_closed`] (every edge shared by
//! exactly two triangles that traverse it in opposite directions) and
//! [`TriSurface::self_intersections`] (non-adjacent triangle pairs that cross,
//! found through a uniform grid, not by testing all pairs).
//! Stays true: the checks never panic on bad data and report the first offending
//! element in a fixed order (sorted edges, ascending triangle pairs).

use crate::math::{Vec3, is_finite3};

/// A triangle surface in metres (or the file's unit until scaled).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriSurface {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Why a triangle surface cannot bound a solid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    #[error("the surface has no vertices or no triangles")]
    Empty,
    #[error("vertex {vertex} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFiniteVertex { vertex: usize, x: f64, y: f64, z: f64 },
    #[error("triangle {triangle} refers to vertex {vertex}, but the surface has {count} vertices")]
    IndexOutOfRange { triangle: usize, vertex: u32, count: usize },
    #[error("triangle {triangle} is degenerate (area {area:e}, relative {relative:e} of its longest edge squared)")]
    DegenerateTriangle { triangle: usize, area: f64, relative: f64 },
    #[error("the surface is not closed: edge ({from}, {to}) of triangle {triangle} has no triangle on its other side")]
    BoundaryEdge { from: u32, to: u32, triangle: usize },
    #[error("the surface is not a manifold: edge ({a}, {b}) is shared by {count} triangles")]
    NonManifoldEdge { a: u32, b: u32, count: usize },
    #[error("inconsistent orientation: triangles {first} and {second} both traverse edge ({from}, {to}) in the same direction")]
    InconsistentOrientation { from: u32, to: u32, first: usize, second: usize },
    #[error("the surface intersects itself: triangles {first} and {second} cross ({count} crossing pairs found)")]
    SelfIntersecting { first: u32, second: u32, count: usize },
}

impl TriSurface {
    /// Checks that the surface is non-empty, finite, in range and has no
    /// zero-area triangle (area below `1e-12` of its longest edge squared).
    pub fn validate(&self) -> Result<(), SurfaceError> {
        if self.positions.is_empty() || self.triangles.is_empty() {
            return Err(SurfaceError::Empty);
        }
        for (vertex, p) in self.positions.iter().enumerate() {
            if !is_finite3(p) {
                return Err(SurfaceError::NonFiniteVertex { vertex, x: p.x, y: p.y, z: p.z });
            }
        }
        let count = self.positions.len();
        for (triangle, t) in self.triangles.iter().enumerate() {
            for &vertex in t {
                if vertex as usize >= count {
                    return Err(SurfaceError::IndexOutOfRange { triangle, vertex, count });
                }
            }
            let [a, b, c] = t.map(|k| self.positions[k as usize]);
            let area = 0.5 * (b - a).cross(&(c - a)).norm();
            let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
            let relative = area / (longest * longest).max(f64::MIN_POSITIVE);
            if !(relative > 1e-12) {
                return Err(SurfaceError::DegenerateTriangle { triangle, area, relative });
            }
        }
        Ok(())
    }

    /// Checks that every edge is shared by exactly two triangles that traverse it
    /// in opposite directions (a closed, consistently oriented 2-manifold edge set).
    /// Runs [`TriSurface::validate`] first. The error names the first offending
    /// edge in ascending (min vertex, max vertex) order.
    pub fn check_closed(&self) -> Result<(), SurfaceError> {
        self.validate()?;
        // (min, max, forward?, triangle): forward when the triangle goes min -> max.
        let mut edges: Vec<(u32, u32, bool, usize)> = Vec::with_capacity(self.triangles.len() * 3);
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (u, v) = (tri[k], tri[(k + 1) % 3]);
                edges.push((u.min(v), u.max(v), u < v, t));
            }
        }
        edges.sort_unstable();
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
                j += 1;
            }
            let (a, b, forward, triangle) = edges[i];
            match j - i {
                1 => {
                    let (from, to) = if forward { (a, b) } else { (b, a) };
                    return Err(SurfaceError::BoundaryEdge { from, to, triangle });
                }
                2 => {
                    let other = edges[i + 1];
                    if other.2 == forward {
                        let (from, to) = if forward { (a, b) } else { (b, a) };
                        return Err(SurfaceError::InconsistentOrientation { from, to, first: triangle, second: other.3 });
                    }
                }
                count => return Err(SurfaceError::NonManifoldEdge { a, b, count }),
            }
            i = j;
        }
        Ok(())
    }

    /// Up to `limit` pairs `(i, j)`, `i < j`, of triangles that share no vertex
    /// and intersect (an edge of one crosses the other), in ascending order.
    /// Uses a uniform grid with cells about the mean edge length; expected cost
    /// is linear in the triangle count for well-spread surfaces. Coplanar
    /// overlaps without a transversal edge crossing are not reported.
    /// Triangles with out-of-range indices are skipped (see [`TriSurface::validate`]).
    pub fn self_intersections(&self, limit: usize) -> Vec<(u32, u32)> {
        let mut found = Vec::new();
        if limit == 0 || self.triangles.is_empty() {
            return found;
        }
        let n = self.positions.len();
        let valid: Vec<bool> = self
            .triangles
            .iter()
            .map(|t| t.iter().all(|&v| (v as usize) < n && is_finite3(&self.positions[v as usize])))
            .collect();
        let Some((lo, hi, mean_edge)) = self.bounds_and_mean_edge(&valid) else {
            return found;
        };
        let extent = hi - lo;
        let diag = extent.norm().max(f64::MIN_POSITIVE);
        // Cell size: about the mean edge, but at most ~2M cells.
        let mut cell = mean_edge.max(diag * 1e-6);
        let cells_of = |c: f64| -> [usize; 3] { [0, 1, 2].map(|a| ((extent[a] / c).floor() as usize).max(0) + 1) };
        let mut dims = cells_of(cell);
        while dims.iter().map(|&d| d as f64).product::<f64>() > 2.0e6 {
            cell *= 1.5;
            dims = cells_of(cell);
        }
        let cell_of = |p: &Vec3| -> [usize; 3] {
            [0, 1, 2].map(|a| (((p[a] - lo[a]) / cell).floor().max(0.0) as usize).min(dims[a] - 1))
        };
        let ranges: Vec<([usize; 3], [usize; 3])> = self
            .triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                if !valid[t] {
                    return ([1, 1, 1], [0, 0, 0]);
                }
                let ps = tri.map(|v| self.positions[v as usize]);
                let (a, b) = (ps[0].inf(&ps[1]).inf(&ps[2]), ps[0].sup(&ps[1]).sup(&ps[2]));
                (cell_of(&a), cell_of(&b))
            })
            .collect();
        // Bucket triangles by cell: (cell index, triangle), sorted.
        let flat = |c: [usize; 3]| c[0] + dims[0] * (c[1] + dims[1] * c[2]);
        let mut entries: Vec<(usize, u32)> = Vec::new();
        for (t, (a, b)) in ranges.iter().enumerate() {
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        entries.push((flat([x, y, z]), t as u32));
                    }
                }
            }
        }
        entries.sort_unstable();
        let mut i = 0;
        while i < entries.len() {
            let mut j = i + 1;
            while j < entries.len() && entries[j].0 == entries[i].0 {
                j += 1;
            }
            let here = entries[i].0;
            for p in i..j {
                for q in p + 1..j {
                    let (s, t) = (entries[p].1, entries[q].1);
                    let (ra, rb) = (&ranges[s as usize], &ranges[t as usize]);
                    // Test a pair only in the first cell both cover.
                    let first = [0, 1, 2].map(|a| ra.0[a].max(rb.0[a]));
                    if flat(first) != here {
                        continue;
                    }
                    let (ts, tt) = (self.triangles[s as usize], self.triangles[t as usize]);
                    if ts.iter().any(|v| tt.contains(v)) {
                        continue;
                    }
                    let a = ts.map(|v| self.positions[v as usize]);
                    let b = tt.map(|v| self.positions[v as usize]);
                    if triangles_cross(&a, &b) {
                        found.push((s.min(t), s.max(t)));
                    }
                }
            }
            i = j;
        }
        found.sort_unstable();
        found.dedup();
        found.truncate(limit);
        found
    }

    /// The bounding box of the `valid` triangles and their mean edge length (`None`: no valid triangle).
    fn bounds_and_mean_edge(&self, valid: &[bool]) -> Option<(Vec3, Vec3, f64)> {
        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        let mut edge_sum = 0.0;
        let mut edge_count = 0usize;
        for (t, tri) in self.triangles.iter().enumerate() {
            if !valid[t] {
                continue;
            }
            for k in 0..3 {
                let p = self.positions[tri[k] as usize];
                lo = lo.inf(&p);
                hi = hi.sup(&p);
                edge_sum += (self.positions[tri[(k + 1) % 3] as usize] - p).norm();
                edge_count += 1;
            }
        }
        (edge_count > 0).then(|| (lo, hi, edge_sum / edge_count as f64))
    }

    /// Volume enclosed by the surface by the divergence theorem (positive when
    /// the triangles are counter-clockwise seen from outside), in unit^3.
    pub fn signed_volume(&self) -> f64 {
        let n = self.positions.len();
        self.triangles
            .iter()
            .filter(|t| t.iter().all(|&v| (v as usize) < n))
            .map(|t| {
                let [a, b, c] = t.map(|k| self.positions[k as usize]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Total area, unit^2.
    pub fn area(&self) -> f64 {
        let n = self.positions.len();
        self.triangles
            .iter()
            .filter(|t| t.iter().all(|&v| (v as usize) < n))
            .map(|t| {
                let [a, b, c] = t.map(|k| self.positions[k as usize]);
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .sum()
    }

    /// Multiplies every coordinate by `factor` (e.g. 1e-3 for a file in mm).
    pub fn scale(&mut self, factor: f64) {
        super::scale_points(&mut self.positions, factor);
    }

    /// Axis-aligned bounding box (min, max) of the vertices.
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        super::bounding_box(&self.positions)
    }
}

/// True when an edge of one triangle crosses the interior of the other.
fn triangles_cross(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    (0..3).any(|k| segment_crosses_triangle(&a[k], &a[(k + 1) % 3], b))
        || (0..3).any(|k| segment_crosses_triangle(&b[k], &b[(k + 1) % 3], a))
}

/// Segment p-q against triangle t (closed segment, closed triangle, non-coplanar).
fn segment_crosses_triangle(p: &Vec3, q: &Vec3, t: &[Vec3; 3]) -> bool {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let dp = n.dot(&(p - t[0]));
    let dq = n.dot(&(q - t[0]));
    if (dp > 0.0 && dq > 0.0) || (dp < 0.0 && dq < 0.0) || dp == dq {
        return false;
    }
    let s = dp / (dp - dq);
    let x = p + (q - p) * s;
    // Inside test by same-side signs of the sub-triangle normals.
    let c0 = (t[1] - t[0]).cross(&(x - t[0])).dot(&n);
    let c1 = (t[2] - t[1]).cross(&(x - t[1])).dot(&n);
    let c2 = (t[0] - t[2]).cross(&(x - t[2])).dot(&n);
    c0 >= 0.0 && c1 >= 0.0 && c2 >= 0.0
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An axis-aligned cube [0,1]^3 as 12 outward triangles.
    pub fn cube_surface() -> TriSurface {
        let positions = (0..8u32).map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
        let triangles = vec![
            [0, 2, 1], [1, 2, 3], // z = 0
            [4, 5, 6], [5, 7, 6], // z = 1
            [0, 1, 4], [1, 5, 4], // y = 0
            [2, 6, 3], [3, 6, 7], // y = 1
            [0, 4, 2], [2, 4, 6], // x = 0
            [1, 3, 5], [3, 7, 5], // x = 1
        ];
        TriSurface { positions, triangles }
    }

    #[test]
    fn cube_is_closed_with_unit_volume() {
        let s = cube_surface();
        assert_eq!(s.check_closed(), Ok(()));
        assert!((s.signed_volume() - 1.0).abs() < 1e-14, "outward cube encloses +1, got {}", s.signed_volume());
        assert!((s.area() - 6.0).abs() < 1e-14);
        assert!(s.self_intersections(10).is_empty());
    }

    #[test]
    fn open_surface_names_its_boundary_edge() {
        let mut s = cube_surface();
        s.triangles.pop();
        match s.check_closed() {
            Err(SurfaceError::BoundaryEdge { from, to, .. }) => {
                let pair = (from.min(to), from.max(to));
                assert!([(3, 5), (3, 7), (5, 7)].contains(&pair), "removed triangle (3,7,5) leaves one of its edges open, got {pair:?}");
            }
            other => panic!("expected a boundary edge, got {other:?}"),
        }
    }

    #[test]
    fn flipped_triangle_is_inconsistent() {
        let mut s = cube_surface();
        s.triangles[0] = [0, 1, 2];
        assert!(matches!(s.check_closed(), Err(SurfaceError::InconsistentOrientation { .. })));
        let mut s = cube_surface();
        s.scale(2.0);
        assert!((s.signed_volume() - 8.0).abs() < 1e-12);
    }

    #[test]
    fn bad_input_is_named() {
        let mut s = cube_surface();
        s.positions[3].x = f64::NAN;
        assert!(matches!(s.check_closed(), Err(SurfaceError::NonFiniteVertex { vertex: 3, .. })));
        let mut s = cube_surface();
        s.triangles[4] = [0, 1, 99];
        assert!(matches!(s.check_closed(), Err(SurfaceError::IndexOutOfRange { triangle: 4, vertex: 99, .. })));
        let _ = s.self_intersections(5); // out-of-range triangles are skipped, never a panic
        let mut s = cube_surface();
        s.triangles[4] = [0, 1, 1];
        assert!(matches!(s.check_closed(), Err(SurfaceError::DegenerateTriangle { triangle: 4, .. })));
        assert_eq!(TriSurface::default().check_closed(), Err(SurfaceError::Empty));
    }

    #[test]
    fn two_interpenetrating_cubes_are_found() {
        let a = cube_surface();
        let mut b = cube_surface();
        for p in &mut b.positions {
            *p += Vec3::new(0.5, 0.3, 0.2);
        }
        let mut s = a.clone();
        let off = s.positions.len() as u32;
        s.positions.extend(b.positions);
        s.triangles.extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
        assert_eq!(s.check_closed(), Ok(()), "two closed cubes are edge-closed");
        let pairs = s.self_intersections(1000);
        assert!(!pairs.is_empty(), "overlapping cubes must intersect");
        assert!(pairs.iter().all(|&(i, j)| i < 12 && j >= 12), "only pairs across the two cubes cross: {pairs:?}");
        assert!(pairs.windows(2).all(|w| w[0] < w[1]), "ascending and unique");
        assert_eq!(s.self_intersections(2).len(), 2, "limit is respected");
    }
}
