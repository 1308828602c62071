//! Cameras: an orbit camera (target, distance, yaw, pitch) and the surgeon's
//! microscope preset that looks down the fissure.
//!
//! In: camera parameters (metres, radians), the viewport aspect. Out: an eye
//! position and f32 view-projection matrices for wgpu's clip space (depth
//! 0..1), computed relative to the camera target so f32 keeps full precision
//! near what is looked at. Stays true: pitch is clamped to ±89° (no gimbal
//! flip), distance stays positive, matrices are finite for finite input.
//!
//! World convention: z is up. Yaw turns about z from +x; pitch raises the eye
//! above the xy plane.

use crate::math::{Point3, Vec3};
use nalgebra::{Isometry3, Matrix4};

/// Largest |pitch|, rad (89°).
pub const MAX_PITCH_RAD: f64 = 89.0 * std::f64::consts::PI / 180.0;

/// An orbit camera looking at `target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    /// Point looked at, metres.
    pub target: Vec3,
    /// Eye–target distance, metres (> 0).
    pub distance_m: f64,
    /// Rotation of the eye about world z, from +x, rad.
    pub yaw_rad: f64,
    /// Elevation of the eye above the xy plane, rad, in [-89°, 89°].
    pub pitch_rad: f64,
    /// Vertical field of view, rad, in (0, pi). Default 40°.
    pub fov_y_rad: f64,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self {
            target: Vec3::zeros(),
            distance_m: 0.3,
            yaw_rad: -std::f64::consts::FRAC_PI_2,
            pitch_rad: 0.5,
            fov_y_rad: 40f64.to_radians(),
        }
    }
}

impl OrbitCamera {
    /// An overview that frames the box `lo..hi` (metres) from the front-left, above.
    pub fn framing(lo: Vec3, hi: Vec3) -> Self {
        let center = (lo + hi) * 0.5;
        let radius = ((hi - lo).norm() * 0.5).max(1e-6);
        let mut cam = Self {
            target: center,
            ..Self::default()
        };
        cam.yaw_rad = -60f64.to_radians();
        cam.pitch_rad = 35f64.to_radians();
        cam.distance_m = radius / (cam.fov_y_rad * 0.5).sin() * 1.05;
        cam
    }

    /// The surgeon's microscope: looks at `target` along `view_direction` (from
    /// the eye towards the target, e.g. down the fissure, the spatulas'
    /// insertion direction), from `distance_m` away. A direction within 1° of
    /// vertical is tilted to the pitch limit.
    pub fn microscope(target: Vec3, view_direction: Vec3, distance_m: f64) -> Self {
        let d = if view_direction.norm() > 0.0 && view_direction.iter().all(|c| c.is_finite()) {
            view_direction.normalize()
        } else {
            -Vec3::z()
        };
        let back = -d; // from target to eye
        let pitch = back
            .z
            .clamp(-1.0, 1.0)
            .asin()
            .clamp(-MAX_PITCH_RAD, MAX_PITCH_RAD);
        let yaw = if back.x.abs() + back.y.abs() > 1e-12 {
            back.y.atan2(back.x)
        } else {
            -std::f64::consts::FRAC_PI_2
        };
        Self {
            target,
            distance_m: distance_m.max(1e-6),
            yaw_rad: yaw,
            pitch_rad: pitch,
            fov_y_rad: 25f64.to_radians(),
        }
    }

    /// A camera at `eye` looking at `target` (metres) with a vertical field of
    /// view of `fov_y_rad`; the orbit turns about `target`. Pitch is clamped
    /// to the limit as in [`OrbitCamera::microscope`].
    pub fn looking(eye: Vec3, target: Vec3, fov_y_rad: f64) -> Self {
        let mut cam = Self::microscope(target, target - eye, (eye - target).norm());
        if fov_y_rad.is_finite() && fov_y_rad > 0.0 && fov_y_rad < std::f64::consts::PI {
            cam.fov_y_rad = fov_y_rad;
        }
        cam
    }

    /// Turns the eye about the target (rad); pitch is clamped.
    pub fn orbit(&mut self, d_yaw: f64, d_pitch: f64) {
        if d_yaw.is_finite() {
            self.yaw_rad = (self.yaw_rad + d_yaw).rem_euclid(std::f64::consts::TAU);
        }
        if d_pitch.is_finite() {
            self.pitch_rad = (self.pitch_rad + d_pitch).clamp(-MAX_PITCH_RAD, MAX_PITCH_RAD);
        }
    }

    /// Multiplies the distance by `factor` (> 0, finite; otherwise ignored).
    pub fn zoom(&mut self, factor: f64) {
        if factor.is_finite() && factor > 0.0 {
            self.distance_m = (self.distance_m * factor).max(1e-5);
        }
    }

