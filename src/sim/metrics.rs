//! Replay outputs: `metrics.csv` (one row a frame) and `summary.json`.
//!
//! In: [`FrameReport`]s in frame order. Out: a CSV whose every row is flushed as
//! it is written (an error or Ctrl-C leaves the rows so far valid) and a summary
//! with percentiles per stage, peak pressures, pressure-time above the 20 mmHg
//! line and the final-state hash. Stays true: the non-timing columns are a pure
//! function of the reports (bitwise deterministic replays give identical bytes);
//! timing columns end in `_ms`.

use crate::math::Vec3;
use super::report::{FrameReport, PASCALS_PER_MMHG, RETRACTION_DANGER_MMHG, StageId};
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Errors writing outputs; each names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct OutputError {
    pub path: PathBuf,
    #[source]
    pub source: io::Error,
}

impl OutputError {
    pub fn new(path: &Path, source: io::Error) -> Self {
        Self { path: path.to_path_buf(), source }
    }
}

/// Writes `metrics.csv` row by row: each row is one `write_all` to the file;
/// a failed write (e.g. a full disk) truncates the file back to the last whole
/// row, so what is there always parses.
pub struct MetricsWriter {
    out: File,
    /// Bytes of whole rows written so far.
    committed: u64,
    path: PathBuf,
    stages: Vec<StageId>,
    spatulas: usize,
    /// Each spatula's force in the previous row (zero before the first).
    previous_force: Vec<Vec3>,
    /// Vessels of the tether columns (`None`: the scene has no tethers, no columns).
    vessels: Option<usize>,
    /// The ischemia columns (the scene has the `Ischemia` effect).
    ischemia: bool,
    line: String,
}

/// The columns a scene's effects add to `metrics.csv`.
#[derive(Debug, Clone, Copy, Default)]
pub struct EffectColumns<'a> {
    /// The scene's vessels' names (the `Tethers` effect).
    pub vessels: Option<&'a [String]>,
    /// The `Ischemia` effect.
    pub ischemia: bool,
}

impl MetricsWriter {
    /// Creates the file and writes the header. `stages` are the built stages;
    /// `spatula_names` name the per-spatula columns.
    pub fn create(path: &Path, stages: &[StageId], spatula_names: &[String]) -> Result<Self, OutputError> {
        Self::create_with(path, stages, spatula_names, EffectColumns::default())
    }

    /// As [`Self::create`], with the columns of the scene's effects. Tethers (`vessels` given): each vessel's
    /// largest stretch this frame (`<vessel>_max_stretch`, the name with every character that is not a letter or
    /// digit as `_`), then `bands_intact`, `bands_torn`, `bands_cut`, `max_band_tension_n`. Ischemia: the area
    /// whose risk is at or over each level (`ischemia_watch_mm2`, `ischemia_at_risk_mm2`, `ischemia_likely_mm2`:
    /// risks 1/6, 1/2, 5/6), `ischemia_max_dose_mmhg_min`, `ischemia_max_risk`, `low_perfusion_longest_s` (the
    /// longest current stretch of a vertex with its perfusion pressure under 10 mmHg), then each blade's
    /// `<blade>_area_at_risk_mm2`.
    pub fn create_with(path: &Path, stages: &[StageId], spatula_names: &[String], effects: EffectColumns<'_>) -> Result<Self, OutputError> {
        let vessel_names = effects.vessels;
        let file = File::create(path).map_err(|e| OutputError::new(path, e))?;
        let mut w = Self {
            out: file,
            committed: 0,
            path: path.to_path_buf(),
            stages: stages.to_vec(),
            spatulas: spatula_names.len(),
            previous_force: vec![Vec3::zeros(); spatula_names.len()],
            vessels: vessel_names.map(<[String]>::len),
            ischemia: effects.ischemia,
            line: String::new(),
        };
        let mut header = vec!["frame".to_string(), "time_s".to_string()];
        header.extend(stages.iter().map(|s| format!("{}_ms", s.name())));
        header.push("frame_ms".into());
        for name in spatula_names {
            for col in ["candidate_pairs", "culled_pairs", "feasible_pairs", "constrained_vertices", "force_n", "force_x_n", "force_y_n", "force_z_n", "contact_area_mm2", "contact_vertices", "mean_pressure_mmhg", "force_jump_n", "tip_x_mm", "tip_y_mm", "tip_z_mm"] {
                header.push(format!("{name}_{col}"));
            }
        }
        header.extend(
            ["constrained_vertices", "skull_contacts", "max_displacement_mm", "inverted_elements", "inverted_scope", "crossed_vertices", "penetrating_vertices", "max_penetration_mm", "rejected_poses", "max_von_mises_pa", "substeps", "solver_capped"]
                .map(String::from),
        );
        if let Some(names) = vessel_names {
            header.extend(names.iter().map(|n| format!("{}_max_stretch", column_word(n))));
            header.extend(["bands_intact", "bands_torn", "bands_cut", "max_band_tension_n"].map(String::from));
        }
        if effects.ischemia {
            header.extend(crate::scenario::tissue_time::RISK_LEVELS.iter().map(|(_, word)| format!("ischemia_{word}_mm2")));
            header.extend(["ischemia_max_dose_mmhg_min", "ischemia_max_risk", "low_perfusion_longest_s"].map(String::from));
            header.extend(spatula_names.iter().map(|n| format!("{n}_area_at_risk_mm2")));
        }
        w.line = header.join(",");
        w.write_line()?;
        Ok(w)
    }

