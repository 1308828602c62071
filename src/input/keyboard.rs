//! Keyboard and mouse input: the fallback when no gamepad or tracker is used.
//!
//! In: [`KeyEvent`]s and mouse deltas (synthetic in tests;
//! [`super::bindings`] converts winit physical keys at the edge). Out: a
//! [`KeyCommand`] each frame: the active blade and its velocity in its own
//! frame; camera orbit and zoom. Stays true: the mapping is a pure function of
//! the held keys and the active blade; keys are physical (layout-independent:
//! "W" is the key left of "E" on any layout); the active blade is always below
//! the scene's blade count.
//!
//! ## Key map (physical keys, US names; the window's table is [`super::bindings::CONTROLS`])
//! | key | action (spatula frame) |
//! |---|---|
//! | W / S | +x / -x: along the blade, towards / away from the tip |
//! | D / A | +y / -y: across the blade |
//! | E / Q | +z / -z: through the blade, towards its +z / -z face |
//! | Up / Down | pitch about y, + / - |
//! | Right / Left | yaw about z, + / - |
//! | Page Up / Page Down | roll about x (blade axis), + / - |
//! | 1 .. 9 | make blade 1 .. 9 the active one (beyond the scene's count: nothing) |
//! | Tab | next blade (cycles) |
//! | Shift (held) | precision: speeds x 0.25 |
//! | mouse drag (left button) | camera orbit |
//! | mouse wheel | camera zoom |
//!
//! Opposite keys held together cancel.

use super::PoseVelocity;
use crate::math::Vec3;

/// Keys this map reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    W,
    A,
    S,
    D,
    Q,
    E,
    Up,
    Down,
    Left,
    Right,
    PageUp,
    PageDown,
    Tab,
    Shift,
    Digit1,
    Digit2,
    Digit3,
    Digit4,
    Digit5,
    Digit6,
    Digit7,
    Digit8,
    Digit9,
}

/// The digit keys in order: `DIGITS[k]` selects blade k (0-based).
pub const DIGITS: [Key; 9] = [
    Key::Digit1,
    Key::Digit2,
    Key::Digit3,
    Key::Digit4,
    Key::Digit5,
    Key::Digit6,
    Key::Digit7,
    Key::Digit8,
    Key::Digit9,
];

#[cfg(test)]
const KEY_COUNT: usize = 23;

impl Key {
    fn bit(self) -> u32 {
        1 << (self as u32)
    }

    /// The blade a digit key selects (0-based), `None` for other keys.
    pub fn digit_index(self) -> Option<usize> {
        DIGITS.iter().position(|d| *d == self)
    }

    /// True for the keys that move the active blade (not Tab, Shift or digits).
    pub fn moves(self) -> bool {
        !matches!(self, Key::Tab | Key::Shift) && self.digit_index().is_none()
    }
}

/// A key going down or up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KeyEvent {
    pub key: Key,
    pub pressed: bool,
}

/// Which keys are held (a bit set).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KeyState {
    held: u32,
}

impl KeyState {
    /// True if `key` is held.
    pub fn is_held(&self, key: Key) -> bool {
        self.held & key.bit() != 0
    }

    /// Marks `key` held or released.
    pub fn set(&mut self, key: Key, held: bool) {
        if held {
            self.held |= key.bit();
        } else {
            self.held &= !key.bit();
        }
    }

    /// True when a key that moves the blade is held.
    pub fn any_motion(&self) -> bool {
        let selection = Key::Tab.bit() | Key::Shift.bit() | DIGITS.iter().fold(0, |m, d| m | d.bit());
        self.held & !selection != 0
    }

    fn axis(&self, plus: Key, minus: Key) -> f64 {
        (self.is_held(plus) as i8 - self.is_held(minus) as i8) as f64
    }
}

/// Tuning of the key map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeyboardMapping {
    /// Spatula speed while a translation key is held, m/s (> 0). Default 0.01.
    pub speed_m_s: f64,
    /// Spatula turn rate while a rotation key is held, rad/s (> 0). Default 0.5.
    pub rate_rad_s: f64,
    /// Speed factor while Shift is held, (0, 1]. Default 0.25.
    pub precision_factor: f64,
    /// Camera orbit per pixel of mouse drag, rad/px (> 0). Default 0.005.
    pub orbit_rad_per_px: f64,
    /// Camera zoom factor per wheel line (> 1 zooms out on negative lines). Default 1.1.
    pub zoom_per_line: f64,
}

