//! The per-frame exact constrained solve (Schur complement on the constraint rows).
//!
//! In: a [`FemModel`], its [`Compliance`], and each frame a slice of [`Constraint`]s (enforced vertex
//! displacements from the spatulas; unilateral skull-sphere candidates). Out: a [`FrameSolution`]: displacement of
//! every surface vertex, reaction per constraint, force per spatula and per sphere.
//!
//! Method: `K u = f + C^T lambda`, `C u = g`. With `u0 = K^-1 f` (gravity) and `W = C K^-1 C^T` gathered from the
//! compliance, `lambda = W^-1 (g - C u0)` and `u = u0 + K^-1 C^T lambda`: exact (no penalty) up to round-off and
//! the compliance's storage precision. `C^T lambda` is the force ON the tissue.
//!
//! Conflict rules (deterministic):
//! - a constraint on a fixed node is ignored; its reaction is zero;
//! - several enforced constraints on one node: one 3-row block with the mean of their targets; the node's
//!   reaction is split equally among them;
//! - an enforced node also claimed by a sphere: the enforced displacement wins, the sphere row is unused;
//! - rows still linearly dependent (two spheres with a common centre at one node) are dropped by
//!   [`crate::linalg::dense`] (the earlier row is kept) and counted in [`FrameSolution::dropped_rows`]; reaction zero,
//!   never NaN.
//!
//! Tool contacts (`ConstraintKind::Contact`) are unilateral. Each frame every such node starts held (three rows:
//! it sticks to the face, as in the paper); a hold whose reaction pulls (`F . n < 0`, n the face's outward normal)
//! is demoted to one face-plane row `n . u >= n . g`, handled like a sphere row: active (sliding on the face,
//! pushed along n only) or inactive (released). A node is never promoted back within a frame, so the loop ends.
//! A node pinched between opposing faces or claimed by `Enforced` stays held bilaterally. A sphere row applies to
//! a tool node only once it is demoted.
//!
//! Blade barriers (`ConstraintKind::Barrier`) are face-plane rows like a demoted hold, inactive until the
//! solution would pass the plane; a held node ignores them. The active set at the end of a frame is where the next
//! one starts (a still scene solves in one iteration).
//!
//! Skull spheres: a row `d . u >= b`, `d` the feasible radial direction at the node's current position. The loop
//! adds violated candidates, else drops the most adhesive active row (lambda < 0), else re-linearizes active rows
//! that miss the sphere, until no candidate is outside by more than `1e-9 R` and no active force pulls.
//!
//! Stays true: no allocation once the scratch has grown to the frame size (except lazily computed columns and the
//! work lists of a first contact's two-thread gather, `gather`); fixed
//! iteration order everywhere. Submodules: `blocks` (candidates' K^-1 blocks kept between frames), `columns` (K^-1
//! columns outside the ROI), `screen` (skipping candidates that cannot be violated).

mod blocks;
mod columns;
mod gather;
mod pairs;
mod screen;
mod tethers;

pub use tethers::{Tether, TetherEnd};

use blocks::{CANDIDATE_BLOCKS_FROM_BYTES, CandidateBlocks};
use columns::KinvSource;
use super::FemError;
use super::compliance::{Compliance, ProductWorkspace};
use super::tuning::{Optimisation, Tuning};
use crate::linalg::kept_factor::ContactFactor;
use super::model::FemModel;
use crate::math::{Matrix3, Vec3, is_finite3};

/// Relative tolerance of a sphere constraint (times its radius).
pub const SPHERE_TOLERANCE: f64 = 1e-9;
/// Under-relaxation of active sphere rows' linearization point after the frame's first
/// [`FULL_RELINEARIZATIONS`] (damps a period-2 oscillation under large forces).
pub const RELINEARIZE_RELAXATION: f64 = 0.5;
/// Re-linearizations a frame makes at its rows' current positions (Newton's step: the miss of a sliding row falls
/// with its square) before it damps them by [`RELINEARIZE_RELAXATION`]. With every step damped, a row took eight
/// to ten halvings to come within the tolerance (measured under tracker noise on the refined default scene: frames
/// of 10 to 32 iterations).
pub const FULL_RELINEARIZATIONS: usize = 3;
/// Relative tolerance of a tool contact: a hold is demoted when its push `F . n` is below `-CONTACT_TOLERANCE`
/// times the largest nodal tool force; a face-plane row activates when its node is behind the plane by more than
/// `CONTACT_TOLERANCE_M + CONTACT_TOLERANCE |n . g|`.
pub const CONTACT_TOLERANCE: f64 = 1e-9;
/// Absolute part of the contact gap tolerance, m.
pub const CONTACT_TOLERANCE_M: f64 = 1e-12;
/// Active-set iterations that demote every pulling hold at once; later ones demote one at a time.
pub const BULK_RELEASE_ITERATIONS: usize = 8;
/// Lazily computed columns kept between frames (each is 3 x free DOFs f64).
pub const LAZY_CAPACITY: usize = 128;

/// What a constraint asks of its node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConstraintKind {
    /// Displacement from rest (m): three bilateral rows.
    Enforced { displacement: Vec3 },
    /// A rigid tool face holding the node (spatula contact) at `displacement` (m, from rest; three rows) while the
    /// reaction pushes along `normal` (the face's outward normal; finite, non-zero, normalized here): `F . n >= 0`.
    /// Where holding would pull, the node is released, but may not pass the face plane through its target:
    /// `(u - displacement) . n >= 0`.
    Contact { displacement: Vec3, normal: Vec3 },
    /// A rigid tool face the node must not pass (a blade's row for a nearby surface vertex no ray claimed):
    /// `(u - displacement) . n >= 0`, `displacement` (m, from rest) a point of the face plane, `normal` as for
    /// `Contact`. Unilateral: zero force while the node is in front. Ignored while a tool holds the node.
    Barrier { displacement: Vec3, normal: Vec3 },
    /// The node stays inside the sphere (centre m, radius m > 0): one unilateral radial row.
    SphereInside { center: Vec3, radius: f64 },
    /// The node stays outside the sphere (centre m, radius m > 0): one unilateral radial row.
    SphereOutside { center: Vec3, radius: f64 },
}

impl ConstraintKind {
    /// The target displacement of a tool constraint (Enforced or Contact).
    pub fn tool_displacement(&self) -> Option<Vec3> {
        match *self {
            ConstraintKind::Enforced { displacement } | ConstraintKind::Contact { displacement, .. } => Some(displacement),
            _ => None,
        }
    }

    /// True for tool constraints (Enforced, Contact, Barrier): their reactions add to their spatula's force.
    pub fn is_tool(&self) -> bool {
        matches!(self, ConstraintKind::Enforced { .. } | ConstraintKind::Contact { .. } | ConstraintKind::Barrier { .. })
    }
}

/// One constraint on one mesh node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraint {
    /// Mesh node index.
    pub node: u32,
    /// Spatula index (Enforced) or sphere index (Sphere*), for per-owner sums.
    pub owner: u16,
    pub kind: ConstraintKind,
}

/// Result of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameSolution {
    /// Per surface vertex (order of `model.surface().vertices`): displacement from rest, m.
    pub displacement_surface: Vec<Vec3>,
    /// Per constraint (same order as the input): force ON the tissue, N.
    pub reactions: Vec<Vec3>,
    /// Per spatula owner (ascending): sum of the enforced reactions, N.
    pub owner_forces: Vec<(u16, Vec3)>,
    /// Per sphere owner (ascending): sum of the sphere reactions, N.
    pub sphere_forces: Vec<(u16, Vec3)>,
    /// Sphere rows active at the end of the frame.
    pub active_sphere_contacts: usize,
    /// Unilateral tool contacts released this frame (their hold would have pulled).
    pub released_contacts: usize,
    /// Blade barrier rows active at the end of the frame (an unclaimed vertex kept on a face plane).
    pub barrier_contacts: usize,
    /// Unilateral tool contacts that ended sliding on their face plane (normal push only).
    pub sliding_contacts: usize,
    /// Largest surface displacement in the working region (vertices with a compliance row, tracked far ones), m.
    pub max_displacement: f64,
    /// Estimate of cond(W) (`(max L_ii / min L_ii)^2`, a lower bound).
    pub conditioning: f64,
    /// Rows of W (3 per enforced node + active sphere rows).
    pub rows: usize,
    /// Rows dropped as linearly dependent.
    pub dropped_rows: usize,
    /// Active-set iterations (1 without spheres).
    pub iterations: usize,
    /// Nodes whose K^-1 columns had to be solved this frame (outside the ROI).
    pub lazy_solves: usize,
    /// Per tether (order of [`ConstrainedSolver::set_tethers`]): its tension, N (0 when slack or gone).
    pub tether_tension: Vec<f64>,
    /// Which entries of `displacement_surface` the last step wrote.
    pub surface_writes: SurfaceWrites,
}

/// Which entries of a [`FrameSolution`]'s `displacement_surface` a step wrote. A step writes every entry into a
/// solution it did not write last (another solver's, a fresh one, or one written since); into its own last one,
/// only the vertices whose displacement may have changed: those with a compliance row and the far vertices brought
/// up to date this step (the others keep the bits they had). Not part of the solution's value: two solutions
/// compare equal whatever wrote them.
#[derive(Debug, Clone, Default)]
pub struct SurfaceWrites {
    /// Unique to the write (0: none yet).
    stamp: u64,
    /// The stamp of the write this one changed (0: every entry was written).
    since: u64,
    /// Otherwise the surface vertices written (the working region's, then the tracked far ones).
    changed: Vec<u32>,
}

