//! Keys through the window's own key handling under Xvfb (the script's
//! `keydown` / `keyup` go where a user's key would): 2 makes the temporal
//! blade (bound to the gamepad in the default scene) the active one and W
//! moves it; with the panel's text field focused W types instead of moving;
//! Esc gives the keys back and Tab moves on to the frontal blade, which E then
//! lifts. R with a recordings folder that cannot be created says so and the
//! session goes on.
//!
//! Window actions fire at the first drawn frame at or after their time, so
//! distances are checked to a few frames. Skips when Xvfb is not installed.

use crate::common;

use std::path::Path;
use std::process::Command;

fn final_position_mm(stdout: &str, name: &str) -> [f64; 3] {
    let line = stdout
        .lines()
        .find_map(|l| l.trim_start().strip_prefix(&format!("{name}: final position_mm (")))
        .unwrap_or_else(|| panic!("no final pose for {name}: {stdout}"));
    let inner = line.split(')').next().unwrap_or("");
    let v: Vec<f64> = inner.split(',').map(|c| c.trim().parse().expect("a number")).collect();
    [v[0], v[1], v[2]]
}

#[test]
fn keys_select_any_blade_esc_and_tab_take_the_keys_back_from_the_panel() {
    let _one = crate::one_at_a_time();
    let Some(x) = common::xvfb::xvfb_or_skip(90) else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let blocker = dir.path().join("not_a_folder");
    std::fs::write(&blocker, "a file where the recordings folder would go").expect("write");
    let script = dir.path().join("script.txt");
    std::fs::write(
        &script,
        "0.20 keydown 2\n0.21 keyup 2\n\
         0.30 keydown W\n1.10 keyup W\n\
         1.20 focus panel\n\
         1.30 keydown W\n1.90 keyup W\n\
         2.00 keydown Esc\n2.01 keyup Esc\n\
         2.05 keydown Tab\n2.06 keyup Tab\n\
         2.10 keydown E\n2.50 keyup E\n\
         2.60 keydown R\n2.61 keyup R\n",
    )
    .expect("write script");
    let mut c = Command::new(env!("CARGO_BIN_EXE_fissure"));
    c.env("XDG_RUNTIME_DIR", dir.path()).env("DISPLAY", &x.display).current_dir(env!("CARGO_MANIFEST_DIR"));
    if std::env::var_os("VK_DRIVER_FILES").is_none() && Path::new("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json").exists() {
        c.env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json").env("WGPU_BACKEND", "vulkan");
    }
    let output = c
        .args(["run", "config/sylvian.ron", "--present-mode", "fifo", "--size", "640x400", "--frames", "280", "--no-haptics", "--script"])
        .arg(&script)
        .arg("--record-dir")
        .arg(blocker.join("recordings"))
        .output()
        .expect("run fissure");
    let stdout = String::from_utf8_lossy(&output.stdout).to_string();
    let stderr = String::from_utf8_lossy(&output.stderr).to_string();
    assert!(output.status.success(), "the window run must exit 0:\nstdout {stdout}\nstderr {stderr}");
    assert!(stdout.contains("simulation: 280 frames"), "{stdout}\n{stderr}");

    // Temporal (bound to the gamepad): 2 made it active, W held ~0.8 s at 10
    // mm/s moved it ~8 mm along its blade (world +x). Had the W typed into the
    // panel's field reached it too, it would have moved ~14 mm.
    let temporal = final_position_mm(&stdout, "temporal");
    let dx = temporal[0] - (-133.09);
    assert!((5.5..=10.5).contains(&dx), "temporal must move ~8 mm with W after 2 (and not with the panel's W): moved {dx} mm\n{stdout}");
    // Frontal: Esc gave the keys back, Tab made it active, E lifted it ~4 mm
    // along its face normal (0, -0.34, 0.94): z up, x unchanged.
    let frontal = final_position_mm(&stdout, "frontal");
    assert!((frontal[0] - (-133.09)).abs() < 1e-9, "frontal must not move along x: {frontal:?}");
    let dz = frontal[2] - (-10.5227);
    assert!((2.5..=5.5).contains(&dz), "after Esc and Tab, E must lift frontal ~3.8 mm in z, got {dz} mm\n{stdout}");
    // R with a folder that cannot be created: said in the log, no crash, no file.
    assert!(stderr.contains("cannot record: cannot create the folder"), "the failure must be logged: {stderr}");
    assert!(!stdout.contains("recorded "), "nothing was recorded: {stdout}");
}
