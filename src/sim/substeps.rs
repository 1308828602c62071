//! How many sub-steps a frame runs: the blade footprint's travel over a
//! fraction of the blade's thickness, less the jitter of the blade's own
//! samples.
//!
//! In: each blade's shape, its pose at the start of the frame and the frame's
//! target, and the targets of the frames before (the jitter estimate). Out: a
//! count in 1..=[`MAX_SUBSTEPS`].
//!
//! Why jitter does not count: sub-steps make a frame's answer that of the same
//! motion sampled finely. A tracker's noise is not motion the hand made;
//! following it in sub-steps of a fraction of a millimetre multiplies the
//! solve and brings the answer no nearer the hand's. On the refined default
//! scene with +-0.5 mm of noise every 10 ms, the forces of the noise followed
//! in sub-steps lie 8.4 / 10.5 mN (rms, frontal / temporal) from those of the
//! clean track, and of the noise taken in one step a frame 7.8 / 9.5 mN
//! (`docs/design-notes.md`, "Sub-steps under tracker noise").
//!
//! The estimate: each frame, the largest second difference of a footprint
//! corner over the last three targets, `|c_k - 2 c_{k-1} + c_{k-2}|`. Smooth
//! motion has none but where its speed changes (a keyframe: one or two frames);
//! a tracker's noise has one of its own size every frame. The median over the
//! last [`JITTER_WINDOW`] frames is the blade's jitter, and a frame's travel
//! counts only beyond it. A median of less than [`JITTER_FLOOR`] of a
//! sub-step's travel counts as none, so smooth tracks (a keyframe track, a
//! slow rotation's curvature, rounding) take exactly the sub-steps of the plain
//! rule. A tracker glitch is one large second difference: it does not move the
//! median, and the jump is split as before.

use crate::geometry::{Pose, SpatulaShape};
use crate::math::Vec3;

/// The default of `solver.substep_travel`: a frame whose blade footprint moves
/// more than this fraction of the blade's thickness is split into sub-steps
/// that move at most this much each.
pub const SUBSTEP_TRAVEL_FRACTION: f64 = 0.125;
/// At most this many sub-steps a frame: a longer jump (a tracker glitch of
/// metres) takes longer sub-steps rather than stalling the frame.
pub const MAX_SUBSTEPS: u32 = 256;
/// Frames of second differences the jitter estimate reads (160 ms at 100 Hz).
pub const JITTER_WINDOW: usize = 16;
/// A jitter estimate under this fraction of a sub-step's travel counts as none.
pub const JITTER_FLOOR: f64 = 0.1;

/// Sub-steps for a frame from `before` to `after`: the largest footprint-corner
/// travel over `fraction` of that blade's thickness, rounded up, in
/// 1..=[`MAX_SUBSTEPS`]; 1 when `fraction` is `None`. `jitter` (one per blade,
/// or empty for none) is subtracted from each blade's travel first.
pub fn substep_count(shapes: &[SpatulaShape], before: &[Pose], after: &[Pose], jitter: &[f64], fraction: Option<f64>) -> u32 {
    let Some(fraction) = fraction else { return 1 };
    let mut ratio: f64 = 0.0;
    for (k, ((shape, b), a)) in shapes.iter().zip(before).zip(after).enumerate() {
        let step = fraction * shape.thickness;
        let travel = travel(shape, b, a) - jitter.get(k).copied().unwrap_or(0.0);
        ratio = ratio.max(travel / step);
    }
    if ratio.is_nan() { MAX_SUBSTEPS } else { (ratio.ceil().min(MAX_SUBSTEPS as f64) as u32).max(1) }
}

/// One blade's jitter estimate: its footprint corners at the last two targets
/// and the last [`JITTER_WINDOW`] second differences, in a ring.
#[derive(Debug, Clone, Default)]
pub struct SampleJitter {
    /// Footprint corners at the last target and the one before.
    corners: [Option<[Vec3; 4]>; 2],
    /// Second differences (m), the newest at `next - 1`.
    ring: [f64; JITTER_WINDOW],
    next: usize,
    filled: usize,
}

impl SampleJitter {
    /// Takes one frame's target pose.
    pub fn observe(&mut self, shape: &SpatulaShape, target: &Pose) {
        let c = footprint_corners(shape, target);
        if let [Some(p1), Some(p2)] = self.corners {
            let s = (0..4).map(|i| (c[i] - 2.0 * p1[i] + p2[i]).norm()).fold(0.0, f64::max);
            self.ring[self.next] = s;
            self.next = (self.next + 1) % JITTER_WINDOW;
            self.filled = (self.filled + 1).min(JITTER_WINDOW);
        }
        self.corners = [Some(c), self.corners[0]];
    }

    /// The travel (m) a frame's motion does not count: the median second
    /// difference over a full window, or 0 when the window is not yet full or
    /// the median is under [`JITTER_FLOOR`] of `step` (a sub-step's travel, m).
    pub fn allowance(&self, step: f64) -> f64 {
        if self.filled < JITTER_WINDOW {
            return 0.0;
        }
        let mut v = self.ring;
        v.sort_unstable_by(f64::total_cmp);
        let median = 0.5 * (v[JITTER_WINDOW / 2 - 1] + v[JITTER_WINDOW / 2]);
        if median.is_finite() && median >= JITTER_FLOOR * step { median } else { 0.0 }
    }

