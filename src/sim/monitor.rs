//! Tunnelling and penetration monitor: is any tissue on the wrong side of a blade?
//!
//! In: the surface before and after a frame, the spatula poses before and after.
//! Out: per frame, the surface vertices inside a blade's footprint that changed
//! side of its mid-plane (tissue pulled *through* the spatula: the paper's
//! Fig. 11b failure) and those left strictly inside the blade (penetration,
//! with the deepest depth). Stays true: read-only on the simulation; O(vertices x
//! spatulas) per frame, no allocation; [`measure_near`] reads only the vertices
//! near each blade and counts the same.

use super::rest_grid::{Near, RestGrid};
use crate::geometry::{Pose, SpatulaShape};
use crate::math::Vec3;

/// Counts of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MonitorCounts {
    /// Vertices that crossed a blade's mid-plane inside its footprint.
    pub crossed: u32,
    /// Vertices strictly inside a blade (beyond a tolerance).
    pub penetrating: u32,
    /// Deepest penetration, m: the shortest way out of the blade (through a
    /// broad face, the tip or a side edge).
    pub max_depth_m: f64,
}

/// Penetration tolerance: a vertex projected onto a face sits on it up to
/// rounding; deeper than this is counted.
pub const PENETRATION_TOLERANCE_M: f64 = 1e-7;

/// Slack of the footprint's first test (m).
const FOOTPRINT_SLACK_M: f64 = 1e-9;

/// Local coordinates of `p` in the spatula frame of `pose`.
#[inline]
fn local(pose: &Pose, p: &Vec3) -> Vec3 {
    pose.rotation.inverse_transform_vector(&(p - pose.position))
}

#[inline]
fn in_footprint(shape: &SpatulaShape, q: &Vec3) -> bool {
    q.x >= 0.0 && q.x <= shape.length && q.y.abs() <= 0.5 * shape.width
}

/// Over the footprint and not on its tip or side-edge plane (to
/// [`PENETRATION_TOLERANCE_M`]): a vertex the barrier's end-face row holds on
/// the tip plane lies there to rounding, beside the blade, not over it.
#[inline]
fn within_footprint(shape: &SpatulaShape, q: &Vec3) -> bool {
    q.x >= 0.0 && q.x < shape.length - PENETRATION_TOLERANCE_M && q.y.abs() < 0.5 * shape.width - PENETRATION_TOLERANCE_M
}

/// One blade's first test: its frame's x and y axes as rows, for a cheap test
/// of the footprint with some slack (far above a transform's rounding); the
/// exact test in [`Blade::count`] decides.
struct Blade<'a> {
    shape: &'a SpatulaShape,
    before: &'a Pose,
    after: &'a Pose,
    ex: Vec3,
    ey: Vec3,
}

impl<'a> Blade<'a> {
    fn new(shape: &'a SpatulaShape, before: &'a Pose, after: &'a Pose) -> Self {
        let axes = after.rotation.to_rotation_matrix();
        Self { shape, before, after, ex: axes.matrix().column(0).into_owned(), ey: axes.matrix().column(1).into_owned() }
    }

    /// Adds one vertex, at `p0` before and `p1` after the move, to `counts`.
    #[inline]
    fn count(&self, p0: &Vec3, p1: &Vec3, counts: &mut MonitorCounts) {
        let (shape, pa) = (self.shape, self.after);
        let half = 0.5 * shape.thickness;
        let d = p1 - pa.position;
        let (x, y) = (self.ex.dot(&d), self.ey.dot(&d));
        if x < -FOOTPRINT_SLACK_M || x > shape.length + FOOTPRINT_SLACK_M || y.abs() > 0.5 * shape.width + FOOTPRINT_SLACK_M {
            return;
        }
        let q1 = local(pa, p1);
        if !in_footprint(shape, &q1) {
            return;
        }
        // How far it would have to move to leave the blade: through a broad
        // face, the tip or a side edge (not the base: the shaft continues).
        let depth = (half - q1.z.abs()).min(shape.length - q1.x).min(0.5 * shape.width - q1.y.abs());
        if depth > PENETRATION_TOLERANCE_M {
            counts.penetrating += 1;
            counts.max_depth_m = counts.max_depth_m.max(depth);
        }
        let q0 = local(self.before, p0);
        // A side is only meaningful outside the blade on both frames; a
        // vertex that starts or ends on the tip or a side-edge plane went
        // round that edge, not through the blade (tissue slipping off a
        // turning blade's tip onto its other side).
        if within_footprint(shape, &q0) && within_footprint(shape, &q1) && q0.z.abs() >= half - PENETRATION_TOLERANCE_M && q1.z.abs() >= half - PENETRATION_TOLERANCE_M && q0.z.signum() != q1.z.signum() {
            counts.crossed += 1;
        }
    }

