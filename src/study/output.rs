//! The study's tables: `results.csv` (a row a run) and `report.md`.
//!
//! In: [`StudyResults`]. Out: the two files. Stays true: one CSV row per run,
//! in plan order, with a fixed header ([`CSV_HEADER`]); times in milliseconds,
//! lengths in millimetres; a failed run keeps its row with empty numbers and
//! its reason in `status`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::plan::{backend_name, contact_name, describe_base, refine_label, skull_label, substep_label};
use super::{Comparison, Knob, RunMeasure, RunRow, StudyError, StudyResults};
use crate::sim::StageId;

/// The paper's Fig. 13: collision for 500 source nodes on a 15,865-triangle model, ms.
pub const PAPER_COLLISION_GPU_MS: f64 = 160.0;
/// As above, on the CPU.
pub const PAPER_COLLISION_CPU_MS: f64 = 2000.0;
/// Surface triangles of the paper's Fig. 13 model.
pub const PAPER_TRIANGLES: usize = 15_865;
/// The paper's whole simulation loop, about, ms.
pub const PAPER_LOOP_MS: f64 = 700.0;
/// Frame budgets of the budget table and chart, ms.
pub const BUDGETS_MS: [f64; 3] = [1.0, 4.0, 16.0];

/// Column names of `results.csv`.
pub const CSV_HEADER: &str = "knob,label,value,reference,mesh,mesh_nodes,surface_triangles,layout,nodes_per_face,backend,culling,\
speed_thickness_per_frame,storage,roi,contact,substep_travel,skull,refine_edges_across,status,frames,build_s,compliance_mb,compliance_cached,\
collision_p50_ms,collision_p95_ms,solve_p50_ms,solve_p95_ms,forces_p50_ms,forces_p95_ms,monitor_p50_ms,monitor_p95_ms,\
frame_p50_ms,frame_p95_ms,comparison,frames_compared,rms_error_mm,max_error_mm,force_rms_pct,force_max_pct,force_points,missed_contact_frames,\
reference_contact_frames,pressure_error_mmhg,peak_pressure_mmhg,crossed_vertices,penetrating_max,penetration_max_mm,inverted_max,\
finest_force_rms_pct,finest_force_max_pct,own_mesh_force_rms_pct,own_mesh_force_max_pct,own_mesh_rms_error_mm,own_mesh_max_error_mm";

fn quote(s: &str) -> String {
    format!("\"{}\"", s.replace('"', "\"\""))
}

/// Commas outside double quotes.
fn separators(line: &str) -> usize {
    let mut quoted = false;
    line.chars()
        .filter(|&c| {
            if c == '"' {
                quoted = !quoted;
            }
            c == ',' && !quoted
        })
        .count()
}

fn comparison_label(c: Comparison) -> String {
    match c {
        Comparison::Reference => "reference".into(),
        Comparison::PerVertex => "per-vertex".into(),
        Comparison::Probes(n) => format!("{n} probes"),
    }
}

fn ms(x: f64) -> String {
    format!("{:.4}", x * 1e3)
}

/// One CSV line (no newline).
pub fn csv_line(r: &RunRow) -> String {
    csv_line_as(r, r.knob.map_or("reference", |k| k.name()))
}

