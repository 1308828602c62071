//! `fissure plot`, run as a user would: a real replay (so the plot reads what
//! the replay writes) overlaid with a run written through the library's own
//! metrics writer (two blades, a pressure above 20 mmHg), at the asked and the
//! default size, as PNG and SVG; values that are NaN are skipped; every broken
//! input or unwritable output is an error that names the file, never a panic.

use std::path::{Path, PathBuf};

use fissure::math::Vec3;
use fissure::sim::metrics::{MetricsWriter, SummaryBuilder, write_summary};
use fissure::sim::report::PASCALS_PER_MMHG;
use fissure::sim::{FrameReport, SpatulaReport, StageId};

use crate::common;
use common::fissure;

/// A path as an argument (the temporary folders' paths are UTF-8).
fn s(path: &Path) -> String {
    path.display().to_string()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Width and height from a PNG's IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(bytes.len() > 24 && bytes.starts_with(b"\x89PNG\r\n\x1a\n") && &bytes[12..16] == b"IHDR", "{} is not a PNG", path.display());
    let be = |k: usize| u32::from_be_bytes(bytes[k..k + 4].try_into().unwrap());
    (be(16), be(20))
}

/// One blade's frame `k` of a retraction: the blade pushes in over the first
/// third, holds, and lets go; `peak_mmhg` is the plateau's mean pressure.
fn blade(k: usize, frames: usize, peak_n: f64, peak_mmhg: f64) -> SpatulaReport {
    let x = k as f64 / frames as f64;
    let level = (3.0 * x).min(1.0) * if x > 0.8 { (1.0 - x) / 0.2 } else { 1.0 };
    let wobble = 1.0 + 0.05 * (40.0 * x).sin();
    SpatulaReport {
        force: Vec3::new(0.0, peak_n * level * wobble, 0.0),
        contact_vertices: (60.0 * level).round() as u32,
        mean_pressure_pa: peak_mmhg * level * wobble * PASCALS_PER_MMHG,
        ..Default::default()
    }
}

/// A run directory written by the library's writers, as a replay writes it:
/// `frames` frames of 10 ms, one blade a name; `frame(k)` gives frame k's blades.
fn write_run(dir: &Path, scenario: &str, names: &[&str], frames: usize, frame: impl Fn(usize) -> Vec<SpatulaReport>) {
    std::fs::create_dir_all(dir).expect("run dir");
    let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
    let stages = [StageId::Collision, StageId::Solve, StageId::Forces];
    let mut metrics = MetricsWriter::create(&dir.join("metrics.csv"), &stages, &names).expect("metrics.csv");
    let mut summary = SummaryBuilder::new(scenario, &stages, &names);
    for k in 0..frames {
        let r = FrameReport { frame: k as u64, time_s: 0.01 * (k + 1) as f64, spatulas: frame(k), substeps: 1, ..Default::default() };
        metrics.write(&r).expect("a row");
        summary.add(&r, 0.01);
    }
    write_summary(&dir.join("summary.json"), &summary.finish("0".into(), false)).expect("summary.json");
}

/// Two blades over 3 s; the temporal one goes above 20 mmHg.
fn two_blade_run(dir: &Path) {
    write_run(dir, "Sylvian fissure, two spatulas", &["frontal", "temporal"], 300, |k| vec![blade(k, 300, 0.25, 14.0), blade(k, 300, 0.4, 27.0)]);
}

