//! Block-low-rank compliance (`ComplianceStorage::LowRank`): every stored
//! block within its tolerance of the f64 compliance, exact ROI symmetry, the
//! surface product, the constrained solve against f64, the disk cache, and
//! bitwise determinism of the build.

#[path = "fem_common/mod.rs"]
mod common;

use common::*;
use fissure::fem::fixtures::{box_mesh, linspace};
use fissure::fem::{
    Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemError, FemModel, FemOptions, FrameSolution, ProductWorkspace,
};
use fissure::math::{Matrix3, Vec3};
use fissure::mesh::TetMesh;
use std::sync::OnceLock;

/// A flat 72 x 48 x 12 mm slab (36 x 24 x 3 cells), bottom fixed: about 1,300
/// free surface nodes, enough for ~20 clusters and far (compressed) blocks.
fn slab() -> TetMesh {
    box_mesh(&linspace(0.0, 0.072, 36), &linspace(0.0, 0.048, 24), &linspace(0.0, 0.012, 3)).expect("valid slab")
}

const TOP: f64 = 0.012;

struct Fixture {
    mesh: TetMesh,
    model: FemModel,
    f64: Compliance,
    lr8: Compliance,
    lr4: Compliance,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let mesh = slab();
        let fixed = bottom_fixed(&mesh);
        let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
        // ROI: the upper half of the slab's surface (top face and upper sides).
        let roi: Vec<u32> = model.surface().vertices.iter().copied().filter(|&n| mesh.positions[n as usize].z >= 0.5 * TOP).collect();
        let build = |s| Compliance::compute(&model, &roi, s, None, &mut |_, _| {}).expect("compliance");
        let f64 = build(ComplianceStorage::F64);
        let lr8 = build(ComplianceStorage::LowRank { digits: 8 });
        let lr4 = build(ComplianceStorage::LowRank { digits: 4 });
        Fixture { mesh, model, f64, lr8, lr4 }
    })
}

fn frobenius2(m: &Matrix3<f64>) -> f64 {
    m.iter().map(|x| x * x).sum()
}

/// Largest relative Frobenius error over the stored cluster blocks (I >= J),
/// and over all blocks including the mirrored ones (I < J).
fn block_errors(lr: &Compliance, reference: &Compliance) -> (f64, f64) {
    let (starts, nc) = lr.low_rank_clusters().expect("low-rank storage exposes its clusters");
    let nr = starts.len() - 1;
    let mut worst_stored = 0.0f64;
    let mut worst_any = 0.0f64;
    for j in 0..nc {
        for i in 0..nr {
            let (mut err, mut norm) = (0.0, 0.0);
            for row in starts[i] as usize..starts[i + 1] as usize {
                for col in starts[j] as usize..starts[j + 1] as usize {
                    let (a, b) = (lr.block(row, col), reference.block(row, col));
                    err += frobenius2(&(a - b));
                    norm += frobenius2(&b);
                }
            }
            let rel = (err / norm.max(f64::MIN_POSITIVE)).sqrt();
            if i >= j {
                worst_stored = worst_stored.max(rel);
            }
            worst_any = worst_any.max(rel);
        }
    }
    (worst_stored, worst_any)
}

#[test]
fn every_block_is_within_its_tolerance_of_the_f64_compliance() {
    let f = fixture();
    for (lr, digits) in [(&f.lr8, 8u8), (&f.lr4, 4)] {
        let s = lr.stats();
        println!(
            "digits {digits}: {} rows x {} cols, {} compressed + {} dense blocks, mean rank {:.1}, max rank {}, {} bytes (f64 dense symmetric {} bytes)",
            s.rows, s.cols, s.compressed_blocks, s.dense_blocks, s.mean_rank, s.max_rank, s.bytes, f.f64.stats().bytes
        );
        assert_eq!(lr.storage(), ComplianceStorage::LowRank { digits });
        assert!(s.compressed_blocks >= 10, "digits {digits}: only {} blocks compressed: the far field is not compressed", s.compressed_blocks);
        assert!(s.bytes < f.f64.stats().bytes, "digits {digits}: low rank ({} B) must be smaller than f64 ({} B)", s.bytes, f.f64.stats().bytes);
        let tol = 10f64.powi(-(digits as i32));
        let (stored, any) = block_errors(lr, &f.f64);
        println!("digits {digits}: largest relative block error {stored:e} (stored), {any:e} (incl. mirrored)");
        assert!(stored <= tol, "digits {digits}: a stored block is off by {stored:e} relative, above {tol:e}");
        assert!(any <= tol, "digits {digits}: a mirrored block is off by {any:e} relative, above {tol:e}");
        assert!(stored > 1e-15, "digits {digits}: the error {stored:e} is f64 round-off: no block is really compressed");
    }
    assert_eq!(f.lr8.row_nodes(), f.f64.row_nodes(), "rows (and their order) do not depend on the storage");
    assert_eq!(f.lr8.column_count(), f.f64.column_count());
}

