//! Blade barrier rows: with unilateral spatula contact, every surface vertex
//! near a blade that no ray of that blade claimed gets one non-penetration row
//! on the face it lies in front of, so a released or unclaimed vertex can end on
//! the blade but never inside it or through it.
//!
//! In: the spatula shapes and poses before and after the frame's move, the
//! collision stage's output for this frame (targets, feasible pairs, nearest
//! hits), the surface triangles, the surface positions at the start of the
//! frame and at rest. Out: [`ConstraintKind::Barrier`] rows appended to the
//! frame's constraints (the solver's active set turns on only those that would
//! be violated; an inactive row costs one candidate evaluation and no force).
//!
//! Which vertices, per spatula (at most one row a vertex and spatula; the first
//! rule that gives one wins):
//! 1. Over the footprint: start position, in the new pose's blade frame, over the
//!    blade's footprint and within
//!    `thickness / 2 + BARRIER_BAND_M + travel` of its mid-plane, `travel` the
//!    largest move of a footprint corner this frame (a fast blade gets a wider
//!    band). Face: the side of the mid-plane the vertex was on at the PREVIOUS
//!    pose when it lay over the old (grown) footprint and outside the old blade (the
//!    swept-side rule of the collision stage: tissue never changes side of a
//!    blade); otherwise the side it is on now.
//! 2. Along the rays: the vertices of a triangle a source node's ray hits in
//!    front of its face within the band, and the unclaimed vertices of a
//!    feasible pair's triangle (the paper's claim covers whole triangles, which
//!    reach past the footprint; without this a vertex claimed in one frame and
//!    free in the next springs back behind the face plane and the contact
//!    chatters between the two states). Face: the ray's. Only vertices in front
//!    of (or on) the face plane at the start of the frame: one already behind it
//!    lies beyond the blade's tip or edge, and a row would shove it sideways.
//! 3. Claimed last frame: a vertex the blade's face claimed in the previous frame
//!    and that no rule above covers keeps a row on that face while it lies within
//!    the band of the face plane, over the footprint grown by [`BARRIER_BAND_M`],
//!    and not behind the face plane. Without it a blade wedged in
//!    a V valley alternated every frame between holding one wall and the other:
//!    pushing one wall drags the apex, and the free wall bulged under the blade.
//! 4. Around the tip and side edges: a vertex off the footprint, in the band
//!    ahead of the tip (`x > length`) or beside a side edge, nearer that end
//!    face's plane than a broad face's, and covered by no rule above, gets a
//!    row on the end face. A vertex a turning blade carried on its face to
//!    just past the tip would otherwise spring back towards its rest position,
//!    which the blade now covers (u_shape scene, frame 222: 0.38 mm inside).
//!    A vertex between the broad faces and on the tip's or a side edge's plane
//!    (to rounding, where such a row holds it) is beside the blade too: rule 1
//!    gave it a broad face's row, which lifted it 0.4 mm onto that face; free
//!    there, it sprang back beside the edge, and a held blade's contact cycled
//!    through these states every frame (the refined default scene's hold).
//!    Last: a vertex rule 3 keeps on its face stays there (a tip row instead
//!    made the apex of a V valley alternate between the two every frame).
//!    Nothing behind the base (the shaft continues there).
//!
//! A vertex a blade's rays claimed is that blade's contact (held, sliding or
//! released on its own face) and gets no barrier from it.
//!
//! Stays true: the rows are a function of the inputs only (fixed order:
//! spatula, rule 1 by surface vertex, rule 2 by ray, then rules 3 and 4 in
//! that order); no allocation once the mark buffers have grown.

use crate::collision::backend::NearestHits;
use crate::collision::{CollisionStage, Pair, SourceNode, VertexTarget};
use crate::fem::{Constraint, ConstraintKind};
use crate::geometry::{Pose, SpatulaShape};
use crate::math::Vec3;
use super::rest_grid::{Near, RestGrid};

/// How far beyond a face (m) a vertex still gets a barrier row, besides the blade's travel.
pub const BARRIER_BAND_M: f64 = 2.0e-3;
/// A vertex within this distance (m) of a face counts as on that face's side.
const SIDE_TOLERANCE_M: f64 = 1e-7;

/// Per-frame barrier rows of every blade; holds only mark buffers.
#[derive(Debug, Clone, Default)]
pub struct BarrierStage {
    /// Per surface vertex: bit s set when spatula s claimed it this frame.
    claimed: Vec<u32>,
    /// Per surface vertex: bit s set when it has a barrier row from spatula s.
    barred: Vec<u32>,
    /// Last frame's claims (surface vertex, spatula, face), in target order.
    previous_claims: Vec<(u32, u8, u8)>,
    /// This frame's rule-4 candidates (surface vertex, spatula, end-face normal
    /// and a point of its plane), in rule-1 order.
    end_candidates: Vec<(u32, u8, Vec3, Vec3)>,
    /// The vertices with a bit set in `claimed` or `barred`: the entries to clear next frame.
    marked: Vec<u32>,
    /// Rule 1's vertices near a blade ([`RestGrid::near`]).
    near: Near,
}

