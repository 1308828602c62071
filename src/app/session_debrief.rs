//! A session debriefed: its recording replayed headless (what the window simulated, frame for frame), the scene's
//! own trajectory (the careful surgeon's) replayed the same way as the reference, both scored by
//! [`crate::debrief`], and the page written beside the recording.
//!
//! In: the scenario the session ran and the recording that holds it from the scene at rest. Out: beside the
//! recording `REC_run/` and `REC_reference/` (run folders as `fissure replay` writes them), `REC_debrief.html` and
//! `REC_debrief.json` ([`SessionFiles`]); a [`SessionDebrief`] for the window's panel. Stays true: the replay
//! plays the recording's lead-in and every row to its last, so the debrief covers the whole session; a replay that
//! fails part-way (a frame that cannot be solved) or is stopped is still debriefed with the frames it has, and the
//! page says so; a scene without a trajectory of its own is judged against the literature's limits alone.
//! Used by the window when a session ends ([`SessionDebriefWorker`], on its own thread) and by
//! `fissure debrief REC.csv --scenario S.ron`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use crate::debrief::{self, Debrief, DebriefReadError};
use crate::scenario::Scenario;
use crate::sim::poses::TrajectoryPoses;
use crate::sim::replay::{ReplayError, ReplayOptions, replay};

/// The files a session's debrief writes beside its recording.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionFiles {
    /// The recording replayed: `REC_run/`.
    pub run_dir: PathBuf,
    /// The scene's trajectory replayed: `REC_reference/`.
    pub reference_dir: PathBuf,
    /// `REC_debrief.html`; its JSON beside it, `REC_debrief.json`.
    pub page: PathBuf,
}

impl SessionFiles {
    /// The files for `recording` (`DIR/NAME.csv` gives `DIR/NAME_run/`, `DIR/NAME_reference/`, `DIR/NAME_debrief.html`).
    pub fn beside(recording: &Path) -> Self {
        let dir = recording.parent().map(Path::to_path_buf).unwrap_or_default();
        let stem = recording.file_stem().map_or_else(|| "session".to_string(), |s| s.to_string_lossy().into_owned());
        Self {
            run_dir: dir.join(format!("{stem}_run")),
            reference_dir: dir.join(format!("{stem}_reference")),
            page: dir.join(format!("{stem}_debrief.html")),
        }
    }

    /// The JSON written beside the page.
    pub fn json(&self) -> PathBuf {
        debrief::page::json_path(&self.page)
    }
}

/// A finished session debrief.
#[derive(Debug, Clone)]
pub struct SessionDebrief {
    pub files: SessionFiles,
    pub debrief: Debrief,
    /// Why there is no reference, when there is none (the scene has no trajectory, or its replay failed).
    pub no_reference: Option<String>,
}

/// Why a session could not be debriefed.
#[derive(Debug, thiserror::Error)]
pub enum SessionDebriefError {
    #[error("the recording {}: {message}", path.display())]
    Recording { path: PathBuf, message: String },
    #[error("replaying the session: {0}")]
    Replay(#[source] ReplayError),
    #[error("reading the replayed session: {0}")]
    Read(#[source] DebriefReadError),
    #[error("writing the debrief {}: {message}", path.display())]
    Page { path: PathBuf, message: String },
    #[error("stopped before the session was replayed")]
    Interrupted,
}

/// What the debrief is doing, for a progress bar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SessionStep {
    /// Replaying the session's recording.
    Session,
    /// Replaying the scene's own trajectory (the reference).
    Reference,
    /// Scoring and writing the page.
    Page,
}

impl SessionStep {
    pub fn words(self) -> &'static str {
        match self {
            SessionStep::Session => "replaying your session",
            SessionStep::Reference => "replaying the careful surgeon's trajectory",
            SessionStep::Page => "writing the page",
        }
    }
}

/// Whether a replay's error leaves a run folder worth debriefing (a frame failed or the run was stopped after its
/// outputs were opened: the rows so far and `summary.json` are written).
fn left_a_run(e: &ReplayError) -> bool {
    matches!(e, ReplayError::Step { .. } | ReplayError::Frames(_))
}

