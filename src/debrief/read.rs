//! Reading a run folder for the debrief: `metrics.csv` by column name, `summary.json`'s facts,
//! `surface_dose.csv` when there is one.
//!
//! In: a folder. Out: [`RunData`] (a series a frame for each blade, the tethers' and ischemia's columns where the
//! scene had them, the summary's injuries, vessels, bands and integrity). Stays true: a missing folder or file,
//! a short row or a field that is not a number is an error naming the file (and the line); a value the replay left
//! empty (a column of a stage not built) reads as NaN and is left out of every sum.

use std::path::{Path, PathBuf};

use crate::fsio::Cap;
use crate::sim::metrics::column_word;
use crate::sim::replay::{SURFACE_DOSE_FILE, SURFACE_DOSE_HEADER};

const METRICS_CAP: Cap = Cap { bytes: 8 << 30, what: "a metrics file" };
const SUMMARY_CAP: Cap = Cap { bytes: 16 << 20, what: "a run summary" };
const DOSE_CAP: Cap = Cap { bytes: 1 << 30, what: "a surface dose file" };

/// Why a run folder was not read; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum DebriefReadError {
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    #[error("{}: line {line}: {message}", path.display())]
    Line { path: PathBuf, line: usize, message: String },
    #[error("{0}")]
    Read(#[from] crate::fsio::ReadError),
}

fn file_error(path: &Path, message: impl Into<String>) -> DebriefReadError {
    DebriefReadError::File { path: path.to_path_buf(), message: message.into() }
}

/// One blade's columns, a value a frame (NaN where the file had none).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BladeTrack {
    pub name: String,
    pub force_n: Vec<f64>,
    pub mean_pressure_mmhg: Vec<f64>,
    pub contact_vertices: Vec<f64>,
    /// The frame-to-frame change of the force vector (`_force_jump_n`), when the file has it.
    pub force_jump_n: Option<Vec<f64>>,
    /// The blade's tip, mm, when the file has the `_tip_x_mm` columns.
    pub tip_mm: Option<Vec<[f64; 3]>>,
    /// The area at even odds of ischemic injury under this blade, mm^2 (the `Ischemia` effect).
    pub area_at_risk_mm2: Option<Vec<f64>>,
}

/// A vessel as the summary gives it, with its stretch a frame from `metrics.csv` when there.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VesselFacts {
    pub name: String,
    pub max_stretch: f64,
    pub warning_stretch: f64,
    pub rupture_stretch: f64,
    pub torn: bool,
    pub stretch: Option<Vec<f64>>,
}

/// A tether torn or cut.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Injury {
    pub time_s: f64,
    /// `torn` or `cut`.
    pub kind: String,
    pub tether: String,
}

/// A surface vertex at rest and the pressure it took over the run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DoseVertex {
    pub position_mm: [f64; 3],
    pub pressure_time_mmhg_s: f64,
    pub peak_pressure_mmhg: f64,
}

/// A run folder, read.
#[derive(Debug, Clone, PartialEq)]
pub struct RunData {
    pub dir: PathBuf,
    /// The scene's name (`summary.json`), when there is one.
    pub scenario: Option<String>,
    /// The run stopped early (`summary.json`), or has no summary at all.
    pub interrupted: bool,
    /// The integrity check's failures, one line each.
    pub integrity_failures: Vec<String>,
    /// Simulated time of each frame, s.
    pub time_s: Vec<f64>,
    pub blades: Vec<BladeTrack>,
    pub vessels: Vec<VesselFacts>,
    /// Arachnoid bands: total, torn, cut (None without tethers).
    pub bands: Option<(u32, u32, u32)>,
    pub injuries: Vec<Injury>,
    /// `ischemia_at_risk_mm2` a frame (the `Ischemia` effect).
    pub ischemia_at_risk_mm2: Option<Vec<f64>>,
    /// `surface_dose.csv`, or why there is no map.
    pub dose: Result<Vec<DoseVertex>, String>,
}

