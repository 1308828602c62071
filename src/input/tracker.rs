//! Plausibility of a tracker's absolute poses: a workspace box and a speed
//! limit, checked before a pose is published.
//!
//! In: each decoded pose of one device with its sender timestamp and its
//! arrival time. Out: accept or a [`Refused`] reason; counts per reason; a
//! warning line through `tracing` for the first refusal and then at most one a
//! second with the count since the last line ([`RateLimitedWarning`]).
//! Stays true: an accepted pose lies in the workspace and is reachable from the
//! previous accepted pose at no more than the speed limit; a refused pose
//! changes nothing but the counts (the last good pose holds).
//!
//! Why these checks: a NaN is caught by the decoder, but a finite pose 1e30 mm
//! away (a unit or registration error, a corrupt sender) would move a spatula
//! out of the scene or, one frame later, through the whole brain. The
//! defaults are far beyond what a hand does: the head lies within some 0.15 m
//! of the scene origin, so ±1 m on each axis leaves a tracker's whole field of
//! view; a hand holding an instrument moves at well under 1 m/s (fast reaching
//! peaks near 2 m/s), so 3 m/s only refuses jumps (a marker swap, a reflection
//! taken for a marker, a stream from another registration).
//!
//! The speed uses the sender's timestamps (the moments the tracker sampled), so
//! two poses that arrive together after a network stall are not taken for a
//! jump; when the sender does not stamp (0) or its clock goes back, the arrival
//! times are used. Neither clock is exact (many senders stamp when they send,
//! not when the tracker sampled, and send back to back), so an interval counts
//! as at least [`MIN_INTERVAL_S`] (one sample of a 100 Hz tracker): a move of
//! up to 30 mm at the default limit is never judged by its speed, a jump
//! beyond that is. The reference is the last *accepted* pose: after a genuine
//! relocation (a re-registered tool) poses are refused only until the time
//! since that pose makes the distance plausible (at 3 m/s, 0.1 s for 0.3 m).

use crate::geometry::Pose;
use std::time::Instant;

/// The shortest interval the speed check assumes between two poses, s: one
/// sample of a 100 Hz tracker (see the module doc).
pub const MIN_INTERVAL_S: f64 = 0.01;

/// Bounds on a tracker's poses (one device).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerLimits {
    /// Half-width of the workspace box around the scene origin, on each axis,
    /// m; finite, > 0. Default 1 m (scenario: `workspace_mm: 1000.0`).
    pub workspace_m: f64,
    /// Fastest credible motion between two accepted poses, m/s; finite, > 0.
    /// Default 3 m/s (scenario: `max_speed_mm_s: 3000.0`).
    pub max_speed_m_s: f64,
}

impl TrackerLimits {
    /// Default workspace half-width, m.
    pub const DEFAULT_WORKSPACE_M: f64 = 1.0;
    /// Default speed limit, m/s.
    pub const DEFAULT_MAX_SPEED_M_S: f64 = 3.0;
}

impl Default for TrackerLimits {
    fn default() -> Self {
        Self { workspace_m: Self::DEFAULT_WORKSPACE_M, max_speed_m_s: Self::DEFAULT_MAX_SPEED_M_S }
    }
}

/// Why a pose was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refused {
    /// Outside the workspace box; `position_mm` is where it claimed to be.
    OutsideWorkspace { position_mm: [f64; 3], workspace_mm: f64 },
    /// Further from the last accepted pose than the speed limit allows.
    TooFast { speed_m_s: f64, max_speed_m_s: f64, distance_mm: f64, interval_s: f64 },
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::OutsideWorkspace { position_mm: [x, y, z], workspace_mm } => {
                let (x, y, z) = (mm(*x), mm(*y), mm(*z));
                write!(f, "position ({x}, {y}, {z}) mm is outside the workspace (±{workspace_mm} mm on each axis around the scene origin)")
            }
            Refused::TooFast { speed_m_s, max_speed_m_s, distance_mm, interval_s } => write!(
                f,
                "a move of {distance_mm:.1} mm in {:.1} ms ({speed_m_s:.3} m/s) is faster than the {max_speed_m_s} m/s limit",
                interval_s * 1e3
            ),
        }
    }
}