/// The blades of one frame: shapes and poses before and after the move.
#[derive(Debug, Clone, Copy)]
pub struct Blades<'a> {
    pub shapes: &'a [SpatulaShape],
    pub before: &'a [Pose],
    pub after: &'a [Pose],
}

/// The surface: triangles (surface-vertex indices), positions at the start of
/// the frame and at rest, surface vertex -> mesh node; optionally the rest
/// positions' grid and a bound on `start - rest` ([`super::rest_grid::displacement_bound`]),
/// with which rule 1 reads only the vertices near a blade (the same rows).
#[derive(Debug, Clone, Copy)]
pub struct SurfaceState<'a> {
    pub triangles: &'a [[u32; 3]],
    pub start: &'a [Vec3],
    pub rest: &'a [Vec3],
    pub nodes: &'a [u32],
    pub grid: Option<(&'a RestGrid, f64)>,
}

/// What the collision stage's rays saw this frame (rule 2): source nodes and
/// their nearest hits (one per ray slot, same order) and the feasible pairs.
#[derive(Debug, Clone, Copy)]
pub struct Rays<'a> {
    pub source_nodes: &'a [SourceNode],
    pub hits: &'a [NearestHits],
    pub feasible: &'a [Pair],
}

/// Distance (m) from `p` to the blade's box at `pose` (0 inside it).
pub fn distance_to_blade(shape: &SpatulaShape, pose: &Pose, p: &Vec3) -> f64 {
    let q = local(pose, p);
    let (lo, hi) = (Vec3::new(0.0, -0.5 * shape.width, -0.5 * shape.thickness), Vec3::new(shape.length, 0.5 * shape.width, 0.5 * shape.thickness));
    Vec3::from_fn(|i, _| (lo[i] - q[i]).max(q[i] - hi[i]).max(0.0)).norm()
}

#[inline]
fn local(pose: &Pose, p: &Vec3) -> Vec3 {
    pose.rotation.inverse_transform_vector(&(p - pose.position))
}

#[inline]
fn over_footprint(shape: &SpatulaShape, q: &Vec3, margin: f64) -> bool {
    q.x >= -margin && q.x <= shape.length + margin && q.y.abs() <= 0.5 * shape.width + margin
}

/// Between the broad faces' planes and on the tip's or a side edge's plane to [`SIDE_TOLERANCE_M`]: a vertex
/// an end-face row holds there lies beside the blade to rounding, not over its footprint.
#[inline]
fn on_end_plane(shape: &SpatulaShape, q: &Vec3) -> bool {
    q.z.abs() < 0.5 * shape.thickness - SIDE_TOLERANCE_M
        && (q.x > shape.length - SIDE_TOLERANCE_M || q.y.abs() > 0.5 * shape.width - SIDE_TOLERANCE_M)
}

/// The plane that separates a point off the footprint (`q`, blade frame of
/// `pose`) from the blade, when the point lies within `band` beyond the tip
/// (`x = length`) or a side edge (`y = ±width/2`): outward normal and a point
/// of the plane, world. Nearer that end face's plane than a broad face's
/// (`|z| - thickness/2` at most its distance beyond the end): the end face's
/// plane. Diagonally off an edge (farther beyond a broad face's plane than
/// beyond the end, and within `band` of it): the plane touching the blade at
/// its nearest point, normal from there to the point, so the vertex may pass
/// beside or below the edge but not into it (without it a vertex 0.2 mm below
/// a face and a hair beside its edge got no row and ended 0.09 mm inside the
/// blade: the fine real brain, a flap swinging back when the blades stopped).
/// `None` for points behind the blade's base (the shaft continues there) or
/// farther than `band`.
fn end_face(shape: &SpatulaShape, pose: &Pose, q: &Vec3, band: f64) -> Option<(Vec3, Vec3)> {
    if q.x < 0.0 {
        return None;
    }
    let beyond_tip = q.x - shape.length;
    let beyond_side = q.y.abs() - 0.5 * shape.width;
    let beyond = beyond_tip.max(beyond_side);
    if !(beyond > 0.0 || on_end_plane(shape, q)) || beyond > band {
        return None;
    }
    let (half_l, half_w, half_t) = (shape.length, 0.5 * shape.width, 0.5 * shape.thickness);
    if q.z.abs() - half_t > beyond {
        if q.z.abs() - half_t > band {
            return None;
        }
        let nearest = Vec3::new(q.x.clamp(0.0, half_l), q.y.clamp(-half_w, half_w), q.z.clamp(-half_t, half_t));
        let n_local = (q - nearest).normalize();
        return Some((pose.rotation * n_local, pose.position + pose.rotation * nearest));
    }
    let (n_local, p_local) = if beyond_tip >= beyond_side {
        (Vec3::x(), Vec3::new(shape.length, 0.0, 0.0))
    } else {
        let sign = q.y.signum();
        (Vec3::y() * sign, Vec3::new(0.0, sign * 0.5 * shape.width, 0.0))
    };
    Some((pose.rotation * n_local, pose.position + pose.rotation * p_local))
}

