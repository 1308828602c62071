//! The working region (`solver.row_band_mm`): surface vertices farther than
//! the band from the region of interest get no compliance rows. What a frame
//! computes in the region is the all-rows build's, bit for bit; the surface
//! beyond it is brought up to date by a sparse solve where an output reads
//! it, equal to the all-rows build's to rounding; a blade that leaves the
//! region brings the vertices it nears up to date every sub-step.

use fissure::math::Vec3;
use fissure::scenario::Scenario;
use fissure::sim::preflight::preflight;
use fissure::sim::{BuildOptions, FrameInput, FrameReport, Pipeline, SimState};
use std::path::Path;

fn scene(set: &[&str]) -> Scenario {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut all: Vec<String> = vec!["solver.cache_dir=None".into(), "duration_s=3.0".into()];
    all.extend(set.iter().map(|s| s.to_string()));
    Scenario::load(&root.join("config/sylvian.ron"), &all).expect("the default scene")
}

/// Builds `scenario` for its own trajectory and plays it; returns the pipeline, its state and every frame's report.
fn play(scenario: &Scenario) -> (Pipeline, SimState, Vec<FrameReport>) {
    let source = preflight(scenario, None).expect("preflight").poses;
    let options = BuildOptions { expected_poses: source.samples(scenario.duration, 200), ..BuildOptions::default() };
    let (mut p, mut state) = Pipeline::build(scenario, options).expect("build");
    let mut input = FrameInput::default();
    let mut reports = Vec::new();
    for k in 0..scenario.step_count() {
        source.poses_at((k + 1) as f64 * scenario.time_step, &mut input);
        reports.push(p.step(&mut state, &input).expect("frame").clone());
    }
    (p, state, reports)
}

fn bits(v: &[Vec3]) -> Vec<u64> {
    v.iter().flat_map(|u| u.iter().map(|x| x.to_bits()).collect::<Vec<_>>()).collect()
}

#[test]
fn the_working_region_is_the_all_rows_build_bit_for_bit_and_the_rest_is_brought_up_to_date() {
    let (mut band, band_state, band_reports) = play(&scene(&["solver.row_band_mm=Some(5.0)"]));
    let (mut all, all_state, all_reports) = play(&scene(&["solver.row_band_mm=None"]));
    let far = band.solver().far_vertices().to_vec();
    assert!(all.solver().far_vertices().is_empty(), "every surface vertex has a row");
    let surface = band.surface().vertices.len();
    assert!(!far.is_empty() && far.len() < surface, "the band leaves some of the surface out: {} of {surface}", far.len());
    let (rows_band, rows_all) = (band.solver().compliance().stats().rows, all.solver().compliance().stats().rows);
    assert!(rows_band < rows_all, "fewer rows stored: {rows_band} against {rows_all}");
    let forces = |r: &[FrameReport]| r.iter().flat_map(|f| f.spatulas.iter().flat_map(|s| s.force.iter().map(|x| x.to_bits()).collect::<Vec<_>>())).collect::<Vec<_>>();
    assert_eq!(forces(&band_reports), forces(&all_reports), "the forces, bit for bit");
    assert!(band_reports.iter().any(|r| r.spatulas.iter().any(|s| s.force.norm() > 0.0)), "the blades touch the tissue");
    let counts = |r: &[FrameReport]| r.iter().map(|f| (f.constrained_vertices, f.crossed_vertices, f.penetrating_vertices, f.inverted_elements)).collect::<Vec<_>>();
    assert_eq!(counts(&band_reports), counts(&all_reports), "contacts, monitor and inverted elements alike");
    // Inside the working region the surface is the all-rows build's, bit for bit.
    let near: Vec<usize> = (0..surface).filter(|k| far.binary_search(&(*k as u32)).is_err()).collect();
    let pick = |s: &SimState| near.iter().map(|&k| s.surface_displacement[k]).collect::<Vec<_>>();
    assert_eq!(bits(&pick(&band_state)), bits(&pick(&all_state)), "the working region's displacement");
    // Beyond it, brought up to date for an output: the all-rows product's to rounding.
    let whole = band.with_whole_surface(&band_state).expect("whole surface").into_owned();
    let scale = all_state.surface_displacement.iter().map(|u| u.norm()).fold(0.0, f64::max);
    let moved = far.iter().map(|&k| all_state.surface_displacement[k as usize].norm()).fold(0.0, f64::max);
    assert!(moved > 1e-3 * scale, "the far surface moves: {moved:e} m of {scale:e} m");
    let worst = far.iter().map(|&k| (whole.surface_displacement[k as usize] - all_state.surface_displacement[k as usize]).norm()).fold(0.0, f64::max);
    assert!(worst <= 1e-9 * scale, "the far surface up to date: {worst:e} m off (of {scale:e} m)");
    // The hash is over the whole surface: deterministic, and what a second run gives.
    let (mut again, again_state, _) = play(&scene(&["solver.row_band_mm=Some(5.0)"]));
    assert_eq!(band.state_hash(&band_state).unwrap(), again.state_hash(&again_state).unwrap());
    // Bringing it up to date for an output changes nothing the next frame reads.
    assert_eq!(bits(&band_state.surface_displacement), bits(&again_state.surface_displacement));
    let _ = all.state_hash(&all_state).unwrap();
}

