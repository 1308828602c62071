//! The K^-1 blocks of the contact candidates against the W nodes, kept between frames ([`CandidateBlocks`]): what
//! the active-set loop reads most on a wide contact of a large model, read once for as long as both nodes stay.

use super::*;
use std::mem::MaybeUninit;

/// A compliance above this many bytes keeps its candidates' blocks (a last-level cache is a few tens of MB at most).
pub(super) const CANDIDATE_BLOCKS_FROM_BYTES: usize = 64 << 20;

/// Whether a solver on a `large` compliance (over [`CANDIDATE_BLOCKS_FROM_BYTES`]) keeps its candidates' blocks.
pub(super) fn wanted(large: bool, tuning: Tuning) -> bool {
    large && tuning.enabled(Optimisation::CandidateBlocks)
}

/// The kept blocks: a row per candidate node, a column per W node, in two flat arrays of `stride` columns a row,
/// so it allocates only when the candidates or W nodes pass their high-water mark. A W node keeps its column
/// whatever its slot in the frame's node list (the held set is reordered for the factor every frame), so a block
/// is read once for as long as both nodes stay. A row or column unused this frame and the last is reused.
#[derive(Debug, Default)]
pub(super) struct CandidateBlocks {
    /// Candidate node -> row.
    index: std::collections::HashMap<u32, u32>,
    /// Frame each row was last used in.
    last_used: Vec<u64>,
    free: Vec<u32>,
    /// W node -> column.
    columns: std::collections::HashMap<u32, u32>,
    /// Frame each column was last used in.
    column_used: Vec<u64>,
    column_free: Vec<u32>,
    /// The column of each slot of the solver's node list, for the list at `slots_version`.
    slot_columns: Vec<u32>,
    slots_version: u64,
    /// The frame the rows and columns were last sorted out for.
    frame: u64,
    /// The solver's `lazy_generation` the kept blocks were read at.
    generation: u64,
    stride: usize,
    /// `nodes[row * stride + column]`: the W node whose block is kept there (`u32::MAX`: none).
    nodes: Vec<u32>,
    /// The kept blocks: `blocks[i]` is written exactly when `nodes[i]` names a node, and read only then, so room
    /// for a new row is not zeroed (a first contact's rows are hundreds of blocks wide, most of them never used).
    blocks: Vec<MaybeUninit<Matrix3<f64>>>,
    /// Rows the step may take (its candidates): room is made for them at once ([`Self::expect_rows`]).
    rows_expected: usize,
    /// Blocks read from the compliance so far.
    pub(super) reads: u64,
    /// Per row (as `last_used`): its last evaluation read nothing from the compliance (a row that did asks for its
    /// missing blocks ahead next time).
    complete: Vec<bool>,
    /// An evaluation's displacements made ahead on two threads ([`Self::displace_ahead`]).
    pub(super) ahead: Ahead,
}

/// An evaluation pass's displacements, made ahead on two threads: every node the pass evaluates reads its kept row
/// (a few hundred blocks), row after row, and a wide contact evaluates hundreds of nodes a pass.
#[derive(Debug)]
pub(super) struct Ahead {
    /// The pass's nodes (ascending, distinct) and, once made, their displacements (before: the parts not from the
    /// kept rows).
    pub(super) nodes: Vec<u32>,
    pub(super) u: Vec<Vec3>,
    /// The forces' slots and values (the nonzero ones, by slot).
    pub(super) forced: Vec<(usize, Vec3)>,
    /// Whether `u` holds this pass's displacements.
    ready: bool,
    /// From this many nodes a pass on (tests: 1).
    pub(super) from: usize,
    /// W's gather ahead from this many entries on ([`super::gather::GATHER_AHEAD_FROM`]; tests: 1).
    pub(super) gather_from: usize,
    /// A pass's work lists, kept for their room: each node's kept row and index, by row; the rows' parts.
    order: Vec<(usize, usize)>,
    parts: Vec<(RowPart<'static>, bool)>,
}

impl Default for Ahead {
    fn default() -> Self {
        Self { nodes: Vec::new(), u: Vec::new(), forced: Vec::new(), ready: false, from: AHEAD_FROM_NODES, gather_from: super::gather::GATHER_AHEAD_FROM, order: Vec::new(), parts: Vec::new() }
    }
}

/// Fewer nodes than this in a pass are evaluated one by one: waking the second thread costs about as much as
/// evaluating a few dozen.
pub(super) const AHEAD_FROM_NODES: usize = 48;

/// Rows a thread takes at a time ([`crate::par::for_each_mut`]).
const AHEAD_ROWS_A_CLAIM: usize = 8;

impl Ahead {
    /// The displacement made ahead for `node` in this pass.
    #[inline]
    pub(super) fn get(&self, node: u32) -> Option<Vec3> {
        if !self.ready {
            return None;
        }
        self.nodes.binary_search(&node).ok().map(|k| self.u[k])
    }

