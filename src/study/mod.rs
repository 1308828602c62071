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
//! printed "exact", never drawn at an invented value); where that run's mesh
//! is not the base's, the runs on the base mesh are also measured against the
//! reference's settings on the base mesh, so the mesh's own error is told
//! apart from the other knobs' (`StudyPlan::mesh_reference`); a run that cannot be done
//! (no GPU adapter, a missing mesh) becomes a row that says why, never a
//! silent gap; the simulation is deterministic, only the times vary.

pub mod accuracy;
pub mod cache;
pub mod motion;
pub mod output;
pub mod plan;
pub mod plot;
pub mod runner;
pub mod runs_plot;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

pub use accuracy::{Accuracy, Comparison};
pub use motion::{FrameKey, Motion};
pub use plan::{Knob, MeshChoice, RoiChoice, RunSpec, Settings, StudyPlan, Sweep};
pub use runner::{RunError, RunTrace};

use crate::math::Vec3;
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
    /// A reduced plan on a short motion (the test suite re-runs it against `docs/study/ci/report.md`).
    Ci,
    /// A mesh family from files (the real brains by default): coarsest as the
    /// base, finest as the reference.
    Brain,
}

/// What `fissure study` was asked.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyOptions {
    pub preset: StudyPreset,
    /// A scenario file to study instead of the built-in scene (its first spatula moves).
    pub scene: Option<PathBuf>,
    /// Output folder (created).
    pub out_dir: PathBuf,
    /// Only these knobs' sweeps (all when empty); the reference always runs.
    pub knobs: Vec<Knob>,
    /// Mesh files (millimetres, coarsest to finest) for the mesh sweep; empty:
    /// the preset's own (the `brain` preset: the real brains beside the checkout).
    pub meshes: Vec<PathBuf>,
    /// Folder of the compliance cache and the reference run's trace
    /// (`None`: `compliance_cache` in the output folder).
    pub cache_dir: Option<PathBuf>,
}

impl StudyOptions {
    /// A preset into `out_dir`, every knob, the preset's meshes, the default cache.
    pub fn new(preset: StudyPreset, out_dir: PathBuf) -> Self {
        StudyOptions { preset, scene: None, out_dir, knobs: Vec::new(), meshes: Vec::new(), cache_dir: None }
    }
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
    #[error("mesh {}: {message}", path.display())]
    Mesh { path: PathBuf, message: String },
    #[error(
        "the brain preset needs a mesh family: brain_pial_coarse.msh.gz and brain_pial_q15.msh.gz are missing from {} (they ship with fissure: restore them from the repository), or pass --mesh COARSE.msh --mesh FINE.msh (millimetres)",
        dir.display()
    )]
    NoBrainMeshes { dir: PathBuf },
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
    /// A note for the row: why `accuracy` is `None`, or that the reference came from the cache.
    pub note: Option<String>,
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
    /// The force on the tissue along the path: (path position nm, F N) a
    /// frame, for the force-vs-path plot and the comparison with the sweep's
    /// finest run.
    pub force_along: Vec<(i64, Vec3)>,
    /// Force RMS / max error against this sweep's finest setting
    /// ([`Knob::finest`]), % of its peak: the knob's own convergence, with
    /// every other knob at the base. `None` for a knob without an order.
    pub against_finest: Option<(f64, f64)>,
    /// Against the plan's mesh reference (the reference's settings on this
    /// run's mesh), when the plan has one and this run is on its mesh.
    pub against_mesh_reference: Option<Accuracy>,
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
    /// The settings each sweep changed one knob of ([`StudyPlan::base`]).
    pub base: plan::Settings,
    /// What the report says about the plan's reference (see [`StudyPlan::notes`]).
    pub notes: Vec<String>,
    /// The motion every run replayed.
    pub motion: Motion,
    pub scene_name: String,
    pub rows: Vec<RunRow>,
    /// The plan's mesh reference ([`StudyPlan::mesh_reference`]), against
    /// the reference: what the mesh alone costs.
    pub mesh_reference: Option<RunRow>,
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
    let mesh_files = match (options.meshes.is_empty(), options.preset) {
        (false, _) => options.meshes.clone(),
        (true, StudyPreset::Brain) => plan::real_brain_family().ok_or_else(|| StudyError::NoBrainMeshes {
            dir: crate::mesh::brain::shipped_dir(),
        })?,
        (true, _) => Vec::new(),
    };
    let mut plan = plan::preset_plan(options.preset, &mesh_files);
    plan.retain_knobs(&options.knobs);
    let scene = load_scene(options.scene.as_deref())?;
    // Every mesh file loads before any run starts: a bad one stops the study here.
    let mut meshes = runner::MeshStore::default();
    for path in &mesh_files {
        let choice = MeshChoice::File { path: path.clone(), fix_height_m: plan::FILE_FIX_HEIGHT_M };
        meshes.get(&choice, &scene).map_err(|e| StudyError::Mesh { path: path.clone(), message: e.to_string() })?;
    }
    let cache = options.cache_dir.clone().unwrap_or_else(|| options.out_dir.join("compliance_cache"));
    run_plan_inner(&plan, &scene, &options.out_dir, &cache, meshes, progress, interrupt)
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

