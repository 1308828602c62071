//! The simulation thread of the window: steps the pipeline at the scenario's
//! fixed time step in real time, publishes each frame for the renderer and the
//! haptic loop, records trajectories.
//!
//! In: a scenario, the live input ([`LiveInput`]: the keyboard and gamepad
//! commands the window writes), an optional OpenIGTLink server, commands
//! ([`SimCommand`]). Out: [`Snapshot`]s through an [`Exchange`] (the sim never
//! waits for the renderer), [`HapticModel`]s to the [`ForceOutput`], trajectory
//! CSVs, and at the end a [`SimExit`]. Stays true: each spatula's pose comes
//! from its binding (keyboard / gamepad velocities integrated over the fixed
//! step, OpenIGTLink's latest pose, or the scenario's trajectory at the frame's
//! time); a recording's t = 0 is the frame at which it was started (key R),
//! and the session before it, from the brain at rest, comes first at negative
//! times (the run-up), so `fissure replay --trajectory` rebuilds the tissue
//! as it was at the press and then plays the recording with the poses the sim
//! actually used; a recording that cannot be started or written says so in
//! the panel and the log and keeps every row written so far; a failing frame
//! is logged and the last state holds.
//!
//! The loop reads as its steps: take the window's commands, wait for the
//! window's scripted actions, take the frame's input, advance (step, record,
//! publish), keep real time. What belongs to one scene (the built pipeline,
//! pose guards, history, recording, a cut asked for, peak forces) is a
//! `Session`, replaced whole when the scene changes (culling, collision
//! backend, another scenario); what lasts the run (scripts, devices, buffers,
//! the background solve, the summary) is the `Run` around it.

use super::draw::{Snapshot, vertex_areas};
use super::exchange::Exchange;
use super::haptics::{ForceOutput, HapticModel};
use super::script::ScriptAction;
use crate::geometry::Pose;
use crate::input::gamepad::PadCommand;
use crate::input::igtl::IgtlServer;
use crate::input::keyboard::{KeyCommand, KeyEvent, KeyboardController};
use crate::input::PoseGuard;
use crate::input::drivers::{BindingKind, DeviceOffers, drive};
use crate::scenario::{CollisionBackend, Effect, EffectSet, InputBinding, Scenario, Trajectory, TrajectoryRecorder};
use crate::sim::{BuildOptions, FrameInput, Pipeline, SimState};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the window asks the simulation to do.
#[derive(Debug, Clone, PartialEq)]
pub enum SimCommand {
    /// Record to this CSV from now on (t = 0 now; the session so far before it
    /// at negative times), then keep appending.
    StartRecording(PathBuf),
    /// Close the recording (every row is already on disk).
    StopRecording,
    /// Rebuild with His-flag culling on or off.
    SetCulling(bool),
    /// Rebuild with another collision backend.
    SetBackend(CollisionBackend),
    /// Load another scenario (rebuild, restart at time 0).
    LoadScenario(PathBuf),
    /// The window shows (true) or stops showing the strain colour: a scene
    /// without the StressField stage then gets its stress from a background
    /// worker on the other core (never waited for; a frame or more behind).
    ShowStrain(bool),
    /// Microscissors at this blade's tip (index from 0): the arachnoid bands
    /// within reach are cut at the next frame (a scene without tethers says so).
    Cut(usize),
    /// Stop after the current frame.
    Quit,
    /// End the session: the recording under way closes, or, with none, the whole session from the scene at rest
    /// is written to this file as a recording; then the loop stops, leaving [`SimShared::ended`] for the debrief.
    EndSession(PathBuf),
}

/// A session the window ended: its recording and the scene it ran, for the debrief.
#[derive(Debug, Clone)]
pub struct EndedSession {
    /// The trajectory file holding the whole session from the scene at rest (a lead-in at negative times, if
    /// recording started mid-session).
    pub recording: PathBuf,
    /// The scenario the session ran (the last one loaded).
    pub scenario: Scenario,
    /// Simulated seconds since the scene was at rest.
    pub simulated_s: f64,
}

/// The commands the window's input devices give now.
#[derive(Debug, Clone, Copy, Default)]
pub struct LiveInput {
    pub keyboard: KeyCommand,
    pub pad: PadCommand,
}

/// Things the window reads without waiting.
#[derive(Debug, Default)]
pub struct SimShared {
    /// The newest frame.
    pub frames: Exchange<Snapshot>,
    /// The pipeline's static drawing data, replaced on a rebuild (with `generation` bumped).
    pub scene: Mutex<Arc<super::draw::SceneStatic>>,
    pub generation: AtomicU64,
    /// Keyboard / gamepad commands, written by the window.
    pub input: Mutex<LiveInput>,
    /// A line for the panel (build progress, errors, recording state).
    pub status: Mutex<String>,
    /// True while recording.
    pub recording: AtomicBool,
    /// The last recording failure (cannot create, a write failed), for the panel.
    pub record_error: Mutex<Option<String>>,
    /// Set when the thread has finished.
    pub finished: AtomicBool,
    /// The first build's progress while it runs (the window's loading screen).
    pub progress: Mutex<Option<BuildProgress>>,
    /// Why the first build failed (the thread then ends without frames).
    pub build_error: Mutex<Option<String>>,
    /// Set when the first build is done and the loop runs (it reads commands).
    pub running: AtomicBool,
    /// The simulated time through which the window has handled its scripted
    /// actions (`None`: none yet); see [`SimOptions::window_script_times`].
    pub window_script_done: Mutex<Option<f64>>,
    /// Set when [`SimCommand::EndSession`] ended the loop: what to debrief (`None` inside: nothing was simulated
    /// or the recording could not be written; the status line says which).
    pub ended: Mutex<Option<Option<EndedSession>>>,
}