#[test]
fn roi_blocks_are_exactly_symmetric() {
    let f = fixture();
    let n = f.lr8.column_count();
    for p in 0..n {
        for q in 0..n {
            let (a, b) = (f.lr8.block(p, q), f.lr8.block(q, p).transpose());
            assert!(a == b, "block({p}, {q}) must be bitwise the transpose of block({q}, {p}): {a} vs {b}");
        }
    }
}

/// The surface product equals the block-by-block sum (all storages) and the f64 product within the tolerance.
#[test]
fn surface_product_matches_blocks_and_f64() {
    let f = fixture();
    let n_rows = f.f64.row_nodes().len();
    let n_cols = f.f64.column_count();
    // Forces on every 7th column plus a dense run: touches many clusters, both sides of the diagonal.
    let mut forces: Vec<(usize, Vec3)> = (0..n_cols).step_by(7).map(|c| (c, Vec3::new(1.0, -0.5 + (c % 3) as f64, 0.25 * (c % 5) as f64 - 0.5))).collect();
    forces.extend((n_cols / 2..n_cols / 2 + 40).filter(|c| c % 7 != 0).map(|c| (c, Vec3::new(0.0, 0.0, -1.0))));
    forces.sort_by_key(|x| x.0);
    let mut u_ref = vec![Vec3::zeros(); n_rows];
    let mut scratch = ProductWorkspace::default();
    f.f64.accumulate(&forces, &mut u_ref, &mut scratch);
    for (lr, digits) in [(&f.lr8, 8), (&f.lr4, 4)] {
        let mut u = vec![Vec3::zeros(); n_rows];
        let mut scratch = ProductWorkspace::default();
        lr.accumulate(&forces, &mut u, &mut scratch);
        let by_blocks: Vec<Vec3> = (0..n_rows).map(|r| forces.iter().map(|&(c, fc)| lr.block(r, c) * fc).sum()).collect();
        let e_blocks = rel_error(&u, &by_blocks);
        let e_f64 = rel_error(&u, &u_ref);
        println!("digits {digits}: product vs its own blocks {e_blocks:e}, vs f64 {e_f64:e}");
        assert!(e_blocks < 1e-12, "digits {digits}: accumulate disagrees with block() by {e_blocks:e}");
        assert!(e_f64 < 10f64.powi(-digits), "digits {digits}: product off the f64 one by {e_f64:e}");
        // Accumulates on top of what u holds, and reuses the scratch without growing it.
        let cap = scratch.bytes();
        let before = u.clone();
        lr.accumulate(&forces, &mut u, &mut scratch);
        assert_eq!(scratch.bytes(), cap, "the scratch must be reused, not regrown");
        let twice: Vec<Vec3> = before.iter().map(|x| x * 2.0).collect();
        assert!(rel_error(&u, &twice) < 1e-14, "accumulate must add to u");
    }
}

/// Press a disc of the top face (a few hundred enforced nodes), with the rest of the top inside a skull sphere.
fn constraints(f: &Fixture) -> Vec<Constraint> {
    let mut cons = Vec::new();
    for (n, p) in f.mesh.positions.iter().enumerate() {
        if (p.z - TOP).abs() > 1e-12 {
            continue;
        }
        let r = ((p.x - 0.030).powi(2) + (p.y - 0.024).powi(2)).sqrt();
        if r <= 0.016 {
            cons.push(Constraint { node: n as u32, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0005, 0.0, -0.002 + 0.05 * r * r) } });
        } else if p.x > 0.05 {
            // A second spatula lifts the far end: large far-field interaction with the first.
            cons.push(Constraint { node: n as u32, owner: 1, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0005, 0.0015) } });
        }
    }
    // Skull: a containing sphere that the lifted far end reaches.
    let center = Vec3::new(0.036, 0.024, -0.050);
    for &n in f.model.surface().vertices.iter() {
        let p = f.mesh.positions[n as usize];
        if (p.z - TOP).abs() < 1e-12 && p.x > 0.045 && p.x <= 0.05 {
            cons.push(Constraint { node: n, owner: 2, kind: ConstraintKind::SphereInside { center, radius: 0.0675 } });
        }
    }
    cons
}

