//! OpenIGTLink with a real third-party client: `pyigtl` sends TRANSFORMs (header
//! v1 and v2) to our server; the decoded poses must match within float32
//! precision, and our force message must reach a raw socket client intact.
//! Skips (with a message) when python3 or pyigtl is missing.
//!
//! And, from a raw socket client: well-formed poses that no tracker can give
//! (1e30 mm away, 1.5 m away, a jump faster than the speed limit) are refused,
//! counted per reason, and the last good pose holds; the limits come from the
//! scenario's `OpenIgtLink` binding, checked there.

use fissure::input::igtl::{IgtlConfig, IgtlServer};
use fissure::input::igtl_codec::encode_transform;
use fissure::input::tracker::TrackerLimits;
use fissure::math::{Matrix3, Vec3};
use fissure::scenario::{IgtlLink, InputBinding, Scenario};
use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn loopback(config: IgtlConfig) -> IgtlServer {
    let config = IgtlConfig { bind: SocketAddr::from(([127, 0, 0, 1], 0)), ..config };
    IgtlServer::start(&config).expect("server on an ephemeral loopback port")
}

fn wait_until(mut done: impl FnMut() -> bool, what: &str) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < Duration::from_secs(20), "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn implausible_tracker_poses_are_refused_counted_and_the_last_good_pose_holds() {
    let server = loopback(IgtlConfig::default());
    let mut client = std::net::TcpStream::connect(server.local_addr()).expect("connect");
    let send = |client: &mut std::net::TcpStream, t: f64, mm: [f64; 3]| {
        client.write_all(&encode_transform("Tool", t, &Matrix3::identity(), &Vec3::from(mm))).expect("send");
    };
    // Sender timestamps 10 ms apart, as a 100 Hz tracker stamps its samples.
    send(&mut client, 100.00, [10.0, -20.0, 30.0]);
    wait_until(|| server.latest("Tool").is_some(), "the first pose");
    let good = server.latest("Tool").unwrap();
    send(&mut client, 100.01, [1e30, 0.0, 0.0]); // a unit or registration error
    send(&mut client, 100.02, [0.0, 1500.0, 0.0]); // 1.5 m from the scene origin
    send(&mut client, 100.03, [10.0, -20.0, 230.0]); // 200 mm in 30 ms: 6.7 m/s
    wait_until(|| server.stats().poses_refused() >= 3, "three refusals");
    let stats = server.stats();
    assert_eq!((stats.poses_outside_workspace, stats.poses_too_fast), (2, 1), "refused per reason: {stats:?}");
    assert_eq!(stats.messages_rejected, 0, "well-formed messages are not malformed ones: {stats:?}");
    assert_eq!(server.latest("Tool"), Some(good), "the last good pose holds (same sequence)");
    // A plausible pose after them: 2 mm in 40 ms from the last accepted one.
    send(&mut client, 100.04, [12.0, -20.0, 30.0]);
    wait_until(|| server.latest("Tool").is_some_and(|p| p.sequence == good.sequence + 1), "the good pose after the refused ones");
    let now = server.latest("Tool").unwrap();
    assert!((now.pose.position - Vec3::new(0.012, -0.020, 0.030)).norm() < 1e-9, "{:?}", now.pose.position);
    // The jump becomes plausible once enough time has passed since the last accepted pose: 200 mm a second later.
    send(&mut client, 101.04, [12.0, -20.0, 230.0]);
    wait_until(|| server.latest("Tool").is_some_and(|p| p.sequence == good.sequence + 2), "a relocation at a plausible speed");
    assert_eq!(server.stats().poses_refused(), 3);
    assert_eq!(server.stats().transforms_accepted, 3);
}

#[test]
fn per_device_limits_apply_to_their_device_only() {
    let tight = TrackerLimits { workspace_m: 0.1, max_speed_m_s: 0.5 };
    let server = loopback(IgtlConfig { device_limits: vec![("Tight".into(), tight)], ..IgtlConfig::default() });
    let mut client = std::net::TcpStream::connect(server.local_addr()).expect("connect");
    for device in ["Tight", "Loose"] {
        client.write_all(&encode_transform(device, 1.0, &Matrix3::identity(), &Vec3::new(150.0, 0.0, 0.0))).expect("send");
    }
    wait_until(|| server.latest("Loose").is_some(), "the default-limited device");
    wait_until(|| server.stats().poses_outside_workspace == 1, "the tight device's refusal");
    assert!(server.latest("Tight").is_none(), "150 mm is outside Tight's 100 mm box");
}

