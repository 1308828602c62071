//! `fissure study`: sweeps over the knobs that trade accuracy for time; writes
//! results.csv, report.md and the plots; a progress bar on a terminal.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::Context;
use fissure::study::{StudyOptions, StudyPreset, StudyProgress, run_study};
use indicatif::{ProgressBar, ProgressStyle};

pub fn run(preset: StudyPreset, scene: Option<PathBuf>, out: PathBuf) -> anyhow::Result<()> {
    // The GPU rows use wgpu; give it a private runtime dir when none is set.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        let dir = std::env::temp_dir().join(format!("fissure-xdg-{}", std::process::id()));
        if std::fs::create_dir_all(&dir).is_ok() {
            // SAFETY: single-threaded here, before any thread that reads the environment starts.
            unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
        }
    }
    let bar = if std::io::stderr().is_terminal() { ProgressBar::new(0) } else { ProgressBar::hidden() };
    bar.set_style(ProgressStyle::with_template("{msg:<40} [{bar:30}] {pos}/{len} ({elapsed})").unwrap_or_else(|_| ProgressStyle::default_bar()));
    let mut progress = |p: StudyProgress| {
        bar.set_length(p.total as u64);
        bar.set_position(p.done as u64);
        bar.set_message(p.label);
    };
    let options = StudyOptions { preset, scene, out_dir: out.clone() };
    let results = run_study(&options, &mut progress).with_context(|| format!("running the study into {}", out.display()))?;
    bar.finish_and_clear();
    println!("study `{}` on {}: {} runs in {:.0} s", results.plan_name, results.scene_name, results.rows.len(), results.elapsed_s);
    for f in &results.files {
        println!("  wrote {}", f.display());
    }
    Ok(())
}
