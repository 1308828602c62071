//! Precomputed compliance: `K^-1` restricted to the surface (rows) and a region of interest (columns), stored once
//! per model and reused every frame.
//!
//! In: a [`FemModel`], the ROI nodes, a storage precision, an optional cache folder. Out: a [`Compliance`] that
//! returns the 3x3 block `K^-1[node_i, node_j]` for a surface (or ROI) node i and a ROI node j, and accumulates
//! `u_rows += K^-1[rows, cols] F` for a few nodal forces.
//!
//! Layout (`Layout`): rows are the free ROI nodes, then the other free surface nodes, each group by free
//! component (bodies `K` does not couple), then Morton order; columns are the ROI nodes. Only blocks with row >=
//! column within one component are stored, column after column, each 3x3 block column-major; a ROI x ROI block
//! above the diagonal is the transpose of its mirror.
//! Stays true: entries are `K^-1` to round-off (f64) or rounded once to f32; ROI x ROI blocks are exactly symmetric
//! in both storages; a cache file is used only when its key matches, each batch only when its checksum does (a
//! batch that does not is computed and the file rewritten; see `cache`).
//!
//! Precompute here and in `fill` (batches of columns, on every core or in the background); cache files in `cache`;
//! the per-frame surface product in `product`.

mod cache;
mod fill;
mod product;
mod projected;

use super::FemError;
use super::assembly::{find, join};
use super::model::FemModel;
use crate::math::{Matrix3, Vec3};
use std::io::Read;
use fill::{Buf, Dense, Fill, FillOwner};
pub use cache::{CACHE_DIR_BUDGET_BYTES, prune_cache_dir};
use cache::{CacheSource, cache_key, finish_write, hex, mark_used, read_at, write_dense_cache};
pub use product::ProductWorkspace;
pub use projected::PROJECTIONS_PER_CALL;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

const NO_ROW: u32 = u32::MAX;
const CACHE_MAGIC: &[u8; 8] = b"FISSCOMP";
const CACHE_VERSION: u32 = 8;
/// ROI nodes solved together (3 right-hand sides each). 64 rather than 32: the substitutions' dense kernels run on
/// rows twice as long, a user's fine-brain Sylvian scene's precompute 0.4 s shorter (of about 6) for 50 MB more
/// scratch, and the same values (each right-hand side's entries are summed in the same order in either batch).
const BATCH_NODES: usize = 64;
/// Stored rows written at a time from a solved batch (96 of its row-major rows: 144 KiB, in a core's cache).
const FILL_ROW_BLOCK: usize = 32;
/// Bytes the precompute's right-hand sides may take over all its threads.
const PRECOMPUTE_RHS_BUDGET: usize = 1 << 30;
/// Rows of one chunk of the surface product (9 f64 partials a row: 36 KiB, a multiple of 8 rows).
const ROW_CHUNK: usize = 512;

/// Precision of the stored compliance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum ComplianceStorage {
    /// 8 bytes an entry; the fast path matches a direct solve to about 1e-12.
    F64,
    /// 4 bytes an entry for the surface product, plus 2 bytes of correction on each ROI x ROI entry (those `W` is
    /// gathered from, where f32 rounding times cond(W) would spoil the reactions), so `W` is exact to about 1e-12;
    /// the surface displacement carries the f32 rounding (about 1e-6 relative). See `tests/suite/fem_fast_path.rs`.
    F32,
}

impl ComplianceStorage {
    /// Bytes 12 and 13 of the cache header and part of the cache key.
    fn code(self) -> [u8; 2] {
        match self {
            ComplianceStorage::F64 => [8, 0],
            ComplianceStorage::F32 => [4, 0],
        }
    }
}

#[derive(Debug, Clone)]
enum Values {
    F64(Arc<Dense<f64>>),
    /// f32 entries and, for the ROI x ROI entries ([`Layout::lo_offset`]), the rest `x - f32(x)` ([`split_f32`]).
    F32(Arc<Dense<f32>>),
}

/// How [`Compliance::compute_with`] orders, fills and caches the columns.
#[derive(Debug, Clone, Copy)]
pub struct ComputeOptions<'a> {
    pub storage: ComplianceStorage,
    /// Folder of the disk cache; `None`: no cache.
    pub cache_dir: Option<&'a Path>,
    /// Dense storage: per mesh node, how soon a tool reaches it (lower: sooner). Each free component's ROI columns
    /// are ordered by it (Morton among equals) and solved in that order, in batches within one component, so the
    /// columns a frame needs first are final first. `None`: Morton order. Part of the cache key.
    pub reach: Option<&'a [u32]>,
    /// Dense storage: return once the storage is allocated (and the cache's batch table checked), and read or solve
    /// the columns on lower-priority background threads. Reading a column not yet final waits for it; the values
    /// are bit for bit those of a build that waits.
    pub background: bool,
    /// The surface nodes stored as rows besides the ROI's (the working region); `None`: every free surface node.
    /// Part of the cache key. A surface node without a row is updated by a sparse solve where something reads it
    /// ([`crate::fem::ConstrainedSolver::track`], `whole_surface`).
    pub rows: Option<&'a [u32]>,
}

impl ComputeOptions<'_> {
    /// Morton order, no cache, built before returning, every surface row.
    pub fn new(storage: ComplianceStorage) -> Self {
        Self { storage, cache_dir: None, reach: None, background: false, rows: None }
    }
}

/// What building or loading the compliance cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ComplianceStats {
    /// Seconds to compute (0 when loaded) and to load (0 when computed).
    pub compute_seconds: f64,
    pub load_seconds: f64,
    /// Bytes of stored entries.
    pub bytes: usize,
    /// True when the entries came from the disk cache.
    pub from_cache: bool,
    /// Stored rows (surface + ROI nodes) and columns (ROI nodes).
    pub rows: usize,
    pub cols: usize,
}

/// `K^-1` over (surface ∪ ROI) x ROI nodes, symmetric storage.
#[derive(Debug, Clone)]
pub struct Compliance {
    values: Values,
    /// Dense storage filled in the background: which columns are final (`None`: all).
    fill: Option<Arc<FillOwner>>,
    row_nodes: Vec<u32>,
    n_cols: usize,
    /// Which rows each column stores.
    layout: Arc<Layout>,
    node_row: Vec<u32>,
    key: [u8; 32],
    model_fingerprint: [u8; 32],
    stats: ComplianceStats,
}

