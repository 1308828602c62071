//! One fixed-step frame: poses -> collision -> skull rows -> exact solve ->
//! forces -> (stress) -> monitor, each stage timed.
//!
//! In: the [`SimState`] (passed explicitly, never global) and a [`FrameInput`]
//! (a pose per spatula, or none to keep the last). Out: the updated state and a
//! [`FrameReport`]. Stays true: stages the scene did not ask for are `None` and
//! report no time; a bad pose is rejected (the last good one holds) and counted;
//! nothing here panics on bad data — errors come back as [`StepError`].

use super::monitor;
use super::report::{FrameReport, SpatulaReport, StageId};
use crate::collision::CollisionStage;
use super::contact::ContactPatch;
use crate::fem::{ConstrainedSolver, Constraint, ConstraintKind, ElementStress, FrameSolution};
use crate::geometry::{Pose, SpatulaShape};
use crate::math::{Vec3, is_finite3};
use crate::mesh::{BoundarySurface, TetMesh, signed_volume};
use crate::scenario::{Effect, EffectSet, Scenario, Skull, SpatulaContact};
use std::time::Instant;

/// Errors of one frame. The state is left as it was before the failing stage.
#[derive(Debug, thiserror::Error)]
pub enum StepError {
    #[error("frame {frame}: collision: {source}")]
    Collision { frame: u64, source: crate::collision::CollisionError },
    #[error("frame {frame}: solve: {source}")]
    Solve { frame: u64, source: crate::fem::FemError },
    #[error("frame {frame}: {count} poses given for {expected} spatulas")]
    PoseCount { frame: u64, count: usize, expected: usize },
    /// A stage produced a NaN or an infinity (the rows before this frame stand).
    #[error("frame {frame}: {}: {what} is not finite (NaN or infinite)", stage.name())]
    NonFinite { frame: u64, stage: StageId, what: &'static str },
}

/// Ends a frame whose solve left a NaN or an infinity in the surface (`surface_finite`: every entry of the state's
/// surface displacement is finite, as its last copy found).
fn check_finite_state(frame: u64, surface_finite: bool, max_displacement: f64) -> Result<(), StepError> {
    if max_displacement.is_finite() && surface_finite {
        Ok(())
    } else {
        Err(StepError::NonFinite { frame, stage: StageId::Solve, what: "the surface displacement" })
    }
}

/// What drives one frame: a pose per spatula (`None` keeps the last good one).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameInput {
    pub poses: Vec<Option<Pose>>,
}

/// The simulation's state between frames.
#[derive(Debug, Clone, PartialEq)]
pub struct SimState {
    /// Frames done.
    pub frame: u64,
    /// Simulated time, s.
    pub time_s: f64,
    /// The last good pose per spatula.
    pub poses: Vec<Pose>,
    /// Current (deformed) surface-vertex positions, m.
    pub surface_positions: Vec<Vec3>,
    /// No component of any `surface_positions[v]` minus its rest position
    /// exceeds this, m ([`super::rest_grid::displacement_bound`]): with it the
    /// barrier rows and the monitor read only the vertices near a blade.
    /// Whoever writes `surface_positions` keeps it (infinity: unknown).
    pub surface_bound_m: f64,
    /// Displacement of each surface vertex from rest, m.
    pub surface_displacement: Vec<Vec3>,
    /// The solver's write the surface holds: a pipeline that wrote it last copies only what its next step changes.
    pub surface_mark: super::surface_sync::SurfaceMark,
    /// Displacement of every node (only with the stress stage), m.
    pub node_displacement: Vec<Vec3>,
    /// Per-tet stress and strain (only with the stress stage).
    pub stress: Vec<ElementStress>,
}

/// Unilateral skull spheres: which surface vertices get rows this frame.
#[derive(Debug, Clone)]
pub struct SkullStage {
    skull: Skull,
    /// Surface vertex -> mesh node.
    nodes: Vec<u32>,
}

/// A surface vertex becomes a skull candidate when its current position is
/// within this distance of violating a sphere (m). The active-set solve then
/// keeps only the rows that must push.
pub const SKULL_CANDIDATE_BAND_M: f64 = 0.005;
/// How far `p` is from violating each sphere (m; negative when it does):
/// `(containing, excluding)`, `None` for a sphere the skull does not have.
pub fn sphere_gaps(skull: &Skull, p: &Vec3) -> (Option<f64>, Option<f64>) {
    (
        skull.containing.map(|s| s.radius - (p - s.center).norm()),
        skull.excluding.map(|s| (p - s.center).norm() - s.radius),
    )
}

/// How far `p` is from violating the nearer sphere (m; infinite without spheres).
/// A vertex gets a skull candidate row when this is under [`SKULL_CANDIDATE_BAND_M`].
pub fn skull_gap(skull: &Skull, p: &Vec3) -> f64 {
    let (inside, outside) = sphere_gaps(skull, p);
    inside.into_iter().chain(outside).fold(f64::INFINITY, f64::min)
}

impl SkullStage {
    pub fn new(skull: Skull, surface_nodes: &[u32]) -> Self {
        Self { skull, nodes: surface_nodes.to_vec() }
    }

    /// Appends the candidate rows for the current positions; returns how many.
    fn push_rows(&self, positions: &[Vec3], out: &mut Vec<Constraint>) -> usize {
        let before = out.len();
        for (v, p) in positions.iter().enumerate() {
            let node = self.nodes[v];
            let (inside, outside) = sphere_gaps(&self.skull, p);
            if let (Some(s), Some(gap)) = (self.skull.containing, inside)
                && gap < SKULL_CANDIDATE_BAND_M
            {
                out.push(Constraint { node, owner: 0, kind: ConstraintKind::SphereInside { center: s.center, radius: s.radius } });
            }
            if let (Some(s), Some(gap)) = (self.skull.excluding, outside)
                && gap < SKULL_CANDIDATE_BAND_M
            {
                out.push(Constraint { node, owner: 1, kind: ConstraintKind::SphereOutside { center: s.center, radius: s.radius } });
            }
        }
        out.len() - before
    }

