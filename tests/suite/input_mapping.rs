//! Gamepad and keyboard mappings driven by synthetic events, integrated into
//! poses; every pose that comes out passes the pose guard.

use fissure::geometry::Pose;
use fissure::input::gamepad::{
    GamepadController, GamepadMapping, MotionMode, PadAxis, PadButton, PadEvent,
};
use fissure::input::keyboard::{Key, KeyEvent, KeyboardController};
use fissure::input::{PoseGuard, integrate};
use fissure::math::Vec3;

#[test]
fn gamepad_session_moves_each_spatula_in_its_own_frame() {
    let mapping = GamepadMapping::default();
    let mut pad = GamepadController::new(mapping);
    let mut poses = [
        Pose::default(),
        Pose {
            position: Vec3::new(0.02, 0.0, 0.0),
            ..Pose::default()
        },
    ];
    let mut guards = poses.map(|p| PoseGuard::new(p, "gamepad"));
    let dt = 0.01;
    let run = |pad: &GamepadController,
               frames: usize,
               poses: &mut [Pose; 2],
               guards: &mut [PoseGuard; 2]| {
        for _ in 0..frames {
            let cmd = pad.command();
            let i = cmd.spatula.index();
            poses[i] = guards[i].offer(integrate(&poses[i], &cmd.velocity, dt));
        }
    };
    // Left spatula: push the left stick fully forward for 1 s -> +x by max speed.
    pad.apply(PadEvent::Axis(PadAxis::LeftStickY, 1.0));
    run(&pad, 100, &mut poses, &mut guards);
    assert!(
        (poses[0].position - Vec3::new(mapping.max_speed_m_s, 0.0, 0.0)).norm() < 1e-12,
        "left moved to {:?}",
        poses[0].position
    );
    // Switch to the right spatula and rotate: stick forward pitches about y.
    pad.apply(PadEvent::Pressed(PadButton::RightShoulder));
    pad.apply(PadEvent::Pressed(PadButton::South));
    assert_eq!(pad.command().mode, MotionMode::Rotate);
    run(&pad, 100, &mut poses, &mut guards);
    assert_eq!(
        poses[1].position,
        Vec3::new(0.02, 0.0, 0.0),
        "rotate mode must not move the right spatula"
    );
    assert!(
        (poses[1].rotation.angle() - mapping.max_rate_rad_s).abs() < 1e-9,
        "right turned by {}",
        poses[1].rotation.angle()
    );
    // The left spatula did not move while the right one was selected.
    assert!((poses[0].position - Vec3::new(mapping.max_speed_m_s, 0.0, 0.0)).norm() < 1e-12);
    // A pad unplugged mid-motion stops everything.
    pad.apply(PadEvent::Disconnected);
    let before = poses;
    run(&pad, 10, &mut poses, &mut guards);
    assert_eq!(poses, before, "no motion after unplug");
    assert_eq!(guards[0].rejected() + guards[1].rejected(), 0);
}

#[test]
fn keyboard_tab_and_translation() {
    let mut keys = KeyboardController::default();
    let mut pose = Pose::default();
    keys.apply(KeyEvent {
        key: Key::Tab,
        pressed: true,
    });
    assert_eq!(keys.command().spatula, 1, "Tab makes the second blade active");
    keys.apply(KeyEvent {
        key: Key::E,
        pressed: true,
    });
    for _ in 0..50 {
        pose = integrate(&pose, &keys.command().velocity, 0.02);
    }
    assert!(
        (pose.position.z - keys.mapping.speed_m_s).abs() < 1e-12,
        "E held 1 s lifts by the key speed: {:?}",
        pose.position
    );
}
