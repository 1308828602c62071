//! The colour bar of the shown field, and the vessel-stretch legend of a scene
//! with vessels, painted with egui: in the window over the scene, and by
//! `fissure screenshot` into its image (the same code, so a screenshot's
//! legend is the window's).
//!
//! In: a [`Legend`] and the rectangle of the scene. Out: shapes on an egui
//! painter (a box at the scene's lower left: title with unit, the marked
//! values' labels, the bar with each marked value as a line, ticks with labels). Stays true: draws nothing for a
//! legend without ticks; needs no layout pass (works on the first frame of a
//! fresh egui context).

use crate::render::legend::Legend;
use crate::render::tethers::VesselLegend;

/// Size of the legend box, points.
pub const LEGEND_SIZE: egui::Vec2 = egui::vec2(300.0, 86.0);

/// The rectangle the legend takes in `scene` (its lower-left corner, with a margin).
pub fn legend_rect(scene: egui::Rect) -> egui::Rect {
    let margin = 12.0;
    egui::Rect::from_min_size(egui::pos2(scene.left() + margin, scene.bottom() - margin - LEGEND_SIZE.y), LEGEND_SIZE)
}

/// Paints `legend` at the lower left of `scene`.
pub fn paint_legend(painter: &egui::Painter, scene: egui::Rect, legend: &Legend) {
    if legend.ticks.is_empty() {
        return;
    }
    let frame = legend_rect(scene);
    // Near-opaque, with an edge: the bar must read over white tissue as well as
    // over the dark background.
    painter.rect_filled(frame, 4.0, egui::Color32::from_rgba_unmultiplied(16, 18, 24, 232));
    painter.rect_stroke(frame, 4.0, egui::Stroke::new(1.0, egui::Color32::from_gray(90)), egui::StrokeKind::Inside);
    let text = egui::Color32::from_gray(235);
    let font = egui::FontId::proportional(13.0);
    painter.text(frame.left_top() + egui::vec2(10.0, 6.0), egui::Align2::LEFT_TOP, &legend.title, font.clone(), text);
    // Title row, then the markers' label row, then the bar and its tick labels.
    let bar = egui::Rect::from_min_size(frame.left_top() + egui::vec2(14.0, 40.0), egui::vec2(frame.width() - 28.0, 14.0));
    let steps = bar.width().round().max(1.0) as usize;
    let step = bar.width() / steps as f32;
    for k in 0..steps {
        let [r, g, b] = legend.colour_at((k as f32 + 0.5) / steps as f32);
        let x = bar.left() + k as f32 * step;
        painter.rect_filled(
            egui::Rect::from_min_max(egui::pos2(x, bar.top()), egui::pos2(x + step + 0.5, bar.bottom())),
            0.0,
            egui::Color32::from_rgb(r, g, b),
        );
    }
    painter.rect_stroke(bar, 0.0, egui::Stroke::new(1.0, egui::Color32::from_gray(200)), egui::StrokeKind::Outside);
    let small = egui::FontId::proportional(11.0);
    for (value, label) in &legend.ticks {
        let x = bar.left() + bar.width() * legend.fraction(*value);
        painter.line_segment([egui::pos2(x, bar.bottom()), egui::pos2(x, bar.bottom() + 4.0)], egui::Stroke::new(1.0, text));
        painter.text(egui::pos2(x, bar.bottom() + 5.0), egui::Align2::CENTER_TOP, label, small.clone(), text);
    }
    let red = egui::Color32::from_rgb(255, 70, 50);
    for marker in &legend.markers {
        let x = bar.left() + bar.width() * legend.fraction(marker.value);
        painter.line_segment([egui::pos2(x, bar.top() - 5.0), egui::pos2(x, bar.bottom() + 3.0)], egui::Stroke::new(2.5, egui::Color32::BLACK));
        painter.line_segment([egui::pos2(x, bar.top() - 5.0), egui::pos2(x, bar.bottom() + 3.0)], egui::Stroke::new(1.5, egui::Color32::WHITE));
        painter.text(egui::pos2(x, bar.top() - 5.0), egui::Align2::CENTER_BOTTOM, &marker.label, small.clone(), red);
    }
}

