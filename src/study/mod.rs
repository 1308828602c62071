//! `fissure study`: what accuracy costs in time.
//!
//! In: [`StudyOptions`] (a preset, an optional scene file, an output folder)
//! or a hand-made [`StudyPlan`]. Each run replays the study motion (insert a
//! spatula into a fissure, open it sideways, close, withdraw; see [`motion`])
//! with one knob changed: source nodes and layout, mesh resolution, speed a
//! frame in blade thicknesses, collision backend and culling, compliance
//! storage, region of interest, contact model, sub-steps. Out: in the folder,
//! `results.csv` (a row a run: stage medians and p95s, build cost, every
//! error), `report.md` (tables, the budget table, the paper's numbers beside
//! ours) and the plots (`pareto`, `knobs`, `budget`, `fig13_collision_vs_nodes`,
//! `speed_vs_error`, each `.png` and `.svg`); the same rows come back as
//! [`StudyResults`]. Stays true: every run's accuracy is measured against one
//! reference run for the whole study, the finest setting of every knob at
//! once, which no swept run equals by construction (an error of exactly 0 is
//! printed "exact", never drawn at an invented value); a run that cannot be done
//! (no GPU adapter, a missing mesh) becomes a row that says why, never a
//! silent gap; the simulation is deterministic, only the times vary.

pub mod accuracy;
pub mod motion;
pub mod output;
pub mod plan;
pub mod plot;
pub mod runner;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

pub use accuracy::{Accuracy, Comparison};
pub use motion::{FrameKey, Motion};
pub use plan::{Knob, MeshChoice, RoiChoice, RunSpec, Settings, StudyPlan, Sweep};
pub use runner::{RunError, RunTrace};

use crate::scenario::{Scenario, ScenarioError};
use crate::sim::StageId;

/// The built-in study scene (`config/study_fissure.ron`), used when no scene is given.
pub const DEFAULT_SCENE: &str = include_str!("../../config/study_fissure.ron");

/// Which set of sweeps to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StudyPreset {
    /// The paper-9k phantom, every knob, a few values (minutes).
    Quick,
    /// The paper-12k phantom, more values, all meshes.
    Full,
    /// A reduced plan on a short motion (the test suite re-runs it against `docs/study/ci.md`).
    Ci,
}

/// What `fissure study` was asked.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyOptions {
    pub preset: StudyPreset,
    /// A scenario file to study instead of the built-in scene (its first spatula moves).
    pub scene: Option<PathBuf>,
    /// Output folder (created).
    pub out_dir: PathBuf,
}

/// Progress: `done` of `total` runs finished; `label` names the run starting (or "done").
#[derive(Debug, Clone, PartialEq)]
pub struct StudyProgress {
    pub done: usize,
    pub total: usize,
    pub label: String,
}

/// Errors that stop a study (a single run's failure does not: its row says why).
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("study scene {scene}: {message}")]
    Scene { scene: PathBuf, message: String },
    #[error("writing {}: {source}", path.display())]
    Output { path: PathBuf, source: std::io::Error },
    #[error("drawing {}: {message}", path.display())]
    Plot { path: PathBuf, message: String },
    #[error("the plan has no runs")]
    EmptyPlan,
}

/// Median and 95th percentile (nearest rank), seconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Percentiles {
    pub p50: f64,
    pub p95: f64,
}

impl Percentiles {
    /// Of `values` (any order); zeros when empty.
    pub fn of(values: &mut [f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        values.sort_by(f64::total_cmp);
        let rank = |q: f64| values[((q * values.len() as f64).ceil() as usize).clamp(1, values.len()) - 1];
        Self { p50: rank(0.5), p95: rank(0.95) }
    }
}

/// What a successful run measured.
#[derive(Debug, Clone, PartialEq)]
pub struct RunMeasure {
    pub frames: usize,
    pub mesh_nodes: usize,
    pub surface_triangles: usize,
    /// Build (assembly, factorization, compliance or its cache), s.
    pub build_s: f64,
    pub compliance_bytes: usize,
    pub compliance_cached: bool,
    /// Per built stage, in frame order.
    pub stages: Vec<(StageId, Percentiles)>,
    /// The whole frame (sum of the stages, monitor included).
    pub frame: Percentiles,
    /// Against the study's reference; `None` when there is none to compare with.
    pub accuracy: Option<Accuracy>,
    /// Why `accuracy` is `None`.
    pub no_accuracy: Option<String>,
    /// Vertices pulled through a blade, summed over frames (tunnelling).
    pub crossed_total: u64,
    /// Most vertices inside a blade in one frame.
    pub penetrating_max: u32,
    /// Deepest penetration over the run, m.
    pub penetration_max_m: f64,
    /// Most inverted elements after a frame.
    pub inverted_max: u32,
    /// Highest mean contact pressure of the run, mmHg.
    pub peak_pressure_mmhg: f64,
}

impl RunMeasure {
    /// The p50/p95 of a stage, if it was built.
    pub fn stage(&self, id: StageId) -> Option<Percentiles> {
        self.stages.iter().find(|(s, _)| *s == id).map(|(_, p)| *p)
    }
}

/// One row of the results.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRow {
    /// The sweep; `None` for the study's reference run.
    pub knob: Option<Knob>,
    pub label: String,
    pub value: f64,
    pub settings: Settings,
    /// The measurement, or why the run could not be done.
    pub outcome: Result<RunMeasure, String>,
}