    fn write_line(&mut self) -> Result<(), OutputError> {
        use std::io::{Seek, SeekFrom};
        self.line.push('\n');
        let r = self.out.write_all(self.line.as_bytes());
        let len = self.line.len() as u64;
        self.line.clear();
        match r {
            Ok(()) => {
                self.committed += len;
                Ok(())
            }
            Err(e) => {
                // Drop the torn tail: the file ends at the last whole row.
                let _ = self.out.set_len(self.committed);
                let _ = self.out.seek(SeekFrom::Start(self.committed));
                Err(OutputError::new(&self.path, e))
            }
        }
    }

    /// Appends one frame and flushes it to the file.
    pub fn write(&mut self, r: &FrameReport) -> Result<(), OutputError> {
        use std::fmt::Write as _;
        let l = &mut self.line;
        let _ = write!(l, "{},{}", r.frame, r.time_s);
        for s in &self.stages {
            let _ = write!(l, ",{:.4}", r.times.get(*s).unwrap_or(0.0) * 1e3);
        }
        let _ = write!(l, ",{:.4}", r.times.total() * 1e3);
        for k in 0..self.spatulas {
            let s = r.spatulas.get(k).copied().unwrap_or_default();
            let jump = (s.force - self.previous_force[k]).norm();
            self.previous_force[k] = s.force;
            let _ = write!(
                l,
                ",{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                s.candidate_pairs,
                s.culled_pairs,
                s.feasible_pairs,
                s.constrained_vertices,
                s.force.norm(),
                s.force.x,
                s.force.y,
                s.force.z,
                s.contact_area_m2 * 1e6,
                s.contact_vertices,
                s.mean_pressure_mmhg(),
                jump,
                s.tip.x * 1e3,
                s.tip.y * 1e3,
                s.tip.z * 1e3
            );
        }
        let _ = write!(
            l,
            ",{},{},{},{},{},{},{},{},{},{},{},{}",
            r.constrained_vertices,
            r.skull_contacts,
            r.max_displacement_m * 1e3,
            r.inverted_elements,
            if r.inverted_scope_all { "all" } else { "surface" },
            r.crossed_vertices,
            r.penetrating_vertices,
            r.max_penetration_m * 1e3,
            r.rejected_poses,
            r.max_von_mises_pa.map(|v| v.to_string()).unwrap_or_default(),
            r.substeps,
            u8::from(r.solver_capped)
        );
        if let Some(vessels) = self.vessels {
            let t = r.tethers.clone().unwrap_or_default();
            for k in 0..vessels {
                let _ = write!(l, ",{}", t.vessel_stretch.get(k).copied().unwrap_or(0.0));
            }
            let _ = write!(l, ",{},{},{},{}", t.bands_intact, t.bands_torn, t.bands_cut, t.max_band_tension_n);
        }
        if self.ischemia {
            let i = r.ischemia.clone().unwrap_or_default();
            for a in i.area_over_m2 {
                let _ = write!(l, ",{}", a * 1e6);
            }
            let _ = write!(l, ",{},{},{}", i.max_dose_mmhg_s / 60.0, i.max_risk, i.longest_low_perfusion_s);
            for k in 0..self.spatulas {
                let _ = write!(l, ",{}", i.blade_area_at_risk_m2.get(k).copied().unwrap_or(0.0) * 1e6);
            }
        }
        self.write_line()
    }
}

