//! `fissure check SCENARIO [--set PATH=VALUE]... [--trajectory FILE]`, and the bare `fissure`.
//!
//! In: a scenario path, overrides and optionally the trajectory a replay would
//! play instead of the scenario's. Out: the validated scenario's summary and
//! what the preflight found (mesh, fixed nodes, skull clearance, blade travel
//! a step) on stdout, each warning on stderr (`warning: file:line:column:
//! field: ...`), or the error (file:line:column: field: problem). Runs the
//! same `sim::preflight` as every build, without frames or the compliance
//! precompute: what `check` accepts, `replay` builds.

use std::path::Path;

use anyhow::Context as _;
use fissure::scenario::Scenario;
use fissure::sim::preflight;

const MM: f64 = 1e-3;

/// Validates, runs the preflight, and prints the summary and the warnings.
pub fn run(path: &Path, overrides: &[String], trajectory: Option<&Path>) -> anyhow::Result<()> {
    let scenario = Scenario::load(path, overrides).with_context(|| format!("scenario {} is not valid", path.display()))?;
    let checked = preflight(&scenario, trajectory).with_context(|| format!("scenario {} is not valid", path.display()))?;
    println!("{}", scenario.summary());
    let m = &checked.mesh.facts;
    println!(
        "  built:     {} nodes, {} tets, {} component{}, {} fixed node{}",
        m.nodes,
        m.tets,
        m.components,
        if m.components == 1 { "" } else { "s" },
        m.fixed_nodes,
        if m.fixed_nodes == 1 { "" } else { "s" }
    );
    if let Some(how) = m.refined {
        println!("  refined:   {} nodes added to the file's {} ({how})", m.nodes.saturating_sub(m.file_nodes), m.file_nodes);
    }
    if let Some(v) = m.surface_vertices {
        let clearance = |c: Option<f64>| c.map_or_else(|| "none".to_string(), |g| format!("{:.2} mm", g / MM));
        println!(
            "  skull:     at rest, {v} surface vertices clear the containing sphere by {}, the excluding one by {}",
            clearance(m.containing_clearance),
            clearance(m.excluding_clearance)
        );
    }
    if let Some(t) = trajectory {
        println!("  trajectory: {} (given in place of the scenario's)", t.display());
    }
    for t in &checked.travel {
        let sp = &scenario.spatulas[t.spatula];
        let split = match scenario.solver.substep_travel {
            Some(f) => {
                let n = ((t.travel / (f * sp.shape.thickness)).ceil() as u32).clamp(1, fissure::sim::MAX_SUBSTEPS);
                let jitter = match scenario.solver.substep_jitter {
                    fissure::scenario::SubstepJitter::Discount => ", fewer where the samples jitter: the jitter does not count",
                    fissure::scenario::SubstepJitter::Follow => "",
                };
                if n > 1 { format!("; such a frame runs as {n} sub-steps{jitter}") } else { String::new() }
            }
            None => String::new(),
        };
        println!(
            "  motion:    spatula {} \"{}\" moves at most {:.3} mm a step (step ending at {:.3} s; blade thickness {:.3} mm{split})",
            t.spatula,
            sp.name,
            t.travel / MM,
            t.time_s,
            sp.shape.thickness / MM
        );
    }
    for w in &checked.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "ok: the scenario is valid{}",
        match checked.warnings.len() {
            0 => String::new(),
            1 => " (1 warning)".to_string(),
            n => format!(" ({n} warnings)"),
        }
    );
    Ok(())
}
