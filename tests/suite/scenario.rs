//! Scenario files: the shipped configs validate, every bad input gives one
//! error naming the file (or `--set` argument), line, column and field, and
//! `--set` overrides are applied and validated like the file.

use std::path::{Path, PathBuf};

use fissure::geometry::NodeLayout;
use fissure::math::Vec3;
use fissure::scenario::{
    CollisionBackend, Effect, FixedRegion, InputBinding, MeshSource, Origin, Scenario, ScenarioError,
};

fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("config")
}

/// The Sylvian scene's text, its trajectory path made absolute so the text
/// can be written anywhere.
fn sylvian_text() -> String {
    let text = std::fs::read_to_string(config_dir().join("sylvian.ron")).expect("config/sylvian.ron is shipped");
    let relative = "\"../assets/trajectories/paper_fig14_sylvian.csv\"";
    assert!(text.contains(relative), "sylvian.ron plays {relative}");
    let absolute = config_dir().join("../assets/trajectories/paper_fig14_sylvian.csv");
    text.replacen(relative, &format!("{:?}", absolute.display().to_string()), 1)
}

/// 1-based line and column of the first occurrence of `needle` in `text`.
fn position_of(text: &str, needle: &str) -> (usize, usize) {
    let at = text.find(needle).unwrap_or_else(|| panic!("`{needle}` not in the text"));
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

/// Writes `text` as a scenario file and loads it.
fn load_text(text: &str) -> (tempfile::TempDir, PathBuf, Result<Scenario, ScenarioError>) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, text).expect("write scenario");
    let result = Scenario::load(&path, &[]);
    (dir, path, result)
}

/// Replaces `from` by `to` in the Sylvian scene, loads it, and checks the error
/// names the file, the line and column of `to`, the field, and the problem.
fn assert_bad(from: &str, to: &str, field: &str, problem: &str) {
    let text = sylvian_text();
    assert!(text.contains(from), "the Sylvian scene must contain `{from}`");
    let text = text.replacen(from, to, 1);
    let (_dir, path, result) = load_text(&text);
    let err = result.expect_err(&format!("`{to}` must be rejected"));
    let message = err.to_string();
    let location = err.location().unwrap_or_else(|| panic!("`{to}`: the error must carry a location: {message}"));
    assert_eq!(location.origin, Origin::File(path.clone()), "`{to}`: error must name the file: {message}");
    let (line, column) = position_of(&text, to);
    assert_eq!(location.line, line, "`{to}`: error must name line {line}: {message}");
    assert!(
        location.column >= column && location.column < column + to.len(),
        "`{to}`: the column must point inside `{to}` (columns {column}..{}): {message}",
        column + to.len()
    );
    assert!(message.contains(&format!("{}:{line}:", path.display())), "message must show file:line:column: {message}");
    assert_eq!(err.field(), Some(field), "`{to}`: field path in {message}");
    assert!(message.contains(problem), "`{to}`: message `{message}` should say `{problem}`");
}

#[test]
fn every_shipped_config_validates() {
    let mut count = 0;
    let mut entries: Vec<_> = std::fs::read_dir(config_dir()).expect("config/").map(|e| e.expect("entry").path()).collect();
    entries.sort();
    for path in entries.iter().filter(|p| p.extension().is_some_and(|e| e == "ron")) {
        let scenario = Scenario::load(path, &[]).unwrap_or_else(|e| panic!("{} must validate: {e}", path.display()));
        assert!(!scenario.spatulas.is_empty(), "{}: at least one spatula", path.display());
        count += 1;
    }
    for name in ["sylvian.ron", "interhemispheric.ron", "v_valley.ron", "u_shape.ron"] {
        assert!(entries.iter().any(|p| p.ends_with(name)), "config/{name} must be shipped");
    }
    assert!(count >= 4);
}

