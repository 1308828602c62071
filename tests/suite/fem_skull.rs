//! Skull spheres (unilateral, active set) and the conflict rules of the
//! constrained solve.

use crate::fem_common as common;

use common::*;
use fissure::mesh::fixtures::sphere_shell;
use fissure::fem::{Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

fn solver_for(mesh: &TetMesh, fixed: &[bool]) -> ConstrainedSolver {
    let model = FemModel::new(mesh, &uniform(BRAIN), fixed, &FemOptions::default()).expect("model");
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    ConstrainedSolver::new(model, c).unwrap()
}

#[test]
fn brain_stays_inside_the_containing_sphere_without_pulling() {
    // A block whose top is pushed up into a sphere that clips the block's top.
    let mesh = block(6, 4, 3);
    let fixed = bottom_fixed(&mesh);
    let mut solver = solver_for(&mesh, &fixed);
    let center = Vec3::new(0.03, 0.02, -0.02);
    let radius = 0.0525; // the top corners (distance ~ 0.0574) start outside; the top centre (0.05) inside
    let surface = solver.model().surface().vertices.clone();
    let mut cons: Vec<Constraint> =
        surface.iter().map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::SphereInside { center, radius } }).collect();
    // a spatula lifts a patch of the top near x = 0.03 up by 4 mm
    for (n, p) in mesh.positions.iter().enumerate() {
        if (p.z - 0.03).abs() < 1e-12 && (p.x - 0.03).abs() < 0.006 && (p.y - 0.02).abs() < 0.006 {
            cons.push(Constraint { node: n as u32, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, 0.001) } });
        }
    }
    let mut out = FrameSolution::default();
    solver.step(&cons, &mut out).expect("active set converges");
    println!("active sphere contacts {}, iterations {}, sphere force {:?}", out.active_sphere_contacts, out.iterations, out.sphere_forces);
    assert!(out.active_sphere_contacts > 0, "the top corners start outside: contacts must be active");
    for (k, &n) in surface.iter().enumerate() {
        let x = mesh.positions[n as usize] + out.displacement_surface[k];
        let outside = (x - center).norm() - radius;
        assert!(outside <= 1e-9 * radius, "surface node {n} ends {outside:e} m outside the skull sphere");
    }
    for (c, r) in cons.iter().zip(&out.reactions) {
        if let ConstraintKind::SphereInside { center, .. } = c.kind {
            let x = mesh.positions[c.node as usize];
            // the skull only pushes inward: the force has no component away from the centre
            assert!(r.dot(&(x - center)) <= 1e-12, "sphere reaction at node {} pulls outward: {r}", c.node);
        }
    }
    // the warm-started next frame gives the same answer in fewer or equal iterations
    let first = out.clone();
    solver.step(&cons, &mut out).unwrap();
    let change = rel_error(&out.displacement_surface, &first.displacement_surface);
    assert!(change < 1e-4, "warm start moves the converged contact (the fixed point meets the radial tolerance 1e-9 R; tangential positions settle to about 1e-5): {change:e}");
    assert!(out.iterations <= first.iterations, "warm start must not need more iterations ({} > {})", out.iterations, first.iterations);
}

