//! The poses a run plays from a trajectory: the scenario's own, or one given
//! in its place (`--trajectory`, a window recording), else each spatula's
//! initial pose held.
//!
//! In: a validated [`Scenario`] and optionally the trajectory file that
//! replaces its own. Out: a [`TrajectoryPoses`] that gives every spatula's
//! pose at a replay time, the cuts the trajectory's rows make in a frame, and
//! pose sets sampled over the run (they size the automatic region of interest
//! and refinement). Stays true: the trajectory has no track for a spatula the
//! scene lacks (else loading it is refused, naming the file); a spatula
//! without a track holds its initial pose; replay time 0 is the trajectory's
//! first row when that row's time is negative (a recording's lead-in).

use super::error::BuildError;
use super::pipeline::{FrameInput, Pipeline};
use crate::geometry::Pose;
use crate::scenario::{Scenario, Trajectory};
use std::path::Path;

/// The pose track a replay plays: a trajectory, or the initial poses held.
pub struct TrajectoryPoses {
    trajectory: Option<Trajectory>,
    initial: Vec<Pose>,
}

impl TrajectoryPoses {
    /// Loads `path` (or the scenario's trajectory) and checks that it has no
    /// track for a spatula the scene lacks (part of `sim::preflight`).
    pub fn for_scenario(scenario: &Scenario, path: Option<&Path>) -> Result<Self, BuildError> {
        let initial = scenario.spatulas.iter().map(|s| s.initial_pose).collect::<Vec<_>>();
        let trajectory = match (path, &scenario.trajectory) {
            (Some(p), _) => {
                let t = Trajectory::load(p).map_err(BuildError::Trajectory)?;
                if t.spatula_count() > initial.len() {
                    let problem = crate::scenario::validate::tracks_beyond_spatulas(p, &t, initial.len());
                    return Err(BuildError::TrackCount { path: p.to_path_buf(), problem });
                }
                Some(t)
            }
            // Validation read it already; it may have changed on disk since.
            (None, Some(p)) => {
                let t = Trajectory::load(p).map_err(|e| scenario.invalid("trajectory", e.to_string()))?;
                if t.spatula_count() > initial.len() {
                    return Err(scenario.invalid("trajectory", crate::scenario::validate::tracks_beyond_spatulas(p, &t, initial.len())).into());
                }
                Some(t)
            }
            (None, None) => None,
        };
        Ok(Self { trajectory, initial })
    }

    /// Replay time of the trajectory's last row, s; `None` without a trajectory.
    pub fn trajectory_end(&self) -> Option<f64> {
        self.trajectory.as_ref().map(|t| t.duration() - self.trajectory_origin())
    }

    /// Where the trajectory's clock starts, s: 0, or the first row's time when
    /// that is negative (a window recording's lead-in: the session from rest
    /// before R was pressed). Replay time 0 is then that row.
    pub fn trajectory_origin(&self) -> f64 {
        self.trajectory.as_ref().map_or(0.0, |t| t.start_time().min(0.0))
    }

    /// Poses at replay time `time_s` into `out` (the trajectory sampled at
    /// `time_s + trajectory_origin()`; a track missing for a spatula holds its initial pose).
    pub fn poses_at(&self, time_s: f64, out: &mut FrameInput) {
        out.poses.clear();
        let origin = self.trajectory_origin();
        for (k, p0) in self.initial.iter().enumerate() {
            let p = self.trajectory.as_ref().and_then(|t| t.sample(k, time_s + origin)).unwrap_or(*p0);
            out.poses.push(Some(p));
        }
    }

    /// The spatulas whose trajectory rows cut in replay time `(after_s, until_s]` (the `cut` column).
    pub fn cuts_between(&self, after_s: f64, until_s: f64) -> Vec<usize> {
        let origin = self.trajectory_origin();
        (0..self.initial.len()).filter(|&k| self.trajectory.as_ref().is_some_and(|t| t.cuts_between(k, after_s + origin, until_s + origin))).collect()
    }

