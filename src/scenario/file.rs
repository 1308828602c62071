//! The scenario file as written: serde types in human units (`_mm`, `_pa`, `_s`,
//! `_deg` in the names), every struct with `deny_unknown_fields`.
//!
//! In: RON text (see `config/*.ron` and docs/usage.md for every field). Out: a
//! [`ScenarioFile`] that has the right shape but is not yet checked for ranges
//! or consistency: [`crate::scenario::Scenario::validate`] does that and converts
//! to SI. Optional fields have the defaults documented on each.

use serde::{Deserialize, Serialize};

/// A whole scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Human name of the scene (non-empty).
    pub name: String,
    /// Where the brain mesh comes from.
    pub mesh: MeshSourceFile,
    /// Local refinement of the mesh's boundary where the blades work, so a
    /// blade holds a patch of many vertices. `None` (the default): the mesh
    /// as it is. `Auto`: where the blades reach along the scenario's own
    /// trajectory (or, without one, inside its `region_of_interest` sphere),
    /// to edges of a quarter of the narrowest blade's width, so each blade
    /// face spans at least four edges across (several times the contact
    /// vertices, and the frame costs more with them). `Some((edge_mm: 1.0,
    /// within: [Box(min_mm: (..), max_mm: (..))]))`: inside the given
    /// volumes, to `edge_mm`. Every boundary edge whose midpoint is in the region is split
    /// (longest-edge bisection, conforming; interior edges only as that rule
    /// needs) until it is no longer than the edge length. A function of the
    /// scenario alone (not of a `--trajectory` a replay plays), so a replay
    /// sees the mesh the window saw.
    #[serde(default)]
    pub refine: RefineChoiceFile,
    /// Linear elastic material of the brain.
    pub material: MaterialFile,
    /// Nodes held fixed (at least one entry; their union is fixed). Checked
    /// against the mesh before a run (and by `fissure check`): the union selects
    /// at least one node, and every connected component of the mesh has one.
    pub fixed: Vec<FixedFile>,
    /// Skull spheres (needed when `effects` has `SkullSpheres`). Default `None`.
    /// With `SkullSpheres`, checked against the mesh at rest: every surface
    /// vertex inside `containing` and outside `excluding`.
    #[serde(default)]
    pub skull: Option<SkullFile>,
    /// The spatulas (1 to 255; names unique).
    pub spatulas: Vec<SpatulaFile>,
    /// The stages the scene wants; the pipeline builds only these.
    pub effects: Vec<Effect>,
    /// Collision options. Default `(backend: Bvh)`.
    #[serde(default)]
    pub collision: CollisionFile,
    /// Solver options. Default `(compliance_storage: F64, region_of_interest: Auto, cache_dir: None)`.
    #[serde(default)]
    pub solver: SolverFile,
    /// Gravity vector, m/s^2 (every component finite). Default `(0.0, 0.0, -9.81)`; used only with the `Gravity` effect.
    #[serde(default = "default_gravity")]
    pub gravity_m_s2: [f64; 3],
    /// Tissue density, kg/m^3, in (0, 1e5]. Default 1040 (brain tissue); used only with `Gravity`.
    #[serde(default = "default_density")]
    pub density_kg_m3: f64,
    /// Fixed simulation step, s: > 0 and at most `duration_s / 10` (a run has
    /// at least 10 steps). A step in which the trajectory moves a blade more
    /// than its thickness gets a warning (the blade could pass through tissue
    /// thinner than its travel).
    pub time_step_s: f64,
    /// Length of a headless run, s (> 0).
    pub duration_s: f64,
    /// A recorded pose track (CSV, see docs/usage.md), relative to this file's
    /// folder: it must exist, parse, and have no rows for a spatula index the
    /// scene lacks. Default `None`.
    #[serde(default)]
    pub trajectory: Option<String>,
    /// Where results go. Default `(dir: "out", vtk: false, frames: false, record_dir: None)`.
    #[serde(default)]
    pub outputs: OutputsFile,
    /// How the window and screenshots show fields. Default `(pressure_max_mmhg: 30.0)`.
    #[serde(default)]
    pub display: DisplayFile,
    /// What a run may do to the tissue before its summary says it failed
    /// (`replay --strict` then exits 3). Default
    /// `(max_penetration_mm: 0.05, max_inverted_elements: 0, max_crossed_vertices: 0)`.
    #[serde(default)]
    pub integrity: IntegrityFile,
    /// Vessels and arachnoid bands (used with the `Tethers` effect). Default none.
    #[serde(default)]
    pub tethers: super::tethers::TethersFile,
    /// The tissue's relaxation function (used with the `Relaxation` effect). Default: halves in 6.6 minutes.
    #[serde(default)]
    pub relaxation: super::tissue_time::RelaxationFile,
    /// The ischemia model under a retractor (used with the `Ischemia` effect). Default: a MAP of 90 mmHg and the
    /// rat-calibrated dose.
    #[serde(default)]
    pub ischemia: super::tissue_time::IschemiaFile,
    /// fissure's OpenIGTLink server (used by `OpenIgtLink` inputs). Default `(listen: "127.0.0.1:18944")`.
    #[serde(default)]
    pub openigtlink: super::devices::OpenIgtLinkFile,
    /// The SpaceMouse's tuning (used by `SpaceMouse` inputs). Default: the gamepad's speeds and dead zone.
    #[serde(default)]
    pub spacemouse: super::devices::SpaceMouseFile,
}

