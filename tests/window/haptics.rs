//! The 1 kHz force output against the simulation: with the pose unchanged
//! since the last frame, `ForceOutput::latest` equals minus the frame's force
//! on the tissue (the reaction on the tool) for both spatulas, while in
//! contact; the loop keeps ticking between frames; a pose moved by the probe
//! changes the force by the contact stiffness.

use fissure::app::haptics::{ForceOutput, HAPTIC_RATE_HZ, HapticModel};
use fissure::math::Vec3;
use fissure::scenario::Scenario;
use fissure::sim::poses::TrajectoryPoses;
use fissure::sim::{BuildOptions, FrameInput, Pipeline};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn force_output_matches_the_simulation_when_the_pose_holds() {
    let _one = crate::one_at_a_time();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sylvian.ron");
    let scenario = Scenario::load(&path, &[]).expect("default scenario");
    let source = TrajectoryPoses::for_scenario(&scenario, None).expect("trajectory");
    let (mut pipeline, mut state) = Pipeline::build(
        &scenario,
        BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: None, ..BuildOptions::default() },
    )
    .expect("build");
    let mut input = FrameInput::default();
    let mut report = None;
    for k in 0..350u64 {
        source.poses_at((k + 1) as f64 * scenario.time_step, &mut input);
        report = Some(pipeline.step(&mut state, &input).expect("step").clone());
    }
    let report = report.expect("frames ran");
    assert!(report.spatulas.iter().all(|s| s.force.norm() > 1e-3), "both blades must be in contact at 3.5 s: {:?}", report.spatulas);
    let mut scratch = Vec::new();
    let model = HapticModel::of_frame(&pipeline, &state.poses, &report, &mut scratch);
    for (k, m) in model.stiffness_n_per_m.iter().enumerate() {
        assert!(m.iter().all(|v| v.is_finite()) && m.norm() > 0.0, "spatula {k}: contact stiffness must be finite and non-zero: {m}");
    }

    let out = ForceOutput::start(2, HAPTIC_RATE_HZ, Box::new(|_, _| None), None);
    out.publish(Arc::new(model.clone()));
    let t0 = Instant::now();
    let ticks0 = out.ticks();
    while out.ticks() < ticks0 + 100 && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(out.ticks() >= ticks0 + 100, "the force loop must keep ticking between frames (got {} ticks)", out.ticks() - ticks0);
    for (k, s) in report.spatulas.iter().enumerate() {
        let (f, t) = out.latest(k).expect("spatula exists");
        assert!(t > 0.0, "timestamped");
        assert!((f + s.force).norm() <= 1e-12 * s.force.norm().max(1.0), "spatula {k}: haptic {f:?} vs simulation {:?} (negated)", s.force);
    }

    // A probe that moves spatula 0 by 0.1 mm along its face normal: force changes by K * delta.
    let normal = state.poses[0].rotation * Vec3::z();
    let mut moved = state.poses[0];
    moved.position += normal * 1e-4;
    let expected = model.tool_force(0, Some(&moved));
    let probe_pose = moved;
    let out2 = ForceOutput::start(2, HAPTIC_RATE_HZ, Box::new(move |k, _| (k == 0).then_some(probe_pose)), None);
    out2.publish(Arc::new(model.clone()));
    let t0 = Instant::now();
    while out2.ticks() < 20 && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(5));
    let (f, _) = out2.latest(0).expect("spatula 0");
    assert!((f - expected).norm() < 1e-12, "moved pose: {f:?} vs model {expected:?}");
    assert!((f + report.spatulas[0].force).norm() > 1e-6, "a 0.1 mm push into contact must change the force: {f:?}");
}