#[test]
fn sylvian_scene_is_converted_to_si() {
    let s = Scenario::load(&config_dir().join("sylvian.ron"), &[]).expect("valid");
    assert_eq!(s.mesh, MeshSource::Phantom { preset: "paper-12k".into() });
    assert_eq!(s.spatulas.len(), 2, "two spatulas open the Sylvian fissure");
    assert!(s.effects.contains(Effect::SkullSpheres) && s.skull.is_some(), "the default scene has skull spheres");
    assert!(!s.effects.contains(Effect::Gravity), "effects not listed are not in the set");
    let sp = &s.spatulas[0];
    assert!((sp.shape.thickness - 1.0e-3).abs() < 1e-15, "thickness 1 mm -> 1e-3 m, got {}", sp.shape.thickness);
    assert_eq!(sp.layout, NodeLayout::Grid { along: 15, across: 10 });
    let p = sp.initial_pose.position;
    assert!((p - Vec3::new(-0.13309, 0.0104115, -0.0105227)).norm() < 1e-15, "position in metres: {p:?}");
    // Blade along +x, face normal the fissure's normal (to the 9 digits of the file).
    let x = sp.initial_pose.transform_vector(&Vec3::x());
    let z = sp.initial_pose.transform_vector(&Vec3::z());
    let normal = Vec3::new(0.0, 0.343, 0.939).normalize();
    assert!((x - Vec3::x()).norm() < 1e-8 && (z - normal).norm() < 1e-3, "pose axes: x {x:?}, z {z:?}");
    assert!((s.body.material.young_modulus - 3000.0).abs() < 1e-12 && (s.body.material.poisson_ratio - 0.45).abs() < 1e-15);
    assert_eq!(s.fixed, vec![FixedRegion::RegionId(3)], "fixed near the brain stem");
    let containing = s.skull.and_then(|k| k.containing).expect("containing sphere");
    assert!((containing.radius - 0.101).abs() < 1e-15, "skull radius in m: {}", containing.radius);
    assert_eq!(s.collision.backend, CollisionBackend::Bvh);
    assert_eq!(s.step_count(), 500, "5 s at 10 ms");
}

#[test]
fn initial_poses_match_the_trajectories_at_time_zero() {
    // A scene whose spatulas jump at the first frame would open with a spike.
    for name in ["sylvian.ron", "interhemispheric.ron", "v_valley.ron", "u_shape.ron"] {
        let s = Scenario::load(&config_dir().join(name), &[]).expect("valid");
        let path = s.trajectory.as_ref().unwrap_or_else(|| panic!("{name} ships a trajectory"));
        let track = fissure::scenario::Trajectory::load(path).expect("trajectory loads");
        for (i, sp) in s.spatulas.iter().enumerate() {
            let start = track.sample(i, 0.0).unwrap_or_else(|| panic!("{name}: no track for spatula {i}"));
            let gap = (start.position - sp.initial_pose.position).norm();
            assert!(gap < 1e-9, "{name}: spatula {i} starts {gap} m away from its initial pose");
            let angle = start.rotation.angle_to(&sp.initial_pose.rotation);
            assert!(angle < 1e-6, "{name}: spatula {i} starts turned {angle} rad from its initial pose");
        }
    }
}