#[test]
fn shell_stays_outside_the_excluding_sphere() {
    // A shell pressed inward at its outer pole; its inner surface must stay outside a sphere of its inner radius.
    let mesh = sphere_shell(0.02, 0.03, 4, 2).unwrap();
    let fixed: Vec<bool> = mesh.positions.iter().map(|p| p.z < -0.025).collect();
    let mut solver = solver_for(&mesh, &fixed);
    let inner: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| (mesh.positions[n as usize].norm() - 0.02).abs() < 1e-9).collect();
    let mut cons: Vec<Constraint> = inner
        .iter()
        .map(|&n| Constraint { node: n, owner: 1, kind: ConstraintKind::SphereOutside { center: Vec3::zeros(), radius: 0.0199 } })
        .collect();
    for (n, p) in mesh.positions.iter().enumerate() {
        if p.z > 0.029 {
            cons.push(Constraint { node: n as u32, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.004) } });
        }
    }
    let mut out = FrameSolution::default();
    solver.step(&cons, &mut out).expect("converges");
    let mut all = Vec::new();
    solver.interior_displacements(&mut all).unwrap();
    println!("outside sphere: {} contacts in {} iterations", out.active_sphere_contacts, out.iterations);
    assert!(out.active_sphere_contacts > 0, "a 4 mm push through a 10 mm wall must reach the inner sphere");
    for &n in &inner {
        let r = (mesh.positions[n as usize] + all[n as usize]).norm();
        assert!(r >= 0.0199 * (1.0 - 1e-9), "inner node {n} ends inside the excluded sphere: r = {r}");
    }
    for (c, r) in cons.iter().zip(&out.reactions) {
        if let ConstraintKind::SphereOutside { .. } = c.kind {
            assert!(r.dot(&mesh.positions[c.node as usize]) >= -1e-12, "an excluding sphere only pushes outward");
        }
    }
}

#[test]
fn conflicts_keep_w_solvable() {
    let mesh = block(4, 3, 3);
    let fixed = bottom_fixed(&mesh);
    let mut solver = solver_for(&mesh, &fixed);
    let top: Vec<u32> = (0..mesh.node_count() as u32).filter(|&n| (mesh.positions[n as usize].z - 0.03).abs() < 1e-12).collect();
    let a = top[0];
    let b = top[1];
    let d1 = Vec3::new(0.0, 0.0, -0.002);
    let d2 = Vec3::new(0.0, 0.0, -0.004);
    let c = Vec3::new(0.0, 0.0, 0.1);
    let cons = vec![
        // node a claimed by both spatulas: mean target, reaction split equally
        Constraint { node: a, owner: 0, kind: ConstraintKind::Enforced { displacement: d1 } },
        Constraint { node: a, owner: 1, kind: ConstraintKind::Enforced { displacement: d2 } },
        // node a also claimed by a sphere that it violates: the enforced displacement wins
        Constraint { node: a, owner: 0, kind: ConstraintKind::SphereOutside { center: mesh.positions[a as usize], radius: 0.01 } },
        // node b claimed twice by the same violated sphere: two identical (dependent) rows
        Constraint { node: b, owner: 0, kind: ConstraintKind::SphereInside { center: c, radius: 0.05 } },
        Constraint { node: b, owner: 1, kind: ConstraintKind::SphereInside { center: c, radius: 0.05 } },
    ];
    let mut out = FrameSolution::default();
    let result = solver.step(&cons, &mut out);
    assert!(result.is_ok(), "conflicting claims must still solve: {result:?}");
    let ka = solver.model().surface().node_to_vertex[a as usize] as usize;
    assert!((out.displacement_surface[ka] - (d1 + d2) / 2.0).norm() < 1e-12, "doubly claimed node gets the mean target");
    assert_eq!(out.reactions[0], out.reactions[1], "the doubly claimed node's reaction is split equally");
    assert_eq!(out.reactions[2], Vec3::zeros(), "the sphere row on an enforced node is not used");
    assert!(out.displacement_surface.iter().chain(&out.reactions).all(|v| v.iter().all(|x| x.is_finite())), "never NaN");
    assert_eq!(out.dropped_rows, 1, "one of the two identical sphere rows is dropped");
    assert!(out.reactions[3].norm() > 0.0 && out.reactions[4] == Vec3::zeros(), "the earlier row keeps the force: {:?}", &out.reactions[3..]);
    let kb = solver.model().surface().node_to_vertex[b as usize] as usize;
    let r = (mesh.positions[b as usize] + out.displacement_surface[kb] - c).norm();
    assert!(r <= 0.05 * (1.0 + 1e-9), "node b must end inside the sphere, r = {r}");
}
