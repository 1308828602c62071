//! The per-frame surface product `u_rows += K^-1[rows, forced columns] F` over a dense compliance
//! ([`super::Compliance::accumulate`]).
//!
//! In: the stored lower triangle (a region of columns at a time, through a closure), the forced ROI columns with
//! their forces, a [`ProductWorkspace`]. Out: the displacement of every stored row. The workspace keeps each forced
//! column's upper entries as a contiguous row ([`RowStore`]), so a frame streams contiguous memory: eight forced
//! columns at a time into 9 partial sums a row, a chunk of rows at a time (AVX2 when the CPU has it).
//! Stays true: nothing is allocated once the workspace has grown; the sums run in a fixed order (bitwise replays).

use super::projected::ProjectedStore;
use super::{Compliance, Layout, ROW_CHUNK, Values};
use crate::fem::tuning::{Optimisation, Tuning};
use std::time::Instant;
use crate::math::Vec3;

impl Compliance {
    /// `u[row] += sum_k K^-1[row, col_k] F_k` over every row, for forces `(col, F)` sorted by ascending column.
    /// `workspace` is reused between calls; once it has grown, nothing is allocated. While the columns fill in the
    /// background it waits for the forced ones; if their filling failed it adds nothing (a frame asks
    /// [`Self::wait_column`] first and stops there).
    pub fn accumulate(&self, forces: &[(usize, Vec3)], u: &mut [Vec3], workspace: &mut ProductWorkspace) {
        self.accumulate_along(forces, &[], u, workspace);
    }

    /// [`Self::accumulate`] with more forces `(col, n, lambda)` along one unit direction each (`F = n lambda`;
    /// ascending, no column in both lists): from the second call in a row that forces a column along the same `n`,
    /// its projection `K^-1[rows, col] n` is kept and streamed instead of its 3x3 blocks (`projected-columns`, see
    /// `compliance/projected.rs`; the surface's last bits differ from the blocks').
    pub fn accumulate_along(&self, forces: &[(usize, Vec3)], along: &[(usize, Vec3, f64)], u: &mut [Vec3], workspace: &mut ProductWorkspace) {
        workspace.gathered = 0;
        workspace.gather_seconds = 0.0;
        if workspace.key != self.key {
            // Rows kept for another compliance are not ours.
            workspace.rows32.clear();
            workspace.rows64.clear();
            workspace.projected.clear();
            workspace.key = self.key;
        }
        if forces.iter().map(|f| f.0).chain(along.iter().map(|f| f.0)).any(|c| self.wait_column(c).is_err()) {
            tracing::error!("the surface product skipped: its compliance columns are not available");
            return;
        }
        let layout = &self.layout;
        // (a chunk is never longer than the rows: off, one chunk holds them all)
        let chunk = workspace.chunk().min(u.len()).max(1);
        let keep = workspace.tuning.enabled(Optimisation::KeptProductRows);
        let project = workspace.tuning.enabled(Optimisation::ProjectedColumns);
        let ProductWorkspace { acc, rows32, rows64, projected, full, proj, split_at, tuning, .. } = workspace;
        let t = Instant::now();
        macro_rules! run {
            ($d:expr, $rows:expr) => {{
                let region = |k: usize| {
                    let g = self.region($d, k);
                    (g.v, g.base)
                };
                // (a workspace split at a given row splits its gathers and projections whatever their size: tests)
                let split = split_at.is_some() || tuning.enabled(Optimisation::ParallelProduct) && crate::par::available();
                let split_from = split.then_some(if split_at.is_some() { 0 } else { SPLIT_GATHER_FROM_BLOCKS });
                if project {
                    projected.prepare(&region, layout, along, full, proj, split);
                } else {
                    projected.clear();
                    proj.clear();
                    full.clear();
                    full.extend(along.iter().map(|&(c, n, l)| (c, n * l)));
                }
                let all = with_forces(full, forces);
                let gathered = $rows.prepare(&region, layout, all, keep, split_from);
                let seconds = t.elapsed().as_secs_f64();
                let pvals = Projections { slab: &projected.slab, slots: &projected.slots, len: projected.slot_len };
                let product = Product { region: &region, layout, forces: all, rows: &$rows.rows, proj, pvals, tuning: *tuning };
                accumulate_impl(product, u, acc, chunk, *split_at);
                (gathered, seconds)
            }};
        }
        let (gathered, seconds) = match &self.values {
            Values::F64(d) => run!(d, rows64),
            Values::F32(d) => run!(d, rows32),
        };
        workspace.gathered = gathered;
        workspace.gather_seconds = seconds;
    }
}