    pub fn skull(&self) -> &Skull {
        &self.skull
    }
}

/// The built pipeline: precomputed data and per-frame scratch.
pub struct Pipeline {
    name: String,
    effects: EffectSet,
    time_step: f64,
    mesh: TetMesh,
    surface: BoundarySurface,
    rest: Vec<Vec3>,
    shapes: Vec<SpatulaShape>,
    names: Vec<String>,
    solver: ConstrainedSolver,
    collision: Option<CollisionStage>,
    skull: Option<SkullStage>,
    /// Vessels and arachnoid bands (the `Tethers` effect).
    tethers: Option<super::tethers::TetherStage>,
    /// Tissue over time: relaxation, ischemia and the held frames that skip the solve.
    time: TissueTime,
    /// A frame's rows, solution and contact patches, reused from frame to frame.
    scratch: FrameScratch,
    /// How a blade holds the tissue.
    contact: ContactRules,
    /// Tets whose four nodes are on the surface, as surface vertex indices
    /// (inverted check without an interior solve), sorted for locality.
    surface_tets: Vec<[u32; 4]>,
    /// The blades between sub-steps: the surface and the poses at the start of the sub-step and of the frame, the
    /// frame's targets, each blade's input filter.
    sub: SubSteps,
    /// What an iteration cap puts back.
    rollback: Rollback,
    /// The far surface kept up to date near the blades.
    far: FarTrack,
    report: FrameReport,
}

/// The blades between sub-steps: the surface and the poses at the start of the sub-step and of the frame, the frame's
/// targets, each blade's input filter.
struct SubSteps {
    /// Surface positions at the start of the current sub-step.
    previous_positions: Vec<Vec3>,
    /// Poses at the start of the current sub-step.
    previous_poses: Vec<Pose>,
    /// Poses at the start of the frame and the frame's target poses.
    frame_start_poses: Vec<Pose>,
    target_poses: Vec<Pose>,
    /// Each spatula's input smoothing (the scenario's `filter`), applied to
    /// the frame's input before sub-steps are counted.
    pose_filters: Vec<Option<super::pose_filter::PoseFilter>>,
    /// Each blade's sample jitter (from its targets, frame by frame) and the travel it takes off this frame's, m.
    jitter: Vec<super::substeps::SampleJitter>,
    allowances: Vec<f64>,
    /// The rest positions binned (with collision only) and the monitor's
    /// scratch: the barrier rows and the monitor read only the vertices near a
    /// blade ([`SimState::surface_bound_m`]).
    grid: Option<super::rest_grid::RestGrid>,
    monitor_near: super::rest_grid::Near,
    /// What the last sub-step's surface copy left, and whether every entry it holds is finite.
    sync: super::surface_sync::SurfaceSync,
    surface_finite: bool,
}

/// What an iteration cap puts back.
struct Rollback {
    /// The rows of the last sub-step that converged, and the collision history
    /// before the current one: what an iteration cap puts back.
    feasible_constraints: Vec<Constraint>,
    saved_history: crate::collision::CollisionHistory,
    saved_claims: Vec<(u32, u8, u8)>,
}

/// The far surface kept up to date near the blades.
struct FarTrack {
    /// The far surface vertices near a blade this sub-step ([`Self::track_far`]), and the blades' boxes it grows.
    near_far: Vec<u32>,
    blade_boxes: Vec<(Vec3, Vec3)>,
    /// The working region's edge: vertices with rows that share a triangle with a far one.
    far_edge: Vec<u32>,
    /// Whether each surface vertex is far (the solver's far set, fixed at its build), and the vertices the rest
    /// grid finds near the blades: the far ones among them are the only ones read.
    is_far: Vec<bool>,
    near: super::rest_grid::Near,
}

/// A frame's rows, solution and contact patches, reused from frame to frame.
struct FrameScratch {
    constraints: Vec<Constraint>,
    solution: FrameSolution,
    patches: Vec<ContactPatch>,
    contact_scratch: super::contact::ContactScratch,
    pressed: Vec<(u32, u16, f64)>,
}

/// Tissue over time: relaxation, ischemia and the held frames that skip the solve.
struct TissueTime {
    /// The blades' forces relaxing while held (the `Relaxation` effect).
    relaxation: Option<super::tissue_time::RelaxationStage>,
    /// Dose and risk per surface vertex (the `Ischemia` effect), and its frame's pressed vertices.
    ischemia: Option<super::tissue_time::IschemiaStage>,
    /// Lumped area per surface vertex at rest (with `Ischemia` only), m^2.
    vertex_areas: Vec<f64>,
    /// Frames in a row solved at unchanged poses, and the last one's rows and surface: a scene with tissue over
    /// time skips the solve once two of them agree (a long hold costs next to nothing).
    still: StillFrames,
}

/// How a blade holds the tissue.
struct ContactRules {
    /// What a spatula target becomes: a sticking `Contact`, a bilateral
    /// `Enforced` hold, or a sliding `Barrier` row.
    law: SpatulaContact,
    /// Largest blade travel of a sub-step, in thicknesses (`None`: one step a frame).
    substep_travel: Option<f64>,
    /// Whether a blade's sample jitter is taken off its travel before the sub-steps are counted.
    discount_jitter: bool,
    /// Blade barrier rows for unclaimed vertices near a blade (unilateral contact only).
    barrier: Option<super::barrier::BarrierStage>,
}

/// Held blades: how many frames in a row were solved at the same poses, and what the last one gave.
#[derive(Debug, Clone, Default)]
struct StillFrames {
    /// Solved frames in a row whose poses did not change (0: the blades moved).
    count: u32,
    /// Whether the last two of them gave the same rows and the same surface, bit for bit.
    settled: bool,
    constraints: Vec<Constraint>,
    displacement: Vec<Vec3>,
}

/// A far surface vertex (one without a compliance row) is brought up to
/// date every sub-step while it lies within this distance (m), plus the
/// largest displacement of the working region's edge, of a blade at the
/// sub-step's start or end: farther than a blade and the tissue it
/// pushes move in a sub-step, so a blade never meets a vertex it last saw
/// out of date.
pub const FAR_TRACK_MARGIN_M: f64 = 0.010;

