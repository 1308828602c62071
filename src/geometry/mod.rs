//! Rigid geometry: spatula shape and pose, source-node layouts, ray–triangle tests.
//!
//! In: spatula dimensions (m), a layout, a pose. Out: source nodes in pairs on the
//! two large faces, world-space rays, ray hits. Stays true: poses hold a finite
//! position and a unit quaternion; hits never carry NaN.

pub mod ray;
pub mod segment;
pub mod spatula;
pub mod triangle;

pub use ray::{LineHit, LineQuery, moller_trumbore};
pub use segment::distance_to_segment;
pub use spatula::{LayoutError, NodeLayout, Pose, SpatulaShape, face_normal_local, slerp};
pub use triangle::{closest_barycentric, closest_point};
