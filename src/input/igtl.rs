//! OpenIGTLink endpoint: a server that receives TRANSFORM messages from
//! trackers, haptic bridges or 3D Slicer, and client links to remote servers
//! (a PlusServer streaming a haptic stylus); publishes the latest good pose
//! per device name and sends force feedback back.
//!
//! In: TCP clients (default `127.0.0.1:18944`), each sending OpenIGTLink
//! messages (header v1 or v2), and the messages of each remote server in
//! [`IgtlConfig::links`] ([`super::igtl_link`]: reconnected with backoff on its
//! own thread). Out: [`IgtlServer::latest`] (via [`PoseSource`]) gives the last
//! good pose of a device, translation converted from millimetres to metres and,
//! for a device with a [`StylusMapping`], mapped to the blade by scale, frame
//! and clutch ([`super::workspace`]); [`IgtlServer::send_force`] writes the
//! `SENSOR` force message documented in [`super::igtl_codec`] to every client,
//! and, for a blade with a [`ForceTransformConfig`], the force as PLUS takes it
//! ([`super::force_transform`]). Stays true: a malformed message (bad CRC,
//! wrong size, NaN, non-orthonormal rotation) is dropped and logged (a warning
//! the first time per connection and kind, counted always) and the last good
//! pose holds; a well-formed pose outside the device's workspace or faster than its
//! speed limit ([`TrackerLimits`], see [`super::tracker`]) is refused the same
//! way, counted per reason and logged the first time and then at most once a
//! second per device with the count; a dropped client is logged and its thread
//! ends; nothing here panics on what a peer sends, and nothing a caller does
//! waits on a network peer longer than the write timeout. Each client and each
//! link has its own thread; the accept loop runs on another; all stop when the
//! server is dropped (which first sends a zero force to the PLUS-form outputs).

use super::force_transform::{ForceTransformConfig, ForceTransformOutput};
use super::igtl_codec;
use super::igtl_link::{self, Backoff, LinkConfig, LinkStatus};
use super::igtl_stream::{Peer, ReadOutcome, serve, setup_client};
use super::tracker::{RateLimitedWarning, Refused, TrackerGuard, TrackerLimits};
use super::workspace::{MappedStylus, StylusMapping};
use super::{PoseSource, TimedPose};
use crate::geometry::Pose;
use crate::math::{Matrix3, Quat, Vec3};
use std::io::{ErrorKind, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Default OpenIGTLink port.
pub const DEFAULT_PORT: u16 = 18944;

/// Endpoint settings.
#[derive(Debug, Clone, PartialEq)]
pub struct IgtlConfig {
    /// Address to listen on. Default `127.0.0.1:18944` (loopback only); port 0
    /// picks a free port (see [`IgtlServer::local_addr`]).
    pub bind: SocketAddr,
    /// Whether to listen at all (default true). Off when every pose comes over
    /// [`IgtlConfig::links`] and nothing goes back: a PlusServer on the same
    /// machine holds port 18944 itself.
    pub listen: bool,
    /// How long a blocked write of a force message may take before the client
    /// is dropped, ms (1..=1000; default 5).
    pub write_timeout_ms: u64,
    /// Workspace and speed limit of a device `device_limits` does not name
    /// (default: [`TrackerLimits::default`], ±1 m and 3 m/s).
    pub limits: TrackerLimits,
    /// Limits per device name (the scenario's `OpenIgtLink` bindings).
    pub device_limits: Vec<(String, TrackerLimits)>,
    /// Remote servers to connect to, each with the devices read from it.
    pub links: Vec<LinkConfig>,
    /// How a lost or refused link waits before it tries again.
    pub backoff: Backoff,
    /// Devices whose poses map to a blade by scale, frame and clutch (a
    /// stylus); a device not listed is taken as an absolute pose in the scene.
    pub mappings: Vec<(String, StylusMapping)>,
    /// Forces sent as PLUS takes them, besides the `SENSOR` message.
    pub force_transforms: Vec<ForceTransformConfig>,
}

impl Default for IgtlConfig {
    fn default() -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], DEFAULT_PORT)),
            listen: true,
            write_timeout_ms: 5,
            limits: TrackerLimits::default(),
            device_limits: Vec::new(),
            links: Vec::new(),
            backoff: Backoff::default(),
            mappings: Vec::new(),
            force_transforms: Vec::new(),
        }
    }
}