impl Default for RunData {
    fn default() -> Self {
        Self {
            dir: PathBuf::new(),
            scenario: None,
            interrupted: false,
            integrity_failures: Vec::new(),
            time_s: Vec::new(),
            blades: Vec::new(),
            vessels: Vec::new(),
            bands: None,
            injuries: Vec::new(),
            ischemia_at_risk_mm2: None,
            dose: Err("no surface_dose.csv read".into()),
        }
    }
}

/// `metrics.csv` as named columns.
struct Table {
    names: Vec<String>,
    columns: Vec<Vec<f64>>,
}

impl Table {
    fn column(&self, name: &str) -> Option<&Vec<f64>> {
        self.names.iter().position(|n| n == name).map(|k| &self.columns[k])
    }
}

/// Reads a CSV whose every field is a number (an empty field, or a word such as `surface`, reads as NaN).
fn read_table(path: &Path, cap: Cap) -> Result<Table, DebriefReadError> {
    let text = crate::fsio::read_regular_text(path, cap)?;
    let mut lines = text.lines();
    let header = lines.next().filter(|h| !h.trim().is_empty()).ok_or_else(|| file_error(path, "empty: no header and no frames"))?;
    let names: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
    let mut columns = vec![Vec::new(); names.len()];
    for (k, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != names.len() {
            return Err(DebriefReadError::Line { path: path.to_path_buf(), line: k + 2, message: format!("{} fields, the header has {}", fields.len(), names.len()) });
        }
        for (column, field) in columns.iter_mut().zip(fields) {
            column.push(field.trim().parse::<f64>().unwrap_or(f64::NAN));
        }
    }
    Ok(Table { names, columns })
}

/// Reads a run folder. A folder without `metrics.csv` is refused naming it; a folder without `summary.json` is
/// read as an interrupted run (the replay writes the summary last).
pub fn read_run(dir: &Path) -> Result<RunData, DebriefReadError> {
    match std::fs::metadata(dir) {
        Err(_) => return Err(file_error(dir, "no such run folder")),
        Ok(m) if !m.is_dir() => return Err(file_error(dir, "not a folder: name a run folder (`fissure replay --out DIR` writes DIR/metrics.csv)")),
        Ok(_) => {}
    }
    let metrics = dir.join("metrics.csv");
    if std::fs::symlink_metadata(&metrics).is_err() {
        return Err(file_error(&metrics, "missing: not a run folder (`fissure replay --out DIR` writes DIR/metrics.csv and DIR/summary.json)"));
    }
    let table = read_table(&metrics, METRICS_CAP)?;
    let time_s = table.column("time_s").cloned().ok_or_else(|| file_error(&metrics, "no `time_s` column: not a fissure metrics.csv"))?;
    let mut blades = Vec::new();
    for name in &table.names {
        let Some(blade) = name.strip_suffix("_mean_pressure_mmhg").filter(|b| !b.is_empty()) else { continue };
        let need = |suffix: &str| table.column(&format!("{blade}{suffix}")).cloned().ok_or_else(|| file_error(&metrics, format!("`{name}` has no `{blade}{suffix}` column beside it")));
        let tip = match (table.column(&format!("{blade}_tip_x_mm")), table.column(&format!("{blade}_tip_y_mm")), table.column(&format!("{blade}_tip_z_mm"))) {
            (Some(x), Some(y), Some(z)) => Some(x.iter().zip(y).zip(z).map(|((&x, &y), &z)| [x, y, z]).collect()),
            _ => None,
        };
        blades.push(BladeTrack {
            name: blade.to_string(),
            force_n: need("_force_n")?,
            mean_pressure_mmhg: need("_mean_pressure_mmhg")?,
            contact_vertices: need("_contact_vertices")?,
            force_jump_n: table.column(&format!("{blade}_force_jump_n")).cloned(),
            tip_mm: tip,
            area_at_risk_mm2: table.column(&format!("{blade}_area_at_risk_mm2")).cloned(),
        });
    }
    if blades.is_empty() {
        return Err(file_error(&metrics, "no blade columns (NAME_force_n, NAME_mean_pressure_mmhg, NAME_contact_vertices): not a fissure metrics.csv"));
    }
    let mut run = RunData { dir: dir.to_path_buf(), time_s, blades, ischemia_at_risk_mm2: table.column("ischemia_at_risk_mm2").cloned(), ..Default::default() };
    read_summary(dir, &table, &mut run)?;
    run.dose = read_dose(dir);
    Ok(run)
}

