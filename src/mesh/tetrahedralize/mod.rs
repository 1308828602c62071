//! Quality tetrahedral meshes of a solid given by a signed distance function or
//! by a closed triangle surface.
//!
//! In: a cutting function `f` (negative inside, zero on the surface, positive
//! outside) over a box, or a closed [`TriSurface`], and a lattice edge length
//! `edge` (metres). Out: a validated [`TetMesh`] with a region id per tet.
//!
//! Method: isosurface stuffing (F. Labelle and J. R. Shewchuk, "Isosurface
//! Stuffing: Fast Tetrahedral Meshes with Good Dihedral Angles", SIGGRAPH 2007)
//! on a uniform body-centred-cubic lattice whose black (axis-parallel) edges
//! have length `edge`: cut points where `f` changes sign along lattice edges,
//! warping with the paper's parameters `alpha_long = 0.24999` and
//! `alpha_short = 0.41189`, then the paper's stencils (quadrilaterals split
//! at the cut point on a black edge, or by a parity rule when the black edge
//! joins the two inside vertices; see `stuffing.rs`).
//!
//! What stays true, and how we know:
//! - **Bound.** For these parameters the paper proves every dihedral angle lies
//!   in [10.7°, 164.8°] ([`MIN_DIHEDRAL_DEG`], [`MAX_DIHEDRAL_DEG`]), whatever
//!   the cut point positions (root-finding accuracy does not matter). Our
//!   parity rule is ours (written from the paper's description of its
//!   purpose), shown in `stuffing.rs` to give configurations congruent to the
//!   paper's; because that is our argument rather than the paper's proof,
//!   every mesh is also CHECKED here: a tet outside the bound is an error
//!   ([`TetrahedralizeError::QualityBound`]), never output. The tests assert
//!   the bound on every mesh they build, including random cutting functions.
//! - **Surface fidelity.** Boundary vertices lie on `f = 0` (to ~1e-7 of an
//!   edge); features thinner than about 1.2 edges may close or vanish.
//! - **Determinism.** Same input -> bitwise-identical mesh (lattice-order
//!   iteration; parallel evaluation of `f` only at input-determined points).
//! - Every tet is positively oriented with positive volume.

mod stuffing;
mod surface_sdf;

pub use stuffing::{ALPHA_LONG, ALPHA_SHORT};
pub use surface_sdf::SurfaceDistance;

use crate::math::{Vec3, is_finite3};
use crate::mesh::trisurface::SurfaceError;
use crate::mesh::{MeshError, TetMesh, TriSurface};
use stuffing::{Lattice, evaluate_parallel, stuff};

/// Smallest dihedral angle the method guarantees (degrees).
pub const MIN_DIHEDRAL_DEG: f64 = 10.7;
/// Largest dihedral angle the method guarantees (degrees).
pub const MAX_DIHEDRAL_DEG: f64 = 164.8;
/// Upper limit on lattice vertices (memory guard: about 100 bytes each).
pub const MAX_LATTICE_VERTICES: usize = 40_000_000;

/// Why a mesh could not be built.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum TetrahedralizeError {
    #[error("edge length must be finite and > 0 m, got {edge}")]
    InvalidEdge { edge: f64 },
    #[error("bounds must be finite with min < max on every axis, got min {min:?} max {max:?}")]
    InvalidBounds { min: [f64; 3], max: [f64; 3] },
    #[error("the lattice would have {count} vertices (limit {limit}); use a longer edge")]
    TooLarge { count: usize, limit: usize },
    #[error("the signed distance is not finite ({value}) at ({x}, {y}, {z})")]
    NonFiniteDistance { value: f64, x: f64, y: f64, z: f64 },
    #[error("no lattice vertex lies inside the solid (is it smaller than the edge {edge} m, or outside the bounds?)")]
    EmptyResult { edge: f64 },
    #[error("the solid reaches the bounds: lattice vertex at ({x}, {y}, {z}) on the lattice border is inside")]
    TouchesBounds { x: f64, y: f64, z: f64 },
    #[error("tetrahedron {tet} has dihedral angles {min_deg:.3}..{max_deg:.3} degrees, outside the guaranteed {MIN_DIHEDRAL_DEG}..{MAX_DIHEDRAL_DEG}")]
    QualityBound { tet: usize, min_deg: f64, max_deg: f64 },
    #[error("invalid surface: {0}")]
    Surface(#[from] SurfaceError),
    #[error("invalid mesh: {0}")]
    Mesh(#[from] MeshError),
}

/// Smallest and largest dihedral angle of a tetrahedron, degrees.
pub fn dihedral_range_deg(p: &[Vec3; 4]) -> (f64, f64) {
    // Outward-or-inward normals of the face opposite each vertex; the dihedral
    // angle at edge (i, j) is pi minus the angle between the normals of the
    // faces opposite the other two vertices, both oriented away from the tet.
    let faces = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let centroid = (p[0] + p[1] + p[2] + p[3]) / 4.0;
    let normals = faces.map(|f| {
        let n = (p[f[1]] - p[f[0]]).cross(&(p[f[2]] - p[f[0]]));
        let n = if n.dot(&(p[f[0]] - centroid)) < 0.0 { -n } else { n };
        let len = n.norm();
        if len > 0.0 { n / len } else { n }
    });
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, l) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        let c = normals[k].dot(&normals[l]).clamp(-1.0, 1.0);
        let angle = 180.0 - c.acos().to_degrees();
        lo = lo.min(angle);
        hi = hi.max(angle);
    }
    (lo, hi)
}

