//! Screening the active-set loop's inactive candidates ([`Screen`]): a candidate whose node's displacement, when
//! last evaluated, left it far from its constraint is not evaluated again until the forces have changed enough to
//! reach it, in this frame or a later one (`screen-across-frames`).
//!
//! In: the nodal forces after each solve of W, the diagonal K^-1 blocks of the nodes, each evaluated node's
//! displacement. Out: per candidate, whether its evaluation can be skipped. Stays true: a skipped candidate would
//! have been found not violated, so the loop makes the same decisions and the frame the same bits
//! (`tests/fem_tuning.rs` checks it with either switch off).
//!
//! The bound: K^-1 is symmetric positive definite, so each 3x3 block satisfies
//! `|K^-1[p, q]| <= sqrt(|K^-1[p, p]| |K^-1[q, q]|)` (spectral norms, bounded above by the diagonal blocks'
//! Frobenius norms). Between two solves the displacement of `p` moves by at most `r_p * sum_q r_q |dF_q|`,
//! `r = sqrt(|K^-1 diagonal|)`, summed over every force change in between (the drift). A violation (a plane's
//! `b - n . u`, a sphere's distance to its surface) is 1-Lipschitz in `u`, so a constraint whose violation at the
//! node's last evaluated displacement `u_e` is below its tolerance by more than the drift since then times `r_p`
//! is not violated now. The bound is on the node's displacement, whatever its constraint: the blade that moved
//! since, a new plane or sphere, is evaluated at `u_e` (no K^-1 read). A wide contact evaluates 200-300 candidates
//! against every W node at up to a dozen iterations; most lie well inside, and a steadily moving blade leaves most
//! of them inside from one frame to the next.

use crate::math::Vec3;

/// Factor on the summed bound: covers by far the stored compliance's rounding (f32 1e-7, lazy columns 1e-10).
const SAFETY: f64 = 1.01;
/// Absolute slack (m): far above a head-scale displacement's rounding (1e-16 m), far below any decision's tolerance.
const ABS_SLACK_M: f64 = 1e-12;

/// The summed force change since the records began, and per node its displacement and that sum when last evaluated.
#[derive(Debug, Default)]
pub(super) struct Screen {
    /// `sqrt(|K^-1[n, n]|_F)` per mesh node, NaN until read; sized once, so a frame allocates nothing for it.
    roots: Vec<f64>,
    /// Forces (node, F) at the last solve, ascending by node.
    prev: Vec<(u32, Vec3)>,
    cur: Vec<(u32, Vec3)>,
    /// `SAFETY * sum_solves sum_q r_q |dF_q|` since the records began (infinite once a root was unknown).
    drift: f64,
    /// Per mesh node: its displacement at its last evaluation, and `drift` then (NaN: no record).
    seen_u: Vec<Vec3>,
    seen_at: Vec<f64>,
    /// The nodes with a record (cleared without a pass over every node).
    seen_nodes: Vec<u32>,
    /// Whether the last frame screened (a frame that did not has not counted its force changes).
    screened_last: bool,
}

impl Screen {
    /// A screen for a mesh of `nodes` nodes.
    pub(super) fn new(nodes: usize) -> Self {
        Self { roots: vec![f64::NAN; nodes], seen_u: vec![Vec3::zeros(); nodes], seen_at: vec![f64::NAN; nodes], ..Self::default() }
    }

    /// Starts a frame that `screening` or not: the records carry over when `across` and the last frame screened
    /// with a finite drift; else they start again.
    pub(super) fn begin_frame(&mut self, screening: bool, across: bool) {
        if !(across && self.screened_last && self.drift.is_finite()) {
            for &n in &self.seen_nodes {
                self.seen_at[n as usize] = f64::NAN;
            }
            self.seen_nodes.clear();
            self.prev.clear();
            self.drift = 0.0;
        }
        self.screened_last = screening;
    }

    /// The cached root of `node`, if known.
    pub(super) fn root(&self, node: u32) -> Option<f64> {
        self.roots.get(node as usize).copied().filter(|r| !r.is_nan())
    }

    /// Keeps `root` for `node`.
    pub(super) fn set_root(&mut self, node: u32, root: f64) {
        if let Some(r) = self.roots.get_mut(node as usize) {
            *r = root;
        }
    }