fn read_summary(dir: &Path, table: &Table, run: &mut RunData) -> Result<(), DebriefReadError> {
    let path = dir.join("summary.json");
    if std::fs::symlink_metadata(&path).is_err() {
        run.interrupted = true;
        run.integrity_failures.push("no summary.json: the run stopped before writing it".into());
        return Ok(());
    }
    let text = crate::fsio::read_regular_text(&path, SUMMARY_CAP)?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| file_error(&path, format!("not a run summary: {e}")))?;
    let str_of = |v: &serde_json::Value, key: &str| v.get(key).and_then(serde_json::Value::as_str).map(String::from);
    let f64_of = |v: &serde_json::Value, key: &str| v.get(key).and_then(serde_json::Value::as_f64);
    run.scenario = str_of(&v, "scenario").filter(|s| !s.trim().is_empty());
    run.interrupted = v.get("interrupted").and_then(serde_json::Value::as_bool).unwrap_or(false);
    if let Some(list) = v.get("integrity").and_then(|i| i.get("failures")).and_then(serde_json::Value::as_array) {
        run.integrity_failures = list.iter().filter_map(|f| f.as_str().map(String::from)).collect();
    }
    for e in v.get("injuries").and_then(serde_json::Value::as_array).into_iter().flatten() {
        let (Some(time_s), Some(kind)) = (f64_of(e, "time_s"), str_of(e, "kind")) else {
            return Err(file_error(&path, "an injury without `time_s` or `kind`"));
        };
        run.injuries.push(Injury { time_s, kind, tether: str_of(e, "tether").unwrap_or_else(|| "?".into()) });
    }
    run.injuries.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    for vessel in v.get("vessels").and_then(serde_json::Value::as_array).into_iter().flatten() {
        let name = str_of(vessel, "name").unwrap_or_default();
        run.vessels.push(VesselFacts {
            stretch: table.column(&format!("{}_max_stretch", column_word(&name))).cloned(),
            max_stretch: f64_of(vessel, "max_stretch").unwrap_or(f64::NAN),
            warning_stretch: f64_of(vessel, "warning_stretch").unwrap_or(f64::NAN),
            rupture_stretch: f64_of(vessel, "rupture_stretch").unwrap_or(f64::NAN),
            torn: vessel.get("torn").and_then(serde_json::Value::as_bool).unwrap_or(false),
            name,
        });
    }
    if let Some(b) = v.get("bands").filter(|b| !b.is_null()) {
        let n = |k: &str| b.get(k).and_then(serde_json::Value::as_u64).unwrap_or(0) as u32;
        run.bands = Some((n("total"), n("torn"), n("cut")));
    }
    Ok(())
}

/// `surface_dose.csv`, or why there is none (older runs).
fn read_dose(dir: &Path) -> Result<Vec<DoseVertex>, String> {
    let path = dir.join(SURFACE_DOSE_FILE);
    if std::fs::symlink_metadata(&path).is_err() {
        return Err(format!("no {SURFACE_DOSE_FILE} in {}: the run was replayed before the replay wrote the per-vertex pressure", dir.display()));
    }
    let table = read_table(&path, DOSE_CAP).map_err(|e| e.to_string())?;
    if table.names.join(",") != SURFACE_DOSE_HEADER {
        return Err(format!("{}: the header is not `{SURFACE_DOSE_HEADER}`", path.display()));
    }
    let c = &table.columns;
    Ok((0..c[0].len())
        .map(|k| DoseVertex { position_mm: [c[0][k], c[1][k], c[2][k]], pressure_time_mmhg_s: c[3][k], peak_pressure_mmhg: c[4][k] })
        .collect())
}