/// Meshes `{p : sdf(p) < 0}` inside `bounds` (min, max corners, metres) with a
/// BCC lattice of edge `edge` (metres); each tet gets `region(centroid)`.
///
/// The solid must stay inside the bounds (a lattice margin is added, and an
/// inside vertex on the lattice border is an error). The result may have
/// several components if the solid does; nothing is dropped.
pub fn tetrahedralize_sdf(
    sdf: &(dyn Fn(&Vec3) -> f64 + Sync),
    bounds: (Vec3, Vec3),
    edge: f64,
    region: &(dyn Fn(&Vec3) -> u32 + Sync),
) -> Result<TetMesh, TetrahedralizeError> {
    tetrahedralize_sdf_report(sdf, bounds, edge, region).map(|(mesh, _)| mesh)
}

/// What [`tetrahedralize_sdf_report`] did besides the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StuffingReport {
    /// Lattice vertices (corners and centres) evaluated.
    pub lattice_vertices: usize,
    /// Violated vertices made zero in place instead of warped, so that no tet
    /// breaks the bound (0 means the paper's algorithm ran unchanged).
    pub snapped_vertices: usize,
}

/// [`tetrahedralize_sdf`] that also says how the bound was kept.
pub fn tetrahedralize_sdf_report(
    sdf: &(dyn Fn(&Vec3) -> f64 + Sync),
    bounds: (Vec3, Vec3),
    edge: f64,
    region: &(dyn Fn(&Vec3) -> u32 + Sync),
) -> Result<(TetMesh, StuffingReport), TetrahedralizeError> {
    if !(edge.is_finite() && edge > 0.0) {
        return Err(TetrahedralizeError::InvalidEdge { edge });
    }
    let (lo, hi) = bounds;
    if !(is_finite3(&lo) && is_finite3(&hi) && (0..3).all(|a| lo[a] < hi[a])) {
        return Err(TetrahedralizeError::InvalidBounds { min: [lo.x, lo.y, lo.z], max: [hi.x, hi.y, hi.z] });
    }
    // One lattice cell of margin on each side beyond the box.
    let mut n = [0usize; 3];
    let mut count = 1.0_f64;
    for a in 0..3 {
        let cells = ((hi[a] - lo[a]) / edge).ceil() + 2.0;
        count *= cells + 1.0;
        n[a] = cells.min(1e9) as usize;
    }
    if count * 2.0 > MAX_LATTICE_VERTICES as f64 {
        return Err(TetrahedralizeError::TooLarge { count: (count * 2.0).min(1e18) as usize, limit: MAX_LATTICE_VERTICES });
    }
    let centre = (lo + hi) * 0.5;
    let span = Vec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * edge;
    let lattice = Lattice { origin: centre - span * 0.5, h: edge, n };

    let ids: Vec<u32> = (0..lattice.vertex_count() as u32).collect();
    let values = evaluate_parallel(&ids, &|&v: &u32| sdf(&lattice.position(v)));
    for (v, &value) in values.iter().enumerate() {
        if !value.is_finite() {
            let p = lattice.position(v as u32);
            return Err(TetrahedralizeError::NonFiniteDistance { value, x: p.x, y: p.y, z: p.z });
        }
    }
    // Corner vertices on the lattice border must be outside.
    for v in 0..lattice.corner_count() as u32 {
        let c = lattice.coord(v);
        let border = (0..3).any(|a| c[a] == 0 || c[a] == 2 * n[a] as i64);
        if border && values[v as usize] <= 0.0 {
            let p = lattice.position(v);
            return Err(TetrahedralizeError::TouchesBounds { x: p.x, y: p.y, z: p.z });
        }
    }
    if !values.iter().any(|&v| v < 0.0) {
        return Err(TetrahedralizeError::EmptyResult { edge });
    }
    let stuffed = stuff(&lattice, &values, sdf);
    if stuffed.tets.is_empty() {
        return Err(TetrahedralizeError::EmptyResult { edge });
    }
    for (t, tet) in stuffed.tets.iter().enumerate() {
        let p = tet.map(|k| stuffed.positions[k as usize]);
        let (min_deg, max_deg) = dihedral_range_deg(&p);
        if !(min_deg >= MIN_DIHEDRAL_DEG && max_deg <= MAX_DIHEDRAL_DEG) {
            return Err(TetrahedralizeError::QualityBound { tet: t, min_deg, max_deg });
        }
    }
    let regions: Vec<u32> = evaluate_parallel(&stuffed.tets, &|t: &[u32; 4]| {
        let c = t.iter().map(|&k| stuffed.positions[k as usize]).sum::<Vec3>() / 4.0;
        region(&c)
    });
    let report = StuffingReport { lattice_vertices: lattice.vertex_count(), snapped_vertices: stuffed.snapped };
    Ok((TetMesh::new(stuffed.positions, stuffed.tets, regions)?, report))
}

