//! The simulator window: winit event loop, wgpu scene + egui panel, devices.
//!
//! In: a scenario and [`WindowOptions`]. Out: an interactive session; at the
//! end a [`WindowSummary`] (frames drawn, frame rate, the simulation's exit).
//! Stays true: the window draws the newest frame the simulation thread
//! published and never waits for the simulation (nor the reverse); no display
//! or no GPU adapter comes back as [`WindowError::NoDisplay`] /
//! [`WindowError::NoAdapter`] (the CLI then runs headless), never a panic;
//! closing the window while recording leaves a complete CSV (every row is
//! flushed as written).
//!
//! Keys: [`crate::input::bindings`] (one table with the README's Controls):
//! the blade map, `M` microscope view, `O` overview, `F` cycles the surface
//! colour (infarct risk too where the scene has `Ischemia`), `R` starts /
//! stops recording, `Esc` gives the keys back to the scene, `Ctrl+Q` quits.
//! The keys drive the scene unless the panel's text field has the focus
//! (clicked into); any other panel interaction hands the focus straight back,
//! and the panel's first line says where keys go.

use super::draw::{DrawOptions, SceneBuffers, SceneStatic, Snapshot, SurfaceField, ViewPreset};
use super::sim_thread::BuildProgress;
use super::haptics::{ForceOutput, HAPTIC_RATE_HZ};
use super::script::ScriptAction;
use super::sim_thread::{SimCommand, SimExit, SimOptions, SimShared, SimThread};
use crate::input::gamepad::{GamepadInput, GamepadMapping, PadCommand};
use crate::input::rumble::{RumbleSettings, RumbleStatus};
use crate::input::bindings::{KeyAction, KeyRoute, route};
use crate::input::keyboard::{KeyEvent, KeyboardController, KeyboardMapping, map_mouse};
use crate::render::window::{FrameOutcome, WindowRenderer};
use crate::render::{FieldKind, OrbitCamera};
use crate::scenario::{CollisionBackend, InputBinding, Scenario};
use crate::sim::StageId;
use crate::ui::debrief::DebriefPanel;
use crate::ui::{FieldChoice, PanelAction, PanelData, PanelState, SpatulaReadout, TimingHistory, draw_panel, update_monitors};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::PhysicalKey;
use winit::window::{Window, WindowId};

/// Why the window could not run.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    #[error("no display ({0})")]
    NoDisplay(String),
    #[error("no usable GPU adapter for the window ({0})")]
    NoAdapter(String),
    #[error("cannot start the simulation: {0}")]
    Simulation(String),
    #[error("the event loop failed: {0}")]
    EventLoop(String),
}

/// Options of a window session.
#[derive(Debug, Clone)]
pub struct WindowOptions {
    /// Present mode (explicit: Xvfb's default, Immediate, misbehaves).
    pub present_mode: wgpu::PresentMode,
    /// Inner size, pixels.
    pub size: (u32, u32),
    /// Stop after this many simulation frames.
    pub max_frames: Option<u64>,
    /// Close after this many wall-clock seconds.
    pub exit_after_s: Option<f64>,
    /// Timed actions (simulation and window ones).
    pub script: Vec<(f64, ScriptAction)>,
    /// Folder for recordings started with R or the panel (see [`record_dir_for`]).
    pub record_dir: PathBuf,
    /// Start the 1 kHz force output.
    pub haptics: bool,
    /// Gamepad force feedback on at start (key H toggles it).
    pub rumble: bool,
}

impl Default for WindowOptions {
    fn default() -> Self {
        Self {
            present_mode: wgpu::PresentMode::Fifo,
            size: (1280, 800),
            max_frames: None,
            exit_after_s: None,
            script: Vec::new(),
            record_dir: record_dir_for(None, None),
            haptics: true,
            rumble: true,
        }
    }
}

/// The user's recordings folder: `<data dir>/fissure/recordings`
/// (`$XDG_DATA_HOME` or `~/.local/share` on Linux, `~/Library/Application
/// Support` on macOS, `%APPDATA%` on Windows); `None` when the system has no
/// data directory (no home).
pub fn user_record_dir() -> Option<PathBuf> {
    dirs::data_dir().map(|d| d.join("fissure").join("recordings"))
}

/// Where recordings go: `--record-dir`, else the scenario's
/// `outputs.record_dir`, else [`user_record_dir`], else `./recordings` (with
/// a warning in the log saying why).
pub fn record_dir_for(cli: Option<&std::path::Path>, scenario: Option<&std::path::Path>) -> PathBuf {
    if let Some(dir) = cli.or(scenario) {
        return dir.to_path_buf();
    }
    user_record_dir().unwrap_or_else(|| {
        tracing::warn!("no user data directory (no HOME or XDG_DATA_HOME): recordings go to ./recordings");
        PathBuf::from("recordings")
    })
}

/// What a session did.
#[derive(Debug, Clone, Default)]
pub struct WindowSummary {
    /// Frames presented.
    pub presented: u64,
    /// Wall time from the first presented frame to the end, s.
    pub wall_s: f64,
    /// Haptic ticks and the wall time they took, s.
    pub haptic_ticks: u64,
    pub haptic_s: f64,
    /// The simulation thread's exit.
    pub sim: SimExit,
    /// Adapter name.
    pub adapter: String,
    /// The debrief page written when the session ended (Ctrl+Q, closing, End session).
    pub debrief: Option<PathBuf>,
    /// A session debrief left unfinished when the window closed: its recording (the debrief can be made from it).
    pub debrief_unfinished: Option<PathBuf>,
}

impl WindowSummary {
    /// Presented frames per second.
    pub fn fps(&self) -> f64 {
        if self.wall_s > 0.0 { self.presented as f64 / self.wall_s } else { 0.0 }
    }
}

struct Gpu {
    window: Arc<Window>,
    renderer: WindowRenderer,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
}

