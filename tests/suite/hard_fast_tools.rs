//! Hard cases, fast tools: a blade that moves many times its thickness in one
//! frame (a surgeon's flick, a tracker glitch) must give what the same motion
//! sampled finely gives. The pipeline splits such a frame into sub-steps of at
//! most `SUBSTEP_TRAVEL_FRACTION` of the blade's thickness; these tests sweep
//! 0.25 to 40 thicknesses a frame and check no tunnelling, no abort, a bounded
//! force, and the end state of the slow motion. And when the contact solve hits
//! its iteration cap, the frame keeps the last feasible state and says so.
//!
//! Scene units: millimetres in the mesh file, metres inside.

use crate::common;

use common::scenes::{Scene, pose_mm, step_checked};
use fissure::sim::{FrameInput, MAX_SUBSTEPS};

const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
/// Block top (mm); the blade lies flat, face 0 up, face 1 down.
const TOP_MM: f64 = 20.0;
/// Blade mid-plane heights (mm): lower face 37 mm above the top, then 3 mm below it.
const START_Z_MM: f64 = TOP_MM + 0.5 + 37.0;
const END_Z_MM: f64 = TOP_MM + 0.5 - 3.0;

/// The block press with the blade 37 mm above the block.
fn press_scene() -> Scene {
    common::scenes::block_press(START_Z_MM)
}

/// The default scene's blades (paper Fig. 14) driven straight from their start
/// poses to where the scene's trajectory ends: 23 mm into the Sylvian fissure
/// and 7 mm apart along its normal at once, a 24 mm diagonal (millimetres; the
/// blades' rotation is the scenario's).
const DIAGONAL: [[(f64, f64, f64); 2]; 2] = [
    [(-133.09, 10.4115, -10.5227), (-110.09, 12.8117, -3.9471)],
    [(-133.09, 9.5885, -12.7773), (-110.09, 7.1883, -19.3529)],
];
const DIAGONAL_MM: f64 = 24.2;

/// Replays the default scene with the diagonal sampled at `speed` thicknesses
/// (1 mm) a frame, plus 10 held frames (a run has at least 10 steps).
fn sylvian_at(speed: f64, cache: &std::path::Path, refine: &str) -> fissure::sim::metrics::Summary {
    let dir = tempfile::tempdir().unwrap();
    let frames = (DIAGONAL_MM / speed).ceil() as usize;
    let times = [0.0, frames as f64 * 0.01];
    let mut csv = String::from("time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    for (s, leg) in DIAGONAL.iter().enumerate() {
        for (t, p) in times.iter().zip(leg) {
            csv += &format!("{t:?},{s},{:?},{:?},{:?},0.984727174,-0.174104545,0.0,0.0\n", p.0, p.1, p.2);
        }
    }
    let trajectory = dir.path().join("diagonal.csv");
    std::fs::write(&trajectory, csv).unwrap();
    let duration = format!("duration_s={:?}", (frames + 10) as f64 * 0.01);
    let cache_dir = format!("solver.cache_dir=Some({:?})", cache.display().to_string());
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenario = fissure::scenario::Scenario::load(&root.join("config/sylvian.ron"), &[duration, cache_dir, format!("refine={refine}")]).expect("default scene");
    let options = fissure::sim::replay::ReplayOptions { out_dir: dir.path().join("out"), trajectory: Some(trajectory), vtk: false };
    let never = std::sync::atomic::AtomicBool::new(false);
    fissure::sim::replay::replay(&scenario, &options, &never, &mut |_, _, _, _| Ok(()), None)
        .unwrap_or_else(|e| panic!("{speed} thicknesses a frame: the replay stopped: {e}"))
}

/// On the phantom's own mesh (`refine: None`) every speed ends within 3 % of the
/// slow motion. On the refined mesh (the scene's default) it ends within 10 %:
/// there a few vertices (up to six of the frontal blade's 70-76) lie within
/// rounding of the blade's mid-plane when its tip meets them head-on, and go to
/// the face they are on at that sub-step, so the answer takes one of a few
/// discrete values as the sampling changes (0.0513, 0.0551, 0.0555 or 0.0558 N
/// over sub-steps of 1/16 to 1/4 of the thickness and 0.125 to 40 thicknesses
/// a frame). A mesh that followed the run's length instead of the scene (a
/// fast run refined less) gave 20-50 % less force.
#[test]
fn blades_at_0_25_to_40_thicknesses_a_frame_open_the_fissure_as_slow_blades_do() {
    let cache = tempfile::tempdir().unwrap();
    for (refine, tolerance) in [("None", 0.03), ("Auto", 0.10)] {
        let slow = sylvian_at(0.25, cache.path(), refine);
        let peak = |s: &fissure::sim::metrics::Summary| s.spatulas.iter().map(|x| x.peak_force_n).fold(0.0, f64::max);
        println!("refine {refine}, slow (0.25 a frame): {} frames, peak force {:.4} N, max |u| {:.3} mm", slow.frames, peak(&slow), slow.worst.max_displacement_mm);
        assert_eq!(slow.max_substeps, 2, "a quarter thickness a frame is two sub-steps of an eighth");
        for speed in [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 40.0] {
            let fast = sylvian_at(speed, cache.path(), refine);
            println!(
                "{speed:>5} thicknesses a frame: {:>3} frames, up to {:>2} sub-steps, {} capped, crossed {}, penetrating {} ({:.4} mm), peak force {:.4} N, max |u| {:.3} mm",
                fast.frames, fast.max_substeps, fast.capped_frames, fast.worst.max_crossed_vertices, fast.worst.max_penetrating_vertices, fast.worst.max_penetration_mm, peak(&fast), fast.worst.max_displacement_mm
            );
            assert_eq!(fast.capped_frames, 0, "refine {refine}, {speed} thicknesses a frame: the contact solve hit its cap");
            assert_eq!(fast.worst.max_crossed_vertices, 0, "refine {refine}, {speed} thicknesses a frame: tissue tunnelled through a blade");
            // Sub-steps of an eighth of the thickness give the slow motion's answer
            // (sampled at 0.3 to 0.5 mm a frame without them, this motion
            // scattered by 20 % in force; in one frame it pulled tissue 54 mm).
            let du = (fast.worst.max_displacement_mm - slow.worst.max_displacement_mm).abs() / slow.worst.max_displacement_mm;
            let df = (peak(&fast) - peak(&slow)).abs() / peak(&slow);
            assert!(
                du <= tolerance && df <= tolerance,
                "refine {refine}, {speed} thicknesses a frame: max |u| {} mm and peak force {} N against {} mm and {} N for the slow motion: the result depends on the sampling",
                fast.worst.max_displacement_mm,
                peak(&fast),
                slow.worst.max_displacement_mm,
                peak(&slow)
            );
        }
    }
}

