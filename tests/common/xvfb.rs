//! A private Xvfb display for window tests; ended on drop.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct Xvfb {
    child: Child,
    pub display: String,
}

impl Drop for Xvfb {
    /// SIGTERM first, so the server removes its lock file and socket (a SIGKILL leaves both behind and the
    /// next test to take the number would find a socket nobody answers); SIGKILL if it has not gone in 2 s.
    fn drop(&mut self) {
        if let Ok(pid) = i32::try_from(self.child.id()) {
            // SAFETY: kill(2) on our own child's pid, which has not been reaped yet.
            unsafe { libc::kill(pid, libc::SIGTERM) };
            let deadline = Instant::now() + Duration::from_secs(2);
            while Instant::now() < deadline {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn socket_path(n: u32) -> String {
    format!("/tmp/.X11-unix/X{n}")
}

/// Whether display `n` belongs to a running X server: its lock file names a live process. A lock left by a
/// server that was killed (its process gone) is stale: its lock and socket are removed here, so that the
/// socket the new server makes is the one waited for, and Xvfb takes the number over.
fn display_taken(n: u32) -> bool {
    let lock = format!("/tmp/.X{n}-lock");
    match std::fs::read_to_string(&lock) {
        Ok(pid) => {
            let live = pid.trim().parse::<u32>().map_or(true, |pid| Path::new(&format!("/proc/{pid}")).exists());
            if !live {
                let _ = std::fs::remove_file(socket_path(n));
                let _ = std::fs::remove_file(&lock);
            }
            live
        }
        Err(_) => Path::new(&socket_path(n)).exists(),
    }
}

/// Whether the X server on display `n` answers: a stale socket file refuses the connection.
fn answers(n: u32) -> bool {
    std::os::unix::net::UnixStream::connect(socket_path(n)).is_ok()
}

/// Starts Xvfb on a free display number in `first..first + 50`; None when Xvfb is not installed.
pub fn start_xvfb(first: u32) -> Option<Xvfb> {
    let found = Command::new("sh").args(["-c", "command -v Xvfb"]).output().ok()?;
    if !found.status.success() {
        return None;
    }
    for n in first..first + 50 {
        if display_taken(n) {
            continue;
        }
        let display = format!(":{n}");
        let mut child = Command::new("Xvfb")
            .args([display.as_str(), "-screen", "0", "1280x800x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .ok()?;
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            if answers(n) {
                return Some(Xvfb { child, display });
            }
            if let Ok(Some(_)) = child.try_wait() {
                break; // lost a race for this number: try the next
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = child.kill();
        let _ = child.wait();
    }
    None
}

/// [`start_xvfb`], or `None` after [`super::skip`] when Xvfb is not installed (a failure where every test must run).
pub fn xvfb_or_skip(first: u32) -> Option<Xvfb> {
    let x = start_xvfb(first);
    if x.is_none() {
        super::skip("Xvfb is not installed (apt-get install xvfb)");
    }
    x
}
