//! The desktop simulator around the simulation core: the window (winit + wgpu
//! + egui), the simulation thread, the 1 kHz force output, and the drawing
//! shared with `fissure screenshot` and `replay --frames`.
//!
//! In: a validated scenario, devices (keyboard, mouse, gamepad, SpaceMouse, OpenIGTLink),
//! scripted input for tests. Out: a window, forces at 1 kHz, trajectories,
//! PNGs. Stays true: the simulation thread steps at the scenario's fixed time
//! step and never waits on rendering; the window draws the newest published
//! frame and never waits on the simulation; the simulation core (`sim`,
//! `fem`, `collision`, ...) does not import this module.

pub mod devices;
pub mod draw;
pub mod exchange;
pub mod haptics;
pub mod overlay;
pub mod progress;
pub mod script;
pub mod session_debrief;
pub mod sim_thread;
pub mod stress_worker;
pub mod tethers;
pub mod tissue_time;
pub mod window;
