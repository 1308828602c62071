//! SpaceMouse input: a 3Dconnexion 6-DoF cap drives a blade by rate, as the
//! gamepad's sticks do.
//!
//! In: [`SpaceEvent`]s, from spacenavd's socket when the daemon runs, else
//! from the device's HID reports ([`decode`]; the reader thread in [`device`]
//! reopens either when it appears). Out: each frame a [`SpaceMouseCommand`]:
//! the velocity of the chosen blade in its own frame, which of the blades
//! bound to the SpaceMouse that is, and whether precision is on; and a status
//! line naming the device or saying why none is read. Stays true: the mapping
//! is a pure function of the cap's last deflection, the precision flag and
//! [`SpaceMouseMapping`]; a deflection inside the dead zone moves nothing; a
//! lost device counts as a released cap (the blade stops); no device (no
//! daemon, no HID device, no permission) is not an error, only a status line.
//!
//! ## Mapping (the cap is the blade: tip away from you, +z face up)
//! | the cap | the blade |
//! |---|---|
//! | pushed away from you | +x along the blade, towards its tip |
//! | pushed to the left | +y across the blade |
//! | lifted | +z, towards its +z face (opens the fissure with an upper blade) |
//! | tilted or twisted | turns the same way about the same axes: tilt away = pitch about y, tilt left = roll about x, twist = yaw about z |
//! | left button | the next blade bound to the SpaceMouse (cycles; one blade: nothing) |
//! | right button | precision on / off: speeds x 0.25 |
//!
//! Full deflection ([`decode::FULL_SCALE_COUNTS`] counts) gives
//! [`SpaceMouseMapping::max_speed_m_s`] or [`SpaceMouseMapping::max_rate_rad_s`];
//! the translation and the rotation each have a radial dead zone with
//! rescaling, so motion starts smoothly at its edge. The defaults are the
//! gamepad's ([`super::gamepad::GamepadMapping`]): the stick's dead zone, its
//! speeds, its precision factor.

pub mod decode;
pub mod device;

use super::PoseVelocity;
use crate::math::{Matrix3, Vec3};
pub use decode::{SpaceEvent, SpaceMotion};
pub use device::{Sources, Update};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::thread::JoinHandle;

/// Tuning of the mapping (the scenario's `spacemouse` section).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceMouseMapping {
    /// Radial dead zone of the translation and of the rotation, fraction of
    /// full deflection [0, 0.9]. Default 0.15 (the gamepad stick's).
    pub dead_zone: f64,
    /// Blade speed at full deflection, m/s (> 0). Default 0.02.
    pub max_speed_m_s: f64,
    /// Blade turn rate at full deflection, rad/s (> 0). Default 0.8.
    pub max_rate_rad_s: f64,
    /// Speed factor in precision mode, (0, 1]. Default 0.25.
    pub precision_factor: f64,
    /// Counts of a full deflection (> 0). Default 350.
    pub full_scale_counts: f64,
}

impl Default for SpaceMouseMapping {
    fn default() -> Self {
        let pad = super::gamepad::GamepadMapping::default();
        Self {
            dead_zone: f64::from(pad.stick_dead_zone),
            max_speed_m_s: pad.max_speed_m_s,
            max_rate_rad_s: pad.max_rate_rad_s,
            precision_factor: pad.precision_factor,
            full_scale_counts: decode::FULL_SCALE_COUNTS,
        }
    }
}

/// The device's axes (x right, y towards the user, z down) in the blade's
/// (x along it away from the user, y to the left, z up): a proper rotation,
/// so turns map as the pushes do.
fn device_to_blade() -> Matrix3<f64> {
    Matrix3::new(0.0, -1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0)
}

/// A radial dead zone with rescaling on a 3-vector of fractions of full
/// deflection: at most `dead` long gives zero, full length stays full, the
/// direction is kept; non-finite components read as zero.
pub fn radial_dead_zone(v: Vec3, dead: f64) -> Vec3 {
    let v = v.map(|c| if c.is_finite() { c.clamp(-1.0, 1.0) } else { 0.0 });
    let dead = if dead.is_finite() { dead.clamp(0.0, 0.9) } else { 0.0 };
    let r = v.norm();
    if r <= dead {
        return Vec3::zeros();
    }
    v * (((r.min(1.0) - dead) / (1.0 - dead)) / r)
}

/// The pure mapping: the cap's deflection and the precision flag to a blade
/// velocity in the blade's frame (see the module table).
pub fn map_motion(motion: &SpaceMotion, precision: bool, mapping: &SpaceMouseMapping) -> PoseVelocity {
    let scale = if mapping.full_scale_counts.is_finite() && mapping.full_scale_counts > 0.0 { mapping.full_scale_counts } else { decode::FULL_SCALE_COUNTS };
    let fraction = |a: [i32; 3]| Vec3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2])) / scale;
    let factor = if precision { mapping.precision_factor } else { 1.0 };
    let axes = device_to_blade();
    PoseVelocity {
        linear_m_s: axes * radial_dead_zone(fraction(motion.translation), mapping.dead_zone) * (mapping.max_speed_m_s * factor),
        angular_rad_s: axes * radial_dead_zone(fraction(motion.rotation), mapping.dead_zone) * (mapping.max_rate_rad_s * factor),
    }
}

