//! Gamepad force feedback: the hand on the pad feels the blade it drives press
//! on the tissue.
//!
//! In: each window frame, the magnitude of the reaction force on the blade the
//! pad drives (newtons; the 1 kHz force output's latest value, else the frame's)
//! and the [`RumbleSettings`]. Out: the rumble strength of both motors of the
//! active pad (gilrs `ff`: one endless effect whose gain follows the force) and a
//! [`RumbleStatus`] the window shows. Stays true: the strength is a pure function
//! of the force ([`strength`]: 0 without contact, growing as the square root of
//! the force so that light contact is felt, never above the cap); a pad without
//! force feedback, no pad, or a failing ff device is a status, never an error;
//! an effect failure is logged once per pad and the pad is left alone after it.

use gilrs::ff::{BaseEffect, BaseEffectType, EffectBuilder, Replay, Ticks};
use gilrs::{GamepadId, Gilrs};

/// How the reaction force becomes rumble.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RumbleSettings {
    /// Off: the motors stay still (key H, `fissure run --no-rumble`).
    pub enabled: bool,
    /// The force that gives the full strength (before the cap), newtons.
    pub full_scale_n: f64,
    /// The strongest rumble, 0..=1 (a pad at full power drowns the feel).
    pub cap: f32,
}

impl Default for RumbleSettings {
    /// 0.5 N at full scale: the upper end of a retraction (0.1-0.5 N), so 0.1 N
    /// already gives 45 % of the scale; capped at 80 %.
    fn default() -> Self {
        Self { enabled: true, full_scale_n: 0.5, cap: 0.8 }
    }
}

/// The rumble strength (0..=cap) for a reaction force of `force_n` newtons:
/// `cap * min(1, sqrt(force / full_scale))`; 0 when off, for no force, or for a
/// value that is not a finite positive number.
pub fn strength(force_n: f64, settings: &RumbleSettings) -> f32 {
    let scale_ok = settings.full_scale_n.is_finite() && settings.full_scale_n > 0.0;
    if !settings.enabled || !force_n.is_finite() || force_n <= 0.0 || !scale_ok {
        return 0.0;
    }
    let cap = if settings.cap.is_finite() { settings.cap.clamp(0.0, 1.0) } else { 0.0 };
    cap * ((force_n / settings.full_scale_n).sqrt().min(1.0) as f32)
}

/// What the window says about the rumble.
#[derive(Debug, Clone, PartialEq)]
pub enum RumbleStatus {
    /// Turned off (key H or `--no-rumble`).
    Off,
    /// No gamepad is driving (none plugged in, or none used yet).
    NoPad,
    /// The pad that drives has no force feedback.
    NotSupported,
    /// The pad's force feedback failed (the cause); it is left alone.
    Failed(String),
    /// Rumbling at this strength (0..=1).
    Active(f32),
}

impl RumbleStatus {
    /// One line for the status bar.
    pub fn describe(&self) -> String {
        match self {
            Self::Off => "pad rumble off (H)".into(),
            Self::NoPad => "pad rumble: no pad".into(),
            Self::NotSupported => "pad rumble: this pad has no force feedback".into(),
            Self::Failed(e) => format!("pad rumble failed: {e}"),
            Self::Active(s) => format!("pad rumble {:.0} %", 100.0 * s),
        }
    }
}

/// Gain changes smaller than this are not sent (the ff server runs on its own
/// thread; a message a frame for nothing felt is noise).
const GAIN_STEP: f32 = 0.01;

/// The endless effect on the driving pad.
#[derive(Default)]
pub struct Rumble {
    effect: Option<(GamepadId, gilrs::ff::Effect)>,
    gain: f32,
    /// Pads whose force feedback failed: not tried again until fissure restarts.
    failed: Vec<(GamepadId, String)>,
}

