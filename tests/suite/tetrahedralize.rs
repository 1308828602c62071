//! Surface -> tetrahedra: closed sphere and torus surfaces are meshed with the
//! right volume inside the stated dihedral bound; open and self-intersecting
//! surfaces are rejected with the error that names the problem.

use std::f64::consts::PI;

use fissure::math::Vec3;
use fissure::mesh::TriSurface;
use fissure::mesh::tetrahedralize::{MAX_DIHEDRAL_DEG, MIN_DIHEDRAL_DEG, TetrahedralizeError, dihedral_range_deg, tetrahedralize_surface};
use fissure::mesh::trisurface::SurfaceError;

/// A torus (major radius `big`, minor `small`) as a closed outward grid of
/// `nu x nv` quads, each split in two triangles.
fn torus(big: f64, small: f64, nu: u32, nv: u32) -> TriSurface {
    let mut positions = Vec::new();
    for i in 0..nu {
        let u = 2.0 * PI * i as f64 / nu as f64;
        for j in 0..nv {
            let v = 2.0 * PI * j as f64 / nv as f64;
            let r = big + small * v.cos();
            positions.push(Vec3::new(r * u.cos(), r * u.sin(), small * v.sin()));
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + (j % nv);
    let mut triangles = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    let mut s = TriSurface { positions, triangles };
    if s.signed_volume() < 0.0 {
        for t in &mut s.triangles {
            t.swap(1, 2);
        }
    }
    s
}

/// A UV sphere of radius r with poles, closed and outward.
fn sphere(r: f64, rings: u32, segments: u32) -> TriSurface {
    let mut positions = vec![Vec3::new(0.0, 0.0, r)];
    for i in 1..rings {
        let th = PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = 2.0 * PI * j as f64 / segments as f64;
            positions.push(Vec3::new(r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()));
        }
    }
    positions.push(Vec3::new(0.0, 0.0, -r));
    let south = positions.len() as u32 - 1;
    let ring = |i: u32, j: u32| 1 + (i - 1) * segments + (j % segments);
    let mut triangles = Vec::new();
    for j in 0..segments {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
        triangles.push([south, ring(rings - 1, j + 1), ring(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let (a, b, c, d) = (ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriSurface { positions, triangles }
}

fn assert_bound(mesh: &fissure::mesh::TetMesh, what: &str) {
    for t in &mesh.tets {
        let (lo, hi) = dihedral_range_deg(&t.map(|k| mesh.positions[k as usize]));
        assert!(lo >= MIN_DIHEDRAL_DEG && hi <= MAX_DIHEDRAL_DEG, "{what}: tet {t:?} has dihedral {lo}..{hi}");
    }
}

#[test]
fn closed_sphere_surface_gives_its_volume() {
    let s = sphere(0.05, 48, 96);
    assert_eq!(s.check_closed(), Ok(()));
    let mesh = tetrahedralize_surface(&s, 0.006).expect("a closed sphere meshes");
    let polyhedron = s.signed_volume();
    let error = (mesh.volume() - polyhedron).abs() / polyhedron;
    assert!(error < 0.02, "sphere: tet volume {} vs surface volume {polyhedron} (error {error})", mesh.volume());
    assert!((polyhedron - 4.0 / 3.0 * PI * 0.05f64.powi(3)).abs() / polyhedron < 0.01, "the test sphere is round");
    assert_bound(&mesh, "sphere");
    // Inward-oriented input gives the same solid.
    let mut inward = s.clone();
    for t in &mut inward.triangles {
        t.swap(1, 2);
    }
    let again = tetrahedralize_surface(&inward, 0.006).expect("inward sphere meshes");
    assert_eq!(again.tets.len(), mesh.tets.len(), "orientation of the input does not change the solid");
}

#[test]
fn closed_torus_surface_gives_its_volume_and_keeps_its_hole() {
    let (big, small) = (0.04, 0.015);
    let s = torus(big, small, 96, 48);
    assert_eq!(s.check_closed(), Ok(()));
    let mesh = tetrahedralize_surface(&s, 0.004).expect("a closed torus meshes");
    let exact = 2.0 * PI * PI * big * small * small;
    let error = (mesh.volume() - exact).abs() / exact;
    assert!(error < 0.03, "torus: volume {} vs {exact} (error {error})", mesh.volume());
    assert_bound(&mesh, "torus");
    assert!(mesh.positions.iter().all(|p| (p.x * p.x + p.y * p.y).sqrt() > big - small - 1e-3), "no node fills the hole");
}

#[test]
fn open_surface_is_rejected_naming_an_edge() {
    let mut s = sphere(0.05, 12, 24);
    s.triangles.remove(5);
    match tetrahedralize_surface(&s, 0.01) {
        Err(TetrahedralizeError::Surface(SurfaceError::BoundaryEdge { from, to, .. })) => {
            assert_ne!(from, to, "the named edge joins two vertices");
        }
        other => panic!("an open surface must be rejected as open, got {other:?}"),
    }
}

#[test]
fn self_intersecting_surface_is_rejected() {
    let a = sphere(0.05, 12, 24);
    let mut b = sphere(0.05, 12, 24);
    for p in &mut b.positions {
        *p += Vec3::new(0.03, 0.0, 0.0);
    }
    let mut s = a.clone();
    let off = s.positions.len() as u32;
    s.positions.extend(b.positions);
    s.triangles.extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
    assert_eq!(s.check_closed(), Ok(()), "two closed spheres are edge-closed");
    match tetrahedralize_surface(&s, 0.01) {
        Err(TetrahedralizeError::Surface(SurfaceError::SelfIntersecting { first, second, count })) => {
            assert!(first < off && second >= off && count > 0, "crossing pairs are across the two spheres");
        }
        other => panic!("overlapping spheres must be rejected as self-intersecting, got {other:?}"),
    }
}

#[test]
fn degenerate_input_is_rejected() {
    let mut s = sphere(0.05, 12, 24);
    s.positions[3] = Vec3::new(f64::INFINITY, 0.0, 0.0);
    assert!(matches!(tetrahedralize_surface(&s, 0.01), Err(TetrahedralizeError::Surface(SurfaceError::NonFiniteVertex { vertex: 3, .. }))));
    assert!(matches!(tetrahedralize_surface(&TriSurface::default(), 0.01), Err(TetrahedralizeError::Surface(SurfaceError::Empty))));
    assert!(matches!(tetrahedralize_surface(&sphere(0.05, 12, 24), -1.0), Err(TetrahedralizeError::InvalidEdge { .. })));
}
