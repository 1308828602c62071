//! The compliance's cache files: the key that names one, writing them whole (a temporary file renamed over the
//! old one), reading them back with their checksums, and keeping the folder under its budget.
//!
//! A file is used only when its key (blake3 of the model's fingerprint, the factor's ordering, the ROI, the
//! storage) matches, each batch only when its own checksum does. Stays true: a reader never sees half a file;
//! failing to write one loses nothing computed, so it is no error.

use super::fill::{Dense, Fill};
use super::{CACHE_VERSION, ComplianceStorage, Layout};
use crate::fem::FemError;
use crate::fem::model::FemModel;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes a dense cache file ([`write_file`]): header, row nodes, the batch table (count, first columns, one blake3
/// a batch over its entries then its corrections), the blake3 of all that, then the entries and the corrections.
/// A reader checks the table once and each batch as it reads it, so a corrupt batch costs only its own columns.
///
/// # Safety
/// Every batch is final.
pub(super) unsafe fn write_dense_cache<T: bytemuck::Pod>(path: &Path, header: &[u8], row_nodes: &[u32], layout: &Layout, fill: &Fill, d: &Dense<T>) -> Result<(), FemError> {
    // SAFETY: the caller's promise.
    let (v, lo) = unsafe { d.all() };
    let (v, lo): (&[u8], &[u8]) = (bytemuck::cast_slice(v), bytemuck::cast_slice(lo));
    let width = std::mem::size_of::<T>();
    let n_batches = fill.batch_count();
    let mut table: Vec<u8> = Vec::with_capacity(8 + 40 * n_batches + 32);
    table.extend_from_slice(&(n_batches as u64).to_le_bytes());
    for b in 0..n_batches {
        table.extend_from_slice(&(fill.batch(b).start as u64).to_le_bytes());
    }
    for b in 0..n_batches {
        let cols = fill.batch(b);
        let mut h = blake3::Hasher::new();
        h.update(&v[9 * width * layout.col_off[cols.start]..9 * width * layout.col_off[cols.end]]);
        if !lo.is_empty() {
            h.update(&lo[18 * layout.lo_off[cols.start]..18 * layout.lo_off[cols.end]]);
        }
        table.extend_from_slice(h.finalize().as_bytes());
    }
    let mut meta = blake3::Hasher::new();
    meta.update(header);
    meta.update(bytemuck::cast_slice(row_nodes));
    meta.update(&table);
    table.extend_from_slice(meta.finalize().as_bytes());
    write_file(path, &[header, bytemuck::cast_slice(row_nodes), &table, v, lo])
}

/// A dense cache file whose header, rows and batch table matched; its batches are read as the columns fill.
#[derive(Debug)]
pub(super) struct CacheSource {
    pub(super) file: std::fs::File,
    pub(super) path: PathBuf,
    /// Per batch: blake3 of its entries' bytes, then its corrections' bytes.
    pub(super) sums: Vec<[u8; 32]>,
    /// File offsets of the entries and of the corrections.
    pub(super) v_at: u64,
    pub(super) lo_at: u64,
    /// Bytes an entry.
    pub(super) width: usize,
    /// Set at the first batch that fails its check (warned once).
    pub(super) failed: std::sync::atomic::AtomicBool,
}

/// Fills `buf` from `file` at byte `at` without moving a shared cursor (the filling threads read at once).
pub(super) fn read_at(file: &std::fs::File, buf: &mut [u8], at: u64) -> std::io::Result<()> {
    if buf.is_empty() {
        return Ok(());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        file.read_exact_at(buf, at)
    }
    #[cfg(windows)]
    {
        use std::os::windows::fs::FileExt;
        let (mut done, mut at) = (0, at);
        while done < buf.len() {
            match file.seek_read(&mut buf[done..], at)? {
                0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
                n => {
                    done += n;
                    at += n as u64;
                }
            }
        }
        Ok(())
    }
    #[cfg(not(any(unix, windows)))]
    {
        let _ = (file, at);
        Err(std::io::Error::new(std::io::ErrorKind::Unsupported, "positioned reads"))
    }
}

/// After a cache file was written, prunes the folder; after a failure, removes the half-written file and warns.
pub(super) fn finish_write(path: &Path, written: Result<(), FemError>) {
    match written {
        Ok(()) => prune_cache_dir(path, CACHE_DIR_BUDGET_BYTES),
        Err(e) => {
            let _ = std::fs::remove_file(tmp_path(path));
            tracing::warn!("{e}; the compliance is used without a cache");
        }
    }
}

/// Marks a cache file as just used (most recently used first when the folder is pruned).
pub(super) fn mark_used(path: &Path) {
    if let Err(e) = std::fs::File::options().append(true).open(path).and_then(|f| f.set_modified(std::time::SystemTime::now())) {
        tracing::debug!("compliance cache {}: could not mark as used ({e})", path.display());
    }
}

/// Writes `parts` in turn into a temporary file renamed to `path` at the end, so a reader never sees half a file.
pub(super) fn write_file(path: &Path, parts: &[&[u8]]) -> Result<(), FemError> {
    let err = |e: std::io::Error| FemError::Cache { path: path.to_path_buf(), reason: e.to_string() };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let tmp = tmp_path(path);
    let file = std::fs::File::create(&tmp).map_err(err)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 22, file);
    for bytes in parts {
        w.write_all(bytes).map_err(err)?;
    }
    w.flush().map_err(err)?;
    drop(w);
    std::fs::rename(&tmp, path).map_err(err)?;
    Ok(())
}