#[test]
fn a_real_replay_and_a_two_blade_run_overlay_into_a_png_of_the_asked_size() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (replayed, two) = (dir.path().join("u_shape"), dir.path().join("two_blades"));
    let (r, t) = (s(&replayed), s(&two));
    let out = fissure(&["replay", "config/u_shape.ron", "--set", "duration_s=0.5", "--out", &r]);
    assert!(out.status.success(), "replay: {}", text(&out.stderr));
    two_blade_run(&two);

    let png = dir.path().join("runs.png");
    let out = fissure(&["plot", &r, &t, "-o", &s(&png), "--size", "1200x900"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "plot: {}", text(&out.stderr));
    assert_eq!(png_size(&png), (1200, 900));
    // The replay's blade is found by the header the replay wrote: 50 frames of 10 ms.
    assert!(stdout.contains("u_shape: 50 frames") && stdout.contains("blades spatula"), "{stdout}");
    assert!(stdout.contains("two_blades: 300 frames") && stdout.contains("blades frontal, temporal"), "{stdout}");

    let default = dir.path().join("default.png");
    let out = fissure(&["plot", &t, "-o", &s(&default)]);
    assert!(out.status.success(), "plot: {}", text(&out.stderr));
    assert_eq!(png_size(&default), (1400, 1000), "the default size");

    let svg = dir.path().join("runs.svg");
    let out = fissure(&["plot", &r, &t, "-o", &s(&svg)]);
    assert!(out.status.success(), "plot: {}", text(&out.stderr));
    let drawing = std::fs::read_to_string(&svg).expect("an SVG");
    assert!(drawing.contains("<svg") && drawing.contains("fissure: force, pressure and contact against time"), "an SVG with the title");
    assert!(drawing.contains("retraction-injury line") && drawing.contains("frontal") && drawing.contains("u_shape"), "the danger line and the legend");
}

#[test]
fn later_runs_force_is_printed_against_the_first_runs() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (first, stronger, other) = (dir.path().join("fine"), dir.path().join("stronger"), dir.path().join("other_blades"));
    two_blade_run(&first);
    // The same blades 10 % stronger on the temporal one: its difference peaks at 10 % of its peak.
    write_run(&stronger, "Sylvian fissure, two spatulas", &["frontal", "temporal"], 300, |k| vec![blade(k, 300, 0.25, 14.0), blade(k, 300, 0.44, 27.0)]);
    write_run(&other, "one blade", &["spatula"], 10, |k| vec![blade(k, 10, 0.1, 5.0)]);
    let png = dir.path().join("runs.png");
    let out = fissure(&["plot", &s(&first), &s(&stronger), &s(&other), "-o", &s(&png)]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "plot: {}", text(&out.stderr));
    assert!(stdout.contains("force against fine, at its frames"), "{stdout}");
    let compared = stdout.split("force against").nth(1).unwrap_or_default();
    let line = compared.lines().find(|l| l.trim_start().starts_with("stronger:")).unwrap_or_else(|| panic!("{stdout}"));
    assert!(line.contains("frontal 0.00 / 0.00 % of 0.2") && line.contains("temporal") && line.contains("/ 10.00 % of 0.4"), "{line}");
    assert!(compared.contains("other_blades: no blade in common"), "{stdout}");
}

#[test]
fn values_that_are_nan_are_skipped_and_a_single_frame_is_drawn() {
    let dir = tempfile::tempdir().expect("temp dir");
    let gappy = dir.path().join("gappy");
    write_run(&gappy, "gaps", &["left", "right"], 200, |k| {
        let mut b = vec![blade(k, 200, 0.3, 22.0), blade(k, 200, 0.2, 10.0)];
        if (50..60).contains(&k) {
            b[0].force.x = f64::NAN;
            b[0].mean_pressure_pa = f64::NAN;
        }
        b
    });
    let text_of = |p: &Path| std::fs::read_to_string(p.join("metrics.csv")).unwrap();
    assert!(text_of(&gappy).contains("NaN"), "the writer writes NaN as NaN");
    let single = dir.path().join("single");
    write_run(&single, "one frame", &["only"], 1, |k| vec![blade(k + 50, 100, 0.3, 25.0)]);
    let png = dir.path().join("gaps.png");
    let out = fissure(&["plot", &s(&gappy), &s(&single), "-o", &s(&png)]);
    assert!(out.status.success(), "plot: {}", text(&out.stderr));
    assert_eq!(png_size(&png), (1400, 1000));
}