impl Pipeline {
    pub(super) fn assemble(
        scenario: &Scenario,
        mesh: TetMesh,
        surface: BoundarySurface,
        rest: Vec<Vec3>,
        solver: ConstrainedSolver,
        collision: Option<CollisionStage>,
        skull: Option<SkullStage>,
        tethers: Option<super::tethers::TetherStage>,
    ) -> Result<Self, super::error::BuildError> {
        let surface_tets = surface_tets(&mesh, &surface, solver.far_vertices());
        let far_edge = region_edge(&surface.triangles, solver.far_vertices());
        let mut is_far = vec![false; surface.vertices.len()];
        for &k in solver.far_vertices() {
            if let Some(f) = is_far.get_mut(k as usize) {
                *f = true;
            }
        }
        let blades = scenario.spatulas.len();
        let relaxation = scenario.tissue_time.relaxation.as_ref().map(|r| super::tissue_time::RelaxationStage::new(r, scenario.time_step, blades));
        let vertex_areas = if scenario.tissue_time.ischemia.is_some() { crate::mesh::surface::vertex_areas(&rest, &surface.triangles) } else { Vec::new() };
        let ischemia = scenario.tissue_time.ischemia.as_ref().map(|m| super::tissue_time::IschemiaStage::new(m, scenario.time_step, vertex_areas.clone(), blades));
        let contact_scratch = super::contact::ContactScratch::for_surface(&surface);
        let n = scenario.spatulas.len();
        let contact_law = scenario.solver.spatula_contact;
        // Barrier rows keep released or sliding tissue out of a blade; the paper's bilateral hold has none.
        let barrier = (contact_law != SpatulaContact::Bilateral && collision.is_some()).then(|| super::barrier::BarrierStage::new(surface.vertices.len()));
        Ok(Self {
            name: scenario.name.clone(),
            contact: ContactRules {
                law: contact_law,
                substep_travel: scenario.solver.substep_travel,
                discount_jitter: scenario.solver.substep_jitter == crate::scenario::SubstepJitter::Discount,
                barrier,
            },
            effects: scenario.effects,
            time_step: scenario.time_step,
            shapes: scenario.spatulas.iter().map(|s| s.shape).collect(),
            names: scenario.spatulas.iter().map(|s| s.name.clone()).collect(),
            sub: SubSteps {
                previous_positions: rest.clone(),
                previous_poses: scenario.spatulas.iter().map(|s| s.initial_pose).collect(),
                frame_start_poses: Vec::new(),
                target_poses: Vec::new(),
                pose_filters: scenario.spatulas.iter().map(|s| s.filter.map(|f| super::pose_filter::PoseFilter::new(f, &s.shape))).collect(),
                jitter: vec![Default::default(); n],
                allowances: vec![0.0; n],
                grid: collision.is_some().then(|| super::rest_grid::RestGrid::new(&rest)),
                monitor_near: Default::default(),
                sync: Default::default(),
                surface_finite: true,
            },
            rollback: Rollback { feasible_constraints: Vec::new(), saved_history: Default::default(), saved_claims: Vec::new() },
            far: FarTrack { near_far: Vec::new(), blade_boxes: Vec::new(), far_edge, is_far, near: Default::default() },
            mesh,
            surface,
            rest,
            solver,
            collision,
            skull,
            tethers,
            time: TissueTime { relaxation, ischemia, vertex_areas, still: StillFrames::default() },
            surface_tets,
            scratch: FrameScratch {
                constraints: Vec::new(),
                solution: FrameSolution::default(),
                patches: Vec::new(),
                contact_scratch,
                pressed: Vec::new(),
            },
            report: FrameReport { spatulas: vec![SpatulaReport::default(); n], ..Default::default() },
        })
    }

    /// The state at time 0: the brain at rest, spatulas at `poses`.
    pub fn initial_state(&self, poses: &[Pose]) -> SimState {
        SimState {
            frame: 0,
            time_s: 0.0,
            poses: poses.to_vec(),
            surface_positions: self.rest.clone(),
            surface_bound_m: 0.0,
            surface_displacement: vec![Vec3::zeros(); self.rest.len()],
            surface_mark: super::surface_sync::SurfaceMark::NONE,
            node_displacement: Vec::new(),
            stress: Vec::new(),
        }
    }

