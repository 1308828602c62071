//! OpenIGTLink as a client: a link to a remote server (a PlusServer streaming a
//! haptic stylus, 3D Slicer's server) whose TRANSFORMs feed the same poses as
//! the server's clients do.
//!
//! In: a [`LinkConfig`] (the server's `host:port` and the device names read
//! from it). Out: the link's messages go through the endpoint's handling
//! ([`super::igtl`]: mapping, plausibility checks, publication), and a
//! [`LinkStatus`] says how the link stands. Stays true: the link runs on its
//! own thread, so a server that is down, slow to answer or silent never holds
//! up a caller; a refused or lost connection is tried again after a wait that
//! doubles from [`Backoff::first_ms`] up to [`Backoff::max_ms`] and starts over
//! once a connection is made (a restarted server is back within the first
//! wait); a connection on which nothing arrives for [`IDLE_LIMIT`] is taken as
//! lost (a PlusServer sends a keep-alive `STATUS` every 0.25 s even without
//! data: PlusLib `vtkPlusOpenIGTLinkServer`, `KeepAliveIntervalSec`); each new
//! connection re-anchors the link's mapped styluses, so the blade does not jump
//! to wherever the stylus was moved while the link was down.

use super::igtl::{Shared, lock};
use super::igtl_stream::{Peer, ReadOutcome, serve, setup_client};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// A connection on which nothing arrives this long is given up and made again.
pub const IDLE_LIMIT: Duration = Duration::from_secs(5);
/// How long one connection attempt may take.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);

/// One remote server.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkConfig {
    /// `host:port` (a name is resolved on the link's thread at each attempt).
    pub address: String,
    /// The device names read from this server (poses and a stylus's buttons);
    /// its other TRANSFORMs are counted as ignored.
    pub devices: Vec<String>,
}

/// The wait between connection attempts: `first_ms`, doubled after each
/// failure up to `max_ms`, back to `first_ms` after a connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    /// The first wait, ms (default 250).
    pub first_ms: u64,
    /// The longest wait, ms (default 4000).
    pub max_ms: u64,
}

impl Default for Backoff {
    fn default() -> Self {
        Self { first_ms: 250, max_ms: 4000 }
    }
}

impl Backoff {
    /// The wait after `wait_ms`.
    pub fn next(&self, wait_ms: u64) -> u64 {
        wait_ms.saturating_mul(2).clamp(self.first_ms.max(1), self.max_ms.max(self.first_ms).max(1))
    }
}

/// Where a link stands.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkState {
    /// Not yet tried, or trying now.
    Connecting,
    /// Connected; messages are read.
    Connected,
    /// The last attempt failed; the next comes after `retry_in_s`.
    Unreachable { error: String, retry_in_s: f64 },
    /// The connection was lost; the next attempt comes after `retry_in_s`.
    Lost { reason: String, retry_in_s: f64 },
}

/// A link's state, for the status line and the tests.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkStatus {
    /// The server's `host:port`.
    pub address: String,
    /// Where it stands.
    pub state: LinkState,
    /// Connections made so far.
    pub connections: u64,
}

impl LinkStatus {
    pub fn new(address: &str) -> Self {
        Self { address: address.to_string(), state: LinkState::Connecting, connections: 0 }
    }

    /// Whether the link is connected now.
    pub fn connected(&self) -> bool {
        self.state == LinkState::Connected
    }
}

impl std::fmt::Display for LinkStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let address = &self.address;
        match &self.state {
            LinkState::Connecting => write!(f, "OpenIGTLink {address}: connecting"),
            LinkState::Connected => write!(f, "OpenIGTLink {address}: connected"),
            LinkState::Unreachable { error, retry_in_s } => {
                write!(f, "OpenIGTLink {address}: cannot connect ({error}); trying again every {retry_in_s:.1} s or less, the blade holds")
            }
            LinkState::Lost { reason, retry_in_s } => {
                write!(f, "OpenIGTLink {address}: connection lost ({reason}); reconnecting in {retry_in_s:.1} s, the blade holds")
            }
        }
    }
}

fn set_state(shared: &Shared, index: usize, state: LinkState) {
    if let Some(status) = lock(&shared.links).get_mut(index)
        && status.state != state
    {
        if state == LinkState::Connected {
            status.connections += 1;
        }
        status.state = state;
        shared.link_changes.fetch_add(1, Ordering::Relaxed);
    }
}

