//! `fissure screenshot SCENARIO -o out.png [--time S] [--size WxH] [--view ..] [--field ..]`:
//! builds the pipeline, plays the scenario's trajectory (or holds the initial
//! poses) to `--time`, and renders one frame offscreen (works on the software
//! Vulkan driver; no display needed), through the same drawing code as the
//! window and `replay --frames`; a shown field gets the window's colour bar
//! (units, ticks, the 20 mmHg line on pressure, whose scale is the scenario's
//! `display.pressure_max_mmhg`, the levels 1/6, 1/2, 5/6 on infarct risk).
//! With the `Relaxation` effect the pressure shown is the relaxed one.

use std::path::PathBuf;

use anyhow::Context;
use fissure::app::draw::{DrawOptions, SurfaceField, ViewPreset};
use fissure::render::capture;
use fissure::scenario::Scenario;
use fissure::sim::poses::TrajectoryPoses;
use fissure::sim::{BuildOptions, FrameInput, FrameReport, Pipeline};

/// Camera preset.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ViewArg {
    Overview,
    Microscope,
}

/// Surface colour.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FieldArg {
    None,
    Displacement,
    Pressure,
    /// Largest principal strain (computed for the shown frame when the scene has no StressField stage).
    Strain,
    /// Risk of infarct under the retractors, 0 to 1 (a scene with the `Ischemia` effect).
    Risk,
}

#[derive(Debug, clap::Args)]
pub struct ScreenshotArgs {
    /// The scenario (.ron).
    pub scenario: PathBuf,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Simulated time to play to, seconds (0: the initial state).
    #[arg(long, default_value_t = 0.0)]
    pub time: f64,
    /// Image size, WIDTHxHEIGHT pixels.
    #[arg(long, default_value = "1280x800", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Camera preset.
    #[arg(long, value_enum, default_value = "overview")]
    pub view: ViewArg,
    /// Surface colour.
    #[arg(long, value_enum, default_value = "none")]
    pub field: FieldArg,
    /// Also draw source nodes and pairs (feasible green, culled red).
    #[arg(long)]
    pub overlays: bool,
    /// Override one field: PATH=VALUE (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
}

/// Parses `WIDTHxHEIGHT` (each 1..=8192).
pub fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(|| format!("expected WIDTHxHEIGHT, got `{text}`"))?;
    let parse = |s: &str| s.trim().parse::<u32>().ok().filter(|v| (1..=8192).contains(v));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("width and height must be whole numbers in 1..=8192, got `{text}`")),
    }
}

pub fn run(args: &ScreenshotArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.time.is_finite() && args.time >= 0.0, "--time must be a finite number of seconds >= 0, got {}", args.time);
    let scenario = Scenario::load(&args.scenario, &args.set).with_context(|| format!("loading {}", args.scenario.display()))?;
    // Risk is dosed frame by frame by the `Ischemia` stage: a scene without it has none to show (fail before building).
    anyhow::ensure!(
        !matches!(args.field, FieldArg::Risk) || scenario.tissue_time.ischemia.is_some(),
        "--field risk needs the Ischemia effect, and scene '{}' ({}) does not list it in `effects` (Ischemia, with ContactPressure: docs/usage.md, Tissue over time)",
        scenario.name,
        args.scenario.display()
    );
    let source = TrajectoryPoses::for_scenario(&scenario, None).context("loading the scenario's trajectory")?;
    let (mut pipeline, mut state) = Pipeline::build(
        &scenario,
        BuildOptions { expected_poses: source.samples(scenario.duration.max(args.time), 200), progress: None, ..BuildOptions::default() },
    )
    .with_context(|| format!("building {}", args.scenario.display()))?;
    let dt = scenario.time_step;
    let steps = ((args.time / dt) - 1e-9).ceil().max(0.0) as u64;
    let mut input = FrameInput::default();
    let mut report = FrameReport::default();
    for k in 0..steps {
        source.poses_at((k + 1) as f64 * dt, &mut input);
        source.request_frame_cuts(k, dt, &mut pipeline);
        report = pipeline.step(&mut state, &input).with_context(|| format!("frame {k}"))?.clone();
    }
    if matches!(args.field, FieldArg::Strain) && state.stress.is_empty() {
        // No StressField stage: the stress of this one frame, on demand.
        let u = pipeline.node_displacement(&state).context("interior displacements for --field strain")?;
        fissure::fem::element_stress(pipeline.solver().model(), &u, &mut state.stress).context("stress for --field strain")?;
    }
    let options = DrawOptions {
        field: match args.field {
            FieldArg::None => SurfaceField::None,
            FieldArg::Displacement => SurfaceField::Displacement,
            FieldArg::Pressure => SurfaceField::Pressure,
            FieldArg::Strain => SurfaceField::Strain,
            FieldArg::Risk => SurfaceField::Risk,
        },
        source_nodes: args.overlays,
        pairs: args.overlays,
        skull: false,
        pressure_max_mmhg: scenario.display.pressure_max_mmhg,
        views: scenario.display.views,
    };
    let view = match args.view {
        ViewArg::Overview => ViewPreset::Overview,
        ViewArg::Microscope => ViewPreset::Microscope,
    };
    let mut frames = super::frames::OffscreenFrames::new(args.size, options, view);
    // the whole surface, the far part brought up to date
    let whole = pipeline.with_whole_surface(&state)?;
    let image = frames.render(&pipeline, &whole, &report)?;
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    capture::save_png(&image, &args.output).with_context(|| format!("writing {}", args.output.display()))?;
    let forces: Vec<String> = pipeline
        .spatula_names()
        .iter()
        .zip(&report.spatulas)
        .map(|(n, s)| format!("{n} {:.3} N, {:.1} mmHg", s.force.norm(), s.mean_pressure_mmhg()))
        .collect();
    println!(
        "wrote {} ({}x{}) at t = {:.3} s after {steps} frames; {}",
        args.output.display(),
        args.size.0,
        args.size.1,
        state.time_s,
        forces.join("; ")
    );
    Ok(())
}
