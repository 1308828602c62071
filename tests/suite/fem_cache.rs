//! The compliance disk cache: reload equals compute, corrupt or mismatched
//! files are rebuilt (never trusted), and the contact pressure functions.

use crate::fem_common as common;

use common::*;
use fissure::fem::{
    Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution, Material,
};
use fissure::sim::contact::{ContactScratch, PA_PER_MMHG, contact_patches};
use fissure::math::Vec3;

fn model(e: f64) -> FemModel {
    let mesh = block(4, 3, 3);
    let fixed = bottom_fixed(&mesh);
    FemModel::new(&mesh, &uniform(Material { young_modulus: e, poisson_ratio: 0.45 }), &fixed, &FemOptions::default()).unwrap()
}

#[test]
fn reload_is_bitwise_equal_and_corruption_is_rebuilt() {
    let dir = tempfile::tempdir().unwrap();
    let m = model(3e3);
    let roi = m.surface().vertices.clone();
    let mut calls = 0;
    let a = Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(dir.path()), &mut |_, _| calls += 1).unwrap();
    assert!(!a.stats().from_cache && calls > 1, "first call computes, with progress");
    let b = Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(dir.path()), &mut |_, _| {}).unwrap();
    assert!(b.stats().from_cache, "second call must load the cache");
    assert_eq!(all_block_bits(&a), all_block_bits(&b), "reloaded entries must be bitwise equal");
    // corrupt one byte in the middle of the data
    let file = std::fs::read_dir(dir.path()).unwrap().next().unwrap().unwrap().path();
    let mut bytes = std::fs::read(&file).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&file, &bytes).unwrap();
    let c = Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(dir.path()), &mut |_, _| {}).unwrap();
    assert!(!c.stats().from_cache, "a corrupt cache must be rebuilt, not trusted");
    assert_eq!(all_block_bits(&a), all_block_bits(&c));
    // truncated file
    std::fs::write(&file, &bytes[..100]).unwrap();
    let d = Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(dir.path()), &mut |_, _| {}).unwrap();
    assert!(!d.stats().from_cache, "a truncated cache must be rebuilt");
    // another material gives another key: not loaded from the first model's file
    let m2 = model(6e3);
    let e = Compliance::compute(&m2, &roi, ComplianceStorage::F64, Some(dir.path()), &mut |_, _| {}).unwrap();
    assert!(!e.stats().from_cache, "a different material must not reuse the cache");
    assert_ne!(a.key(), e.key());
    // f32 storage of the same model is another key too
    let f = Compliance::compute(&m, &roi, ComplianceStorage::F32, Some(dir.path()), &mut |_, _| {}).unwrap();
    let n = f.column_count();
    let roi_lower_entries = 9 * n * (n + 1) / 2;
    assert!(!f.stats().from_cache, "f32 storage is another key");
    assert_eq!(f.stats().bytes, a.stats().bytes / 2 + 2 * roi_lower_entries, "f32 halves the storage, plus 2 bytes a ROI x ROI entry");
    let g = Compliance::compute(&m, &roi, ComplianceStorage::F32, Some(dir.path()), &mut |_, _| {}).unwrap();
    assert!(g.stats().from_cache);
    assert_eq!(all_block_bits(&f), all_block_bits(&g), "reloaded f32 entries (with their corrections) must be bitwise equal");
    // ROI x ROI entries carry their correction: f64 to about 1e-12; the others are f32.
    let (mut worst_roi, mut worst_f32) = (0.0f64, 0.0f64);
    for col in 0..n {
        for row in col..f.row_nodes().len() {
            let (x, y) = (a.block(row, col), f.block(row, col));
            let e = (x - y).abs().max() / a.block(col, col).abs().max();
            if row < n { worst_roi = worst_roi.max(e) } else { worst_f32 = worst_f32.max(e) }
        }
    }
    println!("f32 storage: ROI x ROI error {worst_roi:e}, other rows {worst_f32:e} (relative to the diagonal)");
    assert!(worst_roi < 1e-11, "ROI x ROI entries with their correction: {worst_roi:e}");
    // a compliance of another model is refused by the solver
    assert!(ConstrainedSolver::new(m2, a).is_err(), "compliance and model must match");
}

