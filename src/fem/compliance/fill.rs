//! Filling the dense compliance batch after batch (each read from the cache file, or solved with the factor), on
//! the caller's thread (a build that waits) or in the background ([`super::ComputeOptions::background`]).
//!
//! In: the storage, allocated once and never moved ([`Buf`]); the batches of columns in column order and the order
//! to solve them in. Out: per free component, how many of its leading columns are final ([`Fill::ready`]).
//! Stays true: a batch is solved by one thread exactly as a build that waits solves it (or read, checked, from a
//! file such a build wrote), so values never depend on timing. A reader sees only a component's final leading
//! columns (a column's upper entries are rows of the earlier ones) and waits for a column not yet final.

use super::Layout;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};

/// A heap buffer written by the filling threads (each into its own batch's columns) and read, where [`Fill`] says
/// it is final, by any thread. Owns the allocation of the `Vec` it was made from.
pub(super) struct Buf<T> {
    ptr: *mut T,
    len: usize,
    cap: usize,
}

// SAFETY: a `Buf` is a `Vec` whose parts are handed out by the unsafe methods
// below, whose callers keep writers and readers of a range apart.
unsafe impl<T: Send> Send for Buf<T> {}
// SAFETY: as above; shared access only reads through `slice` or writes through
// `slice_mut`, both under their callers' disjointness guarantee.
unsafe impl<T: Send + Sync> Sync for Buf<T> {}

impl<T> Buf<T> {
    pub(super) fn new(v: Vec<T>) -> Self {
        let mut v = std::mem::ManuallyDrop::new(v);
        Self { ptr: v.as_mut_ptr(), len: v.len(), cap: v.capacity() }
    }

    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// The address of element `i`, for a prefetch hint: never read through here (a filling thread may be writing it).
    pub(super) fn addr(&self, i: usize) -> *const T {
        self.ptr.wrapping_add(i)
    }

    /// # Safety
    /// No thread writes into `range` while the slice lives.
    pub(super) unsafe fn slice(&self, range: Range<usize>) -> &[T] {
        assert!(range.start <= range.end && range.end <= self.len, "compliance buffer range {range:?} of {}", self.len);
        // SAFETY: in bounds (asserted); not written meanwhile (the caller's promise).
        unsafe { std::slice::from_raw_parts(self.ptr.add(range.start), range.end - range.start) }
    }

    /// # Safety
    /// No other thread reads or writes `range` while the slice lives.
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn slice_mut(&self, range: Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len, "compliance buffer range {range:?} of {}", self.len);
        // SAFETY: in bounds (asserted); exclusive (the caller's promise).
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.end - range.start) }
    }
}

impl<T> Drop for Buf<T> {
    fn drop(&mut self) {
        // SAFETY: the parts of the `Vec` this was made from, given back once.
        unsafe { drop(Vec::from_raw_parts(self.ptr, self.len, self.cap)) }
    }
}

impl<T> std::fmt::Debug for Buf<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buf").field("len", &self.len).finish()
    }
}

/// Dense entries (column after column, [`Layout`]) and, for f32 storage, the ROI x ROI corrections (else empty).
#[derive(Debug)]
pub(super) struct Dense<T> {
    pub(super) v: Buf<T>,
    pub(super) lo: Buf<i16>,
}

impl<T> Dense<T> {
    /// The whole storage.
    ///
    /// # Safety
    /// Every batch is final (no thread writes anymore).
    pub(super) unsafe fn all(&self) -> (&[T], &[i16]) {
        // SAFETY: nothing is written any more (the caller's promise).
        unsafe { (self.v.slice(0..self.v.len()), self.lo.slice(0..self.lo.len())) }
    }
}

/// Which batches are final, and per free component how many leading columns.
#[derive(Debug)]
pub(super) struct Fill {
    /// Batch starts in column order, then the column count.
    starts: Vec<usize>,
    /// Per component: its columns `[first, end)`.
    comps: Vec<(usize, usize)>,
    /// Per component: leading columns whose batches are final.
    ready: Vec<AtomicUsize>,
    complete: AtomicBool,
    cancelled: AtomicBool,
    columns_done: AtomicUsize,
    /// Batches read from a cache file, and batches solved.
    loaded: AtomicUsize,
    computed: AtomicUsize,
    state: Mutex<FillState>,
    changed: Condvar,
    /// Batches in solving order (column order unless [`Self::solved_in`] says), as the filling threads take them.
    order: Vec<usize>,
}

