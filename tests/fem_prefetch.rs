//! Lazy columns solved on the background thread ([`ConstrainedSolver::prefetch`]):
//! a frame that meets a prefetched node solves nothing itself, the result
//! stays exact, and no bit depends on when the worker finished.

#[path = "fem_common/mod.rs"]
mod common;

use common::*;
use fissure::fem::constrained::{PREFETCH_BATCH, PREFETCH_JOIN_FRAMES};
use fissure::fem::{Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

/// Top-face nodes within `radius` of `center` pushed by `d`.
fn patch(mesh: &TetMesh, center: (f64, f64), radius: f64, owner: u16, d: Vec3) -> Vec<Constraint> {
    mesh.positions
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.z - 0.03).abs() < 1e-12 && ((p.x - center.0).powi(2) + (p.y - center.1).powi(2)).sqrt() <= radius)
        .map(|(n, _)| Constraint { node: n as u32, owner, kind: ConstraintKind::Enforced { displacement: d } })
        .collect()
}

/// A block whose ROI is the half x <= 30 mm: the right half needs lazy columns.
fn half_roi_solver() -> (TetMesh, ConstrainedSolver) {
    let mesh = block(6, 4, 4);
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
    let roi: Vec<u32> = model.surface().vertices.iter().copied().filter(|&n| mesh.positions[n as usize].x <= 0.03 + 1e-12).collect();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).expect("compliance");
    (mesh, ConstrainedSolver::new(model, c).expect("solver"))
}

/// Frames of a spatula sliding from inside the ROI to outside it.
fn frames(mesh: &TetMesh) -> Vec<Vec<Constraint>> {
    (0..24).map(|k| patch(mesh, (0.02 + 0.0015 * k as f64, 0.02), 0.011, 0, Vec3::new(0.0, 0.0, -0.002))).collect()
}

/// Nodes right of the ROI on the top face, nearest to the ROI first.
fn ahead(mesh: &TetMesh) -> Vec<u32> {
    let mut v: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| {
        let p = mesh.positions[n as usize];
        (p.z - 0.03).abs() < 1e-12 && p.x > 0.03 + 1e-12 && p.x < 0.06
    }).collect();
    v.sort_by(|a, b| mesh.positions[*a as usize].x.total_cmp(&mesh.positions[*b as usize].x).then(a.cmp(b)));
    v
}

#[test]
fn a_prefetched_node_costs_the_frame_no_solve_and_stays_exact() {
    let (mesh, mut solver) = half_roi_solver();
    let right = patch(&mesh, (0.045, 0.02), 0.011, 1, Vec3::new(-0.001, 0.0005, -0.001));
    let nodes: Vec<u32> = right.iter().map(|c| c.node).collect();
    assert!(nodes.len() <= PREFETCH_BATCH && !nodes.is_empty());
    // ROI columns and fixed nodes are not requested.
    let roi_node = patch(&mesh, (0.01, 0.02), 0.005, 0, Vec3::zeros())[0].node;
    assert_eq!(solver.prefetch(&[roi_node, 0]), 0, "a ROI column and a fixed node need no background solve");
    assert_eq!(solver.prefetch(&nodes), nodes.len());
    assert_eq!(solver.prefetch(&nodes), 0, "requested nodes are not requested twice");
    let mut out = FrameSolution::default();
    solver.step(&right, &mut out).expect("step");
    assert_eq!(out.lazy_solves, 0, "every column came from the background batch");
    let mut fresh = half_roi_solver().1;
    let mut expected = FrameSolution::default();
    fresh.step(&right, &mut expected).expect("step");
    assert!(expected.lazy_solves > 0);
    let e_u = rel_error(&out.displacement_surface, &expected.displacement_surface);
    let e_r = rel_error(&out.reactions, &expected.reactions);
    assert!(e_u < 1e-12 && e_r < 1e-12, "prefetched columns give the solve of on-demand columns: {e_u:e}, {e_r:e}");
    assert_eq!(solver.cached_lazy_nodes().count(), nodes.len());
}

