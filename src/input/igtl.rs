//! OpenIGTLink server: receives TRANSFORM messages from trackers, haptic
//! bridges or 3D Slicer and publishes the latest good pose per device name;
//! sends force feedback back to every connected client.
//!
//! In: TCP clients (default `127.0.0.1:18944`), each sending OpenIGTLink
//! messages (header v1 or v2). Out: [`IgtlServer::latest`] (via [`PoseSource`])
//! gives the last good pose of a device, translation converted from millimetres
//! to metres; [`IgtlServer::send_force`] writes the `SENSOR` force message
//! documented in [`super::igtl_codec`]. Stays true: a malformed message (bad CRC,
//! wrong size, NaN, non-orthonormal rotation) is dropped and logged (a warning
//! the first time per client and kind, counted always) and the last good pose
//! holds; a well-formed pose outside the device's workspace or faster than its
//! speed limit ([`TrackerLimits`], see [`super::tracker`]) is refused the same
//! way, counted per reason and logged the first time and then at most once a
//! second per device with the count; a dropped client is logged and its thread
//! ends; nothing here panics on what a client sends. Each client has its own thread; the accept loop runs
//! on another; all stop when the server is dropped.

use super::igtl_codec::{self, HEADER_SIZE, IgtlError, Message};
use super::tracker::{RateLimitedWarning, Refused, TrackerGuard, TrackerLimits};
use super::{PoseSource, TimedPose};
use crate::geometry::Pose;
use crate::math::Quat;
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Default OpenIGTLink port.
pub const DEFAULT_PORT: u16 = 18944;

/// Server settings.
#[derive(Debug, Clone, PartialEq)]
pub struct IgtlConfig {
    /// Address to listen on. Default `127.0.0.1:18944` (loopback only); port 0
    /// picks a free port (see [`IgtlServer::local_addr`]).
    pub bind: SocketAddr,
    /// How long a blocked write of a force message may take before the client
    /// is dropped, ms (1..=1000; default 5).
    pub write_timeout_ms: u64,
    /// Workspace and speed limit of a device `device_limits` does not name
    /// (default: [`TrackerLimits::default`], ±1 m and 3 m/s).
    pub limits: TrackerLimits,
    /// Limits per device name (the scenario's `OpenIgtLink` bindings).
    pub device_limits: Vec<(String, TrackerLimits)>,
}

impl Default for IgtlConfig {
    fn default() -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], DEFAULT_PORT)),
            write_timeout_ms: 5,
            limits: TrackerLimits::default(),
            device_limits: Vec::new(),
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

/// Latest pose per device, kept sorted by name (fixed order, no hashing), and
/// each device's plausibility check.
#[derive(Debug, Default)]
struct PoseSlots {
    slots: Vec<(String, TimedPose)>,
    checks: Vec<(String, DeviceCheck)>,
}

impl PoseSlots {
    /// Publishes `pose` if the device's check accepts it; otherwise returns why,
    /// with `Some(n)` when a log line is due for the `n` refusals since the last.
    fn offer(
        &mut self,
        device: &str,
        pose: Pose,
        timestamp_s: f64,
        arrived: Instant,
        config: &IgtlConfig,
    ) -> Result<(), (Refused, Option<u64>)> {
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

struct Shared {
    config: IgtlConfig,
    poses: Mutex<PoseSlots>,
    writers: Mutex<Vec<(u64, TcpStream)>>,
    stop: AtomicBool,
    stats: IgtlStats,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panicking holder cannot leave these plain containers half-updated in a
    // way that matters; keep serving rather than propagate the poison.
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A running OpenIGTLink server. Dropping it stops its threads.
pub struct IgtlServer {
    shared: Arc<Shared>,
    local_addr: SocketAddr,
    accept_thread: Option<JoinHandle<()>>,
    force_buffer: Vec<u8>,
}

impl IgtlServer {
    /// Binds and starts accepting clients on their own threads.
    pub fn start(config: &IgtlConfig) -> Result<Self, IgtlServerError> {
        let listener = TcpListener::bind(config.bind).map_err(|source| IgtlServerError::Bind {
            addr: config.bind,
            source,
        })?;
        let local_addr = listener
            .local_addr()
            .map_err(|source| IgtlServerError::Configure {
                addr: config.bind,
                source,
            })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| IgtlServerError::Configure {
                addr: local_addr,
                source,
            })?;
        let shared = Arc::new(Shared {
            config: config.clone(),
            poses: Mutex::new(PoseSlots::default()),
            writers: Mutex::new(Vec::new()),
            stop: AtomicBool::new(false),
            stats: IgtlStats::default(),
        });
        let write_timeout = Duration::from_millis(config.write_timeout_ms.clamp(1, 1000));
        let accept_shared = Arc::clone(&shared);
        let accept_thread = std::thread::Builder::new()
            .name("igtl-accept".into())
            .spawn(move || accept_loop(listener, accept_shared, write_timeout))
            .map_err(IgtlServerError::Thread)?;
        tracing::info!(%local_addr, "OpenIGTLink server listening");
        Ok(Self {
            shared,
            local_addr,
            accept_thread: Some(accept_thread),
            force_buffer: Vec::with_capacity(igtl_codec::FORCE_MESSAGE_SIZE),
        })
    }

    /// The address actually bound (useful with port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
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
        }
    }

