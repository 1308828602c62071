//! Validation: a [`ScenarioFile`] (human units, unchecked) becomes a [`Scenario`]
//! (SI units, every range and cross-field rule checked).
//!
//! In: the parsed file and its [`Document`] (for positions). Out: a [`Scenario`]
//! the pipeline reads directly, or the first [`ScenarioError::Invalid`] in file
//! order of checks, naming file, line, column and field path; values that are
//! legal but doubtful (nu near 0.5) become [`ScenarioWarning`]s in
//! [`Scenario::warnings`]. Stays true for a validated scenario: every number is
//! finite; lengths, radii and steps are positive; E in (0, 1e9] Pa, nu in
//! [0, 0.5), density in (0, 1e5] kg/m^3, at least 10 steps a run; poses are
//! unit; input files exist and the trajectory has no track for a spatula the
//! scene lacks; each effect's prerequisites are present. What needs the mesh or
//! the trajectory that will play (fixed nodes, skull against the brain, blade
//! travel a step) is checked by `sim::preflight`, with the positions kept in
//! [`Scenario::locations`].

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Rotation3, Unit};

use super::error::{FieldLocations, Location, ScenarioError, ScenarioWarning};
use super::file::{
    CollisionBackend, ComplianceStorage, DisplayFile, Effect, FilterFile, FixedFile, IntegrityFile, RefineChoiceFile, InputFile, LayoutFile,
    LengthUnit, MaterialFile, MeshSourceFile, OutputsFile, RegionOfInterestFile, RotationFile, ScenarioFile, SkullFile, SolverFile, SphereFile,
    SpatulaContact, SpatulaFile, SubstepJitter, VolumeFile,
};
use super::overrides::Document;
use super::trajectory::Trajectory;
use crate::geometry::{NodeLayout, Pose, SpatulaShape};
use crate::math::{Quat, Vec3};
use crate::mesh::phantom::Preset;

/// Most source nodes a layout may put on one face.
pub const MAX_NODES_PER_FACE: u64 = 1_000_000;

/// Most spatulas a scene may have (the collision stage numbers them in a byte).
pub const MAX_SPATULAS: usize = 255;

/// Largest Young's modulus accepted, Pa. Brain tissue is 1e2..1e4 Pa; 1e9 Pa
/// is already stiffer than cartilage, and beyond it the stiffness entries
/// (E / h^2 on millimetre elements) leave the range where the solve is exact.
pub const MAX_YOUNG_MODULUS_PA: f64 = 1e9;

/// Poisson's ratio above which a warning names volumetric locking: linear
/// tetrahedra lock as nu -> 0.5 (the bulk modulus grows without bound, so do
/// the forces for a given displacement).
pub const LOCKING_POISSON_RATIO: f64 = 0.49;

/// Largest density accepted, kg/m^3 (osmium is 22,600).
pub const MAX_DENSITY_KG_M3: f64 = 1e5;

/// A run has at least this many steps: `time_step_s <= duration_s / MIN_STEPS`.
pub const MIN_STEPS: f64 = 10.0;

const MM: f64 = 1e-3;

/// Where the brain mesh comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshSource {
    /// A procedural phantom, by preset name (checked: it parses as a
    /// [`Preset`]; kept as the name the file gave).
    Phantom {
        /// The preset name ("small", "paper-9k", "paper-12k", "v-valley", "u-shape").
        preset: String,
    },
    /// A mesh file.
    File {
        /// Path resolved against the scenario file's folder (exists at validation).
        path: PathBuf,
        /// Unit of the file's coordinates.
        units: LengthUnit,
    },
}

/// Isotropic linear elastic material, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Young's modulus, Pa, in (0, 1e9].
    pub young_modulus: f64,
    /// Poisson's ratio, in [0, 0.5).
    pub poisson_ratio: f64,
}

/// A material for one region id.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionMaterial {
    /// Region id (Gmsh physical volume).
    pub region: u32,
    /// Its material.
    pub material: Material,
}

/// A sphere, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre, m.
    pub center: Vec3,
    /// Radius, m (> 0).
    pub radius: f64,
}

/// A fixed-node selector, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FixedRegion {
    /// Every node of the tets with this region id.
    RegionId(u32),
    /// Nodes inside the box (min < max componentwise), m.
    Box { min: Vec3, max: Vec3 },
    /// Nodes inside the sphere.
    Sphere(Sphere),
    /// Nodes within `height` (m, > 0) above the lowest point (min z) of their connected component.
    LowestPerComponent { height: f64 },
}

/// A volume of space, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Volume {
    /// An axis-aligned box (min < max componentwise), m.
    Box { min: Vec3, max: Vec3 },
    /// A sphere.
    Sphere(Sphere),
}

impl Volume {
    /// True when `p` (m) is inside or on the boundary.
    pub fn contains(&self, p: &Vec3) -> bool {
        match self {
            Volume::Box { min, max } => (0..3).all(|k| p[k] >= min[k] && p[k] <= max[k]),
            Volume::Sphere(s) => (p - s.center).norm() <= s.radius,
        }
    }
}

/// Local boundary refinement (see [`crate::mesh::refine`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Refinement {
    /// Longest boundary edge wanted inside `within`, m (> 0).
    pub edge: f64,
    /// The volumes (non-empty; their union).
    pub within: Vec<Volume>,
}

/// Where the mesh's boundary is refined (see [`crate::scenario::file::RefineChoiceFile`]).
#[derive(Debug, Clone, PartialEq)]
pub enum RefineChoice {
    /// The mesh as it is.
    Off,
    /// Where the blades reach (along the scenario's trajectory, else in its
    /// region-of-interest sphere, else from their first poses), to a quarter
    /// of the narrowest blade's width.
    Auto,
    /// The given volumes and edge length.
    Given(Refinement),
}

/// Skull spheres (at least one present).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Skull {
    /// The brain stays inside.
    pub containing: Option<Sphere>,
    /// The brain stays outside.
    pub excluding: Option<Sphere>,
}

/// What drives a spatula.
#[derive(Debug, Clone, PartialEq)]
pub enum InputBinding {
    /// Keyboard and mouse.
    Keyboard,
    /// A gamepad.
    Gamepad,
    /// OpenIGTLink TRANSFORM messages from this device name (non-empty, at
    /// most 20 bytes); poses outside the workspace box (half-width
    /// `workspace_m` on each axis around the scene origin, m, > 0) or faster
    /// than `max_speed_m_s` (m/s, > 0) are refused; `link` says where they come
    /// from, how a stylus maps to the blade and how the force goes back.
    OpenIgtLink { device: String, workspace_m: f64, max_speed_m_s: f64, link: super::devices::IgtlLink },
    /// A SpaceMouse, tuned by [`Scenario::spacemouse`].
    SpaceMouse,
    /// The scenario's trajectory, track = this spatula's index.
    Trajectory,
}

impl std::fmt::Display for InputBinding {
    /// A line for `fissure check`: `OpenIgtLink "StylusToBase" from 127.0.0.1:18944,
    /// mapped at scale 0.5 (clutch: ButtonsToBase button 1), force back as ForceToBase`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InputBinding::OpenIgtLink { device, workspace_m, max_speed_m_s, link } => {
                write!(f, "OpenIgtLink \"{device}\"")?;
                if let Some(address) = &link.connect {
                    write!(f, " from {address}")?;
                }
                write!(f, " (within {} mm, at most {} mm/s)", number(workspace_m / MM), number(max_speed_m_s / MM))?;
                if let Some(m) = &link.mapping {
                    write!(f, ", mapped at scale {} turned by {:.1} degrees", number(m.scale), m.rotation.angle().to_degrees())?;
                    if let Some((d, b)) = &m.clutch {
                        write!(f, " (clutch: {d} button {b})")?;
                    }
                }
                if let Some(o) = &link.force {
                    write!(f, ", force back as {} (x{}, at most {} N, {} Hz)", o.name, number(o.scale), number(o.max_force_n), number(o.rate_hz))?;
                }
                Ok(())
            }
            other => write!(f, "{other:?}"),
        }
    }
}

