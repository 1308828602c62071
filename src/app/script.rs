//! Scripted input for the window (`fissure run --script FILE`): timed key
//! presses and app actions, for tests and demos.
//!
//! In: text, one action a line: `TIME_S ACTION [ARG]`, `#` starts a comment.
//! Actions: `press KEY`, `release KEY` (KEY: W S D A E Q Up Down Left Right
//! PageUp PageDown 1 .. 9 Tab Shift), `cut [N]` (microscissors at blade N's
//! tip, numbered from 1 as the digit keys and the panel number them; without
//! N the active blade's, as the X key), `record PATH`, `stop`, `field none|displacement|pressure|strain|risk`,
//! `view overview|microscope`, `quit`, `end` (a window action: the session ends and is debriefed, as Ctrl+Q);
//! and through the window's own key
//! handling (focus rules included, as a user's key would go): `keydown NAME`,
//! `keyup NAME` (NAME: any key of [`crate::input::bindings::KEY_BINDINGS`],
//! e.g. `Tab`, `Esc`, `W`, `2`), `focus panel` (the panel's text field takes
//! the keys, as a click into it does). Out: a [`Script`] sorted by time.
//! Stays true: `press`/`release` and record actions fire on the simulation
//! thread at the first frame whose simulated time reaches TIME_S, so a script
//! drives the simulation deterministically whatever the display rate (and the
//! live keyboard is then ignored); window actions fire in the window at the
//! first drawn frame at or after TIME_S.

use crate::input::bindings::{KEY_BINDINGS, KeyBinding, key_named, key_names};
use crate::input::keyboard::Key;
use std::path::{Path, PathBuf};

use super::draw::{SurfaceField, ViewPreset};

/// A script error, naming the line.
#[derive(Debug, thiserror::Error)]
pub enum ScriptError {
    #[error("cannot read the script {path}: {io}")]
    Read { path: PathBuf, io: std::io::Error },
    #[error("{path}:{line}: {message}")]
    Line { path: PathBuf, line: usize, message: String },
}

/// One scripted action.
#[derive(Debug, Clone, PartialEq)]
pub enum ScriptAction {
    Press(Key),
    Release(Key),
    Record(PathBuf),
    /// Cut the bands at this blade's tip (index from 0; `None`: the active blade).
    Cut(Option<usize>),
    Stop,
    Field(SurfaceField),
    View(ViewPreset),
    Quit,
    /// End the session as Ctrl+Q does: the session is written and debriefed, the window shows the verdicts.
    End,
    /// A key going down (true) or up through the window's key handling.
    WindowKey(KeyBinding, bool),
    /// The panel's text field takes the keyboard focus.
    FocusPanel,
}

impl ScriptAction {
    /// True for actions the simulation thread carries out (keys, cuts, recording, quit).
    pub fn is_simulation(&self) -> bool {
        matches!(self, Self::Press(_) | Self::Release(_) | Self::Cut(_) | Self::Record(_) | Self::Stop | Self::Quit)
    }

    /// True for the actions that drive the blades from the script (the live
    /// keyboard is then ignored, for determinism).
    pub fn is_scripted_key(&self) -> bool {
        matches!(self, Self::Press(_) | Self::Release(_))
    }
}

/// Timed actions, ascending by time (ties keep file order).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Script {
    pub actions: Vec<(f64, ScriptAction)>,
}

impl Script {
    /// Reads a script file.
    pub fn load(path: &Path) -> Result<Self, ScriptError> {
        let text = crate::fsio::read_regular_text(path, crate::fsio::Cap::SCRIPT).map_err(|e| match e {
            crate::fsio::ReadError::Refused { refusal, .. } => ScriptError::Read { path: path.to_path_buf(), io: std::io::Error::other(refusal) },
            crate::fsio::ReadError::Io { source, .. } => ScriptError::Read { path: path.to_path_buf(), io: source },
        })?;
        Self::parse(&text, path)
    }

