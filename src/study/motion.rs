//! The study's deterministic spatula motion: insert into the fissure, open it
//! sideways at a chosen speed, close back, withdraw.
//!
//! In: the spatulas' initial poses, the moving blade's thickness and a
//! [`Motion`]. Out: one [`MotionFrame`] per simulation frame: the pose of every
//! spatula and a [`FrameKey`] naming where on the path the frame is. Stays
//! true: the path is the same polyline for every speed; a frame's key is its
//! phase and its distance along that phase in whole nanometres, so runs at
//! different speeds can be compared exactly at the path positions they share
//! (every speed that divides the phase length visits the positions of the
//! coarser speeds). Only spatula 0 moves; the others hold their initial pose.
//!
//! Phases, in the moving spatula's own frame (x along the blade, z through its
//! thickness): `Insert` along +x by `insert_m` at `insert_step_m` a frame;
//! `Open` along +z (the face normal) by `open_m` at `speed` thicknesses a
//! frame; `Close` back along -z at the same speed; `Withdraw` back along -x.

use crate::geometry::Pose;
use crate::math::Vec3;

/// Where a frame lies on the path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FrameKey {
    /// 0 insert, 1 open, 2 close, 3 withdraw.
    pub phase: u8,
    /// Distance travelled in the phase, nanometres.
    pub distance_nm: i64,
}

/// One frame of the motion.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionFrame {
    pub key: FrameKey,
    pub poses: Vec<Pose>,
}

/// The path and its speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Insertion depth along the blade, m (> 0, e.g. 0.03).
    pub insert_m: f64,
    /// Insertion (and withdrawal) step a frame, m (> 0, e.g. 0.002).
    pub insert_step_m: f64,
    /// Sideways travel along the face normal, m (> 0, e.g. 0.010).
    pub open_m: f64,
}

impl Default for Motion {
    fn default() -> Self {
        Self { insert_m: 0.030, insert_step_m: 0.002, open_m: 0.010 }
    }
}

/// Distances 0 < d_1 < ... < d_n = length at `step` a frame (the last step may be short).
fn stations(length: f64, step: f64) -> Vec<f64> {
    let n = (length / step - 1e-9).ceil().max(1.0) as usize;
    (1..=n).map(|k| (k as f64 * step).min(length)).collect()
}

fn nanometres(d: f64) -> i64 {
    (d * 1e9).round() as i64
}

impl Motion {
    /// Every frame of the path with the sideways phases at `speed`
    /// thicknesses a frame (`thickness` m, the moving blade's).
    pub fn frames(&self, initial: &[Pose], thickness: f64, speed: f64) -> Vec<MotionFrame> {
        let mut out = Vec::new();
        let Some(start) = initial.first().copied() else {
            return out;
        };
        let pose_at = |along: f64, across: f64| {
            let mut poses = initial.to_vec();
            poses[0] = Pose {
                position: start.position + start.rotation * Vec3::new(along, 0.0, across),
                rotation: start.rotation,
            };
            poses
        };
        let side_step = (speed * thickness).max(1e-9);
        for d in stations(self.insert_m, self.insert_step_m) {
            out.push(MotionFrame { key: FrameKey { phase: 0, distance_nm: nanometres(d) }, poses: pose_at(d, 0.0) });
        }
        for d in stations(self.open_m, side_step) {
            out.push(MotionFrame { key: FrameKey { phase: 1, distance_nm: nanometres(d) }, poses: pose_at(self.insert_m, d) });
        }
        for d in stations(self.open_m, side_step) {
            out.push(MotionFrame {
                key: FrameKey { phase: 2, distance_nm: nanometres(d) },
                poses: pose_at(self.insert_m, self.open_m - d),
            });
        }
        for d in stations(self.insert_m, self.insert_step_m) {
            out.push(MotionFrame { key: FrameKey { phase: 3, distance_nm: nanometres(d) }, poses: pose_at(self.insert_m - d, 0.0) });
        }
        out
    }

    /// Distance along the whole path, whole nanometres, of a frame at `key`:
    /// the phases one after another (insert, open, close, withdraw), so it
    /// grows with the key and runs at any speed share one axis, exactly.
    pub fn path_position_nm(&self, key: FrameKey) -> i64 {
        let (insert, open) = (nanometres(self.insert_m), nanometres(self.open_m));
        let before = match key.phase {
            0 => 0,
            1 => insert,
            2 => insert + open,
            _ => insert + 2 * open,
        };
        before + key.distance_nm
    }

    /// Where the blade works (world, m): on its centre line, the middle of the
    /// part that went past its starting tip, half way through the opening.
    /// The natural centre of a region-of-interest sphere.
    pub fn working_point(&self, initial: &Pose, blade_length: f64) -> Vec3 {
        initial.position + initial.rotation * Vec3::new(blade_length + 0.5 * self.insert_m, 0.0, 0.5 * self.open_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Quat;

    #[test]
    fn slower_runs_visit_every_key_of_faster_runs() {
        let m = Motion::default();
        let p = [Pose { position: Vec3::zeros(), rotation: Quat::identity() }];
        let fine = m.frames(&p, 0.001, 0.25);
        let coarse = m.frames(&p, 0.001, 5.0);
        for f in &coarse {
            let twin = fine.iter().find(|g| g.key == f.key);
            let twin = twin.unwrap_or_else(|| panic!("key {:?} of the 5-thickness run is missing at 0.25", f.key));
            assert!((twin.poses[0].position - f.poses[0].position).norm() < 1e-12, "same key, same pose");
        }
        assert_eq!(coarse.len(), 15 + 2 + 2 + 15, "10 mm at 5 mm a frame is 2 frames each way");
        assert_eq!(fine.len(), 15 + 40 + 40 + 15);
    }

    #[test]
    fn the_path_returns_to_the_start_and_opens_along_the_face_normal() {
        let m = Motion::default();
        // Blade pointing down (-z world), face normal +x world.
        let r = Quat::rotation_between(&Vec3::x(), &-Vec3::z()).expect("not antiparallel");
        let p0 = Pose { position: Vec3::new(0.0, 0.0, 0.1), rotation: r };
        let frames = m.frames(&[p0], 0.001, 1.0);
        let last = frames.last().expect("frames");
        assert!((last.poses[0].position - p0.position).norm() < 1e-12, "withdrawn to the start");
        let widest = frames.iter().map(|f| f.poses[0].position - p0.position).fold(0.0_f64, |a, d| a.max((r.inverse() * d).z));
        assert!((widest - 0.010).abs() < 1e-12, "opens by open_m along the blade's z: {widest}");
    }
}