fn measure(trace: &RunTrace, motion: &Motion) -> RunMeasure {
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
        note: None,
        crossed_total: trace.frames.iter().map(|f| f.crossed as u64).sum(),
        penetrating_max: trace.frames.iter().map(|f| f.penetrating).max().unwrap_or(0),
        penetration_max_m: trace.frames.iter().map(|f| f.max_penetration_m).fold(0.0, f64::max),
        inverted_max: trace.frames.iter().map(|f| f.inverted).max().unwrap_or(0),
        peak_pressure_mmhg: trace.frames.iter().map(|f| f.pressure_mmhg).fold(0.0, f64::max),
        force_along: accuracy::force_along(trace, motion),
        against_finest: None,
        against_mesh_reference: None,
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
    run_plan_inner(plan, scene, out_dir, &out_dir.join("compliance_cache"), runner::MeshStore::default(), progress, interrupt)
}

/// The reference's trace: from the cache when a usable one is there, else run
/// (and saved). The second value says where it came from, for the report.
fn reference_trace(
    scene: &Scenario,
    spec: &RunSpec,
    plan: &StudyPlan,
    meshes: &mut runner::MeshStore,
    cache: &Path,
) -> Result<(RunTrace, Option<String>), RunError> {
    let study_mesh = meshes.get(&spec.settings.mesh, scene)?;
    let configured = runner::configure(scene, &spec.settings, &plan.motion, study_mesh, None);
    let key = cache::key(&configured, &spec.settings, &plan.motion, &study_mesh.mesh);
    if key.is_none() {
        tracing::warn!("the running executable cannot be read to key the reference cache; the reference runs and is not cached");
    }
    if let Some(key) = &key {
        match cache::load(cache, key) {
            Ok(Some(trace)) => return Ok((trace, Some("reference from the cache (its times are those of the run that made it)".into()))),
            Ok(None) => {}
            Err(why) => tracing::warn!("reference cache not used, running the reference again: {why}"),
        }
    }
    let trace = runner::execute(scene, &spec.settings, &plan.motion, meshes, Some(cache), true)?;
    if let Some(key) = &key
        && let Err(e) = cache::save(cache, key, &trace)
    {
        tracing::warn!("could not save the reference run's trace into {}: {e}", cache.display());
    }
    Ok((trace, None))
}

/// Each run of a sweep against the sweep's finest run (`finest`, an index
/// into `rows`): its force along the path, as the reference's force columns
/// compare it. Nothing when the finest run failed or there is no order.
fn against_finest(rows: &mut [RunRow], finest: Option<usize>) {
    let Some(fine) = finest.and_then(|f| rows.get(f)).and_then(|r| r.outcome.as_ref().ok()).map(|m| m.force_along.clone()) else { return };
    for m in rows.iter_mut().filter_map(|r| r.outcome.as_mut().ok()) {
        m.against_finest = Some(accuracy::force_error_pct(&fine, &m.force_along));
    }
}

