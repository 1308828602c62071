//! The egui side panel and the small bookkeeping behind it.
//!
//! In: plain per-frame numbers the window app copies from the simulation's
//! report ([`PanelData`]: stage timings, pair counts, per-spatula force and mean
//! retraction pressure), the user's clicks. Out: a drawn panel, updated
//! [`PanelState`] switches, and [`PanelAction`]s for the app to carry out.
//! Stays true: no simulation types; [`PressureMonitor`] and [`TimingHistory`]
//! are pure and allocation-free per frame; the 20 mmHg line (the retraction
//! pressure above which brain injury risk rises) is drawn and exceeding it
//! shows a warning and accumulates pressure-time (simulated seconds); the
//! panel's first line says where the keys go ("keys -> scene" / "keys -> panel")
//! and each blade is listed by the scene's own name, the active one marked;
//! a scene with vessels or arachnoid bands gets their section
//! ([`tethers::tethers_section`]): bands by state, each vessel's stretch
//! against its rupture stretch, what tore or was cut; the simulated time reads
//! in minutes and seconds ("t = 2:03.4"), and a scene with tissue over time
//! says its forces are relaxed and gets its ischemia section
//! ([`tissue_time`]).

pub mod debrief;
pub mod legend;
pub mod tethers;
pub mod tissue_time;

use crate::render::FieldKind;

/// Retraction pressure above which the panel warns, mmHg.
pub const PRESSURE_LIMIT_MMHG: f64 = crate::render::legend::INJURY_LINE_MMHG;

/// Tracks retraction pressure against the limit over time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressureMonitor {
    /// The limit, mmHg (> 0).
    pub limit_mmhg: f64,
    /// Integral of (pressure - limit) over the time above the limit, mmHg*s.
    pub excess_mmhg_s: f64,
    /// Integral of pressure over all time, mmHg*s.
    pub total_mmhg_s: f64,
    /// Time spent above the limit, s.
    pub time_over_s: f64,
    /// Highest pressure seen, mmHg.
    pub peak_mmhg: f64,
    /// Whether the latest sample was above the limit.
    pub over: bool,
}

impl PressureMonitor {
    /// A monitor with the given limit (mmHg).
    pub fn new(limit_mmhg: f64) -> Self {
        Self {
            limit_mmhg,
            excess_mmhg_s: 0.0,
            total_mmhg_s: 0.0,
            time_over_s: 0.0,
            peak_mmhg: 0.0,
            over: false,
        }
    }

    /// Adds one sample held for `dt_s` seconds. Non-finite or negative inputs are ignored.
    pub fn update(&mut self, pressure_mmhg: f64, dt_s: f64) {
        if !pressure_mmhg.is_finite() || !dt_s.is_finite() || dt_s < 0.0 || pressure_mmhg < 0.0 {
            return;
        }
        self.total_mmhg_s += pressure_mmhg * dt_s;
        self.peak_mmhg = self.peak_mmhg.max(pressure_mmhg);
        self.over = pressure_mmhg > self.limit_mmhg;
        if self.over {
            self.time_over_s += dt_s;
            self.excess_mmhg_s += (pressure_mmhg - self.limit_mmhg) * dt_s;
        }
    }
}

impl Default for PressureMonitor {
    fn default() -> Self {
        Self::new(PRESSURE_LIMIT_MMHG)
    }
}

/// A fixed-capacity ring of frame times (ms) per stage, for the timing graph.
#[derive(Debug, Clone)]
pub struct TimingHistory {
    names: Vec<String>,
    samples: Vec<f32>,
    capacity: usize,
    next: usize,
    len: usize,
}

impl TimingHistory {
    /// `capacity` frames (>= 2) of the named stages.
    pub fn new(stage_names: &[&str], capacity: usize) -> Self {
        let capacity = capacity.max(2);
        Self {
            names: stage_names.iter().map(|s| s.to_string()).collect(),
            samples: vec![0.0; capacity * stage_names.len()],
            capacity,
            next: 0,
            len: 0,
        }
    }

