//! Property tests: random and truncated bytes fed to the scenario parser, the
//! `--set` machinery and the trajectory parser give errors, never panics.

use std::path::Path;

use fissure::scenario::{Scenario, Trajectory};
use proptest::prelude::*;

const SYLVIAN: &str = include_str!("../../config/sylvian.ron");
/// The scene with vessels and arachnoid bands: its `tethers` field is mutated too.
const TETHERED: &str = include_str!("../../config/sylvian_tethers.ron");

const TRAJECTORY: &str = "# t\ntime_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0.0,0,1.5,-2.0,3.0,1.0,0.0,0.0,0.0\n\
0.5,1,1.5,-2.0,3.0,0.7071067811865476,0.7071067811865476,0.0,0.0\n1.0,0,4.0,2.0,-1.0,0.0,0.0,1.0,0.0\n";

/// The real file's path, so that relative paths (the trajectory) resolve and
/// mutated texts get as far into validation as they can.
fn origin() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sylvian.ron"))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic_the_scenario_parser(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = Scenario::from_str(&text, origin(), &[]);
    }

    #[test]
    // Every cut before the closing `)` (trailing whitespace aside) loses part of the scene.
    fn truncated_scenarios_never_panic(cut in 0usize..SYLVIAN.trim_end().len()) {
        let mut cut = cut;
        while !SYLVIAN.is_char_boundary(cut) { cut -= 1; }
        let result = Scenario::from_str(&SYLVIAN[..cut], origin(), &[]);
        prop_assert!(result.is_err(), "a truncated scenario ({cut} bytes) must not validate");
    }

    #[test]
    fn corrupted_scenarios_never_panic(at in 0usize..SYLVIAN.len(), byte in any::<u8>()) {
        let mut bytes = SYLVIAN.as_bytes().to_vec();
        bytes[at] = byte;
        let text = String::from_utf8_lossy(&bytes);
        let _ = Scenario::from_str(&text, origin(), &[]);
    }

    #[test]
    fn corrupted_tethered_scenarios_never_panic_and_validate_only_finite_tethers(at in 0usize..TETHERED.len(), byte in any::<u8>()) {
        let mut bytes = TETHERED.as_bytes().to_vec();
        bytes[at] = byte;
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(s) = Scenario::from_str(&text, origin(), &[]) {
            for v in &s.tethers.vessels {
                prop_assert!(v.points.iter().all(|p| p.position().iter().all(|c| c.is_finite())));
                prop_assert!(v.axial_stiffness > 0.0 && v.warning_stretch > 1.0 && v.warning_stretch < v.rupture_stretch);
            }
            for b in &s.tethers.bands {
                prop_assert!(b.stiffness > 0.0 && b.strength > 0.0 && b.slack >= 0.0);
            }
        }
    }

    #[test]
    fn random_tether_overrides_never_panic(index in 0usize..3, field in "(name|kind|points_mm|diameter_mm|rupture_stretch|warning_stretch|axial_stiffness_n)", value in "[ -~]{0,24}") {
        let arg = format!("tethers.vessels[{index}].{field}={value}");
        let _ = Scenario::from_str(TETHERED, origin(), &[arg]);
    }

    #[test]
    fn random_device_overrides_never_panic_and_validate_only_checked_devices(
        field in "(connect|mapping|mapping\\.scale|mapping\\.rotation|mapping\\.clutch|mapping\\.clutch\\.device|mapping\\.clutch\\.button|force|force\\.name|force\\.scale|force\\.max_force_n|force\\.rate_hz|force\\.rotation|device|workspace_mm)",
        value in "[ -~]{0,24}",
        section in "(spacemouse\\.dead_zone|spacemouse\\.max_speed_mm_s|spacemouse\\.max_rate_deg_s|spacemouse\\.precision_factor|spacemouse\\.full_scale_counts|openigtlink\\.listen)",
        section_value in "[ -~]{0,16}",
    ) {
        // A full stylus binding, then one of its fields (or a section's) replaced by noise.
        let binding = "spatulas[0].input=OpenIgtLink(device: \"StylusToBase\", connect: \"127.0.0.1:18944\", mapping: (scale: 0.5, clutch: (device: \"ButtonsToBase\")), force: ())".to_string();
        for set in [format!("spatulas[0].input.{field}={value}"), format!("{section}={section_value}")] {
            if let Ok(s) = Scenario::from_str(SYLVIAN, origin(), &[binding.clone(), set]) {
                prop_assert!(s.devices.spacemouse.dead_zone.is_finite() && (0.0..=0.9).contains(&s.devices.spacemouse.dead_zone));
                prop_assert!(s.devices.spacemouse.max_speed_m_s > 0.0 && s.devices.spacemouse.max_rate_rad_s > 0.0 && s.devices.spacemouse.full_scale_counts > 0.0);
                if let fissure::scenario::InputBinding::OpenIgtLink { device, link, .. } = &s.spatulas[0].input {
                    prop_assert!(!device.is_empty() && device.len() <= 20);
                    if let Some(m) = &link.mapping {
                        prop_assert!(m.scale > 0.0 && m.scale <= 100.0 && m.clutch.as_ref().is_none_or(|(d, b)| (1..=3).contains(b) && d.len() <= 20));
                    }
                    if let Some(f) = &link.force {
                        prop_assert!(f.max_force_n > 0.0 && f.max_force_n <= 100.0 && f.rate_hz > 0.0 && f.scale > 0.0 && f.name.len() <= 20);
                    }
                }
            }
        }
    }

    #[test]
    fn random_overrides_never_panic(path in "[a-z_\\[\\]0-9.]{0,24}", value in "[ -~]{0,24}") {
        let arg = format!("{path}={value}");
        let _ = Scenario::from_str(SYLVIAN, origin(), &[arg]);
    }

    #[test]
    fn random_bytes_never_panic_the_trajectory_parser(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = Trajectory::parse(&text, Path::new("prop.csv"));
    }

    #[test]
    fn truncated_or_corrupted_trajectories_never_panic(cut in 0usize..TRAJECTORY.len(), at in 0usize..TRAJECTORY.len(), byte in any::<u8>()) {
        let _ = Trajectory::parse(&TRAJECTORY[..cut], Path::new("prop.csv"));
        let mut bytes = TRAJECTORY.as_bytes().to_vec();
        bytes[at] = byte;
        if let Ok(t) = Trajectory::parse(&String::from_utf8_lossy(&bytes), Path::new("prop.csv")) {
            for k in 0..t.spatula_count() {
                for time in [-1.0, 0.0, 0.25, 0.75, 2.0] {
                    if let Some(p) = t.sample(k, time) {
                        prop_assert!(p.is_valid(), "a parsed trajectory samples valid poses");
                    }
                }
            }
        }
    }
}

#[test]
fn the_untouched_inputs_are_valid() {
    // The properties above mutate these; the originals must parse, or the
    // truncation property would pass for the wrong reason.
    Scenario::from_str(SYLVIAN, origin(), &[]).expect("sylvian.ron");
    let tethered = Scenario::from_str(TETHERED, origin(), &[]).expect("sylvian_tethers.ron");
    assert_eq!((tethered.tethers.vessels.len(), tethered.tethers.bands.len()), (2, 8));
    let t = Trajectory::parse(TRAJECTORY, Path::new("prop.csv")).expect("trajectory");
    assert_eq!(t.spatula_count(), 2);
}