/// [`csv_line`] with `kind` in the knob column (`mesh_reference` for the plan's mesh reference).
fn csv_line_as(r: &RunRow, kind: &str) -> String {
    let s = &r.settings;
    let mut line = format!(
        "{},{},{},{},{},",
        kind,
        quote(&r.label),
        r.value,
        kind == "reference",
        quote(&s.mesh.label())
    );
    let m = r.outcome.as_ref().ok();
    let _ = write!(
        line,
        "{},{},{},{},{},{},{},{:?},{},{},{},{},{},",
        m.map(|m| m.mesh_nodes.to_string()).unwrap_or_default(),
        m.map(|m| m.surface_triangles.to_string()).unwrap_or_default(),
        quote(&s.layout_label()),
        s.nodes_per_face(),
        backend_name(s.backend),
        s.culling,
        s.speed,
        s.storage,
        quote(&s.roi.label()),
        contact_name(s.contact),
        s.substep_travel.map(|t| t.to_string()).unwrap_or_else(|| "none".into()),
        skull_label(s.skull),
        s.refine.map(|e| e.to_string()).unwrap_or_else(|| "none".into())
    );
    let status = match &r.outcome {
        Ok(m) => m.note.clone().unwrap_or_else(|| "ok".into()),
        Err(e) => format!("failed: {e}"),
    };
    let _ = write!(line, "{},", quote(&status));
    let Some(m) = m else {
        // Empty numbers: pad to the header's field count.
        let missing = separators(CSV_HEADER).saturating_sub(separators(&line));
        line.push_str(&",".repeat(missing));
        return line;
    };
    let stage = |id: StageId| m.stage(id).map(|p| (ms(p.p50), ms(p.p95))).unwrap_or_default();
    let _ = write!(line, "{},{:.3},{:.3},{},", m.frames, m.build_s, m.compliance_bytes as f64 / 1e6, m.compliance_cached);
    for id in [StageId::Collision, StageId::Solve, StageId::Forces, StageId::Monitor] {
        let (a, b) = stage(id);
        let _ = write!(line, "{a},{b},");
    }
    let _ = write!(line, "{},{},", ms(m.frame.p50), ms(m.frame.p95));
    match &m.accuracy {
        Some(a) => {
            let _ = write!(
                line,
                "{},{},{:.6},{:.6},{:.4},{:.4},{},{},{},{:.4},",
                quote(&comparison_label(a.comparison)),
                a.frames_compared,
                a.rms_error_m * 1e3,
                a.max_error_m * 1e3,
                a.force_rms_pct,
                a.force_max_pct,
                a.force_points,
                a.missed_contact_frames,
                a.reference_contact_frames,
                a.pressure_error_mmhg
            );
        }
        None => line.push_str(",,,,,,,,,,"),
    }
    let _ = write!(line, "{:.4},{},{},{:.6},{},", m.peak_pressure_mmhg, m.crossed_total, m.penetrating_max, m.penetration_max_m * 1e3, m.inverted_max);
    match m.against_finest {
        Some((rms, max)) => {
            let _ = write!(line, "{rms:.4},{max:.4},");
        }
        None => line.push_str(",,"),
    }
    match &m.against_mesh_reference {
        Some(a) => {
            let _ = write!(line, "{:.4},{:.4},{:.6},{:.6}", a.force_rms_pct, a.force_max_pct, a.rms_error_m * 1e3, a.max_error_m * 1e3);
        }
        None => line.push_str(",,,"),
    }
    line
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> StudyError + '_ {
    move |source| StudyError::Output { path: path.to_path_buf(), source }
}

/// Writes `results.csv`.
pub fn write_csv(results: &StudyResults, path: &Path) -> Result<PathBuf, StudyError> {
    let mut text = String::from(CSV_HEADER);
    text.push('\n');
    for r in &results.rows {
        text.push_str(&csv_line(r));
        text.push('\n');
    }
    if let Some(r) = &results.mesh_reference {
        text.push_str(&csv_line_as(r, "mesh_reference"));
        text.push('\n');
    }
    crate::fsio::write_atomic(path, text.as_bytes()).map_err(|e| io(path)(e.source))?;
    Ok(path.to_path_buf())
}

fn f_ms(x: f64) -> String {
    let v = x * 1e3;
    if v >= 100.0 { format!("{v:.0}") } else if v >= 1.0 { format!("{v:.2}") } else { format!("{v:.3}") }
}

/// A length error in mm: "exact" when it is 0.
fn f_mm(x: f64) -> String {
    let v = x * 1e3;
    if v == 0.0 { "exact".into() } else if v >= 0.1 { format!("{v:.3}") } else { format!("{v:.1e}") }
}

/// An error in its unit with `digits` decimals: "exact" when it is 0.
fn f_err(v: f64, digits: usize) -> String {
    if v == 0.0 { "exact".into() } else { format!("{v:.digits$}") }
}

/// The force error's RMS and maximum, `rms / max` (or `exact`).
fn force_cell(a: &super::Accuracy, digits: usize) -> String {
    if a.force_rms_pct == 0.0 && a.force_max_pct == 0.0 { "exact".into() } else { format!("{:.digits$} / {:.digits$}", a.force_rms_pct, a.force_max_pct) }
}

/// The most accurate run (RMS error, then max error, then faster) whose frame
/// p95 fits in `budget_ms`; the reference competes like any run.
pub fn best_within(rows: &[RunRow], budget_ms: f64) -> Option<&RunRow> {
    rows.iter()
        .filter_map(|r| {
            let m = r.outcome.as_ref().ok()?;
            let a = m.accuracy.as_ref()?;
            (m.frame.p95 * 1e3 <= budget_ms).then_some((r, a.rms_error_m, a.max_error_m, m.frame.p95))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.2.total_cmp(&b.2)).then(a.3.total_cmp(&b.3)))
        .map(|x| x.0)
}

