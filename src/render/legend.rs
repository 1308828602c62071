//! Colour legends: what a colour bar beside a field shows (title with unit,
//! ticks, marked values such as the 20 mmHg injury line or the infarct risk
//! levels 1/6, 1/2, 5/6).
//!
//! In: a field's kind, colour map and range. Out: a [`Legend`]: sRGB colours
//! along the bar, tick values and labels. Stays true: pure data, no drawing
//! (the window and `fissure screenshot` paint it with the same egui code,
//! `crate::ui::legend`); ticks lie inside the range and include both ends
//! when they are round numbers; a range that is empty or not finite gives no
//! legend.

use super::{ColorMap, FieldKind};

/// A value marked on the bar with a line and a label.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// In the field's unit as shown (mmHg, mm, %).
    pub value: f64,
    pub label: String,
}

/// One colour bar.
#[derive(Debug, Clone, PartialEq)]
pub struct Legend {
    /// The quantity and its unit, e.g. "contact pressure (mmHg)".
    pub title: String,
    pub map: ColorMap,
    /// The range as shown (the unit of `title`), low end first.
    pub range: (f64, f64),
    /// Tick values and their labels (the unit of `title`).
    pub ticks: Vec<(f64, String)>,
    /// Values marked with a line and a label above the bar, low to high (only those inside the range).
    pub markers: Vec<Marker>,
}

/// Retraction pressure above which injury risk rises, mmHg (the line the
/// panel warns at and the pressure legend marks).
pub const INJURY_LINE_MMHG: f64 = 20.0;

/// Top of the pressure colour bar unless a scenario or the panel says
/// otherwise, mmHg: a real retraction's 6-12 mmHg shows yellow to orange.
pub const DEFAULT_PRESSURE_MAX_MMHG: f64 = 30.0;

/// Round tick values in `[lo, hi]`, at most `max_count` of them (>= 2): a step
/// of 1, 2 or 5 times a power of ten.
pub fn nice_ticks(lo: f64, hi: f64, max_count: usize) -> Vec<f64> {
    if !lo.is_finite() || !hi.is_finite() || hi <= lo {
        return Vec::new();
    }
    let max_count = max_count.max(2);
    let raw = (hi - lo) / (max_count - 1) as f64;
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * power).find(|s| *s >= raw * (1.0 - 1e-9)).unwrap_or(10.0 * power);
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// `value` as a fraction with a small denominator ("1/6", "1/2"), else its decimal.
fn fraction_text(value: f64) -> String {
    for d in 2..=12u32 {
        let n = (value * f64::from(d)).round();
        if (n / f64::from(d) - value).abs() < 1e-9 && n > 0.0 && n < f64::from(d) {
            return format!("{n:.0}/{d}");
        }
    }
    label(value)
}

/// The infarct risk bar's marks: the levels the outputs count area over
/// ([`crate::scenario::tissue_time::RISK_LEVELS`]), e.g. "1/6 watch".
pub fn risk_markers() -> Vec<Marker> {
    crate::scenario::tissue_time::RISK_LEVELS
        .iter()
        .map(|&(value, name)| Marker { value, label: format!("{} {}", fraction_text(value), name.replace('_', " ")) })
        .collect()
}

fn label(value: f64) -> String {
    let rounded = (value * 1000.0).round() / 1000.0;
    if rounded == rounded.trunc() { format!("{rounded:.0}") } else { format!("{rounded}") }
}

impl Legend {
    /// The legend of a field of `kind` drawn with `map` over `range` (in the
    /// field's own unit: mm, mmHg, strain as a fraction (shown in %), or risk
    /// from 0 to 1).
    pub fn of(kind: FieldKind, map: ColorMap, range: (f64, f64)) -> Option<Self> {
        let (scale, title) = match kind {
            FieldKind::DisplacementMm => (1.0, "displacement (mm)"),
            FieldKind::Strain => (100.0, "largest principal strain (%)"),
            FieldKind::ContactPressureMmHg => (1.0, "contact pressure (mmHg)"),
            FieldKind::InfarctRisk => (1.0, "infarct risk (0 to 1)"),
        };
        let shown = (range.0 * scale, range.1 * scale);
        let ticks: Vec<(f64, String)> = nice_ticks(shown.0, shown.1, 7).into_iter().map(|v| (v, label(v))).collect();
        if ticks.is_empty() {
            return None;
        }
        let mut markers = match kind {
            FieldKind::ContactPressureMmHg => vec![Marker { value: INJURY_LINE_MMHG, label: "20 mmHg injury line".into() }],
            FieldKind::InfarctRisk => risk_markers(),
            FieldKind::DisplacementMm | FieldKind::Strain => Vec::new(),
        };
        // A mark off the bar would be drawn at its end, where it does not belong.
        markers.retain(|m| shown.0 <= m.value && m.value <= shown.1);
        Some(Self { title: title.into(), map, range: shown, ticks, markers })
    }