/// Which rows of a column dense storage holds. `K` couples only nodes joined by a chain of tets through free nodes,
/// so `K^-1` is block diagonal over the components of the free-node graph; a block between components is exactly
/// zero and not stored. Rows are grouped by component (ROI rows of component 0, 1, ..., then the other rows
/// likewise), so column `j` of component `k` stores two runs: ROI rows `j..roi_end(k)` and the other rows of `k`.
/// With one component this is the packed lower triangle (`offset(j) = j n - j (j-1) / 2`).
#[derive(Debug, Clone, Default)]
struct Layout {
    /// Component of each row (0.. in the order the rows are grouped).
    row_comp: Vec<u32>,
    /// Per component: ROI rows `[s[0], s[1])`, other rows `[s[2], s[3])`.
    spans: Vec<[usize; 4]>,
    /// Per column (+1): offset in blocks of its first stored block.
    col_off: Vec<usize>,
    /// Per column (+1): offset in blocks of its ROI run among all ROI runs.
    lo_off: Vec<usize>,
}

impl Layout {
    /// `row_comp` must be non-decreasing over the first `n_cols` rows and over the rest.
    fn new(row_comp: Vec<u32>, n_cols: usize) -> Self {
        let n_comp = row_comp.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut spans = vec![[0usize; 4]; n_comp];
        for (k, s) in spans.iter_mut().enumerate() {
            let k = k as u32;
            s[0] = row_comp[..n_cols].partition_point(|&c| c < k);
            s[1] = row_comp[..n_cols].partition_point(|&c| c <= k);
            s[2] = n_cols + row_comp[n_cols..].partition_point(|&c| c < k);
            s[3] = n_cols + row_comp[n_cols..].partition_point(|&c| c <= k);
        }
        let mut col_off = Vec::with_capacity(n_cols + 1);
        let mut lo_off = Vec::with_capacity(n_cols + 1);
        let (mut off, mut lo) = (0, 0);
        col_off.push(0);
        lo_off.push(0);
        for j in 0..n_cols {
            let s = spans[row_comp[j] as usize];
            off += (s[1] - j) + (s[3] - s[2]);
            lo += s[1] - j;
            col_off.push(off);
            lo_off.push(lo);
        }
        Self { row_comp, spans, col_off, lo_off }
    }

    /// Stored blocks.
    fn blocks(&self) -> usize {
        self.col_off.last().copied().unwrap_or(0)
    }

    /// Blocks in the ROI runs (the ROI x ROI lower triangle).
    fn lo_blocks(&self) -> usize {
        self.lo_off.last().copied().unwrap_or(0)
    }

    /// Block offset of `(row, col)`, `row >= col`, among the ROI runs, or
    /// `None` when `row` is not a ROI row of `col`'s component.
    #[inline]
    fn lo_offset(&self, row: usize, col: usize) -> Option<usize> {
        let k = self.row_comp[col];
        (self.row_comp[row] == k && row < self.spans[k as usize][1]).then(|| self.lo_off[col] + row - col)
    }

    /// Block offset of `(row, col)`, `row >= col`; `None` across components (the block is exactly zero).
    #[inline]
    fn offset(&self, row: usize, col: usize) -> Option<usize> {
        let k = self.row_comp[col];
        if self.row_comp[row] != k {
            return None;
        }
        let s = &self.spans[k as usize];
        Some(if row < s[1] { self.col_off[col] + row - col } else { self.col_off[col] + (s[1] - col) + row - s[2] })
    }

    /// The two runs of stored rows of column `j`: `(first row, end row, block offset)`.
    #[inline]
    fn runs(&self, j: usize) -> [(usize, usize, usize); 2] {
        let s = &self.spans[self.row_comp[j] as usize];
        let o = self.col_off[j];
        [(j, s[1], o), (s[2], s[3], o + s[1] - j)]
    }

    /// First ROI row of column `j`'s component: the rows `i < j` it couples to are `upper_start(j)..j`.
    #[inline]
    fn upper_start(&self, j: usize) -> usize {
        self.spans[self.row_comp[j] as usize][0]
    }
}

/// Component of every free node in the graph of tets through free nodes (`u32::MAX`: none), numbered by lowest node.
fn free_components(model: &FemModel) -> Vec<u32> {
    let n = model.mesh.node_count();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for t in &model.mesh.tets {
        let mut prev: Option<u32> = None;
        for &v in t.iter().filter(|&&v| !model.is_fixed(v)) {
            if let Some(p) = prev {
                join(&mut parent, p, v);
            }
            prev = Some(v);
        }
    }
    let mut id = vec![u32::MAX; n];
    let mut comp = vec![u32::MAX; n];
    let mut next = 0;
    for v in 0..n as u32 {
        if model.dofs.dof(v).is_none() {
            continue;
        }
        let r = find(&mut parent, v) as usize;
        if id[r] == u32::MAX {
            id[r] = next;
            next += 1;
        }
        comp[v as usize] = id[r];
    }
    comp
}

impl Compliance {
    /// Computes (or loads from `cache_dir`) the compliance for `roi_nodes` (fixed ones skipped, duplicates ignored).
    /// `progress(done, total)` is called after every batch of columns.
    pub fn compute(model: &FemModel, roi_nodes: &[u32], storage: ComplianceStorage, cache_dir: Option<&Path>, progress: &mut dyn FnMut(usize, usize)) -> Result<Self, FemError> {
        Self::compute_with(model, roi_nodes, ComputeOptions { cache_dir, ..ComputeOptions::new(storage) }, progress)
    }

    /// As [`Self::compute`], with [`ComputeOptions`]. With `background`, `progress` is called once with
    /// `(0, total)`; [`Self::fill_progress`] says how far the filling is.
    pub fn compute_with(model: &FemModel, roi_nodes: &[u32], options: ComputeOptions<'_>, progress: &mut dyn FnMut(usize, usize)) -> Result<Self, FemError> {
        let ComputeOptions { storage, cache_dir, reach, background, rows } = options;
        let reach = reach.filter(|r| r.len() == model.mesh.node_count());
        let this = Self::laid_out(model, roi_nodes, storage, reach, rows)?;
        let path = cache_dir.map(|d| d.join(format!("compliance-{}.bin", hex(&this.key[..16]))));
        this.fill_from(model, storage, path, background, reach, progress)
    }