/// A coordinate in mm for a message: `1500.0`, or `1.000e30` when huge.
fn mm(v: f64) -> String {
    if v.abs() < 1e7 { format!("{v:.1}") } else { format!("{v:.3e}") }
}

/// The last accepted pose of one device and its times.
#[derive(Debug, Clone, Copy)]
struct Accepted {
    pose: Pose,
    timestamp_s: f64,
    arrived: Instant,
}

/// Checks one device's poses against its [`TrackerLimits`].
#[derive(Debug, Clone)]
pub struct TrackerGuard {
    limits: TrackerLimits,
    last: Option<Accepted>,
    outside_workspace: u64,
    too_fast: u64,
}

impl TrackerGuard {
    pub fn new(limits: TrackerLimits) -> Self {
        Self { limits, last: None, outside_workspace: 0, too_fast: 0 }
    }

    /// Checks `pose` (sender time `timestamp_s`, arrived at `arrived`);
    /// remembers it when accepted, counts it when refused.
    pub fn check(&mut self, pose: &Pose, timestamp_s: f64, arrived: Instant) -> Result<(), Refused> {
        let verdict = self.verdict(pose, timestamp_s, arrived);
        match verdict {
            Ok(()) => self.last = Some(Accepted { pose: *pose, timestamp_s, arrived }),
            Err(Refused::OutsideWorkspace { .. }) => self.outside_workspace += 1,
            Err(Refused::TooFast { .. }) => self.too_fast += 1,
        }
        verdict
    }

    fn verdict(&self, pose: &Pose, timestamp_s: f64, arrived: Instant) -> Result<(), Refused> {
        let p = pose.position;
        // `!(a <= b)` so a NaN is refused too (the decoder already refuses them).
        if !(p.amax() <= self.limits.workspace_m) {
            return Err(Refused::OutsideWorkspace { position_mm: [p.x * 1e3, p.y * 1e3, p.z * 1e3], workspace_mm: self.limits.workspace_m * 1e3 });
        }
        let Some(last) = &self.last else { return Ok(()) };
        let distance_m = (p - last.pose.position).norm();
        if distance_m == 0.0 {
            return Ok(());
        }
        let stamped = last.timestamp_s > 0.0 && timestamp_s > last.timestamp_s;
        let interval_s = if stamped { timestamp_s - last.timestamp_s } else { arrived.saturating_duration_since(last.arrived).as_secs_f64() };
        if distance_m <= self.limits.max_speed_m_s * interval_s.max(MIN_INTERVAL_S) {
            return Ok(());
        }
        Err(Refused::TooFast {
            speed_m_s: if interval_s > 0.0 { distance_m / interval_s } else { f64::INFINITY },
            max_speed_m_s: self.limits.max_speed_m_s,
            distance_mm: distance_m * 1e3,
            interval_s,
        })
    }

    /// Poses refused for lying outside the workspace.
    pub fn outside_workspace(&self) -> u64 {
        self.outside_workspace
    }

    /// Poses refused for moving faster than the limit.
    pub fn too_fast(&self) -> u64 {
        self.too_fast
    }

    /// The limits in force.
    pub fn limits(&self) -> TrackerLimits {
        self.limits
    }
}

/// Decides when a repeated warning gets a log line: the first time, then at
/// most once per `interval`, carrying how many occurrences the line stands for.
#[derive(Debug, Clone)]
pub struct RateLimitedWarning {
    interval: std::time::Duration,
    last_line: Option<Instant>,
    /// Occurrences since the last line (the current one included once counted).
    pending: u64,
}

impl RateLimitedWarning {
    pub fn new(interval: std::time::Duration) -> Self {
        Self { interval, last_line: None, pending: 0 }
    }

