//! `fissure debrief`: hand-computed numbers, the page's verdict table against its JSON, a real replay against
//! itself, and the refusal of a folder that is not a run.

use std::path::Path;

use fissure::debrief::{Verdict, debrief, read_run};

fn fissure(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_fissure"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the fissure binary runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A run written by hand: blade `a` moves in a straight line at constant speed (3, 4, 0) mm a frame, pushes with
/// a constant 0.2 N at 30 mmHg; rows every 0.5 s from 0.5 s to 2 s (four frames, 2 s). Blade `b` touches nothing.
fn hand_run(dir: &Path) {
    hand_run_pushing(dir, 0.2);
}

/// [`hand_run`] with blade `a` pushing `force_n` (its first frame's jump too).
fn hand_run_pushing(dir: &Path, force_n: f64) {
    std::fs::create_dir_all(dir).unwrap();
    let mut csv = String::from(
        "frame,time_s,a_force_n,a_contact_area_mm2,a_contact_vertices,a_mean_pressure_mmhg,a_force_jump_n,a_tip_x_mm,a_tip_y_mm,a_tip_z_mm,\
         b_force_n,b_contact_area_mm2,b_contact_vertices,b_mean_pressure_mmhg,b_force_jump_n,b_tip_x_mm,b_tip_y_mm,b_tip_z_mm,inverted_scope\n",
    );
    for k in 0..4 {
        let jump = if k == 0 { force_n } else { 0.0 };
        csv += &format!("{k},{},{force_n},10,12,30,{jump},{},{},0,0,0,0,0,0,50,0,0,surface\n", 0.5 * (k + 1) as f64, 3.0 * k as f64, 4.0 * k as f64);
    }
    std::fs::write(dir.join("metrics.csv"), csv).unwrap();
    std::fs::write(dir.join("summary.json"), r#"{"scenario": "hand-made", "interrupted": false, "integrity": {"passed": true, "failures": []}, "injuries": [], "vessels": [], "bands": null}"#).unwrap();
}

#[test]
fn hand_computed_numbers() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("hand");
    hand_run(&dir);
    let run = read_run(&dir).expect("a run");
    let d = debrief(&run, None);
    let a = &d.blades[0];
    let value = |key: &str| a.metrics.iter().find(|m| m.key == key).unwrap_or_else(|| panic!("no {key}")).value;
    assert_eq!(value("path_length_mm"), Some(15.0), "three frames of 5 mm");
    assert_eq!(value("net_displacement_mm"), Some(15.0));
    assert_eq!(value("economy_of_motion"), Some(1.0), "a straight line at constant speed");
    assert_eq!(value("peak_force_n"), Some(0.2));
    assert_eq!(value("mean_force_n"), Some(0.2));
    assert!((value("rms_force_n").unwrap() - 0.2).abs() < 1e-15);
    assert_eq!(value("force_roughness_n"), Some(0.0), "a constant force");
    assert_eq!(value("time_in_contact_s"), Some(2.0));
    assert_eq!(value("time_above_20mmhg_s"), Some(2.0), "30 mmHg for 2 s");
    assert_eq!(value("pressure_time_above_20mmhg_mmhg_s"), Some(20.0), "(30 - 20) mmHg x 2 s");
    let pressure = a.metrics.iter().find(|m| m.key == "peak_mean_pressure_mmhg").unwrap();
    assert_eq!((pressure.limit, pressure.verdict), (Some(20.0), Some(Verdict::OverLimit)));
    assert!(a.sentences[0].contains("30.0 mmHg for 2.00 s from 0.500 s"), "{:?}", a.sentences);
    // Blade b never touched: no mean force, so no force ratio; no time in contact together.
    let pair = d.pair.as_ref().expect("two blades");
    assert_eq!(pair.metrics[0].value, None);
    assert_eq!(pair.metrics[1].value, Some(0.0));
    assert!(d.map_note.as_deref().is_some_and(|n| n.contains("surface_dose.csv")), "{:?}", d.map_note);
}

/// Each `<tr data-section=.. data-key=..>` row of the page: its section, key and the value, reference and limit
/// cells as shown.
fn verdict_rows(html: &str) -> Vec<(String, String, [String; 3])> {
    let attr = |row: &str, name: &str| {
        let start = row.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        row[start..start + row[start..].find('"').unwrap()].to_string()
    };
    let cell = |row: &str, class: &str| {
        let start = row.find(&format!("<td class=\"{class}\">")).unwrap_or_else(|| panic!("no {class} cell in {row}")) + class.len() + 13;
        row[start..start + row[start..].find("</td>").unwrap()].to_string()
    };
    html.split("<tr data-section=")
        .skip(1)
        .map(|rest| {
            let row = format!("<tr data-section={}", &rest[..rest.find("</tr>").unwrap()]);
            (attr(&row, "data-section"), attr(&row, "data-key"), [cell(&row, "value"), cell(&row, "reference"), cell(&row, "limit")])
        })
        .collect()
}

/// The page's number matches the JSON's to the digits it shows.
fn same_number(shown: &str, json: &serde_json::Value, what: &str) {
    if shown == "-" {
        assert!(json.is_null(), "{what}: the page shows none, the JSON has {json}");
        return;
    }
    let page: f64 = shown.parse().unwrap_or_else(|_| panic!("{what}: `{shown}` is not a number"));
    let value = json.as_f64().unwrap_or_else(|| panic!("{what}: the page shows {shown}, the JSON has {json}"));
    let decimals = shown.split('.').nth(1).map_or(0, str::len) as i32;
    assert!((page - value).abs() <= 0.5 * 10f64.powi(-decimals) * (1.0 + 1e-9), "{what}: page {shown}, JSON {value}");
}

fn check_page_against_json(html: &str, json: &serde_json::Value) {
    let rows = verdict_rows(html);
    assert!(rows.len() > 10, "{} verdict rows", rows.len());
    let mut sections: Vec<(String, &serde_json::Value)> = Vec::new();
    for b in json["blades"].as_array().unwrap() {
        sections.push((format!("blade {}", b["name"].as_str().unwrap()), &b["metrics"]));
    }
    if !json["pair"].is_null() {
        sections.push(("pair".into(), &json["pair"]["metrics"]));
    }
    sections.push(("scene".into(), &json["scene"]));
    let mut count = 0;
    for (section, metrics) in &sections {
        for m in metrics.as_array().unwrap() {
            let key = m["key"].as_str().unwrap();
            let (_, _, cells) = rows.iter().find(|(s, k, _)| s == section && k == key).unwrap_or_else(|| panic!("{section} {key} not on the page"));
            for (cell, field) in cells.iter().zip(["value", "reference", "limit"]) {
                same_number(cell, &m[field], &format!("{section} {key} {field}"));
            }
            count += 1;
        }
    }
    assert_eq!(count, rows.len(), "every row of the page is a metric of the JSON");
}

#[test]
fn the_pages_verdict_table_shows_the_jsons_numbers() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("hand");
    hand_run(&dir);
    let reference = tmp.path().join("reference");
    hand_run(&reference);
    let out = fissure(&["debrief", dir.to_str().unwrap(), "--reference", reference.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let html = std::fs::read_to_string(dir.join("debrief.html")).expect("debrief.html");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("debrief.json")).expect("debrief.json")).unwrap();
    check_page_against_json(&html, &json);
    assert!(html.contains("<svg"), "the timeline is inline");
    assert!(html.contains("No pressure map") && html.contains("surface_dose.csv"), "a run without the dose file says why it has no map");
    assert!(!html.contains("src=\"http") && !html.contains("href=\"http"), "nothing outside the page");
}

