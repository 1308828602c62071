//! Sparse Cholesky of a symmetric positive definite matrix, here `K_FF` (faer, supernodal; AMD or nested
//! dissection, [`super::ordering`]).
//!
//! In: the lower triangle of `K_FF` ([`LowerCsc`]). Out: a [`SparseCholesky`] solving `K_FF X = B` in place.
//! Stays true: symbolic analysis once, the numeric factor once per material set; solves run on one core
//! (`Par::Seq`: on a 2-core machine two threads made sparse solves slower, and the other core runs background work
//! or rendering) and allocate only the scratch sized for their column count.

use super::{FactorError, LowerCsc};
use super::ordering::{FillOrdering, nested_dissection};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::dyn_stack::StackReq;
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Conj, MatMut, MatRef, Par, Side, Spec};
use std::time::Instant;

/// Supernode amalgamation (faer's rule: merge two adjacent supernodes of `n` columns in all when the merged one has
/// a fraction of zeros below `z`, for the first `(n, z)` with `n` at most its bound). Coarser than faer's default
/// `[(4, 1.0), (16, 0.8), (48, 0.1), (MAX, 0.05)]`: the precompute's 192-column solves run dense kernels per
/// supernode, which pays for the extra stored entries (`cargo bench --bench fem -- coarse`, "ordering" lines).
const SUPERNODE_RELAX: &[(usize, f64)] = &[(32, 1.0), (96, 0.8), (256, 0.2), (usize::MAX, 0.05)];

