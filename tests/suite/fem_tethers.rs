//! Tethers in the exact solve, against closed forms: a tension-only link between two elastic blocks pulls with
//! the force of a spring in series with the blocks' compliance at its ends (each from a direct solve of the
//! whole mesh); a slack link pulls nothing; a link never pushes; a taken-out link leaves the solve.

use crate::fem_common as common;

use common::*;
use fissure::fem::reference::solve_direct;
use fissure::fem::{Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution, Tether, TetherEnd};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::mesh::fixtures::{box_mesh, linspace};

/// Two 30 x 20 x 20 mm blocks side by side along x, 10 mm apart (block A at x in [0, 30] mm, B at [40, 70] mm),
/// each held at its bottom face.
fn two_blocks() -> TetMesh {
    let a = box_mesh(&linspace(0.0, 0.03, 6), &linspace(0.0, 0.02, 4), &linspace(0.0, 0.02, 4)).unwrap();
    let b = box_mesh(&linspace(0.04, 0.07, 6), &linspace(0.0, 0.02, 4), &linspace(0.0, 0.02, 4)).unwrap();
    let offset = a.node_count() as u32;
    let mut positions = a.positions.clone();
    positions.extend_from_slice(&b.positions);
    let mut tets = a.tets.clone();
    tets.extend(b.tets.iter().map(|t| t.map(|n| n + offset)));
    TetMesh::new(positions, tets, vec![]).unwrap()
}

fn solver(mesh: &TetMesh) -> ConstrainedSolver {
    let fixed = bottom_fixed(mesh);
    let model = FemModel::new(mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).unwrap();
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    ConstrainedSolver::new(model, c).unwrap()
}

/// The point `p` of the surface as a tether end: its boundary triangle's nodes and barycentric weights.
fn tissue_end(mesh: &TetMesh, p: Vec3) -> TetherEnd {
    let surface = mesh.boundary();
    let rest: Vec<Vec3> = surface.vertices.iter().map(|&n| mesh.positions[n as usize]).collect();
    let s = fissure::sim::tethers::snap(&surface.triangles, &rest, &p).unwrap();
    assert!(s.distance < 1e-12, "the point lies on the surface");
    TetherEnd::Tissue { nodes: s.vertices.map(|v| surface.vertices[v as usize]), weights: s.weights }
}

/// Compliance of a tether end along `n`: the displacement of the point along `n` under a unit force along `n`
/// spread by its weights (a direct solve of the whole mesh, fixed nodes prescribed).
fn point_compliance(mesh: &TetMesh, end: &TetherEnd, n: Vec3) -> f64 {
    let TetherEnd::Tissue { nodes, weights } = *end else { return 0.0 };
    let fixed = bottom_fixed(mesh);
    let prescribed: Vec<(usize, f64)> = (0..mesh.node_count()).filter(|&k| fixed[k]).flat_map(|k| (0..3).map(move |c| (3 * k + c, 0.0))).collect();
    let mut forces = vec![Vec3::zeros(); mesh.node_count()];
    for (&node, &w) in nodes.iter().zip(&weights) {
        forces[node as usize] += n * w;
    }
    let lame = vec![BRAIN.lame(); mesh.tets.len()];
    let sol = solve_direct(mesh, &lame, &prescribed, &forces).unwrap();
    nodes.iter().zip(&weights).map(|(&node, &w)| w * sol.displacement[node as usize].dot(&n)).sum()
}

#[test]
fn a_taut_tether_between_two_blocks_is_a_spring_in_series_with_their_compliance() {
    let mesh = two_blocks();
    // Ends inside a triangle of each facing side (not at a node), at the same height and depth.
    let a = tissue_end(&mesh, Vec3::new(0.03, 0.0093, 0.0117));
    let b = tissue_end(&mesh, Vec3::new(0.04, 0.0093, 0.0117));
    let (gap, rest_length, k) = (0.010, 0.006, 40.0);
    let mut s = solver(&mesh);
    s.set_tethers(&[Tether { ends: [a, b], rest_length, stiffness: k }]).unwrap();
    let mut out = FrameSolution::default();
    s.step(&[], &mut out).unwrap();
    let c_a = point_compliance(&mesh, &a, Vec3::x());
    let c_b = point_compliance(&mesh, &b, -Vec3::x());
    let expected = (gap - rest_length) / (1.0 / k + c_a + c_b);
    let t = out.tether_tension[0];
    assert!((t - expected).abs() <= 1e-9 * expected, "tension {t} N, spring in series {expected} N (c_a {c_a:e}, c_b {c_b:e} m/N)");
    // The ends move toward each other by the stretch the tissue takes; the link's own stretch is T / k.
    let surface = mesh.boundary();
    let moved = |end: &TetherEnd| match *end {
        TetherEnd::Tissue { nodes, weights } => {
            nodes.iter().zip(&weights).map(|(&n, &w)| out.displacement_surface[surface.node_to_vertex[n as usize] as usize] * w).sum::<Vec3>()
        }
        TetherEnd::Anchor { .. } => Vec3::zeros(),
    };
    let closing = moved(&a).x - moved(&b).x;
    assert!((closing - t * (c_a + c_b)).abs() <= 1e-9 * closing, "the ends close by T (c_a + c_b): {closing:e} m");
    // Newton's third law: the two blocks' reactions are opposite (the tether pulls them together).
    assert!(out.owner_forces.is_empty() && out.rows == 1, "one row, no tool: {} rows", out.rows);
}