#[test]
fn the_scenario_binding_carries_the_limits_and_refuses_bad_ones() {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sylvian.ron"));
    let text = std::fs::read_to_string(path).expect("read");
    let load = |input: &str| Scenario::from_str(&text, path, &[format!("spatulas[0].input={input}")]);
    let s = load(r#"OpenIgtLink(device: "Frontal")"#).expect("defaults");
    assert_eq!(s.spatulas[0].input, InputBinding::OpenIgtLink { device: "Frontal".into(), workspace_m: 1.0, max_speed_m_s: 3.0, link: IgtlLink::default() });
    let s = load(r#"OpenIgtLink(device: "Frontal", workspace_mm: 250.0, max_speed_mm_s: 500.0)"#).expect("given");
    assert_eq!(s.spatulas[0].input, InputBinding::OpenIgtLink { device: "Frontal".into(), workspace_m: 0.25, max_speed_m_s: 0.5, link: IgtlLink::default() });
    for (input, field) in [
        (r#"OpenIgtLink(device: "F", workspace_mm: 0.0)"#, "spatulas[0].input.workspace_mm"),
        (r#"OpenIgtLink(device: "F", workspace_mm: -5.0)"#, "spatulas[0].input.workspace_mm"),
        (r#"OpenIgtLink(device: "F", max_speed_mm_s: inf)"#, "spatulas[0].input.max_speed_mm_s"),
        (r#"OpenIgtLink(device: "F", max_speed_mm_s: NaN)"#, "spatulas[0].input.max_speed_mm_s"),
    ] {
        let e = load(input).expect_err(input).to_string();
        assert!(e.contains(field) && (e.contains("> 0") || e.contains("finite")), "`{input}` must be refused naming {field}: {e}");
    }
}

fn pyigtl_available() -> bool {
    Command::new("python3")
        .args(["-c", "import pyigtl"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn pyigtl_client_drives_poses_and_receives_force() {
    if !pyigtl_available() {
        println!(
            "SKIP pyigtl_client_drives_poses_and_receives_force: python3 with pyigtl is not available (pip install pyigtl)"
        );
        return;
    }
    let config = IgtlConfig {
        bind: SocketAddr::from(([127, 0, 0, 1], 0)),
        ..IgtlConfig::default()
    };
    let mut server = IgtlServer::start(&config).expect("server on an ephemeral loopback port");
    let port = server.local_addr().port();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/igtl/send_transform.py");
    let child = Command::new("python3")
        .arg(script)
        .arg(port.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start python3");

    // The script's last client ("Probe") waits for a force message.
    let start = Instant::now();
    while server.latest("Probe").is_none() {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "pyigtl never delivered the Probe transform; stats {:?}",
            server.stats()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let force = [0.25, -0.5, 1.5];
    let mut sent = 0;
    while sent == 0 && start.elapsed() < Duration::from_secs(30) {
        sent = server.send_force("Left", 1.0, force);
        std::thread::sleep(Duration::from_millis(10));
    }
    let output = child.wait_with_output().expect("python3 finished");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "client failed: {:?}\nstdout: {stdout}\nstderr: {}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );

    let left = server.latest("Left").expect("pose for Left");
    assert_eq!(left.sequence, 2, "two Left transforms were sent");
    // Second Left message: 30 degrees about z, translation (10, -20, 35.5) mm.
    let expected = Vec3::new(0.010, -0.020, 0.0355);
    assert!(
        (left.pose.position - expected).norm() < 1e-8,
        "Left position {:?}, expected {expected:?} (mm -> m)",
        left.pose.position
    );
    let axis = left.pose.rotation.axis().expect("a rotation");
    assert!(
        (left.pose.rotation.angle() - 30f64.to_radians()).abs() < 1e-6,
        "Left angle {}",
        left.pose.rotation.angle().to_degrees()
    );
    assert!(
        (axis.into_inner() - Vec3::z()).norm() < 1e-6,
        "Left axis {axis:?}"
    );

    let right = server
        .latest("Right")
        .expect("pose for Right (header v2 with metadata)");
    assert!(
        (right.pose.position - Vec3::new(-0.00725, 0.003, 0.120)).norm() < 1e-8,
        "Right position {:?}",
        right.pose.position
    );
    let y_world = right.pose.transform_vector(&Vec3::y());
    assert!(
        (y_world - Vec3::z()).norm() < 1e-6,
        "90 degrees about x maps y to z, got {y_world:?}"
    );

    let line = stdout
        .lines()
        .find(|l| l.starts_with("FORCE "))
        .unwrap_or_else(|| panic!("no FORCE line in {stdout}"));
    let fields: Vec<&str> = line.split_whitespace().collect();
    assert_eq!(
        &fields[1..5],
        ["SENSOR", "Force_Left", "3", "0x02c4000000000000"],
        "force message header: {line}"
    );
    let values: Vec<f64> = fields[5..8]
        .iter()
        .map(|v| v.parse().expect("a number"))
        .collect();
    assert_eq!(values, force, "force values must arrive unchanged");
    assert_eq!(
        server.stats().messages_rejected,
        0,
        "pyigtl's messages must all be accepted: {:?}",
        server.stats()
    );
}
