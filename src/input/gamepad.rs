//! Gamepad input: a documented mapping that drives both spatulas in 6-DoF.
//!
//! In: [`PadEvent`]s (synthetic in tests; [`GamepadInput`] converts gilrs
//! events at the edge). Out: a [`PadCommand`] each frame: the velocity of the
//! selected spatula in its own frame, which spatula that is, and a camera
//! orbit rate. Stays true: the mapping is a pure function of [`PadState`] and
//! [`GamepadMapping`]; dead zones zero small deflections; non-finite axis
//! values read as 0; unplugging the pad zeroes its state (the spatula stops);
//! no pad or no gilrs (no udev) is not an error.
//!
//! ## Mapping (Xbox names; gilrs `Button`/`Axis` in brackets)
//! | control | translate mode | rotate mode |
//! |---|---|---|
//! | left stick x [LeftStickX] | +y across the blade | roll about x (blade axis) |
//! | left stick y [LeftStickY] | +x along the blade (push = towards the tip) | pitch about y |
//! | right trigger − left trigger [RightTrigger2, LeftTrigger2] | +z through the blade (towards its +z face: opens the fissure with an upper blade, closes it with a lower blade facing the same way) | yaw about z |
//! | right stick [RightStickX/Y] | camera orbit (yaw, pitch) | camera orbit |
//! | A [South] | toggle translate / rotate | |
//! | LB [LeftTrigger] | select the spatula on the left of the screen (at the press) | |
//! | RB [RightTrigger] | select the spatula on the right of the screen | |
//! | X [West] | slow (precision) mode toggle: speeds x 0.25 | |
//!
//! Full deflection gives [`GamepadMapping::max_speed_m_s`] or
//! [`GamepadMapping::max_rate_rad_s`]; sticks use a radial dead zone with
//! rescaling so motion starts smoothly at the dead zone's edge.

use super::{PoseVelocity, SpatulaSlot};
use crate::math::Vec3;

/// Translate or rotate the selected spatula.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MotionMode {
    #[default]
    Translate,
    Rotate,
}

/// Pad controls this mapping reads (a device-independent subset of gilrs').
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PadButton {
    /// A / cross: toggles translate / rotate.
    South,
    /// X / square: toggles precision (slow) mode.
    West,
    /// Left shoulder: selects the left spatula.
    LeftShoulder,
    /// Right shoulder: selects the right spatula.
    RightShoulder,
}

/// Analogue controls this mapping reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PadAxis {
    LeftStickX,
    LeftStickY,
    RightStickX,
    RightStickY,
    /// Analogue left trigger, 0..1.
    LeftTrigger,
    /// Analogue right trigger, 0..1.
    RightTrigger,
}

/// One input event, device-independent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PadEvent {
    Pressed(PadButton),
    Released(PadButton),
    /// A new axis value: sticks -1..1, triggers 0..1 (clamped; NaN reads as 0).
    Axis(PadAxis, f32),
    Connected,
    /// The pad went away: every axis returns to 0.
    Disconnected,
}

/// Current analogue state of the pad.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadState {
    /// Left stick (x right, y up), each -1..1.
    pub left_stick: [f32; 2],
    /// Right stick (x right, y up), each -1..1.
    pub right_stick: [f32; 2],
    /// Left analogue trigger, 0..1.
    pub left_trigger: f32,
    /// Right analogue trigger, 0..1.
    pub right_trigger: f32,
}

/// Tuning of the mapping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GamepadMapping {
    /// Radial dead zone of the sticks, fraction of full deflection [0, 0.9]. Default 0.15.
    pub stick_dead_zone: f32,
    /// Dead zone of the triggers, fraction [0, 0.9]. Default 0.05.
    pub trigger_dead_zone: f32,
    /// Spatula speed at full deflection, m/s (> 0). Default 0.02 (2 cm/s).
    pub max_speed_m_s: f64,
    /// Spatula turn rate at full deflection, rad/s (> 0). Default 0.8.
    pub max_rate_rad_s: f64,
    /// Camera orbit rate at full right-stick deflection, rad/s (> 0). Default 1.5.
    pub camera_rate_rad_s: f64,
    /// Speed factor in precision mode, (0, 1]. Default 0.25.
    pub precision_factor: f64,
}