/// Meshes the solid bounded by a closed, consistently oriented, non-self-
/// intersecting triangle surface (either orientation) with lattice edge `edge`
/// (metres, in the surface's unit). All tets get region 1.
///
/// Rejects: an invalid or open surface ([`SurfaceError`] naming the edge or
/// triangle), a self-intersecting one (the first crossing pair), and a
/// surface with no volume. Inside test and distance: the nearest triangle
/// (BVH) and its angle-weighted pseudo-normal (see [`SurfaceDistance`]).
pub fn tetrahedralize_surface(surface: &TriSurface, edge: f64) -> Result<TetMesh, TetrahedralizeError> {
    if !(edge.is_finite() && edge > 0.0) {
        return Err(TetrahedralizeError::InvalidEdge { edge });
    }
    surface.check_closed()?;
    let crossings = surface.self_intersections(usize::MAX);
    if let Some(&(first, second)) = crossings.first() {
        return Err(SurfaceError::SelfIntersecting { first, second, count: crossings.len() }.into());
    }
    let field = SurfaceDistance::new(surface)?;
    let (lo, hi) = surface.bounding_box();
    let margin = Vec3::repeat(edge);
    tetrahedralize_sdf(&|p: &Vec3| field.signed_distance(p), (lo - margin, hi + margin), edge, &|_: &Vec3| 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tet_has_all_dihedrals_at_70_5_degrees() {
        let p = [
            Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0), Vec3::new(-1.0, -1.0, 1.0),
        ];
        let (lo, hi) = dihedral_range_deg(&p);
        let expected = (1.0_f64 / 3.0).acos().to_degrees();
        assert!((lo - expected).abs() < 1e-9 && (hi - expected).abs() < 1e-9, "got {lo}..{hi}");
        // The corner tet of a cube: three right dihedral angles, three of acos(1/sqrt 3) = 54.7°.
        let q = [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        let (lo, hi) = dihedral_range_deg(&q);
        assert!((hi - 90.0).abs() < 1e-9, "corner tet has right dihedral angles, max {hi}");
        assert!((lo - (1.0_f64 / 3.0_f64.sqrt()).acos().to_degrees()).abs() < 1e-9, "corner tet min {lo}");
    }

    #[test]
    fn sphere_volume_converges_and_respects_the_bound() {
        let r = 1.0;
        let sdf = |p: &Vec3| p.norm() - r;
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        let bounds = (Vec3::repeat(-1.2), Vec3::repeat(1.2));
        let coarse = tetrahedralize_sdf(&sdf, bounds, 0.25, &|_| 0).expect("coarse sphere");
        let fine = tetrahedralize_sdf(&sdf, bounds, 0.125, &|_| 0).expect("fine sphere");
        let (ec, ef) = ((coarse.volume() - exact).abs() / exact, (fine.volume() - exact).abs() / exact);
        assert!(ef < 0.01, "fine sphere volume within 1% of 4/3 pi, error {ef}");
        assert!(ef < ec, "refining reduces the volume error ({ec} -> {ef})");
        assert_eq!(fine.reoriented, 0, "stencils are emitted positively oriented");
    }

    #[test]
    fn rejects_bad_parameters() {
        let sdf = |p: &Vec3| p.norm() - 1.0;
        let b = (Vec3::repeat(-1.5), Vec3::repeat(1.5));
        assert!(matches!(tetrahedralize_sdf(&sdf, b, 0.0, &|_| 0), Err(TetrahedralizeError::InvalidEdge { .. })));
        assert!(matches!(tetrahedralize_sdf(&sdf, b, f64::NAN, &|_| 0), Err(TetrahedralizeError::InvalidEdge { .. })));
        assert!(matches!(tetrahedralize_sdf(&sdf, (b.1, b.0), 0.5, &|_| 0), Err(TetrahedralizeError::InvalidBounds { .. })));
        assert!(matches!(tetrahedralize_sdf(&sdf, b, 1e-5, &|_| 0), Err(TetrahedralizeError::TooLarge { .. })));
        let small = (Vec3::repeat(-0.5), Vec3::repeat(0.5));
        assert!(matches!(tetrahedralize_sdf(&sdf, small, 0.1, &|_| 0), Err(TetrahedralizeError::TouchesBounds { .. })));
        let far = |p: &Vec3| (p - Vec3::repeat(10.0)).norm() - 1.0;
        assert!(matches!(tetrahedralize_sdf(&far, b, 0.5, &|_| 0), Err(TetrahedralizeError::EmptyResult { .. })));
        let nan = |_: &Vec3| f64::NAN;
        assert!(matches!(tetrahedralize_sdf(&nan, b, 0.5, &|_| 0), Err(TetrahedralizeError::NonFiniteDistance { .. })));
    }

    /// A small deterministic generator (SplitMix64) for the random-field test.
    fn next_unit(state: &mut u64) -> f64 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn random_cutting_functions_never_break_the_bound() {
        // Guards the stencil and parity rules: random unions/intersections of
        // spheres and slabs cut the lattice at arbitrary fractions; every output
        // tet must stay inside the proven dihedral range (checked in
        // tetrahedralize_sdf, which errors otherwise) and tile a closed body.
        let mut state = 7u64;
        let mut meshes = 0;
        for case in 0..120 {
            let mut spheres = Vec::new();
            for _ in 0..3 {
                let c = Vec3::new(next_unit(&mut state), next_unit(&mut state), next_unit(&mut state)) * 1.2 - Vec3::repeat(0.6);
                spheres.push((c, 0.15 + 0.35 * next_unit(&mut state)));
            }
            let n = Vec3::new(next_unit(&mut state) - 0.5, next_unit(&mut state) - 0.5, next_unit(&mut state) - 0.5).normalize();
            let offset = 0.4 * next_unit(&mut state) - 0.2;
            let sdf = move |p: &Vec3| {
                let union = spheres.iter().map(|(c, r)| (p - c).norm() - r).fold(f64::INFINITY, f64::min);
                if case % 2 == 0 { union.max(n.dot(p) - offset) } else { union }
            };
            let h = 0.09 + 0.05 * next_unit(&mut state);
            match tetrahedralize_sdf(&sdf, (Vec3::repeat(-1.2), Vec3::repeat(1.2)), h, &|_| 0) {
                Ok(mesh) => {
                    meshes += 1;
                    let s = mesh.boundary();
                    let (area, volume) = s.area_vector_and_volume(&s.gather_positions(&mesh.positions));
                    assert!(area.norm() < 1e-9, "case {case}: boundary must be closed, area sum {area}");
                    assert!((volume - mesh.volume()).abs() < 1e-9 * mesh.volume(), "case {case}: outward boundary");
                }
                Err(TetrahedralizeError::EmptyResult { .. }) => {}
                Err(e) => panic!("case {case}: {e}"),
            }
        }
        assert!(meshes > 100, "most random solids are non-empty, got {meshes}");
    }
}
