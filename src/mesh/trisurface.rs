//! Triangle surfaces (OBJ/STL input, tetrahedralization input).
//!
//! In: positions and triangles. Out: a [`TriSurface`] and checks of closedness
//! (every edge shared by exactly two consistently oriented triangles).

use crate::math::Vec3;

/// A triangle surface in metres (or the file's unit until scaled).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriSurface {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}