    /// The rows, columns and layout for `roi_nodes` and the surface `rows` (`None`: all); nothing computed yet.
    fn laid_out(model: &FemModel, roi_nodes: &[u32], storage: ComplianceStorage, reach: Option<&[u32]>, rows: Option<&[u32]>) -> Result<Self, FemError> {
        let count = model.mesh.node_count();
        let mut roi: Vec<u32> = Vec::with_capacity(roi_nodes.len());
        for &n in roi_nodes {
            if n as usize >= count {
                return Err(FemError::NodeOutOfRange { what: "ROI", node: n, count });
            }
            if !model.is_fixed(n) {
                roi.push(n);
            }
        }
        roi.sort_unstable();
        roi.dedup();
        let n_cols = roi.len();
        let mut wanted: Option<Vec<u32>> = rows.map(<[u32]>::to_vec);
        if let Some(w) = &mut wanted {
            w.sort_unstable();
        }
        let stored = |n: u32| wanted.as_ref().is_none_or(|w| w.binary_search(&n).is_ok());
        let mut others: Vec<u32> =
            model.surface.vertices.iter().copied().filter(|&n| !model.is_fixed(n) && roi.binary_search(&n).is_err() && stored(n)).collect();
        // Morton order: a spatula's contact patch maps to a few runs of consecutive columns, so the product streams.
        morton_sort(&mut roi, &model.mesh.positions);
        morton_sort(&mut others, &model.mesh.positions);
        // Rows grouped by free component ([`Layout`]); stable sorts keep each component's reach and Morton order.
        if let Some(reach) = reach {
            roi.sort_by_key(|&n| reach[n as usize]);
        }
        let comp = free_components(model);
        roi.sort_by_key(|&n| comp[n as usize]);
        others.sort_by_key(|&n| comp[n as usize]);
        let mut row_nodes = roi.clone();
        row_nodes.extend_from_slice(&others);
        let layout = Layout::new(row_nodes.iter().map(|&n| comp[n as usize]).collect(), n_cols);
        let mut node_row = vec![NO_ROW; count];
        for (r, &n) in row_nodes.iter().enumerate() {
            node_row[n as usize] = r as u32;
        }
        let key = cache_key(model, &roi, storage, wanted.is_some().then_some(others.as_slice()));
        Ok(Self {
            values: Values::F64(Arc::new(Dense { v: Buf::new(Vec::new()), lo: Buf::new(Vec::new()) })),
            fill: None,
            row_nodes,
            n_cols,
            layout: Arc::new(layout),
            node_row,
            key,
            model_fingerprint: model.fingerprint,
            stats: ComplianceStats::default(),
        })
    }