/// A name as a CSV column word: letters and digits kept, everything else `_`.
pub fn column_word(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
}

/// p50 / p95 / max of a sample, milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Percentiles {
    pub p50_ms: f64,
    pub p95_ms: f64,
    pub max_ms: f64,
}

impl Percentiles {
    /// Nearest-rank percentiles of `seconds` (empty -> zeros).
    pub fn of(seconds: &[f64]) -> Self {
        if seconds.is_empty() {
            return Self::default();
        }
        let mut v = seconds.to_vec();
        v.sort_by(|a, b| a.total_cmp(b));
        Self { p50_ms: nearest_rank(&v, 0.5) * 1e3, p95_ms: nearest_rank(&v, 0.95) * 1e3, max_ms: v[v.len() - 1] * 1e3 }
    }
}

/// The nearest-rank `p` quantile of a sorted, non-empty sample.
fn nearest_rank(sorted: &[f64], p: f64) -> f64 {
    sorted[((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1]
}

/// Per-spatula summary numbers.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SpatulaSummary {
    pub name: String,
    pub peak_force_n: f64,
    pub peak_pressure_mmhg: f64,
    /// Time the mean pressure spent above 20 mmHg, s.
    pub time_above_20mmhg_s: f64,
    /// Integral of (pressure - 20 mmHg) over the time above it, mmHg*s.
    pub pressure_time_above_20mmhg_mmhg_s: f64,
    /// Largest change of the force vector from one frame to the next, N
    /// (what a hand on a haptic device feels as a jolt).
    pub max_force_jump_n: f64,
    /// 95th percentile (nearest rank) of those changes over the frames, N.
    pub p95_force_jump_n: f64,
}

/// `summary.json`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub scenario: String,
    pub frames: u64,
    pub simulated_s: f64,
    /// Percentiles per built stage.
    pub stages: Vec<(StageId, Percentiles)>,
    /// Percentiles of the whole frame.
    pub frame: Percentiles,
    pub spatulas: Vec<SpatulaSummary>,
    /// The worst the tissue came to over the run (in `summary.json` at this level).
    #[serde(flatten)]
    pub worst: Worst,
    pub rejected_poses: u64,
    /// Most sub-steps one frame was split into (fast tools).
    pub max_substeps: u32,
    /// Frames whose contact solve hit its iteration cap (each kept the last feasible state).
    pub capped_frames: u64,
    /// blake3 of the final surface displacements (f64 bits) and His-flags: equal for bitwise-equal replays.
    pub final_state_hash: String,
    /// True when the run stopped early (error or interruption); the rows so far are valid.
    pub interrupted: bool,
    /// The collision backend in use at the end (after an `auto` choice or a GPU
    /// fallback); None without the collision stage.
    pub collision_backend: Option<String>,
    /// What the collision stage said: the `auto` choice, a GPU fallback and its cause.
    pub collision_notes: Vec<String>,
    /// Whether the run kept the tissue whole: penetration, inverted elements and
    /// tunnelling against the scene's limits (`replay --strict` fails on them).
    pub integrity: Integrity,
    /// The precomputed compliance the frames read: what the scene's working region costs.
    pub compliance: ComplianceSummary,
    /// Every tether torn or cut, in the order it happened (empty without tethers).
    pub injuries: Vec<super::tethers::TetherEvent>,
    /// Each vessel's largest stretch over the run (empty without tethers).
    pub vessels: Vec<VesselSummary>,
    /// The arachnoid bands at the end (None without tethers).
    pub bands: Option<BandSummary>,
    /// Injury from retractor pressure over time (None without the `Ischemia` effect).
    pub ischemia: Option<IschemiaSummary>,
}

