//! Contact area and mean retraction pressure per spatula.
//!
//! In: the boundary surface, surface-vertex positions (m; the deformed ones
//! for the contact as it is), the frame's constraints and their reactions (N).
//! Out: per spatula owner the contact area (m^2), total force (N) and mean
//! pressure `|force| / area` in Pa and mmHg (1 mmHg = 133.322 Pa).
//! Contact area = the lumped area (a third of each adjacent triangle's) of the
//! surface vertices that spatula pushes this frame: a row with a non-zero
//! reaction (an enforced displacement of the paper's bilateral contact always
//! counts). A row the solver left inactive is no contact: a released vertex
//! leaves the face, and a blade barrier row only guards a vertex near the
//! blade, up to a couple of millimetres away. A vertex pushed by two spatulas
//! counts for neither. Stays true: owners ascending; area 0 gives
//! pressure 0 (reported as such, never Inf/NaN).

use super::constrained::{Constraint, ConstraintKind};
use crate::math::Vec3;
use crate::mesh::BoundarySurface;
use crate::mesh::surface::NOT_ON_SURFACE;

/// Pascals in one millimetre of mercury.
pub const PA_PER_MMHG: f64 = 133.322;
/// Sustained retraction pressure the injury literature names as a danger line, Pa (about 20 mmHg).
pub const RETRACTION_DANGER_PA: f64 = 20.0 * PA_PER_MMHG;

/// Contact summary of one spatula.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPatch {
    pub owner: u16,
    /// Lumped area of the pushed surface vertices, m^2.
    pub area: f64,
    /// How many surface vertices this spatula alone pushes (the patch's size in
    /// vertices: a few dots or a patch).
    pub vertices: u32,
    /// Sum of the reactions of this owner's enforced constraints (force on the tissue), N.
    pub force: Vec3,
    /// |force| / area, Pa (0 when the area is 0).
    pub mean_pressure_pa: f64,
    /// The same in mmHg.
    pub mean_pressure_mmhg: f64,
}