struct App {
    scenario_path: PathBuf,
    options: WindowOptions,
    sim: Option<SimThread>,
    haptics: Option<Arc<ForceOutput>>,
    spatula_names: Vec<String>,
    gpu: Option<Gpu>,
    error: Option<WindowError>,
    egui: egui::Context,
    front: Snapshot,
    scene: Arc<SceneStatic>,
    /// The scene's generation and the frame last shown.
    seen: Seen,
    view: ViewState,
    keyboard: KeyboardController,
    pad: Pad,
    pointer: Pointer,
    ui: PanelUi,
    window_script: std::iter::Peekable<std::vec::IntoIter<(f64, ScriptAction)>>,
    clock: PresentClock,
    adapter: String,
    session: SessionEnd,
}

/// What the window last took from the simulation.
#[derive(Default)]
struct Seen {
    /// The scene's generation (a new one after a scene is loaded).
    generation: u64,
    /// The newest frame taken.
    frame: u64,
}

/// How the scene is drawn and from where.
struct ViewState {
    buffers: SceneBuffers,
    draw: DrawOptions,
    /// What the simulation was last told about the strain colour.
    strain_told: bool,
    camera: OrbitCamera,
    camera_set: bool,
}

/// The gamepad: its input, force feedback (the settings H toggles, and what it did last), and its blade sides.
struct Pad {
    input: GamepadInput,
    rumble: RumbleSettings,
    status: RumbleStatus,
    /// The pad's last LB / RB choice, and whether it maps to the other blade (the
    /// first blade stood on the right of the screen at that press).
    slot: Option<crate::input::SpatulaSlot>,
    swap: bool,
}

/// The mouse and the modifier keys.
#[derive(Default)]
struct Pointer {
    cursor: Option<(f64, f64)>,
    left_down: bool,
    /// Ctrl held (for Ctrl+Q).
    ctrl: bool,
}

/// The panel and the status bar's own state.
struct PanelUi {
    panel: PanelState,
    history: TimingHistory,
    backend: CollisionBackend,
    load_path: String,
    /// The panel's text field (the one widget that may keep the keys).
    load_field: Option<egui::Id>,
    /// Where the keys went last frame (true: the scene).
    keys_to_scene: bool,
}

/// Frames presented and the frame rate.
struct PresentClock {
    started: Instant,
    first_present: Option<Instant>,
    presented: u64,
    fps_window: (Instant, u64, f64),
}

/// The end of the session, once asked for (Ctrl+Q, closing, the End session button, a script's `end`), and the
/// debrief page once written.
#[derive(Default)]
struct SessionEnd {
    ending: Option<Ending>,
    debrief_page: Option<PathBuf>,
}

/// What one frame of the panel gave: egui's output to draw, the actions asked for, the backend chosen, whether a
/// scenario is to be loaded.
struct PanelFrame {
    full: egui::FullOutput,
    actions: Vec<PanelAction>,
    backend: CollisionBackend,
    load: bool,
}

/// Where the end of a session is: the simulation writing the session's recording, the debrief being made, done.
enum Ending {
    WaitingForSim,
    Debriefing(super::session_debrief::SessionDebriefWorker),
    Done,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// What is missing for a window, in the user's words, when it can be told
/// before the windowing system is asked: on Linux and the BSDs, neither
/// `DISPLAY` (X11) nor `WAYLAND_DISPLAY` is set.
fn missing_display() -> Option<String> {
    let unix_desktop = cfg!(all(unix, not(target_os = "macos"), not(target_os = "ios"), not(target_os = "android")));
    let unset = |name: &str| std::env::var_os(name).is_none_or(|v| v.is_empty());
    (unix_desktop && unset("DISPLAY") && unset("WAYLAND_DISPLAY")).then(|| "DISPLAY and WAYLAND_DISPLAY are unset".to_string())
}

/// The windowing system's error without the source location it prefixes
/// (`os error at <crate>/src/....rs:765: `): what failed, not where in a dependency.
fn display_error(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let Some(start) = text.find("os error at ") else { return text };
    let rest = &text[start + "os error at ".len()..];
    // The location ends at ".rs:<line>: ".
    let cut = rest.find(".rs:").and_then(|i| rest[i + 4..].find(": ").map(|j| i + 4 + j + 2));
    match cut {
        Some(end) => format!("{}{}", &text[..start], &rest[end..]),
        None => text,
    }
}

/// The 1 kHz force output: it reads the OpenIGTLink poses of the blades bound to a device, and sends each
/// blade's force back to the server's clients.
fn start_haptics(scenario: &Scenario, igtl: Option<Arc<Mutex<crate::input::igtl::IgtlServer>>>, names: &[String]) -> Arc<ForceOutput> {
    let devices: Vec<Option<String>> = scenario
        .spatulas
        .iter()
        .map(|s| match &s.input {
            InputBinding::OpenIgtLink { device, .. } => Some(device.clone()),
            _ => None,
        })
        .collect();
    let probe_server = igtl.clone();
    let probe = Box::new(move |k: usize, _since: f64| {
        let device = devices.get(k)?.as_ref()?;
        probe_server.as_ref().and_then(|s| lock(s).latest(device)).map(|t| t.pose)
    });
    let sink = igtl.map(|server| {
        let names = names.to_vec();
        Box::new(move |k: usize, _t: f64, f: crate::math::Vec3| {
            let unix = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs_f64())
                .unwrap_or(0.0);
            if let Some(name) = names.get(k) {
                lock(&server).send_force(name, unix, [f.x, f.y, f.z]);
            }
        }) as super::haptics::ForceSink
    });
    Arc::new(ForceOutput::start(scenario.spatulas.len(), HAPTIC_RATE_HZ, probe, sink))
}