impl Default for GamepadMapping {
    fn default() -> Self {
        Self {
            stick_dead_zone: 0.15,
            trigger_dead_zone: 0.05,
            max_speed_m_s: 0.02,
            max_rate_rad_s: 0.8,
            camera_rate_rad_s: 1.5,
            precision_factor: 0.25,
        }
    }
}

/// What the pad asks for this frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadCommand {
    /// The spatula to move.
    pub spatula: SpatulaSlot,
    /// Its velocity, spatula frame.
    pub velocity: PoseVelocity,
    /// Camera orbit rate: (yaw, pitch), rad/s.
    pub camera_orbit_rad_s: [f64; 2],
    /// The current mode (for the panel).
    pub mode: MotionMode,
    /// Precision mode on (for the panel).
    pub precision: bool,
}

fn finite_clamped(v: f32, lo: f32, hi: f32) -> f32 {
    if v.is_finite() { v.clamp(lo, hi) } else { 0.0 }
}

/// Radial dead zone with rescaling: |s| below `dead` gives 0, full deflection
/// stays full, direction is kept. Inputs are clamped to the unit disc.
pub fn stick_with_dead_zone(stick: [f32; 2], dead: f32) -> [f64; 2] {
    let x = finite_clamped(stick[0], -1.0, 1.0) as f64;
    let y = finite_clamped(stick[1], -1.0, 1.0) as f64;
    let dead = finite_clamped(dead, 0.0, 0.9) as f64;
    let r = (x * x + y * y).sqrt();
    if r <= dead {
        return [0.0, 0.0];
    }
    let scaled = ((r.min(1.0) - dead) / (1.0 - dead)) / r;
    [x * scaled, y * scaled]
}

/// Trigger dead zone with rescaling to 0..1.
pub fn trigger_with_dead_zone(value: f32, dead: f32) -> f64 {
    let v = finite_clamped(value, 0.0, 1.0) as f64;
    let dead = finite_clamped(dead, 0.0, 0.9) as f64;
    if v <= dead {
        0.0
    } else {
        (v - dead) / (1.0 - dead)
    }
}

/// The pure mapping: pad state, mode and precision to a spatula velocity and a
/// camera orbit rate (see the module table).
pub fn map_state(
    state: &PadState,
    mode: MotionMode,
    precision: bool,
    mapping: &GamepadMapping,
) -> (PoseVelocity, [f64; 2]) {
    let [lx, ly] = stick_with_dead_zone(state.left_stick, mapping.stick_dead_zone);
    let [rx, ry] = stick_with_dead_zone(state.right_stick, mapping.stick_dead_zone);
    let z = trigger_with_dead_zone(state.right_trigger, mapping.trigger_dead_zone)
        - trigger_with_dead_zone(state.left_trigger, mapping.trigger_dead_zone);
    let factor = if precision {
        mapping.precision_factor
    } else {
        1.0
    };
    let velocity = match mode {
        MotionMode::Translate => PoseVelocity {
            linear_m_s: Vec3::new(ly, lx, z) * (mapping.max_speed_m_s * factor),
            angular_rad_s: Vec3::zeros(),
        },
        MotionMode::Rotate => PoseVelocity {
            linear_m_s: Vec3::zeros(),
            angular_rad_s: Vec3::new(lx, ly, z) * (mapping.max_rate_rad_s * factor),
        },
    };
    (
        velocity,
        [
            rx * mapping.camera_rate_rad_s,
            ry * mapping.camera_rate_rad_s,
        ],
    )
}

/// Pad state plus the edge-triggered choices (mode, spatula, precision).
#[derive(Debug, Clone, Default)]
pub struct GamepadController {
    /// Analogue state.
    pub state: PadState,
    /// Translate or rotate.
    pub mode: MotionMode,
    /// The spatula being moved.
    pub spatula: SpatulaSlot,
    /// Precision mode on.
    pub precision: bool,
    /// The mapping's tuning.
    pub mapping: GamepadMapping,
}

impl GamepadController {
    /// A controller with the given tuning.
    pub fn new(mapping: GamepadMapping) -> Self {
        Self {
            mapping,
            ..Self::default()
        }
    }