/// `full` (ascending) with `forces` (ascending, other columns) added, by ascending column.
fn with_forces<'o>(full: &'o mut Vec<(usize, Vec3)>, forces: &[(usize, Vec3)]) -> &'o [(usize, Vec3)] {
    let sort = !full.is_empty() && !forces.is_empty();
    full.extend_from_slice(forces);
    if sort {
        full.sort_unstable_by_key(|f| f.0);
    }
    full
}

pub(super) trait Entry: Copy {
    fn f(self) -> f64;
}
impl Entry for f64 {
    #[inline(always)]
    fn f(self) -> f64 {
        self
    }
}
impl Entry for f32 {
    #[inline(always)]
    fn f(self) -> f64 {
        self as f64
    }
}

/// Reusable memory of [`Compliance::accumulate`].
///
/// Dense storage keeps only the lower triangle, so the entries `K^-1[i, c]` with `i < c` of a forced ROI column `c`
/// are row `c` of the stored triangle, one 3x3 block in each earlier column: a strided read. The workspace gathers
/// that row when `c` first carries a force and keeps it while `c` stays forced, so a persisting contact pays the
/// strided read once. Rows of columns no longer forced are reused. With another compliance (key) it starts over.
#[derive(Debug, Default)]
pub struct ProductWorkspace {
    /// Partial sums (9 f64 a row of a chunk), one set a thread.
    acc: [Vec<f64>; 2],
    rows32: RowStore<f32>,
    rows64: RowStore<f64>,
    /// Columns forced along one direction, projected on it ([`super::projected`]).
    projected: ProjectedStore,
    /// The call's forces taken by the 3x3 blocks, and those projected `(col, lambda)`.
    full: Vec<(usize, Vec3)>,
    proj: Vec<(usize, f64)>,
    key: [u8; 32],
    gathered: usize,
    gather_seconds: f64,
    /// Rows a chunk of the product (0: [`ROW_CHUNK`]).
    chunk_rows: usize,
    /// The row the product is split at whatever its size (tests; `None`: as [`split_row`] says).
    split_at: Option<usize>,
    /// The optimisations the product uses (from when the workspace was made).
    pub(crate) tuning: Tuning,
}

impl ProductWorkspace {
    /// Rows `K^-1[c, s..c]` gathered in the last [`Compliance::accumulate`] (columns newly forced).
    pub fn rows_gathered(&self) -> usize {
        self.gathered
    }

    /// A workspace whose product runs in chunks of `rows` rows instead of [`ROW_CHUNK`], for tests that need many
    /// chunks on a small mesh (the result is bitwise the same for any chunk size).
    #[doc(hidden)]
    pub fn with_chunk_rows(rows: usize) -> Self {
        Self { chunk_rows: rows.max(1), ..Self::default() }
    }

    /// A workspace whose product is split over two threads at row `row` whatever its size, for tests that the
    /// split leaves every bit (a row out of range: not split).
    #[doc(hidden)]
    pub fn with_split_row(row: usize) -> Self {
        Self { split_at: Some(row), ..Self::default() }
    }

    fn chunk(&self) -> usize {
        if self.chunk_rows != 0 {
            self.chunk_rows
        } else if self.tuning.enabled(Optimisation::RowChunks) {
            ROW_CHUNK
        } else {
            usize::MAX
        }
    }

    /// Columns projected anew in the last [`Compliance::accumulate_along`] (the second call in a row to force them
    /// along the same direction), and those it streamed projected.
    pub fn columns_projected(&self) -> (usize, usize) {
        (self.projected.built, self.proj.len())
    }

    /// Seconds the last [`Compliance::accumulate`] spent gathering those rows.
    pub fn gather_seconds(&self) -> f64 {
        self.gather_seconds
    }

    /// Bytes reserved (partial sums, kept and spare rows): flat once the frames' force sets have been seen.
    pub fn bytes(&self) -> usize {
        8 * (self.acc[0].capacity() + self.acc[1].capacity()) + self.rows32.bytes() + self.rows64.bytes() + self.projected.bytes()
    }
}

