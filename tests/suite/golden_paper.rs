//! The paper's scenes end to end (golden replays): each states in numbers what
//! the paper shows in pictures. Tolerances are stated beside each assertion.
//!
//! - Fig. 11: a spatula jumps 5 thicknesses sideways in one frame inside the
//!   inter-hemispheric fissure: with the rays' claims (`Unilateral`, as in the
//!   paper) and culling no surface vertex is pulled through the blade; without
//!   culling some are (the failure the paper shows). Sliding contact (the
//!   default) claims nothing and pulls nothing through, culling or not.
//! - Fig. 12: V-valley, both faces give displacements and culling cancels none
//!   of the rays' claims.
//!   (The rotated U channel is checked at the collision stage, where each face's
//!   contact pattern is asserted: `tests/suite/collision_paper_cases.rs`.)
//! - Fig. 14: two spatulas open the Sylvian fissure: its width at depth grows to
//!   the blades' spread, and the skull spheres hold.

use fissure::fem::ConstraintKind;
use fissure::math::Vec3;
use fissure::scenario::Scenario;
use fissure::sim::replay::{ReplayOptions, replay};
use fissure::sim::{BuildOptions, FrameInput, Pipeline, poses::TrajectoryPoses};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Replays a config with a trajectory and overrides; returns the summary and the CSV.
fn run(config: &str, trajectory: &str, overrides: &[&str]) -> (fissure::sim::metrics::Summary, String) {
    let mut sets: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    sets.push("solver.cache_dir=None".into());
    let s = Scenario::load(&repo(config), &sets).expect("config loads");
    let dir = tempfile::tempdir().unwrap();
    let opts = ReplayOptions { out_dir: dir.path().to_path_buf(), trajectory: Some(repo(trajectory)), vtk: false };
    let summary = replay(&s, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay");
    let csv = std::fs::read_to_string(dir.path().join("metrics.csv")).unwrap();
    (summary, csv)
}

/// Column `name` of a metrics CSV as numbers.
fn column(csv: &str, name: &str) -> Vec<f64> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    lines.map(|l| l.split(',').nth(k).unwrap().parse().unwrap()).collect()
}

#[test]
fn fig11_culling_keeps_tissue_out_of_the_blade_and_without_it_tissue_is_pulled_through() {
    let traj = "assets/trajectories/paper_fig11_interhemispheric.csv";
    // One step a frame, as in the paper: sub-steps (our default) make the jump
    // continuous and culling then has nothing to cancel (checked below).
    let claims = "solver.spatula_contact=Unilateral";
    let (with, csv_with) = run("config/interhemispheric.ron", traj, &["duration_s=2.5", "solver.substep_travel=None", claims]);
    let (without, csv_without) =
        run("config/interhemispheric.ron", traj, &["duration_s=2.5", "effects=[Collision, ForceOutput]", "solver.substep_travel=None", claims]);
    let pairs_with: f64 = column(&csv_with, "spatula_feasible_pairs").iter().sum();
    assert!(pairs_with > 0.0, "the spatula must touch the wall");
    let culled: f64 = column(&csv_with, "spatula_culled_pairs").iter().sum();
    println!(
        "Fig. 11: with culling: max crossed {}, culled pairs (sum) {culled}; without: max crossed {}, max displacement {:.2} vs {:.2} mm",
        with.worst.max_crossed_vertices, without.worst.max_crossed_vertices, with.worst.max_displacement_mm, without.worst.max_displacement_mm
    );
    assert_eq!(with.worst.max_crossed_vertices, 0, "with culling no surface vertex may be pulled through the spatula");
    assert!(culled > 0.0, "the one-frame jump must make culling cancel pairs");
    assert!(without.worst.max_crossed_vertices > 0, "without culling the far wall is pulled through the blade (paper Fig. 11b)");
    assert_eq!(column(&csv_without, "spatula_culled_pairs").iter().sum::<f64>(), 0.0);
    // With sub-steps the jump is continuous: nothing is pulled through even without culling.
    let (substepped, _) = run("config/interhemispheric.ron", traj, &["duration_s=2.5", "effects=[Collision, ForceOutput]", claims]);
    println!("Fig. 11 with sub-steps, no culling: max crossed {}, up to {} sub-steps", substepped.worst.max_crossed_vertices, substepped.max_substeps);
    assert!(substepped.max_substeps > 1, "the 5-thickness jump must be split");
    assert_eq!(substepped.worst.max_crossed_vertices, 0, "sub-steps alone keep the far wall out of the blade");
    // Sliding (the default): no claims, so the one-frame jump without culling pulls nothing through either.
    let (sliding, csv_sliding) = run("config/interhemispheric.ron", traj, &["duration_s=2.5", "effects=[Collision, ForceOutput]", "solver.substep_travel=None"]);
    assert!(column(&csv_sliding, "spatula_force_n").iter().any(|&f| f > 0.0), "the sliding blade must push the wall");
    assert_eq!(sliding.worst.max_crossed_vertices, 0, "sliding contact pulls no vertex through the blade");
}

