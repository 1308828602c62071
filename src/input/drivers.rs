//! Which device moves each blade in the window, when the keyboard's active
//! blade is also bound to a gamepad, a tracker or a recorded trajectory.
//!
//! In: a blade's binding ([`BindingKind`]), its current pose, and what each
//! device offers this frame ([`DeviceOffers`]). Out: the candidate pose and
//! the [`Driver`] that gave it. Stays true: the keyboard can move every blade
//! (it picks one with 1, 2, … or Tab); a pure function of its inputs and the
//! blade's take-over flag, so tests drive it without a window.
//!
//! Rules (docs/usage.md, "Who moves a blade"):
//! - `Keyboard`: the keys, while the blade is the active one.
//! - `Gamepad`: the pad (while LB / RB has it selected) and the keys (while it
//!   is the active one) both move it: their velocities add.
//! - `SpaceMouse`: likewise, the SpaceMouse (while its left button has it
//!   picked) and the keys.
//! - `OpenIgtLink`: the tracker wins as soon as it has sent a pose (an
//!   absolute pose would snap any keyboard move back); until then the keys move it.
//! - `Trajectory`: plays its track until a move key is held while it is the
//!   active blade; from then on the keys have it for the rest of the session.

use super::{PoseVelocity, integrate};
use crate::geometry::Pose;

/// A blade's binding in the scenario, as far as driving it goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindingKind {
    Keyboard,
    Gamepad,
    SpaceMouse,
    Tracker,
    Trajectory,
}

/// What moved a blade this frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Driver {
    /// Nothing moved it (not the active blade, no device).
    #[default]
    Held,
    /// The keyboard.
    Keys,
    /// The gamepad.
    Pad,
    /// The gamepad and the keyboard together (velocities added).
    KeysAndPad,
    /// The SpaceMouse.
    SpaceMouse,
    /// The SpaceMouse and the keyboard together (velocities added).
    KeysAndSpaceMouse,
    /// The tracker's latest pose.
    Tracker,
    /// The scenario's trajectory.
    Trajectory,
    /// The keyboard, which took the blade over from its trajectory.
    KeysTookOver,
}

/// What the devices offer one blade this frame.
#[derive(Debug, Clone, Copy, Default)]
pub struct DeviceOffers {
    /// The keys' velocity when this blade is the keyboard's active one.
    pub keys: Option<PoseVelocity>,
    /// True while a move key is held (with `keys`).
    pub keys_moving: bool,
    /// The pad's velocity when the pad selects this blade.
    pub pad: Option<PoseVelocity>,
    /// The SpaceMouse's velocity when it has picked this blade.
    pub spacemouse: Option<PoseVelocity>,
    /// The tracker's latest pose, once it has sent one.
    pub tracker: Option<Pose>,
    /// The trajectory's pose at this frame's time.
    pub trajectory: Option<Pose>,
}

fn add(a: &PoseVelocity, b: &PoseVelocity) -> PoseVelocity {
    PoseVelocity { linear_m_s: a.linear_m_s + b.linear_m_s, angular_rad_s: a.angular_rad_s + b.angular_rad_s }
}

/// The pose a blade takes this frame and what gave it; `taken_over` is the
/// blade's flag (set here when the keys take a trajectory blade over).
pub fn drive(binding: BindingKind, current: &Pose, offers: &DeviceOffers, taken_over: &mut bool, dt_s: f64) -> (Pose, Driver) {
    let keys = |driver| match &offers.keys {
        Some(v) => (integrate(current, v, dt_s), driver),
        None => (*current, Driver::Held),
    };
    match binding {
        BindingKind::Keyboard => keys(Driver::Keys),
        BindingKind::Gamepad => match (&offers.keys, &offers.pad) {
            (Some(k), Some(p)) => (integrate(current, &add(k, p), dt_s), Driver::KeysAndPad),
            (None, Some(p)) => (integrate(current, p, dt_s), Driver::Pad),
            _ => keys(Driver::Keys),
        },
        BindingKind::SpaceMouse => match (&offers.keys, &offers.spacemouse) {
            (Some(k), Some(m)) => (integrate(current, &add(k, m), dt_s), Driver::KeysAndSpaceMouse),
            (None, Some(m)) => (integrate(current, m, dt_s), Driver::SpaceMouse),
            _ => keys(Driver::Keys),
        },
        BindingKind::Tracker => match offers.tracker {
            Some(pose) => (pose, Driver::Tracker),
            None => keys(Driver::Keys),
        },
        BindingKind::Trajectory => {
            if !*taken_over && offers.keys.is_some() && offers.keys_moving {
                *taken_over = true;
            }
            if *taken_over {
                keys(Driver::KeysTookOver)
            } else {
                (offers.trajectory.unwrap_or(*current), Driver::Trajectory)
            }
        }
    }
}

