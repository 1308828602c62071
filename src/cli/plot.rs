//! `fissure plot RUN_DIR... -o FILE.png [--size WxH]`: replay runs drawn
//! against time, three panels on one time axis (force, mean contact pressure
//! with the 20 mmHg line, contact vertices), a colour a run, a line style a
//! blade. The reading and drawing are [`fissure::study::runs_plot`]'s; this
//! only names the command in the error and prints what was drawn, with each
//! later run's force against the first's.

use std::path::PathBuf;

use anyhow::Context;
use fissure::study::runs_plot::{force_against, plot_runs};

/// `fissure plot`'s arguments.
#[derive(Debug, clap::Args)]
pub struct PlotArgs {
    /// Run directories written by `fissure replay --out DIR` (metrics.csv, and
    /// summary.json for the scenario's name); several overlay, a colour a run.
    #[arg(required = true, value_name = "RUN_DIR")]
    pub runs: Vec<PathBuf>,
    /// The plot: FILE.png, or FILE.svg for a vector drawing.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Image size, WIDTHxHEIGHT pixels (at least 480x360).
    #[arg(long, value_name = "WxH", default_value = "1400x1000", value_parser = super::screenshot::parse_size)]
    pub size: (u32, u32),
}

pub fn run(args: &PlotArgs) -> anyhow::Result<()> {
    let runs = plot_runs(&args.runs, &args.output, args.size)
        .with_context(|| format!("plotting {} run{} into {}", args.runs.len(), if args.runs.len() == 1 { "" } else { "s" }, args.output.display()))?;
    println!("wrote {} ({}x{} pixels)", args.output.display(), args.size.0, args.size.1);
    for run in &runs {
        let blades: Vec<&str> = run.blades.iter().map(|b| b.name.as_str()).collect();
        let (t0, t1) = run.time_span().unwrap_or((0.0, 0.0));
        println!("  {}: {} frames, t = {t0:.2} to {t1:.2} s, blades {}", run.label, run.time_s.len(), blades.join(", "));
    }
    if let Some((first, rest)) = runs.split_first().filter(|(_, rest)| !rest.is_empty()) {
        println!("force against {}, at its frames (RMS / max, % of its peak):", first.label);
        for run in rest {
            let d: Vec<String> = force_against(first, run)
                .iter()
                .map(|d| format!("{} {:.2} / {:.2} % of {:.4} N ({} frames)", d.blade, d.rms_pct, d.max_pct, d.peak_n, d.frames))
                .collect();
            println!("  {}: {}", run.label, if d.is_empty() { "no blade in common".to_string() } else { d.join("; ") });
        }
    }
    Ok(())
}