/// Rows `K^-1[c, s..c]` (`s` = [`Layout::upper_start`]; 3x3 blocks as stored) of the last call's forced columns,
/// in the order of its forces.
#[derive(Debug, Default)]
struct RowStore<T> {
    cols: Vec<usize>,
    rows: Vec<Vec<T>>,
    next_cols: Vec<usize>,
    next_rows: Vec<Vec<T>>,
    spare: Vec<Vec<T>>,
    /// Indices of the rows the last call gathered.
    fresh: Vec<usize>,
}

/// From this many blocks gathered in one call, the rows are gathered on two threads ([`crate::par::join`]): a
/// first contact on the refined default scene gathers about 38,000, a steady frame a few hundred.
const SPLIT_GATHER_FROM_BLOCKS: usize = 16 * 1024;

impl<T: Copy> RowStore<T> {
    fn bytes(&self) -> usize {
        let rows: usize = self.rows.iter().chain(&self.spare).map(Vec::capacity).sum();
        rows * std::mem::size_of::<T>()
    }

    fn clear(&mut self) {
        self.spare.extend(self.rows.drain(..));
        self.cols.clear();
    }

    /// The spare buffer with the smallest capacity of at least `len` (else the
    /// largest), so that in a steady state gathering allocates nothing.
    fn take_spare(&mut self, len: usize) -> Vec<T> {
        let mut best: Option<usize> = None;
        for (k, b) in self.spare.iter().enumerate() {
            let better = match best {
                None => true,
                Some(j) => {
                    let (cap, best_cap) = (b.capacity(), self.spare[j].capacity());
                    if best_cap >= len { cap >= len && cap < best_cap } else { cap > best_cap }
                }
            };
            if better {
                best = Some(k);
            }
        }
        best.map(|k| self.spare.swap_remove(k)).unwrap_or_default()
    }

    /// Makes `rows[k]` the row of `forces[k].0` (ascending): rows kept from the last call are moved (when `keep`),
    /// missing ones gathered (on two threads from `split_from` blocks on). Returns how many were gathered.
    fn prepare<'a>(&mut self, region: &(impl Fn(usize) -> (&'a [T], usize) + Sync), layout: &Layout, forces: &[(usize, Vec3)], keep: bool, split_from: Option<usize>) -> usize
    where
        T: 'a + Send + Sync,
    {
        if !keep {
            self.clear();
        }
        self.next_cols.clear();
        self.next_rows.clear();
        self.fresh.clear();
        let mut k = 0;
        for &(c, _) in forces {
            while k < self.cols.len() && self.cols[k] < c {
                self.spare.push(std::mem::take(&mut self.rows[k]));
                k += 1;
            }
            let row = if k < self.cols.len() && self.cols[k] == c {
                k += 1;
                std::mem::take(&mut self.rows[k - 1])
            } else {
                let len = 9 * (c - layout.upper_start(c));
                let mut row = self.take_spare(len);
                row.clear();
                if row.capacity() < len {
                    // Power-of-two capacities: a spare fits most later rows, so the pool stops allocating.
                    row.reserve_exact(len.next_power_of_two());
                }
                self.fresh.push(self.next_rows.len());
                row
            };
            self.next_cols.push(c);
            self.next_rows.push(row);
        }
        for row in &mut self.rows[k..] {
            self.spare.push(std::mem::take(row));
        }
        std::mem::swap(&mut self.cols, &mut self.next_cols);
        std::mem::swap(&mut self.rows, &mut self.next_rows);
        self.gather_fresh(region, layout, split_from);
        self.fresh.len()
    }

    /// Gathers the rows listed in `fresh` (empty, with room): `K^-1[c, s..c]`, one strided block at a time. From
    /// `split_from` blocks on, on two threads, split where half of them have been gathered.
    fn gather_fresh<'a>(&mut self, region: &(impl Fn(usize) -> (&'a [T], usize) + Sync), layout: &Layout, split_from: Option<usize>)
    where
        T: 'a + Send + Sync,
    {
        let gather = |row: &mut Vec<T>, c: usize| {
            let (v, base) = region(layout.row_comp[c] as usize);
            for i in layout.upper_start(c)..c {
                let o = (layout.col_off[i] + c - i - base) * 9;
                row.extend_from_slice(&v[o..o + 9]);
            }
        };
        let blocks = |k: usize| self.cols[k] - layout.upper_start(self.cols[k]);
        let total: usize = self.fresh.iter().map(|&k| blocks(k)).sum();
        let (fresh, cols) = (&self.fresh, &self.cols);
        if split_from.is_none_or(|m| total < m.max(1)) {
            for &k in fresh {
                gather(&mut self.rows[k], cols[k]);
            }
            return;
        }
        // the first fresh row at or past half the blocks starts the second thread's share
        let mut seen = 0;
        let half = fresh.iter().position(|&k| {
            seen += blocks(k);
            2 * seen > total
        });
        let at = half.map_or(fresh.len(), |h| h + 1).min(fresh.len());
        let mid = fresh.get(at).copied().unwrap_or(self.rows.len());
        let (lo, hi) = self.rows.split_at_mut(mid);
        crate::par::join(
            || fresh[..at].iter().for_each(|&k| gather(&mut lo[k], cols[k])),
            || fresh[at..].iter().for_each(|&k| gather(&mut hi[k - mid], cols[k])),
        );
    }
}

