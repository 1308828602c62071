//! `fissure run [SCENARIO]` (and a bare `fissure`): the simulator window on a
//! scenario; `--headless` (or no display / no GPU adapter) plays the
//! scenario's trajectory without a window through the same pipeline and prints
//! the timings.
//!
//! For tests and demos: `--script FILE` injects timed key presses and actions
//! (see `fissure::app::script`), `--frames N` stops after N simulation frames,
//! `--exit-after SECONDS` closes the window that long after it opened (the
//! scene's preparation, shown in the window, counts); the run then
//! prints a summary (frames, frame rate, force-loop rate, final poses, peak
//! forces, poses refused when any, final state hash) and exits 0.

use std::path::{Path, PathBuf};

use anyhow::Context;
use fissure::app::script::Script;
use fissure::app::window::{WindowError, WindowOptions, run_window};
use fissure::scenario::Scenario;

use super::DEFAULT_SCENARIO;

/// Present mode of the window.
#[derive(Debug, Clone, Copy, Default, clap::ValueEnum)]
pub enum PresentArg {
    /// Vsync (always supported; the default).
    #[default]
    Fifo,
    /// Low-latency vsync where supported (falls back to Fifo).
    Mailbox,
}

/// Window options of `run`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct WindowArgs {
    /// Timed input script (lines `TIME_S press E`, `TIME_S record out.csv`, `TIME_S quit`, ...).
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Stop after this many simulation frames.
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,
    /// Close the window after this many seconds of wall time.
    #[arg(long, value_name = "SECONDS")]
    pub exit_after: Option<f64>,
    /// Present mode (set explicitly: Xvfb's default, Immediate, misbehaves).
    #[arg(long, value_enum, default_value = "fifo")]
    pub present_mode: PresentArg,
    /// Window size, WIDTHxHEIGHT pixels.
    #[arg(long, value_parser = super::screenshot::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Folder for recordings (key R, the panel's Record); default: the
    /// scenario's `outputs.record_dir`, else the user's data directory
    /// (`$XDG_DATA_HOME/fissure/recordings`, `~/.local/share/fissure/recordings` on Linux).
    #[arg(long, value_name = "DIR")]
    pub record_dir: Option<PathBuf>,
    /// Do not start the 1 kHz force output.
    #[arg(long)]
    pub no_haptics: bool,
    /// Start with the gamepad's force feedback off (key H turns it on).
    #[arg(long)]
    pub no_rumble: bool,
    /// Also write the session's figures to this file as JSON: frames presented, frame rate, adapter, the
    /// simulation's frames and step times, the final state.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
}

/// The default scene's path: `config/sylvian.ron` under the working directory,
/// else beside the crate (so `cargo run` works from anywhere in the checkout).
pub fn default_scenario() -> PathBuf {
    let here = PathBuf::from(DEFAULT_SCENARIO);
    if here.exists() { here } else { Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SCENARIO) }
}

fn headless(path: &Path, set: &[String]) -> anyhow::Result<()> {
    super::replay::run(super::replay::ReplayArgs { scenario: path, set, trajectory: None, out: None, vtk: false, frames: false, strict: false })?;
    Ok(())
}

pub fn run(scenario: Option<&Path>, set: &[String], headless_only: bool, args: &WindowArgs) -> anyhow::Result<()> {
    let path = scenario.map(Path::to_path_buf).unwrap_or_else(default_scenario);
    if headless_only {
        return headless(&path, set);
    }
    if let Some(t) = args.exit_after {
        anyhow::ensure!(t.is_finite() && t > 0.0, "--exit-after must be a positive number of seconds, got {t}");
    }
    let loaded = Scenario::load(&path, set).with_context(|| format!("loading {}", path.display()))?;
    let script = match &args.script {
        Some(p) => Script::load(p).with_context(|| format!("reading the script {}", p.display()))?.actions,
        None => Vec::new(),
    };
    let mut options = WindowOptions {
        present_mode: match args.present_mode {
            PresentArg::Fifo => wgpu::PresentMode::Fifo,
            PresentArg::Mailbox => wgpu::PresentMode::Mailbox,
        },
        max_frames: args.frames,
        exit_after_s: args.exit_after,
        script,
        haptics: !args.no_haptics,
        rumble: !args.no_rumble,
        ..WindowOptions::default()
    };
    if let Some(size) = args.size {
        options.size = size;
    }
    options.record_dir = fissure::app::window::record_dir_for(args.record_dir.as_deref(), loaded.run.outputs.record_dir.as_deref());
    let names: Vec<String> = loaded.spatulas.iter().map(|s| s.name.clone()).collect();
    let dt = loaded.time_step;
    match run_window(loaded, options) {
        Ok(summary) => report_window(&summary, &names, dt, &path, args.report.as_deref()),
        Err(e @ (WindowError::NoDisplay(_) | WindowError::NoAdapter(_))) => {
            eprintln!("fissure: {e}; running {} headless instead (the same scene without a window; its timings follow)", path.display());
            headless(&path, set)
        }
        Err(e) => Err(e).context("running the window"),
    }
}