#[test]
fn a_jump_of_a_metre_in_one_frame_is_split_at_the_cap_and_stays_finite() {
    let dir = tempfile::tempdir().unwrap();
    let (mut p, mut state) = press_scene().build(dir.path());
    // From 37 mm above the block to a metre away and back onto the block: a tracker glitch.
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([994.0, 0.0, START_Z_MM], IDENTITY)], "glitch out");
    // Its whole path lies 37 mm above the tissue and nothing is held: one step does.
    assert_eq!(r.substeps, 1, "a path through the air needs no sub-steps");
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([-6.0, 0.0, END_Z_MM], IDENTITY)], "glitch back");
    assert_eq!(r.substeps, MAX_SUBSTEPS, "a metre into the tissue is far more than the cap's worth of sub-steps");
    assert!(!r.solver_capped);
    assert_eq!(r.crossed_vertices, 0, "glitch back: tissue tunnelled through the blade");
    // Out again through the air, from holding the tissue: the first frame
    // starts in contact, so it is split whatever its path.
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([-6.0, 0.0, START_Z_MM], IDENTITY)], "lift off");
    assert!(r.substeps > 1, "a frame that starts holding tissue is split");
}

#[test]
fn a_capped_contact_solve_keeps_the_last_feasible_state_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let (mut p, mut state) = press_scene().build(dir.path());
    let mut twin = press_scene().build(dir.path());
    let touch = pose_mm([-6.0, 0.0, TOP_MM + 0.5 - 0.5], IDENTITY);
    for (pipeline, s) in [(&mut p, &mut state), (&mut twin.0, &mut twin.1)] {
        step_checked(pipeline, s, &[pose_mm([-6.0, 0.0, TOP_MM + 0.5 + 0.2], IDENTITY)], "approach");
        step_checked(pipeline, s, &[touch], "touch");
    }
    let before = state.clone();
    // A cap of 0 iterations fails every solve: the frame's first sub-step is
    // undone, the tissue and the blade stay where the last frame left them.
    p.set_solver_iteration_cap(Some(0));
    let input = FrameInput { poses: vec![Some(pose_mm([-6.0, 0.0, TOP_MM + 0.5 - 2.5], IDENTITY))] };
    let r = p.step(&mut state, &input).expect("a capped solve is not an error").clone();
    assert!(r.solver_capped, "the report must say the cap was hit");
    assert_eq!(r.frame, before.frame, "the frame still counts");
    assert_eq!(state.frame, before.frame + 1);
    assert!(state.surface_displacement.iter().all(|u| u.iter().all(|c| c.is_finite())));
    // The last feasible state: the tissue and the blade of the last frame, bit for bit.
    assert_eq!(state.surface_displacement, before.surface_displacement, "the tissue must stay as the last frame left it");
    assert_eq!(state.poses, before.poses, "the blade must stay where the last frame put it");
    let z = state.poses[0].position.z * 1e3;
    let check = common::scenes::check_frame(&p, &state, &r, "capped");
    assert_eq!(r.crossed_vertices, 0);
    println!("capped frame: blade at z {z:.3} mm, {} sub-steps planned, max |u| {:.3} mm", r.substeps, check.max_displacement_m * 1e3);
    // Lifting the cap, the next frame reaches the target and matches a run that was never capped.
    p.set_solver_iteration_cap(None);
    let r = p.step(&mut state, &input).expect("uncapped").clone();
    assert!(!r.solver_capped);
    twin.0.step(&mut twin.1, &input).expect("twin");
    twin.0.step(&mut twin.1, &input).expect("twin hold");
    let gap = state.surface_positions.iter().zip(&twin.1.surface_positions).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(gap < 1e-6, "after the cap lifts the state must rejoin the uncapped run: {gap:e} m apart");
}