/// `out[e] += run_k[e] * p_k[e % 9]` for `k = 0..N` in order, over runs of whole 3x3 blocks: `p_k` is column `k`'s
/// force laid out as `f[(e % 9) / 3]` (lower part: the block column's force component) or `f[e % 3]` (upper part:
/// the transposed block). Each `out[e]` receives its N products one after the other, as N calls with one run
/// would, so the bits do not depend on N; a larger N keeps `out[e]` in a register and streams N columns at once
/// (one column at a time, the product is bound by switching streams). A flat loop the compiler vectorizes (the
/// pattern repeats every 9 entries, so it is unrolled to 72 = lcm(9, 8)).
#[inline(always)]
fn add_scaled_runs<T: Entry, const N: usize>(out: &mut [f64], runs: [&[T]; N], pattern9: [[f64; 9]; N]) {
    let mut pattern = [[0.0f64; 72]; N];
    for (p, p9) in pattern.iter_mut().zip(&pattern9) {
        for (e, x) in p.iter_mut().enumerate() {
            *x = p9[e % 9];
        }
    }
    let len = out.len();
    let whole = len / 72 * 72;
    let mut i = 0;
    while i < whole {
        let o = &mut out[i..i + 72];
        let r: [&[T]; N] = std::array::from_fn(|k| &runs[k][i..i + 72]);
        for e in 0..72 {
            let mut x = o[e];
            for k in 0..N {
                x += r[k][e].f() * pattern[k][e];
            }
            o[e] = x;
        }
        i += 72;
    }
    for e in whole..len {
        let mut x = out[e];
        for k in 0..N {
            x += runs[k][e].f() * pattern9[k][e % 9];
        }
        out[e] = x;
    }
}

/// Columns streamed together by the surface product (see [`add_scaled_runs`]).
const FUSED_COLUMNS: usize = 8;

/// Adds `count` columns in order (`run(i)` covering `out`, `pattern(i)`): groups of [`FUSED_COLUMNS`], then singly.
#[inline(always)]
fn add_columns<'a, T: Entry + 'a>(out: &mut [f64], count: usize, fused: bool, run: impl Fn(usize) -> &'a [T], pattern: impl Fn(usize) -> [f64; 9]) {
    let mut i = 0;
    while fused && i + FUSED_COLUMNS <= count {
        let runs: [&[T]; FUSED_COLUMNS] = std::array::from_fn(|k| run(i + k));
        let pats: [[f64; 9]; FUSED_COLUMNS] = std::array::from_fn(|k| pattern(i + k));
        add_scaled_runs::<T, FUSED_COLUMNS>(out, runs, pats);
        i += FUSED_COLUMNS;
    }
    while i < count {
        add_scaled_runs::<T, 1>(out, [run(i)], [pattern(i)]);
        i += 1;
    }
}

/// The first `rows` rows of 9 partials of `acc`, zeroed, and their length.
#[inline(always)]
fn zeroed_partials(acc: &mut [f64], rows: usize) -> (usize, &mut [f64]) {
    let out = &mut acc[..9 * rows];
    out.iter_mut().for_each(|a| *a = 0.0);
    (9 * rows, out)
}

/// `u[i] += ` the 9 partials of row i summed by block row (`e % 3`).
#[inline(always)]
fn flush_lower(u: &mut [Vec3], partials: &[f64]) {
    for (ui, p) in u.iter_mut().zip(partials.chunks_exact(9)) {
        *ui += Vec3::new(p[0] + p[3] + p[6], p[1] + p[4] + p[7], p[2] + p[5] + p[8]);
    }
}