    /// Where `value` (shown unit) sits along the bar, 0 at the low end, 1 at the high end.
    pub fn fraction(&self, value: f64) -> f32 {
        ((value - self.range.0) / (self.range.1 - self.range.0)).clamp(0.0, 1.0) as f32
    }

    /// The bar's sRGB colour at `fraction` (0..1) of its length.
    pub fn colour_at(&self, fraction: f32) -> [u8; 3] {
        self.map.color_srgb8(f64::from(fraction.clamp(0.0, 1.0)), (0.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_inside_the_range_and_reach_both_ends() {
        assert_eq!(nice_ticks(0.0, 30.0, 7), vec![0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0]);
        assert_eq!(nice_ticks(0.0, 10.0, 7), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(nice_ticks(0.0, 40.0, 7), vec![0.0, 10.0, 20.0, 30.0, 40.0]);
        assert!(nice_ticks(1.0, 1.0, 7).is_empty() && nice_ticks(0.0, f64::NAN, 7).is_empty());
        for (lo, hi) in [(0.0, 7.3), (0.0, 0.1), (-3.0, 12.0), (0.0, 1000.0)] {
            let t = nice_ticks(lo, hi, 7);
            assert!(t.len() >= 2 && t.len() <= 7, "{lo}..{hi}: {t:?}");
            assert!(t.iter().all(|v| *v >= lo - 1e-9 && *v <= hi + 1e-9), "{lo}..{hi}: {t:?}");
        }
    }

    #[test]
    fn the_scenario_default_is_this_default() {
        assert_eq!(crate::scenario::file::DisplayFile::default().pressure_max_mmhg, DEFAULT_PRESSURE_MAX_MMHG);
    }

    #[test]
    fn pressure_legend_marks_the_injury_line_and_strain_shows_percent() {
        let p = Legend::of(FieldKind::ContactPressureMmHg, ColorMap::WhiteYellowRed, (0.0, 30.0)).unwrap();
        assert_eq!(p.title, "contact pressure (mmHg)");
        let m = p.markers.first().expect("20 mmHg is on a 0-30 bar");
        assert!((p.fraction(m.value) - 2.0 / 3.0).abs() < 1e-6);
        assert_eq!(p.ticks.last().map(|t| t.1.as_str()), Some("30"));
        let low = Legend::of(FieldKind::ContactPressureMmHg, ColorMap::WhiteYellowRed, (0.0, 15.0)).unwrap();
        assert!(low.markers.is_empty(), "20 mmHg is off a 0-15 bar: no line drawn at the end");
        let s = Legend::of(FieldKind::Strain, ColorMap::Viridis, (0.0, 0.1)).unwrap();
        assert_eq!((s.range, s.ticks.last().map(|t| t.1.clone())), ((0.0, 10.0), Some("10".to_string())), "strain in %");
        assert!(s.markers.is_empty());
        assert_eq!(p.colour_at(0.0), [255, 255, 255]);
        assert!(Legend::of(FieldKind::DisplacementMm, ColorMap::Viridis, (0.0, 0.0)).is_none());
    }

    /// The risk bar runs 0 to 1 and marks the three levels the outputs count
    /// area over, each at its place, labelled with its fraction and name.
    #[test]
    fn risk_legend_marks_the_three_levels() {
        let r = Legend::of(FieldKind::InfarctRisk, ColorMap::WhitePurple, (0.0, 1.0)).unwrap();
        assert_eq!((r.title.as_str(), r.range), ("infarct risk (0 to 1)", (0.0, 1.0)));
        let marks: Vec<(f64, &str)> = r.markers.iter().map(|m| (m.value, m.label.as_str())).collect();
        assert_eq!(marks, vec![(1.0 / 6.0, "1/6 watch"), (0.5, "1/2 at risk"), (5.0 / 6.0, "5/6 likely")]);
        for (m, want) in r.markers.iter().zip([1.0 / 6.0, 0.5, 5.0 / 6.0]) {
            assert!((f64::from(r.fraction(m.value)) - want).abs() < 1e-6, "{m:?}");
        }
        assert_eq!((r.ticks.first().map(|t| t.1.as_str()), r.ticks.last().map(|t| t.1.as_str())), (Some("0"), Some("1")));
        assert_eq!(r.colour_at(0.0), [255, 255, 255], "no risk stays white");
        let part = Legend::of(FieldKind::InfarctRisk, ColorMap::WhitePurple, (0.0, 0.6)).unwrap();
        assert_eq!(part.markers.len(), 2, "a level off the bar is not marked: {:?}", part.markers);
    }
}
