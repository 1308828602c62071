//! The figures each measuring program writes as JSON, one type a report: the program serializes it, the
//! performance page ([`super::page`]) deserializes it, so a field renamed on one side is a compile error on the
//! other. Times in seconds or milliseconds as each field's name says, memory in MB (2^20 bytes unless said).

use serde::{Deserialize, Serialize};

/// `examples/startup_probe.rs --json`: the build's figures when it waited for every column, the early start's
/// when it did not (`--background`). Times from the probe's start.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartupReport {
    pub scenario: String,
    pub build: Option<BuildFigures>,
    pub early_start: Option<EarlyStartFigures>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildFigures {
    /// When the compliance began (the model and the factor were done).
    pub before_compliance_s: f64,
    pub build_s: f64,
    pub peak_rss_mb: f64,
    pub compliance: ComplianceFigures,
}

/// The compliance a build kept (MB here are 10^6 bytes, as the probe has always printed them).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceFigures {
    pub rows: usize,
    pub cols: usize,
    pub megabytes: f64,
    pub compute_s: f64,
    pub load_s: f64,
    pub from_cache: bool,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EarlyStartFigures {
    pub build_returned_s: f64,
    pub first_frame_s: f64,
    pub frames: usize,
    pub motion_done_s: f64,
    pub slowest_frame_ms: f64,
    pub frames_over_50ms: usize,
    /// When the last column was final.
    pub columns_final_s: f64,
    pub peak_rss_mb: f64,
    pub compliance: ComplianceFigures,
}

/// `benches/fem.rs`: one model's figures (`target/fem-bench-cache/figures/MODEL.json`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FemFigures {
    pub model: String,
    pub nodes: usize,
    pub tets: usize,
    /// Assembly and factor.
    pub factor_total_s: f64,
    /// `K_FF`'s factor under each fill-reducing ordering, AMD first.
    pub orderings: Vec<OrderingFigures>,
    pub compliance: Option<CompliancePrecompute>,
    /// The frames at 100 and at 300 constrained vertices.
    pub frames: Vec<FrameFigures>,
    pub peak_rss_mb: f64,
    pub error_vs_f64: Option<ErrorFigures>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrderingFigures {
    pub ordering: String,
    pub nnz_l_millions: f64,
    pub exact_nnz_l_millions: f64,
    /// This ordering's 96-column solve over AMD's (AMD's own: none).
    pub solve_over_amd: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompliancePrecompute {
    pub rows: usize,
    pub cols: usize,
    pub megabytes: f64,
    pub precompute_s: f64,
    pub reload_s: f64,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameFigures {
    pub constrained: usize,
    pub p50_ms: f64,
    pub p95_ms: f64,
    pub max_ms: f64,
    /// The frame's floor measured in the same run (W's new entries and the cheapest dense factor), and the p95 over it.
    pub floor_ms: Option<f64>,
    pub p95_over_floor: Option<f64>,
    /// The surface product's floor (its columns read once at the machine's streaming rate), the product itself,
    /// the streaming rate, and the p95 over both floors together.
    pub product_floor_ms: Option<f64>,
    pub product_ms: f64,
    pub stream_gb_s: Option<f64>,
    pub two_floors_ms: Option<f64>,
    pub p95_over_two_floors: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorFigures {
    pub constrained: usize,
    /// Relative, max norm, over the working region.
    pub displacement: f64,
    pub reaction: f64,
}

/// One line of the fem bench's audit (`target/fem-bench-cache/figures/MODEL_audit.json`, a list): the phase the
/// switch touches with it on and off (ms, the median of three rounds, or the best of three for a one-off
/// phase), and the frame p95 with it on and off (none for a one-off phase).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuditBar {
    pub switch: String,
    pub sequence: String,
    pub phase: String,
    pub on: f64,
    pub off: f64,
    pub p95_on: Option<f64>,
    pub p95_off: Option<f64>,
}

impl AuditBar {
    /// How many times faster the phase runs with the switch on.
    pub fn gain(&self) -> f64 {
        self.off / self.on
    }
}

/// `fissure run --report`: a window session's figures.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindowReport {
    pub presented: u64,
    pub wall_s: f64,
    pub fps: f64,
    pub adapter: String,
    pub sim_frames: u64,
    pub simulated_s: f64,
    pub step_p50_ms: f64,
    pub step_p95_ms: f64,
    pub step_max_ms: f64,
    pub failed_frames: u64,
    pub final_state: String,
}

/// `fissure bench collision --json`: a row a case and backend.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionReport {
    /// The GPU adapter of the `gpu` rows ("none" without one).
    pub device: String,
    pub rows: Vec<CollisionRow>,
    /// What the bench said beside its rows: a case skipped and why, a backend that could not run.
    #[serde(default)]
    pub notes: Vec<String>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionRow {
    pub surface: String,
    pub triangles: usize,
    pub nodes_a_face: u32,
    pub backend: String,
    pub p50_ms: f64,
    pub p95_ms: f64,
    pub cast_p50_ms: f64,
    pub rest_p50_ms: f64,
    pub candidates: usize,
    pub answer_hash: String,
}

impl CollisionReport {
    /// The row of one case and backend.
    pub fn row(&self, surface: &str, nodes_a_face: u32, backend: &str) -> Option<&CollisionRow> {
        self.rows.iter().find(|r| r.surface == surface && r.nodes_a_face == nodes_a_face && r.backend == backend)
    }
}