/// Replaces field `column` (by header name) of line `line` (1: the header) of `path`.
fn set_field(path: &Path, line: usize, column: &str, value: &str) {
    let csv = std::fs::read_to_string(path).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let k = lines[0].split(',').position(|c| c == column).unwrap_or_else(|| panic!("no column {column}"));
    let mut fields: Vec<&str> = lines[line - 1].split(',').collect();
    fields[k] = value;
    lines[line - 1] = fields.join(",");
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

#[test]
fn broken_runs_and_unwritable_outputs_are_errors_that_name_the_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = |name: &str| dir.path().join(name);
    let good = d("good");
    two_blade_run(&good);
    std::fs::create_dir_all(d("no_metrics")).unwrap();
    std::fs::create_dir_all(d("empty")).unwrap();
    std::fs::write(d("empty").join("metrics.csv"), "").unwrap();
    write_run(&d("header_only"), "h", &["a"], 0, |_| Vec::new());
    two_blade_run(&d("bad_number"));
    set_field(&d("bad_number").join("metrics.csv"), 3, "frontal_force_n", "0.1x");
    two_blade_run(&d("short_row"));
    let short = d("short_row").join("metrics.csv");
    let csv = std::fs::read_to_string(&short).unwrap();
    let cut: Vec<&str> = csv.lines().collect();
    std::fs::write(&short, format!("{}\n{}\n{}\n", cut[0], cut[1], &cut[2][..cut[2].len() / 2])).unwrap();
    std::fs::create_dir_all(d("not_metrics")).unwrap();
    std::fs::write(d("not_metrics").join("metrics.csv"), "a,b\n1,2\n").unwrap();
    two_blade_run(&d("bad_summary"));
    std::fs::write(d("bad_summary").join("summary.json"), "{\"scenario\": ").unwrap();

    let path = |p: PathBuf| s(&p);
    let png = path(d("out.png"));
    // (the run directories, the output, what stderr must say)
    let cases: Vec<(Vec<String>, String, Vec<String>)> = vec![
        (vec![path(d("nowhere"))], png.clone(), vec![path(d("nowhere")), "no such run directory".into()]),
        (vec![path(good.clone()), path(d("no_metrics"))], png.clone(), vec![path(d("no_metrics").join("metrics.csv"))]),
        (vec![path(d("empty"))], png.clone(), vec![path(d("empty").join("metrics.csv")), "empty".into()]),
        (vec![path(d("header_only"))], png.clone(), vec![path(d("header_only").join("metrics.csv")), "no frames".into()]),
        (vec![path(d("bad_number"))], png.clone(), vec![path(d("bad_number").join("metrics.csv")), "line 3".into(), "frontal_force_n".into(), "0.1x".into()]),
        (vec![path(d("short_row"))], png.clone(), vec![path(short.clone()), "line 3".into(), "fields".into()]),
        (vec![path(d("not_metrics"))], png.clone(), vec![path(d("not_metrics").join("metrics.csv")), "line 1".into(), "time_s".into()]),
        (vec![path(d("bad_summary"))], png.clone(), vec![path(d("bad_summary").join("summary.json"))]),
        (vec![path(good.join("metrics.csv"))], png.clone(), vec![path(good.join("metrics.csv")), "not a directory".into()]),
        (vec![path(good.clone())], path(d("no_such_folder").join("out.png")), vec![path(d("no_such_folder").join("out.png"))]),
        (vec![path(good.clone())], path(d("out.jpg")), vec![path(d("out.jpg")), ".png or .svg".into()]),
    ];
    for (runs, output, expected) in cases {
        let mut args = vec!["plot".to_string()];
        args.extend(runs.iter().cloned());
        args.extend(["-o".to_string(), output.clone()]);
        let out = fissure(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?} must fail with exit 1: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        for e in &expected {
            assert!(stderr.contains(e.as_str()), "{args:?}: stderr must say `{e}`: {stderr}");
        }
        assert!(!Path::new(&output).exists(), "{args:?}: no plot is left behind");
    }
    let out = fissure(&["plot", path(good).as_str(), "-o", png.as_str(), "--size", "100x100"]);
    assert_eq!(out.status.code(), Some(1), "too small: {}", text(&out.stderr));
    assert!(text(&out.stderr).contains("too small"), "{}", text(&out.stderr));
}