#[test]
fn look_at_builds_a_right_handed_frame() {
    let text = sylvian_text().replacen(
        "rotation: Quaternion(0.984727174, -0.174104545, 0.0, 0.0)",
        "rotation: LookAt(direction: (0.0, 0.0, -2.0), up: (1.0, 0.0, 0.3))",
        1,
    );
    let (_d, _p, r) = load_text(&text);
    let s = r.expect("valid LookAt");
    let pose = s.spatulas[0].initial_pose;
    let x = pose.transform_vector(&Vec3::x());
    let y = pose.transform_vector(&Vec3::y());
    let z = pose.transform_vector(&Vec3::z());
    assert!((x - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-12, "blade along the direction: {x:?}");
    assert!((z - Vec3::new(1.0, 0.0, 0.0)).norm() < 1e-12, "normal = up without its part along x: {z:?}");
    assert!((x.cross(&y) - z).norm() < 1e-12, "right-handed");
}

#[test]
fn misspelt_field_names_the_field_and_the_valid_keys() {
    assert_bad("thickness_mm: 1.0)", "thicknes_mm: 1.0)", "spatulas[0].shape.thicknes_mm", "expected one of `length_mm`, `width_mm`, or `thickness_mm`");
}

#[test]
fn wrong_type_names_the_field() {
    assert_bad("young_modulus_pa: 3000.0", "young_modulus_pa: \"soft\"", "material.young_modulus_pa", "Expected float");
}

#[test]
fn poisson_ratio_at_one_half_is_rejected() {
    assert_bad("poisson_ratio: 0.45", "poisson_ratio: 0.5", "material.poisson_ratio", "poisson_ratio must be in [0, 0.5), got 0.5");
}

#[test]
fn non_positive_young_modulus_is_rejected() {
    assert_bad("young_modulus_pa: 3000.0", "young_modulus_pa: 0.0", "material.young_modulus_pa", "must be in (0, 1e9] Pa (brain tissue: 1e2..1e4), got 0");
    assert_bad("young_modulus_pa: 3000.0", "young_modulus_pa: -5.0", "material.young_modulus_pa", "must be in (0, 1e9] Pa (brain tissue: 1e2..1e4), got -5");
}

#[test]
fn negative_radius_is_rejected() {
    assert_bad("radius_mm: 101.0", "radius_mm: -101.0", "skull.containing.radius_mm", "must be > 0, got -101");
    assert_bad("radius_mm: 23.2", "radius_mm: 0.0", "skull.excluding.radius_mm", "must be > 0, got 0");
    assert_bad("fixed: [RegionId(3)]", "fixed: [Sphere(center_mm: (0, 0, 0), radius_mm: -1.0)]", "fixed[0].radius_mm", "must be > 0, got -1");
}

#[test]
fn negative_thickness_is_rejected() {
    assert_bad("thickness_mm: 1.0)", "thickness_mm: -0.5)", "spatulas[0].shape.thickness_mm", "must be > 0");
}

#[test]
fn unknown_preset_lists_the_presets() {
    assert_bad("preset: \"paper-12k\"", "preset: \"paper-13k\"", "mesh.preset", "expected one of \"small\", \"paper-9k\"");
}

#[test]
fn skull_spheres_without_skull_is_rejected() {
    let text = sylvian_text();
    let start = text.find("    skull: Some((").expect("skull block");
    let end = start + text[start..].find("    )),\n").expect("end of skull block") + "    )),\n".len();
    let text = format!("{}{}", &text[..start], &text[end..]);
    let (_d, path, r) = load_text(&text);
    let err = r.expect_err("SkullSpheres without skull");
    let msg = err.to_string();
    let (line, _) = position_of(&text, "effects:");
    assert_eq!(err.location().map(|l| l.line), Some(line), "points at the effects line: {msg}");
    assert_eq!(err.field(), Some("effects[2]"), "{msg}");
    assert!(msg.contains("SkullSpheres needs") && msg.contains(&path.display().to_string()), "{msg}");
}

#[test]
fn missing_mesh_file_names_the_resolved_path() {
    assert_bad(
        "mesh: Phantom(preset: \"paper-12k\")",
        "mesh: File(path: \"no-such-brain.msh\", units: Millimetres)",
        "mesh.path",
        "no-such-brain.msh",
    );
}

#[test]
fn missing_scenario_file_names_it() {
    let path = Path::new("/nonexistent/fissure/scene.ron");
    let err = Scenario::load(path, &[]).expect_err("missing file");
    assert!(matches!(err, ScenarioError::Read { .. }), "{err:?}");
    assert!(err.to_string().contains("/nonexistent/fissure/scene.ron"), "{err}");
}

#[test]
fn syntax_error_names_line_and_column() {
    let text = sylvian_text().replacen("duration_s: 5.0,", "duration_s: 5.0 oops,", 1);
    let (_d, path, r) = load_text(&text);
    let err = r.expect_err("syntax error");
    let (line, _) = position_of(&text, "oops");
    let loc = err.location().expect("location");
    assert_eq!((loc.origin.clone(), loc.line), (Origin::File(path), line), "{err}");
}

#[test]
fn mesh_file_resolves_against_the_scenario_folder() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::create_dir(dir.path().join("meshes")).expect("mkdir");
    std::fs::write(dir.path().join("meshes/b.msh"), "not checked here").expect("write");
    let text = sylvian_text().replacen(
        "mesh: Phantom(preset: \"paper-12k\")",
        "mesh: File(path: \"meshes/b.msh\", units: Millimetres)",
        1,
    );
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, text).expect("write");
    let s = Scenario::load(&path, &[]).expect("valid");
    assert_eq!(s.mesh, MeshSource::File { path: dir.path().join("meshes/b.msh"), units: fissure::scenario::LengthUnit::Millimetres });
}

#[test]
fn overrides_change_values() {
    let path = config_dir().join("sylvian.ron");
    let sets = [
        "collision.backend=Gpu".to_string(),
        "material.poisson_ratio=0.49".to_string(),
        "spatulas[0].layout=Grid(along: 20, across: 4)".to_string(),
        "spatulas[1].pose.position_mm[2] = -7.5".to_string(),
        "effects=[Collision, Gravity]".to_string(),
        "density_kg_m3=1000".to_string(),
    ];
    let s = Scenario::load(&path, &sets).expect("overrides are valid");
    assert_eq!(s.collision.backend, CollisionBackend::Gpu);
    assert_eq!(s.body.material.poisson_ratio, 0.49);
    assert_eq!(s.spatulas[0].layout, NodeLayout::Grid { along: 20, across: 4 });
    assert!((s.spatulas[1].initial_pose.position.z + 0.0075).abs() < 1e-15);
    assert!(s.effects.contains(Effect::Gravity) && !s.effects.contains(Effect::SkullSpheres));
    assert_eq!(s.body.density, 1000.0, "an optional field absent from the file is inserted");
}

