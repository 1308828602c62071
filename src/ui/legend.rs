//! The colour bar of the shown field, painted with egui: in the window over
//! the scene, and by `fissure screenshot` into its image (the same code, so a
//! screenshot's legend is the window's).
//!
//! In: a [`Legend`] and the rectangle of the scene. Out: shapes on an egui
//! painter (a box at the scene's lower left: title with unit, the marked
//! value's label, the bar with the marked value as a line, ticks with labels). Stays true: draws nothing for a
//! legend without ticks; needs no layout pass (works on the first frame of a
//! fresh egui context).

use crate::render::legend::Legend;

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
    // Title row, then the marker's label row, then the bar and its tick labels.
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
    if let Some(marker) = &legend.marker {
        let x = bar.left() + bar.width() * legend.fraction(marker.value);
        let red = egui::Color32::from_rgb(255, 70, 50);
        painter.line_segment([egui::pos2(x, bar.top() - 5.0), egui::pos2(x, bar.bottom() + 3.0)], egui::Stroke::new(2.5, egui::Color32::BLACK));
        painter.line_segment([egui::pos2(x, bar.top() - 5.0), egui::pos2(x, bar.bottom() + 3.0)], egui::Stroke::new(1.5, egui::Color32::WHITE));
        painter.text(egui::pos2(x, bar.top() - 5.0), egui::Align2::CENTER_BOTTOM, &marker.label, small, red);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{ColorMap, FieldKind};

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
}
