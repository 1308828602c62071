//! The simulation loop that the window, the headless replay and the tests all drive.
//!
//! In: a validated scenario. Out: a [`Pipeline`] built from the scene's effects
//! (a stage not asked for is never constructed), stepped at a fixed time step by
//! [`Pipeline::step`], each stage timed, reporting a [`FrameReport`].

pub mod barrier;
pub mod build;
pub mod contact;
pub mod error;
pub mod metrics;
pub mod monitor;
pub mod pipeline;
pub mod pose_filter;
pub mod poses;
pub mod preflight;
pub mod replay;
pub mod report;
pub mod rest_grid;
pub mod scene_mesh;
pub mod substeps;
pub mod surface_sync;
pub mod tethers;
pub mod tissue_time;

pub use build::BuildOptions;
pub use error::BuildError;
pub use pipeline::{FrameInput, Pipeline, SimState, SkullStage, StepError};
pub use substeps::{MAX_SUBSTEPS, SUBSTEP_TRAVEL_FRACTION, substep_count};
pub use preflight::{Preflight, preflight};
pub use report::{FrameReport, SpatulaReport, StageId, StageTimes};