/// Width of the vessel legend's box, points (its height grows with its rows).
pub const VESSEL_LEGEND_WIDTH: f32 = 300.0;
/// Height of one of its rows (label, bar, ticks), points.
const VESSEL_ROW_HEIGHT: f32 = 44.0;

/// The rectangle the vessel legend takes in `scene` (its lower-right corner, with a margin).
pub fn vessel_legend_rect(scene: egui::Rect, rows: usize) -> egui::Rect {
    let margin = 12.0;
    let size = egui::vec2(VESSEL_LEGEND_WIDTH, 28.0 + VESSEL_ROW_HEIGHT * rows as f32);
    egui::Rect::from_min_size(egui::pos2(scene.right() - margin - size.x, scene.bottom() - margin - size.y), size)
}

/// Paints the vessel-stretch legend at the lower right of `scene`: per kind
/// of vessel, a bar from stretch 1 (its intact colour) to its rupture stretch
/// (bright yellow), the warning and rupture stretch marked. Nothing without rows.
pub fn paint_vessel_legend(painter: &egui::Painter, scene: egui::Rect, legend: &VesselLegend) {
    if legend.rows.is_empty() {
        return;
    }
    let frame = vessel_legend_rect(scene, legend.rows.len());
    painter.rect_filled(frame, 4.0, egui::Color32::from_rgba_unmultiplied(16, 18, 24, 232));
    painter.rect_stroke(frame, 4.0, egui::Stroke::new(1.0, egui::Color32::from_gray(90)), egui::StrokeKind::Inside);
    let text = egui::Color32::from_gray(235);
    let font = egui::FontId::proportional(13.0);
    let small = egui::FontId::proportional(11.0);
    painter.text(frame.left_top() + egui::vec2(10.0, 6.0), egui::Align2::LEFT_TOP, legend.title(), font, text);
    for (k, row) in legend.rows.iter().enumerate() {
        let top = frame.top() + 28.0 + VESSEL_ROW_HEIGHT * k as f32;
        painter.text(egui::pos2(frame.left() + 10.0, top), egui::Align2::LEFT_TOP, &row.label, small.clone(), text);
        let bar = egui::Rect::from_min_size(egui::pos2(frame.left() + 14.0, top + 15.0), egui::vec2(frame.width() - 28.0, 10.0));
        let steps = bar.width().round().max(1.0) as usize;
        let step = bar.width() / steps as f32;
        for s in 0..steps {
            let [r, g, b] = row.colour_at((s as f32 + 0.5) / steps as f32);
            let x = bar.left() + s as f32 * step;
            painter.rect_filled(
                egui::Rect::from_min_max(egui::pos2(x, bar.top()), egui::pos2(x + step + 0.5, bar.bottom())),
                0.0,
                egui::Color32::from_rgb(r, g, b),
            );
        }
        painter.rect_stroke(bar, 0.0, egui::Stroke::new(1.0, egui::Color32::from_gray(200)), egui::StrokeKind::Outside);
        let ticks = [(1.0, "1".to_string(), egui::Align2::LEFT_TOP), (row.warning, format!("warning {:.2}", row.warning), egui::Align2::CENTER_TOP), (row.top(), format!("rupture {:.2}", row.top()), egui::Align2::RIGHT_TOP)];
        for (value, label, align) in ticks {
            let x = bar.left() + bar.width() * row.fraction(value);
            painter.line_segment([egui::pos2(x, bar.top() - 2.0), egui::pos2(x, bar.bottom() + 3.0)], egui::Stroke::new(1.0, text));
            painter.text(egui::pos2(x, bar.bottom() + 4.0), align, label, small.clone(), text);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{ColorMap, FieldKind};

    /// The vessel legend paints a titled bar per row with its warning and
    /// rupture stretch, and nothing without rows.
    #[test]
    fn vessel_legend_paints_a_bar_per_kind_with_its_limits() {
        use crate::render::tethers::{ARTERY_RED, VEIN_BLUE, VesselLegendRow};
        let mut legend = VesselLegend::default();
        legend.add(VesselLegendRow { label: "artery".into(), base: ARTERY_RED, warning: 1.07, rupture: 1.24 });
        legend.add(VesselLegendRow { label: "vein".into(), base: VEIN_BLUE, warning: 1.25, rupture: 1.5 });
        let ctx = egui::Context::default();
        let scene = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 500.0));
        let mut out = ctx.run_ui(egui::RawInput::default(), |ui| paint_vessel_legend(ui.painter(), scene, &legend));
        out.textures_delta.clear();
        let texts: Vec<String> = out.shapes.iter().filter_map(|c| if let egui::Shape::Text(t) = &c.shape { Some(t.galley.text().to_string()) } else { None }).collect();
        for want in ["vessel stretch (length / rest)", "artery", "vein", "warning 1.07", "rupture 1.24", "rupture 1.50"] {
            assert!(texts.iter().any(|t| t == want), "missing `{want}` in {texts:?}");
        }
        assert!(vessel_legend_rect(scene, 2).max.x <= scene.max.x && vessel_legend_rect(scene, 2).min.y >= 0.0);
        let mut out = ctx.run_ui(egui::RawInput::default(), |ui| paint_vessel_legend(ui.painter(), scene, &VesselLegend::default()));
        out.textures_delta.clear();
        assert!(!out.shapes.iter().any(|c| matches!(c.shape, egui::Shape::Text(_))), "no vessels, no legend");
    }

    /// The legend paints on a fresh context's first pass: the bar's colours,
    /// a label per tick, the title and the marker's label.
    #[test]
    fn paints_bar_ticks_title_and_marker_on_the_first_pass() {
        let legend = Legend::of(FieldKind::ContactPressureMmHg, ColorMap::WhiteYellowRed, (0.0, 30.0)).unwrap();
        let ctx = egui::Context::default();
        let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
            paint_legend(ui.painter(), egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 500.0)), &legend);
        });
        out.textures_delta.clear();
        let mut texts = Vec::new();
        let mut rects = 0;
        for clipped in &out.shapes {
            match &clipped.shape {
                egui::Shape::Text(t) => texts.push(t.galley.text().to_string()),
                egui::Shape::Rect(_) => rects += 1,
                _ => {}
            }
        }
        for want in ["contact pressure (mmHg)", "0", "10", "20", "30", "20 mmHg injury line"] {
            assert!(texts.iter().any(|t| t == want), "missing text `{want}` in {texts:?}");
        }
        assert!(rects > 200, "the bar is painted as one strip a point: {rects} rectangles");
    }

    /// The risk bar paints each of its three levels' labels over the bar.
    #[test]
    fn risk_legend_paints_its_three_levels() {
        let legend = Legend::of(FieldKind::InfarctRisk, ColorMap::WhitePurple, (0.0, 1.0)).unwrap();
        let ctx = egui::Context::default();
        let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
            paint_legend(ui.painter(), egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 500.0)), &legend);
        });
        out.textures_delta.clear();
        let texts: Vec<String> = out.shapes.iter().filter_map(|c| if let egui::Shape::Text(t) = &c.shape { Some(t.galley.text().to_string()) } else { None }).collect();
        for want in ["infarct risk (0 to 1)", "1/6 watch", "1/2 at risk", "5/6 likely", "0", "1"] {
            assert!(texts.iter().any(|t| t == want), "missing text `{want}` in {texts:?}");
        }
    }
}