    /// Stage names.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Records one frame; `ms` holds one value per stage (missing ones read 0,
    /// extra ones are ignored, non-finite ones read 0).
    pub fn push(&mut self, ms: &[f64]) {
        let n = self.names.len();
        for s in 0..n {
            let v = ms.get(s).copied().filter(|v| v.is_finite()).unwrap_or(0.0);
            self.samples[self.next * n + s] = v as f32;
        }
        self.next = (self.next + 1) % self.capacity;
        self.len = (self.len + 1).min(self.capacity);
    }

    /// Frames stored.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Stage `stage`'s value `age` frames ago (0 = latest).
    pub fn get(&self, stage: usize, age: usize) -> Option<f32> {
        if age >= self.len || stage >= self.names.len() {
            return None;
        }
        let slot = (self.next + self.capacity - 1 - age) % self.capacity;
        Some(self.samples[slot * self.names.len() + stage])
    }

    /// Sum over stages of one frame `age` frames ago, ms.
    pub fn frame_total(&self, age: usize) -> Option<f32> {
        (0..self.names.len()).map(|s| self.get(s, age)).sum()
    }
}

/// Per-spatula numbers for the panel.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpatulaReadout {
    /// What moves the blade now (e.g. "keys", "keys + gamepad", "tracker (keys ignored)").
    pub driver: &'static str,
    /// Reaction force, N, world axes.
    pub force_n: [f64; 3],
    /// Mean retraction pressure over the contact, mmHg.
    pub mean_pressure_mmhg: f64,
    /// Feasible pairs this frame.
    pub feasible_pairs: u32,
    /// Pairs culled by the His-flags this frame.
    pub culled_pairs: u32,
}

/// What the panel shows this frame (copied from the simulation's report).
#[derive(Debug, Clone, PartialEq)]
pub struct PanelData {
    /// Frames per second of the window.
    pub fps: f64,
    /// Simulation frame time, ms.
    pub sim_frame_ms: f64,
    /// One per blade of the scene, in its order.
    pub spatulas: Vec<SpatulaReadout>,
    /// The keyboard's active blade (index into `spatulas`).
    pub active_spatula: usize,
    /// True when keys drive the scene, false while the panel's text field has them.
    pub keys_to_scene: bool,
    /// The scene has skull spheres to show (else their switch is greyed out).
    pub has_skull: bool,
    /// Vessels and bands (`None`: the scene has none).
    pub tethers: Option<tethers::TetherPanel>,
    /// Simulated time of the shown frame, s.
    pub time_s: f64,
    /// Relaxation and ischemia (`None`: the scene has neither effect).
    pub tissue: Option<tissue_time::TissuePanel>,
}

impl Default for PanelData {
    fn default() -> Self {
        Self {
            fps: 0.0,
            sim_frame_ms: 0.0,
            spatulas: Vec::new(),
            active_spatula: 0,
            keys_to_scene: true,
            has_skull: false,
            tethers: None,
            time_s: 0.0,
            tissue: None,
        }
    }
}

impl PanelData {
    /// The scene has an infarct risk field to show (the `Ischemia` effect).
    pub fn has_risk(&self) -> bool {
        self.tissue.as_ref().is_some_and(|t| t.ischemia.is_some())
    }
}

/// The focus line: where the keys go now.
pub fn focus_text(keys_to_scene: bool) -> &'static str {
    if keys_to_scene {
        "keys -> scene"
    } else {
        "keys -> panel (Esc or a click on the scene gives them back)"
    }
}

/// Field shown on the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FieldChoice {
    #[default]
    None,
    Field(FieldKind),
}

/// Switches the panel edits.
#[derive(Debug, Clone, PartialEq)]
pub struct PanelState {
    pub field: FieldChoice,
    pub show_source_nodes: bool,
    pub show_pairs: bool,
    pub show_skull: bool,
    pub culling: bool,
    pub recording: bool,
    /// Where recordings go (shown under the Record button).
    pub record_dir: String,
    /// The last recording problem (shown in red until the next start).
    pub record_error: Option<String>,
    /// Top of the pressure colour bar, mmHg (1..=1000, as the scenario's `display.pressure_max_mmhg`).
    pub pressure_max_mmhg: f64,
    /// One per blade (resized by [`update_monitors`]).
    pub monitors: Vec<PressureMonitor>,
    /// The end-of-session debrief, once the session has ended (shown at the top of the panel).
    pub debrief: Option<debrief::DebriefPanel>,
}