impl PartialEq for SurfaceWrites {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl SurfaceWrites {
    /// The write the last step changed and the surface vertices whose entries it wrote; `None`: it wrote all.
    pub fn changed_since(&self) -> Option<(u64, &[u32])> {
        (self.since != 0).then_some((self.since, self.changed.as_slice()))
    }

    /// Unique to the last step's write (0 for a solution no step wrote): equal stamps, the same write.
    pub fn stamp(&self) -> u64 {
        self.stamp
    }
}

/// Stamps of [`SurfaceWrites`], unique in the process.
static NEXT_SURFACE_WRITE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// Seconds spent in the phases of the last [`ConstrainedSolver::step`] (and one count).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhaseTimings {
    /// Gathering W from the compliance (all active-set iterations).
    pub gather: f64,
    /// Dense factorization of W (full or incremental) and the two triangular solves.
    pub factor: f64,
    /// Evaluating the candidates (skull, blade faces) at each iteration's solution.
    pub candidates: f64,
    /// Candidate evaluations the screen skipped (`constrained/screen.rs`), a count.
    pub screened: usize,
    /// Candidate evaluations made (each reads the candidate's blocks against every W node), a count.
    pub evaluated: usize,
    /// The surface product `u = u0 + K^-1 C^T lambda` over every surface row (`surface_gather` included).
    pub surface: f64,
    /// Part of `surface`: gathering the rows `K^-1[c, ..c]` of newly forced columns.
    pub surface_gather: f64,
    /// Sparse solves of columns outside the ROI, and waits for ROI columns still filling in the background.
    pub lazy: f64,
}

/// One row of C: `dir . u[node] = target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstraintRow {
    /// Index into the frame's node list.
    pub slot: usize,
    /// Unit direction.
    pub dir: Vec3,
    /// Target of `dir . u`, m.
    pub target: f64,
}

/// A unilateral row that may engage: its node, what it keeps the node from passing, whether it is on.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// Index of its constraint in the frame's input (a demoted hold has none: `usize::MAX`).
    constraint: usize,
    node: u32,
    owner: u16,
    active: bool,
    /// Linearization point (deformed position), m.
    at: Vec3,
    limit: Limit,
}

/// What an evaluation pass does with a candidate ([`ConstrainedSolver::pass_of`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pass {
    /// Its node is held by a tool this iteration: the row is dropped.
    Engaged,
    /// Held on its face plane by its active row: nothing to check.
    OnPlane,
    /// Inactive, and the screen shows it cannot be violated.
    Screened,
    /// Its node's displacement is made and the row checked.
    Evaluate,
}

/// What a candidate row keeps its node from passing.
#[derive(Debug, Clone, Copy)]
enum Limit {
    /// A skull sphere (centre, radius m): the node stays inside it or outside it.
    Sphere { center: Vec3, radius: f64, inside: bool },
    /// A face plane `normal . u >= b`: a blade barrier (`hold: None`) or a demoted tool hold (`Some(claim group)`).
    Plane { normal: Vec3, b: f64, hold: Option<usize> },
}

impl Limit {
    fn is_sphere(&self) -> bool {
        matches!(self, Limit::Sphere { .. })
    }
}

impl Candidate {
    /// A blade's face-plane row across steps ([`pairs::RowKey`]): its W entries against another stay while both
    /// rows do. A demoted hold's row is appended mid-step, out of the candidates' order, and a sphere row moves
    /// with its linearization point: neither has one.
    fn row_key(&self) -> Option<pairs::RowKey> {
        match self.limit {
            Limit::Plane { normal, hold: None, .. } => Some((self.node, crate::math::bits3(&normal))),
            _ => None,
        }
    }
}

struct LazyColumn {
    node: u32,
    /// 3 columns of length n_free, column major.
    values: Vec<f64>,
    last_used: u64,
}

/// Exact constrained solver; holds the model, the compliance and all scratch, in parts with one job each.
pub struct ConstrainedSolver {
    model: FemModel,
    compliance: Compliance,
    frame: u64,
    /// Replaces the active-set loop's iteration cap (tests of the capped path).
    iteration_cap: Option<usize>,
    /// The optimisations this solver uses (`fem::tuning`), changed only by [`Self::set_tuning`].
    tuning: Tuning,
    timings: PhaseTimings,
    sys: System,
    tools: ToolClaims,
    cands: Candidates,
    columns: LazyColumns,
    surface: SurfaceUpdate,
    tethers: tethers::TetherSet,
}

/// The frame's constraint system: its nodes and rows, W's factor and the solution.
#[derive(Default)]
struct System {
    order: Vec<(u32, usize)>,
    /// Distinct constrained nodes of the frame (enforced first, then active spheres).
    nodes: Vec<u32>,
    /// Counts the changes of `nodes` (the kept blocks' columns follow it).
    nodes_version: u64,
    rows: Vec<ConstraintRow>,
    /// Candidate index of each sphere row (row - enforced rows).
    row_candidate: Vec<usize>,
    /// Persistent factor of W (see [`crate::linalg::kept_factor`] for the order rule).
    factor: ContactFactor,
    /// Sphere rows of W: against the enforced rows (column per sphere row) and among themselves.
    w_es: Vec<f64>,
    w_ss: Vec<f64>,
    lambda: Vec<f64>,
    /// Force on each node (contact rows and tethers), N.
    node_force: Vec<Vec3>,
    /// The part of `node_force` applied through the nodes' columns: all but the pulls of tethers with columns of
    /// their own (`tethers::TetherColumns`), which the surface and the candidates read through those.
    direct_force: Vec<Vec3>,
    /// W's entries between the step's rows, kept across its iterations ([`pairs::RowPairs`]).
    pairs: pairs::RowPairs,
    /// Scratch: the pair slot of each s row this iteration.
    row_slots: Vec<usize>,
    solve_scratch: Option<faer::dyn_stack::MemBuffer>,
}

/// The tool constraints grouped by node, and which of them are held this iteration.
#[derive(Default)]
struct ToolClaims {
    /// Every node a tool claims this frame, ascending; `groups[g]` is node `claimed_sorted[g]`'s.
    claimed_sorted: Vec<u32>,
    groups: Vec<ClaimGroup>,
    /// The claims of every group in turn: (constraint index, owner).
    claims: Vec<(usize, u16)>,
    /// Engaged nodes ascending, and in factor order: engaged node k has rows 3k..3k+3 and group `enforced_group[k]`.
    engaged_sorted: Vec<u32>,
    perm_nodes: Vec<u32>,
    enforced_group: Vec<usize>,
    enforced_nodes: usize,
    /// Unilateral nodes released / sliding on their face plane in the last frame, ascending.
    released: Vec<u32>,
    sliding: Vec<u32>,
}

impl ToolClaims {
    /// Claim group g's claims: (constraint index, owner).
    fn claims_of(&self, g: usize) -> &[(usize, u16)] {
        &self.claims[self.groups[g].start..self.groups[g].end]
    }

    /// Whether a tool holds `node` bilaterally this frame (pinched between opposing faces, or `Enforced`).
    fn holds_bilaterally(&self, node: u32) -> bool {
        self.claimed_sorted.binary_search(&node).is_ok_and(|g| self.groups[g].normal.is_none())
    }
}

/// One node the tools claim this frame.
#[derive(Debug, Clone, Copy)]
struct ClaimGroup {
    /// Its claims: `ToolClaims::claims[start..end]`.
    start: usize,
    end: usize,
    /// The mean of its claims' targets (displacement from rest, m).
    target: Vec3,
    /// The faces' mean outward normal for a unilateral contact; `None`: held bilaterally.
    normal: Option<Vec3>,
    /// Held this iteration (a demoted node is a face-plane candidate instead).
    engaged: bool,
}

/// The unilateral rows that may engage (skull spheres, blade barriers, demoted holds), carried between frames.
struct Candidates {
    candidates: Vec<Candidate>,
    prev_active: Vec<(u32, u16, bool)>,
    /// Blade barrier rows active at the end of the last frame (node, owner), ascending: this frame starts from them.
    prev_barrier: Vec<(u32, u16)>,
    /// Which inactive candidates need no evaluation ([`screen::Screen`]).
    screen: screen::Screen,
    /// Per candidate node, its K^-1 blocks against the W nodes ([`CandidateBlocks`]), read at every iteration, where
    /// a compliance read is a cache miss. A kept block equals a re-read one, bit for bit.
    candidate_blocks: std::cell::RefCell<CandidateBlocks>,
    /// The compliance is over [`CANDIDATE_BLOCKS_FROM_BYTES`] (its blocks miss the CPU caches); fixed when made.
    large_compliance: bool,
}

/// The K^-1 columns solved in a frame for nodes outside the ROI, kept between frames.
#[derive(Default)]
struct LazyColumns {
    lazy: Vec<LazyColumn>,
    lazy_computed: usize,
    /// Counts the changes of `lazy`: [`ConstrainedSolver::kinv`] reads a node's lazy column (exact) when there is
    /// one, else the compliance (f32 beyond the ROI), so a kept block is valid only while `lazy` is unchanged.
    lazy_generation: u64,
}

