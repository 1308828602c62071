//! The spatula: a thin rigid box with two large contact faces.
//!
//! Spatula frame: x along the blade (0 at the handle end, `length` at the tip),
//! y across it (centred), z through its thickness; the large faces are at
//! z = ±thickness/2 with outward normals ±z. Side faces do not collide.
//!
//! Source nodes: a layout gives (x, y) positions in the spatula frame; each one is a
//! *pair* of nodes, one on face 0 (z = +thickness/2, normal +z) and one on face 1
//! (z = -thickness/2, normal -z), on one line along the normal. Within a spatula,
//! node `face * pairs + k` is pair `k` on `face`. Generation is deterministic.

use crate::math::{Quat, Vec3, is_finite3};
use serde::{Deserialize, Serialize};

/// Dimensions of a spatula blade.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpatulaShape {
    /// Blade length along x, metres (> 0).
    pub length: f64,
    /// Blade width along y, metres (> 0).
    pub width: f64,
    /// Blade thickness along z, metres (> 0).
    pub thickness: f64,
}

/// Where the source nodes sit on each face (the same (x, y) on both faces, so
/// the nodes come in pairs along the face normal).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum NodeLayout {
    /// `along` x `across` nodes evenly over the face (paper: 150 a face, e.g. 15 x 10).
    Grid { along: u32, across: u32 },
    /// `count` nodes concentrated on the tip part of the blade: the last
    /// `tip_fraction` (0, 1] of its length (paper Fig. 5b: 30 a face).
    TipConcentrated { count: u32, tip_fraction: f64 },
    /// Explicit (x, y) positions in the spatula frame, metres.
    Explicit(Vec<[f64; 2]>),
}

/// A rigid pose: the spatula frame's origin and orientation in world space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Origin of the spatula frame (handle end of the blade's centre line), metres.
    pub position: Vec3,
    /// Orientation, a unit quaternion.
    pub rotation: Quat,
}

/// Why a shape or layout cannot give source nodes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LayoutError {
    #[error("spatula {field} must be finite and > 0, got {value} m")]
    Shape { field: &'static str, value: f64 },
    #[error("layout {field} must be {expected}, got {value}")]
    Parameter { field: &'static str, expected: &'static str, value: f64 },
    #[error("explicit node {index} at ({x}, {y}) m lies off the face (0..={length} along, ±{half_width} across)")]
    OffFace { index: usize, x: f64, y: f64, length: f64, half_width: f64 },
    #[error("the layout gives no source node")]
    NoNodes,
}

/// Outward normal of face `face` (0: +z, 1: -z) in the spatula frame.
pub fn face_normal_local(face: u8) -> Vec3 {
    if face == 0 { Vec3::z() } else { -Vec3::z() }
}

impl SpatulaShape {
    /// Checks that every dimension is finite and > 0.
    pub fn validate(&self) -> Result<(), LayoutError> {
        for (field, value) in [("length", self.length), ("width", self.width), ("thickness", self.thickness)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(LayoutError::Shape { field, value });
            }
        }
        Ok(())
    }

    /// The (x, y) positions, spatula frame, metres, of the node pairs of `layout`
    /// (one pair = one node on each face). Grid: cell centres of `along` x `across`
    /// cells, ordered along x then across. TipConcentrated: `count` nodes on cell
    /// centres of a near-square grid over the last `tip_fraction` of the blade,
    /// rows filled from the tip, the last (partial) row centred across.
    pub fn node_pairs(&self, layout: &NodeLayout) -> Result<Vec<[f64; 2]>, LayoutError> {
        self.validate()?;
        let (length, width) = (self.length, self.width);
        let mut out = Vec::new();
        match layout {
            NodeLayout::Grid { along, across } => {
                for (field, v) in [("along", *along), ("across", *across)] {
                    if v == 0 {
                        return Err(LayoutError::Parameter { field, expected: ">= 1", value: 0.0 });
                    }
                }
                for i in 0..*along {
                    for j in 0..*across {
                        let x = length * (i as f64 + 0.5) / *along as f64;
                        let y = width * ((j as f64 + 0.5) / *across as f64 - 0.5);
                        out.push([x, y]);
                    }
                }
            }
            NodeLayout::TipConcentrated { count, tip_fraction } => {
                if *count == 0 {
                    return Err(LayoutError::Parameter { field: "count", expected: ">= 1", value: 0.0 });
                }
                if !(tip_fraction.is_finite() && *tip_fraction > 0.0 && *tip_fraction <= 1.0) {
                    return Err(LayoutError::Parameter { field: "tip_fraction", expected: "in (0, 1]", value: *tip_fraction });
                }
                let n = *count as usize;
                let tip_length = length * tip_fraction;
                let across = ((n as f64 * width / tip_length).sqrt().round() as usize).clamp(1, n);
                let rows = n.div_ceil(across);
                for r in 0..rows {
                    let in_row = across.min(n - r * across);
                    // Row 0 is nearest the tip.
                    let x = length - tip_length * (r as f64 + 0.5) / rows as f64;
                    for j in 0..in_row {
                        let y = width / across as f64 * (j as f64 + 0.5 - in_row as f64 / 2.0);
                        out.push([x, y]);
                    }
                }
            }
            NodeLayout::Explicit(points) => {
                for (index, &[x, y]) in points.iter().enumerate() {
                    let half_width = width / 2.0;
                    if !(x.is_finite() && y.is_finite() && (0.0..=length).contains(&x) && y.abs() <= half_width) {
                        return Err(LayoutError::OffFace { index, x, y, length, half_width });
                    }
                    out.push([x, y]);
                }
            }
        }
        if out.is_empty() {
            return Err(LayoutError::NoNodes);
        }
        Ok(out)
    }

    /// A source node in the spatula frame: pair `xy` on `face` (0: z = +h/2, 1: z = -h/2).
    pub fn node_local(&self, xy: [f64; 2], face: u8) -> Vec3 {
        let z = if face == 0 { self.thickness / 2.0 } else { -self.thickness / 2.0 };
        Vec3::new(xy[0], xy[1], z)
    }
}