    /// Forgets every sample (the blade was put somewhere new).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

/// Largest move (m) of a blade footprint corner from `before` to `after`.
pub fn travel(shape: &SpatulaShape, before: &Pose, after: &Pose) -> f64 {
    let (a, b) = (footprint_corners(shape, after), footprint_corners(shape, before));
    (0..4).map(|i| (a[i] - b[i]).norm()).fold(0.0, f64::max)
}

/// A blade footprint's four corners (the face plane's rectangle) at `pose`.
pub fn footprint_corners(shape: &SpatulaShape, pose: &Pose) -> [Vec3; 4] {
    let (l, w) = (shape.length, 0.5 * shape.width);
    [Vec3::new(0.0, -w, 0.0), Vec3::new(0.0, w, 0.0), Vec3::new(l, -w, 0.0), Vec3::new(l, w, 0.0)].map(|c| pose.position + pose.rotation * c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> SpatulaShape {
        SpatulaShape { length: 0.06, width: 0.008, thickness: 0.001 }
    }

    fn at(x: f64, y: f64, z: f64) -> Pose {
        Pose { position: Vec3::new(x, y, z), rotation: crate::math::Quat::identity() }
    }

    /// A deterministic pseudo-random sequence in [-1, 1).
    fn noise(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    #[test]
    fn smooth_motion_has_no_allowance() {
        // Constant speed, then a stop (a keyframe), then a slow turn: all smooth.
        let s = shape();
        let mut j = SampleJitter::default();
        for k in 0..40 {
            let x = if k < 20 { k as f64 * 5e-4 } else { 0.01 };
            j.observe(&s, &at(x, 0.0, 0.0));
            assert_eq!(j.allowance(1.25e-4), 0.0, "frame {k}");
        }
        for k in 0..40 {
            let angle = k as f64 * 0.003;
            let p = Pose { position: Vec3::new(0.01, 0.0, 0.0), rotation: crate::math::Quat::from_euler_angles(0.0, 0.0, angle) };
            j.observe(&s, &p);
            assert_eq!(j.allowance(1.25e-4), 0.0, "turning frame {k}");
        }
    }

    #[test]
    fn noise_is_measured_and_a_glitch_is_not() {
        let s = shape();
        let mut j = SampleJitter::default();
        let mut seed = 7;
        let mut poses = Vec::new();
        for k in 0..64 {
            let p = at(k as f64 * 1e-5 + 5e-4 * noise(&mut seed), 5e-4 * noise(&mut seed), 5e-4 * noise(&mut seed));
            j.observe(&s, &p);
            poses.push(p);
        }
        let a = j.allowance(1.25e-4);
        // Uniform +-0.5 mm a coordinate: a second difference's median norm is about 1.1 mm.
        assert!((7e-4..1.5e-3).contains(&a), "allowance {a}");
        // Most noisy frames run as one sub-step; the plain rule splits them.
        let shapes = [s];
        let one = poses.windows(2).filter(|w| substep_count(&shapes, &w[..1], &w[1..], &[a], Some(0.125)) == 1).count();
        let plain = poses.windows(2).filter(|w| substep_count(&shapes, &w[..1], &w[1..], &[], Some(0.125)) == 1).count();
        assert!(one >= 57 && plain <= 6, "one sub-step: {one} with the allowance, {plain} without, of 63");
        // A 20 mm glitch moves the median by one sample at most: it is split as before, less the jitter.
        let glitch = at(0.02, 0.0, 0.0);
        j.observe(&s, &glitch);
        let b = j.allowance(1.25e-4);
        assert!((b - a).abs() < 3e-4, "{a} -> {b}");
        let n = substep_count(&shapes, &poses[63..], &[glitch], &[b], Some(0.125));
        assert!(n >= 140, "a 20 mm jump runs as {n} sub-steps");
    }

    #[test]
    fn count_matches_the_plain_rule_without_jitter() {
        let shapes = [shape()];
        assert_eq!(substep_count(&shapes, &[at(0.0, 0.0, 0.0)], &[at(0.9e-3, 0.0, 0.0)], &[], Some(0.125)), 8);
        assert_eq!(substep_count(&shapes, &[at(0.0, 0.0, 0.0)], &[at(0.9e-3, 0.0, 0.0)], &[0.0], Some(0.125)), 8);
        assert_eq!(substep_count(&shapes, &[at(0.0, 0.0, 0.0)], &[at(0.9e-3, 0.0, 0.0)], &[5e-4], Some(0.125)), 4);
        assert_eq!(substep_count(&shapes, &[at(0.0, 0.0, 0.0)], &[at(0.9e-3, 0.0, 0.0)], &[2e-3], Some(0.125)), 1);
        assert_eq!(substep_count(&shapes, &[at(0.0, 0.0, 0.0)], &[at(1.0, 0.0, 0.0)], &[], Some(0.125)), MAX_SUBSTEPS);
        assert_eq!(substep_count(&shapes, &[at(0.0, 0.0, 0.0)], &[at(1.0, 0.0, 0.0)], &[], None), 1);
    }
}