#[derive(Debug)]
struct FillState {
    done: Vec<bool>,
    error: Option<String>,
    seconds: f64,
    /// Seconds from the filling's start to its latest final batch.
    latest: f64,
}

impl Fill {
    /// `starts`: batch starts in column order (the first is 0).
    pub(super) fn new(layout: &Layout, n_cols: usize, starts: &[usize]) -> Self {
        let comps: Vec<(usize, usize)> = layout.spans.iter().map(|s| (s[0], s[1])).collect();
        let mut all = starts.to_vec();
        all.push(n_cols);
        let complete = starts.is_empty();
        Self {
            ready: comps.iter().map(|&(a, b)| AtomicUsize::new(if complete { b - a } else { 0 })).collect(),
            comps,
            starts: all,
            complete: AtomicBool::new(complete),
            cancelled: AtomicBool::new(false),
            columns_done: AtomicUsize::new(if complete { n_cols } else { 0 }),
            loaded: AtomicUsize::new(0),
            computed: AtomicUsize::new(0),
            state: Mutex::new(FillState { done: vec![false; starts.len()], error: None, seconds: 0.0, latest: 0.0 }),
            changed: Condvar::new(),
            order: (0..starts.len()).collect(),
        }
    }

    /// The order the batches are solved in (a permutation of the batches).
    pub(super) fn solved_in(mut self, order: Vec<usize>) -> Self {
        debug_assert_eq!(order.len(), self.order.len());
        self.order = order;
        self
    }

