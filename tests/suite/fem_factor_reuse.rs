//! The persistent factor of W (`linalg::kept_factor`): a frame history that grows,
//! repeats, drops nodes at the front and in the middle, and adds sphere rows,
//! must give what a fresh solver (full factorization) gives, to round-off, and
//! match the direct re-factorization to 1e-8; replays are bitwise deterministic.

use crate::fem_common as common;

use common::*;
use fissure::fem::reference::solve_direct;
use fissure::linalg::kept_factor::FactorUpdate;
use fissure::fem::{Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

fn solver(mesh: &TetMesh, fixed: &[bool]) -> ConstrainedSolver {
    let model = FemModel::new(mesh, &uniform(BRAIN), fixed, &FemOptions::default()).expect("model");
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).expect("compliance");
    ConstrainedSolver::new(model, c).expect("solver")
}

/// Frame k: enforced top nodes with indices in `set` (into the top-node list).
fn frame(mesh: &TetMesh, top: &[u32], set: &[usize], k: usize) -> Vec<Constraint> {
    set.iter()
        .map(|&i| {
            let n = top[i];
            let p = mesh.positions[n as usize];
            Constraint {
                node: n,
                owner: (i % 2) as u16,
                kind: ConstraintKind::Enforced { displacement: Vec3::new(1e-4 * k as f64, -2e-4, -0.001 - 0.01 * p.x * (1 + k) as f64) },
            }
        })
        .collect()
}

fn direct(mesh: &TetMesh, solver: &ConstrainedSolver, fixed: &[bool], cons: &[Constraint]) -> Vec<Vec3> {
    let mut prescribed = Vec::new();
    for (n, &f) in fixed.iter().enumerate() {
        if f {
            for c in 0..3 {
                prescribed.push((3 * n + c, 0.0));
            }
        }
    }
    for c in cons {
        if let ConstraintKind::Enforced { displacement } = c.kind {
            for k in 0..3 {
                prescribed.push((3 * c.node as usize + k, displacement[k]));
            }
        }
    }
    let forces = vec![Vec3::zeros(); mesh.node_count()];
    let sol = solve_direct(mesh, solver.model().lame(), &prescribed, &forces).expect("direct");
    solver.model().surface().vertices.iter().map(|&n| sol.displacement[n as usize]).collect()
}

#[test]
fn incremental_factor_matches_full_and_direct_over_a_changing_history() {
    let mesh = block(6, 4, 4);
    let fixed = bottom_fixed(&mesh);
    let top: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| (mesh.positions[n as usize].z - 0.03).abs() < 1e-12).collect();
    assert!(top.len() >= 30, "the block needs enough top nodes");
    // grow, same set, grow, drop the front, drop the middle and add, drop everything but a few
    let history: Vec<(Vec<usize>, FactorUpdate)> = vec![
        ((0..8).collect(), FactorUpdate::Full),
        ((0..8).collect(), FactorUpdate::Reused),
        ((0..14).collect(), FactorUpdate::Extended),
        ((3..14).collect(), FactorUpdate::Full),
        ((3..8).chain(10..20).collect(), FactorUpdate::Trailing),
        // the kept nodes are the leading ones: the tail is cut, new rows appended
        (vec![3, 4, 25, 26], FactorUpdate::Extended),
    ];
    let mut incremental = solver(&mesh, &fixed);
    let mut replay = solver(&mesh, &fixed);
    let mut out = FrameSolution::default();
    let mut out_replay = FrameSolution::default();
    let mut out_fresh = FrameSolution::default();
    for (k, (set, expected)) in history.iter().enumerate() {
        let cons = frame(&mesh, &top, set, k);
        incremental.step(&cons, &mut out).expect("incremental step");
        assert_eq!(incremental.factor_update(), *expected, "frame {k}: which update the order rule implies");
        replay.step(&cons, &mut out_replay).expect("replay step");
        assert_eq!(out, out_replay, "frame {k}: the same history must give the same bits");
        let mut fresh = solver(&mesh, &fixed);
        fresh.step(&cons, &mut out_fresh).expect("fresh step");
        let e = rel_error(&out.displacement_surface, &out_fresh.displacement_surface);
        assert!(e < 1e-10, "frame {k}: incremental vs full factorization differ by {e:e}");
        let rf: Vec<Vec3> = out.reactions.clone();
        let ef = rel_error(&rf, &out_fresh.reactions);
        assert!(ef < 1e-9, "frame {k}: reactions incremental vs full differ by {ef:e}");
        let reference = direct(&mesh, &incremental, &fixed, &cons);
        let ed = rel_error(&out.displacement_surface, &reference);
        assert!(ed < 1e-8, "frame {k}: fast path vs direct refactorization {ed:e}");
    }
}

#[test]
fn sphere_rows_extend_a_reused_enforced_factor() {
    // The same enforced set twice, with a sphere that clips the block top: the
    // second frame reuses the enforced factor and must equal a fresh solve.
    let mesh = block(6, 4, 3);
    let fixed = bottom_fixed(&mesh);
    let center = Vec3::new(0.03, 0.02, -0.02);
    let radius = 0.0525;
    let mut solver_a = solver(&mesh, &fixed);
    let surface = solver_a.model().surface().vertices.clone();
    let mut cons: Vec<Constraint> =
        surface.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::SphereInside { center, radius } }).collect();
    for (n, p) in mesh.positions.iter().enumerate() {
        if (p.z - 0.03).abs() < 1e-12 && (p.x - 0.03).abs() < 0.006 && (p.y - 0.02).abs() < 0.006 {
            cons.push(Constraint { node: n as u32, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, 0.001) } });
        }
    }
    let mut out = FrameSolution::default();
    solver_a.step(&cons, &mut out).expect("first");
    solver_a.step(&cons, &mut out).expect("second");
    assert_eq!(solver_a.factor_update(), FactorUpdate::Reused, "same enforced set: factor reused");
    assert!(out.active_sphere_contacts > 0, "the sphere must be in contact");
    let mut w = Vec::new();
    solver_a.contact_compliance(&mut w);
    let n = out.rows;
    assert_eq!(w.len(), n * n);
    for i in 0..n {
        assert!(w[i * n + i] > 0.0, "W diagonal {i} must be positive");
        for j in 0..n {
            assert_eq!(w[j * n + i], w[i * n + j], "W must be symmetric at ({i}, {j})");
        }
    }
    for (k, &node) in surface.iter().enumerate() {
        let x = mesh.positions[node as usize] + out.displacement_surface[k];
        assert!((x - center).norm() - radius <= 1e-9 * radius, "surface node {node} ends outside the sphere");
    }
}