impl IgtlConfig {
    /// The limits in force for `device`.
    pub fn limits_of(&self, device: &str) -> TrackerLimits {
        self.device_limits.iter().find(|(d, _)| d == device).map_or(self.limits, |(_, l)| *l)
    }
}

/// Errors starting the server.
#[derive(Debug, thiserror::Error)]
pub enum IgtlServerError {
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("cannot configure the listening socket on {addr}: {source}")]
    Configure {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("cannot start the OpenIGTLink thread: {0}")]
    Thread(std::io::Error),
}

/// Counters a panel or test can read; all monotonic.
#[derive(Debug, Default)]
pub struct IgtlStats {
    /// Clients accepted.
    pub clients_accepted: AtomicU64,
    /// Clients whose connection ended (closed, reset, corrupt stream).
    pub clients_dropped: AtomicU64,
    /// TRANSFORMs accepted and published.
    pub transforms_accepted: AtomicU64,
    /// Messages refused (CRC, size, NaN, non-orthonormal, bad header).
    pub messages_rejected: AtomicU64,
    /// Well-formed TRANSFORMs refused: the pose lies outside the device's workspace.
    pub poses_outside_workspace: AtomicU64,
    /// Well-formed TRANSFORMs refused: the pose moved faster than the device's limit.
    pub poses_too_fast: AtomicU64,
    /// Messages of other types, skipped.
    pub messages_ignored: AtomicU64,
    /// Force messages written.
    pub forces_sent: AtomicU64,
    /// Button TRANSFORMs read (a stylus's clutch).
    pub buttons_received: AtomicU64,
    /// Force TRANSFORMs (PLUS's form) written, one per client reached.
    pub force_transforms_sent: AtomicU64,
    /// Force TRANSFORMs whose force was clamped to the device's maximum.
    pub forces_clamped: AtomicU64,
    /// Connections the links made (a reconnection counts again).
    pub links_connected: AtomicU64,
}

/// A copyable snapshot of [`IgtlStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IgtlStatsSnapshot {
    pub clients_accepted: u64,
    pub clients_dropped: u64,
    pub transforms_accepted: u64,
    pub messages_rejected: u64,
    pub poses_outside_workspace: u64,
    pub poses_too_fast: u64,
    pub messages_ignored: u64,
    pub forces_sent: u64,
    pub buttons_received: u64,
    pub force_transforms_sent: u64,
    pub forces_clamped: u64,
    pub links_connected: u64,
}

impl IgtlStatsSnapshot {
    /// Poses refused by the workspace and speed checks (malformed messages are
    /// in `messages_rejected`).
    pub fn poses_refused(&self) -> u64 {
        self.poses_outside_workspace + self.poses_too_fast
    }
}

/// The plausibility check of one device and its log throttle.
#[derive(Debug)]
struct DeviceCheck {
    guard: TrackerGuard,
    warning: RateLimitedWarning,
}

/// Latest pose per device, kept sorted by name (fixed order, no hashing), each
/// device's plausibility check, and the mapped styluses.
#[derive(Debug, Default)]
pub(super) struct PoseSlots {
    slots: Vec<(String, TimedPose)>,
    checks: Vec<(String, DeviceCheck)>,
    /// Mapped styluses by device name, sorted.
    mapped: Vec<(String, MappedStylus)>,
}

impl PoseSlots {
    fn with_mappings(mappings: &[(String, StylusMapping)]) -> Self {
        let mut mapped: Vec<(String, MappedStylus)> = Vec::new();
        for (device, mapping) in mappings {
            if let Err(i) = mapped.binary_search_by(|(name, _)| name.as_str().cmp(device)) {
                mapped.insert(i, (device.clone(), MappedStylus::new(mapping.clone())));
            }
        }
        Self { mapped, ..Self::default() }
    }

    fn mapped_mut(&mut self, device: &str) -> Option<&mut MappedStylus> {
        let i = self.mapped.binary_search_by(|(name, _)| name.as_str().cmp(device)).ok()?;
        Some(&mut self.mapped[i].1)
    }