    /// The forces of a new solve (`nodes[k]` carries `forces[k]`): adds their change since the last solve, each
    /// weighted by its node's root, to the drift (a node without a root makes it infinite: nothing more is skipped).
    pub(super) fn advance(&mut self, nodes: &[u32], forces: &[Vec3]) {
        self.cur.clear();
        self.cur.extend(nodes.iter().copied().zip(forces.iter().copied()));
        self.cur.sort_unstable_by_key(|x| x.0);
        let (mut i, mut j) = (0, 0);
        let mut sum = 0.0;
        let (a, b) = (&self.cur, &self.prev);
        while i < a.len() || j < b.len() {
            let (node, change) = match (a.get(i), b.get(j)) {
                (Some(x), Some(y)) if x.0 == y.0 => {
                    i += 1;
                    j += 1;
                    (x.0, x.1 - y.1)
                }
                (Some(x), Some(y)) if x.0 < y.0 => {
                    i += 1;
                    (x.0, x.1)
                }
                (Some(x), None) => {
                    i += 1;
                    (x.0, x.1)
                }
                (_, Some(y)) => {
                    j += 1;
                    (y.0, -y.1)
                }
                (None, None) => unreachable!("the loop runs while either list has an entry"),
            };
            let size = change.norm();
            if size != 0.0 {
                sum += self.root(node).unwrap_or(f64::INFINITY) * size;
            }
        }
        self.drift += SAFETY * sum;
        if !self.drift.is_finite() {
            self.drift = f64::INFINITY;
        }
        std::mem::swap(&mut self.cur, &mut self.prev);
    }

    /// `node`'s displacement when last evaluated, if it has a record.
    pub(super) fn seen(&self, node: u32) -> Option<Vec3> {
        let at = *self.seen_at.get(node as usize)?;
        (!at.is_nan()).then(|| self.seen_u[node as usize])
    }

    /// Whether a constraint of `node` (root `root`) whose margin (tolerance minus violation) at the node's recorded
    /// displacement is `margin` cannot have been reached since that record.
    pub(super) fn can_skip(&self, node: u32, root: f64, margin: f64) -> bool {
        match self.seen_at.get(node as usize) {
            Some(&at) if !at.is_nan() => root * (self.drift - at) + ABS_SLACK_M < margin,
            _ => false,
        }
    }

    /// `node` was evaluated at displacement `u` after the last solve.
    pub(super) fn record(&mut self, node: u32, u: Vec3) {
        let Some(at) = self.seen_at.get_mut(node as usize) else { return };
        if at.is_nan() {
            self.seen_nodes.push(node);
        }
        *at = self.drift;
        self.seen_u[node as usize] = u;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drift_sums_each_nodes_change_weighted_by_its_root() {
        let mut s = Screen::new(10);
        s.begin_frame(true, true);
        for n in 1..4 {
            s.set_root(n, n as f64);
        }
        s.advance(&[2, 1], &[Vec3::new(3.0, 4.0, 0.0), Vec3::new(0.0, 0.0, 1.0)]);
        // first solve: the whole force counts (2 * 5 + 1 * 1)
        assert!((s.drift - SAFETY * 11.0).abs() < 1e-12);
        // node 1 unchanged, node 2 gone, node 3 new
        s.advance(&[1, 3], &[Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 2.0, 0.0)]);
        assert!((s.drift - SAFETY * (11.0 + 10.0 + 6.0)).abs() < 1e-12);
    }

    #[test]
    fn a_node_is_skipped_only_while_the_bound_stays_inside_its_margin() {
        let mut s = Screen::new(10);
        s.begin_frame(true, true);
        assert!(!s.can_skip(0, 1.0, 1.0), "never evaluated: evaluate it");
        s.record(0, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(s.seen(0), Some(Vec3::new(1.0, 2.0, 3.0)));
        assert!(s.can_skip(0, 1.0, 1.0));
        s.set_root(7, 1.0);
        s.advance(&[7], &[Vec3::new(0.5, 0.0, 0.0)]);
        assert!(s.can_skip(0, 1.0, 1.0), "moved by at most 0.505 of 1.0");
        assert!(!s.can_skip(0, 1.0, 0.5), "moved by at most 0.505 of 0.5");
        s.advance(&[7], &[Vec3::new(1.0, 0.0, 0.0)]);
        assert!(!s.can_skip(0, 1.0, 1.0), "moved by at most 1.01 of 1.0");
        s.record(0, Vec3::zeros());
        s.advance(&[8], &[Vec3::new(1e-3, 0.0, 0.0)]);
        assert!(!s.can_skip(0, 1.0, 1.0), "an unknown root bounds nothing");
    }

    #[test]
    fn records_carry_over_to_the_next_frame_only_across_frames_and_after_a_screened_one() {
        let mut s = Screen::new(10);
        s.begin_frame(true, true);
        s.set_root(7, 1.0);
        s.advance(&[7], &[Vec3::new(0.5, 0.0, 0.0)]);
        s.record(0, Vec3::zeros());
        s.begin_frame(true, true);
        assert!(s.can_skip(0, 1.0, 1.0), "carried over");
        s.advance(&[7], &[Vec3::new(0.0, 0.0, 0.0)]);
        assert!(!s.can_skip(0, 1.0, 0.5), "the force released since the record counts");
        s.begin_frame(true, false);
        assert_eq!(s.seen(0), None, "not across frames: started again");
        s.record(0, Vec3::zeros());
        s.begin_frame(false, true);
        assert!(s.seen(0).is_some(), "a frame that does not screen keeps the records it cannot use");
        s.begin_frame(true, true);
        assert_eq!(s.seen(0), None, "after a frame that did not count its forces: started again");
    }
}
