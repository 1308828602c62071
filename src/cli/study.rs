//! `fissure study`: sweeps over the knobs that trade accuracy for time; writes
//! results.csv, report.md and the plots; a progress bar on a terminal. Ctrl-C
//! finishes the run under way, writes every output with the runs left marked
//! "not run" and returns [`super::Interrupted`] (exit 130).


use anyhow::Context;
use fissure::study::{Knob, NOT_RUN_INTERRUPTED, StudyOptions, StudyProgress, run_study_until};

/// The knobs named on the command line; an unknown name is an error that lists the known ones.
pub fn knobs(names: &[String]) -> anyhow::Result<Vec<Knob>> {
    names
        .iter()
        .map(|n| {
            Knob::from_name(n).ok_or_else(|| {
                let known: Vec<&str> = Knob::ALL.iter().map(|k| k.name()).collect();
                anyhow::anyhow!("--knob {n}: unknown knob; the knobs are {}", known.join(", "))
            })
        })
        .collect()
}

pub fn run(options: StudyOptions) -> anyhow::Result<()> {
    let out = options.out_dir.clone();
    // The GPU rows use wgpu; give it a private runtime dir when none is set.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        let dir = std::env::temp_dir().join(format!("fissure-xdg-{}", std::process::id()));
        if std::fs::create_dir_all(&dir).is_ok() {
            // SAFETY: single-threaded here, before any thread that reads the environment starts.
            unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
        }
    }
    let bar = fissure::app::progress::terminal_bar(0, "", "{msg:<40} [{bar:30}] {pos}/{len} ({elapsed})");
    let mut progress = |p: StudyProgress| {
        bar.set_length(p.total as u64);
        bar.set_position(p.done as u64);
        bar.set_message(p.label);
    };
    let interrupt = super::replay::interrupt_flag();
    let results = run_study_until(&options, &mut progress, &interrupt).with_context(|| format!("running the study into {}", out.display()))?;
    bar.finish_and_clear();
    let runs = || results.rows.iter().chain(&results.mesh_reference);
    let done = runs().filter(|r| r.outcome.as_ref().err().is_none_or(|e| e != NOT_RUN_INTERRUPTED)).count();
    println!("study `{}` on {}: {} runs in {:.0} s", results.plan_name, results.scene_name, done, results.elapsed_s);
    for f in &results.files {
        println!("  wrote {}", f.display());
    }
    if results.interrupted {
        return Err(super::Interrupted {
            what: format!("after {done} of {} runs; partial results in {} (report.md says so)", runs().count(), out.display()),
        }
        .into());
    }
    Ok(())
}
