//! Sparse Cholesky of the free-DOF stiffness (faer, supernodal; AMD or nested
//! dissection ordering, see [`super::ordering`]).
//!
//! In: the lower triangle of `K_FF` ([`LowerCsc`]). Out: a [`SparseCholesky`]
//! that solves `K_FF X = B` in place for any number of right-hand sides.
//! Stays true: symbolic analysis happens once, the numeric factor once per
//! material set; solves run on one core (`Par::Seq`, see DESIGN.md) and allocate
//! only the scratch sized for their column count.

use super::FemError;
use super::assembly::{DofMap, LowerCsc};
use super::ordering::{FillOrdering, nested_dissection};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::cholesky::{CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky};
use faer::{Conj, MatMut, Par, Side, Spec};
use std::time::Instant;

/// Supernode amalgamation (faer's rule: merge two adjacent supernodes of `n`
/// columns in all when the merged one has a fraction of zeros below `z`, for
/// the first `(n, z)` with `n` at most its bound). Coarser than faer's default
/// `[(4, 1.0), (16, 0.8), (48, 0.1), (MAX, 0.05)]`: the precompute's 96-column
/// solves run dense kernels per supernode, and on the coarse brain this made a
/// nested-dissection solve 1.38x AMD's become 0.99x (`cargo bench --bench fem
/// -- coarse`, "ordering" lines) for 9 % more stored entries.
const SUPERNODE_RELAX: &[(usize, f64)] = &[(32, 1.0), (96, 0.8), (256, 0.2), (usize::MAX, 0.05)];

/// A factored `K_FF`.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    /// Seconds spent in the symbolic analysis.
    pub symbolic_seconds: f64,
    /// Seconds spent in the numeric factorization.
    pub numeric_seconds: f64,
    /// The ordering the factor uses ([`FillOrdering::Best`] resolved).
    pub ordering: FillOrdering,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky").field("dim", &self.dim()).field("nnz_l", &self.values.len()).finish()
    }
}

impl SparseCholesky {
    /// Analyzes and factors `k`. A non-positive pivot is reported with the free
    /// DOF (in the caller's numbering) and its node.
    pub fn new(k: &LowerCsc, dofs: &DofMap, ordering: FillOrdering) -> Result<Self, FemError> {
        Self::with_names(k, ordering, &|dof| (dofs.free_nodes.get(dof / 3).copied().unwrap_or(u32::MAX), dof % 3))
    }

    /// As [`SparseCholesky::new`], naming a DOF's (node, component) with `name`.
    pub fn with_names(k: &LowerCsc, ordering: FillOrdering, name: &dyn Fn(usize) -> (u32, usize)) -> Result<Self, FemError> {
        let a = k.as_faer();
        let t0 = Instant::now();
        let analyse = |ord: SymmetricOrdering<'_, usize>| {
            let mut params = CholeskySymbolicParams::default();
            params.supernodal_params.relax = Some(SUPERNODE_RELAX);
            factorize_symbolic_cholesky(a.symbolic(), Side::Lower, ord, params)
                .map_err(|e| FemError::Factorization { reason: format!("symbolic analysis: {e:?}") })
        };
        let nd = || -> Result<Option<SymbolicCholesky<usize>>, FemError> {
            let Some(fwd) = nested_dissection(k) else { return Ok(None) };
            let mut inv = vec![0usize; fwd.len()];
            for (new, &old) in fwd.iter().enumerate() {
                inv[old] = new;
            }
            analyse(SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(&fwd, &inv, fwd.len()))).map(Some)
        };
        let (symbolic, ordering) = match ordering {
            FillOrdering::NestedDissection => match nd()? {
                Some(s) => (s, FillOrdering::NestedDissection),
                None => (analyse(SymmetricOrdering::Amd)?, FillOrdering::Amd),
            },
            FillOrdering::Best => {
                // Both analyses are cheap next to the numeric factor; keep the
                // one with less fill (every solve streams all of L).
                let by_amd = analyse(SymmetricOrdering::Amd)?;
                match nd()? {
                    Some(by_nd) if by_nd.len_val() < by_amd.len_val() => (by_nd, FillOrdering::NestedDissection),
                    _ => (by_amd, FillOrdering::Amd),
                }
            }
            FillOrdering::Amd => (analyse(SymmetricOrdering::Amd)?, FillOrdering::Amd),
        };
        let symbolic_seconds = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let len = symbolic.len_val();
        let mut values = Vec::new();
        values.try_reserve_exact(len).map_err(|_| FemError::OutOfMemory { what: "Cholesky factor", bytes: len * 8 })?;
        values.resize(len, 0.0);
        let req = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Spec::default());
        let mut mem = MemBuffer::try_new(req).map_err(|_| FemError::OutOfMemory { what: "factorization scratch", bytes: 0 })?;
        let stack = MemStack::new(&mut mem);
        let result = symbolic.factorize_numeric_llt(&mut values, a, Side::Lower, LltRegularization::default(), Par::Seq, stack, Spec::default());
        if let Err(LltError::NonPositivePivot { index }) = result {
            // `index` is in the permuted order: map back to our DOF numbering.
            let dof = symbolic.perm().map(|p| p.arrays().0[index]).unwrap_or(index);
            let (node, component) = name(dof);
            return Err(FemError::NotPositiveDefinite { dof, node, component });
        }
        let numeric_seconds = t1.elapsed().as_secs_f64();
        Ok(Self { symbolic, values, symbolic_seconds, numeric_seconds, ordering })
    }

    /// Dimension (free DOFs).
    pub fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Stored entries of the factor L.
    pub fn nnz_l(&self) -> usize {
        self.values.len()
    }

    /// Scratch a solve with `ncols` right-hand sides needs.
    pub fn scratch(&self, ncols: usize) -> Result<MemBuffer, FemError> {
        let req = self.symbolic.solve_in_place_scratch::<f64>(ncols, Par::Seq);
        MemBuffer::try_new(req).map_err(|_| FemError::OutOfMemory { what: "solve scratch", bytes: 0 })
    }

    /// Solves `K_FF X = B` in place (`rhs` is dim x k, column major).
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>, scratch: &mut MemBuffer) {
        let llt = LltRef::new(&self.symbolic, &self.values);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(scratch));
    }

    /// Solves for one right-hand side stored in a slice.
    pub fn solve_vec_in_place(&self, rhs: &mut [f64], scratch: &mut MemBuffer) {
        let n = rhs.len();
        let m = faer::MatMut::from_column_major_slice_mut(rhs, n, 1);
        self.solve_in_place(m, scratch);
    }
}