/// How far a build is: compliance columns done of the total, and the time left
/// at the rate so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildProgress {
    pub done: usize,
    pub total: usize,
    pub eta_s: Option<f64>,
}

/// What the simulation thread leaves when it ends.
#[derive(Debug, Clone, Default)]
pub struct SimExit {
    pub frames: u64,
    pub time_s: f64,
    pub final_poses: Vec<Pose>,
    /// Largest |force| per spatula over the session, N.
    pub peak_force_n: Vec<f64>,
    /// Frame step times (ms) of every frame, for percentiles.
    pub step_ms: Vec<f64>,
    pub state_hash: String,
    pub failed_frames: u64,
    pub recording: Option<PathBuf>,
    /// Frames published with a strain field from the background stress worker.
    pub background_strain_frames: u64,
    /// The collision backend in use at the end, and what the stage said (the `auto`
    /// choice, a GPU fallback).
    pub collision_backend: Option<String>,
    pub collision_notes: Vec<String>,
    /// Poses the pose guard refused (non-finite, non-unit quaternion; the last good one held).
    pub rejected_poses: u64,
    /// OpenIGTLink poses refused for lying outside the workspace / moving too fast
    /// (the server's counts over the session; 0 without a server).
    pub tracker_outside_workspace: u64,
    pub tracker_too_fast: u64,
}

/// Options of the thread.
pub struct SimOptions {
    /// Stop after this many frames (None: run until told).
    pub max_frames: Option<u64>,
    /// Simulation-side scripted actions, ascending by time.
    pub script: Vec<(f64, ScriptAction)>,
    /// Run as fast as possible instead of in real time (tests).
    pub free_running: bool,
    /// Times of the window's own scripted actions (keys through the window's
    /// focus rules, panel focus, views), ascending. The window acts at the
    /// first frame it draws at or after each time; the loop holds the frame
    /// at that time until the window says it has (at most
    /// [`WINDOW_SCRIPT_WAIT`]), so a script moves the blades the same
    /// whatever the display rate or the machine's load.
    pub window_script_times: Vec<f64>,
}

/// The longest the loop waits for the window to handle a scripted action
/// (a window that stopped drawing must not freeze the simulation).
pub const WINDOW_SCRIPT_WAIT: Duration = Duration::from_secs(10);

