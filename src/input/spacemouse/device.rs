//! The SpaceMouse's reader thread: spacenavd's socket when the daemon runs,
//! else the device's `/dev/hidraw*`, reopened whenever either appears.
//!
//! In: [`Sources`] (where the socket and the HID devices are; the system's by
//! default). Out: [`Update`]s on a channel: which device is read, its events,
//! its loss, or why none is read. Stays true: the thread never blocks its
//! owner (it only sends); it checks its stop flag at least every 100 ms; a
//! lost device or daemon is looked for again every [`Sources::retry`]; a HID
//! device it cannot open (permissions) is named in the status with the reason.

use super::decode::{HidDecoder, SPNAV_EVENT_SIZE, SpaceEvent, decode_spnav, is_space_mouse, parse_uevent, socket_from_spnavrc};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::time::Duration;

/// spacenavd's default socket (libspnav `src/spnav.c`, `SPNAV_SOCK_PATH`).
pub const DEFAULT_SPNAV_SOCKET: &str = "/var/run/spnav.sock";

/// Where the thread looks for a SpaceMouse.
#[derive(Debug, Clone, PartialEq)]
pub struct Sources {
    /// spacenavd's Unix socket.
    pub spnav_socket: PathBuf,
    /// The HID devices' class folder (`/sys/class/hidraw`): `NAME/device/uevent` each.
    pub hidraw_class: PathBuf,
    /// Where their device files are (`/dev`): `NAME` each.
    pub dev_dir: PathBuf,
    /// How long to wait before looking again, when nothing was found or the device was lost.
    pub retry: Duration,
}

impl Sources {
    /// The system's: the socket libspnav would use (`SPNAV_SOCKET`, else a
    /// `socket = ` line of `/etc/spnavrc`, else [`DEFAULT_SPNAV_SOCKET`]),
    /// `/sys/class/hidraw`, `/dev`, a retry every second.
    pub fn system() -> Self {
        let socket = std::env::var_os("SPNAV_SOCKET")
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
            .or_else(|| std::fs::read_to_string("/etc/spnavrc").ok().and_then(|t| socket_from_spnavrc(&t)).map(PathBuf::from))
            .unwrap_or_else(|| PathBuf::from(DEFAULT_SPNAV_SOCKET));
        Self { spnav_socket: socket, hidraw_class: PathBuf::from("/sys/class/hidraw"), dev_dir: PathBuf::from("/dev"), retry: Duration::from_secs(1) }
    }
}

/// What the thread tells its owner.
#[derive(Debug, Clone, PartialEq)]
pub enum Update {
    /// A device is read now; the text says which and how (for the panel).
    Connected(String),
    /// One input.
    Event(SpaceEvent),
    /// The device or the daemon went away (the text says why); the cap counts as released.
    Lost(String),
    /// Nothing to read; the text says what was looked for and why it failed.
    Missing(String),
}

/// A 3Dconnexion HID device found under the class folder.
#[derive(Debug, Clone, PartialEq)]
struct Found {
    node: String,
    name: String,
}

/// The 3Dconnexion devices among the HID devices, sorted by node name.
fn space_mice(sources: &Sources) -> Vec<Found> {
    let Ok(entries) = std::fs::read_dir(&sources.hidraw_class) else { return Vec::new() };
    let mut found: Vec<Found> = entries
        .flatten()
        .filter_map(|e| {
            let node = e.file_name().to_string_lossy().into_owned();
            let text = std::fs::read_to_string(e.path().join("device").join("uevent")).ok()?;
            let id = parse_uevent(&text)?;
            is_space_mouse(&id).then(|| Found { name: if id.name.is_empty() { format!("3Dconnexion {:04x}:{:04x}", id.vendor, id.product) } else { id.name }, node })
        })
        .collect();
    found.sort_by(|a, b| a.node.cmp(&b.node));
    found
}

/// Sleeps `wait` in steps of at most 100 ms; false when asked to stop meanwhile.
fn pause(stop: &AtomicBool, wait: Duration) -> bool {
    let until = std::time::Instant::now() + wait;
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let left = until.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            return true;
        }
        std::thread::sleep(left.min(Duration::from_millis(100)));
    }
}

/// The thread's body: until `stop`, read spacenavd, else the HID device,
/// else say what is missing and look again after [`Sources::retry`].
pub fn run(sources: Sources, updates: Sender<Update>, stop: Arc<AtomicBool>) {
    let mut last_missing = String::new();
    while !stop.load(Ordering::Relaxed) {
        // After a device was read and lost, the next miss is news again.
        let spnav = match read_spacenavd(&sources, &updates, &stop) {
            Ok(()) => {
                last_missing.clear();
                continue;
            }
            Err(why) => why,
        };
        let hid = match read_hidraw(&sources, &updates, &stop) {
            Ok(()) => {
                last_missing.clear();
                continue;
            }
            Err(why) => why,
        };
        let missing = format!("no SpaceMouse: {spnav}; {hid}");
        if missing != last_missing {
            last_missing = missing.clone();
            if updates.send(Update::Missing(missing)).is_err() {
                return;
            }
        }
        if !pause(&stop, sources.retry) {
            return;
        }
    }
}

