//! Inputs that move the two spatulas: gamepad (gilrs), keyboard + mouse, a
//! SpaceMouse (spacenavd or its HID device), and OpenIGTLink 6-DoF TRANSFORM
//! messages from a tracker or haptic bridge, served or read from a remote
//! server (a PlusServer with a haptic stylus, whose force goes back in PLUS's form).
//!
//! In: device events (synthetic structs in tests, gilrs / winit / TCP at the
//! edge). Out: either a [`PoseVelocity`] in the spatula's own frame that the
//! caller integrates with [`integrate`], or an absolute [`Pose`] per device name
//! from a [`PoseSource`]. Stays true: every pose that leaves this module through
//! a [`PoseGuard`] is finite with a unit quaternion; a rejected pose leaves the
//! last good one in place and logs a warning once per guard. A tracker's poses
//! are also held to a workspace and a speed limit ([`tracker`]) before the
//! OpenIGTLink server publishes them; a stylus's poses first map to its blade
//! by scale, frame and clutch ([`workspace`]).
//!
//! The mappings from device state to motion are pure functions so tests drive
//! them with synthetic events; only the thin adapters touch gilrs, winit and
//! sockets.

pub mod bindings;
pub mod drivers;
pub mod force_transform;
pub mod gamepad;
pub mod igtl;
pub mod igtl_codec;
pub mod igtl_link;
mod igtl_stream;
pub mod keyboard;
pub mod rumble;
pub mod spacemouse;
pub mod tracker;
pub mod workspace;

use crate::geometry::Pose;
use crate::math::{Quat, Vec3, is_finite3};

/// Which of the two spatulas an input drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub enum SpatulaSlot {
    /// The first spatula of the scene (index 0).
    #[default]
    Left,
    /// The second spatula of the scene (index 1).
    Right,
}

impl SpatulaSlot {
    /// Index into the scene's spatula list (0 or 1).
    pub fn index(self) -> usize {
        match self {
            SpatulaSlot::Left => 0,
            SpatulaSlot::Right => 1,
        }
    }

    /// The other spatula.
    pub fn other(self) -> Self {
        match self {
            SpatulaSlot::Left => SpatulaSlot::Right,
            SpatulaSlot::Right => SpatulaSlot::Left,
        }
    }
}

/// A rigid-body velocity expressed in the spatula's own frame (x along the
/// blade towards the tip, y across it, z through its thickness).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseVelocity {
    /// Linear velocity, m/s, spatula frame.
    pub linear_m_s: Vec3,
    /// Angular velocity, rad/s, about the spatula frame's axes.
    pub angular_rad_s: Vec3,
}

impl PoseVelocity {
    /// True when both parts are exactly zero.
    pub fn is_zero(&self) -> bool {
        self.linear_m_s == Vec3::zeros() && self.angular_rad_s == Vec3::zeros()
    }
}

/// Advances `pose` by `velocity` (spatula frame) for `dt_s` seconds:
/// `p += R v dt`, `R := R exp(omega dt)`. A non-finite velocity or step leaves
/// the pose unchanged (the caller's [`PoseGuard`] would reject the result anyway).
pub fn integrate(pose: &Pose, velocity: &PoseVelocity, dt_s: f64) -> Pose {
    if !dt_s.is_finite()
        || !is_finite3(&velocity.linear_m_s)
        || !is_finite3(&velocity.angular_rad_s)
    {
        return *pose;
    }
    let position = pose.position + pose.rotation * (velocity.linear_m_s * dt_s);
    let step = Quat::from_scaled_axis(velocity.angular_rad_s * dt_s);
    let rotation = Quat::new_normalize((pose.rotation * step).into_inner());
    Pose { position, rotation }
}

/// The latest absolute pose of a named device, with when it was produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedPose {
    /// The pose, metres and a unit quaternion.
    pub pose: Pose,
    /// The sender's timestamp, seconds since the Unix epoch (OpenIGTLink header).
    pub timestamp_s: f64,
    /// How many good poses this device has delivered so far (1 for the first);
    /// a changed value tells the poller the pose is new.
    pub sequence: u64,
}

/// Something the simulation polls for absolute spatula poses, by device name.
pub trait PoseSource {
    /// The last good pose received for `device`, or `None` if none arrived yet.
    fn latest(&self, device: &str) -> Option<TimedPose>;
}

/// Holds the last good pose of one spatula and rejects bad candidates.
///
/// Any candidate with a non-finite position or a non-unit quaternion is
/// refused; the last good pose holds and a warning is logged once (later
/// refusals are counted in [`PoseGuard::rejected`]).
#[derive(Debug, Clone)]
pub struct PoseGuard {
    last_good: Pose,
    rejected: u64,
    warned: bool,
    shown: bool,
    label: &'static str,
}

