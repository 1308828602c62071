//! The solver's K^-1 columns outside the region of interest ("lazy": solved in the frame that first needs them,
//! its missing nodes in one batch; about [`LAZY_CAPACITY`] kept, least recently used out first) and the block read
//! that picks a ROI or a lazy column ([`ConstrainedSolver::kinv`]).

use super::*;
use crate::fem::assembly::DofMap;
use crate::linalg::SparseCholesky;

/// What [`ConstrainedSolver::kinv`] reads (the compliance, the DOF map, the lazy columns), apart from the solver so
/// that two threads reading blocks at once can share it.
#[derive(Clone, Copy)]
pub(super) struct KinvSource<'a> {
    compliance: &'a Compliance,
    dofs: &'a DofMap,
    lazy: &'a [LazyColumn],
}

impl KinvSource<'_> {
    /// K^-1 block between two nodes (both free; lazy columns ensured). A node outside the ROI reads its lazy column
    /// (f64) even when the other is a ROI column: the compliance keeps ROI x other-surface entries only to f32 (for
    /// the product), and W must be exact.
    #[inline]
    pub(super) fn block(&self, p: u32, q: u32) -> Matrix3<f64> {
        let (cp, cq) = (self.compliance.col_of(p), self.compliance.col_of(q));
        if let (Some(cp), Some(cq)) = (cp, cq) {
            return self.compliance.block(cp, cq);
        }
        let n_free = self.dofs.dof_count();
        if let (Ok(l), Some(dp)) = (self.lazy.binary_search_by_key(&q, |c| c.node), self.dofs.dof(p)) {
            let v = &self.lazy[l].values;
            return Matrix3::from_fn(|r, c| v[c * n_free + dp + r]);
        }
        if let (Ok(l), Some(dq)) = (self.lazy.binary_search_by_key(&p, |c| c.node), self.dofs.dof(q)) {
            let v = &self.lazy[l].values;
            return Matrix3::from_fn(|r, c| v[r * n_free + dq + c]);
        }
        if let (Some(rp), Some(cq)) = (self.compliance.row_of(p), cq) {
            return self.compliance.block(rp, cq);
        }
        if let (Some(rq), Some(cp)) = (self.compliance.row_of(q), cp) {
            return self.compliance.block(rq, cp).transpose();
        }
        Matrix3::zeros()
    }

    /// Hints the cache with the compliance block [`Self::block`]`(p, q)` reads when both nodes have ROI rows (a lazy
    /// column is left to the hardware: it lies in one run). Changes no value.
    #[inline]
    pub(super) fn prefetch(&self, p: u32, q: u32) {
        let c = self.compliance;
        match (c.row_of(p), c.row_of(q)) {
            (Some(rp), Some(rq)) if rp < c.column_count() || rq < c.column_count() => c.prefetch_block(rp, rq),
            _ => {}
        }
    }
}

impl ConstrainedSolver {
    /// What [`Self::kinv`] reads.
    #[inline]
    pub(super) fn kinv_source(&self) -> KinvSource<'_> {
        KinvSource { compliance: &self.compliance, dofs: &self.model.dofs, lazy: &self.columns.lazy }
    }

    /// K^-1 block between two nodes ([`KinvSource::block`]).
    #[inline]
    pub(super) fn kinv(&self, p: u32, q: u32) -> Matrix3<f64> {
        self.kinv_source().block(p, q)
    }

    /// Makes sure the listed nodes have K^-1 columns: waits for ROI columns still filling, solves the missing lazy
    /// ones in one batch.
    pub(super) fn ensure_lazy(&mut self, nodes: &[u32]) -> Result<(), FemError> {
        let t = std::time::Instant::now();
        let result = self.ensure_lazy_untimed(nodes);
        self.timings.lazy += t.elapsed().as_secs_f64();
        result
    }

    pub(super) fn ensure_lazy_untimed(&mut self, nodes: &[u32]) -> Result<(), FemError> {
        // ROI columns still being computed in the background: wait for the ones read here.
        for &n in nodes {
            if let Some(c) = self.compliance.col_of(n) {
                self.compliance.wait_column(c)?;
            }
        }
        let frame = self.frame;
        let mut missing: Vec<u32> = Vec::new();
        for &n in nodes {
            if self.compliance.col_of(n).is_some() || self.model.is_fixed(n) {
                continue;
            }
            match self.columns.lazy.binary_search_by_key(&n, |c| c.node) {
                Ok(i) => self.columns.lazy[i].last_used = frame,
                Err(_) => {
                    if !missing.contains(&n) {
                        missing.push(n);
                    }
                }
            }
        }
        if missing.is_empty() {
            return Ok(());
        }
        missing.sort_unstable();
        self.make_room(missing.len(), frame);
        let columns = solve_columns(self.model.chol.get()?, &self.model.dofs, &missing)?;
        self.columns.lazy_computed += columns.len();
        self.insert_columns(columns, frame);
        Ok(())
    }

    /// Evicts least recently used columns last used before frame `keep_from` until `count` more fit (or none can go).
    pub(super) fn make_room(&mut self, count: usize, keep_from: u64) {
        while self.columns.lazy.len() + count > LAZY_CAPACITY {
            let victim = self
                .columns
                .lazy
                .iter()
                .enumerate()
                .filter(|(_, c)| c.last_used < keep_from)
                .min_by_key(|(_, c)| (c.last_used, c.node))
                .map(|(i, _)| i);
            match victim {
                Some(i) => {
                    self.columns.lazy.remove(i);
                    self.columns.lazy_generation += 1;
                }
                None => break,
            }
        }
    }

    /// Adds solved columns (nodes not yet cached), stamped as last used at `stamp`.
    pub(super) fn insert_columns(&mut self, columns: Vec<NodeColumns>, stamp: u64) {
        for (node, values) in columns {
            if let Err(at) = self.columns.lazy.binary_search_by_key(&node, |c| c.node) {
                self.columns.lazy.insert(at, LazyColumn { node, values, last_used: stamp });
                self.columns.lazy_generation += 1;
            }
        }
    }
}

/// Columns of one node: 3 x free DOFs, column major.
pub(super) type NodeColumns = (u32, Vec<f64>);

/// Solves the 3 columns of each node in one sparse solve (fixed nodes get zero columns). A solve's last bits depend
/// on which right-hand sides share it, so a frame solves exactly its missing nodes, ascending: replays agree.
pub(super) fn solve_columns(chol: &SparseCholesky, dofs: &DofMap, nodes: &[u32]) -> Result<Vec<NodeColumns>, FemError> {
    let n_free = dofs.dof_count();
    let first_dofs: Vec<usize> = nodes.iter().filter_map(|&n| dofs.dof(n)).collect();
    let mut rhs = faer::Mat::<f64>::zeros(n_free, 3 * first_dofs.len());
    if !first_dofs.is_empty() {
        let mut scratch = chol.scratch(3 * first_dofs.len())?;
        chol.solve_unit_columns(&first_dofs, rhs.as_mut(), None, &mut scratch);
    }
    let mut b = 0;
    Ok(nodes
        .iter()
        .map(|&n| {
            if dofs.dof(n).is_none() {
                return (n, vec![0.0; 3 * n_free]);
            }
            let mut values = Vec::with_capacity(3 * n_free);
            for c in 0..3 {
                values.extend((0..n_free).map(|i| rhs[(i, 3 * b + c)]));
            }
            b += 1;
            (n, values)
        })
        .collect())
}