/// The world axis-aligned bounds of the box `lo..hi` of the blade frame at
/// `pose`, grown by `grow` (m).
pub fn world_bounds(pose: &Pose, lo: &Vec3, hi: &Vec3, grow: f64) -> (Vec3, Vec3) {
    let centre = pose.position + pose.rotation * ((lo + hi) * 0.5);
    let half = (hi - lo) * 0.5;
    let axes = pose.rotation.to_rotation_matrix();
    let extent = Vec3::from_fn(|i, _| (0..3).map(|k| axes[(i, k)].abs() * half[k]).sum::<f64>() + grow);
    (centre - extent, centre + extent)
}

/// Whether `p` lies outside the bounds `(lo, hi)`.
#[inline]
pub fn outside_bounds(p: &Vec3, (lo, hi): &(Vec3, Vec3)) -> bool {
    (0..3).any(|i| p[i] < lo[i] || p[i] > hi[i])
}

/// Slack of the world-bounds prefilters (m): far above the rounding of a
/// pose transform, far below anything a rule measures, so a prefilter never
/// drops a vertex the exact test in the blade frame would keep.
const BOUNDS_SLACK_M: f64 = 1e-9;

/// Whether a blade moving from `before` to `after`, through every pose the
/// sub-steps interpolate between them, stays further than `margin` from each
/// surface triangle (`triangles` over `positions`). Conservative: the motion
/// is cut into pieces along which no point of the blade moves more than
/// `margin` (`|dt| + angle x r`, `r` the blade's farthest corner from its
/// frame's origin); a piece is clear when each triangle's bounding sphere lies
/// further than that move plus `margin` from the blade box at the piece's
/// start. A motion of more than [`MAX_SWEEP_PIECES`] pieces is not clear.
pub fn sweep_clear(shape: &SpatulaShape, before: &Pose, after: &Pose, triangles: &[[u32; 3]], positions: &[Vec3], margin: f64) -> bool {
    let moved = largest_point_move(shape, before, after);
    let pieces = (moved / margin).ceil().max(1.0);
    if !(pieces.is_finite() && pieces <= MAX_SWEEP_PIECES as f64 && margin > 0.0) {
        return false;
    }
    let pieces = pieces as u32;
    (0..pieces).all(|k| {
        let a = before.interpolate(after, k as f64 / pieces as f64);
        let b = if k + 1 == pieces { *after } else { before.interpolate(after, (k + 1) as f64 / pieces as f64) };
        piece_clear(shape, &a, largest_point_move(shape, &a, &b) + margin, triangles, positions)
    })
}

/// At most this many pieces in [`sweep_clear`] (as many as a frame's sub-steps).
pub const MAX_SWEEP_PIECES: u32 = 256;

/// A bound on how far any point of the blade moves from `before` to `after`
/// along the interpolated path: `|dt| + angle x r`.
fn largest_point_move(shape: &SpatulaShape, before: &Pose, after: &Pose) -> f64 {
    let dot = before.rotation.quaternion().coords.dot(&after.rotation.quaternion().coords).abs().min(1.0);
    let r = Vec3::new(shape.length, 0.5 * shape.width, 0.5 * shape.thickness).norm();
    (after.position - before.position).norm() + 2.0 * dot.acos() * r
}

/// Every triangle's bounding sphere further than `reach` from the blade box at `pose`.
fn piece_clear(shape: &SpatulaShape, pose: &Pose, reach: f64, triangles: &[[u32; 3]], positions: &[Vec3]) -> bool {
    if !reach.is_finite() {
        return false;
    }
    let half = Vec3::new(0.5 * shape.length, 0.5 * shape.width, 0.5 * shape.thickness);
    // The box in world space, grown by `reach`: a cheap first test.
    let (lo, hi) = world_bounds(pose, &Vec3::new(0.0, -half.y, -half.z), &Vec3::new(shape.length, half.y, half.z), reach);
    triangles.iter().all(|t| {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        let (tlo, thi) = (a.inf(&b).inf(&c), a.sup(&b).sup(&c));
        if (0..3).any(|i| thi[i] < lo[i] || tlo[i] > hi[i]) {
            return true;
        }
        let m = (a + b + c) / 3.0;
        let radius = (a - m).norm().max((b - m).norm()).max((c - m).norm());
        let q = local(pose, &m) - Vec3::new(half.x, 0.0, 0.0);
        let outside = Vec3::from_fn(|i, _| (q[i].abs() - half[i]).max(0.0));
        outside.norm() > reach + radius
    })
}

impl BarrierStage {
    /// A stage for a surface of `surface_vertices` vertices.
    pub fn new(surface_vertices: usize) -> Self {
        Self {
            claimed: vec![0; surface_vertices],
            barred: vec![0; surface_vertices],
            previous_claims: Vec::new(),
            end_candidates: Vec::new(),
            marked: Vec::new(),
            near: Near::default(),
        }
    }

    /// Last frame's claims, to save around a frame that may be undone.
    pub fn previous_claims(&self) -> &[(u32, u8, u8)] {
        &self.previous_claims
    }

