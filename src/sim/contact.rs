//! Contact area and mean retraction pressure per spatula.
//!
//! In: the boundary surface, surface-vertex positions (m; deformed for the contact as it is), the frame's
//! constraints and their reactions (N). Out: per spatula owner the contact area (m^2), total force (N) and mean
//! pressure `|force| / area` in Pa and mmHg.
//! Contact area: the lumped area (a third of each adjacent triangle's) of the vertices the spatula pushes this
//! frame, i.e. with a non-zero reaction (an enforced displacement always counts); an inactive row (a released
//! vertex, a blade barrier guarding a nearby vertex) is no contact. A vertex pushed by two spatulas counts for
//! neither. Stays true: owners ascending; area 0 gives pressure 0 (never Inf/NaN).

use crate::fem::{Constraint, ConstraintKind};
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
    /// How many surface vertices this spatula alone pushes (a few dots or a patch).
    pub vertices: u32,
    /// Sum of the reactions of this owner's enforced constraints (force on the tissue), N.
    pub force: Vec3,
    /// |force| / area, Pa (0 when the area is 0).
    pub mean_pressure_pa: f64,
    /// The same in mmHg.
    pub mean_pressure_mmhg: f64,
}

/// Scratch of [`contact_patches`] for one surface, reused between frames: the triangles around each vertex and this
/// frame's vertex owners, so a frame reads only the triangles around the pushed vertices.
#[derive(Debug, Default)]
pub struct ContactScratch {
    /// Triangles around surface vertex v: `around[start[v]..start[v + 1]]`, ascending.
    start: Vec<u32>,
    around: Vec<u32>,
    /// The surface's (vertex, triangle) counts the adjacency was built for.
    built_for: Option<(usize, usize)>,
    owner: Vec<u32>,
    touched: Vec<u32>,
    triangles: Vec<u32>,
}

impl ContactScratch {
    /// Scratch for `surface` (its adjacency built now).
    pub fn for_surface(surface: &BoundarySurface) -> Self {
        let mut s = Self::default();
        s.build(surface);
        s
    }

    fn build(&mut self, surface: &BoundarySurface) {
        let n = surface.vertices.len();
        (self.start, self.around) = crate::mesh::triangles_around_vertices(n, &surface.triangles);
        self.built_for = Some((n, surface.triangles.len()));
        self.owner.clear();
        self.owner.resize(n, NONE);
        self.touched.clear();
    }
}

const NONE: u32 = u32::MAX;
const MANY: u32 = u32::MAX - 1;