/// `rows`: the other rows when not every surface node's (in stored order).
pub(super) fn cache_key(model: &FemModel, roi: &[u32], storage: ComplianceStorage, rows: Option<&[u32]>) -> [u8; 32] {
    let mut h = blake3::Hasher::new();
    h.update(b"fissure-compliance");
    h.update(&CACHE_VERSION.to_le_bytes());
    h.update(&model.fingerprint);
    // The ordering moves the last bits of every column, and a cache must give a fresh precompute's bits. The
    // ordering asked for (`Best` resolves as a fixed function of the matrix), so the key is known before the factor.
    h.update(format!("{:?}", model.chol.requested).as_bytes());
    h.update(&(roi.len() as u64).to_le_bytes());
    h.update(bytemuck::cast_slice(roi));
    h.update(&storage.code()[..1]);
    if let Some(rows) = rows {
        h.update(b"rows");
        h.update(&(rows.len() as u64).to_le_bytes());
        h.update(bytemuck::cast_slice(rows));
    }
    *h.finalize().as_bytes()
}

pub(super) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A cache directory keeps its compliance files under this many bytes: after a new file is written, the least
/// recently used others (modification time; a load marks a file used) are removed until the rest fit.
pub const CACHE_DIR_BUDGET_BYTES: u64 = 4 << 30;
/// Half-written files (`compliance-*.tmp<pid>`, left by a run that died) older than this are pruned.
pub(super) const STALE_TMP_SECS: u64 = 3600;

/// The file a cache is written to before it is renamed into place.
pub(super) fn tmp_path(path: &Path) -> PathBuf {
    path.with_extension(format!("tmp{}", std::process::id()))
}

/// Removes the least recently used compliance files of `kept`'s directory until those left (with `kept`, which
/// always stays) fit in `budget` bytes, and stale half-written files; only `compliance-*`, failures only logged.
pub fn prune_cache_dir(kept: &Path, budget: u64) {
    let Some(dir) = kept.parent() else { return };
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let now = std::time::SystemTime::now();
    let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = Vec::new();
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let Ok(meta) = entry.metadata() else { continue };
        if !meta.is_file() || !name.starts_with("compliance-") {
            continue;
        }
        let modified = meta.modified().unwrap_or(std::time::UNIX_EPOCH);
        let is_tmp = path.extension().is_some_and(|e| e.to_string_lossy().starts_with("tmp"));
        if is_tmp {
            let old = now.duration_since(modified).is_ok_and(|age| age.as_secs() > STALE_TMP_SECS);
            if old && let Err(e) = std::fs::remove_file(&path) {
                tracing::warn!("compliance cache: could not remove stale {} ({e})", path.display());
            }
            continue;
        }
        if path.extension().is_some_and(|e| e == "bin") && path != kept {
            files.push((modified, meta.len(), path));
        }
    }
    let mut used = std::fs::metadata(kept).map(|m| m.len()).unwrap_or(0);
    // newest first; ties by path, so the choice does not depend on directory order
    files.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.2.cmp(&b.2)));
    for (_, len, path) in files {
        if used + len <= budget {
            used += len;
            continue;
        }
        match std::fs::remove_file(&path) {
            Ok(()) => tracing::info!("compliance cache: removed least recently used {} ({} MB) to stay under {} MB", path.display(), len >> 20, budget >> 20),
            Err(e) => tracing::warn!("compliance cache: could not remove {} ({e})", path.display()),
        }
    }
}