impl Default for PanelState {
    fn default() -> Self {
        Self {
            field: FieldChoice::None,
            show_source_nodes: false,
            show_pairs: false,
            show_skull: true,
            culling: true,
            recording: false,
            record_dir: String::new(),
            record_error: None,
            pressure_max_mmhg: crate::render::legend::DEFAULT_PRESSURE_MAX_MMHG,
            monitors: Vec::new(),
            debrief: None,
        }
    }
}

/// Things the app must do after the panel ran.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PanelAction {
    StartRecording,
    StopRecording,
    CameraOverview,
    CameraMicroscope,
    LoadScenario,
    /// Make this blade the keyboard's active one (a click on its name).
    SelectSpatula(usize),
    /// Cut the bands at the active blade's tip (as the X key does).
    Cut,
    /// End the session and debrief it (as Ctrl+Q does); once ended, close the window.
    EndSession,
}

/// Draws the right-hand panel into `ui` (the root ui of `Context::run_ui`),
/// updates `state` and pushes requested actions into `actions`.
pub fn draw_panel(
    ui: &mut egui::Ui,
    data: &PanelData,
    names: &[String],
    history: &TimingHistory,
    state: &mut PanelState,
    actions: &mut Vec<PanelAction>,
) {
    egui::Panel::right("fissure_panel")
        .default_size(280.0)
        .show(ui, |ui| {
            ui.heading("fissure");
            if let Some(d) = &state.debrief {
                egui::ScrollArea::vertical().id_salt("debrief_scroll").max_height(ui.available_height() * 0.7).show(ui, |ui| {
                    if debrief::debrief_section(ui, d) {
                        actions.push(PanelAction::EndSession);
                    }
                });
            }
            status_section(ui, data, history);
            spatula_section(ui, data, names, state, actions);
            if let Some(ischemia) = data.tissue.as_ref().and_then(|t| t.ischemia.as_ref()) {
                ui.separator();
                tissue_time::ischemia_section(ui, ischemia, names);
            }
            if let Some(t) = &data.tethers {
                ui.separator();
                if tethers::tethers_section(ui, t, data.active_spatula) {
                    actions.push(PanelAction::Cut);
                }
            }
            view_section(ui, data, state);
            ui.separator();
            session_section(ui, state, actions);
        });
}

/// Where the keys go, the simulated clock, the frame rate and its graph, the tissue's relaxation.
fn status_section(ui: &mut egui::Ui, data: &PanelData, history: &TimingHistory) {
    let (colour, hint) = if data.keys_to_scene {
        (egui::Color32::from_rgb(110, 210, 120), "1, 2, … or Tab pick the blade")
    } else {
        (egui::Color32::from_rgb(255, 170, 40), "")
    };
    ui.colored_label(colour, egui::RichText::new(focus_text(data.keys_to_scene)).strong());
    if !hint.is_empty() {
        ui.small(hint);
    }
    ui.label(egui::RichText::new(format!("t = {} (simulated)", tissue_time::clock(data.time_s))).strong());
    ui.label(format!(
        "{:.0} fps, simulation {:.2} ms",
        data.fps, data.sim_frame_ms
    ));
    timing_graph(ui, history);
    ui.separator();
    if let Some(t) = &data.tissue {
        tissue_time::relaxation_line(ui, t);
    }
}

/// A block a spatula: its force (a click makes it the active one), what moves it, its pairs and its pressure.
fn spatula_section(ui: &mut egui::Ui, data: &PanelData, names: &[String], state: &PanelState, actions: &mut Vec<PanelAction>) {
    for (k, (s, monitor)) in data.spatulas.iter().zip(state.monitors.iter()).enumerate() {
        let f = s.force_n;
        let magnitude = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        let name = names.get(k).map(String::as_str).unwrap_or("?");
        let active = k == data.active_spatula;
        let title = format!("{} {} {name}: |F| = {magnitude:.3} N", if active { ">" } else { " " }, k + 1);
        if ui.selectable_label(active, egui::RichText::new(title).strong()).clicked() && !active {
            actions.push(PanelAction::SelectSpatula(k));
        }
        ui.label(format!("  moved by: {}{}", s.driver, if active { " (active)" } else { "" }));
        ui.label(format!(
            "  pairs {} feasible, {} culled",
            s.feasible_pairs, s.culled_pairs
        ));
        let text = format!(
            "  pressure {:.1} mmHg (limit {:.0})",
            s.mean_pressure_mmhg, monitor.limit_mmhg
        );
        if monitor.over {
            ui.colored_label(
                egui::Color32::from_rgb(255, 80, 60),
                format!("{text}  ABOVE LIMIT"),
            );
        } else {
            ui.label(text);
        }
        ui.label(format!(
            "  above {:.0} mmHg: {:.2} s (simulated), excess {:.1} mmHg*s, peak {:.1}",
            monitor.limit_mmhg, monitor.time_over_s, monitor.excess_mmhg_s, monitor.peak_mmhg
        ));
        pressure_bar(ui, s.mean_pressure_mmhg, monitor.limit_mmhg);
    }
}

