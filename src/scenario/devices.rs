//! The 6-DoF devices' fields: an OpenIGTLink binding's link, stylus mapping and
//! force in PLUS's form; the server's listening address; the SpaceMouse's
//! tuning. As written (human units) and as checked (SI).
//!
//! In: the `openigtlink` and `spacemouse` sections of a scenario file and the
//! optional fields of an `OpenIgtLink(..)` input. Out: [`IgtlLink`],
//! [`SpaceMouseSettings`] and the listening address, every number finite and
//! in range, every name one the OpenIGTLink device-name field (20 bytes) can
//! carry, or an error naming the field. The device numbers' sources are cited
//! where they are defined (`crate::input::force_transform`,
//! `crate::input::spacemouse`); docs/usage.md ("A haptic stylus through
//! PLUS", "SpaceMouse") says how to set them.

use std::net::SocketAddr;

use serde::{Deserialize, Serialize};

use super::ScenarioError;
use super::file::RotationFile;
use crate::math::Quat;

/// The longest OpenIGTLink device name, bytes (the header's field).
pub const MAX_DEVICE_NAME_BYTES: usize = 20;

/// `openigtlink: (listen: "127.0.0.1:18944")`: fissure's own server.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpenIgtLinkFile {
    /// `IP:port` the server listens on (port 0: any free port). Default
    /// `127.0.0.1:18944`. Give another port when a PlusServer on the same
    /// machine holds 18944 (PLUS's force channel then connects here).
    #[serde(default = "default_listen")]
    pub listen: String,
}

fn default_listen() -> String {
    "127.0.0.1:18944".to_string()
}

impl Default for OpenIgtLinkFile {
    fn default() -> Self {
        Self { listen: default_listen() }
    }
}

/// `spacemouse: (dead_zone: 0.15, max_speed_mm_s: 20.0, max_rate_deg_s: 45.8,
/// precision_factor: 0.25, full_scale_counts: 350.0)`: the SpaceMouse's tuning
/// (one device drives every blade bound to it). Defaults: the gamepad's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpaceMouseFile {
    /// Radial dead zone of the translation and of the rotation, fraction of a
    /// full push, in [0, 0.9]. Default 0.15.
    #[serde(default = "default_dead_zone")]
    pub dead_zone: f64,
    /// Blade speed at a full push, mm/s, in (0, 1000]. Default 20.
    #[serde(default = "default_max_speed_mm_s")]
    pub max_speed_mm_s: f64,
    /// Blade turn rate at a full twist, degrees/s, in (0, 3600]. Default 45.84 (0.8 rad/s).
    #[serde(default = "default_max_rate_deg_s")]
    pub max_rate_deg_s: f64,
    /// Speed factor while precision is on (the right button), in (0, 1]. Default 0.25.
    #[serde(default = "default_precision_factor")]
    pub precision_factor: f64,
    /// Counts of a full push, in (0, 32767]. Default 350 (3Dconnexion's devices).
    #[serde(default = "default_full_scale_counts")]
    pub full_scale_counts: f64,
}

fn default_dead_zone() -> f64 {
    0.15
}
fn default_max_speed_mm_s() -> f64 {
    20.0
}
fn default_max_rate_deg_s() -> f64 {
    0.8_f64.to_degrees()
}
fn default_precision_factor() -> f64 {
    0.25
}
fn default_full_scale_counts() -> f64 {
    350.0
}

impl Default for SpaceMouseFile {
    fn default() -> Self {
        Self {
            dead_zone: default_dead_zone(),
            max_speed_mm_s: default_max_speed_mm_s(),
            max_rate_deg_s: default_max_rate_deg_s(),
            precision_factor: default_precision_factor(),
            full_scale_counts: default_full_scale_counts(),
        }
    }
}

/// `mapping: (scale: 1.0, rotation: AxisAngle(axis: (0, 0, 1), angle_deg: 180), clutch: (device: "ButtonsToBase", button: 1))`:
/// the stylus moves the blade relatively (docs/usage.md, "A haptic stylus through PLUS").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StylusMappingFile {
    /// Blade millimetres per stylus millimetre, in (0, 100]. Default 1.
    #[serde(default = "default_scale")]
    pub scale: f64,
    /// The device frame's axes in the scene's (how the stylus's base stands
    /// before the screen). Default: the same axes.
    #[serde(default)]
    pub rotation: Option<RotationFile>,
    /// The clutch button. Default none.
    #[serde(default)]
    pub clutch: Option<ClutchFile>,
}

