//! The scenario parser on arbitrary text, with and without a `--set` override
//! (the text after the first NUL byte, if any). Ok or Err, never a panic; a
//! validated scenario holds only finite values and valid poses.
#![no_main]

use fissure::scenario::Scenario;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let (file, overrides): (&str, Vec<String>) = match text.split_once('\0') {
        Some((f, o)) => (f, vec![o.to_string()]),
        None => (&text, Vec::new()),
    };
    if let Ok(s) = Scenario::from_str(file, Path::new("/nonexistent/fuzz.ron"), &overrides) {
        assert!(s.time_step.is_finite() && s.time_step > 0.0, "validated time step {}", s.time_step);
        for sp in &s.spatulas {
            assert!(sp.initial_pose.is_valid(), "validated pose {:?}", sp.initial_pose);
            if let fissure::scenario::InputBinding::OpenIgtLink { device, link, .. } = &sp.input {
                assert!(!device.is_empty() && device.len() <= 20, "validated device name {device:?}");
                if let Some(m) = &link.mapping {
                    assert!(m.scale > 0.0 && m.scale <= 100.0, "validated stylus scale {}", m.scale);
                    assert!(m.clutch.as_ref().is_none_or(|(d, b)| (1..=3).contains(b) && !d.is_empty() && d.len() <= 20), "validated clutch {:?}", m.clutch);
                }
                if let Some(f) = &link.force {
                    assert!(f.max_force_n > 0.0 && f.max_force_n <= 100.0 && f.rate_hz > 0.0 && f.rate_hz <= 1000.0 && f.scale > 0.0, "validated force output {f:?}");
                }
            }
        }
        let m = &s.spacemouse;
        assert!((0.0..=0.9).contains(&m.dead_zone) && m.max_speed_m_s > 0.0 && m.max_rate_rad_s > 0.0 && m.precision_factor > 0.0 && m.precision_factor <= 1.0, "validated SpaceMouse tuning {m:?}");
        for v in &s.tethers.vessels {
            assert!(v.points.iter().all(|p| p.position().iter().all(|c| c.is_finite())), "validated vessel points");
            assert!(v.axial_stiffness > 0.0 && v.warning_stretch > 1.0 && v.warning_stretch < v.rupture_stretch, "validated vessel limits");
        }
        for b in &s.tethers.bands {
            assert!(b.stiffness > 0.0 && b.strength > 0.0 && b.slack >= 0.0, "validated band");
        }
    }
});
