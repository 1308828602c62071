//! Enforced displacements (paper Eq. 6): vertices of feasible triangles projected
//! onto their face's plane along its normal; U_enf = V_proj - V_rest.
//!
//! In: feasible pairs, the frame's rays (a node's origin lies on its face plane, its
//! direction is the face normal N), current and rest positions. Out: one
//! [`VertexTarget`] per claimed vertex, ascending by vertex.
//! Stays true (rules of the module `collision`, item 4): a vertex is claimed only
//! when it lies on or behind the face plane (depth d = (S - V) · N >= -e, e the
//! contact tolerance, so a vertex held on the plane last frame stays held; no adhesion);
//! the deepest claim wins, exact ties go to the lower (spatula, face, node); the
//! result does not depend on the order of the pairs.

use super::Pair;
use super::backend::SourceRay;
use crate::math::Vec3;
use std::cmp::Ordering;

/// A target for one surface vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexTarget {
    /// Surface-vertex index.
    pub vertex: u32,
    /// Target displacement from REST, metres: V_proj - V_rest.
    pub displacement: Vec3,
    pub spatula: u8,
    /// 0: the +z face, 1: the -z face.
    pub face: u8,
    /// The claiming face's outward unit normal, world.
    pub normal: Vec3,
    /// How far the vertex lay behind the face plane this frame, metres (>= 0).
    pub depth: f64,
    /// The source node (within its spatula) whose pair claimed it.
    pub node: u32,
}

/// Scratch of [`resolve_targets`], reused across frames: the best claim so far of
/// each claimed vertex, found in one pass (no sort of every claim: at 2000 nodes a
/// face the sort of about 20k claims was 1.5 ms of a 3.8 ms collision stage).
#[derive(Debug, Default)]
pub(crate) struct Claims {
    /// Per surface vertex: its entry in `best`, or `NONE`.
    slot: Vec<u32>,
    /// The winning claim of each claimed vertex, in first-claim order.
    best: Vec<VertexTarget>,
    /// (vertex << 32 | entry in `best`), sorted to emit targets by vertex.
    order: Vec<u64>,
}

const NONE: u32 = u32::MAX;

fn claim_order(a: &VertexTarget, b: &VertexTarget) -> Ordering {
    a.vertex
        .cmp(&b.vertex)
        .then(b.depth.total_cmp(&a.depth))
        .then(a.spatula.cmp(&b.spatula))
        .then(a.face.cmp(&b.face))
        .then(a.node.cmp(&b.node))
}

/// Builds the targets of the feasible pairs into `targets` (cleared first).
#[allow(clippy::too_many_arguments)]
pub(crate) fn resolve_targets(
    triangles: &[[u32; 3]],
    current: &[Vec3],
    rest: &[Vec3],
    rays: &[SourceRay],
    feasible: &[Pair],
    spatula_offsets: &[usize],
    contact_tolerances: &[f64],
    other_side: &OtherSide<'_>,
    claims: &mut Claims,
    targets: &mut Vec<VertexTarget>,
) {
    claims.best.clear();
    if claims.slot.len() < current.len() {
        claims.slot.resize(current.len(), NONE);
    }
    for p in feasible {
        let ray = &rays[spatula_offsets[p.spatula as usize] + p.node as usize];
        let n = ray.direction;
        for &vertex in &triangles[p.triangle as usize] {
            let v = current[vertex as usize];
            let depth = (ray.origin - v).dot(&n);
            if depth >= -contact_tolerances[p.spatula as usize] && !other_side.holds(p.spatula as usize, p.face, &v, depth) {
                let projected = v + n * depth;
                let claim = VertexTarget {
                    vertex,
                    displacement: projected - rest[vertex as usize],
                    spatula: p.spatula,
                    face: p.face,
                    normal: n,
                    depth,
                    node: p.node,
                };
                // Keep the least claim by `claim_order` (a total order on distinct
                // claims: one pair per node), whatever the order of the pairs.
                match claims.slot[vertex as usize] {
                    NONE => {
                        claims.slot[vertex as usize] = claims.best.len() as u32;
                        claims.best.push(claim);
                    }
                    k => {
                        let held = &mut claims.best[k as usize];
                        if claim_order(&claim, held) == Ordering::Less {
                            *held = claim;
                        }
                    }
                }
            }
        }
    }
    claims.order.clear();
    claims.order.extend(claims.best.iter().enumerate().map(|(k, t)| (t.vertex as u64) << 32 | k as u64));
    claims.order.sort_unstable();
    targets.clear();
    for &o in &claims.order {
        let t = claims.best[(o & 0xffff_ffff) as usize];
        claims.slot[t.vertex as usize] = NONE;
        targets.push(t);
    }
}