#[inline(always)]
fn lower_pattern(f: &Vec3) -> [f64; 9] {
    [f.x, f.x, f.x, f.y, f.y, f.y, f.z, f.z, f.z]
}

#[inline(always)]
fn upper_pattern(f: &Vec3) -> [f64; 9] {
    [f.x, f.y, f.z, f.x, f.y, f.z, f.x, f.y, f.z]
}

/// The surface product kernel, per component (forced columns of another component add nothing to its rows).
/// Lower part (rows `i >= c` of each forced column `c`, its two runs of 3x3 blocks, [`Layout::runs`]): each entry
/// times its block column's force component goes into 9 partials a row (`acc[9 i + e] += v[e] f[e / 3]`), summed
/// into `u` at the end of a chunk of rows. Upper part (ROI rows `upper_start(c) <= i < c`): the transposed blocks
/// from the gathered row of `c` (`rows[k]` for `forces[k]`), likewise with `f[e % 3]`. Rows go in chunks of
/// [`ROW_CHUNK`] within one component's ROI or other rows; in a chunk, the columns covering all of it stream
/// together ([`add_columns`]) and those whose diagonal falls inside go one by one, so every row sums its forces
/// in ascending column order. No fused multiply-add: SIMD and scalar builds give the same bits.
#[inline(always)]
fn accumulate_kernel<'a, T: Entry + 'a, R: Fn(usize) -> (&'a [T], usize)>(p: Product<'_, R, T>, u: &mut [Vec3], acc: &mut Vec<f64>, chunk: usize, window: [usize; 2]) {
    let Product { region, layout, forces, rows, proj, pvals, tuning } = p;
    let fused = tuning.enabled(Optimisation::FusedColumns);
    acc.clear();
    acc.resize(9 * chunk, 0.0);
    // `u` holds rows `window[0]..window[1]`; each range below is clipped to them (a row's sums do not depend on
    // where its chunk starts).
    let clip = |a: usize, b: usize| (a.max(window[0]), b.min(window[1]));
    let w0 = window[0];
    for (k, s) in layout.spans.iter().enumerate() {
        let p_lo = proj.partition_point(|f| f.0 < s[0]);
        let p_hi = proj.partition_point(|f| f.0 < s[1]);
        let f_lo = forces.partition_point(|f| f.0 < s[0]);
        let f_hi = forces.partition_point(|f| f.0 < s[1]);
        if f_lo == f_hi {
            add_projected(&proj[p_lo..p_hi], pvals.part(p_lo..p_hi), s, window, u, acc, chunk, fused);
            continue;
        }
        // This component's storage, from its first column's block `base` on.
        let (v, base) = region(k);
        let col_off = |c: usize| layout.col_off[c] - base;
        let fk = &forces[f_lo..f_hi];
        let rows_k = &rows[f_lo..f_hi];
        // Lower part, ROI rows: columns c <= r0 cover the chunk, r0 < c < r1 its rows from c on.
        let (mut r0, end) = clip(s[0], s[1]);
        while r0 < end {
            let r1 = (r0 + chunk).min(end);
            let (len, out) = zeroed_partials(acc, r1 - r0);
            let n_full = fk.partition_point(|f| f.0 <= r0);
            let n_part = fk.partition_point(|f| f.0 < r1);
            add_columns(
                out,
                n_full,
                fused,
                |i| {
                    let o = 9 * (col_off(fk[i].0) + r0 - fk[i].0);
                    &v[o..o + len]
                },
                |i| lower_pattern(&fk[i].1),
            );
            for &(c, f) in &fk[n_full..n_part] {
                let o = 9 * col_off(c);
                add_scaled_runs::<T, 1>(&mut out[9 * (c - r0)..], [&v[o..o + 9 * (r1 - c)]], [lower_pattern(&f)]);
            }
            flush_lower(&mut u[r0 - w0..r1 - w0], out);
            r0 = r1;
        }
        // Lower part, the component's other rows: every column covers every chunk.
        let (mut r0, end) = clip(s[2], s[3]);
        while r0 < end {
            let r1 = (r0 + chunk).min(end);
            let (len, out) = zeroed_partials(acc, r1 - r0);
            add_columns(
                out,
                fk.len(),
                fused,
                |i| {
                    let c = fk[i].0;
                    let o = 9 * (col_off(c) + (s[1] - c) + (r0 - s[2]));
                    &v[o..o + len]
                },
                |i| lower_pattern(&fk[i].1),
            );
            flush_lower(&mut u[r0 - w0..r1 - w0], out);
            r0 = r1;
        }
        let (lo, top) = clip(s[0], fk[fk.len() - 1].0);
        if lo < top {
            add_upper(fk, rows_k, s[0], [lo, top], &mut u[lo - w0..], acc, chunk, fused);
        }
        add_projected(&proj[p_lo..p_hi], pvals.part(p_lo..p_hi), s, window, u, acc, chunk, fused);
    }
}