/// Runs with accuracy on the error-vs-time Pareto front (frame p95 ascending,
/// each strictly more accurate than every faster one).
pub fn pareto_front(rows: &[RunRow]) -> Vec<&RunRow> {
    let mut ok: Vec<(&RunRow, f64, f64)> = rows
        .iter()
        .filter_map(|r| {
            let m = r.outcome.as_ref().ok()?;
            let a = m.accuracy.as_ref()?;
            Some((r, m.frame.p95, a.rms_error_m))
        })
        .collect();
    ok.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.2.total_cmp(&b.2)));
    let mut best = f64::INFINITY;
    let mut front = Vec::new();
    for (r, _, e) in ok {
        if e < best {
            best = e;
            front.push(r);
        }
    }
    front
}

fn settings_summary(r: &RunRow) -> String {
    let s = &r.settings;
    format!(
        "{}, {} nodes/face ({}), {}, culling {}, {} h/frame, {:?}, ROI {}, {}, sub-steps {}, skull {}, mesh {}",
        s.mesh.label(),
        s.nodes_per_face(),
        s.layout_label(),
        backend_name(s.backend),
        if s.culling { "on" } else { "off" },
        s.speed,
        s.storage,
        s.roi.label(),
        contact_name(s.contact),
        substep_label(s.substep_travel),
        skull_label(s.skull),
        refine_label(s.refine)
    )
}

fn measure_of(r: &RunRow) -> Option<&RunMeasure> {
    r.outcome.as_ref().ok()
}

/// Marks the start of the report's summary (the README copies it verbatim).
pub const SUMMARY_BEGIN: &str = "<!-- study summary: begin -->";
/// Marks its end.
pub const SUMMARY_END: &str = "<!-- study summary: end -->";

/// The text between [`SUMMARY_BEGIN`] and [`SUMMARY_END`] (markers excluded), if both are there.
pub fn summary_section(text: &str) -> Option<&str> {
    let a = text.find(SUMMARY_BEGIN)? + SUMMARY_BEGIN.len();
    let b = a + text[a..].find(SUMMARY_END)?;
    Some(&text[a..b])
}

/// The header of every run table; the first [`ACCURACY_COLUMNS`] cells after the
/// value are deterministic (the CI test compares them with a committed report).
const RUN_TABLE_HEADER: &str = "| value | RMS err (mm) | max err (mm) | force RMS / max err (%) | pressure err (mmHg) | missed | crossed | pen. (mm) | inverted | frame p50/p95 (ms) | collision p50/p95 (ms) | solve p50/p95 (ms) | build (s) | compliance (MB) | note |\n\
|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
/// Deterministic cells of a run-table row after the value.
pub const ACCURACY_COLUMNS: usize = 8;

/// Every run-table row of a report as (section, value, its accuracy cells):
/// what the CI test compares between a fresh run and a committed report.
pub fn accuracy_cells(report: &str) -> Vec<(String, String, Vec<String>)> {
    let mut out = Vec::new();
    let mut section = String::new();
    let mut in_table = false;
    for line in report.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            section = h.trim().to_string();
            in_table = false;
        } else if line.starts_with("| value | RMS err") {
            in_table = true;
        } else if in_table && line.starts_with("| ") {
            let cells: Vec<String> = line.trim_matches('|').split(" | ").map(|c| c.trim().to_string()).collect();
            if cells.len() > ACCURACY_COLUMNS {
                out.push((section.clone(), cells[0].clone(), cells[1..=ACCURACY_COLUMNS].to_vec()));
            }
        } else if !line.starts_with('|') {
            in_table = false;
        }
    }
    out
}

/// The knob alone: each run's force against the sweep's finest run (the
/// one that reads exact), when the knob has an order.
fn write_against_finest(t: &mut String, knob: Knob, rows: &[&RunRow]) {
    let Some(finest) = knob.finest(&rows.iter().map(|r| r.value).collect::<Vec<_>>()).map(|f| &rows[f].label) else { return };
    let cells: Vec<(String, (f64, f64))> =
        rows.iter().filter_map(|r| r.outcome.as_ref().ok().and_then(|m| m.against_finest).map(|e| (r.label.clone(), e))).collect();
    if cells.len() < 2 {
        return;
    }
    let _ = write!(
        t,
        "\nThis knob alone, every other at the base: each run's force against this sweep's finest setting ({finest}) along the path, \
         RMS / max % of its peak: "
    );
    let parts: Vec<String> = cells
        .iter()
        .map(|(label, (rms, max))| if (*rms, *max) == (0.0, 0.0) { format!("{label} exact") } else { format!("{label} {rms:.2} / {max:.2}") })
        .collect();
    let _ = writeln!(t, "{}.", parts.join("; "));
}

