//! Line–triangle intersection: the paper's Möller–Trumbore test (Eq. 5) and the
//! watertight form every collision backend uses.
//!
//! In: a line `O + t D` (origin and a non-zero direction, metres) and a triangle
//! (v0, v1, v2). Out: `Some(LineHit { t, u, v })` with the hit point
//! `(1 - u - v) v0 + u v1 + v v2 = O + t D`, `t` of either sign (the collision
//! stage wants the nearest hit behind AND in front in one pass), or `None`.
//!
//! Stays true:
//! - **Watertight.** [`LineQuery::intersect`] follows Woop, Benthin & Wald 2013
//!   ("Watertight ray/triangle intersection"): the vertices are moved into a frame
//!   where the line is the z axis, and the three 2D edge functions are computed
//!   from the two transformed endpoints only, so the edge shared by two triangles
//!   gets exactly opposite values in both (f64 products commute; `a - b == -(b - a)`).
//!   An edge function that is exactly 0 is decided by a symbolic perturbation of
//!   the line by `(ε, ε²)` in that 2D frame: its sign becomes the sign of the edge's
//!   `dy`, else of `-dx`. That is a geometric perturbation, so a line through a
//!   shared edge or a shared vertex of a closed surface crosses exactly one of the
//!   triangles there (a line grazing a silhouette edge touches 0 or 2: parity holds).
//! - The hit is accepted for both windings (all three edge signs equal), so a
//!   triangle is hit from either side; the caller reads the facing from the normal.
//! - A line parallel to the triangle's plane, a zero-area or needle triangle, a
//!   zero or non-finite direction: `None`, never NaN. A hit whose `t` would not be
//!   finite (vanishing determinant) is `None` as well.
//! - `t`, `u`, `v` agree with Möller–Trumbore (Eq. 5) to rounding away from edges.

use crate::math::{Vec3, is_finite3};

/// A line–triangle hit: signed distance parameter `t` along the direction, and the
/// barycentric coordinates `u` (weight of v1) and `v` (weight of v2), both in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineHit {
    /// Line parameter of the hit (metres when the direction is unit); negative: behind the origin.
    pub t: f64,
    /// Barycentric weight of v1, in [0, 1].
    pub u: f64,
    /// Barycentric weight of v2, in [0, 1]; `u + v <= 1` up to rounding.
    pub v: f64,
}

/// The paper's Möller–Trumbore test (Eq. 5), as printed: a hit when
/// 0 <= u, 0 <= v, u + v <= 1 (inclusive, so edge hits may count twice, and rounding
/// may lose them). Kept as the textbook reference; the stage uses [`LineQuery`].
/// Returns `None` for a parallel line or a degenerate triangle (determinant exactly 0).
pub fn moller_trumbore(origin: &Vec3, direction: &Vec3, v0: &Vec3, v1: &Vec3, v2: &Vec3) -> Option<LineHit> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = direction.cross(&e2);
    let det = p.dot(&e1);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tv = origin - v0;
    let u = p.dot(&tv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = tv.cross(&e1);
    let v = q.dot(direction) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = q.dot(&e2) * inv;
    t.is_finite().then_some(LineHit { t, u, v })
}

/// A line prepared for many watertight triangle tests (the per-line part of
/// Woop et al.: the dominant axis and the shear).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineQuery {
    origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f64,
    sy: f64,
    sz: f64,
}

/// Sign of an edge function with the (ε, ε²) perturbation applied when it is exactly 0.
#[inline(always)]
fn perturbed_sign(e: f64, dx: f64, dy: f64) -> i8 {
    if e > 0.0 {
        1
    } else if e < 0.0 {
        -1
    } else if dy > 0.0 {
        1
    } else if dy < 0.0 {
        -1
    } else if dx < 0.0 {
        1
    } else if dx > 0.0 {
        -1
    } else {
        0
    }
}

impl LineQuery {
    /// Prepares the line `origin + t direction`. `None` when the direction is zero
    /// or anything is non-finite. The direction need not be unit; `t` is in its units.
    pub fn new(origin: Vec3, direction: Vec3) -> Option<Self> {
        if !is_finite3(&origin) || !is_finite3(&direction) {
            return None;
        }
        let a = direction.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        if direction[kz] == 0.0 {
            return None;
        }
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let sz = 1.0 / direction[kz];
        Some(Self { origin, kx, ky, kz, sx: direction[kx] * sz, sy: direction[ky] * sz, sz })
    }