/// A factored `K_FF`.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    /// Supernodal factor: the supernode of each (permuted) row, and each supernode's parent in the elimination tree
    /// (`u32::MAX` at a root): what [`Self::solve_sparse_in_place`] prunes along.
    row_supernode: Vec<u32>,
    parent: Vec<u32>,
    /// Solves run row major ([`Self::solve_row_major`]) where they can (on unless [`Self::set_row_major`] says).
    row_major: bool,
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
    /// Analyzes and factors `k`; a non-positive pivot is reported with its DOF and the (node, component) `name`
    /// gives it (e.g. [`crate::fem::assembly::DofMap::name`]).
    pub fn new(k: &LowerCsc, ordering: FillOrdering, name: &dyn Fn(usize) -> (u32, usize)) -> Result<Self, FactorError> {
        let a = k.as_faer();
        let t0 = Instant::now();
        let analyse = |ord: SymmetricOrdering<'_, usize>| {
            let mut params = CholeskySymbolicParams::default();
            params.supernodal_params.relax = Some(SUPERNODE_RELAX);
            factorize_symbolic_cholesky(a.symbolic(), Side::Lower, ord, params)
                .map_err(|e| FactorError::Factorization { reason: format!("symbolic analysis: {e:?}") })
        };
        let nd = || -> Result<Option<SymbolicCholesky<usize>>, FactorError> {
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
                // Both analyses are cheap next to the numeric factor; keep the one with less fill (solves stream L).
                // They run side by side (each alone is deterministic, and the choice depends only on their counts).
                let (by_amd, by_nd) = std::thread::scope(|scope| {
                    let amd = std::thread::Builder::new().name("fissure-amd".into()).spawn_scoped(scope, || analyse(SymmetricOrdering::Amd));
                    let by_nd = nd();
                    let by_amd = match amd {
                        Ok(handle) => handle.join().unwrap_or_else(|_| Err(FactorError::Factorization { reason: "the AMD analysis panicked".into() })),
                        // No thread to spare: one after the other.
                        Err(_) => analyse(SymmetricOrdering::Amd),
                    };
                    (by_amd, by_nd)
                });
                let by_amd = by_amd?;
                match by_nd? {
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
        values.try_reserve_exact(len).map_err(|_| FactorError::OutOfMemory { what: "Cholesky factor", bytes: len * 8 })?;
        values.resize(len, 0.0);
        let req = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Spec::default());
        let mut mem = MemBuffer::try_new(req).map_err(|_| FactorError::OutOfMemory { what: "factorization scratch", bytes: 0 })?;
        let stack = MemStack::new(&mut mem);
        let result = symbolic.factorize_numeric_llt(&mut values, a, Side::Lower, LltRegularization::default(), Par::Seq, stack, Spec::default());
        if let Err(LltError::NonPositivePivot { index }) = result {
            // `index` is in the permuted order: map back to our DOF numbering.
            let dof = symbolic.perm().map(|p| p.arrays().0[index]).unwrap_or(index);
            let (node, component) = name(dof);
            return Err(FactorError::NotPositiveDefinite { dof, node, component });
        }
        let numeric_seconds = t1.elapsed().as_secs_f64();
        let (row_supernode, parent) = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(sn) => elimination_tree(sn),
            SymbolicCholeskyRaw::Simplicial(_) => (Vec::new(), Vec::new()),
        };
        Ok(Self { symbolic, values, row_supernode, parent, row_major: true, symbolic_seconds, numeric_seconds, ordering })
    }

    /// Dimension (free DOFs).
    pub fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Stored entries of the factor L.
    pub fn nnz_l(&self) -> usize {
        self.values.len()
    }

    /// Entries of L counted exactly (column counts of the same ordering, without the explicit zeros of relaxed
    /// supernodes): CHOLMOD's `lnz`, to compare orderings across libraries. `k` is the matrix this was made from.
    pub fn exact_nnz_l(&self, k: &LowerCsc) -> Result<usize, FactorError> {
        use faer::sparse::linalg::SupernodalThreshold;
        let mut params = CholeskySymbolicParams::default();
        params.supernodal_flop_ratio_threshold = SupernodalThreshold::FORCE_SIMPLICIAL;
        let ordering = match self.symbolic.perm() {
            Some(p) => SymmetricOrdering::Custom(p),
            None => SymmetricOrdering::Identity,
        };
        let simplicial = factorize_symbolic_cholesky(k.as_faer().symbolic(), Side::Lower, ordering, params)
            .map_err(|e| FactorError::Factorization { reason: format!("symbolic analysis: {e:?}") })?;
        Ok(simplicial.len_val())
    }

    /// Switches the row-major solve on or off for later solves (the bench's audit; the answers are the same bits).
    pub fn set_row_major(&mut self, on: bool) {
        self.row_major = on;
    }

    /// Scratch a solve with `ncols` right-hand sides needs.
    pub fn scratch(&self, ncols: usize) -> Result<MemBuffer, FactorError> {
        let req = self.symbolic.solve_in_place_scratch::<f64>(ncols, Par::Seq).or(self.row_major_scratch(ncols));
        MemBuffer::try_new(req).map_err(|_| FactorError::OutOfMemory { what: "solve scratch", bytes: req.size_bytes() })
    }

    /// Solves `K_FF X = B` in place (`rhs` dim x k, column major). With [`ROW_MAJOR_MIN_RHS`] or more columns and a
    /// supernodal factor it runs [`Self::solve_row_major`], bit for bit faer's answer.
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>, scratch: &mut MemBuffer) {
        if rhs.ncols() >= ROW_MAJOR_MIN_RHS
            && self.row_major
            && let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw()
        {
            self.solve_row_major(symbolic, rhs, None, None, MemStack::new(scratch));
            return;
        }
        let llt = LltRef::new(&self.symbolic, &self.values);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(scratch));
    }

    /// As [`Self::solve_in_place`] for right-hand sides zero outside `nonzero_rows` (the caller's promise; any order,
    /// repeats allowed), with the same answer bit for bit: the forward substitution visits only the supernodes on
    /// the elimination-tree paths from those rows to the roots, since below them every entry stays an exact zero.
    /// `wanted` ([`Self::supernodes_above`] of the rows the caller reads; `None`: all): the backward substitution
    /// visits only those, so the answer is exact at those rows and meaningless elsewhere.
    pub fn solve_sparse_in_place(&self, rhs: MatMut<'_, f64>, nonzero_rows: &[usize], wanted: Option<&[bool]>, scratch: &mut MemBuffer) {
        if self.row_major
            && let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw()
        {
            let reached = self.supernodes_above(nonzero_rows).unwrap_or_default();
            self.solve_row_major(symbolic, rhs, Some(&reached), wanted, MemStack::new(scratch));
            return;
        }
        self.solve_in_place(rhs, scratch);
    }

    /// The supernodes on the elimination-tree paths from `rows` (any order, repeats allowed) to the roots: those a
    /// forward substitution from right-hand sides nonzero only at `rows` visits, and those a backward substitution
    /// needs for the answer at `rows`. `None` when the factor is not supernodal.
    pub fn supernodes_above(&self, rows: &[usize]) -> Option<Vec<bool>> {
        let mut reached = Vec::new();
        self.supernodes_above_into(rows, &mut reached).then_some(reached)
    }

    /// As [`Self::supernodes_above`], into `reached` (no allocation once grown); false (and `reached` empty) when
    /// the factor is not supernodal.
    pub fn supernodes_above_into(&self, rows: &[usize], reached: &mut Vec<bool>) -> bool {
        reached.clear();
        let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw() else { return false };
        let inv = self.symbolic.perm().map(|p| p.arrays().1);
        reached.resize(symbolic.n_supernodes(), false);
        for &old in rows {
            let row = inv.map_or(old, |v| v[old]);
            if let Some(&s) = self.row_supernode.get(row) {
                reached[s as usize] = true;
            }
        }
        // Children come before their parents: one ascending pass closes the set under "parent of".
        for s in 0..reached.len() {
            if reached[s] && let Some(&p) = self.parent.get(s).filter(|&&p| p != u32::MAX) {
                reached[p as usize] = true;
            }
        }
        true
    }

    /// Solves `K_FF X = B` in place, visiting forward only the supernodes `forward` marks (`B` is zero at the
    /// others' rows: the caller's promise) and backward only those `backward` marks (the answer is read only at
    /// their rows), both from [`Self::supernodes_above_into`]; `None`: all. Bit for bit [`Self::solve_in_place`]'s
    /// answer where read; a factor that is not supernodal solves in full.
    pub fn solve_pruned_in_place(&self, rhs: MatMut<'_, f64>, forward: Option<&[bool]>, backward: Option<&[bool]>, scratch: &mut MemBuffer) {
        if self.row_major
            && let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw()
        {
            self.solve_row_major(symbolic, rhs, forward, backward, MemStack::new(scratch));
            return;
        }
        self.solve_in_place(rhs, scratch);
    }

    /// Columns of `K_FF^-1`: column `3 b + c` of `rhs` (dim x 3 nodes) solves the unit right-hand side at DOF
    /// `first_dofs[b] + c`, pruned as [`Self::solve_sparse_in_place`] (`wanted` likewise). How the lazy columns
    /// turn nodes into columns; the precompute reads the same solve where it is made ([`Self::solve_unit_columns_in`]).
    pub fn solve_unit_columns(&self, first_dofs: &[usize], mut rhs: MatMut<'_, f64>, wanted: Option<&[bool]>, scratch: &mut MemBuffer) {
        rhs.fill(0.0);
        let mut rows = Vec::with_capacity(3 * first_dofs.len());
        for (b, &d) in first_dofs.iter().enumerate() {
            for c in 0..3 {
                rhs[(d + c, 3 * b + c)] = 1.0;
                rows.push(d + c);
            }
        }
        self.solve_sparse_in_place(rhs.subcols_mut(0, 3 * first_dofs.len()), &rows, wanted, scratch);
    }

    /// Scratch of [`Self::solve_row_major`] for `k` columns: the permuted right-hand sides (row major), and one
    /// supernode's diagonal rows and rows below the diagonal block (column major).
    fn row_major_scratch(&self, k: usize) -> StackReq {
        StackReq::new::<f64>(self.dim() * k).and(self.substitute_scratch(k))
    }

    /// Scratch of [`Self::substitute`] for `k` columns: one supernode's diagonal rows and rows below the diagonal block.
    fn substitute_scratch(&self, k: usize) -> StackReq {
        let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw() else { return StackReq::EMPTY };
        let (widest, deepest) = supernode_extent(symbolic);
        StackReq::new::<f64>(widest * k).and(StackReq::new::<f64>(deepest * k))
    }

    /// faer's supernodal solve with the right-hand sides held row major, so an update from a supernode's rows below
    /// its diagonal block touches one contiguous row of all `k` right-hand sides, not `k` entries a column apart
    /// (with the precompute's 96 columns, faer's scatter, gather and permutation took a third of its time). The
    /// arithmetic is faer's, in faer's order: the same triangular solves on a column-major copy of the supernode's
    /// rows, the same product below the diagonal block (its kernel sums each entry in the same order whatever the
    /// layout), each entry subtracted once; so the answer is faer's bit for bit. `forward`: the supernodes the
    /// forward substitution must visit (the others' rows are zero and stay zero); `backward`: those the backward
    /// substitution visits (the rest of the answer is left unfinished); `None`: all.
    fn solve_row_major(
        &self,
        symbolic: &SymbolicSupernodalCholesky<usize>,
        mut rhs: MatMut<'_, f64>,
        forward: Option<&[bool]>,
        backward: Option<&[bool]>,
        stack: &mut MemStack,
    ) {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        let (mut x, stack) = stack.make_with::<f64>(n * k, |_| 0.0);
        let x: &mut [f64] = &mut x;
        // x[inv[old], j] = rhs[old, j], a block of rows at a time so both sides are read and written in runs
        let inv = self.symbolic.perm().map(|p| p.arrays().1);
        let new_row = |old: usize| inv.map_or(old, |v| v[old]);
        for first in (0..n).step_by(ROW_BLOCK) {
            let last = (first + ROW_BLOCK).min(n);
            for j in 0..k {
                let col = rhs.rb().col(j);
                for old in first..last {
                    x[new_row(old) * k + j] = col[old];
                }
            }
        }
        self.substitute(symbolic, x, k, forward, backward, stack);
        // rhs[old, j] = x[inv[old], j]
        for first in (0..n).step_by(ROW_BLOCK) {
            let last = (first + ROW_BLOCK).min(n);
            for j in 0..k {
                let mut col = rhs.rb_mut().col_mut(j);
                for old in first..last {
                    col[old] = x[new_row(old) * k + j];
                }
            }
        }
    }

    /// The forward then the backward substitution of [`Self::solve_row_major`] over `x` (n x k, row major, in the
    /// factor's order), in place; `top` and `below` come from `stack`.
    fn substitute(&self, symbolic: &SymbolicSupernodalCholesky<usize>, x: &mut [f64], k: usize, forward: Option<&[bool]>, backward: Option<&[bool]>, stack: &mut MemStack) {
        let llt = SupernodalLltRef::new(symbolic, &self.values);
        let (widest, deepest) = supernode_extent(symbolic);
        let (mut top, stack) = stack.make_with::<f64>(widest * k, |_| 0.0);
        let top: &mut [f64] = &mut top;
        let (mut below, _) = stack.make_with::<f64>(deepest * k, |_| 0.0);
        let below: &mut [f64] = &mut below;
        forward_substitution(&llt, x, top, below, k, forward);
        backward_substitution(&llt, x, top, below, k, backward);
    }

    /// Scratch of [`Self::solve_unit_columns_in`] for `nodes` nodes (3 right-hand sides each).
    pub fn unit_scratch(&self, nodes: usize) -> Result<UnitScratch, FactorError> {
        let k = 3 * nodes;
        let len = if self.solves_row_major() { self.dim() * k } else { 0 };
        // Zeroed by the allocator: pages of rows a solve never touches are never written, nor resident.
        let x = bytemuck::allocation::try_zeroed_vec(len).map_err(|_| FactorError::OutOfMemory { what: "solve scratch", bytes: len * 8 })?;
        let req = if self.solves_row_major() { self.substitute_scratch(k) } else { self.symbolic.solve_in_place_scratch::<f64>(k, Par::Seq) };
        let stack = MemBuffer::try_new(req).map_err(|_| FactorError::OutOfMemory { what: "solve scratch", bytes: req.size_bytes() })?;
        Ok(UnitScratch { x, stack, fallback: None, nodes })
    }

    fn solves_row_major(&self) -> bool {
        self.row_major && matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// [`Self::solve_unit_columns`] without a dense right-hand side: the unit entries are set in the row-major
    /// right-hand sides themselves and the answer is read there ([`UnitColumns::at`]), bit for bit the same values,
    /// with neither the `dim x 3 nodes` column-major matrix nor the two copies between the layouts. Only the rows a
    /// solve reads are cleared first: those of the supernodes the forward substitution visits (above the right-hand
    /// sides' rows) and of those the backward one visits (`wanted`, all when `None`); no other row is read or written.
    /// A factor that does not solve row major solves column major into the scratch's own matrix.
    /// `first_dofs` holds at most as many nodes as the scratch was made for, or this fails.
    pub fn solve_unit_columns_in<'a>(&'a self, first_dofs: &[usize], wanted: Option<&[bool]>, scratch: &'a mut UnitScratch) -> Result<UnitColumns<'a>, FactorError> {
        if first_dofs.len() > scratch.nodes {
            return Err(FactorError::Factorization { reason: format!("{} nodes solved in a scratch made for {}", first_dofs.len(), scratch.nodes) });
        }
        let k = 3 * first_dofs.len();
        if self.solves_row_major()
            && let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw()
        {
            let rows: Vec<usize> = first_dofs.iter().flat_map(|&d| d..d + 3).collect();
            let reached = self.supernodes_above(&rows).unwrap_or_default();
            let x = &mut scratch.x[..self.dim() * k];
            let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
            for sn in 0..symbolic.n_supernodes() {
                if reached[sn] || wanted.is_none_or(|w| w[sn]) {
                    x[begin[sn] * k..end[sn] * k].fill(0.0);
                }
            }
            let inv = self.symbolic.perm().map(|p| p.arrays().1);
            for (j, &old) in rows.iter().enumerate() {
                x[inv.map_or(old, |v| v[old]) * k + j] = 1.0;
            }
            self.substitute(symbolic, x, k, Some(&reached), wanted, MemStack::new(&mut scratch.stack));
            return Ok(UnitColumns::RowMajor { x: &scratch.x[..self.dim() * k], k, inv });
        }
        let m = scratch.fallback.insert(faer::Mat::zeros(self.dim(), k));
        self.solve_unit_columns(first_dofs, m.as_mut(), wanted, &mut scratch.stack);
        Ok(UnitColumns::ColMajor(m.as_ref()))
    }

    /// Solves for one right-hand side stored in a slice.
    pub fn solve_vec_in_place(&self, rhs: &mut [f64], scratch: &mut MemBuffer) {
        let n = rhs.len();
        let m = faer::MatMut::from_column_major_slice_mut(rhs, n, 1);
        self.solve_in_place(m, scratch);
    }
}

