//! A sub-step's surface into the state: the solver's displacements, the positions, the start's positions and the
//! displacement bound, over the vertices the step changed where it can.
//!
//! In: the solver's [`FrameSolution`] (its [`crate::fem::SurfaceWrites`] say which entries the step wrote), the
//! rest positions, the state. Out: the state's `surface_displacement`, `surface_positions` and `surface_bound_m`,
//! and the start's positions ([`SurfaceSync::copy`]).
//!
//! Why: a step changes the displacement of the vertices with a compliance row and of the far ones it brought up to
//! date, a few thousand of a surface that on a real brain has tens of thousands. A sub-step that rewrote the whole
//! surface read and wrote it five times (the solution, its copy, the positions, their bound, a finiteness check).
//! Stays true: every entry gets the bits the whole pass would give it; the bound only ever exceeds the whole pass's
//! (its users read it as a bound: the rest grid's queries then return more vertices, each tested exactly).

use crate::fem::FrameSolution;
use crate::math::{Vec3, is_finite3};

/// The solution write a state's surface holds ([`SurfaceSync`]); 0: not known. Not part of the state's value: two
/// states compare equal whatever wrote them.
#[derive(Debug, Clone, Copy, Default)]
pub struct SurfaceMark(u64);

impl SurfaceMark {
    /// A state whose surface no copy wrote (its first frame, a copy made for output): the next copy is a whole one.
    pub const NONE: SurfaceMark = SurfaceMark(0);
}

impl PartialEq for SurfaceMark {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// What the last copy left: which solution write the state holds, which vertices it changed, the bound over the
/// vertices without a compliance row.
#[derive(Debug, Default)]
pub struct SurfaceSync {
    /// The stamp of the write last copied (0: none).
    copied: u64,
    /// The vertices the last copy changed (all of them when `last_all`).
    last_changed: Vec<u32>,
    last_all: bool,
    /// Bits of the largest component of any far vertex's displacement written since the last whole copy.
    far_bound: [u64; 3],
}

/// The state's side of a copy.
pub struct SurfaceTarget<'a> {
    pub displacement: &'a mut Vec<Vec3>,
    pub positions: &'a mut Vec<Vec3>,
    pub mark: &'a mut SurfaceMark,
    /// The positions at the start of the sub-step (written here).
    pub previous: &'a mut Vec<Vec3>,
}

impl SurfaceSync {
    /// Copies `solution`'s surface into `target`; returns the new displacement bound (infinite when an entry is
    /// not finite) and whether every displacement is finite. `is_far[v]`: vertex `v` has no compliance row.
    pub fn copy(&mut self, solution: &FrameSolution, rest: &[Vec3], is_far: &[bool], target: SurfaceTarget<'_>) -> (f64, bool) {
        let n = target.positions.len();
        let writes = &solution.surface_writes;
        let fits = target.previous.len() == n && rest.len() == n && target.displacement.len() == n && solution.displacement_surface.len() == n && is_far.len() == n;
        let result = match writes.changed_since() {
            Some((since, changed)) if fits && since != 0 && since == self.copied && target.mark.0 == self.copied => {
                self.copy_changed(solution, changed, rest, is_far, target)
            }
            _ => self.copy_all(solution, rest, is_far, target),
        };
        // A non-finite entry: the next copy is a whole one (this one's entries stand for the error's report).
        self.copied = if result.1 { writes.stamp() } else { 0 };
        result
    }

    /// Every entry, as a sub-step always did: the start's positions are the buffer the positions leave.
    fn copy_all(&mut self, solution: &FrameSolution, rest: &[Vec3], is_far: &[bool], t: SurfaceTarget<'_>) -> (f64, bool) {
        t.displacement.clone_from(&solution.displacement_surface);
        let n = t.positions.len();
        if t.previous.len() == n && rest.len() == n && t.displacement.len() == n {
            // The start's positions become the previous ones, and every entry of the buffer they leave is written below.
            std::mem::swap(t.previous, t.positions);
        } else {
            t.previous.clone_from(t.positions);
        }
        let (mut bound, mut far_bound, mut finite) = ([0u64; 3], [0u64; 3], true);
        for (v, ((p, r), u)) in t.positions.iter_mut().zip(rest).zip(t.displacement.iter()).enumerate() {
            *p = r + u;
            super::rest_grid::add_to_bound(&mut bound, p, r);
            if is_far.get(v).copied().unwrap_or(true) {
                super::rest_grid::add_to_bound(&mut far_bound, p, r);
            }
            finite &= is_finite3(u);
        }
        self.far_bound = far_bound;
        self.last_all = true;
        *t.mark = SurfaceMark(solution.surface_writes.stamp());
        (super::rest_grid::finish_bound(bound), finite)
    }

    /// The entries the step wrote (`changed`); every other one already holds the bits of the write it follows.
    fn copy_changed(&mut self, solution: &FrameSolution, changed: &[u32], rest: &[Vec3], is_far: &[bool], t: SurfaceTarget<'_>) -> (f64, bool) {
        // The start's positions equal the positions except where the last copy changed them.
        if self.last_all {
            t.previous.copy_from_slice(t.positions);
        } else {
            self.last_changed.iter().for_each(|&v| t.previous[v as usize] = t.positions[v as usize]);
        }
        let (mut bound, mut finite) = (self.far_bound, true);
        for &v in changed {
            let v = v as usize;
            let u = solution.displacement_surface[v];
            t.previous[v] = t.positions[v];
            t.displacement[v] = u;
            let p = rest[v] + u;
            t.positions[v] = p;
            super::rest_grid::add_to_bound(&mut bound, &p, &rest[v]);
            if is_far[v] {
                super::rest_grid::add_to_bound(&mut self.far_bound, &p, &rest[v]);
            }
            finite &= is_finite3(&u);
        }
        self.last_all = false;
        self.last_changed.clear();
        self.last_changed.extend_from_slice(changed);
        *t.mark = SurfaceMark(solution.surface_writes.stamp());
        (super::rest_grid::finish_bound(bound), finite)
    }
}