/// The surface colour and the overlays.
fn view_section(ui: &mut egui::Ui, data: &PanelData, state: &mut PanelState) {
    ui.separator();
    ui.label("Surface colour");
    ui.radio_value(&mut state.field, FieldChoice::None, "none");
    for kind in [
        FieldKind::DisplacementMm,
        FieldKind::Strain,
        FieldKind::ContactPressureMmHg,
    ] {
        ui.radio_value(&mut state.field, FieldChoice::Field(kind), kind.label());
    }
    if data.has_risk() {
        let kind = FieldKind::InfarctRisk;
        ui.radio_value(&mut state.field, FieldChoice::Field(kind), kind.label());
    }
    ui.add(egui::Slider::new(&mut state.pressure_max_mmhg, 1.0..=1000.0).logarithmic(true).text("pressure bar top (mmHg)"));
    ui.checkbox(&mut state.show_source_nodes, "source nodes");
    ui.checkbox(&mut state.show_pairs, "pairs (feasible / culled)");
    ui.add_enabled(data.has_skull, egui::Checkbox::new(&mut state.show_skull, "skull spheres"))
        .on_disabled_hover_text("this scene has no skull spheres");
    ui.checkbox(&mut state.culling, "His-flag culling");
}

/// The camera, recording, scenario and end-of-session buttons.
fn session_section(ui: &mut egui::Ui, state: &mut PanelState, actions: &mut Vec<PanelAction>) {
    ui.horizontal(|ui| {
        if ui.button("Overview").clicked() {
            actions.push(PanelAction::CameraOverview);
        }
        if ui.button("Microscope").clicked() {
            actions.push(PanelAction::CameraMicroscope);
        }
    });
    ui.horizontal(|ui| {
        let label = if state.recording {
            "Stop recording"
        } else {
            "Record"
        };
        if ui.button(label).clicked() {
            state.recording = !state.recording;
            actions.push(if state.recording {
                PanelAction::StartRecording
            } else {
                PanelAction::StopRecording
            });
        }
        if ui.button("Load scenario…").clicked() {
            actions.push(PanelAction::LoadScenario);
        }
    });
    if state.debrief.is_none()
        && ui.button("End session").on_hover_text("the session is written as a recording and debriefed against the scene's careful trajectory (Ctrl+Q)").clicked()
    {
        actions.push(PanelAction::EndSession);
    }
    if !state.record_dir.is_empty() {
        ui.small(format!("recordings -> {}", state.record_dir));
    }
    if let Some(e) = &state.record_error {
        ui.colored_label(egui::Color32::from_rgb(255, 80, 60), e);
    }
}

/// Updates the pressure monitors from this frame's data (call once per simulation frame).
pub fn update_monitors(state: &mut PanelState, data: &PanelData, dt_s: f64) {
    state.monitors.resize(data.spatulas.len(), PressureMonitor::default());
    for (m, s) in state.monitors.iter_mut().zip(data.spatulas.iter()) {
        m.update(s.mean_pressure_mmhg, dt_s);
    }
}

