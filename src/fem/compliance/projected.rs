//! Forced columns projected on their one direction, kept from call to call ([`ProjectedStore`]): the surface
//! product's third of the memory traffic for a node held by a single row.
//!
//! A node a blade rests on by one face-plane row carries the force `F = n lambda` along the face's normal `n`, and
//! adds `K^-1[rows, c] n lambda` to the surface: with `P = K^-1[rows, c] n` (3 values a row instead of a 3x3 block)
//! kept while the node stays forced along the same `n`, a frame streams a third of the bytes. A blade that holds
//! or slides without turning keeps its normals frame after frame; one that turns changes them every frame, and
//! building `P` would cost more than the plain product, so a column is projected only from the second call in a
//! row that forces it along the same normal (the first takes the 3x3 blocks), and at most
//! [`PROJECTIONS_PER_CALL`] anew a call. The rule depends on the calls
//! before, never on timing: replays stay bit for bit the same. `P` rounds differently from the blocks times `F`,
//! so the surface's last bits differ from the plain product's (that frame's contact forces do not: they come before
//! it; later frames see the surface through the collision).
//! Stays true: in a steady state nothing is allocated (the slab and the lists are reused).

use super::Layout;
use super::product::Entry;
use crate::math::{Vec3, bits3};

/// At most this many columns are projected anew in one call; the others wait for a later one on the 3x3 blocks. A
/// projection reads the whole column (its upper part strided), about 50 us on the refined default scene: a blade
/// settling on 150 vertices at once would otherwise spend 7 ms of one frame on them.
pub const PROJECTIONS_PER_CALL: usize = 16;

/// A direction by its bits (a normal is the same when its bits are).
type DirBits = [u64; 3];

/// The projected columns of the last call, ascending, and those asked for along a direction but not yet projected.
/// The projections lie in one slab of equal slots (the largest component's length), so the store allocates only
/// when the slab doubles.
#[derive(Debug, Default)]
pub(super) struct ProjectedStore {
    cols: Vec<(usize, DirBits)>,
    /// `slots[k]`: the slab slot of `cols[k]`'s projection `K^-1[rows of the component, cols[k]] n` (3 values a row,
    /// the component's ROI rows, then its other rows).
    pub(super) slots: Vec<u32>,
    /// (column, direction) asked in the last call and taken by the blocks.
    pending: Vec<(usize, DirBits)>,
    next_cols: Vec<(usize, DirBits)>,
    next_slots: Vec<u32>,
    next_pending: Vec<(usize, DirBits)>,
    pub(super) slab: Vec<f64>,
    /// Values a slot (0 until the first projection).
    pub(super) slot_len: usize,
    free: Vec<u32>,
    /// Columns projected anew in the last call.
    pub(super) built: usize,
    /// Their slots, columns and directions, projected once the call's slots are handed out.
    builds: Vec<(u32, usize, Vec3)>,
}

impl ProjectedStore {
    pub(super) fn clear(&mut self) {
        self.cols.clear();
        self.slots.clear();
        self.pending.clear();
        self.free.clear();
        self.slab.clear();
        self.slot_len = 0;
    }

    pub(super) fn bytes(&self) -> usize {
        8 * self.slab.capacity()
    }

    /// A free slot of the slab (the slab grows by doubling when none is).
    fn take_slot(&mut self, layout: &Layout) -> u32 {
        if self.slot_len == 0 {
            self.slot_len = (0..layout.spans.len()).map(|k| component_len(layout, k)).max().unwrap_or(0);
        }
        if let Some(s) = self.free.pop() {
            return s;
        }
        let s = self.slab.len() / self.slot_len.max(1);
        self.slab.resize(self.slab.len() + self.slot_len, 0.0);
        s as u32
    }