    /// Sends the force on `spatula` (newtons, world axes) to every connected
    /// client as a `SENSOR` message named `Force_<spatula>`. A client whose
    /// write fails or times out is dropped (logged). Returns how many clients
    /// received it. Allocation-free after the first call.
    pub fn send_force(&mut self, spatula: &str, timestamp_s: f64, force_n: [f64; 3]) -> usize {
        igtl_codec::encode_force(&mut self.force_buffer, spatula, timestamp_s, force_n);
        let mut writers = lock(&self.shared.writers);
        let mut sent = 0;
        let buffer = &self.force_buffer;
        writers.retain_mut(|(id, stream)| match stream.write_all(buffer) {
            Ok(()) => {
                sent += 1;
                true
            }
            Err(e) => {
                tracing::warn!(client = *id, error = %e, "force message not delivered; no more force messages to this client");
                false
            }
        });
        self.shared
            .stats
            .forces_sent
            .fetch_add(sent as u64, Ordering::Relaxed);
        sent
    }
}

impl PoseSource for IgtlServer {
    fn latest(&self, device: &str) -> Option<TimedPose> {
        IgtlServer::latest(self, device)
    }
}

impl Drop for IgtlServer {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for (_, stream) in lock(&self.shared.writers).drain(..) {
            let _ = stream.shutdown(std::net::Shutdown::Both);
        }
        if let Some(handle) = self.accept_thread.take() {
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

fn setup_client(stream: &TcpStream, write_timeout: Duration) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(Duration::from_millis(50)))?;
    stream.set_write_timeout(Some(write_timeout))
}

/// Why reading one message failed.
enum ReadOutcome {
    Closed,
    Stopped,
    Io(std::io::Error),
}

/// Fills `buf` completely, retrying on read timeouts until the server stops.
fn read_full(stream: &mut TcpStream, buf: &mut [u8], stop: &AtomicBool) -> Result<(), ReadOutcome> {
    let mut filled = 0;
    while filled < buf.len() {
        if stop.load(Ordering::Relaxed) {
            return Err(ReadOutcome::Stopped);
        }
        match stream.read(&mut buf[filled..]) {
            Ok(0) => return Err(ReadOutcome::Closed),
            Ok(n) => filled += n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(ReadOutcome::Io(e)),
        }
    }
    Ok(())
}

/// Warn the first time per client and error kind; count always.
struct RejectLog {
    warned: [bool; 8],
}

impl RejectLog {
    fn report(&mut self, client: u64, error: &IgtlError, shared: &Shared) {
        shared
            .stats
            .messages_rejected
            .fetch_add(1, Ordering::Relaxed);
        let kind = match error {
            IgtlError::Truncated { .. } => 0,
            IgtlError::UnsupportedVersion { .. } => 1,
            IgtlError::BodyTooLarge { .. } => 2,
            IgtlError::CrcMismatch { .. } => 3,
            IgtlError::BadExtendedHeader { .. } => 4,
            IgtlError::WrongContentSize { .. } => 5,
            IgtlError::NonFinite { .. } => 6,
            IgtlError::NotOrthonormal { .. } => 7,
        };
        if !self.warned[kind] {
            self.warned[kind] = true;
            tracing::warn!(client, %error, "OpenIGTLink message refused; the last good pose holds (further refusals of this kind are counted, not logged)");
        } else {
            tracing::debug!(client, %error, "OpenIGTLink message refused");
        }
    }
}

fn client_loop(id: u64, mut stream: TcpStream, shared: Arc<Shared>) {
    let mut header_bytes = [0u8; HEADER_SIZE];
    let mut body = Vec::new();
    let mut rejects = RejectLog { warned: [false; 8] };
    let outcome = loop {
        if let Err(outcome) = read_full(&mut stream, &mut header_bytes, &shared.stop) {
            break outcome;
        }
        let header = match igtl_codec::decode_header(&header_bytes) {
            Ok(h) => h,
            Err(e) => {
                // Without a trustworthy body size the stream cannot be re-synchronised.
                rejects.report(id, &e, &shared);
                break ReadOutcome::Io(std::io::Error::new(ErrorKind::InvalidData, e.to_string()));
            }
        };
        body.resize(header.body_size as usize, 0);
        if let Err(outcome) = read_full(&mut stream, &mut body, &shared.stop) {
            break outcome;
        }
        match igtl_codec::decode_body(&header, &body) {
            Ok(Message::Transform(t)) => match transform_to_pose(&t) {
                Some(pose) => {
                    let offered = lock(&shared.poses).offer(&t.device, pose, t.timestamp_s, Instant::now(), &shared.config);
                    match offered {
                        Ok(()) => {
                            shared
                                .stats
                                .transforms_accepted
                                .fetch_add(1, Ordering::Relaxed);
                        }
                        Err((why, log_line)) => {
                            let counter = match why {
                                Refused::OutsideWorkspace { .. } => &shared.stats.poses_outside_workspace,
                                Refused::TooFast { .. } => &shared.stats.poses_too_fast,
                            };
                            counter.fetch_add(1, Ordering::Relaxed);
                            match log_line {
                                Some(1) => tracing::warn!(client = id, device = %t.device, "OpenIGTLink pose refused: {why}; the last good pose holds"),
                                Some(n) => tracing::warn!(client = id, device = %t.device, "OpenIGTLink: {n} poses refused in the last second or more (latest: {why}); the last good pose holds"),
                                None => tracing::debug!(client = id, device = %t.device, "OpenIGTLink pose refused: {why}"),
                            }
                        }
                    }
                }
                None => rejects.report(
                    id,
                    &IgtlError::NotOrthonormal {
                        device: t.device.clone(),
                        error: f64::NAN,
                    },
                    &shared,
                ),
            },
            Ok(Message::Other {
                message_type,
                device,
            }) => {
                shared
                    .stats
                    .messages_ignored
                    .fetch_add(1, Ordering::Relaxed);
                tracing::debug!(client = id, %message_type, %device, "OpenIGTLink message ignored");
            }
            Err(e) => rejects.report(id, &e, &shared),
        }
    };
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
