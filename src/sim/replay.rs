//! Headless replay: a scenario and a trajectory in, metrics, a summary and
//! optionally a ParaView series out.
//!
//! In: a validated [`Scenario`], an optional trajectory (else the scenario's,
//! else the spatulas hold their initial poses), an output folder. Out:
//! `metrics.csv` (a row a frame, flushed as written), `summary.json`, and with
//! `vtk` a `series.pvd` + `frame_NNNNN.vtu` per frame (deformed mesh with point
//! displacement and cell stress / strain / region), and `surface_dose.csv`: per
//! surface vertex at rest, the time integral of its contact pressure (mmHg s)
//! and its peak (mmHg) over the frames played. Stays true: an error or an
//! interruption (the `interrupt` flag, set by Ctrl-C in the CLI) stops the loop
//! with every row written so far valid; the summary is still written, marked
//! `interrupted`.

use super::build::BuildOptions;
use super::error::BuildError;
use super::metrics::{MetricsWriter, OutputError, Summary, SummaryBuilder, write_summary};
use super::pipeline::{FrameInput, Pipeline, SimState, StepError};
use super::report::StageId;
use crate::mesh::io::{Field, FieldData, save_tet_mesh, write_pvd};
use crate::scenario::Scenario;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Errors of a replay.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error(transparent)]
    Build(#[from] BuildError),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error("writing VTK output: {0}")]
    Vtk(#[from] crate::mesh::io::MeshFileError),
    #[error("{source} (the {frames} frames before it are in {dir}/metrics.csv)")]
    Step { source: StepError, frames: u64, dir: PathBuf },
    #[error("{0}")]
    Frames(String),
}

/// What to write beyond `metrics.csv` and `summary.json`.
#[derive(Debug, Clone, Default)]
pub struct ReplayOptions {
    /// Output folder (created).
    pub out_dir: PathBuf,
    /// A trajectory file overriding the scenario's.
    pub trajectory: Option<PathBuf>,
    /// Write the ParaView series.
    pub vtk: bool,
}

/// Writes one `.vtu` of the current state (interior solved here if the
/// pipeline has no stress stage).
pub fn write_vtu(pipeline: &mut Pipeline, state: &mut SimState, path: &Path) -> Result<(), ReplayError> {
    let frame = state.frame;
    let node_u = pipeline.node_displacement(state).map_err(|source| ReplayError::Step { source, frames: frame, dir: path.to_path_buf() })?;
    let mut mesh = pipeline.mesh().clone();
    for (p, u) in mesh.positions.iter_mut().zip(&node_u) {
        *p += u;
    }
    let mut fields = FieldData::default();
    fields.point.push(("displacement".into(), Field::Vector(node_u)));
    if !state.stress.is_empty() {
        fields.cell.push(("von_mises_pa".into(), Field::Scalar(state.stress.iter().map(|s| s.von_mises).collect())));
        fields.cell.push(("max_principal_strain".into(), Field::Scalar(state.stress.iter().map(|s| s.max_principal_strain).collect())));
    }
    save_tet_mesh(path, &mesh, &fields)?;
    Ok(())
}

/// Runs a whole replay. `on_frame(done, total)` is called after every frame
/// (progress bars, PNG frames); returning an error stops the replay like any other.
pub fn replay(
    scenario: &Scenario,
    options: &ReplayOptions,
    interrupt: &AtomicBool,
    on_frame: &mut dyn FnMut(&mut Pipeline, &SimState, u64, u64) -> Result<(), String>,
    compliance_progress: Option<&mut dyn FnMut(usize, usize)>,
) -> Result<Summary, ReplayError> {
    let checked = super::preflight::preflight(scenario, options.trajectory.as_deref())?;
    checked.log_warnings();
    let source = checked.poses;
    let (mut pipeline, mut state) = Pipeline::build_checked(
        scenario,
        checked.mesh,
        BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: compliance_progress, ..BuildOptions::default() },
    )?;
    std::fs::create_dir_all(&options.out_dir).map_err(|e| OutputError::new(&options.out_dir, e))?;
    let stages = pipeline.built_stages();
    let names = pipeline.spatula_names().to_vec();
    let vessel_names: Option<Vec<String>> = pipeline.tethers().map(|t| t.vessel_names().map(|(n, _)| n.to_string()).collect());
    let columns = super::metrics::EffectColumns { vessels: vessel_names.as_deref(), ischemia: pipeline.ischemia().is_some() };
    let mut writer = MetricsWriter::create_with(&options.out_dir.join("metrics.csv"), &stages, &names, columns)?;
    let mut summary = summary_for(scenario, &pipeline, &stages, &names);
    let total = scenario.step_count();
    let dt = scenario.time_step;
    let mut input = FrameInput::default();
    let mut pvd: Vec<(f64, String)> = Vec::new();
    let mut failure: Option<ReplayError> = None;
    let mut dose = SurfaceDose::new(&pipeline);
    for k in 0..total {
        if interrupt.load(Ordering::Relaxed) {
            break;
        }
        source.poses_at((k + 1) as f64 * dt, &mut input);
        source.request_frame_cuts(k, dt, &mut pipeline);
        // The report borrows the pipeline only until it is written (no per-frame copy).
        match pipeline.step(&mut state, &input) {
            Ok(report) => {
                if let Err(e) = writer.write(report) {
                    failure = Some(e.into());
                    break;
                }
                summary.add(report, dt);
                dose.add(&pipeline, dt);
            }
            Err(e) => {
                failure = Some(ReplayError::Step { source: e, frames: k, dir: options.out_dir.clone() });
                break;
            }
        }
        if options.vtk {
            let name = format!("frame_{k:05}.vtu");
            if let Err(e) = write_vtu(&mut pipeline, &mut state, &options.out_dir.join(&name)) {
                failure = Some(e);
                break;
            }
            pvd.push((state.time_s, name));
            if let Err(e) = write_pvd(&options.out_dir.join("series.pvd"), &pvd) {
                failure = Some(e.into());
                break;
            }
        }
        if let Err(e) = on_frame(&mut pipeline, &state, k + 1, total) {
            failure = Some(ReplayError::Frames(e));
            break;
        }
    }
    let interrupted = failure.is_some() || summary_frames(&summary) < total;
    let hash = match pipeline.state_hash(&state) {
        Ok(h) => h,
        Err(e) => {
            let frames = summary_frames(&summary);
            failure.get_or_insert(ReplayError::Step { source: e, frames, dir: options.out_dir.clone() });
            String::new()
        }
    };
    let mut result = summary.finish(hash, interrupted);
    if let Some(c) = pipeline.collision() {
        result.collision_backend = Some(format!("{:?}", c.backend()).to_lowercase());
        result.collision_notes = c.warnings().to_vec();
    }
    let written = write_summary(&options.out_dir.join("summary.json"), &result)
        .and_then(|()| dose.write(&options.out_dir.join(SURFACE_DOSE_FILE), pipeline.rest_positions()));
    match failure {
        Some(e) => Err(e),
        None => {
            written?;
            Ok(result)
        }
    }
}

