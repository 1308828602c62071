//! One switch per measured optimisation of fem/, so each one's gain can be measured again on today's code and
//! machine (`cargo bench --bench fem -- audit`, `scripts/fem_audit.sh`; docs/design-notes.md).
//!
//! In: `FISSURE_FEM_OFF=name,name` (read once; names in [`Optimisation::ALL`], `all` turns every one off), or
//! [`set_enabled`] from a test. Out: a [`Tuning`], taken by value when a solver, product workspace or factor is
//! made ([`Tuning::current`]), so no hot loop reads the process-wide switches and a bench can turn one off on a
//! built solver (`ConstrainedSolver::set_tuning`). Off runs the plain path the optimisation replaced. Answers stay
//! the same bit for bit unless the switch's doc says otherwise. A diagnostic, not a setting: scenes cannot name these.

use std::sync::Once;
use std::sync::atomic::{AtomicU32, Ordering};

/// A measured optimisation of fem/ that can be switched off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Optimisation {
    /// The AVX2 build of the surface product's kernel (`src/fem/compliance/product.rs`; off: the portable build, same bits).
    Avx2Product,
    /// Eight columns at a time in the surface product (`src/fem/compliance/product.rs`; off: one at a time, same order).
    FusedColumns,
    /// The surface product in cache-sized chunks of 512 rows (off: a component's rows in one pass, same sums).
    RowChunks,
    /// The forced columns' gathered rows kept from frame to frame (`src/fem/compliance/product.rs`; off: gathered again).
    KeptProductRows,
    /// W's factor kept across frames and updated (`src/linalg/kept_factor.rs`; off: factored in full every time, which differs in
    /// the last bits as an incremental factor does).
    WFactorReuse,
    /// The contact candidates' K^-1 blocks kept between frames (`src/fem/constrained/blocks.rs`, compliance over 64 MB; off:
    /// read from the compliance every time).
    CandidateBlocks,
    /// The row-major multi-column sparse solve (`src/linalg/cholesky.rs`; off: faer's column-major supernodal solve).
    RowMajorSolve,
    /// Huge pages under a computed compliance (`src/fem/compliance/mod.rs`).
    HugePages,
    /// Skipping the inactive candidates that cannot have reached their constraint since last evaluated
    /// (`src/fem/constrained/screen.rs`; off: every candidate at every iteration).
    CandidateScreen,
    /// W's entries between the step's candidate and tether rows kept across its active-set iterations
    /// (`src/fem/constrained/pairs.rs`; off: the whole block gathered again every iteration, same bits).
    KeptRowPairs,
    /// A taut tether's compliance read from its own columns over the stored rows, made once from its nodes'
    /// (`src/fem/constrained/tethers.rs`; off: node by node from their 3x3 blocks, which differs in the last bits).
    TetherColumns,
    /// The surface product split at one row over two threads, and its gathers of many new rows and its new
    /// projections split likewise (`src/fem/compliance/product.rs`, `src/par.rs`; off: one thread, same bits).
    ParallelProduct,
    /// A column forced along one direction (a face-plane row's node) streamed as its projection `K^-1[rows, c] n`,
    /// kept while the direction stays (`src/fem/compliance/projected.rs`; off: its 3x3 blocks, which differs in the
    /// surface's last bits).
    ProjectedColumns,
    /// An active-set iteration that activates violated candidates also releases the rows its solve found pulling
    /// (a primal-dual step, in the first `BULK_RELEASE_ITERATIONS`; `src/fem/constrained/mod.rs`; off: they wait
    /// until no candidate is violated). Both end on an active set within the same tolerances; where more than one
    /// is (a vertex within tolerance of its blade), they can end on different ones, and the kept factor's last bits
    /// follow the path, so answers can differ in their last bits.
    PrimalDualSteps,
    /// The candidate screen's records kept from frame to frame: a candidate whose node, when last evaluated in an
    /// earlier frame, lay further inside its new plane or sphere than the forces' change since can have moved it is
    /// not evaluated (`src/fem/constrained/screen.rs`; off: every frame evaluates its candidates anew, same bits).
    ScreenAcrossFrames,
    /// The compliance blocks a row is about to read asked into cache all at once first, where the row is new to the
    /// step (W's entries) or read blocks last time (a candidate's kept row): they lie apart in the storage
    /// (`src/fem/constrained/mod.rs`; off: each read waits on memory in turn, same bits).
    PrefetchBlocks,
    /// An evaluation pass's displacements made ahead on two threads when it evaluates many nodes, each through its
    /// kept row (`src/fem/constrained/blocks.rs`, `src/par.rs`; off: one after the other, same bits).
    ParallelCandidates,
    /// W's entries of many rows new to the step (a first contact's) gathered on two threads
    /// (`src/fem/constrained/gather.rs`, `src/par.rs`; off: one row after the other, same bits).
    ParallelGather,
}

