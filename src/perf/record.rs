//! One run of `scripts/perf_docs.sh`, read back from its folder (`target/perf/`): the reports each measure wrote
//! (typed, [`super::reports`]), the replays' `summary.json` ([`Summary`]) and `metrics.csv`, and what the script
//! itself knows (the machine, the commit, how long each measure took). Stays true: a figure the page needs that
//! is not there is an error naming its file, never a blank on the page.

use super::reports::{AuditBar, CollisionReport, FemFigures, StartupReport, WindowReport};
use crate::fsio::Cap;
use crate::sim::metrics::Summary;
use serde::de::DeserializeOwned;
use std::path::{Path, PathBuf};

/// A file of the run that is missing or does not say what the page needs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct PerfError {
    pub path: PathBuf,
    pub message: String,
}

impl PerfError {
    pub fn new(path: &Path, message: impl Into<String>) -> Self {
        Self { path: path.to_path_buf(), message: message.into() }
    }
}

/// Largest file of a run the page reads (a ten-minute replay's `metrics.csv` is about 30 MB).
const FILE_CAP: Cap = Cap { bytes: 1 << 30, what: "a performance record file" };

fn read_text(path: &Path) -> Result<String, PerfError> {
    crate::fsio::read_regular_text(path, FILE_CAP).map_err(|e| match e {
        crate::fsio::ReadError::Refused { refusal, .. } => PerfError::new(path, refusal.to_string()),
        crate::fsio::ReadError::Io { source, .. } => PerfError::new(path, source.to_string()),
    })
}

/// Writes `bytes` to `path` whole (or not at all).
pub fn write_whole(path: &Path, bytes: &[u8]) -> Result<(), PerfError> {
    crate::fsio::write_atomic(path, bytes).map_err(|e| PerfError::new(path, e.source.to_string()))
}

/// A JSON report, as its writer's type.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T, PerfError> {
    serde_json::from_str(&read_text(path)?).map_err(|e| PerfError::new(path, format!("not the report this page reads: {e}")))
}

/// What the script says about the run it made (its command-line arguments to the page).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunInfo {
    /// "CPU model, N cores, X GiB RAM".
    pub machine: String,
    /// "YYYY-MM-DD HH:MM UTC".
    pub date: String,
    /// The short hash, with " + uncommitted changes" when the tree had them.
    pub commit: String,
    /// The script's command line as a reader types it (`FAST=1 scripts/perf_docs.sh`).
    pub command: String,
    /// `FAST=1`: one run a replay, no audit, no coarse brain in the fem bench, no cold early start, no CHOLMOD.
    pub fast: bool,
    /// Runs of each replay.
    pub repeat: usize,
    /// Xvfb was not installed, so the window was not measured.
    pub no_window: bool,
    /// CHOLMOD was not installed, so it was not compared.
    pub no_cholmod: bool,
    /// The machine's core count (the window's second run uses every core).
    pub cores: usize,
}

/// One replay run: what `fissure replay --out DIR` wrote, and what `/usr/bin/time` said of the process.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayRun {
    /// The scene's name on the page (`sylvian`, `real_brain/sylvian`, `effects/tethers`, ...).
    pub tag: String,
    pub run: usize,
    /// The command as the page shows it (`fissure replay config/sylvian.ron --set solver.cache_dir=None`).
    pub command: String,
    pub summary: Summary,
    /// Whole process, s (the precompute included), and its peak resident memory, MB (None without `/usr/bin/time`).
    pub wall_s: f64,
    pub peak_mb: Option<f64>,
    /// From `metrics.csv`'s last row, a figure a blade: the vertices carrying its force, the force, N.
    pub contact_vertices: Vec<String>,
    pub forces_n: Vec<f64>,
}