/// Integrity limits: `(max_penetration_mm: 0.05, max_inverted_elements: 0, max_crossed_vertices: 0)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntegrityFile {
    /// Deepest a surface vertex may end a frame inside a blade, mm (finite, >= 0). Default 0.05.
    #[serde(default = "default_max_penetration_mm")]
    pub max_penetration_mm: f64,
    /// Most inverted elements in a frame. Default 0.
    #[serde(default)]
    pub max_inverted_elements: u32,
    /// Most surface vertices pulled through a blade in a frame. Default 0.
    #[serde(default)]
    pub max_crossed_vertices: u32,
    /// Most vessels a run may tear (with the `Tethers` effect). Default 0.
    #[serde(default)]
    pub max_torn_vessels: u32,
}

fn default_max_penetration_mm() -> f64 {
    0.05
}

impl Default for IntegrityFile {
    fn default() -> Self {
        Self { max_penetration_mm: default_max_penetration_mm(), max_inverted_elements: 0, max_crossed_vertices: 0, max_torn_vessels: 0 }
    }
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

fn default_density() -> f64 {
    1040.0
}

/// Mesh source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum MeshSourceFile {
    /// A procedural phantom: `Phantom(preset: "paper-12k")`.
    Phantom {
        /// One of "small", "paper-9k", "paper-12k", "v-valley", "u-shape".
        preset: String,
    },
    /// A mesh file: `File(path: "brain.msh", units: Millimetres)`.
    File {
        /// Path, relative to the scenario file's folder unless absolute.
        path: String,
        /// Length unit of the file's coordinates.
        units: LengthUnit,
    },
}

/// Length unit of a mesh file's coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum LengthUnit {
    /// Coordinates in millimetres (scaled by 1e-3 on load).
    Millimetres,
    /// Coordinates in metres.
    Metres,
}

impl LengthUnit {
    /// Factor that turns the file's coordinates into metres.
    pub fn to_metres(self) -> f64 {
        match self {
            LengthUnit::Millimetres => 1e-3,
            LengthUnit::Metres => 1.0,
        }
    }
}

/// Material: `(young_modulus_pa: 3000.0, poisson_ratio: 0.45, regions: [...])`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    /// Young's modulus E, Pa, in (0, 1e9] (brain tissue: 1e2..1e4).
    pub young_modulus_pa: f64,
    /// Poisson's ratio nu, in [0, 0.5); above 0.49 a warning names volumetric
    /// locking (linear tetrahedra: forces grow without bound as nu -> 0.5).
    pub poisson_ratio: f64,
    /// Per-region overrides (region ids unique). Default empty.
    #[serde(default)]
    pub regions: Vec<RegionMaterialFile>,
}