impl Optimisation {
    /// Every switch with its name in `FISSURE_FEM_OFF`, in declaration order.
    pub const ALL: [(Optimisation, &'static str); 18] = [
        (Optimisation::Avx2Product, "avx2-product"),
        (Optimisation::FusedColumns, "fused-columns"),
        (Optimisation::RowChunks, "row-chunks"),
        (Optimisation::KeptProductRows, "kept-product-rows"),
        (Optimisation::WFactorReuse, "w-factor-reuse"),
        (Optimisation::CandidateBlocks, "candidate-blocks"),
        (Optimisation::RowMajorSolve, "row-major-solve"),
        (Optimisation::HugePages, "huge-pages"),
        (Optimisation::CandidateScreen, "candidate-screen"),
        (Optimisation::KeptRowPairs, "kept-row-pairs"),
        (Optimisation::TetherColumns, "tether-columns"),
        (Optimisation::ParallelProduct, "parallel-product"),
        (Optimisation::ProjectedColumns, "projected-columns"),
        (Optimisation::PrimalDualSteps, "primal-dual-steps"),
        (Optimisation::ScreenAcrossFrames, "screen-across-frames"),
        (Optimisation::PrefetchBlocks, "prefetch-blocks"),
        (Optimisation::ParallelCandidates, "parallel-candidates"),
        (Optimisation::ParallelGather, "parallel-gather"),
    ];

    /// Its name in `FISSURE_FEM_OFF`.
    pub fn name(self) -> &'static str {
        Self::ALL[self as usize].1
    }

    fn bit(self) -> u32 {
        1 << self as u32
    }
}

static OFF: AtomicU32 = AtomicU32::new(0);
static FROM_ENV: Once = Once::new();

fn off_mask() -> u32 {
    FROM_ENV.call_once(|| {
        let Ok(list) = std::env::var("FISSURE_FEM_OFF") else { return };
        let mut mask = 0;
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match Optimisation::ALL.iter().find(|(_, n)| *n == name) {
                Some((o, _)) => mask |= o.bit(),
                None if name == "all" => mask = u32::MAX,
                None => tracing::warn!(
                    "FISSURE_FEM_OFF: unknown optimisation {name:?} (known: {}, all); ignored",
                    Optimisation::ALL.iter().map(|(_, n)| *n).collect::<Vec<_>>().join(", ")
                ),
            }
        }
        if mask != 0 {
            tracing::warn!("FISSURE_FEM_OFF={list}: measured optimisations switched off (a diagnostic)");
        }
        OFF.fetch_or(mask, Ordering::Relaxed);
    });
    OFF.load(Ordering::Relaxed)
}

/// Which optimisations are on: a value a solver keeps from when it was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tuning {
    off: u32,
}

impl Tuning {
    /// Every optimisation on.
    pub const ALL_ON: Tuning = Tuning { off: 0 };

    /// The process's switches now (`FISSURE_FEM_OFF`, then [`set_enabled`]).
    pub fn current() -> Self {
        Self { off: off_mask() }
    }

    /// Whether `o` is on.
    #[inline]
    pub fn enabled(self, o: Optimisation) -> bool {
        self.off & o.bit() == 0
    }

    /// The same with `o` switched on or off.
    pub fn with(self, o: Optimisation, on: bool) -> Self {
        Self { off: if on { self.off & !o.bit() } else { self.off | o.bit() } }
    }
}

/// [`Tuning::current`]: what a solver made without being told takes.
impl Default for Tuning {
    fn default() -> Self {
        Self::current()
    }
}

/// Switches `o` for the whole process: the default of every solver, workspace and factor made afterwards (tests).
pub fn set_enabled(o: Optimisation, on: bool) {
    off_mask();
    if on {
        OFF.fetch_and(!o.bit(), Ordering::Relaxed);
    } else {
        OFF.fetch_or(o.bit(), Ordering::Relaxed);
    }
}