    /// The displacements no longer hold (the forces change).
    pub(super) fn expire(&mut self) {
        self.ready = false;
    }
}

/// A kept row, its blocks and the W nodes they belong to, with its node's index in [`Ahead::nodes`], its
/// displacement and the blocks it read.
type RowPart<'a> = (&'a mut [MaybeUninit<Matrix3<f64>>], &'a mut [u32], usize, Vec3, u64);

/// `v` emptied and retyped on its own allocation (an in-place collection: `T` and `U` differ only in lifetimes), so
/// a work list of rows borrowed for one pass keeps its room from pass to pass.
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().map(|_| unreachable!("the vector is empty")).collect()
}

/// `v` lengthened to `len` (when shorter) with entries left unwritten.
fn grow_uninit<T>(v: &mut Vec<MaybeUninit<T>>, len: usize) {
    if len > v.len() {
        v.reserve(len - v.len());
        // SAFETY: the capacity holds `len` entries (just reserved), and a `MaybeUninit` needs no initialisation.
        unsafe { v.set_len(len) };
    }
}

/// Frees the entries of `index` (node -> slot) whose slot was last used before the frame before `frame`.
pub(super) fn hand_on_unused(index: &mut std::collections::HashMap<u32, u32>, last_used: &[u64], free: &mut Vec<u32>, frame: u64) {
    index.retain(|_, k| {
        let keep = last_used[*k as usize] + 1 >= frame;
        if !keep {
            free.push(*k);
        }
        keep
    });
}

impl CandidateBlocks {
    /// Ready for `frame`, the lazy columns at `generation` and the W nodes `slots` (the node list at `version`):
    /// frees the rows and columns unused this frame and the last, and gives every slot a column.
    pub(super) fn prepare(&mut self, frame: u64, generation: u64, slots: &[u32], version: u64) {
        if generation != self.generation {
            // Other lazy columns: start again (a cache).
            self.generation = generation;
            self.clear_rows();
            self.columns.clear();
            self.column_used.clear();
            self.column_free.clear();
            self.slots_version = u64::MAX;
        }
        if frame != self.frame {
            self.frame = frame;
            self.slots_version = u64::MAX;
            hand_on_unused(&mut self.index, &self.last_used, &mut self.free, frame);
            hand_on_unused(&mut self.columns, &self.column_used, &mut self.column_free, frame);
            // Hand out the lowest free columns first: the rows stay short.
            self.column_free.sort_unstable_by(|a, b| b.cmp(a));
        }
        if version == self.slots_version {
            return;
        }
        self.slots_version = version;
        self.slot_columns.clear();
        for &q in slots {
            let c = match self.columns.get(&q) {
                Some(&c) => c,
                None => {
                    let c = match self.column_free.pop() {
                        Some(c) => c,
                        None => {
                            self.column_used.push(0);
                            (self.column_used.len() - 1) as u32
                        }
                    };
                    self.columns.insert(q, c);
                    c
                }
            };
            self.column_used[c as usize] = frame;
            self.slot_columns.push(c);
        }
        if self.column_used.len() > self.stride {
            // More columns than a row holds: wider rows (only the high-water mark grows), each keeping its blocks;
            // rows that hold none yet start again, each allocated when first used.
            let stride = self.column_used.len().next_power_of_two().max(16);
            if self.stride == 0 {
                self.clear_rows();
                self.stride = stride;
            } else {
                self.widen(stride);
            }
        }
    }

    /// Lays every row out at `stride` columns (more than now), in place: the last row moves first, so no row is
    /// overwritten before it has moved; the new columns are empty.
    fn widen(&mut self, stride: usize) {
        let (old, rows) = (self.stride, self.last_used.len());
        self.nodes.resize(rows * stride, u32::MAX);
        grow_uninit(&mut self.blocks, rows * stride);
        for r in (0..rows).rev() {
            self.nodes.copy_within(r * old..(r + 1) * old, r * stride);
            self.blocks.copy_within(r * old..(r + 1) * old, r * stride);
            self.nodes[r * stride + old..(r + 1) * stride].fill(u32::MAX);
        }
        self.stride = stride;
    }

    pub(super) fn clear_rows(&mut self) {
        self.index.clear();
        self.free.clear();
        self.last_used.clear();
        self.nodes.clear();
        self.blocks.clear();
        self.complete.clear();
    }

