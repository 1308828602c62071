//! Mesh quality and connectivity: what `fissure mesh info` reports.
//!
//! In: a validated [`TetMesh`]. Out: a [`QualityReport`] (counts, connected
//! components, reoriented tets, dihedral angles, mean-ratio quality, volume,
//! bounding box, tets per region), serializable to JSON and printable for
//! people, and [`components`] (tets connected through shared nodes).
//! Stays true: results depend only on the mesh (sorted statistics, components
//! numbered in order of their lowest node index), so two runs print the same.
//!
//! Mean ratio of a tet: `12 (3 V)^(2/3) / sum of its six squared edge lengths`,
//! 1 for the regular tet, tending to 0 for slivers and needles. Dihedral
//! angles: the six angles between face pairs, in degrees (70.53 for the regular
//! tet). Medians of an even count average the two middle values.

use std::collections::BTreeMap;
use std::fmt;

use serde::Serialize;

use super::TetMesh;
use crate::math::Vec3;

/// Marks a node used by no tetrahedron in [`Components::node_component`].
pub const NO_COMPONENT: u32 = u32::MAX;

/// Connected components of a mesh: tets sharing a node are connected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Components {
    /// Number of components.
    pub count: usize,
    /// Component of each node ([`NO_COMPONENT`] for a node no tet uses).
    pub node_component: Vec<u32>,
    /// Component of each tetrahedron.
    pub tet_component: Vec<u32>,
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Connected components; numbered 0, 1, ... in order of each component's lowest node index.
pub fn components(mesh: &TetMesh) -> Components {
    let n = mesh.node_count();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut used = vec![false; n];
    for t in &mesh.tets {
        for &k in t {
            used[k as usize] = true;
        }
        for &k in &t[1..] {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, k));
            // Attach the larger root under the smaller: a root is its component's lowest node.
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut id_of_root = vec![NO_COMPONENT; n];
    let mut node_component = vec![NO_COMPONENT; n];
    let mut count = 0u32;
    for v in 0..n {
        if !used[v] {
            continue;
        }
        let r = find(&mut parent, v as u32) as usize;
        if id_of_root[r] == NO_COMPONENT {
            id_of_root[r] = count;
            count += 1;
        }
        node_component[v] = id_of_root[r];
    }
    let tet_component = mesh.tets.iter().map(|t| node_component[t[0] as usize]).collect();
    Components { count: count as usize, node_component, tet_component }
}

/// The six dihedral angles (radians) and the mean ratio of a tet.
pub fn tet_shape(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> ([f64; 6], f64) {
    let p = [a, b, c, d];
    // Outward-or-inward face normals opposite each vertex (consistent sign: all inward here).
    let face = |i: usize, j: usize, k: usize, opposite: usize| {
        let n = (p[j] - p[i]).cross(&(p[k] - p[i]));
        if n.dot(&(p[opposite] - p[i])) < 0.0 { -n } else { n }
    };
    let normals = [face(1, 2, 3, 0), face(0, 2, 3, 1), face(0, 1, 3, 2), face(0, 1, 2, 3)];
    let mut angles = [0.0; 6];
    let mut e = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            let (ni, nj) = (normals[i], normals[j]);
            let denom = ni.norm() * nj.norm();
            // Inward normals: the dihedral angle at the shared edge is pi minus their angle.
            let cos = if denom > 0.0 { (-ni.dot(&nj) / denom).clamp(-1.0, 1.0) } else { 1.0 };
            angles[e] = cos.acos();
            e += 1;
        }
    }
    let volume = super::signed_volume(a, b, c, d);
    let sum_sq: f64 = [b - a, c - a, d - a, c - b, d - b, d - c].iter().map(|v| v.norm_squared()).sum();
    let mean_ratio = if sum_sq > 0.0 { 12.0 * (3.0 * volume.abs()).powf(2.0 / 3.0) / sum_sq } else { 0.0 };
    (angles, if volume < 0.0 { -mean_ratio } else { mean_ratio })
}

/// Tets of one region.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RegionCount {
    pub id: u32,
    pub tets: usize,
}

/// The summary `fissure mesh info` prints (and writes as JSON).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QualityReport {
    pub nodes: usize,
    pub tets: usize,
    pub surface_triangles: usize,
    pub components: usize,
    /// Nodes used by no tetrahedron (they make the stiffness matrix singular).
    pub unused_nodes: usize,
    /// Tets that arrived negatively oriented and were reordered ([`TetMesh::reoriented`]).
    pub inverted: usize,
    pub min_dihedral_deg: f64,
    pub median_dihedral_deg: f64,
    pub max_dihedral_deg: f64,
    pub min_mean_ratio: f64,
    pub median_mean_ratio: f64,
    /// Sum of tet volumes, in the mesh's unit cubed (m^3 once scaled).
    pub volume_m3: f64,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    /// Tets per region id, ascending ids.
    pub regions: Vec<RegionCount>,
}

fn median(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => sorted[n / 2],
        _ => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
    }
}

