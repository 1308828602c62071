//! Scenarios: what a simulation is, read from a RON file in two steps.
//!
//! In: a `.ron` file (human units: `_mm`, `_pa`, `_s`, `_deg` in the field
//! names; see `config/*.ron` and docs/usage.md), and `--set PATH=VALUE` overrides.
//! Step 1 ([`file`]): serde into [`ScenarioFile`] with `deny_unknown_fields`
//! (after the overrides are spliced into the text, [`overrides`]). Step 2
//! ([`validate`]): ranges and cross-field rules, conversion to SI, into a
//! [`Scenario`]. Out: a [`Scenario`] or one [`ScenarioError`] naming the file
//! (or the `--set` argument), line, column, field path and problem.
//! Also here: recorded pose tracks ([`trajectory`]).
//! Stays true: nothing here panics on any input text; a `Scenario` holds only
//! checked, finite SI values. This module reads no mesh and builds no stage.

pub mod devices;
pub mod error;
pub mod file;
pub mod overrides;
pub mod tethers;
pub mod tissue_time;
pub mod trajectory;
pub mod tree;
pub mod validate;

use std::path::Path;

pub use devices::{ForceTransformSettings, IgtlLink, SpaceMouseSettings, StylusMappingSettings};
pub use error::{Location, Origin, ScenarioError};
pub use file::{CollisionBackend, ComplianceStorage, DEFAULT_ROW_BAND_MM, Effect, LengthUnit, ScenarioFile, SpatulaContact, SubstepJitter};
pub use overrides::Document;
pub use tethers::{Band, TetherPoint, Tethers, Vessel, VesselKind};
pub use tissue_time::{Ischemia, Relaxation};
pub use trajectory::{Sample, Trajectory, TrajectoryError, TrajectoryRecorder};
pub use validate::{
    Display, EffectSet, FixedRegion, InputBinding, IntegrityLimits, Material, MeshSource, Outputs, RegionMaterial, RegionOfInterest,
    NamedView, OneEuro, RefineChoice, Refinement, Scenario, Skull, SolverOptions, SpatulaConfig, Sphere, Views, Volume,
};

impl Scenario {
    /// Reads, overrides (`PATH=VALUE` each) and validates a scenario file (a
    /// regular file of at most [`crate::fsio::Cap::SCENARIO`]; anything else is
    /// refused before it is opened).
    pub fn load(path: &Path, overrides: &[String]) -> Result<Scenario, ScenarioError> {
        let text = crate::fsio::read_regular_text(path, crate::fsio::Cap::SCENARIO).map_err(|e| match e {
            crate::fsio::ReadError::Refused { refusal, .. } => ScenarioError::Refused { path: path.to_path_buf(), refusal },
            crate::fsio::ReadError::Io { source, .. } => ScenarioError::Read { path: path.to_path_buf(), io: source },
        })?;
        Self::from_str(&text, path, overrides)
    }

    /// Like [`Scenario::load`] for text already in memory; `origin_path` names
    /// it in errors and anchors its relative paths (its folder).
    pub fn from_str(text: &str, origin_path: &Path, overrides: &[String]) -> Result<Scenario, ScenarioError> {
        let document = Self::parse_document(text, origin_path, overrides)?;
        let file = parse_typed(&document)?;
        Self::validate(file, &document)
    }

    /// Step 1 only, as text: the document with its overrides applied (the file's
    /// syntax is checked first, so a broken file is reported before any override).
    pub fn parse_document(text: &str, origin_path: &Path, overrides: &[String]) -> Result<Document, ScenarioError> {
        let mut document = Document::new(origin_path, text.to_string());
        if !overrides.is_empty() && tree::parse(text).is_err() {
            // Report the file's own syntax error, with ron's message and position.
            parse_typed(&document)?;
        }
        for o in overrides {
            document.apply(o)?;
        }
        Ok(document)
    }
}

/// The serde step on a document's text, with ron's errors mapped to file/argument, line, column and field.
pub fn parse_typed(document: &Document) -> Result<ScenarioFile, ScenarioError> {
    // IMPLICIT_SOME: an optional field may be written `Some(x)` or just `x`
    // (so `--set skull.containing=(...)` can create a field the file left out).
    let options = ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    options.from_str::<ScenarioFile>(&document.text).map_err(|e| {
        // ron's span starts where its cursor was: before the whitespace that
        // precedes the offending token. Point at the token.
        let offset = tree::skip_trivia(&document.text, tree::offset_of(&document.text, e.span.start.line, e.span.start.col));
        ScenarioError::Parse { location: document.locate(offset), field: document.path_at(offset), message: e.code.to_string() }
    })
}