/// What [`SparseCholesky::solve_unit_columns_in`] solves in, kept from one solve to the next
/// ([`SparseCholesky::unit_scratch`]): the row-major right-hand sides, the substitutions' scratch, and the
/// column-major matrix of a factor that does not solve row major.
pub struct UnitScratch {
    x: Vec<f64>,
    stack: MemBuffer,
    fallback: Option<faer::Mat<f64>>,
    /// Nodes a solve may hold.
    nodes: usize,
}

/// The columns [`SparseCholesky::solve_unit_columns_in`] solved, where they were solved.
pub enum UnitColumns<'a> {
    /// Row major in the factor's order: DOF `d` of column `j` at `x[inv[d] k + j]`.
    RowMajor { x: &'a [f64], k: usize, inv: Option<&'a [usize]> },
    /// Column major, `dim x k`.
    ColMajor(MatRef<'a, f64>),
}

impl UnitColumns<'_> {
    /// The entry of column `j` at DOF `dof`.
    #[inline]
    pub fn at(&self, dof: usize, j: usize) -> f64 {
        match self {
            Self::RowMajor { x, k, inv } => x[inv.map_or(dof, |v| v[dof]) * k + j],
            Self::ColMajor(m) => m[(dof, j)],
        }
    }
}

/// Right-hand sides from which [`SparseCholesky::solve_in_place`] runs row major (one column gains nothing).
pub const ROW_MAJOR_MIN_RHS: usize = 8;

