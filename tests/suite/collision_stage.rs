//! Stage contract: bad poses and counts are typed errors (never panics) that leave
//! the state untouched; outputs are deterministic; reset_history clears flags;
//! counts agree with the pair lists; config serde names are "reference"/"bvh"/"gpu".

use fissure::collision::scenes::{icosphere, pose_from_axes};
use fissure::collision::{BackendKind, CollisionConfig, CollisionError, CollisionStage, SpatulaSpec};
use fissure::geometry::{NodeLayout, Pose, SpatulaShape};
use fissure::math::{Quat, Vec3};

const MM: f64 = 1e-3;

fn setup(backend: BackendKind) -> (CollisionStage, Vec<Vec3>, Pose) {
    let (t, p) = icosphere(Vec3::zeros(), 30.0 * MM, 3);
    let spec = SpatulaSpec { shape: SpatulaShape { length: 40.0 * MM, width: 8.0 * MM, thickness: 1.0 * MM }, layout: NodeLayout::Grid { along: 10, across: 4 } };
    let mut s = CollisionStage::new(CollisionConfig { backend, culling: true }, &t, &p, &[spec]).expect("stage");
    // These tests step the stage against a surface that no FEM moves, so tissue the blade
    // passes stays where it was; the swept-side rule (which assumes the solve pushed it
    // out of the blade's way) would cull it. Test the paper's rules alone here.
    s.set_swept_culling(false);
    // Blade enters the sphere from +x, face 0 toward +z.
    let pose = pose_from_axes(Vec3::new(45.0 * MM, 0.0, 5.0 * MM), -Vec3::x(), Vec3::z());
    (s, p, pose)
}

#[test]
fn invalid_input_is_an_error_and_changes_nothing() {
    let (mut s, p, pose) = setup(BackendKind::Bvh);
    let good = s.step(&p, &[pose]).expect("good frame").clone();
    assert!(!good.feasible_pairs.is_empty(), "the blade inside the sphere must give feasible pairs");
    let flags = s.his_flags().clone();
    let nan = Pose { position: Vec3::new(f64::NAN, 0.0, 0.0), ..pose };
    assert_eq!(s.step(&p, &[nan]).unwrap_err(), CollisionError::InvalidPose { spatula: 0 });
    let mut q = pose;
    q.rotation = Quat::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0));
    assert_eq!(s.step(&p, &[q]).unwrap_err(), CollisionError::InvalidPose { spatula: 0 }, "a non-unit quaternion is an error");
    assert!(matches!(s.step(&p, &[]), Err(CollisionError::PoseCount { expected: 1, got: 0 })));
    assert!(matches!(s.step(&p[1..], &[pose]), Err(CollisionError::VertexCount { .. })));
    let mut bad = p.clone();
    bad[7].y = f64::INFINITY;
    assert_eq!(s.step(&bad, &[pose]).unwrap_err(), CollisionError::NonFiniteVertex { vertex: 7 });
    assert_eq!(s.his_flags(), &flags, "failed frames must not touch the His-flags");
    assert_eq!(s.output(), &good, "failed frames must not touch the last output");
}

#[test]
fn construction_errors_name_the_problem() {
    let (t, p) = icosphere(Vec3::zeros(), 30.0 * MM, 1);
    let cfg = CollisionConfig { backend: BackendKind::Reference, culling: true };
    let spec = SpatulaSpec { shape: SpatulaShape { length: 0.04, width: 0.008, thickness: 0.0 }, layout: NodeLayout::Grid { along: 2, across: 2 } };
    assert!(matches!(CollisionStage::new(cfg, &t, &p, &[spec]), Err(CollisionError::Layout { spatula: 0, .. })));
    let spec = SpatulaSpec { shape: SpatulaShape { length: 0.04, width: 0.008, thickness: 0.001 }, layout: NodeLayout::Grid { along: 2, across: 2 } };
    assert!(matches!(CollisionStage::new(cfg, &[[0, 1, 999]], &p, std::slice::from_ref(&spec)), Err(CollisionError::TriangleIndex { triangle: 0, vertex: 999, .. })));
    assert!(matches!(CollisionStage::new(cfg, &[], &p, std::slice::from_ref(&spec)), Err(CollisionError::EmptySurface)));
    assert!(matches!(CollisionStage::new(cfg, &t, &p, &[]), Err(CollisionError::SpatulaCount { count: 0 })));
}

#[test]
fn output_is_deterministic_counts_agree_and_reset_clears_history() {
    for backend in [BackendKind::Reference, BackendKind::Bvh] {
        let (mut a, p, pose) = setup(backend);
        let (mut b, _, _) = setup(backend);
        for k in 0..5 {
            let mut q = pose;
            q.position.x -= k as f64 * 2.0 * MM;
            let oa = a.step(&p, &[q]).expect("a").clone();
            let ob = b.step(&p, &[q]).expect("b");
            assert_eq!(&oa, ob, "{backend:?} frame {k}: two identical stages must agree exactly");
            let c = oa.per_spatula[0];
            assert_eq!(c.candidates as usize, oa.candidate_pairs.len());
            assert_eq!(c.candidates, c.culled + c.feasible, "every candidate is culled or feasible");
            assert_eq!(c.constrained_vertices as usize, oa.targets.len());
            assert_eq!(c.flagged_nodes as usize, a.his_flags().count());
            assert!(oa.targets.windows(2).all(|w| w[0].vertex < w[1].vertex), "targets sorted by vertex, one each");
            assert_eq!(oa.source_nodes.len(), a.node_count());
        }
        assert!(a.his_flags().count() > 0, "{backend:?}: contact must raise flags");
        a.reset_history();
        assert_eq!(a.his_flags().count(), 0, "reset_history clears every flag");
        assert_eq!(a.backend(), backend);
        assert!(a.warnings().is_empty());
    }
}

#[test]
fn backend_names_in_config_files() {
    let c: CollisionConfig = ron::from_str("(backend: gpu, culling: false)").expect("ron");
    assert_eq!(c, CollisionConfig { backend: BackendKind::Gpu, culling: false });
    assert_eq!(ron::to_string(&BackendKind::Reference).expect("ron"), "reference");
    assert!(ron::from_str::<CollisionConfig>("(backend: bvh, culling: true, extra: 1)").is_err(), "unknown fields are rejected");
}