    /// Puts back claims saved with [`Self::previous_claims`].
    pub fn restore_previous_claims(&mut self, claims: &[(u32, u8, u8)]) {
        self.previous_claims.clear();
        self.previous_claims.extend_from_slice(claims);
    }

    /// Forgets last frame's claims (a scene reset or a teleported tool).
    pub fn reset(&mut self) {
        self.previous_claims.clear();
    }

    /// Appends the barrier rows of every spatula; returns how many. `collision`
    /// has run this frame on `surface.start` with `blades.after`. With
    /// `claims` the vertices its targets claim get no row (their own rows hold
    /// them); without (sliding contact) every vertex near a blade gets one.
    pub fn push_rows(&mut self, blades: Blades<'_>, collision: &CollisionStage, claims: bool, surface: SurfaceState<'_>, out: &mut Vec<Constraint>) -> usize {
        let output = collision.output();
        let rays = Rays { source_nodes: &output.source_nodes, hits: collision.nearest_hits(), feasible: &output.feasible_pairs };
        let targets = if claims { &output.targets[..] } else { &[] };
        self.push_rows_from(blades, targets, Some(rays), surface, out)
    }

    /// [`Self::push_rows`] from the collision stage's pieces; `rays: None` applies rule 1 only.
    pub fn push_rows_from(
        &mut self,
        blades: Blades<'_>,
        targets: &[VertexTarget],
        rays: Option<Rays<'_>>,
        surface: SurfaceState<'_>,
        out: &mut Vec<Constraint>,
    ) -> usize {
        let n_vertices = surface.start.len();
        if self.claimed.len() == n_vertices && self.barred.len() == n_vertices {
            // Only last frame's marks are set.
            for &v in &self.marked {
                self.claimed[v as usize] = 0;
                self.barred[v as usize] = 0;
            }
        } else {
            self.claimed.clear();
            self.claimed.resize(n_vertices, 0);
            self.barred.clear();
            self.barred.resize(n_vertices, 0);
        }
        self.marked.clear();
        for t in targets {
            if let Some(m) = self.claimed.get_mut(t.vertex as usize) {
                *m |= 1u32 << (t.spatula as u32).min(31);
                self.marked.push(t.vertex);
            }
        }
        self.end_candidates.clear();
        let before = out.len();
        for (s, ((shape, pb), pa)) in blades.shapes.iter().zip(blades.before).zip(blades.after).enumerate() {
            let band = BARRIER_BAND_M + super::substeps::travel(shape, pb, pa);
            self.footprint_rows(s, shape, (pb, pa), band, surface, out);
            if let Some(rays) = rays {
                self.ray_rows(s, rays, band, surface, out);
            }
        }
        self.previous_claim_rows(blades, surface, out);
        // Rule 4: around the tip and side edges, for vertices no rule above covers.
        for i in 0..self.end_candidates.len() {
            let (v, s, n, face_point) = self.end_candidates[i];
            let (v, s) = (v as usize, s as usize);
            if (self.claimed[v] | self.barred[v]) & (1u32 << (s as u32).min(31)) == 0 {
                self.push(v, s, n, face_point, surface, out);
            }
        }
        self.previous_claims.clear();
        self.previous_claims.extend(targets.iter().map(|t| (t.vertex, t.spatula, t.face)));
        out.len() - before
    }

    /// Rule 1 for spatula `s`, moving from `pb` to `pa`: every unclaimed vertex over its footprint within `band` of
    /// its faces gets a row on the face it was on before the move; the vertices beyond the tip or a side edge are
    /// kept for rule 4.
    fn footprint_rows(&mut self, s: usize, shape: &SpatulaShape, (pb, pa): (&Pose, &Pose), band: f64, surface: SurfaceState<'_>, out: &mut Vec<Constraint>) {
        let half = 0.5 * shape.thickness;
        let bit = 1u32 << (s as u32).min(31);
        let axis = pa.rotation * Vec3::z();
        // Rules 1 and 4 reach no vertex outside the footprint grown by the
        // band beyond the tip and the side edges, and by the band off the faces.
        let reach = Vec3::new(shape.length + band, 0.5 * shape.width + band, half + band);
        let bounds = world_bounds(pa, &Vec3::new(0.0, -reach.y, -reach.z), &reach, BOUNDS_SLACK_M);
        // Rule 1: over the footprint; with the grid, only the vertices that may lie in the bounds, in the same order.
        let mut near = std::mem::take(&mut self.near);
        match surface.grid {
            Some((grid, bound)) if grid.len() == surface.start.len() => grid.near(&bounds.0, &bounds.1, bound, &mut near),
            _ => near.all = true,
        }
        near.for_each(surface.start.len(), |v| {
            let p = &surface.start[v];
            if self.claimed[v] & bit != 0 || outside_bounds(p, &bounds) {
                return;
            }
            let q1 = local(pa, p);
            if q1.z.abs() > half + band {
                return;
            }
            if !over_footprint(shape, &q1, 0.0) || on_end_plane(shape, &q1) {
                // Rule 4 (after rules 2 and 3): beyond the tip or a side edge, or on its plane.
                if let Some((n, face_point)) = end_face(shape, pa, &q1, band) {
                    self.end_candidates.push((v as u32, s as u8, n, face_point));
                }
                return;
            }
            let q0 = local(pb, p);
            let side = if over_footprint(shape, &q0, 0.0) && q0.z.abs() >= half - SIDE_TOLERANCE_M {
                q0.z.signum()
            } else if q1.z < 0.0 {
                -1.0
            } else {
                1.0
            };
            self.push(v, s, axis * side, pa.position + axis * (side * half), surface, out);
        });
        self.near = near;
    }