impl PoseGuard {
    /// A guard starting from `initial` (which must be valid; an invalid one is
    /// replaced by the identity pose). `label` names the input in the log.
    pub fn new(initial: Pose, label: &'static str) -> Self {
        let last_good = if initial.is_valid() {
            initial
        } else {
            Pose::default()
        };
        Self {
            last_good,
            rejected: 0,
            warned: false,
            shown: false,
            label,
        }
    }

    /// Offers a candidate; returns the pose now held (the candidate if valid).
    pub fn offer(&mut self, candidate: Pose) -> Pose {
        if candidate.is_valid() {
            self.last_good = candidate;
        } else {
            self.rejected += 1;
            if !self.warned {
                self.warned = true;
                tracing::warn!(
                    input = self.label,
                    "rejected a pose with a non-finite value or a non-unit quaternion; the last good pose holds (further rejections are counted, not logged)"
                );
            }
        }
        self.last_good
    }

    /// The pose held now.
    pub fn pose(&self) -> Pose {
        self.last_good
    }

    /// How many candidates were refused.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    /// The message a window shows once, right after the first refusal
    /// (`Some` exactly once per guard; later refusals are only counted).
    pub fn take_warning(&mut self) -> Option<String> {
        if self.rejected == 0 || self.shown {
            return None;
        }
        self.shown = true;
        Some(format!(
            "{}: refused a pose with a non-finite value or a non-unit quaternion; the last good pose holds",
            self.label
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrate_moves_along_the_spatula_frame() {
        // Spatula rotated 90 degrees about world z: its x axis is world +y.
        let pose = Pose {
            position: Vec3::new(1.0, 0.0, 0.0),
            rotation: Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2),
        };
        let v = PoseVelocity {
            linear_m_s: Vec3::new(0.01, 0.0, 0.0),
            angular_rad_s: Vec3::zeros(),
        };
        let next = integrate(&pose, &v, 2.0);
        assert!(
            (next.position - Vec3::new(1.0, 0.02, 0.0)).norm() < 1e-12,
            "moved to {:?}",
            next.position
        );
        let w = PoseVelocity {
            linear_m_s: Vec3::zeros(),
            angular_rad_s: Vec3::new(0.0, 0.0, 0.5),
        };
        let turned = integrate(&Pose::default(), &w, 1.0);
        assert!(
            (turned.rotation.angle() - 0.5).abs() < 1e-12,
            "turned by {}",
            turned.rotation.angle()
        );
        assert!(turned.is_valid());
    }

    #[test]
    fn integrate_ignores_non_finite_velocity() {
        let pose = Pose::default();
        let v = PoseVelocity {
            linear_m_s: Vec3::new(f64::NAN, 0.0, 0.0),
            angular_rad_s: Vec3::zeros(),
        };
        assert_eq!(
            integrate(&pose, &v, 0.01),
            pose,
            "a NaN velocity must not move the pose"
        );
        assert_eq!(
            integrate(&pose, &PoseVelocity::default(), f64::INFINITY),
            pose
        );
    }

    #[test]
    fn guard_keeps_last_good_pose() {
        let good = Pose {
            position: Vec3::new(0.1, 0.2, 0.3),
            rotation: Quat::identity(),
        };
        let mut guard = PoseGuard::new(Pose::default(), "test");
        assert_eq!(guard.offer(good), good);
        let mut bad = good;
        bad.position.x = f64::NAN;
        assert_eq!(guard.offer(bad), good, "a NaN position must be refused");
        let mut not_unit = good;
        not_unit.rotation = Quat::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0));
        assert_eq!(
            guard.offer(not_unit),
            good,
            "a non-unit quaternion must be refused"
        );
        assert_eq!(guard.rejected(), 2);
        assert_eq!(guard.pose(), good);
    }

    #[test]
    fn guard_warning_is_shown_once_after_the_first_refusal() {
        let mut guard = PoseGuard::new(Pose::default(), "window");
        assert_eq!(guard.take_warning(), None, "nothing refused yet");
        guard.offer(Pose::default());
        assert_eq!(guard.take_warning(), None, "a good pose is no reason to warn");
        let mut bad = Pose::default();
        bad.position.y = f64::INFINITY;
        guard.offer(bad);
        let shown = guard.take_warning().expect("the first refusal is shown");
        assert!(shown.starts_with("window: refused a pose"), "{shown}");
        guard.offer(bad);
        assert_eq!(guard.take_warning(), None, "later refusals are only counted");
        assert_eq!(guard.rejected(), 2);
    }
}
