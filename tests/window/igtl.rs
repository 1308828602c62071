//! A third-party OpenIGTLink client drives a spatula in the window: pyigtl
//! streams TRANSFORM messages for the device the scenario binds to the frontal
//! spatula, the window's recording (the trajectory `fissure replay` plays)
//! shows the spatula at that pose, and the replay of the recording runs.
//!
//! Skips with a message when Xvfb or pyigtl is missing (CI installs both).

use crate::common;

use std::path::Path;
use std::process::{Command, Stdio};

fn fissure(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_fissure"));
    c.env("XDG_RUNTIME_DIR", dir).current_dir(env!("CARGO_MANIFEST_DIR"));
    let lvp = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json";
    if std::env::var_os("VK_DRIVER_FILES").is_none() && Path::new(lvp).exists() {
        c.env("VK_DRIVER_FILES", lvp).env("WGPU_BACKEND", "vulkan");
    }
    c
}

#[test]
fn a_pyigtl_client_moves_a_spatula_and_the_recording_shows_it() {
    let _one = crate::one_at_a_time();
    let pyigtl = Command::new("python3").args(["-c", "import pyigtl"]).output();
    if !pyigtl.map(|o| o.status.success()).unwrap_or(false) {
        common::skip("pyigtl is not importable (pip install pyigtl)");
        return;
    }
    let Some(x) = common::xvfb::xvfb_or_skip(140) else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let recording = dir.path().join("igtl.csv");
    let script = dir.path().join("script.txt");
    std::fs::write(&script, format!("0.0 record {}\n", recording.display())).expect("script");
    // A pose above the brain (no contact), identity rotation, in millimetres.
    let target = [-120.0, 10.0, 30.0];
    // A port free now, so that no other server on the machine (the default 18944 included) takes the client.
    let port = std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).expect("a free loopback port").port();
    let listen = format!("openigtlink.listen=\"127.0.0.1:{port}\"");
    let window = fissure(dir.path())
        .env("DISPLAY", &x.display)
        .args(["run", "config/sylvian.ron", "--set", "spatulas[0].input=OpenIgtLink(device: \"Frontal\")", "--set", &listen])
        .args(["--present-mode", "fifo", "--size", "320x200", "--frames", "800", "--no-haptics", "--script"])
        .arg(&script)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the window");
    let sender = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/igtl/stream_pose.py"))
        .args([port.to_string().as_str(), "Frontal"])
        .args(target.map(|v| v.to_string()))
        .arg("30")
        .output()
        .expect("run the pyigtl client");
    let out = window.wait_with_output().expect("window exit");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "window run failed:\n{stdout}\n{stderr}");
    assert!(!stderr.contains("headless instead"), "the window must open under Xvfb, not fall back: {stderr}");
    assert!(
        sender.status.success(),
        "the pyigtl client must connect and send: {}{}\nwindow:\n{stdout}\n{stderr}",
        String::from_utf8_lossy(&sender.stdout),
        String::from_utf8_lossy(&sender.stderr)
    );

    let trajectory = fissure::scenario::Trajectory::load(&recording).expect("the recording parses");
    let frontal = trajectory.samples(0);
    assert!(!frontal.is_empty(), "the recording has the frontal spatula's rows");
    let last = frontal.last().unwrap();
    for k in 0..3 {
        assert!((last.position_mm[k] - target[k]).abs() < 1e-3, "frontal ends at the streamed pose {target:?}, recorded {:?}", last.position_mm);
    }
    assert!((last.quaternion[0].abs() - 1.0).abs() < 1e-6, "identity rotation streamed, recorded {:?}", last.quaternion);
    // The scenario's own initial pose is elsewhere and rotated: the pose came from the client.
    let s = fissure::scenario::Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sylvian.ron"), &[]).unwrap();
    assert!((s.spatulas[0].initial_pose.position.z * 1e3 - target[2]).abs() > 10.0);

    // The recording replays headless.
    let replay = fissure(dir.path())
        .args(["replay", "config/sylvian.ron", "--trajectory"])
        .arg(&recording)
        .args(["--set", "duration_s=1.0", "--set", "solver.cache_dir=None", "--out"])
        .arg(dir.path().join("replay"))
        .output()
        .expect("replay");
    assert!(replay.status.success(), "replay of the IGTL recording: {}", String::from_utf8_lossy(&replay.stderr));
}