/// One spatula, SI.
#[derive(Debug, Clone, PartialEq)]
pub struct SpatulaConfig {
    /// Unique name.
    pub name: String,
    /// Blade dimensions, m.
    pub shape: SpatulaShape,
    /// Source-node layout (explicit positions in m).
    pub layout: NodeLayout,
    /// Pose at time 0.
    pub initial_pose: Pose,
    /// What moves it.
    pub input: InputBinding,
    /// The smoothing of its input poses (`None`: the poses as they come).
    pub filter: Option<OneEuro>,
}

/// The One Euro filter's parameters, SI (see [`crate::scenario::file::FilterFile`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneEuro {
    /// Cut-off for a still blade, Hz (> 0).
    pub min_cutoff_hz: f64,
    /// Added cut-off per m/s of the blade tip's speed, Hz / (m/s) = 1/m (>= 0).
    pub beta_per_m: f64,
    /// Cut-off of the speed estimate, Hz (> 0).
    pub d_cutoff_hz: f64,
}

/// The set of effects a scene asked for; iteration in [`Effect::ALL`] order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EffectSet(u16);

impl Effect {
    /// Every effect, in the fixed order used for iteration and display.
    pub const ALL: [Effect; 10] = [
        Effect::Collision,
        Effect::Culling,
        Effect::SkullSpheres,
        Effect::Gravity,
        Effect::ForceOutput,
        Effect::StressField,
        Effect::ContactPressure,
        Effect::Tethers,
        Effect::Relaxation,
        Effect::Ischemia,
    ];

    fn bit(self) -> u16 {
        1 << (self as u16)
    }
}

impl EffectSet {
    /// True when the scene asked for `effect`.
    pub fn contains(&self, effect: Effect) -> bool {
        self.0 & effect.bit() != 0
    }

    /// Adds an effect; false when it was already there.
    pub fn insert(&mut self, effect: Effect) -> bool {
        let had = self.contains(effect);
        self.0 |= effect.bit();
        !had
    }

    /// The effects in [`Effect::ALL`] order.
    pub fn iter(&self) -> impl Iterator<Item = Effect> + '_ {
        Effect::ALL.into_iter().filter(|e| self.contains(*e))
    }

    /// Number of effects.
    pub fn len(&self) -> usize {
        self.0.count_ones() as usize
    }

    /// True when no effect is asked for.
    pub fn is_empty(&self) -> bool {
        self.0 == 0
    }
}

/// Region of interest for the precomputed compliance, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RegionOfInterest {
    /// Chosen by the solver: the spatulas' reach, plus the vertices near a skull sphere at rest.
    Auto,
    /// Every surface vertex.
    All,
    /// Surface vertices inside the sphere.
    Sphere(Sphere),
}

/// Solver options.
#[derive(Debug, Clone, PartialEq)]
pub struct SolverOptions {
    /// Storage of the surface compliance.
    pub compliance_storage: ComplianceStorage,
    /// Which surface vertices get precomputed compliance.
    pub region_of_interest: RegionOfInterest,
    /// Compliance cache folder (as written: relative to the working directory); `None`: no cache.
    pub cache_dir: Option<PathBuf>,
    /// How a spatula holds the tissue it claims.
    pub spatula_contact: SpatulaContact,
    /// Largest blade travel of one sub-step, in blade thicknesses; `None`: one step a frame.
    pub substep_travel: Option<f64>,
    /// Whether a blade's sample jitter counts as travel for the sub-steps.
    pub substep_jitter: SubstepJitter,
    /// Compliance columns ordered by the blades' reach; the window starts before they are all computed.
    pub early_start: bool,
    /// Surface vertices within this distance (m) of the region of interest
    /// get compliance rows (the working region); `None`: every surface vertex.
    pub row_band: Option<f64>,
}

/// Output options.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outputs {
    /// Output folder (as written: relative to the working directory).
    pub dir: PathBuf,
    /// Write a VTK series.
    pub vtk: bool,
    /// Write PNG frames.
    pub frames: bool,
    /// The window's recordings folder (as written), `None`: the user's data directory.
    pub record_dir: Option<PathBuf>,
}

/// How fields are shown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Display {
    /// Top of the contact-pressure colour bar, mmHg, in [1, 1000].
    pub pressure_max_mmhg: f64,
    /// The scene's own cameras (`None`: computed from the mesh and the blades).
    pub views: Views,
}

/// Cameras a scenario names.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Views {
    pub overview: Option<NamedView>,
    pub microscope: Option<NamedView>,
}

/// A camera from a scenario: eye and target (m, distinct), vertical field of view (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NamedView {
    pub eye: Vec3,
    pub target: Vec3,
    pub fov_y_rad: f64,
}

/// Pass/fail limits on what a run may do to the tissue (scenario `integrity`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IntegrityLimits {
    /// Deepest a surface vertex may end a frame inside a blade, mm.
    pub max_penetration_mm: f64,
    /// Most inverted elements in a frame (in the frame's scope: all tets with the
    /// stress stage, surface tets otherwise).
    pub max_inverted_elements: u32,
    /// Most surface vertices pulled through a blade in a frame.
    pub max_crossed_vertices: u32,
    /// Most vessels a run may tear (the `Tethers` effect).
    pub max_torn_vessels: u32,
}

impl Default for IntegrityLimits {
    /// 0.05 mm of penetration (a tenth of the thinnest shipped blade's half
    /// thickness: what a surgeon cannot see), no inverted element, no tunnelling.
    fn default() -> Self {
        Self { max_penetration_mm: 0.05, max_inverted_elements: 0, max_crossed_vertices: 0, max_torn_vessels: 0 }
    }
}

/// A validated scenario in SI units: what the pipeline reads.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Scene name.
    pub name: String,
    /// The scenario file (as given; for messages and relative paths).
    pub source_path: PathBuf,
    /// Mesh source.
    pub mesh: MeshSource,
    /// Local refinement of the mesh's boundary, when asked for.
    pub refine: RefineChoice,
    /// The tissue's material and its body force.
    pub body: Body,
    /// Fixed-node selectors (non-empty; their union is fixed).
    pub fixed: Vec<FixedRegion>,
    /// Skull spheres, when given.
    pub skull: Option<Skull>,
    /// Spatulas (at least one), in file order: spatula index = position here.
    pub spatulas: Vec<SpatulaConfig>,
    /// The stages the scene asked for.
    pub effects: EffectSet,
    /// The collision backend and its culling.
    pub collision: CollisionOptions,
    /// Solver options.
    pub solver: SolverOptions,
    /// Fixed time step, s (> 0, <= duration / 10).
    pub time_step: f64,
    /// Headless run length, s (> 0).
    pub duration: f64,
    /// Recorded trajectory, resolved against the scenario's folder (exists and parses at validation).
    pub trajectory: Option<PathBuf>,
    /// What a run writes and the limits of its integrity verdict.
    pub run: RunOutputs,
    /// Display options.
    pub display: Display,
    /// Vessels and arachnoid bands (empty unless the scene has the `Tethers` effect).
    pub tethers: super::tethers::Tethers,
    /// Tissue over time: relaxation and ischemia.
    pub tissue_time: TissueTime,
    /// The input devices' settings.
    pub devices: DeviceSettings,
    /// What validation found: warnings and where the fields are.
    pub checks: Checks,
}

/// The tissue's material and the body force on it.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Material of every region without an override.
    pub material: Material,
    /// Per-region overrides, sorted by region id, ids unique.
    pub region_materials: Vec<RegionMaterial>,
    /// Gravity, m/s^2 (finite).
    pub gravity: Vec3,
    /// Density, kg/m^3, in (0, 1e5].
    pub density: f64,
}

/// The collision stage's backend and culling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionOptions {
    /// Collision backend.
    pub backend: CollisionBackend,
    /// Swept-side culling on top of the paper's His-flags (see `collision` docs, rule 3b).
    pub swept_culling: bool,
}

/// What a run writes, and the limits its integrity verdict holds it to.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutputs {
    /// Outputs.
    pub outputs: Outputs,
    /// Pass/fail limits of the run's integrity verdict.
    pub integrity: IntegrityLimits,
}