impl RunRow {
    /// The study's reference run (the one row of no sweep).
    pub fn is_reference(&self) -> bool {
        self.knob.is_none()
    }
}

/// Everything a study produced.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyResults {
    pub plan_name: String,
    /// The motion every run replayed.
    pub motion: Motion,
    pub scene_name: String,
    pub rows: Vec<RunRow>,
    /// Files written, in order.
    pub files: Vec<PathBuf>,
    /// Wall time of the whole study, s.
    pub elapsed_s: f64,
    /// True when an interruption stopped the study: the runs not done are rows
    /// that say so, and every output is still written.
    pub interrupted: bool,
}

/// The outcome of a run skipped because the study was interrupted.
pub const NOT_RUN_INTERRUPTED: &str = "not run: the study was interrupted (Ctrl-C)";

/// Runs a preset study.
pub fn run_study(options: &StudyOptions, progress: &mut dyn FnMut(StudyProgress)) -> Result<StudyResults, StudyError> {
    run_study_until(options, progress, &AtomicBool::new(false))
}

/// [`run_study`] that stops starting runs once `interrupt` is set (the CLI's
/// entry point; Ctrl-C sets it): see [`run_plan_until`].
pub fn run_study_until(
    options: &StudyOptions,
    progress: &mut dyn FnMut(StudyProgress),
    interrupt: &AtomicBool,
) -> Result<StudyResults, StudyError> {
    let plan = plan::preset_plan(options.preset);
    let scene = load_scene(options.scene.as_deref())?;
    run_plan_until(&plan, &scene, &options.out_dir, progress, interrupt)
}

/// The study scene: `path`, or the built-in one.
pub fn load_scene(path: Option<&Path>) -> Result<Scenario, StudyError> {
    let scene = match path {
        Some(p) => Scenario::load(p, &[])?,
        None => {
            let origin = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/study_fissure.ron"));
            Scenario::from_str(DEFAULT_SCENE, origin, &[])?
        }
    };
    if scene.spatulas.is_empty() {
        return Err(StudyError::Scene { scene: scene.source_path.clone(), message: "the study moves the first spatula; there is none".into() });
    }
    Ok(scene)
}

fn measure(trace: &RunTrace) -> RunMeasure {
    let mut stages = Vec::new();
    for id in StageId::ALL {
        let mut v: Vec<f64> = trace.frames.iter().filter_map(|f| f.times.get(id)).collect();
        if !v.is_empty() {
            stages.push((id, Percentiles::of(&mut v)));
        }
    }
    let mut total: Vec<f64> = trace.frames.iter().map(|f| f.times.total()).collect();
    RunMeasure {
        frames: trace.frames.len(),
        mesh_nodes: trace.nodes,
        surface_triangles: trace.triangles.len(),
        build_s: trace.build_s,
        compliance_bytes: trace.compliance_bytes,
        compliance_cached: trace.compliance_cached,
        stages,
        frame: Percentiles::of(&mut total),
        accuracy: None,
        no_accuracy: None,
        crossed_total: trace.frames.iter().map(|f| f.crossed as u64).sum(),
        penetrating_max: trace.frames.iter().map(|f| f.penetrating).max().unwrap_or(0),
        penetration_max_m: trace.frames.iter().map(|f| f.max_penetration_m).fold(0.0, f64::max),
        inverted_max: trace.frames.iter().map(|f| f.inverted).max().unwrap_or(0),
        peak_pressure_mmhg: trace.frames.iter().map(|f| f.pressure_mmhg).fold(0.0, f64::max),
    }
}

