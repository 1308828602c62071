//! The panel's tissue over time: the simulated time as minutes and seconds, the
//! line saying the forces shown are the relaxed ones (the `Relaxation`
//! effect), and the ischemia section (the `Ischemia` effect): each blade's area
//! at risk and when it first had any, the largest dose and its risk, the
//! longest stretch of perfusion under 10 mmHg, the mean arterial pressure.
//!
//! In: [`TissuePanel`], plain numbers the window copies from the simulation's
//! snapshot and the scene. Out: drawn labels. Stays true: no simulation types;
//! a scene with neither effect has no line and no section (the window passes
//! `None`); a retraction held for minutes reads in minutes ("2:03.4"); the
//! low-perfusion time turns to the warning colour past the six minutes
//! patients tolerated ([`RCPP_TOLERANCE_S`]).

use crate::scenario::tissue_time::{RCPP_LIMIT_MMHG, RCPP_TOLERANCE_S};

/// One blade's line of the ischemia section.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BladeRisk {
    /// Area whose risk is at least one half, pressed last by this blade, mm^2.
    pub area_at_risk_mm2: f64,
    /// When its area at risk first passed zero, simulated s (`None`: not yet).
    pub first_at_risk_s: Option<f64>,
}

/// What the ischemia section shows this frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IschemiaPanel {
    /// One per blade of the scene, in its order.
    pub blades: Vec<BladeRisk>,
    /// Area at or over each risk level (1/6, 1/2, 5/6), mm^2.
    pub area_over_mm2: [f64; 3],
    /// The largest dose of any vertex, mmHg min, and its risk (0 to 1).
    pub max_dose_mmhg_min: f64,
    pub max_risk: f64,
    /// The longest current stretch of any vertex with its perfusion pressure under 10 mmHg, s.
    pub longest_low_perfusion_s: f64,
    /// The patient's mean arterial pressure, mmHg.
    pub map_mmhg: f64,
}

/// Tissue over time in the panel (`None` in [`super::PanelData`]: the scene has neither effect).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TissuePanel {
    /// The forces and pressures shown are relaxed (the `Relaxation` effect).
    pub relaxing: bool,
    /// The time the relaxation function takes to halve, s (`None`: not known, or it never halves).
    pub half_time_s: Option<f64>,
    /// The ischemia section (`None`: the scene has no `Ischemia` effect).
    pub ischemia: Option<IschemiaPanel>,
}

/// Simulated time as minutes, seconds and tenths: "2:03.4" (0 for a time that
/// is negative or not finite).
pub fn clock(t_s: f64) -> String {
    let tenths = if t_s.is_finite() && t_s > 0.0 { (t_s * 10.0).round() as u64 } else { 0 };
    format!("{}:{:02}.{}", tenths / 600, tenths % 600 / 10, tenths % 10)
}

/// The relaxation line: "tissue relaxing: forces are the held tissue's, G(t) halves in 6.6 min".
pub fn relaxation_text(half_time_s: Option<f64>) -> String {
    match half_time_s {
        Some(t) if t.is_finite() && t > 0.0 => format!("tissue relaxing: forces are the held tissue's, G(t) halves in {:.1} min", t / 60.0),
        _ => "tissue relaxing: forces are the held tissue's".to_string(),
    }
}

/// One blade's line: "  frontal: 3.2 mm² at risk, first at 4:12.0" (or "none yet").
pub fn blade_text(name: &str, blade: &BladeRisk) -> String {
    let first = blade.first_at_risk_s.map_or("none yet".to_string(), |t| format!("first at {}", clock(t)));
    format!("  {name}: {:.1} mm² at risk, {first}", blade.area_at_risk_mm2)
}

/// The low-perfusion line: "  perfusion < 10 mmHg: longest 1:23.0 (tolerated 6:00.0)".
pub fn low_perfusion_text(longest_s: f64) -> String {
    format!("  perfusion < {RCPP_LIMIT_MMHG:.0} mmHg: longest {} (tolerated {})", clock(longest_s), clock(RCPP_TOLERANCE_S))
}

const WARN: egui::Color32 = egui::Color32::from_rgb(255, 170, 40);
const DANGER: egui::Color32 = egui::Color32::from_rgb(255, 80, 60);

/// The colour of a risk: the danger colour from even odds, the warning colour
/// from one in six, else none.
fn risk_colour(risk: f64) -> Option<egui::Color32> {
    if risk >= 0.5 {
        Some(DANGER)
    } else if risk >= 1.0 / 6.0 {
        Some(WARN)
    } else {
        None
    }
}