/// The tissue over time (each with its effect only).
#[derive(Debug, Clone, PartialEq)]
pub struct TissueTime {
    /// The relaxation function, with the `Relaxation` effect only.
    pub relaxation: Option<super::tissue_time::Relaxation>,
    /// The ischemia model, with the `Ischemia` effect only.
    pub ischemia: Option<super::tissue_time::Ischemia>,
}

/// The input devices' settings.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceSettings {
    /// Where fissure's OpenIGTLink server listens (`openigtlink.listen`).
    pub igtl_listen: std::net::SocketAddr,
    /// The SpaceMouse's tuning (`spacemouse`).
    pub spacemouse: super::devices::SpaceMouseSettings,
}

/// What validation found beside errors.
#[derive(Debug, Clone, PartialEq)]
pub struct Checks {
    /// Legal but doubtful values, in the order found (`fissure check` prints
    /// them; the pipeline's build logs them).
    pub warnings: Vec<ScenarioWarning>,
    /// Where the fields that later checks name are (`mesh`, `fixed[i]`,
    /// `skull.containing`, `skull.excluding`, `time_step_s`, `trajectory`, ...).
    pub locations: FieldLocations,
}

/// Fields whose positions [`Scenario::locations`] keeps (plus `fixed[i]` and `spatulas[i]`).
const LOCATED_FIELDS: [&str; 9] =
    ["mesh", "mesh.path", "refine", "fixed", "skull.containing", "skull.excluding", "time_step_s", "trajectory", "spatulas"];

struct Checker<'d> {
    doc: &'d Document,
    base: PathBuf,
    warnings: std::cell::RefCell<Vec<ScenarioWarning>>,
}

impl Checker<'_> {
    fn invalid(&self, field: &str, problem: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid { location: self.doc.locate_path(field), field: field.to_string(), problem: problem.into() }
    }

    fn warn(&self, field: &str, message: impl Into<String>) {
        let w = ScenarioWarning { location: self.doc.locate_path(field), field: field.to_string(), message: message.into() };
        self.warnings.borrow_mut().push(w);
    }

    fn finite(&self, field: &str, v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() { Ok(v) } else { Err(self.invalid(field, format!("must be a finite number, got {v}"))) }
    }

    fn positive(&self, field: &str, v: f64) -> Result<f64, ScenarioError> {
        self.finite(field, v)?;
        if v > 0.0 { Ok(v) } else { Err(self.invalid(field, format!("must be > 0, got {v}"))) }
    }

    fn vec3(&self, field: &str, v: [f64; 3]) -> Result<Vec3, ScenarioError> {
        for (i, c) in v.iter().enumerate() {
            self.finite(&format!("{field}[{i}]"), *c)?;
        }
        Ok(Vec3::new(v[0], v[1], v[2]))
    }

    fn vec_mm(&self, field: &str, v: [f64; 3]) -> Result<Vec3, ScenarioError> {
        Ok(self.vec3(field, v)? * MM)
    }

    fn view(&self, field: &str, v: Option<super::file::ViewFile>) -> Result<Option<NamedView>, ScenarioError> {
        let Some(v) = v else { return Ok(None) };
        let eye = self.vec_mm(&format!("{field}.eye_mm"), v.eye_mm)?;
        let target = self.vec_mm(&format!("{field}.target_mm"), v.target_mm)?;
        if (eye - target).norm() < 1e-3 {
            return Err(self.invalid(field, "eye_mm and target_mm must be at least 1 mm apart (the camera looks from the eye to the target)"));
        }
        let fov = self.finite(&format!("{field}.fov_deg"), v.fov_deg)?;
        if !(5.0..=120.0).contains(&fov) {
            return Err(self.invalid(&format!("{field}.fov_deg"), format!("must be in [5, 120] degrees, got {}", number(fov))));
        }
        Ok(Some(NamedView { eye, target, fov_y_rad: fov.to_radians() }))
    }

    fn material(&self, field: &str, young_modulus_pa: f64, poisson_ratio: f64) -> Result<Material, ScenarioError> {
        let e_field = format!("{field}.young_modulus_pa");
        let young_modulus = self.finite(&e_field, young_modulus_pa)?;
        if !(young_modulus > 0.0 && young_modulus <= MAX_YOUNG_MODULUS_PA) {
            return Err(self.invalid(&e_field, format!(
                "young_modulus_pa must be in (0, {MAX_YOUNG_MODULUS_PA:e}] Pa (brain tissue: 1e2..1e4), got {}",
                number(young_modulus)
            )));
        }
        let nu_field = format!("{field}.poisson_ratio");
        let nu = self.finite(&nu_field, poisson_ratio)?;
        if !(0.0..0.5).contains(&nu) {
            return Err(self.invalid(&nu_field, format!("poisson_ratio must be in [0, 0.5), got {nu}")));
        }
        if nu > LOCKING_POISSON_RATIO {
            self.warn(&nu_field, format!(
                "poisson_ratio {nu} is above {LOCKING_POISSON_RATIO}: linear tetrahedra lock volumetrically as nu -> 0.5 \
                 (the bulk modulus E / (3 (1 - 2 nu)) = {:.3e} Pa grows without bound, and so do the forces for a given \
                 displacement); 0.45 is the usual value for brain tissue",
                young_modulus / (3.0 * (1.0 - 2.0 * nu))
            ));
        }
        Ok(Material { young_modulus, poisson_ratio: nu })
    }

    /// An axis-aligned box `field.min_mm` .. `field.max_mm` in metres, min < max in every component.
    fn box_mm(&self, field: &str, min_mm: [f64; 3], max_mm: [f64; 3]) -> Result<(Vec3, Vec3), ScenarioError> {
        let min = self.vec_mm(&format!("{field}.min_mm"), min_mm)?;
        let max = self.vec_mm(&format!("{field}.max_mm"), max_mm)?;
        if (0..3).any(|k| min[k] >= max[k]) {
            return Err(self.invalid(&format!("{field}.max_mm"), format!("must exceed min_mm in every component: min {min_mm:?}, max {max_mm:?}")));
        }
        Ok((min, max))
    }

    fn sphere(&self, field: &str, s: &SphereFile) -> Result<Sphere, ScenarioError> {
        let center = self.vec_mm(&format!("{field}.center_mm"), s.center_mm)?;
        let radius = self.positive(&format!("{field}.radius_mm"), s.radius_mm)? * MM;
        Ok(Sphere { center, radius })
    }

    fn existing_file(&self, field: &str, written: &str) -> Result<PathBuf, ScenarioError> {
        if written.trim().is_empty() {
            return Err(self.invalid(field, "the path is empty"));
        }
        let path = self.base.join(written);
        if !path.is_file() {
            return Err(self.invalid(field, format!("file not found: {} (relative paths resolve against the scenario's folder)", path.display())));
        }
        Ok(path)
    }

    fn rotation(&self, field: &str, r: &RotationFile) -> Result<Quat, ScenarioError> {
        match r {
            RotationFile::AxisAngle { axis, angle_deg } => {
                let f = format!("{field}.axis");
                let a = self.vec3(&f, *axis)?;
                if a.norm() < 1e-12 {
                    return Err(self.invalid(&f, "the axis must be non-zero"));
                }
                let angle = self.finite(&format!("{field}.angle_deg"), *angle_deg)?;
                Ok(Quat::from_axis_angle(&Unit::new_normalize(a), angle.to_radians()))
            }
            RotationFile::Quaternion(w, x, y, z) => {
                for (i, c) in [w, x, y, z].into_iter().enumerate() {
                    self.finite(&format!("{field}[{i}]"), *c)?;
                }
                let q = nalgebra::Quaternion::new(*w, *x, *y, *z);
                if (q.norm() - 1.0).abs() > 1e-4 {
                    return Err(self.invalid(field, format!("the quaternion must be unit (norm within 1e-4 of 1), its norm is {}", q.norm())));
                }
                Ok(Quat::new_normalize(q))
            }
            RotationFile::LookAt { direction, up } => {
                let fd = format!("{field}.direction");
                let fu = format!("{field}.up");
                let d = self.vec3(&fd, *direction)?;
                let u = self.vec3(&fu, *up)?;
                if d.norm() < 1e-12 {
                    return Err(self.invalid(&fd, "the direction must be non-zero"));
                }
                let x = d.normalize();
                let z = u - x * u.dot(&x);
                if u.norm() < 1e-12 || z.norm() < 1e-6 * u.norm() {
                    return Err(self.invalid(&fu, "`up` must be non-zero and not parallel to `direction`"));
                }
                let z = z.normalize();
                let y = z.cross(&x);
                let m = Matrix3::from_columns(&[x, y, z]);
                Ok(Quat::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)))
            }
        }
    }
}

