//! Screening the active-set loop's inactive candidates ([`Screen`]): a candidate whose last evaluation left it far
//! from its constraint is not evaluated again until the forces have changed enough to reach it.
//!
//! In: the nodal forces after each solve of W, the diagonal K^-1 blocks of the nodes. Out: per candidate, whether
//! its evaluation can be skipped. Stays true: a skipped candidate would have been found not violated, so the loop
//! makes the same decisions and the frame the same bits (`tests/fem_tuning.rs` checks it with the switch off).
//!
//! The bound: K^-1 is symmetric positive definite, so each 3x3 block satisfies
//! `|K^-1[p, q]| <= sqrt(|K^-1[p, p]| |K^-1[q, q]|)` (spectral norms, bounded above by the diagonal blocks'
//! Frobenius norms). Between two evaluations the displacement of `p` moves by at most `r_p * sum_q r_q |dF_q|`,
//! `r = sqrt(|K^-1 diagonal|)`, summed over every force change in between. A violation (a plane's `b - n . u`, a
//! sphere's distance to its surface) is 1-Lipschitz in `u`, so while that bound stays below the margin (tolerance
//! minus violation) found at the last evaluation, the candidate stays inside. A wide contact evaluates 200-300
//! candidates against every W node at up to a dozen iterations; most lie well inside.

use crate::math::Vec3;

/// Factor on the summed bound: covers by far the stored compliance's rounding (f32 1e-7, lazy columns 1e-10).
const SAFETY: f64 = 1.01;
/// Absolute slack (m): far above a head-scale displacement's rounding (1e-16 m), far below any decision's tolerance.
const ABS_SLACK_M: f64 = 1e-12;

/// Per frame: the summed force change so far, and per candidate the sum and margin at its last evaluation.
#[derive(Debug, Default)]
pub(super) struct Screen {
    /// `sqrt(|K^-1[n, n]|_F)` per mesh node, NaN until read; sized once, so a frame allocates nothing for it.
    roots: Vec<f64>,
    /// Forces (node, F) at the last solve, ascending by node.
    prev: Vec<(u32, Vec3)>,
    cur: Vec<(u32, Vec3)>,
    /// `SAFETY * sum_iterations sum_q r_q |dF_q|` since the frame began (infinite once a root was unknown).
    drift: f64,
    /// Per candidate: `drift` and its margin (tolerance minus violation; -inf: none) at its last inactive evaluation.
    at: Vec<f64>,
    margin: Vec<f64>,
}

impl Screen {
    /// A screen for a mesh of `nodes` nodes.
    pub(super) fn new(nodes: usize) -> Self {
        Self { roots: vec![f64::NAN; nodes], ..Self::default() }
    }

    /// Starts a frame (no candidate has a margin yet).
    pub(super) fn begin_frame(&mut self) {
        self.prev.clear();
        self.drift = 0.0;
        self.at.clear();
        self.margin.clear();
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

    /// Whether candidate `ci` (root `root`) cannot have reached its constraint since its last evaluation.
    pub(super) fn can_skip(&self, ci: usize, root: f64) -> bool {
        match (self.margin.get(ci), self.at.get(ci)) {
            (Some(&m), Some(&at)) => root * (self.drift - at) + ABS_SLACK_M < m,
            _ => false,
        }
    }

    /// Candidate `ci` was evaluated inactive and stays so, `margin` inside its tolerance.
    pub(super) fn record(&mut self, ci: usize, margin: f64) {
        if self.margin.len() <= ci {
            self.margin.resize(ci + 1, f64::NEG_INFINITY);
            self.at.resize(ci + 1, 0.0);
        }
        self.margin[ci] = margin;
        self.at[ci] = self.drift;
    }

    /// Candidate `ci` changed state (activated or released): evaluate it next time.
    pub(super) fn forget(&mut self, ci: usize) {
        if let Some(m) = self.margin.get_mut(ci) {
            *m = f64::NEG_INFINITY;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drift_sums_each_nodes_change_weighted_by_its_root() {
        let mut s = Screen::new(10);
        s.begin_frame();
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
    fn a_candidate_is_skipped_only_while_the_bound_stays_inside_its_margin() {
        let mut s = Screen::new(10);
        s.begin_frame();
        assert!(!s.can_skip(0, 1.0), "never evaluated: evaluate it");
        s.record(0, 1.0);
        assert!(s.can_skip(0, 1.0));
        s.set_root(7, 1.0);
        s.advance(&[7], &[Vec3::new(0.5, 0.0, 0.0)]);
        assert!(s.can_skip(0, 1.0), "moved by at most 0.505 of 1.0");
        s.advance(&[7], &[Vec3::new(1.0, 0.0, 0.0)]);
        assert!(!s.can_skip(0, 1.0), "moved by at most 1.01 of 1.0");
        s.forget(0);
        assert!(!s.can_skip(0, 0.0));
        s.record(0, 1.0);
        s.advance(&[8], &[Vec3::new(1e-3, 0.0, 0.0)]);
        assert!(!s.can_skip(0, 1.0), "an unknown root bounds nothing");
    }
}
