//! `fissure study --preset ci` (the `paper-9k` phantom, a subset of the
//! knobs, a short motion). Checks the outputs exist and are well formed (CSV
//! rows, decodable non-blank PNGs, a report with the paper's numbers and the
//! budget table), that accuracy behaves (one reference, exact against itself
//! and equalled by no run; BVH answers exactly like the brute-force backend;
//! bilateral contact without culling pulls tissue through a fast blade and
//! culling pulls less), and that the accuracy columns equal the committed
//! `docs/study/ci/report.md`; and that the README's study section is the
//! committed quick report's summary.

use fissure::study::output::{accuracy_cells, summary_section};
use fissure::study::plan::preset_plan;
use fissure::study::{Knob, RunRow, StudyPreset, load_scene, run_plan};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn find<'a>(rows: &'a [RunRow], knob: Knob, label: &str) -> &'a RunRow {
    rows.iter().find(|r| r.knob == Some(knob) && r.label == label).unwrap_or_else(|| panic!("no row {knob:?} {label}"))
}

#[test]
fn reduced_study_writes_its_outputs_and_accuracy_behaves() {
    let dir = tempfile::tempdir().expect("temp dir");
    let plan = preset_plan(StudyPreset::Ci, &[]);
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
        assert!(r.outcome.is_ok(), "{} {} failed: {:?}", r.knob.map_or("reference", |k| k.name()), r.label, r.outcome.as_ref().err());
    }

    // Files.
    let csv = std::fs::read_to_string(dir.path().join("results.csv")).expect("results.csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), total + 1, "header + one row a run");
    assert!(lines[0].starts_with("knob,label,value,reference,"));
    assert!(lines.iter().skip(1).all(|l| !l.contains("failed")), "no failed run in the CSV");
    let report = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
    for needle in ["For this much accuracy, this much time", "160 ms (GPU)", "2000 ms (CPU)", "700 ms", "## Sweep: speed", "## Sweep: contact", "| 16 ms |"] {
        assert!(report.contains(needle), "report.md lacks `{needle}`");
    }
    for stem in ["pareto", "knobs", "budget", "fig13_collision_vs_nodes", "speed_vs_error", "force_path"] {
        let png = dir.path().join(format!("{stem}.png"));
        let img = image::open(&png).unwrap_or_else(|e| panic!("{} does not decode: {e}", png.display())).to_rgb8();
        let first = *img.get_pixel(0, 0);
        let differing = img.pixels().filter(|p| **p != first).count();
        assert!(differing > (img.width() * img.height()) as usize / 100, "{stem}.png is (nearly) blank: {differing} non-background pixels");
        let svg = std::fs::read_to_string(dir.path().join(format!("{stem}.svg"))).expect("svg");
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"), "{stem}.svg is an SVG document");
    }

    // Each ordered knob's runs against the sweep's finest (the knob alone):
    // the finest reads exact, the report says it under the sweep.
    for knob in [Knob::SourceNodes, Knob::Speed] {
        let rows: Vec<&RunRow> = results.rows.iter().filter(|r| r.knob == Some(knob)).collect();
        let finest = knob.finest(&rows.iter().map(|r| r.value).collect::<Vec<_>>()).expect("an ordered knob");
        for (i, r) in rows.iter().enumerate() {
            let e = r.outcome.as_ref().ok().and_then(|m| m.against_finest).unwrap_or_else(|| panic!("{} against the sweep's finest", r.label));
            assert!(e.0 >= 0.0 && e.0 <= e.1, "{}: {e:?}", r.label);
            if i == finest {
                assert_eq!(e, (0.0, 0.0), "the finest against itself");
            }
        }
        assert!(report.contains(&format!("finest setting ({})", rows[finest].label)), "report.md names the {} sweep's finest", knob.name());
    }
    assert!(results.rows.iter().filter(|r| r.knob == Some(Knob::Backend)).all(|r| r.outcome.as_ref().is_ok_and(|m| m.against_finest.is_none())), "backends have no order");

    // Accuracy: one reference, exact against itself, and no other run equals it.
    let references: Vec<&RunRow> = results.rows.iter().filter(|r| r.is_reference()).collect();
    assert_eq!(references.len(), 1, "one reference for the whole study");
    let a = references[0].outcome.as_ref().ok().and_then(|m| m.accuracy).expect("reference has accuracy");
    assert_eq!((a.rms_error_m, a.max_error_m, a.force_rms_pct, a.force_max_pct, a.pressure_error_mmhg), (0.0, 0.0, 0.0, 0.0, 0.0));
    assert!(a.frames_compared > 0);
    assert_eq!(a.force_points, a.frames_compared, "the reference's force is compared at each of its frames");
    for r in results.rows.iter().filter(|r| !r.is_reference()) {
        let a = r.outcome.as_ref().ok().and_then(|m| m.accuracy).expect("every run is compared");
        assert!(a.rms_error_m > 0.0, "{} {} is not the reference but has error 0", r.knob.map_or("", |k| k.name()), r.label);
    }
    let acc = |r: &RunRow| r.outcome.as_ref().ok().and_then(|m| m.accuracy).expect("accuracy");
    // BVH and the brute-force reference give the same answers, bit for bit.
    let (bvh, brute) = (acc(find(&results.rows, Knob::Backend, "bvh 30")), acc(find(&results.rows, Knob::Backend, "reference 30")));
    assert_eq!(bvh, brute, "BVH and the reference backend must give the same answers");
    // Denser nodes: 150 a face is no worse than 8 a face (plus 0.1 mm slack).
    let e8 = acc(find(&results.rows, Knob::SourceNodes, "grid 8")).rms_error_m;
    assert!(e8 > 0.0, "8 nodes a face differ from 150 (else the sweep measures nothing)");
    // The contact actually happens in the reference run.
    let sref = find(&results.rows, Knob::Speed, "0.5 h/frame");
    assert!(acc(sref).reference_contact_frames > 0, "the spatula must touch the wall in the reference run");
    // A faster blade has fewer frames, and its force is judged at the reference's frames between them too.
    let fastest = results.rows.iter().filter(|r| r.knob == Some(Knob::Speed)).max_by(|a, b| a.value.total_cmp(&b.value)).expect("speed runs");
    let f = acc(fastest);
    assert!(f.force_points > f.frames_compared, "{}: force compared at {} points, frames shared {}", fastest.label, f.force_points, f.frames_compared);
    // The paper's point: without culling, bilateral contact pulls tissue through a fast blade; with it, not.
    let crossed = |label: &str| find(&results.rows, Knob::Contact, label).outcome.as_ref().map(|m| m.crossed_total).unwrap_or(0);
    assert!(crossed("bilateral, culling off, 5 h/frame") > 0, "bilateral contact without culling must pull tissue through");
    assert!(crossed("bilateral, culling on, 5 h/frame") < crossed("bilateral, culling off, 5 h/frame"), "culling pulls less tissue through");
    let slow = sref.outcome.as_ref().expect("ran");
    assert!(slow.penetration_max_m < 0.5e-3 + 1e-9, "no vertex deeper than half the blade: {} m", slow.penetration_max_m);

    // The committed report of this preset (docs/study/ci/report.md, made by
    // `fissure study --preset ci`) has the same accuracy columns to the printed
    // digits: a change of the answers shows here, and both reports are regenerated.
    let committed = std::fs::read_to_string(format!("{ROOT}/docs/study/ci/report.md")).expect("docs/study/ci/report.md");
    let (fresh, old) = (accuracy_cells(&report), accuracy_cells(&committed));
    assert!(!fresh.is_empty());
    assert_eq!(fresh, old, "the ci preset's accuracy columns differ from docs/study/ci/report.md: regenerate it and docs/study/quick (README says how)");
}

