//! How open each point of the brain surface is to the microscope's light: a per-vertex ambient factor, computed
//! once from the surface at rest, that darkens the sulci and the depth of a fissure as a surgeon sees them.
//!
//! In: surface positions (m) and triangles. Out: per vertex a factor in [`MIN_AMBIENT`, 1]. Method: for each vertex
//! the surface vertices within [`RADIUS_M`] are found in a uniform grid; those lying above its tangent plane (by more
//! than [`ABOVE_M`]) close it in. The factor is one minus [`STRENGTH`] times the distance-weighted share of its
//! neighbours that lie above (weight `1 - d / R`), so a flat or convex patch keeps 1 and a vertex between the walls of
//! a sulcus or at the floor of a fissure falls towards [`MIN_AMBIENT`]. A screen-free stand-in for ambient occlusion:
//! no rays, the same answer for every view, and cheap (a grid pass, under a second on the fine brain's surface).
//! Stays true: finite output for any finite input; an isolated vertex keeps 1.

use crate::math::Vec3;
use std::collections::HashMap;

/// The neighbourhood that can shade a vertex, m (the width of a sulcus).
pub const RADIUS_M: f64 = 6e-3;
/// A neighbour closes a vertex in when it lies this far above its tangent plane, m.
pub const ABOVE_M: f64 = 0.3e-3;
/// How dark a fully enclosed vertex gets.
pub const STRENGTH: f64 = 1.1;
/// The darkest factor.
pub const MIN_AMBIENT: f64 = 0.35;

/// The per-vertex ambient factor of the surface `positions` / `triangles` (module doc).
pub fn surface_occlusion(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<f32> {
    let mut normals = Vec::new();
    super::meshes::area_weighted_normals(positions, triangles, &mut normals);
    let cell = |p: &Vec3| [(p.x / RADIUS_M).floor() as i64, (p.y / RADIUS_M).floor() as i64, (p.z / RADIUS_M).floor() as i64];
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (i, p) in positions.iter().enumerate() {
        if p.iter().all(|c| c.is_finite()) {
            grid.entry(cell(p)).or_default().push(i as u32);
        }
    }
    positions
        .iter()
        .zip(&normals)
        .enumerate()
        .map(|(i, (p, n))| {
            if !p.iter().all(|c| c.is_finite()) || n.norm() == 0.0 {
                return 1.0;
            }
            let c = cell(p);
            let (mut above, mut all) = (0.0, 0.0);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else { continue };
                        for &j in list {
                            if j as usize == i {
                                continue;
                            }
                            let d = positions[j as usize] - p;
                            let dist = d.norm();
                            if dist >= RADIUS_M {
                                continue;
                            }
                            let w = 1.0 - dist / RADIUS_M;
                            all += w;
                            if n.dot(&d) > ABOVE_M {
                                above += w;
                            }
                        }
                    }
                }
            }
            let share = if all > 0.0 { above / all } else { 0.0 };
            (1.0 - STRENGTH * share).clamp(MIN_AMBIENT, 1.0) as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat sheet with a V-shaped groove (walls 45 degrees): the flat far from the groove keeps 1, the groove's floor
    /// is darker than its rim, and nothing is below the floor.
    #[test]
    fn a_flat_sheet_keeps_its_light_and_a_groove_floor_is_darker_than_its_rim() {
        let (n, step) = (41usize, 1e-3);
        let depth = |x: f64| (8e-3 - x.abs()).max(0.0); // a V 8 mm deep at x = 0, flat beyond |x| = 8 mm
        let mut positions = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let x = (i as f64 - 20.0) * step;
                positions.push(Vec3::new(x, (j as f64 - 20.0) * step, -depth(x)));
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                triangles.push([a, a + 1, a + n as u32 + 1]);
                triangles.push([a, a + n as u32 + 1, a + n as u32]);
            }
        }
        let ao = surface_occlusion(&positions, &triangles);
        let at = |i: usize, j: usize| ao[j * n + i];
        assert_eq!(at(0, 20), 1.0, "far flat: open to the light");
        assert!(at(20, 20) < at(14, 20), "the floor ({}) is darker than the wall near the rim ({})", at(20, 20), at(14, 20));
        assert!(at(20, 20) < 0.7 && at(20, 20) >= MIN_AMBIENT as f32, "the floor is shaded: {}", at(20, 20));
        assert!(ao.iter().all(|a| a.is_finite() && *a <= 1.0));
    }
}