/// `clutch: (device: "ButtonsToBase", button: 1)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClutchFile {
    /// The device name of the buttons' TRANSFORM (PLUS: `ButtonsTo<frame>`), not the pose's.
    pub device: String,
    /// The button, 1 to 3 (PLUS sends buttons 1 to 3 over OpenIGTLink). Default 1 (the Touch's front button).
    #[serde(default = "default_button")]
    pub button: u8,
}

fn default_scale() -> f64 {
    1.0
}
fn default_button() -> u8 {
    1
}

/// `force: (name: "ForceToBase", scale: 1.0, max_force_n: 3.3, rate_hz: 100.0)`:
/// the force on the blade also sent as a TRANSFORM the way PLUS's OpenHaptics
/// device takes it (its translation the force, N, in the device's frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceTransformFile {
    /// The TRANSFORM's name: `<Id>To<ToolReferenceFrame>` of the PLUS force
    /// tool (at most 20 bytes). Default `ForceToBase`.
    #[serde(default = "default_force_name")]
    pub name: String,
    /// Device newtons per simulated newton, in (0, 100]. Default 1.
    #[serde(default = "default_scale")]
    pub scale: f64,
    /// The device's largest force, N, in (0, 100]: longer forces are cut to it
    /// (a warning, then one a second with the count). Default 3.3 (a Geomagic Touch).
    #[serde(default = "default_max_force_n")]
    pub max_force_n: f64,
    /// The device's loop rate, Hz, in (0, 1000]: at most this many messages a
    /// second. Default 100 (the shipped PLUS configuration's).
    #[serde(default = "default_rate_hz")]
    pub rate_hz: f64,
    /// Scene axes to device axes. Default: the inverse of the mapping's
    /// `rotation` (the force is felt along the motion that caused it); the
    /// same axes without a mapping.
    #[serde(default)]
    pub rotation: Option<RotationFile>,
}

fn default_force_name() -> String {
    "ForceToBase".to_string()
}
fn default_max_force_n() -> f64 {
    3.3
}
fn default_rate_hz() -> f64 {
    100.0
}

/// A checked stylus mapping (SI).
#[derive(Debug, Clone, PartialEq)]
pub struct StylusMappingSettings {
    /// Blade metres per stylus metre.
    pub scale: f64,
    /// The device frame's axes in the scene's.
    pub rotation: Quat,
    /// The clutch: buttons' device name and button (1 to 3).
    pub clutch: Option<(String, u8)>,
}

/// A checked force output in PLUS's form.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceTransformSettings {
    /// The TRANSFORM's name.
    pub name: String,
    /// Device newtons per simulated newton.
    pub scale: f64,
    /// Largest force sent, N.
    pub max_force_n: f64,
    /// Most messages a second.
    pub rate_hz: f64,
    /// Scene axes to device axes.
    pub rotation: Quat,
}

/// What an `OpenIgtLink` binding adds to its device name and limits.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IgtlLink {
    /// `host:port` of a server to read the device from (fissure as a client);
    /// `None`: the device sends to fissure's server.
    pub connect: Option<String>,
    /// The stylus mapping; `None`: the poses are the blade's, in the scene.
    pub mapping: Option<StylusMappingSettings>,
    /// The force as PLUS takes it; `None`: only the `SENSOR` message.
    pub force: Option<ForceTransformSettings>,
}

/// A checked SpaceMouse tuning (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceMouseSettings {
    /// Dead zone, fraction of a full push.
    pub dead_zone: f64,
    /// Speed at a full push, m/s.
    pub max_speed_m_s: f64,
    /// Turn rate at a full twist, rad/s.
    pub max_rate_rad_s: f64,
    /// Speed factor with precision on.
    pub precision_factor: f64,
    /// Counts of a full push.
    pub full_scale_counts: f64,
}

