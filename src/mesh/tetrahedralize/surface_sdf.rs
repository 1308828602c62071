//! Signed distance to a closed triangle surface.
//!
//! In: a closed, consistently oriented [`TriSurface`]. Out: `signed_distance(p)`,
//! negative inside. Distance: to the nearest triangle, through parry's BVH.
//! Sign: the angle-weighted pseudo-normal of the nearest feature (face, edge or
//! vertex; Bærentzen & Aanæs 2005), exact for closed manifold surfaces and
//! independent of ray directions. Inward-oriented surfaces are handled by
//! flipping the sign when the enclosed volume is negative.

use parry3d_f64::math::Vector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::{TriMesh, TriMeshFlags};

use crate::math::Vec3;
use crate::mesh::TriSurface;
use crate::mesh::trisurface::SurfaceError;

/// A signed distance field of a closed surface.
pub struct SurfaceDistance {
    mesh: TriMesh,
    /// +1 for outward surfaces, -1 for inward ones.
    orientation: f64,
}

impl SurfaceDistance {
    /// Builds the BVH and pseudo-normals. The surface must pass
    /// [`TriSurface::check_closed`]; a zero enclosed volume is rejected.
    pub fn new(surface: &TriSurface) -> Result<Self, SurfaceError> {
        surface.check_closed()?;
        let volume = surface.signed_volume();
        let vertices: Vec<Vector> = surface.positions.iter().map(|p| Vector::new(p.x, p.y, p.z)).collect();
        let mesh = TriMesh::with_flags(vertices, surface.triangles.clone(), TriMeshFlags::ORIENTED)
            .map_err(|_| SurfaceError::Empty)?;
        if !(volume.abs() > 0.0) {
            return Err(SurfaceError::Empty);
        }
        Ok(Self { mesh, orientation: volume.signum() })
    }

    /// Distance to the surface, negative inside (unit of the surface).
    pub fn signed_distance(&self, p: &Vec3) -> f64 {
        let q = Vector::new(p.x, p.y, p.z);
        let (proj, _) = self.mesh.project_local_point_and_get_location(q, false);
        let d = (proj.point - q).length();
        let inside = proj.is_inside == (self.orientation > 0.0);
        if inside { -d } else { d }
    }
}