#[test]
fn overrides_are_validated_like_the_file() {
    let path = config_dir().join("sylvian.ron");
    let arg = "material.poisson_ratio=0.5".to_string();
    let err = Scenario::load(&path, std::slice::from_ref(&arg)).expect_err("nu = 0.5");
    let loc = err.location().expect("location");
    assert_eq!(loc.origin, Origin::Override(arg.clone()), "the error names the --set argument: {err}");
    assert_eq!(loc.column, 24, "column of the value inside the argument: {err}");
    assert_eq!(err.field(), Some("material.poisson_ratio"));

    let arg = "spatulas[0].shape.thickness_mm=thick".to_string();
    let err = Scenario::load(&path, &[arg]).expect_err("wrong type");
    assert!(err.to_string().contains("--set spatulas[0].shape.thickness_mm=thick"), "{err}");
}

#[test]
fn unknown_override_path_lists_the_valid_keys() {
    let path = config_dir().join("sylvian.ron");
    let err = Scenario::load(&path, &["colision.backend=Gpu".to_string()]).expect_err("typo");
    let msg = err.to_string();
    assert!(msg.contains("colision.backend=Gpu") && msg.contains("`colision`"), "{msg}");
    assert!(msg.contains("`collision`") && msg.contains("`spatulas`"), "the keys valid at the top level: {msg}");

    let err = Scenario::load(&path, &["collision.backnd=Gpu".to_string()]).expect_err("typo");
    assert!(err.to_string().contains("`backend`") && err.to_string().contains("`swept_culling`"), "{err}");

    let err = Scenario::load(&path, &["spatulas[5].name=x".to_string()]).expect_err("index");
    assert!(matches!(err, ScenarioError::Override { .. }) && err.to_string().contains("has 2 element"), "{err}");
}

#[test]
fn trajectory_input_needs_a_trajectory_with_that_track() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(
        dir.path().join("t.csv"),
        "# test\ntime_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,0,1,0,0,0\n1,0,10,0,0,1,0,0,0\n",
    )
    .expect("write");
    let base = sylvian_text().replacen("input: Keyboard", "input: Trajectory", 1);
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, &base).expect("write");
    let err = Scenario::load(&path, &["trajectory=None".to_string()]).expect_err("no trajectory given");
    assert_eq!(err.field(), Some("spatulas[0].input"), "{err}");

    let s = Scenario::load(&path, &["trajectory=\"t.csv\"".to_string()]).expect("valid with trajectory");
    assert_eq!(s.spatulas[0].input, InputBinding::Trajectory);
    assert_eq!(s.trajectory.as_deref(), Some(dir.path().join("t.csv").as_path()));

    let err = Scenario::load(&path, &["trajectory=\"t.csv\"".to_string(), "spatulas[1].input=Trajectory".to_string()])
        .expect_err("track 1 missing");
    assert!(err.to_string().contains("no rows for spatula 1"), "{err}");

    std::fs::write(dir.path().join("bad.csv"), "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,0,2,0,0,0\n").expect("write");
    let err = Scenario::load(&path, &["trajectory=\"bad.csv\"".to_string()]).expect_err("bad trajectory");
    assert!(err.to_string().contains("bad.csv:2:") && err.to_string().contains("unit"), "names the trajectory line: {err}");
}

#[test]
fn a_trajectory_with_a_track_past_the_spatulas_is_refused() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(dir.path().join("five.csv"), "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,0,1,0,0,0\n0,5,0,0,0,1,0,0,0\n").expect("write");
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, sylvian_text()).expect("write");
    let err = Scenario::load(&path, &["trajectory=\"five.csv\"".to_string()]).expect_err("spatula 5 in a two-spatula scene");
    assert_eq!(err.field(), Some("trajectory"), "{err}");
    assert!(err.to_string().contains("has rows for spatula 5, but the scene has 2 spatulas (indices 0..=1)"), "{err}");
}

#[test]
fn physical_ranges_are_refused_at_their_field() {
    let e = "must be in (0, 1e9] Pa (brain tissue: 1e2..1e4), got 1e300";
    assert_bad("young_modulus_pa: 3000.0", "young_modulus_pa: 1e300", "material.young_modulus_pa", e);
    assert_bad("poisson_ratio: 0.45", "poisson_ratio: -0.1", "material.poisson_ratio", "poisson_ratio must be in [0, 0.5), got -0.1");
    assert_bad("time_step_s: 0.01", "time_step_s: 5.0", "time_step_s", "at most duration_s / 10 = 0.5 s (a run of 5 s needs at least 10 steps), got 5");
    let text = sylvian_text().replacen("time_step_s: 0.01,", "time_step_s: 0.01, density_kg_m3: -1.0,", 1);
    let (_dir, _path, result) = load_text(&text);
    let err = result.expect_err("density -1");
    assert_eq!(err.field(), Some("density_kg_m3"));
    assert!(err.to_string().contains("density_kg_m3 must be in (0, 1e5] kg/m^3 (brain tissue: 1040), got -1"), "{err}");
}