/// The README's study section is the committed quick report's summary, verbatim.
#[test]
fn readme_study_section_is_the_committed_quick_report() {
    let readme = std::fs::read_to_string(format!("{ROOT}/README.md")).expect("README.md");
    let quick = std::fs::read_to_string(format!("{ROOT}/docs/study/quick/report.md")).expect("docs/study/quick/report.md");
    let (a, b) = (summary_section(&readme).expect("README has the study summary markers"), summary_section(&quick).expect("the report has them"));
    assert_eq!(a, b, "README's study section differs from docs/study/quick/report.md: copy it again");
}

/// A plan whose reference mesh is finer than its base (what the `brain`
/// preset does with the real brains, here with two phantoms): the reference's
/// settings also run on the base mesh, every run on that mesh is measured
/// against that run as well, and the report and `results.csv` say so.
#[test]
fn a_finer_reference_mesh_brings_the_base_meshs_own_reference() {
    use fissure::scenario::CollisionBackend;
    use fissure::study::plan::{MeshChoice, PlanValues, RoiChoice, base_settings};
    use fissure::study::{Comparison, Motion, StudyPlan};
    let small = MeshChoice::Phantom("small".into());
    let values = PlanValues {
        base: base_settings(small.clone()),
        nodes: Vec::new(),
        tip_nodes: Vec::new(),
        meshes: vec![small.clone(), MeshChoice::Phantom("paper-9k".into())],
        speeds: vec![5.0],
        contact_speeds: Vec::new(),
        substeps: Vec::new(),
        substep_speed: 5.0,
        backends: Vec::new(),
        backend_nodes: Vec::new(),
        storage: false,
        roi_radii_m: Vec::new(),
        skull: false,
        refine: Vec::new(),
        reference_backend: CollisionBackend::Bvh,
        reference_roi: RoiChoice::Auto,
    };
    let mut plan = StudyPlan::from_values("two meshes", Motion { insert_m: 0.030, insert_step_m: 0.010, open_m: 0.010 }, &values);
    plan.retain_knobs(&[Knob::Speed]);
    assert_eq!(plan.run_count(), 3, "the reference, the mesh reference, one speed");
    let dir = tempfile::tempdir().expect("temp dir");
    let results = run_plan(&plan, &load_scene(None).expect("built-in study scene"), dir.path(), &mut |_| {}).expect("study runs");

    let own = results.mesh_reference.as_ref().expect("a mesh reference");
    assert_eq!(own.settings.mesh, small);
    let own_m = own.outcome.as_ref().expect("the mesh reference ran");
    let own_a = own_m.accuracy.expect("compared with the reference");
    assert!(matches!(own_a.comparison, Comparison::Probes(_)), "another mesh than the reference's: {:?}", own_a.comparison);
    assert!(own_a.force_rms_pct > 0.0, "two meshes do not give the same force");
    let run = find(&results.rows, Knob::Speed, "5 h/frame").outcome.as_ref().expect("the speed run");
    let against = run.against_mesh_reference.expect("a run on the base mesh is measured against its mesh reference");
    assert_eq!(against.comparison, Comparison::PerVertex, "the same mesh: vertex by vertex");
    assert!(against.force_rms_pct > 0.0, "a faster blade is not the finest setting");
    let reference = results.rows.iter().find(|r| r.is_reference()).and_then(|r| r.outcome.as_ref().ok()).expect("the reference ran");
    assert!(reference.against_mesh_reference.is_none(), "the reference is on the finer mesh");

    let report = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
    assert!(report.contains("The mesh's share: the reference's settings on small instead of paper-9k"), "{report}");
    assert!(report.contains("On small against its own finest settings"), "{report}");
    let csv = std::fs::read_to_string(dir.path().join("results.csv")).expect("results.csv");
    assert_eq!(csv.lines().count(), plan.run_count() + 1, "header + one row a run, the mesh reference included");
    assert!(csv.lines().any(|l| l.starts_with("mesh_reference,")), "{csv}");
}
