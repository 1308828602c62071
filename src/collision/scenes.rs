//! Small closed test and benchmark surfaces (metres), built in code: an icosphere,
//! heightfield solids (slab with a V valley, U channel), subdivided boxes (two of
//! them with a gap = a fissure between two hemispheres), and spatula poses.
//!
//! In: sizes. Out: `(triangles, positions)`, triangles outward CCW. Stays true:
//! every surface is closed, consistently oriented, with positive enclosed volume.

use crate::geometry::Pose;
use crate::math::{Matrix3, Quat, Vec3};
use std::collections::BTreeMap;

/// A closed triangle surface: triangles (outward CCW) and vertex positions.
pub type Surface = (Vec<[u32; 3]>, Vec<Vec3>);

/// Enclosed volume by the divergence theorem (positive for an outward surface).
pub fn enclosed_volume(triangles: &[[u32; 3]], positions: &[Vec3]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

/// An icosphere of `radius` about `centre`: 20 * 4^subdivisions triangles.
pub fn icosphere(centre: Vec3, radius: f64, subdivisions: u32) -> Surface {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        (-1.0, g, 0.0), (1.0, g, 0.0), (-1.0, -g, 0.0), (1.0, -g, 0.0),
        (0.0, -1.0, g), (0.0, 1.0, g), (0.0, -1.0, -g), (0.0, 1.0, -g),
        (g, 0.0, -1.0), (g, 0.0, 1.0), (-g, 0.0, -1.0), (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        let mut next = Vec::with_capacity(t.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<Vec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                (p.len() - 1) as u32
            })
        };
        for &[a, b, c] in &t {
            let ab = midpoint(a, b, &mut p);
            let bc = midpoint(b, c, &mut p);
            let ca = midpoint(c, a, &mut p);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = next;
    }
    (t, p.into_iter().map(|q| centre + q * radius).collect())
}

/// A solid whose top is the heightfield z = `top(x, y)` over the grid `xs` x `ys`
/// (ascending), whose bottom is the plane z = `bottom`, closed by vertical sides.
pub fn heightfield_solid(xs: &[f64], ys: &[f64], bottom: f64, top: impl Fn(f64, f64) -> f64) -> Surface {
    let (nx, ny) = (xs.len(), ys.len());
    let idx = |i: usize, j: usize| (i * ny + j) as u32;
    let layer = (nx * ny) as u32;
    let mut p = Vec::with_capacity(2 * nx * ny);
    for &x in xs {
        for &y in ys {
            p.push(Vec3::new(x, y, top(x, y)));
        }
    }
    for &x in xs {
        for &y in ys {
            p.push(Vec3::new(x, y, bottom));
        }
    }
    let mut t = Vec::new();
    for i in 0..nx - 1 {
        for j in 0..ny - 1 {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            t.push([a, b, c]);
            t.push([a, c, d]);
            t.push([a + layer, c + layer, b + layer]);
            t.push([a + layer, d + layer, c + layer]);
        }
    }
    // Boundary loop, counter-clockwise seen from above.
    let mut ring = Vec::new();
    ring.extend((0..nx - 1).map(|i| idx(i, 0)));
    ring.extend((0..ny - 1).map(|j| idx(nx - 1, j)));
    ring.extend((1..nx).rev().map(|i| idx(i, ny - 1)));
    ring.extend((1..ny).rev().map(|j| idx(0, j)));
    for k in 0..ring.len() {
        let (pt, qt) = (ring[k], ring[(k + 1) % ring.len()]);
        let (pb, qb) = (pt + layer, qt + layer);
        t.push([pb, qb, qt]);
        t.push([pb, qt, pt]);
    }
    (t, p)
}

/// `n + 1` evenly spaced values from `a` to `b`.
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|k| a + (b - a) * k as f64 / n as f64).collect()
}

/// An axis-aligned box [lo, hi] with its top and bottom split into `nx` x `ny` cells.
pub fn subdivided_box(lo: Vec3, hi: Vec3, nx: usize, ny: usize) -> Surface {
    heightfield_solid(&linspace(lo.x, hi.x, nx), &linspace(lo.y, hi.y, ny), lo.z, |_, _| hi.z)
}

/// Concatenates surfaces (indices shifted).
pub fn merge(parts: &[Surface]) -> Surface {
    let mut t = Vec::new();
    let mut p = Vec::new();
    for (pt, pp) in parts {
        let off = p.len() as u32;
        t.extend(pt.iter().map(|tri| tri.map(|i| i + off)));
        p.extend_from_slice(pp);
    }
    (t, p)
}

/// A pose whose spatula axes (x along the blade, y across, z through the thickness)
/// point along the given world directions (`blade` and `normal` are made orthonormal;
/// y = z x x completes a right-handed frame).
pub fn pose_from_axes(position: Vec3, blade: Vec3, normal: Vec3) -> Pose {
    let x = blade.normalize();
    let z = (normal - x * x.dot(&normal)).normalize();
    let y = z.cross(&x);
    let m = Matrix3::from_columns(&[x, y, z]);
    let rotation = Quat::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(m));
    Pose { position, rotation }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_are_closed_and_outward() {
        let (t, p) = icosphere(Vec3::new(0.1, 0.0, 0.0), 0.05, 2);
        assert_eq!(t.len(), 320);
        let v = enclosed_volume(&t, &p);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.05f64.powi(3);
        assert!(v > 0.9 * exact && v < exact, "icosphere volume {v} vs sphere {exact}");
        let (t, p) = subdivided_box(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.02, 0.03, 0.01), 4, 5);
        assert!((enclosed_volume(&t, &p) - 6e-6).abs() < 1e-18, "box volume must be 0.02*0.03*0.01");
        // Closed: every directed edge appears once and its reverse once.
        let mut edges = BTreeMap::new();
        for tri in &t {
            for k in 0..3 {
                *edges.entry((tri[k], tri[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        assert!(edges.iter().all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1)), "box surface must be closed and consistently oriented");
        let pose = pose_from_axes(Vec3::zeros(), -Vec3::z(), Vec3::x());
        assert!(pose.is_valid());
        assert!((pose.transform_vector(&Vec3::z()) - Vec3::x()).norm() < 1e-15);
        assert!((pose.transform_vector(&Vec3::x()) + Vec3::z()).norm() < 1e-15);
    }
}