/// Runs the window on `scenario` until closed; see the module docs.
pub fn run_window(scenario: Scenario, options: WindowOptions) -> Result<WindowSummary, WindowError> {
    let rumble_on = options.rumble;
    if let Some(missing) = missing_display() {
        return Err(WindowError::NoDisplay(missing));
    }
    let event_loop = EventLoop::new().map_err(|e| WindowError::NoDisplay(display_error(&e)))?;
    event_loop.set_control_flow(ControlFlow::Poll);

    // OpenIGTLink when any spatula is bound to it: server, links, force back.
    let igtl = super::devices::start_igtl(&scenario);
    let names: Vec<String> = scenario.spatulas.iter().map(|s| s.name.clone()).collect();
    let haptics = options.haptics.then(|| start_haptics(&scenario, igtl.clone(), &names));
    let (sim_script, window_script): (Vec<_>, Vec<_>) = options.script.iter().cloned().partition(|(_, a)| a.is_simulation());
    let backend = scenario.collision.backend;
    let pressure_max_mmhg = scenario.display.pressure_max_mmhg;
    let views = scenario.display.views;
    let scenario_path = scenario.source_path.clone();
    let sim = SimThread::start(
        scenario,
        igtl,
        haptics.clone(),
        SimOptions {
            max_frames: options.max_frames,
            script: sim_script,
            free_running: false,
            window_script_times: window_script.iter().map(|(t, _)| *t).collect(),
        },
    )
    .map_err(WindowError::Simulation)?;
    let scene = lock(&sim.shared.scene).clone();
    let names_len = names.len();
    let record_dir_display = options.record_dir.display().to_string();
    let stage_names: Vec<&str> = StageId::ALL.iter().map(|s| s.name()).collect();
    let mut app = App {
        scenario_path: scenario_path.clone(),
        options,
        sim: Some(sim),
        haptics,
        spatula_names: names,
        gpu: None,
        error: None,
        egui: egui::Context::default(),
        front: Snapshot::default(),
        scene,
        seen: Seen::default(),
        view: ViewState {
            buffers: SceneBuffers::default(),
            draw: DrawOptions { views, ..DrawOptions::default() },
            strain_told: false,
            camera: OrbitCamera::default(),
            camera_set: false,
        },
        keyboard: {
            let mut k = KeyboardController::new(KeyboardMapping::default());
            k.set_spatula_count(names_len);
            k
        },
        pad: Pad {
            input: GamepadInput::new(GamepadMapping::default()),
            rumble: RumbleSettings { enabled: rumble_on, ..RumbleSettings::default() },
            status: RumbleStatus::NoPad,
            slot: None,
            swap: false,
        },
        pointer: Pointer::default(),
        ui: PanelUi {
            panel: PanelState { record_dir: record_dir_display, pressure_max_mmhg, ..PanelState::default() },
            history: TimingHistory::new(&stage_names, 240),
            backend,
            load_path: scenario_path.display().to_string(),
            load_field: None,
            keys_to_scene: true,
        },
        window_script: window_script.into_iter().peekable(),
        clock: PresentClock { started: Instant::now(), first_present: None, presented: 0, fps_window: (Instant::now(), 0, 0.0) },
        adapter: String::new(),
        session: SessionEnd::default(),
    };
    app.view.camera = OrbitCamera::framing(app.scene.bounds.0, app.scene.bounds.1);
    app.seen.generation = app.sim.as_ref().map(|s| s.shared.generation.load(std::sync::atomic::Ordering::Relaxed)).unwrap_or(0);
    let result = event_loop.run_app(&mut app);
    app.finish(result)
}

impl App {
    /// Stops the simulation (and an unfinished debrief) and sums the session up.
    fn finish(mut self, result: Result<(), winit::error::EventLoopError>) -> Result<WindowSummary, WindowError> {
        let wall_s = self.clock.first_present.map(|t| t.elapsed().as_secs_f64()).unwrap_or(0.0);
        let sim_exit = self.sim.take().map(SimThread::stop).unwrap_or_default();
        let debrief_unfinished = match self.session.ending.take() {
            Some(Ending::Debriefing(worker)) => {
                worker.stop();
                Some(worker.recording.clone())
            }
            _ => None,
        };
        let (haptic_ticks, haptic_s) = self.haptics.as_ref().map(|h| (h.ticks(), h.elapsed_s())).unwrap_or((0, 0.0));
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        result.map_err(|e| WindowError::EventLoop(e.to_string()))?;
        Ok(WindowSummary {
            presented: self.clock.presented,
            wall_s,
            haptic_ticks,
            haptic_s,
            sim: sim_exit,
            adapter: self.adapter,
            debrief: self.session.debrief_page,
            debrief_unfinished,
        })
    }

    fn preset(&mut self, preset: ViewPreset) {
        // camera_for needs the pipeline only for the mesh box and blade shapes, both in SceneStatic.
        self.view.camera = camera_for_static(preset, &self.scene, &self.front.poses, &self.view.draw.views);
    }

    /// Tells the simulation whether the strain colour is shown (it then
    /// computes stress in the background when the scene has no StressField stage).
    fn tell_strain(&mut self) {
        let on = self.view.draw.field == SurfaceField::Strain;
        if on != self.view.strain_told {
            self.view.strain_told = on;
            self.send(SimCommand::ShowStrain(on));
        }
    }

    /// Shows `field` (infarct risk only where the scene has it: else none).
    fn set_field(&mut self, field: SurfaceField) {
        let field = if field == SurfaceField::Risk && self.scene.ischemia.is_none() { SurfaceField::None } else { field };
        self.view.draw.field = field;
        self.ui.panel.field = match field {
            SurfaceField::None => FieldChoice::None,
            SurfaceField::Displacement => FieldChoice::Field(FieldKind::DisplacementMm),
            SurfaceField::Pressure => FieldChoice::Field(FieldKind::ContactPressureMmHg),
            SurfaceField::Strain => FieldChoice::Field(FieldKind::Strain),
            SurfaceField::Risk => FieldChoice::Field(FieldKind::InfarctRisk),
        };
    }

    fn send(&self, c: SimCommand) {
        if let Some(s) = &self.sim {
            s.send(c);
        }
    }

    /// A new session file in the recordings folder (`session_<unix time>.csv`), the folder created; the error says
    /// which folder could not be.
    fn new_session_file(&self) -> Result<PathBuf, String> {
        let dir = &self.options.record_dir;
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create the folder {}: {e} (set another with --record-dir)", dir.display()))?;
        let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
        Ok(dir.join(format!("session_{secs}.csv")))
    }