impl Default for SpaceMouseSettings {
    fn default() -> Self {
        // The file's defaults, checked by construction.
        let f = SpaceMouseFile::default();
        Self {
            dead_zone: f.dead_zone,
            max_speed_m_s: f.max_speed_mm_s * 1e-3,
            max_rate_rad_s: f.max_rate_deg_s.to_radians(),
            precision_factor: f.precision_factor,
            full_scale_counts: f.full_scale_counts,
        }
    }
}

type Invalid<'a> = &'a dyn Fn(&str, String) -> ScenarioError;
type Rotation<'a> = &'a dyn Fn(&str, &RotationFile) -> Result<Quat, ScenarioError>;

/// `v` in `(0, max]`, finite.
fn in_range(field: &str, v: f64, max: f64, unit: &str, invalid: Invalid) -> Result<f64, ScenarioError> {
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(invalid(field, format!("must be in (0, {max}]{unit}, got {v}")))
    }
}

/// A non-empty OpenIGTLink device name of at most [`MAX_DEVICE_NAME_BYTES`] bytes.
pub fn device_name(field: &str, name: &str, invalid: Invalid) -> Result<(), ScenarioError> {
    if name.trim().is_empty() {
        return Err(invalid(field, "the OpenIGTLink device name must not be empty".to_string()));
    }
    if name.len() > MAX_DEVICE_NAME_BYTES {
        return Err(invalid(field, format!(
            "\"{name}\" is {} bytes; an OpenIGTLink device name has at most {MAX_DEVICE_NAME_BYTES} (the header's field)",
            name.len()
        )));
    }
    Ok(())
}

/// `host:port` (a name or an address; IPv6 in brackets), port 1 to 65535.
pub fn connect_address(field: &str, address: &str, invalid: Invalid) -> Result<String, ScenarioError> {
    let bad = |why: &str| invalid(field, format!("\"{address}\" is not host:port ({why}), e.g. \"127.0.0.1:18944\""));
    if let Ok(addr) = address.parse::<SocketAddr>() {
        return if addr.port() == 0 { Err(bad("port 0 names no server")) } else { Ok(address.to_string()) };
    }
    let Some((host, port)) = address.rsplit_once(':') else { return Err(bad("no port")) };
    match port.parse::<u16>() {
        Ok(0) | Err(_) => return Err(bad("the port must be 1 to 65535")),
        Ok(_) => {}
    }
    let host_ok = !host.is_empty() && host.len() <= 253 && host.chars().all(|c| c.is_ascii_alphanumeric() || c == '.' || c == '-');
    if !host_ok {
        return Err(bad("the host must be a name of letters, digits, '.' and '-', or an address"));
    }
    Ok(address.to_string())
}

/// `openigtlink.listen`: an `IP:port`.
pub fn validate_listen(file: &OpenIgtLinkFile, invalid: Invalid) -> Result<SocketAddr, ScenarioError> {
    file.listen.parse::<SocketAddr>().map_err(|_| {
        invalid("openigtlink.listen", format!("\"{}\" is not IP:port (the server binds an address, e.g. \"127.0.0.1:18945\")", file.listen))
    })
}

/// The `spacemouse` section.
pub fn validate_spacemouse(file: &SpaceMouseFile, invalid: Invalid) -> Result<SpaceMouseSettings, ScenarioError> {
    let dead_zone = file.dead_zone;
    if !(dead_zone.is_finite() && (0.0..=0.9).contains(&dead_zone)) {
        return Err(invalid("spacemouse.dead_zone", format!("must be in [0, 0.9], got {dead_zone}")));
    }
    Ok(SpaceMouseSettings {
        dead_zone,
        max_speed_m_s: in_range("spacemouse.max_speed_mm_s", file.max_speed_mm_s, 1000.0, " mm/s", invalid)? * 1e-3,
        max_rate_rad_s: in_range("spacemouse.max_rate_deg_s", file.max_rate_deg_s, 3600.0, " degrees/s", invalid)?.to_radians(),
        precision_factor: in_range("spacemouse.precision_factor", file.precision_factor, 1.0, "", invalid)?,
        full_scale_counts: in_range("spacemouse.full_scale_counts", file.full_scale_counts, 32767.0, " counts", invalid)?,
    })
}

