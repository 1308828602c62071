//! The oracle: every ray against every triangle, f64, with the watertight line test.
//!
//! In: triangles, positions, rays. Out: nearest hits per ray. Stays true: the
//! result depends on nothing but the geometry (no visiting order enters it).

use super::{LineAccumulator, PairHits, PairLine, RayCaster, TriangleHit};
use crate::collision::{BackendKind, CollisionError};
use crate::geometry::LineQuery;
use crate::math::Vec3;

/// Brute-force ray caster (the paper's method on the CPU).
#[derive(Debug, Clone)]
pub struct ReferenceCaster {
    triangles: Vec<[u32; 3]>,
    positions: Vec<Vec3>,
}

impl ReferenceCaster {
    /// A caster over `triangles` (indices already validated against `positions`).
    pub fn new(triangles: &[[u32; 3]], positions: &[Vec3]) -> Self {
        Self { triangles: triangles.to_vec(), positions: positions.to_vec() }
    }
}

/// Nearest hits of one pair line over all triangles.
pub fn cast_one(triangles: &[[u32; 3]], positions: &[Vec3], line: &PairLine) -> PairHits {
    let mut best = LineAccumulator::new(line.thickness);
    let Some(query) = LineQuery::new(line.origin, line.direction) else {
        return best.finish();
    };
    for (k, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| &positions[i as usize]);
        if let Some(h) = query.intersect(a, b, c) {
            best.offer(TriangleHit { triangle: k as u32, t: h.t, u: h.u, v: h.v });
        }
    }
    best.finish()
}

impl RayCaster for ReferenceCaster {
    fn kind(&self) -> BackendKind {
        BackendKind::Reference
    }

    fn update_surface(&mut self, positions: &[Vec3]) -> Result<(), CollisionError> {
        self.positions.copy_from_slice(positions);
        Ok(())
    }

    fn cast(&mut self, lines: &[PairLine], out: &mut Vec<PairHits>) -> Result<(), CollisionError> {
        out.clear();
        out.extend(lines.iter().map(|l| cast_one(&self.triangles, &self.positions, l)));
        Ok(())
    }
}