    fn toggle_recording(&mut self, on: bool) {
        if on {
            let path = match self.new_session_file() {
                Ok(p) => p,
                Err(e) => {
                    let message = format!("cannot record: {e}");
                    tracing::error!("{message}");
                    self.ui.panel.record_error = Some(message);
                    self.ui.panel.recording = false;
                    return;
                }
            };
            self.ui.panel.record_error = None;
            self.send(SimCommand::StartRecording(path));
        } else {
            self.send(SimCommand::StopRecording);
        }
        self.ui.panel.recording = on;
    }

    /// Ends the session (Ctrl+Q, closing the window, the End session button, a script's `end`): the first time, the
    /// simulation writes the session from the scene at rest as a recording and stops, and its debrief is made on
    /// another thread while the window shows its progress and then its verdicts; again (or before the scene was
    /// built, when nothing was simulated), the window closes.
    fn end_session(&mut self, event_loop: &ActiveEventLoop) {
        let running = self.sim.as_ref().is_some_and(|s| s.shared.running.load(std::sync::atomic::Ordering::Acquire) && !s.finished());
        if self.session.ending.is_some() || !running {
            event_loop.exit();
            return;
        }
        let path = match self.new_session_file() {
            Ok(p) => p,
            Err(e) => {
                // Nowhere to write the session: say so and close as before.
                tracing::error!("cannot write the session for its debrief: {e}");
                event_loop.exit();
                return;
            }
        };
        self.send(SimCommand::EndSession(path));
        self.keyboard.release_all();
        self.ui.panel.recording = false;
        self.ui.panel.debrief = Some(DebriefPanel::Working { what: "ending the session".into(), fraction: 0.0 });
        self.session.ending = Some(Ending::WaitingForSim);
    }

    /// Moves the session's end along: starts the debrief once the simulation has written the session, shows its
    /// progress, then its verdicts and where the page is.
    fn advance_ending(&mut self) {
        let Some(ending) = self.session.ending.as_mut() else { return };
        match ending {
            Ending::WaitingForSim => {
                let Some(sim) = self.sim.as_ref().filter(|s| s.finished()) else { return };
                let ended = lock(&sim.shared.ended).take();
                let status = lock(&sim.shared.status).clone();
                match ended {
                    Some(Some(session)) => match super::session_debrief::SessionDebriefWorker::start(session.scenario, session.recording) {
                        Ok(worker) => *ending = Ending::Debriefing(worker),
                        Err(e) => {
                            self.ui.panel.debrief = Some(DebriefPanel::Failed(e));
                            *ending = Ending::Done;
                        }
                    },
                    Some(None) => {
                        self.ui.panel.debrief = Some(DebriefPanel::Failed(status));
                        *ending = Ending::Done;
                    }
                    None => {
                        self.ui.panel.debrief = Some(DebriefPanel::Failed("the simulation stopped before the session was written".into()));
                        *ending = Ending::Done;
                    }
                }
            }
            Ending::Debriefing(worker) => match worker.poll() {
                None => {
                    let p = worker.progress();
                    self.ui.panel.debrief = Some(DebriefPanel::Working { what: p.step.words().into(), fraction: p.fraction });
                }
                Some(result) => {
                    let status = match result {
                        Ok(d) => {
                            let page = d.files.page.clone();
                            tracing::info!("debrief written to {}", page.display());
                            self.ui.panel.debrief = Some(DebriefPanel::Ready(super::session_debrief::panel_summary(&d)));
                            self.session.debrief_page = Some(page.clone());
                            format!("debrief written to {}", page.display())
                        }
                        Err(e) => {
                            tracing::error!("the session's debrief failed: {e}");
                            self.ui.panel.debrief = Some(DebriefPanel::Failed(format!("the debrief failed: {e}")));
                            format!("the debrief failed: {e}")
                        }
                    };
                    if let Some(sim) = &self.sim {
                        *lock(&sim.shared.status) = status;
                    }
                    *ending = Ending::Done;
                }
            },
            Ending::Done => {}
        }
    }

    /// The session is ending and its debrief not yet made (the window waits for it before a timed exit).
    fn debriefing(&self) -> bool {
        matches!(self.session.ending, Some(Ending::WaitingForSim | Ending::Debriefing(_)))
    }

    /// Moves the first build's error, if any, into `self.error` (the window then
    /// closes with it: the same error, naming the file, and exit code as before
    /// the window existed). True when there was one.
    fn take_build_error(&mut self) -> bool {
        let Some(e) = self.sim.as_ref().and_then(|s| lock(&s.shared.build_error).take()) else { return false };
        self.error = Some(WindowError::Simulation(e));
        true
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let Some(sim) = &self.sim else { return };
        let shared = sim.shared.clone();
        if self.take_build_error() {
            event_loop.exit();
            return;
        }
        self.take_scene_change(&shared);
        self.take_frame(&shared);
        let scripted_through = self.run_window_script(event_loop);
        let pad = self.drive_devices(&shared);
        if self.gpu.is_none() {
            if let Some(t) = scripted_through {
                *lock(&shared.window_script_done) = Some(t);
            }
            return;
        }
        let previous_culling = self.ui.panel.culling;
        let Some(mut frame) = self.run_panel(&shared, &pad) else { return };
        self.apply_panel(event_loop, &mut frame, previous_culling);
        if let Some(t) = scripted_through {
            // This frame's scripted actions are in the keys (and the panel's
            // focus): the simulation, held at `t`, may go on.
            lock(&shared.input).keyboard = self.keyboard.command();
            *lock(&shared.window_script_done) = Some(t);
        }
        self.present(event_loop, frame.full);
    }