#[test]
fn contact_pressure_per_spatula() {
    let m = model(3e3);
    let mesh = m.mesh().clone();
    let roi = m.surface().vertices.clone();
    let c = Compliance::compute(&m, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    let mut solver = ConstrainedSolver::new(m, c).unwrap();
    // spatula 0 presses the whole top face down 1 mm
    let cons: Vec<Constraint> = (0..mesh.node_count() as u32)
        .filter(|&n| (mesh.positions[n as usize].z - 0.03).abs() < 1e-12)
        .map(|n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.001) } })
        .collect();
    let mut out = FrameSolution::default();
    solver.step(&cons, &mut out).unwrap();
    let surface = solver.model().surface();
    let positions = surface.gather_positions(&mesh.positions);
    let (mut scratch, mut patches) = (ContactScratch::for_surface(surface), Vec::new());
    contact_patches(surface, &positions, &cons, &out.reactions, &mut scratch, &mut patches);
    assert_eq!(patches.len(), 1);
    let p = patches[0];
    // The area is the pushed vertices' lumped area: the whole top face, plus the
    // share (a third a pushed vertex) of the side triangles along its rim.
    let on_top = |v: u32| (positions[v as usize].z - 0.03).abs() < 1e-12;
    let rim: f64 = surface
        .triangles
        .iter()
        .filter(|t| t.iter().any(|&v| on_top(v)) && !t.iter().all(|&v| on_top(v)))
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            0.5 * (b - a).cross(&(c - a)).norm() * t.iter().filter(|&&v| on_top(v)).count() as f64 / 3.0
        })
        .sum();
    assert!(rim > 0.0);
    assert!((p.area - (0.06 * 0.04 + rim)).abs() < 1e-12, "the whole top face is in contact: area {} (top 0.0024 m^2, rim share {rim})", p.area);
    assert!(p.force.z < 0.0, "the spatula pushes the tissue down");
    assert!((p.mean_pressure_pa - p.force.norm() / p.area).abs() < 1e-9 * p.mean_pressure_pa);
    assert!((p.mean_pressure_mmhg * PA_PER_MMHG - p.mean_pressure_pa).abs() < 1e-9 * p.mean_pressure_pa);
    println!("top-face press 1 mm: force {:.4} N, pressure {:.1} Pa = {:.2} mmHg", p.force.norm(), p.mean_pressure_pa, p.mean_pressure_mmhg);
}

/// Sets a file's modification time `age_s` seconds in the past.
fn age(path: &std::path::Path, age_s: u64) {
    let t = std::time::SystemTime::now() - std::time::Duration::from_secs(age_s);
    std::fs::File::options().append(true).open(path).unwrap().set_modified(t).unwrap();
}

/// The cache directory stays under its budget: the least recently used
/// compliance files go first, a load counts as a use, half-written files of a
/// dead run go once stale, and files that are not ours stay.
#[test]
fn the_cache_directory_keeps_the_most_recently_used_files_within_its_budget() {
    use fissure::fem::compliance::prune_cache_dir;
    let dir = tempfile::tempdir().unwrap();
    let file = |name: &str, bytes: usize, age_s: u64| {
        let p = dir.path().join(name);
        std::fs::write(&p, vec![0u8; bytes]).unwrap();
        age(&p, age_s);
        p
    };
    let oldest = file("compliance-aaaa.bin", 400, 3000);
    let older = file("compliance-bbbb.bin", 400, 2000);
    let recent = file("compliance-cccc.bin", 400, 1000);
    let kept = file("compliance-dddd.bin", 400, 0);
    let stale_tmp = file("compliance-eeee.tmp123", 50, 7200);
    let fresh_tmp = file("compliance-ffff.tmp456", 50, 10);
    let other = file("notes.bin", 5000, 9000);
    prune_cache_dir(&kept, 1300);
    // kept 400 + recent 400 + older 400 = 1200 <= 1300; oldest would make 1600
    assert!(kept.exists() && recent.exists() && older.exists(), "the newest files that fit stay");
    assert!(!oldest.exists(), "the least recently used file goes");
    assert!(!stale_tmp.exists() && fresh_tmp.exists(), "only stale half-written files go");
    assert!(other.exists(), "files not named compliance-* are never touched");
    prune_cache_dir(&kept, 0);
    assert!(kept.exists() && !recent.exists() && !older.exists(), "the file just written stays even over budget");

    // A reload marks its file as used.
    let m = model(3e3);
    let roi = m.surface().vertices.clone();
    let cache = tempfile::tempdir().unwrap();
    Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(cache.path()), &mut |_, _| {}).unwrap();
    let written: Vec<_> = std::fs::read_dir(cache.path()).unwrap().flatten().map(|e| e.path()).collect();
    assert_eq!(written.len(), 1, "one cache file: {written:?}");
    age(&written[0], 5000);
    let before = std::fs::metadata(&written[0]).unwrap().modified().unwrap();
    let again = Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(cache.path()), &mut |_, _| {}).unwrap();
    assert!(again.stats().from_cache);
    assert!(std::fs::metadata(&written[0]).unwrap().modified().unwrap() > before, "a load marks the file as recently used");
}

/// A cache that cannot be written loses nothing: the compliance computed is
/// returned (with a warning), equal to one computed without a cache.
#[test]
fn an_unwritable_cache_directory_is_not_an_error() {
    let m = model(3e3);
    let roi = m.surface().vertices.clone();
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("not_a_dir");
    std::fs::write(&blocker, b"a file where the cache directory should be").unwrap();
    let cached = Compliance::compute(&m, &roi, ComplianceStorage::F64, Some(&blocker.join("cache")), &mut |_, _| {}).unwrap();
    let plain = Compliance::compute(&m, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    assert!(!cached.stats().from_cache);
    assert_eq!(all_block_bits(&cached), all_block_bits(&plain));
}