/// The surface product: displacement of every stored row, and what it reads.
struct SurfaceUpdate {
    u_rows: Vec<Vec3>,
    prev_u_rows: Vec<Vec3>,
    col_forces: Vec<(usize, Vec3)>,
    /// Forced columns along one row's direction `(col, n, lambda)`, and per node slot its rows' count and its last
    /// row's direction and lambda.
    col_along: Vec<(usize, Vec3, f64)>,
    slot_rows: Vec<(u8, Vec3, f64)>,
    /// Scratch of the surface product (partial sums, gathered rows of forced columns).
    product: ProductWorkspace,
    /// The compliance row of each surface vertex (`u32::MAX`: none), read when the frame's surface is written.
    vertex_rows: Vec<u32>,
    /// The surface vertices with a compliance row, ascending: what a step writes besides the tracked far ones.
    row_vertices: Vec<u32>,
    /// The stamp of the last solution this solver wrote ([`SurfaceWrites`]).
    last_write: u64,
    /// Nodal forces of the last frame (node, force) for interior displacements.
    last_forces: Vec<(u32, Vec3)>,
    /// Free surface vertices (indices into `model.surface().vertices`) without a compliance row.
    far: Vec<u32>,
    /// Per surface vertex: a far vertex's displacement when last brought up to date (gravity's at first).
    held: Vec<Vec3>,
    /// Far vertices a blade is near ([`ConstrainedSolver::track`]), ascending: brought up to date each frame.
    tracked: Vec<u32>,
    /// Scratch of the sparse solves: right-hand side, every node's displacement, a tracked solve's rows and marks.
    solve_rhs: Vec<f64>,
    solve_u: Vec<Vec3>,
    solve_rows: Vec<usize>,
    solve_marks: [Vec<bool>; 2],
}

impl ConstrainedSolver {
    /// Takes ownership of the model and its compliance.
    pub fn new(model: FemModel, compliance: Compliance) -> Result<Self, FemError> {
        if compliance.model_fingerprint() != model.fingerprint() {
            return Err(FemError::InvalidOption { field: "compliance", value: f64::NAN, reason: "was computed for another model" });
        }
        let rows = compliance.row_nodes().len();
        let large_compliance = compliance.stats().bytes > CANDIDATE_BLOCKS_FROM_BYTES;
        let node_count = model.mesh.node_count();
        let vertex_rows: Vec<u32> = model.surface.vertices.iter().map(|&n| compliance.row_of(n).map_or(u32::MAX, |r| r as u32)).collect();
        let far: Vec<u32> = (0..vertex_rows.len() as u32)
            .filter(|&k| vertex_rows[k as usize] == u32::MAX && !model.is_fixed(model.surface.vertices[k as usize]))
            .collect();
        let row_vertices: Vec<u32> = (0..vertex_rows.len() as u32).filter(|&k| vertex_rows[k as usize] != u32::MAX).collect();
        let held = model.surface.vertices.iter().map(|&n| model.gravity_displacement(n)).collect();
        let tuning = Tuning::current();
        Ok(Self {
            model,
            compliance,
            frame: 0,
            iteration_cap: None,
            tuning,
            timings: PhaseTimings::default(),
            sys: System::default(),
            tools: ToolClaims::default(),
            cands: Candidates {
                candidates: Vec::new(),
                prev_active: Vec::new(),
                prev_barrier: Vec::new(),
                screen: screen::Screen::new(node_count),
                candidate_blocks: std::cell::RefCell::new(CandidateBlocks::default()),
                large_compliance,
            },
            columns: LazyColumns::default(),
            tethers: tethers::TetherSet::default(),
            surface: SurfaceUpdate {
                u_rows: vec![Vec3::zeros(); rows],
                prev_u_rows: vec![Vec3::zeros(); rows],
                col_forces: Vec::new(),
                col_along: Vec::new(),
                slot_rows: Vec::new(),
                product: ProductWorkspace::default(),
                vertex_rows,
                row_vertices,
                last_write: 0,
                last_forces: Vec::new(),
                far,
                held,
                tracked: Vec::new(),
                solve_rhs: Vec::new(),
                solve_u: Vec::new(),
                solve_rows: Vec::new(),
                solve_marks: [Vec::new(), Vec::new()],
            },
        })
    }

    /// The model.
    pub fn model(&self) -> &FemModel {
        &self.model
    }

    /// How the enforced block of W's factor was updated in the last frame ([`crate::linalg::kept_factor`]).
    pub fn factor_update(&self) -> crate::linalg::kept_factor::FactorUpdate {
        self.sys.factor.last_update()
    }

    /// Phase timings of the last frame (s).
    pub fn timings(&self) -> PhaseTimings {
        self.timings
    }

    /// The compliance.
    pub fn compliance(&self) -> &Compliance {
        &self.compliance
    }

    /// Unilateral tool nodes released in the last frame (their hold would have pulled), ascending; zero reaction.
    pub fn released_nodes(&self) -> &[u32] {
        &self.tools.released
    }

    /// Unilateral tool nodes that ended the last frame sliding on their face plane, ascending.
    pub fn sliding_nodes(&self) -> &[u32] {
        &self.tools.sliding
    }

    /// Copies the last frame's `W = C K^-1 C^T` into `out` (n x n, column major, full symmetric), n =
    /// the number of rows; for a haptic thread that wants its own copy.
    pub fn contact_compliance(&self, out: &mut Vec<f64>) {
        let n = self.row_count();
        let e = 3 * self.tools.enforced_nodes;
        let s = n - e;
        out.clear();
        out.resize(n * n, 0.0);
        self.sys.factor.copy_enforced_w(out, n);
        for t in 0..s {
            for i in 0..e {
                out[(e + t) * n + i] = self.sys.w_es[t * e + i];
                out[i * n + e + t] = self.sys.w_es[t * e + i];
            }
            for u in 0..s {
                out[(e + u) * n + e + t] = self.sys.w_ss[u * s + t];
            }
        }
    }

    /// Change of the force ON the tissue from spatula `owner` when it moves by `delta` (m) and the active set stays
    /// as in the last frame: its held vertices move by `delta`, its active face rows' planes by `n . delta`;
    /// `delta_lambda = W^-1 delta_g`. Exact for the linear model; two triangular solves, no allocation once
    /// `scratch` has grown. The haptic force on the tool is its negative.
    pub fn spatula_force_delta(&self, owner: u16, delta: Vec3, scratch: &mut Vec<f64>) -> Vec3 {
        let n = self.row_count();
        scratch.clear();
        scratch.resize(n, 0.0);
        let mut any = false;
        for k in 0..self.tools.enforced_nodes {
            if self.owner_share(k, owner) > 0.0 {
                scratch[3 * k] = delta.x;
                scratch[3 * k + 1] = delta.y;
                scratch[3 * k + 2] = delta.z;
                any = true;
            }
        }
        let enforced_rows = 3 * self.tools.enforced_nodes;
        for (k, &ci) in self.sys.row_candidate.iter().enumerate() {
            if self.face_row_share(ci, owner) > 0.0 {
                scratch[enforced_rows + k] = self.sys.rows[enforced_rows + k].dir.dot(&delta);
                any = true;
            }
        }
        if !any {
            return Vec3::zeros();
        }
        self.sys.factor.solve_in_place(scratch);
        let mut f = Vec3::zeros();
        for k in 0..self.tools.enforced_nodes {
            let share = self.owner_share(k, owner);
            if share > 0.0 {
                f += Vec3::new(scratch[3 * k], scratch[3 * k + 1], scratch[3 * k + 2]) * share;
            }
        }
        for (k, &ci) in self.sys.row_candidate.iter().enumerate() {
            let share = self.face_row_share(ci, owner);
            if share > 0.0 {
                f += self.sys.rows[enforced_rows + k].dir * (scratch[enforced_rows + k] * share);
            }
        }
        f
    }

    /// Rows of W: the per-node rows, then the taut tethers'.
    fn row_count(&self) -> usize {
        self.sys.rows.len() + self.tethers.rows.len()
    }

    /// Fraction of candidate `ci`'s face-row reaction that belongs to spatula `owner` (0 for a sphere row).
    fn face_row_share(&self, ci: usize, owner: u16) -> f64 {
        let c = &self.cands.candidates[ci];
        match c.limit {
            Limit::Sphere { .. } => 0.0,
            Limit::Plane { hold: None, .. } => f64::from(u8::from(c.owner == owner)),
            Limit::Plane { hold: Some(g), .. } => self.group_share(g, owner),
        }
    }

    /// Fraction of enforced node k's reaction that belongs to `owner`.
    fn owner_share(&self, k: usize, owner: u16) -> f64 {
        self.group_share(self.tools.enforced_group[k], owner)
    }

    /// Fraction of claim group g's reaction that belongs to `owner`.
    fn group_share(&self, g: usize, owner: u16) -> f64 {
        let claims = self.tools.claims_of(g);
        claims.iter().filter(|&&(_, o)| o == owner).count() as f64 / claims.len().max(1) as f64
    }

    /// Caps the active-set loop at `cap` iterations (`None`: 100 + 2 x (candidates + claimed vertices);
    /// `Some(0)`: every frame fails as capped). For tests of the capped path.
    pub fn set_iteration_cap(&mut self, cap: Option<usize>) {
        self.iteration_cap = cap;
    }

    /// Switches this solver's optimisations (`fem::tuning`, the surface product's included) from the next frame on.
    pub fn set_tuning(&mut self, tuning: Tuning) {
        self.tuning = tuning;
        self.surface.product.tuning = tuning;
    }

    /// Keeps the candidates' blocks whatever the compliance's size (tests: the kept path on a small model).
    #[doc(hidden)]
    pub fn keep_candidate_blocks_always(&mut self) {
        self.cands.large_compliance = true;
        // and an evaluation pass, and W's gather, of any size made ahead on two threads
        let mut kept = self.cands.candidate_blocks.borrow_mut();
        kept.ahead.from = 1;
        kept.ahead.gather_from = 1;
    }

    /// Whether the candidates' blocks are kept between frames (a large compliance, the optimisation on).
    fn keep_candidate_blocks(&self) -> bool {
        blocks::wanted(self.cands.large_compliance, self.tuning)
    }