    /// The step has `rows` candidates: a row store that must grow makes room for that many rows at once.
    pub(super) fn expect_rows(&mut self, rows: usize) {
        self.rows_expected = rows;
    }

    /// Whether the row at `base` read nothing from the compliance when last evaluated.
    pub(super) fn complete(&self, base: usize) -> bool {
        self.complete.get(base / self.stride.max(1)).copied().unwrap_or(false)
    }

    /// Records whether the row at `base` read anything from the compliance in the evaluation just made.
    pub(super) fn set_complete(&mut self, base: usize, complete: bool) {
        if let Some(c) = self.complete.get_mut(base / self.stride.max(1)) {
            *c = complete;
        }
    }

    /// Marks `node`'s row, if it has one, used in `frame`: a candidate the screen skipped keeps its blocks for when
    /// it is evaluated again.
    pub(super) fn touch(&mut self, node: u32, frame: u64) {
        if let Some(&r) = self.index.get(&node) {
            self.last_used[r as usize] = frame;
        }
    }

    /// The first index of `node`'s row (after [`Self::prepare`] for this frame).
    pub(super) fn row(&mut self, node: u32) -> usize {
        let stride = self.stride;
        let r = match self.index.get(&node) {
            Some(&r) => r as usize,
            None => {
                let r = match self.free.pop() {
                    Some(r) => r as usize,
                    None => {
                        self.last_used.push(0);
                        self.complete.push(false);
                        let rows = self.last_used.len();
                        if rows * stride > self.blocks.capacity() {
                            // room for twice the rows the step's candidates can take at once: a first contact's rows,
                            // arriving one by one, are not copied again and again, nor the store later in the
                            // press as other candidates come and go (room not yet used is not touched)
                            let room = (2 * rows.max(self.rows_expected)).next_power_of_two() * stride;
                            self.nodes.reserve_exact(room - self.nodes.len());
                            self.blocks.reserve_exact(room - self.blocks.len());
                        }
                        self.nodes.resize(rows * stride, u32::MAX);
                        grow_uninit(&mut self.blocks, rows * stride);
                        rows - 1
                    }
                };
                self.nodes[r * stride..(r + 1) * stride].fill(u32::MAX);
                self.complete[r] = false;
                self.index.insert(node, r as u32);
                r
            }
        };
        self.last_used[r] = self.frame;
        r * stride
    }
}

/// A kept row's blocks and the W nodes they belong to.
pub(super) type RowSlices<'a> = (&'a mut [MaybeUninit<Matrix3<f64>>], &'a mut [u32]);

impl CandidateBlocks {
    /// The kept rows whose first indices are `bases` (ascending, distinct; each from [`Self::row`] this frame), each
    /// as its slices, in that order; and the column of each slot of the solver's node list.
    pub(super) fn rows_at<'s>(&'s mut self, bases: impl Iterator<Item = usize>, out: &mut Vec<RowSlices<'s>>) -> &'s [u32] {
        let stride = self.stride.max(1);
        let mut chunks = self.blocks.chunks_exact_mut(stride).zip(self.nodes.chunks_exact_mut(stride)).enumerate();
        for base in bases {
            let Some((_, row)) = chunks.by_ref().find(|(i, _)| *i == base / stride) else { break };
            out.push(row);
        }
        &self.slot_columns
    }

    /// Reads `K^-1[p, slot_nodes[slot]]` through a kept row (`row`, from [`Self::rows_at`]), as
    /// [`ConstrainedSolver::kept_block`] does; `reads` counts the blocks read from `src`.
    #[inline(always)]
    pub(super) fn read_through(row: &mut RowSlices<'_>, columns: &[u32], src: KinvSource<'_>, p: u32, q: u32, slot: usize, reads: &mut u64) -> Matrix3<f64> {
        let c = columns[slot] as usize;
        if row.1[c] != q {
            row.0[c] = MaybeUninit::new(src.block(p, q));
            row.1[c] = q;
            *reads += 1;
        }
        // SAFETY: `row.1[c]` names `q`, so `row.0[c]` has been written (with `q`'s block).
        unsafe { row.0[c].assume_init() }
    }

    /// Adds blocks read elsewhere from the compliance to the count.
    pub(super) fn count_reads(&mut self, reads: u64) {
        self.reads += reads;
    }