/// Rows moved between layouts a block at a time (a block of 32 rows of up to 192 columns stays in the core's cache).
const ROW_BLOCK: usize = 32;

/// `L y = x` over the row-major right-hand sides `x` (n x k), in place: the supernodes in order, those `forward`
/// marks (all when `None`); `top` and `below` are scratch of the widest and deepest supernode.
fn forward_substitution(llt: &SupernodalLltRef<'_, usize, f64>, x: &mut [f64], top: &mut [f64], below: &mut [f64], k: usize, forward: Option<&[bool]>) {
    for s in 0..llt.symbolic().n_supernodes() {
        if forward.is_some_and(|f| !f[s]) {
            continue;
        }
        let node = llt.supernode(s);
        let (start, pattern, ls) = (node.start(), node.pattern(), node.val());
        let size = ls.ncols();
        let (ls_top, ls_bot) = ls.split_at_row(size);
        let mut x_top = MatMut::from_column_major_slice_mut(&mut top[..size * k], size, k);
        rows_to_columns(x, k, start, x_top.rb_mut());
        faer::linalg::triangular_solve::solve_lower_triangular_in_place_with_conj(ls_top, Conj::No, x_top.rb_mut(), Par::Seq);
        let mut update = MatMut::from_row_major_slice_mut(&mut below[..pattern.len() * k], pattern.len(), k);
        faer::linalg::matmul::matmul_with_conj(update.rb_mut(), Accum::Replace, ls_bot, Conj::No, x_top.rb(), Conj::No, 1.0, Par::Seq);
        columns_to_rows(x_top.rb(), x, k, start);
        for (idx, &i) in pattern.iter().enumerate() {
            let row = &mut x[i * k..][..k];
            for (v, u) in row.iter_mut().zip(&below[idx * k..][..k]) {
                *v -= u;
            }
        }
    }
}