    /// The cap set by [`Self::set_iteration_cap`].
    pub fn iteration_cap(&self) -> Option<usize> {
        self.iteration_cap
    }

    /// Solves one frame. `out` is overwritten (its buffers are reused).
    pub fn step(&mut self, constraints: &[Constraint], out: &mut FrameSolution) -> Result<(), FemError> {
        self.frame += 1;
        self.timings = PhaseTimings::default();
        self.validate(constraints)?;
        let lazy_before = self.columns.lazy_computed;
        self.prepare(constraints)?;
        let iterations = self.solve_active_set()?;
        let t = std::time::Instant::now();
        self.update_surface();
        self.keep_last_forces();
        self.update_tracked()?;
        self.timings.surface += t.elapsed().as_secs_f64();
        self.timings.surface_gather += self.surface.product.gather_seconds();
        self.write_solution(constraints, out, iterations, self.columns.lazy_computed - lazy_before);
        Ok(())
    }

    /// The frame's claims and candidates, every K^-1 column they read available, and the held nodes in the factor.
    fn prepare(&mut self, constraints: &[Constraint]) -> Result<(), FemError> {
        self.group_claims(constraints);
        self.collect_candidates(constraints);
        self.linearize_tethers()?;
        self.touch_candidate_columns();
        // ROI candidates need their columns final (a W entry between two ROI nodes is read from the earlier
        // column); this waits only while they are computed in the background.
        let t = std::time::Instant::now();
        for c in &self.cands.candidates {
            if let Some(col) = self.compliance.col_of(c.node) {
                self.compliance.wait_column(col)?;
            }
        }
        self.timings.lazy += t.elapsed().as_secs_f64();
        // Candidates that are neither surface nor ROI rows need their own columns to be evaluated.
        let mut extra: Vec<u32> = Vec::new();
        for c in &self.cands.candidates {
            if self.compliance.row_of(c.node).is_none() {
                extra.push(c.node);
            }
        }
        self.ensure_lazy(&extra)?;
        let claimed = std::mem::take(&mut self.tools.claimed_sorted);
        let ensured = self.ensure_lazy(&claimed);
        self.tools.claimed_sorted = claimed;
        ensured?;
        self.arrange_engaged();
        Ok(())
    }

    /// The active-set loop: solve, then add violated candidates, demote pulling holds, release the most adhesive
    /// row or re-linearize spheres, until none applies. Returns the iterations it took.
    fn solve_active_set(&mut self) -> Result<usize, FemError> {
        let max_iterations = self.iteration_cap.unwrap_or(100 + 2 * (self.cands.candidates.len() + self.tools.claimed_sorted.len()));
        if max_iterations == 0 {
            return Err(self.not_converged(0, 0.0));
        }
        let mut iterations = 0;
        let mut relinearized = 0;
        let screening = self.tuning.enabled(Optimisation::CandidateScreen);
        self.cands.screen.begin_frame(screening, self.tuning.enabled(Optimisation::ScreenAcrossFrames));
        self.sys.pairs.begin_step(self.cands.candidates.len() + self.tethers.count(), self.columns.lazy_generation);
        loop {
            iterations += 1;
            self.build_rows();
            let nodes = std::mem::take(&mut self.sys.nodes);
            let ensured = self.ensure_lazy(&nodes);
            self.sys.nodes = nodes;
            ensured?;
            self.solve_rows();
            if self.cands.candidates.is_empty() && !self.tethers.any() && self.tools.groups.iter().all(|g| g.normal.is_none()) {
                return Ok(iterations);
            }
            let (any_add, worst_inactive, worst_active) = self.evaluate_candidates(screening);
            let cap = |this: &Self, worst: f64| if iterations >= max_iterations { Err(this.not_converged(iterations, worst)) } else { Ok(()) };
            if any_add {
                cap(self, worst_inactive)?;
                if iterations <= BULK_RELEASE_ITERATIONS && self.tuning.enabled(Optimisation::PrimalDualSteps) {
                    // A primal-dual step: the rows this solve found pulling go in the same iteration as the
                    // violated candidates come (a jittering blade both meets and leaves a few dozen vertices a
                    // frame; one after the other took an iteration each).
                    self.release_adhesive_candidates(self.lambda_scale());
                }
            } else if self.demote_pulling_holds(iterations) {
                cap(self, worst_active)?;
                self.arrange_engaged();
            } else if self.release_most_adhesive(iterations)
                || worst_active > 0.0 && {
                    relinearized += 1;
                    self.relinearize_active(if relinearized <= FULL_RELINEARIZATIONS { 1.0 } else { RELINEARIZE_RELAXATION });
                    true
                }
            {
                cap(self, worst_active)?;
            } else {
                return Ok(iterations);
            }
        }
    }

    /// Evaluates every candidate the screen cannot skip at the current solution and activates the violated ones.
    /// Returns (any activated, largest violation of an inactive one, largest miss of an active sphere row).
    fn evaluate_candidates(&mut self, screening: bool) -> (bool, f64, f64) {
        let evaluated = std::time::Instant::now();
        if screening {
            for k in 0..self.sys.nodes.len() {
                self.screen_root(self.sys.nodes[k]);
            }
            self.cands.screen.advance(&self.sys.nodes, &self.sys.node_force);
        }
        let mut worst_inactive: f64 = 0.0;
        let mut worst_active: f64 = 0.0;
        let mut any_add = false;
        if self.keep_candidate_blocks() {
            self.cands.candidate_blocks.borrow_mut().expect_rows(self.cands.candidates.len());
            if self.tuning.enabled(Optimisation::ParallelCandidates) && crate::par::available() {
                self.displace_ahead(screening);
            }
        }
        for ci in 0..self.cands.candidates.len() {
            let c = self.cands.candidates[ci];
            match self.pass_of(c, screening) {
                Pass::Engaged => {
                    // Held by a tool this iteration: the enforced displacement wins.
                    self.cands.candidates[ci].active = false;
                    continue;
                }
                // Held on its face plane by its row: nothing to check.
                Pass::OnPlane => continue,
                Pass::Screened => {
                    self.timings.screened += 1;
                    if self.keep_candidate_blocks() {
                        self.cands.candidate_blocks.borrow_mut().touch(c.node, self.frame);
                    }
                    continue;
                }
                Pass::Evaluate => {}
            }
            let ahead = self.cands.candidate_blocks.borrow().ahead.get(c.node);
            let u = ahead.unwrap_or_else(|| self.displacement_of(c.node));
            self.timings.evaluated += 1;
            if screening {
                self.cands.screen.record(c.node, u);
            }
            let (violation, tol) = self.violation(c, u);
            if !c.active && violation > tol {
                any_add = true;
                worst_inactive = worst_inactive.max(violation);
                self.cands.candidates[ci].active = true;
                if c.limit.is_sphere() {
                    self.cands.candidates[ci].at = self.model.mesh.positions[c.node as usize] + u;
                    self.sys.pairs.redefine(self.tethers.count() + ci);
                }
            } else if c.active && c.limit.is_sphere() && violation.abs() > tol {
                worst_active = worst_active.max(violation.abs());
            }
        }
        self.cands.candidate_blocks.borrow_mut().ahead.expire();
        let (tether_added, tether_worst) = self.evaluate_tethers();
        any_add |= tether_added;
        worst_inactive = worst_inactive.max(tether_worst);
        self.timings.candidates += evaluated.elapsed().as_secs_f64();
        (any_add, worst_inactive, worst_active)
    }

    /// Makes, on two threads, the displacements of the nodes the evaluation pass is about to evaluate (chosen by
    /// [`Self::pass_of`], as the pass chooses them; a node listed twice is made once), when there are many
    /// ([`blocks::AHEAD_FROM_NODES`]): the pass then reads them instead of making each in turn. The same bits.
    fn displace_ahead(&mut self, screening: bool) {
        let mut nodes = std::mem::take(&mut self.cands.candidate_blocks.borrow_mut().ahead.nodes);
        nodes.clear();
        for ci in 0..self.cands.candidates.len() {
            let c = self.cands.candidates[ci];
            if matches!(self.pass_of(c, screening), Pass::Evaluate) {
                nodes.push(c.node);
            }
        }
        nodes.sort_unstable();
        nodes.dedup();
        let mut kept = self.cands.candidate_blocks.borrow_mut();
        let wanted = nodes.len() >= kept.ahead.from;
        kept.ahead.nodes = nodes;
        if !wanted {
            return;
        }
        kept.prepare(self.frame, self.columns.lazy_generation, &self.sys.nodes, self.sys.nodes_version);
        let blocks::Ahead { nodes, u, forced, .. } = &mut kept.ahead;
        u.clear();
        u.extend(nodes.iter().map(|&n| self.model.gravity_displacement(n) + self.tether_pull_at(n)));
        forced.clear();
        forced.extend(self.sys.direct_force.iter().enumerate().filter(|(_, f)| **f != Vec3::zeros()).map(|(slot, f)| (slot, *f)));
        kept.displace_ahead(self.kinv_source(), &self.sys.nodes, self.tuning.enabled(Optimisation::PrefetchBlocks));
    }

    /// What an evaluation pass does with candidate `c`, in the order the pass asks: the one choice both the pass and
    /// [`Self::displace_ahead`] make. (A node that is a candidate twice may be chosen differently by the two: the
    /// pass records the first one's displacement before it asks about the second, and a node the list lacks is
    /// made one by one, the same bits.)
    fn pass_of(&mut self, c: Candidate, screening: bool) -> Pass {
        if self.tools.engaged_sorted.binary_search(&c.node).is_ok() {
            Pass::Engaged
        } else if c.active && !c.limit.is_sphere() {
            Pass::OnPlane
        } else if screening && !c.active && self.can_skip(c) {
            Pass::Screened
        } else {
            Pass::Evaluate
        }
    }