    /// Makes `ahead.u` for `ahead.nodes` from the parts given there: `u += K^-1[node, slot] f` over `ahead.forced`
    /// in slot order, through the kept rows, as [`ConstrainedSolver::displacement_of`] makes it (the same bits),
    /// half the rows on a second thread ([`crate::par::join`]). A row reads from `src` the blocks it lacks (asked for
    /// first, where `prefetch` and its last evaluation read any) and records whether it read any.
    pub(super) fn displace_ahead(&mut self, src: KinvSource<'_>, slot_nodes: &[u32], prefetch: bool) {
        let stride = self.stride;
        self.ahead.ready = false;
        if stride == 0 || self.ahead.u.len() != self.ahead.nodes.len() {
            return;
        }
        let mut rows = std::mem::take(&mut self.ahead.order);
        rows.clear();
        for k in 0..self.ahead.nodes.len() {
            let base = self.row(self.ahead.nodes[k]);
            rows.push((base / stride, k));
        }
        rows.sort_unstable();
        let mut parts: Vec<(RowPart<'_>, bool)> = recycle(std::mem::take(&mut self.ahead.parts));
        let complete = &self.complete;
        let Ahead { nodes: ahead_nodes, u, forced, .. } = &self.ahead;
        let mut chunks = self.blocks.chunks_exact_mut(stride).zip(self.nodes.chunks_exact_mut(stride)).enumerate();
        for &(r, k) in &rows {
            let Some((_, (blocks, nodes))) = chunks.by_ref().find(|(i, _)| *i == r) else { break };
            parts.push(((blocks, nodes, k, u[k], 0), complete.get(r).copied().unwrap_or(false)));
        }
        let slot_columns = &self.slot_columns;
        let run = |part: &mut (RowPart<'_>, bool)| {
            {
                let ((blocks, nodes, k, u, reads), complete) = part;
                let p = ahead_nodes[*k];
                if !*complete && prefetch {
                    for &(slot, _) in forced.iter() {
                        if nodes[slot_columns[slot] as usize] != slot_nodes[slot] {
                            src.prefetch(p, slot_nodes[slot]);
                        }
                    }
                }
                for (i, &(slot, f)) in forced.iter().enumerate() {
                    if let Some(&(ahead, _)) = forced.get(i + PREFETCH_AHEAD) {
                        crate::math::prefetch::<{ std::mem::size_of::<Matrix3<f64>>() }, _>(blocks.as_ptr().wrapping_add(slot_columns[ahead] as usize));
                    }
                    let (q, c) = (slot_nodes[slot], slot_columns[slot] as usize);
                    if nodes[c] != q {
                        blocks[c] = MaybeUninit::new(src.block(p, q));
                        nodes[c] = q;
                        *reads += 1;
                    }
                    // SAFETY: `nodes[c]` names `q`, so `blocks[c]` has been written (with `q`'s block).
                    *u += unsafe { blocks[c].assume_init() } * f;
                }
            }
        };
        crate::par::for_each_mut(&mut parts, AHEAD_ROWS_A_CLAIM, run);
        let made = parts.len();
        for (&(r, _), &((_, _, k, u, reads), _)) in rows.iter().zip(&parts) {
            self.ahead.u[k] = u;
            self.reads += reads;
            if let Some(c) = self.complete.get_mut(r) {
                *c = reads == 0;
            }
        }
        self.ahead.ready = made == rows.len();
        self.ahead.parts = recycle(parts);
        self.ahead.order = rows;
    }
}

/// Slots ahead whose kept block [`CandidateBlocks::prefetch`] asks for: about a memory latency's worth of blocks.
pub(super) const PREFETCH_AHEAD: usize = 16;

impl CandidateBlocks {
    /// Asks the CPU to bring the block of `slot` in the row at `base` into cache, if the slot exists. The blocks a
    /// candidate reads lie in the order the W nodes were first seen, not their slots', which the hardware's own
    /// prefetch cannot follow; a hint changes no value.
    #[inline(always)]
    pub(super) fn prefetch(&self, base: usize, slot: usize) {
        if let Some(&c) = self.slot_columns.get(slot) {
            crate::math::prefetch::<{ std::mem::size_of::<Matrix3<f64>>() }, _>(self.blocks.as_ptr().wrapping_add(base + c as usize));
        }
    }

    /// Whether the row at `base` keeps the block of `slot`, node `q` (a read of it would not go to the compliance).
    #[inline]
    pub(super) fn holds(&self, base: usize, slot: usize, q: u32) -> bool {
        self.slot_columns.get(slot).is_some_and(|&c| self.nodes.get(base + c as usize) == Some(&q))
    }
}

impl ConstrainedSolver {
    /// Hints the cache with the compliance block [`Self::kinv`]`(p, q)` reads ([`KinvSource::prefetch`]). Its
    /// callers' loops run only with `prefetch-blocks` on.
    #[inline]
    pub(super) fn prefetch_kinv(&self, p: u32, q: u32) {
        self.kinv_source().prefetch(p, q);
    }

