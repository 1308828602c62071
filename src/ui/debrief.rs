//! The panel's end-of-session section: while the debrief is made, what it is doing and a progress bar; then the
//! verdicts and key figures per blade, what to do differently, and where the page was written.
//!
//! In: [`DebriefPanel`], plain strings and numbers the window fills from the debrief. Out: drawn widgets. Stays
//! true: no simulation or debrief types here; a verdict's colour follows its level (within green, above amber, far
//! above or over a limit red), and its words are always written beside the colour.

/// How a row's verdict reads: 0 within, 1 above, 2 far above or over a limit; `None`: not judged.
pub type Level = Option<u8>;

/// One figure of the debrief.
#[derive(Debug, Clone, PartialEq)]
pub struct DebriefRow {
    /// "frontal", "both blades", "scene".
    pub section: String,
    pub name: String,
    /// The value with its unit.
    pub value: String,
    /// The reference's value (the careful surgeon's), `-` when none.
    pub reference: String,
    /// The reference's value (or the limit) it was judged against, with its unit; empty when none.
    pub against: String,
    /// "within", "above", "far above", "over the limit"; empty when not judged.
    pub verdict: String,
    pub level: Level,
}

/// A finished debrief, in the panel's words.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DebriefSummary {
    /// "12.4 s simulated against the careful surgeon's trajectory".
    pub headline: String,
    pub rows: Vec<DebriefRow>,
    /// What to do differently (the page's sentences).
    pub sentences: Vec<String>,
    /// Where the page is.
    pub page: String,
    /// Why something is missing (no reference, a run that stopped early).
    pub notes: Vec<String>,
}

/// The end-of-session section.
#[derive(Debug, Clone, PartialEq)]
pub enum DebriefPanel {
    /// Being made: the step in words and its fraction done.
    Working { what: String, fraction: f64 },
    Ready(DebriefSummary),
    /// Nothing to debrief or it failed: the reason.
    Failed(String),
}

fn colour(level: Level) -> egui::Color32 {
    match level {
        Some(0) => egui::Color32::from_rgb(110, 210, 120),
        Some(1) => egui::Color32::from_rgb(255, 170, 40),
        Some(_) => egui::Color32::from_rgb(255, 80, 60),
        None => egui::Color32::from_gray(170),
    }
}

/// Draws the section; true when its "Close" button was clicked.
pub fn debrief_section(ui: &mut egui::Ui, panel: &DebriefPanel) -> bool {
    ui.heading("Session debrief");
    match panel {
        DebriefPanel::Working { what, fraction } => {
            ui.label(format!("{what} ..."));
            ui.add(egui::ProgressBar::new(*fraction as f32).show_percentage());
            ui.small("Ctrl+Q again closes without it (the recording is kept)");
        }
        DebriefPanel::Failed(why) => {
            ui.colored_label(egui::Color32::from_rgb(255, 80, 60), why);
        }
        DebriefPanel::Ready(s) => {
            ui.label(&s.headline);
            let mut section = "";
            egui::Grid::new("debrief_rows").num_columns(4).striped(true).show(ui, |ui| {
                for row in &s.rows {
                    if row.section != section {
                        section = &row.section;
                        ui.label(egui::RichText::new(section).strong());
                        ui.small("you");
                        ui.small("careful");
                        ui.end_row();
                    }
                    ui.label(&row.name);
                    ui.label(&row.value).on_hover_text(if row.against.is_empty() { "not judged".to_string() } else { format!("against {}", row.against) });
                    ui.label(&row.reference);
                    ui.colored_label(colour(row.level), if row.verdict.is_empty() { "-" } else { &row.verdict });
                    ui.end_row();
                }
            });
            for sentence in &s.sentences {
                ui.label(format!("- {sentence}"));
            }
            for note in &s.notes {
                ui.small(note);
            }
            ui.small(format!("page: {}", s.page));
        }
    }
    let close = ui.button("Close fissure").clicked();
    ui.separator();
    close
}
