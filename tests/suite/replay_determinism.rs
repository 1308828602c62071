//! Headless replay: two runs of one scene give byte-identical `metrics.csv`
//! (timing columns aside) and the same final-state hash; an interrupted run
//! leaves valid rows and a summary marked interrupted.

use crate::common;

use fissure::math::Vec3;
use fissure::scenario::Scenario;
use fissure::sim::replay::{ReplayOptions, replay};
use std::path::Path;
use std::sync::atomic::AtomicBool;

fn scene(dir: &Path) -> Scenario {
    scene_with_roi(dir, "All")
}

/// The block scene with another region of interest.
fn scene_with_roi(dir: &Path, roi: &str) -> Scenario {
    let mesh = common::block(8, 8, 4, Vec3::new(40.0, 40.0, 20.0), Vec3::new(-20.0, -20.0, 0.0));
    let mesh_path = common::write_mesh(dir, "block.msh", &mesh);
    // The blade comes down 2.5 mm into the top face, slides sideways, and leaves.
    let traj = "# press, slide, withdraw\ntime_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n\
        0.0,0,-10.0,0.0,21.0,1.0,0.0,0.0,0.0\n\
        0.1,0,-10.0,0.0,18.0,1.0,0.0,0.0,0.0\n\
        0.2,0,-6.0,2.0,18.0,1.0,0.0,0.0,0.0\n\
        0.3,0,-6.0,2.0,25.0,1.0,0.0,0.0,0.0\n";
    std::fs::write(dir.join("press.csv"), traj).unwrap();
    let text = format!(
        r#"(
    name: "block replay",
    mesh: File(path: "{}", units: Millimetres),
    material: (young_modulus_pa: 3000.0, poisson_ratio: 0.45),
    fixed: [LowestPerComponent(height_mm: 1.0)],
    spatulas: [(
        name: "blade",
        shape: (length_mm: 20.0, width_mm: 10.0, thickness_mm: 1.0),
        layout: Grid(along: 10, across: 5),
        pose: (position_mm: (-10.0, 0.0, 21.0), rotation: Quaternion(1.0, 0.0, 0.0, 0.0)),
        input: Trajectory,
    )],
    effects: [Collision, Culling, ForceOutput, ContactPressure],
    collision: (backend: Bvh),
    solver: (compliance_storage: F64, region_of_interest: {roi}, cache_dir: None),
    time_step_s: 0.01,
    duration_s: 0.3,
    trajectory: Some("press.csv"),
)"#,
        mesh_path.display(),
        roi = roi
    );
    Scenario::from_str(&text, &dir.join("block.ron"), &[]).expect("valid")
}

/// The CSV with every `_ms` column removed.
fn without_timings(csv: &str) -> String {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<bool> = header.iter().map(|h| !h.ends_with("_ms")).collect();
    std::iter::once(header.iter().zip(&keep).filter(|(_, k)| **k).map(|(h, _)| *h).collect::<Vec<_>>().join(","))
        .chain(lines.map(|l| l.split(',').zip(&keep).filter(|(_, k)| **k).map(|(v, _)| v).collect::<Vec<_>>().join(",")))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn two_replays_are_bitwise_identical() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let mut runs = Vec::new();
    for k in 0..2 {
        let out = dir.path().join(format!("run{k}"));
        let opts = ReplayOptions { out_dir: out.clone(), trajectory: None, vtk: k == 0 };
        let summary = replay(&s, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay");
        assert_eq!(summary.frames, 30);
        assert!(!summary.interrupted);
        let csv = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
        assert_eq!(csv.lines().count(), 31, "header + one row a frame");
        runs.push((without_timings(&csv), summary.final_state_hash.clone(), summary));
    }
    assert_eq!(runs[0].0, runs[1].0, "metrics.csv differs between two replays of one scene");
    assert_eq!(runs[0].1, runs[1].1, "final-state hashes differ");
    let s0 = &runs[0].2;
    assert!(s0.spatulas[0].peak_force_n > 0.0, "the blade pressed the block");
    assert!(s0.worst.max_displacement_mm > 1.0 && s0.worst.max_displacement_mm < 10.0, "{}", s0.worst.max_displacement_mm);
    // The VTK series of the first run: a .pvd naming 30 .vtu files that load back.
    let pvd = std::fs::read_to_string(dir.path().join("run0/series.pvd")).unwrap();
    assert_eq!(pvd.matches(".vtu").count(), 30);
    let m = fissure::mesh::io::load_tet_mesh(&dir.path().join("run0/frame_00010.vtu")).expect("a written frame loads back");
    // The scene says nothing about refinement: the block refined where the blade reaches.
    let refined = fissure::sim::scene_mesh::load_mesh(&s).expect("the scene's mesh").tets.len();
    assert!(refined > 8 * 8 * 4 * 6, "refine: Auto, the default, refined under the blade");
    assert_eq!(m.tets.len(), refined);
}

#[test]
fn an_interrupted_replay_keeps_its_rows_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = dir.path().join("cut");
    let stop = AtomicBool::new(false);
    let opts = ReplayOptions { out_dir: out.clone(), trajectory: None, vtk: false };
    let summary = replay(
        &s,
        &opts,
        &stop,
        &mut |_, _, done, _| {
            if done == 12 {
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            Ok(())
        },
        None,
    )
    .expect("an interruption is not an error");
    assert!(summary.interrupted);
    assert_eq!(summary.frames, 12);
    let csv = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
    assert_eq!(csv.lines().count(), 13);
    assert!(csv.lines().all(|l| l.split(',').count() == csv.lines().next().unwrap().split(',').count()), "every row complete");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["interrupted"], true);
}