#[test]
fn fig12_v_valley_both_faces_push_and_culling_cancels_none() {
    // The rays' claims, as in the paper (sliding contact claims nothing for culling to cancel).
    let (s, csv) = run("config/v_valley.ron", "assets/trajectories/paper_fig12_v_valley.csv", &["solver.spatula_contact=Unilateral"]);
    let culled: f64 = column(&csv, "spatula_culled_pairs").iter().sum();
    let feasible = column(&csv, "spatula_feasible_pairs");
    println!("Fig. 12 V: final feasible pairs {}, culled total {culled}, max displacement {:.2} mm", feasible.last().unwrap(), s.worst.max_displacement_mm);
    assert_eq!(culled, 0.0, "in the V valley culling cancels none of the feasible pairs");
    // The valley's apex line lies exactly on the blade's mid-plane (x = 0) at rest: whichever
    // face claims it moves it to its side, which the monitor counts as one crossing. Nothing else may cross.
    assert!(s.worst.max_crossed_vertices <= 1, "only the apex vertex on the mid-plane may change side: {}", s.worst.max_crossed_vertices);
    // Both faces: checked over the last two frames with the collision stage's per-face targets
    // and the active barrier rows (the apex line once alternated between the faces every frame;
    // `fig12_v_valley_holds_steady_once_the_blade_stops` guards the fix).
    let sc = Scenario::load(&repo("config/v_valley.ron"), &["solver.cache_dir=None".into()]).unwrap();
    let faces = faces_over_last_frames(&sc, "assets/trajectories/paper_fig12_v_valley.csv", 2);
    assert!(faces[0] > 0 && faces[1] > 0, "both faces constrain the walls: {faces:?}");
}

#[test]
fn fig12_v_valley_holds_steady_once_the_blade_stops() {
    let (_, csv) = run("config/v_valley.ron", "assets/trajectories/paper_fig12_v_valley.csv", &[]);
    let fx = column(&csv, "spatula_force_x_n");
    // The trajectory stops at 2 s (frame 200); the last 50 frames hold one pose.
    let tail = &fx[fx.len() - 50..];
    let jump = tail.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
    assert!(jump <= 1e-6, "at a still pose the force must settle: largest frame-to-frame change {jump:e} N");
}