/// The worst the tissue came to over a run, each the largest over its frames.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Worst {
    pub max_displacement_mm: f64,
    /// Surface vertices pulled through a blade in one frame.
    pub max_crossed_vertices: u32,
    /// Surface vertices inside a blade at the end of one frame.
    pub max_penetrating_vertices: u32,
    pub max_inverted_elements: u32,
    /// Deepest penetration of a surface vertex into a blade at the end of a frame, mm.
    pub max_penetration_mm: f64,
}

/// Ischemia over a run: areas, dose, perfusion.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct IschemiaSummary {
    pub mean_arterial_pressure_mmhg: f64,
    /// The largest area over each risk level during the run.
    pub levels: Vec<RiskLevelSummary>,
    /// The largest dose of any vertex, mmHg min, its risk, and when it was reached, s.
    pub max_dose_mmhg_min: f64,
    pub max_risk: f64,
    pub max_dose_time_s: f64,
    /// The longest stretch of any vertex with its perfusion pressure under 10 mmHg, s, and whether it passed the
    /// six minutes after which five of six patients infarcted.
    pub longest_low_perfusion_s: f64,
    pub low_perfusion_over_tolerance: bool,
    /// Per blade: its largest area at risk (even odds) and when it first had any.
    pub blades: Vec<BladeRisk>,
}

/// One risk level over a run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RiskLevelSummary {
    /// `watch` (1/6), `at_risk` (1/2), `likely` (5/6).
    pub level: String,
    pub risk: f64,
    /// The largest area at or over it, mm^2, and the area at the end.
    pub max_area_mm2: f64,
    pub final_area_mm2: f64,
    /// When a vertex first reached it, s.
    pub first_time_s: Option<f64>,
}

/// One blade's share of the area at risk.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BladeRisk {
    pub name: String,
    pub max_area_at_risk_mm2: f64,
    pub first_at_risk_s: Option<f64>,
}

/// A vessel over the run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct VesselSummary {
    pub name: String,
    /// `artery`, `vein` or `bridging vein`.
    pub kind: String,
    /// Largest stretch of any of its segments (length over rest length).
    pub max_stretch: f64,
    pub warning_stretch: f64,
    pub rupture_stretch: f64,
    pub torn: bool,
}

/// The arachnoid bands at the end of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct BandSummary {
    pub total: u32,
    pub intact: u32,
    pub torn: u32,
    pub cut: u32,
    /// Largest tension an intact band carried, N.
    pub max_tension_n: f64,
}

/// The size of a run's precomputed compliance.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ComplianceSummary {
    /// Surface vertices with stored rows (the working region), of all surface vertices.
    pub rows: usize,
    pub surface_vertices: usize,
    /// Stored columns (the region of interest's vertices).
    pub columns: usize,
    pub megabytes: f64,
}

pub use crate::scenario::IntegrityLimits;

/// The verdict on a run's integrity.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Integrity {
    /// True when no limit was crossed.
    pub passed: bool,
    pub limits: IntegrityLimits,
    /// One line per crossed limit: the worst value, the limit and the first frame that crossed it.
    pub failures: Vec<String>,
}

/// Accumulates the summary as frames arrive.
#[derive(Debug, Default)]
pub struct SummaryBuilder {
    limits: IntegrityLimits,
    /// First frame (and time) that crossed each limit: penetration, inverted, crossed.
    first_violation: [Option<(u64, f64)>; 3],
    stages: Vec<StageId>,
    stage_seconds: Vec<Vec<f64>>,
    frame_seconds: Vec<f64>,
    summary: Summary,
    last_time: f64,
    /// Each spatula's force in the previous frame and its frame-to-frame changes so far.
    previous_force: Vec<Vec3>,
    force_jumps: Vec<Vec<f64>>,
    /// First frame (and time) the torn vessels passed the scene's limit.
    first_torn_over: Option<(u64, f64)>,
}

impl SummaryBuilder {
    pub fn new(scenario: &str, stages: &[StageId], spatula_names: &[String]) -> Self {
        Self {
            stages: stages.to_vec(),
            stage_seconds: vec![Vec::new(); stages.len()],
            summary: Summary {
                scenario: scenario.to_string(),
                spatulas: spatula_names.iter().map(|n| SpatulaSummary { name: n.clone(), ..Default::default() }).collect(),
                ..Default::default()
            },
            previous_force: vec![Vec3::zeros(); spatula_names.len()],
            force_jumps: vec![Vec::new(); spatula_names.len()],
            ..Default::default()
        }
    }