/// Connects to the first address `address` resolves to that answers.
fn connect(address: &str) -> std::io::Result<TcpStream> {
    let mut last = std::io::Error::new(std::io::ErrorKind::NotFound, "the name resolves to no address");
    for addr in address.to_socket_addrs()? {
        match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
            Ok(stream) => return Ok(stream),
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Sleeps `wait` in short steps; false when the endpoint stops meanwhile.
fn pause(shared: &Shared, wait: Duration) -> bool {
    let until = Instant::now() + wait;
    while Instant::now() < until {
        if shared.stop.load(Ordering::Relaxed) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(10).min(until.saturating_duration_since(Instant::now())));
    }
    !shared.stop.load(Ordering::Relaxed)
}

/// The link's thread: connect, read until lost, wait, again; until the endpoint stops.
pub(super) fn run(index: usize, shared: std::sync::Arc<Shared>, write_timeout: Duration) {
    let Some(link) = shared.config.links.get(index).cloned() else { return };
    let backoff = shared.config.backoff;
    let peer = Peer::Link { address: link.address.clone(), devices: link.devices.clone() };
    let mut wait_ms = backoff.first_ms.max(1);
    // One warning per outage: the first failed attempt after a connection (or at the start).
    let mut warned = false;
    while !shared.stop.load(Ordering::Relaxed) {
        set_state(&shared, index, LinkState::Connecting);
        let failure = match connect(&link.address).and_then(|s| setup_client(&s, write_timeout).map(|()| s)) {
            Ok(stream) => {
                wait_ms = backoff.first_ms.max(1);
                warned = false;
                lock(&shared.poses).reanchor(&link.devices);
                shared.stats.links_connected.fetch_add(1, Ordering::Relaxed);
                set_state(&shared, index, LinkState::Connected);
                tracing::info!(server = %link.address, "OpenIGTLink: connected");
                let outcome = serve(&peer, stream, &shared, Some(IDLE_LIMIT));
                // The buttons' state is unknown until they are heard again.
                lock(&shared.poses).reanchor(&link.devices);
                let reason = match outcome {
                    ReadOutcome::Stopped => break,
                    ReadOutcome::Closed => "closed by the server".to_string(),
                    ReadOutcome::Io(e) => e.to_string(),
                };
                tracing::warn!(server = %link.address, %reason, "OpenIGTLink: connection lost; reconnecting");
                LinkState::Lost { reason, retry_in_s: wait_ms as f64 * 1e-3 }
            }
            Err(e) => {
                if warned {
                    tracing::debug!(server = %link.address, error = %e, "OpenIGTLink: cannot connect");
                } else {
                    warned = true;
                    tracing::warn!(server = %link.address, error = %e, "OpenIGTLink: cannot connect; trying again with backoff (further failures are not logged until it connects)");
                }
                LinkState::Unreachable { error: e.to_string(), retry_in_s: wait_ms as f64 * 1e-3 }
            }
        };
        set_state(&shared, index, failure);
        if !pause(&shared, Duration::from_millis(wait_ms)) {
            break;
        }
        wait_ms = backoff.next(wait_ms);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_to_its_cap() {
        let b = Backoff { first_ms: 250, max_ms: 4000 };
        let mut w = b.first_ms;
        let mut waits = vec![w];
        for _ in 0..6 {
            w = b.next(w);
            waits.push(w);
        }
        assert_eq!(waits, [250, 500, 1000, 2000, 4000, 4000, 4000]);
        assert_eq!(Backoff { first_ms: 0, max_ms: 0 }.next(0), 1, "never a zero wait (a busy loop)");
    }

    #[test]
    fn the_status_line_says_what_the_link_does() {
        let mut s = LinkStatus::new("127.0.0.1:18944");
        assert_eq!(s.to_string(), "OpenIGTLink 127.0.0.1:18944: connecting");
        s.state = LinkState::Unreachable { error: "Connection refused (os error 111)".into(), retry_in_s: 0.5 };
        assert!(s.to_string().contains("cannot connect (Connection refused (os error 111))"), "{s}");
        s.state = LinkState::Connected;
        assert!(s.connected());
    }
}