    /// Rule 2 for spatula `s`: the front hits of its rays within `band`, and the unclaimed vertices of its feasible
    /// triangles.
    fn ray_rows(&mut self, s: usize, rays: Rays<'_>, band: f64, surface: SurfaceState<'_>, out: &mut Vec<Constraint>) {
        let Some(first) = rays.source_nodes.iter().position(|n| n.spatula as usize == s) else { return };
        for (node, hits) in rays.source_nodes[first..].iter().zip(&rays.hits[first.min(rays.hits.len())..]).take_while(|(n, _)| n.spatula as usize == s) {
            if let Some(h) = hits.front {
                if h.t <= band {
                    self.bar_triangle(h.triangle, s, node.normal, node.position, surface, out);
                }
            }
        }
        for pair in rays.feasible.iter().filter(|p| p.spatula as usize == s) {
            // Source nodes are in slot order: spatula s's node j is at `first + j`.
            match rays.source_nodes.get(first + pair.node as usize) {
                Some(node) if node.spatula == pair.spatula && node.node == pair.node => {
                    self.bar_triangle(pair.triangle, s, node.normal, node.position, surface, out);
                }
                _ => {}
            }
        }
    }

    /// Rule 3: a vertex claimed last frame, no longer claimed nor barred, still over the footprint and not behind
    /// the face it was claimed on, keeps a row on that face.
    fn previous_claim_rows(&mut self, blades: Blades<'_>, surface: SurfaceState<'_>, out: &mut Vec<Constraint>) {
        let n_vertices = surface.start.len();
        for i in 0..self.previous_claims.len() {
            let (v, s, face) = self.previous_claims[i];
            let (v, s) = (v as usize, s as usize);
            let (Some(shape), Some(pa), Some(pb)) = (blades.shapes.get(s), blades.after.get(s), blades.before.get(s)) else { continue };
            if v >= n_vertices || (self.claimed[v] | self.barred[v]) & (1u32 << (s as u32).min(31)) != 0 {
                continue;
            }
            let half = 0.5 * shape.thickness;
            let band = BARRIER_BAND_M + super::substeps::travel(shape, pb, pa);
            let q1 = local(pa, &surface.start[v]);
            if q1.z.abs() > half + band || !over_footprint(shape, &q1, BARRIER_BAND_M) {
                continue;
            }
            let n = pa.rotation * Vec3::z() * if face == 0 { 1.0 } else { -1.0 };
            let face_point = pa.position + n * half;
            if n.dot(&(surface.start[v] - face_point)) < -SIDE_TOLERANCE_M {
                continue;
            }
            self.push(v, s, n, face_point, surface, out);
        }
    }

    /// Rule 2 for one triangle seen from a face (outward normal `n`, a point `face_point` on it).
    #[allow(clippy::too_many_arguments)]
    fn bar_triangle(&mut self, triangle: u32, s: usize, n: Vec3, face_point: Vec3, surface: SurfaceState<'_>, out: &mut Vec<Constraint>) {
        let Some(tri) = surface.triangles.get(triangle as usize) else { return };
        let bit = 1u32 << (s as u32).min(31);
        for &v in tri {
            let v = v as usize;
            if v >= surface.start.len() || (self.claimed[v] | self.barred[v]) & bit != 0 {
                continue;
            }
            // Already behind the face plane (beyond the tip or an edge, or past the
            // mid-plane: the other face's business): a row would shove it sideways.
            if n.dot(&(surface.start[v] - face_point)) < -SIDE_TOLERANCE_M {
                continue;
            }
            self.push(v, s, n, face_point, surface, out);
        }
    }