    /// New static data after a rebuild: the scene, its cameras and colour bar; the pad's sides are decided again.
    fn take_scene_change(&mut self, shared: &SimShared) {
        let generation = shared.generation.load(std::sync::atomic::Ordering::Relaxed);
        if generation != self.seen.generation {
            self.seen.generation = generation;
            self.scene = lock(&shared.scene).clone();
            self.view.camera_set = false;
            // Other blades: the next LB / RB decides their sides again.
            self.pad.slot = None;
            self.pad.swap = false;
            // Another scene was loaded: its colour-bar top and its cameras.
            if let Some(display) = self.scene.display {
                self.view.draw.views = display.views;
                self.ui.panel.pressure_max_mmhg = display.pressure_max_mmhg;
            }
            // A scene without infarct risk shows none of it.
            if self.view.draw.field == SurfaceField::Risk {
                self.set_field(SurfaceField::Risk);
            }
        }
    }

    /// The newest frame: the timing graph and the pressure monitors, and the first camera once there are poses.
    fn take_frame(&mut self, shared: &SimShared) {
        if shared.frames.take_latest(&mut self.front) && self.front.frame != self.seen.frame {
            let ms: Vec<f64> = StageId::ALL.iter().map(|s| self.front.report.times.get(*s).unwrap_or(0.0) * 1e3).collect();
            self.ui.history.push(&ms);
            let dt = if self.front.frame > self.seen.frame && self.seen.frame > 0 {
                (self.front.frame - self.seen.frame) as f64 * self.front.time_s / self.front.frame.max(1) as f64
            } else {
                0.0
            };
            self.seen.frame = self.front.frame;
            let data = self.panel_data();
            update_monitors(&mut self.ui.panel, &data, dt);
        }
        if !self.view.camera_set && !self.front.poses.is_empty() {
            self.view.camera = match self.view.draw.views.overview {
                Some(v) => OrbitCamera::looking(v.eye, v.target, v.fov_y_rad),
                None => OrbitCamera::framing(self.scene.bounds.0, self.scene.bounds.1),
            };
            self.view.camera_set = true;
        }
    }

    /// Carries out the window's script actions due by the newest frame's simulated time; the time they ran
    /// through, if any ran.
    fn run_window_script(&mut self, event_loop: &ActiveEventLoop) -> Option<f64> {
        let mut scripted_through = None;
        while let Some((t, _)) = self.window_script.peek() {
            if *t > self.front.time_s + 1e-12 {
                break;
            }
            scripted_through = Some(self.front.time_s);
            let Some((_, action)) = self.window_script.next() else { break };
            match action {
                ScriptAction::Field(f) => self.set_field(f),
                ScriptAction::View(v) => self.preset(v),
                ScriptAction::WindowKey(binding, down) => {
                    let panel_has_keys = self.egui.text_edit_focused();
                    // A key the panel would get is typed into its field: nothing for the scene.
                    let _ = self.on_key(event_loop, route(binding.code, binding.ctrl, down, panel_has_keys), down, false);
                }
                ScriptAction::FocusPanel => {
                    if let Some(id) = self.ui.load_field {
                        self.egui.memory_mut(|m| m.request_focus(id));
                    }
                }
                ScriptAction::End => self.end_session(event_loop),
                _ => {}
            }
        }
        scripted_through
    }

    /// Polls the gamepad (its blade sides, the camera it orbits) and hands the keys and the pad to the simulation.
    fn drive_devices(&mut self, shared: &SimShared) -> PadCommand {
        let mut pad = self.pad.input.poll();
        // LB / RB name blades by their side on the screen, decided at the press.
        if self.pad.slot != Some(pad.spatula) && self.front.poses.len() >= 2 {
            self.pad.slot = Some(pad.spatula);
            let centre = |k: usize| {
                let p = &self.front.poses[k];
                let half = self.scene.shapes.get(k).map_or(0.0, |s| 0.5 * s.length);
                p.position + p.rotation * crate::math::Vec3::new(half, 0.0, 0.0)
            };
            self.pad.swap = crate::input::gamepad::screen_order_swaps(centre(0), centre(1), self.view.camera.right_up().0);
        }
        if self.pad.swap {
            pad.spatula = pad.spatula.other();
        }
        if pad.camera_orbit_rad_s != [0.0, 0.0] {
            let dt = 1.0 / self.clock.fps_window.2.max(30.0);
            self.view.camera.orbit(pad.camera_orbit_rad_s[0] * dt, pad.camera_orbit_rad_s[1] * dt);
        }
        {
            let mut input = lock(&shared.input);
            input.keyboard = self.keyboard.command();
            input.pad = pad;
        }
        pad
    }

