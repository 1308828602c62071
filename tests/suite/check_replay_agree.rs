//! `fissure check` and `fissure replay` accept and refuse the same scenarios:
//! a corpus of good and bad scenes on the `small` phantom (and a
//! two-block mesh), each written as a file into a temporary folder, goes
//! through `check` and through a short `replay`; both exit 0 or both refuse,
//! with the same last cause, which names the file (or the `--set` / trajectory
//! argument), the field and the problem. Also: every shipped config passes
//! `check`, and a warning shows in `check`'s output without refusing the scene.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use fissure::math::Vec3;

/// The short run `replay` plays (10 steps of 0.01 s).
const SHORT: &str = "duration_s=0.1";

fn fissure(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fissure")).args(args).current_dir(dir).output().expect("the fissure binary runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The last `caused by:` line of an error report (the problem itself), or the whole stderr.
fn cause(stderr: &str) -> String {
    stderr.lines().filter_map(|l| l.trim().strip_prefix("caused by: ")).next_back().unwrap_or(stderr).to_string()
}

/// Fields of a scene on the `small` phantom (region 3 is its brain stem), each
/// overridable by a case: two blades above the inter-hemispheric fissure
/// (entry (0, 0, 36.7) mm, normal +x), pointing down; the mesh as it is
/// (`refine: None`), so the counts a refusal quotes are the phantom's own.
struct Scene {
    mesh: String,
    material: String,
    fixed: String,
    skull: String,
    effects: String,
    gravity: String,
    density: String,
    time_step: String,
    trajectory: String,
    /// `solver.substep_travel`.
    substep_travel: String,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            mesh: r#"Phantom(preset: "small")"#.into(),
            material: "(young_modulus_pa: 3000.0, poisson_ratio: 0.45)".into(),
            fixed: "RegionId(3)".into(),
            skull: "None".into(),
            effects: "Collision, Culling, ForceOutput".into(),
            gravity: "(0.0, 0.0, -9.81)".into(),
            density: "1040.0".into(),
            time_step: "0.01".into(),
            trajectory: "None".into(),
            substep_travel: "Some(0.125)".into(),
        }
    }
}

impl Scene {
    fn text(&self) -> String {
        let blade = |name: &str, x: f64| {
            format!(
                "(name: \"{name}\", shape: (length_mm: 20.0, width_mm: 6.0, thickness_mm: 1.0), layout: Grid(along: 5, across: 3),\n     \
                 pose: (position_mm: ({x:?}, 0.0, 70.0), rotation: LookAt(direction: (0.0, 0.0, -1.0), up: (1.0, 0.0, 0.0))), input: Keyboard)"
            )
        };
        format!(
            "(\n    name: \"corpus\",\n    mesh: {},\n    refine: None,\n    material: {},\n    fixed: [{}],\n    skull: {},\n    spatulas: [\n    {},\n    {},\n    ],\n    \
             effects: [{}],\n    gravity_m_s2: {},\n    density_kg_m3: {},\n    time_step_s: {},\n    duration_s: 1.0,\n    trajectory: {},\n    \
             solver: (region_of_interest: Auto, cache_dir: None, substep_travel: {}),\n)\n",
            self.mesh,
            self.material,
            self.fixed,
            self.skull,
            blade("left", -2.5),
            blade("right", 2.5),
            self.effects,
            self.gravity,
            self.density,
            self.time_step,
            self.trajectory,
            self.substep_travel
        )
    }
}