#[test]
fn poisson_ratio_near_one_half_is_valid_with_a_locking_warning() {
    let text = sylvian_text().replacen("poisson_ratio: 0.45", "poisson_ratio: 0.4999999", 1);
    let line = 1 + text.lines().position(|l| l.contains("poisson_ratio: 0.4999999")).expect("the material line");
    let (_dir, path, result) = load_text(&text);
    let s = result.expect("nu = 0.4999999 is in range");
    assert_eq!(s.checks.warnings.len(), 1, "{:?}", s.checks.warnings);
    let w = s.checks.warnings[0].to_string();
    assert!(w.starts_with(&format!("{}:{line}:", path.display())), "the warning names file and line: {w}");
    assert!(w.contains("material.poisson_ratio: poisson_ratio 0.4999999 is above 0.49") && w.contains("lock volumetrically"), "{w}");
    let shipped = Scenario::load(&config_dir().join("sylvian.ron"), &[]).expect("valid");
    assert!(shipped.checks.warnings.is_empty(), "the shipped scene warns of nothing: {:?}", shipped.checks.warnings);
}

/// A storage the solver does not have is refused, naming the file, the line
/// and the storages there are.
#[test]
fn an_unknown_compliance_storage_names_the_choices() {
    let text = sylvian_text();
    let from = "compliance_storage: F64";
    assert!(text.contains(from), "the Sylvian scene must name its storage");
    let to = "compliance_storage: LowRank(digits: 8)";
    let text = text.replacen(from, to, 1);
    let (_dir, path, result) = load_text(&text);
    let err = result.expect_err("an unknown storage must be rejected");
    let message = err.to_string();
    let location = err.location().unwrap_or_else(|| panic!("the error must carry a location: {message}"));
    assert_eq!(location.origin, Origin::File(path.clone()), "the error must name the file: {message}");
    assert_eq!(location.line, position_of(&text, to).0, "the error must name the line: {message}");
    for part in ["LowRank", "F64", "F32"] {
        assert!(message.contains(part), "{message:?} lacks {part:?}");
    }
}

/// `display.pressure_max_mmhg` (the pressure colour bar's top) defaults to 30
/// mmHg, takes a value in [1, 1000], and a bad one or an unknown key under
/// `display` names the file, line and field; `outputs.record_dir` is kept as
/// written and may not be empty.
#[test]
fn display_pressure_scale_and_record_dir_validate() {
    let (_dir, _path, default) = load_text(&sylvian_text());
    let default = default.expect("the Sylvian scene loads");
    assert_eq!(default.display.pressure_max_mmhg, 30.0);
    assert_eq!(default.run.outputs.record_dir, None, "no record_dir: the user's data directory");
    let anchor = "outputs: (dir: \"out/sylvian\", vtk: false, frames: false),";
    let text = sylvian_text().replacen(anchor, "outputs: (dir: \"out/sylvian\", record_dir: \"my/recs\"),\n    display: (pressure_max_mmhg: 15.0),", 1);
    let (_dir, _path, set) = load_text(&text);
    let set = set.expect("valid display and record_dir");
    assert_eq!(set.display.pressure_max_mmhg, 15.0);
    assert_eq!(set.run.outputs.record_dir.as_deref(), Some(Path::new("my/recs")));
    assert_bad(anchor, "outputs: (dir: \"out\"), display: (pressure_max_mmhg: 0.5),", "display.pressure_max_mmhg", "must be in [1, 1000] mmHg, got 0.5");
    assert_bad(anchor, "outputs: (dir: \"out\", record_dir: \" \"),", "outputs.record_dir", "must not be empty");
    let text = sylvian_text().replacen(anchor, "display: (pressure_top: 20.0),", 1);
    let (_dir, path, result) = load_text(&text);
    let message = result.expect_err("an unknown key under display").to_string();
    assert!(message.contains(&path.display().to_string()) && message.contains("pressure_top"), "{message}");
}

/// `display.microscope` / `display.overview` name a camera (eye and target in
/// mm, field of view in degrees, default 25); an eye on the target or a field
/// of view outside [5, 120] degrees is refused naming the field.
#[test]
fn display_views_validate() {
    let anchor = "outputs: (dir: \"out/sylvian\", vtk: false, frames: false),";
    let text = sylvian_text()
        .replacen(anchor, "display: (microscope: Some((eye_mm: (-200.0, 10.0, 0.0), target_mm: (-70.0, 10.0, -11.0)))),", 1);
    let (_dir, _path, set) = load_text(&text);
    let v = set.expect("a valid microscope").display.views;
    assert!(v.overview.is_none());
    let m = v.microscope.expect("the named microscope");
    assert!((m.eye.x + 0.2).abs() < 1e-12 && (m.target.z + 0.011).abs() < 1e-12, "mm to m: {m:?}");
    assert!((m.fov_y_rad - 25f64.to_radians()).abs() < 1e-12, "default 25 degrees");
    assert_bad(
        anchor,
        "display: (overview: Some((eye_mm: (1.0, 2.0, 3.0), target_mm: (1.0, 2.0, 3.0)))),",
        "display.overview",
        "at least 1 mm apart",
    );
    assert_bad(
        anchor,
        "display: (microscope: Some((eye_mm: (0.0, 0.0, 100.0), target_mm: (0.0, 0.0, 0.0), fov_deg: 170.0))),",
        "display.microscope.fov_deg",
        "must be in [5, 120] degrees, got 170",
    );
}