    /// Applies one event.
    pub fn apply(&mut self, event: PadEvent) {
        match event {
            PadEvent::Pressed(PadButton::South) => {
                self.mode = match self.mode {
                    MotionMode::Translate => MotionMode::Rotate,
                    MotionMode::Rotate => MotionMode::Translate,
                }
            }
            PadEvent::Pressed(PadButton::West) => self.precision = !self.precision,
            PadEvent::Pressed(PadButton::LeftShoulder) => self.spatula = SpatulaSlot::Left,
            PadEvent::Pressed(PadButton::RightShoulder) => self.spatula = SpatulaSlot::Right,
            PadEvent::Released(_) | PadEvent::Connected => {}
            PadEvent::Axis(axis, value) => {
                let stick = finite_clamped(value, -1.0, 1.0);
                let trigger = finite_clamped(value, 0.0, 1.0);
                match axis {
                    PadAxis::LeftStickX => self.state.left_stick[0] = stick,
                    PadAxis::LeftStickY => self.state.left_stick[1] = stick,
                    PadAxis::RightStickX => self.state.right_stick[0] = stick,
                    PadAxis::RightStickY => self.state.right_stick[1] = stick,
                    PadAxis::LeftTrigger => self.state.left_trigger = trigger,
                    PadAxis::RightTrigger => self.state.right_trigger = trigger,
                }
            }
            PadEvent::Disconnected => self.state = PadState::default(),
        }
    }

    /// This frame's command.
    pub fn command(&self) -> PadCommand {
        let (velocity, camera_orbit_rad_s) =
            map_state(&self.state, self.mode, self.precision, &self.mapping);
        PadCommand {
            spatula: self.spatula,
            velocity,
            camera_orbit_rad_s,
            mode: self.mode,
            precision: self.precision,
        }
    }
}

/// The mapped gilrs button (gilrs names the shoulder buttons `LeftTrigger` /
/// `RightTrigger` and the analogue triggers `LeftTrigger2` / `RightTrigger2`).
pub fn pad_button(b: gilrs::Button) -> Option<PadButton> {
    use gilrs::Button;
    match b {
        Button::South => Some(PadButton::South),
        Button::West => Some(PadButton::West),
        Button::LeftTrigger => Some(PadButton::LeftShoulder),
        Button::RightTrigger => Some(PadButton::RightShoulder),
        _ => None,
    }
}

/// The mapped gilrs stick axis.
pub fn pad_axis(a: gilrs::Axis) -> Option<PadAxis> {
    use gilrs::Axis;
    match a {
        Axis::LeftStickX => Some(PadAxis::LeftStickX),
        Axis::LeftStickY => Some(PadAxis::LeftStickY),
        Axis::RightStickX => Some(PadAxis::RightStickX),
        Axis::RightStickY => Some(PadAxis::RightStickY),
        _ => None,
    }
}

/// Converts a gilrs event to a [`PadEvent`] (`None` for controls we do not map).
pub fn from_gilrs(event: &gilrs::EventType) -> Option<PadEvent> {
    use gilrs::{Button, EventType};
    let button = |b: &Button| pad_button(*b);
    match event {
        EventType::ButtonPressed(b, _) => button(b).map(PadEvent::Pressed),
        EventType::ButtonReleased(b, _) => button(b).map(PadEvent::Released),
        EventType::ButtonChanged(Button::LeftTrigger2, v, _) => {
            Some(PadEvent::Axis(PadAxis::LeftTrigger, *v))
        }
        EventType::ButtonChanged(Button::RightTrigger2, v, _) => {
            Some(PadEvent::Axis(PadAxis::RightTrigger, *v))
        }
        EventType::AxisChanged(axis, v, _) => pad_axis(*axis).map(|a| PadEvent::Axis(a, *v)),
        EventType::Connected => Some(PadEvent::Connected),
        EventType::Disconnected => Some(PadEvent::Disconnected),
        _ => None,
    }
}

/// True when LB / RB must swap blades so that LB picks the blade on the LEFT of
/// the screen: the first blade's centre lies to the right of the second's along
/// the camera's right vector. The window applies it when LB / RB is pressed (not
/// while a blade is being driven, so orbiting the camera never hands the pad to
/// the other blade mid-motion).
pub fn screen_order_swaps(first_centre: Vec3, second_centre: Vec3, camera_right: Vec3) -> bool {
    let (a, b) = (first_centre.dot(&camera_right), second_centre.dot(&camera_right));
    a.is_finite() && b.is_finite() && a > b
}