/// The summary a replay of `scenario` on `pipeline` fills: its stages, spatulas, integrity limits, tethers,
/// ischemia and compliance.
fn summary_for(scenario: &Scenario, pipeline: &Pipeline, stages: &[StageId], names: &[String]) -> SummaryBuilder {
    let mut summary = SummaryBuilder::new(&scenario.name, stages, names).with_limits(scenario.run.integrity);
    if let Some(t) = pipeline.tethers() {
        summary = summary.with_tethers(t.tethers());
    }
    if let Some(i) = pipeline.ischemia() {
        summary = summary.with_ischemia(i.model().mean_arterial_pressure_mmhg);
    }
    let cs = pipeline.solver().compliance().stats();
    summary.set_compliance(super::metrics::ComplianceSummary {
        rows: cs.rows,
        surface_vertices: pipeline.surface().vertices.len(),
        columns: cs.cols,
        megabytes: cs.bytes as f64 / 1e6,
    });
    summary
}

/// The per-vertex pressure file a replay writes beside `metrics.csv`.
pub const SURFACE_DOSE_FILE: &str = "surface_dose.csv";
/// Its header: the vertex's rest position, its pressure-time integral and its peak pressure.
pub const SURFACE_DOSE_HEADER: &str = "x_mm,y_mm,z_mm,pressure_time_mmhg_s,peak_pressure_mmhg";

/// Per surface vertex, the integral of its contact pressure over the frames played (mmHg s) and its peak (mmHg):
/// where on the brain the blades pressed, and for how long. A frame's pressure is the ischemia stage's relaxed
/// pressure when the scene has one, else the tool rows' reactions over the rest areas
/// ([`super::contact::vertex_pressures_mmhg`]).
struct SurfaceDose {
    areas_m2: Vec<f64>,
    frame_mmhg: Vec<f64>,
    dose_mmhg_s: Vec<f64>,
    peak_mmhg: Vec<f64>,
}

impl SurfaceDose {
    fn new(pipeline: &Pipeline) -> Self {
        let n = pipeline.surface().vertices.len();
        let areas_m2 = crate::mesh::surface::vertex_areas(pipeline.rest_positions(), &pipeline.surface().triangles);
        Self { areas_m2, frame_mmhg: Vec::with_capacity(n), dose_mmhg_s: vec![0.0; n], peak_mmhg: vec![0.0; n] }
    }

    /// Adds the pipeline's last frame, of `dt` seconds.
    fn add(&mut self, pipeline: &Pipeline, dt: f64) {
        let pressures: &[f64] = match pipeline.ischemia() {
            Some(i) => i.pressure_mmhg(),
            None => {
                let solution = pipeline.last_solution();
                super::contact::vertex_pressures_mmhg(pipeline.surface(), pipeline.last_constraints(), &solution.reactions, &self.areas_m2, pipeline.relaxation_ratios(), &mut self.frame_mmhg);
                &self.frame_mmhg
            }
        };
        for ((dose, peak), &p) in self.dose_mmhg_s.iter_mut().zip(&mut self.peak_mmhg).zip(pressures) {
            if p > 0.0 {
                *dose += p * dt;
                *peak = peak.max(p);
            }
        }
    }

    /// Writes the file whole: a row per surface vertex at its rest position (mm).
    fn write(&self, path: &Path, rest_m: &[crate::math::Vec3]) -> Result<(), OutputError> {
        use std::fmt::Write as _;
        let mut text = String::with_capacity(64 * rest_m.len() + 64);
        text.push_str(SURFACE_DOSE_HEADER);
        text.push('\n');
        for ((x, dose), peak) in rest_m.iter().zip(&self.dose_mmhg_s).zip(&self.peak_mmhg) {
            let _ = writeln!(text, "{},{},{},{},{}", x.x * 1e3, x.y * 1e3, x.z * 1e3, dose, peak);
        }
        crate::fsio::write_atomic(path, text.as_bytes()).map_err(|e| OutputError::new(path, e.source))
    }
}

fn summary_frames(s: &SummaryBuilder) -> u64 {
    s.frames()
}