/// `refine` (local boundary refinement) is read in SI; a non-positive edge,
/// an empty volume list or an inverted box is refused at its field; the mesh
/// the scene loads keeps every input node, has no boundary edge longer than
/// `edge_mm` inside the volume, and stays coarse outside it; and a
/// refinement past four times the nodes is refused naming `refine`.
#[test]
fn refine_validates_and_refines_the_loaded_mesh() {
    // The shipped scene names no `refine` (Auto): the field goes before its material.
    let anchor = "    material: (young_modulus_pa: 3000.0, poisson_ratio: 0.45),\n";
    let volume = "Box(min_mm: (-75.0, 0.0, -25.0), max_mm: (-55.0, 20.0, 0.0))";
    assert!(sylvian_text().contains(anchor) && !sylvian_text().contains("    refine:"), "sylvian.ron names its material and no refine");
    let text = sylvian_text().replacen(anchor, &format!("    refine: Some((edge_mm: 3.0, within: [{volume}])),\n{anchor}"), 1);
    let (_dir, _path, set) = load_text(&text);
    let s = set.expect("a valid refine");
    let fissure::scenario::RefineChoice::Given(r) = s.refine.clone() else { panic!("refine read: {:?}", s.refine) };
    assert!((r.edge - 0.003).abs() < 1e-15 && r.within.len() == 1, "mm to m: {r:?}");
    assert!(r.within[0].contains(&Vec3::new(-0.068, 0.01, -0.0117)), "the Sylvian entry is inside");

    let coarse = fissure::sim::scene_mesh::load_mesh(&Scenario::load(&config_dir().join("sylvian.ron"), &["refine=None".into()]).expect("valid")).expect("phantom");
    let fine = fissure::sim::scene_mesh::load_mesh(&s).expect("refined phantom");
    assert_eq!(fine.positions[..coarse.node_count()], coarse.positions[..], "every input node kept, same index");
    assert!(fine.node_count() > coarse.node_count() + 50, "{} -> {} nodes", coarse.node_count(), fine.node_count());
    assert!((fine.volume() - coarse.volume()).abs() < 1e-9 * coarse.volume(), "volume kept");
    let surface = fine.boundary();
    let (mut inside, mut longest_outside) = (0, 0.0_f64);
    for t in &surface.triangles {
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let (p, q) = (fine.positions[surface.vertices[t[i] as usize] as usize], fine.positions[surface.vertices[t[j] as usize] as usize]);
            if r.within[0].contains(&((p + q) * 0.5)) {
                inside += 1;
                assert!((p - q).norm() <= 0.003 + 1e-12, "a boundary edge in the box is {} mm", (p - q).norm() * 1e3);
            } else {
                longest_outside = longest_outside.max((p - q).norm());
            }
        }
    }
    assert!(inside > 100 && longest_outside > 0.004, "{inside} edges inside; longest outside {longest_outside} m");

    let with = |refine: &str| format!("    refine: {refine},\n{anchor}");
    assert_bad(anchor, &with(&format!("Some((edge_mm: 0.0, within: [{volume}]))")), "refine.edge_mm", "must be > 0, got 0");
    assert_bad(anchor, &with("Some((edge_mm: 1.0, within: []))"), "refine.within", "give at least one volume");
    assert_bad(
        anchor,
        &with("Some((edge_mm: 1.0, within: [Box(min_mm: (0.0, 0.0, 0.0), max_mm: (1.0, -1.0, 1.0))]))"),
        "refine.within[0].max_mm",
        "must exceed min_mm",
    );
    let everywhere = sylvian_text().replacen(anchor, &with("Some((edge_mm: 0.2, within: [Sphere(center_mm: (0.0, 0.0, 0.0), radius_mm: 500.0)]))"), 1);
    let (_dir, path, all) = load_text(&everywhere);
    let err = fissure::sim::scene_mesh::load_mesh(&all.expect("valid")).expect_err("0.2 mm everywhere is too many nodes");
    let message = err.to_string();
    assert!(message.contains(&path.display().to_string()) && message.contains("refine") && message.contains("give a larger edge length"), "{message}");
}