/// A per-region material: `(id: 2, young_modulus_pa: 5000.0, poisson_ratio: 0.45)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionMaterialFile {
    /// Region id (the mesh's physical volume number).
    pub id: u32,
    /// Young's modulus E, Pa, in (0, 1e9].
    pub young_modulus_pa: f64,
    /// Poisson's ratio nu, in [0, 0.5) (a warning above 0.49, as for the default material).
    pub poisson_ratio: f64,
}

/// One fixed-node selector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum FixedFile {
    /// Every node of the tets with this region id: `RegionId(3)`.
    RegionId(u32),
    /// Nodes inside an axis-aligned box: `Box(min_mm: (..), max_mm: (..))`, min < max.
    Box {
        /// Lower corner, mm.
        min_mm: [f64; 3],
        /// Upper corner, mm.
        max_mm: [f64; 3],
    },
    /// Nodes inside a sphere: `Sphere(center_mm: (..), radius_mm: 10.0)`.
    Sphere {
        /// Centre, mm.
        center_mm: [f64; 3],
        /// Radius, mm (> 0).
        radius_mm: f64,
    },
    /// The lowest `height_mm` (along -z) of each connected component: `LowestPerComponent(height_mm: 5.0)`.
    LowestPerComponent {
        /// Height of the fixed slab above each component's lowest point, mm (> 0).
        height_mm: f64,
    },
}

/// Where the boundary is refined: `Auto`, `None` or `Some((edge_mm: .., within: [..]))`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub enum RefineChoiceFile {
    /// Where the blades reach, to a quarter of the narrowest blade's width
    /// (the default: a blade face then rests on tens of vertices on any mesh).
    #[default]
    Auto,
    /// No refinement.
    #[serde(rename = "None")]
    Off,
    /// Inside the given volumes, to the given edge length.
    #[serde(rename = "Some")]
    Given(RefineFile),
}

/// Local boundary refinement: `(edge_mm: 1.0, within: [Sphere(center_mm: (..), radius_mm: 15.0)])`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefineFile {
    /// Longest boundary edge wanted inside `within`, mm (> 0). A refinement
    /// that would more than quadruple the mesh's nodes is refused.
    pub edge_mm: f64,
    /// The volumes whose boundary edges are refined (at least one; their union).
    pub within: Vec<VolumeFile>,
}

/// A volume of space: `Box(min_mm: (..), max_mm: (..))` or `Sphere(center_mm: (..), radius_mm: ..)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum VolumeFile {
    /// An axis-aligned box, min < max.
    Box {
        /// Lower corner, mm.
        min_mm: [f64; 3],
        /// Upper corner, mm.
        max_mm: [f64; 3],
    },
    /// A sphere.
    Sphere {
        /// Centre, mm.
        center_mm: [f64; 3],
        /// Radius, mm (> 0).
        radius_mm: f64,
    },
}

/// Skull spheres: `(containing: Some((center_mm: .., radius_mm: ..)), excluding: None)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkullFile {
    /// The brain stays inside this sphere. Default `None`.
    #[serde(default)]
    pub containing: Option<SphereFile>,
    /// The brain stays outside this sphere. Default `None`.
    #[serde(default)]
    pub excluding: Option<SphereFile>,
}

/// A sphere: `(center_mm: (x, y, z), radius_mm: r)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereFile {
    /// Centre, mm.
    pub center_mm: [f64; 3],
    /// Radius, mm (> 0).
    pub radius_mm: f64,
}

/// One spatula.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpatulaFile {
    /// Unique, non-empty name ("left", "Spatula1", ...).
    pub name: String,
    /// Blade dimensions.
    pub shape: ShapeFile,
    /// Source-node layout on each large face.
    pub layout: LayoutFile,
    /// Initial pose.
    pub pose: PoseFile,
    /// What moves it.
    pub input: InputFile,
    /// Smoothing of the poses its input sends (default `Auto`).
    #[serde(default)]
    pub filter: FilterFile,
}

