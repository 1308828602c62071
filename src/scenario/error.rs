//! Scenario errors: each names where the problem is (the file with line and
//! column, or the `--set` argument), the field path, and the problem.
//!
//! In: positions from the RON outline and from `ron`'s own errors. Out: one
//! [`ScenarioError`] whose `Display` reads
//! `config/sylvian.ron:12:22: material.poisson_ratio: poisson_ratio must be in [0, 0.5), got 0.5`;
//! a [`ScenarioWarning`] reads the same way.

use std::fmt;
use std::path::PathBuf;

/// Where a piece of scenario text came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// The scenario file (as the user named it).
    File(PathBuf),
    /// A `--set PATH=VALUE` argument, verbatim.
    Override(String),
}

/// A position in a scenario: origin, 1-based line and column (chars).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// File or `--set` argument.
    pub origin: Origin,
    /// 1-based line (always 1 for a `--set` argument).
    pub line: usize,
    /// 1-based column in characters.
    pub column: usize,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.origin {
            Origin::File(p) => write!(f, "{}:{}:{}", p.display(), self.line, self.column),
            Origin::Override(arg) => write!(f, "--set {arg} (column {})", self.column),
        }
    }
}

/// Everything that can be wrong with a scenario.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The scenario file could not be read.
    #[error("cannot read scenario file {}: {io}", path.display())]
    Read {
        /// The path as given.
        path: PathBuf,
        /// The I/O error (shown in the message, so not repeated as a cause).
        io: std::io::Error,
    },
    /// The scenario path is not a regular file, or is over [`crate::fsio::Cap::SCENARIO`]; nothing was read.
    #[error("cannot read scenario file {}: {refusal}", path.display())]
    Refused {
        /// The path as given.
        path: PathBuf,
        /// Why.
        refusal: crate::fsio::Refusal,
    },
    /// RON syntax, a wrong type, an unknown or missing field (from the typed parse).
    #[error("{location}: {}{message}", field_prefix(field))]
    Parse {
        /// Where.
        location: Location,
        /// Field path, when the position lies inside a field (`spatulas[0].shape`).
        field: String,
        /// `ron`'s message.
        message: String,
    },
    /// A value out of range or inconsistent with the rest of the scene.
    #[error("{location}: {field}: {problem}")]
    Invalid {
        /// Where (the field's value, or the nearest enclosing one that exists).
        location: Location,
        /// Field path (`spatulas[1].shape.thickness_mm`).
        field: String,
        /// What is wrong, with the value found.
        problem: String,
    },
    /// A `--set` argument that cannot be applied.
    #[error("--set {argument}: {problem}")]
    Override {
        /// The argument verbatim.
        argument: String,
        /// What is wrong (malformed, unknown path with the keys valid there, ...).
        problem: String,
    },
}

/// Something a scenario may say but probably should not (a value inside its
/// range but near a limit of the method): reported, never refused. `Display`
/// reads like an error: `config/x.ron:16:52: material.poisson_ratio: ...`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioWarning {
    /// Where (the field's value).
    pub location: Location,
    /// Field path (`material.poisson_ratio`).
    pub field: String,
    /// What is doubtful and why, with the value found.
    pub message: String,
}

impl fmt::Display for ScenarioWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}: {}", self.location, self.field, self.message)
    }
}

/// Positions of the fields that checks after validation (those that need the
/// mesh or the played trajectory, `sim::preflight`) name in their errors.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FieldLocations {
    entries: Vec<(String, Location)>,
}

impl FieldLocations {
    /// Records where `field` is.
    pub fn insert(&mut self, field: &str, location: Location) {
        self.entries.push((field.to_string(), location));
    }

    /// Where `field` is: its own entry, else the nearest recorded enclosing
    /// field (`skull.containing` for `skull.containing.radius_mm`), else `None`.
    pub fn get(&self, field: &str) -> Option<&Location> {
        let mut path = field;
        loop {
            if let Some((_, l)) = self.entries.iter().find(|(f, _)| f == path) {
                return Some(l);
            }
            path = &path[..path.rfind(['.', '['])?];
        }
    }
}

fn field_prefix(field: &str) -> String {
    if field.is_empty() { String::new() } else { format!("{field}: ") }
}

impl ScenarioError {
    /// The field path the error is about, when there is one.
    pub fn field(&self) -> Option<&str> {
        match self {
            ScenarioError::Parse { field, .. } | ScenarioError::Invalid { field, .. } => Some(field),
            _ => None,
        }
    }

    /// The location the error is about, when there is one.
    pub fn location(&self) -> Option<&Location> {
        match self {
            ScenarioError::Parse { location, .. } | ScenarioError::Invalid { location, .. } => Some(location),
            _ => None,
        }
    }
}