    /// How far from the blade's mid-plane (after the move) a vertex may be
    /// counted, when no vertex moved more than `motion` (m): `None` when the
    /// blade turned too far to say.
    ///
    /// A penetrating vertex lies within half the thickness. A crossing one is
    /// within the footprint before and after, on opposite sides: with `ez`
    /// the blades' normals and `o` their origins, |z1| + |z0| = |z1 - z0| <=
    /// motion + |ez_a - ez_b| |p0 - o_b| + |o_a - o_b|, and |p0 - o_b| <= r + |z0|
    /// (r the footprint's farthest corner), so while |ez_a - ez_b| < 1,
    /// |z1| <= motion + |ez_a - ez_b| r + |o_a - o_b|. Past half that turn (about
    /// 29 degrees in one sub-step, which sub-steps never reach while the blade
    /// is near tissue) the reach is a blade length or more: every vertex is read.
    fn reach(&self, motion: f64) -> Option<f64> {
        let shape = self.shape;
        let turn = (self.after.rotation * Vec3::z() - self.before.rotation * Vec3::z()).norm();
        if !(turn < 0.5) {
            return None;
        }
        let corner = shape.length.hypot(0.5 * shape.width);
        let shift = (self.after.position - self.before.position).norm();
        let reach = (0.5 * shape.thickness).max(motion + turn * corner + shift);
        // Rounding of the terms: far below the slack.
        Some(reach * (1.0 + 1e-12) + FOOTPRINT_SLACK_M)
    }
}

/// Measures one frame. `before`/`after` are surface-vertex positions, `poses_*`
/// one per spatula.
pub fn measure(
    shapes: &[SpatulaShape],
    poses_before: &[Pose],
    poses_after: &[Pose],
    before: &[Vec3],
    after: &[Vec3],
) -> MonitorCounts {
    let mut counts = MonitorCounts::default();
    for ((shape, pb), pa) in shapes.iter().zip(poses_before).zip(poses_after) {
        let blade = Blade::new(shape, pb, pa);
        for (p0, p1) in before.iter().zip(after) {
            blade.count(p0, p1, &mut counts);
        }
    }
    counts
}