/// Everything one run of the script measured.
#[derive(Debug, Clone, PartialEq)]
pub struct PerfRecord {
    pub info: RunInfo,
    /// Seconds each measure took: collision, replays, startup, window, fem, cholmod.
    pub seconds: Vec<(String, u64)>,
    pub collision: CollisionReport,
    /// The bench's own table (`collision.md`), as it wrote it.
    pub collision_table: String,
    pub replays: Vec<ReplayRun>,
    /// `startup/NAME.json` by name (q15_cold, q15_cache, ...).
    pub startup: Vec<(String, StartupReport)>,
    /// llvmpipe on cores - 1 threads, then on every core (None when the window was not measured).
    pub window: Option<[WindowReport; 2]>,
    /// The fem bench's figures: paper-12k, then the coarse brain (not with `fast`).
    pub fem: Vec<FemFigures>,
    /// The audit's lines for each model (empty with `fast`).
    pub audit: Vec<(String, Vec<AuditBar>)>,
    /// `scripts/cholmod_compare.sh`'s output (None when it did not run).
    pub cholmod_log: Option<String>,
}

/// The fem bench's models, in the page's order: (the bench's name for it, the page's).
pub const FEM_MODELS: [(&str, &str); 2] = [("paper-12k", "paper-12k"), ("brain_pial_coarse", "coarse real brain")];

/// The startup probe's runs the page reads (`startup/NAME.json`); with `fast` the cold early start is not run.
pub const STARTUP_RUNS: [&str; 8] =
    ["q15_cold", "q15_cold_background", "q15_cache", "q15_cache_background", "sylvian_cold", "sylvian_cache_background", "user_sylvian_cold", "user_sylvian_background"];

impl PerfRecord {
    /// Reads the run in `dir` (the script's `target/perf/`); the fem bench's figures are in `fem_dir`
    /// (`target/fem-bench-cache/figures/`).
    pub fn load(dir: &Path, fem_dir: &Path, info: RunInfo) -> Result<Self, PerfError> {
        let seconds = read_seconds(&dir.join("seconds.tsv"))?;
        let collision: CollisionReport = read_json(&dir.join("collision.json"))?;
        let collision_table = read_text(&dir.join("collision.md"))?;
        let replays = read_replays(dir)?;
        let mut startup = Vec::new();
        for name in STARTUP_RUNS {
            if info.fast && name == "q15_cold_background" {
                continue;
            }
            startup.push((name.to_string(), read_json(&dir.join("startup").join(format!("{name}.json")))?));
        }
        check_cache_use(&dir.join("startup"), &startup)?;
        let window = if info.no_window {
            None
        } else {
            Some([read_json(&dir.join("window/threads_default.json"))?, read_json(&dir.join("window/threads_all.json"))?])
        };
        let models = if info.fast { &FEM_MODELS[..1] } else { &FEM_MODELS[..] };
        let mut fem = Vec::new();
        let mut audit = Vec::new();
        for (model, _) in models {
            fem.push(read_json(&fem_dir.join(format!("{model}.json")))?);
            if !info.fast {
                audit.push((model.to_string(), read_json(&fem_dir.join(format!("{model}_audit.json")))?));
            }
        }
        let cholmod_log = if info.fast || info.no_cholmod { None } else { Some(read_text(&dir.join("cholmod.log"))?) };
        Ok(Self { info, seconds, collision, collision_table, replays, startup, window, fem, audit, cholmod_log })
    }

    /// How long a measure took, s (0 when the script did not say).
    pub fn seconds_of(&self, measure: &str) -> u64 {
        self.seconds.iter().find(|(m, _)| m == measure).map_or(0, |(_, s)| *s)
    }

    /// A startup run's report.
    pub fn startup(&self, name: &str) -> Option<&StartupReport> {
        self.startup.iter().find(|(n, _)| n == name).map(|(_, r)| r)
    }
}

/// The fine brain's first run computed its columns and wrote the cache; the second read it.
fn check_cache_use(dir: &Path, startup: &[(String, StartupReport)]) -> Result<(), PerfError> {
    for (name, from_cache) in [("q15_cold", false), ("q15_cache", true)] {
        let path = dir.join(format!("{name}.json"));
        let build = startup.iter().find(|(n, _)| n == name).and_then(|(_, r)| r.build.as_ref()).ok_or_else(|| PerfError::new(&path, "no build figures"))?;
        if build.compliance.from_cache != from_cache {
            let said = if from_cache { "did not read the cache the cold run wrote" } else { "read a cache: it was not cold" };
            return Err(PerfError::new(&path, said));
        }
    }
    Ok(())
}

