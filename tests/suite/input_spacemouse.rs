//! The SpaceMouse's reader against a fake spacenavd (a Unix socket in a
//! temporary folder speaking spacenavd's 32-byte events): no daemon and no HID
//! device gives a status line that says so and no motion; the daemon appearing
//! is found (hot-plug), its motion and button events drive the mapping, its
//! going away stops the blade and says so, and it is found again.

#![cfg(unix)]

use fissure::input::spacemouse::decode::{SpaceEvent, SpaceMotion, encode_spnav};
use fissure::input::spacemouse::{SpaceMouseInput, SpaceMouseMapping, Sources, map_motion};
use std::io::Write;
use std::os::unix::net::UnixListener;
use std::time::{Duration, Instant};

fn poll_until(mouse: &mut SpaceMouseInput, blades: usize, what: &str, mut done: impl FnMut(&SpaceMouseInput, &fissure::input::spacemouse::SpaceMouseCommand) -> bool) {
    let start = Instant::now();
    loop {
        let command = mouse.poll(blades);
        if done(mouse, &command) {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(20), "timed out waiting for {what}; status: {}", mouse.status());
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_spacenavd_that_comes_and_goes_is_found_read_and_found_again() {
    let dir = tempfile::tempdir().expect("temp dir");
    let socket = dir.path().join("spnav.sock");
    let sources = Sources { spnav_socket: socket.clone(), hidraw_class: dir.path().join("no-hidraw"), dev_dir: dir.path().join("dev"), retry: Duration::from_millis(20) };
    let mapping = SpaceMouseMapping::default();
    let mut mouse = SpaceMouseInput::start(mapping, sources);

    poll_until(&mut mouse, 2, "the missing-device line", |m, c| m.status().starts_with("no SpaceMouse") && c.velocity.is_zero());
    let line = mouse.status().to_string();
    assert!(line.contains("spacenavd is not running") && line.contains("no 3Dconnexion HID device"), "{line}");
    assert!(mouse.device().is_none());

    // spacenavd starts: the reader connects on its next look.
    let daemon = UnixListener::bind(&socket).expect("the fake daemon's socket");
    let (mut client, _) = daemon.accept().expect("the reader connects");
    poll_until(&mut mouse, 2, "the connection", |m, _| m.device().is_some());
    assert!(mouse.status().contains("through spacenavd"), "{}", mouse.status());

    let push = SpaceMotion { translation: [0, -300, 0], rotation: [0, 0, -100] };
    client.write_all(&encode_spnav(&SpaceEvent::Motion(push), 16)).expect("a motion event");
    let expected = map_motion(&push, false, &mapping);
    poll_until(&mut mouse, 2, "the motion", |_, c| c.velocity == expected);
    assert!(expected.linear_m_s.x > 0.0 && expected.angular_rad_s.z > 0.0, "away and a left twist: {expected:?}");

    // Left button: the second blade; right button: precision.
    let mut buttons = Vec::new();
    for (index, pressed) in [(0, true), (0, false), (1, true), (1, false)] {
        buttons.extend(encode_spnav(&SpaceEvent::Button { index, pressed }, 0));
    }
    client.write_all(&buttons).expect("button events");
    poll_until(&mut mouse, 2, "the buttons", |_, c| c.selected == 1 && c.precision);
    let slow = mouse.poll(2).velocity;
    assert!((slow.linear_m_s.norm() - expected.linear_m_s.norm() * mapping.precision_factor).abs() < 1e-12);

    // The daemon goes away: the blade stops, the line says why, and it is looked for again.
    drop(client);
    drop(daemon);
    std::fs::remove_file(&socket).expect("the socket goes with the daemon");
    poll_until(&mut mouse, 2, "the loss", |m, c| m.status().starts_with("SpaceMouse lost") && c.velocity.is_zero());
    poll_until(&mut mouse, 2, "the search", |m, _| m.status().starts_with("no SpaceMouse"));

    // And found when it comes back.
    let daemon = UnixListener::bind(&socket).expect("the daemon again");
    let (mut client, _) = daemon.accept().expect("the reader reconnects");
    poll_until(&mut mouse, 2, "the reconnection", |m, _| m.device().is_some());
    client.write_all(&encode_spnav(&SpaceEvent::Motion(push), 16)).expect("a motion event");
    poll_until(&mut mouse, 2, "motion after the reconnection", |_, c| !c.velocity.is_zero());
}
