//! A private Xvfb display for window tests; killed on drop.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct Xvfb {
    child: Child,
    pub display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Whether display `n` belongs to a running X server: its lock file names a live process. A lock left by a
/// server that was killed (its process gone) is stale, and Xvfb takes the number over.
fn display_taken(n: u32) -> bool {
    match std::fs::read_to_string(format!("/tmp/.X{n}-lock")) {
        Ok(pid) => pid.trim().parse::<u32>().map_or(true, |pid| Path::new(&format!("/proc/{pid}")).exists()),
        Err(_) => Path::new(&format!("/tmp/.X11-unix/X{n}")).exists(),
    }
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
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
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