/// Smoothing of a spatula's input poses before the simulation plays them.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum FilterFile {
    /// The One Euro filter with its defaults for an OpenIGTLink tracker
    /// (absolute poses from a noisy pointing device: an optical tracker
    /// jitters by some 0.1-0.5 mm); none for the keyboard, the gamepad (they
    /// send velocities, integrated from the pose the blade holds, which a
    /// filter behind them would slow down) or a trajectory.
    #[default]
    Auto,
    /// The poses as they come.
    Off,
    /// `OneEuro(min_cutoff_hz: 1.0, beta_hz_per_mm_s: 0.05, d_cutoff_hz: 1.0)`:
    /// a low-pass whose cut-off is `min_cutoff_hz` for a still blade and rises
    /// by `beta_hz_per_mm_s` for each mm/s of the blade tip's speed, which is
    /// itself smoothed with `d_cutoff_hz` (Casiez et al., CHI 2012). Lower
    /// `min_cutoff_hz` steadies a still blade more and lags more; higher
    /// `beta_hz_per_mm_s` lags less in fast moves and lets more jitter through.
    OneEuro {
        /// Cut-off for a still blade, Hz (> 0; default 1).
        #[serde(default = "default_min_cutoff_hz")]
        min_cutoff_hz: f64,
        /// Added cut-off per mm/s of tip speed, Hz (>= 0; default 0.05).
        #[serde(default = "default_beta_hz_per_mm_s")]
        beta_hz_per_mm_s: f64,
        /// Cut-off of the speed estimate, Hz (> 0; default 1).
        #[serde(default = "default_d_cutoff_hz")]
        d_cutoff_hz: f64,
    },
}

fn default_min_cutoff_hz() -> f64 {
    1.0
}
fn default_beta_hz_per_mm_s() -> f64 {
    0.05
}
fn default_d_cutoff_hz() -> f64 {
    1.0
}

impl FilterFile {
    /// The One Euro filter's defaults (what `Auto` gives a tracker or a gamepad).
    pub fn one_euro_defaults() -> Self {
        FilterFile::OneEuro { min_cutoff_hz: default_min_cutoff_hz(), beta_hz_per_mm_s: default_beta_hz_per_mm_s(), d_cutoff_hz: default_d_cutoff_hz() }
    }
}

/// Blade dimensions: `(length_mm: 60.0, width_mm: 8.0, thickness_mm: 0.5)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeFile {
    /// Length along the blade (x), mm (> 0).
    pub length_mm: f64,
    /// Width across the blade (y), mm (> 0).
    pub width_mm: f64,
    /// Thickness (z), mm (> 0).
    pub thickness_mm: f64,
}

/// Source-node layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum LayoutFile {
    /// `Grid(along: 15, across: 10)`: along >= 1, across >= 1 nodes a face.
    Grid {
        /// Nodes along the blade (>= 1).
        along: u32,
        /// Nodes across the blade (>= 1).
        across: u32,
    },
    /// `TipConcentrated(count: 30, tip_fraction: 0.3)`: count >= 1, fraction in (0, 1].
    TipConcentrated {
        /// Nodes a face (>= 1).
        count: u32,
        /// Part of the blade length, from the tip, that holds the nodes, in (0, 1].
        tip_fraction: f64,
    },
    /// `Explicit([(x_mm, y_mm), ...])`: positions in the spatula frame, mm,
    /// 0 <= x <= length, |y| <= width / 2; at least one.
    Explicit(Vec<[f64; 2]>),
}

/// Initial pose: `(position_mm: (x, y, z), rotation: AxisAngle(axis: (0, 0, 1), angle_deg: 90))`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseFile {
    /// Origin of the spatula frame (handle end of the blade's centre line), mm.
    pub position_mm: [f64; 3],
    /// Orientation of the spatula frame.
    pub rotation: RotationFile,
}

/// An orientation, three ways.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum RotationFile {
    /// Rotation by `angle_deg` about `axis` (non-zero; normalised).
    AxisAngle {
        /// Axis, any non-zero length.
        axis: [f64; 3],
        /// Angle, degrees (finite).
        angle_deg: f64,
    },
    /// A unit quaternion `Quaternion(w, x, y, z)` (norm within 1e-4 of 1; normalised).
    Quaternion(f64, f64, f64, f64),
    /// The blade (spatula x) points along `direction`; the face normal (+z) is the
    /// part of `up` perpendicular to it. Both non-zero and not parallel.
    LookAt {
        /// Blade direction, any non-zero length.
        direction: [f64; 3],
        /// Approximate +z (face normal) direction.
        up: [f64; 3],
    },
}