/// `L^T z = y` in place, as [`forward_substitution`] but in reverse order over the supernodes `backward` marks.
fn backward_substitution(llt: &SupernodalLltRef<'_, usize, f64>, x: &mut [f64], top: &mut [f64], below: &mut [f64], k: usize, backward: Option<&[bool]>) {
    for s in (0..llt.symbolic().n_supernodes()).rev() {
        if backward.is_some_and(|b| !b[s]) {
            continue;
        }
        let node = llt.supernode(s);
        let (start, pattern, ls) = (node.start(), node.pattern(), node.val());
        let size = ls.ncols();
        let (ls_top, ls_bot) = ls.split_at_row(size);
        let depth = pattern.len();
        for (idx, &i) in pattern.iter().enumerate() {
            below[idx * k..][..k].copy_from_slice(&x[i * k..][..k]);
        }
        let gathered = MatRef::from_row_major_slice(&below[..depth * k], depth, k);
        let mut x_top = MatMut::from_column_major_slice_mut(&mut top[..size * k], size, k);
        rows_to_columns(x, k, start, x_top.rb_mut());
        faer::linalg::matmul::matmul_with_conj(x_top.rb_mut(), Accum::Add, ls_bot.transpose(), Conj::Yes, gathered, Conj::No, -1.0, Par::Seq);
        faer::linalg::triangular_solve::solve_upper_triangular_in_place_with_conj(ls_top.transpose(), Conj::Yes, x_top.rb_mut(), Par::Seq);
        columns_to_rows(x_top.rb(), x, k, start);
    }
}

