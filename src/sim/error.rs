//! The error of building a pipeline, shared by the scene's mesh, the preflight,
//! the build and the replay.
//!
//! In: what went wrong, from the mesh file, the phantom generator, the
//! scenario, a trajectory, the FEM or the collision stage. Out: a [`BuildError`]
//! whose message says which input is at fault (the scenario's file, line,
//! column and field, or the trajectory's file).

use crate::fem;
use crate::scenario::{ScenarioError, TrajectoryError};
use std::path::PathBuf;

/// Errors building a pipeline; each says which input is at fault.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("loading the mesh: {0}")]
    MeshFile(#[from] crate::mesh::io::MeshFileError),
    #[error("generating phantom `{preset}`: {message}")]
    Phantom { preset: String, message: String },
    /// A scenario field that does not fit the mesh or the motion (fixed
    /// nodes, skull at rest, ...): file, line, column and field named.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The trajectory given in place of the scenario's cannot be read (the
    /// message is shown here, so it is not repeated as a cause).
    #[error("--trajectory: {0}")]
    Trajectory(TrajectoryError),
    /// The trajectory given in place of the scenario's has a track for a spatula the scene lacks.
    #[error("--trajectory: {problem}")]
    TrackCount { path: PathBuf, problem: String },
    #[error("scenario `{scenario}`: {message}")]
    Scene { scenario: PathBuf, message: String },
    #[error("FEM: {0}")]
    Fem(#[from] fem::FemError),
    #[error("collision: {0}")]
    Collision(#[from] crate::collision::CollisionError),
}
