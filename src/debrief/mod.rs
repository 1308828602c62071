//! `fissure debrief`: a replay's run folder scored and explained for the trainee who made it.
//!
//! In: run folders as `fissure replay` writes them: `metrics.csv` (a row a frame, columns found by name),
//! `summary.json` (scene name, tethers torn and cut, vessels, bands, ischemia, integrity, `interrupted`) and, when
//! the replay wrote one, `surface_dose.csv` (per surface vertex, its pressure-time dose); optionally a reference
//! run (the careful surgeon's trajectory replayed the same way). Out: a [`Debrief`] per run ([`score::debrief`], a
//! pure function of the parsed data), written as `debrief.json` and as one self-contained HTML page
//! ([`page::write_page`]: verdict tables, sentences, the timeline of `fissure plot`, a top view of where pressure
//! was applied). Stays true: every number the page shows is a number of the JSON; a folder that is not a run is
//! refused naming the file that is missing; a run that stopped early or failed its integrity check is debriefed
//! with what it has, and the page says so; a run without `surface_dose.csv` gets no map and the page says why.
//!
//! Beside [`crate::study`] (it draws with the study's plotting and reuses `fissure plot`'s timeline); reads
//! only files, never the simulation.

pub mod page;
pub mod read;
pub mod score;

pub use read::{BladeTrack, DebriefReadError, DoseVertex, RunData, VesselFacts, read_run};
pub use score::{BladeDebrief, Debrief, Metric, PairDebrief, Verdict, debrief};