impl Default for Pose {
    fn default() -> Self {
        Self { position: Vec3::zeros(), rotation: Quat::identity() }
    }
}

/// Shortest-arc spherical interpolation of two quaternions (normalised first);
/// never panics (antipodal inputs take the sign-flipped short way, near-equal
/// ones fall back to normalised lerp).
pub fn slerp(a: &nalgebra::Quaternion<f64>, b: &nalgebra::Quaternion<f64>, alpha: f64) -> Quat {
    let qa = a.normalize();
    let mut qb = b.normalize();
    let mut dot = qa.coords.dot(&qb.coords);
    if dot < 0.0 {
        qb = -qb;
        dot = -dot;
    }
    let q = if dot > 0.9995 {
        qa + (qb - qa) * alpha
    } else {
        let theta = dot.clamp(-1.0, 1.0).acos();
        let sin = theta.sin();
        qa * (((1.0 - alpha) * theta).sin() / sin) + qb * ((alpha * theta).sin() / sin)
    };
    Quat::new_normalize(q)
}

impl Pose {
    /// A pose from a position and a rotation given as any quaternion: `None` when
    /// anything is non-finite or the quaternion is not unit within 1e-6.
    pub fn checked(position: Vec3, quaternion_wxyz: [f64; 4]) -> Option<Self> {
        let [w, x, y, z] = quaternion_wxyz;
        let q = nalgebra::Quaternion::new(w, x, y, z);
        if !is_finite3(&position) || !q.coords.iter().all(|c| c.is_finite()) {
            return None;
        }
        if (q.norm() - 1.0).abs() > 1e-6 {
            return None;
        }
        Some(Self { position, rotation: Quat::new_normalize(q) })
    }

    /// True when position and rotation are finite and the rotation is unit.
    pub fn is_valid(&self) -> bool {
        is_finite3(&self.position)
            && self.rotation.coords.iter().all(|c| c.is_finite())
            && (self.rotation.norm() - 1.0).abs() < 1e-6
    }

    /// The pose a fraction `alpha` (0..=1) of the way from `self` to `other`:
    /// linear in position, shortest-arc slerp in rotation (as trajectories sample).
    pub fn interpolate(&self, other: &Pose, alpha: f64) -> Pose {
        let position = self.position + (other.position - self.position) * alpha;
        Pose { position, rotation: slerp(self.rotation.quaternion(), other.rotation.quaternion(), alpha) }
    }

    /// A point of the spatula frame in world space.
    pub fn transform_point(&self, local: &Vec3) -> Vec3 {
        self.position + self.rotation * local
    }

    /// A direction of the spatula frame in world space.
    pub fn transform_vector(&self, local: &Vec3) -> Vec3 {
        self.rotation * local
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPE: SpatulaShape = SpatulaShape { length: 0.06, width: 0.01, thickness: 0.001 };

    #[test]
    fn layouts_give_the_requested_counts_on_the_face() {
        let grid = SHAPE.node_pairs(&NodeLayout::Grid { along: 15, across: 10 }).expect("grid");
        assert_eq!(grid.len(), 150, "paper grid: 150 a face");
        let tip = SHAPE.node_pairs(&NodeLayout::TipConcentrated { count: 30, tip_fraction: 0.3 }).expect("tip");
        assert_eq!(tip.len(), 30, "paper tip layout: 30 a face");
        for &[x, y] in grid.iter().chain(&tip) {
            assert!((0.0..=SHAPE.length).contains(&x) && y.abs() <= SHAPE.width / 2.0, "node ({x}, {y}) off the face");
        }
        assert!(tip.iter().all(|p| p[0] >= SHAPE.length * 0.7), "tip nodes must lie in the last 30% of the blade");
        let local = SHAPE.node_local(grid[0], 1);
        assert_eq!(local.z, -SHAPE.thickness / 2.0);
        assert_eq!(face_normal_local(1), -Vec3::z());
    }

    #[test]
    fn invalid_layouts_and_shapes_are_errors() {
        assert!(matches!(SHAPE.node_pairs(&NodeLayout::Grid { along: 0, across: 3 }), Err(LayoutError::Parameter { field: "along", .. })));
        assert!(matches!(
            SHAPE.node_pairs(&NodeLayout::TipConcentrated { count: 3, tip_fraction: 1.5 }),
            Err(LayoutError::Parameter { field: "tip_fraction", .. })
        ));
        assert!(matches!(SHAPE.node_pairs(&NodeLayout::Explicit(vec![[0.0, 0.02]])), Err(LayoutError::OffFace { index: 0, .. })));
        assert_eq!(SHAPE.node_pairs(&NodeLayout::Explicit(vec![])), Err(LayoutError::NoNodes));
        let bad = SpatulaShape { thickness: f64::NAN, ..SHAPE };
        assert!(matches!(bad.node_pairs(&NodeLayout::Grid { along: 1, across: 1 }), Err(LayoutError::Shape { field: "thickness", .. })));
    }
}