#[test]
fn the_pose_filter_defaults_to_the_tracker_and_refuses_non_physical_parameters() {
    let path = config_dir().join("sylvian.ron");
    let load = |set: &[&str]| Scenario::load(&path, &set.iter().map(|s| s.to_string()).collect::<Vec<_>>());
    // The shipped default scene: keyboard and gamepad, no filter.
    let s = load(&[]).expect("default scene");
    assert!(s.spatulas.iter().all(|sp| sp.filter.is_none()));
    // A tracker gets the One Euro filter with its defaults, unless the scene says Off.
    let s = load(&["spatulas[0].input=OpenIgtLink(device: \"S1\")"]).expect("tracker");
    let f = s.spatulas[0].filter.expect("Auto gives a tracker the filter");
    assert_eq!((f.min_cutoff_hz, f.beta_per_m, f.d_cutoff_hz), (1.0, 50.0, 1.0), "0.05 Hz per mm/s is 50 Hz per m/s");
    let s = load(&["spatulas[0].input=OpenIgtLink(device: \"S1\")", "spatulas[0].filter=Off"]).expect("off");
    assert!(s.spatulas[0].filter.is_none());
    let s = load(&["spatulas[1].filter=OneEuro(min_cutoff_hz: 2.5)"]).expect("explicit");
    assert_eq!(s.spatulas[1].filter.map(|f| (f.min_cutoff_hz, f.beta_per_m)), Some((2.5, 50.0)));
    for (set, field) in [
        ("spatulas[0].filter=OneEuro(min_cutoff_hz: 0.0)", "spatulas[0].filter.min_cutoff_hz"),
        ("spatulas[1].filter=OneEuro(beta_hz_per_mm_s: -1.0)", "spatulas[1].filter.beta_hz_per_mm_s"),
        ("spatulas[0].filter=OneEuro(d_cutoff_hz: 1e400)", "spatulas[0].filter.d_cutoff_hz"),
    ] {
        let e = load(&[set]).expect_err(set).to_string();
        assert!(e.contains(field), "{set}: {e}");
    }
    let e = load(&["spatulas[0].filter=Kalman"]).expect_err("unknown filter").to_string();
    assert!(e.contains("filter"), "{e}");
}

/// `refine: Auto` refines the scene's mesh, not the run's: the run's length
/// (`duration_s`, which a session's debrief sets to its recording's) and a
/// trajectory played in place of the scene's own (`replay --trajectory`, a
/// window's recording) leave the mesh node for node as it is. Otherwise a
/// recording's replay ran on other tissue than the window's session, and the
/// same motion sampled faster met a coarser mesh (a 5 mm a frame insertion gave
/// 20-50 % less force than a slow one because its shorter run refined less).
#[test]
fn refine_auto_refines_the_scene_whatever_is_played_on_it() {
    use fissure::sim::preflight::preflight;
    let path = config_dir().join("sylvian.ron");
    let whole = Scenario::load(&path, &[]).expect("default scene");
    let short = Scenario::load(&path, &["duration_s=0.15".into()]).expect("a short run");
    let dir = tempfile::tempdir().unwrap();
    let other = dir.path().join("elsewhere.csv");
    // Both blades straight down 20 mm, far from the scene's own path.
    std::fs::write(
        &other,
        "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0.0,0,-133.09,10.4115,-10.5227,1,0,0,0\n0.1,0,-133.09,10.4115,-30.5,1,0,0,0\n\
         0.0,1,-133.09,9.5885,-12.7773,1,0,0,0\n0.1,1,-133.09,9.5885,-32.7,1,0,0,0\n",
    )
    .unwrap();
    let reference = preflight(&whole, None).expect("valid").mesh.mesh;
    assert!(reference.node_count() > 12_383 + 1000, "the default scene is refined: {} nodes", reference.node_count());
    for (what, scenario, trajectory) in [("a 0.15 s run", &short, None), ("another trajectory", &whole, Some(other.as_path())), ("both", &short, Some(other.as_path()))] {
        let mesh = preflight(scenario, trajectory).expect("valid").mesh.mesh;
        assert_eq!((&mesh.positions, &mesh.tets), (&reference.positions, &reference.tets), "{what}: the scene's mesh");
    }
}