/// What the SpaceMouse asks for this frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpaceMouseCommand {
    /// The velocity of the chosen blade, its own frame.
    pub velocity: PoseVelocity,
    /// Which of the blades bound to the SpaceMouse it drives (0-based, in the
    /// scenario's order).
    pub selected: usize,
    /// Precision mode on (for the panel).
    pub precision: bool,
}

/// The cap's state plus the buttons' choices.
#[derive(Debug, Clone, Default)]
pub struct SpaceMouseController {
    /// The cap's last deflection.
    pub motion: SpaceMotion,
    /// Precision mode on.
    pub precision: bool,
    /// Left-button presses so far (the blade is this modulo the bound blades).
    pub presses: usize,
    /// The mapping's tuning.
    pub mapping: SpaceMouseMapping,
}

impl SpaceMouseController {
    pub fn new(mapping: SpaceMouseMapping) -> Self {
        Self { mapping, ..Self::default() }
    }

    /// Applies one input.
    pub fn apply(&mut self, event: SpaceEvent) {
        match event {
            SpaceEvent::Motion(m) => self.motion = m,
            SpaceEvent::Button { index: 0, pressed: true } => self.presses = self.presses.wrapping_add(1),
            SpaceEvent::Button { index: 1, pressed: true } => self.precision = !self.precision,
            SpaceEvent::Button { .. } => {}
        }
    }

    /// The device went away: the cap counts as released.
    pub fn release(&mut self) {
        self.motion = SpaceMotion::default();
    }

    /// This frame's command, for `blades` blades bound to the SpaceMouse.
    pub fn command(&self, blades: usize) -> SpaceMouseCommand {
        SpaceMouseCommand {
            velocity: map_motion(&self.motion, self.precision, &self.mapping),
            selected: if blades == 0 { 0 } else { self.presses % blades },
            precision: self.precision,
        }
    }
}

/// The SpaceMouse: its reader thread and the controller its events drive.
pub struct SpaceMouseInput {
    updates: Option<Receiver<Update>>,
    /// The controller the events drive.
    pub controller: SpaceMouseController,
    status: String,
    status_changes: u64,
    device: Option<String>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SpaceMouseInput {
    /// Starts the reader thread on `sources` ([`Sources::system`] normally).
    pub fn start(mapping: SpaceMouseMapping, sources: Sources) -> Self {
        let (tx, rx) = std::sync::mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let thread = std::thread::Builder::new().name("spacemouse".into()).spawn(move || device::run(sources, tx, thread_stop));
        let (thread, updates, status) = match thread {
            Ok(t) => (Some(t), Some(rx), "SpaceMouse: looking for spacenavd or a 3Dconnexion HID device".to_string()),
            Err(e) => (None, None, format!("SpaceMouse: cannot start its reader thread: {e}")),
        };
        Self { updates, controller: SpaceMouseController::new(mapping), status, status_changes: 0, device: None, stop, thread }
    }

    /// Drains the reader's updates and returns this frame's command for
    /// `blades` blades bound to the SpaceMouse. Never blocks.
    pub fn poll(&mut self, blades: usize) -> SpaceMouseCommand {
        let before = self.status_changes;
        while let Some(rx) = &self.updates {
            match rx.try_recv() {
                Ok(Update::Event(e)) => self.controller.apply(e),
                Ok(Update::Connected(what)) => {
                    tracing::info!(device = %what, "SpaceMouse connected");
                    self.status = format!("SpaceMouse: {what}");
                    self.status_changes = before + 1;
                    self.device = Some(what);
                }
                Ok(Update::Lost(why)) => {
                    tracing::info!(%why, "SpaceMouse lost");
                    self.controller.release();
                    self.status = format!("SpaceMouse lost: {why}; looking for it again");
                    self.status_changes = before + 1;
                    self.device = None;
                }
                Ok(Update::Missing(what)) => {
                    self.controller.release();
                    self.status = what;
                    self.status_changes = before + 1;
                    self.device = None;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    self.controller.release();
                    self.status = "SpaceMouse: its reader thread ended".to_string();
                    self.status_changes = before + 1;
                    self.device = None;
                    self.updates = None;
                }
            }
        }
        self.controller.command(blades)
    }

    /// One line for the panel: the device read and how, or why none is.
    pub fn status(&self) -> &str {
        &self.status
    }

    /// How many polls changed the status line so far (read it each frame,
    /// [`SpaceMouseInput::status`] when it moved).
    pub fn status_changes(&self) -> u64 {
        self.status_changes
    }

    /// The device read now, if any (name and how it is read).
    pub fn device(&self) -> Option<&str> {
        self.device.as_deref()
    }
}

impl Drop for SpaceMouseInput {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn push(translation: [i32; 3], rotation: [i32; 3]) -> SpaceEvent {
        SpaceEvent::Motion(SpaceMotion { translation, rotation })
    }