/// Handle to the running simulation thread.
pub struct SimThread {
    pub shared: Arc<SimShared>,
    commands: Sender<SimCommand>,
    thread: Option<JoinHandle<SimExit>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A pipeline ready to run, with what goes with it.
struct Built {
    scenario: Scenario,
    pipeline: Pipeline,
    state: SimState,
    trajectory: Option<Trajectory>,
    areas: Vec<f64>,
}

fn build(scenario: Scenario, shared: &SimShared) -> Result<Built, String> {
    *lock(&shared.status) = format!("building {} ...", scenario.name);
    let trajectory = match &scenario.trajectory {
        Some(p) => Some(Trajectory::load(p).map_err(|e| e.to_string())?),
        None => None,
    };
    // The compliance precompute can take minutes on a fine mesh: its progress
    // goes to the panel's status line (a reload in the open window) and to a
    // bar on the terminal, and to the window's loading screen ([`SimShared::progress`]).
    let bar = super::progress::terminal_bar(0, "compliance", "{msg:>12} [{bar:40}] {pos}/{len} columns ({eta})");
    let name = scenario.name.clone();
    let mut first: Option<(std::time::Instant, usize)> = None;
    let mut progress = |done: usize, total: usize| {
        // The rate since the first report (the factorization before it is not columns).
        let (t0, d0) = *first.get_or_insert((std::time::Instant::now(), done));
        let rate = (done - d0.min(done)) as f64 / t0.elapsed().as_secs_f64().max(1e-9);
        let eta_s = (done > d0 && rate > 0.0).then(|| (total.saturating_sub(done)) as f64 / rate);
        *lock(&shared.status) = match eta_s {
            Some(eta) => format!("building {name}: compliance {done} / {total} columns, about {eta:.0} s left"),
            None => format!("building {name}: compliance {done} / {total} columns"),
        };
        *lock(&shared.progress) = Some(BuildProgress { done, total, eta_s });
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    // With `solver.early_start` the columns are computed in the background
    // once the factor is done: the scene opens without waiting for them.
    // Blades that follow the trajectory: their path sets the `Auto` region of
    // interest, as in a replay of the scene.
    let follows = scenario.spatulas.iter().any(|s| matches!(s.input, InputBinding::Trajectory));
    let expected_poses = match crate::sim::poses::TrajectoryPoses::for_scenario(&scenario, None) {
        Ok(source) if follows => source.samples(scenario.duration, 200),
        _ => Vec::new(),
    };
    let expected_step_s = scenario.duration / 200.0;
    let built = Pipeline::build(&scenario, BuildOptions { expected_poses, expected_step_s, progress: Some(&mut progress), background_columns: true });
    bar.finish_and_clear();
    *lock(&shared.progress) = None;
    let (pipeline, state) = built.map_err(|e| e.to_string())?;
    let areas = vertex_areas(pipeline.rest_positions(), &pipeline.surface().triangles);
    *lock(&shared.scene) = Arc::new(super::draw::SceneStatic {
        display: Some(scenario.display),
        relaxation_half_time_s: scenario.tissue_time.relaxation.as_ref().and_then(super::tissue_time::half_time_s),
        ..super::draw::SceneStatic::of(&pipeline)
    });
    shared.generation.fetch_add(1, Ordering::Relaxed);
    *lock(&shared.status) = String::new();
    Ok(Built { scenario, pipeline, state, trajectory, areas })
}

impl SimThread {
    /// Starts the thread, which builds the pipeline and then runs the loop; the
    /// window opens meanwhile and shows the build's progress
    /// ([`SimShared::progress`]). A build that fails ends the thread with
    /// [`SimShared::build_error`] set (the window then closes with it).
    pub fn start(
        scenario: Scenario,
        igtl: Option<Arc<Mutex<IgtlServer>>>,
        haptics: Option<Arc<ForceOutput>>,
        options: SimOptions,
    ) -> Result<Self, String> {
        let shared = Arc::new(SimShared::default());
        *lock(&shared.status) = format!("building {} ...", scenario.name);
        let (tx, rx) = std::sync::mpsc::channel();
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("fissure-sim".into())
            .spawn(move || {
                let exit = match build(scenario, &s) {
                    Ok(built) => {
                        s.running.store(true, Ordering::Release);
                        run_loop(built, &s, rx, igtl, haptics, options)
                    }
                    Err(e) => {
                        *lock(&s.status) = format!("could not build the scene: {e}");
                        *lock(&s.build_error) = Some(e);
                        SimExit::default()
                    }
                };
                *lock(&s.progress) = None;
                s.finished.store(true, Ordering::Release);
                exit
            })
            .map_err(|e| format!("cannot start the simulation thread: {e}"))?;
        Ok(Self { shared, commands: tx, thread: Some(thread) })
    }

    /// Sends a command (ignored once the thread has ended).
    pub fn send(&self, command: SimCommand) {
        let _ = self.commands.send(command);
    }

    /// True when the loop has ended (frame limit, quit, or failure).
    pub fn finished(&self) -> bool {
        self.shared.finished.load(Ordering::Acquire)
    }

    /// Stops the loop (flushing any recording) and returns its summary.
    ///
    /// Closed while the first build still runs (it reads no commands until it
    /// is done, a minute or more on a fine mesh), the thread is left to the
    /// process's exit instead of being waited for: nothing was simulated or
    /// recorded yet, and a compliance cache file is written whole or not at all.
    pub fn stop(mut self) -> SimExit {
        self.join_if_running().unwrap_or_default()
    }

    fn join_if_running(&mut self) -> Option<SimExit> {
        let _ = self.commands.send(SimCommand::Quit);
        let thread = self.thread.take()?;
        let running = self.shared.running.load(Ordering::Acquire) || self.shared.finished.load(Ordering::Acquire);
        running.then(|| thread.join().ok()).flatten()
    }
}

impl Drop for SimThread {
    fn drop(&mut self) {
        let _ = self.join_if_running();
    }
}

/// The pose a trajectory CSV reproduces: millimetres and a renormalised
/// quaternion, as `Trajectory` reads them back. The simulation uses this
/// representable pose so a recording replays bit for bit (iterated to a fixed
/// point of the round trip; it settles in one or two passes).
fn as_recorded(pose: Pose) -> Pose {
    let mut p = pose;
    for _ in 0..4 {
        let q = p.rotation.quaternion();
        let next = Pose {
            position: (p.position * 1e3) * 1e-3,
            rotation: crate::math::Quat::new_normalize(nalgebra::Quaternion::new(q.w, q.i, q.j, q.k)),
        };
        if next == p {
            break;
        }
        p = next;
    }
    p
}

/// The session's poses so far, from the scene at rest (time 0), for a
/// recording started mid-session, with the blades that cut in each frame.
struct History {
    rows: Vec<(f64, Vec<Pose>)>,
    /// Per row, a bit per blade: microscissors cut at its tip in the frame ending at the row's time.
    cuts: Vec<u64>,
    /// The scene has tethers: recordings get the `cut` column.
    with_cut: bool,
}

impl History {
    /// A history starting with the poses at rest.
    fn at_rest(poses: &[Pose], with_cut: bool) -> Self {
        Self { rows: vec![(0.0, poses.to_vec())], cuts: vec![0], with_cut }
    }

    fn push(&mut self, time_s: f64, poses: Vec<Pose>, cut: Option<usize>) {
        self.rows.push((time_s, poses));
        self.cuts.push(cut.filter(|&k| k < 64).map_or(0, |k| 1u64 << k));
    }
}

/// Whether the scene's recordings carry the `cut` column (it has tethers to cut).
fn records_cuts(scenario: &Scenario) -> bool {
    scenario.effects.contains(Effect::Tethers)
}

/// A recording under way: rows at session time minus `origin_s` (the session
/// time at which it was started).
struct Recording {
    recorder: TrajectoryRecorder,
    origin_s: f64,
}

/// Starts a recording at session time `origin_s`: t = 0 is now, the history
/// before it (the run-up the replay needs to rebuild the tissue) at negative times.
fn open_recording(path: &std::path::Path, history: &History, origin_s: f64) -> Result<Recording, String> {
    let note = format!(
        "recording: t = 0 is the moment it was started ({origin_s} s into the session); the rows before it are the session from the scene at rest (replay plays them first)"
    );
    let mut recorder = TrajectoryRecorder::create_with(path, &note, history.with_cut).map_err(|e| e.to_string())?;
    for ((t, poses), cuts) in history.rows.iter().zip(&history.cuts) {
        for (k, p) in poses.iter().enumerate() {
            recorder.record_with_cut(t - origin_s, k, p, k < 64 && cuts & (1 << k) != 0).map_err(|e| e.to_string())?;
        }
    }
    Ok(Recording { recorder, origin_s })
}

/// Ends the session for the debrief: the recording under way is the session's file (it holds the session from
/// rest); with none, the whole history is written to `path` as one. `None` when nothing was simulated yet or the
/// file cannot be written (the status line says which).
fn end_session(path: &std::path::Path, recording: Option<Recording>, history: &History, b: &Built, shared: &SimShared) -> Option<EndedSession> {
    if history.rows.len() < 2 {
        *lock(&shared.status) = "session ended before its first frame: nothing to debrief".into();
        stopped(shared, recording);
        return None;
    }
    let file = match recording {
        Some(r) => {
            let file = r.recorder.path().to_path_buf();
            stopped(shared, Some(r));
            file
        }
        None => match open_recording(path, history, b.state.time_s) {
            Ok(r) => r.recorder.path().to_path_buf(),
            Err(e) => {
                recording_failed(shared, format!("cannot write the session for its debrief: {e}"));
                return None;
            }
        },
    };
    *lock(&shared.status) = format!("session ended: {}", file.display());
    Some(EndedSession { recording: file, scenario: b.scenario.clone(), simulated_s: b.state.time_s })
}

/// Says in the panel and the log that a recording failed; what was written stays.
fn recording_failed(shared: &SimShared, message: String) {
    tracing::error!("{message}");
    *lock(&shared.status) = message.clone();
    *lock(&shared.record_error) = Some(message);
    shared.recording.store(false, Ordering::Relaxed);
}

fn started(shared: &SimShared, path: &std::path::Path) {
    *lock(&shared.record_error) = None;
    shared.recording.store(true, Ordering::Relaxed);
    *lock(&shared.status) = format!("recording to {}", path.display());
}

/// Ends a recording (the file is flushed as it is dropped); the status line
/// names the file, whether the window's key or a script stopped it.
fn stopped(shared: &SimShared, recording: Option<Recording>) {
    if let Some(r) = recording {
        *lock(&shared.status) = format!("recorded {}", r.recorder.path().display());
    }
    shared.recording.store(false, Ordering::Relaxed);
}

/// Asks the pipeline to cut at blade `k`'s tip; the blade when the scene has
/// tethers (the frame that cuts then says what it cut), else `None` and the
/// status line says there is nothing to cut.
fn request_cut(b: &mut Built, k: usize, shared: &SimShared) -> Option<usize> {
    let name = b.scenario.spatulas.get(k).map_or_else(|| format!("blade {}", k + 1), |s| s.name.clone());
    if k >= b.scenario.spatulas.len() {
        *lock(&shared.status) = format!("cut: this scene has no {name}");
        return None;
    }
    if b.pipeline.request_cut(k) {
        Some(k)
    } else {
        *lock(&shared.status) = format!("cut at {name}'s tip: this scene has no vessels or bands");
        None
    }
}

/// The status line after a frame that carried out a cut at blade `k`'s tip.
fn say_what_was_cut(b: &Built, k: usize, report: &crate::sim::FrameReport, shared: &SimShared) {
    let cut = report.tethers.as_ref().map_or(0, |t| t.events.iter().filter(|e| e.kind == crate::sim::tethers::LinkState::Cut).count());
    let name = b.scenario.spatulas.get(k).map_or("the blade", |s| s.name.as_str());
    let reach_mm = crate::sim::tethers::CUT_RADIUS_M * 1e3;
    *lock(&shared.status) = match cut {
        0 => format!("cut at {name}'s tip: no band within {reach_mm:.0} mm"),
        1 => format!("cut at {name}'s tip: 1 band cut"),
        n => format!("cut at {name}'s tip: {n} bands cut"),
    };
}

/// The background solve (`app::stress_worker::StressWorker`, on the other core, never waited
/// for): the strain colour for a scene without the StressField stage
/// (started when the window first asks for strain) and the surface beyond
/// the working region, whose vertices have no compliance rows and so move
/// in the picture only by this solve (started with the first frame).
#[derive(Default)]
struct BackgroundSolve {
    /// The window shows strain.
    wanted: bool,
    worker: Option<super::stress_worker::StressWorker>,
    /// Set when the worker could not start or stopped: no more tries.
    failed: bool,
    /// The newest stress the worker finished (empty: none yet, or not asked).
    stress: Vec<crate::fem::ElementStress>,
    /// Every node's displacement for the newest frame the worker finished (empty: none yet).
    nodes: Vec<crate::math::Vec3>,
    /// When the far surface alone was last asked for.
    far_posted: Option<Instant>,
}

/// The far surface alone is solved at most this often (s): it moves slowly
/// and a solve a frame would take the simulation's core on a small machine.
const FAR_SURFACE_PERIOD_S: f64 = 0.1;

impl BackgroundSolve {
    /// Another scene: the worker's factor and mesh, and what it solved, are stale.
    fn forget_scene(&mut self) {
        self.worker = None;
        self.stress.clear();
        self.nodes.clear();
    }

    /// Posts this frame's forces and picks up the newest finished solve;
    /// true when there is stress to show. Never waits; failures go to the status line once.
    fn update(&mut self, pipeline: &Pipeline, state: &SimState, shared: &SimShared) -> bool {
        let strain = self.wanted && !pipeline.effects().contains(Effect::StressField);
        let far = !pipeline.solver().far_vertices().is_empty();
        if self.failed || !(strain || far) {
            return false;
        }
        if self.worker.is_none() {
            match super::stress_worker::StressWorker::start(pipeline.solver().model()) {
                Ok(w) => self.worker = Some(w),
                Err(e) => {
                    self.failed = true;
                    *lock(&shared.status) = format!("background solve unavailable (strain colour, far surface): {e}");
                    return false;
                }
            }
        }
        let Some(worker) = self.worker.as_mut() else { return false };
        let due = self.far_posted.is_none_or(|t| t.elapsed().as_secs_f64() >= FAR_SURFACE_PERIOD_S);
        if strain || due {
            worker.post(state.frame, pipeline.solver().last_forces(), strain);
            self.far_posted = Some(Instant::now());
        }
        worker.take(&mut self.stress, &mut self.nodes);
        if let Some(reason) = worker.take_failure() {
            self.failed = true;
            self.worker = None;
            *lock(&shared.status) = format!("background solve stopped (strain colour, far surface): {reason}");
            return false;
        }
        strain && !self.stress.is_empty()
    }
}

/// What lasts the whole run, whatever the scene: the window's shared state and
/// devices, the scripts, the buffers reused frame after frame, the background
/// solve and the run's summary.
struct Run<'a> {
    shared: &'a SimShared,
    igtl: Option<Arc<Mutex<IgtlServer>>>,
    haptics: Option<Arc<ForceOutput>>,
    /// Stop after this many frames of the scene (None: run until told).
    max_frames: Option<u64>,
    free_running: bool,
    script: Scripted,
    devices: super::devices::Devices,
    background: BackgroundSolve,
    buffers: FrameBuffers,
    exit: SimExit,
    /// The poses refused by the guards of the scenes before this one.
    rejected_before: u64,
    /// The count of tracker poses the server refused, as last shown in the panel.
    tracker_refused_shown: u64,
    /// A failed frame was logged (further failures are only counted).
    failed_logged: bool,
    /// The script asked to stop (after the frame under way).
    quit: bool,
}

/// The scripted input: the simulation's actions, the times of the window's
/// own, and the keys the script holds.
struct Scripted {
    actions: std::iter::Peekable<std::vec::IntoIter<(f64, ScriptAction)>>,
    window_times: std::iter::Peekable<std::vec::IntoIter<f64>>,
    keys: KeyboardController,
    /// A scripted key came: the script's keys drive the blades from then on.
    active: bool,
}

/// Buffers reused frame after frame.
#[derive(Default)]
struct FrameBuffers {
    /// The snapshot being filled (the exchange swaps it with the window's).
    back: Snapshot,
    input: FrameInput,
    haptic_scratch: Vec<f64>,
}

/// One scene's run from the scene at rest: the built scene and what the loop
/// keeps about it. A scene change replaces it whole.
struct Session {
    scene: Built,
    /// One per spatula: refuses bad poses, keeps the last good one.
    guards: Vec<PoseGuard>,
    history: History,
    recording: Option<Recording>,
    /// Per blade: the keys took it over from its trajectory.
    taken_over: Vec<bool>,
    /// A cut asked for (the blade): the frame that carries it out says what it cut.
    cut_asked: Option<usize>,
    /// Compliance columns computed in the background: the count last shown.
    columns_shown: Option<usize>,
    /// Largest |force| per spatula in this scene, N.
    peak_force_n: Vec<f64>,
    /// When the next frame is due (real time).
    next_frame: Instant,
}

/// What the window's commands leave the loop to do.
enum Commands {
    /// None left: go on with the frame.
    Drained,
    /// Change the scene to this one (the commands after it apply to the new scene).
    ChangeScene(Box<Scenario>),
    /// End the loop.
    Stop,
}

fn run_loop(
    built: Built,
    shared: &SimShared,
    commands: Receiver<SimCommand>,
    igtl: Option<Arc<Mutex<IgtlServer>>>,
    haptics: Option<Arc<ForceOutput>>,
    options: SimOptions,
) -> SimExit {
    let mut run = Run::new(shared, igtl, haptics, options, &built);
    let mut session = Session::new(built);
    loop {
        match session.take_commands(&commands, &mut run) {
            Commands::Drained => {}
            Commands::ChangeScene(scenario) => {
                // A scene change restarts at rest: the history and any recording end here.
                match build(*scenario, shared) {
                    Ok(built) => session = run.change_scene(session, built),
                    Err(e) => *lock(&shared.status) = format!("rebuild failed, keeping the old scene: {e}"),
                }
                continue;
            }
            Commands::Stop => break,
        }
        if run.quit || run.max_frames.is_some_and(|m| session.scene.state.frame >= m) {
            break;
        }
        session.wait_for_window_script(&mut run);
        let dt = session.take_input(&mut run);
        session.advance(&mut run);
        if !run.free_running {
            session.keep_real_time(dt);
        }
    }
    run.finish(session)
}

impl<'a> Run<'a> {
    fn new(
        shared: &'a SimShared,
        igtl: Option<Arc<Mutex<IgtlServer>>>,
        haptics: Option<Arc<ForceOutput>>,
        options: SimOptions,
        built: &Built,
    ) -> Self {
        let mut keys = KeyboardController::default();
        keys.set_spatula_count(built.scenario.spatulas.len());
        let script = Scripted {
            actions: options.script.into_iter().peekable(),
            window_times: options.window_script_times.into_iter().peekable(),
            keys,
            active: false,
        };
        Self {
            shared,
            igtl,
            haptics,
            max_frames: options.max_frames,
            free_running: options.free_running,
            script,
            devices: super::devices::Devices::default(),
            background: BackgroundSolve::default(),
            buffers: FrameBuffers::default(),
            exit: SimExit::default(),
            rejected_before: 0,
            tracker_refused_shown: 0,
            failed_logged: false,
            quit: false,
        }
    }