/// Both blades 25 mm down in 1 s (0.25 mm a step), as trajectory rows; with
/// `jump_at`, each first jumps 6 mm outward (six thicknesses) in the 10 ms after it.
fn descent(jump_at: Option<f64>) -> String {
    let mut s = String::from("time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    // LookAt(direction: -z, up: +x) as a quaternion: a rotation of 90 degrees about +y.
    let q = "0.7071067811865476,0.0,0.7071067811865476,0.0";
    for (k, x) in [(0, -2.5), (1, 2.5)] {
        s.push_str(&format!("0.0,{k},{x},0.0,70.0,{q}\n"));
        let x = match jump_at {
            Some(t) => {
                let moved = x + 6.0 * (k as f64 * 2.0 - 1.0);
                s.push_str(&format!("{t},{k},{x},0.0,70.0,{q}\n{},{k},{moved},0.0,70.0,{q}\n", t + 0.01));
                moved
            }
            None => x,
        };
        s.push_str(&format!("1.0,{k},{x},0.0,45.0,{q}\n"));
    }
    s
}

/// What a case expects: `None` for a valid scene, else phrases the refusal must contain.
struct Case {
    name: &'static str,
    scene: Scene,
    /// Extra arguments to both commands (`--trajectory FILE`).
    extra: Vec<String>,
    refusal: Option<Vec<&'static str>>,
    /// Phrases `check` must print as a warning of a valid scene.
    warning: Vec<&'static str>,
}

fn case(name: &'static str, edit: impl FnOnce(&mut Scene), refusal: Option<Vec<&'static str>>) -> Case {
    let mut scene = Scene::default();
    edit(&mut scene);
    Case { name, scene, extra: Vec::new(), refusal, warning: Vec::new() }
}

fn corpus(dir: &Path) -> Vec<Case> {
    std::fs::write(dir.join("garbage.msh"), b"\x7fELF not a mesh \x00\x01\x02\n$Nodes\nthree\n").expect("write");
    std::fs::write(dir.join("descent.csv"), descent(None)).expect("write");
    std::fs::write(dir.join("jump.csv"), descent(Some(0.05))).expect("write");
    let mut five = descent(None);
    five.push_str("0.0,5,0.0,0.0,70.0,1.0,0.0,0.0,0.0\n");
    std::fs::write(dir.join("five.csv"), five).expect("write");
    // Two 20 mm blocks 10 mm apart, far below the blades: regions 1 and 2, two components.
    let block = |x: f64| common::block(2, 2, 2, Vec3::new(20.0, 20.0, 20.0), Vec3::new(x, -10.0, -100.0));
    common::write_mesh(dir, "two_blocks.msh", &common::scenes::merge(&[block(-25.0), block(5.0)]));
    let two_blocks = r#"File(path: "two_blocks.msh", units: Millimetres)"#;
    let skull = |containing: &str, excluding: &str| format!("Some((containing: {containing}, excluding: {excluding}))");
    // The small phantom's own skull landmarks (`fissure mesh phantom --preset small`).
    let containing = "Some((center_mm: (0.5, 0.1, -12.4), radius_mm: 100.8))";
    let excluding = "Some((center_mm: (20.0, 45.0, -68.6), radius_mm: 23.4))";
    let with_skull = "Collision, Culling, SkullSpheres, ForceOutput";

    let mut cases = vec![
        // valid
        case("plain", |_| {}, None),
        case("trajectory and skull", |s| {
            s.trajectory = r#"Some("descent.csv")"#.into();
            s.skull = skull(containing, excluding);
            s.effects = with_skull.into();
        }, None),
        case("gravity and stress", |s| s.effects = "Collision, Gravity, ForceOutput, StressField".into(), None),
        case("two components, each fixed", |s| {
            s.mesh = two_blocks.into();
            s.fixed = "LowestPerComponent(height_mm: 1.0)".into();
        }, None),
        case("skull given, not simulated", |s| s.skull = skull("Some((center_mm: (0.0, 0.0, 0.0), radius_mm: 10.0))", "None"), None),
        // refused by the ranges
        case("E = 1e300", |s| s.material = "(young_modulus_pa: 1e300, poisson_ratio: 0.45)".into(),
            Some(vec!["material.young_modulus_pa", "must be in (0, 1e9] Pa", "got 1e300"])),
        case("E = 0", |s| s.material = "(young_modulus_pa: 0.0, poisson_ratio: 0.45)".into(),
            Some(vec!["material.young_modulus_pa", "must be in (0, 1e9] Pa", "got 0"])),
        case("nu = 0.5", |s| s.material = "(young_modulus_pa: 3000.0, poisson_ratio: 0.5)".into(),
            Some(vec!["material.poisson_ratio", "must be in [0, 0.5)", "got 0.5"])),
        case("nu = -0.1", |s| s.material = "(young_modulus_pa: 3000.0, poisson_ratio: -0.1)".into(),
            Some(vec!["material.poisson_ratio", "must be in [0, 0.5)", "got -0.1"])),
        case("region nu = 0.5", |s| s.material = "(young_modulus_pa: 3000.0, poisson_ratio: 0.45, regions: [(id: 2, young_modulus_pa: 3000.0, poisson_ratio: 0.5)])".into(),
            Some(vec!["material.regions[0].poisson_ratio", "got 0.5"])),
        case("time step = duration", |s| s.time_step = "0.1".into(),
            Some(vec!["time_step_s", "at most duration_s / 10", "got 0.1"])),
        case("density = -1", |s| s.density = "-1.0".into(), Some(vec!["density_kg_m3", "must be in (0, 1e5] kg/m^3", "got -1"])),
        case("NaN gravity", |s| s.gravity = "(0.0, NaN, -9.81)".into(), Some(vec!["gravity_m_s2[1]", "must be a finite number, got NaN"])),
        case("missing mesh file", |s| s.mesh = r#"File(path: "missing.msh", units: Millimetres)"#.into(),
            Some(vec!["mesh.path", "file not found", "missing.msh"])),
        // refused once the mesh or the trajectory is read
        case("garbage mesh file", |s| s.mesh = r#"File(path: "garbage.msh", units: Millimetres)"#.into(),
            Some(vec!["mesh.path", "garbage.msh:1"])),
        case("a region id that selects nothing", |s| s.fixed = "RegionId(9)".into(),
            Some(vec!["fixed", "[RegionId(9)] select no node of the mesh", "region ids 1, 2, 3"])),
        case("a box that selects nothing", |s| s.fixed = "Box(min_mm: (200.0, 200.0, 200.0), max_mm: (300.0, 300.0, 300.0))".into(),
            Some(vec!["fixed", "Box(min_mm: (200, 200, 200), max_mm: (300, 300, 300))] select no node"])),
        case("everything fixed", |s| s.fixed = "Sphere(center_mm: (0.0, 0.0, 0.0), radius_mm: 1000.0)".into(),
            Some(vec!["fixed", "fix every node of the mesh (1188): nothing is left to move"])),
        case("a component without a fixed node", |s| {
            s.mesh = two_blocks.into();
            s.fixed = "RegionId(1)".into();
        }, Some(vec!["fixed", "mesh component 1 of 2", "has no fixed node"])),
        case("containing skull smaller than the brain", |s| {
            s.skull = skull("Some((center_mm: (0.0, 0.0, -12.4), radius_mm: 10.0))", "None");
            s.effects = with_skull.into();
        }, Some(vec!["skull.containing", "of 670 surface vertices of the mesh at rest lie outside the sphere", "the smallest containing sphere with this centre has radius 95.52 mm"])),
        case("excluding skull inside the brain", |s| {
            s.skull = skull(containing, "Some((center_mm: (0.0, 0.0, -12.4), radius_mm: 50.0))");
            s.effects = with_skull.into();
        }, Some(vec!["skull.excluding", "lie inside the sphere", "the largest excluding sphere with this centre has radius 10.40 mm"])),
        case("the scenario's trajectory has a track for spatula 5", |s| s.trajectory = r#"Some("five.csv")"#.into(),
            Some(vec!["trajectory", "has rows for spatula 5, but the scene has 2 spatulas (indices 0..=1)"])),
    ];
    let mut given = case("--trajectory has a track for spatula 5", |_| {}, Some(vec!["--trajectory", "five.csv has rows for spatula 5, but the scene has 2 spatulas"]));
    given.extra = vec!["--trajectory".into(), dir.join("five.csv").display().to_string()];
    cases.push(given);
    let mut broken = case("--trajectory that does not parse", |_| {}, Some(vec!["trajectory", "garbage.msh:1", "header"]));
    broken.extra = vec!["--trajectory".into(), dir.join("garbage.msh").display().to_string()];
    cases.push(broken);
    // valid, with a warning
    let mut locking = case("nu = 0.495", |s| s.material = "(young_modulus_pa: 3000.0, poisson_ratio: 0.495)".into(), None);
    locking.warning = vec!["material.poisson_ratio: poisson_ratio 0.495 is above 0.49", "lock volumetrically"];
    cases.push(locking);
    // With sub-steps (the default) the jump is split and needs no warning; without them it does.
    cases.push(case("a blade moves 6 mm in one step, split into sub-steps", |s| s.trajectory = r#"Some("jump.csv")"#.into(), None));
    let mut coarse = case(
        "a blade moves 6 mm in one step without sub-steps",
        |s| {
            s.trajectory = r#"Some("jump.csv")"#.into();
            s.substep_travel = "None".into();
        },
        None,
    );
    coarse.warning = vec!["time_step_s: the trajectory", "moves spatula 0 (\"left\") 6.000 mm in one step (the step ending at 0.060 s), more than its blade's thickness 1.000 mm"];
    cases.push(coarse);
    cases
}

#[test]
fn check_and_replay_accept_and_refuse_the_same_scenarios() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases = corpus(dir.path());
    let (mut valid, mut refused) = (0, 0);
    for (k, c) in cases.iter().enumerate() {
        let ron = c.scene.text();
        let path: PathBuf = dir.path().join(format!("case{k:02}.ron"));
        std::fs::write(&path, &ron).expect("write scene");
        let scene = path.display().to_string();
        let mut check_args = vec!["check", scene.as_str(), "--set", SHORT];
        check_args.extend(c.extra.iter().map(String::as_str));
        let out_dir = dir.path().join(format!("out{k:02}"));
        let out_str = out_dir.display().to_string();
        let mut replay_args = vec!["replay", scene.as_str(), "--set", SHORT, "--out", out_str.as_str()];
        replay_args.extend(c.extra.iter().map(String::as_str));
        let check = fissure(dir.path(), &check_args);
        let replay = fissure(dir.path(), &replay_args);
        let (check_err, replay_err) = (text(&check.stderr), text(&replay.stderr));
        let label = format!("case {k} `{}`", c.name);
        assert_eq!(
            check.status.success(),
            replay.status.success(),
            "{label}: check and replay must agree\n--- check (exit {:?}):\n{check_err}\n--- replay (exit {:?}):\n{replay_err}\n--- scene:\n{ron}",
            check.status.code(),
            replay.status.code()
        );
        match &c.refusal {
            None => {
                assert!(check.status.success(), "{label} is valid, check refused it:\n{check_err}\n{ron}");
                assert!(text(&check.stdout).contains("ok: the scenario is valid"), "{label}: {}", text(&check.stdout));
                assert!(out_dir.join("metrics.csv").is_file() && out_dir.join("summary.json").is_file(), "{label}: replay wrote its outputs");
                for phrase in &c.warning {
                    assert!(check_err.contains(&format!("warning: {}", scene)) && check_err.contains(phrase), "{label}: check warns `{phrase}` at the file: {check_err}");
                }
                if c.warning.is_empty() {
                    assert!(!check_err.contains("warning:"), "{label}: no warning expected: {check_err}");
                }
                valid += 1;
            }
            Some(phrases) => {
                assert_eq!(check.status.code(), Some(1), "{label}: check refuses with exit 1: {check_err}");
                let (a, b) = (cause(&check_err), cause(&replay_err));
                assert_eq!(a, b, "{label}: check and replay give the same reason");
                for phrase in phrases {
                    assert!(a.contains(phrase), "{label}: the refusal must say `{phrase}`: {a}");
                }
                // The scenario's problems name the file with line and column; the --trajectory ones the CSV.
                if c.extra.is_empty() {
                    let mut at = a.strip_prefix(&format!("{scene}:")).unwrap_or_default().splitn(3, ':');
                    let (line, column) = (at.next().and_then(|l| l.parse::<usize>().ok()), at.next().and_then(|c| c.parse::<usize>().ok()));
                    assert!(line.is_some_and(|l| l > 1) && column.is_some_and(|c| c > 1), "{label}: names the file, line and column: {a}");
                } else {
                    assert!(a.contains(".csv") || a.contains("garbage.msh"), "{label}: names the trajectory file: {a}");
                }
                refused += 1;
            }
        }
    }
    println!("{valid} valid and {refused} refused scenes: check and replay agree on each");
    assert!(valid >= 3 && refused >= 15, "the corpus holds good and bad scenes");
}

/// Every shipped scene passes `check` (config/*.ron, and config/real_brain/*.ron when its mesh is beside the checkout).
#[test]
fn every_shipped_config_passes_check() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut checked = 0;
    for folder in ["config", "config/real_brain"] {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(root.join(folder))
            .expect("config folder")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        paths.sort();
        for path in paths {
            let out = fissure(root, &["check", path.to_str().expect("utf-8 path")]);
            assert!(out.status.success(), "{} must pass check: {}", path.display(), text(&out.stderr));
            checked += 1;
        }
    }
    assert!(checked >= 5, "the shipped scenes were checked ({checked})");
}