/// The optional fields of an `OpenIgtLink` input at `field` (`spatulas[i].input`)
/// whose pose device is `device`.
pub fn validate_link(
    field: &str,
    device: &str,
    connect: Option<&str>,
    mapping: Option<&StylusMappingFile>,
    force: Option<&ForceTransformFile>,
    invalid: Invalid,
    rotation: Rotation,
) -> Result<IgtlLink, ScenarioError> {
    let connect = connect.map(|a| connect_address(&format!("{field}.connect"), a, invalid)).transpose()?;
    let mapping = match mapping {
        None => None,
        Some(m) => {
            let mf = format!("{field}.mapping");
            let scale = in_range(&format!("{mf}.scale"), m.scale, 100.0, "", invalid)?;
            let frame = match &m.rotation {
                Some(r) => rotation(&format!("{mf}.rotation"), r)?,
                None => Quat::identity(),
            };
            let clutch = match &m.clutch {
                None => None,
                Some(c) => {
                    let cf = format!("{mf}.clutch");
                    device_name(&format!("{cf}.device"), &c.device, invalid)?;
                    if c.device == device {
                        return Err(invalid(&format!("{cf}.device"), format!(
                            "\"{}\" is the stylus's pose device; the clutch reads the buttons' TRANSFORM (PLUS: \"ButtonsTo<frame>\")",
                            c.device
                        )));
                    }
                    if !(1..=3).contains(&c.button) {
                        return Err(invalid(&format!("{cf}.button"), format!("must be 1, 2 or 3 (PLUS sends buttons 1 to 3 over OpenIGTLink), got {}", c.button)));
                    }
                    Some((c.device.clone(), c.button))
                }
            };
            Some(StylusMappingSettings { scale, rotation: frame, clutch })
        }
    };
    let force = match force {
        None => None,
        Some(f) => {
            let ff = format!("{field}.force");
            device_name(&format!("{ff}.name"), &f.name, invalid)?;
            let frame = match &f.rotation {
                Some(r) => rotation(&format!("{ff}.rotation"), r)?,
                None => mapping.as_ref().map_or(Quat::identity(), |m| m.rotation.inverse()),
            };
            Some(ForceTransformSettings {
                name: f.name.clone(),
                scale: in_range(&format!("{ff}.scale"), f.scale, 100.0, "", invalid)?,
                max_force_n: in_range(&format!("{ff}.max_force_n"), f.max_force_n, 100.0, " N", invalid)?,
                rate_hz: in_range(&format!("{ff}.rate_hz"), f.rate_hz, 1000.0, " Hz", invalid)?,
                rotation: frame,
            })
        }
    };
    Ok(IgtlLink { connect, mapping, force })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn invalid(field: &str, problem: String) -> ScenarioError {
        let location = super::super::Location { origin: super::super::Origin::Override(String::new()), line: 1, column: 1 };
        ScenarioError::Invalid { location, field: field.to_string(), problem }
    }

    #[test]
    fn addresses() {
        for ok in ["127.0.0.1:18944", "plus-host.local:18944", "[::1]:18944", "localhost:1"] {
            assert!(connect_address("f", ok, &invalid).is_ok(), "{ok}");
        }
        for bad in ["127.0.0.1", "host:0", "host:70000", ":18944", "a b:1", "127.0.0.1:0"] {
            let e = connect_address("spatulas[0].input.connect", bad, &invalid).expect_err(bad).to_string();
            assert!(e.contains("host:port"), "{bad}: {e}");
        }
        assert!(validate_listen(&OpenIgtLinkFile { listen: "localhost:18945".into() }, &invalid).is_err(), "the server binds an address");
        assert_eq!(validate_listen(&OpenIgtLinkFile::default(), &invalid).expect("default").port(), 18944);
    }

    #[test]
    fn the_defaults_are_the_gamepads_and_validate() {
        let s = validate_spacemouse(&SpaceMouseFile::default(), &invalid).expect("defaults");
        assert_eq!(s, SpaceMouseSettings::default());
        assert!((s.max_rate_rad_s - 0.8).abs() < 1e-12 && (s.max_speed_m_s - 0.02).abs() < 1e-15);
    }
}