    /// Fills a compliance from [`Self::laid_out`]: from the cache file at `path` where its batches check, else solved.
    fn fill_from(
        self,
        model: &FemModel,
        storage: ComplianceStorage,
        path: Option<PathBuf>,
        background: bool,
        reach: Option<&[u32]>,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Self, FemError> {
        let mut this = self;
        let n_cols = this.n_cols;
        let t = Instant::now();
        let mut job = this.prepare_fill(model, storage, reach, background)?;
        if let Some(p) = &path {
            match this.open_dense(p, storage, &job.fill) {
                Ok(source) => {
                    job.source = Some(source);
                    mark_used(p);
                }
                Err(reason) => {
                    if p.exists() {
                        tracing::warn!("compliance cache {} not used ({reason}); rebuilding", p.display());
                    }
                }
            }
        }
        if job.source.is_some() {
            // Every column a frame reads is in the file: the factor is made beside the frames (for lazy columns,
            // interior displacements and any batch that fails its check).
            model.start_factor();
        } else {
            // Made here, so a matrix that cannot be factored fails the build.
            model.chol.get()?;
        }
        this.values = job.values.clone();
        let fill = Arc::clone(&job.fill);
        if background {
            let cache = path.clone().map(|p| (p, this.header(storage), this.row_nodes.clone()));
            progress(0, n_cols);
            match job.spawn(cache) {
                Ok(()) => {
                    this.fill = Some(Arc::new(FillOwner(fill)));
                    this.stats = this.make_stats(0.0, 0.0, false);
                    return Ok(this);
                }
                Err(job) => {
                    // No thread: fill here, as a build that waits.
                    tracing::warn!("the compliance columns are computed before the first frame (no background thread)");
                    job.run(progress)?;
                }
            }
        } else {
            progress(0, n_cols);
            job.run(progress)?;
        }
        let seconds = t.elapsed().as_secs_f64();
        let from_cache = fill.computed() == 0 && fill.loaded() > 0;
        this.stats = if from_cache { this.make_stats(0.0, seconds, true) } else { this.make_stats(seconds, 0.0, false) };
        if let Some(p) = &path
            && !from_cache
        {
            let header = this.header(storage);
            // SAFETY: the filling above ran to its end; nothing writes any more.
            let written = match &this.values {
                Values::F64(d) => unsafe { write_dense_cache(p, &header, &this.row_nodes, &this.layout, &fill, d) },
                Values::F32(d) => unsafe { write_dense_cache(p, &header, &this.row_nodes, &this.layout, &fill, d) },
            };
            finish_write(p, written);
        }
        Ok(this)
    }

    fn make_stats(&self, compute_seconds: f64, load_seconds: f64, from_cache: bool) -> ComplianceStats {
        let bytes = match &self.values {
            Values::F64(d) => d.v.len() * 8,
            Values::F32(d) => d.v.len() * 4 + d.lo.len() * 2,
        };
        ComplianceStats { compute_seconds, load_seconds, bytes, from_cache, rows: self.row_nodes.len(), cols: self.n_cols }
    }

    fn entry_count(&self) -> usize {
        self.layout.blocks() * 9
    }

    /// Allocates the dense storage (after checking it fits) and lays out batches of [`BATCH_NODES`] columns, cut at
    /// component starts and ordered by their first column's reach when `reach` is given, else in column order.
    fn prepare_fill(&self, model: &FemModel, storage: ComplianceStorage, reach: Option<&[u32]>, background: bool) -> Result<FillJob, FemError> {
        let len = self.entry_count();
        let n_free = model.dofs.dof_count();
        let starts: Vec<usize> = match reach {
            Some(_) => self.layout.spans.iter().flat_map(|s| (s[0]..s[1]).step_by(BATCH_NODES)).collect(),
            None => (0..self.n_cols).step_by(BATCH_NODES).collect(),
        };
        let mut order: Vec<usize> = (0..starts.len()).collect();
        if let Some(reach) = reach {
            order.sort_by_key(|&b| reach[self.row_nodes[starts[b]] as usize]);
        }
        let threads = precompute_threads(n_free, starts.len());
        // The stored entries plus every thread's right-hand sides (row major, in its solve's scratch).
        let entry_bytes = if storage == ComplianceStorage::F32 { 4 } else { 8 };
        let need = len * entry_bytes
            + self.layout.lo_blocks() * 9 * 2 * usize::from(storage == ComplianceStorage::F32)
            + threads * n_free * 3 * BATCH_NODES * 8;
        region_fits(self.n_cols, self.row_nodes.len(), storage, need as u64, crate::meminfo::available_bytes())?;
        let values = match storage {
            ComplianceStorage::F64 => {
                let mut v: Vec<f64> = bytemuck::allocation::try_zeroed_vec(len).map_err(|_| FemError::OutOfMemory { what: "compliance", bytes: len * 8 })?;
                advise_huge_pages(&mut v);
                Values::F64(Arc::new(Dense { v: Buf::new(v), lo: Buf::new(Vec::new()) }))
            }
            ComplianceStorage::F32 => {
                let mut v: Vec<f32> = bytemuck::allocation::try_zeroed_vec(len).map_err(|_| FemError::OutOfMemory { what: "compliance", bytes: len * 4 })?;
                advise_huge_pages(&mut v);
                let n_lo = self.layout.lo_blocks() * 9;
                let lo: Vec<i16> = bytemuck::allocation::try_zeroed_vec(n_lo).map_err(|_| FemError::OutOfMemory { what: "compliance", bytes: n_lo * 2 })?;
                Values::F32(Arc::new(Dense { v: Buf::new(v), lo: Buf::new(lo) }))
            }
        };
        let fill = Arc::new(Fill::new(&self.layout, self.n_cols, &starts).solved_in(order));
        let row_dofs: Vec<usize> = self.row_nodes.iter().map(|&n| model.dofs.dof(n).unwrap_or(0)).collect();
        Ok(FillJob { chol: Arc::clone(&model.chol), row_dofs, wanted: std::sync::OnceLock::new(), layout: Arc::clone(&self.layout), values, fill, threads, background, source: None })
    }
    /// Statistics of the last build or load.
    pub fn stats(&self) -> ComplianceStats {
        let mut s = self.stats;
        if let Some(f) = &self.fill {
            let f = &f.0;
            if f.is_complete() && f.computed() == 0 && f.loaded() > 0 {
                (s.from_cache, s.load_seconds) = (true, f.seconds());
            } else {
                s.compute_seconds = f.seconds();
            }
        }
        s
    }

    /// While the columns fill in the background ([`ComputeOptions::background`]): `(final columns, all columns)`;
    /// `None` once every column is final.
    pub fn fill_progress(&self) -> Option<(usize, usize)> {
        let f = &self.fill.as_ref()?.0;
        (!f.is_complete()).then(|| (f.columns_done(), self.n_cols))
    }

    /// Waits until every column is final (at once when none is being computed).
    pub fn wait_complete(&self) -> Result<(), FemError> {
        let Some(f) = &self.fill else { return Ok(()) };
        for (k, s) in self.layout.spans.iter().enumerate() {
            f.0.wait(k, s[1] - s[0]).map_err(|reason| FemError::ComplianceIncomplete { reason })?;
        }
        Ok(())
    }

    /// With the columns filling in the background: waits until the rest of the filling, at the rate measured so far
    /// slowed by [`AHEAD_SLOWDOWN`], is predicted to make every column readable before `due_s(node)` seconds from
    /// now, when a blade is first expected to read it; a scene starting then never waits for a column.
    /// `progress(done, total)` on each final batch; returns at once when nothing is filling.
    pub fn wait_until_ahead(&self, due_s: &dyn Fn(u32) -> f64, progress: &mut dyn FnMut(usize, usize)) -> Result<(), FemError> {
        let Some(owner) = &self.fill else { return Ok(()) };
        let f = &owner.0;
        // A column is readable once its component's columns before it are final: a batch is due when the earliest
        // of its own and its component's later columns is.
        let mut due = vec![f64::INFINITY; f.batch_count()];
        for s in &self.layout.spans {
            let mut earliest = f64::INFINITY;
            for col in (s[0]..s[1]).rev() {
                earliest = earliest.min(due_s(self.row_nodes[col]));
                let b = f.batch_of(col);
                due[b] = due[b].min(earliest);
            }
        }
        let n_cols = self.n_cols;
        let ahead = |done: &[bool], columns_done: usize, seconds: f64| {
            progress(columns_done, n_cols);
            // Trust the rate only after a few batches (the first ones also wait for the threads to start).
            if done.iter().filter(|&&d| d).count() < AHEAD_MIN_BATCHES || seconds <= 0.0 {
                return false;
            }
            let seconds_per_column = AHEAD_SLOWDOWN * seconds / columns_done as f64;
            let mut left = 0usize;
            f.order().iter().filter(|&&b| !done[b]).all(|&b| {
                left += f.batch(b).len();
                left as f64 * seconds_per_column <= due[b]
            })
        };
        f.wait_until(ahead).map(|_| ()).map_err(|reason| FemError::ComplianceIncomplete { reason })
    }

    /// Whether column `col` is readable now (its component's columns up to it are final), without waiting.
    pub fn column_ready(&self, col: usize) -> bool {
        match &self.fill {
            Some(f) if !f.0.is_complete() && col < self.n_cols => {
                let k = self.layout.row_comp[col] as usize;
                f.0.ready(k) > col - self.layout.spans[k][0]
            }
            _ => true,
        }
    }

    /// Waits until column `col` is readable (its component's columns up to it are final); at once unless filling.
    #[inline]
    pub fn wait_column(&self, col: usize) -> Result<(), FemError> {
        let Some(f) = &self.fill else { return Ok(()) };
        if f.0.is_complete() || col >= self.n_cols {
            return Ok(());
        }
        let k = self.layout.row_comp[col] as usize;
        f.0.wait(k, col + 1 - self.layout.spans[k][0]).map_err(|reason| FemError::ComplianceIncomplete { reason })
    }

    /// The final leading columns of component `k`: their entries from block `col_off[first column]` on, and their
    /// ROI corrections (f32 storage) from block `lo_off[first column]` on.
    #[inline]
    fn region<'a, T>(&'a self, d: &'a Dense<T>, k: usize) -> Region<'a, T> {
        let s = &self.layout.spans[k];
        let ready = match &self.fill {
            Some(f) if !f.0.is_complete() => f.0.ready(k),
            _ => s[1] - s[0],
        };
        let (col_off, lo_off) = (&self.layout.col_off, &self.layout.lo_off);
        let (a, b) = (col_off[s[0]], col_off[s[0] + ready]);
        let (la, lb) = (lo_off[s[0]], lo_off[s[0] + ready]);
        // SAFETY: columns s[0]..s[0] + ready are final: the filling threads
        // wrote them before publishing `ready` (release, read with acquire
        // above) and never write them again.
        unsafe {
            Region {
                v: d.v.slice(9 * a..9 * b),
                base: a,
                lo: if d.lo.len() == 0 { &[] } else { d.lo.slice(9 * la..9 * lb) },
                lo_base: la,
            }
        }
    }

    /// The cache key (blake3 of the model fingerprint, ROI and precision).
    pub fn key(&self) -> [u8; 32] {
        self.key
    }

    /// Fingerprint of the model this compliance belongs to.
    pub fn model_fingerprint(&self) -> [u8; 32] {
        self.model_fingerprint
    }

    /// Precision of the stored entries.
    pub fn storage(&self) -> ComplianceStorage {
        match &self.values {
            Values::F64(_) => ComplianceStorage::F64,
            Values::F32(..) => ComplianceStorage::F32,
        }
    }

    /// Row nodes: ROI nodes first (they are also the columns), then the other free surface nodes.
    pub fn row_nodes(&self) -> &[u32] {
        &self.row_nodes
    }

    /// Number of ROI (column) nodes.
    pub fn column_count(&self) -> usize {
        self.n_cols
    }

    /// Row index of a node, or `None` when it is neither a free surface node nor in the ROI.
    #[inline]
    pub fn row_of(&self, node: u32) -> Option<usize> {
        match self.node_row.get(node as usize) {
            Some(&r) if r != NO_ROW => Some(r as usize),
            _ => None,
        }
    }

    /// Column index of a node, or `None` when it is outside the ROI.
    #[inline]
    pub fn col_of(&self, node: u32) -> Option<usize> {
        self.row_of(node).filter(|&r| r < self.n_cols)
    }

    /// `K^-1[row node, col node]` by row and column index (`col < column_count()`). While the columns fill in the
    /// background it waits for those it reads (a frame asks [`Self::wait_column`] first, which can fail; here a
    /// failed filling reads as zero).
    #[inline]
    pub fn block(&self, row: usize, col: usize) -> Matrix3<f64> {
        if row >= col {
            self.stored(row, col)
        } else {
            self.stored(col, row).transpose()
        }
    }

    /// Asks the CPU to bring the stored block [`Self::block`]`(row, col)` reads into cache: a hint for a loop about to
    /// read blocks that lie apart in the storage. It reads nothing (a column still filling included) and changes no
    /// value.
    #[inline]
    pub fn prefetch_block(&self, row: usize, col: usize) {
        let (r, c) = if row >= col { (row, col) } else { (col, row) };
        let Some(b) = self.layout.offset(r, c) else { return };
        match &self.values {
            Values::F64(d) => crate::math::prefetch::<72, _>(d.v.addr(9 * b)),
            Values::F32(d) => {
                crate::math::prefetch::<36, _>(d.v.addr(9 * b));
                if let Some(l) = self.layout.lo_offset(r, c) {
                    crate::math::prefetch::<18, _>(d.lo.addr(9 * l));
                }
            }
        }
    }

    /// The block as the surface product reads it: f32 storage without the ROI x ROI correction, else [`Self::block`].
    pub fn product_block(&self, row: usize, col: usize) -> Matrix3<f64> {
        let (r, c, transpose) = if row >= col { (row, col, false) } else { (col, row, true) };
        let m = match (&self.values, self.layout.offset(r, c)) {
            (Values::F32(d), Some(b)) => {
                if self.wait_column(c).is_err() {
                    return Matrix3::zeros();
                }
                let g = self.region(d, self.layout.row_comp[c] as usize);
                let o = 9 * (b - g.base);
                Matrix3::from_iterator(g.v[o..o + 9].iter().map(|&x| x as f64))
            }
            (Values::F32(..), None) => Matrix3::zeros(),
            _ => return self.block(row, col),
        };
        if transpose { m.transpose() } else { m }
    }

    #[inline]
    fn stored(&self, row: usize, col: usize) -> Matrix3<f64> {
        let Some(b) = self.layout.offset(row, col) else {
            return Matrix3::zeros();
        };
        if self.wait_column(col).is_err() {
            return Matrix3::zeros();
        }
        let k = self.layout.row_comp[col] as usize;
        match &self.values {
            Values::F64(d) => {
                let g = self.region(d, k);
                let o = 9 * (b - g.base);
                Matrix3::from_column_slice(&g.v[o..o + 9])
            }
            Values::F32(d) => {
                let g = self.region(d, k);
                let o = 9 * (b - g.base);
                match self.layout.lo_offset(row, col) {
                    Some(l) => {
                        let lo = 9 * (l - g.lo_base);
                        Matrix3::from_fn(|r, c| join_f32(g.v[o + 3 * c + r], g.lo[lo + 3 * c + r]))
                    }
                    None => Matrix3::from_iterator(g.v[o..o + 9].iter().map(|&x| x as f64)),
                }
            }
        }
    }

    fn header(&self, storage: ComplianceStorage) -> Vec<u8> {
        let mut h = Vec::with_capacity(72);
        h.extend_from_slice(CACHE_MAGIC);
        h.extend_from_slice(&CACHE_VERSION.to_le_bytes());
        let [code, digits] = storage.code();
        h.extend_from_slice(&[code, digits, 0, 0]);
        h.extend_from_slice(&self.key);
        h.extend_from_slice(&(self.row_nodes.len() as u64).to_le_bytes());
        h.extend_from_slice(&(self.n_cols as u64).to_le_bytes());
        h
    }

    /// Opens a dense cache file ([`write_dense_cache`]) for `fill`'s batches: checks its size, header, rows and batch
    /// table (checksum and batches). Its entries are read later, batch by batch.
    fn open_dense(&self, path: &Path, storage: ComplianceStorage, fill: &Fill) -> Result<CacheSource, String> {
        let (mut file, _) = crate::fsio::open_regular(path, crate::fsio::Cap::COMPLIANCE_CACHE).map_err(|e| e.to_string())?;
        let (width, n_lo) = match storage {
            ComplianceStorage::F32 => (4, self.layout.lo_blocks() * 9),
            ComplianceStorage::F64 => (8, 0),
        };
        let n_batches = fill.batch_count();
        let want = self.header(storage);
        let table = 8 + 40 * n_batches + 32;
        let prefix = want.len() + 4 * self.row_nodes.len() + table;
        let expected = prefix + width * self.entry_count() + 2 * n_lo;
        let size = file.metadata().map_err(|e| e.to_string())?.len() as usize;
        if size != expected {
            return Err(format!("size {size} bytes, expected {expected}"));
        }
        let mut head = vec![0u8; prefix];
        file.read_exact(&mut head).map_err(|e| e.to_string())?;
        let (header, rest) = head.split_at(want.len());
        if header != want.as_slice() {
            return Err("header or key mismatch".into());
        }
        let (rows, rest) = rest.split_at(4 * self.row_nodes.len());
        if rows != bytemuck::cast_slice::<u32, u8>(&self.row_nodes) {
            return Err("row nodes mismatch".into());
        }
        let (table, sum) = rest.split_at(rest.len() - 32);
        let mut meta = blake3::Hasher::new();
        meta.update(&head[..prefix - 32]);
        if meta.finalize().as_bytes() != sum {
            return Err("checksum mismatch (corrupt batch table)".into());
        }
        let u64_at = |k: usize| u64::from_le_bytes(table[8 * k..8 * k + 8].try_into().unwrap_or([0xff; 8]));
        if u64_at(0) != n_batches as u64 || (0..n_batches).any(|b| u64_at(1 + b) != fill.batch(b).start as u64) {
            return Err("written for other batches of columns".into());
        }
        let sums = table[8 + 8 * n_batches..].chunks_exact(32).map(|c| c.try_into().unwrap_or([0; 32])).collect();
        let v_at = prefix as u64;
        Ok(CacheSource {
            file,
            path: path.to_path_buf(),
            sums,
            v_at,
            lo_at: v_at + (width * self.entry_count()) as u64,
            width,
            failed: std::sync::atomic::AtomicBool::new(false),
        })
    }
}

/// `x` as an f32 and the rest `x - f32(x)` in units of 2^-15 of that f32's ulp (at most half an ulp, so it fits an
/// i16): [`join_f32`] gives `x` back to about 2^-39 relative.
#[inline]
fn split_f32(x: f64) -> (f32, i16) {
    let hi = x as f32;
    let rest = x - hi as f64;
    (hi, (rest / f32_unit(hi)).round().clamp(i16::MIN as f64, i16::MAX as f64) as i16)
}

/// Inverse of [`split_f32`].
#[inline]
fn join_f32(hi: f32, lo: i16) -> f64 {
    hi as f64 + lo as f64 * f32_unit(hi)
}

/// 2^-15 of the ulp of an f32 (subnormals and zero: of the smallest subnormal).
#[inline]
fn f32_unit(hi: f32) -> f64 {
    let exp = ((hi.to_bits() >> 23) & 0xff).max(1) as u64;
    // 2^(exp - 127 - 23 - 15) as an f64 (its biased exponent exp + 858 is always normal).
    f64::from_bits((exp + 1023 - 165) << 52)
}

/// Asks Linux for transparent huge pages under a large buffer: the per-frame product touches a few hundred columns
/// of up to a megabyte each, a TLB miss every 4 KiB page otherwise. A hint: refusal changes only speed. Given
/// before the first write when the buffer is computed (faults then take huge pages), and after the read when it
/// is loaded, so a reload never waits on the kernel compacting memory.
fn advise_huge_pages<T>(v: &mut [T]) {
    #[cfg(target_os = "linux")]
    if crate::fem::tuning::Tuning::current().enabled(crate::fem::tuning::Optimisation::HugePages) {
        let bytes = std::mem::size_of_val(v);
        const HUGE: usize = 2 << 20;
        let start = (v.as_mut_ptr() as usize).next_multiple_of(HUGE);
        let end = (v.as_mut_ptr() as usize + bytes) / HUGE * HUGE;
        if end > start {
            // SAFETY: the range lies inside `v`'s allocation; MADV_HUGEPAGE does not change its contents.
            unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
        }
    }
}

/// How much slower the background filling is assumed to run beside the frames ([`Compliance::wait_until_ahead`]).
pub const AHEAD_SLOWDOWN: f64 = 1.25;
/// Final batches before the filling's rate is trusted ([`Compliance::wait_until_ahead`]).
const AHEAD_MIN_BATCHES: usize = 4;

/// Refuses a compliance of `need` bytes when the machine has less `available` (unknown: allowed).
fn region_fits(cols: usize, rows: usize, storage: ComplianceStorage, need: u64, available: Option<u64>) -> Result<(), FemError> {
    match available {
        Some(available) if need > available => Err(FemError::RegionTooLarge {
            cols,
            rows,
            storage: format!("{storage:?}"),
            need_mb: need >> 20,
            available_mb: available >> 20,
        }),
        _ => Ok(()),
    }
}

/// The final leading columns of one component ([`Compliance::region`]).
struct Region<'a, T> {
    v: &'a [T],
    /// Block offset of `v[0]` in the whole storage.
    base: usize,
    /// ROI corrections (f32 storage; empty otherwise) and the block offset of `lo[0]`.
    lo: &'a [i16],
    lo_base: usize,
}