/// Reads spacenavd until it goes away (`Ok`, after a `Lost` update) or says
/// why it cannot be read (`Err`).
#[cfg(unix)]
fn read_spacenavd(sources: &Sources, updates: &Sender<Update>, stop: &AtomicBool) -> Result<(), String> {
    use std::io::Read;
    let socket = &sources.spnav_socket;
    let mut stream = std::os::unix::net::UnixStream::connect(socket).map_err(|e| format!("spacenavd is not running ({}: {e})", socket.display()))?;
    stream.set_read_timeout(Some(Duration::from_millis(100))).map_err(|e| format!("spacenavd's socket {}: {e}", socket.display()))?;
    let connected = match space_mice(sources).first() {
        Some(f) => format!("{} through spacenavd ({})", f.name, socket.display()),
        None => format!(
            "the device spacenavd reads, through spacenavd ({}; no 3Dconnexion USB device in {})",
            socket.display(),
            sources.hidraw_class.display()
        ),
    };
    let _ = updates.send(Update::Connected(connected));
    let mut event = [0u8; SPNAV_EVENT_SIZE];
    let mut filled = 0;
    let reason = loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        match stream.read(&mut event[filled..]) {
            Ok(0) => break "spacenavd closed the connection".to_string(),
            Ok(n) => {
                filled += n;
                if filled == SPNAV_EVENT_SIZE {
                    filled = 0;
                    if let Some(e) = decode_spnav(&event)
                        && updates.send(Update::Event(e)).is_err()
                    {
                        return Ok(());
                    }
                }
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted) => {}
            Err(e) => break format!("spacenavd's socket: {e}"),
        }
    };
    let _ = updates.send(Update::Lost(reason));
    pause(stop, sources.retry);
    Ok(())
}

#[cfg(not(unix))]
fn read_spacenavd(_sources: &Sources, _updates: &Sender<Update>, _stop: &AtomicBool) -> Result<(), String> {
    Err("spacenavd is read on Unix systems only".to_string())
}

/// Reads the first 3Dconnexion HID device that opens until it goes away
/// (`Ok`, after a `Lost` update) or says why none can be read (`Err`).
#[cfg(target_os = "linux")]
fn read_hidraw(sources: &Sources, updates: &Sender<Update>, stop: &AtomicBool) -> Result<(), String> {
    use std::io::Read;
    use std::os::unix::fs::OpenOptionsExt;
    use std::os::unix::io::AsRawFd;
    let found = space_mice(sources);
    if found.is_empty() {
        return Err(format!("no 3Dconnexion HID device in {}", sources.hidraw_class.display()));
    }
    let mut refusals = Vec::new();
    let mut opened = None;
    for f in &found {
        let path = sources.dev_dir.join(&f.node);
        match std::fs::OpenOptions::new().read(true).custom_flags(libc::O_NONBLOCK).open(&path) {
            Ok(file) => {
                opened = Some((file, path, f.name.clone()));
                break;
            }
            Err(e) => refusals.push(format!("{} ({}) cannot be opened: {e}", path.display(), f.name)),
        }
    }
    let Some((mut file, path, name)) = opened else {
        return Err(format!("{} (a udev rule gives your user access, see docs/usage.md)", refusals.join("; ")));
    };
    let _ = updates.send(Update::Connected(format!("{name} ({})", path.display())));
    let mut decoder = HidDecoder::default();
    let mut events = Vec::new();
    let mut report = [0u8; 64];
    let reason = loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        // Wait for a report at most 100 ms, so the stop flag is seen.
        let mut poll = libc::pollfd { fd: file.as_raw_fd(), events: libc::POLLIN, revents: 0 };
        // SAFETY: `poll` points to one valid pollfd for the duration of the call.
        let ready = unsafe { libc::poll(&mut poll, 1, 100) };
        if ready < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            break format!("{}: {e}", path.display());
        }
        if ready == 0 {
            continue;
        }
        if poll.revents & (libc::POLLERR | libc::POLLHUP | libc::POLLNVAL) != 0 && poll.revents & libc::POLLIN == 0 {
            break format!("{} was unplugged", path.display());
        }
        match file.read(&mut report) {
            Ok(0) => break format!("{} was unplugged", path.display()),
            Ok(n) => {
                decoder.report(&report[..n], &mut events);
                for e in events.drain(..) {
                    if updates.send(Update::Event(e)).is_err() {
                        return Ok(());
                    }
                }
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted) => {}
            Err(e) => break format!("{}: {e}", path.display()),
        }
    };
    let _ = updates.send(Update::Lost(reason));
    pause(stop, sources.retry);
    Ok(())
}

#[cfg(not(target_os = "linux"))]
fn read_hidraw(_sources: &Sources, _updates: &Sender<Update>, _stop: &AtomicBool) -> Result<(), String> {
    Err("HID devices are read on Linux only".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hid_devices_are_found_by_their_uevent_only() {
        let dir = tempfile::tempdir().expect("temp dir");
        let class = dir.path().join("class");
        for (node, uevent) in [
            ("hidraw0", "HID_ID=0003:0000046D:0000C31C\nHID_NAME=Logitech USB Keyboard\n"),
            ("hidraw3", "HID_ID=0003:0000256F:0000C635\nHID_NAME=3Dconnexion SpaceMouse Compact\n"),
            ("hidraw1", "HID_ID=0003:0000046D:0000C626\nHID_NAME=3Dconnexion SpaceNavigator\n"),
        ] {
            std::fs::create_dir_all(class.join(node).join("device")).expect("mkdir");
            std::fs::write(class.join(node).join("device").join("uevent"), uevent).expect("write");
        }
        let sources = Sources { spnav_socket: dir.path().join("none.sock"), hidraw_class: class, dev_dir: dir.path().join("dev"), retry: Duration::from_millis(10) };
        let found = space_mice(&sources);
        let names: Vec<(&str, &str)> = found.iter().map(|f| (f.node.as_str(), f.name.as_str())).collect();
        assert_eq!(names, [("hidraw1", "3Dconnexion SpaceNavigator"), ("hidraw3", "3Dconnexion SpaceMouse Compact")]);
    }
}