    /// Records the size of the compliance the run reads.
    pub fn set_compliance(&mut self, compliance: ComplianceSummary) {
        self.summary.compliance = compliance;
    }

    /// Names the scene's vessels (their limits) and bands, so the summary reports them.
    pub fn with_tethers(mut self, tethers: &crate::scenario::Tethers) -> Self {
        self.summary.vessels = tethers
            .vessels
            .iter()
            .map(|v| VesselSummary {
                name: v.name.clone(),
                kind: v.kind.word().into(),
                max_stretch: 1.0,
                warning_stretch: v.warning_stretch,
                rupture_stretch: v.rupture_stretch,
                torn: false,
            })
            .collect();
        self.summary.bands = Some(BandSummary { total: tethers.bands.len() as u32, intact: tethers.bands.len() as u32, ..Default::default() });
        self
    }

    /// Reports ischemia (the `Ischemia` effect) at the scene's mean arterial pressure.
    pub fn with_ischemia(mut self, mean_arterial_pressure_mmhg: f64) -> Self {
        let levels = crate::scenario::tissue_time::RISK_LEVELS.iter().map(|&(risk, word)| RiskLevelSummary { level: word.into(), risk, ..Default::default() }).collect();
        let blades = self.summary.spatulas.iter().map(|s| BladeRisk { name: s.name.clone(), ..Default::default() }).collect();
        self.summary.ischemia = Some(IschemiaSummary { mean_arterial_pressure_mmhg, levels, blades, ..Default::default() });
        self
    }

    /// Sets the integrity limits the summary judges the run by (default: [`IntegrityLimits::default`]).
    pub fn with_limits(mut self, limits: IntegrityLimits) -> Self {
        self.limits = limits;
        self
    }

    /// Adds a frame; `dt` is the frame's simulated duration.
    pub fn add(&mut self, r: &FrameReport, dt: f64) {
        let crossed = [
            r.max_penetration_m * 1e3 > self.limits.max_penetration_mm,
            r.inverted_elements > self.limits.max_inverted_elements,
            r.crossed_vertices > self.limits.max_crossed_vertices,
        ];
        for (first, now) in self.first_violation.iter_mut().zip(crossed) {
            if now && first.is_none() {
                *first = Some((r.frame, r.time_s));
            }
        }
        for (k, s) in self.stages.iter().enumerate() {
            if let Some(t) = r.times.get(*s) {
                self.stage_seconds[k].push(t);
            }
        }
        self.frame_seconds.push(r.times.total());
        let danger_pa = RETRACTION_DANGER_MMHG * PASCALS_PER_MMHG;
        for (k, (acc, s)) in self.summary.spatulas.iter_mut().zip(&r.spatulas).enumerate() {
            let jump = (s.force - self.previous_force[k]).norm();
            self.previous_force[k] = s.force;
            self.force_jumps[k].push(jump);
            acc.max_force_jump_n = acc.max_force_jump_n.max(jump);
            acc.peak_force_n = acc.peak_force_n.max(s.force.norm());
            acc.peak_pressure_mmhg = acc.peak_pressure_mmhg.max(s.mean_pressure_mmhg());
            if s.mean_pressure_pa > danger_pa {
                acc.time_above_20mmhg_s += dt;
                acc.pressure_time_above_20mmhg_mmhg_s += (s.mean_pressure_mmhg() - RETRACTION_DANGER_MMHG) * dt;
            }
        }
        let m = &mut self.summary;
        m.frames += 1;
        m.worst.max_displacement_mm = m.worst.max_displacement_mm.max(r.max_displacement_m * 1e3);
        m.worst.max_crossed_vertices = m.worst.max_crossed_vertices.max(r.crossed_vertices);
        m.worst.max_penetrating_vertices = m.worst.max_penetrating_vertices.max(r.penetrating_vertices);
        m.worst.max_inverted_elements = m.worst.max_inverted_elements.max(r.inverted_elements);
        m.worst.max_penetration_mm = m.worst.max_penetration_mm.max(r.max_penetration_m * 1e3);
        m.rejected_poses += r.rejected_poses as u64;
        m.max_substeps = m.max_substeps.max(r.substeps);
        m.capped_frames += u64::from(r.solver_capped);
        if let Some(t) = &r.tethers {
            for (v, (&stretch, &torn)) in m.vessels.iter_mut().zip(t.vessel_stretch.iter().zip(&t.vessel_torn)) {
                v.max_stretch = v.max_stretch.max(stretch);
                v.torn |= torn;
            }
            if let Some(b) = &mut m.bands {
                (b.intact, b.torn, b.cut) = (t.bands_intact, t.bands_torn, t.bands_cut);
                b.max_tension_n = b.max_tension_n.max(t.max_band_tension_n);
            }
            m.injuries.extend(t.events.iter().cloned());
            let torn = m.vessels.iter().filter(|v| v.torn).count() as u32;
            if torn > self.limits.max_torn_vessels && self.first_torn_over.is_none() {
                self.first_torn_over = Some((r.frame, r.time_s));
            }
        }
        if let (Some(i), Some(frame)) = (&mut m.ischemia, &r.ischemia) {
            for (level, &area) in i.levels.iter_mut().zip(&frame.area_over_m2) {
                level.max_area_mm2 = level.max_area_mm2.max(area * 1e6);
                level.final_area_mm2 = area * 1e6;
                if area > 0.0 && level.first_time_s.is_none() {
                    level.first_time_s = Some(r.time_s);
                }
            }
            if frame.max_dose_mmhg_s / 60.0 > i.max_dose_mmhg_min {
                (i.max_dose_mmhg_min, i.max_risk, i.max_dose_time_s) = (frame.max_dose_mmhg_s / 60.0, frame.max_risk, r.time_s);
            }
            i.longest_low_perfusion_s = i.longest_low_perfusion_s.max(frame.longest_low_perfusion_s);
            i.low_perfusion_over_tolerance = i.longest_low_perfusion_s > crate::scenario::tissue_time::RCPP_TOLERANCE_S;
            for (b, &area) in i.blades.iter_mut().zip(&frame.blade_area_at_risk_m2) {
                b.max_area_at_risk_mm2 = b.max_area_at_risk_mm2.max(area * 1e6);
                if area > 0.0 && b.first_at_risk_s.is_none() {
                    b.first_at_risk_s = Some(r.time_s);
                }
            }
        }
        self.last_time = r.time_s;
    }