    /// Whether `device` is a mapped stylus whose clutch is held.
    pub(super) fn clutched(&self, device: &str) -> bool {
        self.mapped.binary_search_by(|(name, _)| name.as_str().cmp(device)).is_ok_and(|i| self.mapped[i].1.clutched())
    }

    /// Whether `device` carries the buttons of some stylus's clutch.
    pub(super) fn is_clutch_device(&self, device: &str) -> bool {
        self.mapped.iter().any(|(_, m)| m.mapping().clutch.as_ref().is_some_and(|c| c.device == device))
    }

    /// Sets the clutch of every stylus whose clutch button `device` carries.
    pub(super) fn buttons(&mut self, device: &str, pressed: [bool; 4]) {
        for (_, m) in &mut self.mapped {
            if let Some(button) = m.mapping().clutch.as_ref().filter(|c| c.device == device).map(|c| c.button) {
                let held = pressed.get(usize::from(button.max(1)) - 1).copied().unwrap_or(false);
                m.set_clutch(held);
            }
        }
    }

    /// Re-anchors the mapped styluses among `devices` (a link came back).
    pub(super) fn reanchor(&mut self, devices: &[String]) {
        for (name, m) in &mut self.mapped {
            if devices.iter().any(|d| d == name) {
                m.reanchor();
            }
        }
    }

    /// Maps `pose` if the device is a stylus, then publishes it if the
    /// device's check accepts it; otherwise returns why, with `Some(n)` when a
    /// log line is due for the `n` refusals since the last.
    pub(super) fn offer(
        &mut self,
        device: &str,
        pose: Pose,
        timestamp_s: f64,
        arrived: Instant,
        config: &IgtlConfig,
    ) -> Result<(), (Refused, Option<u64>)> {
        let pose = match self.mapped_mut(device) {
            Some(m) => m.map(&pose),
            None => pose,
        };
        let i = match self.checks.binary_search_by(|(name, _)| name.as_str().cmp(device)) {
            Ok(i) => i,
            Err(i) => {
                let check = DeviceCheck {
                    guard: TrackerGuard::new(config.limits_of(device)),
                    warning: RateLimitedWarning::new(Duration::from_secs(1)),
                };
                self.checks.insert(i, (device.to_string(), check));
                i
            }
        };
        let check = &mut self.checks[i].1;
        match check.guard.check(&pose, timestamp_s, arrived) {
            Ok(()) => {
                if let Some(m) = self.mapped_mut(device) {
                    m.accept(pose);
                }
                self.publish(device, pose, timestamp_s);
                Ok(())
            }
            Err(why) => Err((why, check.warning.occur(arrived))),
        }
    }

    fn publish(&mut self, device: &str, pose: Pose, timestamp_s: f64) {
        match self
            .slots
            .binary_search_by(|(name, _)| name.as_str().cmp(device))
        {
            Ok(i) => {
                let slot = &mut self.slots[i].1;
                *slot = TimedPose {
                    pose,
                    timestamp_s,
                    sequence: slot.sequence + 1,
                };
            }
            Err(i) => self.slots.insert(
                i,
                (
                    device.to_string(),
                    TimedPose {
                        pose,
                        timestamp_s,
                        sequence: 1,
                    },
                ),
            ),
        }
    }

    fn get(&self, device: &str) -> Option<TimedPose> {
        self.slots
            .binary_search_by(|(name, _)| name.as_str().cmp(device))
            .ok()
            .map(|i| self.slots[i].1)
    }
}

pub(super) struct Shared {
    pub(super) config: IgtlConfig,
    pub(super) poses: Mutex<PoseSlots>,
    writers: Mutex<Vec<(u64, TcpStream)>>,
    pub(super) stop: AtomicBool,
    pub(super) stats: IgtlStats,
    /// One status per link, in [`IgtlConfig::links`] order.
    pub(super) links: Mutex<Vec<LinkStatus>>,
    /// Counts changes of `links` (a caller re-reads them only when it moved).
    pub(super) link_changes: AtomicU64,
}

pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panicking holder cannot leave these plain containers half-updated in a
    // way that matters; keep serving rather than propagate the poison.
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A running OpenIGTLink endpoint. Dropping it stops its threads.
pub struct IgtlServer {
    shared: Arc<Shared>,
    local_addr: Option<SocketAddr>,
    accept_thread: Option<JoinHandle<()>>,
    link_threads: Vec<JoinHandle<()>>,
    force_buffer: Vec<u8>,
    transform_buffer: Vec<u8>,
    force_outputs: Vec<ForceTransformOutput>,
}

impl IgtlServer {
    /// Binds (when [`IgtlConfig::listen`]) and starts accepting clients on
    /// their own threads; starts one thread per link.
    pub fn start(config: &IgtlConfig) -> Result<Self, IgtlServerError> {
        let listener = if config.listen {
            let listener = TcpListener::bind(config.bind).map_err(|source| IgtlServerError::Bind { addr: config.bind, source })?;
            let local_addr = listener.local_addr().map_err(|source| IgtlServerError::Configure { addr: config.bind, source })?;
            listener.set_nonblocking(true).map_err(|source| IgtlServerError::Configure { addr: local_addr, source })?;
            Some((listener, local_addr))
        } else {
            None
        };
        let shared = Arc::new(Shared {
            config: config.clone(),
            poses: Mutex::new(PoseSlots::with_mappings(&config.mappings)),
            writers: Mutex::new(Vec::new()),
            stop: AtomicBool::new(false),
            stats: IgtlStats::default(),
            links: Mutex::new(config.links.iter().map(|l| LinkStatus::new(&l.address)).collect()),
            link_changes: AtomicU64::new(0),
        });
        let write_timeout = Duration::from_millis(config.write_timeout_ms.clamp(1, 1000));
        let mut server = Self {
            shared: Arc::clone(&shared),
            local_addr: listener.as_ref().map(|(_, a)| *a),
            accept_thread: None,
            link_threads: Vec::new(),
            force_buffer: Vec::with_capacity(igtl_codec::FORCE_MESSAGE_SIZE),
            transform_buffer: Vec::with_capacity(igtl_codec::TRANSFORM_MESSAGE_SIZE),
            force_outputs: config.force_transforms.iter().cloned().map(ForceTransformOutput::new).collect(),
        };
        if let Some((listener, local_addr)) = listener {
            let accept_shared = Arc::clone(&shared);
            let accept_thread = std::thread::Builder::new()
                .name("igtl-accept".into())
                .spawn(move || accept_loop(listener, accept_shared, write_timeout))
                .map_err(IgtlServerError::Thread)?;
            server.accept_thread = Some(accept_thread);
            tracing::info!(%local_addr, "OpenIGTLink server listening");
        }
        for index in 0..config.links.len() {
            let link_shared = Arc::clone(&shared);
            let thread = std::thread::Builder::new()
                .name(format!("igtl-link-{index}"))
                .spawn(move || igtl_link::run(index, link_shared, write_timeout))
                .map_err(IgtlServerError::Thread)?;
            server.link_threads.push(thread);
        }
        Ok(server)
    }

    /// The address actually bound (useful with port 0); `None` when not listening.
    pub fn listening_on(&self) -> Option<SocketAddr> {
        self.local_addr
    }