/// The projected columns of one component (span `s`) over rows `window` (`u` holds them): `u[i] += sum_k
/// P_k[i] lambda_k`, the columns in ascending order into 3 partials a row (after the blocks' sums).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn add_projected(pk: &[(usize, f64)], vals: Projections<'_>, s: &[usize; 4], window: [usize; 2], u: &mut [Vec3], acc: &mut [f64], chunk: usize, fused: bool) {
    if pk.is_empty() {
        return;
    }
    // Rows of the projections: the ROI rows from s[0], then the other rows from s[2] at s[1] - s[0].
    for (first, end, at) in [(s[0], s[1], 0), (s[2], s[3], s[1] - s[0])] {
        let (mut r0, end) = (first.max(window[0]), end.min(window[1]));
        while r0 < end {
            let r1 = (r0 + chunk).min(end);
            let len = 3 * (r1 - r0);
            let out = &mut acc[..len];
            out.iter_mut().for_each(|a| *a = 0.0);
            let o = 3 * (at + r0 - first);
            add_columns(out, pk.len(), fused, |k| vals.run(k, o, len), |k| [pk[k].1; 9]);
            for (ui, a) in u[r0 - window[0]..r1 - window[0]].iter_mut().zip(out.chunks_exact(3)) {
                *ui += Vec3::new(a[0], a[1], a[2]);
            }
            r0 = r1;
        }
    }
}

/// The upper part of one component's product (ROI rows `s0 <= i < c` of each forced column `c`) from `rows_k`,
/// over rows `range` (within `s0..` the last forced column); `u` starts at row `range[0]`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn add_upper<T: Entry>(fk: &[(usize, Vec3)], rows_k: &[Vec<T>], s0: usize, range: [usize; 2], u: &mut [Vec3], acc: &mut [f64], chunk: usize, fused: bool) {
    // Columns r0 < c < r1 cover [r0, c); columns c >= r1 the whole chunk.
    let [mut r0, top] = range;
    let w0 = range[0];
    while r0 < top {
        let r1 = (r0 + chunk).min(top);
        let (len, out) = zeroed_partials(acc, r1 - r0);
        let first = fk.partition_point(|f| f.0 <= r0);
        let n_part = fk.partition_point(|f| f.0 < r1);
        let o = 9 * (r0 - s0);
        for (&(c, f), row) in fk[first..n_part].iter().zip(&rows_k[first..n_part]) {
            add_scaled_runs::<T, 1>(&mut out[..9 * (c - r0)], [&row[o..9 * (c - s0)]], [upper_pattern(&f)]);
        }
        let (fu, ru) = (&fk[n_part..], &rows_k[n_part..]);
        add_columns(out, fu.len(), fused, |i| &ru[i][o..o + len], |i| upper_pattern(&fu[i].1));
        for (ui, a) in u[r0 - w0..r1 - w0].iter_mut().zip(out.chunks_exact(9)) {
            // the transposed blocks: partial e belongs to component e / 3
            *ui += Vec3::new(a[0] + a[1] + a[2], a[3] + a[4] + a[5], a[6] + a[7] + a[8]);
        }
        r0 = r1;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2<'a, T: Entry + 'a, R: Fn(usize) -> (&'a [T], usize)>(p: Product<'_, R, T>, u: &mut [Vec3], acc: &mut Vec<f64>, chunk: usize, window: [usize; 2]) {
    accumulate_kernel(p, u, acc, chunk, window)
}

/// What the surface product reads: each component's storage (`region(k)`: its final columns and their first
/// block's offset), the layout, the forces `(column, F)` ascending, and `rows[k]`, the gathered row of `forces[k]`.
struct Product<'p, R, T> {
    region: &'p R,
    layout: &'p Layout,
    forces: &'p [(usize, Vec3)],
    rows: &'p [Vec<T>],
    /// Columns forced along their one direction `(col, lambda)`, ascending, and their projections (same order).
    proj: &'p [(usize, f64)],
    pvals: Projections<'p>,
    tuning: Tuning,
}