#[test]
fn a_tether_to_an_anchor_pulls_with_the_series_force_and_a_slack_one_with_none() {
    let mesh = two_blocks();
    let a = tissue_end(&mesh, Vec3::new(0.0142, 0.0077, 0.02));
    let anchor = Vec3::new(0.0142, 0.0077, 0.035);
    let k = 15.0;
    for (rest_length, taut) in [(0.010, true), (0.016, false)] {
        let mut s = solver(&mesh);
        s.set_tethers(&[Tether { ends: [a, TetherEnd::Anchor { point: anchor }], rest_length, stiffness: k }]).unwrap();
        let mut out = FrameSolution::default();
        s.step(&[], &mut out).unwrap();
        let t = out.tether_tension[0];
        if taut {
            let c = point_compliance(&mesh, &a, Vec3::z());
            let expected = (0.015 - rest_length) / (1.0 / k + c);
            assert!((t - expected).abs() <= 1e-9 * expected, "tension {t} N against {expected} N");
        } else {
            assert_eq!(t, 0.0, "a slack tether pulls nothing");
            assert_eq!(out.rows, 0);
            assert!(out.max_displacement == 0.0, "nothing moves");
        }
    }
}

#[test]
fn a_tether_never_pushes_and_a_cut_one_leaves_the_solve() {
    // A press on block A's top pushes its side toward B; a slack tether across the gap stays slack; then a pull
    // the other way stretches it, and once taken out it pulls nothing.
    let mesh = two_blocks();
    let a = tissue_end(&mesh, Vec3::new(0.03, 0.0093, 0.0117));
    let b = tissue_end(&mesh, Vec3::new(0.04, 0.0093, 0.0117));
    let mut s = solver(&mesh);
    s.set_tethers(&[Tether { ends: [a, b], rest_length: 0.0099, stiffness: 40.0 }]).unwrap();
    let top_a: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| (mesh.positions[n as usize].z - 0.02).abs() < 1e-12 && mesh.positions[n as usize].x < 0.031).collect();
    let push = |dx: f64| -> Vec<Constraint> { top_a.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(dx, 0.0, 0.0) } }).collect() };
    let mut out = FrameSolution::default();
    // A moves toward B by 2 mm at the top: the gap closes, the link would push: it stays slack.
    s.step(&push(0.002), &mut out).unwrap();
    assert_eq!(out.tether_tension[0], 0.0, "a tether never pushes");
    // A moves away from B: the 0.1 mm of slack is taken up and the link pulls.
    s.step(&push(-0.002), &mut out).unwrap();
    let pulled = out.tether_tension[0];
    assert!(pulled > 0.0, "stretched: {pulled} N");
    let with = out.owner_forces[0].1;
    s.set_tether_enabled(0, false);
    s.step(&push(-0.002), &mut out).unwrap();
    assert_eq!(out.tether_tension[0], 0.0, "a cut tether pulls nothing");
    let without = out.owner_forces[0].1;
    assert!(with.x < without.x, "the blade holding A back pushes harder against the tether: {with:?} vs {without:?}");
}

#[test]
fn tethers_read_through_their_own_columns_give_the_node_by_node_answers() {
    // Five links across the gap, some slack, some taut, pulled apart and pushed together over several frames
    // (links become taut and slack again): the tensions and the surface agree with the node-by-node reading to
    // rounding, frame by frame; the first frames read links whose columns are not made yet.
    use fissure::fem::tuning::{Optimisation, Tuning};
    let mesh = two_blocks();
    let links: Vec<Tether> = [(0.0041, 0.0117, 0.0095), (0.0093, 0.0117, 0.0099), (0.0152, 0.0061, 0.0102), (0.0093, 0.0052, 0.0088), (0.0148, 0.0149, 0.0097)]
        .iter()
        .map(|&(y, z, rest_length)| Tether { ends: [tissue_end(&mesh, Vec3::new(0.03, y, z)), tissue_end(&mesh, Vec3::new(0.04, y, z))], rest_length, stiffness: 25.0 })
        .collect();
    let top_a: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| (mesh.positions[n as usize].z - 0.02).abs() < 1e-12 && mesh.positions[n as usize].x < 0.031).collect();
    let push = |dx: f64| -> Vec<Constraint> { top_a.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(dx, 0.0, 0.0) } }).collect() };
    let run = |columns: bool| {
        let mut s = solver(&mesh);
        s.set_tuning(Tuning::ALL_ON.with(Optimisation::TetherColumns, columns));
        s.set_tethers(&links).unwrap();
        let mut out = FrameSolution::default();
        let mut frames = Vec::new();
        for dx in [0.0, -0.001, -0.002, -0.003, 0.001, -0.0025, -0.004] {
            s.step(&push(dx), &mut out).unwrap();
            frames.push((out.tether_tension.clone(), out.displacement_surface.clone(), out.owner_forces[0].1));
        }
        frames
    };
    let (by_columns, by_nodes) = (run(true), run(false));
    let mut taut = 0;
    for ((t1, u1, f1), (t2, u2, f2)) in by_columns.iter().zip(&by_nodes) {
        let scale = t2.iter().fold(1e-6_f64, |m, t| m.max(t.abs()));
        for (a, b) in t1.iter().zip(t2) {
            assert!((a - b).abs() <= 1e-12 * scale, "tension {a} against {b} N");
            taut += usize::from(*b > 0.0);
        }
        let umax = u2.iter().fold(1e-9_f64, |m, u| m.max(u.norm()));
        assert!(u1.iter().zip(u2).all(|(a, b)| (a - b).norm() <= 1e-12 * umax), "the surface agrees");
        assert!((f1 - f2).norm() <= 1e-12 * f2.norm().max(1e-9), "the blade's force agrees: {f1:?} against {f2:?}");
    }
    assert!(taut >= 8, "links were taut in several frames: {taut}");
}