    /// Runs the panel, the status bar and the legends through egui; `None` without a window.
    fn run_panel(&mut self, shared: &SimShared, pad: &PadCommand) -> Option<PanelFrame> {
        let gpu = self.gpu.as_mut()?;
        let raw = gpu.egui_state.take_egui_input(&gpu.window);
        let mut data = panel_data_of(&self.front, self.clock.fps_window.2);
        data.active_spatula = self.front.scripted_spatula.unwrap_or(self.keyboard.spatula);
        data.keys_to_scene = self.ui.keys_to_scene;
        data.has_skull = !self.scene.skull.is_empty();
        data.tethers = self.scene.tethers.as_ref().map(|info| super::tethers::panel(info, &self.front.tethers, self.front.report.tethers.as_ref()));
        data.tissue = super::tissue_time::panel(&self.scene, &self.front);
        let mut actions = Vec::new();
        let mut backend = self.ui.backend;
        let mut load = false;
        let status = lock(&shared.status).clone();
        if let Some(e) = lock(&shared.record_error).take() {
            // The sim could not start or had to stop the recording (its rows so far are kept).
            self.ui.panel.record_error = Some(e);
            self.ui.panel.recording = false;
        }
        let haptic: Vec<(f64, f64)> = (0..self.spatula_names.len())
            .map(|k| self.haptics.as_ref().and_then(|h| h.latest(k)).map(|(f, t)| (f.norm(), t)).unwrap_or((0.0, 0.0)))
            .collect();
        let haptic_rate = self.haptics.as_ref().map(|h| h.ticks() as f64 / h.elapsed_s().max(1e-9)).unwrap_or(0.0);
        // The pad feels the blade it drives: the 1 kHz output's force, else the frame's.
        let driven = pad.spatula.index();
        let pad_force = match &self.haptics {
            Some(_) => haptic.get(driven).map_or(0.0, |h| h.0),
            None => data.spatulas.get(driven).map_or(0.0, |s| crate::math::Vec3::from(s.force_n).norm()),
        };
        self.pad.status = self.pad.input.rumble(pad_force, &self.pad.rumble);
        let rumble_line = self.pad.status.describe();
        let names = &self.spatula_names;
        let load_path = &mut self.ui.load_path;
        let panel = &mut self.ui.panel;
        let history = &self.ui.history;
        let time_s = self.front.time_s;
        let legend = super::draw::legend_for(&self.view.draw, &self.front);
        let mut load_field = self.ui.load_field;
        let building = *lock(&shared.progress);
        let loading = (self.front.surface_positions.is_empty() || building.is_some()).then(|| self.scenario_path.display().to_string());
        let vessel_legend = self.scene.vessel_legend.as_ref().filter(|_| loading.is_none());
        let full = self.egui.run_ui(raw, |ui| {
            if let Some(scene_name) = &loading {
                loading_screen(ui, scene_name, building, &status);
            }
            draw_panel(ui, &data, names, history, panel, &mut actions);
            egui::Panel::bottom("fissure_status").show(ui, |ui| {
                // Wraps onto a second line rather than cutting the end off (1280 px).
                ui.horizontal_wrapped(|ui| {
                    ui.label(format!("t = {}", crate::ui::tissue_time::clock(time_s)));
                    for (name, (f, _)) in names.iter().zip(&haptic) {
                        ui.label(format!("{name}: haptic |F| {f:.3} N"));
                    }
                    ui.label(format!("force loop {haptic_rate:.0} Hz"));
                    ui.label(&rumble_line);
                    egui::ComboBox::from_label("backend")
                        .selected_text(format!("{backend:?}"))
                        .show_ui(ui, |ui| {
                            for b in [CollisionBackend::Reference, CollisionBackend::Bvh, CollisionBackend::Gpu, CollisionBackend::Auto] {
                                ui.selectable_value(&mut backend, b, format!("{b:?}"));
                            }
                        });
                    load_field = Some(ui.text_edit_singleline(load_path).id);
                    if ui.button("Load").clicked() {
                        load = true;
                    }
                    if !status.is_empty() {
                        ui.label(&status);
                    }
                });
            });
            if let Some(legend) = &legend {
                let scene = ui.available_rect_before_wrap();
                let painter = ui.ctx().layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("fissure_legend")));
                crate::ui::legend::paint_legend(&painter, scene, legend);
            }
            if let Some(vessels) = vessel_legend {
                let painter = ui.ctx().layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("fissure_vessel_legend")));
                crate::ui::legend::paint_vessel_legend(&painter, ui.available_rect_before_wrap(), vessels);
            }
        });
        self.ui.load_field = load_field;
        // Only the text field may keep the keys: a clicked button, slider or
        // checkbox hands them straight back to the scene.
        if !self.egui.text_edit_focused() {
            self.egui.memory_mut(|m| m.stop_text_input());
        }
        let keys_to_scene = !self.egui.text_edit_focused();
        if !keys_to_scene && self.ui.keys_to_scene {
            self.keyboard.release_all(); // a key held while the focus moved must not drive on
        }
        self.ui.keys_to_scene = keys_to_scene;
        gpu.egui_state.handle_platform_output(&gpu.window, full.platform_output.clone());
        Some(PanelFrame { full, actions, backend, load })
    }

    /// Carries out what the panel asked for and shows what it set.
    fn apply_panel(&mut self, event_loop: &ActiveEventLoop, frame: &mut PanelFrame, previous_culling: bool) {
        let (backend, mut load) = (frame.backend, frame.load);
        for action in std::mem::take(&mut frame.actions) {
            match action {
                PanelAction::StartRecording => self.toggle_recording(true),
                PanelAction::StopRecording => self.toggle_recording(false),
                PanelAction::CameraOverview => self.preset(ViewPreset::Overview),
                PanelAction::CameraMicroscope => self.preset(ViewPreset::Microscope),
                PanelAction::LoadScenario => load = true,
                PanelAction::Cut => self.cut(),
                PanelAction::EndSession => self.end_session(event_loop),
                PanelAction::SelectSpatula(k) => {
                    if let Some(key) = crate::input::keyboard::DIGITS.get(k) {
                        self.keyboard.apply(KeyEvent { key: *key, pressed: true });
                        self.keyboard.apply(KeyEvent { key: *key, pressed: false });
                    }
                }
            }
        }
        if load {
            self.send(SimCommand::LoadScenario(PathBuf::from(self.ui.load_path.trim())));
        }
        if self.ui.panel.culling != previous_culling {
            self.send(SimCommand::SetCulling(self.ui.panel.culling));
        }
        if backend != self.ui.backend {
            self.ui.backend = backend;
            self.send(SimCommand::SetBackend(backend));
        }
        self.view.draw.source_nodes = self.ui.panel.show_source_nodes;
        self.view.draw.pairs = self.ui.panel.show_pairs;
        self.view.draw.skull = self.ui.panel.show_skull;
        self.view.draw.pressure_max_mmhg = self.ui.panel.pressure_max_mmhg;
        match self.ui.panel.field {
            FieldChoice::None => self.view.draw.field = SurfaceField::None,
            FieldChoice::Field(FieldKind::DisplacementMm) => self.view.draw.field = SurfaceField::Displacement,
            FieldChoice::Field(FieldKind::ContactPressureMmHg) => self.view.draw.field = SurfaceField::Pressure,
            FieldChoice::Field(FieldKind::Strain) => self.view.draw.field = SurfaceField::Strain,
            FieldChoice::Field(FieldKind::InfarctRisk) => self.view.draw.field = SurfaceField::Risk,
        }
        self.tell_strain();
    }

    /// Draws the scene and the panel and presents them; counts the frames presented.
    fn present(&mut self, event_loop: &ActiveEventLoop, mut full: egui::FullOutput) {
        let Some(gpu) = self.gpu.as_mut() else { return };
        let mut textures = std::mem::take(&mut full.textures_delta);
        let paint_jobs = self.egui.tessellate(full.shapes, full.pixels_per_point);
        let (w, h) = gpu.renderer.size();
        let screen = egui_wgpu::ScreenDescriptor { size_in_pixels: [w, h], pixels_per_point: full.pixels_per_point };
        {
            let device = gpu.renderer.renderer().device();
            let queue = gpu.renderer.renderer().queue();
            for (id, deltas) in &textures.set {
                for delta in deltas.iter() {
                    gpu.egui_renderer.update_texture(device, queue, *id, delta);
                }
            }
        }
        // Before the first frame (the scene is still being built) only the panel
        // and the loading screen are drawn, over an empty scene.
        let empty = SceneStatic::default();
        let scene = if self.front.surface_positions.is_empty() { &empty } else { &*self.scene };
        let view = self.view.buffers.view(scene, &self.front, &self.view.draw, self.view.camera);
        let egui_renderer = &mut gpu.egui_renderer;
        let outcome = gpu.renderer.render(&view, |device, queue, encoder, target| {
            let extra = super::overlay::egui_pass(egui_renderer, device, queue, encoder, target, &paint_jobs, &screen);
            queue.submit(extra);
        });
        for id in &textures.free {
            gpu.egui_renderer.free_texture(id);
        }
        textures.clear();
        match outcome {
            Ok(FrameOutcome::Presented) => {
                self.clock.presented += 1;
                let now = Instant::now();
                self.clock.first_present.get_or_insert(now);
                let (since, count, _) = self.clock.fps_window;
                let elapsed = now.duration_since(since).as_secs_f64();
                if elapsed >= 0.5 {
                    self.clock.fps_window = (now, self.clock.presented, (self.clock.presented - count) as f64 / elapsed);
                }
            }
            Ok(FrameOutcome::Skipped) => {}
            Err(e) => {
                tracing::error!(error = %e, "rendering failed; closing the window");
                self.error = Some(WindowError::NoAdapter(e.to_string()));
                event_loop.exit();
                return;
            }
        }
        gpu.window.request_redraw();
    }

    /// Carries out one routed key event; true when egui should get it (the
    /// panel's text field has the keys).
    fn on_key(&mut self, event_loop: &ActiveEventLoop, routed: KeyRoute, pressed: bool, repeat: bool) -> bool {
        match routed {
            KeyRoute::Panel => return true,
            KeyRoute::Ignore => {}
            KeyRoute::ReturnToScene => {
                self.egui.memory_mut(|m| m.stop_text_input());
                self.ui.keys_to_scene = true;
            }
            KeyRoute::Scene(KeyAction::Blade(key)) => self.keyboard.apply(KeyEvent { key, pressed }),
            KeyRoute::Scene(action) if pressed && !repeat => match action {
                KeyAction::Quit => self.end_session(event_loop),
                KeyAction::SceneFocus => {
                    self.egui.memory_mut(|m| m.stop_text_input());
                    self.ui.keys_to_scene = true;
                }
                KeyAction::Microscope => self.preset(ViewPreset::Microscope),
                KeyAction::Overview => self.preset(ViewPreset::Overview),
                KeyAction::CycleField => self.set_field(self.view.draw.field.next(self.scene.ischemia.is_some())),
                KeyAction::Record => {
                    let on = !self.ui.panel.recording;
                    self.toggle_recording(on);
                }
                KeyAction::Rumble => self.pad.rumble.enabled = !self.pad.rumble.enabled,
                KeyAction::Cut => self.cut(),
                KeyAction::Blade(_) => {}
            },
            KeyRoute::Scene(_) => {}
        }
        false
    }

    /// Microscissors at the active blade's tip (the one the keys drive).
    fn cut(&self) {
        self.send(SimCommand::Cut(self.front.scripted_spatula.unwrap_or(self.keyboard.spatula)));
    }

    fn panel_data(&self) -> PanelData {
        panel_data_of(&self.front, self.clock.fps_window.2)
    }
}

