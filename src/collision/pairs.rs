//! Candidate pairs (paper A2): a source node and the nearest triangle behind it,
//! kept when the triangle faces the node's face (N · N_tri < 0).
//!
//! In: the frame's rays and nearest hits, the surface. Out: candidate [`Pair`]s in
//! ray order (spatula, face, node). Stays true: a zero-area triangle (zero normal)
//! is never a candidate; nothing here produces NaN.

use super::SlotFaces;
use super::backend::{NearestHits, SourceRay};
use crate::math::Vec3;

/// A source node paired with a surface triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    pub spatula: u8,
    /// 0: the +z face, 1: the -z face.
    pub face: u8,
    /// Node index within the spatula (`face * pairs + k`).
    pub node: u32,
    /// Surface triangle index.
    pub triangle: u32,
    /// Signed line parameter of the hit (metres, <= 0 for a candidate: its depth is -t).
    pub t: f64,
}

impl Pair {
    /// (spatula, face, node, triangle): the identity of a pair, without its f64 data.
    pub fn key(&self) -> (u8, u8, u32, u32) {
        (self.spatula, self.face, self.node, self.triangle)
    }
}

/// Un-normalised normal (v1 - v0) x (v2 - v0) of triangle `t` at `positions`.
#[inline]
pub fn triangle_normal(positions: &[Vec3], t: &[u32; 3]) -> Vec3 {
    let [a, b, c] = t.map(|i| positions[i as usize]);
    (b - a).cross(&(c - a))
}

/// Appends the candidate pairs of every ray to `out`.
pub(crate) fn collect_candidates(
    triangles: &[[u32; 3]],
    positions: &[Vec3],
    rays: &[SourceRay],
    hits: &[NearestHits],
    tags: SlotFaces<'_>,
    out: &mut Vec<Pair>,
) {
    for (r, (ray, h)) in rays.iter().zip(hits).enumerate() {
        let Some(b) = h.behind else { continue };
        let n = triangle_normal(positions, &triangles[b.triangle as usize]);
        if ray.direction.dot(&n) < 0.0 {
            let (spatula, face, node) = tags.tag(r);
            out.push(Pair { spatula, face, node, triangle: b.triangle, t: b.t });
        }
    }
}
