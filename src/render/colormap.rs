//! Colour maps for scalar fields (displacement, strain, contact pressure, infarct risk).
//!
//! In: a value, a range (min, max), a [`ColorMap`]. Out: a linear-RGB colour
//! (each 0..1) for the GPU. Stays true: values outside the range clamp to the
//! ends; a non-finite value or an empty/invalid range gives [`NO_DATA`].
//! The tables are sampled from matplotlib's viridis and inferno (sRGB), then
//! interpolated piecewise-linearly in sRGB and converted to linear RGB.

/// Linear-RGB colour of a vertex with no valid value (mid grey).
pub const NO_DATA: [f32; 3] = [0.2, 0.2, 0.2];

/// Named colour maps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorMap {
    /// Perceptually uniform, dark blue -> green -> yellow.
    Viridis,
    /// Perceptually uniform, black -> red -> yellow (pressure).
    Inferno,
    /// Diverging blue -> white -> red (signed quantities).
    BlueWhiteRed,
    /// White -> yellow -> orange -> red -> dark red (contact pressure: tissue
    /// without contact stays white, a few mmHg already show yellow). The
    /// white start, then ColorBrewer's YlOrRd.
    WhiteYellowRed,
    /// White -> pale blue -> violet -> dark purple (infarct risk: untouched
    /// tissue stays white, and the hues differ from the pressure map's, so
    /// the two fields are not mistaken for each other). The white start, then
    /// ColorBrewer's BuPu.
    WhitePurple,
}

const VIRIDIS: [[f32; 3]; 9] = [
    [0.267, 0.005, 0.329],
    [0.283, 0.141, 0.458],
    [0.254, 0.265, 0.530],
    [0.207, 0.372, 0.553],
    [0.164, 0.471, 0.558],
    [0.128, 0.567, 0.551],
    [0.135, 0.659, 0.518],
    [0.478, 0.821, 0.317],
    [0.993, 0.906, 0.144],
];
const INFERNO: [[f32; 3]; 9] = [
    [0.001, 0.000, 0.014],
    [0.122, 0.047, 0.282],
    [0.333, 0.059, 0.427],
    [0.532, 0.134, 0.416],
    [0.729, 0.212, 0.333],
    [0.894, 0.352, 0.193],
    [0.978, 0.557, 0.035],
    [0.976, 0.788, 0.197],
    [0.988, 0.998, 0.645],
];
const BLUE_WHITE_RED: [[f32; 3]; 3] = [
    [0.230, 0.299, 0.754],
    [0.865, 0.865, 0.865],
    [0.706, 0.016, 0.150],
];

const WHITE_YELLOW_RED: [[f32; 3]; 9] = [
    [1.000, 1.000, 1.000],
    [1.000, 0.929, 0.627],
    [0.996, 0.851, 0.463],
    [0.996, 0.698, 0.298],
    [0.992, 0.553, 0.235],
    [0.988, 0.306, 0.165],
    [0.890, 0.102, 0.110],
    [0.741, 0.000, 0.149],
    [0.502, 0.000, 0.149],
];

const WHITE_PURPLE: [[f32; 3]; 9] = [
    [1.000, 1.000, 1.000],
    [0.878, 0.925, 0.957],
    [0.749, 0.827, 0.902],
    [0.620, 0.737, 0.855],
    [0.549, 0.588, 0.776],
    [0.549, 0.420, 0.694],
    [0.533, 0.255, 0.616],
    [0.506, 0.059, 0.486],
    [0.302, 0.000, 0.294],
];

/// Linear component (0..1) to sRGB.
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB component (0..1) to linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl ColorMap {
    fn table(self) -> &'static [[f32; 3]] {
        match self {
            ColorMap::Viridis => &VIRIDIS,
            ColorMap::Inferno => &INFERNO,
            ColorMap::BlueWhiteRed => &BLUE_WHITE_RED,
            ColorMap::WhiteYellowRed => &WHITE_YELLOW_RED,
            ColorMap::WhitePurple => &WHITE_PURPLE,
        }
    }

    /// 8-bit sRGB colour of `value` within `range` (for legends drawn in sRGB).
    pub fn color_srgb8(self, value: f64, range: (f64, f64)) -> [u8; 3] {
        self.color(value, range).map(|c| (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8)
    }

    /// Linear-RGB colour of `value` within `range`.
    pub fn color(self, value: f64, range: (f64, f64)) -> [f32; 3] {
        let (lo, hi) = range;
        if !value.is_finite() || !lo.is_finite() || !hi.is_finite() || hi <= lo {
            return NO_DATA;
        }
        let t = ((value - lo) / (hi - lo)).clamp(0.0, 1.0) as f32;
        let table = self.table();
        let x = t * (table.len() - 1) as f32;
        let i = (x.floor() as usize).min(table.len() - 2);
        let f = x - i as f32;
        let a = table[i];
        let b = table[i + 1];
        [0, 1, 2].map(|k| srgb_to_linear(a[k] + (b[k] - a[k]) * f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_clamp_and_bad_values_are_grey() {
        let m = ColorMap::Viridis;
        assert_eq!(
            m.color(-5.0, (0.0, 1.0)),
            m.color(0.0, (0.0, 1.0)),
            "below range clamps to the low end"
        );
        assert_eq!(m.color(7.0, (0.0, 1.0)), m.color(1.0, (0.0, 1.0)));
        assert_eq!(m.color(f64::NAN, (0.0, 1.0)), NO_DATA);
        assert_eq!(m.color(0.5, (1.0, 1.0)), NO_DATA, "empty range");
    }

    #[test]
    fn white_yellow_red_darkens_monotonically_and_low_pressure_shows() {
        let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let m = ColorMap::WhiteYellowRed;
        assert_eq!(m.color_srgb8(0.0, (0.0, 30.0)), [255, 255, 255], "no contact stays white");
        let mut last = 2.0;
        for k in 0..=30 {
            let l = lum(m.color(k as f64, (0.0, 30.0)));
            assert!(l < last, "luminance must fall with pressure: {k} mmHg gave {l} after {last}");
            last = l;
        }
        // 6-12 mmHg must be visible (it was not on a white->red 0-40 scale).
        let blue = m.color_srgb8(8.0, (0.0, 30.0))[2];
        assert!(blue < 140, "8 mmHg of 30 must be clearly yellow (blue channel {blue})");
    }

    #[test]
    fn white_purple_darkens_monotonically_from_white() {
        let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let m = ColorMap::WhitePurple;
        assert_eq!(m.color_srgb8(0.0, (0.0, 1.0)), [255, 255, 255], "no risk stays white");
        let mut last = 2.0;
        for k in 0..=30 {
            let l = lum(m.color(k as f64 / 30.0, (0.0, 1.0)));
            assert!(l < last, "luminance must fall with risk: {k}/30 gave {l} after {last}");
            last = l;
        }
    }

    #[test]
    fn srgb_round_trips() {
        for k in 0..=20 {
            let c = k as f32 / 20.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5, "{c}");
        }
    }

    #[test]
    fn inferno_brightens_monotonically() {
        let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let mut last = -1.0;
        for k in 0..=20 {
            let l = lum(ColorMap::Inferno.color(k as f64, (0.0, 20.0)));
            assert!(
                l > last,
                "inferno luminance must increase: step {k} gave {l} after {last}"
            );
            last = l;
        }
    }
}
