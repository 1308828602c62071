//! Lazy `K^-1` columns (nodes outside the compliance's region of interest)
//! solved on a background thread before a contact needs them.
//!
//! In: batches of nodes the spatulas are about to reach, each with the frame at
//! which it is joined. Out: the 3 columns `K^-1[:, node]` of each node (free
//! DOFs, column major), handed over at the join.
//! Stays true: values never depend on timing. A sparse solve's bits depend on
//! which right-hand sides share the solve (measured: batched and single
//! columns differ in the last bit), so a batch is solved exactly as it was
//! requested, and its columns enter the solver only at deterministic points: at
//! its join frame, or earlier when a frame needs one of its nodes (the frame
//! then waits for that batch). Whether the worker was early or late changes
//! wall-clock time, never a result. A worker that fails (out of memory, a
//! panic) reports its batches as missing; the frame path then solves the
//! columns itself and never panics.

use super::FemError;
use super::assembly::DofMap;
use super::factor::{LazyFactor, SparseCholesky};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};

/// Columns of one node: 3 x free DOFs, column major.
pub type NodeColumns = (u32, Vec<f64>);

/// Solves the 3 columns of each node in one sparse solve with `3 * nodes.len()`
/// right-hand sides. Fixed nodes get zero columns.
pub fn solve_columns(chol: &SparseCholesky, dofs: &DofMap, nodes: &[u32]) -> Result<Vec<NodeColumns>, FemError> {
    let n_free = dofs.dof_count();
    let m = nodes.len();
    if m == 0 {
        return Ok(Vec::new());
    }
    let mut rhs = faer::Mat::<f64>::zeros(n_free, 3 * m);
    for (b, &n) in nodes.iter().enumerate() {
        if let Some(d) = dofs.dof(n) {
            for c in 0..3 {
                rhs[(d + c, 3 * b + c)] = 1.0;
            }
        }
    }
    let mut scratch = chol.scratch(3 * m)?;
    chol.solve_in_place(rhs.as_mut(), &mut scratch);
    Ok(nodes
        .iter()
        .enumerate()
        .map(|(b, &n)| {
            let mut values = Vec::with_capacity(3 * n_free);
            for c in 0..3 {
                values.extend((0..n_free).map(|i| rhs[(i, 3 * b + c)]));
            }
            (n, values)
        })
        .collect())
}

/// A requested batch not yet joined.
#[derive(Debug, Clone)]
pub struct OpenBatch {
    pub id: u64,
    /// The first frame that joins it (waiting for it if needed).
    pub join_frame: u64,
    /// Its nodes, ascending.
    pub nodes: Vec<u32>,
}

type Reply = (u64, Result<Vec<NodeColumns>, FemError>);

/// The background worker and its open batches. The thread starts with the
/// first request; dropping this closes its channel, and the thread ends after
/// its current batch (it is not waited for: closing a scene never stalls on a solve).
pub struct Prefetcher {
    chol: Arc<LazyFactor>,
    dofs: DofMap,
    link: Option<(Sender<(u64, Vec<u32>)>, Receiver<Reply>)>,
    open: Vec<OpenBatch>,
    /// Replies received for open batches not yet joined.
    arrived: Vec<Reply>,
    next_id: u64,
    /// Set when the worker could not start or died: requests are refused.
    failed: bool,
}

impl std::fmt::Debug for Prefetcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prefetcher").field("open", &self.open.len()).field("failed", &self.failed).finish()
    }
}

impl Prefetcher {
    /// A prefetcher for the factor `chol` (no thread yet).
    pub fn new(chol: Arc<LazyFactor>, dofs: DofMap) -> Self {
        Self { chol, dofs, link: None, open: Vec::new(), arrived: Vec::new(), next_id: 0, failed: false }
    }

    /// Batches requested and not yet joined, in request order.
    pub fn open(&self) -> &[OpenBatch] {
        &self.open
    }

    /// True when `node` is in an open batch.
    pub fn is_open(&self, node: u32) -> bool {
        self.open.iter().any(|b| b.nodes.binary_search(&node).is_ok())
    }

    /// Queues `nodes` (ascending, distinct) to be joined at `join_frame`.
    /// False when the worker is unavailable (the caller solves on demand).
    pub fn request(&mut self, nodes: Vec<u32>, join_frame: u64) -> bool {
        if self.failed || nodes.is_empty() {
            return false;
        }
        if self.link.is_none() {
            let (req_tx, req_rx) = channel::<(u64, Vec<u32>)>();
            let (rep_tx, rep_rx) = channel::<Reply>();
            let chol = Arc::clone(&self.chol);
            let dofs = self.dofs.clone();
            let spawned = std::thread::Builder::new().name("fissure-lazy-columns".into()).spawn(move || {
                for (id, nodes) in req_rx {
                    let result = chol.get().and_then(|chol| solve_columns(chol, &dofs, &nodes));
                    if rep_tx.send((id, result)).is_err() {
                        break;
                    }
                }
            });
            match spawned {
                Ok(_) => self.link = Some((req_tx, rep_rx)),
                Err(e) => {
                    tracing::warn!("lazy-column worker did not start ({e}); columns outside the ROI are solved on demand");
                    self.failed = true;
                    return false;
                }
            }
        }
        let id = self.next_id;
        let sent = self.link.as_ref().is_some_and(|(tx, _)| tx.send((id, nodes.clone())).is_ok());
        if !sent {
            self.fail();
            return false;
        }
        self.next_id += 1;
        self.open.push(OpenBatch { id, join_frame, nodes });
        true
    }

    /// Removes open batch `id` and returns its columns, waiting for the worker
    /// if they have not arrived. `None` when the worker failed on it.
    pub fn join(&mut self, id: u64) -> Option<Vec<NodeColumns>> {
        let at = self.open.iter().position(|b| b.id == id)?;
        self.open.remove(at);
        loop {
            if let Some(k) = self.arrived.iter().position(|r| r.0 == id) {
                let (_, result) = self.arrived.swap_remove(k);
                return match result {
                    Ok(columns) => Some(columns),
                    Err(e) => {
                        tracing::warn!("background solve of lazy columns failed ({e}); solving on demand");
                        None
                    }
                };
            }
            let reply = match &self.link {
                Some((_, rx)) => rx.recv().ok(),
                None => None,
            };
            match reply {
                Some(r) => self.arrived.push(r),
                None => {
                    self.fail();
                    return None;
                }
            }
        }
    }

    fn fail(&mut self) {
        if !self.failed {
            tracing::warn!("lazy-column worker stopped; columns outside the ROI are solved on demand");
        }
        self.failed = true;
        self.open.clear();
        self.arrived.clear();
        self.link = None;
    }
}