fn run_table_row(t: &mut String, r: &RunRow) {
    let label = if r.is_reference() { format!("**{}**", r.label) } else { r.label.clone() };
    match &r.outcome {
        Err(e) => {
            let _ = writeln!(t, "| {label} | | | | | | | | | | | | | | not run: {} |", e.replace('|', "/"));
        }
        Ok(m) => {
            let pp = |id| m.stage(id).map(|p: super::Percentiles| format!("{} / {}", f_ms(p.p50), f_ms(p.p95))).unwrap_or_else(|| "—".into());
            let (rms, max, force, pressure, missed) = match &m.accuracy {
                Some(a) if a.comparison == Comparison::Reference => ("—".into(), "—".into(), "—".into(), "—".into(), "—".into()),
                Some(a) => (
                    f_mm(a.rms_error_m),
                    f_mm(a.max_error_m),
                    force_cell(a, 2),
                    f_err(a.pressure_error_mmhg, 2),
                    format!("{}/{}", a.missed_contact_frames, a.reference_contact_frames),
                ),
                None => ("—".into(), "—".into(), "—".into(), "—".into(), "—".into()),
            };
            let mut note = m.note.clone().unwrap_or_default();
            if let Some(Comparison::Probes(n)) = m.accuracy.map(|a| a.comparison) {
                note = format!("another mesh: {n} probes");
            }
            if m.compliance_cached {
                note = format!("{note} compliance from cache").trim().to_string();
            }
            let _ = writeln!(
                t,
                "| {label} | {rms} | {max} | {force} | {pressure} | {missed} | {} | {} ({}) | {} | {} / {} | {} | {} | {:.2} | {:.1} | {note} |",
                m.crossed_total,
                m.penetrating_max,
                if m.penetration_max_m == 0.0 { "0".into() } else { f_mm(m.penetration_max_m) },
                m.inverted_max,
                f_ms(m.frame.p50),
                f_ms(m.frame.p95),
                pp(StageId::Collision),
                pp(StageId::Solve),
                m.build_s,
                m.compliance_bytes as f64 / 1e6,
            );
        }
    }
}

/// The mesh reference's figure of a run, `force RMS / max %, RMS / max mm`.
fn mesh_share_cell(a: &super::Accuracy) -> String {
    if (a.force_rms_pct, a.force_max_pct, a.max_error_m) == (0.0, 0.0, 0.0) {
        return "exact".into();
    }
    format!("force {:.1} / {:.1} %, {} / {} mm", a.force_rms_pct, a.force_max_pct, f_mm(a.rms_error_m), f_mm(a.max_error_m))
}

/// Where the reference's mesh is not the base's: what the mesh alone costs
/// (the reference's settings on the base mesh against the reference) and what
/// the budget table's rows on the base mesh cost against that mesh's own
/// finest settings.
fn write_mesh_share(t: &mut String, results: &StudyResults) {
    let Some(row) = &results.mesh_reference else { return };
    let mesh = row.settings.mesh.label();
    let m = match &row.outcome {
        Ok(m) => m,
        Err(why) => {
            let _ = writeln!(t, "\nThe mesh's share could not be measured: the finest setting of every other knob on {mesh}: {why}.\n");
            return;
        }
    };
    let own = m.accuracy.filter(|a| a.comparison != Comparison::Reference).map_or_else(|| "—".into(), |a| mesh_share_cell(&a));
    let _ = write!(
        t,
        "\nThe mesh's share: the reference's settings on {mesh} instead of {} differ from the reference by {own} (the mesh alone). \
         Against that run (the finest setting of every other knob on {mesh}), the rows above on {mesh} read: ",
        results.rows.iter().find(|r| r.is_reference()).map_or_else(|| "its mesh".into(), |r| r.settings.mesh.label()),
    );
    let mut parts = Vec::new();
    for budget in BUDGETS_MS {
        let Some(r) = best_within(&results.rows, budget) else { continue };
        if let Some(a) = measure_of(r).and_then(|m| m.against_mesh_reference) {
            parts.push(format!("{budget} ms ({}: {}) {}", r.knob.map_or("reference", |k| k.name()), r.label, mesh_share_cell(&a)));
        }
    }
    let _ = writeln!(t, "{}.", if parts.is_empty() { "none is on that mesh".to_string() } else { parts.join("; ") });
}