    /// Replaces the session with one of the newly built scene; the old one's
    /// recording closes, its refused poses stay counted.
    fn change_scene(&mut self, old: Session, built: Built) -> Session {
        self.rejected_before += old.rejected_poses();
        drop(old);
        self.background.forget_scene();
        self.script.keys.set_spatula_count(built.scenario.spatulas.len());
        self.shared.recording.store(false, Ordering::Relaxed);
        Session::new(built)
    }

    /// Tracker poses the server refused (workspace, speed): says so in the panel when the count grows.
    fn show_tracker_refusals(&mut self) {
        if let Some(server) = &self.igtl {
            let refused = lock(server).stats().poses_refused();
            if refused > self.tracker_refused_shown {
                self.tracker_refused_shown = refused;
                *lock(&self.shared.status) = format!(
                    "OpenIGTLink: {refused} poses refused (outside the workspace or too fast); the last good pose holds"
                );
            }
        }
    }

    /// The run's summary, from the last scene.
    fn finish(mut self, mut session: Session) -> SimExit {
        let exit = &mut self.exit;
        exit.rejected_poses = self.rejected_before + session.rejected_poses();
        exit.peak_force_n = std::mem::take(&mut session.peak_force_n);
        let b = &mut session.scene;
        exit.frames = b.state.frame;
        exit.time_s = b.state.time_s;
        exit.final_poses = b.state.poses.clone();
        exit.state_hash = b.pipeline.state_hash(&b.state).unwrap_or_else(|e| {
            tracing::error!("the final state's hash: {e}");
            String::new()
        });
        if let Some(server) = &self.igtl {
            let stats = lock(server).stats();
            exit.tracker_outside_workspace = stats.poses_outside_workspace;
            exit.tracker_too_fast = stats.poses_too_fast;
        }
        if let Some(c) = b.pipeline.collision() {
            exit.collision_backend = Some(format!("{:?}", c.backend()).to_lowercase());
            exit.collision_notes = c.warnings().to_vec();
        }
        self.exit
    }
}

impl Session {
    /// A session of a scene just built, at rest.
    fn new(scene: Built) -> Self {
        let blades = scene.scenario.spatulas.len();
        Self {
            guards: scene.state.poses.iter().map(|p| PoseGuard::new(*p, "window")).collect(),
            history: History::at_rest(&scene.state.poses, records_cuts(&scene.scenario)),
            recording: None,
            taken_over: vec![false; blades],
            cut_asked: None,
            columns_shown: None,
            peak_force_n: vec![0.0; scene.state.poses.len()],
            next_frame: Instant::now(),
            scene,
        }
    }