/// The rule that keeps a face from claiming tissue lying on the blade's OTHER
/// face: a vertex past the blade's mid-plane as seen from the claiming face
/// (more than half a thickness behind it), which at the previous pose lay over
/// the blade's footprint (grown by one thickness) at or beyond the other face,
/// belongs to the other face; projecting it onto this face would pull it
/// through the blade. At a V valley's apex the line pushed onto one face was
/// otherwise claimed by the other face next frame, and the two alternated
/// every frame; in the u_shape scene a turning blade moved 0.02 mm into a
/// vertex held on its +z face, and the -z face's ray, hitting the vertex's
/// triangle around the tip, pulled it through (frame 163). Without a previous
/// pose the rule is off.
pub(crate) struct OtherSide<'a> {
    /// Spatula shapes (thickness, footprint).
    pub shapes: &'a [crate::geometry::SpatulaShape],
    pub previous: Option<&'a [crate::geometry::Pose]>,
    pub tolerances: &'a [f64],
}

impl OtherSide<'_> {
    /// True when vertex `v`, `depth` behind face `face` of spatula `s`, belongs to the other face.
    fn holds(&self, s: usize, face: u8, v: &Vec3, depth: f64) -> bool {
        let (Some(previous), Some(shape), Some(&tol)) = (self.previous, self.shapes.get(s), self.tolerances.get(s)) else {
            return false;
        };
        let Some(pose) = previous.get(s) else { return false };
        if depth <= 0.5 * shape.thickness {
            return false;
        }
        let q = pose.rotation.inverse_transform_vector(&(v - pose.position));
        let side = if face == 0 { q.z } else { -q.z };
        // Over the footprint grown by one thickness (a vertex at the blade's edge is claimed through its triangle).
        let m = shape.thickness;
        let over = q.x >= -m && q.x <= shape.length + m && q.y.abs() <= 0.5 * shape.width + m;
        // At or beyond the other face, give or take a thousandth of the thickness:
        // a vertex held on that face sits on its plane only to the solver's
        // accuracy (f32 compliance rows, a few nm on a brain), more than the
        // contact tolerance (1e-6 of the thickness). At a blade's tip on the fine
        // real brain (blades 18 mm deep), a vertex held on the upper face 1 nm
        // inside the slab was claimed by the lower face's ray through its
        // triangle and went 5.6 mm through the blade in one frame. (A quarter
        // thickness also fixed it but gave the other face vertices that had
        // really crossed three quarters of a fast blade, changing the study's
        // answers widely; a thousandth changes only its culling-off row.)
        over && side <= -0.5 * shape.thickness + (1e-3 * shape.thickness).max(tol)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NO_PREVIOUS: OtherSide<'static> = OtherSide { shapes: &[], previous: None, tolerances: &[] };

    #[test]
    fn deepest_claim_wins_and_front_vertices_stay_free() {
        // Triangle 0 straddles the plane z = 0 (face normal +z at the origin); vertex 2 is in front.
        let current = vec![Vec3::new(0.0, 0.0, -0.002), Vec3::new(0.001, 0.0, -0.001), Vec3::new(0.0, 0.001, 0.001)];
        let rest = vec![Vec3::new(0.0, 0.0, -0.001), Vec3::new(0.001, 0.0, -0.001), Vec3::new(0.0, 0.001, 0.0)];
        let triangles = vec![[0, 1, 2]];
        let rays = vec![
            SourceRay { origin: Vec3::zeros(), direction: Vec3::z() },
            // A second spatula's face at z = -0.0015 also claims the triangle: shallower for vertex 0.
            SourceRay { origin: Vec3::new(0.0, 0.0, -0.0015), direction: Vec3::z() },
        ];
        let feasible = vec![
            Pair { spatula: 1, face: 0, node: 0, triangle: 0, t: -0.001 },
            Pair { spatula: 0, face: 0, node: 0, triangle: 0, t: -0.001 },
        ];
        let (mut claims, mut targets) = (Claims::default(), Vec::new());
        resolve_targets(&triangles, &current, &rest, &rays, &feasible, &[0, 1, 2], &[0.0, 0.0], &NO_PREVIOUS, &mut claims, &mut targets);
        assert_eq!(targets.len(), 2, "vertex 2 lies in front of both planes and must stay free: {targets:?}");
        let t0 = targets[0];
        assert_eq!((t0.vertex, t0.spatula), (0, 0), "the deeper claim (spatula 0, depth 2 mm) must win vertex 0");
        assert!((t0.displacement - Vec3::new(0.0, 0.0, 0.001)).norm() < 1e-15, "U = V_proj - V_rest = (0,0,0) - (0,0,-1mm)");
        assert_eq!(targets[1].vertex, 1);
        // Order independence.
        let reversed: Vec<Pair> = feasible.iter().rev().copied().collect();
        let mut again = Vec::new();
        resolve_targets(&triangles, &current, &rest, &rays, &reversed, &[0, 1, 2], &[0.0, 0.0], &NO_PREVIOUS, &mut claims, &mut again);
        assert_eq!(again, targets, "targets must not depend on the order of the feasible pairs");
    }

    #[test]
    fn a_vertex_the_blade_moved_into_stays_with_the_face_it_lay_on() {
        use crate::geometry::{Pose, SpatulaShape};
        // A 1 mm blade at the origin (faces z = +-0.5 mm); the vertex lay on its +z
        // face and the blade moved 0.02 mm into it. The -z face's ray (origin on
        // z = -0.5 mm, direction -z) sees it 0.98 mm behind: past the mid-plane.
        let shapes = [SpatulaShape { length: 0.04, width: 0.01, thickness: 0.001 }];
        let previous = [Pose { position: Vec3::new(0.0, 0.0, -0.00002), ..Pose::default() }];
        let other = OtherSide { shapes: &shapes, previous: Some(&previous), tolerances: &[1e-6] };
        let current = vec![Vec3::new(0.02, 0.0, 0.00048), Vec3::new(0.02, 0.001, 0.00048), Vec3::new(0.021, 0.0, 0.00048)];
        let rays = vec![SourceRay { origin: Vec3::new(0.02, 0.0, -0.0005), direction: -Vec3::z() }];
        let feasible = vec![Pair { spatula: 0, face: 1, node: 0, triangle: 0, t: -0.00098 }];
        let (mut claims, mut targets) = (Claims::default(), Vec::new());
        resolve_targets(&[[0, 1, 2]], &current, &current, &rays, &feasible, &[0, 1], &[1e-6], &other, &mut claims, &mut targets);
        assert!(targets.is_empty(), "the -z face must not pull the +z face's tissue through the blade: {targets:?}");
        // Without the previous pose the rule is off and the claim goes through.
        resolve_targets(&[[0, 1, 2]], &current, &current, &rays, &feasible, &[0, 1], &[1e-6], &NO_PREVIOUS, &mut claims, &mut targets);
        assert_eq!(targets.len(), 3);
    }

    #[test]
    fn a_vertex_held_on_the_other_face_to_the_solvers_accuracy_stays_there() {
        use crate::geometry::{Pose, SpatulaShape};
        // The fine real brain's case: a 0.5 mm blade moving up 0.0525 mm a frame;
        // at the previous pose the vertex sat on the +z face 1 nm inside the slab
        // (the solver holds it on the plane only that well), near the tip.
        let shapes = [SpatulaShape { length: 0.06, width: 0.008, thickness: 0.0005 }];
        let previous = [Pose::default()];
        let tol = 1e-6 * 0.0005;
        let other = OtherSide { shapes: &shapes, previous: Some(&previous), tolerances: &[tol] };
        let v = Vec3::new(0.0576, 0.0, 0.00025 - 1e-9);
        // Seen from the -z face at the new pose (0.0525 mm higher): 0.4475 mm behind, past the mid-plane.
        assert!(other.holds(0, 1, &v, 0.0004475), "the +z face's vertex is not the -z face's to claim");
        // A vertex in front of the -z face at the previous pose stays the -z face's.
        assert!(!other.holds(0, 1, &Vec3::new(0.0576, 0.0, -0.0003), 0.0004475));
        // One that had crossed most of the blade (10 um short of the +z face) is not held by the +z face.
        assert!(!other.holds(0, 1, &Vec3::new(0.0576, 0.0, 0.00025 - 1e-5), 0.0004475));
    }

    #[test]
    fn exact_tie_goes_to_lower_spatula() {
        let current = vec![Vec3::new(0.0, 0.0, -0.001), Vec3::new(1.0, 0.0, -0.001), Vec3::new(0.0, 1.0, -0.001)];
        let rays = vec![SourceRay { origin: Vec3::zeros(), direction: Vec3::z() }; 2];
        let feasible = vec![
            Pair { spatula: 1, face: 0, node: 0, triangle: 0, t: -0.001 },
            Pair { spatula: 0, face: 0, node: 0, triangle: 0, t: -0.001 },
        ];
        let (mut claims, mut targets) = (Claims::default(), Vec::new());
        resolve_targets(&[[0, 1, 2]], &current, &current, &rays, &feasible, &[0, 1, 2], &[0.0, 0.0], &NO_PREVIOUS, &mut claims, &mut targets);
        assert!(targets.iter().all(|t| t.spatula == 0), "equal depth: the lower spatula index must win: {targets:?}");
    }
}