/// One [`ContactPatch`] per spatula owner in `constraints`. `scratch` serves one surface (made for it by
/// [`ContactScratch::for_surface`], or default and built on first use); it is rebuilt when the surface's counts change.
pub fn contact_patches(
    surface: &BoundarySurface,
    positions: &[Vec3],
    constraints: &[Constraint],
    reactions: &[Vec3],
    scratch: &mut ContactScratch,
    out: &mut Vec<ContactPatch>,
) {
    out.clear();
    if scratch.built_for != Some((surface.vertices.len(), surface.triangles.len())) {
        scratch.build(surface);
    }
    // Only the entries of last call's vertices are set.
    for &v in &scratch.touched {
        scratch.owner[v as usize] = NONE;
    }
    scratch.touched.clear();
    let vertex_owner = &mut scratch.owner;
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
            if *slot == NONE {
                scratch.touched.push(v);
            }
            *slot = if *slot == NONE || *slot == c.owner as u32 { c.owner as u32 } else { MANY };
        }
    }
    for &v in &scratch.touched {
        let o = vertex_owner[v as usize];
        if o != MANY
            && let Ok(i) = out.binary_search_by_key(&(o as u16), |p| p.owner)
        {
            out[i].vertices += 1;
        }
    }
    // The triangles with an owned vertex, ascending: the areas add up in the order of a pass over all triangles.
    scratch.triangles.clear();
    for &v in &scratch.touched {
        if vertex_owner[v as usize] != MANY {
            let (a, b) = (scratch.start[v as usize] as usize, scratch.start[v as usize + 1] as usize);
            scratch.triangles.extend_from_slice(&scratch.around[a..b]);
        }
    }
    scratch.triangles.sort_unstable();
    scratch.triangles.dedup();
    for &t in &scratch.triangles {
        let tri = &surface.triangles[t as usize];
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

/// Per surface vertex, the contact pressure the blades put on it this frame, mmHg, into `out` (resized to the
/// surface's vertices, zero where no blade pushes): the magnitude of each tool row's reaction on the vertex (rows of
/// several blades on one vertex add) over the vertex's lumped rest area `vertex_area_m2`
/// ([`crate::mesh::surface::vertex_areas`]), scaled by its blade's `ratios` entry where the scene relaxes. Barrier rows and non-tool rows (skull, tethers) count only as tool
/// rows do in [`contact_patches`]: a tool row with a zero reaction adds nothing. A vertex of zero area stays 0.
pub fn vertex_pressures_mmhg(
    surface: &BoundarySurface,
    constraints: &[Constraint],
    reactions: &[Vec3],
    vertex_area_m2: &[f64],
    ratios: Option<&[f64]>,
    out: &mut Vec<f64>,
) {
    out.clear();
    out.resize(surface.vertices.len(), 0.0);
    for (v, owner, pa) in tool_vertex_pressures(surface, constraints, reactions, vertex_area_m2) {
        let ratio = ratios.and_then(|r| r.get(usize::from(owner)).copied()).unwrap_or(1.0);
        if let Some(slot) = out.get_mut(v as usize) {
            *slot += pa * ratio / super::report::PASCALS_PER_MMHG;
        }
    }
}

/// Each tool row's (surface vertex, owner, pressure in Pa): `|reaction| / vertex area`, for the rows on a
/// surface vertex with an area. The one place a row's reaction becomes a vertex's pressure (the ischemia
/// stage, the window's pressure field, the replay's pressure-time dose).
pub fn tool_vertex_pressures<'a>(
    surface: &'a BoundarySurface,
    constraints: &'a [Constraint],
    reactions: &'a [Vec3],
    vertex_area_m2: &'a [f64],
) -> impl Iterator<Item = (u32, u16, f64)> + 'a {
    constraints.iter().zip(reactions).filter(|(c, _)| c.kind.is_tool()).filter_map(|(c, r)| {
        let v = surface.node_to_vertex.get(c.node as usize).copied().unwrap_or(NOT_ON_SURFACE);
        let area = vertex_area_m2.get(v as usize).copied().unwrap_or(0.0);
        (v != NOT_ON_SURFACE && area > 0.0).then(|| (v, c.owner, r.norm() / area))
    })
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
        let (mut owner, mut out) = (ContactScratch::default(), Vec::new());
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

    /// The plain pass over every triangle: the reference the adjacency must match.
    fn plain_areas(surface: &BoundarySurface, positions: &[Vec3], constraints: &[Constraint], reactions: &[Vec3]) -> Vec<(u16, f64, u32)> {
        let mut owner = vec![NONE; surface.vertices.len()];
        for (c, r) in constraints.iter().zip(reactions) {
            if !c.kind.is_tool() || (!matches!(c.kind, ConstraintKind::Enforced { .. }) && *r == Vec3::zeros()) {
                continue;
            }
            let v = surface.node_to_vertex[c.node as usize] as usize;
            owner[v] = if owner[v] == NONE || owner[v] == c.owner as u32 { c.owner as u32 } else { MANY };
        }
        let mut owners: Vec<u16> = constraints.iter().filter(|c| c.kind.is_tool()).map(|c| c.owner).collect();
        owners.sort_unstable();
        owners.dedup();
        let mut out: Vec<(u16, f64, u32)> = owners.iter().map(|&o| (o, 0.0, owner.iter().filter(|&&x| x == o as u32).count() as u32)).collect();
        for tri in &surface.triangles {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            let third = (b - a).cross(&(c - a)).norm() / 6.0;
            for &v in tri {
                if let Some(e) = out.iter_mut().find(|e| e.0 as u32 == owner[v as usize]) {
                    e.1 += third;
                }
            }
        }
        out
    }

    #[test]
    fn the_adjacency_gives_the_plain_passs_bits_frame_after_frame_and_on_another_surface() {
        // A 9 x 7 grid of squares, two triangles each, slightly bumped.
        let grid = |nx: u32, ny: u32| {
            let mut triangles = Vec::new();
            for j in 0..ny {
                for i in 0..nx {
                    let v = |i: u32, j: u32| j * (nx + 1) + i;
                    triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                    triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
                }
            }
            let n = (nx + 1) * (ny + 1);
            let positions: Vec<Vec3> = (0..n).map(|k| Vec3::new((k % (nx + 1)) as f64 * 1e-3, (k / (nx + 1)) as f64 * 1e-3, 1e-4 * ((k * 7 % 5) as f64))).collect();
            let surface = BoundarySurface { triangles, vertices: (0..n).collect(), node_to_vertex: (0..n).collect(), triangle_tet: Vec::new() };
            (surface, positions)
        };
        let mut scratch = ContactScratch::default();
        let mut out = Vec::new();
        for (nx, ny) in [(9, 7), (9, 7), (4, 3)] {
            let (surface, positions) = grid(nx, ny);
            let n = surface.vertices.len() as u32;
            for frame in 0..3u32 {
                // two owners, overlapping on a few vertices, some rows without force
                let mut constraints = Vec::new();
                let mut reactions = Vec::new();
                for v in (frame..n).step_by(3) {
                    constraints.push(barrier(v, (v % 2) as u16));
                    reactions.push(if v % 5 == 0 { Vec3::zeros() } else { Vec3::new(0.0, 0.0, 1e-3) });
                }
                for v in (0..n).step_by(7) {
                    constraints.push(barrier(v, 1));
                    reactions.push(Vec3::new(0.0, 1e-4, 1e-3));
                }
                contact_patches(&surface, &positions, &constraints, &reactions, &mut scratch, &mut out);
                let plain = plain_areas(&surface, &positions, &constraints, &reactions);
                assert_eq!(out.len(), plain.len());
                for (p, q) in out.iter().zip(&plain) {
                    assert_eq!((p.owner, p.area.to_bits(), p.vertices), (q.0, q.1.to_bits(), q.2), "grid {nx}x{ny}, frame {frame}");
                    assert!(p.area > 0.0);
                }
            }
        }
    }

    #[test]
    fn vertex_pressure_is_the_reaction_over_the_lumped_rest_area() {
        let (surface, positions) = square();
        let areas = crate::mesh::surface::vertex_areas(&positions, &surface.triangles);
        // Vertex 0 (a third of 1 mm^2) pushed with 1 mN by two rows of two blades; vertex 1 guarded, no force.
        let constraints = [barrier(0, 0), barrier(0, 1), barrier(1, 0)];
        let reactions = [Vec3::new(0.0, 0.0, 0.6e-3), Vec3::new(0.0, 0.0, 0.4e-3), Vec3::zeros()];
        let mut out = Vec::new();
        vertex_pressures_mmhg(&surface, &constraints, &reactions, &areas, None, &mut out);
        assert_eq!(out.len(), 4);
        let expected = 1e-3 / (1e-6 / 3.0) / super::super::report::PASCALS_PER_MMHG;
        assert!((out[0] - expected).abs() < 1e-9 * expected, "{} against {expected}", out[0]);
        assert_eq!(&out[1..], &[0.0, 0.0, 0.0]);
    }

    #[test]
    fn enforced_rows_count_even_at_zero_reaction_and_shared_vertices_count_for_neither() {
        let (surface, positions) = square();
        let enforced = |node, owner| Constraint { node, owner, kind: ConstraintKind::Enforced { displacement: Vec3::zeros() } };
        let constraints = [enforced(0, 0), enforced(2, 1), barrier(2, 0)];
        let reactions = [Vec3::zeros(), Vec3::new(0.0, 0.0, 1e-3), Vec3::new(0.0, 0.0, 1e-3)];
        let (mut owner, mut out) = (ContactScratch::default(), Vec::new());
        contact_patches(&surface, &positions, &constraints, &reactions, &mut owner, &mut out);
        assert_eq!(out.len(), 2);
        assert!((out[0].area - 1e-6 / 3.0).abs() < 1e-18, "vertex 0 only: {}", out[0].area);
        assert_eq!(out[1].area, 0.0, "vertex 2 is pushed by both spatulas");
        assert_eq!(out[1].mean_pressure_pa, 0.0);
    }
}