/// The factor of `K_FF`, made on first use or on a background thread.
///
/// In: `K_FF` (lower) and the DOF names, moved in. Out: the factor, or the
/// error its build gave, to every caller of [`LazyFactor::get`] (which waits
/// while it is made). Stays true: it is made once, by one thread, exactly as
/// [`SparseCholesky::new`] makes it; so every answer is the same whether it
/// was made at the start, in the background, or by the first caller. A scene
/// whose compliance comes from a valid cache starts without it (the cache
/// holds every column a frame reads); the lazy columns, interior
/// displacements and a rebuilt cache batch wait for it.
pub struct LazyFactor {
    cell: std::sync::OnceLock<Result<SparseCholesky, FemError>>,
    k: LowerCsc,
    dofs: DofMap,
    /// The ordering asked for ([`FillOrdering::Best`] is resolved by the factor).
    pub(crate) requested: FillOrdering,
    started: std::sync::atomic::AtomicBool,
}

impl std::fmt::Debug for LazyFactor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LazyFactor").field("dim", &self.k.dim).field("ready", &self.is_ready()).finish()
    }
}

impl LazyFactor {
    pub(crate) fn new(k: LowerCsc, dofs: DofMap, requested: FillOrdering) -> Self {
        Self { cell: std::sync::OnceLock::new(), k, dofs, requested, started: std::sync::atomic::AtomicBool::new(false) }
    }

    /// The factor: made here if nobody has started it, else waits for the thread making it.
    pub fn get(&self) -> Result<&SparseCholesky, FemError> {
        self.cell.get_or_init(|| SparseCholesky::new(&self.k, &self.dofs, self.requested)).as_ref().map_err(Clone::clone)
    }

    /// True once the factor (or its error) is there.
    pub fn is_ready(&self) -> bool {
        self.cell.get().is_some()
    }

    /// The lower triangle of `K_FF` it factors.
    pub(crate) fn stiffness(&self) -> &LowerCsc {
        &self.k
    }

    /// Starts making the factor on its own thread (once; nothing when it is
    /// made or being made). If the thread cannot start, the first caller of
    /// [`Self::get`] makes it.
    pub(crate) fn start_background(self: &std::sync::Arc<Self>) {
        if self.is_ready() || self.started.swap(true, std::sync::atomic::Ordering::AcqRel) {
            return;
        }
        let this = std::sync::Arc::clone(self);
        let spawned = std::thread::Builder::new().name("fissure-factor".into()).spawn(move || {
            let t = Instant::now();
            match this.get() {
                Ok(_) => tracing::debug!("factor of K_FF ready after {:.2} s in the background", t.elapsed().as_secs_f64()),
                Err(e) => tracing::error!("factor of K_FF in the background: {e}"),
            }
        });
        if let Err(e) = spawned {
            tracing::warn!("factor thread did not start ({e}); the first solve makes the factor");
        }
    }
}
