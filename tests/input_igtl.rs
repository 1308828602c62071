//! OpenIGTLink with a real third-party client: `pyigtl` sends TRANSFORMs (header
//! v1 and v2) to our server; the decoded poses must match within float32
//! precision, and our force message must reach a raw socket client intact.
//! Skips (with a message) when python3 or pyigtl is missing.

use fissure::input::igtl::{IgtlConfig, IgtlServer};
use fissure::math::Vec3;
use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

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