    /// The scenario's name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The fixed step, s.
    pub fn time_step(&self) -> f64 {
        self.time_step
    }
    /// The effects this pipeline was built for.
    pub fn effects(&self) -> EffectSet {
        self.effects
    }
    /// The mesh (rest positions, metres).
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }
    /// The boundary surface (triangles in surface-vertex indices).
    pub fn surface(&self) -> &BoundarySurface {
        &self.surface
    }
    /// Rest positions of the surface vertices.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }
    /// Spatula blades, in scenario order.
    pub fn spatula_shapes(&self) -> &[SpatulaShape] {
        &self.shapes
    }
    /// Spatula names, in scenario order.
    pub fn spatula_names(&self) -> &[String] {
        &self.names
    }
    /// The collision stage, when the scene asked for collision.
    pub fn collision(&self) -> Option<&CollisionStage> {
        self.collision.as_ref()
    }
    /// The skull stage, when the scene asked for skull spheres.
    pub fn skull(&self) -> Option<&SkullStage> {
        self.skull.as_ref()
    }
    /// The tether stage, when the scene asked for tethers.
    pub fn tethers(&self) -> Option<&super::tethers::TetherStage> {
        self.tethers.as_ref()
    }

    /// The dose and risk per surface vertex (the `Ischemia` effect).
    pub fn ischemia(&self) -> Option<&super::tissue_time::IschemiaStage> {
        self.time.ischemia.as_ref()
    }

    /// Per blade, its relaxed over its elastic force this frame (the `Relaxation` effect): what each of its
    /// contact pressures is scaled by.
    pub fn relaxation_ratios(&self) -> Option<&[f64]> {
        self.time.relaxation.as_ref().map(|r| r.ratios())
    }
    /// Asks the microscissors at blade `spatula`'s tip to cut the arachnoid
    /// bands within [`super::tethers::CUT_RADIUS_M`] of it at the next frame
    /// (nothing without tethers). Returns whether the scene has tethers.
    pub fn request_cut(&mut self, spatula: usize) -> bool {
        match &mut self.tethers {
            Some(t) => {
                t.request_cut(spatula);
                true
            }
            None => false,
        }
    }
    /// The exact solver (for the haptic thread's contact compliance).
    pub fn solver(&self) -> &ConstrainedSolver {
        &self.solver
    }
    /// Caps the contact solve's active-set iterations (`None`: the default);
    /// for tests and diagnosis of the capped-frame path.
    pub fn set_solver_iteration_cap(&mut self, cap: Option<usize>) {
        self.solver.set_iteration_cap(cap);
    }
    /// The solver's last frame solution.
    pub fn last_solution(&self) -> &FrameSolution {
        &self.scratch.solution
    }
    /// The constraints of the last frame.
    pub fn last_constraints(&self) -> &[Constraint] {
        &self.scratch.constraints
    }
    /// Which stages are built, in frame order.
    pub fn built_stages(&self) -> Vec<StageId> {
        let mut v = Vec::new();
        if self.collision.is_some() {
            v.push(StageId::Collision);
        }
        if self.skull.is_some() {
            v.push(StageId::Skull);
        }
        v.push(StageId::Solve);
        if self.forces_built() {
            v.push(StageId::Forces);
        }
        if self.effects.contains(Effect::StressField) {
            v.push(StageId::Stress);
        }
        if self.collision.is_some() {
            v.push(StageId::Monitor);
        }
        v
    }

    fn forces_built(&self) -> bool {
        self.effects.contains(Effect::ForceOutput) || self.effects.contains(Effect::ContactPressure)
    }

    /// Clears the collision history (His-flags).
    pub fn reset_history(&mut self) {
        if let Some(c) = &mut self.collision {
            c.reset_history();
        }
        if let Some(b) = &mut self.contact.barrier {
            b.reset();
        }
        self.sub.jitter.iter_mut().for_each(super::substeps::SampleJitter::reset);
    }

    /// Runs one frame. A frame whose blades move more than
    /// `solver.substep_travel` of their thickness, less their samples' own
    /// jitter ([`super::substeps`]), is split into sub-steps
    /// (poses interpolated, collision history carried through each), so the
    /// result does not depend on how the motion was sampled. When the contact
    /// solve hits its iteration cap, the frame keeps the last feasible state
    /// (the last sub-step that converged) and its report says `solver_capped`.
    /// On any other error the state is that of the last completed sub-step.
    pub fn step(&mut self, state: &mut SimState, input: &FrameInput) -> Result<&FrameReport, StepError> {
        let frame = state.frame;
        if input.poses.len() != state.poses.len() {
            return Err(StepError::PoseCount { frame, count: input.poses.len(), expected: state.poses.len() });
        }
        // The last sub-step ended with no row in W and no blade inside the tissue.
        let free = self.scratch.solution.rows == 0 && self.report.spatulas.iter().all(|s| s.candidate_pairs == 0);
        let r = &mut self.report;
        r.times = Default::default();
        r.rejected_poses = 0;
        r.solver_capped = false;
        r.crossed_vertices = 0;
        self.sub.frame_start_poses.clone_from(&state.poses);
        self.sub.target_poses.clone_from(&state.poses);
        for ((slot, new), filter) in self.sub.target_poses.iter_mut().zip(&input.poses).zip(&mut self.sub.pose_filters) {
            let accepted = match new {
                Some(p) if p.is_valid() => Some(*p),
                Some(_) => {
                    r.rejected_poses += 1;
                    None
                }
                None => None,
            };
            match filter {
                Some(f) => *slot = f.apply(frame, self.time_step, accepted, slot),
                None => *slot = accepted.unwrap_or(*slot),
            }
        }
        self.observe_jitter();
        // Held blades: with tissue over time, a frame at the poses of two frames that gave the same rows and
        // surface is that answer again (the solve is a function of them), so it is not solved.
        let still = self.sub.target_poses == self.sub.frame_start_poses && !self.tethers.as_ref().is_some_and(|t| t.has_pending_cuts());
        let over_time = self.time.relaxation.is_some() || self.time.ischemia.is_some();
        if still && over_time && self.time.still.settled {
            self.report.substeps = 0;
            return self.finish_frame(state, frame);
        }
        let r = &mut self.report;
        r.penetrating_vertices = 0;
        r.max_penetration_m = 0.0;
        for s in r.spatulas.iter_mut() {
            *s = SpatulaReport::default();
        }
        if let Some(t) = &mut self.tethers {
            t.begin_frame();
        }
        let mut substeps = super::substeps::substep_count(
            &self.shapes,
            &self.sub.frame_start_poses,
            &self.sub.target_poses,
            &self.sub.allowances,
            self.contact.substep_travel,
        );
        if substeps > 1 && free && self.sweeps_clear(&state.surface_positions) {
            // Nothing near the blades' path and nothing held: every sub-step
            // would find no contact and solve to the same free state.
            substeps = 1;
        }
        self.report.substeps = substeps;
        for k in 1..=substeps {
            self.sub.previous_poses.clone_from(&state.poses);
            if k == substeps {
                state.poses.clone_from(&self.sub.target_poses);
            } else {
                let alpha = k as f64 / substeps as f64;
                for ((p, a), b) in state.poses.iter_mut().zip(&self.sub.frame_start_poses).zip(&self.sub.target_poses) {
                    *p = a.interpolate(b, alpha);
                }
            }
            match self.advance(state, frame) {
                Ok(()) => {}
                Err(StepError::Solve { source: crate::fem::FemError::ActiveSetNotConverged { .. }, .. }) => {
                    self.undo_substep(state, frame)?;
                    self.report.solver_capped = true;
                    break;
                }
                Err(e) => return Err(e),
            }
        }
        check_finite_state(frame, self.sub.surface_finite, self.report.max_displacement_m)?;
        if over_time {
            self.note_still(still, state);
        }
        self.finish_frame(state, frame)
    }

    /// Takes the frame's targets into each blade's jitter estimate and sets the travel it takes off this frame's
    /// (none unless sub-steps are on and jitter is discounted).
    fn observe_jitter(&mut self) {
        let sub = &mut self.sub;
        for (((j, a), shape), target) in sub.jitter.iter_mut().zip(&mut sub.allowances).zip(&self.shapes).zip(&sub.target_poses) {
            j.observe(shape, target);
            *a = match self.contact.substep_travel {
                Some(f) if self.contact.discount_jitter => j.allowance(f * shape.thickness),
                _ => 0.0,
            };
        }
    }

    /// After a frame solved at unchanged poses (`still`), whether it agreed with the one before bit for bit.
    fn note_still(&mut self, still: bool, state: &SimState) {
        let events = self.tethers.as_ref().is_some_and(|t| !t.frame().events.is_empty());
        let w = &mut self.time.still;
        if !still || events || self.report.solver_capped {
            w.count = 0;
            w.settled = false;
            return;
        }
        w.settled = w.count > 0 && w.constraints == self.scratch.constraints && w.displacement == state.surface_displacement;
        w.count += 1;
        w.constraints.clone_from(&self.scratch.constraints);
        w.displacement.clone_from(&state.surface_displacement);
    }

    /// The frame's forces, pressures, tissue over time, stress and bookkeeping, from the solution it ends with.
    fn finish_frame(&mut self, state: &mut SimState, frame: u64) -> Result<&FrameReport, StepError> {
        let r = &mut self.report;
        // Forces, contact areas and pressures.
        if self.effects.contains(Effect::ForceOutput) || self.effects.contains(Effect::ContactPressure) {
            let t = Instant::now();
            for s in r.spatulas.iter_mut() {
                // The collision's counts stay (a settled still frame keeps the last solved frame's); what follows is this frame's.
                (s.force, s.contact_area_m2, s.contact_vertices, s.mean_pressure_pa) = (Vec3::zeros(), 0.0, 0, 0.0);
            }
            for (owner, f) in &self.scratch.solution.owner_forces {
                if let Some(s) = r.spatulas.get_mut(*owner as usize) {
                    s.force = *f;
                }
            }
            if self.effects.contains(Effect::ContactPressure) {
                super::contact::contact_patches(
                    &self.surface,
                    &state.surface_positions,
                    &self.scratch.constraints,
                    &self.scratch.solution.reactions,
                    &mut self.scratch.contact_scratch,
                    &mut self.scratch.patches,
                );
                for p in &self.scratch.patches {
                    if let Some(s) = r.spatulas.get_mut(p.owner as usize) {
                        s.contact_area_m2 = p.area;
                        s.contact_vertices = p.vertices;
                        s.mean_pressure_pa = p.mean_pressure_pa;
                    }
                }
            }
            if let Some(relaxation) = &mut self.time.relaxation {
                relaxation.apply(&mut r.spatulas);
            }
            if r.spatulas.iter().any(|s| !(is_finite3(&s.force) && s.contact_area_m2.is_finite() && s.mean_pressure_pa.is_finite())) {
                return Err(StepError::NonFinite { frame, stage: StageId::Forces, what: "a spatula's force or pressure" });
            }
            r.times.set(StageId::Forces, t.elapsed().as_secs_f64());
        }
        if let Some(ischemia) = &mut self.time.ischemia {
            let t = Instant::now();
            self.scratch.pressed.clear();
            self.scratch.pressed.extend(super::contact::tool_vertex_pressures(&self.surface, &self.scratch.constraints, &self.scratch.solution.reactions, &self.time.vertex_areas));
            ischemia.step(&self.scratch.pressed, self.time.relaxation.as_ref().map(|r| r.ratios()), (frame + 1) as f64 * self.time_step);
            r.times.add(StageId::Forces, t.elapsed().as_secs_f64());
            match &mut r.ischemia {
                Some(out) => out.copy_from(ischemia.frame()),
                None => r.ischemia = Some(ischemia.frame().clone()),
            }
        }

        // Interior displacements and stress, only when the scene asks.
        if self.effects.contains(Effect::StressField) {
            let t = Instant::now();
            self.solver.interior_displacements(&mut state.node_displacement).map_err(|source| StepError::Solve { frame, source })?;
            crate::fem::element_stress(self.solver.model(), &state.node_displacement, &mut state.stress)
                .map_err(|source| StepError::Solve { frame, source })?;
            let peak = state.stress.iter().map(|s| s.von_mises).fold(0.0, f64::max);
            if !peak.is_finite() || !state.node_displacement.iter().all(is_finite3) {
                return Err(StepError::NonFinite { frame, stage: StageId::Stress, what: "interior displacement or stress" });
            }
            r.max_von_mises_pa = Some(peak);
            r.inverted_elements = count_inverted_all(&self.mesh, &state.node_displacement);
            r.inverted_scope_all = true;
            r.times.set(StageId::Stress, t.elapsed().as_secs_f64());
        } else {
            r.inverted_elements = count_inverted_surface_tets(&self.rest, &self.surface_tets, &state.surface_displacement);
            r.inverted_scope_all = false;
        }

        match (&self.tethers, &mut r.tethers) {
            (Some(t), Some(out)) => out.copy_from(t.frame()),
            (Some(t), None) => r.tethers = Some(t.frame().clone()),
            _ => {}
        }
        for ((s, shape), pose) in r.spatulas.iter_mut().zip(&self.shapes).zip(&state.poses) {
            s.tip = pose.transform_point(&Vec3::new(shape.length, 0.0, 0.0));
        }
        state.frame += 1;
        state.time_s = state.frame as f64 * self.time_step;
        r.frame = frame;
        r.time_s = state.time_s;
        Ok(&self.report)
    }

    /// Whether every blade's path this frame stays clear of the surface by
    /// more than the reach of the collision's rays and of the barrier rows
    /// ([`super::barrier::sweep_clear`]).
    fn sweeps_clear(&self, positions: &[Vec3]) -> bool {
        self.shapes.iter().zip(&self.sub.frame_start_poses).zip(&self.sub.target_poses).all(|((shape, before), after)| {
            let margin = super::barrier::BARRIER_BAND_M + 2.0 * shape.thickness;
            super::barrier::sweep_clear(shape, before, after, &self.surface.triangles, positions, margin)
        })
    }

    /// The sub-step's collision: the rays' targets (claims unless contact slides), then the barrier rows, into
    /// `constraints`; the per-spatula counts into the report.
    fn collide(&mut self, state: &SimState, frame: u64) -> Result<(), StepError> {
        let r = &mut self.report;
        if let Some(collision) = &mut self.collision {
            let t = Instant::now();
            collision.save_history(&mut self.rollback.saved_history);
            if let Some(barrier) = &self.contact.barrier {
                self.rollback.saved_claims.clear();
                self.rollback.saved_claims.extend_from_slice(barrier.previous_claims());
            }
            let out = collision.step(&state.surface_positions, &state.poses).map_err(|source| StepError::Collision { frame, source })?;
            // Sliding: the rays claim nothing; the barrier rows hold every vertex under a blade alike.
            let claims = self.contact.law != SpatulaContact::Sliding;
            for target in out.targets.iter().filter(|_| claims) {
                self.scratch.constraints.push(Constraint {
                    node: self.surface.vertices[target.vertex as usize],
                    owner: target.spatula as u16,
                    kind: if self.contact.law == SpatulaContact::Unilateral {
                        ConstraintKind::Contact { displacement: target.displacement, normal: target.normal }
                    } else {
                        ConstraintKind::Enforced { displacement: target.displacement }
                    },
                });
            }
            for (s, c) in r.spatulas.iter_mut().zip(&out.per_spatula) {
                s.candidate_pairs = c.candidates;
                s.culled_pairs = c.culled;
                s.feasible_pairs = c.feasible;
                s.constrained_vertices = c.constrained_vertices;
            }
            r.constrained_vertices = self.scratch.constraints.len() as u32;
            if let Some(barrier) = &mut self.contact.barrier {
                use super::barrier::{Blades, SurfaceState};
                let blades = Blades { shapes: &self.shapes, before: &self.sub.previous_poses, after: &state.poses };
                let surface = SurfaceState {
                    triangles: &self.surface.triangles,
                    start: &state.surface_positions,
                    rest: &self.rest,
                    nodes: &self.surface.vertices,
                    grid: self.sub.grid.as_ref().map(|g| (g, state.surface_bound_m)),
                };
                barrier.push_rows(blades, collision, claims, surface, &mut self.scratch.constraints);
                if !claims {
                    // Every row is a blade's: a spatula constrains the vertices it has rows for.
                    for s in r.spatulas.iter_mut() {
                        s.constrained_vertices = 0;
                    }
                    for c in &self.scratch.constraints {
                        if let Some(s) = r.spatulas.get_mut(usize::from(c.owner)) {
                            s.constrained_vertices += 1;
                        }
                    }
                    r.constrained_vertices = self.scratch.constraints.len() as u32;
                }
            }
            r.times.add(StageId::Collision, t.elapsed().as_secs_f64());
        }
        Ok(())
    }

    /// One sub-step at the poses in `state`: collision, skull rows, the exact
    /// solve and surface update, the tunnelling monitor. Saves what
    /// [`Self::undo_substep`] needs to put the last feasible state back.
    fn advance(&mut self, state: &mut SimState, frame: u64) -> Result<(), StepError> {
        self.scratch.constraints.clear();
        self.collide(state, frame)?;
        let r = &mut self.report;

        // Skull: unilateral candidate rows.
        if let Some(skull) = &self.skull {
            let t = Instant::now();
            skull.push_rows(&state.surface_positions, &mut self.scratch.constraints);
            r.times.add(StageId::Skull, t.elapsed().as_secs_f64());
        }

        // Exact constrained solve and surface update.
        let t = Instant::now();
        let time_s = (frame + 1) as f64 * self.time_step;
        if let Some(tethers) = self.tethers.as_mut().filter(|t| t.has_pending_cuts()) {
            // Only a frame that cuts gathers the tips (a cut is rare; the frame stays allocation-free otherwise).
            let tips: Vec<Vec3> = self.shapes.iter().zip(&state.poses).map(|(s, p)| p.transform_point(&Vec3::new(s.length, 0.0, 0.0))).collect();
            tethers.apply_cuts(&tips, &state.surface_positions, time_s, frame, &mut self.solver);
        }
        self.track_far(state);
        self.solver.step(&self.scratch.constraints, &mut self.scratch.solution).map_err(|source| StepError::Solve { frame, source })?;
        self.rollback.feasible_constraints.clone_from(&self.scratch.constraints);
        let bound_before = state.surface_bound_m;
        // The new displacements, positions and their bound, over the vertices the step changed where it can.
        let target = super::surface_sync::SurfaceTarget {
            displacement: &mut state.surface_displacement,
            positions: &mut state.surface_positions,
            mark: &mut state.surface_mark,
            previous: &mut self.sub.previous_positions,
        };
        (state.surface_bound_m, self.sub.surface_finite) = self.sub.sync.copy(&self.scratch.solution, &self.rest, &self.far.is_far, target);
        if let Some(tethers) = &mut self.tethers {
            tethers.after_solve(&state.surface_positions, &self.scratch.solution.tether_tension, time_s, frame, &mut self.solver);
        }
        let r = &mut self.report;
        r.max_displacement_m = self.scratch.solution.max_displacement;
        r.skull_contacts = self.scratch.solution.active_sphere_contacts as u32;
        r.times.add(StageId::Solve, t.elapsed().as_secs_f64());

        // Tunnelling / penetration monitor, over this sub-step's motion.
        if self.collision.is_some() {
            let t = Instant::now();
            let (before, after) = (&self.sub.previous_positions, &state.surface_positions);
            let m = match &self.sub.grid {
                Some(grid) => monitor::measure_near(
                    &self.shapes,
                    &self.sub.previous_poses,
                    &state.poses,
                    before,
                    after,
                    grid,
                    (bound_before, state.surface_bound_m),
                    &mut self.sub.monitor_near,
                ),
                None => monitor::measure(&self.shapes, &self.sub.previous_poses, &state.poses, before, after),
            };
            r.crossed_vertices += m.crossed;
            r.penetrating_vertices = m.penetrating;
            r.max_penetration_m = m.max_depth_m;
            r.times.add(StageId::Monitor, t.elapsed().as_secs_f64());
        }
        Ok(())
    }

    /// Puts back the state before the sub-step that failed: the poses and the
    /// collision history of the last feasible sub-step, and the solver's
    /// solution of that sub-step's rows (solved again: it converged before).
    /// The surface in `state` was not touched by the failed sub-step.
    fn undo_substep(&mut self, state: &mut SimState, frame: u64) -> Result<(), StepError> {
        state.poses.clone_from(&self.sub.previous_poses);
        if let Some(collision) = &mut self.collision {
            collision.restore_history(&self.rollback.saved_history);
        }
        if let Some(barrier) = &mut self.contact.barrier {
            barrier.restore_previous_claims(&self.rollback.saved_claims);
        }
        std::mem::swap(&mut self.scratch.constraints, &mut self.rollback.feasible_constraints);
        // These rows converged under the default cap before: solve them under it again.
        let cap = self.solver.iteration_cap();
        self.solver.set_iteration_cap(None);
        let solved = self.solver.step(&self.scratch.constraints, &mut self.scratch.solution);
        self.solver.set_iteration_cap(cap);
        solved.map_err(|source| StepError::Solve { frame, source })?;
        self.rollback.feasible_constraints.clone_from(&self.scratch.constraints);
        let r = &mut self.report;
        r.constrained_vertices = self.scratch.constraints.iter().filter(|c| c.kind.tool_displacement().is_some()).count() as u32;
        r.max_displacement_m = self.scratch.solution.max_displacement;
        r.skull_contacts = self.scratch.solution.active_sphere_contacts as u32;
        Ok(())
    }

    /// Displacement of every node for the current state: the stress stage's
    /// when it ran this frame, else one sparse solve now (VTK output, on demand).
    pub fn node_displacement(&mut self, state: &SimState) -> Result<Vec<Vec3>, StepError> {
        if self.effects.contains(Effect::StressField) && state.node_displacement.len() == self.mesh.node_count() {
            return Ok(state.node_displacement.clone());
        }
        let mut u = Vec::new();
        self.solver.interior_displacements(&mut u).map_err(|source| StepError::Solve { frame: state.frame, source })?;
        Ok(u)
    }

    /// Names to the solver the far surface vertices (no compliance row)
    /// within [`FAR_TRACK_MARGIN_M`] of a blade's box at the sub-step's
    /// start or end; it brings them up to date this sub-step.
    fn track_far(&mut self, state: &SimState) {
        if self.solver.far_vertices().is_empty() {
            return;
        }
        self.far.near_far.clear();
        // A far vertex not brought up to date may have moved since: by about
        // as much as the region's edge has (displacement decays away from
        // the blades), so the margin grows by the edge's largest displacement.
        let edge = self.far.far_edge.iter().map(|&k| state.surface_displacement[k as usize].norm_squared()).fold(0.0, f64::max).sqrt();
        let grow = FAR_TRACK_MARGIN_M + edge;
        self.far.blade_boxes.clear();
        for ((shape, before), after) in self.shapes.iter().zip(&self.sub.previous_poses).zip(&state.poses) {
            let (lo, hi) = (Vec3::new(0.0, -0.5 * shape.width, -0.5 * shape.thickness), Vec3::new(shape.length, 0.5 * shape.width, 0.5 * shape.thickness));
            for pose in [before, after] {
                self.far.blade_boxes.push(super::barrier::world_bounds(pose, &lo, &hi, grow));
            }
        }
        let poses = self.shapes.iter().zip(&self.sub.previous_poses).zip(&state.poses).flat_map(|((shape, before), after)| [(shape, before), (shape, after)]);
        // Every box lies inside their union: most far vertices are outside it, one test each.
        let empty = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        let union = self.far.blade_boxes.iter().fold(empty, |(lo, hi), (l, h)| (lo.inf(l), hi.sup(h)));
        let far = &mut self.far;
        let mut visit = |k: usize| {
            let p = &state.surface_positions[k];
            if super::barrier::outside_bounds(p, &union) {
                return;
            }
            // the world box first (cheap), then the distance to the blade itself
            let near = far.blade_boxes.iter().zip(poses.clone()).any(|(b, (shape, pose))| {
                !super::barrier::outside_bounds(p, b) && super::barrier::distance_to_blade(shape, pose, p) <= grow
            });
            if near {
                far.near_far.push(k as u32);
            }
        };
        // Through the rest grid, the far vertices that may lie in the union, ascending as the far set is.
        let n = state.surface_positions.len();
        match &self.sub.grid {
            Some(grid) if grid.len() == n && far.is_far.len() == n => {
                grid.near(&union.0, &union.1, state.surface_bound_m, &mut far.near);
                let (near, is_far) = (std::mem::take(&mut far.near), std::mem::take(&mut far.is_far));
                near.for_each(n, |k| {
                    if is_far[k] {
                        visit(k);
                    }
                });
                (far.near, far.is_far) = (near, is_far);
            }
            _ => self.solver.far_vertices().iter().for_each(|&k| visit(k as usize)),
        }
        self.solver.track(&self.far.near_far);
    }

    /// `state` with its whole surface up to date: the far vertices (no
    /// compliance row, left as last brought up to date by the frames) from
    /// one sparse solve with the last frame's forces. For outputs that show
    /// or hash the whole surface (the final state, PNG frames); the frames
    /// that follow are not changed by it. Borrows `state` when every surface
    /// vertex has a row.
    pub fn with_whole_surface<'a>(&mut self, state: &'a SimState) -> Result<std::borrow::Cow<'a, SimState>, StepError> {
        if self.solver.far_vertices().is_empty() {
            return Ok(std::borrow::Cow::Borrowed(state));
        }
        let mut whole = state.clone();
        // (its far vertices are not the solver's: a pipeline given it copies its next step whole)
        whole.surface_mark = super::surface_sync::SurfaceMark::NONE;
        self.solver.whole_surface(&mut whole.surface_displacement).map_err(|source| StepError::Solve { frame: state.frame, source })?;
        let mut bound = [0u64; 3];
        for ((p, rest), u) in whole.surface_positions.iter_mut().zip(&self.rest).zip(&whole.surface_displacement) {
            *p = rest + u;
            super::rest_grid::add_to_bound(&mut bound, p, rest);
        }
        whole.surface_bound_m = super::rest_grid::finish_bound(bound);
        Ok(std::borrow::Cow::Owned(whole))
    }

    /// Brings the far part of a frame's `surface_displacement` up to date
    /// from that frame's nodal forces (`solver().last_forces()` then), as
    /// [`Self::with_whole_surface`] would have then, bit for bit: a run that
    /// keeps every frame's surface does the solves after its timed frames.
    pub fn whole_surface_for(&mut self, frame: u64, forces: &[(u32, Vec3)], surface_displacement: &mut [Vec3]) -> Result<(), StepError> {
        self.solver.whole_surface_for(forces, surface_displacement).map_err(|source| StepError::Solve { frame, source })
    }

    /// blake3 over the whole surface's displacement bits
    /// ([`Self::with_whole_surface`]) and the His-flags: equal for bitwise-equal states.
    pub fn state_hash(&mut self, state: &SimState) -> Result<String, StepError> {
        let whole = self.with_whole_surface(state)?;
        let mut h = blake3::Hasher::new();
        for u in &whole.surface_displacement {
            for c in u.iter() {
                h.update(&c.to_bits().to_le_bytes());
            }
        }
        if let Some(c) = &self.collision {
            let flags = c.his_flags();
            for k in 0..c.node_count() {
                h.update(&[flags.get(k) as u8]);
            }
        }
        Ok(h.finalize().to_hex().to_string())
    }
}