impl QualityReport {
    /// Measures `mesh`.
    pub fn of(mesh: &TetMesh) -> Self {
        let mut dihedral = Vec::with_capacity(6 * mesh.tets.len());
        let mut ratio = Vec::with_capacity(mesh.tets.len());
        for t in &mesh.tets {
            let [a, b, c, d] = t.map(|k| mesh.positions[k as usize]);
            let (angles, q) = tet_shape(&a, &b, &c, &d);
            dihedral.extend(angles.iter().map(|x| x.to_degrees()));
            ratio.push(q);
        }
        dihedral.sort_unstable_by(f64::total_cmp);
        ratio.sort_unstable_by(f64::total_cmp);
        let comps = components(mesh);
        let mut regions: BTreeMap<u32, usize> = BTreeMap::new();
        for &r in &mesh.regions {
            *regions.entry(r).or_default() += 1;
        }
        let (lo, hi) = mesh.bounding_box();
        Self {
            nodes: mesh.node_count(),
            tets: mesh.tets.len(),
            surface_triangles: mesh.boundary().triangles.len(),
            components: comps.count,
            unused_nodes: comps.node_component.iter().filter(|&&c| c == NO_COMPONENT).count(),
            inverted: mesh.reoriented,
            min_dihedral_deg: dihedral.first().copied().unwrap_or(f64::NAN),
            median_dihedral_deg: median(&dihedral),
            max_dihedral_deg: dihedral.last().copied().unwrap_or(f64::NAN),
            min_mean_ratio: ratio.first().copied().unwrap_or(f64::NAN),
            median_mean_ratio: median(&ratio),
            volume_m3: mesh.volume(),
            bbox_min: [lo.x, lo.y, lo.z],
            bbox_max: [hi.x, hi.y, hi.z],
            regions: regions.into_iter().map(|(id, tets)| RegionCount { id, tets }).collect(),
        }
    }
}

impl fmt::Display for QualityReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "nodes              {}", self.nodes)?;
        writeln!(f, "tetrahedra         {}", self.tets)?;
        writeln!(f, "surface triangles  {}", self.surface_triangles)?;
        writeln!(f, "components         {}", self.components)?;
        if self.unused_nodes > 0 {
            writeln!(f, "unused nodes       {} (used by no tetrahedron)", self.unused_nodes)?;
        }
        writeln!(f, "reoriented tets    {}", self.inverted)?;
        writeln!(
            f,
            "dihedral angle     min {:.2} deg, median {:.2} deg, max {:.2} deg",
            self.min_dihedral_deg, self.median_dihedral_deg, self.max_dihedral_deg
        )?;
        writeln!(f, "mean ratio         min {:.4}, median {:.4}", self.min_mean_ratio, self.median_mean_ratio)?;
        writeln!(f, "volume             {:.6e}", self.volume_m3)?;
        writeln!(
            f,
            "bounding box       [{:.6e}, {:.6e}, {:.6e}] .. [{:.6e}, {:.6e}, {:.6e}]",
            self.bbox_min[0], self.bbox_min[1], self.bbox_min[2], self.bbox_max[0], self.bbox_max[1], self.bbox_max[2]
        )?;
        write!(f, "regions           ")?;
        for r in &self.regions {
            write!(f, " {}: {} tets;", r.id, r.tets)?;
        }
        writeln!(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::tests::cube;

    #[test]
    fn regular_tet_has_mean_ratio_one_and_dihedral_70_53() {
        let s = 1.0 / 2f64.sqrt();
        let p = [Vec3::new(1.0, 0.0, -s), Vec3::new(-1.0, 0.0, -s), Vec3::new(0.0, 1.0, s), Vec3::new(0.0, -1.0, s)];
        let (angles, q) = tet_shape(&p[0], &p[1], &p[2], &p[3]);
        assert!((q.abs() - 1.0).abs() < 1e-12, "regular tet mean ratio {q}");
        for a in angles {
            assert!((a.to_degrees() - (1.0f64 / 3.0).acos().to_degrees()).abs() < 1e-9, "angle {}", a.to_degrees());
        }
    }

    #[test]
    fn sliver_has_small_mean_ratio_and_extreme_angles() {
        let p = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 0.0, 0.001), Vec3::new(0.0, 1.0, 0.001)];
        let (angles, q) = tet_shape(&p[0], &p[1], &p[2], &p[3]);
        assert!(q.abs() < 0.05, "sliver mean ratio {q}");
        let max = angles.iter().cloned().fold(0.0, f64::max).to_degrees();
        let min = angles.iter().cloned().fold(f64::INFINITY, f64::min).to_degrees();
        assert!(max > 170.0 && min < 10.0, "sliver angles {min}..{max}");
    }

    #[test]
    fn cube_report_and_two_components() {
        let m = cube();
        let r = QualityReport::of(&m);
        assert_eq!((r.nodes, r.tets, r.surface_triangles, r.components), (8, 6, 12, 1));
        assert!((r.volume_m3 - 1.0).abs() < 1e-14);
        assert_eq!(r.regions, vec![RegionCount { id: 0, tets: 6 }]);
        assert!((r.min_dihedral_deg - 45.0).abs() < 1e-9 && (r.max_dihedral_deg - 90.0).abs() < 1e-9, "{r}");

        // Two cubes side by side, not touching, listed second-first: numbering follows the lowest node.
        let mut p = m.positions.clone();
        p.extend(m.positions.iter().map(|q| q + Vec3::new(3.0, 0.0, 0.0)));
        let mut tets: Vec<[u32; 4]> = m.tets.iter().map(|t| t.map(|k| k + 8)).collect();
        tets.extend(m.tets.iter().copied());
        let two = TetMesh::new(p, tets, vec![]).expect("valid");
        let c = components(&two);
        assert_eq!(c.count, 2);
        assert_eq!(c.node_component[0], 0, "the component holding node 0 is numbered 0");
        assert_eq!(c.node_component[8], 1);
        assert_eq!(c.tet_component[0], 1, "the first tet lies in the second cube");
        let json = serde_json::to_value(QualityReport::of(&two)).expect("serializes");
        for key in ["nodes", "tets", "surface_triangles", "components", "inverted", "min_dihedral_deg"] {
            assert!(json.get(key).is_some(), "JSON key {key} missing: {json}");
        }
        assert_eq!(json["components"], 2);
    }
}