    /// Counts one occurrence at `now`; `Some(n)` when a line is due now, for
    /// the `n` occurrences since the previous line (1 for the very first).
    pub fn occur(&mut self, now: Instant) -> Option<u64> {
        self.pending += 1;
        let due = self.last_line.is_none_or(|t| now.saturating_duration_since(t) >= self.interval);
        if !due {
            return None;
        }
        self.last_line = Some(now);
        Some(std::mem::take(&mut self.pending))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Quat, Vec3};
    use std::time::Duration;

    fn at(x_mm: f64) -> Pose {
        Pose { position: Vec3::new(x_mm * 1e-3, 0.0, 0.0), rotation: Quat::identity() }
    }

    #[test]
    fn workspace_and_speed_refuse_and_count() {
        let t0 = Instant::now();
        let mut g = TrackerGuard::new(TrackerLimits::default());
        assert_eq!(g.check(&at(900.0), 0.0, t0), Ok(()), "inside the 1 m box: the first pose is taken");
        assert!(matches!(g.check(&at(1e30), 0.0, t0), Err(Refused::OutsideWorkspace { .. })));
        assert!(matches!(g.check(&at(-1500.0), 0.0, t0), Err(Refused::OutsideWorkspace { .. })));
        // 100 mm in 10 ms of arrival time (no sender stamps): 10 m/s.
        let r = g.check(&at(800.0), 0.0, t0 + Duration::from_millis(10));
        assert!(matches!(r, Err(Refused::TooFast { .. })), "{r:?}");
        // The same place 50 ms after the last accepted pose: 2 m/s, taken.
        assert_eq!(g.check(&at(800.0), 0.0, t0 + Duration::from_millis(50)), Ok(()));
        assert_eq!((g.outside_workspace(), g.too_fast()), (2, 1));
    }

    #[test]
    fn sender_timestamps_win_over_arrival_times() {
        let t0 = Instant::now();
        let mut g = TrackerGuard::new(TrackerLimits::default());
        g.check(&at(0.0), 100.0, t0).unwrap();
        // Arrives together with the first (a stall), but sampled 40 ms later: 1 m/s.
        assert_eq!(g.check(&at(40.0), 100.04, t0), Ok(()), "stamped 40 ms apart: 1 m/s");
        // Stamped 20 ms apart though it arrives a second later: 50 mm is 2.5 m/s, 100 mm is 5 m/s.
        assert!(g.check(&at(140.0), 100.06, t0 + Duration::from_secs(1)).is_err());
        assert_eq!(g.check(&at(90.0), 100.06, t0 + Duration::from_secs(1)), Ok(()));
        // A clock going back falls back to arrival time (1 s later: slow).
        assert_eq!(g.check(&at(190.0), 50.0, t0 + Duration::from_secs(2)), Ok(()));
    }

    #[test]
    fn moves_within_one_short_interval_are_not_judged_by_speed() {
        // Senders that stamp at send time and send back to back: 5 mm "in 0 s" is not a jump.
        let t0 = Instant::now();
        let mut g = TrackerGuard::new(TrackerLimits::default());
        g.check(&at(0.0), 7.0, t0).unwrap();
        assert_eq!(g.check(&at(5.0), 7.0, t0), Ok(()), "5 mm, same stamp and arrival");
        assert_eq!(g.check(&at(34.0), 7.0, t0), Ok(()), "29 mm: under 3 m/s over the 10 ms floor");
        assert!(g.check(&at(66.0), 7.0, t0).is_err(), "32 mm at once is a jump");
    }

    #[test]
    fn rate_limited_warning_says_how_many() {
        let t0 = Instant::now();
        let mut w = RateLimitedWarning::new(Duration::from_secs(1));
        assert_eq!(w.occur(t0), Some(1), "the first is logged at once");
        for k in 1..=9 {
            assert_eq!(w.occur(t0 + Duration::from_millis(100 * k)), None);
        }
        assert_eq!(w.occur(t0 + Duration::from_millis(1000)), Some(10), "one line for the 10 since");
        assert_eq!(w.occur(t0 + Duration::from_millis(1500)), None);
    }
}
