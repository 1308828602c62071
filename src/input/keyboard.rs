//! Keyboard and mouse input: the fallback when no gamepad or tracker is used.
//!
//! In: [`KeyEvent`]s and mouse deltas (synthetic in tests; [`key_from_winit`]
//! converts winit physical keys at the edge). Out: a [`KeyCommand`] each frame:
//! the selected spatula's velocity in its own frame, camera orbit and zoom.
//! Stays true: the mapping is a pure function of the held keys; keys are
//! physical (layout-independent: "W" is the key left of "E" on any layout).
//!
//! ## Key map (physical keys, US names)
//! | key | action (spatula frame) |
//! |---|---|
//! | W / S | +x / -x: along the blade, towards / away from the tip |
//! | D / A | +y / -y: across the blade |
//! | E / Q | +z / -z: through the blade (opens / closes the fissure) |
//! | Up / Down | pitch about y, + / - |
//! | Right / Left | yaw about z, + / - |
//! | Page Up / Page Down | roll about x (blade axis), + / - |
//! | Tab | switch spatula (left <-> right) |
//! | Shift (held) | precision: speeds x 0.25 |
//! | mouse drag (left button) | camera orbit |
//! | mouse wheel | camera zoom |
//!
//! Opposite keys held together cancel.

use super::{PoseVelocity, SpatulaSlot};
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
}

#[cfg(test)]
const KEY_COUNT: usize = 14;

impl Key {
    fn bit(self) -> u16 {
        1 << (self as u16)
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
    held: u16,
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
    pub spatula: SpatulaSlot,
    pub velocity: PoseVelocity,
}

/// Held keys plus the selected spatula (Tab toggles on key-down only).
#[derive(Debug, Clone, Default)]
pub struct KeyboardController {
    pub keys: KeyState,
    pub spatula: SpatulaSlot,
    pub mapping: KeyboardMapping,
}

impl KeyboardController {
    /// A controller with the given tuning.
    pub fn new(mapping: KeyboardMapping) -> Self {
        Self {
            mapping,
            ..Self::default()
        }
    }

    /// Applies one key event; auto-repeat of a held Tab does not switch again.
    pub fn apply(&mut self, event: KeyEvent) {
        if event.key == Key::Tab && event.pressed && !self.keys.is_held(Key::Tab) {
            self.spatula = self.spatula.other();
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
        }
    }
}

/// The key a winit physical key stands for in this map.
pub fn key_from_winit(key: &winit::keyboard::PhysicalKey) -> Option<Key> {
    use winit::keyboard::{KeyCode, PhysicalKey};
    let PhysicalKey::Code(code) = key else {
        return None;
    };
    Some(match code {
        KeyCode::KeyW => Key::W,
        KeyCode::KeyA => Key::A,
        KeyCode::KeyS => Key::S,
        KeyCode::KeyD => Key::D,
        KeyCode::KeyQ => Key::Q,
        KeyCode::KeyE => Key::E,
        KeyCode::ArrowUp => Key::Up,
        KeyCode::ArrowDown => Key::Down,
        KeyCode::ArrowLeft => Key::Left,
        KeyCode::ArrowRight => Key::Right,
        KeyCode::PageUp => Key::PageUp,
        KeyCode::PageDown => Key::PageDown,
        KeyCode::Tab => Key::Tab,
        KeyCode::ShiftLeft | KeyCode::ShiftRight => Key::Shift,
        _ => return None,
    })
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
        ];
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
        assert_eq!(
            c.spatula,
            SpatulaSlot::Right,
            "auto-repeat must not switch back"
        );
        c.apply(KeyEvent {
            key: Key::Tab,
            pressed: false,
        });
        press(&mut c, Key::Tab);
        assert_eq!(c.spatula, SpatulaSlot::Left);
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

    #[test]
    fn winit_keys_convert() {
        use winit::keyboard::{KeyCode, PhysicalKey};
        assert_eq!(
            key_from_winit(&PhysicalKey::Code(KeyCode::KeyW)),
            Some(Key::W)
        );
        assert_eq!(
            key_from_winit(&PhysicalKey::Code(KeyCode::ShiftRight)),
            Some(Key::Shift)
        );
        assert_eq!(key_from_winit(&PhysicalKey::Code(KeyCode::KeyZ)), None);
    }
}