/// The gilrs adapter: polls events and feeds the controller. Only the pad that
/// sent the latest event drives (a second pad takes over when it is used); a
/// disconnect of the active pad zeroes the state.
pub struct GamepadInput {
    gilrs: Option<gilrs::Gilrs>,
    active: Option<gilrs::GamepadId>,
    /// The controller the events drive.
    pub controller: GamepadController,
    rumble: super::rumble::Rumble,
}

impl GamepadInput {
    /// Initialises gilrs; if that fails (e.g. no udev) logs once and runs
    /// without a gamepad. No pad plugged in is normal.
    pub fn new(mapping: GamepadMapping) -> Self {
        let gilrs = match gilrs::Gilrs::new() {
            Ok(g) => Some(g),
            Err(gilrs::Error::NotImplemented(g)) => {
                tracing::warn!(
                    "gamepad support is not implemented on this platform; continuing without a gamepad"
                );
                Some(g)
            }
            Err(e) => {
                tracing::warn!(error = %e, "gamepad input unavailable; continuing without a gamepad");
                None
            }
        };
        Self {
            gilrs,
            active: None,
            controller: GamepadController::new(mapping),
            rumble: super::rumble::Rumble::default(),
        }
    }

    /// True when gilrs initialised.
    pub fn available(&self) -> bool {
        self.gilrs.is_some()
    }

    /// Rumbles the driving pad for a reaction force of `force_n` newtons on the
    /// blade it drives (see [`super::rumble`]) and says how that went.
    pub fn rumble(&mut self, force_n: f64, settings: &super::rumble::RumbleSettings) -> super::rumble::RumbleStatus {
        match self.gilrs.as_mut() {
            Some(gilrs) => self.rumble.update(gilrs, self.active, force_n, settings),
            None if settings.enabled => super::rumble::RumbleStatus::NoPad,
            None => super::rumble::RumbleStatus::Off,
        }
    }

