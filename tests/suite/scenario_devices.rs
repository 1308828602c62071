//! The 6-DoF devices' scenario fields: a SpaceMouse binding and its
//! `spacemouse` tuning, an `OpenIgtLink` binding's `connect`, `mapping` and
//! `force`, and `openigtlink.listen`. Good values become SI; every bad one is
//! refused with an error naming the file (or the `--set` argument), the line
//! and column, and the field, and saying what is wrong; a misspelt field lists
//! the valid keys.

use std::path::{Path, PathBuf};

use fissure::math::{Quat, Vec3};
use fissure::scenario::{InputBinding, Origin, Scenario, ScenarioError};

fn sylvian() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sylvian.ron")
}

fn load(set: &[&str]) -> Result<Scenario, ScenarioError> {
    Scenario::load(&sylvian(), &set.iter().map(|s| s.to_string()).collect::<Vec<_>>())
}

/// A stylus binding for spatula 0 with `extra` fields appended.
fn stylus(extra: &str) -> String {
    format!("spatulas[0].input=OpenIgtLink(device: \"StylusToBase\", connect: \"127.0.0.1:18944\"{extra})")
}

#[test]
fn a_full_stylus_binding_and_a_spacemouse_validate_into_si() {
    let s = load(&[
        &stylus(", mapping: (scale: 0.5, rotation: AxisAngle(axis: (0.0, 0.0, 1.0), angle_deg: 180.0), clutch: (device: \"ButtonsToBase\", button: 2)), force: (max_force_n: 0.88, rate_hz: 200.0)"),
        "spatulas[1].input=SpaceMouse",
        "spacemouse=(max_speed_mm_s: 10.0, dead_zone: 0.1)",
        "openigtlink=(listen: \"127.0.0.1:18945\")",
    ])
    .expect("valid");
    let InputBinding::OpenIgtLink { device, link, .. } = &s.spatulas[0].input else { panic!("{:?}", s.spatulas[0].input) };
    assert_eq!(device, "StylusToBase");
    assert_eq!(link.connect.as_deref(), Some("127.0.0.1:18944"));
    let m = link.mapping.as_ref().expect("mapping");
    assert_eq!((m.scale, m.clutch.clone()), (0.5, Some(("ButtonsToBase".to_string(), 2))));
    let half_turn = Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::PI);
    assert!(m.rotation.angle_to(&half_turn) < 1e-12);
    let f = link.force.as_ref().expect("force");
    assert_eq!((f.name.as_str(), f.scale, f.max_force_n, f.rate_hz), ("ForceToBase", 1.0, 0.88, 200.0), "the name and scale default");
    assert!(f.rotation.angle_to(&half_turn.inverse()) < 1e-12, "the force's frame defaults to the mapping's, inverted");
    assert!(s.spatulas[0].filter.is_some(), "a stylus keeps the tracker's One Euro filter by default");
    assert_eq!(s.spatulas[1].input, InputBinding::SpaceMouse);
    assert!(s.spatulas[1].filter.is_none(), "a rate device is not filtered");
    assert!((s.devices.spacemouse.max_speed_m_s - 0.010).abs() < 1e-15 && s.devices.spacemouse.dead_zone == 0.1);
    assert!((s.devices.spacemouse.max_rate_rad_s - 0.8).abs() < 1e-12, "the gamepad's turn rate by default");
    assert_eq!(s.devices.igtl_listen.port(), 18945);
    let s = load(&[]).expect("the default scene");
    assert_eq!(s.devices.igtl_listen.to_string(), "127.0.0.1:18944", "the server's address as before");
    // Every force field defaults: `force: ()`; a section's field is set on its own.
    let s = load(&[&stylus(", force: ()"), "spacemouse.dead_zone=0.5", "openigtlink.listen=\"0.0.0.0:18946\""]).expect("defaults");
    let InputBinding::OpenIgtLink { link, .. } = &s.spatulas[0].input else { panic!("a binding") };
    let f = link.force.as_ref().expect("force");
    assert_eq!((f.max_force_n, f.rate_hz, f.rotation), (3.3, 100.0, Quat::identity()), "a Touch's 3.3 N at 100 Hz, the same axes without a mapping");
    assert_eq!((s.devices.spacemouse.dead_zone, s.devices.igtl_listen.port()), (0.5, 18946));
}

