//! `fissure replay`: a scenario played headless from a trajectory, with metrics,
//! a summary and optional VTK/PNG output; a progress bar on a terminal; Ctrl-C
//! stops after the current frame with every row so far valid and the summary
//! written, then the command returns [`super::Interrupted`] (exit 130).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;
use fissure::scenario::Scenario;
use fissure::sim::metrics::Summary;
use fissure::sim::replay::{ReplayOptions, replay};
use indicatif::ProgressBar;

/// Options of one replay from the command line.
pub struct ReplayArgs<'a> {
    pub scenario: &'a Path,
    pub set: &'a [String],
    pub trajectory: Option<PathBuf>,
    pub out: Option<PathBuf>,
    pub vtk: bool,
    pub frames: bool,
    /// Fail (exit 3) when the summary's integrity verdict fails.
    pub strict: bool,
}

fn bar(len: u64, message: &str) -> ProgressBar {
    fissure::app::progress::terminal_bar(len, message, fissure::app::progress::DEFAULT_TEMPLATE)
}

/// Sets a flag on Ctrl-C (once per process; later calls reuse the flag): the
/// command finishes its current frame (or run), writes its outputs and returns
/// [`super::Interrupted`]. A second Ctrl-C quits at once with exit code 130
/// (for a long precompute that cannot stop in the middle; the rows written so
/// far stay valid, the final files are whole or absent).
pub fn interrupt_flag() -> Arc<AtomicBool> {
    static FLAG: std::sync::OnceLock<Arc<AtomicBool>> = std::sync::OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let f = flag.clone();
        if let Err(e) = ctrlc::set_handler(move || {
            if f.swap(true, Ordering::Relaxed) {
                eprintln!("fissure: interrupted twice; quitting now");
                std::process::exit(130);
            }
        }) {
            tracing::warn!("Ctrl-C handler not installed: {e}");
        }
        flag
    })
    .clone()
}

/// Runs the replay and prints where the outputs are.
/// An interrupted replay (Ctrl-C) writes everything, prints its summary and
/// returns [`super::Interrupted`].
pub fn run(args: ReplayArgs<'_>) -> anyhow::Result<Summary> {
    // First, so a Ctrl-C during the load or the precompute is a graceful stop too.
    let interrupt = interrupt_flag();
    let scenario = Scenario::load(args.scenario, args.set).with_context(|| format!("loading {}", args.scenario.display()))?;
    let out_dir = args.out.clone().unwrap_or_else(|| scenario.run.outputs.dir.clone());
    let vtk = args.vtk || scenario.run.outputs.vtk;
    let frames = args.frames || scenario.run.outputs.frames;
    let options = ReplayOptions { out_dir: out_dir.clone(), trajectory: args.trajectory.clone(), vtk };
    let precompute = bar(0, "compliance");
    let mut told = false;
    let mut on_precompute = |done: usize, total: usize| {
        precompute.set_length(total as u64);
        precompute.set_position(done as u64);
        if !told && interrupt.load(Ordering::Relaxed) {
            told = true;
            precompute.suspend(|| eprintln!("fissure: Ctrl-C: stopping when the compliance precompute ends (Ctrl-C again quits now)"));
        }
    };
    let progress = bar(scenario.step_count(), "frames");
    let mut frame_writer = if frames { Some(super::frames::FrameWriter::new(&out_dir)?) } else { None };
    let mut on_frame = |pipeline: &mut fissure::sim::Pipeline, state: &fissure::sim::SimState, done: u64, _total: u64| {
        precompute.finish_and_clear();
        progress.set_position(done);
        match &mut frame_writer {
            Some(w) => {
                // the picture shows the whole surface, the far part brought up to date
                let whole = pipeline.with_whole_surface(state).map_err(|e| format!("{e:#}"))?;
                w.write(pipeline, &whole).map_err(|e| format!("{e:#}"))
            }
            None => Ok(()),
        }
    };
    let result = replay(&scenario, &options, &interrupt, &mut on_frame, Some(&mut on_precompute));
    progress.finish_and_clear();
    let summary = result.with_context(|| format!("replaying {}", args.scenario.display()))?;
    print_summary(&scenario, &summary, &out_dir, vtk);
    if summary.interrupted {
        return Err(super::Interrupted {
            what: format!(
                "after {} of {} frames; partial results in {} (summary.json says \"interrupted\": true)",
                summary.frames,
                scenario.step_count(),
                out_dir.display()
            ),
        }
        .into());
    }
    if args.strict && !summary.integrity.passed {
        return Err(super::IntegrityFailed { what: format!("{}: {}", args.scenario.display(), summary.integrity.failures.join("; ")) }.into());
    }
    Ok(summary)
}

