//! W's entries between the step's candidate and tether rows, kept across the active-set iterations of one step,
//! and between a blade's face-plane rows across steps ([`RowPairs`]).
//!
//! An iteration adds or releases a few rows and solves again; without this every iteration gathers the whole
//! `s x s` block of W again, `O(s^2)` blocks of `K^-1` (a wide press of a refined mesh holds 150 rows; a rough
//! opening through its tethers iterates 20 to 40 times). A row is known by its identity in the step (a tether's
//! index, or a candidate's after every tether: a demoted hold appends a candidate mid-step), so an entry computed
//! once is read back while both rows keep their definition: a face plane's and a tether's are fixed for the step,
//! a sphere row's changes with its linearization point ([`RowPairs::redefine`]). A face plane's row is also known
//! by its node and normal ([`RowKey`]), which is all its entries depend on: a blade that holds or slides without
//! turning keeps its rows' normals, so the next step reads their entries back instead of gathering the block
//! again (the refined default scene holds 160 such rows frame after frame). Entries are computed by the same code
//! in the same orientation (rows stay in candidate order, which the collision keeps from frame to frame, tethers
//! after), so a kept entry equals a recomputed one bit for bit; a new lazy column changes what `kinv` reads, and
//! clears every entry.
//!
//! Memory: `slots^2` entries for the distinct rows held during a step and the face rows of the two before (a few
//! hundred), reused from step to step.

/// What a face-plane row is across steps: its node and the bits of its unit normal. Its entries against another
/// such row depend on nothing else (but the lazy columns, [`RowPairs::check_generation`]).
pub(super) type RowKey = (u32, [u64; 3]);

/// The kept entries: a slot per row identity that has held a row this step, a square of entries over slots. A
/// face-plane row's slot is also found by its [`RowKey`] and outlives the step while the row comes back in the next
/// ones (a held or sliding blade keeps its face rows frame after frame), so its entries are read once for as long
/// as both rows stay.
#[derive(Debug, Default)]
pub(super) struct RowPairs {
    /// Row identity -> slot (`u32::MAX`: none this step).
    slot_of: Vec<u32>,
    /// Identities given a slot this step (to clear `slot_of` at the next).
    given: Vec<u32>,
    /// Face-plane rows' slots across steps.
    keyed: std::collections::HashMap<RowKey, u32>,
    /// Per slot: the step it was last given in, and whether a key holds it.
    used: Vec<(u64, bool)>,
    /// Slots free to give, highest first (the lowest is given first).
    free: Vec<u32>,
    /// Slots ever given (the square's used rows and columns).
    slots: usize,
    step: u64,
    stride: usize,
    values: Vec<f64>,
    valid: Vec<bool>,
    /// The solver's lazy-column generation the entries were read at.
    generation: u64,
}

/// A keyed slot not given in this many steps is freed.
const KEYED_STEPS: u64 = 2;

impl RowPairs {
    /// Ready for a step with `identities` possible rows: every slot but those of recent face-plane rows freed.
    pub(super) fn begin_step(&mut self, identities: usize, generation: u64) {
        for &id in &self.given {
            if let Some(s) = self.slot_of.get_mut(id as usize) {
                *s = u32::MAX;
            }
        }
        self.given.clear();
        if self.slot_of.len() < identities {
            self.slot_of.resize(identities, u32::MAX);
        }
        self.step += 1;
        let step = self.step;
        let used = &mut self.used;
        self.keyed.retain(|_, s| used[*s as usize].0 + KEYED_STEPS >= step);
        for (s, u) in used.iter_mut().enumerate() {
            if u.0 != u64::MAX && (!u.1 || u.0 + KEYED_STEPS < step) {
                *u = (u64::MAX, false);
                self.free.push(s as u32);
            }
        }
        self.free.sort_unstable_by(|a, b| b.cmp(a));
        self.check_generation(generation);
    }

    /// The slot of row identity `id` (a face-plane row also by its `key`), given one if it has none (its entries
    /// unknown unless the key's slot kept them).
    pub(super) fn slot(&mut self, id: usize, key: Option<RowKey>) -> usize {
        if id >= self.slot_of.len() {
            self.slot_of.resize(id + 1, u32::MAX);
        }
        if self.slot_of[id] != u32::MAX {
            return self.slot_of[id] as usize;
        }
        let kept = key.and_then(|k| self.keyed.get(&k).copied()).filter(|&s| self.used[s as usize].0 != self.step);
        let s = match kept {
            Some(s) => s as usize,
            None => {
                let s = self.new_slot();
                if let Some(k) = key {
                    self.keyed.insert(k, s as u32);
                }
                s
            }
        };
        self.used[s] = (self.step, key.is_some());
        self.slot_of[id] = s as u32;
        self.given.push(id as u32);
        s
    }

