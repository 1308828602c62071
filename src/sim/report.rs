//! What one frame reports: stage times, pair counts, forces, pressures, safety numbers.
//!
//! In: filled by [`crate::sim::Pipeline::step`]. Out: a [`FrameReport`] the window,
//! the replay writer and the tests read. Stays true: a stage the scene did not
//! ask for has no entry in [`StageTimes`] (it is `None`, never `0`).

use crate::math::Vec3;
use serde::Serialize;

/// 1 mmHg in pascals.
pub const PASCALS_PER_MMHG: f64 = 133.322_387_415;
/// The brain-retraction danger line used in the literature: about 20 mmHg sustained.
pub const RETRACTION_DANGER_MMHG: f64 = 20.0;

/// The pipeline's stages, in the order a frame runs them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StageId {
    /// Rays from the source nodes, pairs, His-flag culling, enforced displacements.
    Collision,
    /// Unilateral skull-sphere constraint rows.
    Skull,
    /// The exact constrained FEM solve (Schur complement) and surface update.
    Solve,
    /// Reaction forces, contact areas and pressures per spatula.
    Forces,
    /// Interior displacements and per-tet stress / strain (on demand).
    Stress,
    /// Tunnelling / penetration monitor (vertices on the wrong side of a blade).
    Monitor,
}

impl StageId {
    /// Every stage, in frame order.
    pub const ALL: [StageId; 6] =
        [StageId::Collision, StageId::Skull, StageId::Solve, StageId::Forces, StageId::Stress, StageId::Monitor];

    /// Column name stem (`collision`, `skull`, ...).
    pub fn name(self) -> &'static str {
        match self {
            StageId::Collision => "collision",
            StageId::Skull => "skull",
            StageId::Solve => "solve",
            StageId::Forces => "forces",
            StageId::Stress => "stress",
            StageId::Monitor => "monitor",
        }
    }
}

/// Wall time per stage of one frame, seconds; `None` for a stage that is not built.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StageTimes {
    pub seconds: [Option<f64>; StageId::ALL.len()],
}

impl StageTimes {
    pub fn get(&self, stage: StageId) -> Option<f64> {
        self.seconds[stage as usize]
    }
    pub fn set(&mut self, stage: StageId, seconds: f64) {
        self.seconds[stage as usize] = Some(seconds);
    }
    /// Adds `seconds` to a stage (a frame split into sub-steps runs a stage several times).
    pub fn add(&mut self, stage: StageId, seconds: f64) {
        *self.seconds[stage as usize].get_or_insert(0.0) += seconds;
    }
    /// Sum over the built stages.
    pub fn total(&self) -> f64 {
        // From +0.0: `sum` starts at -0.0, so a frame with no stage timed read "-0.00 ms".
        self.seconds.iter().flatten().fold(0.0, |a, b| a + b)
    }
}

/// Per-spatula numbers of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SpatulaReport {
    /// Candidate pairs (node, nearest triangle behind, facing it).
    pub candidate_pairs: u32,
    /// Candidates cancelled by His-flag culling.
    pub culled_pairs: u32,
    /// Pairs that gave enforced displacements.
    pub feasible_pairs: u32,
    /// Surface vertices this spatula constrains.
    pub constrained_vertices: u32,
    /// Total force the spatula exerts on the tissue, N (world frame).
    pub force: Vec3,
    /// Contact area (triangles whose three vertices this spatula constrains), m^2.
    pub contact_area_m2: f64,
    /// Surface vertices this spatula pushes (the contact patch in vertices).
    pub contact_vertices: u32,
    /// Mean contact pressure |force| / area, Pa (0 without contact).
    pub mean_pressure_pa: f64,
    /// The blade's tip at the end of the frame, m (world frame).
    pub tip: Vec3,
}

impl SpatulaReport {
    /// Mean contact pressure in mmHg.
    pub fn mean_pressure_mmhg(&self) -> f64 {
        self.mean_pressure_pa / PASCALS_PER_MMHG
    }
}

/// Everything one frame tells.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FrameReport {
    /// Frame index, from 0.
    pub frame: u64,
    /// Simulated time at the end of the frame, s.
    pub time_s: f64,
    /// Wall time per built stage.
    pub times: StageTimes,
    /// One entry per spatula, in scenario order.
    pub spatulas: Vec<SpatulaReport>,
    /// Constraint rows' vertices: spatula-constrained surface vertices this frame.
    pub constrained_vertices: u32,
    /// Skull contacts active after the unilateral solve.
    pub skull_contacts: u32,
    /// Largest vertex displacement from rest, m.
    pub max_displacement_m: f64,
    /// Inverted tets among those whose displacement is known this frame (see `inverted_scope_all`).
    pub inverted_elements: u32,
    /// True when `inverted_elements` counts every tet (interior solved this frame); false when it
    /// counts only tets whose four nodes are on the surface.
    pub inverted_scope_all: bool,
    /// Surface vertices within a blade's footprint that changed side of its mid-plane this frame (tunnelling).
    pub crossed_vertices: u32,
    /// Surface vertices strictly inside a blade.
    pub penetrating_vertices: u32,
    /// Deepest such penetration, m.
    pub max_penetration_m: f64,
    /// Poses rejected this frame (NaN/Inf or non-unit quaternion); the last good pose held.
    pub rejected_poses: u32,
    /// Largest von Mises stress, Pa (only with the stress stage).
    pub max_von_mises_pa: Option<f64>,
    /// Sub-steps the frame was split into (1 unless a blade moved more than
    /// `solver.substep_travel` of its thickness; 0 for a held frame of a scene
    /// with tissue over time that was not solved again, its answer unchanged).
    pub substeps: u32,
    /// True when the contact solve hit its iteration cap: the frame kept the
    /// last feasible state (tissue and poses of the last sub-step that converged).
    pub solver_capped: bool,
    /// Vessels and bands this frame (only with the tether stage).
    pub tethers: Option<super::tethers::TetherFrame>,
    /// Ischemic area and dose (the `Ischemia` effect).
    pub ischemia: Option<IschemiaFrame>,
}

/// Per frame: what the ischemia stage reports.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct IschemiaFrame {
    /// Surface area whose risk is at or over each of [`RISK_LEVELS`](crate::scenario::tissue_time::RISK_LEVELS), m^2.
    pub area_over_m2: [f64; 3],
    /// Per blade (the blade that last pressed each vertex): area at risk (the second level, even odds), m^2.
    pub blade_area_at_risk_m2: Vec<f64>,
    /// Largest dose of any vertex, mmHg s, and its risk.
    pub max_dose_mmhg_s: f64,
    pub max_risk: f64,
    /// Longest current stretch of any vertex with its perfusion pressure under 10 mmHg, s.
    pub longest_low_perfusion_s: f64,
}

impl IschemiaFrame {
    /// Copies `other` into `self`, reusing the blade list's memory (the frame path allocates nothing).
    pub fn copy_from(&mut self, other: &Self) {
        self.area_over_m2 = other.area_over_m2;
        self.blade_area_at_risk_m2.clone_from(&other.blade_area_at_risk_m2);
        self.max_dose_mmhg_s = other.max_dose_mmhg_s;
        self.max_risk = other.max_risk;
        self.longest_low_perfusion_s = other.longest_low_perfusion_s;
    }
}
