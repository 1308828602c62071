//! Ctrl-C on `fissure replay`: the frame under way finishes, metrics.csv keeps
//! every row, summary.json is written whole and says `"interrupted": true`,
//! and the process exits 130 (not 0), so a script or CI job can tell an
//! interrupted run from a finished one; also when the interruption comes
//! before the first frame (during the mesh build or the compliance precompute).

use crate::common;

use fissure::math::Vec3;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A block pressed by one blade (the replay scene of `hard_entrances.rs`),
/// `duration_s` long at 10 ms a frame.
fn write_block_scene(dir: &Path) -> PathBuf {
    let mesh = common::block(6, 6, 3, Vec3::new(40.0, 40.0, 20.0), Vec3::new(-20.0, -20.0, 0.0));
    common::write_mesh(dir, "block.msh", &mesh);
    std::fs::write(
        dir.join("press.csv"),
        "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0.0,0,-10.0,0.0,21.0,1.0,0.0,0.0,0.0\n0.1,0,-10.0,0.0,18.0,1.0,0.0,0.0,0.0\n",
    )
    .unwrap();
    let scene = dir.join("scene.ron");
    std::fs::write(
        &scene,
        r#"(
    name: "interrupt",
    mesh: File(path: "block.msh", units: Millimetres),
    material: (young_modulus_pa: 3000.0, poisson_ratio: 0.45),
    fixed: [LowestPerComponent(height_mm: 1.0)],
    spatulas: [(name: "blade", shape: (length_mm: 20.0, width_mm: 10.0, thickness_mm: 1.0), layout: Grid(along: 6, across: 3),
        pose: (position_mm: (-10.0, 0.0, 21.0), rotation: Quaternion(1.0, 0.0, 0.0, 0.0)), input: Trajectory)],
    effects: [Collision, Culling, ForceOutput, ContactPressure],
    solver: (compliance_storage: F64, region_of_interest: All, cache_dir: None),
    time_step_s: 0.01,
    duration_s: 10000.0,
    trajectory: Some("press.csv"),
)"#,
    )
    .unwrap();
    scene
}

fn replay(scenario: &Path, set: &[&str], out: &Path) -> Child {
    let mut c = Command::new(env!("CARGO_BIN_EXE_fissure"));
    c.current_dir(env!("CARGO_MANIFEST_DIR")).arg("replay").arg(scenario).arg("--out").arg(out);
    for s in set {
        c.args(["--set", s]);
    }
    c.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("start fissure replay")
}

fn rows(csv: &Path) -> usize {
    std::fs::read_to_string(csv).map(|t| t.lines().count().saturating_sub(1)).unwrap_or(0)
}

fn sigint(child: &Child) {
    // SAFETY: kill(2) on our own child's pid; no memory is involved.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    assert_eq!(r, 0, "kill(SIGINT) failed");
}

/// Waits (at most `limit`) and checks the interrupted run's outputs; returns the frames.
fn check_interrupted(child: Child, out: &Path, limit: Duration) -> u64 {
    let start = Instant::now();
    let mut child = child;
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("the replay did not stop within {limit:?} of Ctrl-C");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let output = child.wait_with_output().expect("output");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("stdout: {stdout}\nstderr: {stderr}");
    assert_eq!(output.status.code(), Some(130), "Ctrl-C must exit 130 (not 0, not killed by the signal): {:?}", output.status);
    assert!(stderr.contains("interrupted by Ctrl-C") && stderr.contains(&out.display().to_string()), "one line naming where the partial results are: {stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).expect("summary.json is written")).expect("summary.json parses");
    assert_eq!(summary["interrupted"], true, "{summary}");
    let frames = summary["frames"].as_u64().expect("frames");
    assert_eq!(frames as usize, rows(&out.join("metrics.csv")), "the summary counts exactly the rows in metrics.csv");
    frames
}

#[test]
fn ctrl_c_on_replay_writes_everything_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_block_scene(dir.path());
    let out = dir.path().join("out");
    let child = replay(&scene, &[], &out);
    let start = Instant::now();
    while rows(&out.join("metrics.csv")) < 5 {
        assert!(start.elapsed() < Duration::from_secs(120), "no frames after 2 minutes");
        std::thread::sleep(Duration::from_millis(10));
    }
    sigint(&child);
    let frames = check_interrupted(child, &out, Duration::from_secs(60));
    assert!((5..1_000_000).contains(&frames), "stopped part way: {frames} frames");
}

#[test]
fn ctrl_c_before_the_first_frame_exits_130_with_an_empty_run() {
    // The default scene without its cache: the phantom and its compliance take seconds to build.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let child = replay(Path::new("config/sylvian.ron"), &["solver.cache_dir=None", "duration_s=30"], &out);
    std::thread::sleep(Duration::from_millis(500));
    let before_frames = !out.join("metrics.csv").exists();
    sigint(&child);
    let frames = check_interrupted(child, &out, Duration::from_secs(300));
    if before_frames {
        assert_eq!(frames, 0, "interrupted while building: no frame is run");
    } else {
        println!("NOTE: the build finished within 0.5 s; interrupted after {frames} frames instead");
    }
}
