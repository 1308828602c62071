//! The window under Xvfb: `fissure run` opens the default scene, a script
//! pushes the frontal spatula into the fissure with the keyboard map
//! (W: along the blade), starts recording mid-push, switches view and colour
//! (pressure, then strain from the background stress worker), and the run
//! stops after a set number of simulation frames with exit code 0. Then the
//! recording round trip: the recorded CSV's t = 0 is the moment recording
//! started, the session before it (from rest) comes first at negative times,
//! it ends at the window's final pose, and replayed headless (lead-in first)
//! gives the window's peak force.
//!
//! Skips with a message when `Xvfb` is not installed (CI installs `xvfb`).
//! Uses the software Vulkan driver and a private XDG_RUNTIME_DIR.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn fissure(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_fissure"));
    c.env("XDG_RUNTIME_DIR", dir).current_dir(env!("CARGO_MANIFEST_DIR"));
    if std::env::var_os("VK_DRIVER_FILES").is_none() {
        let lvp = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json";
        if Path::new(lvp).exists() {
            c.env("VK_DRIVER_FILES", lvp).env("WGPU_BACKEND", "vulkan");
        }
    }
    c
}

/// Runs `fissure` with `args` on the display `x` from `dir`; asserts exit 0; returns stdout and stderr.
fn run_window(dir: &Path, x: &common::xvfb::Xvfb, args: &[&std::ffi::OsStr]) -> (String, String) {
    let output = fissure(dir).env("DISPLAY", &x.display).args(args).output().expect("run fissure");
    let stdout = String::from_utf8_lossy(&output.stdout).to_string();
    let stderr = String::from_utf8_lossy(&output.stderr).to_string();
    assert!(output.status.success(), "the window run must exit 0:\nstdout {stdout}\nstderr {stderr}");
    (stdout, stderr)
}

fn line_after<'a>(text: &'a str, prefix: &str) -> Option<&'a str> {
    text.lines().find_map(|l| l.trim_start().strip_prefix(prefix))
}

