//! The real brain meshes in `../shared/data/brain` load with the counts its
//! README states. Skipped, with a message, when that folder is absent.
//! Load times are printed (run with `--release -- --nocapture`), never asserted.

use std::path::{Path, PathBuf};
use std::time::Instant;

use fissure::mesh::io;
use fissure::mesh::quality::{QualityReport, components};

fn data(name: &str) -> Option<PathBuf> {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/brain")).join(name);
    if path.exists() {
        Some(path)
    } else {
        println!("skipped: {} is absent (the real brain meshes live beside the project)", path.display());
        None
    }
}

#[test]
fn coarse_brain_has_the_readme_counts() {
    let Some(path) = data("brain_pial_coarse.msh") else { return };
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
    let Some(path) = data("brain_pial_q15.msh") else { return };
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
fn brain_surface_obj_has_two_objects_merged() {
    let Some(path) = data("brain_pial_coarse_surface.obj") else { return };
    let start = Instant::now();
    let s = io::load_surface(&path).unwrap_or_else(|e| panic!("{e}"));
    println!("loaded {} in {:.3} s", path.display(), start.elapsed().as_secs_f64());
    assert_eq!(s.positions.len(), 20_484);
    assert_eq!(s.triangles.len(), 40_960);
}
