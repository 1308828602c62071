//! The shipped real brain meshes (`assets/brain/`, gzip'd Gmsh) load with the
//! counts its NOTICE.md states. Load times are printed (run with `--release --
//! --nocapture`), never asserted.

use std::path::PathBuf;
use std::time::Instant;

use fissure::mesh::brain;
use fissure::mesh::io;
use fissure::mesh::quality::{QualityReport, components};

fn data(stem: &str) -> PathBuf {
    let path = brain::shipped(stem);
    assert!(path.is_file(), "{} is missing from the checkout", path.display());
    path
}

#[test]
fn coarse_brain_has_the_readme_counts() {
    let path = data(brain::COARSE);
    let start = Instant::now();
    let mesh = io::load_tet_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
    println!("loaded {} in {:.3} s", path.display(), start.elapsed().as_secs_f64());
    assert_eq!(mesh.positions.len(), 25_757, "nodes");
    assert_eq!(mesh.tets.len(), 94_876, "tets");
    let report = QualityReport::of(&mesh);
    println!("{report}");
    assert_eq!(report.surface_triangles, 40_960, "boundary triangles");
    assert_eq!(report.components, 2, "two hemispheres");
    assert_eq!(report.unused_nodes, 0, "every node belongs to a tet");
    assert_eq!(report.regions.iter().map(|r| r.id).collect::<Vec<_>>(), vec![1, 2], "physical volumes 1 and 2");
    assert_eq!(report.regions.iter().map(|r| r.tets).sum::<usize>(), 94_876);
    assert!((report.min_mean_ratio - 0.025).abs() < 0.005, "README: minimum mean ratio 0.025, got {}", report.min_mean_ratio);
    // Each hemisphere is one component and one region.
    let c = components(&mesh);
    for (t, (&comp, &region)) in c.tet_component.iter().zip(&mesh.regions).enumerate() {
        assert_eq!(comp + 1, region, "tet {t}: component {comp} should be region {region} (left = 1 holds node 0)");
    }
    let surface = mesh.boundary();
    let pos = surface.gather_positions(&mesh.positions);
    let (area, volume) = surface.area_vector_and_volume(&pos);
    assert!(area.norm() < 1e-6 * report.volume_m3.powf(2.0 / 3.0), "closed surface: area vectors sum to {area}");
    assert!((volume - report.volume_m3).abs() < 1e-9 * report.volume_m3, "divergence volume {volume} vs tets {}", report.volume_m3);
}

#[test]
fn refined_brain_has_the_readme_counts() {
    let path = data(brain::FINE);
    let start = Instant::now();
    let mesh = io::load_tet_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
    println!("loaded {} in {:.3} s", path.display(), start.elapsed().as_secs_f64());
    assert_eq!(mesh.positions.len(), 62_773, "nodes");
    assert_eq!(mesh.tets.len(), 282_845, "tets");
    assert_eq!(components(&mesh).count, 2, "two hemispheres");
    let mut ids: Vec<u32> = mesh.regions.clone();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids, vec![1, 2]);
}

#[test]
fn coarse_brain_surface_round_trips_through_obj_and_gzip() {
    // The closed surface of the coarse mesh: 20,484 vertices, 40,960 triangles,
    // the fsaverage5 pial surfaces of both hemispheres. Written as gzip'd OBJ
    // and read back, it keeps its counts and every coordinate's bits.
    let mesh = io::load_tet_mesh(&data(brain::COARSE)).unwrap_or_else(|e| panic!("{e}"));
    let boundary = mesh.boundary();
    let surface = fissure::mesh::TriSurface { positions: boundary.gather_positions(&mesh.positions), triangles: boundary.triangles.clone() };
    assert_eq!(surface.positions.len(), 20_484);
    assert_eq!(surface.triangles.len(), 40_960);
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("pial.obj.gz");
    io::save_surface(&path, &surface).unwrap_or_else(|e| panic!("{e}"));
    let start = Instant::now();
    let back = io::load_surface(&path).unwrap_or_else(|e| panic!("{e}"));
    println!("loaded {} in {:.3} s", path.display(), start.elapsed().as_secs_f64());
    assert_eq!(back.triangles, surface.triangles);
    assert_eq!(back.positions, surface.positions, "shortest round-trip f64 text reads back to the same bits");
}