fn solve(c: &Compliance, f: &Fixture, cons: &[Constraint]) -> FrameSolution {
    // FemModel is not Clone: the same inputs give the same model (and fingerprint).
    let model = FemModel::new(&f.mesh, &uniform(BRAIN), &bottom_fixed(&f.mesh), &FemOptions::default()).expect("model");
    let mut solver = ConstrainedSolver::new(model, c.clone()).expect("solver");
    let mut out = FrameSolution::default();
    solver.step(cons, &mut out).expect("step");
    out
}

#[test]
fn constrained_solve_matches_f64_within_the_stated_bounds() {
    let f = fixture();
    let cons = constraints(f);
    let enforced = cons.iter().filter(|c| matches!(c.kind, ConstraintKind::Enforced { .. })).count();
    assert!(enforced >= 200, "the test needs a few hundred enforced nodes, has {enforced}");
    let reference = solve(&f.f64, f, &cons);
    assert!(reference.active_sphere_contacts > 0, "the skull sphere must take part (no active contact)");
    let mut errors = Vec::new();
    for (lr, digits, bound) in [(&f.lr8, 8, 1e-6), (&f.lr4, 4, 1e-2)] {
        let out = solve(lr, f, &cons);
        let e_u = rel_error(&out.displacement_surface, &reference.displacement_surface);
        let e_r = rel_error(&out.reactions, &reference.reactions);
        println!(
            "digits {digits}: {enforced} enforced + {} sphere contacts; displacement rel. error {e_u:e}, reaction rel. error {e_r:e} (bound {bound:e})",
            out.active_sphere_contacts
        );
        assert!(e_u < bound && e_r < bound, "digits {digits}: errors {e_u:e} / {e_r:e} above the stated bound {bound:e}");
        assert_eq!(out.active_sphere_contacts, reference.active_sphere_contacts, "digits {digits}: another active set than f64");
        errors.push(e_u.max(e_r));
    }
    assert!(errors[1] > errors[0], "4 digits must be less accurate than 8 ({:e} vs {:e}): is the tolerance used?", errors[1], errors[0]);
}

fn all_blocks(c: &Compliance) -> Vec<f64> {
    let mut v = Vec::new();
    for col in 0..c.column_count() {
        for row in 0..c.row_nodes().len() {
            v.extend(c.block(row, col).iter().copied());
        }
    }
    v
}

fn product(c: &Compliance) -> Vec<Vec3> {
    let forces: Vec<(usize, Vec3)> = (0..c.column_count()).step_by(5).map(|k| (k, Vec3::new(0.3, -1.0, 0.7))).collect();
    let mut u = vec![Vec3::zeros(); c.row_nodes().len()];
    c.accumulate(&forces, &mut u, &mut ProductWorkspace::default());
    u
}

/// A 96 x 16 x 4 mm strip (one cell thick), bottom fixed, its free surface as
/// ROI: seven clusters along it, so far (compressed) blocks, yet fast to rebuild.
fn small_model() -> (FemModel, Vec<u32>) {
    let mesh = box_mesh(&linspace(0.0, 0.096, 48), &linspace(0.0, 0.016, 8), &linspace(0.0, 0.004, 1)).expect("valid strip");
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
    let roi = model.surface().vertices.clone();
    (model, roi)
}