/// `refine: Auto`: where the blades reach along the scenario's
/// trajectory, every boundary edge is at most a quarter of the narrowest
/// blade's width; away from them the mesh is as it was; the refined mesh is
/// the same from one load to the next, and `refine: None` leaves the mesh
/// untouched. A scene with no trajectory and no region-of-interest sphere (one
/// driven by hand) is refined along the reach from the blades' first poses.
#[test]
fn refine_auto_refines_where_the_trajectory_takes_the_blades() {
    use fissure::sim::scene_mesh::{AUTO_REFINE_EDGES_ACROSS, auto_edge, load_mesh};
    let path = config_dir().join("sylvian.ron");
    assert_eq!(Scenario::load(&path, &[]).expect("default scene").refine, fissure::scenario::RefineChoice::Auto, "Auto unless the scene says otherwise");
    let auto = Scenario::load(&path, &["refine=Auto".into()]).expect("Auto");
    assert_eq!(auto.refine, fissure::scenario::RefineChoice::Auto);
    let edge = auto_edge(&auto);
    let narrowest = auto.spatulas.iter().map(|s| s.shape.width).fold(f64::INFINITY, f64::min);
    assert_eq!(edge, narrowest / AUTO_REFINE_EDGES_ACROSS);
    let off = load_mesh(&Scenario::load(&path, &["refine=None".into()]).expect("None")).expect("unrefined");
    let fine = load_mesh(&auto).expect("auto-refined");
    assert_eq!(fine.positions[..off.node_count()], off.positions[..], "every input node kept, same index");
    assert!(fine.node_count() > off.node_count(), "{} -> {} nodes", off.node_count(), fine.node_count());
    let again = load_mesh(&auto).expect("again");
    assert_eq!((again.positions.len(), &again.tets), (fine.positions.len(), &fine.tets), "deterministic");
    // Along each blade's centre line at the trajectory's last pose (within its
    // half width), every boundary edge is at most `edge`; 5 cm away they are longer.
    let last = fissure::sim::poses::TrajectoryPoses::for_scenario(&auto, None).expect("poses").samples(auto.duration, 1).pop().expect("a set");
    let blades: Vec<(Vec3, Vec3, f64)> = auto
        .spatulas
        .iter()
        .zip(&last)
        .map(|(s, p)| (p.transform_point(&Vec3::zeros()), p.transform_point(&Vec3::new(s.shape.length, 0.0, 0.0)), 0.5 * s.shape.width))
        .collect();
    let distance = |m: &Vec3, (a, b, _): &(Vec3, Vec3, f64)| {
        let ab = b - a;
        let s = ((m - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
        (m - (a + ab * s)).norm()
    };
    let surface = fine.boundary();
    let (mut near, mut longest_far) = (0, 0.0_f64);
    for t in &surface.triangles {
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let (p, q) = (fine.positions[surface.vertices[t[i] as usize] as usize], fine.positions[surface.vertices[t[j] as usize] as usize]);
            let mid = (p + q) * 0.5;
            if blades.iter().any(|b| distance(&mid, b) <= b.2) {
                near += 1;
                assert!((p - q).norm() <= edge + 1e-12, "an edge under a blade is {} mm (wanted <= {} mm)", (p - q).norm() * 1e3, edge * 1e3);
            } else if blades.iter().all(|b| distance(&mid, b) > 0.05) {
                longest_far = longest_far.max((p - q).norm());
            }
        }
    }
    assert!(near > 10 && longest_far > 1.5 * edge, "{near} edges under the blades; longest 5 cm away {} mm", longest_far * 1e3);
    // No trajectory and no sphere: refined where the blades can go from their
    // first poses (the tips pushed on by half a length), not elsewhere.
    let bare = Scenario::load(&path, &["refine=Auto".into(), "trajectory=None".into(), "spatulas[0].input=Keyboard".into(), "spatulas[1].input=Keyboard".into()]).expect("no trajectory");
    let by_hand = load_mesh(&bare).expect("bare");
    assert!(by_hand.node_count() > off.node_count(), "{} -> {} nodes", off.node_count(), by_hand.node_count());
    assert_eq!(by_hand.positions[..off.node_count()], off.positions[..], "every input node kept, same index");
    let start: Vec<(Vec3, Vec3, f64)> = bare
        .spatulas
        .iter()
        .map(|s| {
            let p = s.initial_pose;
            let tip = p.transform_point(&Vec3::new(s.shape.length, 0.0, 0.0));
            (tip, p.transform_point(&Vec3::new(1.5 * s.shape.length, 0.0, 0.0)), 0.5 * s.shape.width)
        })
        .collect();
    let surface = by_hand.boundary();
    let mut under = 0;
    for t in &surface.triangles {
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let (p, q) = (by_hand.positions[surface.vertices[t[i] as usize] as usize], by_hand.positions[surface.vertices[t[j] as usize] as usize]);
            if start.iter().any(|b| distance(&((p + q) * 0.5), b) <= b.2) {
                under += 1;
                assert!((p - q).norm() <= edge + 1e-12, "an edge ahead of a blade's first pose is {} mm", (p - q).norm() * 1e3);
            }
        }
    }
    assert!(under > 10, "{under} edges ahead of the blades' first poses");
}