    /// Parses script text; `origin` names the file in errors.
    pub fn parse(text: &str, origin: &Path) -> Result<Self, ScriptError> {
        let mut actions = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let err = |message: String| ScriptError::Line { path: origin.to_path_buf(), line: i + 1, message };
            let mut words = line.split_whitespace();
            let time: f64 = words
                .next()
                .and_then(|w| w.parse().ok())
                .filter(|t: &f64| t.is_finite() && *t >= 0.0)
                .ok_or_else(|| err("expected a time in seconds (>= 0) first".into()))?;
            let verb = words.next().ok_or_else(|| err("expected an action after the time".into()))?;
            let arg = words.next();
            let need = |what: &str| err(format!("`{verb}` needs {what}"));
            let action = match verb {
                "press" | "release" => {
                    let name = arg.ok_or_else(|| need("a key"))?;
                    let key = key_named(name).ok_or_else(|| err(format!("unknown key `{name}` (keys: {})", key_names())))?;
                    if verb == "press" { ScriptAction::Press(key) } else { ScriptAction::Release(key) }
                }
                "record" => ScriptAction::Record(PathBuf::from(arg.ok_or_else(|| need("a file path"))?)),
                "keydown" | "keyup" => {
                    let name = arg.ok_or_else(|| need("a key name"))?;
                    let binding = KEY_BINDINGS
                        .iter()
                        .find(|b| b.name.eq_ignore_ascii_case(name))
                        .ok_or_else(|| err(format!("unknown key `{name}`")))?;
                    ScriptAction::WindowKey(*binding, verb == "keydown")
                }
                "focus" => match arg {
                    Some("panel") => ScriptAction::FocusPanel,
                    _ => return Err(need("panel")),
                },
                "cut" => ScriptAction::Cut(match arg {
                    None => None,
                    Some(n) => match n.parse::<usize>() {
                        Ok(n) if n >= 1 => Some(n - 1),
                        _ => return Err(err(format!("`cut` takes a blade number from 1 (or nothing: the active blade), got `{n}`"))),
                    },
                }),
                "stop" => ScriptAction::Stop,
                "quit" => ScriptAction::Quit,
                "end" => ScriptAction::End,
                "field" => ScriptAction::Field(match arg {
                    Some("none") => SurfaceField::None,
                    Some("displacement") => SurfaceField::Displacement,
                    Some("pressure") => SurfaceField::Pressure,
                    Some("strain") => SurfaceField::Strain,
                    Some("risk") => SurfaceField::Risk,
                    _ => return Err(need("none, displacement, pressure, strain or risk")),
                }),
                "view" => ScriptAction::View(match arg {
                    Some("overview") => ViewPreset::Overview,
                    Some("microscope") => ViewPreset::Microscope,
                    _ => return Err(need("overview or microscope")),
                }),
                other => return Err(err(format!("unknown action `{other}`"))),
            };
            actions.push((time, action));
        }
        actions.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Self { actions })
    }

    /// Splits into (simulation actions, window actions), both still sorted.
    pub fn split(self) -> (Vec<(f64, ScriptAction)>, Vec<(f64, ScriptAction)>) {
        self.actions.into_iter().partition(|(_, a)| a.is_simulation())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sorts_and_names_bad_lines() {
        let s = Script::parse("# demo\n0.5 release E\n0.1 press e  # open\n1 quit\n0.2 view microscope\n", Path::new("s.txt")).unwrap();
        assert_eq!(s.actions[0], (0.1, ScriptAction::Press(Key::E)), "sorted by time, key names case-insensitive");
        assert_eq!(s.actions.len(), 4);
        let (sim, window) = s.split();
        assert_eq!(sim.len(), 3);
        assert_eq!(window, vec![(0.2, ScriptAction::View(ViewPreset::Microscope))]);
        let e = Script::parse("0.1 press\n", Path::new("s.txt")).unwrap_err().to_string();
        assert!(e.contains("s.txt:1") && e.contains("needs a key"), "error must name file:line: {e}");
        let e = Script::parse("\n-1 quit\n", Path::new("s.txt")).unwrap_err().to_string();
        assert!(e.contains("s.txt:2"), "negative time rejected on line 2: {e}");
        let s = Script::parse("0 press 2\n0.1 keydown esc\n0.2 keyup Tab\n0.3 focus panel\n", Path::new("s.txt")).unwrap();
        assert_eq!(s.actions[0].1, ScriptAction::Press(Key::Digit2));
        assert!(matches!(s.actions[1].1, ScriptAction::WindowKey(b, true) if b.name == "Esc"), "{:?}", s.actions[1]);
        assert!(matches!(s.actions[2].1, ScriptAction::WindowKey(b, false) if b.name == "Tab"));
        assert_eq!(s.actions[3].1, ScriptAction::FocusPanel);
        assert!(!s.actions[1].1.is_simulation() && s.actions[0].1.is_scripted_key());
        let e = Script::parse("0 keydown Z\n", Path::new("s.txt")).unwrap_err().to_string();
        assert!(e.contains("unknown key `Z`"), "{e}");
    }

    /// `cut N` names the blade as the digit keys do (from 1); `cut` alone is
    /// the active blade's; both run on the simulation thread; `keydown X`
    /// goes through the window's keys.
    #[test]
    fn cut_names_the_blade_from_one_and_runs_in_the_simulation() {
        let s = Script::parse("0.5 cut 2\n0.6 cut\n0.7 keydown X\n", Path::new("s.txt")).unwrap();
        assert_eq!(s.actions[0].1, ScriptAction::Cut(Some(1)));
        assert_eq!(s.actions[1].1, ScriptAction::Cut(None));
        assert!(s.actions[0].1.is_simulation() && !s.actions[0].1.is_scripted_key());
        assert!(matches!(s.actions[2].1, ScriptAction::WindowKey(b, true) if b.name == "X"));
        for bad in ["0 cut 0\n", "0 cut left\n"] {
            let e = Script::parse(bad, Path::new("s.txt")).unwrap_err().to_string();
            assert!(e.contains("s.txt:1") && e.contains("blade number from 1"), "{e}");
        }
    }
}