impl Rumble {
    /// Sets the driving pad's rumble for this frame's force; `pad` is the pad
    /// that drives (the last one used), if any.
    pub fn update(&mut self, gilrs: &mut Gilrs, pad: Option<GamepadId>, force_n: f64, settings: &RumbleSettings) -> RumbleStatus {
        let Some(id) = pad else {
            self.effect = None;
            return if settings.enabled { RumbleStatus::NoPad } else { RumbleStatus::Off };
        };
        if let Some((_, e)) = self.failed.iter().find(|(p, _)| *p == id) {
            return RumbleStatus::Failed(e.clone());
        }
        let supported = gilrs.connected_gamepad(id).is_some_and(|g| g.is_ff_supported());
        if !supported {
            self.effect = None;
            return if settings.enabled { RumbleStatus::NotSupported } else { RumbleStatus::Off };
        }
        let s = strength(force_n, settings);
        if self.effect.as_ref().is_none_or(|(p, _)| *p != id) {
            // Dropping the old handle ends its effect on the pad it was on.
            self.effect = None;
            self.gain = 0.0;
            match start_effect(gilrs, id) {
                Ok(e) => self.effect = Some((id, e)),
                Err(e) => {
                    tracing::warn!(pad = %id, error = %e, "gamepad force feedback failed; the pad is left without rumble");
                    self.failed.push((id, e.clone()));
                    return RumbleStatus::Failed(e);
                }
            }
        }
        if let Some((_, effect)) = &self.effect
            && ((s - self.gain).abs() >= GAIN_STEP || (s == 0.0 && self.gain != 0.0))
        {
            if let Err(e) = effect.set_gain(s) {
                let e = e.to_string();
                tracing::warn!(pad = %id, error = %e, "gamepad force feedback failed; the pad is left without rumble");
                self.effect = None;
                self.failed.push((id, e.clone()));
                return RumbleStatus::Failed(e);
            }
            self.gain = s;
        }
        if settings.enabled { RumbleStatus::Active(self.gain) } else { RumbleStatus::Off }
    }
}

/// Both motors at full magnitude, repeated without end, at gain 0: the gain is
/// what [`Rumble::update`] moves.
fn start_effect(gilrs: &mut Gilrs, id: GamepadId) -> Result<gilrs::ff::Effect, String> {
    let replay = Replay { play_for: Ticks::from_ms(100), ..Default::default() };
    let effect = EffectBuilder::new()
        .add_effect(BaseEffect { kind: BaseEffectType::Strong { magnitude: u16::MAX }, scheduling: replay, ..Default::default() })
        .add_effect(BaseEffect { kind: BaseEffectType::Weak { magnitude: u16::MAX / 2 }, scheduling: replay, ..Default::default() })
        .gamepads(&[id])
        .repeat(gilrs::ff::Repeat::Infinitely)
        .gain(0.0)
        .finish(gilrs)
        .map_err(|e| e.to_string())?;
    effect.play().map_err(|e| e.to_string())?;
    Ok(effect)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strength_is_zero_without_contact_and_grows_to_the_cap() {
        let s = RumbleSettings::default();
        assert_eq!(strength(0.0, &s), 0.0);
        assert_eq!(strength(-1.0, &s), 0.0, "a negative magnitude is not a force");
        assert_eq!(strength(f64::NAN, &s), 0.0);
        assert_eq!(strength(f64::INFINITY, &s), 0.0);
        let light = strength(0.1, &s);
        assert!((light - 0.8 * (0.2f32).sqrt()).abs() < 1e-6, "0.1 N of a 0.5 N scale: {light}");
        assert!(light > 0.3, "light contact must be felt: {light}");
        assert!(strength(0.2, &s) > light, "more force, more rumble");
        assert_eq!(strength(0.5, &s), 0.8, "full scale gives the cap");
        assert_eq!(strength(50.0, &s), 0.8, "never above the cap");
    }

    #[test]
    fn off_or_a_broken_setting_gives_no_rumble() {
        let off = RumbleSettings { enabled: false, ..Default::default() };
        assert_eq!(strength(0.3, &off), 0.0);
        let zero_scale = RumbleSettings { full_scale_n: 0.0, ..Default::default() };
        assert_eq!(strength(0.3, &zero_scale), 0.0);
        let nan_cap = RumbleSettings { cap: f32::NAN, ..Default::default() };
        assert_eq!(strength(0.3, &nan_cap), 0.0);
        let big_cap = RumbleSettings { cap: 7.0, ..Default::default() };
        assert_eq!(strength(5.0, &big_cap), 1.0, "the cap is clamped to 1");
    }

    #[test]
    fn status_lines_say_what_the_user_can_do() {
        assert!(RumbleStatus::Off.describe().contains("(H)"));
        assert!(RumbleStatus::NotSupported.describe().contains("no force feedback"));
        assert_eq!(RumbleStatus::Active(0.456).describe(), "pad rumble 46 %");
    }
}
