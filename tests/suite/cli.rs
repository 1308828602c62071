//! The built `fissure` binary: `check` (good, bad, `--set`), the bare command,
//! and each `mesh` subcommand, run as a user would.

use std::path::Path;
use std::process::{Command, Output};

use crate::common;
use common::fissure;

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn json_of(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("stdout is JSON ({e}): {}", text(&out.stdout)))
}

#[test]
fn check_accepts_every_shipped_scene() {
    for name in ["sylvian", "interhemispheric", "v_valley", "u_shape"] {
        let path = format!("config/{name}.ron");
        let out = fissure(&["check", &path]);
        assert!(out.status.success(), "check {path} must pass: {}", text(&out.stderr));
        assert!(text(&out.stdout).contains("ok: the scenario is valid"), "summary for {path}: {}", text(&out.stdout));
    }
}

/// `check` says what `refine: Auto` (the default scene's, which names no
/// `refine`) added and where: along the trajectory's reach, or, for a scene
/// driven by hand, from the blades' first poses; `refine: None` adds nothing
/// and says nothing of it.
#[test]
fn check_says_what_refinement_added_and_where() {
    let added = |args: &[&str]| {
        let out = fissure(args);
        assert!(out.status.success(), "check {args:?}: {}", text(&out.stderr));
        let summary = text(&out.stdout);
        let line = summary.lines().find(|l| l.trim_start().starts_with("refined:")).map(str::to_string);
        let nodes = |key: &str| -> usize {
            let l = summary.lines().find(|l| l.trim_start().starts_with(key)).unwrap_or_else(|| panic!("{key} in {summary}"));
            l.split_whitespace().nth(1).and_then(|n| n.parse().ok()).unwrap_or_else(|| panic!("a count in {l}"))
        };
        (line, nodes("built:"))
    };
    let (none, file) = added(&["check", "config/sylvian.ron", "--set", "refine=None"]);
    assert_eq!(none, None, "refine: None adds nothing");
    let (traj, along) = added(&["check", "config/sylvian.ron"]);
    assert_eq!(added(&["check", "config/sylvian.ron", "--set", "refine=Auto"]), (Some(traj.clone().expect("a refined line")), along), "the default is Auto");
    let traj = traj.expect("a refined line");
    assert!(traj.contains(&format!("{} nodes added to the file's {file}", along - file)) && traj.contains("over the trajectory"), "{traj}");
    let by_hand = ["--set", "trajectory=None", "--set", "spatulas[0].input=Keyboard", "--set", "spatulas[1].input=Keyboard"];
    let (hand, _) = added(&[&["check", "config/sylvian.ron", "--set", "refine=Auto"][..], &by_hand[..]].concat());
    let hand = hand.expect("a refined line");
    assert!(hand.contains("from their first poses"), "{hand}");
    // Blades so narrow that a quarter of their width would pass the node
    // limit: Auto takes half as many edges across, or leaves the mesh, and
    // says so as a warning on `refine`; the scene stays valid.
    let narrow = |w: &str| {
        let (a, b) = (format!("spatulas[0].shape.width_mm={w}"), format!("spatulas[1].shape.width_mm={w}"));
        let out = fissure(&["check", "config/sylvian.ron", "--set", "refine=Auto", "--set", &a, "--set", &b]);
        assert!(out.status.success(), "narrow blades ({w} mm) stay valid: {}", text(&out.stderr));
        (text(&out.stdout), text(&out.stderr))
    };
    let (summary, warning) = narrow("1.0");
    assert!(warning.contains("refine: Auto refined to 0.500 mm edges (2 across the narrowest blade), not 0.250 mm"), "{warning}");
    assert!(!summary.contains(" 0 nodes added"), "{summary}");
    let (summary, warning) = narrow("0.5");
    assert!(warning.contains("refine: Auto left the mesh as it is") && warning.contains("refine: None"), "{warning}");
    assert!(summary.contains(&format!(" 0 nodes added to the file's {file}")), "{summary}");
}