impl Default for KeyboardMapping {
    fn default() -> Self {
        Self {
            speed_m_s: 0.01,
            rate_rad_s: 0.5,
            precision_factor: 0.25,
            orbit_rad_per_px: 0.005,
            zoom_per_line: 1.1,
        }
    }
}

/// The pure mapping: held keys to a velocity in the spatula frame.
pub fn map_keys(keys: &KeyState, mapping: &KeyboardMapping) -> PoseVelocity {
    let factor = if keys.is_held(Key::Shift) {
        mapping.precision_factor
    } else {
        1.0
    };
    let linear = Vec3::new(
        keys.axis(Key::W, Key::S),
        keys.axis(Key::D, Key::A),
        keys.axis(Key::E, Key::Q),
    );
    let angular = Vec3::new(
        keys.axis(Key::PageUp, Key::PageDown),
        keys.axis(Key::Up, Key::Down),
        keys.axis(Key::Right, Key::Left),
    );
    PoseVelocity {
        linear_m_s: linear * (mapping.speed_m_s * factor),
        angular_rad_s: angular * (mapping.rate_rad_s * factor),
    }
}

/// Camera change asked for by the mouse.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CameraNudge {
    /// Orbit: (yaw, pitch) change, rad.
    pub orbit_rad: [f64; 2],
    /// Multiply the camera distance by this (1 = no change, > 0).
    pub zoom_factor: f64,
}

/// The pure mouse mapping: a drag (pixels, only while the left button is held)
/// and wheel lines (positive = away from the user = zoom in).
pub fn map_mouse(
    drag_px: [f64; 2],
    left_button: bool,
    wheel_lines: f64,
    mapping: &KeyboardMapping,
) -> CameraNudge {
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    let orbit_rad = if left_button {
        [
            -finite(drag_px[0]) * mapping.orbit_rad_per_px,
            finite(drag_px[1]) * mapping.orbit_rad_per_px,
        ]
    } else {
        [0.0, 0.0]
    };
    let zoom_factor = mapping
        .zoom_per_line
        .powf(-finite(wheel_lines).clamp(-20.0, 20.0));
    CameraNudge {
        orbit_rad,
        zoom_factor,
    }
}

/// What the keyboard asks for this frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct KeyCommand {
    /// The active blade (index into the scene's spatulas).
    pub spatula: usize,
    pub velocity: PoseVelocity,
    /// True while a key that moves the blade is held (a trajectory-bound
    /// blade is taken over by the keys only then).
    pub moving: bool,
}

/// Held keys plus the active blade (Tab cycles and digits select, on key-down only).
#[derive(Debug, Clone)]
pub struct KeyboardController {
    pub keys: KeyState,
    /// The active blade, below `spatula_count`.
    pub spatula: usize,
    /// Blades in the scene (>= 1).
    spatula_count: usize,
    pub mapping: KeyboardMapping,
}

impl Default for KeyboardController {
    fn default() -> Self {
        Self { keys: KeyState::default(), spatula: 0, spatula_count: 2, mapping: KeyboardMapping::default() }
    }
}

impl KeyboardController {
    /// A controller with the given tuning (two blades until [`Self::set_spatula_count`]).
    pub fn new(mapping: KeyboardMapping) -> Self {
        Self {
            mapping,
            ..Self::default()
        }
    }

    /// Tells the controller how many blades the scene has (at least 1 is
    /// assumed); the active blade stays in range.
    pub fn set_spatula_count(&mut self, count: usize) {
        self.spatula_count = count.max(1);
        if self.spatula >= self.spatula_count {
            self.spatula = 0;
        }
    }

    /// Blades the controller cycles through.
    pub fn spatula_count(&self) -> usize {
        self.spatula_count
    }

    /// Applies one key event; auto-repeat of a held Tab or digit does not
    /// select again; a digit beyond the scene's blades does nothing.
    pub fn apply(&mut self, event: KeyEvent) {
        let fresh = event.pressed && !self.keys.is_held(event.key);
        if fresh && event.key == Key::Tab {
            self.spatula = (self.spatula + 1) % self.spatula_count;
        }
        if fresh && let Some(k) = event.key.digit_index().filter(|k| *k < self.spatula_count) {
            self.spatula = k;
        }
        self.keys.set(event.key, event.pressed);
    }