/// A run's measure with its accuracy against the study's reference, or a
/// note that the reference failed.
fn measured_against(trace: &RunTrace, reference: &Result<(RunTrace, Option<String>), RunError>, spec: &RunSpec, plan: &StudyPlan) -> RunMeasure {
    let mut m = measure(trace, &plan.motion);
    match reference {
        Ok((r, _)) => m.accuracy = Some(accuracy::compare(r, trace, spec.settings.mesh == plan.reference.settings.mesh, &plan.motion)),
        Err(_) => m.note = Some("the reference run failed".into()),
    }
    m
}

/// The reference run's row: measured against itself (the comparison marked as the reference), or its error.
fn reference_row(spec: &RunSpec, reference: &Result<(RunTrace, Option<String>), RunError>, plan: &StudyPlan) -> RunRow {
    RunRow {
        knob: None,
        label: spec.label.clone(),
        value: spec.value,
        settings: spec.settings.clone(),
        outcome: match reference {
            Ok((t, note)) => {
                let mut m = measure(t, &plan.motion);
                m.accuracy = Some(Accuracy { comparison: Comparison::Reference, ..accuracy::compare(t, t, true, &plan.motion) });
                m.note = note.clone();
                Ok(m)
            }
            Err(e) => Err(e.to_string()),
        },
    }
}

fn run_plan_inner(
    plan: &StudyPlan,
    scene: &Scenario,
    out_dir: &Path,
    cache: &Path,
    mut meshes: runner::MeshStore,
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
    let mut rows = Vec::with_capacity(total);
    let spec = &plan.reference;
    progress(StudyProgress { done: 0, total, label: format!("reference: {}", spec.label) });
    interrupted |= stopped();
    let reference = if interrupted { Err(RunError::Interrupted) } else { reference_trace(scene, spec, plan, &mut meshes, cache) };
    rows.push(reference_row(spec, &reference, plan));
    let mut done = 1;
    let mesh_reference = plan.mesh_reference.as_ref().map(|spec| {
        progress(StudyProgress { done, total, label: format!("mesh reference: {}", spec.label) });
        done += 1;
        interrupted |= stopped();
        let trace = if interrupted { Err(RunError::Interrupted) } else { reference_trace(scene, spec, plan, &mut meshes, cache) };
        let row = RunRow {
            knob: None,
            label: spec.label.clone(),
            value: spec.value,
            settings: spec.settings.clone(),
            outcome: match &trace {
                Ok((t, note)) => {
                    let mut m = measured_against(t, &reference, spec, plan);
                    m.note = m.note.or_else(|| note.clone());
                    Ok(m)
                }
                Err(e) => Err(e.to_string()),
            },
        };
        (row, trace.ok().map(|(t, _)| t))
    });
    let (mesh_reference, mesh_trace) = mesh_reference.map_or((None, None), |(row, t)| (Some(row), t));
    for sweep in &plan.sweeps {
        let first = rows.len();
        for spec in &sweep.runs {
            progress(StudyProgress { done, total, label: format!("{}: {}", sweep.knob.name(), spec.label) });
            interrupted |= stopped();
            let outcome = if interrupted {
                Err(NOT_RUN_INTERRUPTED.to_string())
            } else {
                runner::execute(scene, &spec.settings, &plan.motion, &mut meshes, Some(cache), true).map_err(|e| e.to_string())
            };
            done += 1;
            let outcome = outcome.map(|trace| {
                let mut m = measured_against(&trace, &reference, spec, plan);
                if let (Some(mr), Some(mesh_spec)) = (&mesh_trace, &plan.mesh_reference)
                    && spec.settings.mesh == mesh_spec.settings.mesh
                {
                    m.against_mesh_reference = Some(accuracy::compare(mr, &trace, true, &plan.motion));
                }
                m
            });
            rows.push(RunRow { knob: Some(sweep.knob), label: spec.label.clone(), value: spec.value, settings: spec.settings.clone(), outcome });
        }
        against_finest(&mut rows[first..], sweep.knob.finest(&sweep.runs.iter().map(|r| r.value).collect::<Vec<_>>()));
    }
    progress(StudyProgress { done: total, total, label: "writing the report".into() });
    let mut results = StudyResults {
        plan_name: plan.name.clone(),
        base: plan.base.clone(),
        notes: plan.notes.clone(),
        motion: plan.motion,
        scene_name: scene.name.clone(),
        rows,
        mesh_reference,
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