/// `seconds.tsv`: "MEASURE SECONDS" a line.
fn read_seconds(path: &Path) -> Result<Vec<(String, u64)>, PerfError> {
    let mut out = Vec::new();
    for (k, line) in read_text(path)?.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let mut words = line.split_whitespace();
        let (Some(name), Some(Ok(s))) = (words.next(), words.next().map(str::parse)) else {
            return Err(PerfError::new(path, format!("line {}: not \"MEASURE SECONDS\": {line:?}", k + 1)));
        };
        out.push((name.to_string(), s));
    }
    Ok(out)
}

/// `replays.tsv`: "TAG<tab>RUN<tab>COMMAND<tab>DIR" a run (DIR under the run's folder, `DIR.time` beside it).
fn read_replays(dir: &Path) -> Result<Vec<ReplayRun>, PerfError> {
    let manifest = dir.join("replays.tsv");
    let mut out = Vec::new();
    for (k, line) in read_text(&manifest)?.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let fields: Vec<&str> = line.split('\t').collect();
        let [tag, run, command, out_dir] = fields[..] else {
            return Err(PerfError::new(&manifest, format!("line {}: not TAG, RUN, COMMAND and DIR separated by tabs", k + 1)));
        };
        let run = run.parse().map_err(|_| PerfError::new(&manifest, format!("line {}: the run {run:?} is not a number", k + 1)))?;
        let base = dir.join(out_dir);
        let summary: Summary = read_json(&base.join("summary.json"))?;
        let (wall_s, peak_mb) = read_time(&base.with_extension("time"))?;
        let (contact_vertices, forces_n) = last_row_per_blade(&base.join("metrics.csv"))?;
        out.push(ReplayRun { tag: tag.to_string(), run, command: command.to_string(), summary, wall_s, peak_mb, contact_vertices, forces_n });
    }
    if out.is_empty() {
        return Err(PerfError::new(&manifest, "no replay listed"));
    }
    Ok(out)
}

/// `/usr/bin/time -f '%e %M'`'s last line: wall seconds and peak KB ("n/a" without `/usr/bin/time`).
fn read_time(path: &Path) -> Result<(f64, Option<f64>), PerfError> {
    let text = read_text(path)?;
    let line = text.lines().last().unwrap_or_default();
    let mut words = line.split_whitespace();
    let wall = words.next().and_then(|w| w.parse::<f64>().ok()).ok_or_else(|| PerfError::new(path, format!("no wall time in {line:?}")))?;
    let peak = words.next().and_then(|w| w.parse::<f64>().ok()).map(|kb| kb / 1024.0);
    Ok((wall, peak))
}

/// Each blade's contact vertices and force in `metrics.csv`'s last row (columns `NAME_contact_vertices`,
/// `NAME_force_n`, in the file's order).
fn last_row_per_blade(path: &Path) -> Result<(Vec<String>, Vec<f64>), PerfError> {
    let text = read_text(path)?;
    let mut lines = text.lines().filter(|l| !l.is_empty());
    let header: Vec<&str> = lines.next().ok_or_else(|| PerfError::new(path, "empty"))?.split(',').collect();
    let last: Vec<&str> = lines.last().ok_or_else(|| PerfError::new(path, "no frame"))?.split(',').collect();
    let cell = |k: usize| last.get(k).copied().unwrap_or_default();
    let contact = header.iter().enumerate().filter(|(_, h)| h.ends_with("_contact_vertices")).map(|(k, _)| cell(k).to_string()).collect();
    let mut forces = Vec::new();
    for (k, _) in header.iter().enumerate().filter(|(_, h)| h.ends_with("_force_n")) {
        forces.push(cell(k).parse().map_err(|_| PerfError::new(path, format!("the last row's {} is not a number", header[k])))?);
    }
    Ok((contact, forces))
}