/// The storage of one batch of columns (see [`FillJob::solve_batch`]).
enum Piece<'a> {
    F64(&'a mut [f64]),
    F32(&'a mut [f32], &'a mut [i16]),
}

/// Everything the threads that fill a dense compliance need ([`Compliance::prepare_fill`]).
struct FillJob {
    /// Waited for at the first batch that is solved (none when the cache has every batch).
    chol: Arc<super::model::LazyFactor>,
    /// First free DOF of every stored row.
    row_dofs: Vec<usize>,
    /// The supernodes above the stored rows, made by the first batch solved.
    wanted: std::sync::OnceLock<Option<Vec<bool>>>,
    layout: Arc<Layout>,
    values: Values,
    fill: Arc<Fill>,
    threads: usize,
    /// Filling beside the frames: its threads run at a lower priority.
    background: bool,
    /// A cache file whose batches are read (each checked against its checksum) instead of solved.
    source: Option<CacheSource>,
}

impl FillJob {
    /// Fills every batch on `threads` scoped threads until all are final or one fails; `progress` after each.
    fn run(&self, progress: &mut dyn FnMut(usize, usize)) -> Result<(), FemError> {
        let t = Instant::now();
        let n_cols = self.layout.col_off.len() - 1;
        let next = std::sync::atomic::AtomicUsize::new(0);
        let result = std::thread::scope(|scope| -> Result<(), FemError> {
            let (done_tx, done_rx) = std::sync::mpsc::channel::<Result<usize, FemError>>();
            for _ in 0..self.threads {
                let (next, done_tx) = (&next, done_tx.clone());
                scope.spawn(move || {
                    if self.background {
                        lower_thread_priority();
                    }
                    let work = || -> Result<(), FemError> {
                        // The solve's scratch is allocated only once a batch is solved.
                        let mut solver: Option<crate::linalg::UnitScratch> = None;
                        loop {
                            if self.fill.is_cancelled() {
                                return Ok(());
                            }
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(&b) = self.fill.order().get(i) else { return Ok(()) };
                            let cols = self.fill.batch(b);
                            // SAFETY: batch b is taken by this thread alone (the
                            // counter hands each out once) and nobody reads its
                            // columns before `finish_batch` publishes them.
                            let mut piece = unsafe { self.piece(cols.clone()) };
                            if self.read_batch(b, &mut piece) {
                                self.fill.count_loaded();
                            } else {
                                let chol = self.chol.get()?;
                                if solver.is_none() {
                                    solver = Some(chol.unit_scratch(BATCH_NODES)?);
                                }
                                if let Some(scratch) = solver.as_mut() {
                                    self.solve_batch(chol, cols.clone(), scratch, piece)?;
                                }
                                self.fill.count_computed();
                            }
                            self.fill.finish_batch(b, t.elapsed().as_secs_f64());
                            if done_tx.send(Ok(cols.len())).is_err() {
                                return Ok(()); // the caller stopped listening
                            }
                        }
                    };
                    if let Err(e) = work() {
                        let _ = done_tx.send(Err(e));
                    }
                });
            }
            drop(done_tx);
            let mut done = 0;
            for msg in done_rx {
                done += msg?;
                progress(done, n_cols);
            }
            Ok(())
        });
        if let Err(e) = &result {
            self.fill.fail(e.to_string());
        } else if !self.fill.is_complete() {
            // Stopped (cancelled, or a thread that died without a word).
            let reason = if self.fill.is_cancelled() { "stopped" } else { "a precompute thread stopped" };
            self.fill.fail(reason.into());
            return Err(FemError::ComplianceIncomplete { reason: reason.into() });
        }
        result
    }