impl Scenario {
    /// Validates a parsed file into SI working objects. `document` supplies the
    /// positions for errors and the scenario's folder for relative paths.
    /// Sections are checked in this order, so the first error is always the
    /// same one.
    pub fn validate(file: ScenarioFile, document: &Document) -> Result<Scenario, ScenarioError> {
        let base = document.path.parent().map(Path::to_path_buf).unwrap_or_default();
        let c = Checker { doc: document, base, warnings: Default::default() };
        if file.name.trim().is_empty() {
            return Err(c.invalid("name", "must not be empty"));
        }
        let mesh = c.mesh(&file.mesh)?;
        let refine = c.refine(&file.refine)?;
        let (material, region_materials) = c.materials(&file.material)?;
        let fixed = c.fixed(&file.fixed)?;
        let skull = c.skull(file.skull.as_ref())?;
        let trajectory = c.trajectory(file.trajectory.as_deref())?;
        let spatulas = c.spatulas(&file.spatulas, trajectory.as_ref())?;
        let effects = c.effects(&file.effects, skull.is_some(), &file.tethers)?;
        let (tethers, relaxation, ischemia) = c.tissue(&file, effects)?;
        let igtl_listen = super::devices::validate_listen(&file.openigtlink, &|field, problem| c.invalid(field, problem))?;
        let spacemouse = super::devices::validate_spacemouse(&file.spacemouse, &|field, problem| c.invalid(field, problem))?;
        let solver = c.solver(&file.solver)?;
        let (gravity, density) = c.body(file.gravity_m_s2, file.density_kg_m3)?;
        let (time_step, duration) = c.run_time(file.time_step_s, file.duration_s)?;
        let outputs = c.outputs(&file.outputs)?;
        let display = c.display(&file.display)?;
        let integrity = c.integrity(&file.integrity)?;
        Ok(Scenario {
            name: file.name,
            source_path: document.path.clone(),
            mesh,
            refine,
            body: Body { material, region_materials, gravity, density },
            fixed,
            skull,
            spatulas,
            effects,
            collision: CollisionOptions { backend: file.collision.backend, swept_culling: file.collision.swept_culling },
            solver,
            time_step,
            duration,
            trajectory: trajectory.map(|(p, _)| p),
            run: RunOutputs { outputs, integrity },
            display,
            tethers,
            tissue_time: TissueTime { relaxation, ischemia },
            devices: DeviceSettings { igtl_listen, spacemouse },
            checks: Checks {
                warnings: c.warnings.take(),
                locations: field_locations(document, file.fixed.len(), file.spatulas.len(), &file.tethers),
            },
        })
    }

    /// Where `field` is written (its own position or the nearest enclosing
    /// recorded one, see [`Scenario::locations`]); the file's start otherwise.
    pub fn locate(&self, field: &str) -> Location {
        self.checks.locations.get(field).cloned().unwrap_or_else(|| Location {
            origin: super::error::Origin::File(self.source_path.clone()),
            line: 1,
            column: 1,
        })
    }

    /// A [`ScenarioError::Invalid`] about `field`, at its position: for the
    /// checks that need the mesh or the played trajectory (`sim::preflight`).
    pub fn invalid(&self, field: &str, problem: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid { location: self.locate(field), field: field.to_string(), problem: problem.into() }
    }

    /// A [`ScenarioWarning`] about `field`, at its position.
    pub fn warning(&self, field: &str, message: impl Into<String>) -> ScenarioWarning {
        ScenarioWarning { location: self.locate(field), field: field.to_string(), message: message.into() }
    }

    /// Number of fixed steps in a headless run (`ceil(duration / time_step)`, at least 1).
    pub fn step_count(&self) -> u64 {
        ((self.duration / self.time_step) - 1e-9).ceil().max(1.0) as u64
    }

    /// A short human summary (what `fissure check` prints).
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "scenario \"{}\" ({})", self.name, self.source_path.display());
        match &self.mesh {
            MeshSource::Phantom { preset } => {
                let _ = writeln!(s, "  mesh:      phantom preset {preset}");
            }
            MeshSource::File { path, units } => {
                let _ = writeln!(s, "  mesh:      {} ({units:?})", path.display());
            }
        }
        let _ = match &self.refine {
            RefineChoice::Off => writeln!(s, "  refine:    none"),
            RefineChoice::Auto => writeln!(s, "  refine:    Auto (where the blades reach, to a quarter of the narrowest blade's width)"),
            RefineChoice::Given(r) => writeln!(s, "  refine:    to {} mm inside {} volume(s)", r.edge / MM, r.within.len()),
        };
        let _ = writeln!(
            s,
            "  material:  E = {} Pa, nu = {}{}",
            self.body.material.young_modulus,
            self.body.material.poisson_ratio,
            if self.body.region_materials.is_empty() { String::new() } else { format!(", {} region override(s)", self.body.region_materials.len()) }
        );
        let _ = writeln!(s, "  fixed:     {} selector(s)", self.fixed.len());
        match &self.skull {
            None => {
                let _ = writeln!(s, "  skull:     none");
            }
            Some(k) => {
                let sphere = |x: &Option<Sphere>| match x {
                    Some(sp) => format!("centre ({:.1}, {:.1}, {:.1}) mm, radius {:.1} mm", sp.center.x / MM, sp.center.y / MM, sp.center.z / MM, sp.radius / MM),
                    None => "none".to_string(),
                };
                let _ = writeln!(s, "  skull:     containing {}; excluding {}", sphere(&k.containing), sphere(&k.excluding));
            }
        }
        for (i, sp) in self.spatulas.iter().enumerate() {
            let layout = match &sp.layout {
                NodeLayout::Grid { along, across } => format!("grid {along} x {across}"),
                NodeLayout::TipConcentrated { count, tip_fraction } => format!("{count} nodes on the tip {tip_fraction}"),
                NodeLayout::Explicit(p) => format!("{} explicit nodes", p.len()),
            };
            let p = sp.initial_pose.position / MM;
            let _ = writeln!(
                s,
                "  spatula {i} \"{}\": {:.1} x {:.1} x {:.2} mm, {layout}, at ({:.1}, {:.1}, {:.1}) mm, input {}",
                sp.name,
                sp.shape.length / MM,
                sp.shape.width / MM,
                sp.shape.thickness / MM,
                p.x,
                p.y,
                p.z,
                sp.input
            );
        }
        let effects: Vec<String> = self.effects.iter().map(|e| format!("{e:?}")).collect();
        let _ = writeln!(s, "  effects:   {}", if effects.is_empty() { "none".to_string() } else { effects.join(", ") });
        let _ = writeln!(s, "  collision: {:?}; compliance {:?}, region of interest {:?}", self.collision.backend, self.solver.compliance_storage, self.solver.region_of_interest);
        let _ = writeln!(s, "  time:      step {} s, duration {} s ({} steps)", self.time_step, self.duration, self.step_count());
        if let Some(t) = &self.trajectory {
            let _ = writeln!(s, "  trajectory: {}", t.display());
        }
        let _ = write!(s, "  outputs:   {} (vtk {}, frames {})", self.run.outputs.dir.display(), self.run.outputs.vtk, self.run.outputs.frames);
        s
    }
}