#[test]
fn fig14_refined_holds_steady_once_the_blades_stop() {
    // The Sylvian scene refined under the blades (`refine: Auto`): the blades spread until 4 s and hold until 5 s.
    // Each held frame must find the rows the frame before ended with, at once (one active-set iteration), and the
    // force must settle. A vertex lying on a blade's side-edge plane between its faces once got a broad face's row
    // instead of the edge's, was lifted onto that face, sprang back beside the edge when free, and the contact
    // cycled through these states every held frame (0.3 mN on the blade, 4 mN on the vertex).
    let s = Scenario::load(&repo("config/sylvian.ron"), &["refine=Auto".into(), "solver.cache_dir=None".into()]).unwrap();
    let source = TrajectoryPoses::for_scenario(&s, None).unwrap();
    let (mut p, mut state) = Pipeline::build(&s, BuildOptions { expected_poses: source.samples(s.duration, 200), progress: None, ..BuildOptions::default() }).unwrap();
    let mut input = FrameInput::default();
    let active = |p: &Pipeline| -> Vec<(u32, u16, [u64; 3])> {
        p.last_constraints()
            .iter()
            .zip(&p.last_solution().reactions)
            .filter(|(_, r)| r.norm() > 0.0)
            .map(|(c, _)| match c.kind {
                ConstraintKind::Barrier { normal, .. } | ConstraintKind::Contact { normal, .. } => (c.node, c.owner, fissure::math::bits3(&normal)),
                _ => (c.node, c.owner, [0; 3]),
            })
            .collect()
    };
    let (mut last_active, mut last_force) = (Vec::new(), [0.0; 2]);
    let mut held = 0;
    for k in 0..s.step_count() {
        source.poses_at((k + 1) as f64 * s.time_step, &mut input);
        let report = p.step(&mut state, &input).unwrap();
        let force = [report.spatulas[0].force.norm(), report.spatulas[1].force.norm()];
        let now = active(&p);
        // The hold starts at frame 400; a frame to settle.
        if k > 401 {
            held += 1;
            assert_eq!(p.last_solution().iterations, 1, "frame {k}: the held frame changed its rows");
            assert_eq!(now, last_active, "frame {k}: the active rows changed at a held pose");
            for b in 0..2 {
                let jump = (force[b] - last_force[b]).abs();
                assert!(jump <= 1e-12 * force[b], "frame {k}, blade {b}: the force moved {jump:e} N at a held pose");
            }
        }
        (last_active, last_force) = (now, force);
    }
    assert!(held >= 90, "{held} held frames checked");
}

/// Replays in-process and returns, per face, the number of vertices it held or kept
/// off its plane (an active barrier row) in the last `frames` frames.
fn faces_over_last_frames(s: &Scenario, traj: &str, frames: usize) -> [usize; 2] {
    let source = TrajectoryPoses::for_scenario(s, Some(&repo(traj))).unwrap();
    let (mut p, mut state) = Pipeline::build(s, BuildOptions { expected_poses: source.samples(s.duration, 50), progress: None, ..BuildOptions::default() }).unwrap();
    let mut input = FrameInput::default();
    let mut faces = [0; 2];
    let steps = s.step_count();
    for k in 0..steps {
        source.poses_at((k + 1) as f64 * s.time_step, &mut input);
        p.step(&mut state, &input).unwrap();
        if k + frames as u64 >= steps {
            for t in &p.collision().unwrap().output().targets {
                faces[t.face as usize] += 1;
            }
            // Unilateral contact: a face also pushes through its barrier rows (vertices it keeps off its plane).
            let axis = state.poses[0].rotation * Vec3::z();
            for (c, r) in p.last_constraints().iter().zip(&p.last_solution().reactions) {
                if let ConstraintKind::Barrier { normal, .. } = c.kind {
                    if r.norm() > 0.0 {
                        faces[usize::from(normal.dot(&axis) < 0.0)] += 1;
                    }
                }
            }
        }
    }
    faces
}

/// Skull contacts seen over a replay, and how their compliance columns came.
#[derive(Default)]
struct LazyColumnUse {
    skull_contacts: usize,
    skull_contacts_outside_roi: usize,
    in_frame_solves: usize,
}

