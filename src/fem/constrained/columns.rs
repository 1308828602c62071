//! The solver's K^-1 columns outside the region of interest ("lazy"
//! columns: sparse solves, a batch of nodes at a time; about
//! [`LAZY_CAPACITY`] kept, the least recently used out first), their prefetch
//! in background batches, and the
//! block read that picks a ROI column or a lazy one ([`ConstrainedSolver::kinv`]).

use super::*;

impl ConstrainedSolver {
    /// K^-1 block between two nodes (both free; lazy columns ensured). A node
    /// outside the ROI reads its lazy column (f64 from a sparse solve) even when
    /// the other is a ROI column, since the compliance keeps ROI x other-surface
    /// entries only to f32 (for the product) and W must be exact.
    pub(super) fn kinv(&self, p: u32, q: u32) -> Matrix3<f64> {
        let (cp, cq) = (self.compliance.col_of(p), self.compliance.col_of(q));
        if let (Some(cp), Some(cq)) = (cp, cq) {
            return self.compliance.block(cp, cq);
        }
        let dofs = &self.model.dofs;
        let n_free = dofs.dof_count();
        if let (Ok(l), Some(dp)) = (self.lazy.binary_search_by_key(&q, |c| c.node), dofs.dof(p)) {
            let v = &self.lazy[l].values;
            return Matrix3::from_fn(|r, c| v[c * n_free + dp + r]);
        }
        if let (Ok(l), Some(dq)) = (self.lazy.binary_search_by_key(&p, |c| c.node), dofs.dof(q)) {
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

    /// Computes K^-1 columns for the listed nodes that are not ROI columns:
    /// joins the background batches holding any of them (waiting if needed),
    /// then solves the rest in one batch.
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
        loop {
            missing.clear();
            for &n in nodes {
                if self.compliance.col_of(n).is_some() || self.model.is_fixed(n) {
                    continue;
                }
                match self.lazy.binary_search_by_key(&n, |c| c.node) {
                    Ok(i) => self.lazy[i].last_used = frame,
                    Err(_) => {
                        if !missing.contains(&n) {
                            missing.push(n);
                        }
                    }
                }
            }
            // A node of an open background batch: join that batch (in request order) first.
            let open = self.prefetcher.open().iter().find(|b| missing.iter().any(|n| b.nodes.binary_search(n).is_ok())).map(|b| b.id);
            // Each join removes an open batch, so this ends.
            match open {
                Some(id) => self.join_batch(id),
                None => break,
            }
        }
        if missing.is_empty() {
            return Ok(());
        }
        missing.sort_unstable();
        self.make_room(missing.len(), frame);
        let columns = crate::fem::prefetch::solve_columns(self.model.chol.get()?, &self.model.dofs, &missing)?;
        self.lazy_computed += columns.len();
        self.insert_columns(columns, frame);
        Ok(())
    }

    /// Evicts least recently used columns last used before frame `keep_from`
    /// until `count` more fit (or none is left to evict).
    pub(super) fn make_room(&mut self, count: usize, keep_from: u64) {
        while self.lazy.len() + count > LAZY_CAPACITY {
            let victim = self
                .lazy
                .iter()
                .enumerate()
                .filter(|(_, c)| c.last_used < keep_from)
                .min_by_key(|(_, c)| (c.last_used, c.node))
                .map(|(i, _)| i);
            match victim {
                Some(i) => {
                    self.lazy.remove(i);
                    self.lazy_generation += 1;
                }
                None => break,
            }
        }
    }

    /// Adds solved columns (nodes not yet cached), stamped as last used at `stamp`.
    pub(super) fn insert_columns(&mut self, columns: Vec<crate::fem::prefetch::NodeColumns>, stamp: u64) {
        for (node, values) in columns {
            if let Err(at) = self.lazy.binary_search_by_key(&node, |c| c.node) {
                self.lazy.insert(at, LazyColumn { node, values, last_used: stamp });
                self.lazy_generation += 1;
            }
        }
    }

    /// Joins background batch `id`: its columns enter the cache as far as
    /// columns unused since before the last frame make room (a guess never
    /// evicts a column a contact used last frame), stamped one frame old, so
    /// a column a frame needs wins over a guess.
    pub(super) fn join_batch(&mut self, id: u64) {
        if let Some(columns) = self.prefetcher.join(id) {
            let fresh: Vec<_> = columns.into_iter().filter(|(n, _)| self.lazy.binary_search_by_key(n, |c| c.node).is_err()).collect();
            let last = self.frame.saturating_sub(1);
            self.make_room(fresh.len(), last);
            let room = LAZY_CAPACITY.saturating_sub(self.lazy.len());
            self.insert_columns(fresh.into_iter().take(room).collect(), last);
        }
    }

    /// Joins every background batch whose join frame has come.
    pub(super) fn join_due_batches(&mut self) {
        while let Some(id) = self.prefetcher.open().iter().find(|b| b.join_frame <= self.frame).map(|b| b.id) {
            self.join_batch(id);
        }
    }

    /// Asks the background thread for the K^-1 columns of `nodes` (in the given
    /// order of priority, e.g. nearest to a spatula first) so that a contact
    /// there later needs no sparse solve in the frame. Nodes that are ROI
    /// columns, fixed, cached or already requested are skipped; at most
    /// [`PREFETCH_BATCH`] nodes a call and [`PREFETCH_OPEN`] batches in flight.
    /// The batch is joined [`PREFETCH_JOIN_FRAMES`] frames later, or earlier
    /// when a frame needs one of its nodes; results never depend on timing
    /// (see [`super::prefetch`]). Returns the number of nodes requested.
    pub fn prefetch(&mut self, nodes: &[u32]) -> usize {
        if !self.can_prefetch() || !crate::fem::tuning::enabled(crate::fem::tuning::Optimisation::Prefetch) {
            return 0;
        }
        let mut batch: Vec<u32> = Vec::new();
        for &n in nodes {
            if batch.len() == PREFETCH_BATCH {
                break;
            }
            if (n as usize) >= self.model.mesh.node_count()
                || self.compliance.col_of(n).is_some()
                || self.model.is_fixed(n)
                || batch.contains(&n)
                || self.lazy.binary_search_by_key(&n, |c| c.node).is_ok()
                || self.prefetcher.is_open(n)
            {
                continue;
            }
            batch.push(n);
        }
        batch.sort_unstable();
        let count = batch.len();
        if self.prefetcher.request(batch, self.frame + PREFETCH_JOIN_FRAMES) { count } else { 0 }
    }

    /// False while [`PREFETCH_OPEN`] batches are in flight (a request now
    /// would be ignored, so a caller can skip choosing its nodes).
    pub fn can_prefetch(&self) -> bool {
        self.prefetcher.open().len() < PREFETCH_OPEN
    }

    /// True when `node` is a column of the precomputed compliance (inside the ROI).
    pub fn is_roi_column(&self, node: u32) -> bool {
        self.compliance.col_of(node).is_some()
    }

    /// Nodes whose columns are cached (lazy, outside the ROI), ascending.
    pub fn cached_lazy_nodes(&self) -> impl Iterator<Item = u32> + '_ {
        self.lazy.iter().map(|c| c.node)
    }
}
