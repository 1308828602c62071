//! Unilateral tool contact (`ConstraintKind::Contact`): a hold that pushes is
//! exactly the bilateral enforced displacement; a hold that would pull is
//! released (zero force, not behind its face plane) or slides on the face.

use crate::fem_common as common;

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

/// Blade barrier rows (`ConstraintKind::Barrier`): a row the solution does not
/// violate carries no force and changes nothing; a press that drags a free
/// neighbour below a barrier plane activates it: the neighbour ends on the plane,
/// pushed along the normal only.
#[test]
fn barrier_rows_act_only_where_the_tissue_would_pass_the_face() {
    let mesh = block(6, 4, 3);
    let patch = top_patch(&mesh, 0.011);
    let ring: Vec<u32> = top_patch(&mesh, 0.021).into_iter().filter(|n| !patch.contains(n)).collect();
    assert!(ring.len() >= 8, "ring of {} nodes around the patch", ring.len());
    let press = Vec3::new(0.0, 0.0, -0.003);
    let mut solver = solver_for(&mesh);
    let mut plain = FrameSolution::default();
    let held = contacts(&patch, |_| press);
    solver.step(&held, &mut plain).unwrap();
    let node_to_vertex = solver.model().surface().node_to_vertex.clone();
    let vertex = |n: u32| node_to_vertex[n as usize] as usize;
    // The press drags the ring down by some amount below 3 mm.
    let sag: Vec<f64> = ring.iter().map(|&n| -plain.displacement_surface[vertex(n)].z).collect();
    let (min_sag, max_sag) = sag.iter().fold((f64::INFINITY, 0.0_f64), |(a, b), &s| (a.min(s), b.max(s)));
    assert!(min_sag > 0.0 && max_sag < 0.003, "the ring sags 0..3 mm: {min_sag:e}..{max_sag:e} m");

    // Barriers 5 mm down: never reached, no force, the solution is unchanged.
    let with_far: Vec<Constraint> = held
        .iter()
        .copied()
        .chain(ring.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Barrier { displacement: Vec3::new(0.0, 0.0, -0.005), normal: -DOWN } }))
        .collect();
    let mut far = FrameSolution::default();
    solver.step(&with_far, &mut far).unwrap();
    assert_eq!(far.barrier_contacts, 0, "a barrier below the sag stays inactive");
    assert!(far.reactions[held.len()..].iter().all(|r| *r == Vec3::zeros()), "inactive barriers carry no force");
    let diff = far.displacement_surface.iter().zip(&plain.displacement_surface).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff <= 1e-15, "inactive barriers change nothing: {diff:e} m");

    // Barriers (a blade face below the ring, normal +z) at half the smallest sag: every ring node would pass.
    let level = 0.5 * min_sag;
    let with_near: Vec<Constraint> = held
        .iter()
        .copied()
        .chain(ring.iter().map(|&n| Constraint { node: n, owner: 1, kind: ConstraintKind::Barrier { displacement: Vec3::new(0.0, 0.0, -level), normal: -DOWN } }))
        .collect();
    let mut near = FrameSolution::default();
    solver.step(&with_near, &mut near).unwrap();
    assert!(near.barrier_contacts > 0, "the sag passes the barrier plane: some rows must be active");
    for (k, &n) in ring.iter().enumerate() {
        let u = near.displacement_surface[vertex(n)];
        let r = near.reactions[held.len() + k];
        assert!(u.z >= -level - 1e-12, "ring node {n} ends {:e} m behind its barrier", -level - u.z);
        assert!(r.x.abs() + r.y.abs() <= 1e-12 * r.norm().max(1e-300) && r.z >= 0.0, "barrier on {n} pushes along +z only: {r:?}");
        if r.z > 0.0 {
            assert!((u.z + level).abs() <= 1e-12, "an active barrier holds node {n} on its plane: {:e} m off", u.z + level);
        }
    }
    let up: f64 = near.reactions[held.len()..].iter().map(|r| r.z).sum();
    assert!(up > 0.0, "the barriers hold the ring up");
    assert_eq!(near.owner_forces.len(), 2, "the barriers' owner (spatula 1) gets its own force sum");
}

#[test]
fn a_frame_that_meets_new_tissue_and_leaves_the_old_does_both_in_one_iteration() {
    use fissure::fem::tuning::{Optimisation, Tuning};
    let mesh = block(6, 4, 3);
    let top: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| (mesh.positions[n as usize].z - 0.03).abs() < 1e-12).collect();
    let side = |n: u32| mesh.positions[n as usize].x;
    let (a, b): (Vec<u32>, Vec<u32>) = top.iter().copied().filter(|&n| side(n) <= 0.02 + 1e-12 || side(n) >= 0.04 - 1e-12).partition(|&n| side(n) < 0.03);
    assert!(a.len() >= 10 && b.len() >= 10, "two groups of top nodes: {} and {}", a.len(), b.len());
    // A face under each node (normal +z): 1 mm up pushes the node, 1 mm down lets it be.
    let floors = |up: &[u32], down: &[u32]| -> Vec<Constraint> {
        let floor = |n: u32, z: f64| Constraint { node: n, owner: 0, kind: ConstraintKind::Barrier { displacement: Vec3::new(0.0, 0.0, z), normal: -DOWN } };
        up.iter().map(|&n| floor(n, 0.001)).chain(down.iter().map(|&n| floor(n, -0.001))).collect()
    };
    // Frame 1 lifts A; frame 2 drops A's faces and lifts B's: A's carried rows now pull, B's nodes are violated.
    let frames = [floors(&a, &b), floors(&b, &a)];
    let run = |primal_dual: bool| {
        let mut solver = solver_for(&mesh);
        solver.set_tuning(Tuning::ALL_ON.with(Optimisation::PrimalDualSteps, primal_dual));
        let mut out = FrameSolution::default();
        let mut iterations = Vec::new();
        for cons in &frames {
            solver.step(cons, &mut out).unwrap();
            iterations.push(out.iterations);
        }
        (iterations, out)
    };
    let (steps, both) = run(true);
    let (plain_steps, plain) = run(false);
    assert_eq!(steps[0], plain_steps[0], "the first frame only adds rows");
    assert!(steps[1] < plain_steps[1], "releasing A's rows as B's come saves an iteration: {steps:?} against {plain_steps:?}");
    // The same contact: B held on its faces, A free; the answers agree but for the factor's path.
    let count = b.len();
    assert_eq!(both.barrier_contacts, count, "B's rows, and only B's, are active");
    assert_eq!(plain.barrier_contacts, count, "B's rows, and only B's, are active");
    let scale = max_norm(&plain.displacement_surface);
    let diff = both.displacement_surface.iter().zip(&plain.displacement_surface).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max);
    assert!(diff <= 1e-12 * scale, "the same surface: {diff:e} m of {scale:e} m");
    for (k, (x, y)) in both.reactions.iter().zip(&plain.reactions).enumerate() {
        assert!((x - y).norm() <= 1e-12 * y.norm().max(1e-9), "reaction {k}: {x:?} against {y:?}");
    }
}
