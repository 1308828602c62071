//! The one error every mesh reader and writer returns.
//!
//! In: what went wrong (a [`MeshFileErrorKind`]) and where: the file, a 1-based
//! line for text, a byte offset inside binary blocks. Out: a message that reads
//! `brain.msh:123: node 57 has a non-finite coordinate`.
//! Stays true: a parser never panics on file content; it returns one of these.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::mesh::MeshError;

/// A mesh file could not be read or written.
#[derive(Debug)]
pub struct MeshFileError {
    /// The file concerned.
    pub path: PathBuf,
    /// 1-based line of the problem, where the file is text there.
    pub line: Option<usize>,
    /// Byte offset of the problem inside a binary block (0-based from the file start).
    pub byte_offset: Option<usize>,
    /// What went wrong.
    pub kind: MeshFileErrorKind,
}

/// What went wrong in a mesh file.
#[derive(Debug, thiserror::Error)]
pub enum MeshFileErrorKind {
    #[error("cannot access the file")]
    Io(#[source] std::io::Error),
    /// Not read at all: not a regular file, or over its size cap.
    #[error("{0}")]
    Refused(crate::fsio::Refusal),
    #[error("unknown mesh file extension \"{extension}\" (expected {expected})")]
    UnknownExtension { extension: String, expected: &'static str },
    #[error("unexpected end of file (expected {expected})")]
    UnexpectedEof { expected: String },
    #[error("expected {expected}, found \"{found}\"")]
    Expected { expected: String, found: String },
    #[error("malformed number \"{token}\" ({what})")]
    BadNumber { token: String, what: String },
    #[error("unsupported file format version {version}")]
    UnsupportedVersion { version: String },
    #[error("unsupported element type {element_type}")]
    UnsupportedElementType { element_type: i64 },
    #[error("unsupported: {0}")]
    Unsupported(String),
    #[error("element {element} refers to node {node}, which the file does not define")]
    UnknownNode { element: i64, node: i64 },
    #[error("node {node} is defined twice")]
    DuplicateNode { node: i64 },
    #[error("node {node} has a non-finite coordinate")]
    NonFiniteCoordinate { node: i64 },
    #[error("the header announces {announced} {what} but the file holds {found}")]
    CountMismatch { what: &'static str, announced: u64, found: u64 },
    #[error("{0}")]
    Invalid(String),
    #[error("the file holds no {0}")]
    Empty(&'static str),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("field \"{name}\" has {found} values but the mesh has {expected} {of}")]
    FieldLength { name: String, expected: usize, found: usize, of: &'static str },
    #[error("field name \"{name}\" is empty or holds whitespace or one of <>&\"'")]
    FieldName { name: String },
    #[error("field \"{name}\" has a non-finite value at index {index}")]
    NonFiniteField { name: String, index: usize },
    #[error("XML: {0}")]
    Xml(String),
    /// A `.gz` file whose compressed stream is broken or truncated.
    #[error("not a valid gzip file ({0})")]
    Gzip(String),
    /// A `.gz` file whose content is larger than the cap for its kind.
    #[error("decompresses to more than the {} limit for {what}", crate::fsio::bytes(*cap))]
    Inflated { cap: u64, what: &'static str },
}

impl MeshFileError {
    /// An error at no particular place in `path`.
    pub fn new(path: &Path, kind: MeshFileErrorKind) -> Self {
        Self { path: path.to_path_buf(), line: None, byte_offset: None, kind }
    }

    /// An error at 1-based `line` of `path`.
    pub fn at_line(path: &Path, line: usize, kind: MeshFileErrorKind) -> Self {
        Self { path: path.to_path_buf(), line: Some(line), byte_offset: None, kind }
    }

    /// An error at byte `offset` of a binary block of `path`.
    pub fn at_offset(path: &Path, offset: usize, kind: MeshFileErrorKind) -> Self {
        Self { path: path.to_path_buf(), line: None, byte_offset: Some(offset), kind }
    }

    /// An I/O failure on `path`.
    pub fn io(path: &Path, error: std::io::Error) -> Self {
        Self::new(path, MeshFileErrorKind::Io(error))
    }
}

impl fmt::Display for MeshFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(offset) = self.byte_offset {
            write!(f, ": byte {offset}")?;
        }
        write!(f, ": {}", self.kind)
    }
}

impl std::error::Error for MeshFileError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        std::error::Error::source(&self.kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_path_line_and_problem() {
        let e = MeshFileError::at_line(Path::new("brain.msh"), 123, MeshFileErrorKind::NonFiniteCoordinate { node: 57 });
        assert_eq!(e.to_string(), "brain.msh:123: node 57 has a non-finite coordinate");
        let e = MeshFileError::new(
            Path::new("a.msh"),
            MeshFileErrorKind::UnexpectedEof { expected: "$EndElements".into() },
        );
        assert_eq!(e.to_string(), "a.msh: unexpected end of file (expected $EndElements)");
        let e = MeshFileError::at_offset(Path::new("b.msh"), 40, MeshFileErrorKind::UnsupportedElementType { element_type: 5 });
        assert_eq!(e.to_string(), "b.msh: byte 40: unsupported element type 5");
    }
}