    /// One row: vertex `v` stays in front of the plane through `face_point` with normal `n`.
    fn push(&mut self, v: usize, s: usize, n: Vec3, face_point: Vec3, surface: SurfaceState<'_>, out: &mut Vec<Constraint>) {
        self.barred[v] |= 1u32 << (s as u32).min(31);
        self.marked.push(v as u32);
        let p = surface.start[v];
        // The start position projected onto the face plane: a point of the plane near the vertex.
        let on_plane = p - n * n.dot(&(p - face_point));
        out.push(Constraint { node: surface.nodes[v], owner: s as u16, kind: ConstraintKind::Barrier { displacement: on_plane - surface.rest[v], normal: n } });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Quat;

    fn blade() -> SpatulaShape {
        SpatulaShape { length: 0.04, width: 0.01, thickness: 0.001 }
    }

    fn at(z: f64) -> Pose {
        Pose { position: Vec3::new(0.0, 0.0, z), rotation: Quat::identity() }
    }

    fn rows(before: Pose, after: Pose, start: &[Vec3], targets: &[VertexTarget]) -> Vec<Constraint> {
        let mut stage = BarrierStage::new(start.len());
        let mut out = Vec::new();
        let nodes: Vec<u32> = (0..start.len() as u32).map(|v| 10 + v).collect();
        let shapes = [blade()];
        let blades = Blades { shapes: &shapes, before: &[before], after: &[after] };
        let surface = SurfaceState { triangles: &[], start, rest: start, nodes: &nodes, grid: None };
        stage.push_rows_from(blades, targets, None, surface, &mut out);
        out
    }

    /// Rule 1 through the rest grid pushes the rows of the whole pass, in the same order, over displaced surfaces
    /// around a moving blade, and with the same stage (its marks cleared between frames) frame after frame.
    #[test]
    fn rows_through_the_rest_grid_are_the_rows_of_the_whole_pass() {
        let mut next = crate::math::test_rng::uniform(0x853c49e6748fea9bu64);
        let rest: Vec<Vec3> = (0..4000).map(|_| Vec3::new(next() * 0.1 - 0.03, next() * 0.04 - 0.02, next() * 0.02 - 0.01)).collect();
        let nodes: Vec<u32> = (0..rest.len() as u32).map(|v| 10 + v).collect();
        let grid = RestGrid::new(&rest);
        let shapes = [blade()];
        let (mut whole_stage, mut near_stage) = (BarrierStage::new(rest.len()), BarrierStage::new(rest.len()));
        let mut total = 0;
        for round in 0..100 {
            let amp = [0.0, 0.0005, 0.004][round % 3];
            let start: Vec<Vec3> = rest.iter().map(|r| r + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * (2.0 * amp)).collect();
            let bound = super::super::rest_grid::displacement_bound(&start, &rest);
            let before = Pose { position: Vec3::new(next() * 0.01, 0.0, (next() - 0.5) * 0.004), rotation: Quat::from_axis_angle(&Vec3::y_axis(), (next() - 0.5) * 0.3) };
            let after = Pose { position: before.position + Vec3::new(0.001, 0.0, (next() - 0.5) * 0.002), ..before };
            let targets: Vec<VertexTarget> = (0..5).map(|k| VertexTarget { vertex: (round * 37 + k * 11) as u32 % 4000, displacement: Vec3::zeros(), spatula: 0, face: 0, normal: Vec3::z(), depth: 0.0, node: 0 }).collect();
            let blades = Blades { shapes: &shapes, before: &[before], after: &[after] };
            let (mut whole, mut near) = (Vec::new(), Vec::new());
            let surface = SurfaceState { triangles: &[], start: &start, rest: &rest, nodes: &nodes, grid: None };
            whole_stage.push_rows_from(blades, &targets, None, surface, &mut whole);
            near_stage.push_rows_from(blades, &targets, None, SurfaceState { grid: Some((&grid, bound)), ..surface }, &mut near);
            assert_eq!(near, whole, "round {round}");
            assert!(!near_stage.near.all, "round {round}: the blade's bounds are a small part of the surface");
            total += whole.len();
        }
        assert!(total > 1000, "the blade must meet the surface: {total} rows");
    }

    /// One small triangle (1 mm a side) around `centre` (m), in the z = centre.z plane.
    fn triangle_at(centre: Vec3) -> Vec<Vec3> {
        [Vec3::new(-5e-4, -5e-4, 0.0), Vec3::new(5e-4, -5e-4, 0.0), Vec3::new(0.0, 5e-4, 0.0)].iter().map(|d| centre + d).collect()
    }

    #[test]
    fn a_sweep_is_clear_only_when_no_pose_in_between_comes_near_a_triangle() {
        let shape = blade();
        let tri = [[0u32, 1, 2]];
        let clear = |before: Pose, after: Pose, centre: Vec3, margin: f64| sweep_clear(&shape, &before, &after, &tri, &triangle_at(centre), margin);
        // The blade (40 mm long) slides 60 mm along x, 10 mm above the z = 0 plane.
        let (a, b) = (at(0.01), Pose { position: Vec3::new(0.06, 0.0, 0.01), ..at(0.01) });
        assert!(clear(a, b, Vec3::new(0.05, 0.05, 0.01), 1e-3), "50 mm beside the path");
        assert!(clear(a, b, Vec3::new(0.05, 0.0, 0.0), 1e-3), "10 mm under the path");
        assert!(!clear(a, b, Vec3::new(0.05, 0.0, 0.01), 1e-3), "on the path, between the two end poses");
        assert!(!clear(a, b, Vec3::new(0.05, 0.0, 0.008), 1e-3), "1.5 mm under the path");
        // Still: clear unless the triangle lies within the margin.
        assert!(clear(a, a, Vec3::new(0.02, 0.0, 0.0), 1e-3), "10 mm under a blade that stays");
        assert!(!clear(a, a, Vec3::new(0.02, 0.0, 0.0), 0.0095), "the margin reaches the triangle's edge");
        // A turn of 90 degrees about z: the tip sweeps a quarter circle of 40 mm
        // radius, through a triangle neither end pose comes near.
        let turned = Pose { rotation: Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2), ..a };
        let on_arc = Vec3::new(0.04 * 0.25_f64.cos(), 0.04 * 0.25_f64.sin(), 0.01);
        assert!(!clear(a, turned, on_arc, 1e-3), "the tip's arc");
        assert!(clear(a, turned, Vec3::new(-0.1, -0.1, 0.01), 1e-3), "behind the handle, far");
        // Not a pose, or a move of more than the pieces allowed: never clear.
        let nan = Pose { position: Vec3::new(f64::NAN, 0.0, 0.0), ..a };
        assert!(!clear(a, nan, Vec3::new(1.0, 1.0, 1.0), 1e-3));
        let far = Pose { position: Vec3::new(1.0, 0.0, 0.01), ..a };
        assert!(clear(a, far, Vec3::new(0.5, 0.0, -0.05), 1e-2), "a metre in 100 pieces, 60 mm above the triangle");
        assert!(!clear(a, far, Vec3::new(0.5, 0.0, -0.05), 1e-3), "a metre is more than 256 pieces of a millimetre");
    }

