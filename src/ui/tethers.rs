//! The panel's tethers section: the arachnoid bands by state, each vessel's
//! stretch against its rupture stretch, and what tore or was cut, as it happened.
//!
//! In: [`TetherPanel`], plain numbers and names the window copies from the
//! simulation's snapshot. Out: drawn widgets, and a cut request when its
//! button is clicked. Stays true: no simulation types; a scene without
//! tethers has no section (the window passes `None`); event lines read
//! "0.84 s  band 'trabecula 3' torn at 0.051 N", "1.20 s  vein 'superficial
//! Sylvian vein' torn at stretch 1.50", "2.05 s  band 'trabecula 1' cut".

/// One vessel's readout.
#[derive(Debug, Clone, PartialEq)]
pub struct VesselReadout {
    pub name: String,
    /// "artery", "vein", "bridging vein".
    pub kind: &'static str,
    /// Its largest segment stretch this frame (length / rest length).
    pub stretch: f64,
    pub warning: f64,
    pub rupture: f64,
    pub torn: bool,
}

/// Something that happened to a tether.
#[derive(Debug, Clone, PartialEq)]
pub struct EventLine {
    pub time_s: f64,
    /// "band", or the vessel's kind ("artery", "vein", ...).
    pub noun: String,
    pub name: String,
    /// Cut by the trainee (else torn).
    pub cut: bool,
    /// A band (its tension is told), else a vessel (its stretch is told).
    pub band: bool,
    pub stretch: f64,
    pub tension_n: f64,
}

impl EventLine {
    /// The line the panel shows.
    pub fn text(&self) -> String {
        let head = format!("{:.2} s  {} '{}'", self.time_s, self.noun, self.name);
        if self.cut {
            format!("{head} cut")
        } else if self.band {
            format!("{head} torn at {:.3} N", self.tension_n)
        } else {
            format!("{head} torn at stretch {:.2}", self.stretch)
        }
    }
}

/// What the tethers section shows this frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TetherPanel {
    pub bands_intact: u32,
    pub bands_torn: u32,
    pub bands_cut: u32,
    pub vessels: Vec<VesselReadout>,
    /// The latest events, oldest first.
    pub events: Vec<EventLine>,
    /// Events in the whole run (more than `events` holds when old ones were left out).
    pub event_count: usize,
}

/// Most event lines the window passes to the panel (the newest).
pub const MAX_EVENT_LINES: usize = 40;

const WARN: egui::Color32 = egui::Color32::from_rgb(255, 170, 40);
const TORN: egui::Color32 = egui::Color32::from_rgb(255, 80, 60);

/// Draws the section; true when its Cut button was clicked.
pub fn tethers_section(ui: &mut egui::Ui, data: &TetherPanel, active_blade: usize) -> bool {
    ui.label(egui::RichText::new("Vessels and arachnoid bands").strong());
    let bands = data.bands_intact + data.bands_torn + data.bands_cut;
    if bands > 0 {
        ui.label(format!("  bands: {} intact, {} torn, {} cut", data.bands_intact, data.bands_torn, data.bands_cut));
    }
    for v in &data.vessels {
        let text = format!("  {} ({}): stretch {:.2} / {:.2}", v.name, v.kind, v.stretch, v.rupture);
        if v.torn {
            ui.colored_label(TORN, format!("{text}  TORN"));
        } else if v.stretch.is_finite() && v.stretch > v.warning {
            ui.colored_label(WARN, format!("{text}  stretched"));
        } else {
            ui.label(text);
        }
        stretch_bar(ui, v);
    }
    let clicked = ui
        .button(format!("Cut bands at blade {} (X)", active_blade + 1))
        .on_hover_text("microscissors at the active blade's tip cut the bands within 2 mm")
        .clicked();
    if data.events.is_empty() {
        ui.small("nothing torn or cut yet");
    } else {
        if data.event_count > data.events.len() {
            ui.small(format!("{} earlier events not shown", data.event_count - data.events.len()));
        }
        egui::ScrollArea::vertical().id_salt("fissure_tether_events").max_height(140.0).stick_to_bottom(true).show(ui, |ui| {
            for e in &data.events {
                let line = egui::RichText::new(e.text()).monospace().size(11.0);
                if e.cut { ui.label(line) } else { ui.colored_label(TORN, line) };
            }
        });
    }
    clicked
}

/// A bar of the stretch from 1 to the rupture stretch, the warning stretch marked.
fn stretch_bar(ui: &mut egui::Ui, v: &VesselReadout) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width().min(240.0), 8.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    let span = if v.rupture.is_finite() && v.rupture > 1.0 { v.rupture - 1.0 } else { 1.0 };
    let at = |s: f64| if s.is_finite() { ((s - 1.0) / span).clamp(0.0, 1.0) as f32 } else { 0.0 };
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(40));
    let colour = if v.torn {
        TORN
    } else if v.stretch > v.warning {
        WARN
    } else {
        egui::Color32::from_rgb(80, 180, 90)
    };
    let fill = if v.torn { 1.0 } else { at(v.stretch) };
    painter.rect_filled(egui::Rect::from_min_size(rect.min, egui::vec2(rect.width() * fill, rect.height())), 2.0, colour);
    let x = rect.left() + rect.width() * at(v.warning);
    painter.line_segment([egui::pos2(x, rect.top() - 2.0), egui::pos2(x, rect.bottom() + 2.0)], egui::Stroke::new(1.5, egui::Color32::WHITE));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn event_lines_read_as_the_panel_shows_them() {
        let band = EventLine { time_s: 0.84, noun: "band".into(), name: "trabecula 3".into(), cut: false, band: true, stretch: 1.3, tension_n: 0.0512 };
        assert_eq!(band.text(), "0.84 s  band 'trabecula 3' torn at 0.051 N");
        let vein = EventLine { time_s: 1.2, noun: "vein".into(), name: "superficial Sylvian vein".into(), cut: false, band: false, stretch: 1.5, tension_n: 0.8 };
        assert_eq!(vein.text(), "1.20 s  vein 'superficial Sylvian vein' torn at stretch 1.50");
        let cut = EventLine { cut: true, ..band };
        assert_eq!(cut.text(), "0.84 s  band 'trabecula 3' cut");
    }

    #[test]
    fn section_shows_bands_vessels_and_events_and_clicks_nothing_by_itself() {
        let data = TetherPanel {
            bands_intact: 3,
            bands_torn: 1,
            bands_cut: 2,
            vessels: vec![VesselReadout { name: "Sylvian vein".into(), kind: "vein", stretch: 1.3, warning: 1.25, rupture: 1.5, torn: false }],
            events: vec![EventLine { time_s: 0.5, noun: "band".into(), name: "t1".into(), cut: true, band: true, stretch: 1.0, tension_n: 0.0 }],
            event_count: 1,
        };
        let ctx = egui::Context::default();
        let mut texts = Vec::new();
        for _ in 0..2 {
            let mut out = ctx.run_ui(egui::RawInput::default(), |ui| assert!(!tethers_section(ui, &data, 0)));
            out.textures_delta.clear();
            texts = out.shapes.iter().filter_map(|c| if let egui::Shape::Text(t) = &c.shape { Some(t.galley.text().to_string()) } else { None }).collect();
        }
        for want in ["  bands: 3 intact, 1 torn, 2 cut", "  Sylvian vein (vein): stretch 1.30 / 1.50  stretched", "0.50 s  band 't1' cut", "Cut bands at blade 1 (X)"] {
            assert!(texts.iter().any(|t| t == want), "missing `{want}` in {texts:?}");
        }
    }
}
