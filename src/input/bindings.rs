//! The window's key bindings: one table the window, the script reader and the
//! README test all read, so the Controls table cannot drift from the code.
//!
//! In: a winit physical key and whether Ctrl is held (or a key's name in a
//! script). Out: the [`KeyAction`] it stands for. Stays true: every bound key
//! appears in exactly one row of [`CONTROLS`], and `tests/suite/readme_controls.rs`
//! holds README's Controls table to [`CONTROLS`] row for row.

use super::keyboard::Key;
use winit::keyboard::KeyCode;

/// What a key does in the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyAction {
    /// A key of the blade map ([`super::keyboard`]): held keys move the active
    /// blade, Tab and the digits select it, Shift slows.
    Blade(Key),
    /// Microscope camera preset.
    Microscope,
    /// Overview camera preset.
    Overview,
    /// Next surface colour.
    CycleField,
    /// Start / stop recording.
    Record,
    /// Gamepad force feedback on / off.
    Rumble,
    /// Microscissors at the active blade's tip: cut the arachnoid bands near it.
    Cut,
    /// Give the keys back to the scene (from the panel's text field).
    SceneFocus,
    /// Quit (Ctrl+Q).
    Quit,
}

/// One bound key: its winit code, whether Ctrl must be held, its name (in
/// scripts and in [`CONTROLS`]) and what it does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KeyBinding {
    pub code: KeyCode,
    pub ctrl: bool,
    pub name: &'static str,
    pub action: KeyAction,
}

const fn bind(code: KeyCode, name: &'static str, action: KeyAction) -> KeyBinding {
    KeyBinding { code, ctrl: false, name, action }
}

const fn blade(code: KeyCode, name: &'static str, key: Key) -> KeyBinding {
    bind(code, name, KeyAction::Blade(key))
}

/// Every key the window reacts to.
pub const KEY_BINDINGS: &[KeyBinding] = &[
    blade(KeyCode::KeyW, "W", Key::W),
    blade(KeyCode::KeyS, "S", Key::S),
    blade(KeyCode::KeyD, "D", Key::D),
    blade(KeyCode::KeyA, "A", Key::A),
    blade(KeyCode::KeyE, "E", Key::E),
    blade(KeyCode::KeyQ, "Q", Key::Q),
    blade(KeyCode::ArrowUp, "Up", Key::Up),
    blade(KeyCode::ArrowDown, "Down", Key::Down),
    blade(KeyCode::ArrowLeft, "Left", Key::Left),
    blade(KeyCode::ArrowRight, "Right", Key::Right),
    blade(KeyCode::PageUp, "PageUp", Key::PageUp),
    blade(KeyCode::PageDown, "PageDown", Key::PageDown),
    blade(KeyCode::Digit1, "1", Key::Digit1),
    blade(KeyCode::Digit2, "2", Key::Digit2),
    blade(KeyCode::Digit3, "3", Key::Digit3),
    blade(KeyCode::Digit4, "4", Key::Digit4),
    blade(KeyCode::Digit5, "5", Key::Digit5),
    blade(KeyCode::Digit6, "6", Key::Digit6),
    blade(KeyCode::Digit7, "7", Key::Digit7),
    blade(KeyCode::Digit8, "8", Key::Digit8),
    blade(KeyCode::Digit9, "9", Key::Digit9),
    blade(KeyCode::Tab, "Tab", Key::Tab),
    blade(KeyCode::ShiftLeft, "Shift", Key::Shift),
    blade(KeyCode::ShiftRight, "Shift", Key::Shift),
    bind(KeyCode::KeyM, "M", KeyAction::Microscope),
    bind(KeyCode::KeyO, "O", KeyAction::Overview),
    bind(KeyCode::KeyF, "F", KeyAction::CycleField),
    bind(KeyCode::KeyR, "R", KeyAction::Record),
    bind(KeyCode::KeyH, "H", KeyAction::Rumble),
    bind(KeyCode::KeyX, "X", KeyAction::Cut),
    bind(KeyCode::Escape, "Esc", KeyAction::SceneFocus),
    KeyBinding { code: KeyCode::KeyQ, ctrl: true, name: "Ctrl+Q", action: KeyAction::Quit },
];