/// The surface vertices not in `far` (ascending) that share a triangle with one in it.
fn region_edge(triangles: &[[u32; 3]], far: &[u32]) -> Vec<u32> {
    let is_far = |v: &u32| far.binary_search(v).is_ok();
    let mut edge: Vec<u32> = triangles.iter().filter(|t| t.iter().any(is_far)).flat_map(|t| t.iter().copied().filter(|v| !is_far(v))).collect();
    edge.sort_unstable();
    edge.dedup();
    edge
}

/// The tets whose four nodes are on `surface`, as surface vertex indices,
/// sorted by their first vertex (a frame reads them in memory order).
/// Those with a vertex in `far` (ascending surface indices of the vertices
/// without compliance rows) are left out: the frames leave such a vertex as
/// it was, so its tets are judged only in the working region.
fn surface_tets(mesh: &TetMesh, surface: &BoundarySurface, far: &[u32]) -> Vec<[u32; 4]> {
    let mut tets: Vec<[u32; 4]> = mesh
        .tets
        .iter()
        .filter(|t| t.iter().all(|&n| surface.node_to_vertex[n as usize] != crate::mesh::surface::NOT_ON_SURFACE))
        .map(|t| t.map(|n| surface.node_to_vertex[n as usize]))
        .filter(|t| t.iter().all(|v| far.binary_search(v).is_err()))
        .collect();
    tets.sort_unstable_by_key(|t| t[0]);
    tets
}

