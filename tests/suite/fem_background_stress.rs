//! The background stress worker gives, for a frame's forces, exactly the
//! stress the synchronous path gives (same solve, same arithmetic), never makes
//! the caller wait, and a newer request replaces one not yet started.

use crate::fem_common as common;

use common::*;
use fissure::fem::{
    Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution, element_stress,
};
use fissure::app::stress_worker::StressWorker;
use fissure::math::Vec3;

#[test]
fn background_stress_equals_the_synchronous_stress_of_the_same_frame() {
    let mesh = block(4, 3, 3);
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).unwrap();
    let roi = model.surface().vertices.clone();
    let top: Vec<u32> = roi.iter().copied().filter(|&n| mesh.positions[n as usize].z > 0.99 * mesh.bounding_box().1.z).collect();
    assert!(!top.is_empty());
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    let mut solver = ConstrainedSolver::new(model, c).unwrap();
    let worker = StressWorker::start(solver.model()).unwrap();
    let mut out = FrameSolution::default();
    let (mut nodes, mut expected, mut got, mut got_nodes) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for frame in 1..=3u64 {
        let press = -0.001 * frame as f64;
        let cons: Vec<Constraint> = top
            .iter()
            .map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, press) } })
            .collect();
        solver.step(&cons, &mut out).unwrap();
        worker.post(frame, solver.last_forces(), true);
        solver.interior_displacements(&mut nodes).unwrap();
        element_stress(solver.model(), &nodes, &mut expected).unwrap();
        assert!(expected.iter().any(|s| s.von_mises > 0.0), "the press strains the block");
        let done = worker.wait_for(frame, &mut got, &mut got_nodes).expect("the worker finishes");
        assert_eq!(done, frame, "nothing newer was asked for");
        assert_eq!(got, expected, "frame {frame}: the same stress, bit for bit");
        assert_eq!(got_nodes, nodes, "frame {frame}: the same displacements, bit for bit");
    }
    // Requests posted faster than the worker finishes: the newest wins and
    // nothing older arrives after it.
    let forces = solver.last_forces().to_vec();
    for frame in 10..20u64 {
        worker.post(frame, &forces, true);
    }
    assert_eq!(worker.wait_for(19, &mut got, &mut got_nodes), Some(19));
    assert_eq!(got, expected, "the same forces give the same stress");
    assert!(worker.take(&mut got, &mut got_nodes).is_none_or(|f| f >= 19), "no older result after the newest");
    // Displacements only: no stress pass.
    worker.post(20, &forces, false);
    assert_eq!(worker.wait_for(20, &mut got, &mut got_nodes), Some(20));
    assert!(got.is_empty(), "no stress was asked for");
    assert_eq!(got_nodes, nodes, "the same forces give the same displacements");
}