fn coloured(ui: &mut egui::Ui, colour: Option<egui::Color32>, text: String) {
    match colour {
        Some(c) => ui.colored_label(c, text),
        None => ui.label(text),
    };
}

/// Draws the relaxation line (small, under the blade list's forces).
pub fn relaxation_line(ui: &mut egui::Ui, data: &TissuePanel) {
    if data.relaxing {
        ui.small(relaxation_text(data.half_time_s));
    }
}

/// Draws the ischemia section; `names` are the blades' names in the scene's order.
pub fn ischemia_section(ui: &mut egui::Ui, data: &IschemiaPanel, names: &[String]) {
    ui.label(egui::RichText::new("Ischemia").strong());
    for (k, blade) in data.blades.iter().enumerate() {
        let name = names.get(k).map(String::as_str).unwrap_or("?");
        let colour = (blade.area_at_risk_mm2 > 0.0).then_some(DANGER);
        coloured(ui, colour, blade_text(name, blade));
    }
    let [watch, at_risk, likely] = data.area_over_mm2;
    ui.label(format!("  risk over 1/6: {watch:.1} mm², 1/2: {at_risk:.1}, 5/6: {likely:.1}"));
    coloured(ui, risk_colour(data.max_risk), format!("  largest dose {:.0} mmHg min, risk {:.2}", data.max_dose_mmhg_min, data.max_risk));
    let over = data.longest_low_perfusion_s > RCPP_TOLERANCE_S;
    coloured(ui, over.then_some(WARN), low_perfusion_text(data.longest_low_perfusion_s));
    ui.label(format!("  MAP {:.0} mmHg", data.map_mmhg));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_reads_minutes_seconds_and_tenths() {
        assert_eq!(clock(123.4), "2:03.4");
        assert_eq!(clock(0.0), "0:00.0");
        assert_eq!(clock(59.96), "1:00.0", "rounding carries into the minute");
        assert_eq!(clock(3600.0), "60:00.0");
        assert_eq!((clock(-1.0), clock(f64::NAN)), ("0:00.0".to_string(), "0:00.0".to_string()));
    }

    #[test]
    fn lines_read_as_the_panel_shows_them() {
        assert_eq!(relaxation_text(Some(396.0)), "tissue relaxing: forces are the held tissue's, G(t) halves in 6.6 min");
        assert_eq!(relaxation_text(None), "tissue relaxing: forces are the held tissue's");
        assert_eq!(blade_text("frontal", &BladeRisk { area_at_risk_mm2: 3.21, first_at_risk_s: Some(252.0) }), "  frontal: 3.2 mm² at risk, first at 4:12.0");
        assert_eq!(blade_text("temporal", &BladeRisk::default()), "  temporal: 0.0 mm² at risk, none yet");
        assert_eq!(low_perfusion_text(83.0), "  perfusion < 10 mmHg: longest 1:23.0 (tolerated 6:00.0)");
    }

    #[test]
    fn the_section_shows_each_blade_the_dose_the_perfusion_and_the_map() {
        let data = IschemiaPanel {
            blades: vec![BladeRisk { area_at_risk_mm2: 1.5, first_at_risk_s: Some(61.0) }, BladeRisk::default()],
            area_over_mm2: [4.0, 1.5, 0.3],
            max_dose_mmhg_min: 251.0,
            max_risk: 0.63,
            longest_low_perfusion_s: 400.0,
            map_mmhg: 70.0,
        };
        let panel = TissuePanel { relaxing: true, half_time_s: Some(396.0), ischemia: Some(data.clone()) };
        let names = ["frontal".to_string(), "temporal".to_string()];
        let ctx = egui::Context::default();
        let mut texts = Vec::new();
        for _ in 0..2 {
            let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
                relaxation_line(ui, &panel);
                ischemia_section(ui, &data, &names);
            });
            out.textures_delta.clear();
            texts = out.shapes.iter().filter_map(|c| if let egui::Shape::Text(t) = &c.shape { Some(t.galley.text().to_string()) } else { None }).collect();
        }
        for want in [
            "tissue relaxing: forces are the held tissue's, G(t) halves in 6.6 min",
            "Ischemia",
            "  frontal: 1.5 mm² at risk, first at 1:01.0",
            "  temporal: 0.0 mm² at risk, none yet",
            "  risk over 1/6: 4.0 mm², 1/2: 1.5, 5/6: 0.3",
            "  largest dose 251 mmHg min, risk 0.63",
            "  perfusion < 10 mmHg: longest 6:40.0 (tolerated 6:00.0)",
            "  MAP 70 mmHg",
        ] {
            assert!(texts.iter().any(|t| t == want), "missing `{want}` in {texts:?}");
        }
    }
}