    /// Releases every key (call when the window loses focus, or keys stick).
    pub fn release_all(&mut self) {
        self.keys = KeyState::default();
    }

    /// This frame's command.
    pub fn command(&self) -> KeyCommand {
        KeyCommand {
            spatula: self.spatula,
            velocity: map_keys(&self.keys, &self.mapping),
            moving: self.keys.any_motion(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn press(c: &mut KeyboardController, key: Key) {
        c.apply(KeyEvent { key, pressed: true });
    }

    #[test]
    fn keys_bits_are_distinct() {
        let all = [
            Key::W,
            Key::A,
            Key::S,
            Key::D,
            Key::Q,
            Key::E,
            Key::Up,
            Key::Down,
            Key::Left,
            Key::Right,
            Key::PageUp,
            Key::PageDown,
            Key::Tab,
            Key::Shift,
        ]
        .into_iter()
        .chain(DIGITS)
        .collect::<Vec<_>>();
        assert_eq!(all.len(), KEY_COUNT);
        let mut state = KeyState::default();
        for k in all {
            assert!(!state.is_held(k), "{k:?} aliases another key's bit");
            state.set(k, true);
        }
    }

    #[test]
    fn translation_rotation_and_cancel() {
        let m = KeyboardMapping::default();
        let mut c = KeyboardController::new(m);
        press(&mut c, Key::W);
        press(&mut c, Key::E);
        press(&mut c, Key::Right);
        let v = c.command().velocity;
        assert_eq!(
            v.linear_m_s,
            Vec3::new(m.speed_m_s, 0.0, m.speed_m_s),
            "W + E"
        );
        assert_eq!(
            v.angular_rad_s,
            Vec3::new(0.0, 0.0, m.rate_rad_s),
            "Right yaws +z"
        );
        press(&mut c, Key::S);
        assert_eq!(c.command().velocity.linear_m_s.x, 0.0, "W and S cancel");
        press(&mut c, Key::Shift);
        assert!(
            (c.command().velocity.linear_m_s.z - m.speed_m_s * m.precision_factor).abs() < 1e-15,
            "Shift slows"
        );
        c.release_all();
        assert!(c.command().velocity.is_zero());
    }

    #[test]
    fn tab_switches_once_per_press() {
        let mut c = KeyboardController::default();
        press(&mut c, Key::Tab);
        press(&mut c, Key::Tab); // auto-repeat
        assert_eq!(c.spatula, 1, "auto-repeat must not switch back");
        c.apply(KeyEvent {
            key: Key::Tab,
            pressed: false,
        });
        press(&mut c, Key::Tab);
        assert_eq!(c.spatula, 0, "two blades: Tab cycles back to the first");
    }

    #[test]
    fn digits_select_a_blade_of_the_scene_only() {
        let mut c = KeyboardController::default();
        c.set_spatula_count(3);
        press(&mut c, Key::Digit3);
        assert_eq!(c.command().spatula, 2, "3 selects the third blade");
        assert!(!c.command().moving, "selecting is not moving");
        press(&mut c, Key::Digit9);
        assert_eq!(c.spatula, 2, "9 is beyond three blades: nothing changes");
        press(&mut c, Key::Tab);
        assert_eq!(c.spatula, 0, "Tab after the last blade cycles to the first");
        press(&mut c, Key::Digit2);
        press(&mut c, Key::W);
        assert!(c.command().moving && c.command().spatula == 1);
        c.set_spatula_count(1);
        assert_eq!(c.spatula, 0, "a smaller scene keeps the active blade in range");
    }

    #[test]
    fn mouse_orbits_only_while_dragging_and_zooms() {
        let m = KeyboardMapping::default();
        let idle = map_mouse([10.0, 5.0], false, 0.0, &m);
        assert_eq!(idle.orbit_rad, [0.0, 0.0]);
        assert_eq!(idle.zoom_factor, 1.0);
        let drag = map_mouse([10.0, 5.0], true, 1.0, &m);
        assert!((drag.orbit_rad[0] + 10.0 * m.orbit_rad_per_px).abs() < 1e-15);
        assert!(drag.zoom_factor < 1.0, "wheel forward zooms in");
        assert_eq!(
            map_mouse([f64::NAN, 0.0], true, f64::NAN, &m).orbit_rad,
            [0.0, 0.0]
        );
    }
}
