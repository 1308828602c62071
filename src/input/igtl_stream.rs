//! One OpenIGTLink connection's messages, for the server's clients and the
//! client links alike: read whole, decoded, and handed to the endpoint's pose
//! store ([`super::igtl`]).
//!
//! In: a connected `TcpStream` and who is on the other end ([`Peer`]). Out:
//! each stylus's buttons set its clutch; each pose is mapped (a stylus),
//! checked and published; malformed messages are refused and logged once per
//! connection and kind, counted always. Stays true: nothing a peer sends
//! panics here; a read waits at most 50 ms at a time, so the endpoint's stop
//! flag is seen; a header that cannot be trusted ends the connection (its
//! stream cannot be re-synchronised).

use super::igtl::{Shared, lock, transform_to_pose};
use super::igtl_codec::{self, HEADER_SIZE, IgtlError, RawMessage};
use super::tracker::Refused;
use super::workspace::plus_buttons;
use std::io::{ErrorKind, Read};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

pub(super) fn setup_client(stream: &TcpStream, write_timeout: Duration) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(Duration::from_millis(50)))?;
    stream.set_write_timeout(Some(write_timeout))
}

/// Why reading one message failed.
pub(super) enum ReadOutcome {
    Closed,
    Stopped,
    Io(std::io::Error),
}

/// Fills `buf` completely, retrying on read timeouts until the endpoint stops
/// or, with `idle_limit`, until nothing has come for that long.
fn read_full(stream: &mut TcpStream, buf: &mut [u8], stop: &AtomicBool, idle_limit: Option<Duration>) -> Result<(), ReadOutcome> {
    let mut filled = 0;
    let mut last_byte = Instant::now();
    while filled < buf.len() {
        if stop.load(Ordering::Relaxed) {
            return Err(ReadOutcome::Stopped);
        }
        match stream.read(&mut buf[filled..]) {
            Ok(0) => return Err(ReadOutcome::Closed),
            Ok(n) => {
                filled += n;
                last_byte = Instant::now();
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) =>
            {
                if let Some(limit) = idle_limit
                    && last_byte.elapsed() >= limit
                {
                    let silent = format!("nothing received for {:.1} s", limit.as_secs_f64());
                    return Err(ReadOutcome::Io(std::io::Error::new(ErrorKind::TimedOut, silent)));
                }
            }
            Err(e) => return Err(ReadOutcome::Io(e)),
        }
    }
    Ok(())
}

/// Warn the first time per connection and error kind; count always.
struct RejectLog {
    warned: [bool; 8],
}

impl RejectLog {
    fn report(&mut self, peer: &Peer, error: &IgtlError, shared: &Shared) {
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
            tracing::warn!(%peer, %error, "OpenIGTLink message refused; the last good pose holds (further refusals of this kind are counted, not logged)");
        } else {
            tracing::debug!(%peer, %error, "OpenIGTLink message refused");
        }
    }
}

/// Who sent a message: a client of the server, or a link's remote server.
#[derive(Debug, Clone)]
pub(super) enum Peer {
    /// A client the server accepted, by its number.
    Client(u64),
    /// A remote server, by its address; only these devices are read from it.
    Link { address: String, devices: Vec<String> },
}

impl std::fmt::Display for Peer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Peer::Client(id) => write!(f, "client {id}"),
            Peer::Link { address, .. } => write!(f, "server {address}"),
        }
    }
}

impl Peer {
    /// Whether messages for `device` from this peer are read.
    fn reads(&self, device: &str) -> bool {
        match self {
            Peer::Client(_) => true,
            Peer::Link { devices, .. } => devices.iter().any(|d| d == device),
        }
    }
}

/// Reads messages from `stream` until it closes, fails, falls silent for
/// `idle_limit`, or the endpoint stops; each message goes to [`handle`].
pub(super) fn serve(peer: &Peer, mut stream: TcpStream, shared: &Shared, idle_limit: Option<Duration>) -> ReadOutcome {
    let mut header_bytes = [0u8; HEADER_SIZE];
    let mut body = Vec::new();
    let mut rejects = RejectLog { warned: [false; 8] };
    loop {
        if let Err(outcome) = read_full(&mut stream, &mut header_bytes, &shared.stop, idle_limit) {
            return outcome;
        }
        let header = match igtl_codec::decode_header(&header_bytes) {
            Ok(h) => h,
            Err(e) => {
                // Without a trustworthy body size the stream cannot be re-synchronised.
                rejects.report(peer, &e, shared);
                return ReadOutcome::Io(std::io::Error::new(ErrorKind::InvalidData, e.to_string()));
            }
        };
        body.resize(header.body_size as usize, 0);
        if let Err(outcome) = read_full(&mut stream, &mut body, &shared.stop, idle_limit) {
            return outcome;
        }
        handle(peer, &header, &body, shared, &mut rejects);
    }
}

/// One message: a stylus's buttons set its clutch; a pose is mapped (a
/// stylus), checked and published; anything else is counted and skipped.
fn handle(peer: &Peer, header: &igtl_codec::Header, body: &[u8], shared: &Shared, rejects: &mut RejectLog) {
    let raw = match igtl_codec::decode_body_raw(header, body) {
        Ok(RawMessage::Transform(raw)) if peer.reads(&raw.device) || lock(&shared.poses).is_clutch_device(&raw.device) => raw,
        Ok(RawMessage::Transform(raw)) => {
            shared.stats.messages_ignored.fetch_add(1, Ordering::Relaxed);
            tracing::debug!(%peer, device = %raw.device, "OpenIGTLink TRANSFORM for a device no spatula reads from this peer; ignored");
            return;
        }
        Ok(RawMessage::Other { message_type, device }) => {
            shared.stats.messages_ignored.fetch_add(1, Ordering::Relaxed);
            tracing::debug!(%peer, %message_type, %device, "OpenIGTLink message ignored");
            return;
        }
        Err(e) => return rejects.report(peer, &e, shared),
    };
    {
        let mut poses = lock(&shared.poses);
        if poses.is_clutch_device(&raw.device) {
            poses.buttons(&raw.device, plus_buttons(&raw.matrix));
            shared.stats.buttons_received.fetch_add(1, Ordering::Relaxed);
            return;
        }
    }
    let t = match igtl_codec::validate_rotation(raw) {
        Ok(t) => t,
        Err(e) => return rejects.report(peer, &e, shared),
    };
    let Some(pose) = transform_to_pose(&t) else {
        return rejects.report(peer, &IgtlError::NotOrthonormal { device: t.device.clone(), error: f64::NAN }, shared);
    };
    let offered = lock(&shared.poses).offer(&t.device, pose, t.timestamp_s, Instant::now(), &shared.config);
    match offered {
        Ok(()) => {
            shared.stats.transforms_accepted.fetch_add(1, Ordering::Relaxed);
        }
        Err((why, log_line)) => {
            let counter = match why {
                Refused::OutsideWorkspace { .. } => &shared.stats.poses_outside_workspace,
                Refused::TooFast { .. } => &shared.stats.poses_too_fast,
            };
            counter.fetch_add(1, Ordering::Relaxed);
            match log_line {
                Some(1) => tracing::warn!(%peer, device = %t.device, "OpenIGTLink pose refused: {why}; the last good pose holds"),
                Some(n) => tracing::warn!(%peer, device = %t.device, "OpenIGTLink: {n} poses refused in the last second or more (latest: {why}); the last good pose holds"),
                None => tracing::debug!(%peer, device = %t.device, "OpenIGTLink pose refused: {why}"),
            }
        }
    }
}