/// [`measure`], reading only the vertices that may be counted: `grid` bins the
/// rest positions, and `bounds` bound every component of `before - rest` and of
/// `after - rest` ([`super::rest_grid::displacement_bound`]). The same counts.
#[allow(clippy::too_many_arguments)]
pub fn measure_near(
    shapes: &[SpatulaShape],
    poses_before: &[Pose],
    poses_after: &[Pose],
    before: &[Vec3],
    after: &[Vec3],
    grid: &RestGrid,
    bounds: (f64, f64),
    near: &mut Near,
) -> MonitorCounts {
    if grid.len() != after.len() || before.len() != after.len() {
        return measure(shapes, poses_before, poses_after, before, after);
    }
    let mut counts = MonitorCounts::default();
    // No component of a vertex's move exceeds the sum of the bounds.
    let motion = 3f64.sqrt() * (bounds.0 + bounds.1);
    for ((shape, pb), pa) in shapes.iter().zip(poses_before).zip(poses_after) {
        let blade = Blade::new(shape, pb, pa);
        match blade.reach(motion) {
            Some(z) => {
                let (x, y) = (shape.length + FOOTPRINT_SLACK_M, 0.5 * shape.width + FOOTPRINT_SLACK_M);
                let (lo, hi) = super::barrier::world_bounds(pa, &Vec3::new(-FOOTPRINT_SLACK_M, -y, -z), &Vec3::new(x, y, z), FOOTPRINT_SLACK_M);
                grid.near(&lo, &hi, bounds.1, near);
            }
            None => near.all = true,
        }
        near.for_each(after.len(), |v| blade.count(&before[v], &after[v], &mut counts));
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blade() -> SpatulaShape {
        SpatulaShape { length: 0.05, width: 0.01, thickness: 0.001 }
    }

    #[test]
    fn vertex_pulled_through_the_blade_is_counted_as_crossed() {
        let pose = Pose::default();
        let before = [Vec3::new(0.02, 0.0, 0.002), Vec3::new(0.02, 0.0, -0.003)];
        let after = [Vec3::new(0.02, 0.0, -0.0005), Vec3::new(0.02, 0.0, -0.003)];
        let c = measure(&[blade()], &[pose], &[pose], &before, &after);
        assert_eq!(c.crossed, 1, "the first vertex went from +z to -z through the blade");
        assert_eq!(c.penetrating, 0, "z = -0.5 mm lies on the face, not inside");
    }

    #[test]
    fn vertex_that_goes_round_the_tip_onto_its_plane_has_not_crossed() {
        let pose = Pose::default();
        // On the +z face 26 um short of the tip, then on the tip's plane below the -z face
        // (the u_shape scene refined, a wall slipping off the turning blade's tip).
        let before = [Vec3::new(0.049974, -0.0007, 0.0005), Vec3::new(0.0499, 0.0, 0.0005)];
        let after = [Vec3::new(0.05, -0.0006, -0.002), Vec3::new(0.0499, 0.0, -0.002)];
        let c = measure(&[blade()], &[pose], &[pose], &before, &after);
        assert_eq!(c.crossed, 1, "only the second vertex, 0.1 mm inside the tip on both frames, crossed");
        // The same on a side edge's plane.
        let before = [Vec3::new(0.02, 0.005, 0.0005)];
        let after = [Vec3::new(0.02, 0.005, -0.002)];
        assert_eq!(measure(&[blade()], &[pose], &[pose], &before, &after).crossed, 0);
    }

    #[test]
    fn vertex_inside_the_blade_is_penetrating_and_outside_footprint_is_ignored() {
        let pose = Pose::default();
        let before = [Vec3::new(0.02, 0.0, 0.0002), Vec3::new(0.2, 0.0, 0.0)];
        let after = before;
        let c = measure(&[blade()], &[pose], &[pose], &before, &after);
        assert_eq!(c.penetrating, 1);
        assert!((c.max_depth_m - 0.0003).abs() < 1e-12, "depth is half-thickness minus |z|: {}", c.max_depth_m);
        assert_eq!(c.crossed, 0);
    }

    #[test]
    fn depth_near_the_tip_or_an_edge_is_the_way_out_through_it() {
        let pose = Pose::default();
        // 0.04 mm short of the tip, 0.1 mm from the -z face: 0.04 mm deep.
        let near_tip = [Vec3::new(0.04996, 0.0, -0.0004)];
        let c = measure(&[blade()], &[pose], &[pose], &near_tip, &near_tip);
        assert_eq!(c.penetrating, 1);
        assert!((c.max_depth_m - 0.00004).abs() < 1e-12, "{}", c.max_depth_m);
        // 0.02 mm inside a side edge, on the mid-plane.
        let near_side = [Vec3::new(0.02, -0.00498, 0.0)];
        let c = measure(&[blade()], &[pose], &[pose], &near_side, &near_side);
        assert!((c.max_depth_m - 0.00002).abs() < 1e-12, "{}", c.max_depth_m);
    }

    /// The near-vertex count equals the whole pass, on surfaces crowding a moving and turning blade (vertices
    /// pushed through it, left inside it, slipping off its tip) and when the blade turns too far to bound.
    #[test]
    fn measure_near_counts_what_the_whole_pass_counts() {
        use crate::math::Quat;
        let mut next = crate::math::test_rng::uniform(0x9e3779b97f4a7c15u64);
        let b = blade();
        let rest: Vec<Vec3> = (0..3000).map(|_| Vec3::new(next() * 0.08 - 0.01, next() * 0.03 - 0.015, next() * 0.02 - 0.01)).collect();
        let grid = RestGrid::new(&rest);
        let mut near = Near::default();
        let (mut crossed, mut penetrating, mut scanned_less) = (0, 0, 0);
        for round in 0..300 {
            let amp = [0.0, 0.0005, 0.003][round % 3];
            let mut moved = |_: usize| rest.iter().map(|r| r + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * (2.0 * amp)).collect::<Vec<Vec3>>();
            let (before, after) = (moved(0), moved(1));
            let bounds = (super::super::rest_grid::displacement_bound(&before, &rest), super::super::rest_grid::displacement_bound(&after, &rest));
            let turn = if round % 10 == 9 { 2.5 } else { 0.05 };
            let pb = Pose { position: Vec3::new(next() * 0.01, next() * 0.004, next() * 0.004), rotation: Quat::from_axis_angle(&Vec3::y_axis(), (next() - 0.5) * 0.2) };
            let pa = Pose { position: pb.position + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.002, rotation: pb.rotation * Quat::from_axis_angle(&Vec3::x_axis(), (next() - 0.5) * turn) };
            // Every fourth round the blade stands still: only the tissue's own motion carries a vertex through.
            let pa = if round % 4 == 3 { pb } else { pa };
            let whole = measure(&[b], &[pb], &[pa], &before, &after);
            let got = measure_near(&[b], &[pb], &[pa], &before, &after, &grid, bounds, &mut near);
            assert_eq!(got, whole, "round {round}");
            crossed += whole.crossed;
            penetrating += whole.penetrating;
            scanned_less += usize::from(!near.all);
        }
        assert!(crossed > 0 && penetrating > 0, "the draws must cross and penetrate: {crossed} / {penetrating}");
        assert!(scanned_less > 200, "most rounds must read only the vertices near the blade: {scanned_less}");
    }

    /// A vertex carried through a still blade from far off (its rest position 4.6 mm above the blade, its
    /// position before 0.6 mm under it, after 4 mm above it): the near count reaches it through the sub-step's
    /// motion, not through the bound of the positions after alone (0.6 mm).
    #[test]
    fn measure_near_reaches_a_vertex_carried_through_from_far() {
        let (b, pose) = (blade(), Pose::default());
        let rest = [Vec3::new(0.02, 0.0, 0.0046), Vec3::new(0.06, 0.0, 0.0)];
        let before = [rest[0] + Vec3::new(0.0, 0.0, -0.0052), rest[1]];
        let after = [rest[0] + Vec3::new(0.0, 0.0, -0.0006), rest[1]];
        let bounds = (super::super::rest_grid::displacement_bound(&before, &rest), super::super::rest_grid::displacement_bound(&after, &rest));
        let whole = measure(&[b], &[pose], &[pose], &before, &after);
        assert_eq!(whole.crossed, 1);
        let mut near = Near::default();
        assert_eq!(measure_near(&[b], &[pose], &[pose], &before, &after, &RestGrid::new(&rest), bounds, &mut near), whole);
    }

    #[test]
    fn pushed_wall_moving_with_the_blade_does_not_cross() {
        // The blade moves +z by 3 thicknesses; the wall ahead of it is pushed to its front face.
        let b = blade();
        let p0 = Pose::default();
        let p1 = Pose { position: Vec3::new(0.0, 0.0, 0.003), ..p0 };
        let before = [Vec3::new(0.02, 0.0, 0.001)];
        let after = [Vec3::new(0.02, 0.0, 0.003 + 0.0005)];
        assert_eq!(measure(&[b], &[p0], &[p1], &before, &after).crossed, 0);
        // Left behind (not pushed) it would have crossed.
        assert_eq!(measure(&[b], &[p0], &[p1], &before, &before).crossed, 1);
    }
}