/// One method per section of the scenario, in the order [`Scenario::validate`] calls them.
impl Checker<'_> {
    /// `mesh`: a known phantom preset, or a file that exists.
    fn mesh(&self, mesh: &MeshSourceFile) -> Result<MeshSource, ScenarioError> {
        Ok(match mesh {
            MeshSourceFile::Phantom { preset } => {
                let _: Preset = preset.parse().map_err(|_| {
                    let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
                    self.invalid("mesh.preset", format!("unknown phantom preset \"{preset}\", expected one of {}", quoted(&names)))
                })?;
                MeshSource::Phantom { preset: preset.clone() }
            }
            MeshSourceFile::File { path, units } => MeshSource::File { path: self.existing_file("mesh.path", path)?, units: *units },
        })
    }

    /// `refine`: `Auto`, `None`, or an edge and at least one volume.
    fn refine(&self, refine: &RefineChoiceFile) -> Result<RefineChoice, ScenarioError> {
        Ok(match refine {
            RefineChoiceFile::Auto => RefineChoice::Auto,
            RefineChoiceFile::Off => RefineChoice::Off,
            RefineChoiceFile::Given(r) => {
                let edge = self.positive("refine.edge_mm", r.edge_mm)? * MM;
                if r.within.is_empty() {
                    return Err(self.invalid("refine.within", "give at least one volume (or leave `refine` out for `Auto`, or `refine: None`)"));
                }
                let mut within = Vec::with_capacity(r.within.len());
                for (i, v) in r.within.iter().enumerate() {
                    let field = format!("refine.within[{i}]");
                    within.push(match v {
                        VolumeFile::Box { min_mm, max_mm } => {
                            let (min, max) = self.box_mm(&field, *min_mm, *max_mm)?;
                            Volume::Box { min, max }
                        }
                        VolumeFile::Sphere { center_mm, radius_mm } => {
                            Volume::Sphere(self.sphere(&field, &SphereFile { center_mm: *center_mm, radius_mm: *radius_mm })?)
                        }
                    });
                }
                RefineChoice::Given(Refinement { edge, within })
            }
        })
    }

    /// `material`: the default and each region's, region ids unique (sorted by id).
    fn materials(&self, material: &MaterialFile) -> Result<(Material, Vec<RegionMaterial>), ScenarioError> {
        let default = self.material("material", material.young_modulus_pa, material.poisson_ratio)?;
        let mut region_materials = Vec::with_capacity(material.regions.len());
        for (i, r) in material.regions.iter().enumerate() {
            let field = format!("material.regions[{i}]");
            if region_materials.iter().any(|m: &RegionMaterial| m.region == r.id) {
                return Err(self.invalid(&format!("{field}.id"), format!("region {} is given twice", r.id)));
            }
            region_materials.push(RegionMaterial { region: r.id, material: self.material(&field, r.young_modulus_pa, r.poisson_ratio)? });
        }
        region_materials.sort_by_key(|m| m.region);
        Ok((default, region_materials))
    }

    /// `fixed`: at least one selector, each well formed.
    fn fixed(&self, fixed: &[FixedFile]) -> Result<Vec<FixedRegion>, ScenarioError> {
        if fixed.is_empty() {
            return Err(self.invalid("fixed", "at least one fixed region is needed (without one the stiffness matrix is singular)"));
        }
        let mut out = Vec::with_capacity(fixed.len());
        for (i, f) in fixed.iter().enumerate() {
            let field = format!("fixed[{i}]");
            out.push(match f {
                FixedFile::RegionId(id) => FixedRegion::RegionId(*id),
                FixedFile::Box { min_mm, max_mm } => {
                    let (min, max) = self.box_mm(&field, *min_mm, *max_mm)?;
                    FixedRegion::Box { min, max }
                }
                FixedFile::Sphere { center_mm, radius_mm } => {
                    FixedRegion::Sphere(self.sphere(&field, &SphereFile { center_mm: *center_mm, radius_mm: *radius_mm })?)
                }
                FixedFile::LowestPerComponent { height_mm } => {
                    FixedRegion::LowestPerComponent { height: self.positive(&format!("{field}.height_mm"), *height_mm)? * MM }
                }
            });
        }
        Ok(out)
    }

    /// `skull`: a containing sphere, an excluding one, or both.
    fn skull(&self, skull: Option<&SkullFile>) -> Result<Option<Skull>, ScenarioError> {
        let Some(s) = skull else { return Ok(None) };
        let containing = s.containing.as_ref().map(|x| self.sphere("skull.containing", x)).transpose()?;
        let excluding = s.excluding.as_ref().map(|x| self.sphere("skull.excluding", x)).transpose()?;
        if containing.is_none() && excluding.is_none() {
            return Err(self.invalid("skull", "give `containing`, `excluding` or both (or leave `skull` out)"));
        }
        Ok(Some(Skull { containing, excluding }))
    }

    /// `trajectory`: a file that exists and parses, with its rows.
    fn trajectory(&self, trajectory: Option<&str>) -> Result<Option<(PathBuf, Trajectory)>, ScenarioError> {
        let Some(p) = trajectory else { return Ok(None) };
        let path = self.existing_file("trajectory", p)?;
        let track = Trajectory::load(&path).map_err(|e| self.invalid("trajectory", e.to_string()))?;
        Ok(Some((path, track)))
    }

    /// `spatulas`: one to [`MAX_SPATULAS`], no fewer than the trajectory has tracks, each checked.
    fn spatulas(&self, spatulas: &[SpatulaFile], trajectory: Option<&(PathBuf, Trajectory)>) -> Result<Vec<SpatulaConfig>, ScenarioError> {
        if spatulas.is_empty() {
            return Err(self.invalid("spatulas", "at least one spatula is needed"));
        }
        if spatulas.len() > MAX_SPATULAS {
            return Err(self.invalid("spatulas", format!("at most {MAX_SPATULAS} spatulas, got {}", spatulas.len())));
        }
        if let Some((path, track)) = trajectory
            && track.spatula_count() > spatulas.len()
        {
            return Err(self.invalid("trajectory", tracks_beyond_spatulas(path, track, spatulas.len())));
        }
        let mut out: Vec<SpatulaConfig> = Vec::with_capacity(spatulas.len());
        for (i, s) in spatulas.iter().enumerate() {
            let spatula = self.spatula(i, s, &out, trajectory)?;
            out.push(spatula);
        }
        Ok(out)
    }

    /// `spatulas[i]`: a unique name among the `earlier` ones, shape, layout, pose, input and filter.
    fn spatula(&self, i: usize, s: &SpatulaFile, earlier: &[SpatulaConfig], trajectory: Option<&(PathBuf, Trajectory)>) -> Result<SpatulaConfig, ScenarioError> {
        let field = format!("spatulas[{i}]");
        if s.name.trim().is_empty() {
            return Err(self.invalid(&format!("{field}.name"), "must not be empty"));
        }
        if earlier.iter().any(|o| o.name == s.name) {
            return Err(self.invalid(&format!("{field}.name"), format!("the name \"{}\" is used twice", s.name)));
        }
        let shape = SpatulaShape {
            length: self.positive(&format!("{field}.shape.length_mm"), s.shape.length_mm)? * MM,
            width: self.positive(&format!("{field}.shape.width_mm"), s.shape.width_mm)? * MM,
            thickness: self.positive(&format!("{field}.shape.thickness_mm"), s.shape.thickness_mm)? * MM,
        };
        let layout = self.layout(&format!("{field}.layout"), s, &shape)?;
        let pf = format!("{field}.pose");
        let position = self.vec_mm(&format!("{pf}.position_mm"), s.pose.position_mm)?;
        let rotation = self.rotation(&format!("{pf}.rotation"), &s.pose.rotation)?;
        let initial_pose = Pose { position, rotation };
        let input = self.input(&field, i, &s.input, earlier, trajectory)?;
        let filter = self.filter(&field, &s.filter, &input)?;
        Ok(SpatulaConfig { name: s.name.clone(), shape, layout, initial_pose, input, filter })
    }

    /// `spatulas[i].layout` (field `lf`): a grid, tip-concentrated nodes or points on the blade `shape`.
    fn layout(&self, lf: &str, s: &SpatulaFile, shape: &SpatulaShape) -> Result<NodeLayout, ScenarioError> {
        Ok(match &s.layout {
            LayoutFile::Grid { along, across } => {
                if *along == 0 || *across == 0 {
                    return Err(self.invalid(lf, format!("a grid needs along >= 1 and across >= 1, got {along} x {across}")));
                }
                if u64::from(*along) * u64::from(*across) > MAX_NODES_PER_FACE {
                    return Err(self.invalid(lf, format!("{along} x {across} nodes exceed {MAX_NODES_PER_FACE} a face")));
                }
                NodeLayout::Grid { along: *along, across: *across }
            }
            LayoutFile::TipConcentrated { count, tip_fraction } => {
                if *count == 0 || u64::from(*count) > MAX_NODES_PER_FACE {
                    return Err(self.invalid(&format!("{lf}.count"), format!("must be in 1..={MAX_NODES_PER_FACE}, got {count}")));
                }
                let f = self.finite(&format!("{lf}.tip_fraction"), *tip_fraction)?;
                if !(f > 0.0 && f <= 1.0) {
                    return Err(self.invalid(&format!("{lf}.tip_fraction"), format!("must be in (0, 1], got {f}")));
                }
                NodeLayout::TipConcentrated { count: *count, tip_fraction: f }
            }
            LayoutFile::Explicit(points) => {
                if points.is_empty() || points.len() as u64 > MAX_NODES_PER_FACE {
                    return Err(self.invalid(lf, format!("needs 1..={MAX_NODES_PER_FACE} points, got {}", points.len())));
                }
                let mut out = Vec::with_capacity(points.len());
                for (k, p) in points.iter().enumerate() {
                    let pf = format!("{lf}[0][{k}]");
                    let x = self.finite(&format!("{pf}[0]"), p[0])? * MM;
                    let y = self.finite(&format!("{pf}[1]"), p[1])? * MM;
                    let tol = 1e-9;
                    if x < -tol || x > shape.length + tol || y.abs() > shape.width / 2.0 + tol {
                        return Err(self.invalid(&pf, format!(
                            "({}, {}) mm lies off the blade: need 0 <= x <= {} and |y| <= {}",
                            p[0], p[1], s.shape.length_mm, s.shape.width_mm / 2.0
                        )));
                    }
                    out.push([x, y]);
                }
                NodeLayout::Explicit(out)
            }
        })
    }

    /// `spatulas[i].input` (`field` is `spatulas[i]`): a device, or the trajectory's track `i`.
    fn input(
        &self,
        field: &str,
        i: usize,
        input: &InputFile,
        earlier: &[SpatulaConfig],
        trajectory: Option<&(PathBuf, Trajectory)>,
    ) -> Result<InputBinding, ScenarioError> {
        Ok(match input {
            InputFile::Keyboard => InputBinding::Keyboard,
            InputFile::Gamepad => InputBinding::Gamepad,
            InputFile::SpaceMouse => InputBinding::SpaceMouse,
            InputFile::OpenIgtLink { device, workspace_mm, max_speed_mm_s, connect, mapping, force } => {
                let invalid = |field: &str, problem: String| self.invalid(field, problem);
                super::devices::device_name(&format!("{field}.input.device"), device, &invalid)?;
                let workspace_mm = self.positive(&format!("{field}.input.workspace_mm"), *workspace_mm)?;
                let max_speed_mm_s = self.positive(&format!("{field}.input.max_speed_mm_s"), *max_speed_mm_s)?;
                let rotation = |field: &str, r: &RotationFile| self.rotation(field, r);
                let link = super::devices::validate_link(
                    &format!("{field}.input"),
                    device,
                    connect.as_deref(),
                    mapping.as_ref(),
                    force.as_ref(),
                    &invalid,
                    &rotation,
                )?;
                if link.mapping.is_some()
                    && let Some(j) = earlier.iter().position(|o: &SpatulaConfig| matches!(&o.input, InputBinding::OpenIgtLink { device: d, .. } if d == device))
                {
                    return Err(self.invalid(&format!("{field}.input.device"), format!(
                        "\"{device}\" also drives spatulas[{j}]; a mapped stylus drives one blade"
                    )));
                }
                if let Some(j) = earlier.iter().position(|o: &SpatulaConfig| {
                    matches!(&o.input, InputBinding::OpenIgtLink { device: d, link: l, .. } if d == device && l.mapping.is_some())
                }) {
                    return Err(self.invalid(&format!("{field}.input.device"), format!(
                        "\"{device}\" is spatulas[{j}]'s mapped stylus; a mapped stylus drives one blade"
                    )));
                }
                InputBinding::OpenIgtLink { device: device.clone(), workspace_m: workspace_mm * 1e-3, max_speed_m_s: max_speed_mm_s * 1e-3, link }
            }
            InputFile::Trajectory => {
                let Some((path, track)) = trajectory else {
                    return Err(self.invalid(&format!("{field}.input"), "input `Trajectory` needs the scenario's `trajectory` file"));
                };
                if track.samples(i).is_empty() {
                    return Err(self.invalid(&format!("{field}.input"), format!(
                        "the trajectory {} has no rows for spatula {i}", path.display()
                    )));
                }
                InputBinding::Trajectory
            }
        })
    }

    /// `spatulas[i].filter` (`field` is `spatulas[i]`): `Auto` is the One Euro
    /// filter's defaults for a tracker, none for any other `input`.
    fn filter(&self, field: &str, filter: &FilterFile, input: &InputBinding) -> Result<Option<OneEuro>, ScenarioError> {
        let filter_file = match (filter, input) {
            (FilterFile::Auto, InputBinding::OpenIgtLink { .. }) => FilterFile::one_euro_defaults(),
            (FilterFile::Auto, _) => FilterFile::Off,
            (other, _) => other.clone(),
        };
        Ok(match filter_file {
            FilterFile::OneEuro { min_cutoff_hz, beta_hz_per_mm_s, d_cutoff_hz } => {
                let ff = format!("{field}.filter");
                let beta = self.finite(&format!("{ff}.beta_hz_per_mm_s"), beta_hz_per_mm_s)?;
                if beta < 0.0 {
                    return Err(self.invalid(&format!("{ff}.beta_hz_per_mm_s"), format!("must be >= 0, got {beta}")));
                }
                Some(OneEuro {
                    min_cutoff_hz: self.positive(&format!("{ff}.min_cutoff_hz"), min_cutoff_hz)?,
                    beta_per_m: beta * 1e3,
                    d_cutoff_hz: self.positive(&format!("{ff}.d_cutoff_hz"), d_cutoff_hz)?,
                })
            }
            FilterFile::Auto | FilterFile::Off => None,
        })
    }

    /// `effects`: each listed once, each with what it needs (`skull` given,
    /// `tethers` listing a vessel or band, the effects it builds on).
    fn effects(&self, listed: &[Effect], skull_given: bool, tethers: &super::tethers::TethersFile) -> Result<EffectSet, ScenarioError> {
        let mut effects = EffectSet::default();
        for (i, e) in listed.iter().enumerate() {
            if !effects.insert(*e) {
                return Err(self.invalid(&format!("effects[{i}]"), format!("{e:?} is listed twice")));
            }
        }
        for (i, e) in listed.iter().enumerate() {
            let field = format!("effects[{i}]");
            match e {
                Effect::SkullSpheres if !skull_given => {
                    return Err(self.invalid(&field, "SkullSpheres needs the `skull` spheres, but `skull` is not given"));
                }
                Effect::Culling | Effect::ContactPressure if !effects.contains(Effect::Collision) => {
                    return Err(self.invalid(&field, format!("{e:?} needs the Collision effect")));
                }
                Effect::Ischemia if !effects.contains(Effect::ContactPressure) => {
                    return Err(self.invalid(&field, "Ischemia needs the ContactPressure effect (the pressure it doses)"));
                }
                Effect::Relaxation if !effects.contains(Effect::ForceOutput) && !effects.contains(Effect::ContactPressure) => {
                    return Err(self.invalid(&field, "Relaxation needs ForceOutput or ContactPressure (the forces it relaxes)"));
                }
                Effect::Tethers if tethers.vessels.is_empty() && tethers.bands.is_empty() => {
                    return Err(self.invalid(&field, "Tethers needs `tethers` with at least one vessel or band, but none is given"));
                }
                _ => {}
            }
        }
        Ok(effects)
    }

    /// `tethers`, `relaxation` and `ischemia`: each checked whether or not its
    /// effect is listed, and kept only when it is (tethers without their
    /// effect are a warning).
    fn tissue(
        &self,
        file: &ScenarioFile,
        effects: EffectSet,
    ) -> Result<(super::tethers::Tethers, Option<super::tissue_time::Relaxation>, Option<super::tissue_time::Ischemia>), ScenarioError> {
        let tethers = super::tethers::validate(&file.tethers, &|field, problem| self.invalid(field, problem))?;
        if !tethers.is_empty() && !effects.contains(Effect::Tethers) {
            self.warn("tethers", "the scene lists tethers but not the Tethers effect: they are not built (add Tethers to `effects`)");
        }
        let tethers = if effects.contains(Effect::Tethers) { tethers } else { Default::default() };
        let relaxation = super::tissue_time::validate_relaxation(&file.relaxation, &|field, problem| self.invalid(field, problem))?;
        let relaxation = effects.contains(Effect::Relaxation).then_some(relaxation);
        let ischemia = super::tissue_time::validate_ischemia(&file.ischemia, &|field, problem| self.invalid(field, problem))?;
        let ischemia = effects.contains(Effect::Ischemia).then_some(ischemia);
        Ok((tethers, relaxation, ischemia))
    }

    /// `solver`: the region of interest, the cache folder, the sub-step travel and the row band.
    fn solver(&self, solver: &SolverFile) -> Result<SolverOptions, ScenarioError> {
        Ok(SolverOptions {
            compliance_storage: solver.compliance_storage,
            region_of_interest: match &solver.region_of_interest {
                RegionOfInterestFile::Auto => RegionOfInterest::Auto,
                RegionOfInterestFile::All => RegionOfInterest::All,
                RegionOfInterestFile::Sphere { center_mm, radius_mm } => RegionOfInterest::Sphere(
                    self.sphere("solver.region_of_interest", &SphereFile { center_mm: *center_mm, radius_mm: *radius_mm })?,
                ),
            },
            cache_dir: match &solver.cache_dir {
                Some(d) if d.trim().is_empty() => return Err(self.invalid("solver.cache_dir", "the path is empty (use None for no cache)")),
                Some(d) => Some(PathBuf::from(d)),
                None => None,
            },
            spatula_contact: solver.spatula_contact,
            substep_travel: match solver.substep_travel {
                Some(t) if !(0.01..=10.0).contains(&t) => {
                    return Err(self.invalid("solver.substep_travel", format!("must be in 0.01..=10 blade thicknesses (or None), got {t}")));
                }
                t => t,
            },
            substep_jitter: solver.substep_jitter,
            early_start: solver.early_start,
            row_band: match solver.row_band_mm {
                Some(b) if !(b.is_finite() && b > 0.0 && b <= 1000.0) => {
                    return Err(self.invalid("solver.row_band_mm", format!("must be in (0, 1000] mm (or None: every surface vertex), got {}", number(b))));
                }
                b => b.map(|b| b * 1e-3),
            },
        })
    }

    /// `gravity_m_s2` (m/s^2) and `density_kg_m3` (kg/m^3).
    fn body(&self, gravity_m_s2: [f64; 3], density_kg_m3: f64) -> Result<(Vec3, f64), ScenarioError> {
        let gravity = self.vec3("gravity_m_s2", gravity_m_s2)?;
        let density = self.finite("density_kg_m3", density_kg_m3)?;
        if !(density > 0.0 && density <= MAX_DENSITY_KG_M3) {
            return Err(self.invalid("density_kg_m3", format!(
                "density_kg_m3 must be in (0, {MAX_DENSITY_KG_M3:e}] kg/m^3 (brain tissue: 1040), got {}",
                number(density)
            )));
        }
        Ok((gravity, density))
    }

    /// `time_step_s` and `duration_s` (s): at least [`MIN_STEPS`] steps a run, at most 1e9.
    fn run_time(&self, time_step_s: f64, duration_s: f64) -> Result<(f64, f64), ScenarioError> {
        let time_step = self.positive("time_step_s", time_step_s)?;
        let duration = self.positive("duration_s", duration_s)?;
        // A relative tolerance keeps 0.01 s in 0.1 s (0.1 / 10 rounds below 0.01).
        if time_step > duration / MIN_STEPS * (1.0 + 1e-9) {
            return Err(self.invalid("time_step_s", format!(
                "time_step_s must be at most duration_s / {MIN_STEPS} = {} s (a run of {duration} s needs at least {MIN_STEPS} steps), got {time_step}",
                duration / MIN_STEPS
            )));
        }
        if duration / time_step > 1e9 {
            return Err(self.invalid("duration_s", format!("{} steps of {time_step} s are too many (at most 1e9)", duration / time_step)));
        }
        Ok((time_step, duration))
    }

    /// `outputs`: the folders are not empty.
    fn outputs(&self, outputs: &OutputsFile) -> Result<Outputs, ScenarioError> {
        if outputs.dir.trim().is_empty() {
            return Err(self.invalid("outputs.dir", "must not be empty"));
        }
        if outputs.record_dir.as_ref().is_some_and(|d| d.trim().is_empty()) {
            return Err(self.invalid("outputs.record_dir", "must not be empty (leave it out for the user's data directory)"));
        }
        Ok(Outputs {
            dir: PathBuf::from(&outputs.dir),
            vtk: outputs.vtk,
            frames: outputs.frames,
            record_dir: outputs.record_dir.as_ref().map(PathBuf::from),
        })
    }

    /// `display`: the pressure scale's top, then the named views.
    fn display(&self, display: &DisplayFile) -> Result<Display, ScenarioError> {
        let pressure_max_mmhg = display.pressure_max_mmhg;
        if !(pressure_max_mmhg.is_finite() && (1.0..=1000.0).contains(&pressure_max_mmhg)) {
            return Err(self.invalid("display.pressure_max_mmhg", format!("must be in [1, 1000] mmHg, got {pressure_max_mmhg}")));
        }
        Ok(Display {
            pressure_max_mmhg,
            views: Views { overview: self.view("display.overview", display.overview)?, microscope: self.view("display.microscope", display.microscope)? },
        })
    }

    /// `integrity`: the run's pass/fail limits.
    fn integrity(&self, integrity: &IntegrityFile) -> Result<IntegrityLimits, ScenarioError> {
        Ok(IntegrityLimits {
            max_penetration_mm: match integrity.max_penetration_mm {
                d if d.is_finite() && d >= 0.0 => d,
                d => return Err(self.invalid("integrity.max_penetration_mm", format!("must be a finite number >= 0 mm, got {d}"))),
            },
            max_inverted_elements: integrity.max_inverted_elements,
            max_crossed_vertices: integrity.max_crossed_vertices,
            max_torn_vessels: integrity.max_torn_vessels,
        })
    }
}

