//! Tissue over time in the window: the panel's relaxation line and ischemia
//! section from a [`super::draw::Snapshot`] and the scene's static data (the
//! risk field itself is drawn through [`super::draw`]).
//!
//! In: the scene's relaxation (whether it relaxes, how fast) and ischemia model
//! (its mean arterial pressure), the frame's ischemia figures (the report's)
//! and each blade's time to first risk (the snapshot's). Out: a
//! [`TissuePanel`], plain numbers in the panel's units (mm^2, mmHg min). Stays
//! true: a scene with neither effect gives `None`; a frame without ischemia
//! figures yet (before the first step) shows zeros, never a panic.

use super::draw::{SceneStatic, Snapshot};
use crate::scenario::Relaxation;
use crate::sim::report::IschemiaFrame;
use crate::ui::tissue_time::{BladeRisk, IschemiaPanel, TissuePanel};

/// The time the relaxation function `G(t) / G(0)` takes to fall to one half, s
/// (`None` when it never does: its long-term share is a half or more). Found by
/// bisection: the function falls monotonically from 1 to its long-term share.
pub fn half_time_s(relaxation: &Relaxation) -> Option<f64> {
    if relaxation.long_term >= 0.5 {
        return None;
    }
    let longest = relaxation.terms.iter().map(|t| t.1).fold(0.0, f64::max);
    let (mut lo, mut hi) = (0.0, longest.max(1e-3));
    // Past enough time constants the ratio is within rounding of its long-term share, under one half.
    while relaxation.modulus_ratio(hi) > 0.5 && hi < longest * 1e3 {
        hi *= 2.0;
    }
    if relaxation.modulus_ratio(hi) > 0.5 {
        return None;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if relaxation.modulus_ratio(mid) > 0.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// The panel's tissue over time for `snapshot` in `scene` (`None`: the scene
/// neither relaxes nor doses ischemia).
pub fn panel(scene: &SceneStatic, snapshot: &Snapshot) -> Option<TissuePanel> {
    if !scene.relaxing && scene.ischemia.is_none() {
        return None;
    }
    let none_yet = IschemiaFrame::default();
    let ischemia = scene.ischemia.as_ref().map(|model| {
        let frame = snapshot.report.ischemia.as_ref().unwrap_or(&none_yet);
        let blades = snapshot.report.spatulas.len().max(frame.blade_area_at_risk_m2.len());
        IschemiaPanel {
            blades: (0..blades)
                .map(|k| BladeRisk {
                    area_at_risk_mm2: frame.blade_area_at_risk_m2.get(k).copied().unwrap_or(0.0) * 1e6,
                    first_at_risk_s: snapshot.first_at_risk_s.get(k).copied().flatten(),
                })
                .collect(),
            area_over_mm2: frame.area_over_m2.map(|a| a * 1e6),
            max_dose_mmhg_min: frame.max_dose_mmhg_s / 60.0,
            max_risk: frame.max_risk,
            longest_low_perfusion_s: frame.longest_low_perfusion_s,
            map_mmhg: model.mean_arterial_pressure_mmhg,
        }
    });
    Some(TissuePanel { relaxing: scene.relaxing, half_time_s: scene.relaxation_half_time_s, ischemia })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Ischemia;

    #[test]
    fn the_default_relaxation_halves_in_six_point_six_minutes() {
        let t = half_time_s(&Relaxation::default()).expect("the default halves");
        assert!((t - 396.0).abs() < 1e-6, "{t}");
        let stiff = Relaxation { terms: vec![(0.3, 10.0)], long_term: 0.7 };
        assert_eq!(half_time_s(&stiff), None, "a long-term share over a half never halves");
        let two = Relaxation { terms: vec![(0.4, 2.0), (0.4, 100.0)], long_term: 0.2 };
        let t = half_time_s(&two).expect("halves");
        assert!((two.modulus_ratio(t) - 0.5).abs() < 1e-9, "{t}");
    }

    #[test]
    fn the_panel_reads_the_report_the_snapshot_and_the_scene() {
        let mut scene = SceneStatic::default();
        let mut snapshot = Snapshot::default();
        assert_eq!(panel(&scene, &snapshot), None, "neither effect: no section");
        scene.relaxing = true;
        scene.relaxation_half_time_s = Some(396.0);
        let p = panel(&scene, &snapshot).expect("relaxing");
        assert!(p.relaxing && p.ischemia.is_none());
        scene.ischemia = Some(Ischemia { mean_arterial_pressure_mmhg: 70.0, ..Ischemia::default() });
        snapshot.report.spatulas = vec![Default::default(); 2];
        let empty = panel(&scene, &snapshot).and_then(|p| p.ischemia).expect("ischemia");
        assert_eq!((empty.blades.len(), empty.max_risk, empty.map_mmhg), (2, 0.0, 70.0), "before the first step: zeros");
        snapshot.report.ischemia = Some(IschemiaFrame {
            area_over_m2: [4e-6, 2e-6, 1e-6],
            blade_area_at_risk_m2: vec![2e-6, 0.0],
            max_dose_mmhg_s: 15_000.0,
            max_risk: 0.7,
            longest_low_perfusion_s: 30.0,
        });
        snapshot.first_at_risk_s = vec![Some(600.0), None];
        let i = panel(&scene, &snapshot).and_then(|p| p.ischemia).expect("ischemia");
        assert!((i.blades[0].area_at_risk_mm2 - 2.0).abs() < 1e-9 && i.blades[0].first_at_risk_s == Some(600.0), "{i:?}");
        assert_eq!(i.blades[1], BladeRisk { area_at_risk_mm2: 0.0, first_at_risk_s: None });
        assert!((i.max_dose_mmhg_min - 250.0).abs() < 1e-9 && (i.area_over_mm2[0] - 4.0).abs() < 1e-9, "{i:?}");
    }
}
