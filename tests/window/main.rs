//! The window tests, one module a file, in one test binary. They run one at a
//! time ([`one_at_a_time`]): each measures what the window or the force loop
//! does in real time (frames presented, the background stress worker's
//! frames, a debrief's replays, haptic ticks), which another's load on a
//! two-core machine would starve.

#[path = "../common/mod.rs"]
mod common;

mod haptics;
mod igtl;
mod input;
mod run;

static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Held for the whole of each test of this binary (a failed test's poisoned lock is taken over).
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner())
}
