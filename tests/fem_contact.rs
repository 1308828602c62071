//! Unilateral tool contact (`ConstraintKind::Contact`): a hold that pushes is
//! exactly the bilateral enforced displacement; a hold that would pull is
//! released (zero force, not behind its face plane) or slides on the face.

#[path = "fem_common/mod.rs"]
mod common;

use common::*;
use fissure::fem::{Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

fn solver_for(mesh: &TetMesh) -> ConstrainedSolver {
    let fixed = bottom_fixed(mesh);
    let model = FemModel::new(mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    ConstrainedSolver::new(model, c).unwrap()
}

/// Top-face nodes within `half` (m) of the top's centre (the 6 x 4 x 3 block is 60 x 40 x 30 mm).
fn top_patch(mesh: &TetMesh, half: f64) -> Vec<u32> {
    (0..mesh.node_count() as u32)
        .filter(|&n| {
            let p = mesh.positions[n as usize];
            (p.z - 0.03).abs() < 1e-12 && (p.x - 0.03).abs() <= half && (p.y - 0.02).abs() <= half
        })
        .collect()
}

/// A blade face above the top pushes down: its outward normal is -z.
const DOWN: Vec3 = Vec3::new(0.0, 0.0, -1.0);

fn contacts(nodes: &[u32], target: impl Fn(u32) -> Vec3) -> Vec<Constraint> {
    nodes.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Contact { displacement: target(n), normal: DOWN } }).collect()
}

#[test]
fn a_pushing_hold_is_the_bilateral_solution() {
    let mesh = block(6, 4, 3);
    let patch = top_patch(&mesh, 0.011);
    assert!(patch.len() >= 9, "patch of {} nodes", patch.len());
    let press = Vec3::new(0.0, 0.0, -0.002);
    let mut solver = solver_for(&mesh);
    let (mut uni, mut bi) = (FrameSolution::default(), FrameSolution::default());
    solver.step(&contacts(&patch, |_| press), &mut uni).unwrap();
    let enforced: Vec<Constraint> =
        patch.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: press } }).collect();
    solver.step(&enforced, &mut bi).unwrap();
    assert_eq!((uni.released_contacts, uni.sliding_contacts), (0, 0), "a flat press pushes at every held node");
    for (k, (a, b)) in uni.reactions.iter().zip(&bi.reactions).enumerate() {
        assert!((a - b).norm() <= 1e-12 * b.norm().max(1e-12), "reaction {k}: unilateral {a:?} vs bilateral {b:?}");
        assert!(a.dot(&DOWN) > 0.0, "node {} pushed along the face normal: {a:?}", patch[k]);
    }
    let diff = uni.displacement_surface.iter().zip(&bi.displacement_surface).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff <= 1e-15, "same surface displacement: {diff:e} m");
}

#[test]
fn a_retreating_face_releases_its_tissue() {
    let mesh = block(6, 4, 3);
    let patch = top_patch(&mesh, 0.011);
    let mut solver = solver_for(&mesh);
    let mut out = FrameSolution::default();
    // The face moved up 1 mm above the rest surface: holding the tissue there would pull it up.
    solver.step(&contacts(&patch, |_| Vec3::new(0.0, 0.0, 0.001)), &mut out).unwrap();
    assert_eq!(out.released_contacts, patch.len(), "every hold pulls: all released ({} sliding)", out.sliding_contacts);
    assert!(out.reactions.iter().all(|r| *r == Vec3::zeros()), "released nodes carry no force");
    assert!(out.max_displacement <= 1e-15, "nothing pushes: the block stays at rest ({:e} m)", out.max_displacement);
    assert_eq!(solver.released_nodes().len(), patch.len());
}

#[test]
fn a_domed_press_never_pulls_and_nothing_ends_behind_the_face() {
    // A press deepest at the centre (3 mm) and shallow at the rim (0.5 mm) with every node
    // held: the bilateral solve pulls rim nodes (the centre drags them deeper than their
    // targets); the unilateral one must not.
    let mesh = block(6, 4, 3);
    let patch = top_patch(&mesh, 0.021);
    let centre = Vec3::new(0.03, 0.02, 0.03);
    let target = |n: u32| {
        let r = (mesh.positions[n as usize] - centre).norm();
        Vec3::new(0.0, 0.0, -(0.003 - 0.0025 * (r / 0.021).min(1.0)))
    };
    let mut solver = solver_for(&mesh);
    let enforced: Vec<Constraint> =
        patch.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: target(n) } }).collect();
    let mut bi = FrameSolution::default();
    solver.step(&enforced, &mut bi).unwrap();
    let bilateral_pull = bi.reactions.iter().map(|r| -r.dot(&DOWN)).fold(0.0, f64::max);
    assert!(bilateral_pull > 0.0, "the case must make the bilateral hold pull somewhere");

    let mut out = FrameSolution::default();
    solver.step(&contacts(&patch, target), &mut out).unwrap();
    let scale = out.reactions.iter().map(|r| r.norm()).fold(0.0, f64::max);
    let surface = solver.model().surface();
    for (k, &n) in patch.iter().enumerate() {
        let r = out.reactions[k];
        assert!(r.dot(&DOWN) >= -1e-9 * scale, "node {n} pulled: {r:?}");
        let u = out.displacement_surface[surface.node_to_vertex[n as usize] as usize];
        let gap = (u - target(n)).dot(&DOWN);
        assert!(gap >= -1e-12, "node {n} ends {:e} m behind the face", -gap);
        if solver.released_nodes().binary_search(&n).is_err() && solver.sliding_nodes().binary_search(&n).is_err() {
            assert!((u - target(n)).norm() <= 1e-12, "held node {n} misses its target by {:e} m", (u - target(n)).norm());
        }
    }
    println!(
        "domed press: bilateral max pull {bilateral_pull:.3e} N; unilateral released {}, sliding {}, iterations {}",
        out.released_contacts, out.sliding_contacts, out.iterations
    );
    assert!(out.released_contacts + out.sliding_contacts > 0, "some rim holds must have let go");
}
