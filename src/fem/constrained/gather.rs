//! W's entries of a first contact's rows gathered on two threads (`parallel-gather`): a blade settling on a refined
//! patch brings 150 rows new to the step at once, each reading its blocks against the rows before it from the
//! compliance, where they lie apart, and against the W nodes through its node's kept row.

use super::*;
use blocks::RowSlices;

/// From this many entries of rows new to the step (each row's own and those before it), W's gather goes on two
/// threads: a first contact on the refined default scene has about 11,000, a steady frame a few dozen.
pub(super) const GATHER_AHEAD_FROM: usize = 2048;

/// A row gathered ahead: its node's kept row, its index among the candidate rows, its rows of `w_ss` (up to its
/// own column) and `w_es`, and the blocks it read from the compliance.
type RowJob<'a> = (RowSlices<'a>, usize, &'a mut [f64], &'a mut [f64], u64);

impl ConstrainedSolver {
    /// Gathers, when they are many ([`GATHER_AHEAD_FROM`]), the entries of the candidate rows new to the step (their
    /// own entry unknown; the first row of each node, a second row of a node is left to the gather loop) on two
    /// threads ([`crate::par::for_each_mut`]): `w_es` row `t`, `w_ss` row `t` up to its own column, each entry by
    /// the expression and from the blocks the gather loop in `solve_rows` uses, so the bits are the same. Then
    /// mirrors them into `w_ss` and keeps those the step did not know in `pairs`. Returns which rows it gathered
    /// (empty: none).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn gather_rows_ahead(
        &self,
        kept: &mut blocks::CandidateBlocks,
        e: usize,
        s: usize,
        s_c: usize,
        mut pairs: Option<&mut pairs::RowPairs>,
        slots: &[usize],
        w_es: &mut [f64],
        w_ss: &mut [f64],
    ) -> Vec<bool> {
        let new = |t: usize| pairs.as_deref().is_none_or(|p| !p.has(slots[t], slots[t]));
        let entries: usize = (0..s_c).filter(|&t| new(t)).map(|t| t + 1).sum();
        if entries < kept.ahead.gather_from {
            return Vec::new();
        }
        // the first new row of each node, by its kept row
        let mut rows: Vec<(usize, usize)> = Vec::with_capacity(s_c);
        for t in (0..s_c).filter(|&t| new(t)) {
            rows.push((kept.row(self.sys.nodes[self.sys.rows[e + t].slot]), t));
        }
        rows.sort_unstable();
        rows.dedup_by_key(|r| r.0);
        let lazy: Vec<bool> = rows.iter().map(|&(_, t)| self.columns.lazy.binary_search_by_key(&self.sys.nodes[self.sys.rows[e + t].slot], |c| c.node).is_ok()).collect();
        let n_enforced = self.tools.enforced_nodes;
        let es_width = 3 * n_enforced;
        let mut ss_rows: Vec<Option<&mut [f64]>> = w_ss.chunks_exact_mut(s.max(1)).map(Some).collect();
        let mut es_rows: Vec<Option<&mut [f64]>> = w_es.chunks_exact_mut(es_width.max(1)).map(Some).collect();
        let mut kept_rows = Vec::with_capacity(rows.len());
        let columns = kept.rows_at(rows.iter().map(|r| r.0), &mut kept_rows);
        if kept_rows.len() != rows.len() {
            return Vec::new();
        }
        let mut jobs: Vec<(RowJob<'_>, bool)> = Vec::with_capacity(rows.len());
        for ((row, &(_, t)), &lazy) in kept_rows.into_iter().zip(&rows).zip(&lazy) {
            let (Some(ss), es) = (ss_rows[t].take(), es_rows.get_mut(t).and_then(Option::take)) else { continue };
            jobs.push(((row, t, &mut ss[..=t], es.map_or(&mut [][..], |r| &mut r[..es_width]), 0), lazy));
        }
        let mut ahead = vec![false; s_c];
        jobs.iter().for_each(|j| ahead[j.0.1] = true);
        let (src, nodes, crows, prefetch) = (self.kinv_source(), &self.sys.nodes, &self.sys.rows, self.tuning.enabled(Optimisation::PrefetchBlocks));
        let known = pairs.as_deref();
        crate::par::for_each_mut(&mut jobs, 4, |((row, t, ss, es, reads), lazy)| {
            let t = *t;
            let ri = crows[e + t];
            let pi = nodes[ri.slot];
            let entry = |u: usize| known.and_then(|p| p.get(slots[t], slots[u]));
            if prefetch {
                for u in (0..=t).filter(|&u| entry(u).is_none()) {
                    let (slot, q) = (crows[e + u].slot, nodes[crows[e + u].slot]);
                    if row.1[columns[slot] as usize] != q {
                        src.prefetch(pi, q);
                    }
                }
            }
            for l in 0..n_enforced {
                let q = nodes[l];
                let block = if *lazy { src.block(q, pi) } else { blocks::CandidateBlocks::read_through(row, columns, src, pi, q, l, reads).transpose() };
                let v = block * ri.dir;
                es[3 * l..3 * l + 3].copy_from_slice(v.as_slice());
            }
            for (u, w) in ss.iter_mut().enumerate() {
                let rj = crows[e + u];
                *w = entry(u).unwrap_or_else(|| {
                    let block = blocks::CandidateBlocks::read_through(row, columns, src, pi, nodes[rj.slot], rj.slot, reads);
                    ri.dir.dot(&(block * rj.dir))
                });
            }
        });
        let reads = jobs.iter().map(|j| j.0.4).sum();
        drop(jobs);
        kept.count_reads(reads);
        for t in (0..s_c).filter(|&t| ahead[t]) {
            for u in 0..=t {
                let value = w_ss[t * s + u];
                w_ss[u * s + t] = value;
                if let Some(p) = pairs.as_deref_mut() {
                    p.get_or(slots[t], slots[u], || value);
                }
            }
        }
        ahead
    }
}
