//! The simulation loop that the window, the headless replay and the tests all drive.
//!
//! In: a validated scenario. Out: a pipeline built from the scene's effects
//! (a stage not asked for is never constructed), stepped at a fixed time step,
//! each stage timed, reporting a [`FrameReport`].

pub mod metrics;
pub mod monitor;
pub mod report;

pub use report::{FrameReport, SpatulaReport, StageId, StageTimes};