/// Computes one [`ContactPatch`] per spatula owner present in `constraints`.
/// `vertex_owner` is scratch (one entry per surface vertex).
pub fn contact_patches(
    surface: &BoundarySurface,
    positions: &[Vec3],
    constraints: &[Constraint],
    reactions: &[Vec3],
    vertex_owner: &mut Vec<u32>,
    out: &mut Vec<ContactPatch>,
) {
    out.clear();
    const NONE: u32 = u32::MAX;
    const MANY: u32 = u32::MAX - 1;
    vertex_owner.clear();
    vertex_owner.resize(surface.vertices.len(), NONE);
    for (c, r) in constraints.iter().zip(reactions) {
        if !c.kind.is_tool() {
            continue;
        }
        match out.binary_search_by_key(&c.owner, |p| p.owner) {
            Ok(i) => out[i].force += r,
            Err(i) => out.insert(i, ContactPatch { owner: c.owner, area: 0.0, vertices: 0, force: *r, mean_pressure_pa: 0.0, mean_pressure_mmhg: 0.0 }),
        }
        if !matches!(c.kind, ConstraintKind::Enforced { .. }) && *r == Vec3::zeros() {
            continue;
        }
        let v = surface.node_to_vertex.get(c.node as usize).copied().unwrap_or(NOT_ON_SURFACE);
        if v != NOT_ON_SURFACE {
            let slot = &mut vertex_owner[v as usize];
            *slot = if *slot == NONE || *slot == c.owner as u32 { c.owner as u32 } else { MANY };
        }
    }
    for &o in vertex_owner.iter() {
        if o != NONE
            && o != MANY
            && let Ok(i) = out.binary_search_by_key(&(o as u16), |p| p.owner)
        {
            out[i].vertices += 1;
        }
    }
    for tri in &surface.triangles {
        if tri.iter().all(|&v| matches!(vertex_owner[v as usize], NONE | MANY)) {
            continue;
        }
        let [a, b, c] = tri.map(|v| positions[v as usize]);
        let third = (b - a).cross(&(c - a)).norm() / 6.0;
        for &v in tri {
            let o = vertex_owner[v as usize];
            if o == NONE || o == MANY {
                continue;
            }
            if let Ok(i) = out.binary_search_by_key(&(o as u16), |p| p.owner) {
                out[i].area += third;
            }
        }
    }
    for p in out.iter_mut() {
        p.mean_pressure_pa = if p.area > 0.0 { p.force.norm() / p.area } else { 0.0 };
        p.mean_pressure_mmhg = p.mean_pressure_pa / PA_PER_MMHG;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1 x 1 mm square of two triangles, surface vertex k = mesh node k.
    fn square() -> (BoundarySurface, Vec<Vec3>) {
        let surface = BoundarySurface { triangles: vec![[0, 1, 2], [0, 2, 3]], vertices: vec![0, 1, 2, 3], node_to_vertex: vec![0, 1, 2, 3], triangle_tet: vec![0, 0] };
        let positions = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.001, 0.0, 0.0), Vec3::new(0.001, 0.001, 0.0), Vec3::new(0.0, 0.001, 0.0)];
        (surface, positions)
    }

    fn barrier(node: u32, owner: u16) -> Constraint {
        Constraint { node, owner, kind: ConstraintKind::Barrier { displacement: Vec3::zeros(), normal: Vec3::z() } }
    }

    #[test]
    fn area_is_the_lumped_area_of_the_pushed_vertices_only() {
        let (surface, positions) = square();
        // Vertex 0 pushed with 1 mN; vertices 1 and 2 guarded by inactive barrier rows.
        let constraints = [barrier(0, 0), barrier(1, 0), barrier(2, 0)];
        let reactions = [Vec3::new(0.0, 0.0, 1e-3), Vec3::zeros(), Vec3::zeros()];
        let (mut owner, mut out) = (Vec::new(), Vec::new());
        contact_patches(&surface, &positions, &constraints, &reactions, &mut owner, &mut out);
        assert_eq!(out.len(), 1);
        // Vertex 0 touches both triangles (0.5 mm^2 each): a third of each.
        assert!((out[0].area - 1e-6 / 3.0).abs() < 1e-18, "area {}", out[0].area);
        assert_eq!(out[0].vertices, 1, "one pushed vertex; the inactive barrier rows are no contact");
        assert!((out[0].mean_pressure_pa - 1e-3 / (1e-6 / 3.0)).abs() < 1e-9);
        // Every vertex pushed: the whole square.
        let constraints: Vec<Constraint> = (0..4).map(|v| barrier(v, 0)).collect();
        let reactions = [Vec3::new(0.0, 0.0, 1e-3); 4];
        contact_patches(&surface, &positions, &constraints, &reactions, &mut owner, &mut out);
        assert!((out[0].area - 1e-6).abs() < 1e-18, "area {}", out[0].area);
    }

    #[test]
    fn enforced_rows_count_even_at_zero_reaction_and_shared_vertices_count_for_neither() {
        let (surface, positions) = square();
        let enforced = |node, owner| Constraint { node, owner, kind: ConstraintKind::Enforced { displacement: Vec3::zeros() } };
        let constraints = [enforced(0, 0), enforced(2, 1), barrier(2, 0)];
        let reactions = [Vec3::zeros(), Vec3::new(0.0, 0.0, 1e-3), Vec3::new(0.0, 0.0, 1e-3)];
        let (mut owner, mut out) = (Vec::new(), Vec::new());
        contact_patches(&surface, &positions, &constraints, &reactions, &mut owner, &mut out);
        assert_eq!(out.len(), 2);
        assert!((out[0].area - 1e-6 / 3.0).abs() < 1e-18, "vertex 0 only: {}", out[0].area);
        assert_eq!(out[1].area, 0.0, "vertex 2 is pushed by both spatulas");
        assert_eq!(out[1].mean_pressure_pa, 0.0);
    }
}