/// Tets of `tets` (surface vertex indices) with a non-positive volume at
/// `rest + surface_displacement`: the same sums as at the mesh's nodes (`rest`
/// is the mesh positions gathered per vertex), so the same count.
fn count_inverted_surface_tets(rest: &[Vec3], tets: &[[u32; 4]], surface_displacement: &[Vec3]) -> u32 {
    tets.iter()
        .filter(|t| {
            let p = t.map(|v| rest[v as usize] + surface_displacement[v as usize]);
            signed_volume(&p[0], &p[1], &p[2], &p[3]) <= 0.0
        })
        .count() as u32
}

fn count_inverted_all(mesh: &TetMesh, u: &[Vec3]) -> u32 {
    mesh.tets
        .iter()
        .filter(|t| {
            let p = t.map(|n| mesh.positions[n as usize] + u[n as usize]);
            signed_volume(&p[0], &p[1], &p[2], &p[3]) <= 0.0
        })
        .count() as u32
}


#[cfg(test)]
mod tests {
    use super::*;

    /// The count by surface vertex equals the count at the mesh's nodes
    /// (the surface's own displacement per node), with some tets inverted.
    #[test]
    fn surface_tets_inverted_count_is_the_count_at_the_nodes() {
        let mesh = crate::mesh::tests::cube();
        let surface = mesh.boundary();
        let tets = surface_tets(&mesh, &surface, &[]);
        assert_eq!(tets.len(), mesh.tets.len(), "every node of the cube is on its surface");
        let rest = surface.gather_positions(&mesh.positions);
        let mut next = crate::math::test_rng::uniform(0x9e3779b97f4a7c15u64);
        let mut mixed = false;
        for _ in 0..50 {
            let u: Vec<Vec3> = (0..rest.len()).map(|_| Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 1.5).collect();
            let at_nodes = mesh
                .tets
                .iter()
                .filter(|t| {
                    let p = t.map(|n| mesh.positions[n as usize] + u[surface.node_to_vertex[n as usize] as usize]);
                    signed_volume(&p[0], &p[1], &p[2], &p[3]) <= 0.0
                })
                .count() as u32;
            mixed |= at_nodes > 0 && (at_nodes as usize) < tets.len();
            assert_eq!(count_inverted_surface_tets(&rest, &tets, &u), at_nodes);
        }
        assert!(mixed, "some draws must invert some tets and not others");
    }
}