    /// The address actually bound (useful with port 0). Without a listener
    /// (see [`IgtlConfig::listen`]) this is the configured address, unbound.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr.unwrap_or(self.shared.config.bind)
    }

    /// How each link stands, in [`IgtlConfig::links`] order.
    pub fn link_status(&self) -> Vec<LinkStatus> {
        lock(&self.shared.links).clone()
    }

    /// How many times a link's status changed so far (cheap: read it each
    /// frame, [`IgtlServer::link_status`] only when it moved).
    pub fn link_changes(&self) -> u64 {
        self.shared.link_changes.load(Ordering::Relaxed)
    }

    /// Whether the stylus `device` has its clutch held.
    pub fn clutched(&self, device: &str) -> bool {
        lock(&self.shared.poses).clutched(device)
    }

    /// The latest good pose of `device` (also through [`PoseSource`]).
    pub fn latest(&self, device: &str) -> Option<TimedPose> {
        lock(&self.shared.poses).get(device)
    }

    /// Names of the devices that have delivered a good pose, sorted.
    pub fn devices(&self) -> Vec<String> {
        lock(&self.shared.poses)
            .slots
            .iter()
            .map(|(n, _)| n.clone())
            .collect()
    }

    /// A snapshot of the counters.
    pub fn stats(&self) -> IgtlStatsSnapshot {
        let s = &self.shared.stats;
        IgtlStatsSnapshot {
            clients_accepted: s.clients_accepted.load(Ordering::Relaxed),
            clients_dropped: s.clients_dropped.load(Ordering::Relaxed),
            transforms_accepted: s.transforms_accepted.load(Ordering::Relaxed),
            messages_rejected: s.messages_rejected.load(Ordering::Relaxed),
            poses_outside_workspace: s.poses_outside_workspace.load(Ordering::Relaxed),
            poses_too_fast: s.poses_too_fast.load(Ordering::Relaxed),
            messages_ignored: s.messages_ignored.load(Ordering::Relaxed),
            forces_sent: s.forces_sent.load(Ordering::Relaxed),
            buttons_received: s.buttons_received.load(Ordering::Relaxed),
            force_transforms_sent: s.force_transforms_sent.load(Ordering::Relaxed),
            forces_clamped: s.forces_clamped.load(Ordering::Relaxed),
            links_connected: s.links_connected.load(Ordering::Relaxed),
        }
    }

    /// Sends the force on `spatula` (newtons, world axes) to every connected
    /// client as a `SENSOR` message named `Force_<spatula>`, and, when a
    /// [`ForceTransformConfig`] names the spatula and its period has passed
    /// on `timestamp_s`, as PLUS's force TRANSFORM (device frame, scaled,
    /// clamped). A client whose write fails or times out is dropped (logged).
    /// Returns how many clients received the `SENSOR` message.
    /// Allocation-free after the first call.
    pub fn send_force(&mut self, spatula: &str, timestamp_s: f64, force_n: [f64; 3]) -> usize {
        igtl_codec::encode_force(&mut self.force_buffer, spatula, timestamp_s, force_n);
        let sent = broadcast(&self.shared.writers, &self.force_buffer, "force message");
        self.shared.stats.forces_sent.fetch_add(sent as u64, Ordering::Relaxed);
        for output in &mut self.force_outputs {
            if output.config().spatula != spatula {
                continue;
            }
            let clutched = output.config().clutch_device.as_deref().is_some_and(|d| lock(&self.shared.poses).clutched(d));
            let Some(force) = output.tick(timestamp_s, Vec3::from(force_n), clutched, Instant::now()) else { continue };
            igtl_codec::encode_transform_into(&mut self.transform_buffer, &output.config().name, timestamp_s, &Matrix3::identity(), &force.force_n);
            let reached = broadcast(&self.shared.writers, &self.transform_buffer, "force TRANSFORM");
            self.shared.stats.force_transforms_sent.fetch_add(reached as u64, Ordering::Relaxed);
            if force.clamped {
                self.shared.stats.forces_clamped.fetch_add(1, Ordering::Relaxed);
            }
        }
        sent
    }
}

/// Writes `message` to every client; drops (and logs) those whose write fails.
/// Returns how many were reached.
fn broadcast(writers: &Mutex<Vec<(u64, TcpStream)>>, message: &[u8], what: &str) -> usize {
    let mut writers = lock(writers);
    let mut sent = 0;
    writers.retain_mut(|(id, stream)| match stream.write_all(message) {
        Ok(()) => {
            sent += 1;
            true
        }
        Err(e) => {
            tracing::warn!(client = *id, error = %e, "{what} not delivered; no more force messages to this client");
            false
        }
    });
    sent
}

impl PoseSource for IgtlServer {
    fn latest(&self, device: &str) -> Option<TimedPose> {
        IgtlServer::latest(self, device)
    }
}

