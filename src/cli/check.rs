//! `fissure check SCENARIO [--set PATH=VALUE]...`, and the bare `fissure`.
//!
//! In: a scenario path and overrides. Out: the validated scenario's summary on
//! stdout, or the scenario error (file:line:column: field: problem).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use fissure::scenario::Scenario;

use super::DEFAULT_SCENARIO;

/// Validates and prints the summary.
pub fn run(path: &Path, overrides: &[String]) -> anyhow::Result<()> {
    let scenario = Scenario::load(path, overrides).with_context(|| format!("scenario {} is not valid", path.display()))?;
    println!("{}", scenario.summary());
    println!("ok: the scenario is valid");
    Ok(())
}

/// The bare `fissure`: the default scene. Until the simulator's `run` command
/// exists this says so and checks the default scene.
pub fn default_scene() -> anyhow::Result<()> {
    let path = default_scenario_path();
    println!("fissure: the simulator's run command is not built yet; checking the default scene {} instead.", path.display());
    run(&path, &[])
}

/// `config/sylvian.ron` from the working directory, else from the source tree this binary was built from.
fn default_scenario_path() -> PathBuf {
    let here = PathBuf::from(DEFAULT_SCENARIO);
    if here.is_file() {
        return here;
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SCENARIO)
}