fn field_locations(document: &Document, fixed: usize, spatulas: usize, tethers: &super::tethers::TethersFile) -> FieldLocations {
    let mut locations = FieldLocations::default();
    let vessel_points = tethers.vessels.iter().enumerate().flat_map(|(v, f)| (0..f.points_mm.len()).map(move |p| super::tethers::Tethers::vessel_point_field(v, p)));
    let band_ends = (0..tethers.bands.len()).flat_map(|b| (0..2).map(move |e| super::tethers::Tethers::band_end_field(b, e)));
    let indexed = (0..fixed).map(|i| format!("fixed[{i}]")).chain((0..spatulas).map(|i| format!("spatulas[{i}]"))).chain(vessel_points).chain(band_ends);
    for field in LOCATED_FIELDS.iter().map(|f| f.to_string()).chain(indexed) {
        locations.insert(&field, document.locate_path(&field));
    }
    locations
}

/// The problem of a trajectory with rows for a spatula index the scene lacks.
pub fn tracks_beyond_spatulas(path: &Path, track: &Trajectory, spatulas: usize) -> String {
    format!(
        "the trajectory {} has rows for spatula {}, but the scene has {spatulas} spatula{} (indices 0..={})",
        path.display(),
        track.spatula_count() - 1,
        if spatulas == 1 { "" } else { "s" },
        spatulas.saturating_sub(1)
    )
}

