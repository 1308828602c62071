//! The One Euro filter on a blade's pose (Casiez, Roussel and Vogel, CHI
//! 2012): a low-pass whose cut-off rises with the blade's speed, so a tracker's
//! or a gamepad's jitter is smoothed while the blade stands or moves slowly,
//! and a deliberate fast move passes with little lag.
//!
//! In: the raw pose of each frame (or none, when the device sent nothing new)
//! and the frame's duration. Out: the pose the simulation plays. Position and
//! orientation share one smoothing factor, taken from the speed of the blade's
//! tip (the point a surgeon watches; rotation moves it too): position by
//! linear interpolation, orientation by slerp, each the same fraction of the
//! way from the last filtered pose to the raw one.
//! Stays true: a pure function of the raw poses and the frame durations (no
//! clock, no randomness), so a recorded raw track replays to the same bits;
//! a filter restarts from the pose the blade holds when frames are not
//! consecutive (a reset scene, a new run); a non-finite or non-unit raw pose
//! never reaches it (the pipeline refuses those first).

use crate::geometry::{Pose, SpatulaShape};
use crate::math::Vec3;
use crate::scenario::OneEuro;

/// One blade's filter state.
#[derive(Debug, Clone)]
pub struct PoseFilter {
    params: OneEuro,
    /// The blade tip in the spatula frame (the tip of the centre line).
    tip: Vec3,
    /// The last filtered pose, its tip speed estimate (m/s, filtered), the
    /// last raw pose, and the frame they belong to.
    last: Option<FilterState>,
}

#[derive(Debug, Clone, Copy)]
struct FilterState {
    filtered: Pose,
    speed: f64,
    raw: Pose,
    frame: u64,
}

/// The smoothing factor of a first-order low-pass with cut-off `cutoff_hz`
/// sampled every `dt` seconds.
fn alpha(cutoff_hz: f64, dt: f64) -> f64 {
    let tau = 1.0 / (2.0 * std::f64::consts::PI * cutoff_hz);
    1.0 / (1.0 + tau / dt)
}

impl PoseFilter {
    /// A filter for a blade of `shape`.
    pub fn new(params: OneEuro, shape: &SpatulaShape) -> Self {
        Self { params, tip: Vec3::new(shape.length, 0.0, 0.0), last: None }
    }

    /// The pose to play at `frame` (of duration `dt`, s): `raw` filtered, or
    /// the last raw pose filtered again when `raw` is `None` (the device sent
    /// nothing new this frame, so the blade keeps settling towards it).
    /// `holding` is the pose the blade holds now: where a filter (re)starts.
    pub fn apply(&mut self, frame: u64, dt: f64, raw: Option<Pose>, holding: &Pose) -> Pose {
        let state = match self.last {
            Some(s) if s.frame + 1 == frame => s,
            _ => FilterState { filtered: *holding, speed: 0.0, raw: *holding, frame: frame.wrapping_sub(1) },
        };
        let raw = raw.unwrap_or(state.raw);
        // The tip's speed towards the raw pose, smoothed with the derivative cut-off.
        let tip_travel = (raw.transform_point(&self.tip) - state.filtered.transform_point(&self.tip)).norm();
        let speed = state.speed + alpha(self.params.d_cutoff_hz, dt) * (tip_travel / dt - state.speed);
        let cutoff = self.params.min_cutoff_hz + self.params.beta_per_m * speed;
        let filtered = state.filtered.interpolate(&raw, alpha(cutoff, dt));
        self.last = Some(FilterState { filtered, speed, raw, frame });
        filtered
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Quat;

    fn params() -> OneEuro {
        OneEuro { min_cutoff_hz: 1.0, beta_per_m: 50.0, d_cutoff_hz: 1.0 }
    }

    fn shape() -> SpatulaShape {
        SpatulaShape { length: 0.06, width: 0.008, thickness: 0.0005 }
    }

    fn at(x_mm: f64) -> Pose {
        Pose { position: Vec3::new(x_mm * 1e-3, 0.0, 0.0), rotation: Quat::identity() }
    }

    /// Deterministic jitter in [-1, 1] (SplitMix64 of `k`).
    fn jitter(k: u64) -> f64 {
        let mut z = k.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        2.0 * ((z >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    }

    #[test]
    fn a_still_blade_with_jitter_is_steadied() {
        let mut f = PoseFilter::new(params(), &shape());
        let dt = 0.01;
        let (mut raw_step, mut filtered_step) = (0.0_f64, 0.0_f64);
        let mut previous = at(0.0);
        for k in 1..=500 {
            let raw = at(0.5 * jitter(k));
            let out = f.apply(k, dt, Some(raw), &at(0.0));
            if k > 100 {
                raw_step = raw_step.max((raw.position - at(0.5 * jitter(k - 1)).position).norm());
                filtered_step = filtered_step.max((out.position - previous.position).norm());
            }
            previous = out;
        }
        assert!(raw_step > 0.8e-3, "the jitter moves the raw pose up to 1 mm a frame ({raw_step})");
        assert!(filtered_step < 0.25 * raw_step, "the filtered pose moves under a quarter of that: {filtered_step} against {raw_step}");
    }

    #[test]
    fn a_fast_move_passes_with_little_lag_and_the_filter_settles_on_the_target() {
        let mut f = PoseFilter::new(params(), &shape());
        let dt = 0.01;
        // 100 mm/s for 0.3 s, then hold.
        let mut out = at(0.0);
        for k in 1..=30 {
            out = f.apply(k, dt, Some(at(k as f64)), &at(0.0));
        }
        let lag_mm = 30.0 - out.position.x * 1e3;
        assert!(lag_mm > 0.0 && lag_mm < 6.0, "at 100 mm/s the blade trails by {lag_mm} mm (a 1 Hz low-pass alone: 16 mm)");
        for k in 31..=400 {
            out = f.apply(k, dt, None, &out.clone());
        }
        assert!((out.position.x * 1e3 - 30.0).abs() < 1e-3, "with no new input it settles on the last raw pose: {}", out.position.x * 1e3);
    }

    #[test]
    fn the_same_raw_track_gives_the_same_bits_and_a_gap_restarts_the_filter() {
        let run = || {
            let mut f = PoseFilter::new(params(), &shape());
            (1..=200u64)
                .map(|k| {
                    let raw = Pose { position: Vec3::new(jitter(k), jitter(k + 7), k as f64) * 1e-3, rotation: Quat::from_euler_angles(0.01 * jitter(k + 3), 0.02, 0.0) };
                    let p = f.apply(k, 0.01, (k % 3 != 0).then_some(raw), &at(0.0));
                    [p.position.x.to_bits(), p.position.y.to_bits(), p.rotation.w.to_bits()]
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(run(), run());
        let mut f = PoseFilter::new(params(), &shape());
        f.apply(1, 0.01, Some(at(10.0)), &at(0.0));
        // Frame 5 does not follow frame 1: the filter starts again from the held pose.
        let restarted = f.apply(5, 0.01, Some(at(0.0)), &at(0.0));
        assert_eq!(restarted.position, at(0.0).position);
    }
}