    /// Whether the screen shows candidate `c` (inactive) cannot be violated: its violation at its node's recorded
    /// displacement is inside the tolerance by more than the forces' change since can have moved the node.
    fn can_skip(&mut self, c: Candidate) -> bool {
        let (Some(root), Some(seen)) = (self.screen_root(c.node), self.cands.screen.seen(c.node)) else { return false };
        let (violation, tol) = self.violation(c, seen);
        self.cands.screen.can_skip(c.node, root, tol - violation)
    }

    /// Candidate `c`'s violation at its node's displacement `u` (positive: past its plane or sphere), and its tolerance.
    fn violation(&self, c: Candidate, u: Vec3) -> (f64, f64) {
        match c.limit {
            // Face plane: exact row, nothing to re-linearize.
            Limit::Plane { normal, b, .. } => (b - normal.dot(&u), CONTACT_TOLERANCE_M + CONTACT_TOLERANCE * b.abs()),
            Limit::Sphere { center, radius, inside } => {
                let dist = (self.model.mesh.positions[c.node as usize] + u - center).norm();
                (if inside { dist - radius } else { radius - dist }, SPHERE_TOLERANCE * radius)
            }
        }
    }

    /// The largest |lambda| of the last solve: what a row's pull is measured against.
    fn lambda_scale(&self) -> f64 {
        self.sys.lambda.iter().fold(0.0_f64, |m, l| m.max(l.abs()))
    }

    /// Releases every active candidate row that pulls (lambda below `-1e-12 scale`, `scale` the largest |lambda|)
    /// at the last solve; returns whether any.
    fn release_adhesive_candidates(&mut self, scale: f64) -> bool {
        let enforced_rows = 3 * self.tools.enforced_nodes;
        let mut any = false;
        for (k, &ci) in self.sys.row_candidate.iter().enumerate() {
            if self.sys.lambda[enforced_rows + k] < -1e-12 * scale {
                self.cands.candidates[ci].active = false;
                any = true;
            }
        }
        any
    }

    /// Releases the most adhesive active candidate row (lambda < 0 pulls the tissue) or the most compressive
    /// tether (T < 0 would push), whichever is further below zero (a candidate on a tie); in the first
    /// [`BULK_RELEASE_ITERATIONS`] every such row at once (a blade pulled back from a wide contact leaves dozens
    /// pulling; the solution is the same, W being positive definite). Returns whether it released any.
    fn release_most_adhesive(&mut self, iterations: usize) -> bool {
        let enforced_rows = 3 * self.tools.enforced_nodes;
        let scale = self.lambda_scale();
        if iterations <= BULK_RELEASE_ITERATIONS {
            let any = self.release_adhesive_candidates(scale);
            return self.release_compressive_tethers(self.sys.rows.len(), scale) || any;
        }
        let mut most: Option<(usize, f64)> = None;
        for (k, &ci) in self.sys.row_candidate.iter().enumerate() {
            let l = self.sys.lambda[enforced_rows + k];
            if l < -1e-12 * scale && most.is_none_or(|(_, m)| l < m) {
                most = Some((ci, l));
            }
        }
        let tether = self.most_compressive_tether(self.sys.rows.len(), scale);
        match (most, tether) {
            (Some((ci, l)), t) if t.is_none_or(|(_, lt)| l <= lt) => {
                self.cands.candidates[ci].active = false;
                true
            }
            (_, Some((i, _))) => {
                self.release_tether(i);
                true
            }
            _ => false,
        }
    }

    /// Moves each active sphere row's linearization point `relaxation` of the way to its node's current position.
    fn relinearize_active(&mut self, relaxation: f64) {
        for ci in 0..self.cands.candidates.len() {
            if self.cands.candidates[ci].active && self.cands.candidates[ci].limit.is_sphere() {
                let node = self.cands.candidates[ci].node;
                let x = self.model.mesh.positions[node as usize] + self.displacement_of(node);
                let at = self.cands.candidates[ci].at;
                self.cands.candidates[ci].at = if relaxation == 1.0 { x } else { at + (x - at) * relaxation };
                self.sys.pairs.redefine(self.tethers.count() + ci);
            }
        }
    }

    fn not_converged(&self, iterations: usize, max_violation: f64) -> FemError {
        let enforced_rows = 3 * self.tools.enforced_nodes;
        let min_force = self.sys.lambda.get(enforced_rows..).map(|l| l.iter().fold(0.0_f64, |m, &x| m.min(x))).unwrap_or(0.0);
        FemError::ActiveSetNotConverged { iterations, max_violation, min_force }
    }

    fn validate(&self, constraints: &[Constraint]) -> Result<(), FemError> {
        let count = self.model.mesh.node_count();
        for (index, c) in constraints.iter().enumerate() {
            if c.node as usize >= count {
                return Err(FemError::NodeOutOfRange { what: "constraint", node: c.node, count });
            }
            let ok = match c.kind {
                ConstraintKind::Enforced { displacement } => is_finite3(&displacement),
                ConstraintKind::Contact { displacement, normal } | ConstraintKind::Barrier { displacement, normal } => {
                    is_finite3(&displacement) && is_finite3(&normal) && normal.norm() > 0.0
                }
                ConstraintKind::SphereInside { center, radius } | ConstraintKind::SphereOutside { center, radius } => {
                    is_finite3(&center) && radius.is_finite() && radius > 0.0
                }
            };
            if !ok {
                return Err(FemError::InvalidConstraint {
                    index,
                    node: c.node,
                    reason: "non-finite displacement, normal or centre, zero normal, or radius not > 0",
                });
            }
        }
        Ok(())
    }

    /// Groups the tool constraints by node (ascending), averaging their targets. A node is unilateral when every
    /// claim is a `Contact` and their normals pairwise agree (`n_i . n_j > 0`); otherwise it is held bilaterally.
    fn group_claims(&mut self, constraints: &[Constraint]) {
        self.sys.order.clear();
        for (i, c) in constraints.iter().enumerate() {
            if c.kind.tool_displacement().is_some() && !self.model.is_fixed(c.node) {
                self.sys.order.push((c.node, i));
            }
        }
        self.sys.order.sort_unstable();
        self.tools.claimed_sorted.clear();
        self.tools.groups.clear();
        self.tools.claims.clear();
        let mut k = 0;
        while k < self.sys.order.len() {
            let node = self.sys.order[k].0;
            let mut sum = Vec3::zeros();
            let mut normal_sum = Vec3::zeros();
            let mut unilateral = true;
            let start = k;
            while k < self.sys.order.len() && self.sys.order[k].0 == node {
                let i = self.sys.order[k].1;
                match constraints[i].kind {
                    ConstraintKind::Contact { displacement, normal } => {
                        sum += displacement;
                        let n = normal.normalize();
                        for &j in &self.sys.order[start..k] {
                            if let ConstraintKind::Contact { normal: other, .. } = constraints[j.1].kind {
                                if other.normalize().dot(&n) <= 0.0 {
                                    unilateral = false;
                                }
                            }
                        }
                        normal_sum += n;
                    }
                    ConstraintKind::Enforced { displacement } => {
                        sum += displacement;
                        unilateral = false;
                    }
                    _ => {}
                }
                self.tools.claims.push((i, constraints[i].owner));
                k += 1;
            }
            let normal = if unilateral && normal_sum.norm() > 0.0 { Some(normal_sum.normalize()) } else { None };
            self.tools.claimed_sorted.push(node);
            let end = self.tools.claims.len();
            self.tools.groups.push(ClaimGroup { start: end - (k - start), end, target: sum / (k - start) as f64, normal, engaged: true });
        }
    }

    /// Puts the engaged tool nodes in the factor's persistent order ([`crate::linalg::kept_factor`]) and updates the factor.
    fn arrange_engaged(&mut self) {
        self.tools.engaged_sorted.clear();
        self.tools.engaged_sorted.extend(self.tools.claimed_sorted.iter().zip(&self.tools.groups).filter(|(_, g)| g.engaged).map(|(n, _)| *n));
        self.sys.factor.order_for(&self.tools.engaged_sorted, &mut self.tools.perm_nodes);
        self.tools.enforced_group.clear();
        for &node in &self.tools.perm_nodes {
            if let Ok(g) = self.tools.claimed_sorted.binary_search(&node) {
                self.tools.enforced_group.push(g);
            }
        }
        self.sys.nodes.clear();
        self.sys.nodes.extend_from_slice(&self.tools.perm_nodes);
        self.sys.nodes_version += 1;
        self.tools.enforced_nodes = self.sys.nodes.len();
        let t = std::time::Instant::now();
        let mut factor = std::mem::take(&mut self.sys.factor);
        if !self.tuning.enabled(Optimisation::WFactorReuse) {
            factor.reset();
        }
        factor.update_enforced(&self.tools.perm_nodes, &|p, q| self.kinv(p, q));
        self.sys.factor = factor;
        self.timings.factor += t.elapsed().as_secs_f64();
    }