/// Runs `plan` on `scene`, writes the outputs into `out_dir`.
pub fn run_plan(
    plan: &StudyPlan,
    scene: &Scenario,
    out_dir: &Path,
    progress: &mut dyn FnMut(StudyProgress),
) -> Result<StudyResults, StudyError> {
    run_plan_until(plan, scene, out_dir, progress, &AtomicBool::new(false))
}

/// [`run_plan`] that starts no further run once `interrupt` is set: the run
/// under way finishes, the runs left become rows saying
/// [`NOT_RUN_INTERRUPTED`], every output is written and the results say
/// `interrupted`.
pub fn run_plan_until(
    plan: &StudyPlan,
    scene: &Scenario,
    out_dir: &Path,
    progress: &mut dyn FnMut(StudyProgress),
    interrupt: &AtomicBool,
) -> Result<StudyResults, StudyError> {
    let stopped = || interrupt.load(Ordering::Relaxed);
    let mut interrupted = false;
    let start = Instant::now();
    let total = plan.run_count();
    if total == 0 {
        return Err(StudyError::EmptyPlan);
    }
    std::fs::create_dir_all(out_dir).map_err(|source| StudyError::Output { path: out_dir.to_path_buf(), source })?;
    let cache = out_dir.join("compliance_cache");
    let mut meshes = runner::MeshStore::default();
    let mut rows = Vec::with_capacity(total);
    let spec = &plan.reference;
    progress(StudyProgress { done: 0, total, label: format!("reference: {}", spec.label) });
    interrupted |= stopped();
    let reference = if interrupted {
        Err(RunError::Interrupted)
    } else {
        runner::execute(scene, &spec.settings, &plan.motion, &mut meshes, Some(&cache), true)
    };
    rows.push(RunRow {
        knob: None,
        label: spec.label.clone(),
        value: spec.value,
        settings: spec.settings.clone(),
        outcome: match &reference {
            Ok(t) => {
                let mut m = measure(t);
                m.accuracy = Some(Accuracy { comparison: Comparison::Reference, ..accuracy::compare(t, t, true) });
                Ok(m)
            }
            Err(e) => Err(e.to_string()),
        },
    });
    let mut done = 1;
    for sweep in &plan.sweeps {
        for spec in &sweep.runs {
            progress(StudyProgress { done, total, label: format!("{}: {}", sweep.knob.name(), spec.label) });
            interrupted |= stopped();
            let outcome = if interrupted {
                Err(NOT_RUN_INTERRUPTED.to_string())
            } else {
                runner::execute(scene, &spec.settings, &plan.motion, &mut meshes, Some(&cache), true).map_err(|e| e.to_string())
            };
            done += 1;
            let outcome = outcome.map(|trace| {
                let mut m = measure(&trace);
                let other_anatomy = matches!(spec.settings.mesh, MeshChoice::File { .. }) != matches!(plan.reference.settings.mesh, MeshChoice::File { .. });
                match &reference {
                    Ok(r) if !other_anatomy => m.accuracy = Some(accuracy::compare(r, &trace, spec.settings.mesh == plan.reference.settings.mesh)),
                    Ok(_) => m.no_accuracy = Some("other anatomy: timed only".into()),
                    Err(_) => m.no_accuracy = Some("the reference run failed".into()),
                }
                m
            });
            rows.push(RunRow { knob: Some(sweep.knob), label: spec.label.clone(), value: spec.value, settings: spec.settings.clone(), outcome });
        }
    }
    progress(StudyProgress { done: total, total, label: "writing the report".into() });
    let mut results = StudyResults {
        plan_name: plan.name.clone(),
        motion: plan.motion,
        scene_name: scene.name.clone(),
        rows,
        files: Vec::new(),
        elapsed_s: 0.0,
        interrupted,
    };
    results.elapsed_s = start.elapsed().as_secs_f64();
    results.files.push(output::write_csv(&results, &out_dir.join("results.csv"))?);
    results.files.extend(plot::draw_all(&results, out_dir)?);
    results.files.push(output::write_report(&results, &out_dir.join("report.md"))?);
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_rank() {
        let mut v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let p = Percentiles::of(&mut v);
        assert_eq!((p.p50, p.p95), (50.0, 95.0));
        assert_eq!(Percentiles::of(&mut []), Percentiles::default());
    }

    #[test]
    fn the_built_in_scene_validates() {
        let s = load_scene(None).expect("config/study_fissure.ron is valid");
        assert!(!s.spatulas.is_empty());
    }
}