impl Drop for IgtlServer {
    fn drop(&mut self) {
        // A device that keeps its last force (PLUS's tracker holds the last
        // transform it read) must not go on pushing once the simulation ends.
        for output in &self.force_outputs {
            igtl_codec::encode_transform_into(&mut self.transform_buffer, &output.config().name, 0.0, &Matrix3::identity(), &Vec3::zeros());
            broadcast(&self.shared.writers, &self.transform_buffer, "zero force TRANSFORM");
        }
        self.shared.stop.store(true, Ordering::Relaxed);
        for (_, stream) in lock(&self.shared.writers).drain(..) {
            let _ = stream.shutdown(std::net::Shutdown::Both);
        }
        if let Some(handle) = self.accept_thread.take() {
            let _ = handle.join();
        }
        for handle in self.link_threads.drain(..) {
            let _ = handle.join();
        }
    }
}

/// Converts a validated TRANSFORM to a pose: millimetres to metres, the
/// rotation matrix to a unit quaternion. `None` if the result is not a valid pose.
pub fn transform_to_pose(t: &igtl_codec::Transform) -> Option<Pose> {
    let rotation = Quat::from_matrix_eps(&t.rotation, 1e-9, 100, Quat::identity());
    let pose = Pose {
        position: t.translation_mm * 1e-3,
        rotation,
    };
    // from_matrix_eps is iterative; make sure it landed on the given rotation.
    let back = rotation.to_rotation_matrix().into_inner();
    let close = (back - t.rotation).abs().max() < 10.0 * igtl_codec::ORTHONORMAL_TOLERANCE;
    (close && pose.is_valid()).then_some(pose)
}

fn accept_loop(listener: TcpListener, shared: Arc<Shared>, write_timeout: Duration) {
    let mut next_id = 0u64;
    let mut clients: Vec<JoinHandle<()>> = Vec::new();
    while !shared.stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, peer)) => {
                next_id += 1;
                let id = next_id;
                shared
                    .stats
                    .clients_accepted
                    .fetch_add(1, Ordering::Relaxed);
                tracing::info!(client = id, %peer, "OpenIGTLink client connected");
                if let Err(e) = setup_client(&stream, write_timeout) {
                    tracing::warn!(client = id, error = %e, "cannot configure client socket; dropping it");
                    shared.stats.clients_dropped.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                match stream.try_clone() {
                    Ok(writer) => lock(&shared.writers).push((id, writer)),
                    Err(e) => {
                        tracing::warn!(client = id, error = %e, "no force feedback to this client")
                    }
                }
                let client_shared = Arc::clone(&shared);
                match std::thread::Builder::new()
                    .name(format!("igtl-client-{id}"))
                    .spawn(move || client_loop(id, stream, client_shared))
                {
                    Ok(h) => clients.push(h),
                    Err(e) => {
                        tracing::warn!(client = id, error = %e, "cannot start a client thread; dropping it")
                    }
                }
                clients.retain(|h| !h.is_finished());
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(10))
            }
            Err(e) => {
                tracing::warn!(error = %e, "accept failed");
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }
    for h in clients {
        let _ = h.join();
    }
}