/// What drives a spatula.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum InputFile {
    /// Keyboard and mouse.
    Keyboard,
    /// A gamepad (gilrs).
    Gamepad,
    /// A 3Dconnexion SpaceMouse (spacenavd, else its HID device): the cap's
    /// pushes and turns are the blade's rates; tuned by the scene's `spacemouse`.
    SpaceMouse,
    /// An OpenIGTLink TRANSFORM stream from the named device. A pose outside
    /// the workspace or faster than the speed limit is refused (counted, logged;
    /// the last good pose holds).
    OpenIgtLink {
        /// Device name in the OpenIGTLink messages (non-empty), e.g. "Spatula1".
        device: String,
        /// Half-width of the workspace box around the scene origin on each axis,
        /// mm (finite, > 0; default 1000).
        #[serde(default = "default_igtl_workspace_mm")]
        workspace_mm: f64,
        /// Fastest credible move between two accepted poses, mm/s (finite, > 0;
        /// default 3000).
        #[serde(default = "default_igtl_max_speed_mm_s")]
        max_speed_mm_s: f64,
        /// `host:port` of a server to read the device from, fissure connecting
        /// as a client (a PlusServer: `"127.0.0.1:18944"`), reconnecting with
        /// backoff. Default `None`: the device sends to fissure's server.
        #[serde(default)]
        connect: Option<String>,
        /// The poses move the blade relatively, by scale, frame and clutch (a
        /// stylus). Default `None`: each pose is the blade's, in the scene.
        #[serde(default)]
        mapping: Option<super::devices::StylusMappingFile>,
        /// Also send the force on the blade as PLUS's OpenHaptics device takes it.
        /// Default `None`: only `SENSOR Force_<spatula>`.
        #[serde(default)]
        force: Option<super::devices::ForceTransformFile>,
    },
    /// The scenario's recorded `trajectory` (which must then be given).
    Trajectory,
}

/// The stages a scene can ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Effect {
    /// Spatula–surface collision by rays (the paper's method).
    Collision,
    /// His-flag culling of infeasible pairs (needs `Collision`).
    Culling,
    /// Unilateral skull-sphere constraints (needs `skull`).
    SkullSpheres,
    /// Body force of gravity (uses `gravity_m_s2`, `density_kg_m3`).
    Gravity,
    /// Reaction force per spatula (haptic output).
    ForceOutput,
    /// Per-element stress and strain (costs an interior solve when read).
    StressField,
    /// Contact (retraction) pressure per spatula (needs `Collision`).
    ContactPressure,
    /// Vessels and arachnoid bands that tie the tissue and tear (needs `tethers`).
    Tethers,
    /// The tissue's stress relaxes while a blade holds (forces, pressures and tether pulls; `relaxation`).
    Relaxation,
    /// Injury from retractor pressure over time, per surface vertex (needs `Collision`; `ischemia`).
    Ischemia,
}

/// Collision options: `(backend: Bvh)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionFile {
    /// Which backend answers the ray queries. Default `Bvh`.
    #[serde(default)]
    pub backend: CollisionBackend,
    /// Our swept-side culling on top of the paper's His-flags (needs `Culling`):
    /// a face never pulls tissue that lay beyond the blade's other face at the
    /// previous frame. Default `true`; `false` leaves exactly the paper's method.
    #[serde(default = "default_true")]
    pub swept_culling: bool,
}

fn default_igtl_workspace_mm() -> f64 {
    1000.0
}

fn default_igtl_max_speed_mm_s() -> f64 {
    3000.0
}

fn default_true() -> bool {
    true
}

impl Default for CollisionFile {
    fn default() -> Self {
        Self { backend: CollisionBackend::Bvh, swept_culling: true }
    }
}

/// Collision backends (all give the same answers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum CollisionBackend {
    /// Brute-force Möller–Trumbore on the CPU (the reference).
    Reference,
    /// Bounding-volume hierarchy on the CPU.
    #[default]
    Bvh,
    /// Our BVH on the GPU (wgpu compute), answers decided in f64: the same as `Bvh`.
    Gpu,
    /// Time `Bvh` and `Gpu` on the first frames and keep the faster (the summary
    /// and the stage's warnings say which); `Bvh` when there is no GPU.
    Auto,
}

