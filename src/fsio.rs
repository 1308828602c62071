//! The file system at the program's edges: a path a user names is read only
//! when it is a regular file under a size cap; a final output appears whole or
//! not at all.
//!
//! In: a path and a [`Cap`] ([`read_regular`], [`open_regular`]), or a path and
//! bytes ([`write_atomic`]). Out: the file's bytes (or an open handle), or a
//! [`ReadError`] naming the file; a complete file at the path, or a
//! [`WriteError`] naming the final path with nothing new left beside it.
//! Stays true: a FIFO, a character or block device, a directory or a socket is
//! refused before it is opened for reading (so nothing blocks on a pipe or
//! reads /dev/zero until memory runs out); no read returns more than its cap,
//! even from a file that grows while it is read; `write_atomic` writes to
//! `.<name>.tmp-<pid>` in the same folder, syncs it and renames it over the
//! final name, so the final path never holds a partial or empty file (on a full
//! disk it is absent, or keeps its previous content).
//!
//! Streamed outputs (`metrics.csv`, trajectory recordings) are not written
//! here: they append row by row so an interruption keeps every row so far.

use std::fs::{File, Metadata};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

/// The largest file one kind of input may be, and the words that name the kind
/// in a refusal ("a scenario file").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cap {
    /// Bytes, inclusive.
    pub bytes: u64,
    /// What the file is, for messages: "a mesh file".
    pub what: &'static str,
}

const MIB: u64 = 1 << 20;
const GIB: u64 = 1 << 30;

impl Cap {
    /// Scenario (`.ron`) text: the largest in `config/` is under 10 KiB.
    pub const SCENARIO: Cap = Cap { bytes: 4 * MIB, what: "a scenario file" };
    /// A window input script (`--script`): a line a key press.
    pub const SCRIPT: Cap = Cap { bytes: 4 * MIB, what: "an input script" };
    /// A trajectory CSV: about 100 bytes a row, so some 5 million rows
    /// (a day of two spatulas at 30 Hz).
    pub const TRAJECTORY: Cap = Cap { bytes: 512 * MIB, what: "a trajectory file" };
    /// A tet mesh (`.msh`, `.vtk`, `.vtu`, `.node`/`.ele`): the fine real brain
    /// (`brain_pial_q15.msh`) is 13 MB; 2 GiB of ASCII is some 20 million
    /// tetrahedra, beyond what the solver factors in memory here.
    pub const MESH: Cap = Cap { bytes: 2 * GIB, what: "a mesh file" };
    /// A JSON list of nodes (`fissure solve --fixed / --enforced`): some 40
    /// bytes an entry, so millions of nodes.
    pub const NODE_LIST: Cap = Cap { bytes: 256 * MIB, what: "a node list" };
    /// A triangle surface (`.obj`, `.stl`): the pial surfaces are 1.4 MB.
    pub const SURFACE: Cap = Cap { bytes: GIB, what: "a surface file" };
    /// The compliance cache: its exact size is checked against its header, so
    /// this only bounds a file that is not what it claims.
    pub const COMPLIANCE_CACHE: Cap = Cap { bytes: 256 * GIB, what: "a compliance cache file" };
}

