//! W's entries between the step's candidate and tether rows, kept across the active-set iterations of one step
//! ([`RowPairs`]).
//!
//! An iteration adds or releases a few rows and solves again; without this every iteration gathers the whole
//! `s x s` block of W again, `O(s^2)` blocks of `K^-1` (a wide press of a refined mesh holds 150 rows; a rough
//! opening through its tethers iterates 20 to 40 times). A row is known by its identity in the step (a tether's
//! index, or a candidate's after every tether: a demoted hold appends a candidate mid-step), so an entry computed once is read back while both rows keep their
//! definition: a face plane's and a tether's are fixed for the step, a sphere row's changes with its linearization
//! point ([`RowPairs::redefine`]). Entries are computed by the same code in the same orientation (rows stay in
//! candidate order, tethers after), so a kept entry equals a recomputed one bit for bit; a new lazy column changes
//! what `kinv` reads, and clears every entry.
//!
//! Memory: `slots^2` entries for the distinct rows held during one step (a few hundred), reused from step to step.

/// The kept entries: a slot per row identity that has held a row this step, a square of entries over slots.
#[derive(Debug, Default)]
pub(super) struct RowPairs {
    /// Row identity -> slot (`u32::MAX`: none this step).
    slot_of: Vec<u32>,
    /// Identities given a slot this step (to clear `slot_of` at the next).
    given: Vec<u32>,
    /// Slots in use this step.
    slots: usize,
    stride: usize,
    values: Vec<f64>,
    valid: Vec<bool>,
    /// The solver's lazy-column generation the entries were read at.
    generation: u64,
}

impl RowPairs {
    /// Ready for a step with `identities` possible rows: every slot freed.
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
        self.slots = 0;
        self.generation = generation;
    }

    /// The slot of row identity `id`, given one (its entries unknown) if it has none.
    pub(super) fn slot(&mut self, id: usize) -> usize {
        if id >= self.slot_of.len() {
            self.slot_of.resize(id + 1, u32::MAX);
        }
        if self.slot_of[id] != u32::MAX {
            return self.slot_of[id] as usize;
        }
        let s = self.slots;
        self.slots += 1;
        if self.slots > self.stride {
            self.grow();
        }
        self.forget_slot(s);
        self.slot_of[id] = s as u32;
        self.given.push(id as u32);
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

    /// The kept entry between slots `a` and `b`, or `compute()` kept for both orders.
    #[inline]
    pub(super) fn get_or(&mut self, a: usize, b: usize, compute: impl FnOnce() -> f64) -> f64 {
        let i = a * self.stride + b;
        if self.valid[i] {
            return self.values[i];
        }
        let v = compute();
        let j = b * self.stride + a;
        self.values[i] = v;
        self.values[j] = v;
        self.valid[i] = true;
        self.valid[j] = true;
        v
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
        let (a, b) = (p.slot(3), p.slot(7));
        let mut calls = 0;
        let mut get = |p: &mut RowPairs, x: usize, y: usize, v: f64| {
            p.get_or(x, y, || {
                calls += 1;
                v
            })
        };
        assert_eq!(get(&mut p, a, b, 1.5), 1.5);
        assert_eq!(get(&mut p, b, a, 9.0), 1.5, "the transposed entry is the same");
        p.redefine(7);
        assert_eq!(get(&mut p, a, b, 2.5), 2.5, "a redefined row is computed again");
        p.check_generation(1);
        assert_eq!(get(&mut p, a, b, 3.5), 3.5, "new lazy columns: computed again");
        p.begin_step(10, 1);
        let (a, b) = (p.slot(3), p.slot(7));
        assert_eq!(get(&mut p, a, b, 4.5), 4.5, "a new step starts empty");
        drop(get);
        assert_eq!(calls, 4);
    }

    #[test]
    fn growing_keeps_what_was_kept() {
        let mut p = RowPairs::default();
        p.begin_step(200, 0);
        let first = p.slot(0);
        let second = p.slot(1);
        p.get_or(first, second, || 7.0);
        for id in 2..150 {
            p.slot(id);
        }
        assert_eq!(p.get_or(first, second, || f64::NAN), 7.0);
        assert!(p.stride >= 150);
    }
}