    /// Frames added so far.
    pub fn frames(&self) -> u64 {
        self.summary.frames
    }

    /// The finished summary.
    pub fn finish(mut self, final_state_hash: String, interrupted: bool) -> Summary {
        self.summary.stages = self.stages.iter().zip(&self.stage_seconds).map(|(s, v)| (*s, Percentiles::of(v))).collect();
        self.summary.frame = Percentiles::of(&self.frame_seconds);
        for (acc, jumps) in self.summary.spatulas.iter_mut().zip(&mut self.force_jumps) {
            if !jumps.is_empty() {
                jumps.sort_by(|a, b| a.total_cmp(b));
                acc.p95_force_jump_n = nearest_rank(jumps, 0.95);
            }
        }
        self.summary.simulated_s = self.last_time;
        self.summary.final_state_hash = final_state_hash;
        self.summary.interrupted = interrupted;
        let (m, l) = (&self.summary, self.limits);
        let worst = [
            format!("max penetration into a blade {:.3} mm > {} mm", m.worst.max_penetration_mm, l.max_penetration_mm),
            format!("inverted elements {} > {}", m.worst.max_inverted_elements, l.max_inverted_elements),
            format!("vertices pulled through a blade {} > {}", m.worst.max_crossed_vertices, l.max_crossed_vertices),
        ];
        let torn = m.vessels.iter().filter(|v| v.torn).count();
        let torn_text = format!("torn vessels {torn} > {}", l.max_torn_vessels);
        let failures = worst
            .into_iter()
            .zip(self.first_violation)
            .chain([(torn_text, self.first_torn_over)])
            .filter_map(|(text, first)| first.map(|(frame, t)| format!("{text} (first at frame {frame}, t = {t:.2} s)")))
            .collect::<Vec<_>>();
        self.summary.integrity = Integrity { passed: failures.is_empty(), limits: l, failures };
        self.summary
    }
}