    /// Demotes held tool nodes whose hold pulls (`F . n < 0`) to a face-plane row (see the module doc): all of them
    /// in the first [`BULK_RELEASE_ITERATIONS`], then the most adhesive one per iteration. Returns whether any was.
    fn demote_pulling_holds(&mut self, iterations: usize) -> bool {
        let scale = self.sys.node_force[..self.tools.enforced_nodes].iter().fold(0.0_f64, |m, f| m.max(f.norm()));
        let mut most: Option<(usize, usize, f64)> = None;
        let mut changed = false;
        for k in 0..self.tools.enforced_nodes {
            let g = self.tools.enforced_group[k];
            let Some(n) = self.tools.groups[g].normal else { continue };
            let push = self.sys.node_force[k].dot(&n);
            if push < -CONTACT_TOLERANCE * scale {
                if iterations <= BULK_RELEASE_ITERATIONS {
                    self.demote(k, n);
                    changed = true;
                } else if most.is_none_or(|(_, _, m)| push < m) {
                    most = Some((k, g, push));
                }
            }
        }
        if let Some((k, g, _)) = most {
            if let Some(n) = self.tools.groups[g].normal {
                self.demote(k, n);
                changed = true;
            }
        }
        changed
    }

    /// Moves held slot `k` to a face-plane candidate (active: it starts on the plane).
    fn demote(&mut self, k: usize, n: Vec3) {
        let g = self.tools.enforced_group[k];
        self.tools.groups[g].engaged = false;
        let node = self.tools.claimed_sorted[g];
        let target = self.tools.groups[g].target;
        let owner = self.tools.claims_of(g)[0].1;
        let at = self.model.mesh.positions[node as usize] + target;
        let limit = Limit::Plane { normal: n, b: n.dot(&target), hold: Some(g) };
        self.cands.candidates.push(Candidate { constraint: usize::MAX, node, owner, active: true, at, limit });
    }

    fn collect_candidates(&mut self, constraints: &[Constraint]) {
        self.cands.candidates.clear();
        for (i, c) in constraints.iter().enumerate() {
            let limit = match c.kind {
                ConstraintKind::Enforced { .. } | ConstraintKind::Contact { .. } => continue,
                ConstraintKind::Barrier { displacement, normal } => {
                    // A held node ignores it (skipped each iteration); a bilaterally held one never needs it.
                    if self.model.is_fixed(c.node) || self.tools.holds_bilaterally(c.node) {
                        continue;
                    }
                    let n = normal.normalize();
                    let at = self.model.mesh.positions[c.node as usize] + displacement;
                    let active = self.cands.prev_barrier.binary_search(&(c.node, c.owner)).is_ok();
                    let limit = Limit::Plane { normal: n, b: n.dot(&displacement), hold: None };
                    self.cands.candidates.push(Candidate { constraint: i, node: c.node, owner: c.owner, active, at, limit });
                    continue;
                }
                ConstraintKind::SphereInside { center, radius } => Limit::Sphere { center, radius, inside: true },
                ConstraintKind::SphereOutside { center, radius } => Limit::Sphere { center, radius, inside: false },
            };
            // A bilaterally held node takes no sphere row; a unilateral tool node does while released.
            let bilateral = self.tools.holds_bilaterally(c.node);
            if self.model.is_fixed(c.node) || bilateral {
                continue;
            }
            let rest = self.model.mesh.positions[c.node as usize];
            let at = match (self.compliance.row_of(c.node), self.model.surface.node_to_vertex.get(c.node as usize)) {
                (Some(r), _) => rest + self.surface.prev_u_rows[r],
                // a far surface vertex: as last brought up to date
                (None, Some(&k)) => rest + self.surface.held.get(k as usize).copied().unwrap_or_else(Vec3::zeros),
                (None, None) => rest,
            };
            let inside = matches!(limit, Limit::Sphere { inside: true, .. });
            let active = self.cands.prev_active.binary_search(&(c.node, c.owner, inside)).is_ok();
            self.cands.candidates.push(Candidate { constraint: i, node: c.node, owner: c.owner, active, at, limit });
        }
    }

    /// Marks the cached lazy columns of this frame's candidates as used, so this frame never evicts the column of
    /// a vertex that may engage.
    fn touch_candidate_columns(&mut self) {
        let frame = self.frame;
        for c in &self.cands.candidates {
            if let Ok(i) = self.columns.lazy.binary_search_by_key(&c.node, |l| l.node) {
                self.columns.lazy[i].last_used = frame;
            }
        }
    }

    /// Rows: 3 per enforced node, then one per active candidate.
    fn build_rows(&mut self) {
        self.sys.rows.clear();
        self.sys.nodes.truncate(self.tools.enforced_nodes);
        self.sys.nodes_version += 1;
        for k in 0..self.tools.enforced_nodes {
            let g = self.tools.groups[self.tools.enforced_group[k]].target;
            self.sys.rows.push(ConstraintRow { slot: k, dir: Vec3::x(), target: g.x });
            self.sys.rows.push(ConstraintRow { slot: k, dir: Vec3::y(), target: g.y });
            self.sys.rows.push(ConstraintRow { slot: k, dir: Vec3::z(), target: g.z });
        }
        self.sys.row_candidate.clear();
        for (ci, c) in self.cands.candidates.iter().enumerate() {
            if !c.active || self.tools.engaged_sorted.binary_search(&c.node).is_ok() {
                continue;
            }
            let slot = match self.sys.nodes[self.tools.enforced_nodes..].iter().position(|&n| n == c.node) {
                Some(p) => self.tools.enforced_nodes + p,
                None => {
                    self.sys.nodes.push(c.node);
                    self.sys.nodes.len() - 1
                }
            };
            let (center, radius, inside) = match c.limit {
                Limit::Plane { normal, b, .. } => {
                    self.sys.rows.push(ConstraintRow { slot, dir: normal, target: b });
                    self.sys.row_candidate.push(ci);
                    continue;
                }
                Limit::Sphere { center, radius, inside } => (center, radius, inside),
            };
            let rest = self.model.mesh.positions[c.node as usize];
            let radial = c.at - center;
            let len = radial.norm();
            // A point at the centre has no radial direction: use the rest direction, else +z.
            let n = if len > 0.0 {
                radial / len
            } else {
                let r = rest - center;
                if r.norm() > 0.0 { r.normalize() } else { Vec3::z() }
            };
            // inside: n.(X+u-c) <= R  <=>  (-n).u >= n.(X-c) - R;  outside: n.u >= r - n.(X-c)
            let (dir, target) = if inside { (-n, n.dot(&(rest - center)) - radius) } else { (n, radius - n.dot(&(rest - center))) };
            self.sys.rows.push(ConstraintRow { slot, dir, target });
            self.sys.row_candidate.push(ci);
        }
        self.build_tether_rows();
    }

    /// Gathers the candidate rows of W, then solves the system they extend ([`Self::solve_lambda`]).
    fn solve_rows(&mut self) {
        let t = std::time::Instant::now();
        let n = self.row_count();
        let e = 3 * self.tools.enforced_nodes;
        let s = n - e;
        // the candidate rows come first in the s block, the tethers' after them
        let s_c = self.sys.rows.len() - e;
        self.sys.w_es.clear();
        self.sys.w_es.resize(e * s, 0.0);
        self.sys.w_ss.clear();
        self.sys.w_ss.resize(s * s, 0.0);
        let (mut w_es, mut w_ss) = (std::mem::take(&mut self.sys.w_es), std::mem::take(&mut self.sys.w_ss));
        let (mut pairs, slots) = self.take_row_pairs();
        let mut kept = self.keep_candidate_blocks().then(|| self.cands.candidate_blocks.borrow_mut());
        if let Some(kept) = kept.as_mut() {
            kept.prepare(self.frame, self.columns.lazy_generation, &self.sys.nodes, self.sys.nodes_version);
            kept.expect_rows(self.cands.candidates.len());
        }
        let ahead = match kept.as_mut() {
            Some(k) if self.tuning.enabled(Optimisation::ParallelGather) && crate::par::available() => {
                self.gather_rows_ahead(k, e, s, s_c, pairs.as_mut(), &slots, &mut w_es, &mut w_ss)
            }
            _ => Vec::new(),
        };
        for t in (0..s_c).filter(|&t| !ahead.get(t).is_some_and(|&a| a)) {
            let ri = self.sys.rows[e + t];
            let pi = self.sys.nodes[ri.slot];
            // A sphere or face row's node is a candidate: its blocks against the W nodes are kept (K^-1[q, p] is
            // K^-1[p, q] transposed, bit for bit, unless both have lazy columns: then each reads its own).
            let mut row = kept.as_mut().map(|k| (k.row(pi), self.columns.lazy.binary_search_by_key(&pi, |c| c.node).is_ok()));
            if self.tuning.enabled(Optimisation::PrefetchBlocks) && pairs.as_ref().is_none_or(|p| !p.has(slots[t], slots[t])) {
                // a row new to the step (its own entry unknown): its entries not kept for the step nor in the
                // candidate's kept row are read from the compliance, blocks that lie apart: ask for them all first
                for l in 0..self.tools.enforced_nodes {
                    let q = self.sys.nodes[l];
                    if !matches!((kept.as_ref(), row), (Some(k), Some((base, false))) if k.holds(base, l, q)) {
                        self.prefetch_kinv(q, pi);
                    }
                }
                for u in 0..=t {
                    let slot = self.sys.rows[e + u].slot;
                    let q = self.sys.nodes[slot];
                    let known = pairs.as_ref().is_some_and(|p| p.has(slots[t], slots[u]))
                        || matches!((kept.as_ref(), row), (Some(k), Some((base, _))) if k.holds(base, slot, q));
                    if !known {
                        self.prefetch_kinv(pi, q);
                    }
                }
            }
            for l in 0..self.tools.enforced_nodes {
                let q = self.sys.nodes[l];
                let block = match (kept.as_mut(), row) {
                    (Some(k), Some((base, false))) => self.kept_block(k, base, pi, l).transpose(),
                    _ => self.kinv(q, pi),
                };
                let v = block * ri.dir;
                for c in 0..3 {
                    w_es[t * e + 3 * l + c] = v[c];
                }
            }
            for u in 0..=t {
                let rj = self.sys.rows[e + u];
                let mut compute = || {
                    let block = match (kept.as_mut(), row.as_mut()) {
                        (Some(k), Some((base, _))) => self.kept_block(k, *base, pi, rj.slot),
                        _ => self.kinv(pi, self.sys.nodes[rj.slot]),
                    };
                    ri.dir.dot(&(block * rj.dir))
                };
                let value = match pairs.as_mut() {
                    Some(p) => p.get_or(slots[t], slots[u], compute),
                    None => compute(),
                };
                w_ss[u * s + t] = value;
                w_ss[t * s + u] = value;
            }
        }
        drop(kept);
        self.gather_tether_rows(e, s, &mut w_es, &mut w_ss, pairs.as_mut().map(|p| (p, slots.as_slice())));
        if let Some(p) = pairs {
            self.sys.pairs = p;
        }
        self.sys.row_slots = slots;
        (self.sys.w_es, self.sys.w_ss) = (w_es, w_ss);
        self.timings.gather += t.elapsed().as_secs_f64();
        self.solve_lambda(s);
    }