#[test]
fn a_blade_beyond_the_working_region_brings_the_vertices_it_nears_up_to_date() {
    // The region of interest a small sphere far from where the blades go: every
    // vertex they touch is outside it, and a 1 mm band leaves them without rows.
    let set = [
        "solver.row_band_mm=Some(1.0)",
        "solver.region_of_interest=Sphere(center_mm: (0.0, 0.0, -200.0), radius_mm: 1.0)",
        "effects=[Collision, Culling, ForceOutput, ContactPressure]",
    ];
    let (mut band, band_state, band_reports) = play(&scene(&set));
    let all_set = ["solver.row_band_mm=None", set[1], set[2]];
    let (_, all_state, all_reports) = play(&scene(&all_set));
    let far = band.solver().far_vertices().to_vec();
    assert!(10 * far.len() > 9 * band.surface().vertices.len(), "almost every vertex is far: {} of {}", far.len(), band.surface().vertices.len());
    // Far vertices the frames brought up to date (no gravity: the others stay at rest).
    let tracked = far.iter().filter(|&&k| band_state.surface_displacement[k as usize] != Vec3::zeros()).count();
    assert!(tracked > 0, "the blades' neighbourhood was brought up to date");
    assert!(band_reports.iter().any(|r| r.spatulas.iter().any(|s| s.force.norm() > 0.0)), "the blades touch the tissue");
    // The vertices the blades touched were brought up to date as they came:
    // the forces follow the all-rows build's to rounding, and nothing passes a blade.
    let peak = all_reports.iter().flat_map(|r| r.spatulas.iter().map(|s| s.force.norm())).fold(0.0, f64::max);
    for (k, (a, b)) in band_reports.iter().zip(&all_reports).enumerate() {
        for (x, y) in a.spatulas.iter().zip(&b.spatulas) {
            assert!((x.force - y.force).norm() <= 1e-6 * peak, "frame {k}: {:?} against {:?}", x.force, y.force);
        }
        assert_eq!(a.crossed_vertices, 0, "frame {k}: no vertex passes a blade");
    }
    let whole = band.with_whole_surface(&band_state).expect("whole surface").into_owned();
    let scale = all_state.surface_displacement.iter().map(|u| u.norm()).fold(0.0, f64::max);
    let worst = whole.surface_displacement.iter().zip(&all_state.surface_displacement).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(worst <= 1e-6 * scale, "the whole surface: {worst:e} m off (of {scale:e} m)");
}

#[test]
fn a_band_that_is_not_a_distance_is_refused() {
    for bad in ["solver.row_band_mm=Some(0.0)", "solver.row_band_mm=Some(-3.0)", "solver.row_band_mm=Some(1e9)"] {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let e = Scenario::load(&root.join("config/sylvian.ron"), &[bad.to_string()]).expect_err(bad).to_string();
        assert!(e.contains("row_band_mm"), "{bad}: {e}");
    }
}