#[test]
fn cache_round_trip_is_bitwise_and_corruption_is_rebuilt() {
    let (model, roi) = small_model();
    let dir = tempfile::tempdir().unwrap();
    let storage = ComplianceStorage::LowRank { digits: 6 };
    let compute = |s| Compliance::compute(&model, &roi, s, Some(dir.path()), &mut |_, _| {}).expect("compute");
    let a = compute(storage);
    assert!(!a.stats().from_cache);
    assert!(a.stats().compressed_blocks > 0, "the cache test must cover compressed blocks");
    let file = std::fs::read_dir(dir.path()).unwrap().next().unwrap().unwrap().path();
    let good = std::fs::read(&file).unwrap();
    let b = compute(storage);
    assert!(b.stats().from_cache, "the second call must load the cache");
    assert_eq!(all_blocks(&a), all_blocks(&b), "reloaded blocks must be bitwise equal");
    assert_eq!(product(&a), product(&b), "reloaded surface product must be bitwise equal");
    assert_eq!(b.stats().compressed_blocks, a.stats().compressed_blocks);
    assert_eq!(b.stats().bytes, a.stats().bytes);
    let corruptions: Vec<(&str, Vec<u8>)> = vec![
        ("a value in the middle", { let mut x = good.clone(); let m = x.len() / 2; x[m] ^= 0x40; x }),
        ("the block table", { let mut x = good.clone(); let at = 64 + 4 * a.row_nodes().len() + 24 + 4 * a.low_rank_clusters().unwrap().0.len() + 1; x[at] ^= 0x01; x }),
        ("the digits byte", { let mut x = good.clone(); x[13] = 7; x }),
        ("truncated", good[..good.len() - 9].to_vec()),
        ("one byte more", [good.as_slice(), &[0]].concat()),
    ];
    for (what, bytes) in corruptions {
        std::fs::write(&file, &bytes).unwrap();
        let c = compute(storage);
        assert!(!c.stats().from_cache, "a cache with {what} corrupted must be rebuilt, not trusted");
        assert_eq!(all_blocks(&c), all_blocks(&a), "{what}: the rebuilt compliance must equal the original bit for bit");
        assert_eq!(std::fs::read(&file).unwrap(), good, "{what}: the rebuilt file is rewritten intact");
    }
    // Other digits or another storage are other keys: never loaded from this file.
    let d = compute(ComplianceStorage::LowRank { digits: 7 });
    assert!(!d.stats().from_cache && d.key() != a.key(), "digits are part of the cache key");
    let e = compute(ComplianceStorage::F64);
    assert!(!e.stats().from_cache && e.key() != a.key(), "the storage variant is part of the cache key");
}

#[test]
fn two_builds_write_bitwise_identical_caches() {
    let (model, roi) = small_model();
    let storage = ComplianceStorage::LowRank { digits: 8 };
    let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let a = Compliance::compute(&model, &roi, storage, Some(d1.path()), &mut |_, _| {}).unwrap();
    // The second build runs on another thread: the result must not depend on where it runs.
    let b = std::thread::scope(|s| {
        s.spawn(|| Compliance::compute(&model, &roi, storage, Some(d2.path()), &mut |_, _| {}).unwrap()).join().unwrap()
    });
    assert!(!a.stats().from_cache && !b.stats().from_cache);
    let read = |d: &std::path::Path| std::fs::read(std::fs::read_dir(d).unwrap().next().unwrap().unwrap().path()).unwrap();
    assert!(read(d1.path()) == read(d2.path()), "two builds of the same inputs must write the same bytes");
    assert_eq!(product(&a), product(&b));
}

#[test]
fn digits_out_of_range_are_an_error_naming_the_field() {
    let (model, roi) = small_model();
    for digits in [0u8, 3, 13, 255] {
        match Compliance::compute(&model, &roi, ComplianceStorage::LowRank { digits }, None, &mut |_, _| {}) {
            Err(e @ FemError::InvalidOption { .. }) => assert!(e.to_string().contains("digits"), "the error must name the field: {e}"),
            Err(e) => panic!("digits {digits}: wrong error {e}"),
            Ok(_) => panic!("digits {digits} must be refused (valid 4..=12)"),
        }
    }
}

#[test]
fn low_rank_storage_serializes_with_its_digits() {
    let s = ComplianceStorage::LowRank { digits: 8 };
    let json = serde_json::to_string(&s).unwrap();
    assert_eq!(serde_json::from_str::<ComplianceStorage>(&json).unwrap(), s, "round trip of {json}");
    assert_ne!(json, serde_json::to_string(&ComplianceStorage::LowRank { digits: 6 }).unwrap(), "the digits are serialized");
}