    fn rejected_poses(&self) -> u64 {
        self.guards.iter().map(PoseGuard::rejected).sum()
    }

    /// Handles the window's commands until none is left, one changes the
    /// scene, or one ends the loop.
    fn take_commands(&mut self, commands: &Receiver<SimCommand>, run: &mut Run) -> Commands {
        loop {
            let command = match commands.try_recv() {
                Ok(c) => c,
                Err(TryRecvError::Empty) => return Commands::Drained,
                Err(TryRecvError::Disconnected) => return Commands::Stop,
            };
            match command {
                SimCommand::Quit => return Commands::Stop,
                SimCommand::EndSession(path) => {
                    self.end(&path, run);
                    return Commands::Stop;
                }
                SimCommand::StartRecording(path) => self.start_recording(path, run),
                SimCommand::StopRecording => stopped(run.shared, self.recording.take()),
                SimCommand::SetCulling(on) => return Commands::ChangeScene(Box::new(with_culling(&self.scene.scenario, on))),
                SimCommand::SetBackend(backend) => {
                    let mut s = self.scene.scenario.clone();
                    s.collision.backend = backend;
                    return Commands::ChangeScene(Box::new(s));
                }
                SimCommand::LoadScenario(path) => match Scenario::load(&path, &[]) {
                    Ok(s) => return Commands::ChangeScene(Box::new(s)),
                    Err(e) => *lock(&run.shared.status) = format!("cannot load {}: {e}", path.display()),
                },
                SimCommand::ShowStrain(on) => {
                    run.background.wanted = on;
                    run.background.stress.clear();
                }
                SimCommand::Cut(k) => self.cut(k, run.shared),
            }
        }
    }

