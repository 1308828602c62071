//! The scene's 6-DoF devices brought up for the window: the OpenIGTLink
//! endpoint its bindings ask for (server, client links, stylus mappings, the
//! force in PLUS's form) and the SpaceMouse the simulation thread polls.
//!
//! In: a validated [`Scenario`]. Out: an [`IgtlConfig`] (and a started
//! [`IgtlServer`]), and each frame [`FrameDevices`]: what the SpaceMouse
//! offers which blade, with the devices' status lines written to the panel's
//! status when they change. Stays true: nothing here waits on a device (the
//! SpaceMouse and every link read on their own threads); a server that cannot
//! listen still lets the links read their poses (with a warning that no force
//! goes back); a scene without a SpaceMouse binding starts no reader.
//!
//! Which way the endpoint is built: it listens when a binding has no
//! `connect` (the device sends to fissure) or asks for the force in PLUS's
//! form (PLUS's `OpenIGTLinkTracker` connects to fissure for it); it connects
//! to each `connect` address once, reading there every device bound to it.

use crate::input::drivers::{BindingKind, DeviceOffers};
use crate::input::force_transform::ForceTransformConfig;
use crate::input::igtl::{IgtlConfig, IgtlServer, IgtlServerError};
use crate::input::igtl_link::LinkConfig;
use crate::input::spacemouse::{SpaceMouseInput, SpaceMouseMapping, Sources};
use crate::input::tracker::TrackerLimits;
use crate::input::workspace::{Clutch, StylusMapping};
use crate::input::PoseVelocity;
use crate::scenario::{InputBinding, Scenario, SpaceMouseSettings};
use std::sync::{Arc, Mutex};

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The endpoint the scene's `OpenIgtLink` bindings need; `None` when none has one.
pub fn igtl_config(scenario: &Scenario) -> Option<IgtlConfig> {
    let mut config = IgtlConfig { bind: scenario.devices.igtl_listen, listen: false, ..IgtlConfig::default() };
    let mut bound = false;
    for s in &scenario.spatulas {
        let InputBinding::OpenIgtLink { device, workspace_m, max_speed_m_s, link } = &s.input else { continue };
        bound = true;
        // The first binding of a name gives its limits.
        if !config.device_limits.iter().any(|(d, _)| d == device) {
            config.device_limits.push((device.clone(), TrackerLimits { workspace_m: *workspace_m, max_speed_m_s: *max_speed_m_s }));
        }
        let clutch = link.mapping.as_ref().and_then(|m| m.clutch.clone()).map(|(device, button)| Clutch { device, button });
        match &link.connect {
            Some(address) => {
                let i = match config.links.iter().position(|l| &l.address == address) {
                    Some(i) => i,
                    None => {
                        config.links.push(LinkConfig { address: address.clone(), devices: Vec::new() });
                        config.links.len() - 1
                    }
                };
                let devices = &mut config.links[i].devices;
                for d in std::iter::once(device).chain(clutch.as_ref().map(|c| &c.device)) {
                    if !devices.contains(d) {
                        devices.push(d.clone());
                    }
                }
            }
            None => config.listen = true,
        }
        if let Some(m) = &link.mapping {
            let mapping = StylusMapping { scale: m.scale, rotation: m.rotation.to_rotation_matrix().into_inner(), origin: s.initial_pose, clutch: clutch.clone() };
            config.mappings.push((device.clone(), mapping));
        }
        if let Some(f) = &link.force {
            config.listen = true;
            config.force_transforms.push(ForceTransformConfig {
                spatula: s.name.clone(),
                name: f.name.clone(),
                rotation: f.rotation.to_rotation_matrix().into_inner(),
                scale: f.scale,
                max_force_n: f.max_force_n,
                rate_hz: f.rate_hz,
                clutch_device: clutch.is_some().then(|| device.clone()),
            });
        }
    }
    bound.then_some(config)
}