/// Each run of a sweep on the mesh reference's mesh against it, force RMS / max %.
fn write_against_mesh_reference(t: &mut String, results: &StudyResults, rows: &[&RunRow]) {
    let Some(mesh_row) = &results.mesh_reference else { return };
    let parts: Vec<String> = rows
        .iter()
        .filter_map(|r| r.outcome.as_ref().ok().and_then(|m| m.against_mesh_reference).map(|a| (r, a)))
        .map(|(r, a)| format!("{} {}", r.label, mesh_share_cell(&a)))
        .collect();
    if !parts.is_empty() {
        let _ = writeln!(t, "\nOn {} against its own finest settings ({}): {}.", mesh_row.settings.mesh.label(), mesh_row.label, parts.join("; "));
    }
}

/// The summary the README copies: the budget table and one line a knob.
fn write_summary(t: &mut String, results: &StudyResults) {
    let _ = writeln!(t, "{SUMMARY_BEGIN}");
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let _ = writeln!(
        t,
        "Every run against one reference (the finest setting of every knob at once: {}); errors of exactly 0 read \"exact\". \
         `fissure study --preset {}`, {} runs, {:.0} s on {} logical cores ({} build).\n",
        results.rows.iter().find(|r| r.is_reference()).map(settings_summary).unwrap_or_else(|| "not run".into()),
        results.plan_name,
        results.rows.len() + usize::from(results.mesh_reference.is_some()),
        results.elapsed_s,
        cores,
        if cfg!(debug_assertions) { "debug" } else { "release" }
    );
    t.push_str("| frame budget (p95) | most accurate setting that fits | frame p50 / p95 (ms) | RMS / max err (mm) | force RMS / max err (%) | pressure err (mmHg) |\n|---|---|---:|---:|---:|---:|\n");
    for budget in BUDGETS_MS {
        match best_within(&results.rows, budget) {
            None => {
                let _ = writeln!(t, "| {budget} ms | nothing fits | | | | |");
            }
            Some(r) => {
                let (Some(m), Some(a)) = (measure_of(r), measure_of(r).and_then(|m| m.accuracy.as_ref())) else { continue };
                let exact = a.comparison == Comparison::Reference;
                let _ = writeln!(
                    t,
                    "| {budget} ms | {}: {} | {} / {} | {} | {} | {} |",
                    r.knob.map_or("reference", |k| k.name()),
                    r.label,
                    f_ms(m.frame.p50),
                    f_ms(m.frame.p95),
                    if exact { "exact".into() } else { format!("{} / {}", f_mm(a.rms_error_m), f_mm(a.max_error_m)) },
                    if exact { "exact".into() } else { force_cell(a, 1) },
                    if exact { "exact".into() } else { f_err(a.pressure_error_mmhg, 2) },
                );
            }
        }
    }
    write_mesh_share(t, results);
    t.push_str("\n| knob | setting: frame p95 (ms), RMS error (mm), vertices pulled through |\n|---|---|\n");
    for knob in Knob::ALL {
        let cells: Vec<String> = results
            .rows
            .iter()
            .filter(|r| r.knob == Some(knob))
            .map(|r| match &r.outcome {
                Ok(m) => format!(
                    "{}: {}, {}, {}",
                    r.label,
                    f_ms(m.frame.p95),
                    m.accuracy.map(|a| f_mm(a.rms_error_m)).unwrap_or_else(|| "—".into()),
                    m.crossed_total
                ),
                Err(_) => format!("{}: not run", r.label),
            })
            .collect();
        if !cells.is_empty() {
            let _ = writeln!(t, "| {} | {} |", knob.name(), cells.join("; "));
        }
    }
    let _ = writeln!(t, "\n{SUMMARY_END}");
}

