//! How vessels and arachnoid bands look: their colours by stretch and the
//! vessel-stretch legend's data.
//!
//! In: a vessel's intact colour, its stretch (length over rest length), its
//! warning and rupture stretch. Out: linear-RGB colours for the tubes, and a
//! [`VesselLegend`] (one bar a kind of vessel: intact colour up to the warning
//! stretch, then towards bright orange and yellow at rupture). Stays true: pure
//! data, no drawing and no simulation type; the tubes and the legend's bars
//! take their colours from the one function [`vessel_color`], so the legend
//! reads the picture; non-finite or inverted limits never panic (the intact
//! colour is kept).

use super::colormap::linear_to_srgb;

/// Intact artery (linear RGB): a deep red.
pub const ARTERY_RED: [f32; 3] = [0.6, 0.05, 0.05];
/// Intact vein (linear RGB): a dark blue-purple.
pub const VEIN_BLUE: [f32; 3] = [0.15, 0.1, 0.35];
/// Half way from the warning to the rupture stretch (linear RGB).
pub const STRETCH_ORANGE: [f32; 3] = [1.0, 0.38, 0.02];
/// At the rupture stretch (linear RGB): bright yellow.
pub const RUPTURE_YELLOW: [f32; 3] = [1.0, 0.9, 0.1];
/// The stubs left at a torn vessel's ends (linear RGB): bright orange-red.
pub const TORN_END: [f32; 3] = [1.0, 0.2, 0.02];
/// An intact arachnoid band (linear RGB, drawn translucent).
pub const BAND_WHITE: [f32; 3] = [0.82, 0.84, 0.86];
/// An intact band's opacity.
pub const BAND_ALPHA: f32 = 0.55;
/// An intact band's tube radius, m (a fine strand).
pub const BAND_RADIUS_M: f32 = 1e-4;

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0);
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

/// The colour of a vessel segment of intact colour `base` at `stretch`: `base`
/// up to `warning`, then to [`STRETCH_ORANGE`] half way to `rupture` and
/// [`RUPTURE_YELLOW`] at it (and beyond).
pub fn vessel_color(base: [f32; 3], stretch: f64, warning: f64, rupture: f64) -> [f32; 3] {
    if !(stretch.is_finite() && warning.is_finite() && rupture.is_finite()) || rupture <= warning {
        return base;
    }
    let t = ((stretch - warning) / (rupture - warning)).clamp(0.0, 1.0) as f32;
    // the ends exactly (a blend at 0 or 1 may round off them)
    if t <= 0.0 {
        return base;
    }
    if t >= 1.0 {
        return RUPTURE_YELLOW;
    }
    if t <= 0.5 { mix(base, STRETCH_ORANGE, 2.0 * t) } else { mix(STRETCH_ORANGE, RUPTURE_YELLOW, 2.0 * t - 1.0) }
}

/// One bar of the vessel legend: a kind of vessel and its limits.
#[derive(Debug, Clone, PartialEq)]
pub struct VesselLegendRow {
    /// E.g. "artery", "vein", "bridging vein".
    pub label: String,
    /// Intact colour (linear RGB).
    pub base: [f32; 3],
    /// Stretch at which the colour starts to turn (length / rest length).
    pub warning: f64,
    /// Stretch at which the vessel tears.
    pub rupture: f64,
}

/// The vessel-stretch legend: one bar per distinct (kind, limits), stretch 1
/// at the left, the rupture stretch at the right.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VesselLegend {
    pub rows: Vec<VesselLegendRow>,
}

/// Most bars the legend shows (vessels with their own limits beyond these share the last lines' look).
pub const MAX_LEGEND_ROWS: usize = 4;

impl VesselLegend {
    /// Adds a row unless one with the same label and limits is there (or the legend is full).
    pub fn add(&mut self, row: VesselLegendRow) {
        if self.rows.len() < MAX_LEGEND_ROWS && !self.rows.contains(&row) {
            self.rows.push(row);
        }
    }

    /// The legend's title.
    pub fn title(&self) -> &'static str {
        "vessel stretch (length / rest)"
    }
}

impl VesselLegendRow {
    /// Stretch at the right end of the bar.
    pub fn top(&self) -> f64 {
        if self.rupture.is_finite() && self.rupture > 1.0 { self.rupture } else { 2.0 }
    }

    /// Where `stretch` sits along the bar, 0 (stretch 1) to 1 (rupture).
    pub fn fraction(&self, stretch: f64) -> f32 {
        ((stretch - 1.0) / (self.top() - 1.0)).clamp(0.0, 1.0) as f32
    }

    /// The bar's sRGB colour at `fraction` (0..1) of its length.
    pub fn colour_at(&self, fraction: f32) -> [u8; 3] {
        let stretch = 1.0 + f64::from(fraction.clamp(0.0, 1.0)) * (self.top() - 1.0);
        vessel_color(self.base, stretch, self.warning, self.rupture).map(|c| (linear_to_srgb(c).clamp(0.0, 1.0) * 255.0).round() as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_holds_below_warning_and_turns_yellow_at_rupture() {
        assert_eq!(vessel_color(ARTERY_RED, 1.0, 1.07, 1.24), ARTERY_RED);
        assert_eq!(vessel_color(ARTERY_RED, 1.07, 1.07, 1.24), ARTERY_RED);
        let mid = vessel_color(VEIN_BLUE, 1.375, 1.25, 1.5);
        assert!(mid.iter().zip(STRETCH_ORANGE).all(|(a, b)| (a - b).abs() < 1e-6), "{mid:?}");
        assert_eq!(vessel_color(VEIN_BLUE, 1.5, 1.25, 1.5), RUPTURE_YELLOW);
        assert_eq!(vessel_color(VEIN_BLUE, 9.0, 1.25, 1.5), RUPTURE_YELLOW);
        assert_eq!(vessel_color(VEIN_BLUE, f64::NAN, 1.25, 1.5), VEIN_BLUE, "no number, no change");
        assert_eq!(vessel_color(VEIN_BLUE, 2.0, 1.5, 1.25), VEIN_BLUE, "inverted limits never panic");
    }

    #[test]
    fn legend_rows_are_distinct_and_bars_end_at_rupture() {
        let row = VesselLegendRow { label: "artery".into(), base: ARTERY_RED, warning: 1.07, rupture: 1.24 };
        let mut legend = VesselLegend::default();
        legend.add(row.clone());
        legend.add(row.clone());
        assert_eq!(legend.rows.len(), 1);
        assert_eq!(row.fraction(1.24), 1.0);
        assert_eq!(row.fraction(1.0), 0.0);
        assert!((row.fraction(1.07) - 0.07 / 0.24).abs() < 1e-6);
        let [r, g, _] = row.colour_at(1.0);
        assert!(r == 255 && g > 200, "bright yellow at rupture: {r} {g}");
    }
}