    #[test]
    fn a_vertex_the_blade_jumped_past_keeps_its_old_side() {
        // The vertex lay 1 mm above the blade; the blade moved 3 mm up past it.
        let start = [Vec3::new(0.02, 0.0, 0.001)];
        let out = rows(at(0.0), at(0.003), &start, &[]);
        assert_eq!(out.len(), 1, "the vertex is within the band of the moved blade");
        let ConstraintKind::Barrier { displacement, normal } = out[0].kind else { panic!("not a barrier: {:?}", out[0].kind) };
        assert_eq!(out[0].node, 10);
        assert!((normal - Vec3::z()).norm() < 1e-15, "the +z face (its old side), got {normal:?}");
        // The plane is the +z face at the new pose: z = 3.5 mm; the row asks u.z >= 2.5 mm.
        assert!((normal.dot(&displacement) - 0.0025).abs() < 1e-12, "n . g = {}", normal.dot(&displacement));
    }

    #[test]
    fn claimed_far_and_off_footprint_vertices_get_no_row() {
        let start = [
            Vec3::new(0.02, 0.0, -0.001),  // below: the -z face
            Vec3::new(0.02, 0.0, 0.004),   // 3.5 mm above the face: outside the 2 mm band
            Vec3::new(0.02, 0.008, 0.0),   // beside the blade (|y| > 5.5 mm)
            Vec3::new(0.02, 0.0, 0.0008),  // claimed by the blade's rays
        ];
        let claim = VertexTarget { vertex: 3, displacement: Vec3::zeros(), spatula: 0, face: 0, normal: Vec3::z(), depth: 0.0, node: 0 };
        let out = rows(at(0.0), at(0.0), &start, &[claim]);
        assert_eq!(out.len(), 1, "only the vertex below the blade: {out:?}");
        assert_eq!(out[0].node, 10);
        let ConstraintKind::Barrier { normal, .. } = out[0].kind else { panic!() };
        assert!((normal + Vec3::z()).norm() < 1e-15);
    }

    #[test]
    fn vertices_past_the_tip_or_beside_an_edge_get_a_row_on_that_end_face() {
        let start = [
            Vec3::new(0.04001, 0.001, -0.0001), // 0.01 mm past the tip, inside the slab: the tip
            Vec3::new(0.02, -0.0052, 0.0002),   // 0.2 mm beside the -y edge: that edge
            Vec3::new(0.0403, 0.0, 0.0015),     // past the tip but 1 mm above the +z face: the tip's edge
            Vec3::new(-0.001, 0.0, 0.0),        // behind the base (the shaft): none
            Vec3::new(0.045, 0.0, 0.0),         // 5 mm past the tip: outside the band
            Vec3::new(0.0403, 0.0, 0.0031),     // past the tip and 2.6 mm above the face: outside the band
        ];
        let out = rows(at(0.0), at(0.0), &start, &[]);
        assert_eq!(out.len(), 3, "{out:?}");
        let ConstraintKind::Barrier { displacement, normal } = out[0].kind else { panic!() };
        assert_eq!(out[0].node, 10);
        assert!((normal - Vec3::x()).norm() < 1e-15, "the tip's plane, got {normal:?}");
        assert!((normal.dot(&displacement) + 1e-5).abs() < 1e-12, "0.01 mm in front of the tip plane x = 40 mm: the row asks u.x >= -0.01 mm");
        let ConstraintKind::Barrier { normal, .. } = out[1].kind else { panic!() };
        assert_eq!(out[1].node, 11);
        assert!((normal + Vec3::y()).norm() < 1e-15, "the -y edge's plane, got {normal:?}");
        let ConstraintKind::Barrier { displacement, normal } = out[2].kind else { panic!() };
        assert_eq!(out[2].node, 12);
        let expected = Vec3::new(0.3, 0.0, 1.0).normalize();
        assert!((normal - expected).norm() < 1e-12, "from the tip's upper edge towards the vertex, got {normal:?}");
        // The plane touches the edge (x = 40 mm, z = 0.5 mm): the vertex is |(0.3, 1.0)| mm in front of it.
        assert!((normal.dot(&displacement) + 0.3f64.hypot(1.0) * 1e-3).abs() < 1e-12, "n . g = {}", normal.dot(&displacement));
    }