impl Driver {
    /// A few words for the panel.
    pub fn label(self) -> &'static str {
        match self {
            Driver::Held => "held",
            Driver::Keys => "keys",
            Driver::Pad => "gamepad",
            Driver::KeysAndPad => "keys + gamepad",
            Driver::SpaceMouse => "SpaceMouse",
            Driver::KeysAndSpaceMouse => "keys + SpaceMouse",
            Driver::Tracker => "tracker (keys ignored)",
            Driver::Trajectory => "trajectory (a move key takes over)",
            Driver::KeysTookOver => "keys (took over the trajectory)",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn forward(speed: f64) -> PoseVelocity {
        PoseVelocity { linear_m_s: Vec3::new(speed, 0.0, 0.0), angular_rad_s: Vec3::zeros() }
    }

    #[test]
    fn every_binding_moves_under_the_keys_when_nothing_else_holds_it() {
        for binding in [BindingKind::Keyboard, BindingKind::Gamepad, BindingKind::SpaceMouse, BindingKind::Tracker, BindingKind::Trajectory] {
            let offers = DeviceOffers { keys: Some(forward(0.01)), keys_moving: true, ..DeviceOffers::default() };
            let mut taken = false;
            let (pose, driver) = drive(binding, &Pose::default(), &offers, &mut taken, 1.0);
            assert!((pose.position.x - 0.01).abs() < 1e-15, "{binding:?}: the keys must move the active blade, got {pose:?} by {driver:?}");
            assert_ne!(driver, Driver::Held, "{binding:?}");
        }
        let (pose, driver) = drive(BindingKind::Keyboard, &Pose::default(), &DeviceOffers::default(), &mut false, 1.0);
        assert_eq!((pose, driver), (Pose::default(), Driver::Held), "not the active blade: it holds");
    }

    #[test]
    fn pad_and_keys_add_and_a_live_tracker_wins() {
        let offers = DeviceOffers { keys: Some(forward(0.01)), keys_moving: true, pad: Some(forward(0.02)), ..DeviceOffers::default() };
        let (pose, driver) = drive(BindingKind::Gamepad, &Pose::default(), &offers, &mut false, 1.0);
        assert!((pose.position.x - 0.03).abs() < 1e-15 && driver == Driver::KeysAndPad, "{pose:?} {driver:?}");
        let tracked = Pose { position: Vec3::new(0.0, 0.5, 0.0), ..Pose::default() };
        let offers = DeviceOffers { tracker: Some(tracked), ..offers };
        let (pose, driver) = drive(BindingKind::Tracker, &Pose::default(), &offers, &mut false, 1.0);
        assert_eq!((pose, driver), (tracked, Driver::Tracker), "the tracker's absolute pose wins over the keys");
    }

    #[test]
    fn the_spacemouse_and_the_keys_add_and_only_its_picked_blade_moves() {
        let offers = DeviceOffers { keys: Some(forward(0.01)), keys_moving: true, spacemouse: Some(forward(0.03)), ..DeviceOffers::default() };
        let (pose, driver) = drive(BindingKind::SpaceMouse, &Pose::default(), &offers, &mut false, 1.0);
        assert!((pose.position.x - 0.04).abs() < 1e-15 && driver == Driver::KeysAndSpaceMouse, "{pose:?} {driver:?}");
        let alone = DeviceOffers { spacemouse: Some(forward(0.03)), ..DeviceOffers::default() };
        let (pose, driver) = drive(BindingKind::SpaceMouse, &Pose::default(), &alone, &mut false, 1.0);
        assert!((pose.position.x - 0.03).abs() < 1e-15 && driver == Driver::SpaceMouse, "{pose:?} {driver:?}");
        assert_eq!(driver.label(), "SpaceMouse", "the panel names the device");
        let not_picked = DeviceOffers { pad: Some(forward(0.5)), ..DeviceOffers::default() };
        assert_eq!(drive(BindingKind::SpaceMouse, &Pose::default(), &not_picked, &mut false, 1.0), (Pose::default(), Driver::Held), "a pad does not move a SpaceMouse blade");
    }

    #[test]
    fn keys_take_a_trajectory_blade_over_for_good_only_when_moving() {
        let track = Pose { position: Vec3::new(0.0, 0.0, 0.7), ..Pose::default() };
        let mut taken = false;
        let selected = DeviceOffers { keys: Some(PoseVelocity::default()), keys_moving: false, trajectory: Some(track), ..DeviceOffers::default() };
        assert_eq!(drive(BindingKind::Trajectory, &Pose::default(), &selected, &mut taken, 0.01), (track, Driver::Trajectory), "selecting alone must not take over");
        assert!(!taken);
        let moving = DeviceOffers { keys: Some(forward(1.0)), keys_moving: true, ..selected };
        let (pose, driver) = drive(BindingKind::Trajectory, &Pose::default(), &moving, &mut taken, 0.01);
        assert!(taken && driver == Driver::KeysTookOver && (pose.position.x - 0.01).abs() < 1e-15, "{pose:?} {driver:?}");
        let released = DeviceOffers { keys: None, ..selected };
        let (pose, driver) = drive(BindingKind::Trajectory, &Pose::default(), &released, &mut taken, 0.01);
        assert_eq!((pose, driver), (Pose::default(), Driver::Held), "once taken over, the track never pulls it back");
    }
}
