//! Binary-only CLI: clap definitions and one function per subcommand.
//!
//! In: parsed arguments. Out: text on stdout (or JSON where asked) and an
//! `anyhow::Result` whose chain `main` prints ([`Interrupted`] for Ctrl-C,
//! exit 130). Library errors are typed; this layer only adds context (which
//! file, which command).

mod bench;
mod check;
mod debrief;
mod frames;
mod mesh;
mod plot;
mod replay;
mod run;
mod study;
mod screenshot;
mod solve;
mod units;

use std::path::PathBuf;

use clap::{Parser, Subcommand};

/// A command stopped by Ctrl-C after it wrote everything it had done; `main`
/// prints the message and exits 130, so a script can tell an interrupted run
/// from a finished one.
#[derive(Debug, thiserror::Error)]
#[error("interrupted by Ctrl-C {what}")]
pub struct Interrupted {
    /// How far it got and where the partial results are, e.g. "after 12 of 300
    /// frames; partial results in out/ (summary.json says \"interrupted\": true)".
    pub what: String,
}

/// `replay --strict` on a run whose integrity verdict failed (penetration,
/// inverted elements or tunnelling beyond the scene's limits); every output
/// is written; `main` exits 3.
#[derive(Debug, thiserror::Error)]
#[error("integrity check failed: {what}")]
pub struct IntegrityFailed {
    pub what: String,
}

/// The default scene, run by a bare `fissure`.
pub const DEFAULT_SCENARIO: &str = "config/sylvian.ron";

/// fissure: a real-time simulator for opening a brain fissure with two spatulas.
///
/// With no subcommand, runs the default scene (config/sylvian.ron).
#[derive(Debug, Parser)]
#[command(name = "fissure", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the simulator on a scenario (default: config/sylvian.ron).
    Run {
        /// The scenario (.ron).
        scenario: Option<PathBuf>,
        /// Override one field: PATH=VALUE (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Run without a window: play the scenario's trajectory and print the timings.
        #[arg(long)]
        headless: bool,
        #[command(flatten)]
        window: run::WindowArgs,
    },
    /// Render one frame of a scenario to a PNG, offscreen (no display needed).
    Screenshot(screenshot::ScreenshotArgs),
    /// Play a scenario headless from a trajectory: metrics.csv, summary.json, optional VTK / PNG frames.
    Replay {
        /// The scenario (.ron).
        scenario: PathBuf,
        /// Override one field: PATH=VALUE (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Trajectory (.csv) to play instead of the scenario's.
        #[arg(long)]
        trajectory: Option<PathBuf>,
        /// Output folder (default: the scenario's outputs.dir).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also write a ParaView series (series.pvd + one .vtu a frame).
        #[arg(long)]
        vtk: bool,
        /// Also write a PNG a frame (DIR/frames/), rendered offscreen.
        #[arg(long)]
        frames: bool,
        /// Exit 3 when the run fails its integrity limits (scenario `integrity`:
        /// penetration into a blade, inverted elements, tissue pulled through).
        #[arg(long)]
        strict: bool,
    },
    /// Plot replay runs against time: force, mean contact pressure (with the 20 mmHg
    /// line) and contact vertices per blade; several runs overlay, a colour a run.
    Plot(plot::PlotArgs),
    /// Score and explain a trainee's run: a self-contained HTML page (verdicts per blade against a reference run
    /// and the literature's limits, what to do differently, the timeline, a map of where pressure was applied)
    /// and its numbers as JSON beside it.
    Debrief(debrief::DebriefArgs),
    /// Measure what accuracy costs in time: sweeps, results.csv, report.md and plots.
    Study {
        /// quick (minutes, paper-9k: the README's table), full (paper-12k, three phantom resolutions), ci (a short plan the tests re-run against docs/study/ci/report.md) or brain (the real brains, coarse against q15: the shipped assets/brain/ or --mesh).
        #[arg(long, value_enum, default_value = "quick")]
        preset: StudyPresetArg,
        /// The study scene (default: config/study_fissure.ron).
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Run only this knob's sweep (repeatable; the reference always runs): source_nodes, mesh, speed, contact, substeps, backend, storage, region_of_interest, skull, refine.
        #[arg(long = "knob", value_name = "KNOB")]
        knobs: Vec<String>,
        /// A tet mesh in millimetres for the mesh sweep (repeatable, coarsest first; the last is the reference's); two bodies: the spatula enters the gap between them.
        #[arg(long = "mesh", value_name = "MESH")]
        meshes: Vec<PathBuf>,
        /// Folder of the compliance cache and the reference run's trace, kept between studies (default: OUT/compliance_cache).
        #[arg(long)]
        cache_dir: Option<PathBuf>,
    },
    /// Validate a scenario as replay would (mesh, fixed nodes, skull, trajectory; no frames) and print a summary (exit 0 when valid).
    Check {
        /// The scenario (.ron).
        scenario: PathBuf,
        /// Override one field: PATH=VALUE, e.g. material.poisson_ratio=0.49 (repeatable).
        #[arg(long = "set", value_name = "PATH=VALUE")]
        set: Vec<String>,
        /// Trajectory (.csv) to check instead of the scenario's, as `replay --trajectory` plays it.
        #[arg(long)]
        trajectory: Option<PathBuf>,
    },
    /// One static linear-elastic solve on a mesh with fixed and enforced nodes (JSON lists): displacements and reactions to a .vtu.
    Solve(solve::SolveArgs),
    /// Mesh tools: inspect, generate phantoms, tetrahedralize surfaces, convert.
    #[command(subcommand)]
    Mesh(MeshCommand),
    /// Benchmarks that run from the release binary alone (e.g. on a GPU machine).
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Collision stage per backend in one run: paper-12k at 150 / 500 / 2000 nodes a
    /// face and both real brains at 500 / 2000, p50 / p95 a frame, the GPU's breakdown.
    Collision(bench::CollisionArgs),
}