fn pressure_bar(ui: &mut egui::Ui, pressure: f64, limit: f64) {
    let (rect, _) = ui.allocate_exact_size(
        egui::vec2(ui.available_width().min(240.0), 10.0),
        egui::Sense::hover(),
    );
    let painter = ui.painter_at(rect);
    let full_scale = (limit * 2.0).max(1e-9);
    let fraction = (pressure / full_scale).clamp(0.0, 1.0) as f32;
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(40));
    let filled =
        egui::Rect::from_min_size(rect.min, egui::vec2(rect.width() * fraction, rect.height()));
    let colour = if pressure > limit {
        egui::Color32::from_rgb(230, 70, 50)
    } else {
        egui::Color32::from_rgb(80, 180, 90)
    };
    painter.rect_filled(filled, 2.0, colour);
    let x = rect.left() + rect.width() * 0.5; // the limit sits at half scale
    painter.line_segment(
        [
            egui::pos2(x, rect.top() - 2.0),
            egui::pos2(x, rect.bottom() + 2.0),
        ],
        egui::Stroke::new(1.5, egui::Color32::WHITE),
    );
}

fn timing_graph(ui: &mut egui::Ui, history: &TimingHistory) {
    let (rect, _) = ui.allocate_exact_size(
        egui::vec2(ui.available_width().min(260.0), 60.0),
        egui::Sense::hover(),
    );
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(25));
    if history.is_empty() {
        return;
    }
    let n = history.len();
    let max = (0..n)
        .filter_map(|a| history.frame_total(a))
        .fold(1.0f32, f32::max);
    let colours = [
        egui::Color32::LIGHT_BLUE,
        egui::Color32::LIGHT_GREEN,
        egui::Color32::GOLD,
        egui::Color32::LIGHT_RED,
        egui::Color32::WHITE,
    ];
    let step = rect.width() / n.max(2) as f32;
    for age in 0..n {
        let x = rect.right() - (age as f32 + 1.0) * step;
        let mut y = rect.bottom();
        for stage in 0..history.names().len() {
            let h = history.get(stage, age).unwrap_or(0.0) / max * rect.height();
            painter.rect_filled(
                egui::Rect::from_min_max(egui::pos2(x, y - h), egui::pos2(x + step, y)),
                0.0,
                colours[stage % colours.len()],
            );
            y -= h;
        }
    }
    painter.text(
        rect.left_top(),
        egui::Align2::LEFT_TOP,
        format!("max {max:.2} ms"),
        egui::FontId::monospace(10.0),
        egui::Color32::WHITE,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pressure_monitor_accumulates_over_the_limit_only() {
        let mut m = PressureMonitor::default();
        m.update(10.0, 1.0);
        assert!(!m.over);
        assert_eq!(m.time_over_s, 0.0);
        m.update(30.0, 0.5);
        assert!(m.over, "30 mmHg is above 20");
        assert!((m.time_over_s - 0.5).abs() < 1e-12);
        assert!(
            (m.excess_mmhg_s - 5.0).abs() < 1e-12,
            "(30-20)*0.5 = 5, got {}",
            m.excess_mmhg_s
        );
        assert!((m.total_mmhg_s - 25.0).abs() < 1e-12);
        m.update(f64::NAN, 1.0);
        m.update(50.0, -1.0);
        assert_eq!(m.peak_mmhg, 30.0, "bad samples must be ignored");
    }

    #[test]
    fn timing_history_wraps_in_order() {
        let mut h = TimingHistory::new(&["rays", "fem"], 3);
        for k in 0..5 {
            h.push(&[k as f64, 10.0 * k as f64]);
        }
        assert_eq!(h.len(), 3);
        assert_eq!(h.get(0, 0), Some(4.0), "latest first");
        assert_eq!(h.get(1, 2), Some(20.0), "oldest kept is frame 2");
        assert_eq!(h.get(0, 3), None);
        assert_eq!(h.frame_total(1), Some(33.0));
        h.push(&[f64::NAN]);
        assert_eq!(h.get(0, 0), Some(0.0));
        assert_eq!(h.get(1, 0), Some(0.0), "missing stages read 0");
    }

    #[test]
    fn panel_runs_headless_and_reports_clicks_only_when_clicked() {
        let ctx = egui::Context::default();
        let mut state = PanelState::default();
        let mut history = TimingHistory::new(&["collision", "fem"], 120);
        history.push(&[0.4, 1.2]);
        let mut data = PanelData {
            fps: 60.0,
            sim_frame_ms: 1.6,
            spatulas: vec![SpatulaReadout::default(); 2],
            ..PanelData::default()
        };
        data.spatulas[0].mean_pressure_mmhg = 25.0;
        let names = ["frontal".to_string(), "temporal".to_string()];
        update_monitors(&mut state, &data, 0.1);
        assert!(state.monitors[0].over && !state.monitors[1].over);
        let mut actions = Vec::new();
        for _ in 0..2 {
            ctx.run_ui(egui::RawInput::default(), |ui| {
                draw_panel(ui, &data, &names, &history, &mut state, &mut actions)
            })
            .drop_without_applying_deltas();
        }
        assert!(actions.is_empty(), "no input, no actions: {actions:?}");
        assert_eq!(
            state,
            PanelState {
                monitors: state.monitors.clone(),
                ..PanelState::default()
            },
            "no input must not flip switches"
        );
    }

    fn panel_texts(data: &PanelData, names: &[String]) -> Vec<String> {
        let ctx = egui::Context::default();
        let mut state = PanelState::default();
        update_monitors(&mut state, data, 0.0);
        let history = TimingHistory::new(&["fem"], 4);
        let mut texts = Vec::new();
        for _ in 0..2 {
            let mut out = ctx.run_ui(egui::RawInput::default(), |ui| draw_panel(ui, data, names, &history, &mut state, &mut Vec::new()));
            out.textures_delta.clear();
            texts = out.shapes.iter().filter_map(|c| if let egui::Shape::Text(t) = &c.shape { Some(t.galley.text().to_string()) } else { None }).collect();
        }
        texts
    }

    /// The panel names blades as the scene does, marks the active one and
    /// says where the keys go (not "Spatula left/right" with no cue of the key focus).
    #[test]
    fn panel_uses_the_scene_names_marks_the_active_blade_and_the_key_focus() {
        let names = ["frontal".to_string(), "temporal".to_string(), "third".to_string()];
        let mut data = PanelData { spatulas: vec![SpatulaReadout { driver: "keys", ..SpatulaReadout::default() }; 3], active_spatula: 1, ..PanelData::default() };
        let texts = panel_texts(&data, &names);
        assert!(texts.iter().any(|t| t.starts_with("> 2 temporal")), "the active blade is marked with its scene name: {texts:?}");
        assert!(texts.iter().any(|t| t.contains("1 frontal")) && texts.iter().any(|t| t.contains("3 third")), "{texts:?}");
        assert!(!texts.iter().any(|t| t.contains("left") || t.contains("right")), "no left/right names: {texts:?}");
        assert!(texts.iter().any(|t| t == "keys -> scene"), "{texts:?}");
        data.keys_to_scene = false;
        let texts = panel_texts(&data, &names);
        assert!(texts.iter().any(|t| t.starts_with("keys -> panel")), "{texts:?}");
    }

    /// The panel shows the simulated time in minutes and seconds; with tissue
    /// over time, the relaxation line, the ischemia section and the risk
    /// field's switch; without, none of them.
    #[test]
    fn panel_shows_the_clock_and_tissue_over_time_only_with_its_effects() {
        let names = ["frontal".to_string()];
        let mut data = PanelData { spatulas: vec![SpatulaReadout::default()], time_s: 123.4, ..PanelData::default() };
        let texts = panel_texts(&data, &names);
        assert!(texts.iter().any(|t| t == "t = 2:03.4 (simulated)"), "{texts:?}");
        assert!(!texts.iter().any(|t| t == "Ischemia" || t.starts_with("tissue relaxing") || t == "infarct risk (0 to 1)"), "{texts:?}");
        data.tissue = Some(tissue_time::TissuePanel {
            relaxing: true,
            half_time_s: Some(396.0),
            ischemia: Some(tissue_time::IschemiaPanel { blades: vec![tissue_time::BladeRisk::default()], map_mmhg: 90.0, ..Default::default() }),
        });
        assert!(data.has_risk());
        let texts = panel_texts(&data, &names);
        for want in ["tissue relaxing: forces are the held tissue's, G(t) halves in 6.6 min", "Ischemia", "  frontal: 0.0 mm² at risk, none yet", "  MAP 90 mmHg", "infarct risk (0 to 1)"] {
            assert!(texts.iter().any(|t| t == want), "missing `{want}` in {texts:?}");
        }
    }
}