    /// Asks `pipeline` for the cuts the trajectory's rows make in frame `k` of `dt` seconds (replay time
    /// `(k dt, (k + 1) dt]`; the first frame takes those at or before its start too).
    pub fn request_frame_cuts(&self, k: u64, dt: f64, pipeline: &mut Pipeline) {
        let after = if k == 0 { f64::NEG_INFINITY } else { k as f64 * dt };
        for spatula in self.cuts_between(after, (k + 1) as f64 * dt) {
            pipeline.request_cut(spatula);
        }
    }

    /// Pose sets over the run, to size the automatic region of interest and refinement: `count + 1` evenly
    /// spaced; and when those lie farther apart than [`MOTION_SAMPLE_S`] (a long run), samples of their own for
    /// the stretches between the trajectory's rows in which a blade moves (at most about `count` more), so that a
    /// spread of a few seconds in a ten-minute hold is followed as closely as in a run of a few seconds.
    pub fn samples(&self, duration: f64, count: usize) -> Vec<Vec<Pose>> {
        let mut input = FrameInput::default();
        let mut at = |t: f64| -> Vec<Pose> {
            self.poses_at(t, &mut input);
            input.poses.iter().flatten().copied().collect()
        };
        let mut out: Vec<Vec<Pose>> = (0..=count).map(|k| at(duration * k as f64 / count.max(1) as f64)).collect();
        let Some(trajectory) = self.trajectory.as_ref().filter(|_| duration / count.max(1) as f64 > MOTION_SAMPLE_S) else {
            return out;
        };
        let origin = self.trajectory_origin();
        let mut times: Vec<f64> = (0..trajectory.spatula_count())
            .flat_map(|k| trajectory.samples(k).iter().map(move |s| s.time_s - origin))
            .filter(|t| (0.0..=duration).contains(t))
            .chain([0.0, duration])
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        // Between two rows a blade moves on a straight line: a stretch moves when its ends differ.
        let moving: Vec<(f64, f64)> = times.windows(2).map(|w| (w[0], w[1])).filter(|&(a, b)| at(a) != at(b)).collect();
        let moving_s: f64 = moving.iter().map(|(a, b)| b - a).sum();
        let step = (moving_s / count.max(1) as f64).max(MOTION_SAMPLE_S);
        for (a, b) in moving {
            let n = ((b - a) / step).ceil().max(1.0) as usize;
            out.extend((0..=n).map(|j| at(a + (b - a) * j as f64 / n as f64)));
        }
        out
    }
}

/// Evenly spaced pose samples closer than this (s) already follow a blade's motion
/// ([`TrajectoryPoses::samples`]); a longer run gets samples of its moving stretches too.
pub const MOTION_SAMPLE_S: f64 = 0.05;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_holds_short_spread_is_sampled_as_closely_as_a_short_runs() {
        let text = "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,0,1,0,0,0\n1,0,0,0,0,1,0,0,0\n3.5,0,0,0,10,1,0,0,0\n603.5,0,0,0,10,1,0,0,0\n";
        let trajectory = Trajectory::parse(text, Path::new("hold.csv")).expect("a track");
        let source = TrajectoryPoses { trajectory: Some(trajectory), initial: vec![Pose::default()] };
        let spread = |poses: &[Vec<Pose>]| poses.iter().filter(|p| p[0].position.z > 1e-4 && p[0].position.z < 0.0099).count();
        // Evenly spaced over ten minutes, 200 samples are 3 s apart: at most one falls inside the 2.5 s spread.
        let long = source.samples(603.5, 200);
        assert!(spread(&long) >= 40, "{} samples inside the spread", spread(&long));
        // A run of a few seconds is sampled as it always was: evenly, 201 pose sets.
        assert_eq!(source.samples(4.0, 200).len(), 201);
    }
}