    #[test]
    fn a_vertex_on_an_end_plane_between_the_faces_keeps_that_end_face() {
        // Held on the +y edge's plane (to rounding either side of it) 0.36 mm below the +z face, and on the tip's
        // plane: beside the blade, so the end face's row, not a broad face's (which lifted such a vertex onto the
        // face, from where it sprang back: a held blade's contact cycled every frame).
        let start = [
            Vec3::new(0.02, 0.005 - 1e-12, 0.00014), // a rounding inside the +y edge's plane
            Vec3::new(0.02, 0.005, 0.00014),         // on it
            Vec3::new(0.04 - 1e-12, 0.0, -0.0002),   // a rounding inside the tip's plane
            Vec3::new(0.02, 0.005 - 1e-6, 0.00014),  // 1 um inside the edge: over the footprint, inside the blade
            Vec3::new(0.02, 0.005 - 1e-12, 0.0005),  // on the +z face's plane at the edge: that face
        ];
        let out = rows(at(0.0), at(0.0), &start, &[]);
        assert_eq!(out.len(), 5, "{out:?}");
        let normal = |i: usize| match out.iter().find(|c| c.node == 10 + i as u32).map(|c| c.kind) {
            Some(ConstraintKind::Barrier { normal, .. }) => normal,
            other => panic!("vertex {i}: {other:?}"),
        };
        assert!((normal(0) - Vec3::y()).norm() < 1e-15, "the +y edge's plane, got {:?}", normal(0));
        assert!((normal(1) - Vec3::y()).norm() < 1e-15, "the +y edge's plane, got {:?}", normal(1));
        assert!((normal(2) - Vec3::x()).norm() < 1e-15, "the tip's plane, got {:?}", normal(2));
        assert!((normal(3) - Vec3::z()).norm() < 1e-15, "inside the blade: out through the nearer broad face, got {:?}", normal(3));
        assert!((normal(4) - Vec3::z()).norm() < 1e-15, "on the +z face: that face, got {:?}", normal(4));
    }

    #[test]
    fn a_vertex_below_a_face_a_hair_beside_its_edge_cannot_enter_the_blade() {
        // The fine real brain's flap: 0.23 mm below the -z face, 1e-8 m beside the -y edge.
        let start = [Vec3::new(0.02, -0.005 - 1e-8, -0.0005 - 0.00023)];
        let out = rows(at(0.0), at(0.0), &start, &[]);
        assert_eq!(out.len(), 1, "{out:?}");
        let ConstraintKind::Barrier { displacement, normal } = out[0].kind else { panic!() };
        assert!(normal.z < -0.999 && normal.y < 0.0, "from the lower edge, nearly straight down: {normal:?}");
        // Moving 0.32 mm up and 0.12 mm inwards (what it did) violates the row.
        let moved = Vec3::new(0.0, 0.00012, 0.00032);
        assert!(normal.dot(&moved) < normal.dot(&displacement), "the row stops that move");
    }

    #[test]
    fn a_vertex_held_on_a_face_last_frame_keeps_that_face_not_the_tip() {
        let mut stage = BarrierStage::new(1);
        let shapes = [blade()];
        let (before, after) = (at(0.0), at(0.0));
        let blades = Blades { shapes: &shapes, before: &[before], after: &[after] };
        // Claimed by the +z face last frame; now 0.1 mm past the tip, on the face plane.
        let start = [Vec3::new(0.0401, 0.0, 0.0005)];
        let claim = VertexTarget { vertex: 0, displacement: Vec3::zeros(), spatula: 0, face: 0, normal: Vec3::z(), depth: 0.0, node: 0 };
        let surface = SurfaceState { triangles: &[], start: &start, rest: &start, nodes: &[7], grid: None };
        let mut out = Vec::new();
        stage.push_rows_from(blades, &[claim], None, surface, &mut out);
        out.clear();
        stage.push_rows_from(blades, &[], None, surface, &mut out);
        assert_eq!(out.len(), 1);
        let ConstraintKind::Barrier { normal, .. } = out[0].kind else { panic!() };
        assert!((normal - Vec3::z()).norm() < 1e-15, "rule 3 (its old face) before rule 4 (the tip): {normal:?}");
    }

    #[test]
    fn a_fast_blade_widens_the_band() {
        // 5 mm below the blade's new position, but the blade moved 5 mm this frame.
        let start = [Vec3::new(0.02, 0.0, -0.0045)];
        assert_eq!(rows(at(0.0), at(0.0), &start, &[]).len(), 0, "still blade: outside the band");
        assert_eq!(rows(at(0.005), at(0.0), &start, &[]).len(), 1, "moving blade: inside the widened band");
    }
}
