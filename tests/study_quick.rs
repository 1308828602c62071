//! `fissure study`, reduced for CI: the `paper-9k` phantom, a subset of every
//! knob, a short motion. Checks the outputs exist and are well formed (CSV
//! rows, decodable non-blank PNGs, a report with the paper's numbers) and
//! that accuracy behaves: the reference rows have zero error, BVH answers
//! exactly like the reference backend, fewer nodes do change the result, the
//! spatula does touch the wall, and nothing sinks deeper into a blade than
//! half its thickness.

use fissure::scenario::CollisionBackend;
use fissure::study::plan::{PlanValues, base_settings};
use fissure::study::{Knob, MeshChoice, Motion, RunRow, StudyPlan, load_scene, run_plan};

fn ci_plan() -> StudyPlan {
    let values = PlanValues {
        base: base_settings(MeshChoice::Phantom("paper-9k".into())),
        nodes: vec![8, 150],
        tip_nodes: Vec::new(),
        meshes: Vec::new(),
        extra_meshes: Vec::new(),
        speeds: vec![0.5, 5.0],
        backends: vec![CollisionBackend::Reference, CollisionBackend::Bvh],
        backend_nodes: vec![30],
        // Storage and ROI sweeps need extra compliance precomputes (the whole-surface
        // reference alone takes minutes unoptimized): they run in the presets only.
        storage: false,
        roi_radii_m: Vec::new(),
    };
    // The paper-9k phantom's fissure is 9.4 mm wide: opening 10 mm pushes about 5 mm into the wall.
    // (The `small` phantom's coarse sulci leave no wall where this scene's blade works.)
    let motion = Motion { insert_m: 0.030, insert_step_m: 0.010, open_m: 0.010 };
    StudyPlan::from_values("ci", motion, &values)
}

fn find<'a>(rows: &'a [RunRow], knob: Knob, label: &str) -> &'a RunRow {
    rows.iter().find(|r| r.knob == knob && r.label == label).unwrap_or_else(|| panic!("no row {knob:?} {label}"))
}

#[test]
fn reduced_study_writes_its_outputs_and_accuracy_behaves() {
    let dir = tempfile::tempdir().expect("temp dir");
    let plan = ci_plan();
    let scene = load_scene(None).expect("built-in study scene");
    let mut calls = Vec::new();
    let results = run_plan(&plan, &scene, dir.path(), &mut |p| calls.push(p)).expect("study runs");
    println!("{}", std::fs::read_to_string(dir.path().join("report.md")).unwrap_or_default());

    // Progress: monotone, ends at total.
    let total = plan.run_count();
    assert!(calls.windows(2).all(|w| w[0].done <= w[1].done), "progress never goes back");
    assert_eq!(calls.last().map(|p| (p.done, p.total)), Some((total, total)), "progress ends at the run count");

    // Every run succeeded (no GPU in this plan) and has one row.
    assert_eq!(results.rows.len(), total);
    for r in &results.rows {
        assert!(r.outcome.is_ok(), "{} {} failed: {:?}", r.knob.name(), r.label, r.outcome.as_ref().err());
    }

    // Files.
    let csv = std::fs::read_to_string(dir.path().join("results.csv")).expect("results.csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), total + 1, "header + one row a run");
    assert!(lines[0].starts_with("knob,label,value,reference,"));
    assert!(lines.iter().skip(1).all(|l| !l.contains("failed")), "no failed run in the CSV");
    let report = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
    for needle in ["For this much accuracy, this much time", "160 ms (GPU)", "2000 ms (CPU)", "700 ms", "## Sweep: speed"] {
        assert!(report.contains(needle), "report.md lacks `{needle}`");
    }
    for stem in ["pareto", "fig13_collision_vs_nodes", "speed_vs_error"] {
        let png = dir.path().join(format!("{stem}.png"));
        let img = image::open(&png).unwrap_or_else(|e| panic!("{} does not decode: {e}", png.display())).to_rgb8();
        let first = *img.get_pixel(0, 0);
        let differing = img.pixels().filter(|p| **p != first).count();
        assert!(differing > (img.width() * img.height()) as usize / 100, "{stem}.png is (nearly) blank: {differing} non-background pixels");
        let svg = std::fs::read_to_string(dir.path().join(format!("{stem}.svg"))).expect("svg");
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"), "{stem}.svg is an SVG document");
    }

    // Accuracy: references are exact.
    for r in results.rows.iter().filter(|r| r.is_reference) {
        let a = r.outcome.as_ref().ok().and_then(|m| m.accuracy).expect("reference has accuracy");
        assert_eq!((a.rms_error_m, a.max_error_m, a.force_error_pct), (0.0, 0.0, 0.0), "reference row {} is its own reference", r.label);
        assert!(a.frames_compared > 0);
    }
    let acc = |r: &RunRow| r.outcome.as_ref().ok().and_then(|m| m.accuracy).expect("accuracy");
    // BVH and the brute-force reference give the same answers, bit for bit.
    let bvh = acc(find(&results.rows, Knob::Backend, "bvh 30, culling on"));
    assert_eq!(bvh.max_error_m, 0.0, "BVH differs from the reference backend: {bvh:?}");
    // Denser nodes: 150 a face is no worse than 8 a face (plus 0.1 mm slack).
    let e8 = acc(find(&results.rows, Knob::SourceNodes, "grid 8")).rms_error_m;
    assert!(e8 > 0.0, "8 nodes a face differ from 150 (else the sweep measures nothing)");
    // The contact actually happens in the reference run.
    let sref = find(&results.rows, Knob::Speed, "0.5 h/frame, culling on");
    assert!(acc(sref).reference_contact_frames > 0, "the spatula must touch the wall in the reference run");
    let crossed = |label: &str| find(&results.rows, Knob::Speed, label).outcome.as_ref().map(|m| m.crossed_total).unwrap_or(0);
    println!("crossed vertices at 5 thicknesses a frame: culling on {}, off {}", crossed("5 h/frame, culling on"), crossed("5 h/frame, culling off"));
    // What the monitor sees is reported, not forced: on this scene some wall vertices released
    // by the contact set spring back through the blade even slowly and culled (see the report).
    let slow = find(&results.rows, Knob::Speed, "0.5 h/frame, culling on").outcome.as_ref().expect("ran");
    assert!(slow.penetration_max_m < 0.5e-3 + 1e-9, "no vertex deeper than half the blade: {} m", slow.penetration_max_m);
}
