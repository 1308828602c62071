//! Contact area and mean retraction pressure per spatula.
//!
//! In: the boundary surface, surface-vertex positions (m; the deformed ones
//! for the contact as it is), the frame's constraints and their reactions (N).
//! Out: per spatula owner the contact area (m^2), total force (N) and mean
//! pressure `|force| / area` in Pa and mmHg (1 mmHg = 133.322 Pa).
//! Contact area = area of the surface triangles whose three vertices are all
//! enforced by that spatula. Stays true: owners ascending; area 0 gives
//! pressure 0 (reported as such, never Inf/NaN).

use super::constrained::Constraint;
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
    /// Area of the fully constrained triangles, m^2.
    pub area: f64,
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
            Err(i) => out.insert(i, ContactPatch { owner: c.owner, area: 0.0, force: *r, mean_pressure_pa: 0.0, mean_pressure_mmhg: 0.0 }),
        }
        let v = surface.node_to_vertex.get(c.node as usize).copied().unwrap_or(NOT_ON_SURFACE);
        if v != NOT_ON_SURFACE {
            let slot = &mut vertex_owner[v as usize];
            *slot = if *slot == NONE || *slot == c.owner as u32 { c.owner as u32 } else { MANY };
        }
    }
    for tri in &surface.triangles {
        let o = vertex_owner[tri[0] as usize];
        if o == NONE || o == MANY || tri.iter().any(|&v| vertex_owner[v as usize] != o) {
            continue;
        }
        let [a, b, c] = tri.map(|v| positions[v as usize]);
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        if let Ok(i) = out.binary_search_by_key(&(o as u16), |p| p.owner) {
            out[i].area += area;
        }
    }
    for p in out.iter_mut() {
        p.mean_pressure_pa = if p.area > 0.0 { p.force.norm() / p.area } else { 0.0 };
        p.mean_pressure_mmhg = p.mean_pressure_pa / PA_PER_MMHG;
    }
}