    #[test]
    fn the_cap_moves_the_blade_as_the_table_says() {
        let m = SpaceMouseMapping::default();
        let mut c = SpaceMouseController::new(m);
        // Full push away from the user (HID -y) and a full lift (HID -z).
        c.apply(push([0, -350, -350], [0, 0, 0]));
        let v = c.command(1).velocity;
        let full = m.max_speed_m_s / 2f64.sqrt();
        assert!((v.linear_m_s - Vec3::new(full, 0.0, full)).norm() < 1e-12, "away = +x, lift = +z, radial full scale: {v:?}");
        assert_eq!(v.angular_rad_s, Vec3::zeros());
        // Push left (HID -x): +y.
        c.apply(push([-350, 0, 0], [0, 0, 0]));
        assert!((c.command(1).velocity.linear_m_s - Vec3::new(0.0, m.max_speed_m_s, 0.0)).norm() < 1e-12);
        // Twist counter-clockwise seen from above (about -z of the device, up): +yaw about the blade's z.
        c.apply(push([0, 0, 0], [0, 0, -350]));
        assert!((c.command(1).velocity.angular_rad_s - Vec3::new(0.0, 0.0, m.max_rate_rad_s)).norm() < 1e-12);
        // Inside the dead zone: nothing.
        c.apply(push([40, -20, 10], [30, 0, -10]));
        assert!(c.command(1).velocity.is_zero(), "{:?}", c.command(1).velocity);
    }

    #[test]
    fn spacenavd_and_hid_give_the_same_velocity() {
        let m = SpaceMouseMapping::default();
        let mut hid = decode::HidDecoder::default();
        let mut events = Vec::new();
        let mut from_hid = SpaceMouseController::new(m);
        for report in [[0x01u8, 0x78, 0x00, 0x38, 0xff, 0x23, 0x00], [0x02, 0xf6, 0xff, 0x3c, 0x00, 0xfa, 0x00]] {
            hid.report(&report, &mut events);
            events.drain(..).for_each(|e| from_hid.apply(e));
        }
        let mut spnav = [0u8; decode::SPNAV_EVENT_SIZE];
        for (k, v) in [0i32, 120, -35, 200, -10, -250, -60, 16].iter().enumerate() {
            spnav[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
        }
        let mut from_spnav = SpaceMouseController::new(m);
        from_spnav.apply(decode::decode_spnav(&spnav).expect("a motion"));
        let (a, b) = (from_hid.command(1).velocity, from_spnav.command(1).velocity);
        assert_eq!(a, b);
        assert!(a.linear_m_s.x > 0.0 && a.linear_m_s.y < 0.0, "away and to the right: +x, -y: {a:?}");
    }

    #[test]
    fn the_buttons_pick_the_blade_and_precision_and_a_loss_stops() {
        let m = SpaceMouseMapping::default();
        let mut c = SpaceMouseController::new(m);
        c.apply(push([350, 0, 0], [0, 0, 0]));
        let fast = c.command(2).velocity.linear_m_s.norm();
        c.apply(SpaceEvent::Button { index: 1, pressed: true });
        c.apply(SpaceEvent::Button { index: 1, pressed: false });
        let cmd = c.command(2);
        assert!(cmd.precision && (cmd.velocity.linear_m_s.norm() - fast * m.precision_factor).abs() < 1e-12, "right button: precision");
        assert_eq!(cmd.selected, 0);
        c.apply(SpaceEvent::Button { index: 0, pressed: true });
        assert_eq!(c.command(2).selected, 1, "left button: the next blade");
        c.apply(SpaceEvent::Button { index: 0, pressed: true });
        assert_eq!(c.command(2).selected, 0, "cycles");
        assert_eq!(c.command(1).selected, 0, "one blade: always it");
        c.release();
        assert!(c.command(2).velocity.is_zero(), "a lost device stops the blade");
    }

    #[test]
    fn the_dead_zone_is_radial_and_rescaled() {
        assert_eq!(radial_dead_zone(Vec3::new(0.1, 0.05, 0.0), 0.15), Vec3::zeros());
        let v = radial_dead_zone(Vec3::new(0.16, 0.0, 0.0), 0.15);
        assert!(v.x > 0.0 && v.x < 0.02, "starts smoothly: {v:?}");
        assert!((radial_dead_zone(Vec3::new(3.0, 0.0, 0.0), 0.15) - Vec3::x()).norm() < 1e-12, "clamped to full");
        assert_eq!(radial_dead_zone(Vec3::new(f64::NAN, 0.0, 0.0), 0.15), Vec3::zeros());
    }
}