#[test]
fn bad_device_fields_are_refused_naming_the_field() {
    let cases: [(String, &str, &str); 20] = [
        (stylus("").replace("127.0.0.1:18944", "plus-host"), "spatulas[0].input.connect", "not host:port (no port)"),
        (stylus("").replace("18944", "0"), "spatulas[0].input.connect", "port 0"),
        (stylus("").replace("127.0.0.1:18944", "a host:1"), "spatulas[0].input.connect", "not host:port"),
        (stylus(", mapping: (scale: 0.0)"), "spatulas[0].input.mapping.scale", "must be in (0, 100]"),
        (stylus(", mapping: (scale: inf)"), "spatulas[0].input.mapping.scale", "must be in (0, 100]"),
        (stylus(", mapping: (rotation: AxisAngle(axis: (0.0, 0.0, 0.0), angle_deg: 90.0))"), "spatulas[0].input.mapping.rotation.axis", "non-zero"),
        (stylus(", mapping: (clutch: (device: \"ButtonsToBase\", button: 4))"), "spatulas[0].input.mapping.clutch.button", "must be 1, 2 or 3"),
        (stylus(", mapping: (clutch: (device: \"StylusToBase\"))"), "spatulas[0].input.mapping.clutch.device", "the stylus's pose device"),
        (stylus(", mapping: (clutch: (device: \"\"))"), "spatulas[0].input.mapping.clutch.device", "must not be empty"),
        (stylus(", force: (name: \"AForceNameLongerThanTwenty\")"), "spatulas[0].input.force.name", "at most 20"),
        (stylus(", force: (max_force_n: -1.0)"), "spatulas[0].input.force.max_force_n", "must be in (0, 100] N"),
        (stylus(", force: (rate_hz: 5000.0)"), "spatulas[0].input.force.rate_hz", "must be in (0, 1000] Hz"),
        (stylus(", force: (scale: NaN)"), "spatulas[0].input.force.scale", "must be in (0, 100]"),
        (stylus(", force: (rotation: Quaternion(2.0, 0.0, 0.0, 0.0))"), "spatulas[0].input.force.rotation", "must be unit"),
        ("spatulas[0].input=OpenIgtLink(device: \"ADeviceNameLongerThan20\")".to_string(), "spatulas[0].input.device", "at most 20"),
        ("spacemouse=(dead_zone: 0.95)".to_string(), "spacemouse.dead_zone", "must be in [0, 0.9]"),
        ("spacemouse=(max_speed_mm_s: 0.0)".to_string(), "spacemouse.max_speed_mm_s", "must be in (0, 1000] mm/s"),
        ("spacemouse=(precision_factor: 1.5)".to_string(), "spacemouse.precision_factor", "must be in (0, 1]"),
        ("spacemouse=(full_scale_counts: 40000.0)".to_string(), "spacemouse.full_scale_counts", "must be in (0, 32767] counts"),
        ("openigtlink=(listen: \"localhost:18945\")".to_string(), "openigtlink.listen", "not IP:port"),
    ];
    for (set, field, problem) in &cases {
        let err = load(&[set.as_str()]).expect_err(set);
        let message = err.to_string();
        assert_eq!(err.field(), Some(*field), "`{set}`: {message}");
        assert!(message.contains(problem), "`{set}` must say `{problem}`: {message}");
        assert!(matches!(err.location().map(|l| &l.origin), Some(Origin::Override(_))), "`{set}` names the --set argument: {message}");
    }
}

#[test]
fn a_mapped_stylus_drives_one_blade() {
    let both = [stylus(", mapping: (scale: 1.0)"), "spatulas[1].input=OpenIgtLink(device: \"StylusToBase\")".to_string()];
    let err = load(&[both[0].as_str(), both[1].as_str()]).expect_err("two blades on one mapped stylus");
    assert_eq!(err.field(), Some("spatulas[1].input.device"), "{err}");
    assert!(err.to_string().contains("a mapped stylus drives one blade"), "{err}");
    // Unmapped, two blades may follow one tracker (as before).
    load(&["spatulas[0].input=OpenIgtLink(device: \"T\")", "spatulas[1].input=OpenIgtLink(device: \"T\")"]).expect("one tracker, two blades");
}

/// In the file itself: the error names the file, the line and the field.
#[test]
fn in_the_file_errors_name_the_line_and_a_misspelt_field_the_valid_keys() {
    let text = std::fs::read_to_string(sylvian()).expect("read");
    let absolute = sylvian().parent().expect("config").join("../assets/trajectories/paper_fig14_sylvian.csv");
    let text = text.replacen("\"../assets/trajectories/paper_fig14_sylvian.csv\"", &format!("{:?}", absolute.display().to_string()), 1);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("touch.ron");
    let bad = "input: OpenIgtLink(device: \"StylusToBase\", connect: \"127.0.0.1:18944\",\n                mapping: (scale: 0.5, clutch: (device: \"ButtonsToBase\", button: 7))),";
    let written = text.replacen("input: Keyboard,", bad, 1);
    std::fs::write(&path, &written).expect("write");
    let err = Scenario::load(&path, &[]).expect_err("button 7");
    let line = written[..written.find("button: 7").expect("in the text")].matches('\n').count() + 1;
    let location = err.location().expect("located");
    assert_eq!((location.origin.clone(), location.line), (Origin::File(path.clone()), line), "{err}");
    assert_eq!(err.field(), Some("spatulas[0].input.mapping.clutch.button"), "{err}");

    let misspelt = text.replacen("input: Keyboard,", "input: OpenIgtLink(device: \"StylusToBase\", conect: \"127.0.0.1:18944\"),", 1);
    std::fs::write(&path, &misspelt).expect("write");
    let message = Scenario::load(&path, &[]).expect_err("misspelt").to_string();
    assert!(message.contains("conect") && message.contains("`connect`") && message.contains("`mapping`") && message.contains("`force`"), "{message}");
    let misspelt = text.replacen("input: Keyboard,", "input: SpaceMouse,", 1).replacen("duration_s:", "spacemouse: (dead_zon: 0.1),\n    duration_s:", 1);
    std::fs::write(&path, &misspelt).expect("write");
    let message = Scenario::load(&path, &[]).expect_err("misspelt").to_string();
    assert!(message.contains("dead_zon") && message.contains("`dead_zone`"), "{message}");
}