    /// Unit vector from the target to the eye.
    pub fn back_direction(&self) -> Vec3 {
        let pitch = self.pitch_rad.clamp(-MAX_PITCH_RAD, MAX_PITCH_RAD);
        Vec3::new(
            pitch.cos() * self.yaw_rad.cos(),
            pitch.cos() * self.yaw_rad.sin(),
            pitch.sin(),
        )
    }

    /// Eye position, metres, world frame.
    pub fn eye(&self) -> Vec3 {
        self.target + self.back_direction() * self.distance_m
    }

    /// (right, up) unit vectors of the view, world frame.
    pub fn right_up(&self) -> (Vec3, Vec3) {
        let forward = -self.back_direction();
        let right = forward.cross(&Vec3::z());
        let right = if right.norm() > 1e-9 {
            right.normalize()
        } else {
            Vec3::x()
        };
        (right, right.cross(&forward).normalize())
    }

    /// View-projection for a viewport of `aspect` = width / height, mapping
    /// world points taken *relative to `self.target`* to wgpu clip space.
    pub fn view_projection(&self, aspect: f64) -> Matrix4<f64> {
        let distance = self.distance_m.max(1e-6);
        let eye = Point3::from(self.back_direction() * distance);
        let view = Isometry3::look_at_rh(&eye, &Point3::origin(), &Vec3::z()).to_homogeneous();
        let near = distance * 0.01;
        let far = distance * 20.0;
        perspective_zero_to_one(self.fov_y_rad.clamp(1e-3, 3.1), aspect.max(1e-6), near, far) * view
    }
}

/// Right-handed perspective projection with depth mapped to 0 (near) .. 1 (far).
pub fn perspective_zero_to_one(fov_y: f64, aspect: f64, near: f64, far: f64) -> Matrix4<f64> {
    let f = 1.0 / (fov_y * 0.5).tan();
    Matrix4::new(
        f / aspect,
        0.0,
        0.0,
        0.0, //
        0.0,
        f,
        0.0,
        0.0, //
        0.0,
        0.0,
        far / (near - far),
        near * far / (near - far), //
        0.0,
        0.0,
        -1.0,
        0.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn project(m: &Matrix4<f64>, p: Vec3) -> Vec3 {
        let h = m * p.push(1.0);
        h.xyz() / h.w
    }

    #[test]
    fn target_projects_to_centre_and_depth_is_zero_to_one() {
        let cam = OrbitCamera {
            target: Vec3::new(5.0, 5.0, 5.0),
            ..OrbitCamera::default()
        };
        let m = cam.view_projection(4.0 / 3.0);
        let c = project(&m, Vec3::zeros());
        assert!(
            c.x.abs() < 1e-12 && c.y.abs() < 1e-12,
            "target must land mid-screen: {c:?}"
        );
        assert!(c.z > 0.0 && c.z < 1.0, "depth inside 0..1: {}", c.z);
        let near = project(&m, cam.back_direction() * cam.distance_m * 0.99);
        let far = project(&m, -cam.back_direction() * cam.distance_m * 5.0);
        assert!(
            near.z < c.z && c.z < far.z,
            "depth must grow away from the eye: {} {} {}",
            near.z,
            c.z,
            far.z
        );
    }

    #[test]
    fn up_is_up_on_screen() {
        let cam = OrbitCamera::default();
        let m = cam.view_projection(1.0);
        let above = project(&m, Vec3::new(0.0, 0.0, 0.01));
        assert!(
            above.y > 0.0,
            "world +z must appear above the centre: {above:?}"
        );
    }

    #[test]
    fn microscope_looks_along_the_given_direction() {
        let dir = Vec3::new(0.0, 0.3, -1.0).normalize();
        let cam = OrbitCamera::microscope(Vec3::new(0.0, 0.0, 0.05), dir, 0.2);
        assert!(
            (cam.back_direction() + dir).norm() < 1e-9,
            "eye must sit behind the view direction"
        );
        let straight_down = OrbitCamera::microscope(Vec3::zeros(), -Vec3::z(), 0.2);
        assert!(
            straight_down.pitch_rad <= MAX_PITCH_RAD
                && straight_down
                    .view_projection(1.0)
                    .iter()
                    .all(|x| x.is_finite())
        );
    }

    #[test]
    fn orbit_clamps_pitch_and_ignores_nan() {
        let mut cam = OrbitCamera::default();
        cam.orbit(0.0, 10.0);
        assert_eq!(cam.pitch_rad, MAX_PITCH_RAD);
        let before = cam;
        cam.orbit(f64::NAN, f64::NAN);
        cam.zoom(f64::NAN);
        cam.zoom(-1.0);
        assert_eq!(cam, before);
    }
}