/// Prints what a window session did (and writes it as JSON where `--report` asks).
fn report_window(summary: &fissure::app::window::WindowSummary, names: &[String], dt: f64, path: &Path, report: Option<&Path>) -> anyhow::Result<()> {
    let sim = &summary.sim;
    let mut steps = sim.step_ms.clone();
    steps.sort_by(f64::total_cmp);
    let pct = |q: f64| if steps.is_empty() { 0.0 } else { steps[((steps.len() - 1) as f64 * q).round() as usize] };
    if let Some(file) = report {
        let figures = fissure::perf::reports::WindowReport {
            presented: summary.presented,
            wall_s: summary.wall_s,
            fps: summary.fps(),
            adapter: summary.adapter.clone(),
            sim_frames: sim.frames,
            simulated_s: sim.time_s,
            step_p50_ms: pct(0.5),
            step_p95_ms: pct(0.95),
            step_max_ms: pct(1.0),
            failed_frames: sim.failed_frames,
            final_state: sim.state_hash.clone(),
        };
        let text = serde_json::to_string_pretty(&figures).context("the window's report")?;
        fissure::fsio::write_atomic(file, text.as_bytes()).with_context(|| format!("writing the window's report {}", file.display()))?;
    }
    println!("window: {} frames presented in {:.2} s ({:.1} fps) on {}", summary.presented, summary.wall_s, summary.fps(), summary.adapter);
    println!(
        "simulation: {} frames ({:.3} s simulated, step {dt} s), step p50 {:.3} ms, p95 {:.3} ms, {} failed",
        sim.frames,
        sim.time_s,
        pct(0.5),
        pct(0.95),
        sim.failed_frames
    );
    if summary.haptic_s > 0.0 {
        println!("force output: {} ticks in {:.2} s ({:.0} Hz)", summary.haptic_ticks, summary.haptic_s, summary.haptic_ticks as f64 / summary.haptic_s);
    }
    if sim.state_hash.is_empty() {
        // The loop never ran: the window closed while the scene was being built.
        println!("  closed while the scene was being built: nothing was simulated");
        return Ok(());
    }
    for (k, name) in names.iter().enumerate() {
        let p = sim.final_poses.get(k).map(|p| p.position * 1e3).unwrap_or_default();
        let peak = sim.peak_force_n.get(k).copied().unwrap_or(0.0);
        println!("  {name}: final position_mm ({:?}, {:?}, {:?}), peak force {peak:.6} N", p.x, p.y, p.z);
    }
    if let Some(r) = &sim.recording {
        println!("  recorded {}", r.display());
    }
    if let Some(page) = &summary.debrief {
        println!("  debrief {}", page.display());
    }
    if let Some(rec) = &summary.debrief_unfinished {
        println!(
            "  the session's debrief was not finished (the window closed first); make it with: fissure debrief {} --scenario {}",
            rec.display(),
            path.display()
        );
    }
    if sim.background_strain_frames > 0 {
        println!("  strain colour from the background stress worker: {} frames", sim.background_strain_frames);
    }
    let tracker_refused = sim.tracker_outside_workspace + sim.tracker_too_fast;
    if sim.rejected_poses > 0 || tracker_refused > 0 {
        println!(
            "  poses refused: {} non-finite or non-unit, {} OpenIGTLink outside the workspace, {} OpenIGTLink too fast (the last good pose held)",
            sim.rejected_poses, sim.tracker_outside_workspace, sim.tracker_too_fast
        );
    }
    if let Some(b) = &sim.collision_backend {
        println!("  collision backend: {b}");
    }
    for note in &sim.collision_notes {
        println!("  collision: {note}");
    }
    println!("  final state {}", sim.state_hash);
    Ok(())
}