    /// Drains pending events and returns this frame's command.
    pub fn poll(&mut self) -> PadCommand {
        if let Some(gilrs) = self.gilrs.as_mut() {
            while let Some(gilrs::Event { id, event, .. }) = gilrs.next_event() {
                match event {
                    gilrs::EventType::Connected => tracing::info!(pad = %id, "gamepad connected"),
                    gilrs::EventType::Disconnected => {
                        tracing::info!(pad = %id, "gamepad disconnected");
                        if self.active == Some(id) {
                            self.active = None;
                            self.controller.apply(PadEvent::Disconnected);
                        }
                        continue;
                    }
                    _ => {}
                }
                if let Some(ev) = from_gilrs(&event) {
                    if self.active != Some(id) && !matches!(ev, PadEvent::Connected) {
                        // A different pad took over: start from rest.
                        self.controller.state = PadState::default();
                        self.active = Some(id);
                    }
                    self.controller.apply(ev);
                }
            }
        }
        self.controller.command()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lb_picks_the_blade_on_the_left_of_the_screen() {
        let (a, b) = (Vec3::new(-0.02, 0.0, 0.0), Vec3::new(0.02, 0.0, 0.0));
        assert!(!screen_order_swaps(a, b, Vec3::x()), "first blade on the left: LB keeps it");
        assert!(screen_order_swaps(a, b, -Vec3::x()), "camera turned round: the first blade is on the right, LB takes the second");
        assert!(!screen_order_swaps(a, b, Vec3::z()), "side by side in depth only: no swap");
        assert!(!screen_order_swaps(Vec3::repeat(f64::NAN), b, Vec3::x()), "a NaN pose never swaps");
    }

    #[test]
    fn dead_zone_zeroes_small_and_keeps_full() {
        assert_eq!(
            stick_with_dead_zone([0.1, -0.1], 0.15),
            [0.0, 0.0],
            "inside the radial dead zone"
        );
        let [x, y] = stick_with_dead_zone([1.0, 0.0], 0.15);
        assert!(
            (x - 1.0).abs() < 1e-12 && y == 0.0,
            "full deflection stays full: {x} {y}"
        );
        let [x, _] = stick_with_dead_zone([0.16, 0.0], 0.15);
        assert!(
            x > 0.0 && x < 0.02,
            "motion starts smoothly just past the edge: {x}"
        );
        assert_eq!(
            stick_with_dead_zone([f32::NAN, 0.0], 0.15),
            [0.0, 0.0],
            "NaN reads as 0"
        );
        assert_eq!(trigger_with_dead_zone(0.04, 0.05), 0.0);
        assert!((trigger_with_dead_zone(1.0, 0.05) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn translate_and_rotate_follow_the_table() {
        let m = GamepadMapping::default();
        let mut c = GamepadController::new(m);
        c.apply(PadEvent::Axis(PadAxis::LeftStickY, 1.0));
        c.apply(PadEvent::Axis(PadAxis::RightTrigger, 1.0));
        let cmd = c.command();
        assert_eq!(cmd.spatula, SpatulaSlot::Left);
        assert!(
            (cmd.velocity.linear_m_s - Vec3::new(m.max_speed_m_s, 0.0, m.max_speed_m_s)).norm()
                < 1e-12,
            "push + RT: {:?}",
            cmd.velocity
        );
        assert_eq!(cmd.velocity.angular_rad_s, Vec3::zeros());

        c.apply(PadEvent::Pressed(PadButton::South));
        c.apply(PadEvent::Released(PadButton::South));
        c.apply(PadEvent::Pressed(PadButton::RightShoulder));
        let cmd = c.command();
        assert_eq!(
            (cmd.mode, cmd.spatula),
            (MotionMode::Rotate, SpatulaSlot::Right)
        );
        assert_eq!(
            cmd.velocity.linear_m_s,
            Vec3::zeros(),
            "rotate mode must not translate"
        );
        assert!(
            (cmd.velocity.angular_rad_s - Vec3::new(0.0, m.max_rate_rad_s, m.max_rate_rad_s))
                .norm()
                < 1e-12,
            "{:?}",
            cmd.velocity
        );

        c.apply(PadEvent::Pressed(PadButton::West));
        let slow = c.command();
        assert!(
            (slow.velocity.angular_rad_s.norm()
                - cmd.velocity.angular_rad_s.norm() * m.precision_factor)
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn unplug_stops_the_spatula_and_camera_uses_right_stick() {
        let mut c = GamepadController::default();
        c.apply(PadEvent::Axis(PadAxis::LeftStickX, -1.0));
        c.apply(PadEvent::Axis(PadAxis::RightStickX, 1.0));
        let cmd = c.command();
        assert!(cmd.velocity.linear_m_s.y < 0.0);
        assert!(cmd.camera_orbit_rad_s[0] > 0.0);
        c.apply(PadEvent::Disconnected);
        let cmd = c.command();
        assert!(
            cmd.velocity.is_zero(),
            "after unplug the spatula must stop: {:?}",
            cmd.velocity
        );
        assert_eq!(cmd.camera_orbit_rad_s, [0.0, 0.0]);
        c.apply(PadEvent::Axis(PadAxis::LeftTrigger, f32::INFINITY));
        assert_eq!(
            c.state.left_trigger, 0.0,
            "non-finite axis values read as 0"
        );
    }

    #[test]
    fn gilrs_events_convert() {
        // gilrs event codes cannot be built outside gilrs; the button and axis
        // tables are what from_gilrs applies.
        assert_eq!(pad_button(gilrs::Button::South), Some(PadButton::South));
        assert_eq!(
            pad_button(gilrs::Button::LeftTrigger),
            Some(PadButton::LeftShoulder),
            "gilrs LeftTrigger is the shoulder"
        );
        assert_eq!(
            pad_button(gilrs::Button::LeftTrigger2),
            None,
            "the analogue trigger is an axis, not a button"
        );
        assert_eq!(pad_button(gilrs::Button::Start), None);
        assert_eq!(
            pad_axis(gilrs::Axis::RightStickY),
            Some(PadAxis::RightStickY)
        );
        assert_eq!(pad_axis(gilrs::Axis::DPadX), None);
        assert_eq!(
            from_gilrs(&gilrs::EventType::Disconnected),
            Some(PadEvent::Disconnected)
        );
    }

    #[test]
    fn missing_gamepad_support_is_not_an_error() {
        // On CI there is no pad (and maybe no udev): construction and polling
        // must neither fail nor move anything.
        let mut input = GamepadInput::new(GamepadMapping::default());
        let cmd = input.poll();
        assert!(
            cmd.velocity.is_zero(),
            "no pad must mean no motion: {:?}",
            cmd.velocity
        );
    }
}