#[test]
fn check_rejects_a_bad_scene_naming_file_line_and_field() {
    let dir = tempfile::tempdir().expect("tmp");
    let original = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/v_valley.ron")).expect("read");
    let bad = original
        .replacen("poisson_ratio: 0.45", "poisson_ratio: 0.5", 1)
        .replacen("\"../assets/", &format!("\"{}/assets/", env!("CARGO_MANIFEST_DIR")), 1);
    let path = dir.path().join("bad.ron");
    std::fs::write(&path, &bad).expect("write");
    let line = bad[..bad.find("poisson_ratio: 0.5").expect("edited")].matches('\n').count() + 1;
    let out = fissure(&["check", path.to_str().expect("utf-8 path")]);
    assert!(!out.status.success(), "nu = 0.5 must fail");
    let err = text(&out.stderr);
    assert!(err.contains(&format!("{}:{line}:", path.display())), "stderr names file and line {line}: {err}");
    assert!(err.contains("material.poisson_ratio") && err.contains("[0, 0.5)"), "stderr names field and range: {err}");
}

#[test]
fn check_applies_and_validates_overrides() {
    let out = fissure(&["check", "config/sylvian.ron", "--set", "collision.backend=Gpu", "--set", "material.poisson_ratio=0.49"]);
    assert!(out.status.success(), "valid overrides: {}", text(&out.stderr));
    let summary = text(&out.stdout);
    assert!(summary.contains("collision: Gpu") && summary.contains("nu = 0.49"), "overrides show in the summary: {summary}");

    let out = fissure(&["check", "config/sylvian.ron", "--set", "material.poisson_ratio=0.7"]);
    assert!(!out.status.success(), "nu = 0.7 must fail");
    assert!(text(&out.stderr).contains("--set material.poisson_ratio=0.7"), "names the argument: {}", text(&out.stderr));

    let out = fissure(&["check", "config/sylvian.ron", "--set", "solver.backend=Gpu"]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("`backend`") && err.contains("`compliance_storage`"), "unknown path lists valid keys: {err}");
}

#[test]
fn check_of_a_missing_file_fails_with_its_name() {
    let out = fissure(&["check", "config/no-such-scene.ron"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("config/no-such-scene.ron"), "{}", text(&out.stderr));
}

#[test]
fn bare_fissure_without_a_display_runs_the_default_scene_headless() {
    // No DISPLAY / WAYLAND_DISPLAY: the window cannot open, so the default scene
    // (config/sylvian.ron) runs headless through the same pipeline and says so.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_fissure"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run fissure");
    assert!(out.status.success(), "bare fissure: {}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.contains("Sylvian fissure, two spatulas") && stdout.contains("500 frames"), "{stdout}");
    let stderr = text(&out.stderr);
    assert!(stderr.contains("no display (DISPLAY and WAYLAND_DISPLAY are unset)"), "it says what is missing: {stderr}");
    assert!(stderr.contains("headless instead"), "it says what happens instead: {stderr}");
    assert!(!stderr.contains(".rs:") && !stderr.contains("registry"), "no dependency's source location: {stderr}");
}

#[test]
fn mesh_phantom_info_and_convert_agree() {
    let dir = tempfile::tempdir().expect("tmp");
    let msh = dir.path().join("small.msh");
    let out = fissure(&["mesh", "phantom", "--preset", "small", "-o", msh.to_str().expect("path")]);
    assert!(out.status.success(), "phantom: {}", text(&out.stderr));
    assert!(text(&out.stdout).contains("landmarks"), "prints landmarks: {}", text(&out.stdout));
    assert!(msh.is_file(), "the phantom file is written");

    let info = fissure(&["mesh", "info", msh.to_str().expect("path"), "--json"]);
    assert!(info.status.success(), "info: {}", text(&info.stderr));
    let j = json_of(&info);
    for key in ["nodes", "tets", "surface_triangles", "components", "inverted", "min_dihedral_deg"] {
        assert!(j.get(key).is_some(), "mesh info --json has `{key}`: {j}");
    }
    assert_eq!(j["components"], 1, "the phantom is one body");
    assert_eq!(j["inverted"], 0);

    let vtu = dir.path().join("small.vtu");
    let conv = fissure(&["mesh", "convert", msh.to_str().expect("path"), vtu.to_str().expect("path")]);
    assert!(conv.status.success(), "convert: {}", text(&conv.stderr));
    let back = json_of(&fissure(&["mesh", "info", vtu.to_str().expect("path"), "--json"]));
    for key in ["nodes", "tets", "surface_triangles", "components"] {
        assert_eq!(back[key], j[key], "`{key}` survives .msh -> .vtu");
    }
}

#[test]
fn mesh_phantom_rejects_an_unknown_preset() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = fissure(&["mesh", "phantom", "--preset", "huge", "-o", dir.path().join("x.msh").to_str().expect("path")]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("paper-12k"), "lists the presets: {}", text(&out.stderr));
}

/// A closed cube surface, `side` mm, outward triangles, as OBJ text.
fn cube_obj(side: f64) -> String {
    let mut s = String::new();
    for k in 0..8 {
        let (x, y, z) = ((k & 1) as f64 * side, ((k >> 1) & 1) as f64 * side, ((k >> 2) & 1) as f64 * side);
        s.push_str(&format!("v {x} {y} {z}\n"));
    }
    // Faces as quads (1-based), counter-clockwise seen from outside.
    for [a, b, c, d] in [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]] {
        s.push_str(&format!("f {a} {b} {c}\nf {a} {c} {d}\n"));
    }
    s
}