    /// Extends the enforced factor with the gathered s rows, solves for lambda and the nodal forces.
    fn solve_lambda(&mut self, s: usize) {
        let t = std::time::Instant::now();
        self.sys.factor.set_sphere_rows(s, &self.sys.w_es, &self.sys.w_ss);
        self.sys.lambda.clear();
        for row in &self.sys.rows {
            let u0 = self.model.gravity_displacement(self.sys.nodes[row.slot]);
            self.sys.lambda.push(row.target - row.dir.dot(&u0));
        }
        let mut lambda = std::mem::take(&mut self.sys.lambda);
        self.tether_rhs(&mut lambda);
        self.sys.lambda = lambda;
        self.sys.factor.solve_in_place(&mut self.sys.lambda);
        self.timings.factor += t.elapsed().as_secs_f64();
        self.sys.node_force.clear();
        self.sys.node_force.resize(self.sys.nodes.len(), Vec3::zeros());
        for (row, l) in self.sys.rows.iter().zip(&self.sys.lambda) {
            self.sys.node_force[row.slot] += row.dir * *l;
        }
        self.sys.direct_force.clone_from(&self.sys.node_force);
        self.add_tether_forces(self.sys.rows.len());
    }

    /// The step's kept W entries (when kept) and the pair slot of each s row (candidate rows, then tethers), taken
    /// out of the system for the gather.
    fn take_row_pairs(&mut self) -> (Option<pairs::RowPairs>, Vec<usize>) {
        let mut pairs = self.tuning.enabled(Optimisation::KeptRowPairs).then(|| std::mem::take(&mut self.sys.pairs));
        let mut slots = std::mem::take(&mut self.sys.row_slots);
        slots.clear();
        if let Some(pairs) = pairs.as_mut() {
            pairs.check_generation(self.columns.lazy_generation);
            let first_candidate = self.tethers.count();
            let candidates = &self.cands.candidates;
            slots.extend(self.sys.row_candidate.iter().map(|&ci| pairs.slot(first_candidate + ci, candidates[ci].row_key())));
            slots.extend(self.tethers.rows.iter().map(|&(i, _)| pairs.slot(i, None)));
        }
        (pairs, slots)
    }

    /// `sqrt(|K^-1[node, node]|_F)` for the screen, when the node has a ROI or lazy column; kept once read.
    fn screen_root(&mut self, node: u32) -> Option<f64> {
        if let Some(r) = self.cands.screen.root(node) {
            return Some(r);
        }
        let column = self.compliance.col_of(node).is_some() || self.columns.lazy.binary_search_by_key(&node, |c| c.node).is_ok();
        if !column || self.model.dofs.dof(node).is_none() {
            return None;
        }
        let r = self.kinv(node, node).norm().sqrt();
        r.is_finite().then(|| {
            self.cands.screen.set_root(node, r);
            r
        })
    }

    /// Displacement of one node at the current forces (gravity included).
    fn displacement_of(&self, node: u32) -> Vec3 {
        let mut u = self.model.gravity_displacement(node) + self.tether_pull_at(node);
        if !self.keep_candidate_blocks() {
            for (slot, f) in self.sys.direct_force.iter().enumerate() {
                if *f != Vec3::zeros() {
                    u += self.kinv(node, self.sys.nodes[slot]) * f;
                }
            }
            return u;
        }
        let mut kept = self.cands.candidate_blocks.borrow_mut();
        kept.prepare(self.frame, self.columns.lazy_generation, &self.sys.nodes, self.sys.nodes_version);
        let base = kept.row(node);
        for slot in 0..blocks::PREFETCH_AHEAD {
            kept.prefetch(base, slot);
        }
        let complete = kept.complete(base);
        if !complete && self.tuning.enabled(Optimisation::PrefetchBlocks) {
            // the row read blocks from the compliance last time (or is new): those it lacks lie apart there, so
            // ask for them all first
            for (slot, f) in self.sys.direct_force.iter().enumerate() {
                if *f != Vec3::zeros() && !kept.holds(base, slot, self.sys.nodes[slot]) {
                    self.prefetch_kinv(node, self.sys.nodes[slot]);
                }
            }
        }
        let reads = kept.reads;
        for (slot, f) in self.sys.direct_force.iter().enumerate() {
            kept.prefetch(base, slot + blocks::PREFETCH_AHEAD);
            if *f != Vec3::zeros() {
                u += self.kept_block(&mut kept, base, node, slot) * f;
            }
        }
        let now = kept.reads == reads;
        if now != complete {
            kept.set_complete(base, now);
        }
        u
    }

    /// u_rows = u0 + K^-1[rows, nodes] F.
    fn update_surface(&mut self) {
        let row_nodes = self.compliance.row_nodes();
        for (u, &n) in self.surface.u_rows.iter_mut().zip(row_nodes) {
            *u = self.model.gravity_displacement(n);
        }
        // A node held by one row (a face plane or sphere row) is forced along that row's direction; the product
        // may stream its column projected on it (`compliance/projected.rs`).
        let slot_rows = &mut self.surface.slot_rows;
        slot_rows.clear();
        slot_rows.resize(self.sys.nodes.len(), (0, Vec3::zeros(), 0.0));
        for (row, &l) in self.sys.rows.iter().zip(&self.sys.lambda) {
            let s = &mut slot_rows[row.slot];
            *s = (s.0.saturating_add(1), row.dir, l);
        }
        self.surface.col_forces.clear();
        self.surface.col_along.clear();
        for (slot, f) in self.sys.direct_force.iter().enumerate() {
            // (a node without a direct force adds exactly nothing: a tether's node, whose pull is its link's)
            let Some(c) = self.compliance.col_of(self.sys.nodes[slot]).filter(|_| *f != Vec3::zeros()) else { continue };
            match slot_rows[slot] {
                (1, n, l) if slot >= self.tools.enforced_nodes => self.surface.col_along.push((c, n, l)),
                _ => self.surface.col_forces.push((c, *f)),
            }
        }
        self.surface.col_forces.sort_unstable_by_key(|x| x.0);
        self.surface.col_along.sort_unstable_by_key(|x| x.0);
        self.compliance.accumulate_along(&self.surface.col_forces, &self.surface.col_along, &mut self.surface.u_rows, &mut self.surface.product);
        let n_free = self.model.dofs.dof_count();
        for (slot, f) in self.sys.direct_force.iter().enumerate() {
            let node = self.sys.nodes[slot];
            if self.compliance.col_of(node).is_some() {
                continue;
            }
            if let Ok(l) = self.columns.lazy.binary_search_by_key(&node, |c| c.node) {
                let v = &self.columns.lazy[l].values;
                for (u, &rn) in self.surface.u_rows.iter_mut().zip(row_nodes) {
                    if let Some(d) = self.model.dofs.dof(rn) {
                        for r in 0..3 {
                            u[r] += v[d + r] * f.x + v[n_free + d + r] * f.y + v[2 * n_free + d + r] * f.z;
                        }
                    }
                }
            }
        }
        let mut u_rows = std::mem::take(&mut self.surface.u_rows);
        self.add_tether_pulls(&mut u_rows);
        self.surface.u_rows = u_rows;
        std::mem::swap(&mut self.surface.u_rows, &mut self.surface.prev_u_rows);
    }

    fn write_solution(&mut self, constraints: &[Constraint], out: &mut FrameSolution, iterations: usize, lazy_solves: usize) {
        self.write_surface(out);
        // Over the working region (rows and tracked far vertices). sqrt is monotonic and correctly rounded: the
        // root of the largest squared norm is the largest norm, bit for bit.
        let tracked = self.surface.tracked.iter().map(|&k| &out.displacement_surface[k as usize]);
        out.max_displacement = self.surface.prev_u_rows.iter().chain(tracked).fold(0.0_f64, |m, u| m.max(u.norm_squared())).sqrt();
        out.reactions.clear();
        out.reactions.resize(constraints.len(), Vec3::zeros());
        for k in 0..self.tools.enforced_nodes {
            let claims = self.tools.claims_of(self.tools.enforced_group[k]);
            let share = self.sys.node_force[k] / claims.len() as f64;
            for &(c, _) in claims {
                out.reactions[c] = share;
            }
        }
        let enforced_rows = 3 * self.tools.enforced_nodes;
        for (k, &ci) in self.sys.row_candidate.iter().enumerate() {
            let row = enforced_rows + k;
            let force = self.sys.rows[row].dir * self.sys.lambda[row];
            match self.cands.candidates[ci].limit {
                Limit::Plane { hold: Some(g), .. } => {
                    let claims = self.tools.claims_of(g);
                    for &(c, _) in claims {
                        out.reactions[c] = force / claims.len() as f64;
                    }
                }
                _ => out.reactions[self.cands.candidates[ci].constraint] = force,
            }
        }
        out.owner_forces.clear();
        out.sphere_forces.clear();
        for (c, r) in constraints.iter().zip(&out.reactions) {
            let list = if c.kind.is_tool() { &mut out.owner_forces } else { &mut out.sphere_forces };
            match list.binary_search_by_key(&c.owner, |x| x.0) {
                Ok(i) => list[i].1 += r,
                Err(i) => list.insert(i, (c.owner, *r)),
            }
        }
        self.carry_active_set(out);
        out.active_sphere_contacts = self.sys.row_candidate.iter().filter(|&&ci| self.cands.candidates[ci].limit.is_sphere()).count();
        let mut tensions = std::mem::take(&mut out.tether_tension);
        self.write_tether_tensions(self.sys.rows.len(), &mut tensions);
        out.tether_tension = tensions;
        let n = self.row_count();
        out.rows = n;
        out.dropped_rows = self.sys.factor.dropped().filter(|d| *d).count();
        out.conditioning = self.sys.factor.conditioning_estimate();
        out.iterations = iterations;
        out.lazy_solves = lazy_solves;
    }