    /// Reads batch `b` from the cache file into `piece` when there is one and the bytes match their checksum.
    fn read_batch(&self, b: usize, piece: &mut Piece<'_>) -> bool {
        let Some(src) = &self.source else { return false };
        let (v, lo): (&mut [u8], &mut [u8]) = match piece {
            Piece::F64(v) => (bytemuck::cast_slice_mut(&mut **v), &mut []),
            Piece::F32(v, lo) => (bytemuck::cast_slice_mut(&mut **v), bytemuck::cast_slice_mut(&mut **lo)),
        };
        let cols = self.fill.batch(b);
        let (col_off, lo_off) = (&self.layout.col_off, &self.layout.lo_off);
        let v_at = src.v_at + (9 * col_off[cols.start] * src.width) as u64;
        let lo_at = src.lo_at + (9 * lo_off[cols.start] * 2) as u64;
        let checked = read_at(&src.file, v, v_at).and_then(|()| read_at(&src.file, lo, lo_at)).map_err(|e| e.to_string()).and_then(|()| {
            let mut h = blake3::Hasher::new();
            h.update(v);
            h.update(lo);
            if h.finalize().as_bytes() == &src.sums[b] { Ok(()) } else { Err("checksum mismatch (corrupt)".to_string()) }
        });
        match checked {
            Ok(()) => true,
            Err(reason) => {
                if !src.failed.swap(true, std::sync::atomic::Ordering::Relaxed) {
                    tracing::warn!(
                        "compliance cache {}: columns {}..{} not used ({reason}); they are computed (and any other batch that fails its check) and the file is rewritten",
                        src.path.display(),
                        cols.start,
                        cols.end
                    );
                }
                false
            }
        }
    }