/// A region of interest that covers only where the blade comes down: the
/// slide leaves it, so the frames solve lazy columns. Two replays agree to the bit. Against the all-surface
/// ROI every frame agrees to round-off until the first frame whose contact
/// set differs (in count or in area): a claim is a discrete decision (a ray
/// against a triangle), so round-off between two differently built
/// compliances can flip a borderline vertex, and from then on the runs are
/// two different (each exact) motions.
#[test]
fn replays_with_contacts_outside_the_roi_are_bitwise_identical() {
    let dir = tempfile::tempdir().unwrap();
    let small = scene_with_roi(dir.path(), "Sphere(center_mm: (-10.0, 0.0, 20.0), radius_mm: 6.0)");
    let mut runs = Vec::new();
    for k in 0..2 {
        let out = dir.path().join(format!("small{k}"));
        let opts = ReplayOptions { out_dir: out.clone(), trajectory: None, vtk: false };
        let summary = replay(&small, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay");
        let csv = std::fs::read_to_string(out.join("metrics.csv")).unwrap();
        runs.push((without_timings(&csv), summary));
    }
    assert_eq!(runs[0].0, runs[1].0, "metrics.csv differs between two replays with lazy columns");
    assert_eq!(runs[0].1.final_state_hash, runs[1].1.final_state_hash);
    let all = scene(dir.path());
    let out = dir.path().join("all");
    let opts = ReplayOptions { out_dir: out.clone(), trajectory: None, vtk: false };
    replay(&all, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay");
    let reference = without_timings(&std::fs::read_to_string(out.join("metrics.csv")).unwrap());
    let header: Vec<&str> = reference.lines().next().unwrap().split(',').collect();
    let count_col = header.iter().position(|h| *h == "constrained_vertices").expect("constrained_vertices column");
    let area_col = header.iter().position(|h| *h == "blade_contact_area_mm2").expect("contact area column");
    let mut compared = 0;
    for (s_row, a_row) in runs[0].0.lines().zip(reference.lines()).skip(1) {
        let (s, a): (Vec<&str>, Vec<&str>) = (s_row.split(',').collect(), a_row.split(',').collect());
        // Another contact set: as many vertices but not the same ones changes the area beyond round-off.
        let (area_s, area_a) = (s[area_col].parse::<f64>().unwrap_or(0.0), a[area_col].parse::<f64>().unwrap_or(0.0));
        if s[count_col] != a[count_col] || (area_s - area_a).abs() > 1e-9 * area_s.abs().max(area_a.abs()) {
            break;
        }
        // A force change is a difference of forces compared just above: its
        // round-off is the forces', not its own size.
        for ((x, y), name) in s.iter().zip(&a).zip(&header).filter(|(_, name)| !name.ends_with("_force_jump_n")) {
            if let (Ok(x), Ok(y)) = (x.parse::<f64>(), y.parse::<f64>()) {
                assert!((x - y).abs() <= 1e-10 * x.abs().max(y.abs()).max(1e-12), "frame {}: {name} {x} with a small ROI, {y} with all", s[0]);
            }
        }
        if s[count_col] != "0" {
            compared += 1;
        }
    }
    assert!(compared >= 5, "only {compared} frames with contacts before the runs diverged");
}

/// The default scene's spread as a jittery tracker sends it (+-0.5 mm every
/// 10 ms): through the One Euro filter it replays to the same bits twice, and
/// the filter keeps the jitter from multiplying the frame's sub-steps.
#[test]
fn a_noisy_track_through_the_pose_filter_replays_bitwise_and_needs_fewer_substeps() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let cache = format!("solver.cache_dir=Some({:?})", dir.path().join("cache").display().to_string());
    let filter = "OneEuro(min_cutoff_hz: 1.0, beta_hz_per_mm_s: 0.05, d_cutoff_hz: 1.0)";
    let load = |filtered: bool| {
        // Past the entry (tips 18 mm deep at 1.5 s) into the spread.
        let mut set = vec!["duration_s=2.5".to_string(), cache.clone()];
        if filtered {
            set.push(format!("spatulas[0].filter={filter}"));
            set.push(format!("spatulas[1].filter={filter}"));
        }
        Scenario::load(&root.join("config/sylvian.ron"), &set).expect("the default scene")
    };
    let noisy = root.join("assets/trajectories/paper_fig14_sylvian_noisy.csv");
    let run = |s: &Scenario, name: &str| {
        let opts = ReplayOptions { out_dir: dir.path().join(name), trajectory: Some(noisy.clone()), vtk: false };
        replay(s, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay")
    };
    let filtered = load(true);
    assert!(filtered.spatulas.iter().all(|s| s.filter.is_some()));
    let (a, b) = (run(&filtered, "a"), run(&filtered, "b"));
    assert_eq!(a.final_state_hash, b.final_state_hash, "the filtered noisy track replays to the same bits");
    let raw = run(&load(false), "raw");
    assert_ne!(raw.final_state_hash, a.final_state_hash, "the filter changes what the blades do");
    assert!(
        a.max_substeps < raw.max_substeps,
        "the filter steadies the blades: {} sub-steps a frame at most against {} unfiltered",
        a.max_substeps,
        raw.max_substeps
    );
}