/// Solver options.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverFile {
    /// Storage of the precomputed surface compliance. Default `F64`.
    #[serde(default)]
    pub compliance_storage: ComplianceStorage,
    /// Which surface vertices get precomputed compliance. Default `Auto`.
    #[serde(default)]
    pub region_of_interest: RegionOfInterestFile,
    /// Folder for the compliance cache (relative to the working directory); `None`: no cache.
    #[serde(default)]
    pub cache_dir: Option<String>,
    /// How a spatula holds the tissue it claims. Default `Unilateral`.
    #[serde(default)]
    pub spatula_contact: SpatulaContact,
    /// Largest blade travel of one sub-step, in blade thicknesses (0.01..=10):
    /// a frame whose blade moves farther is split into sub-steps, so a fast
    /// tool gives what the same motion sampled finely gives. `None`: one step a
    /// frame however far the blade moves (the paper's method; fast tools can
    /// then pull tissue through a blade). Default `Some(0.125)` (measured:
    /// the default scene's motion gives the same forces within 1 % at any speed).
    #[serde(default = "default_substep_travel")]
    pub substep_travel: Option<f64>,
    /// Whether a blade's own sample jitter counts as travel for the
    /// sub-steps. Default `Discount`.
    #[serde(default)]
    pub substep_jitter: SubstepJitter,
    /// Order the compliance columns (dense storage) by how soon a blade
    /// reaches them, so that the window shows the scene and runs its frames
    /// while the rest are computed in the background, from when the rest is
    /// predicted to keep ahead of the blades; a frame that needs a column not
    /// yet computed waits for it. Replays, benches and the study
    /// compute every column first. The answers do not depend on when a column
    /// became final; the order is part of the cache key. Default `false`.
    #[serde(default)]
    pub early_start: bool,
    /// The working region, mm: surface vertices within this distance of the
    /// region of interest (at rest) get compliance rows, as do those within
    /// 15 mm of a skull sphere; every frame reads and moves them exactly.
    /// The rest of the surface moves only as far as the picture needs: a
    /// sparse solve brings it up to date for the final state, PNG frames
    /// and the window's display, and a blade that comes within 10 mm of a
    /// vertex outside brings it up to date every sub-step. `None`: every
    /// surface vertex gets a row. Default `Some(10.0)`
    /// ([`DEFAULT_ROW_BAND_MM`]).
    #[serde(default = "default_row_band_mm")]
    pub row_band_mm: Option<f64>,
}

fn default_substep_travel() -> Option<f64> {
    Some(0.125)
}

/// `solver.row_band_mm`'s default: the working region reaches this far (mm) beyond the region of interest.
pub const DEFAULT_ROW_BAND_MM: f64 = 10.0;

fn default_row_band_mm() -> Option<f64> {
    Some(DEFAULT_ROW_BAND_MM)
}

impl Default for SolverFile {
    fn default() -> Self {
        Self {
            compliance_storage: ComplianceStorage::default(),
            region_of_interest: RegionOfInterestFile::default(),
            cache_dir: None,
            spatula_contact: SpatulaContact::default(),
            substep_travel: default_substep_travel(),
            substep_jitter: SubstepJitter::default(),
            early_start: false,
            row_band_mm: default_row_band_mm(),
        }
    }
}

/// Whether a blade's sample jitter counts as travel for the sub-steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum SubstepJitter {
    /// A frame's travel counts only beyond the blade's jitter: the median, over
    /// the last 16 frames, of its footprint corners' second differences
    /// (`sim::substeps`). Smooth motion has none, so its sub-steps are those of
    /// `Follow` exactly; a tracker's noise is taken in one step a frame. The default.
    #[default]
    Discount,
    /// Every travel counts, noise too: each jitter is followed in sub-steps.
    Follow,
}