/// Writes `report.md`.
pub fn write_report(results: &StudyResults, path: &Path) -> Result<PathBuf, StudyError> {
    let mut t = String::new();
    let _ = writeln!(t, "# What accuracy costs in time — `fissure study --preset {}`\n", results.plan_name);
    let _ = writeln!(
        t,
        "Scene: {}. Times are wall-clock per frame stage (median p50 and 95th percentile p95 over the run's frames); \
         the frame is the sum of the stages; they vary from run to run, the errors do not (the simulation is deterministic).\n",
        results.scene_name,
    );
    if results.interrupted {
        let _ = writeln!(t, "**Interrupted (Ctrl-C): the runs not done say so; their sweeps are incomplete.**\n");
    }
    let m = &results.motion;
    let _ = write!(
        t,
        "Each run replays the same motion: the spatula goes {:.0} mm into the fissure ({:.1} mm a frame), {:.0} mm sideways \
         along its face normal and back (at the run's speed), and out. ",
        m.insert_m * 1e3,
        m.insert_step_m * 1e3,
        m.open_m * 1e3
    );
    let _ = write!(t, "Every sweep changes one knob from the base ({}) ", describe_base(&results.base));
    t.push_str(
        "and every run is compared with \
         one *reference* run, the finest setting of every knob at once, which no swept run equals. The reference is \
         run once and kept in the cache folder; a later study by the same build with the same scene, mesh, motion and settings reads it back.\n\n\
         - **RMS / max error**: surface displacement vs the reference, mm, at the frames where both runs are at the same \
         point of the path; RMS over the vertices the reference moves (more than 1% of its peak), max over all. Same mesh: \
         vertex by vertex; across meshes: at the reference's moving surface vertices, where the other mesh's displacement is \
         interpolated barycentrically at the closest point of its rest surface (this includes the meshes' different fissure geometry).\n\
         - **force RMS / max err**: |F − F_ref| at every frame of the reference within the run's path, the run's force \
         interpolated linearly along the path between its frames on either side (so a run with fewer frames is judged at the \
         same points as the reference, not only where their frames coincide); RMS and largest, % of the reference's peak force. \
         **pressure err**: largest difference of the mean contact pressure (the highest over the spatulas) at the shared \
         points of the path, mmHg. ![force along the path](force_path.png) shows each knob's runs against the reference.\n\
         - **missed**: frames where the reference had contact and this run had none (tunnelling), of the reference's contact frames.\n\
         - **crossed**: surface vertices pulled through a blade (summed over frames); **pen.**: most vertices inside a blade in one \
         frame (deepest, mm); **inverted**: most inverted elements after a frame.\n\
         - An error of exactly 0 reads **exact**.\n\n",
    );

    for n in &results.notes {
        let _ = writeln!(t, "{n}\n");
    }
    write_front(&mut t, results);
    write_beside_paper(&mut t, results);
    write_sweeps(&mut t, results);
    t.push_str(
        "Files: `results.csv` (every number above, one row a run), `pareto`, `knobs`, `budget`, `fig13_collision_vs_nodes`, \
         `speed_vs_error`, `force_path` (each `.png` and `.svg`).\n",
    );
    crate::fsio::write_atomic(path, t.as_bytes()).map_err(|e| io(path)(e.source))?;
    Ok(path.to_path_buf())
}

/// The summary, the reference's row and the Pareto front.
fn write_front(t: &mut String, results: &StudyResults) {
    t.push_str("## Summary\n\n");
    write_summary(t, results);
    t.push_str("\n![For a frame budget, the most accurate setting](budget.png)\n\n![One panel a knob](knobs.png)\n\n");

    t.push_str("## Reference\n\n");
    t.push_str(RUN_TABLE_HEADER);
    for r in results.rows.iter().filter(|r| r.is_reference()).chain(&results.mesh_reference) {
        run_table_row(t, r);
    }
    t.push('\n');

    t.push_str("## For this much accuracy, this much time\n\n");
    t.push_str("The error-vs-time Pareto front over all runs: no run is both faster and more accurate than a row here.\n\n");
    t.push_str("| frame p95 (ms) | frame p50 (ms) | RMS err (mm) | max err (mm) | force RMS / max err (%) | setting |\n|---:|---:|---:|---:|---:|---|\n");
    for r in pareto_front(&results.rows) {
        let (Some(m), Some(a)) = (measure_of(r), measure_of(r).and_then(|m| m.accuracy.as_ref())) else { continue };
        let _ = writeln!(
            t,
            "| {} | {} | {} | {} | {} | {} = {} ({}) |",
            f_ms(m.frame.p95),
            f_ms(m.frame.p50),
            f_mm(a.rms_error_m),
            f_mm(a.max_error_m),
            force_cell(a, 2),
            r.knob.map_or("reference", |k| k.name()),
            r.label,
            settings_summary(r)
        );
    }
    t.push_str("\n![Pareto front](pareto.png)\n\n");
}