/// Starts the endpoint the scene needs (see [`igtl_config`]); `None` when it
/// needs none or it could not start (logged: its blades hold their poses).
pub fn start_igtl(scenario: &Scenario) -> Option<Arc<Mutex<IgtlServer>>> {
    let config = igtl_config(scenario)?;
    let started = match IgtlServer::start(&config) {
        Err(IgtlServerError::Bind { addr, source }) if !config.links.is_empty() => {
            tracing::warn!(%addr, error = %source, "OpenIGTLink server not started, so no force goes back (set `openigtlink.listen` to a free port); the links still read their poses");
            IgtlServer::start(&IgtlConfig { listen: false, ..config })
        }
        other => other,
    };
    match started {
        Ok(s) => Some(Arc::new(Mutex::new(s))),
        Err(e) => {
            tracing::warn!(error = %e, "OpenIGTLink not started; its spatulas hold their poses");
            None
        }
    }
}

fn mapping_of(settings: &SpaceMouseSettings) -> SpaceMouseMapping {
    SpaceMouseMapping {
        dead_zone: settings.dead_zone,
        max_speed_m_s: settings.max_speed_m_s,
        max_rate_rad_s: settings.max_rate_rad_s,
        precision_factor: settings.precision_factor,
        full_scale_counts: settings.full_scale_counts,
    }
}

/// The devices the simulation thread polls each frame (the SpaceMouse) and
/// whose status lines it shows.
#[derive(Default)]
pub struct Devices {
    spacemouse: Option<SpaceMouseInput>,
    /// The status changes last shown: the SpaceMouse's and the links'.
    seen: Option<(u64, u64)>,
    shown: Vec<String>,
}

/// What the devices offer this frame.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameDevices {
    /// The SpaceMouse's blade (scenario index) and velocity.
    spacemouse: Option<(usize, PoseVelocity)>,
}

impl FrameDevices {
    /// The SpaceMouse's offer to blade `k` (bound to it): its velocity when it
    /// has picked that blade.
    pub fn offer(&self, k: usize, offers: &mut DeviceOffers) -> BindingKind {
        offers.spacemouse = self.spacemouse.and_then(|(j, v)| (j == k).then_some(v));
        BindingKind::SpaceMouse
    }
}

fn on_spacemouse(s: &crate::scenario::SpatulaConfig) -> bool {
    matches!(s.input, InputBinding::SpaceMouse)
}

impl Devices {
    /// Polls the SpaceMouse when the scene binds blades to it (starting its
    /// reader the first time, stopping it when a new scene binds none), and
    /// writes each device status line that changed to `status`. Never blocks;
    /// allocates only when a status changed.
    pub fn poll(&mut self, scenario: &Scenario, igtl: Option<&Arc<Mutex<IgtlServer>>>, status: &Mutex<String>) -> FrameDevices {
        let bound = scenario.spatulas.iter().filter(|s| on_spacemouse(s)).count();
        let mut frame = FrameDevices::default();
        if bound == 0 {
            self.spacemouse = None;
        } else {
            let mapping = mapping_of(&scenario.devices.spacemouse);
            let mouse = self.spacemouse.get_or_insert_with(|| SpaceMouseInput::start(mapping, Sources::system()));
            mouse.controller.mapping = mapping;
            let command = mouse.poll(bound);
            let blade = scenario.spatulas.iter().enumerate().filter(|(_, s)| on_spacemouse(s)).nth(command.selected);
            frame.spacemouse = blade.map(|(k, _)| (k, command.velocity));
        }
        let seen = (self.spacemouse.as_ref().map_or(0, SpaceMouseInput::status_changes), igtl.map_or(0, |s| lock(s).link_changes()));
        if self.seen != Some(seen) {
            self.seen = Some(seen);
            let mut lines: Vec<String> = self.spacemouse.iter().map(|m| m.status().to_string()).collect();
            if let Some(server) = igtl {
                lines.extend(lock(server).link_status().iter().map(ToString::to_string));
            }
            for line in &lines {
                if !self.shown.contains(line) {
                    *lock(status) = line.clone();
                }
            }
            self.shown = lines;
        }
        frame
    }