fn panel_data_of(front: &Snapshot, fps: f64) -> PanelData {
    let mut data = PanelData { fps, sim_frame_ms: front.report.times.total() * 1e3, time_s: front.time_s, ..PanelData::default() };
    for (k, s) in front.report.spatulas.iter().enumerate() {
        data.spatulas.push(SpatulaReadout {
            driver: front.drivers.get(k).map(|d| d.label()).unwrap_or("held"),
            force_n: [s.force.x, s.force.y, s.force.z],
            mean_pressure_mmhg: s.mean_pressure_mmhg(),
            feasible_pairs: s.feasible_pairs,
            culled_pairs: s.culled_pairs,
        });
    }
    data
}

/// The loading screen over the scene while a build runs: the scene's file, what
/// is being done, a progress bar with the time left once the compliance
/// columns are being computed.
fn loading_screen(ui: &mut egui::Ui, scene: &str, progress: Option<BuildProgress>, status: &str) {
    egui::Area::new(egui::Id::unique("fissure_loading")).anchor(egui::Align2::CENTER_CENTER, [-160.0, 0.0]).show(ui.ctx(), |ui| {
        egui::Frame::popup(ui.style()).show(ui, |ui| {
            ui.set_width(420.0);
            ui.heading("Preparing the scene");
            ui.label(scene);
            match progress {
                Some(p) if p.total > 0 => {
                    let fraction = p.done as f32 / p.total as f32;
                    let left = p.eta_s.map_or("estimating the time left".to_string(), |s| format!("about {s:.0} s left"));
                    ui.add(egui::ProgressBar::new(fraction).text(format!("compliance {} / {} columns, {left}", p.done, p.total)));
                }
                _ => {
                    ui.label(if status.is_empty() { "loading the mesh and factorizing the stiffness ..." } else { status });
                }
            }
            ui.label("The window stays usable; the simulation starts when this is done.");
        });
    });
}

