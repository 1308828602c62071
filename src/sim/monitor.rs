//! Tunnelling and penetration monitor: is any tissue on the wrong side of a blade?
//!
//! In: the surface before and after a frame, the spatula poses before and after.
//! Out: per frame, the surface vertices inside a blade's footprint that changed
//! side of its mid-plane (tissue pulled *through* the spatula: the paper's
//! Fig. 11b failure) and those left strictly inside the blade (penetration,
//! with the deepest depth). Stays true: read-only on the simulation; O(vertices x
//! spatulas) per frame, no allocation.

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
        let half = 0.5 * shape.thickness;
        // The blade frame's x and y axes as rows, for a cheap first test of
        // the footprint with some slack (far above a transform's rounding):
        // the exact test below decides.
        let axes = pa.rotation.to_rotation_matrix();
        let (ex, ey) = (axes.matrix().column(0).into_owned(), axes.matrix().column(1).into_owned());
        let (x_max, y_max) = (shape.length + FOOTPRINT_SLACK_M, 0.5 * shape.width + FOOTPRINT_SLACK_M);
        for (p0, p1) in before.iter().zip(after) {
            let d = p1 - pa.position;
            let (x, y) = (ex.dot(&d), ey.dot(&d));
            if x < -FOOTPRINT_SLACK_M || x > x_max || y.abs() > y_max {
                continue;
            }
            let q1 = local(pa, p1);
            if !in_footprint(shape, &q1) {
                continue;
            }
            // How far it would have to move to leave the blade: through a broad
            // face, the tip or a side edge (not the base: the shaft continues).
            let depth = (half - q1.z.abs()).min(shape.length - q1.x).min(0.5 * shape.width - q1.y.abs());
            if depth > PENETRATION_TOLERANCE_M {
                counts.penetrating += 1;
                counts.max_depth_m = counts.max_depth_m.max(depth);
            }
            let q0 = local(pb, p0);
            // A side is only meaningful outside the blade on both frames; a
            // vertex that starts or ends on the tip or a side-edge plane went
            // round that edge, not through the blade (tissue slipping off a
            // turning blade's tip onto its other side).
            if within_footprint(shape, &q0) && within_footprint(shape, &q1) && q0.z.abs() >= half - PENETRATION_TOLERANCE_M && q1.z.abs() >= half - PENETRATION_TOLERANCE_M && q0.z.signum() != q1.z.signum() {
                counts.crossed += 1;
            }
        }
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