/// Replays `scenario` (with `trajectory` in place of its own) into `out_dir`, reporting frames to `progress`.
fn replay_into(
    scenario: &Scenario,
    trajectory: Option<&Path>,
    out_dir: &Path,
    interrupt: &AtomicBool,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(), ReplayError> {
    let options = ReplayOptions { out_dir: out_dir.to_path_buf(), trajectory: trajectory.map(Path::to_path_buf), vtk: false };
    let mut on_frame = |_: &mut crate::sim::Pipeline, _: &crate::sim::SimState, done: u64, total: u64| {
        progress(done, total);
        Ok(())
    };
    match replay(scenario, &options, interrupt, &mut on_frame, None) {
        Ok(_) => Ok(()),
        Err(e) if left_a_run(&e) => {
            tracing::warn!("the replay stopped early, debriefing the frames it has: {e}");
            Ok(())
        }
        Err(e) => Err(e),
    }
}

/// Debriefs the session in `recording` (a window recording: the session from the scene at rest, lead-in at
/// negative times) on `scenario`, against the scenario's own trajectory when it has one. `progress(step, done,
/// total)` is told each frame of each replay. Writes the [`SessionFiles`] beside the recording.
pub fn debrief_recording(
    scenario: &Scenario,
    recording: &Path,
    interrupt: &AtomicBool,
    progress: &mut dyn FnMut(SessionStep, u64, u64),
) -> Result<SessionDebrief, SessionDebriefError> {
    let files = SessionFiles::beside(recording);
    let bad = |message: String| SessionDebriefError::Recording { path: recording.to_path_buf(), message };
    let source = TrajectoryPoses::for_scenario(scenario, Some(recording)).map_err(|e| bad(e.to_string()))?;
    let end = source.trajectory_end().unwrap_or(0.0);
    if !(end > 0.0) {
        return Err(bad("it spans no time: nothing to replay".into()));
    }
    // The session's replay lasts exactly as long as the recording (lead-in included).
    let mut session = scenario.clone();
    session.duration = end;
    replay_into(&session, Some(recording), &files.run_dir, interrupt, &mut |d, t| progress(SessionStep::Session, d, t))
        .map_err(SessionDebriefError::Replay)?;
    if interrupt.load(Ordering::Relaxed) {
        return Err(SessionDebriefError::Interrupted);
    }
    let run = debrief::read_run(&files.run_dir).map_err(SessionDebriefError::Read)?;
    let (reference, no_reference) = match &scenario.trajectory {
        None => (None, Some(format!("the scene {} has no trajectory of its own to compare with", scenario.name))),
        Some(_) => {
            let replayed = replay_into(scenario, None, &files.reference_dir, interrupt, &mut |d, t| progress(SessionStep::Reference, d, t));
            match replayed.map_err(|e| e.to_string()).and_then(|()| debrief::read_run(&files.reference_dir).map_err(|e| e.to_string())) {
                Ok(r) if !interrupt.load(Ordering::Relaxed) => (Some(r), None),
                Ok(_) => return Err(SessionDebriefError::Interrupted),
                Err(e) => (None, Some(format!("the scene's own trajectory could not be replayed: {e}"))),
            }
        }
    };
    progress(SessionStep::Page, 0, 1);
    let debrief = debrief::debrief(&run, reference.as_ref());
    debrief::page::write_page(std::slice::from_ref(&run), std::slice::from_ref(&debrief), &files.page)
        .map_err(|e| SessionDebriefError::Page { path: files.page.clone(), message: e.to_string() })?;
    progress(SessionStep::Page, 1, 1);
    Ok(SessionDebrief { files, debrief, no_reference })
}

/// The figures a blade's panel rows always show (the rest only when judged past "within").
const KEY_FIGURES: [&str; 4] = ["peak_force_n", "time_above_20mmhg_s", "path_length_mm", "economy_of_motion"];

fn level(v: Option<debrief::Verdict>) -> Option<u8> {
    v.map(|v| match v {
        debrief::Verdict::Within => 0,
        debrief::Verdict::Above => 1,
        debrief::Verdict::FarAbove | debrief::Verdict::OverLimit => 2,
    })
}

fn row(section: &str, m: &debrief::Metric) -> crate::ui::debrief::DebriefRow {
    use debrief::page::shown;
    let unit = |v: Option<f64>| if m.unit.is_empty() { shown(v) } else { format!("{} {}", shown(v), m.unit) };
    let against = match (m.reference, m.limit) {
        (Some(r), Some(l)) => format!("the reference's {}, limit {}", unit(Some(r)), unit(Some(l))),
        (Some(r), None) => format!("the reference's {}", unit(Some(r))),
        (None, Some(l)) => format!("the limit {}", unit(Some(l))),
        (None, None) => String::new(),
    };
    crate::ui::debrief::DebriefRow {
        section: section.to_string(),
        name: m.name.clone(),
        value: unit(m.value),
        reference: m.reference.map_or_else(|| "-".to_string(), |r| unit(Some(r))),
        against,
        verdict: m.verdict.map(|v| v.words().to_string()).unwrap_or_default(),
        level: level(m.verdict),
    }
}

/// The panel's view of a finished debrief: per blade its key figures (peak force, time above 20 mmHg, path length,
/// economy of motion) and every other figure judged past "within"; the pair's and the scene's judged figures; the
/// sentences; where the page is.
pub fn panel_summary(d: &SessionDebrief) -> crate::ui::debrief::DebriefSummary {
    let b = &d.debrief;
    let against = match &b.reference {
        Some(_) => "against the careful surgeon's trajectory".to_string(),
        None => "against the literature's limits".to_string(),
    };
    let mut rows = Vec::new();
    let mut sentences = Vec::new();
    for blade in &b.blades {
        let shown = blade.metrics.iter().filter(|m| KEY_FIGURES.contains(&m.key.as_str()) || m.verdict.is_some_and(|v| v > debrief::Verdict::Within));
        rows.extend(shown.map(|m| row(&blade.name, m)));
        sentences.extend(blade.sentences.iter().cloned());
    }
    if let Some(p) = &b.pair {
        rows.extend(p.metrics.iter().filter(|m| m.verdict.is_some()).map(|m| row("both blades", m)));
    }
    rows.extend(b.scene.iter().map(|m| row("scene", m)));
    sentences.extend(b.scene_sentences.iter().cloned());
    let mut notes: Vec<String> = d.no_reference.iter().cloned().collect();
    if b.interrupted {
        notes.push(format!("the replay stopped early: {} frames debriefed", b.frames));
    }
    notes.extend(b.integrity_failures.iter().map(|f| format!("integrity: {f}")));
    crate::ui::debrief::DebriefSummary {
        headline: format!("{} s simulated, {against}", debrief::page::shown(Some(b.simulated_s))),
        rows,
        sentences,
        page: d.files.page.display().to_string(),
        notes,
    }
}

/// How far a [`SessionDebriefWorker`] is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SessionProgress {
    pub step: SessionStep,
    /// Of this step, 0 to 1.
    pub fraction: f64,
}

