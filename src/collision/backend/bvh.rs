//! BVH backend: parry's `partitioning::Bvh` over the deformed surface's triangle
//! AABBs, built once (PLOC) and REFIT every frame (`insert_or_update_partially` +
//! `refit_without_opt`: the tree's topology never changes), traversed per ray with
//! our f64 watertight line test at the leaves.
//!
//! In: triangles (fixed), positions per frame, rays. Out: nearest hits per ray,
//! bit for bit those of `reference`. Stays true: pruning is conservative. A node is
//! skipped only when the line misses its box grown by `margin` in every direction,
//! or when the line's parameter interval through that grown box lies beyond the
//! current nearest hits by more than `margin` on both sides. `margin` is 1e-7 of
//! the surface's bounding-box diagonal, so a leaf can only be skipped wrongly when
//! the rounding error of a hit's `t` exceeds that (a line within about 1e-9 rad of
//! a triangle's plane). Exact ties are kept (never pruned) and go to the lower
//! triangle index by [`LineAccumulator::offer`], whatever the visiting order.

use super::{LineAccumulator, PairHits, PairLine, RayCaster, TriangleHit};
use crate::collision::{BackendKind, CollisionError};
use crate::geometry::LineQuery;
use crate::math::Vec3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, TraversalAction};

/// Relative size of the conservative margin (of the surface's AABB diagonal).
const MARGIN_RELATIVE: f64 = 1e-7;

fn triangle_aabb(positions: &[Vec3], t: &[u32; 3]) -> Aabb {
    let [a, b, c] = t.map(|i| positions[i as usize]);
    let lo = a.inf(&b).inf(&c);
    let hi = a.sup(&b).sup(&c);
    Aabb::new(PVec::new(lo.x, lo.y, lo.z), PVec::new(hi.x, hi.y, hi.z))
}

/// Refit-per-frame BVH ray caster.
#[derive(Clone)]
pub struct BvhCaster {
    triangles: Vec<[u32; 3]>,
    positions: Vec<Vec3>,
    bvh: Bvh,
    margin: f64,
}

impl BvhCaster {
    /// Builds the tree once over the triangles at `positions` (indices validated by the caller).
    pub fn new(triangles: &[[u32; 3]], positions: &[Vec3]) -> Self {
        let leaves: Vec<Aabb> = triangles.iter().map(|t| triangle_aabb(positions, t)).collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Ploc, &leaves);
        let mut s = Self { triangles: triangles.to_vec(), positions: positions.to_vec(), bvh, margin: 0.0 };
        s.margin = s.compute_margin();
        s
    }

    fn compute_margin(&self) -> f64 {
        if self.bvh.is_empty() {
            return 0.0;
        }
        let root = self.bvh.root_aabb();
        let d = root.maxs - root.mins;
        MARGIN_RELATIVE * d.length().max(f64::MIN_POSITIVE)
    }

    /// Nearest hits of one pair line (traversal of the current tree).
    pub fn cast_one(&self, ray: &PairLine) -> PairHits {
        let mut best = LineAccumulator::new(ray.thickness);
        let Some(query) = LineQuery::new(ray.origin, ray.direction) else {
            return best.finish();
        };
        let o = [ray.origin.x, ray.origin.y, ray.origin.z];
        let d = [ray.direction.x, ray.direction.y, ray.direction.z];
        let inv = d.map(|c| if c != 0.0 { 1.0 / c } else { 0.0 });
        let m = self.margin;
        let (triangles, positions) = (&self.triangles, &self.positions);
        self.bvh.traverse(|node| {
            let (mins, maxs) = (node.mins(), node.maxs());
            let (lo, hi) = ([mins.x, mins.y, mins.z], [maxs.x, maxs.y, maxs.z]);
            let mut t0 = f64::NEG_INFINITY;
            let mut t1 = f64::INFINITY;
            for a in 0..3 {
                let (l, h) = (lo[a] - m, hi[a] + m);
                if d[a] == 0.0 {
                    if o[a] < l || o[a] > h {
                        return TraversalAction::Prune;
                    }
                } else {
                    let ta = (l - o[a]) * inv[a];
                    let tb = (h - o[a]) * inv[a];
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
            }
            if t0 > t1 + m {
                return TraversalAction::Prune;
            }
            let (need_lo, need_hi) = best.needed_interval(m);
            if t1 < need_lo || t0 > need_hi {
                return TraversalAction::Prune;
            }
            if let Some(k) = node.leaf_data() {
                let [a, b, c] = triangles[k as usize].map(|i| &positions[i as usize]);
                if let Some(h) = query.intersect(a, b, c) {
                    best.offer(TriangleHit { triangle: k, t: h.t, u: h.u, v: h.v });
                }
            }
            TraversalAction::Continue
        });
        best.finish()
    }
}

impl RayCaster for BvhCaster {
    fn kind(&self) -> BackendKind {
        BackendKind::Bvh
    }

    fn update_surface(&mut self, positions: &[Vec3]) -> Result<(), CollisionError> {
        self.positions.copy_from_slice(positions);
        for (k, t) in self.triangles.iter().enumerate() {
            let aabb = triangle_aabb(&self.positions, t);
            let _ = self.bvh.insert_or_update_partially(aabb, k as u32, 0.0);
        }
        self.bvh.refit_without_opt();
        self.margin = self.compute_margin();
        Ok(())
    }

    fn cast(&mut self, lines: &[PairLine], out: &mut Vec<PairHits>) -> Result<(), CollisionError> {
        out.clear();
        out.extend(lines.iter().map(|l| self.cast_one(l)));
        Ok(())
    }
}