#[test]
fn mesh_tetrahedralize_fills_a_closed_surface() {
    let dir = tempfile::tempdir().expect("tmp");
    let obj = dir.path().join("cube.obj");
    std::fs::write(&obj, cube_obj(20.0)).expect("write");
    let msh = dir.path().join("cube.msh");
    let out = fissure(&["mesh", "tetrahedralize", obj.to_str().expect("path"), "-o", msh.to_str().expect("path"), "--edge", "5mm"]);
    assert!(out.status.success(), "tetrahedralize: {}", text(&out.stderr));
    let j = json_of(&fissure(&["mesh", "info", msh.to_str().expect("path"), "--json"]));
    assert!(j["tets"].as_u64().unwrap_or(0) > 0 && j["components"] == 1, "one filled body: {j}");
    let min_dihedral = j["min_dihedral_deg"].as_f64().expect("number");
    assert!(min_dihedral >= 10.0, "isosurface stuffing keeps its dihedral bound, got {min_dihedral}");

    let bad = fissure(&["mesh", "tetrahedralize", obj.to_str().expect("path"), "-o", msh.to_str().expect("path"), "--edge", "5"]);
    assert!(!bad.status.success() && text(&bad.stderr).contains("mm or m"), "an edge without a unit is refused: {}", text(&bad.stderr));
}

#[test]
fn mesh_info_on_garbage_names_the_file() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("broken.msh");
    std::fs::write(&path, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0\n").expect("write");
    let out = fissure(&["mesh", "info", path.to_str().expect("path")]);
    assert!(!out.status.success(), "a truncated mesh must fail");
    assert!(text(&out.stderr).contains("broken.msh"), "{}", text(&out.stderr));
}