    /// The origin of the line.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// Watertight intersection of the line with triangle (v0, v1, v2); see the module docs.
    #[inline]
    pub fn intersect(&self, v0: &Vec3, v1: &Vec3, v2: &Vec3) -> Option<LineHit> {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = v0 - self.origin;
        let b = v1 - self.origin;
        let c = v2 - self.origin;
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        // Edge function of the directed edge P -> Q: E = Qx Py - Qy Px.
        let eu = cx * by - cy * bx; // edge v1 -> v2, weight of v0
        let ev = ax * cy - ay * cx; // edge v2 -> v0, weight of v1
        let ew = bx * ay - by * ax; // edge v0 -> v1, weight of v2
        let su = perturbed_sign(eu, cx - bx, cy - by);
        let sv = perturbed_sign(ev, ax - cx, ay - cy);
        let sw = perturbed_sign(ew, bx - ax, by - ay);
        if su == 0 || su != sv || su != sw {
            return None;
        }
        let det = eu + ev + ew;
        if det == 0.0 {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let inv = 1.0 / det;
        let t = (eu * az + ev * bz + ew * cz) * inv;
        let u = ev * inv;
        let v = ew * inv;
        (t.is_finite() && u.is_finite() && v.is_finite()).then_some(LineHit { t, u, v })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [Vec3; 3] {
        [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)]
    }

    #[test]
    fn hit_in_front_and_behind_give_signed_t_and_barycentrics() {
        let [a, b, c] = tri();
        let q = LineQuery::new(Vec3::new(0.25, 0.5, 2.0), -Vec3::z()).expect("valid line");
        let h = q.intersect(&a, &b, &c).expect("the line crosses the triangle");
        assert!((h.t - 2.0).abs() < 1e-15 && (h.u - 0.25).abs() < 1e-15 && (h.v - 0.5).abs() < 1e-15, "{h:?}");
        let q = LineQuery::new(Vec3::new(0.25, 0.5, 2.0), Vec3::z()).expect("valid line");
        let h = q.intersect(&a, &b, &c).expect("a line hits behind as well");
        assert!((h.t + 2.0).abs() < 1e-15, "behind the origin t must be -2, got {}", h.t);
        let mt = moller_trumbore(&Vec3::new(0.25, 0.5, 2.0), &Vec3::z(), &a, &b, &c).expect("MT hit");
        assert!((mt.t - h.t).abs() < 1e-14 && (mt.u - h.u).abs() < 1e-14 && (mt.v - h.v).abs() < 1e-14);
    }

    #[test]
    fn parallel_degenerate_and_zero_direction_miss_without_nan() {
        let [a, b, c] = tri();
        let q = LineQuery::new(Vec3::new(0.2, 0.2, 0.0), Vec3::x()).expect("valid line");
        assert_eq!(q.intersect(&a, &b, &c), None, "a line in the triangle's plane must miss");
        let q = LineQuery::new(Vec3::new(0.2, 0.2, 1.0), Vec3::x()).expect("valid line");
        assert_eq!(q.intersect(&a, &b, &c), None, "a parallel line must miss");
        let down = LineQuery::new(Vec3::new(0.0, 0.0, 1.0), -Vec3::z()).expect("valid line");
        assert_eq!(down.intersect(&a, &a, &a), None, "a point triangle must miss");
        assert_eq!(down.intersect(&a, &b, &(b * 2.0)), None, "a needle (collinear) triangle must miss");
        assert_eq!(LineQuery::new(Vec3::zeros(), Vec3::zeros()), None);
        assert_eq!(LineQuery::new(Vec3::new(f64::NAN, 0.0, 0.0), Vec3::z()), None);
        assert_eq!(moller_trumbore(&Vec3::new(0.0, 0.0, 1.0), &-Vec3::z(), &a, &a, &a), None);
    }

    #[test]
    fn shared_edge_and_vertex_are_hit_exactly_once() {
        // A square split along its diagonal, and a fan of 6 triangles around the origin.
        let p = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let square = [[0, 1, 2], [0, 2, 3]];
        for origin in [Vec3::new(0.5, 0.5, 1.0), Vec3::new(0.25, 0.25, -1.0), Vec3::new(0.75, 0.75, 1.0), Vec3::new(0.1, 0.1, -2.0)] {
            for dir in [Vec3::z(), -Vec3::z(), Vec3::new(0.0, 0.0, 3.0)] {
                let q = LineQuery::new(origin, dir).expect("valid");
                let hits = square.iter().filter(|t| q.intersect(&p[t[0]], &p[t[1]], &p[t[2]]).is_some()).count();
                assert_eq!(hits, 1, "line from {origin:?} along {dir:?} through the diagonal must hit once");
            }
        }
        let mut fan = vec![Vec3::zeros()];
        for k in 0..6 {
            let a = k as f64 * std::f64::consts::PI / 3.0;
            fan.push(Vec3::new(a.cos(), a.sin(), 0.1 * (k % 2) as f64));
        }
        for dir in [Vec3::z(), Vec3::new(0.1, 0.2, 1.0), Vec3::new(0.0, 1.0, 1.0)] {
            let q = LineQuery::new(-dir, dir).expect("valid");
            let hits = (0..6).filter(|&k| q.intersect(&fan[0], &fan[1 + k], &fan[1 + (k + 1) % 6]).is_some()).count();
            assert_eq!(hits, 1, "a line through the fan's centre vertex along {dir:?} must hit exactly one triangle");
        }
    }
}
