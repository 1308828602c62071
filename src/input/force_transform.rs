//! The force on a blade in the form PLUS's OpenHaptics device takes it: a
//! TRANSFORM whose translation is the force, in newtons, in the device's frame.
//!
//! In: the force on a blade (newtons, scene axes) at the haptic loop's ticks,
//! each with its timestamp (seconds), and whether the blade's stylus is
//! clutched. Out: at most one [`DeviceForce`] per device loop period: the
//! force in the device's frame, scaled, and clamped to the device's maximum.
//! Stays true: no output is longer than `max_force_n`; two outputs are at
//! least one period (`1 / rate_hz`) apart on the caller's clock, and a tick
//! that comes a period or more after the last output sends (so ticks at a
//! multiple of the rate send at exactly the rate); a clamp is logged
//! the first time and then at most once a second with the count
//! ([`RateLimitedWarning`], as the tracker's refusals are); a non-finite force
//! sends zero.
//!
//! Why this form: PLUS's OpenHaptics device renders the translation of the
//! latest item of a tool whose port name is `Force`, on its first input
//! channel, multiplied by the same RAS correction as its stylus pose, so the
//! force is given in the frame the stylus pose arrives in (PlusLib
//! `src/PlusDataCollection/OpenHaptics/vtkPlusOpenHapticsDevice.cxx`,
//! `positionCallback`; the device's documentation, `DeviceOpenHaptics.dox`,
//! says the force vector goes in the translation, RAS coordinates). That
//! channel is fed by a PLUS `OpenIGTLinkTracker` device, an OpenIGTLink
//! *client* that connects to fissure's server and turns the TRANSFORMs named
//! `<Id>To<ToolReferenceFrame>` into its tools (PlusLibData
//! `ConfigFiles/PlusDeviceSet_Server_OpenHaptics_WithForces.xml`). The device
//! reads it at its acquisition rate, hence the rate limit: sending faster
//! only queues messages it reads late. A Geomagic Touch exerts at most 3.3 N
//! (0.88 N continuously; 3D Systems, Touch specifications,
//! <https://www.3dsystems.com/haptics-devices/touch/specifications>), hence the
//! default clamp; a stylus whose force limit is not the simulation's range
//! gets a `scale` below 1.
//!
//! While the stylus is clutched the blade stands still and the hand moves
//! freely, so the force sent is zero (the blade's force would push the hand
//! for no motion of its own).

use super::tracker::RateLimitedWarning;
use crate::math::{Matrix3, Vec3};
use std::time::{Duration, Instant};

/// Default maximum force, N: the Geomagic Touch's peak (see the module doc).
pub const DEFAULT_MAX_FORCE_N: f64 = 3.3;
/// Default rate, Hz: the acquisition rate of the shipped PLUS configuration's
/// force channel (`assets/devices/PlusDeviceSet_fissure_Touch.xml`).
pub const DEFAULT_RATE_HZ: f64 = 100.0;

/// One force output in PLUS's form.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceTransformConfig {
    /// The blade (the scenario's spatula name) whose force this sends.
    pub spatula: String,
    /// The TRANSFORM's device name: PLUS's `<Id>To<ToolReferenceFrame>` of the
    /// force tool, e.g. `ForceToBase` (at most 20 bytes).
    pub name: String,
    /// Scene axes to device axes: `f_device = scale * rotation * f_scene`.
    pub rotation: Matrix3<f64>,
    /// Device newtons per simulated newton (> 0, finite).
    pub scale: f64,
    /// The largest force sent, N (> 0, finite).
    pub max_force_n: f64,
    /// The device's loop rate, Hz (> 0, finite): at most this many messages a second.
    pub rate_hz: f64,
    /// The OpenIGTLink device whose clutch zeroes the force while held (the
    /// stylus's pose device), if any.
    pub clutch_device: Option<String>,
}

/// What to send this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceForce {
    /// The force in the device's frame, N (at most `max_force_n` long).
    pub force_n: Vec3,
    /// Whether the scaled force was longer than `max_force_n` and was cut to it.
    pub clamped: bool,
    /// The scaled force's length before the clamp, N.
    pub requested_n: f64,
}

/// The state of one output: its schedule and its clamp counter.
#[derive(Debug, Clone)]
pub struct ForceTransformOutput {
    config: ForceTransformConfig,
    last_sent_s: Option<f64>,
    sent: u64,
    clamped: u64,
    warning: RateLimitedWarning,
}

impl ForceTransformOutput {
    pub fn new(config: ForceTransformConfig) -> Self {
        Self { config, last_sent_s: None, sent: 0, clamped: 0, warning: RateLimitedWarning::new(Duration::from_secs(1)) }
    }

    /// The configuration.
    pub fn config(&self) -> &ForceTransformConfig {
        &self.config
    }

