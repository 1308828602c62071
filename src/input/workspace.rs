//! Workspace mapping: a stylus with a few centimetres of travel moves a blade
//! by scale, frame and clutch, and PLUS's `Buttons` tool tells the clutch.
//!
//! In: the stylus's absolute poses in its device frame (metres, a unit
//! quaternion) and its button states. Out: the blade pose each stylus pose
//! maps to, in the scene frame. Stays true: a pure function of the poses and
//! buttons received (no clock); while the clutch is held the blade does not
//! move; releasing it never makes the blade jump (the stylus's pose at the
//! release maps to where the blade stands).
//!
//! ## The mapping
//! With `M` the device frame's axes in scene axes ([`StylusMapping::rotation`]),
//! `s` the scale, and an anchor (a stylus pose `(R_s0, p_s0)` and a blade pose
//! `(R_b0, p_b0)`):
//!
//! - position: `p_b = p_b0 + s M (p_s - p_s0)` (a 1 mm stylus move is `s` mm of blade);
//! - orientation: `R_b = (M R_s R_s0^T M^T) R_b0` (the stylus's turn since the
//!   anchor, seen in scene axes, turns the blade; rotations are not scaled).
//!
//! The first stylus pose anchors at the blade's scenario pose (the offset:
//! wherever the stylus starts, the blade starts where the scene puts it). With
//! a clutch, holding its button freezes the blade and releasing it takes a new
//! anchor: the stylus's pose then and the blade's last pose. So a trainee whose
//! stylus reaches the edge of its travel holds the button, brings the stylus
//! back to the middle, releases, and goes on. A link that reconnects (the
//! server restarted) re-anchors the same way.
//!
//! ## What PLUS sends for the buttons
//! PLUS's OpenHaptics device (`vtkPlusOpenHapticsDevice`, PlusLib
//! `src/PlusDataCollection/OpenHaptics/vtkPlusOpenHapticsDevice.cxx`; its
//! documentation `DeviceOpenHaptics.dox`) streams three tools: `Stylus` (the
//! pose, mm), `StylusVelocity` and `Buttons`, a matrix whose first column
//! holds buttons 1 to 4 as 0 or 1 and whose element (0, 1) is the inkwell
//! switch. Over OpenIGTLink a TRANSFORM carries the upper 3x4 block, so
//! buttons 1 to 3 arrive (`R11`, `R21`, `R31`) and button 4 does not; the
//! matrix is no rotation, so it is read without the orthonormality check
//! ([`super::igtl_codec::decode_body_raw`]). The Geomagic Touch has two stylus
//! buttons, 1 (front, dark grey) and 2 (rear, light grey).

use crate::geometry::Pose;
use crate::math::{Matrix3, Quat};

/// The clutch: a button of a `Buttons` tool.
#[derive(Debug, Clone, PartialEq)]
pub struct Clutch {
    /// The OpenIGTLink device name of the buttons' TRANSFORM (PLUS:
    /// `ButtonsTo<ToolReferenceFrame>`, e.g. `ButtonsToBase`).
    pub device: String,
    /// The button that clutches, 1 to 3 (PLUS's numbering; 1 is the Touch's front button).
    pub button: u8,
}

/// How a stylus's motion maps to a blade (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct StylusMapping {
    /// Blade metres per stylus metre (> 0, finite).
    pub scale: f64,
    /// The device frame's axes in scene axes (a rotation): `v_scene = rotation v_device`.
    pub rotation: Matrix3<f64>,
    /// Where the first stylus pose maps: the blade's pose at the start of the scene.
    pub origin: Pose,
    /// The clutch button, if any.
    pub clutch: Option<Clutch>,
}