/// The action of `code` with Ctrl held or not. With Ctrl held only the Ctrl
/// chords count (Ctrl+W does not move a blade); Shift is bound either way.
pub fn action_of(code: KeyCode, ctrl: bool) -> Option<KeyAction> {
    KEY_BINDINGS
        .iter()
        .find(|b| b.code == code && (b.ctrl == ctrl || b.action == KeyAction::Blade(Key::Shift)))
        .map(|b| b.action)
}

/// Where one key event goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyRoute {
    /// The scene acts on it.
    Scene(KeyAction),
    /// The panel's text field gets it.
    Panel,
    /// The keys go back to the scene (the panel's text field loses its focus).
    ReturnToScene,
    /// Not bound: nothing happens.
    Ignore,
}

/// Routes a key event: the panel gets keys only while its text field has the
/// focus, and even then Esc and Tab give them back to the scene (Tab never
/// moves the focus into the panel), Ctrl+Q still quits, and a blade key's
/// release still reaches the blade map (a key held when the focus moved must
/// not stick).
pub fn route(code: KeyCode, ctrl: bool, pressed: bool, panel_has_keys: bool) -> KeyRoute {
    let action = action_of(code, ctrl);
    if !panel_has_keys {
        return action.map_or(KeyRoute::Ignore, KeyRoute::Scene);
    }
    match action {
        Some(KeyAction::SceneFocus | KeyAction::Blade(Key::Tab)) if pressed => KeyRoute::ReturnToScene,
        Some(KeyAction::Quit) => KeyRoute::Scene(KeyAction::Quit),
        Some(a @ KeyAction::Blade(_)) if !pressed => KeyRoute::Scene(a),
        _ => KeyRoute::Panel,
    }
}

/// The blade-map key a script names (`W`, `pageup`, `1`, `Tab`, ...; case-insensitive).
pub fn key_named(name: &str) -> Option<Key> {
    KEY_BINDINGS.iter().find_map(|b| match b.action {
        KeyAction::Blade(k) if b.name.eq_ignore_ascii_case(name) => Some(k),
        _ => None,
    })
}

/// The names scripts accept for blade-map keys, for error messages.
pub fn key_names() -> String {
    let mut names: Vec<&str> = Vec::new();
    for b in KEY_BINDINGS {
        if matches!(b.action, KeyAction::Blade(_)) && !names.contains(&b.name) {
            names.push(b.name);
        }
    }
    names.join(" ")
}

/// One row of the README's Controls table: the input and action cells as
/// written there, and the key names ([`KeyBinding::name`]) the row documents.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControlRow {
    pub input: &'static str,
    pub action: &'static str,
    pub keys: &'static [&'static str],
}

