//! The distance from a point to a segment.
//!
//! In: a point and the segment's ends. Out: the Euclidean distance to the
//! segment's nearest point. Stays true: finite for finite input, also for a
//! segment whose ends coincide (then the distance to that point).

use crate::math::Vec3;

/// Distance from `p` to the segment a-b.
pub fn distance_to_segment(p: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let s = if len2 > 0.0 { ((p - a).dot(&ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * s)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_point_is_an_end_or_the_foot_of_the_perpendicular() {
        let (a, b) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0));
        assert_eq!(distance_to_segment(&Vec3::new(1.0, 3.0, 0.0), &a, &b), 3.0);
        assert_eq!(distance_to_segment(&Vec3::new(-3.0, 4.0, 0.0), &a, &b), 5.0);
        assert_eq!(distance_to_segment(&Vec3::new(5.0, 0.0, 4.0), &a, &b), 5.0);
        assert_eq!(distance_to_segment(&Vec3::new(0.0, 0.0, 2.0), &a, &a), 2.0);
    }
}