fn client_loop(id: u64, stream: TcpStream, shared: Arc<Shared>) {
    let outcome = serve(&Peer::Client(id), stream, &shared, None);
    match outcome {
        ReadOutcome::Closed => tracing::info!(client = id, "OpenIGTLink client disconnected"),
        ReadOutcome::Stopped => {}
        ReadOutcome::Io(e) => tracing::warn!(client = id, error = %e, "OpenIGTLink client dropped"),
    }
    shared.stats.clients_dropped.fetch_add(1, Ordering::Relaxed);
    lock(&shared.writers).retain(|(w, _)| *w != id);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::igtl_codec::HEADER_SIZE;
    use std::io::Read;
    use crate::math::{Matrix3, Vec3};
    use std::time::Instant;

    fn local_server() -> IgtlServer {
        let config = IgtlConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            ..IgtlConfig::default()
        };
        IgtlServer::start(&config).expect("bind an ephemeral loopback port")
    }

    fn wait_for(mut cond: impl FnMut() -> bool) -> bool {
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(5) {
            if cond() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        false
    }

    #[test]
    fn pose_slots_keep_sorted_order_and_count() {
        let mut slots = PoseSlots::default();
        slots.publish("b", Pose::default(), 1.0);
        slots.publish("a", Pose::default(), 2.0);
        slots.publish("b", Pose::default(), 3.0);
        let names: Vec<_> = slots.slots.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(
            slots.get("b").map(|p| (p.sequence, p.timestamp_s)),
            Some((2, 3.0))
        );
        assert!(slots.get("c").is_none());
    }

    #[test]
    fn bad_messages_keep_last_good_pose_and_force_goes_back() {
        let mut server = local_server();
        let mut client = TcpStream::connect(server.local_addr()).expect("connect");
        let r = *nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), 0.25).matrix();
        client
            .write_all(&igtl_codec::encode_transform(
                "Left",
                1.0,
                &r,
                &Vec3::new(10.0, 20.0, -30.0),
            ))
            .expect("send");
        assert!(
            wait_for(|| server.latest("Left").is_some()),
            "first pose never arrived"
        );
        let good = server.latest("Left").expect("pose");
        assert!(
            (good.pose.position - Vec3::new(0.010, 0.020, -0.030)).norm() < 1e-7,
            "mm must become m: {:?}",
            good.pose.position
        );

        // Bad CRC, then a skewed matrix: both refused, the pose holds.
        let mut bad = igtl_codec::encode_transform("Left", 2.0, &r, &Vec3::new(99.0, 0.0, 0.0));
        bad[HEADER_SIZE] ^= 1;
        client.write_all(&bad).expect("send");
        client
            .write_all(&igtl_codec::encode_transform(
                "Left",
                3.0,
                &(r * 2.0),
                &Vec3::zeros(),
            ))
            .expect("send");
        // An unknown message type is skipped without breaking the stream.
        let mut other =
            igtl_codec::encode_transform("X", 4.0, &Matrix3::identity(), &Vec3::zeros());
        other[2..14].copy_from_slice(b"STATUS\0\0\0\0\0\0");
        client.write_all(&other).expect("send");
        client
            .write_all(&igtl_codec::encode_transform(
                "Right",
                5.0,
                &Matrix3::identity(),
                &Vec3::new(1.0, 0.0, 0.0),
            ))
            .expect("send");
        assert!(
            wait_for(|| server.latest("Right").is_some()),
            "stream broke after bad messages"
        );
        let stats = server.stats();
        assert_eq!(
            stats.messages_rejected, 2,
            "CRC and skew must be refused: {stats:?}"
        );
        assert_eq!(
            stats.messages_ignored, 1,
            "STATUS must be skipped: {stats:?}"
        );
        assert_eq!(
            server.latest("Left"),
            Some(good),
            "the last good pose must hold"
        );

        // Force goes back to the client as a SENSOR message.
        assert!(
            wait_for(|| server.send_force("Left", 6.0, [1.0, 2.0, 3.0]) == 1),
            "force not sent"
        );
        client
            .set_read_timeout(Some(Duration::from_secs(5)))
            .expect("timeout");
        let mut msg = [0u8; igtl_codec::FORCE_MESSAGE_SIZE];
        client.read_exact(&mut msg).expect("read force");
        let header = igtl_codec::decode_header(&msg).expect("force header");
        assert_eq!(
            (header.message_type.as_str(), header.device.as_str()),
            ("SENSOR", "Force_Left")
        );
        let (_, values) = igtl_codec::decode_sensor_body(&msg[HEADER_SIZE..]).expect("sensor body");
        assert_eq!(values, vec![1.0, 2.0, 3.0]);

        // A dropped client is noticed, the server keeps its poses.
        drop(client);
        assert!(
            wait_for(|| server.stats().clients_dropped == 1),
            "dropped client not noticed"
        );
        assert_eq!(server.latest("Left"), Some(good));
    }

    #[test]
    fn garbage_header_drops_only_that_client() {
        let server = local_server();
        let mut garbage = TcpStream::connect(server.local_addr()).expect("connect");
        garbage.write_all(&[0xFFu8; 200]).expect("send");
        assert!(
            wait_for(|| server.stats().clients_dropped == 1),
            "corrupt stream must drop its client"
        );
        let mut good = TcpStream::connect(server.local_addr()).expect("connect again");
        good.write_all(&igtl_codec::encode_transform(
            "T",
            1.0,
            &Matrix3::identity(),
            &Vec3::zeros(),
        ))
        .expect("send");
        assert!(
            wait_for(|| server.latest("T").is_some()),
            "server must keep accepting after a bad client"
        );
    }
}