/// The same frames and prefetch calls, with the worker given all the time it
/// wants in one run and none in the other: every frame bitwise equal.
#[test]
fn results_do_not_depend_on_when_the_worker_finishes() {
    let run = |patient: bool| -> (Vec<FrameSolution>, usize) {
        let (mesh, mut solver) = half_roi_solver();
        let ahead = ahead(&mesh);
        let mut outs = Vec::new();
        let mut requested = 0;
        for (k, cons) in frames(&mesh).iter().enumerate() {
            if k % 4 == 0 {
                requested += solver.prefetch(&ahead[(k / 4 * 3).min(ahead.len())..]);
                if patient {
                    std::thread::sleep(std::time::Duration::from_millis(40));
                }
            }
            let mut out = FrameSolution::default();
            solver.step(cons, &mut out).expect("step");
            outs.push(out);
        }
        (outs, requested)
    };
    let (a, ra) = run(true);
    let (b, rb) = run(false);
    assert!(ra > 0 && ra == rb, "the same requests in both runs: {ra} / {rb}");
    assert!(a.iter().any(|o| o.displacement_surface.iter().any(|u| u.norm() > 0.0)));
    assert!(a.len() as u64 > PREFETCH_JOIN_FRAMES, "batches are joined at their join frame within the run");
    assert!(a.iter().any(|o| o.lazy_solves == 0 && o.rows > 0) && a.iter().any(|o| o.lazy_solves > 0), "some frames meet prefetched nodes, some solve on demand");
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        assert!(x == y, "frame {k} differs between a patient and an impatient run");
    }
}

/// A batch joined while the cache is nearly full takes room only from columns
/// unused since before the last frame: it never evicts the columns of a
/// contact that is still held, so those frames solve nothing themselves.
#[test]
fn a_joined_batch_never_evicts_columns_in_use() {
    use fissure::fem::constrained::LAZY_CAPACITY;
    let mesh = block(16, 8, 4);
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
    let roi: Vec<u32> = model.surface().vertices.iter().copied().filter(|&n| mesh.positions[n as usize].x <= 0.006).collect();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).expect("compliance");
    let mut solver = ConstrainedSolver::new(model, c).expect("solver");
    // Hold 120 top-face nodes outside the ROI: 120 lazy columns of LAZY_CAPACITY.
    let held: Vec<Constraint> = (0..mesh.node_count() as u32)
        .filter(|&n| {
            let p = mesh.positions[n as usize];
            (p.z - 0.03).abs() < 1e-12 && p.x > 0.006
        })
        .take(120)
        .map(|n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.001) } })
        .collect();
    assert_eq!(held.len(), 120);
    assert!(held.len() + PREFETCH_BATCH > LAZY_CAPACITY, "the joined batch must not fit without evicting");
    let mut out = FrameSolution::default();
    solver.step(&held, &mut out).expect("step");
    assert_eq!(out.lazy_solves, 120);
    // Guesses: side-face nodes outside the ROI, not held.
    let side: Vec<u32> = (0..mesh.node_count() as u32)
        .filter(|&n| {
            let p = mesh.positions[n as usize];
            p.y.abs() < 1e-12 && p.z > 1e-9 && p.z < 0.03 - 1e-9 && p.x > 0.006
        })
        .collect();
    assert_eq!(solver.prefetch(&side), PREFETCH_BATCH);
    for frame in 0..(PREFETCH_JOIN_FRAMES + 3) {
        solver.step(&held, &mut out).expect("step");
        assert_eq!(out.lazy_solves, 0, "frame {frame}: a held contact's columns were evicted by a guess");
    }
    let cached = solver.cached_lazy_nodes().count();
    assert!(cached <= LAZY_CAPACITY && cached > 120, "the batch took the free room: {cached} cached");
}