    /// Splits `along` (`(column, unit n, lambda)`, ascending) into the columns projected this call (`proj`:
    /// `(column, lambda)`, in the order of [`Self::slots`]) and those taken by the blocks (`full`, as `n lambda`,
    /// ascending), building the newly projected ones from the storage.
    /// Two or more new projections go on two threads when `split` ([`crate::par::join`]).
    pub(super) fn prepare<'a, T: Entry + Send + Sync + 'a>(
        &mut self,
        region: &(impl Fn(usize) -> (&'a [T], usize) + Sync),
        layout: &Layout,
        along: &[(usize, Vec3, f64)],
        full: &mut Vec<(usize, Vec3)>,
        proj: &mut Vec<(usize, f64)>,
        split: bool,
    ) {
        self.next_cols.clear();
        self.next_slots.clear();
        self.next_pending.clear();
        full.clear();
        proj.clear();
        self.built = 0;
        self.builds.clear();
        let mut k = 0;
        for &(c, n, lambda) in along {
            let key = (c, bits3(&n));
            while k < self.cols.len() && self.cols[k].0 < c {
                self.free.push(self.slots[k]);
                k += 1;
            }
            let slot = if k < self.cols.len() && self.cols[k] == key {
                k += 1;
                Some(self.slots[k - 1])
            } else if self.built < PROJECTIONS_PER_CALL && self.pending.binary_search(&key).is_ok() {
                let slot = self.take_slot(layout);
                self.builds.push((slot, c, n));
                self.built += 1;
                Some(slot)
            } else {
                None
            };
            match slot {
                Some(slot) => {
                    self.next_cols.push(key);
                    self.next_slots.push(slot);
                    proj.push((c, lambda));
                }
                None => {
                    self.next_pending.push(key);
                    full.push((c, n * lambda));
                }
            }
        }
        self.free.extend_from_slice(&self.slots[k..]);
        self.build(region, layout, split);
        std::mem::swap(&mut self.cols, &mut self.next_cols);
        std::mem::swap(&mut self.slots, &mut self.next_slots);
        std::mem::swap(&mut self.pending, &mut self.next_pending);
    }
}

impl ProjectedStore {
    /// Projects the call's new columns into their slots, half of them on a second thread when `split`.
    fn build<'a, T: Entry + Send + Sync + 'a>(&mut self, region: &(impl Fn(usize) -> (&'a [T], usize) + Sync), layout: &Layout, split: bool) {
        let len = self.slot_len;
        let run = |slab: &mut [f64], first: usize, builds: &[(u32, usize, Vec3)]| {
            for &(slot, c, n) in builds {
                let at = slot as usize * len - first;
                project(region, layout, c, &n, &mut slab[at..at + len]);
            }
        };
        if !split || self.builds.len() < 2 {
            run(&mut self.slab, 0, &self.builds);
            return;
        }
        // by slot, so that the two halves write apart in the slab
        self.builds.sort_unstable_by_key(|b| b.0);
        let (a, b) = self.builds.split_at(self.builds.len() / 2);
        let first = b[0].0 as usize * len;
        let (lo, hi) = self.slab.split_at_mut(first);
        crate::par::join(|| run(lo, 0, a), || run(hi, first, b));
    }
}

/// Values in a projection of component `k`'s columns: 3 for each of its rows.
fn component_len(layout: &Layout, k: usize) -> usize {
    let s = layout.spans[k];
    3 * (s[1] - s[0] + s[3] - s[2])
}

/// `out` starts with `K^-1[rows of c's component, c] n`, 3 values a row: the ROI rows (those before `c` from the stored row
/// of `c`, transposed blocks; from `c` on its own column), then the component's other rows.
fn project<'a, T: Entry + 'a>(region: &impl Fn(usize) -> (&'a [T], usize), layout: &Layout, c: usize, n: &Vec3, out: &mut [f64]) {
    let k = layout.row_comp[c] as usize;
    let s = layout.spans[k];
    let (v, base) = region(k);
    let block = |o: usize| -> [f64; 9] { std::array::from_fn(|e| v[(o - base) * 9 + e].f()) };
    let (nx, ny, nz) = (n.x, n.y, n.z);
    let mut at = 0;
    let mut push = |x: f64| {
        out[at] = x;
        at += 1;
    };
    for i in s[0]..c {
        // block (row c, column i) holds K^-1[3i + j, 3c + r] at 3r + j
        let b = block(layout.col_off[i] + c - i);
        for row in 0..3 {
            push(b[3 * row] * nx + b[3 * row + 1] * ny + b[3 * row + 2] * nz);
        }
    }
    let lower = |i: usize| if i < s[1] { layout.col_off[c] + i - c } else { layout.col_off[c] + (s[1] - c) + (i - s[2]) };
    for i in (c..s[1]).chain(s[2]..s[3]) {
        // block (row i, column c) holds K^-1[3i + r, 3c + j] at 3j + r
        let b = block(lower(i));
        for row in 0..3 {
            push(b[row] * nx + b[3 + row] * ny + b[6 + row] * nz);
        }
    }
}