/// Why a file was not read, beyond an ordinary I/O error.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// Not a regular file: `kind` says what it is ("a FIFO (named pipe)").
    #[error("{kind}, not a regular file (refused without reading)")]
    NotRegular { kind: &'static str },
    /// Larger than the cap before reading.
    #[error("{} is over the {} limit for {what}", bytes(*size), bytes(*cap))]
    TooLarge { size: u64, cap: u64, what: &'static str },
    /// Grew past the cap while it was read.
    #[error("grew past the {} limit for {what} while it was read", bytes(*cap))]
    Grew { cap: u64, what: &'static str },
}

/// A file that could not be read; the message names it.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// Refused (not a regular file, too large).
    #[error("{}: {refusal}", path.display())]
    Refused { path: PathBuf, refusal: Refusal },
    /// The file system said no (missing, permissions, ...).
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
}

impl ReadError {
    /// The file concerned.
    pub fn path(&self) -> &Path {
        match self {
            ReadError::Refused { path, .. } | ReadError::Io { path, .. } => path,
        }
    }
}

/// A final output that could not be written; nothing new is left at `path`.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", path.display())]
pub struct WriteError {
    /// The final path (not the temporary one).
    pub path: PathBuf,
    pub source: io::Error,
}

/// `1536` -> `1.5 KiB (1536 bytes)`.
pub(crate) fn bytes(n: u64) -> String {
    let units = [("GiB", GIB), ("MiB", MIB), ("KiB", 1 << 10)];
    match units.iter().find(|(_, u)| n >= *u) {
        Some((name, u)) => format!("{:.1} {name} ({n} bytes)", n as f64 / *u as f64),
        None => format!("{n} bytes"),
    }
}

/// What a non-regular file is, in words.
fn kind_of(meta: &Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a plain file")
}

fn check(path: &Path, meta: &Metadata, cap: Cap) -> Result<u64, ReadError> {
    if let Some(kind) = kind_of(meta) {
        return Err(ReadError::Refused { path: path.to_path_buf(), refusal: Refusal::NotRegular { kind } });
    }
    let size = meta.len();
    if size > cap.bytes {
        return Err(ReadError::Refused { path: path.to_path_buf(), refusal: Refusal::TooLarge { size, cap: cap.bytes, what: cap.what } });
    }
    Ok(size)
}

/// Opens `path` for reading if it is a regular file of at most `cap` bytes;
/// returns the file and its size. The type is checked before opening (through
/// symbolic links) and again on the open handle; on Linux the open itself does
/// not wait for a writer, so a FIFO swapped in between the two checks is still
/// refused, never waited on.
pub fn open_regular(path: &Path, cap: Cap) -> Result<(File, u64), ReadError> {
    let io = |source| ReadError::Io { path: path.to_path_buf(), source };
    check(path, &std::fs::metadata(path).map_err(io)?, cap)?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // Only the open does not block: reads of a regular file are unaffected.
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(io)?;
    let size = check(path, &file.metadata().map_err(io)?, cap)?;
    Ok((file, size))
}

/// Reads the whole of `path` if it is a regular file of at most `cap` bytes
/// (see [`open_regular`]); reads at most `cap + 1` bytes, so a file growing
/// meanwhile is refused rather than read without end.
pub fn read_regular(path: &Path, cap: Cap) -> Result<Vec<u8>, ReadError> {
    let (file, size) = open_regular(path, cap)?;
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(cap.bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|source| ReadError::Io { path: path.to_path_buf(), source })?;
    if bytes.len() as u64 > cap.bytes {
        return Err(ReadError::Refused { path: path.to_path_buf(), refusal: Refusal::Grew { cap: cap.bytes, what: cap.what } });
    }
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text (invalid UTF-8 is an `InvalidData` I/O error, as in `fs::read_to_string`).
pub fn read_regular_text(path: &Path, cap: Cap) -> Result<String, ReadError> {
    let bytes = read_regular(path, cap)?;
    String::from_utf8(bytes).map_err(|e| ReadError::Io {
        path: path.to_path_buf(),
        source: io::Error::new(io::ErrorKind::InvalidData, format!("not valid UTF-8 ({e})")),
    })
}

/// The temporary name [`write_atomic`] uses for `path`: `.<name>.tmp-<pid>` beside it.
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Writes `bytes` to `path` all or nothing: a temporary file in the same folder
/// ([`temp_path`]), `write_all`, `sync_all`, then a rename over `path`. On any
/// error the temporary file is removed and `path` is as it was (absent, or its
/// previous content). A symbolic link at `path` is replaced, not followed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut file = File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        WriteError { path: path.to_path_buf(), source }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_in_binary_units() {
        assert_eq!(bytes(12), "12 bytes");
        assert_eq!(bytes(1536), "1.5 KiB (1536 bytes)");
        assert_eq!(bytes(4 << 20), "4.0 MiB (4194304 bytes)");
    }

    #[test]
    fn a_directory_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_regular(dir.path(), Cap::SCENARIO).expect_err("a directory is no scenario");
        let text = e.to_string();
        assert!(text.contains(&dir.path().display().to_string()) && text.contains("a directory"), "{text}");
    }

    #[test]
    fn the_cap_is_inclusive_and_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ten.txt");
        std::fs::write(&p, b"0123456789").unwrap();
        let cap = |bytes| Cap { bytes, what: "a test file" };
        assert_eq!(read_regular(&p, cap(10)).unwrap(), b"0123456789");
        let e = read_regular(&p, cap(9)).expect_err("one byte over").to_string();
        assert!(e.contains("ten.txt") && e.contains("10 bytes is over the 9 bytes limit for a test file"), "{e}");
    }

    #[test]
    fn write_atomic_replaces_whole_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.json");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["out.json"], "no temporary file is left");
    }

    #[test]
    fn write_atomic_failure_names_the_final_path_and_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        // A directory at the final name: the rename fails after the temp was written.
        let p = dir.path().join("summary.json");
        std::fs::create_dir(&p).unwrap();
        std::fs::write(p.join("keep"), b"x").unwrap();
        let e = write_atomic(&p, b"{}").expect_err("cannot rename over a non-empty directory");
        assert_eq!(e.path, p);
        assert!(e.to_string().contains("summary.json"), "{e}");
        assert!(!temp_path(&p).exists(), "the temporary file is removed");
        // A missing folder: nothing is created.
        let q = dir.path().join("missing/out.csv");
        assert!(write_atomic(&q, b"a").is_err());
        assert!(!q.exists());
    }
}
