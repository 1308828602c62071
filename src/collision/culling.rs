//! History culling (paper B1–B3): His-flags per source node; the nearest front
//! triangles of flagged nodes are infeasible for their spatula; candidates using
//! them are culled.
//!
//! In: last frame's flags, this frame's nearest hits and candidates. Out: culled
//! pairs (with the flagged node that made each infeasible) and feasible pairs, both
//! in ray order. Stays true: no allocation per frame (a generation-stamped marker per
//! triangle replaces a set); the result does not depend on anything but the inputs.

use super::Pair;
use super::backend::NearestHits;
use std::ops::Range;

/// Why a candidate pair was culled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CullReason {
    /// Its triangle is the nearest triangle in front of `node` (same spatula),
    /// whose His-flag was on: the lowest such node is named.
    FrontOfFlaggedNode { node: u32 },
    /// Its hit point lay beyond the blade's other face at the previous pose
    /// (swept-side rule): pushing it would pull tissue through the blade.
    CrossedBlade { previous_side_m: f64 },
}

/// Swept-side culling (rule 3b of the stage docs): moves the feasible pairs whose
/// hit point was on the far side of the blade at the previous pose into `culled`.
/// Keeps the ray order of the remaining feasible pairs.
pub(crate) fn cull_swept(
    rays: &[super::backend::SourceRay],
    offsets: &[usize],
    spatulas: &[super::SpatulaSpec],
    previous: &[crate::geometry::Pose],
    tolerances: &[f64],
    feasible: &mut Vec<Pair>,
    culled: &mut Vec<(Pair, CullReason)>,
) {
    feasible.retain(|p| {
        let s = p.spatula as usize;
        let ray = &rays[offsets[s] + p.node as usize];
        let hit = ray.origin + ray.direction * p.t;
        let pose = &previous[s];
        let shape = &spatulas[s].shape;
        let q = pose.rotation.inverse_transform_vector(&(hit - pose.position));
        let inside_footprint = q.x >= 0.0 && q.x <= shape.length && q.y.abs() <= 0.5 * shape.width;
        // Signed distance along this face's outward normal (+z for face 0, -z for face 1).
        let side = if p.face == 0 { q.z } else { -q.z };
        if inside_footprint && side < -0.5 * shape.thickness - tolerances[s] {
            culled.push((*p, CullReason::CrossedBlade { previous_side_m: side }));
            false
        } else {
            true
        }
    });
}

/// One His-flag per ray slot.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct HisFlags(Vec<bool>);

impl Clone for HisFlags {
    fn clone(&self) -> Self {
        Self(self.0.clone())
    }
    /// Reuses the buffer (the pipeline saves the flags every sub-step).
    fn clone_from(&mut self, source: &Self) {
        self.0.clone_from(&source.0);
    }
}

impl HisFlags {
    /// `n` flags, all off.
    pub fn new(n: usize) -> Self {
        Self(vec![false; n])
    }
    pub fn get(&self, slot: usize) -> bool {
        self.0[slot]
    }
    pub fn set(&mut self, slot: usize, on: bool) {
        self.0[slot] = on;
    }
    pub fn clear(&mut self) {
        self.0.fill(false);
    }
    /// Number of flags on.
    pub fn count(&self) -> usize {
        self.0.iter().filter(|&&f| f).count()
    }
    pub fn as_slice(&self) -> &[bool] {
        &self.0
    }
}

/// Per-triangle infeasibility marks, reused across frames.
#[derive(Debug, Clone)]
pub(crate) struct Culler {
    stamp: Vec<u64>,
    by_node: Vec<u32>,
    generation: u64,
}

impl Culler {
    pub fn new(triangle_count: usize) -> Self {
        Self { stamp: vec![0; triangle_count], by_node: vec![0; triangle_count], generation: 0 }
    }

    /// Splits the candidates of `spatula` (whose ray slots are `range`) into culled and
    /// feasible. With `enabled == false` all of them are feasible.
    #[allow(clippy::too_many_arguments)]
    pub fn cull_spatula(
        &mut self,
        enabled: bool,
        flags: &HisFlags,
        range: Range<usize>,
        hits: &[NearestHits],
        candidates: &[Pair],
        spatula: u8,
        culled: &mut Vec<(Pair, CullReason)>,
        feasible: &mut Vec<Pair>,
    ) {
        self.generation += 1;
        let g = self.generation;
        let offset = range.start;
        if enabled {
            for r in range {
                if !flags.get(r) {
                    continue;
                }
                if let Some(f) = hits[r].front {
                    let k = f.triangle as usize;
                    if self.stamp[k] != g {
                        self.stamp[k] = g;
                        self.by_node[k] = (r - offset) as u32;
                    }
                }
            }
        }
        for p in candidates.iter().filter(|p| p.spatula == spatula) {
            let k = p.triangle as usize;
            if enabled && self.stamp[k] == g {
                culled.push((*p, CullReason::FrontOfFlaggedNode { node: self.by_node[k] }));
            } else {
                feasible.push(*p);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::backend::TriangleHit;

    fn hit(triangle: u32, t: f64) -> Option<TriangleHit> {
        Some(TriangleHit { triangle, t, u: 0.3, v: 0.3 })
    }

    #[test]
    fn front_triangles_of_flagged_nodes_cull_candidates() {
        // Two nodes; node 0 flagged with front triangle 7; node 1 has candidate on 7 and node 0 on 3.
        let mut flags = HisFlags::new(2);
        flags.set(0, true);
        let hits = vec![NearestHits { behind: hit(3, -0.1), front: hit(7, 0.2) }, NearestHits { behind: hit(7, -0.05), front: None }];
        let candidates = vec![
            Pair { spatula: 0, face: 0, node: 0, triangle: 3, t: -0.1 },
            Pair { spatula: 0, face: 1, node: 1, triangle: 7, t: -0.05 },
        ];
        let mut c = Culler::new(10);
        let (mut culled, mut feasible) = (Vec::new(), Vec::new());
        c.cull_spatula(true, &flags, 0..2, &hits, &candidates, 0, &mut culled, &mut feasible);
        assert_eq!(feasible, vec![candidates[0]], "the pair on triangle 3 is not in front of a flagged node");
        assert_eq!(culled, vec![(candidates[1], CullReason::FrontOfFlaggedNode { node: 0 })]);
        // Next generation: marks from the previous call must not leak.
        let (mut culled, mut feasible) = (Vec::new(), Vec::new());
        c.cull_spatula(true, &HisFlags::new(2), 0..2, &hits, &candidates, 0, &mut culled, &mut feasible);
        assert!(culled.is_empty(), "no flags on: nothing may be culled, got {culled:?}");
        let (mut culled, mut feasible) = (Vec::new(), Vec::new());
        c.cull_spatula(false, &flags, 0..2, &hits, &candidates, 0, &mut culled, &mut feasible);
        assert!(culled.is_empty() && feasible.len() == 2, "culling off keeps every candidate");
    }
}
