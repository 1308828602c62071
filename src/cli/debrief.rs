//! `fissure debrief RUN_DIR... [--reference REF_RUN_DIR] [-o OUT.html]`: a replay's run scored and explained as one
//! self-contained HTML page and its JSON. The reading, scoring and page are [`fissure::debrief`]'s; this names the
//! folder in each error and prints what was written and each blade's worst verdict. `fissure debrief REC.csv
//! --scenario S.ron` debriefs a recording as the window does when a session ends
//! ([`fissure::app::session_debrief`]: the recording and the scene's own trajectory replayed, the page beside it).

use std::path::PathBuf;

use anyhow::Context;
use fissure::debrief::{self, Verdict};

/// `fissure debrief`'s arguments.
#[derive(Debug, clap::Args)]
pub struct DebriefArgs {
    /// Run folders written by `fissure replay --out DIR` (metrics.csv, summary.json, surface_dose.csv); several are
    /// shown side by side with each metric's trend from the first to the last.
    #[arg(required = true, value_name = "RUN_DIR")]
    pub runs: Vec<PathBuf>,
    /// The reference run (the careful surgeon's trajectory replayed the same way): each value against its own.
    #[arg(long, value_name = "REF_RUN_DIR")]
    pub reference: Option<PathBuf>,
    /// The page (default RUN_DIR/debrief.html for one run; required for several); the JSON goes beside it, same stem.
    #[arg(short, long, value_name = "OUT.html")]
    pub output: Option<PathBuf>,
    /// The scenario a recording (a trajectory CSV given as the run) was made on: the recording and the scenario's
    /// own trajectory (the reference) are replayed beside it and the page written there, as the window does.
    #[arg(long, value_name = "SCENARIO")]
    pub scenario: Option<PathBuf>,
}

/// `fissure debrief REC.csv --scenario S.ron`: the window's end-of-session debrief, from the command line.
fn recording(args: &DebriefArgs, scenario: &std::path::Path) -> anyhow::Result<()> {
    let [rec] = args.runs.as_slice() else {
        anyhow::bail!("with --scenario, give one recording (a trajectory CSV), not {}", args.runs.len());
    };
    if args.reference.is_some() || args.output.is_some() {
        anyhow::bail!("with --scenario the reference is the scenario's own trajectory and the page goes beside the recording: drop --reference and -o");
    }
    let loaded = fissure::scenario::Scenario::load(scenario, &[]).with_context(|| format!("loading {}", scenario.display()))?;
    let interrupt = super::replay::interrupt_flag();
    let bar = fissure::app::progress::terminal_bar(0, "debrief", fissure::app::progress::DEFAULT_TEMPLATE);
    let mut progress = |step: fissure::app::session_debrief::SessionStep, done: u64, total: u64| {
        bar.set_message(step.words());
        bar.set_length(total);
        bar.set_position(done);
    };
    let made = fissure::app::session_debrief::debrief_recording(&loaded, rec, &interrupt, &mut progress);
    bar.finish_and_clear();
    let made = match made {
        Err(fissure::app::session_debrief::SessionDebriefError::Interrupted) => {
            let what = format!("before the debrief of {} was written (the replayed frames so far are beside it)", rec.display());
            return Err(super::Interrupted { what }.into());
        }
        other => other.with_context(|| format!("debriefing {}", rec.display()))?,
    };
    println!("wrote {} and {}", made.files.page.display(), made.files.json().display());
    if let Some(why) = &made.no_reference {
        println!("  no reference: {why}");
    }
    print_verdicts(std::slice::from_ref(&made.debrief));
    Ok(())
}

pub fn run(args: &DebriefArgs) -> anyhow::Result<()> {
    if let Some(scenario) = &args.scenario {
        return recording(args, scenario);
    }
    let out = match (&args.output, args.runs.as_slice()) {
        (Some(out), _) => out.clone(),
        (None, [one]) => one.join("debrief.html"),
        (None, _) => anyhow::bail!("debriefing {} runs: name the page with -o OUT.html", args.runs.len()),
    };
    let reference = match &args.reference {
        Some(dir) => Some(debrief::read_run(dir).with_context(|| format!("reading the reference run {}", dir.display()))?),
        None => None,
    };
    let runs = args.runs.iter().map(|dir| debrief::read_run(dir).with_context(|| format!("debriefing {}", dir.display()))).collect::<anyhow::Result<Vec<_>>>()?;
    let debriefs: Vec<_> = runs.iter().map(|r| debrief::debrief(r, reference.as_ref())).collect();
    let json = debrief::page::write_page(&runs, &debriefs, &out).with_context(|| format!("writing the debrief {}", out.display()))?;
    println!("wrote {} and {}", out.display(), json.display());
    print_verdicts(&debriefs);
    Ok(())
}

/// Each blade's worst verdict, and a run that stopped early.
fn print_verdicts(debriefs: &[debrief::Debrief]) {
    for d in debriefs {
        if d.interrupted {
            println!("  {}: stopped early, {} frames", d.run, d.frames);
        }
        for b in &d.blades {
            let worst = b.metrics.iter().filter_map(|m| m.verdict.map(|v| (v, m))).max_by_key(|(v, _)| *v);
            match worst {
                Some((v, m)) if v > Verdict::Within => println!("  {} {}: {} {}", d.run, b.name, m.name, v.words()),
                _ => println!("  {} {}: within", d.run, b.name),
            }
        }
    }
}
