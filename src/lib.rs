//! fissure: a real-time simulator for opening a brain fissure with two spatulas.
//!
//! Data flows input -> spatula poses -> collision (rays, His-flag culling) ->
//! enforced displacements -> skull constraints -> FEM (exact constrained solve)
//! -> deformed surface, reaction forces -> renderer / replay metrics.
//! See `ARCHITECTURE.md` for the map. The simulation core (`mesh`, `geometry`,
//! `collision`, `fem`, `sim`, `scenario`) never imports `render`, `ui` or `input`;
//! files a user names are read, and final outputs written, through [`fsio`].

pub mod app;
pub mod collision;
pub mod debrief;
pub mod fem;
pub mod fsio;
pub mod geometry;
pub mod input;
pub mod linalg;
pub mod math;
pub mod meminfo;
pub mod par;
pub mod mesh;
pub mod perf;
pub mod render;
pub mod scenario;
pub mod sim;
pub mod study;
pub mod ui;