/// A number as a user wrote it: `1e300`, not three hundred digits.
fn number(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) { format!("{v:e}") } else { format!("{v}") }
}

fn quoted(names: &[&str]) -> String {
    names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::error::Origin;

    /// A valid scene on the small phantom; `{E}`, `{NU}`, ... are replaced by the test.
    const SCENE: &str = r#"(
    name: "ranges",
    mesh: Phantom(preset: "small"),
    material: (young_modulus_pa: {E}, poisson_ratio: {NU}, regions: [(id: 2, young_modulus_pa: {RE}, poisson_ratio: {RNU})]),
    fixed: [RegionId(3)],
    spatulas: [(name: "a", shape: (length_mm: 20.0, width_mm: 5.0, thickness_mm: 1.0), layout: Grid(along: 2, across: 2),
                pose: (position_mm: (0.0, 0.0, 80.0), rotation: Quaternion(1.0, 0.0, 0.0, 0.0)), input: Keyboard)],
    effects: [Collision, Gravity],
    gravity_m_s2: {G},
    density_kg_m3: {RHO},
    time_step_s: {DT},
    duration_s: 1.0,
)"#;

    const GOOD: [(&str, &str); 8] = [
        ("{E}", "3000.0"),
        ("{NU}", "0.45"),
        ("{RE}", "5000.0"),
        ("{RNU}", "0.45"),
        ("{G}", "(0.0, 0.0, -9.81)"),
        ("{RHO}", "1040.0"),
        ("{DT}", "0.01"),
        ("", ""),
    ];

    /// The scene with `key` set to `value` (the rest good), its text, and the result.
    fn load(key: &str, value: &str) -> (String, Result<Scenario, ScenarioError>) {
        let mut text = SCENE.to_string();
        for (k, v) in GOOD.iter().filter(|(k, _)| !k.is_empty()) {
            text = text.replace(k, if *k == key { value } else { v });
        }
        let result = Scenario::from_str(&text, Path::new("ranges.ron"), &[]);
        (text, result)
    }

    /// Line and column (1-based) where `value` first follows `after` in `text`.
    fn position(text: &str, after: &str, value: &str) -> (usize, usize) {
        let at = text.find(after).expect("anchor") + text[text.find(after).expect("anchor")..].find(value).expect("value");
        let line = text[..at].matches('\n').count() + 1;
        let column = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
        (line, column)
    }

    /// `key = value` is refused with an error at the value's position, naming `field` and saying `problem`.
    fn refused(key: &str, value: &str, anchor: &str, field: &str, problem: &str) {
        let (text, result) = load(key, value);
        let err = result.expect_err(&format!("{field} = {value} must be refused"));
        let message = err.to_string();
        let location = err.location().unwrap_or_else(|| panic!("{message}: no location"));
        assert_eq!(location.origin, Origin::File(PathBuf::from("ranges.ron")), "{message}");
        let (line, column) = position(&text, anchor, value);
        assert_eq!(location.line, line, "{field} = {value}: line in {message}");
        assert!(
            (column..column + value.len()).contains(&location.column),
            "{field} = {value}: the column must point into the value (columns {column}..{}): {message}",
            column + value.len()
        );
        assert_eq!(err.field(), Some(field), "{message}");
        assert!(message.contains(problem), "{field} = {value}: `{message}` should say `{problem}`");
    }

    #[test]
    fn the_good_scene_is_valid_without_warnings() {
        let (_, result) = load("", "");
        let s = result.expect("valid");
        assert!(s.checks.warnings.is_empty(), "{:?}", s.checks.warnings);
    }

    #[test]
    fn young_modulus_must_lie_in_0_to_1e9_pa() {
        let range = "young_modulus_pa must be in (0, 1e9] Pa";
        for (value, got) in [("1e300", "got 1e300"), ("0.0", "got 0"), ("-5.0", "got -5"), ("1.5e9", "got 1.5e9")] {
            refused("{E}", value, "material:", "material.young_modulus_pa", &format!("{range} (brain tissue: 1e2..1e4), {got}"));
        }
        refused("{RE}", "1e10", "regions:", "material.regions[0].young_modulus_pa", &format!("{range} (brain tissue: 1e2..1e4), got 1e10"));
        refused("{E}", "inf", "material:", "material.young_modulus_pa", "must be a finite number, got inf");
        let (_, ok) = load("{E}", "1e9");
        assert!(ok.is_ok(), "1e9 Pa is the upper bound, included: {:?}", ok.err());
    }

    #[test]
    fn poisson_ratio_must_lie_in_0_to_one_half() {
        for value in ["0.5", "-0.1", "0.7"] {
            refused("{NU}", value, "material:", "material.poisson_ratio", &format!("poisson_ratio must be in [0, 0.5), got {value}"));
        }
        refused("{RNU}", "0.5", "regions:", "material.regions[0].poisson_ratio", "poisson_ratio must be in [0, 0.5), got 0.5");
        let (_, ok) = load("{NU}", "0.0");
        assert!(ok.is_ok_and(|s| s.checks.warnings.is_empty()), "nu = 0 is allowed, silently");
    }

    #[test]
    fn poisson_ratio_above_0_49_warns_of_volumetric_locking() {
        let (text, result) = load("{NU}", "0.495");
        let s = result.expect("nu = 0.495 is valid");
        assert_eq!(s.checks.warnings.len(), 1, "{:?}", s.checks.warnings);
        let w = &s.checks.warnings[0];
        assert_eq!(w.field, "material.poisson_ratio");
        assert_eq!((w.location.line, w.location.column), position(&text, "material:", "0.495"));
        let shown = w.to_string();
        assert!(shown.starts_with(&format!("ranges.ron:{}:", w.location.line)), "file:line:column first: {shown}");
        assert!(shown.contains("poisson_ratio 0.495 is above 0.49") && shown.contains("lock volumetrically"), "{shown}");
        // Per region too; 0.49 itself is quiet.
        let (_, result) = load("{RNU}", "0.4999999");
        let s = result.expect("valid");
        assert_eq!(s.checks.warnings.iter().map(|w| w.field.as_str()).collect::<Vec<_>>(), ["material.regions[0].poisson_ratio"]);
        let (_, result) = load("{NU}", "0.49");
        assert!(result.expect("valid").checks.warnings.is_empty(), "0.49 is the threshold, not above it");
    }

    #[test]
    fn density_must_lie_in_0_to_1e5() {
        for (value, got) in [("-1.0", "got -1"), ("0.0", "got 0"), ("2e5", "got 200000")] {
            refused("{RHO}", value, "density_kg_m3:", "density_kg_m3", &format!("density_kg_m3 must be in (0, 1e5] kg/m^3 (brain tissue: 1040), {got}"));
        }
        refused("{RHO}", "NaN", "density_kg_m3:", "density_kg_m3", "must be a finite number, got NaN");
    }

    #[test]
    fn a_run_needs_at_least_ten_steps() {
        let problem = "time_step_s must be at most duration_s / 10 = 0.1 s (a run of 1 s needs at least 10 steps)";
        for (value, got) in [("1.0", "1"), ("0.5", "0.5"), ("0.11", "0.11")] {
            refused("{DT}", value, "time_step_s:", "time_step_s", &format!("{problem}, got {got}"));
        }
        refused("{DT}", "0.0", "time_step_s:", "time_step_s", "must be > 0, got 0");
        let (_, ok) = load("{DT}", "0.1");
        assert!(ok.is_ok(), "exactly 10 steps is enough: {:?}", ok.err());
    }

    #[test]
    fn gravity_must_be_finite() {
        refused("{G}", "(0.0, NaN, -9.81)", "gravity_m_s2:", "gravity_m_s2[1]", "must be a finite number, got NaN");
        refused("{G}", "(inf, 0.0, -9.81)", "gravity_m_s2:", "gravity_m_s2[0]", "must be a finite number, got inf");
    }

    #[test]
    fn locations_name_the_fields_later_checks_use() {
        let (text, result) = load("", "");
        let s = result.expect("valid");
        let fixed = s.locate("fixed[0]");
        assert_eq!((fixed.line, fixed.column), position(&text, "fixed:", "RegionId(3)"));
        // An unrecorded field falls back to its nearest recorded parent.
        assert_eq!(s.locate("fixed[0].radius_mm"), fixed);
        let err = s.invalid("time_step_s", "too coarse").to_string();
        let (line, column) = position(&text, "time_step_s:", "0.01");
        assert_eq!(err, format!("ranges.ron:{line}:{column}: time_step_s: too coarse"));
    }
}