/// The paper's Fig. 13 and loop time beside ours.
fn write_beside_paper(t: &mut String, results: &StudyResults) {
    t.push_str("## Beside the paper\n\n");
    t.push_str("| quantity | paper (Fukuhara et al. 2014) | ours |\n|---|---|---|\n");
    // Our backend rows nearest to the paper's 500 nodes a face.
    let backend_rows: Vec<&RunRow> = results.rows.iter().filter(|r| r.knob == Some(Knob::Backend)).collect();
    let nearest = backend_rows.iter().map(|r| r.settings.nodes_per_face()).min_by_key(|&n| (n as i64 - 500).abs());
    let ours_for = |backends: &[crate::scenario::CollisionBackend]| -> String {
        let mut parts = Vec::new();
        for r in backend_rows.iter().filter(|r| Some(r.settings.nodes_per_face()) == nearest && backends.contains(&r.settings.backend)) {
            parts.push(match &r.outcome {
                Ok(m) => m
                    .stage(StageId::Collision)
                    .map(|p| {
                        format!(
                            "{}: {} ms p50, {} ms p95 ({} nodes a face, {} triangles)",
                            backend_name(r.settings.backend),
                            f_ms(p.p50),
                            f_ms(p.p95),
                            r.settings.nodes_per_face(),
                            m.surface_triangles
                        )
                    })
                    .unwrap_or_else(|| "—".into()),
                Err(e) => format!("{}: not run: {}", backend_name(r.settings.backend), e.replace('|', "/")),
            });
        }
        if parts.is_empty() { "not in this plan".into() } else { parts.join("; ") }
    };
    use crate::scenario::CollisionBackend as B;
    let _ = writeln!(
        t,
        "| collision, 500 nodes a face, {PAPER_TRIANGLES} triangles, CPU (Fig. 13) | {PAPER_COLLISION_CPU_MS:.0} ms (CPU) | {} |",
        ours_for(&[B::Reference, B::Bvh])
    );
    let _ = writeln!(
        t,
        "| collision, 500 nodes a face, {PAPER_TRIANGLES} triangles, GPU (Fig. 13) | {PAPER_COLLISION_GPU_MS:.0} ms (GPU) | {} |",
        ours_for(&[B::Gpu])
    );
    // The base setting's run (a sweep's run at the base), else any run.
    let base = results.rows.iter().find(|r| r.knob.is_some() && r.settings == results.base).or_else(|| results.rows.first());
    if let Some(base) = base
        && let Some(m) = measure_of(base)
    {
        let _ = writeln!(
            t,
            "| one simulation loop | about {PAPER_LOOP_MS:.0} ms | {} ms p50, {} ms p95 ({}; {} nodes, {} triangles) |",
            f_ms(m.frame.p50),
            f_ms(m.frame.p95),
            settings_summary(base),
            m.mesh_nodes,
            m.surface_triangles
        );
    }
    t.push_str("\n![Collision time vs source nodes per backend](fig13_collision_vs_nodes.png)\n\n");
}