#[test]
fn window_runs_scripted_frames_records_and_the_recording_replays_the_same_poses_and_forces() {
    let _one = crate::one_at_a_time();
    let Some(x) = common::xvfb::xvfb_or_skip(90) else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let recording: PathBuf = dir.path().join("rec.csv");
    let script = dir.path().join("script.txt");
    std::fs::write(
        &script,
        format!(
            "1.0 record {}\n0.05 press W\n1.65 release W\n1.7 press E\n2.2 release E\n0.3 view microscope\n0.5 field pressure\n1.2 field strain\n",
            recording.display()
        ),
    )
    .expect("write script");
    let frames = 240;
    let frame_count = frames.to_string();
    let args = ["run", "config/sylvian.ron", "--present-mode", "fifo", "--size", "640x400", "--frames", &frame_count, "--script"];
    let report = dir.path().join("report.json");
    let mut args: Vec<&std::ffi::OsStr> = args.iter().map(std::ffi::OsStr::new).collect();
    args.extend([script.as_os_str(), std::ffi::OsStr::new("--report"), report.as_os_str()]);
    let (stdout, stderr) = run_window(dir.path(), &x, &args);
    assert!(!stderr.contains("running") || !stderr.contains("headless instead"), "the window must open under Xvfb, not fall back: {stderr}");
    assert!(stdout.contains(&format!("simulation: {frames} frames")), "the run stops after {frames} frames: {stdout}");
    let presented: u64 = line_after(&stdout, "window: ")
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .expect("a window line with the presented frame count");
    assert!(presented >= 1, "the window must present frames: {stdout}");
    // `--report`: the same figures as JSON, by name.
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).expect("the report")).expect("valid JSON");
    assert_eq!(json["presented"].as_u64(), Some(presented), "{json}");
    assert_eq!(json["sim_frames"].as_u64(), Some(frames as u64), "{json}");
    let (p50, p95, max) = (json["step_p50_ms"].as_f64(), json["step_p95_ms"].as_f64(), json["step_max_ms"].as_f64());
    assert!(p50.zip(p95).zip(max).is_some_and(|((a, b), c)| 0.0 < a && a <= b && b <= c), "{json}");
    assert!(json["adapter"].as_str().is_some_and(|a| !a.is_empty()) && json["fps"].as_f64().is_some(), "the adapter is named: {json}");
    assert_eq!(json["final_state"].as_str(), line_after(&stdout, "final state "), "{json}");
    assert!(stdout.contains("0 failed"), "no simulation frame may fail: {stdout}");
    // From 1.2 s the strain colour is shown; sylvian.ron has no StressField
    // stage, so its stress comes from the background worker.
    let strain_frames: u64 = line_after(&stdout, "strain colour from the background stress worker: ")
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .expect("a line counting the frames shown with background strain");
    assert!(strain_frames > 0, "the strain colour must get stress from the worker: {stdout}");

    // W held for 1.6 s at 10 mm/s moves the frontal blade 16 mm along +x (its
    // blade axis is world +x); E then lifts it 5 mm along its face normal.
    let frontal = line_after(&stdout, "frontal: final position_mm (").expect("frontal's final pose");
    let x_mm: f64 = frontal.split(',').next().and_then(|v| v.trim().parse().ok()).expect("x in mm");
    assert!((x_mm - (-117.09)).abs() < 1e-6, "frontal must end 16 mm deeper (-133.09 -> -117.09 mm), got {x_mm}");
    let hash = line_after(&stdout, "final state ").expect("final state hash").trim().to_string();

    // The recording: the rest poses and every frame of both spatulas, t = 0
    // at the frame recording started (1.0 s into the session, the script
    // fires at the frame reaching it), ending at the window's final pose.
    let trajectory = fissure::scenario::Trajectory::load(&recording).expect("the recording parses as a trajectory");
    assert_eq!(trajectory.samples(0).len(), frames + 1, "the rest row plus one row per frame for spatula 0");
    assert_eq!(trajectory.samples(1).len(), frames + 1, "the rest row plus one row per frame for spatula 1");
    let start = trajectory.start_time();
    assert!((start + 0.99).abs() < 1e-9, "the run-up starts at rest, 0.99 s before the press (the frame before 1.0 s), got {start}");
    for k in 0..2 {
        assert!(trajectory.samples(k).iter().any(|s| s.time_s == 0.0), "spatula {k}: a row at t = 0, the pose at the press");
    }
    let at_press = trajectory.sample(0, 0.0).expect("pose at the press");
    assert!(at_press.position.x * 1e3 > -133.09 + 9.0, "at the press W had pushed the frontal blade ~9.5 mm: {:?}", at_press.position * 1e3);
    let last = trajectory.samples(0).last().expect("rows");
    assert!((last.time_s - (frames as f64 * 0.01 + start)).abs() < 1e-9, "the last row is the last frame in recording time: {}", last.time_s);
    assert!((last.position_mm[0] - x_mm).abs() < 1e-9, "recorded last pose {:?} vs window {x_mm}", last.position_mm);

    // Replay it headless for the same frames (the run-up first, from rest).
    let out = dir.path().join("replay");
    let replay = fissure(dir.path())
        .args(["replay", "config/sylvian.ron", "--trajectory"])
        .arg(&recording)
        .args(["--set", &format!("duration_s={}", frames as f64 * 0.01), "--out"])
        .arg(&out)
        .output()
        .expect("run replay");
    let replay_out = String::from_utf8_lossy(&replay.stdout);
    assert!(replay.status.success(), "replay failed: {}", String::from_utf8_lossy(&replay.stderr));
    assert!(replay_out.contains(&format!("{frames} frames")), "replay plays the same frame count: {replay_out}");
    // The final-state hash is not compared: the window builds its region of
    // interest without knowing the future poses, the replay from the whole
    // recording, so K^-1 columns come from different (equally exact) paths and
    // differ in the last bits. Poses match exactly; forces to print precision.
    assert!(!hash.is_empty() && line_after(&replay_out, "final state ").is_some(), "both runs report a final state");
    assert!(replay_out.contains("frontal: peak force") && !replay_out.contains("frontal: peak force 0.000 N"), "the blade must have touched tissue so the replay check means something: {replay_out}");
    let window_peak: f64 = frontal.split("peak force ").nth(1).and_then(|v| v.split_whitespace().next()).and_then(|v| v.parse().ok()).expect("window peak force");
    let replay_peak: f64 = line_after(&replay_out, "frontal: peak force ").and_then(|v| v.split_whitespace().next()).and_then(|v| v.parse().ok()).expect("replay peak force");
    assert!((window_peak - replay_peak).abs() <= 0.0005 + 1e-12, "peak force: window {window_peak} N vs replay {replay_peak} N (replay prints 3 decimals)");
}