#[derive(Debug, Subcommand)]
pub enum MeshCommand {
    /// Counts, connected components and element quality of a tet mesh (.msh, .vtk, .vtu, .node/.ele).
    Info {
        /// The mesh file.
        path: PathBuf,
        /// Print JSON (keys nodes, tets, surface_triangles, components, inverted, min_dihedral_deg, ...).
        #[arg(long)]
        json: bool,
    },
    /// Generate a procedural phantom (coordinates in metres) and print its landmarks.
    Phantom {
        /// small, paper-9k, paper-12k, v-valley or u-shape.
        #[arg(long)]
        preset: String,
        /// Output mesh (.msh, .vtk, .vtu, .node/.ele).
        #[arg(short, long)]
        output: PathBuf,
        /// Print only the quality report, as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Fill a closed surface (.obj, .stl) with quality tetrahedra (isosurface stuffing).
    Tetrahedralize {
        /// The closed surface.
        surface: PathBuf,
        /// Output mesh (.msh, .vtk, .vtu, .node/.ele), in the surface's unit.
        #[arg(short, long)]
        output: PathBuf,
        /// Lattice edge length with its unit, e.g. 2.5mm.
        #[arg(long, value_parser = units::parse_length)]
        edge: f64,
        /// Unit of the surface's coordinates.
        #[arg(long, value_enum, default_value = "mm")]
        surface_units: SurfaceUnits,
    },
    /// Convert a tet mesh (.msh, .vtk, .vtu, .node/.ele) or a surface (.obj, .stl); formats by extension.
    Convert {
        /// Input file.
        input: PathBuf,
        /// Output file.
        output: PathBuf,
    },
}

/// Study presets.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum StudyPresetArg {
    Quick,
    Full,
    Ci,
    Brain,
}

/// Length unit of a surface or mesh file.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum SurfaceUnits {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
}

/// Runs one parsed command line.
pub fn dispatch(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        None => run::run(None, &[], false, &run::WindowArgs::default()),
        Some(Command::Run { scenario, set, headless, window }) => run::run(scenario.as_deref(), &set, headless, &window),
        Some(Command::Screenshot(args)) => screenshot::run(&args),
        Some(Command::Replay { scenario, set, trajectory, out, vtk, frames, strict }) => {
            replay::run(replay::ReplayArgs { scenario: &scenario, set: &set, trajectory, out, vtk, frames, strict }).map(|_| ())
        }
        Some(Command::Plot(args)) => plot::run(&args),
        Some(Command::Debrief(args)) => debrief::run(&args),
        Some(Command::Study { preset, scene, out, knobs, meshes, cache_dir }) => {
            let preset = match preset {
                StudyPresetArg::Quick => fissure::study::StudyPreset::Quick,
                StudyPresetArg::Full => fissure::study::StudyPreset::Full,
                StudyPresetArg::Ci => fissure::study::StudyPreset::Ci,
                StudyPresetArg::Brain => fissure::study::StudyPreset::Brain,
            };
            study::run(fissure::study::StudyOptions { preset, scene, out_dir: out, knobs: study::knobs(&knobs)?, meshes, cache_dir })
        }
        Some(Command::Check { scenario, set, trajectory }) => check::run(&scenario, &set, trajectory.as_deref()),
        Some(Command::Solve(args)) => solve::run(&args),
        Some(Command::Mesh(MeshCommand::Info { path, json })) => mesh::info(&path, json),
        Some(Command::Mesh(MeshCommand::Phantom { preset, output, json })) => mesh::phantom(&preset, &output, json),
        Some(Command::Mesh(MeshCommand::Tetrahedralize { surface, output, edge, surface_units })) => {
            let units = match surface_units {
                SurfaceUnits::Mm => fissure::scenario::LengthUnit::Millimetres,
                SurfaceUnits::M => fissure::scenario::LengthUnit::Metres,
            };
            mesh::tetrahedralize(&surface, &output, edge, units)
        }
        Some(Command::Mesh(MeshCommand::Convert { input, output })) => mesh::convert(&input, &output),
        Some(Command::Bench(BenchCommand::Collision(args))) => bench::collision(&args),
    }
}