/// The README's Controls table, row for row (`tests/suite/readme_controls.rs`).
pub const CONTROLS: &[ControlRow] = &[
    ControlRow {
        input: "W / S, D / A, E / Q",
        action: "move the active blade along it, across it, through it (E towards its +z face; in the default scene both blades face up, so E lifts and Q lowers: E opens with the frontal blade, Q with the temporal one)",
        keys: &["W", "S", "D", "A", "E", "Q"],
    },
    ControlRow {
        input: "arrows, Page Up / Down",
        action: "pitch, yaw, roll the active blade",
        keys: &["Up", "Down", "Left", "Right", "PageUp", "PageDown"],
    },
    ControlRow {
        input: "1, 2, … 9",
        action: "make blade 1, 2, … the active one, in the scenario's order (the panel names it; a number beyond the scene's blades does nothing)",
        keys: &["1", "2", "3", "4", "5", "6", "7", "8", "9"],
    },
    ControlRow {
        input: "Tab",
        action: "next blade (cycles); never moves the keys into the panel",
        keys: &["Tab"],
    },
    ControlRow { input: "Shift (held)", action: "precision: speeds x 0.25", keys: &["Shift"] },
    ControlRow { input: "mouse drag / wheel", action: "orbit / zoom the camera; a click on the scene gives the keys back to it", keys: &[] },
    ControlRow { input: "M / O", action: "microscope view / overview", keys: &["M", "O"] },
    ControlRow {
        input: "F",
        action: "surface colour: none, displacement, contact pressure, largest principal strain, infarct risk (a scene with `Ischemia`), each with its colour bar (without the scene's `StressField` stage, strain comes from a background worker on the other core, a frame or a few behind; the simulation never waits for it)",
        keys: &["F"],
    },
    ControlRow {
        input: "R",
        action: "record / stop: a trajectory CSV in the recordings folder (see Recordings below) that `fissure replay --trajectory` plays back",
        keys: &["R"],
    },
    ControlRow {
        input: "H",
        action: "gamepad force feedback on / off: the pad rumbles with the reaction force on the blade it drives (stronger with more force, capped; the status bar says \"pad rumble N %\", or that the pad has none); `fissure run --no-rumble` starts with it off",
        keys: &["H"],
    },
    ControlRow {
        input: "X",
        action: "microscissors: cut the arachnoid bands within 2 mm of the active blade's tip (a scene with tethers; the panel lists what was cut or torn)",
        keys: &["X"],
    },
    ControlRow {
        input: "Esc",
        action: "keys back to the scene (after typing in the panel's text field); the panel shows where keys go: \"keys -> scene\" or \"keys -> panel\"",
        keys: &["Esc"],
    },
    ControlRow { input: "Ctrl+Q", action: "end the session: the session from the scene at rest is written as a recording and debriefed against the scene's careful trajectory, the panel shows the verdicts and the page's path (the End session button and closing the window do the same); again: quit", keys: &["Ctrl+Q"] },
    ControlRow {
        input: "gamepad",
        action: "left stick and triggers move (A toggles translate / rotate), LB / RB pick the spatula on the left / right of the screen, right stick orbits, X precision (table in `src/input/gamepad.rs`)",
        keys: &[],
    },
    ControlRow {
        input: "SpaceMouse",
        action: "a blade bound to it (`input: SpaceMouse`) moves at the rates its cap is pushed and turned, read through spacenavd or else its HID device; the cap is the blade: push away to advance it, lift towards its +z face, tilt and twist to turn it; left button: the next SpaceMouse blade, right button: precision (speeds x 0.25); the status line names the device or says why none is read",
        keys: &[],
    },
    ControlRow {
        input: "haptic stylus (PLUS)",
        action: "a blade bound to `OpenIgtLink(device: \"StylusToBase\", connect: \"127.0.0.1:18944\", mapping: .., force: ..)` follows a PlusServer's stylus by scale and frame; holding the clutch button (the Touch's front one in `config/sylvian_touch.ron`) holds the blade while the stylus is re-centred; the blade's force goes back as PLUS's `ForceToBase` TRANSFORM, cut to the device's maximum",
        keys: &[],
    },
    ControlRow {
        input: "OpenIGTLink",
        action: "TRANSFORM messages on 127.0.0.1:18944, device names bound in the scenario (`input: OpenIgtLink(device: \"Spatula1\")`, millimetres); the force on each spatula goes back as `SENSOR Force_<spatula>` (3 float64 N). A pose outside the workspace (default ±1000 mm on each axis around the scene origin) or further from the last accepted pose than the speed limit allows (default 3000 mm/s, by the sender's timestamps, an interval counting as at least 10 ms) is refused: the last good pose holds, a warning is logged (the first, then at most one a second with the count), the panel's status line and the exit summary count them",
        keys: &[],
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    /// Every bound key is documented in exactly one Controls row, and every
    /// key a row documents is bound: the table cannot list a key the code
    /// lacks, nor the code gain a key the table does not show.
    #[test]
    fn every_binding_is_in_exactly_one_controls_row_and_back() {
        for b in KEY_BINDINGS {
            let rows: Vec<&str> = CONTROLS.iter().filter(|r| r.keys.contains(&b.name)).map(|r| r.input).collect();
            assert_eq!(rows.len(), 1, "key {} ({:?}) must be in exactly one Controls row, found in {rows:?}", b.name, b.code);
        }
        for row in CONTROLS {
            for name in row.keys {
                assert!(KEY_BINDINGS.iter().any(|b| b.name == *name), "Controls row `{}` lists {name}, which no binding has", row.input);
            }
        }
    }

    #[test]
    fn codes_map_to_one_action_and_ctrl_chords_do_not_move_blades() {
        for (i, a) in KEY_BINDINGS.iter().enumerate() {
            for b in &KEY_BINDINGS[i + 1..] {
                assert!(!(a.code == b.code && a.ctrl == b.ctrl), "{:?} (ctrl {}) is bound twice: {} and {}", a.code, a.ctrl, a.name, b.name);
            }
        }
        assert_eq!(action_of(KeyCode::KeyQ, false), Some(KeyAction::Blade(Key::Q)));
        assert_eq!(action_of(KeyCode::KeyQ, true), Some(KeyAction::Quit), "Ctrl+Q quits");
        assert_eq!(action_of(KeyCode::KeyW, true), None, "Ctrl+W must not move a blade");
        assert_eq!(action_of(KeyCode::ShiftLeft, true), Some(KeyAction::Blade(Key::Shift)));
        assert_eq!(action_of(KeyCode::Escape, false), Some(KeyAction::SceneFocus), "Esc gives the keys back, it does not quit");
        assert_eq!(action_of(KeyCode::Digit2, false), Some(KeyAction::Blade(Key::Digit2)));
        assert_eq!(action_of(KeyCode::KeyZ, false), None);
        assert_eq!(action_of(KeyCode::KeyX, false), Some(KeyAction::Cut), "X cuts at the active blade");
    }

    /// Tab never moves the focus into the panel (the keys would stop
    /// driving the blades): Tab and Esc always end with the keys on the scene.
    #[test]
    fn tab_and_esc_never_leave_the_keys_in_the_panel() {
        assert_eq!(route(KeyCode::Tab, false, true, false), KeyRoute::Scene(KeyAction::Blade(Key::Tab)), "Tab on the scene picks the next blade");
        assert_eq!(route(KeyCode::Tab, false, true, true), KeyRoute::ReturnToScene, "Tab in the text field gives the keys back");
        assert_eq!(route(KeyCode::Escape, false, true, true), KeyRoute::ReturnToScene);
        assert_eq!(route(KeyCode::Escape, false, true, false), KeyRoute::Scene(KeyAction::SceneFocus), "Esc on the scene does not quit");
        assert_eq!(route(KeyCode::KeyW, false, true, true), KeyRoute::Panel, "typing W in the text field types");
        assert_eq!(route(KeyCode::KeyW, false, false, true), KeyRoute::Scene(KeyAction::Blade(Key::W)), "a release reaches the blade map");
        assert_eq!(route(KeyCode::KeyQ, true, true, true), KeyRoute::Scene(KeyAction::Quit), "Ctrl+Q quits from anywhere");
        assert_eq!(route(KeyCode::KeyZ, false, true, false), KeyRoute::Ignore);
    }

    #[test]
    fn scripts_name_keys_from_the_same_table() {
        assert_eq!(key_named("w"), Some(Key::W));
        assert_eq!(key_named("PAGEUP"), Some(Key::PageUp));
        assert_eq!(key_named("2"), Some(Key::Digit2));
        assert_eq!(key_named("M"), None, "M is a window action, not a blade key");
        assert!(key_names().starts_with("W S D A E Q Up"), "{}", key_names());
    }
}