impl LazyColumnUse {
    fn add(&mut self, p: &Pipeline) {
        let solution = p.last_solution();
        self.in_frame_solves += solution.lazy_solves;
        for (c, f) in p.last_constraints().iter().zip(&solution.reactions) {
            let sphere = matches!(c.kind, ConstraintKind::SphereInside { .. } | ConstraintKind::SphereOutside { .. });
            if sphere && f.norm() > 0.0 {
                self.skull_contacts += 1;
                self.skull_contacts_outside_roi += usize::from(p.solver().compliance().col_of(c.node).is_none());
            }
        }
    }
}

/// The automatic ROI of the default scene: the blades' reach plus the skull
/// candidates at rest, least gap first and at most `AUTO_ROI_SKULL_MAX` of
/// them; without the SkullSpheres effect the skull adds nothing.
#[test]
fn the_automatic_roi_takes_the_skull_candidates_at_rest_up_to_its_cap() {
    use fissure::sim::scene_mesh::{AUTO_ROI_SKULL_MAX, load_mesh, region_of_interest};
    use fissure::sim::pipeline::{SKULL_CANDIDATE_BAND_M, skull_gap};
    let roi_of = |sets: &[&str]| {
        let s = Scenario::load(&repo("config/sylvian.ron"), &sets.iter().map(|x| x.to_string()).collect::<Vec<_>>()).unwrap();
        let mesh = load_mesh(&s).unwrap();
        let surface = fissure::mesh::BoundarySurface::of(&mesh);
        let initial: Vec<_> = s.spatulas.iter().map(|sp| sp.initial_pose).collect();
        let roi = region_of_interest(&s, &mesh, &surface.vertices, &[initial]);
        (s, mesh, surface, roi)
    };
    let no_skull_effect = "effects=[Collision, Culling, ForceOutput]";
    let tight = "skull=Some((containing: Some((center_mm: (0.0, 0.0, -12.4), radius_mm: 88.0)), excluding: None))";
    let (_, _, _, blades) = roi_of(&[no_skull_effect]);
    assert_eq!(roi_of(&[no_skull_effect, tight]).3, blades, "a skull the scene does not simulate adds nothing");
    // the scene's own skull (26 candidates), then one hugging the brain (hundreds)
    for (skull, expect_capped) in [(None, false), (Some(tight), true)] {
        let sets: Vec<&str> = skull.into_iter().collect();
        let (s, mesh, surface, roi) = roi_of(&sets);
        assert!(roi.windows(2).all(|w| w[0] < w[1]), "ascending, distinct");
        assert!(blades.iter().all(|n| roi.binary_search(n).is_ok()), "the blades' reach stays");
        let added: Vec<u32> = roi.iter().copied().filter(|n| blades.binary_search(n).is_err()).collect();
        let sk = s.skull.unwrap();
        let gap = |n: u32| skull_gap(&sk, &mesh.positions[n as usize]);
        let band: Vec<u32> = surface.vertices.iter().copied().filter(|&n| blades.binary_search(&n).is_err() && gap(n) < SKULL_CANDIDATE_BAND_M).collect();
        println!("skull override {skull:?}: {} in the band outside the blades' reach, {} added", band.len(), added.len());
        assert!(added.iter().all(|&n| gap(n) < SKULL_CANDIDATE_BAND_M), "only skull candidates are added");
        assert_eq!(added.len(), band.len().min(AUTO_ROI_SKULL_MAX));
        assert_eq!(band.len() > AUTO_ROI_SKULL_MAX, expect_capped, "this skull tests the cap");
        // least gap first: every candidate left out is at least as far as every one taken
        let worst_in = added.iter().map(|&n| gap(n)).fold(f64::NEG_INFINITY, f64::max);
        assert!(band.iter().filter(|n| added.binary_search(n).is_err()).all(|&n| gap(n) >= worst_in));
    }
}