    /// The SpaceMouse's status line, when the scene binds one.
    pub fn spacemouse_status(&self) -> Option<&str> {
        self.spacemouse.as_ref().map(SpaceMouseInput::status)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn scene(overrides: &[&str]) -> Scenario {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sylvian.ron"));
        let text = std::fs::read_to_string(path).expect("read");
        let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        Scenario::from_str(&text, path, &overrides).expect("valid")
    }

    #[test]
    fn a_stylus_read_from_plus_with_force_back_listens_and_connects_once() {
        let s = scene(&[
            r#"spatulas[0].input=OpenIgtLink(device: "StylusToBase", connect: "127.0.0.1:18944", mapping: (scale: 0.5, clutch: (device: "ButtonsToBase")), force: (max_force_n: 2.0))"#,
            "openigtlink.listen=\"127.0.0.1:18945\"",
        ]);
        let c = igtl_config(&s).expect("bound");
        assert!(c.listen && c.bind.port() == 18945, "force back: PLUS connects here");
        assert_eq!(c.links, [LinkConfig { address: "127.0.0.1:18944".into(), devices: vec!["StylusToBase".into(), "ButtonsToBase".into()] }]);
        assert_eq!(c.mappings.len(), 1);
        assert_eq!(c.mappings[0].1.origin, s.spatulas[0].initial_pose, "the stylus's first pose maps to the blade's start");
        let f = &c.force_transforms[0];
        assert_eq!((f.spatula.as_str(), f.name.as_str(), f.max_force_n, f.clutch_device.as_deref()), ("frontal", "ForceToBase", 2.0, Some("StylusToBase")));
    }

    #[test]
    fn a_spacemouse_scene_says_where_its_device_is_and_offers_only_its_picked_blade() {
        let s = scene(&["spatulas[0].input=SpaceMouse", "spatulas[1].input=SpaceMouse"]);
        let status = Mutex::new(String::new());
        let mut devices = Devices::default();
        let frame = devices.poll(&s, None, &status);
        assert!(lock(&status).contains("SpaceMouse"), "the status line speaks of the device: {}", lock(&status));
        let mut offers = DeviceOffers::default();
        assert_eq!(frame.offer(1, &mut offers), BindingKind::SpaceMouse);
        assert!(offers.spacemouse.is_none(), "the left button has not picked the second blade");
        frame.offer(0, &mut offers);
        assert!(offers.spacemouse.is_some(), "the first SpaceMouse blade is picked at the start");
        // The reader's first look ends in a device or in what is missing.
        let start = std::time::Instant::now();
        while devices.spacemouse_status().is_some_and(|l| l.contains("looking for")) {
            assert!(start.elapsed() < std::time::Duration::from_secs(10), "the reader never reported");
            std::thread::sleep(std::time::Duration::from_millis(5));
            devices.poll(&s, None, &status);
        }
        assert_eq!(devices.spacemouse_status(), Some(lock(&status).as_str()), "the new line is shown");
        *lock(&status) = String::new();
        devices.poll(&s, None, &status);
        assert_eq!(lock(&status).as_str(), "", "an unchanged status is not written again");
        devices.poll(&scene(&[]), None, &status);
        assert!(devices.spacemouse_status().is_none(), "a scene without a SpaceMouse stops its reader");
    }

    #[test]
    fn a_taken_port_still_lets_the_link_read_the_stylus() {
        let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = taken.local_addr().expect("addr").port();
        let s = scene(&[
            r#"spatulas[0].input=OpenIgtLink(device: "StylusToBase", connect: "127.0.0.1:9", force: ())"#,
            &format!("openigtlink.listen=\"127.0.0.1:{port}\""),
        ]);
        let server = start_igtl(&s).expect("started without its server");
        let server = lock(&server);
        assert_eq!(server.listening_on(), None, "the port is taken: no server, so no force back (logged)");
        assert_eq!(server.link_status().len(), 1, "the link runs");
    }

    #[test]
    fn a_client_only_binding_does_not_listen_and_other_scenes_need_nothing() {
        let s = scene(&[r#"spatulas[0].input=OpenIgtLink(device: "StylusToBase", connect: "127.0.0.1:18944")"#]);
        let c = igtl_config(&s).expect("bound");
        assert!(!c.listen, "a PlusServer on this machine holds 18944: fissure must not try to");
        assert!(igtl_config(&scene(&[])).is_none(), "keyboard and gamepad only");
        let s = scene(&[r#"spatulas[1].input=OpenIgtLink(device: "Tracker1")"#]);
        assert!(igtl_config(&s).expect("bound").listen, "a tracker sends to fissure");
    }
}