    /// Fills in the background, then writes the cache `(path, header, row nodes)` unless every batch came from it.
    /// `Err(self)` when no thread starts.
    fn spawn(self, cache: Option<(PathBuf, Vec<u8>, Vec<u32>)>) -> Result<(), Self> {
        let job = Arc::new(self);
        let worker = Arc::clone(&job);
        let started = std::thread::Builder::new().name("fissure-compliance".into()).spawn(move || {
            match worker.run(&mut |_, _| {}) {
                Ok(()) => {
                    tracing::info!("compliance: every column final after {:.1} s in the background", worker.fill.seconds());
                    if let Some((path, header, row_nodes)) = cache
                        && worker.fill.computed() > 0
                    {
                        // SAFETY: every batch is final (run returned Ok); nothing writes any more.
                        let written = match &worker.values {
                            Values::F64(d) => unsafe { write_dense_cache(&path, &header, &row_nodes, &worker.layout, &worker.fill, d) },
                            Values::F32(d) => unsafe { write_dense_cache(&path, &header, &row_nodes, &worker.layout, &worker.fill, d) },
                        };
                        finish_write(&path, written);
                    }
                }
                Err(e) if worker.fill.is_cancelled() => tracing::debug!("compliance filling stopped: {e}"),
                Err(e) => tracing::error!("compliance columns in the background: {e}"),
            }
        });
        match started {
            Ok(_) => Ok(()),
            Err(e) => {
                tracing::warn!("compliance thread did not start: {e}");
                // The closure that held the other reference was dropped with the error.
                Arc::try_unwrap(job).map_err(|job| job.fill.fail(format!("the compliance thread did not start: {e}")))
                    .map_or(Ok(()), Err)
            }
        }
    }