    /// `K^-1[p, nodes[slot]]` through the kept blocks; `base` is `p`'s row (after [`CandidateBlocks::prepare`]).
    /// A block read from the compliance counts in [`CandidateBlocks::reads`]. (Returned by value from the kept row,
    /// inlined: how the block reaches the caller's product decides the candidates' evaluation time.)
    #[inline(always)]
    pub(super) fn kept_block(&self, kept: &mut CandidateBlocks, base: usize, p: u32, slot: usize) -> Matrix3<f64> {
        let q = self.sys.nodes[slot];
        let i = base + kept.slot_columns[slot] as usize;
        if kept.nodes[i] != q {
            kept.blocks[i] = MaybeUninit::new(self.kinv(p, q));
            kept.nodes[i] = q;
            kept.reads += 1;
        }
        // SAFETY: `nodes[i]` names `q`, so `blocks[i]` has been written (with `q`'s block).
        unsafe { kept.blocks[i].assume_init() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes block `K[p, q] = (p * 1000 + q) I` where `p`'s row meets `q`'s column.
    fn fill(store: &mut CandidateBlocks, candidates: &[u32], slots: &[u32]) {
        for &p in candidates {
            let base = store.row(p);
            for (slot, &q) in slots.iter().enumerate() {
                let i = base + store.slot_columns[slot] as usize;
                store.nodes[i] = q;
                store.blocks[i] = MaybeUninit::new(Matrix3::identity() * (p * 1000 + q) as f64);
            }
        }
    }

    #[test]
    fn a_recycled_work_list_keeps_its_room() {
        let v: Vec<(&mut [u32], u64, bool)> = Vec::with_capacity(40);
        let (at, room) = (v.as_ptr() as usize, v.capacity());
        let w: Vec<(&mut [u32], u64, bool)> = recycle(v);
        assert_eq!((w.as_ptr() as usize, w.capacity(), w.len()), (at, room, 0));
    }

    #[test]
    fn rows_arriving_one_by_one_do_not_move_the_store() {
        let mut store = CandidateBlocks::default();
        let w: Vec<u32> = (1000..1150).collect();
        store.prepare(1, 0, &w, 1);
        store.expect_rows(300);
        store.row(0);
        let at = store.blocks.as_ptr();
        for node in 1..300 {
            store.row(node);
        }
        assert_eq!(store.blocks.as_ptr(), at, "a first contact's 300 candidates copied the store as it grew");
        assert_eq!(store.blocks.len(), 300 * store.stride);
    }

    #[test]
    fn a_row_is_complete_only_once_evaluated_without_reads() {
        let mut store = CandidateBlocks::default();
        let w: Vec<u32> = (100..110).collect();
        store.prepare(1, 0, &w, 1);
        let base = store.row(7);
        assert!(!store.complete(base), "a new row lacks its blocks");
        store.set_complete(base, true);
        assert!(store.complete(base));
        // unused for two frames, the row is handed to another candidate: it starts empty again
        store.prepare(4, 0, &w, 2);
        let other = store.row(8);
        assert_eq!(other, base);
        assert!(!store.complete(other));
    }

    #[test]
    fn rows_widened_for_more_w_nodes_keep_their_blocks() {
        let mut store = CandidateBlocks::default();
        let candidates = [5u32, 9, 12];
        let first: Vec<u32> = (100..110).collect();
        store.prepare(1, 0, &first, 1);
        fill(&mut store, &candidates, &first);
        assert_eq!(store.stride, 16);
        // 40 W nodes: the rows widen to 64 columns
        let more: Vec<u32> = (100..140).collect();
        store.prepare(2, 0, &more, 2);
        assert_eq!(store.stride, 64);
        for &p in &candidates {
            let base = store.row(p);
            for (slot, &q) in more.iter().enumerate() {
                let i = base + store.slot_columns[slot] as usize;
                if q < 110 {
                    assert_eq!(store.nodes[i], q, "candidate {p}: the block of {q} is kept");
                    // SAFETY: the slot names `q`, so `fill` wrote it
                    assert_eq!(unsafe { store.blocks[i].assume_init() }, Matrix3::identity() * (p * 1000 + q) as f64);
                } else {
                    assert_eq!(store.nodes[i], u32::MAX, "candidate {p}: {q}'s column starts empty");
                }
            }
        }
    }
}