/// The most columns and the most rows below the diagonal block of any supernode.
fn supernode_extent(symbolic: &SymbolicSupernodalCholesky<usize>) -> (usize, usize) {
    let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
    (0..symbolic.n_supernodes()).fold((0, 0), |(w, d), s| (w.max(end[s] - begin[s]), d.max(symbolic.supernode(s).pattern().len())))
}

/// The supernode of every row and the parent of every supernode (the supernode of the first row below its
/// diagonal block; `u32::MAX` at a root).
fn elimination_tree(symbolic: &SymbolicSupernodalCholesky<usize>) -> (Vec<u32>, Vec<u32>) {
    let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
    let mut row_supernode = vec![0u32; symbolic.nrows()];
    for s in 0..symbolic.n_supernodes() {
        row_supernode[begin[s]..end[s]].fill(s as u32);
    }
    let parent = (0..symbolic.n_supernodes())
        .map(|s| symbolic.supernode(s).pattern().iter().min().map_or(u32::MAX, |&r| row_supernode[r]))
        .collect();
    (row_supernode, parent)
}

/// `dst` (column major, `dst.nrows()` rows) = rows `start..` of the row-major `x` with `k` columns.
fn rows_to_columns(x: &[f64], k: usize, start: usize, mut dst: MatMut<'_, f64>) {
    for r in 0..dst.nrows() {
        let row = &x[(start + r) * k..][..k];
        for (j, v) in row.iter().enumerate() {
            dst[(r, j)] = *v;
        }
    }
}