/// What a replay prints: frame times a stage, each spatula's force and pressure, the tissue's ischemia, then
/// [`print_model`], for a person; `summary.json` carries the same figures for programs (the performance page reads it).
fn print_summary(scenario: &Scenario, summary: &Summary, out_dir: &Path, vtk: bool) {
    println!("{}: {} frames ({:.2} s simulated){}", scenario.name, summary.frames, summary.simulated_s, if summary.interrupted { ", INTERRUPTED" } else { "" });
    println!("  frame time p50 {:.3} ms, p95 {:.3} ms, max {:.3} ms", summary.frame.p50_ms, summary.frame.p95_ms, summary.frame.max_ms);
    for (stage, p) in &summary.stages {
        println!("    {:<10} p50 {:>9.3} ms  p95 {:>9.3} ms", stage.name(), p.p50_ms, p.p95_ms);
    }
    let pressure = scenario.effects.contains(fissure::scenario::Effect::ContactPressure);
    for s in &summary.spatulas {
        if pressure {
            println!(
                "  {}: peak force {:.3} N, peak mean pressure {:.1} mmHg, {:.2} s above 20 mmHg",
                s.name, s.peak_force_n, s.peak_pressure_mmhg, s.time_above_20mmhg_s
            );
        } else {
            println!("  {}: peak force {:.3} N (contact pressure not simulated: add ContactPressure to effects)", s.name, s.peak_force_n);
        }
        println!(
            "  {}: force change from one frame to the next at most {:.4} N, p95 {:.4} N",
            s.name, s.max_force_jump_n, s.p95_force_jump_n
        );
    }
    if let Some(i) = &summary.ischemia {
        let levels: Vec<String> = i.levels.iter().map(|l| format!("{} {:.1} mm2", l.level.replace('_', " "), l.max_area_mm2)).collect();
        println!(
            "  ischemia (MAP {:.0} mmHg): largest area {}; largest dose {:.1} mmHg min (risk {:.2}) at {:.1} s; perfusion under 10 mmHg at most {:.1} s{}",
            i.mean_arterial_pressure_mmhg,
            levels.join(", "),
            i.max_dose_mmhg_min,
            i.max_risk,
            i.max_dose_time_s,
            i.longest_low_perfusion_s,
            if i.low_perfusion_over_tolerance { " (over the 6 minutes that preceded infarcts)" } else { "" }
        );
    }
    print_model(summary, out_dir, vtk);
}

/// The compliance, the displacement, the collision backend and its notes, the sub-steps, the integrity check, the
/// final state's hash and the files written.
fn print_model(summary: &Summary, out_dir: &Path, vtk: bool) {
    let c = &summary.compliance;
    println!(
        "  compliance: {} rows (the working region, of {} surface vertices) x {} columns, {:.0} MB",
        c.rows, c.surface_vertices, c.columns, c.megabytes
    );
    println!("  max displacement {:.2} mm, tissue pulled through a blade: {} vertices (max in a frame)", summary.worst.max_displacement_mm, summary.worst.max_crossed_vertices);
    if let Some(b) = &summary.collision_backend {
        println!("  collision backend: {b}");
    }
    for note in &summary.collision_notes {
        println!("  collision: {note}");
    }
    if summary.max_substeps > 1 || summary.capped_frames > 0 {
        println!("  fast blades: up to {} sub-steps a frame; {} frames hit the contact solve's cap (each kept the last feasible state)", summary.max_substeps, summary.capped_frames);
    }
    match summary.integrity.failures.as_slice() {
        [] => println!(
            "  integrity: pass (penetration {:.3} mm <= {} mm, inverted elements {} <= {}, pulled through {} <= {})",
            summary.worst.max_penetration_mm,
            summary.integrity.limits.max_penetration_mm,
            summary.worst.max_inverted_elements,
            summary.integrity.limits.max_inverted_elements,
            summary.worst.max_crossed_vertices,
            summary.integrity.limits.max_crossed_vertices
        ),
        failures => {
            for f in failures {
                println!("  integrity: FAIL: {f}");
            }
        }
    }
    println!("  final state {}", summary.final_state_hash);
    println!("  wrote {}/metrics.csv, {}/summary.json{}", out_dir.display(), out_dir.display(), if vtk { ", series.pvd" } else { "" });
}