/// The button states in a PLUS `Buttons` matrix: buttons 1 to 3 (index 0 to
/// 2) from the first column, the inkwell switch (index 3) from element (0, 1).
/// A value above one half counts as pressed.
pub fn plus_buttons(matrix: &Matrix3<f64>) -> [bool; 4] {
    let on = |v: f64| v > 0.5;
    [on(matrix[(0, 0)]), on(matrix[(1, 0)]), on(matrix[(2, 0)]), on(matrix[(0, 1)])]
}

/// A stylus mapped to a blade: the mapping, its anchor and its clutch state.
#[derive(Debug, Clone)]
pub struct MappedStylus {
    mapping: StylusMapping,
    /// (stylus pose, blade pose) the motion is measured from; `None`: the next
    /// stylus pose anchors.
    anchor: Option<(Pose, Pose)>,
    /// The blade's last accepted pose.
    blade: Pose,
    clutched: bool,
    releases: u64,
}

impl MappedStylus {
    pub fn new(mapping: StylusMapping) -> Self {
        let blade = mapping.origin;
        Self { mapping, anchor: None, blade, clutched: false, releases: 0 }
    }

    /// The mapping in force.
    pub fn mapping(&self) -> &StylusMapping {
        &self.mapping
    }

    /// The blade pose `stylus` maps to now. While the clutch is held this is
    /// the blade's last accepted pose. Call [`MappedStylus::accept`] with the
    /// result once it has passed the plausibility checks.
    pub fn map(&mut self, stylus: &Pose) -> Pose {
        if self.clutched {
            return self.blade;
        }
        let (s0, b0) = *self.anchor.get_or_insert((*stylus, self.blade));
        let m = self.mapping.rotation;
        let position = b0.position + m * (stylus.position - s0.position) * self.mapping.scale;
        let turn_device = (stylus.rotation * s0.rotation.inverse()).to_rotation_matrix().into_inner();
        let turn_scene = m * turn_device * m.transpose();
        let turn = Quat::from_matrix_eps(&turn_scene, 1e-12, 100, Quat::identity());
        let rotation = Quat::new_normalize((turn * b0.rotation).into_inner());
        Pose { position, rotation }
    }

    /// Records that the blade took `pose` (a pose [`MappedStylus::map`] gave).
    pub fn accept(&mut self, pose: Pose) {
        self.blade = pose;
    }

    /// Sets the clutch button's state. A release re-anchors at the next stylus pose.
    pub fn set_clutch(&mut self, held: bool) {
        if self.clutched && !held {
            self.anchor = None;
            self.releases += 1;
        }
        if held {
            self.anchor = None;
        }
        self.clutched = held;
    }

    /// Forgets the anchor (and a held clutch): the next stylus pose maps to the
    /// blade's last pose. For a link that was lost and came back.
    pub fn reanchor(&mut self) {
        self.anchor = None;
        self.clutched = false;
    }

    /// Whether the clutch is held.
    pub fn clutched(&self) -> bool {
        self.clutched
    }

    /// How many times the clutch was released.
    pub fn releases(&self) -> u64 {
        self.releases
    }

    /// The blade's last accepted pose.
    pub fn blade(&self) -> Pose {
        self.blade
    }
}

