//! The pipeline end to end on a small block: a spatula presses the top face,
//! the brain-like block deforms exactly to the blade, the force pushes into the
//! tissue, and when the blade withdraws the block returns to rest.

use crate::common;

use fissure::geometry::Pose;
use fissure::math::{Quat, Vec3};
use fissure::scenario::Scenario;
use fissure::sim::{BuildOptions, FrameInput, Pipeline, StageId};

const BLOCK_MM: (f64, f64, f64) = (40.0, 40.0, 20.0);

fn scenario(dir: &std::path::Path, effects: &str, culling_backend: &str) -> Scenario {
    let mesh = common::block(10, 10, 5, Vec3::new(0.04, 0.04, 0.02) * 1e3, Vec3::new(-20.0, -20.0, 0.0));
    let path = common::write_mesh(dir, "block.msh", &mesh);
    let text = format!(
        r#"(
    name: "block press",
    mesh: File(path: "{}", units: Millimetres),
    material: (young_modulus_pa: 3000.0, poisson_ratio: 0.45),
    fixed: [LowestPerComponent(height_mm: 1.0)],
    spatulas: [(
        name: "blade",
        shape: (length_mm: 20.0, width_mm: 10.0, thickness_mm: 1.0),
        layout: Grid(along: 12, across: 6),
        pose: (position_mm: (-10.0, 0.0, 25.0), rotation: Quaternion(1.0, 0.0, 0.0, 0.0)),
        input: Keyboard,
    )],
    effects: [{effects}],
    collision: (backend: {culling_backend}),
    solver: (compliance_storage: F64, region_of_interest: All, cache_dir: None),
    time_step_s: 0.01,
    duration_s: 0.1,
)"#,
        path.display()
    );
    Scenario::from_str(&text, &dir.join("block.ron"), &[]).expect("test scenario is valid")
}

fn pose_at_height_mm(z_mm: f64) -> Pose {
    Pose { position: Vec3::new(-0.010, 0.0, z_mm * 1e-3), rotation: Quat::identity() }
}

#[test]
fn pressing_deforms_to_the_blade_and_withdrawing_returns_to_rest() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "Collision, Culling, ForceOutput, ContactPressure", "Bvh");
    let (mut pipeline, mut state) = Pipeline::build(&s, BuildOptions::default()).expect("build");
    let top = BLOCK_MM.2;
    let press_mm = 2.0;
    // Lower the blade in steps of 0.4 mm until its lower face is `press_mm` below the top.
    let mut input = FrameInput { poses: vec![None] };
    let mut last_force_z = 0.0;
    let steps = 20;
    for k in 1..=steps {
        let face_z = top + 0.5 - (press_mm + 0.5) * k as f64 / steps as f64;
        input.poses[0] = Some(pose_at_height_mm(face_z + 0.5));
        let r = pipeline.step(&mut state, &input).expect("step");
        last_force_z = r.spatulas[0].force.z;
        assert!(r.max_displacement_m.is_finite());
    }
    let r = pipeline.step(&mut state, &input).expect("step").clone();
    assert!(r.constrained_vertices > 0, "the blade must constrain the top face");
    assert!(last_force_z < 0.0, "the blade pushes the tissue down: force z {last_force_z}");
    // The blade pushes the top down by the press; the tissue slides along the
    // frictionless face as it bulges, so a vertex also moves sideways.
    let max_down = state.surface_displacement.iter().map(|u| -u.z).fold(0.0, f64::max);
    assert!((max_down - press_mm * 1e-3).abs() < 1e-6, "vertices follow the blade down: {max_down} m");
    assert!(r.max_displacement_m >= max_down && r.max_displacement_m < 1.1 * press_mm * 1e-3, "max displacement {} m", r.max_displacement_m);
    // Every constrained vertex sits on the blade's lower face plane (z = top - press).
    let face_z = (top - press_mm) * 1e-3;
    let mut on_face = 0;
    for p in &state.surface_positions {
        if p.x > -0.0099 && p.x < 0.0099 && p.y.abs() < 0.0049 && p.z > 0.01 {
            assert!(p.z <= face_z + 1e-9, "no top vertex under the blade stays above its face: z {}", p.z);
            on_face += 1;
        }
    }
    assert!(on_face > 0);
    assert_eq!(r.penetrating_vertices, 0, "no vertex inside the blade");
    assert!(r.spatulas[0].mean_pressure_pa > 0.0 && r.spatulas[0].contact_area_m2 > 0.0);

    // Withdraw: the block returns to rest.
    input.poses[0] = Some(pose_at_height_mm(top + 10.0));
    let r = pipeline.step(&mut state, &input).expect("step");
    assert_eq!(r.constrained_vertices, 0);
    let max_u = state.surface_displacement.iter().map(|u| u.norm()).fold(0.0, f64::max);
    assert!(max_u < 1e-9, "after withdrawal the block is at rest, max |u| = {max_u}");
}

#[test]
fn a_stage_the_scene_does_not_ask_for_is_not_built_and_reports_no_time() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "Collision", "Reference");
    let (mut pipeline, mut state) = Pipeline::build(&s, BuildOptions::default()).expect("build");
    assert_eq!(pipeline.built_stages(), vec![StageId::Collision, StageId::Solve, StageId::Monitor]);
    assert!(pipeline.skull().is_none());
    let r = pipeline.step(&mut state, &FrameInput { poses: vec![Some(pose_at_height_mm(20.0))] }).unwrap();
    assert!(r.times.get(StageId::Collision).is_some());
    for absent in [StageId::Skull, StageId::Forces, StageId::Stress] {
        assert_eq!(r.times.get(absent), None, "{absent:?} was not asked for and must report no time");
    }
    // No collision at all: only the solve remains.
    let s = scenario(dir.path(), "", "Bvh");
    let (pipeline, _) = Pipeline::build(&s, BuildOptions::default()).expect("build");
    assert!(pipeline.collision().is_none());
    assert_eq!(pipeline.built_stages(), vec![StageId::Solve]);
}

#[test]
fn a_nan_pose_is_rejected_and_the_last_good_pose_holds() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "Collision, Culling", "Bvh");
    let (mut pipeline, mut state) = Pipeline::build(&s, BuildOptions::default()).expect("build");
    let good = pose_at_height_mm(20.0);
    pipeline.step(&mut state, &FrameInput { poses: vec![Some(good)] }).unwrap();
    let mut bad = good;
    bad.position.x = f64::NAN;
    let r = pipeline.step(&mut state, &FrameInput { poses: vec![Some(bad)] }).unwrap();
    assert_eq!(r.rejected_poses, 1);
    assert_eq!(state.poses[0], good);
    assert!(state.surface_positions.iter().all(|p| p.iter().all(|c| c.is_finite())));
}