/// [`camera_for`] from the static scene data (the window has no pipeline).
pub fn camera_for_static(preset: ViewPreset, scene: &SceneStatic, poses: &[crate::geometry::Pose], views: &crate::scenario::Views) -> OrbitCamera {
    super::draw::camera_from_parts(preset, scene.bounds, &scene.shapes, poses, views)
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gpu.is_some() {
            return;
        }
        let attributes = Window::default_attributes()
            .with_title(format!("fissure — {}", self.scenario_path.display()))
            .with_inner_size(winit::dpi::PhysicalSize::new(self.options.size.0, self.options.size.1));
        let window = match event_loop.create_window(attributes) {
            Ok(w) => Arc::new(w),
            Err(e) => {
                self.error = Some(WindowError::NoDisplay(display_error(&e)));
                event_loop.exit();
                return;
            }
        };
        let renderer = match WindowRenderer::new(window.clone(), Some(self.options.present_mode)) {
            Ok(r) => r,
            Err(e) => {
                self.error = Some(WindowError::NoAdapter(e.to_string()));
                event_loop.exit();
                return;
            }
        };
        self.adapter = renderer.renderer().adapter_name().to_string();
        let max_texture = renderer.renderer().device().limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(
            self.egui.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_texture),
        );
        let egui_renderer = egui_wgpu::Renderer::new(
            renderer.renderer().device(),
            renderer.renderer().color_format(),
            egui_wgpu::RendererOptions::default(),
        );
        window.request_redraw();
        self.gpu = Some(Gpu { window, renderer, egui_state, egui_renderer });
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        // Keys first: egui sees a key only when the route gives it to the panel
        // (so Tab never moves egui's focus into the panel).
        if let WindowEvent::KeyboardInput { event: key, .. } = &event {
            let pressed = key.state == ElementState::Pressed;
            let to_panel = match key.physical_key {
                PhysicalKey::Code(code) => {
                    let routed = route(code, self.pointer.ctrl, pressed, self.egui.text_edit_focused());
                    self.on_key(event_loop, routed, pressed, key.repeat)
                }
                PhysicalKey::Unidentified(_) => self.egui.text_edit_focused(),
            };
            if to_panel && let Some(gpu) = self.gpu.as_mut() {
                let _ = gpu.egui_state.on_window_event(&gpu.window, &event);
            }
            return;
        }
        let consumed = match self.gpu.as_mut() {
            Some(gpu) => gpu.egui_state.on_window_event(&gpu.window, &event).consumed,
            None => false,
        };
        match event {
            WindowEvent::CloseRequested => self.end_session(event_loop),
            WindowEvent::Resized(size) => {
                if let Some(gpu) = self.gpu.as_mut() {
                    gpu.renderer.resize(size.width, size.height);
                }
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            WindowEvent::Focused(false) => self.keyboard.release_all(),
            WindowEvent::ModifiersChanged(modifiers) => self.pointer.ctrl = modifiers.state().control_key(),
            WindowEvent::MouseInput { button: MouseButton::Left, state: ElementState::Pressed, .. } if !self.egui.is_pointer_over_egui() => {
                // A click on the scene gives the keys back to it (and starts an orbit).
                self.egui.memory_mut(|m| m.stop_text_input());
                self.ui.keys_to_scene = true;
                self.pointer.left_down = true;
            }
            WindowEvent::MouseInput { button: MouseButton::Left, state, .. } => {
                self.pointer.left_down = state == ElementState::Pressed && !consumed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let Some((x, y)) = self.pointer.cursor
                    && self.pointer.left_down
                    && !self.egui.egui_wants_pointer_input()
                {
                    let nudge = map_mouse([position.x - x, position.y - y], true, 0.0, &self.keyboard.mapping);
                    self.view.camera.orbit(nudge.orbit_rad[0], nudge.orbit_rad[1]);
                }
                self.pointer.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y as f64,
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                let nudge = map_mouse([0.0, 0.0], false, lines, &self.keyboard.mapping);
                self.view.camera.zoom(nudge.zoom_factor);
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let sim_done = self.sim.as_ref().is_none_or(|s| s.finished());
        if sim_done {
            // A build that failed ends the thread at once: keep its error even when
            // no redraw came in between.
            self.take_build_error();
        }
        self.advance_ending();
        // An ended session stays open on its debrief until closed; a timed exit waits for the debrief.
        let timed_out = self.options.exit_after_s.is_some_and(|t| self.clock.started.elapsed().as_secs_f64() >= t) && !self.debriefing();
        if (sim_done && self.session.ending.is_none()) || timed_out {
            event_loop.exit();
            return;
        }
        if let Some(gpu) = &self.gpu {
            gpu.window.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn a_display_error_reads_without_the_dependency_source_location() {
        let winit = "os error at /root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/winit-0.30.13/src/platform_impl/linux/mod.rs:765: neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set.";
        assert_eq!(display_error(&winit), "neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set.");
        assert_eq!(display_error(&"failed to open display :99"), "failed to open display :99");
        assert_eq!(display_error(&"os error at nowhere"), "os error at nowhere");
    }

    /// `--record-dir` wins over the scenario's `outputs.record_dir`, which
    /// wins over the user's data directory (never the working directory
    /// while the system has one).
    #[test]
    fn record_dir_comes_from_the_cli_then_the_scenario_then_the_data_dir() {
        assert_eq!(record_dir_for(Some(Path::new("cli")), Some(Path::new("scene"))), PathBuf::from("cli"));
        assert_eq!(record_dir_for(None, Some(Path::new("scene"))), PathBuf::from("scene"));
        let default = record_dir_for(None, None);
        match user_record_dir() {
            Some(user) => {
                assert_eq!(default, user);
                assert!(user.ends_with("fissure/recordings") && user.is_absolute(), "{}", user.display());
            }
            None => assert_eq!(default, PathBuf::from("recordings"), "no data directory: ./recordings"),
        }
    }
}