    /// Waits until `enough(done, columns_done, seconds)` holds, asked again after each final batch (`done`: per
    /// batch, final; `seconds`: from the start to the latest final batch). `Ok(true)` when it did, `Ok(false)` when
    /// every batch is final first, `Err` when the filling failed or was stopped.
    pub(super) fn wait_until(&self, mut enough: impl FnMut(&[bool], usize, f64) -> bool) -> Result<bool, String> {
        let mut state = self.lock();
        loop {
            if let Some(e) = &state.error {
                return Err(e.clone());
            }
            if self.is_complete() {
                return Ok(false);
            }
            if enough(&state.done, self.columns_done(), state.latest) {
                return Ok(true);
            }
            state = self.changed.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// The batches in the order they are solved.
    pub(super) fn order(&self) -> &[usize] {
        &self.order
    }

    /// The batch holding column `col`.
    pub(super) fn batch_of(&self, col: usize) -> usize {
        self.starts.partition_point(|&s| s <= col) - 1
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, FillState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Number of batches.
    pub(super) fn batch_count(&self) -> usize {
        self.starts.len() - 1
    }

    /// Counts a batch read from the cache file.
    pub(super) fn count_loaded(&self) {
        self.loaded.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a batch solved.
    pub(super) fn count_computed(&self) {
        self.computed.fetch_add(1, Ordering::Relaxed);
    }

    /// Batches read from the cache file so far.
    pub(super) fn loaded(&self) -> usize {
        self.loaded.load(Ordering::Relaxed)
    }

    /// Batches solved so far.
    pub(super) fn computed(&self) -> usize {
        self.computed.load(Ordering::Relaxed)
    }

    /// Columns of batch `b`.
    pub(super) fn batch(&self, b: usize) -> Range<usize> {
        self.starts[b]..self.starts[b + 1]
    }

    /// True once every batch is final.
    #[inline]
    pub(super) fn is_complete(&self) -> bool {
        self.complete.load(Ordering::Acquire)
    }

    /// Leading columns of component `k` that are final.
    #[inline]
    pub(super) fn ready(&self, k: usize) -> usize {
        self.ready[k].load(Ordering::Acquire)
    }

    /// Columns final so far (any component).
    pub(super) fn columns_done(&self) -> usize {
        self.columns_done.load(Ordering::Relaxed)
    }

    /// Seconds the filling took (0 until complete).
    pub(super) fn seconds(&self) -> f64 {
        self.lock().seconds
    }

    /// Waits until component `k` has `need` final leading columns; `Err` when the filling failed or stopped first.
    pub(super) fn wait(&self, k: usize, need: usize) -> Result<(), String> {
        if self.ready(k) >= need {
            return Ok(());
        }
        let mut state = self.lock();
        loop {
            if self.ready(k) >= need {
                return Ok(());
            }
            if let Some(e) = &state.error {
                return Err(e.clone());
            }
            state = self.changed.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Marks batch `b` final and moves the ready counts past it.
    pub(super) fn finish_batch(&self, b: usize, seconds_so_far: f64) {
        let mut state = self.lock();
        state.done[b] = true;
        state.latest = seconds_so_far;
        let cols = self.batch(b);
        for (k, &(first, end)) in self.comps.iter().enumerate() {
            if cols.end <= first || cols.start >= end {
                continue;
            }
            // The first batch (in column order) of this component that is not final.
            let from = self.starts.partition_point(|&s| s <= first) - 1;
            let mut upto = end;
            for bb in from..state.done.len() {
                if self.starts[bb] >= end {
                    break;
                }
                if !state.done[bb] {
                    upto = self.starts[bb].max(first);
                    break;
                }
            }
            self.ready[k].store(upto - first, Ordering::Release);
        }
        self.columns_done.fetch_add(cols.len(), Ordering::Relaxed);
        if state.done.iter().all(|&d| d) {
            state.seconds = seconds_so_far;
            self.complete.store(true, Ordering::Release);
        }
        self.changed.notify_all();
    }

    /// Records why the filling stopped; waiting readers get it.
    pub(super) fn fail(&self, reason: String) {
        let mut state = self.lock();
        state.error.get_or_insert(reason);
        self.changed.notify_all();
    }

    /// Asks the filling threads to stop after their current batch (nobody reads the result any more).
    pub(super) fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
        self.fail("the compliance was dropped before it was complete".into());
    }

    pub(super) fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }
}

/// Held by every clone of a background-filling [`super::Compliance`]: when the last one goes, the filling stops.
#[derive(Debug)]
pub(super) struct FillOwner(pub(super) std::sync::Arc<Fill>);

impl Drop for FillOwner {
    fn drop(&mut self) {
        if !self.0.is_complete() {
            self.0.cancel();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout_two_components() -> Layout {
        // ROI rows: 5 of component 0, 3 of component 1; then 2 other rows of each.
        Layout::new(vec![0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 1, 1], 8)
    }

    #[test]
    fn ready_counts_follow_the_leading_final_batches_of_each_component() {
        let layout = layout_two_components();
        // Batches of 2 columns in column order: [0,2) [2,4) [4,6) [6,8); [4,6) straddles the components.
        let fill = Fill::new(&layout, 8, &[0, 2, 4, 6]);
        assert_eq!((fill.ready(0), fill.ready(1)), (0, 0));
        fill.finish_batch(1, 0.0);
        assert_eq!((fill.ready(0), fill.ready(1)), (0, 0), "column 2 waits for columns 0 and 1");
        fill.finish_batch(3, 0.0);
        assert_eq!(fill.ready(1), 0, "component 1 starts in batch 2");
        fill.finish_batch(0, 0.0);
        assert_eq!((fill.ready(0), fill.ready(1)), (4, 0));
        assert!(!fill.is_complete());
        fill.finish_batch(2, 1.5);
        assert_eq!((fill.ready(0), fill.ready(1)), (5, 3));
        assert!(fill.is_complete());
        assert_eq!(fill.columns_done(), 8);
        assert_eq!(fill.seconds(), 1.5);
    }

    #[test]
    fn a_failed_fill_wakes_its_waiters_with_the_reason() {
        let layout = layout_two_components();
        let fill = std::sync::Arc::new(Fill::new(&layout, 8, &[0, 4]));
        let waiter = {
            let fill = std::sync::Arc::clone(&fill);
            std::thread::spawn(move || fill.wait(0, 5))
        };
        fill.finish_batch(0, 0.0);
        fill.fail("out of memory".into());
        assert_eq!(waiter.join().unwrap(), Err("out of memory".to_string()));
        assert_eq!(fill.wait(0, 4), Ok(()), "what is final stays readable");
    }

    #[test]
    fn dropping_the_last_owner_stops_an_incomplete_fill() {
        let layout = layout_two_components();
        let fill = std::sync::Arc::new(Fill::new(&layout, 8, &[0]));
        let owner = std::sync::Arc::new(FillOwner(std::sync::Arc::clone(&fill)));
        let clone = std::sync::Arc::clone(&owner);
        drop(owner);
        assert!(!fill.is_cancelled());
        drop(clone);
        assert!(fill.is_cancelled());
    }
}