    /// The storage of columns `cols` (one batch).
    ///
    /// # Safety
    /// No other thread reads or writes these columns while the piece lives.
    unsafe fn piece(&self, cols: std::ops::Range<usize>) -> Piece<'_> {
        let (col_off, lo_off) = (&self.layout.col_off, &self.layout.lo_off);
        let range = 9 * col_off[cols.start]..9 * col_off[cols.end];
        // SAFETY: exclusive (the caller's promise).
        unsafe {
            match &self.values {
                Values::F64(d) => Piece::F64(d.v.slice_mut(range)),
                Values::F32(d) => Piece::F32(d.v.slice_mut(range), d.lo.slice_mut(9 * lo_off[cols.start]..9 * lo_off[cols.end])),
            }
        }
    }

    /// Solves columns `cols` (3 right-hand sides a node) and writes their stored rows into `piece`, their storage.
    fn solve_batch(
        &self,
        chol: &crate::linalg::SparseCholesky,
        cols: std::ops::Range<usize>,
        scratch: &mut crate::linalg::UnitScratch,
        mut piece: Piece<'_>,
    ) -> Result<(), FemError> {
        let (j0, nb) = (cols.start, cols.len());
        let row_dofs = &self.row_dofs;
        // Only the stored rows are read: the backward pass visits only their supernodes and those above.
        let wanted = self.wanted.get_or_init(|| chol.supernodes_above(&row_dofs.iter().flat_map(|&d| d..d + 3).collect::<Vec<_>>()));
        let solved = chol.solve_unit_columns_in(&row_dofs[j0..j0 + nb], wanted.as_deref(), scratch)?;
        let (base, base_lo) = (self.layout.col_off[j0] * 9, self.layout.lo_off[j0] * 9);
        // A block of stored rows at a time for every column of the batch: the solve's rows of the block are read
        // from memory once, whichever layout holds them.
        for first in (0..row_dofs.len()).step_by(FILL_ROW_BLOCK) {
            let last = (first + FILL_ROW_BLOCK).min(row_dofs.len());
            for b in 0..nb {
                let j = j0 + b;
                let at = |d: usize, c: usize| solved.at(d, 3 * b + c);
                for (run, (r0, r1, off)) in self.layout.runs(j).into_iter().enumerate() {
                    let (s, e) = (r0.max(first), r1.min(last));
                    if s >= e {
                        continue;
                    }
                    let (start, count) = ((off + s - r0) * 9 - base, (e - s) * 9);
                    match &mut piece {
                        Piece::F64(v) => fill_column(&mut v[start..start + count], &row_dofs[s..e], at, |x| x),
                        Piece::F32(v, lo) => {
                            fill_column(&mut v[start..start + count], &row_dofs[s..e], at, |x| split_f32(x).0);
                            if run == 0 {
                                let b = (self.layout.lo_off[j] + s - r0) * 9 - base_lo;
                                fill_column(&mut lo[b..b + count], &row_dofs[s..e], at, |x| split_f32(x).1);
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// Makes the calling thread yield to the frames: Linux nice 10 for this thread alone. A hint: where refused, or on
/// other systems, the thread keeps the default priority.
pub(crate) fn lower_thread_priority() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: plain system calls on the calling thread's own id.
        let refused = unsafe {
            let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
            libc::setpriority(libc::PRIO_PROCESS, tid, 10) != 0
        };
        if refused {
            tracing::debug!("background thread: lower priority refused");
        }
    }
}

/// Threads for the precompute: one a core, as many as [`PRECOMPUTE_RHS_BUDGET`] allows for their right-hand sides
/// (`n_free x 3 BATCH_NODES` f64 each), at least one, at most one a batch.
fn precompute_threads(n_free: usize, batches: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let per_thread = n_free * 3 * BATCH_NODES * 8;
    let by_memory = PRECOMPUTE_RHS_BUDGET / per_thread.max(1);
    cores.min(by_memory).min(batches).max(1)
}

/// Writes the 3x3 blocks of one column node at `row_dofs` (column `c`, DOF `d + r` read by `at(d + r, c)`).
fn fill_column<T: Copy>(out: &mut [T], row_dofs: &[usize], at: impl Fn(usize, usize) -> f64, conv: impl Fn(f64) -> T) {
    for (k, &d) in row_dofs.iter().enumerate() {
        let o = 9 * k;
        for c in 0..3 {
            for r in 0..3 {
                out[o + 3 * c + r] = conv(at(d + r, c));
            }
        }
    }
}

/// Sorts nodes by Morton code in their bounding box (21 bits an axis), ties by node index: deterministic.
fn morton_sort(nodes: &mut [u32], positions: &[Vec3]) {
    if nodes.is_empty() {
        return;
    }
    let codes = morton_codes(nodes, positions);
    let mut keyed: Vec<(u64, u32)> = codes.into_iter().zip(nodes.iter().copied()).collect();
    keyed.sort_unstable();
    for (n, (_, k)) in nodes.iter_mut().zip(keyed) {
        *n = k;
    }
}

/// Morton code (21 bits an axis) of every node in the nodes' bounding box.
fn morton_codes(nodes: &[u32], positions: &[Vec3]) -> Vec<u64> {
    if nodes.is_empty() {
        return Vec::new();
    }
    let mut lo = Vec3::repeat(f64::INFINITY);
    let mut hi = Vec3::repeat(f64::NEG_INFINITY);
    for &n in nodes.iter() {
        lo = lo.inf(&positions[n as usize]);
        hi = hi.sup(&positions[n as usize]);
    }
    let extent = (hi - lo).max().max(f64::MIN_POSITIVE);
    let spread = |mut v: u64| {
        v &= 0x1f_ffff;
        v = (v | v << 32) & 0x1f00000000ffff;
        v = (v | v << 16) & 0x1f0000ff0000ff;
        v = (v | v << 8) & 0x100f00f00f00f00f;
        v = (v | v << 4) & 0x10c30c30c30c30c3;
        (v | v << 2) & 0x1249249249249249
    };
    let code = |n: u32| {
        let q = (positions[n as usize] - lo) / extent * 2_097_151.0;
        spread(q.x as u64) | spread(q.y as u64) << 1 | spread(q.z as u64) << 2
    };
    nodes.iter().map(|&n| code(n)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_region_larger_than_memory_is_refused_with_its_size() {
        assert!(region_fits(10, 20, ComplianceStorage::F32, 1 << 30, None).is_ok());
        assert!(region_fits(10, 20, ComplianceStorage::F32, 1 << 30, Some(2 << 30)).is_ok());
        let e = region_fits(3864, 33601, ComplianceStorage::F32, 2271 << 20, Some(1 << 30)).unwrap_err().to_string();
        for part in ["3864 nodes", "33601 stored rows", "F32", "2271 MB", "1024 MB", "smaller region of interest"] {
            assert!(e.contains(part), "{e:?} lacks {part:?}");
        }
    }

    #[test]
    fn split_f32_keeps_about_39_bits_more() {
        for &x in &[1.0e-4f64, -3.3e-7, 0.1 + 1e-12, 12345.678, 1e-40, 0.0, -2.5e-3 / 3.0] {
            let (hi, lo) = split_f32(x);
            assert_eq!(hi, x as f32);
            let back = join_f32(hi, lo);
            let tol = (x.abs() * 2f64.powi(-38)).max(2f64.powi(-149 - 15));
            assert!((back - x).abs() <= tol, "{x:e}: {back:e}");
        }
    }
}