/// The projections of [`Product::proj`]'s columns: slot `slots[k]` of `slab`, `len` values a slot.
#[derive(Clone, Copy)]
struct Projections<'p> {
    slab: &'p [f64],
    slots: &'p [u32],
    len: usize,
}

impl Projections<'_> {
    /// The projections of columns `range` of the call's list.
    fn part(&self, range: std::ops::Range<usize>) -> Self {
        Self { slots: &self.slots[range], ..*self }
    }

    #[inline(always)]
    fn run(&self, k: usize, from: usize, len: usize) -> &[f64] {
        let at = self.slots[k] as usize * self.len + from;
        &self.slab[at..at + len]
    }
}

impl<R, T> Clone for Product<'_, R, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<R, T> Copy for Product<'_, R, T> {}

/// Below this many (row, forced column) pairs the product runs on one thread (splitting costs more than it saves).
const SPLIT_FROM_PAIRS: usize = 32 * 1024;

/// The row at which the product's work is halved (each row costs its component's forced columns), or `None` when
/// the product is too small to split.
fn split_row(layout: &Layout, forces: &[(usize, Vec3)]) -> Option<usize> {
    let mut total = 0;
    let forced = |s: &[usize; 4]| forces.partition_point(|f| f.0 < s[1]) - forces.partition_point(|f| f.0 < s[0]);
    for s in &layout.spans {
        total += forced(s) * (s[1] - s[0] + s[3] - s[2]);
    }
    if total < SPLIT_FROM_PAIRS {
        return None;
    }
    // Rows lie in that order: every component's ROI rows, then every component's other rows.
    let stretches = layout.spans.iter().map(|s| (s[0], s[1], forced(s))).chain(layout.spans.iter().map(|s| (s[2], s[3], forced(s))));
    let mut seen = 0;
    for (a, b, f) in stretches {
        if f > 0 && 2 * (seen + f * (b - a)) >= total {
            return Some(a + (total / 2 - seen).div_ceil(f).min(b - a));
        }
        seen += f * (b - a);
    }
    None
}

/// Dispatches the kernel to an AVX2 build when the CPU has it (runtime detection, no `RUSTFLAGS`); both builds
/// round identically. (AVX-512 is no faster: the kernel waits on memory.) A large product is split at one row
/// over the calling thread and one beside it (`parallel-product`, [`crate::par::join`]): every row sums the same terms in the same order
/// whichever thread adds it, so the bits do not change.
fn accumulate_impl<'a, T: Entry + Sync + 'a, R: Fn(usize) -> (&'a [T], usize) + Sync>(
    p: Product<'_, R, T>,
    u: &mut [Vec3],
    acc: &mut [Vec<f64>; 2],
    chunk: usize,
    split_at: Option<usize>,
) {
    let wanted = p.tuning.enabled(Optimisation::ParallelProduct) && crate::par::available();
    let split = split_at.or_else(|| wanted.then(|| split_row(p.layout, p.forces)).flatten());
    let Some(m) = split.filter(|&m| m > 0 && m < u.len()) else {
        return accumulate_window(p, u, &mut acc[0], chunk, [0, u.len()]);
    };
    let n = u.len();
    let (ua, ub) = u.split_at_mut(m);
    let [acc_a, acc_b] = acc;
    crate::par::join(|| accumulate_window(p, ua, acc_a, chunk, [0, m]), || accumulate_window(p, ub, acc_b, chunk, [m, n]));
}

/// The kernel over rows `window` (`u` holds them), in its AVX2 build when the CPU has it.
fn accumulate_window<'a, T: Entry + 'a, R: Fn(usize) -> (&'a [T], usize)>(p: Product<'_, R, T>, u: &mut [Vec3], acc: &mut Vec<f64>, chunk: usize, window: [usize; 2]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && p.tuning.enabled(Optimisation::Avx2Product) {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { accumulate_avx2(p, u, acc, chunk, window) };
        return;
    }
    accumulate_kernel(p, u, acc, chunk, window)
}