/// How a spatula holds the tissue it claims.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum SpatulaContact {
    /// Every claimed vertex is held at its target (the paper's enforced
    /// displacement): a retreating face can pull its tissue after it.
    Bilateral,
    /// A held vertex sticks while the face pushes it; a hold that would pull is
    /// released (or slides on the face): no adhesion. Every unclaimed vertex near
    /// a blade gets a non-penetration row on the face it lies in front of
    /// (`sim::barrier`), so released tissue never passes a blade. Which
    /// vertices stick depends on where the rays land.
    Unilateral,
    /// Frictionless sliding: every vertex under a blade, claimed by a ray or
    /// not, is only kept in front of the face (pushed along its normal, free
    /// along it), so which vertices the rays claim does not change the law.
    /// Wet brain on metal is nearly frictionless (porcine brain against metal
    /// with saline: mu 0.09 +- 0.03 at a strain rate of 1/s; Rashid,
    /// Destrade and Gilchrist 2013, arXiv:1303.0048). The default.
    #[default]
    Sliding,
}

/// Number format of the stored compliance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ComplianceStorage {
    /// f64 (exact path, 1e-8 relative to the direct solve).
    #[default]
    F64,
    /// f32 (half the memory; the solver states its measured error).
    F32,
}

/// Region of interest for the precomputed compliance.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum RegionOfInterestFile {
    /// Chosen by the solver: the spatulas' reach, plus the vertices near a skull sphere at rest.
    #[default]
    Auto,
    /// Every surface vertex.
    All,
    /// Surface vertices inside a sphere: `Sphere(center_mm: (..), radius_mm: r)`.
    Sphere {
        /// Centre, mm.
        center_mm: [f64; 3],
        /// Radius, mm (> 0).
        radius_mm: f64,
    },
}

/// Outputs: `(dir: "out/sylvian", vtk: false, frames: false)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputsFile {
    /// Output folder (relative to the working directory). Default "out".
    #[serde(default = "default_out_dir")]
    pub dir: String,
    /// Write a `.pvd` + `.vtu` series. Default false.
    #[serde(default)]
    pub vtk: bool,
    /// Write PNG frames (needs the renderer). Default false.
    #[serde(default)]
    pub frames: bool,
    /// Folder for the window's recordings (key R), relative to the working
    /// directory; `--record-dir` wins over it. Default `None`: the user's data
    /// directory (`$XDG_DATA_HOME/fissure/recordings` on Linux).
    #[serde(default)]
    pub record_dir: Option<String>,
}

/// Display options: `(pressure_max_mmhg: 30.0)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DisplayFile {
    /// Top of the contact-pressure colour bar, mmHg, in [1, 1000]. Default 30
    /// (a real retraction's 6-12 mmHg shows; the 20 mmHg line is marked).
    #[serde(default = "default_pressure_max_mmhg")]
    pub pressure_max_mmhg: f64,
    /// The overview camera (key `O`). Default `None`: framed from the mesh and the blades.
    #[serde(default)]
    pub overview: Option<ViewFile>,
    /// The microscope camera (key `M`). Default `None`: down the blades'
    /// insertion direction at their tips, from behind the handles.
    #[serde(default)]
    pub microscope: Option<ViewFile>,
}

/// A named camera: `(eye_mm: (x, y, z), target_mm: (x, y, z), fov_deg: 25.0)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewFile {
    /// Where the eye is, mm.
    pub eye_mm: [f64; 3],
    /// What it looks at (the orbit centre), mm; not the eye.
    pub target_mm: [f64; 3],
    /// Vertical field of view, degrees, in [5, 120]. Default 25 (a microscope's).
    #[serde(default = "default_fov_deg")]
    pub fov_deg: f64,
}

fn default_fov_deg() -> f64 {
    25.0
}

/// `render::legend::DEFAULT_PRESSURE_MAX_MMHG` (the scenario core does not
/// import the renderer; a test there holds the two equal).
fn default_pressure_max_mmhg() -> f64 {
    30.0
}

impl Default for DisplayFile {
    fn default() -> Self {
        Self { pressure_max_mmhg: default_pressure_max_mmhg(), overview: None, microscope: None }
    }
}

fn default_out_dir() -> String {
    "out".to_string()
}

impl Default for OutputsFile {
    fn default() -> Self {
        Self { dir: default_out_dir(), vtk: false, frames: false, record_dir: None }
    }
}