#[test]
fn fig14_two_spatulas_open_the_sylvian_fissure_and_the_skull_holds() {
    let traj = "assets/trajectories/paper_fig14_sylvian.csv";
    let s = Scenario::load(&repo("config/sylvian.ron"), &["solver.cache_dir=None".into(), "time_step_s=0.02".into()]).unwrap();
    let source = TrajectoryPoses::for_scenario(&s, Some(&repo(traj))).unwrap();
    let (mut p, mut state) = Pipeline::build(&s, BuildOptions { expected_poses: source.samples(s.duration, 100), progress: None, ..BuildOptions::default() }).unwrap();
    let mut input = FrameInput::default();
    let mut max_crossed = 0;
    let mut lazy = LazyColumnUse::default();
    for k in 0..s.step_count() {
        source.poses_at((k + 1) as f64 * s.time_step, &mut input);
        let r = p.step(&mut state, &input).expect("step");
        max_crossed = max_crossed.max(r.crossed_vertices);
        assert!(r.max_displacement_m.is_finite());
        lazy.add(&p);
    }
    // The automatic ROI covers the blades' reach and the vertices that touch the
    // skull at rest, so no contact stalls the frame on a sparse solve.
    assert!(lazy.skull_contacts > 0, "the brain meets the skull in this scene");
    assert_eq!(lazy.skull_contacts_outside_roi, 0, "the automatic ROI holds the skull contacts");
    assert_eq!(lazy.in_frame_solves, 0, "columns solved inside frames");
    // The fissure frame (from the phantom's landmarks, as in scripts/make_trajectories.py).
    let entry = Vec3::new(-68.09e-3, 10e-3, -11.65e-3);
    let inward = Vec3::x();
    let normal = Vec3::new(0.0, 0.3429, 0.9394).normalize();
    let across = normal.cross(&inward);
    let rest = p.rest_positions();
    let (mut rest_upper, mut rest_lower, mut now_upper, mut now_lower) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for (r, now) in rest.iter().zip(&state.surface_positions) {
        let d = r - entry;
        let depth = d.dot(&inward);
        if !(0.006..=0.014).contains(&depth) || d.dot(&across).abs() > 0.002 {
            continue;
        }
        let s_rest = d.dot(&normal);
        let s_now = (now - entry).dot(&normal);
        if s_rest > 0.0 && s_rest < 0.008 {
            rest_upper = rest_upper.min(s_rest);
            now_upper = now_upper.min(s_now);
        } else if s_rest < 0.0 && s_rest > -0.008 {
            rest_lower = rest_lower.max(s_rest);
            now_lower = now_lower.max(s_now);
        }
    }
    let width_rest = (rest_upper - rest_lower) * 1e3;
    let width_now = (now_upper - now_lower) * 1e3;
    let blades_outer_faces = 2.0 * (1.2 + 7.0 + 0.5);
    println!("Fig. 14: fissure width at 6-14 mm depth: rest {width_rest:.2} mm, opened {width_now:.2} mm, blades' outer faces {blades_outer_faces:.1} mm apart; max crossed {max_crossed}");
    assert!(width_rest.is_finite() && width_now.is_finite(), "both walls found in the measuring window");
    assert!((width_now - blades_outer_faces).abs() < 0.5, "the opened fissure's walls rest on the blades (tolerance 0.5 mm)");
    assert!(width_now - width_rest > 0.8 * (blades_outer_faces - width_rest), "the fissure opened by the spread");
    assert_eq!(max_crossed, 0);
    // The skull spheres hold for every surface vertex.
    let skull = p.skull().expect("sylvian.ron asks for skull spheres").skull();
    for q in &state.surface_positions {
        if let Some(c) = skull.containing {
            assert!((q - c.center).norm() <= c.radius * (1.0 + 1e-9), "vertex outside the containing sphere");
        }
        if let Some(e) = skull.excluding {
            assert!((q - e.center).norm() >= e.radius * (1.0 - 1e-9), "vertex inside the excluding sphere");
        }
    }
}