#[test]
fn mesh_info_on_the_real_brains() {
    let path = fissure::mesh::brain::shipped(fissure::mesh::brain::COARSE);
    let out = fissure(&["mesh", "info", path.to_str().expect("path"), "--json"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let j = json_of(&out);
    assert_eq!((j["nodes"].as_u64(), j["tets"].as_u64()), (Some(25_757), Some(94_876)), "counts of the README: {j}");
    assert_eq!(j["components"], 2, "two hemispheres");
}

#[test]
fn mesh_info_on_a_fifo_or_a_device_fails_at_once_naming_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let fifo = dir.path().join("pipe.msh");
    let made = Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success());
    let zero = dir.path().join("zero.msh");
    std::os::unix::fs::symlink("/dev/zero", &zero).expect("symlink");
    let mut cases = vec![(zero, "a character device")];
    if made {
        cases.push((fifo, "a FIFO"));
    } else {
        println!("SKIP the FIFO case: mkfifo is not available");
    }
    for (path, what) in cases {
        // Before: a FIFO blocked in open() forever, /dev/zero was read for seconds.
        let start = std::time::Instant::now();
        let mut child = Command::new(env!("CARGO_BIN_EXE_fissure"))
            .args(["mesh", "info"])
            .arg(&path)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("start fissure");
        let status = loop {
            if let Some(s) = child.try_wait().expect("wait") {
                break s;
            }
            if start.elapsed() > std::time::Duration::from_secs(10) {
                let _ = child.kill();
                panic!("`fissure mesh info {}` still runs after 10 s", path.display());
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().expect("stderr"), &mut err).expect("stderr");
        println!("{} ({:.0} ms, {status}): {err}", path.display(), start.elapsed().as_secs_f64() * 1e3);
        assert_eq!(status.code(), Some(1), "refused with exit code 1: {err}");
        assert!(err.contains(&path.display().to_string()) && err.contains(what) && err.contains("not a regular file"), "{err}");
    }
}

#[test]
fn study_refuses_an_unknown_knob_and_a_mesh_that_does_not_load_before_any_run() {
    let dir = tempfile::tempdir().expect("tmp");
    let out_dir = dir.path().join("out");
    let out = fissure(&["study", "--knob", "skul", "--out", out_dir.to_str().expect("utf-8")]);
    assert!(!out.status.success(), "an unknown knob must fail");
    let err = text(&out.stderr);
    assert!(err.contains("--knob skul: unknown knob") && err.contains("skull"), "names the knob and the known ones: {err}");
    assert!(!out_dir.exists(), "nothing ran");

    let bad = dir.path().join("broken.msh");
    std::fs::write(&bad, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n").expect("write");
    let out = fissure(&["study", "--preset", "brain", "--mesh", bad.to_str().expect("utf-8"), "--out", out_dir.to_str().expect("utf-8")]);
    assert!(!out.status.success(), "a broken mesh must fail");
    let err = text(&out.stderr);
    assert!(err.contains("broken.msh"), "names the mesh: {err}");
    assert!(!out_dir.join("results.csv").exists(), "no run started");
}

#[test]
fn check_warns_when_a_blade_starts_inside_the_tissue() {
    // The U block's wall spans x = 8..30 mm and z = 0..30 mm; a blade pointing
    // down from z = 50 mm at x = 20 mm reaches z = 10 mm, 10 mm deep in it.
    let inside = ["spatulas[0].pose.position_mm=(20.0, 0.0, 50.0)", "trajectory=None", "spatulas[0].input=Keyboard"];
    let out = fissure(&["check", "config/u_shape.ron", "--set", inside[0], "--set", inside[1], "--set", inside[2]]);
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "a warning, not an error: {stderr}");
    assert!(stderr.contains("spatula 0 (\"spatula\") starts inside the tissue at its initial pose"), "{stderr}");
    assert!(stderr.contains("u_shape.ron:") && stderr.contains("spatulas[0]"), "names the file and the field: {stderr}");
    let depth: f64 = stderr.split("the deepest ").nth(1).and_then(|r| r.split(" mm").next()).and_then(|d| d.parse().ok()).expect("a depth");
    assert!((depth - 10.0).abs() < 0.6, "the tip is 10 mm from the wall's bottom and 12 from the channel: {depth} mm");
    assert!(text(&out.stdout).contains("(1 warning)"), "{}", text(&out.stdout));
    // The trajectory's first pose is checked too: this one starts 3 mm above the channel's mouth, outside.
    let out = fissure(&["check", "config/u_shape.ron"]);
    assert!(out.status.success() && !text(&out.stderr).contains("inside the tissue"), "{}", text(&out.stderr));
}

#[test]
fn no_shipped_scene_starts_a_blade_inside_the_tissue() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for scene in ["config/sylvian.ron", "config/interhemispheric.ron", "config/v_valley.ron", "config/real_brain/interhemispheric.ron", "config/real_brain/sylvian.ron"] {
        assert!(root.join(scene).is_file(), "{scene}");
        let out = fissure(&["check", scene]);
        assert!(out.status.success(), "{scene}: {}", text(&out.stderr));
        assert!(!text(&out.stderr).contains("inside the tissue"), "{scene}: {}", text(&out.stderr));
    }
}