    /// The force to send at `t_s` for `force_scene_n` on the blade, or `None`
    /// when the last message is less than a period old. `clutched`: the
    /// stylus's clutch is held (zero force). `now` dates the clamp warning.
    pub fn tick(&mut self, t_s: f64, force_scene_n: Vec3, clutched: bool, now: Instant) -> Option<DeviceForce> {
        if !t_s.is_finite() {
            return None;
        }
        let period = 1.0 / self.config.rate_hz;
        // Rounding of the caller's clock must not skip a tick that is due
        // (ticks at 1 ms, a 10 ms period: every tenth tick sends).
        let slack = period * 1e-6;
        if let Some(last) = self.last_sent_s
            && t_s - last + slack < period
            && t_s >= last
        {
            return None;
        }
        self.last_sent_s = Some(t_s);
        let finite = force_scene_n.iter().all(|c| c.is_finite());
        let device = if clutched || !finite { Vec3::zeros() } else { self.config.rotation * force_scene_n * self.config.scale };
        let requested_n = device.norm();
        let clamped = requested_n > self.config.max_force_n;
        let force_n = if clamped { device * (self.config.max_force_n / requested_n) } else { device };
        self.sent += 1;
        if clamped {
            self.clamped += 1;
            match self.warning.occur(now) {
                Some(1) => tracing::warn!(
                    spatula = %self.config.spatula, transform = %self.config.name,
                    "force {requested_n:.2} N clamped to the device's {} N (further clamps are counted, logged at most once a second)",
                    self.config.max_force_n
                ),
                Some(n) => tracing::warn!(
                    spatula = %self.config.spatula, transform = %self.config.name,
                    "{n} forces clamped to the device's {} N in the last second or more (latest {requested_n:.2} N)",
                    self.config.max_force_n
                ),
                None => {}
            }
        }
        Some(DeviceForce { force_n, clamped, requested_n })
    }

    /// Messages this output has produced.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Of those, how many were clamped.
    pub fn clamped(&self) -> u64 {
        self.clamped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(rate_hz: f64) -> ForceTransformConfig {
        ForceTransformConfig {
            spatula: "frontal".into(),
            name: "ForceToBase".into(),
            rotation: Matrix3::identity(),
            scale: 1.0,
            max_force_n: DEFAULT_MAX_FORCE_N,
            rate_hz,
            clutch_device: None,
        }
    }

    #[test]
    fn a_1_khz_loop_sends_at_the_device_rate() {
        let mut out = ForceTransformOutput::new(config(100.0));
        let now = Instant::now();
        let mut times = Vec::new();
        for tick in 0..=1000 {
            let t = 5000.0 + tick as f64 * 1e-3;
            if out.tick(t, Vec3::new(0.1, 0.0, 0.0), false, now).is_some() {
                times.push(t);
            }
        }
        assert_eq!(times.len(), 101, "one second at 1 kHz, sent at 100 Hz (both ends included)");
        for w in times.windows(2) {
            assert!((w[1] - w[0] - 0.01).abs() < 1e-6, "evenly 10 ms apart: {w:?}");
        }
        // Jittered ticks (0.9 to 1.3 ms): never two within a period, and each
        // message goes at the first tick of its period (at most one tick late).
        let mut out = ForceTransformOutput::new(config(100.0));
        let (mut t, mut sent) = (0.0, Vec::<f64>::new());
        for k in 0..3000 {
            t += 1e-3 * (0.9 + 0.4 * ((k * 7919) % 11) as f64 / 10.0);
            if out.tick(t, Vec3::zeros(), false, now).is_some() {
                if let Some(last) = sent.last() {
                    assert!(t - last >= 0.01 - 1e-9, "two messages {} ms apart", (t - last) * 1e3);
                    assert!(t - last < 0.01 + 1.3e-3, "a message skipped its tick: {} ms", (t - last) * 1e3);
                }
                sent.push(t);
            }
        }
        let rate = (sent.len() - 1) as f64 / (sent[sent.len() - 1] - sent[0]);
        assert!((88.0..=100.0).contains(&rate), "average rate {rate} Hz");
    }

    #[test]
    fn frame_scale_and_clamp() {
        // Scene x is device y: a quarter turn about z.
        let quarter = *nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2).matrix();
        let mut out = ForceTransformOutput::new(ForceTransformConfig { rotation: quarter, scale: 0.5, max_force_n: 1.0, ..config(100.0) });
        let now = Instant::now();
        let f = out.tick(0.0, Vec3::new(1.2, 0.0, 0.0), false, now).expect("the first tick sends");
        assert!((f.force_n - Vec3::new(0.0, 0.6, 0.0)).norm() < 1e-12 && !f.clamped, "{f:?}");
        let f = out.tick(0.01, Vec3::new(0.0, 0.0, -4.0), false, now).expect("a period later");
        assert!(f.clamped && (f.requested_n - 2.0).abs() < 1e-12, "{f:?}");
        assert!((f.force_n - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-12, "cut to 1 N along the same direction: {f:?}");
        let f = out.tick(0.02, Vec3::new(f64::NAN, 0.0, 0.0), false, now).expect("sent");
        assert_eq!(f.force_n, Vec3::zeros(), "a NaN force sends zero");
        let f = out.tick(0.03, Vec3::new(1.0, 1.0, 1.0), true, now).expect("sent");
        assert_eq!(f.force_n, Vec3::zeros(), "clutched: the hand moves freely");
        assert_eq!((out.sent(), out.clamped()), (4, 1));
    }
}
