//! `fissure check SCENARIO [--set PATH=VALUE]...`, and the bare `fissure`.
//!
//! In: a scenario path and overrides. Out: the validated scenario's summary on
//! stdout, or the scenario error (file:line:column: field: problem).

use std::path::Path;

use anyhow::Context as _;
use fissure::scenario::Scenario;


/// Validates and prints the summary.
pub fn run(path: &Path, overrides: &[String]) -> anyhow::Result<()> {
    let scenario = Scenario::load(path, overrides).with_context(|| format!("scenario {} is not valid", path.display()))?;
    println!("{}", scenario.summary());
    println!("ok: the scenario is valid");
    Ok(())
}