/// A session's debrief made on its own thread (the window keeps drawing meanwhile).
pub struct SessionDebriefWorker {
    progress: Arc<Mutex<SessionProgress>>,
    interrupt: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<SessionDebrief, String>>>,
    /// The recording being debriefed (for a message when the window closes first).
    pub recording: PathBuf,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl SessionDebriefWorker {
    /// Starts debriefing `recording` on `scenario`; an error starting the thread comes back as the result.
    pub fn start(scenario: Scenario, recording: PathBuf) -> Result<Self, String> {
        let progress = Arc::new(Mutex::new(SessionProgress { step: SessionStep::Session, fraction: 0.0 }));
        let interrupt = Arc::new(AtomicBool::new(false));
        let (p, stop, rec) = (progress.clone(), interrupt.clone(), recording.clone());
        let thread = std::thread::Builder::new()
            .name("fissure-debrief".into())
            .spawn(move || {
                let mut tell = |step: SessionStep, done: u64, total: u64| {
                    *lock(&p) = SessionProgress { step, fraction: if total > 0 { done as f64 / total as f64 } else { 0.0 } };
                };
                debrief_recording(&scenario, &rec, &stop, &mut tell).map_err(|e| format!("{e:#}"))
            })
            .map_err(|e| format!("cannot start the debrief: {e}"))?;
        Ok(Self { progress, interrupt, thread: Some(thread), recording })
    }

    pub fn progress(&self) -> SessionProgress {
        *lock(&self.progress)
    }

    /// The result once the thread is done (taken once; `None` while it runs and after).
    pub fn poll(&mut self) -> Option<Result<SessionDebrief, String>> {
        if !self.thread.as_ref().is_some_and(JoinHandle::is_finished) {
            return None;
        }
        let thread = self.thread.take()?;
        Some(thread.join().unwrap_or_else(|_| Err("the debrief stopped unexpectedly".into())))
    }

    /// Asks the thread to stop after the frame it is on (the window is closing).
    pub fn stop(&self) {
        self.interrupt.store(true, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_files_go_beside_the_recording_named_after_it() {
        let f = SessionFiles::beside(Path::new("/data/rec/session_17.csv"));
        assert_eq!(f.run_dir, PathBuf::from("/data/rec/session_17_run"));
        assert_eq!(f.reference_dir, PathBuf::from("/data/rec/session_17_reference"));
        assert_eq!(f.page, PathBuf::from("/data/rec/session_17_debrief.html"));
        assert_eq!(f.json(), PathBuf::from("/data/rec/session_17_debrief.json"));
    }
}
