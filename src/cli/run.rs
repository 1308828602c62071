//! `fissure run [SCENARIO]` (and a bare `fissure`): the simulator on a scenario.
//!
//! `--headless` plays the scenario's trajectory (or holds the initial poses)
//! without a window through the same pipeline as the window, and prints the
//! timings.

use std::path::{Path, PathBuf};

use super::DEFAULT_SCENARIO;

/// The default scene's path: `config/sylvian.ron` under the working directory,
/// else beside the crate (so `cargo run` works from anywhere in the checkout).
pub fn default_scenario() -> PathBuf {
    let here = PathBuf::from(DEFAULT_SCENARIO);
    if here.exists() { here } else { Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SCENARIO) }
}

pub fn run(scenario: Option<&Path>, set: &[String], headless: bool) -> anyhow::Result<()> {
    let path = scenario.map(Path::to_path_buf).unwrap_or_else(default_scenario);
    if !headless {
        eprintln!("fissure: the window is not built yet; running {} headless", path.display());
    }
    super::replay::run(super::replay::ReplayArgs { scenario: &path, set, trajectory: None, out: None, vtk: false, frames: false })?;
    Ok(())
}
