//! The spatula: a thin rigid box with two large contact faces.
//!
//! Spatula frame: x along the blade (0 at the handle end, `length` at the tip),
//! y across it (centred), z through its thickness; the large faces are at
//! z = ±thickness/2 with outward normals ±z. Side faces do not collide.

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

impl Default for Pose {
    fn default() -> Self {
        Self { position: Vec3::zeros(), rotation: Quat::identity() }
    }
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

    /// A point of the spatula frame in world space.
    pub fn transform_point(&self, local: &Vec3) -> Vec3 {
        self.position + self.rotation * local
    }

    /// A direction of the spatula frame in world space.
    pub fn transform_vector(&self, local: &Vec3) -> Vec3 {
        self.rotation * local
    }
}