/// Writes `summary` as pretty JSON, whole or not at all (a temporary file
/// renamed over `path`: a full disk leaves no empty or truncated summary).
pub fn write_summary(path: &Path, summary: &Summary) -> Result<(), OutputError> {
    let text = serde_json::to_string_pretty(summary).map_err(|e| OutputError::new(path, io::Error::other(e)))?;
    crate::fsio::write_atomic(path, (text + "\n").as_bytes()).map_err(|e| OutputError::new(path, e.source))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_use_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(|k| k as f64 * 1e-3).collect();
        let p = Percentiles::of(&v);
        assert_eq!((p.p50_ms, p.p95_ms, p.max_ms), (50.0, 95.0, 100.0));
    }

    #[test]
    fn pressure_time_accumulates_only_above_the_line() {
        let mut b = SummaryBuilder::new("t", &[], &["a".into()]);
        let mut r = FrameReport { spatulas: vec![Default::default()], ..Default::default() };
        r.spatulas[0].mean_pressure_pa = 30.0 * PASCALS_PER_MMHG;
        b.add(&r, 0.1);
        r.spatulas[0].mean_pressure_pa = 10.0 * PASCALS_PER_MMHG;
        b.add(&r, 0.1);
        let s = b.finish(String::new(), false);
        assert!((s.spatulas[0].time_above_20mmhg_s - 0.1).abs() < 1e-12);
        assert!((s.spatulas[0].pressure_time_above_20mmhg_mmhg_s - 1.0).abs() < 1e-9);
        assert!((s.spatulas[0].peak_pressure_mmhg - 30.0).abs() < 1e-9);
    }

    #[test]
    fn force_jumps_are_the_changes_of_the_force_vector_between_frames() {
        let mut b = SummaryBuilder::new("t", &[], &["a".into()]);
        let mut r = FrameReport { spatulas: vec![Default::default()], ..Default::default() };
        // 0 -> 1 N along x (jump 1), -> 1 N along y (jump sqrt 2), held (jump 0).
        for force in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)] {
            r.spatulas[0].force = force;
            b.add(&r, 0.01);
        }
        let s = b.finish(String::new(), false);
        assert_eq!(s.spatulas[0].max_force_jump_n, 2f64.sqrt());
        assert_eq!(s.spatulas[0].p95_force_jump_n, 2f64.sqrt(), "nearest rank of three: the largest");
        // metrics.csv carries the same change on each row.
        let dir = std::env::temp_dir().join(format!("fissure-jumps-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("metrics.csv");
        let mut w = MetricsWriter::create(&path, &[], &["a".into()]).unwrap();
        for force in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)] {
            r.spatulas[0].force = force;
            w.write(&r).unwrap();
        }
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
        let col = rows[0].iter().position(|h| *h == "a_force_jump_n").expect("a force-jump column");
        assert_eq!(rows[1][col].parse::<f64>().unwrap(), 1.0);
        assert_eq!(rows[2][col].parse::<f64>().unwrap(), 2f64.sqrt());
    }

    #[test]
    fn integrity_fails_on_each_crossed_limit_and_names_the_first_frame() {
        let mut b = SummaryBuilder::new("t", &[], &[]);
        let mut r = FrameReport { frame: 0, time_s: 0.01, max_penetration_m: 0.04e-3, ..Default::default() };
        b.add(&r, 0.01);
        r = FrameReport { frame: 1, time_s: 0.02, max_penetration_m: 0.18e-3, inverted_elements: 1, ..Default::default() };
        b.add(&r, 0.01);
        let s = b.finish(String::new(), false);
        assert!(!s.integrity.passed);
        assert_eq!(s.integrity.failures.len(), 2, "{:?}", s.integrity.failures);
        assert!(s.integrity.failures[0].contains("0.180 mm > 0.05 mm") && s.integrity.failures[0].contains("frame 1"), "{:?}", s.integrity.failures);
        let mut b = SummaryBuilder::new("t", &[], &[]).with_limits(IntegrityLimits { max_penetration_mm: 0.2, max_inverted_elements: 1, max_crossed_vertices: 0, max_torn_vessels: 0 });
        b.add(&r, 0.01);
        assert!(b.finish(String::new(), false).integrity.passed, "within the scene's own limits");
    }
}