    /// The step's surface into `out.displacement_surface` ([`SurfaceWrites`]): every entry, or into the solution
    /// this solver wrote last, the working region's and the tracked far vertices' alone (no other entry can have
    /// changed: a far vertex's changes only when it is brought up to date, a fixed one's never).
    fn write_surface(&mut self, out: &mut FrameSolution) {
        let s = &mut self.surface;
        let w = &mut out.surface_writes;
        let d = &mut out.displacement_surface;
        if w.stamp != 0 && w.stamp == s.last_write && d.len() == s.vertex_rows.len() {
            w.since = w.stamp;
            w.changed.clear();
            for &k in &s.row_vertices {
                d[k as usize] = s.prev_u_rows[s.vertex_rows[k as usize] as usize];
            }
            for &k in &s.tracked {
                d[k as usize] = s.held[k as usize];
            }
            w.changed.extend_from_slice(&s.row_vertices);
            w.changed.extend_from_slice(&s.tracked);
        } else {
            w.since = 0;
            w.changed.clear();
            d.clear();
            d.extend(s.vertex_rows.iter().zip(&s.held).map(|(&r, held)| {
                match s.prev_u_rows.get(r as usize) {
                    Some(u) => *u,
                    // a far vertex: as last brought up to date (a fixed one: zero)
                    None => *held,
                }
            }));
        }
        w.stamp = NEXT_SURFACE_WRITE.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        s.last_write = w.stamp;
    }

    fn keep_last_forces(&mut self) {
        self.surface.last_forces.clear();
        for (slot, f) in self.sys.node_force.iter().enumerate() {
            self.surface.last_forces.push((self.sys.nodes[slot], *f));
        }
    }

    /// Brings the tracked far vertices up to date: one sparse solve with this frame's forces, pruned forward from
    /// the forced rows (not with gravity: a body force is nonzero everywhere) and backward to the tracked ones.
    /// Their answer is the full solve's bit for bit.
    fn update_tracked(&mut self) -> Result<(), FemError> {
        if self.surface.tracked.is_empty() {
            return Ok(());
        }
        let m = &self.model;
        let chol = m.chol.get()?;
        let s = &mut self.surface;
        let n = m.dofs.dof_count();
        s.solve_rows.clear();
        super::model::force_rhs((&m.dofs, &m.body_force), &s.last_forces, &mut s.solve_rhs, Some(&mut s.solve_rows));
        let [forward, backward] = &mut s.solve_marks;
        let pruned_forward = m.body_force.is_empty() && chol.supernodes_above_into(&s.solve_rows, forward);
        s.solve_rows.clear();
        for &k in &s.tracked {
            if let Some(d) = m.dofs.dof(m.surface.vertices[k as usize]) {
                s.solve_rows.extend(d..d + 3);
            }
        }
        let pruned_backward = chol.supernodes_above_into(&s.solve_rows, backward);
        if self.sys.solve_scratch.is_none() {
            self.sys.solve_scratch = Some(chol.scratch(1)?);
        }
        if let Some(scratch) = self.sys.solve_scratch.as_mut() {
            let rhs = faer::MatMut::from_column_major_slice_mut(&mut s.solve_rhs, n, 1);
            chol.solve_pruned_in_place(rhs, pruned_forward.then_some(forward.as_slice()), pruned_backward.then_some(backward.as_slice()), scratch);
        }
        for &k in &s.tracked {
            if let Some(d) = m.dofs.dof(m.surface.vertices[k as usize]) {
                s.held[k as usize] = Vec3::new(s.solve_rhs[d], s.solve_rhs[d + 1], s.solve_rhs[d + 2]);
            }
        }
        Ok(())
    }

    /// Every node's displacement for the last frame's forces, into `surface.solve_u`.
    fn solve_last_forces(&mut self) -> Result<(), FemError> {
        let forces = std::mem::take(&mut self.surface.last_forces);
        let solved = self.solve_forces(&forces);
        self.surface.last_forces = forces;
        solved
    }

    /// Every node's displacement for nodal `forces` (and the body force), into `surface.solve_u`.
    fn solve_forces(&mut self, forces: &[(u32, Vec3)]) -> Result<(), FemError> {
        let m = &self.model;
        let s = &mut self.surface;
        super::model::displacements_from_forces(
            (m.chol.get()?, &m.dofs, &m.body_force),
            m.mesh.node_count(),
            forces,
            (&mut s.solve_rhs, &mut self.sys.solve_scratch),
            &mut s.solve_u,
        )
    }

    /// The free surface vertices without a compliance row (indices into `model.surface().vertices`, ascending): a
    /// frame leaves them as last brought up to date unless [`Self::track`] names them.
    pub fn far_vertices(&self) -> &[u32] {
        &self.surface.far
    }

    /// The far vertices (surface indices) the next frames bring up to date: those a blade is near; others ignored.
    pub fn track(&mut self, vertices: &[u32]) {
        let s = &mut self.surface;
        s.tracked.clear();
        s.tracked.extend(vertices.iter().copied().filter(|k| s.far.binary_search(k).is_ok()));
        s.tracked.sort_unstable();
        s.tracked.dedup();
    }

    /// Writes the far vertices' displacement for the last frame's forces into `displacement_surface` (per surface
    /// vertex), for an output that shows or hashes the whole surface. Changes nothing the next frame reads; no
    /// solve when every surface vertex has a row.
    pub fn whole_surface(&mut self, displacement_surface: &mut [Vec3]) -> Result<(), FemError> {
        let forces = std::mem::take(&mut self.surface.last_forces);
        let done = self.whole_surface_for(&forces, displacement_surface);
        self.surface.last_forces = forces;
        done
    }

    /// As [`Self::whole_surface`] for a frame's kept nodal forces ([`Self::last_forces`]): the same bits, later.
    pub fn whole_surface_for(&mut self, forces: &[(u32, Vec3)], displacement_surface: &mut [Vec3]) -> Result<(), FemError> {
        if self.surface.far.is_empty() {
            return Ok(());
        }
        self.solve_forces(forces)?;
        let s = &self.surface;
        for &k in &s.far {
            if let Some(u) = displacement_surface.get_mut(k as usize) {
                *u = s.solve_u[self.model.surface.vertices[k as usize] as usize];
            }
        }
        Ok(())
    }

    /// Keeps the rows active at the end of the frame (sphere rows, blade barriers) for the next one, lists the
    /// released and sliding tool nodes, and counts them into `out`.
    fn carry_active_set(&mut self, out: &mut FrameSolution) {
        self.cands.prev_active.clear();
        for c in &self.cands.candidates {
            if let (true, Limit::Sphere { inside, .. }) = (c.active, c.limit) {
                self.cands.prev_active.push((c.node, c.owner, inside));
            }
        }
        self.cands.prev_active.sort_unstable();
        self.cands.prev_barrier.clear();
        for c in &self.cands.candidates {
            if c.active && matches!(c.limit, Limit::Plane { hold: None, .. }) {
                self.cands.prev_barrier.push((c.node, c.owner));
            }
        }
        self.cands.prev_barrier.sort_unstable();
        self.tools.released.clear();
        self.tools.sliding.clear();
        out.barrier_contacts = 0;
        for c in &self.cands.candidates {
            match c.limit {
                Limit::Plane { hold: None, .. } => out.barrier_contacts += usize::from(c.active && self.tools.engaged_sorted.binary_search(&c.node).is_err()),
                Limit::Plane { .. } if c.active => self.tools.sliding.push(c.node),
                Limit::Plane { .. } => self.tools.released.push(c.node),
                Limit::Sphere { .. } => {}
            }
        }
        self.tools.released.sort_unstable();
        self.tools.sliding.sort_unstable();
        out.released_contacts = self.tools.released.len();
        out.sliding_contacts = self.tools.sliding.len();
    }

    /// Displacement of every node (m) for the last frame's forces: one sparse solve; fixed nodes get zero. Errors
    /// only when the solve scratch cannot be allocated.
    pub fn interior_displacements(&mut self, out: &mut Vec<Vec3>) -> Result<(), FemError> {
        self.solve_last_forces()?;
        std::mem::swap(out, &mut self.surface.solve_u);
        Ok(())
    }

    /// Nodal forces (node, N, on the tissue) of the last frame.
    pub fn last_forces(&self) -> &[(u32, Vec3)] {
        &self.surface.last_forces
    }
}