#[test]
fn a_folder_that_is_not_a_run_is_refused_naming_what_is_missing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = fissure(&["debrief", tmp.path().to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains("metrics.csv") && err.contains("not a run folder"), "{err}");
    // Several runs need the page's name.
    let out = fissure(&["debrief", tmp.path().to_str().unwrap(), tmp.path().to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("-o"), "{}", text(&out.stderr));
}

#[test]
fn an_interrupted_run_is_debriefed_and_the_page_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("cut_short");
    hand_run(&dir);
    std::fs::write(dir.join("summary.json"), r#"{"scenario": "hand-made", "interrupted": true, "integrity": {"passed": false, "failures": ["inverted elements 3 > 0 (first at frame 2, t = 1.50 s)"]}}"#).unwrap();
    let out = fissure(&["debrief", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let html = std::fs::read_to_string(dir.join("debrief.html")).unwrap();
    assert!(html.contains("stopped early") && html.contains("inverted elements 3 &gt; 0"), "the page says the run is incomplete");
}

#[test]
fn a_real_replay_against_itself_is_within_everywhere_with_a_map() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("v_valley");
    let out = fissure(&["replay", "config/v_valley.ron", "--set", "solver.cache_dir=None", "--out", run.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let dose = std::fs::read_to_string(run.join("surface_dose.csv")).expect("the replay writes surface_dose.csv");
    let mut lines = dose.lines();
    assert_eq!(lines.next(), Some("x_mm,y_mm,z_mm,pressure_time_mmhg_s,peak_pressure_mmhg"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|f| f.parse().unwrap()).collect()).collect();
    assert!(rows.len() > 100 && rows.iter().all(|r| r.len() == 5 && r.iter().all(|v| v.is_finite())));
    assert!(rows.iter().any(|r| r[3] > 0.0 && r[4] > 0.0), "the blade pressed somewhere");
    let page = tmp.path().join("page.html");
    let out = fissure(&["debrief", run.to_str().unwrap(), "--reference", run.to_str().unwrap(), "-o", page.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(tmp.path().join("page.json")).expect("page.json beside the page")).unwrap();
    let html = std::fs::read_to_string(&page).unwrap();
    check_page_against_json(&html, &json);
    assert!(html.contains("data:image/png;base64,"), "the map is embedded");
    let run_data = read_run(&run).unwrap();
    let d = debrief(&run_data, Some(&run_data));
    assert!(d.blades[0].metrics.iter().any(|m| m.key == "path_length_mm" && m.value.is_some_and(|v| v > 0.0)), "the tip moved");
    for (section, m) in d.all_metrics() {
        assert!(m.reference_verdict.is_none_or(|v| v == Verdict::Within), "{section} {}: {:?}", m.key, m.reference_verdict);
        if m.reference.is_some() || m.value.is_some() {
            assert_eq!(m.value, m.reference, "{section} {}", m.key);
        }
    }
}

/// A trainee's first, second and third tries side by side: the page's trend column gives each metric's change from
/// the first run to the last, by hand: peak force 0.4 -> 0.2 N is -50 %, the unchanged path length "+0 %".
#[test]
fn several_runs_side_by_side_give_each_metrics_trend() {
    let tmp = tempfile::tempdir().unwrap();
    let runs: Vec<_> = [0.4, 0.3, 0.2]
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let dir = tmp.path().join(format!("try{}", k + 1));
            hand_run_pushing(&dir, *f);
            dir
        })
        .collect();
    let page = tmp.path().join("progress.html");
    let args: Vec<&str> = ["debrief"].into_iter().chain(runs.iter().map(|d| d.to_str().unwrap())).chain(["-o", page.to_str().unwrap()]).collect();
    let out = fissure(&args);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("Trend, first run to last"), "a trend table");
    let row = |name: &str| -> Vec<String> {
        let start = html.find(&format!("<tr><td>{name} (blade a)")).unwrap_or_else(|| panic!("no row {name}"));
        let end = start + html[start..].find("</tr>").unwrap();
        html[start..end].split("<td>").skip(2).map(|c| c.trim_end_matches("</td>").to_string()).collect()
    };
    assert_eq!(row("peak force"), ["0.4000", "0.3000", "0.2000", "-50 %"], "each run's value, then the trend");
    assert_eq!(row("instrument tip path length"), ["15.00", "15.00", "15.00", "+0 %"]);
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(page.with_extension("json")).unwrap()).unwrap();
    let peaks: Vec<f64> = json
        .as_array()
        .expect("one debrief a run")
        .iter()
        .map(|d| d["blades"][0]["metrics"].as_array().unwrap().iter().find(|m| m["key"] == "peak_force_n").unwrap()["value"].as_f64().unwrap())
        .collect();
    assert_eq!(peaks, [0.4, 0.3, 0.2], "the JSON holds the same numbers, run by run");
}