/// A table a swept knob, with what its finest value and the mesh's own reference say.
fn write_sweeps(t: &mut String, results: &StudyResults) {
    for knob in Knob::ALL {
        let rows: Vec<&RunRow> = results.rows.iter().filter(|r| r.knob == Some(knob)).collect();
        if rows.is_empty() {
            continue;
        }
        let _ = writeln!(t, "## Sweep: {}\n", knob.name());
        t.push_str(RUN_TABLE_HEADER);
        for r in &rows {
            run_table_row(t, r);
        }
        write_against_finest(t, knob, &rows);
        write_against_mesh_reference(t, results, &rows);
        if knob == Knob::Contact {
            t.push_str("\n![Culling under both contact models](speed_vs_error.png)\n");
        }
        t.push('\n');
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::plan::{MeshChoice, Settings, base_settings};

    #[test]
    fn a_failed_row_has_as_many_fields_as_the_header() {
        let r = RunRow {
            knob: Some(Knob::Backend),
            label: "gpu 150, culling on".into(),
            value: 150.0,
            settings: base_settings(MeshChoice::Scene),
            outcome: Err("no adapter, \"lavapipe\" absent".into()),
        };
        let line = csv_line(&r);
        assert_eq!(separators(&line), separators(CSV_HEADER), "{line}");
        assert!(line.starts_with("backend,\"gpu 150, culling on\",150,false,"), "{line}");
        assert!(line.contains("failed: no adapter"));
    }

    #[test]
    fn the_summary_and_the_accuracy_cells_are_found_again() {
        let report = format!("# r\n\n## Summary\n\n{SUMMARY_BEGIN}\nbudget table\n{SUMMARY_END}\n\n## Sweep: speed\n\n{RUN_TABLE_HEADER}| 0.5 h/frame | 0.012 | 0.300 | 1.50 | exact | 0/10 | 0 | 0 (0) | 0 | 0.2 / 0.3 | 0.1 / 0.2 | 0.1 / 0.1 | 0.10 | 12.0 | |\n\ntext\n");
        assert_eq!(summary_section(&report), Some("\nbudget table\n"));
        let cells = accuracy_cells(&report);
        assert_eq!(cells.len(), 1, "{cells:?}");
        assert_eq!(cells[0].0, "Sweep: speed");
        assert_eq!(cells[0].1, "0.5 h/frame");
        assert_eq!(cells[0].2, ["0.012", "0.300", "1.50", "exact", "0/10", "0", "0 (0)", "0"]);
    }

    fn accuracy(comparison: Comparison, force_rms_pct: f64, force_max_pct: f64) -> crate::study::Accuracy {
        crate::study::Accuracy {
            comparison,
            frames_compared: 10,
            rms_error_m: 1e-4,
            max_error_m: 1e-3,
            force_rms_pct,
            force_max_pct,
            force_points: 10,
            pressure_error_mmhg: 0.5,
            missed_contact_frames: 0,
            reference_contact_frames: 10,
        }
    }

    fn row(knob: Option<Knob>, label: &str, mesh: MeshChoice, frame_p95_s: f64, accuracy: crate::study::Accuracy, own: Option<crate::study::Accuracy>) -> RunRow {
        let frame = crate::study::Percentiles { p50: frame_p95_s / 2.0, p95: frame_p95_s };
        let measure = RunMeasure {
            frames: 10,
            mesh_nodes: 100,
            surface_triangles: 200,
            build_s: 1.0,
            compliance_bytes: 1_000_000,
            compliance_cached: false,
            stages: Vec::new(),
            frame,
            accuracy: Some(accuracy),
            note: None,
            crossed_total: 0,
            penetrating_max: 0,
            penetration_max_m: 0.0,
            inverted_max: 0,
            peak_pressure_mmhg: 3.0,
            force_along: Vec::new(),
            against_finest: None,
            against_mesh_reference: own,
        };
        RunRow { knob, label: label.into(), value: 1.0, settings: Settings { mesh, ..base_settings(MeshChoice::Scene) }, outcome: Ok(measure) }
    }

    /// A plan whose reference mesh is finer than its base says what the base
    /// mesh alone costs and what the budget rows cost against that mesh's own
    /// finest settings, and the CSV carries both.
    #[test]
    fn the_mesh_share_is_reported_where_the_reference_mesh_is_not_the_base() {
        let (coarse, fine) = (MeshChoice::Phantom("small".into()), MeshChoice::Phantom("paper-9k".into()));
        let results = StudyResults {
            plan_name: "brain".into(),
            base: base_settings(coarse.clone()),
            notes: Vec::new(),
            motion: crate::study::Motion::default(),
            scene_name: "scene".into(),
            rows: vec![
                row(None, "reference", fine.clone(), 0.020, accuracy(Comparison::Reference, 0.0, 0.0), None),
                row(Some(Knob::Speed), "0.5 h/frame", coarse.clone(), 0.010, accuracy(Comparison::Probes(50), 7.25, 17.5), Some(accuracy(Comparison::PerVertex, 0.125, 0.75))),
            ],
            mesh_reference: Some(row(None, "small, every other knob as the reference", coarse, 0.015, accuracy(Comparison::Probes(50), 7.0, 17.0), None)),
            files: Vec::new(),
            elapsed_s: 1.0,
            interrupted: false,
        };
        let mut summary = String::new();
        write_summary(&mut summary, &results);
        assert!(summary.contains("on small instead of paper-9k differ from the reference by force 7.0 / 17.0 %"), "{summary}");
        assert!(summary.contains("16 ms (speed: 0.5 h/frame) force 0.1 / 0.8 %"), "{summary}");
        let dir = tempfile::tempdir().expect("temp dir");
        let csv = std::fs::read_to_string(write_csv(&results, &dir.path().join("results.csv")).expect("csv")).expect("read");
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 4, "header, two rows, the mesh reference");
        assert!(lines.iter().all(|l| separators(l) == separators(CSV_HEADER)), "{csv}");
        assert!(lines[2].ends_with(",0.1250,0.7500,0.100000,1.000000"), "{}", lines[2]);
        assert!(lines[3].starts_with("mesh_reference,\"small, every other knob as the reference\",1,false,"), "{}", lines[3]);
        assert!(lines[1].starts_with("reference,\"reference\",1,true,"), "{}", lines[1]);

        let without = StudyResults { mesh_reference: None, ..results };
        let mut summary = String::new();
        write_summary(&mut summary, &without);
        assert!(!summary.contains("mesh's share"), "{summary}");
    }
}