/// Ending a session with Ctrl+Q writes the session from rest as a recording, replays it and the scene's own
/// trajectory, and writes the debrief page beside the recording; the window stays open on the verdicts until the
/// timed exit, which waits for the debrief. The page's numbers are the replay's: the frontal blade's peak force in
/// the JSON is the window's.
#[test]
fn ctrl_q_ends_the_session_and_writes_its_debrief_beside_the_recording() {
    let _one = crate::one_at_a_time();
    let Some(x) = common::xvfb::xvfb_or_skip(90) else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let records = dir.path().join("recordings");
    let script = dir.path().join("script.txt");
    std::fs::write(&script, "0.05 press W\n1.65 release W\n1.7 press E\n2.2 release E\n2.3 keydown Ctrl+Q\n2.31 keyup Ctrl+Q\n")
        .expect("write script");
    // Ctrl+Q comes at 2.3 s of simulated time; the window's clock counts the scene's preparation too, which
    // takes seconds on a loaded machine: 8 s leave room for both (the window then waits on its debrief).
    let args = ["run", "config/sylvian.ron", "--present-mode", "fifo", "--size", "640x400", "--exit-after", "8", "--record-dir"];
    let mut args: Vec<&std::ffi::OsStr> = args.iter().map(std::ffi::OsStr::new).collect();
    args.extend([records.as_os_str(), std::ffi::OsStr::new("--script"), script.as_os_str()]);
    let (stdout, _) = run_window(dir.path(), &x, &args);
    let page = PathBuf::from(line_after(&stdout, "debrief ").expect("the run names its debrief page").trim());
    let recording = PathBuf::from(line_after(&stdout, "recorded ").expect("the session was written as a recording").trim());
    assert_eq!(page.parent(), recording.parent(), "the page is beside the recording");
    assert_eq!(recording.parent(), Some(records.as_path()), "the recording is in --record-dir");
    let stem = recording.file_stem().and_then(|s| s.to_str()).expect("stem").to_string();
    assert_eq!(page.file_name().and_then(|s| s.to_str()), Some(format!("{stem}_debrief.html").as_str()));
    let html = std::fs::read_to_string(&page).expect("the page");
    assert!(html.contains("<h1>Debrief: ") && html.contains("reference"), "a page against the reference");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(page.with_extension("json")).expect("json")).expect("valid JSON");
    assert!(json["reference"].as_str().is_some_and(|r| r.ends_with(&format!("{stem}_reference"))), "{}", json["reference"]);
    assert_eq!(json["interrupted"], serde_json::Value::Bool(false));
    // The whole session from rest: Ctrl+Q at 2.3 s, so about 230 frames (the window acts at its first frame after).
    let frames = json["frames"].as_u64().expect("frames");
    assert!((230..=240).contains(&frames), "the debrief covers the session from rest to Ctrl+Q: {frames} frames");
    let frontal = json["blades"].as_array().and_then(|b| b.iter().find(|b| b["name"] == "frontal")).expect("the frontal blade");
    let peak = frontal["metrics"].as_array().and_then(|m| m.iter().find(|m| m["key"] == "peak_force_n")).expect("peak force");
    let debrief_peak = peak["value"].as_f64().expect("a peak force");
    let window_peak: f64 = line_after(&stdout, "frontal: final position_mm (")
        .and_then(|l| l.split("peak force ").nth(1))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .expect("the window's peak force");
    assert!(window_peak > 0.01, "the blade must have pressed tissue so the comparison means something: {window_peak} N");
    assert!((debrief_peak - window_peak).abs() < 5e-4, "the debrief replays the session: peak {debrief_peak} N against the window's {window_peak} N");
    assert!(peak["reference"].as_f64().is_some_and(|r| r > 0.0), "judged against the careful trajectory's peak force: {peak}");
}