/// The rotation matrix of a unit quaternion (how a configuration states a frame).
pub fn rotation_matrix(q: &Quat) -> Matrix3<f64> {
    q.to_rotation_matrix().into_inner()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn at(x_mm: f64, y_mm: f64, z_mm: f64) -> Pose {
        Pose { position: Vec3::new(x_mm, y_mm, z_mm) * 1e-3, rotation: Quat::identity() }
    }

    fn mapping(scale: f64, rotation: Matrix3<f64>) -> StylusMapping {
        let origin = Pose { position: Vec3::new(0.1, 0.2, 0.3), rotation: Quat::from_axis_angle(&Vec3::x_axis(), 0.3) };
        StylusMapping { scale, rotation, origin, clutch: None }
    }

    #[test]
    fn the_first_pose_maps_to_the_origin_and_motion_is_scaled_in_scene_axes() {
        // Device x is scene -x, device y is scene -y (a half turn about z).
        let half_turn = rotation_matrix(&Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::PI));
        let mut m = MappedStylus::new(mapping(0.5, half_turn));
        let origin = m.mapping().origin;
        let first = m.map(&at(40.0, -10.0, 5.0));
        assert!((first.position - origin.position).norm() < 1e-15 && first.rotation.angle_to(&origin.rotation) < 1e-12, "{first:?}");
        m.accept(first);
        let moved = m.map(&at(50.0, -10.0, 25.0));
        let expected = origin.position + Vec3::new(-10.0, 0.0, 20.0) * 0.5e-3;
        assert!((moved.position - expected).norm() < 1e-12, "10 mm device +x is 5 mm scene -x; 20 mm +z is 10 mm +z: {:?}", moved.position);
    }

    #[test]
    fn a_stylus_turn_turns_the_blade_about_the_same_scene_axis() {
        let quarter_z = rotation_matrix(&Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::FRAC_PI_2));
        let mut m = MappedStylus::new(mapping(1.0, quarter_z));
        let origin = m.mapping().origin;
        let start = Pose { position: Vec3::zeros(), rotation: Quat::from_axis_angle(&Vec3::y_axis(), 0.2) };
        m.map(&start);
        // Turn the stylus by 0.4 rad about device x (in the device's base frame).
        let turned = Pose { position: Vec3::zeros(), rotation: Quat::from_axis_angle(&Vec3::x_axis(), 0.4) * start.rotation };
        let blade = m.map(&turned);
        // Device x is scene y: the blade turns by 0.4 rad about scene y.
        let expected = Quat::from_axis_angle(&Vec3::y_axis(), 0.4) * origin.rotation;
        assert!(blade.rotation.angle_to(&expected) < 1e-9, "turned to {:?}, expected {:?}", blade.rotation, expected);
        assert!((blade.position - origin.position).norm() < 1e-15, "a turn in place does not move the blade");
    }

    #[test]
    fn the_clutch_freezes_the_blade_and_its_release_recentres_without_a_jump() {
        let mut m = MappedStylus::new(mapping(2.0, Matrix3::identity()));
        let origin = m.mapping().origin.position;
        let first = m.map(&at(0.0, 0.0, 0.0));
        m.accept(first);
        let b = m.map(&at(30.0, 0.0, 0.0));
        m.accept(b);
        assert!((b.position - (origin + Vec3::new(0.06, 0.0, 0.0))).norm() < 1e-12, "30 mm at scale 2 is 60 mm");
        m.set_clutch(true);
        // The stylus goes back to the middle of its travel: the blade stays.
        for x in [20.0, 10.0, 0.0] {
            let held = m.map(&at(x, 0.0, 0.0));
            assert!((held.position - b.position).norm() < 1e-15, "clutched at {x} mm: {:?}", held.position);
        }
        m.set_clutch(false);
        let again = m.map(&at(0.0, 0.0, 0.0));
        assert!((again.position - b.position).norm() < 1e-15, "the release re-anchors: no jump back to the origin");
        m.accept(again);
        let further = m.map(&at(10.0, 0.0, 0.0));
        assert!((further.position - (b.position + Vec3::new(0.02, 0.0, 0.0))).norm() < 1e-12, "and the next 10 mm go on from there");
        assert_eq!(m.releases(), 1);
    }

    #[test]
    fn plus_buttons_read_the_first_column_and_the_inkwell() {
        let mut matrix = Matrix3::zeros();
        assert_eq!(plus_buttons(&matrix), [false; 4]);
        matrix[(1, 0)] = 1.0;
        matrix[(0, 1)] = 1.0;
        assert_eq!(plus_buttons(&matrix), [false, true, false, true], "button 2 and the inkwell");
        matrix[(0, 0)] = f64::NAN;
        assert!(!plus_buttons(&matrix)[0], "NaN is not a press");
    }
}