/// Rows `start..` of the row-major `x` with `k` columns = `src`.
fn columns_to_rows(src: MatRef<'_, f64>, x: &mut [f64], k: usize, start: usize) {
    for r in 0..src.nrows() {
        let row = &mut x[(start + r) * k..][..k];
        for (j, v) in row.iter_mut().enumerate() {
            *v = src[(r, j)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::assembly::{DofMap, assemble_lower};
    use crate::mesh::fixtures;

    /// `K_FF` of `mesh` (one soft material) with its nodes at z = 0 held, and its DOFs: the matrices these solves
    /// are for. (On a 27-point grid Laplacian times tridiag(1, 2, 1) the row-major and pruned solves differ from
    /// faer's in the last two bits: the same-bits promise is measured on stiffness matrices only.)
    fn held_at_the_bottom(mesh: &crate::mesh::TetMesh) -> (LowerCsc, DofMap) {
        let fixed: Vec<bool> = mesh.positions.iter().map(|p| p.z <= 1e-12).collect();
        let dofs = DofMap::new(mesh, &fixed);
        let lame = vec![(1.0e3, 1.0e4); mesh.regions.len()];
        (assemble_lower(mesh, &lame, &dofs), dofs)
    }

    /// The row-major solve against faer's own on the same factor: the same bits for each ordering and for column
    /// counts below, at and above the switch (and the precompute's 96).
    #[test]
    fn row_major_solve_is_faers_bit_for_bit() {
        let mesh = fixtures::box_mesh(&fixtures::linspace(0.0, 0.06, 13), &fixtures::linspace(0.0, 0.05, 11), &fixtures::linspace(0.0, 0.04, 9)).unwrap();
        let (k, dofs) = held_at_the_bottom(&mesh);
        for ordering in [FillOrdering::Amd, FillOrdering::NestedDissection] {
            let chol = SparseCholesky::new(&k, ordering, &|d| dofs.name(d)).unwrap();
            assert!(matches!(chol.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)), "{ordering:?}: the test needs a supernodal factor");
            for ncols in [1, ROW_MAJOR_MIN_RHS - 1, ROW_MAJOR_MIN_RHS, 33, 96] {
                let b = faer::Mat::<f64>::from_fn(k.dim, ncols, |i, j| ((i * 31 + j * 17) % 23) as f64 - 11.0 + 1e-3 * j as f64);
                let mut ours = b.clone();
                let mut scratch = chol.scratch(ncols).unwrap();
                chol.solve_in_place(ours.as_mut(), &mut scratch);
                let mut faers = b.clone();
                let llt = LltRef::new(&chol.symbolic, &chol.values);
                llt.solve_in_place_with_conj(Conj::No, faers.as_mut(), Par::Seq, MemStack::new(&mut scratch));
                for j in 0..ncols {
                    for i in 0..k.dim {
                        assert_eq!(ours[(i, j)].to_bits(), faers[(i, j)].to_bits(), "{ordering:?}, {ncols} columns: entry ({i}, {j})");
                    }
                }
                // and it solves: K x = b to rounding
                let mut worst = 0.0f64;
                for j in 0..ncols {
                    let mut r: Vec<f64> = (0..k.dim).map(|i| -b[(i, j)]).collect();
                    for c in 0..k.dim {
                        for p in k.col_ptr[c]..k.col_ptr[c + 1] {
                            let (i, v) = (k.row_idx[p], k.values[p]);
                            r[i] += v * ours[(c, j)];
                            if i != c {
                                r[c] += v * ours[(i, j)];
                            }
                        }
                    }
                    worst = worst.max(r.iter().fold(0.0f64, |m, x| m.max(x.abs())));
                }
                assert!(worst < 1e-8, "{ordering:?}, {ncols} columns: residual {worst:e}");
            }
        }
    }

    /// Two boxes `K` does not couple, held at the bottom: a factor with skipped supernodes either way.
    fn two_bodies() -> (LowerCsc, DofMap) {
        let axis = fixtures::linspace(0.0, 0.04, 9);
        let a = fixtures::box_mesh(&fixtures::linspace(0.0, 0.06, 13), &axis, &axis).unwrap();
        let b = fixtures::box_mesh(&fixtures::linspace(0.1, 0.13, 7), &axis, &axis).unwrap();
        let mut mesh = a.clone();
        let shift = a.positions.len() as u32;
        mesh.positions.extend_from_slice(&b.positions);
        mesh.tets.extend(b.tets.iter().map(|t| t.map(|v| v + shift)));
        mesh.regions.extend_from_slice(&b.regions);
        held_at_the_bottom(&mesh)
    }

    /// The precompute's solve in its kept scratch reads the same bits as the column-major unit solve wherever it
    /// is read: batch after batch in one scratch (rows a batch left behind are cleared where the next one reads),
    /// with the backward pass pruned to every fifth node's rows and not pruned, with each ordering, and column
    /// major where the factor does not solve row major. More nodes than the scratch holds is an error.
    #[test]
    fn unit_columns_in_the_kept_scratch_are_the_column_major_solve_bit_for_bit() {
        let (k, dofs) = two_bodies();
        let nodes = dofs.dof_count() / 3;
        let read: Vec<usize> = (0..nodes).step_by(5).flat_map(|n| 3 * n..3 * n + 3).collect();
        let all: Vec<usize> = (0..k.dim).collect();
        for ordering in [FillOrdering::Amd, FillOrdering::NestedDissection] {
            for row_major in [true, false] {
                let mut chol = SparseCholesky::new(&k, ordering, &|d| dofs.name(d)).unwrap();
                chol.set_row_major(row_major);
                let wanted = chol.supernodes_above(&read).unwrap();
                let mut kept = chol.unit_scratch(64).unwrap();
                let batches: [Vec<usize>; 4] = [
                    (0..64).map(|b| 3 * ((b * 41) % nodes)).collect(),
                    vec![3 * (nodes / 2)],
                    (0..32).map(|b| 3 * ((b * 37 + 5) % nodes)).collect(),
                    (0..64).map(|b| 3 * ((b * 13 + 2) % nodes)).collect(),
                ];
                for (n, first) in batches.iter().enumerate() {
                    let (rows, pruned) = if n % 2 == 0 { (&read, Some(wanted.as_slice())) } else { (&all, None) };
                    let m = 3 * first.len();
                    let mut expected = faer::Mat::<f64>::zeros(k.dim, m);
                    let mut scratch = chol.scratch(m).unwrap();
                    chol.solve_unit_columns(first, expected.as_mut(), pruned, &mut scratch);
                    let solved = chol.solve_unit_columns_in(first, pruned, &mut kept).unwrap();
                    assert_eq!(matches!(solved, UnitColumns::RowMajor { .. }), row_major, "{ordering:?}: the layout");
                    for j in 0..m {
                        for &i in rows {
                            assert_eq!(solved.at(i, j).to_bits(), expected[(i, j)].to_bits(), "{ordering:?}, row major {row_major}, batch {n}: entry ({i}, {j})");
                        }
                    }
                }
                let too_many: Vec<usize> = (0..65).map(|b| 3 * (b % nodes)).collect();
                assert!(chol.solve_unit_columns_in(&too_many, None, &mut kept).is_err(), "65 nodes in a scratch for 64");
            }
        }
    }

    /// Unit columns solved pruned along the elimination tree are the full solve's bit for bit, for one node and a
    /// batch spread over the mesh, on two bodies `K` does not couple (the second's entries are exact zeros either
    /// way), with each ordering.
    #[test]
    fn pruned_unit_columns_are_the_full_solve_bit_for_bit_where_read() {
        let (k, dofs) = two_bodies();
        for ordering in [FillOrdering::Amd, FillOrdering::NestedDissection] {
            let chol = SparseCholesky::new(&k, ordering, &|d| dofs.name(d)).unwrap();
            assert!(!chol.parent.is_empty(), "{ordering:?}: the test needs a supernodal factor");
            let nodes = dofs.dof_count() / 3;
            for first in [vec![0usize], vec![3 * (nodes / 2)], (0..32).map(|b| 3 * ((b * 37) % nodes)).collect()] {
                let m = 3 * first.len();
                let mut pruned = faer::Mat::<f64>::zeros(k.dim, m);
                let mut scratch = chol.scratch(m).unwrap();
                chol.solve_unit_columns(&first, pruned.as_mut(), None, &mut scratch);
                // The answer read only at every fifth node's rows: the backward pass pruned too.
                let read: Vec<usize> = (0..nodes).step_by(5).flat_map(|n| 3 * n..3 * n + 3).collect();
                let wanted = chol.supernodes_above(&read).unwrap();
                assert!(wanted.iter().any(|w| !w), "{ordering:?}: some supernode is skipped");
                let mut partial = faer::Mat::<f64>::zeros(k.dim, m);
                chol.solve_unit_columns(&first, partial.as_mut(), Some(&wanted), &mut scratch);
                let mut full = faer::Mat::<f64>::zeros(k.dim, m);
                for (b, &d) in first.iter().enumerate() {
                    for c in 0..3 {
                        full[(d + c, 3 * b + c)] = 1.0;
                    }
                }
                let llt = LltRef::new(&chol.symbolic, &chol.values);
                llt.solve_in_place_with_conj(Conj::No, full.as_mut(), Par::Seq, MemStack::new(&mut scratch));
                let mut zeros = 0;
                for j in 0..m {
                    for i in 0..k.dim {
                        assert_eq!(pruned[(i, j)].to_bits(), full[(i, j)].to_bits(), "{ordering:?}, {m} columns: entry ({i}, {j})");
                        if read.binary_search(&i).is_ok() {
                            assert_eq!(partial[(i, j)].to_bits(), full[(i, j)].to_bits(), "{ordering:?}, {m} columns, read rows: entry ({i}, {j})");
                        }
                        zeros += usize::from(full[(i, j)] == 0.0);
                    }
                }
                assert!(zeros > 0, "the other body's entries are zero");
            }
        }
    }
}