    /// Records to `path` from this frame on: t = 0 now, the session so far
    /// before it; a recording that cannot start says so in the panel.
    fn start_recording(&mut self, path: PathBuf, run: &mut Run) {
        match open_recording(&path, &self.history, self.scene.state.time_s) {
            Ok(r) => {
                started(run.shared, &path);
                run.exit.recording = Some(path);
                self.recording = Some(r);
            }
            Err(e) => recording_failed(run.shared, format!("cannot record: {e}")),
        }
    }

    /// Asks for a cut at blade `k`'s tip in the next frame (a cut asked for before it stays if this one cannot be).
    fn cut(&mut self, k: usize, shared: &SimShared) {
        self.cut_asked = request_cut(&mut self.scene, k, shared).or(self.cut_asked);
    }

    /// Ends the session for the debrief ([`SimShared::ended`]).
    fn end(&mut self, path: &std::path::Path, run: &mut Run) {
        let ended = end_session(path, self.recording.take(), &self.history, &self.scene, run.shared);
        if let Some(e) = &ended {
            run.exit.recording = Some(e.recording.clone());
        }
        *lock(&run.shared.ended) = Some(ended);
    }

    /// The window's scripted actions due at this frame's time: waits until it has handled them.
    fn wait_for_window_script(&mut self, run: &mut Run) {
        while let Some(&due) = run.script.window_times.peek() {
            if due > self.scene.state.time_s + 1e-12 {
                break;
            }
            let waiting = Instant::now();
            while !lock(&run.shared.window_script_done).is_some_and(|done| done >= due - 1e-12) {
                if waiting.elapsed() > WINDOW_SCRIPT_WAIT {
                    tracing::warn!("the window did not handle its scripted action at t = {due} s within {WINDOW_SCRIPT_WAIT:?}; going on");
                    break;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            run.script.window_times.next();
            self.next_frame = Instant::now();
        }
    }

    /// The frame's input: the scripted actions due, each blade's pose from its
    /// binding, the cuts its trajectory asks for. Returns the time step, s.
    fn take_input(&mut self, run: &mut Run) -> f64 {
        let dt = self.scene.pipeline.time_step();
        let t_next = self.scene.state.time_s + dt;
        self.take_script(t_next, run);
        self.drive_poses(t_next, dt, run);
        self.trajectory_cuts(t_next, run.shared);
        run.show_tracker_refusals();
        dt
    }

    /// Scripted actions due by this frame's time `t_next`.
    fn take_script(&mut self, t_next: f64, run: &mut Run) {
        while let Some((t, _)) = run.script.actions.peek() {
            if *t > t_next + 1e-12 {
                break;
            }
            let Some((_, action)) = run.script.actions.next() else { break };
            run.script.active |= action.is_scripted_key();
            match action {
                ScriptAction::Press(key) => run.script.keys.apply(KeyEvent { key, pressed: true }),
                ScriptAction::Release(key) => run.script.keys.apply(KeyEvent { key, pressed: false }),
                ScriptAction::Record(path) => self.start_recording(path, run),
                ScriptAction::Stop => stopped(run.shared, self.recording.take()),
                ScriptAction::Cut(blade) => {
                    let active =
                        if run.script.active { run.script.keys.command().spatula } else { lock(&run.shared.input).keyboard.spatula };
                    self.cut(blade.unwrap_or(active), run.shared);
                }
                ScriptAction::Quit => run.quit = true,
                _ => {}
            }
        }
    }

    /// Each blade's pose from its binding (keys, gamepad, SpaceMouse, tracker,
    /// trajectory at `t_next`), as a recording holds it, through its guard.
    fn drive_poses(&mut self, t_next: f64, dt: f64, run: &mut Run) {
        let shared = run.shared;
        let live = *lock(&shared.input);
        let keyboard = if run.script.active { run.script.keys.command() } else { live.keyboard };
        let buffers = &mut run.buffers;
        buffers.back.scripted_spatula = run.script.active.then_some(keyboard.spatula);
        let mouse = run.devices.poll(&self.scene.scenario, run.igtl.as_ref(), &shared.status);
        buffers.input.poses.clear();
        buffers.back.drivers.clear();
        for (k, spatula) in self.scene.scenario.spatulas.iter().enumerate() {
            let current = self.scene.state.poses.get(k).copied().unwrap_or(spatula.initial_pose);
            let mut offers = DeviceOffers {
                keys: (keyboard.spatula == k).then_some(keyboard.velocity),
                keys_moving: keyboard.moving,
                ..DeviceOffers::default()
            };
            let binding = match &spatula.input {
                InputBinding::Keyboard => BindingKind::Keyboard,
                InputBinding::Gamepad => {
                    offers.pad = (live.pad.spatula.index() == k).then_some(live.pad.velocity);
                    BindingKind::Gamepad
                }
                InputBinding::SpaceMouse => mouse.offer(k, &mut offers),
                InputBinding::OpenIgtLink { device, .. } => {
                    offers.tracker = run.igtl.as_ref().and_then(|s| lock(s).latest(device)).map(|t| t.pose);
                    BindingKind::Tracker
                }
                InputBinding::Trajectory => {
                    offers.trajectory = self.scene.trajectory.as_ref().and_then(|t| t.sample(k, t_next));
                    BindingKind::Trajectory
                }
            };
            let (candidate, driver) = drive(binding, &current, &offers, &mut self.taken_over[k], dt);
            buffers.back.drivers.push(driver);
            let candidate = as_recorded(candidate);
            let pose = match self.guards.get_mut(k) {
                Some(g) => {
                    let pose = g.offer(candidate);
                    if let Some(warning) = g.take_warning() {
                        *lock(&shared.status) = format!("spatula {}: {warning}", spatula.name);
                    }
                    pose
                }
                None => candidate,
            };
            buffers.input.poses.push(Some(pose));
        }
    }

    /// A blade still on its trajectory cuts where the trajectory's rows say
    /// (the frame's interval up to `t_next`, as a replay).
    fn trajectory_cuts(&mut self, t_next: f64, shared: &SimShared) {
        let b = &self.scene;
        let Some(t) = b.trajectory.as_ref().filter(|t| t.has_cuts()) else { return };
        let after = if b.state.frame == 0 { f64::NEG_INFINITY } else { b.state.time_s };
        let cutting = (0..b.scenario.spatulas.len().min(64))
            .filter(|&k| matches!(b.scenario.spatulas[k].input, InputBinding::Trajectory) && !self.taken_over[k] && t.cuts_between(k, after, t_next))
            .fold(0u64, |mask, k| mask | 1 << k);
        for k in (0..64).filter(|k| cutting & (1 << k) != 0) {
            self.cut(k, shared);
        }
    }

    /// Steps the pipeline with the frame's input, then records and publishes
    /// the frame; a failing frame is counted (logged once) and the last state holds.
    fn advance(&mut self, run: &mut Run) {
        let started = Instant::now();
        match self.scene.pipeline.step(&mut self.scene.state, &run.buffers.input) {
            Ok(report) => {
                let report = report.clone();
                run.exit.step_ms.push(started.elapsed().as_secs_f64() * 1e3);
                self.record(&report, run);
                self.publish(&report, run);
            }
            Err(e) => {
                run.exit.failed_frames += 1;
                if !run.failed_logged {
                    run.failed_logged = true;
                    tracing::warn!(error = %e, "a simulation frame failed; the last state holds (further failures are counted)");
                }
                *lock(&run.shared.status) = format!("frame failed: {e}");
            }
        }
    }

    /// Keeps the frame: the peak forces, the recording's row, the history a later recording starts from.
    fn record(&mut self, report: &crate::sim::FrameReport, run: &mut Run) {
        for (peak, s) in self.peak_force_n.iter_mut().zip(&report.spatulas) {
            *peak = peak.max(s.force.norm());
        }
        // The input as it came (before the scenario's pose filter, which
        // a replay of the recording applies again in the same frames),
        // or the pose the blade kept where the input was refused.
        let raw: Vec<Pose> =
            run.buffers.input.poses.iter().zip(&self.scene.state.poses).map(|(i, s)| i.filter(Pose::is_valid).unwrap_or(*s)).collect();
        // The blade whose cut this frame carried out: its row says so, and a replay cuts in the same frame.
        let cut_now = self.cut_asked;
        if let Some(r) = self.recording.as_mut() {
            let t = self.scene.state.time_s - r.origin_s;
            if let Some(e) = raw.iter().enumerate().find_map(|(k, p)| r.recorder.record_with_cut(t, k, p, cut_now == Some(k)).err()) {
                let path = r.recorder.path().display().to_string();
                recording_failed(run.shared, format!("recording stopped: {e} (the rows before are kept in {path})"));
                self.recording = None;
            }
        }
        self.history.push(self.scene.state.time_s, raw, cut_now);
    }

    /// Publishes the frame: the haptic model, the snapshot for the renderer
    /// (with the background solve's strain and far surface), the status line.
    fn publish(&mut self, report: &crate::sim::FrameReport, run: &mut Run) {
        let b = &self.scene;
        if let Some(h) = &run.haptics {
            let model = HapticModel::of_frame(&b.pipeline, &b.state.poses, report, &mut run.buffers.haptic_scratch);
            h.publish(Arc::new(model));
        }
        if let Some(k) = self.cut_asked.take() {
            say_what_was_cut(b, k, report, run.shared);
        }
        let back = &mut run.buffers.back;
        back.capture(&b.pipeline, &b.state, report, &b.areas);
        if run.background.update(&b.pipeline, &b.state, run.shared) {
            back.set_strain(b.pipeline.surface(), &run.background.stress);
            run.exit.background_strain_frames += 1;
        }
        back.set_far_surface(&b.pipeline, &run.background.nodes);
        run.shared.frames.publish(back);
        match b.pipeline.solver().compliance().fill_progress() {
            Some((done, total)) if self.columns_shown != Some(done) => {
                self.columns_shown = Some(done);
                *lock(&run.shared.status) = format!(
                    "compliance {done} / {total} columns, the rest in the background (a blade on tissue not yet computed waits for it)"
                );
            }
            None if self.columns_shown.take().is_some() => *lock(&run.shared.status) = "compliance complete".into(),
            _ => {}
        }
    }

    /// Waits until the next frame is due, `dt` after this one; slower than
    /// real time, it does not try to catch up in a burst.
    fn keep_real_time(&mut self, dt: f64) {
        self.next_frame += Duration::from_secs_f64(dt);
        let now = Instant::now();
        if self.next_frame > now {
            std::thread::sleep(self.next_frame - now);
        } else if now - self.next_frame > Duration::from_secs_f64(dt * 5.0) {
            self.next_frame = now;
        }
    }
}

/// The scenario with His-flag culling on or off.
fn with_culling(scenario: &Scenario, on: bool) -> Scenario {
    let mut s = scenario.clone();
    let mut e = EffectSet::default();
    for x in s.effects.iter().filter(|x| *x != Effect::Culling) {
        e.insert(x);
    }
    if on {
        e.insert(Effect::Culling);
    }
    s.effects = e;
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn at_x(x_m: f64) -> Pose {
        Pose { position: Vec3::new(x_m, 0.0, 0.0), ..Pose::default() }
    }

    /// A recording starts its clock at the press, not when the window
    /// opened: t = 0 is the press; the poses before it stay (the run-up,
    /// from rest, at negative times), and each later row is at session time
    /// minus the press's, so a replay that starts its clock at the first row
    /// samples the rows at exactly the window's frame times.
    #[test]
    fn a_recording_starts_at_the_press_and_keeps_the_lead_in() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("rec.csv");
        let dt = 0.01;
        let mut history = History::at_rest(&[at_x(0.0)], false);
        for frame in 1..=30u32 {
            history.push(f64::from(frame) * dt, vec![at_x(f64::from(frame) * 1e-3)], None);
        }
        let origin = 30.0 * dt;
        let mut rec = open_recording(&path, &history, origin).expect("recording starts");
        for frame in 31..=40u32 {
            let t = f64::from(frame) * dt;
            rec.recorder.record(t - rec.origin_s, 0, &at_x(f64::from(frame) * 1e-3)).expect("row");
        }
        drop(rec);
        let text = std::fs::read_to_string(&path).expect("file");
        assert!(text.starts_with("# recording: t = 0 is the moment it was started (0.3"), "{text}");
        let t = Trajectory::load(&path).expect("a valid trajectory");
        assert_eq!(t.samples(0).len(), 41, "rest + 30 lead-in frames + 10 recorded");
        assert_eq!(t.start_time(), -origin, "the run-up starts at rest, at -press");
        let at_press = t.sample(0, 0.0).expect("pose");
        assert!((at_press.position.x - 0.030).abs() < 1e-12, "t = 0 holds the pose at the press: {:?}", at_press.position);
        // A replay's frame k samples (k * dt) + start_time: frame 35's pose.
        let replay_t = 35.0 * dt + t.start_time();
        assert_eq!(t.sample(0, replay_t).map(|p| p.position.x), Some(0.035), "replay time 0.35 s is the window's frame 35, bit for bit");
        // A folder that does not exist: an error, no panic, nothing created.
        let bad = dir.path().join("missing").join("rec.csv");
        let e = open_recording(&bad, &history, origin).err().expect("cannot create");
        assert!(e.contains("missing"), "the error names the file: {e}");
    }
}