    /// A free slot, its entries unknown.
    fn new_slot(&mut self) -> usize {
        let s = match self.free.pop() {
            Some(s) => s as usize,
            None => {
                self.slots += 1;
                self.used.push((u64::MAX, false));
                if self.slots > self.stride {
                    self.grow();
                }
                self.slots - 1
            }
        };
        self.forget_slot(s);
        s
    }

    /// Row identity `id` is defined anew (a sphere row linearized at another point): its entries are unknown.
    pub(super) fn redefine(&mut self, id: usize) {
        if let Some(&s) = self.slot_of.get(id)
            && s != u32::MAX
        {
            self.forget_slot(s as usize);
        }
    }

    /// The lazy columns changed (`generation`): every entry is unknown.
    pub(super) fn check_generation(&mut self, generation: u64) {
        if generation != self.generation {
            self.generation = generation;
            self.valid.iter_mut().for_each(|v| *v = false);
        }
    }

    /// The kept entry between slots `a` and `b` in that orientation (`a`'s row after `b`'s), or `compute()` kept.
    /// The other orientation is not filled: two rows may come in the other order in a later step, and the entry
    /// computed that way may differ in its last bit.
    #[inline]
    pub(super) fn get_or(&mut self, a: usize, b: usize, compute: impl FnOnce() -> f64) -> f64 {
        let i = a * self.stride + b;
        if self.valid[i] {
            return self.values[i];
        }
        let v = compute();
        self.values[i] = v;
        self.valid[i] = true;
        v
    }

    /// The kept entry between slots `a` and `b` (in that orientation), if any.
    #[inline]
    pub(super) fn get(&self, a: usize, b: usize) -> Option<f64> {
        let i = a * self.stride + b;
        self.valid.get(i).is_some_and(|&v| v).then(|| self.values[i])
    }

    /// Whether the entry between slots `a` and `b` (in that orientation) is kept.
    #[inline]
    pub(super) fn has(&self, a: usize, b: usize) -> bool {
        self.valid.get(a * self.stride + b).copied().unwrap_or(false)
    }

    fn forget_slot(&mut self, s: usize) {
        let n = self.stride;
        self.valid[s * n..(s + 1) * n].iter_mut().for_each(|v| *v = false);
        for r in 0..n {
            self.valid[r * n + s] = false;
        }
    }

    /// A wider square (powers of two, at least 64): what was kept is copied over.
    fn grow(&mut self) {
        let old = self.stride;
        let new = self.slots.next_power_of_two().max(64);
        let mut values = vec![0.0; new * new];
        let mut valid = vec![false; new * new];
        for r in 0..old {
            values[r * new..r * new + old].copy_from_slice(&self.values[r * old..(r + 1) * old]);
            valid[r * new..r * new + old].copy_from_slice(&self.valid[r * old..(r + 1) * old]);
        }
        self.values = values;
        self.valid = valid;
        self.stride = new;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_entry_is_computed_once_per_definition_and_step() {
        let mut p = RowPairs::default();
        p.begin_step(10, 0);
        let (a, b) = (p.slot(3, None), p.slot(7, None));
        let mut calls = 0;
        let mut get = |p: &mut RowPairs, x: usize, y: usize, v: f64| {
            p.get_or(x, y, || {
                calls += 1;
                v
            })
        };
        assert_eq!(get(&mut p, a, b, 1.5), 1.5);
        assert_eq!(get(&mut p, b, a, 1.5), 1.5, "the other orientation is computed on its own");
        p.redefine(7);
        assert_eq!(get(&mut p, a, b, 2.5), 2.5, "a redefined row is computed again");
        p.check_generation(1);
        assert_eq!(get(&mut p, a, b, 3.5), 3.5, "new lazy columns: computed again");
        p.begin_step(10, 1);
        let (a, b) = (p.slot(3, None), p.slot(7, None));
        assert_eq!(get(&mut p, a, b, 4.5), 4.5, "a new step starts empty");
        drop(get);
        assert_eq!(calls, 5);
    }

    #[test]
    fn growing_keeps_what_was_kept() {
        let mut p = RowPairs::default();
        p.begin_step(200, 0);
        let first = p.slot(0, None);
        let second = p.slot(1, None);
        p.get_or(first, second, || 7.0);
        for id in 2..150 {
            p.slot(id, None);
        }
        assert_eq!(p.get_or(first, second, || f64::NAN), 7.0);
        assert!(p.stride >= 150);
    }
}
