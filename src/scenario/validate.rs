//! Validation: a [`ScenarioFile`] (human units, unchecked) becomes a [`Scenario`]
//! (SI units, every range and cross-field rule checked).
//!
//! In: the parsed file and its [`Document`] (for positions). Out: a [`Scenario`]
//! the pipeline reads directly, or the first [`ScenarioError::Invalid`] in file
//! order of checks, naming file, line, column and field path. Stays true for a
//! validated scenario: every number is finite; lengths, radii, moduli and steps
//! are positive; nu in (-1, 0.5); poses are unit; input files exist; each
//! effect's prerequisites are present.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Rotation3, Unit};

use super::error::ScenarioError;
use super::file::{
    CollisionBackend, ComplianceStorage, Effect, FixedFile, InputFile, LayoutFile, LengthUnit, MeshSourceFile,
    RegionOfInterestFile, RotationFile, ScenarioFile, SphereFile, SpatulaContact,
};
use super::overrides::Document;
use super::trajectory::Trajectory;
use crate::geometry::{NodeLayout, Pose, SpatulaShape};
use crate::math::{Quat, Vec3};
use crate::mesh::phantom::Preset;

/// Most source nodes a layout may put on one face.
pub const MAX_NODES_PER_FACE: u64 = 1_000_000;

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
    /// Young's modulus, Pa (> 0).
    pub young_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5).
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
    /// OpenIGTLink TRANSFORM messages from this device name (non-empty); poses
    /// outside the workspace box (half-width `workspace_m` on each axis around
    /// the scene origin, m, > 0) or faster than `max_speed_m_s` (m/s, > 0) are refused.
    OpenIgtLink { device: String, workspace_m: f64, max_speed_m_s: f64 },
    /// The scenario's trajectory, track = this spatula's index.
    Trajectory,
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
}

/// The set of effects a scene asked for; iteration in [`Effect::ALL`] order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EffectSet(u16);

impl Effect {
    /// Every effect, in the fixed order used for iteration and display.
    pub const ALL: [Effect; 7] = [
        Effect::Collision,
        Effect::Culling,
        Effect::SkullSpheres,
        Effect::Gravity,
        Effect::ForceOutput,
        Effect::StressField,
        Effect::ContactPressure,
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
    /// Material of every region without an override.
    pub material: Material,
    /// Per-region overrides, sorted by region id, ids unique.
    pub region_materials: Vec<RegionMaterial>,
    /// Fixed-node selectors (non-empty; their union is fixed).
    pub fixed: Vec<FixedRegion>,
    /// Skull spheres, when given.
    pub skull: Option<Skull>,
    /// Spatulas (at least one), in file order: spatula index = position here.
    pub spatulas: Vec<SpatulaConfig>,
    /// The stages the scene asked for.
    pub effects: EffectSet,
    /// Collision backend.
    pub collision_backend: CollisionBackend,
    /// Swept-side culling on top of the paper's His-flags (see `collision` docs, rule 3b).
    pub swept_culling: bool,
    /// Solver options.
    pub solver: SolverOptions,
    /// Gravity, m/s^2.
    pub gravity: Vec3,
    /// Density, kg/m^3 (> 0).
    pub density: f64,
    /// Fixed time step, s (> 0, <= duration).
    pub time_step: f64,
    /// Headless run length, s (> 0).
    pub duration: f64,
    /// Recorded trajectory, resolved against the scenario's folder (exists and parses at validation).
    pub trajectory: Option<PathBuf>,
    /// Outputs.
    pub outputs: Outputs,
}

struct Checker<'d> {
    doc: &'d Document,
    base: PathBuf,
}

impl Checker<'_> {
    fn invalid(&self, field: &str, problem: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid { location: self.doc.locate_path(field), field: field.to_string(), problem: problem.into() }
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

    fn material(&self, field: &str, young_modulus_pa: f64, poisson_ratio: f64) -> Result<Material, ScenarioError> {
        let e_field = format!("{field}.young_modulus_pa");
        let young_modulus = self.finite(&e_field, young_modulus_pa)?;
        if young_modulus <= 0.0 {
            return Err(self.invalid(&e_field, format!("young_modulus_pa must be > 0, got {young_modulus}")));
        }
        let nu_field = format!("{field}.poisson_ratio");
        let nu = self.finite(&nu_field, poisson_ratio)?;
        if !(nu > -1.0 && nu < 0.5) {
            return Err(self.invalid(&nu_field, format!("poisson_ratio must be in (-1, 0.5), got {nu}")));
        }
        Ok(Material { young_modulus, poisson_ratio: nu })
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
    pub fn validate(file: ScenarioFile, document: &Document) -> Result<Scenario, ScenarioError> {
        let base = document.path.parent().map(Path::to_path_buf).unwrap_or_default();
        let c = Checker { doc: document, base };

        if file.name.trim().is_empty() {
            return Err(c.invalid("name", "must not be empty"));
        }

        let mesh = match &file.mesh {
            MeshSourceFile::Phantom { preset } => {
                let _: Preset = preset.parse().map_err(|_| {
                    let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
                    c.invalid("mesh.preset", format!("unknown phantom preset \"{preset}\", expected one of {}", quoted(&names)))
                })?;
                MeshSource::Phantom { preset: preset.clone() }
            }
            MeshSourceFile::File { path, units } => MeshSource::File { path: c.existing_file("mesh.path", path)?, units: *units },
        };

        let material = c.material("material", file.material.young_modulus_pa, file.material.poisson_ratio)?;
        let mut region_materials = Vec::with_capacity(file.material.regions.len());
        for (i, r) in file.material.regions.iter().enumerate() {
            let field = format!("material.regions[{i}]");
            if region_materials.iter().any(|m: &RegionMaterial| m.region == r.id) {
                return Err(c.invalid(&format!("{field}.id"), format!("region {} is given twice", r.id)));
            }
            region_materials.push(RegionMaterial { region: r.id, material: c.material(&field, r.young_modulus_pa, r.poisson_ratio)? });
        }
        region_materials.sort_by_key(|m| m.region);

        if file.fixed.is_empty() {
            return Err(c.invalid("fixed", "at least one fixed region is needed (without one the stiffness matrix is singular)"));
        }
        let mut fixed = Vec::with_capacity(file.fixed.len());
        for (i, f) in file.fixed.iter().enumerate() {
            let field = format!("fixed[{i}]");
            fixed.push(match f {
                FixedFile::RegionId(id) => FixedRegion::RegionId(*id),
                FixedFile::Box { min_mm, max_mm } => {
                    let min = c.vec_mm(&format!("{field}.min_mm"), *min_mm)?;
                    let max = c.vec_mm(&format!("{field}.max_mm"), *max_mm)?;
                    if (0..3).any(|k| min[k] >= max[k]) {
                        return Err(c.invalid(&format!("{field}.max_mm"), format!("must exceed min_mm in every component: min {min_mm:?}, max {max_mm:?}")));
                    }
                    FixedRegion::Box { min, max }
                }
                FixedFile::Sphere { center_mm, radius_mm } => {
                    FixedRegion::Sphere(c.sphere(&field, &SphereFile { center_mm: *center_mm, radius_mm: *radius_mm })?)
                }
                FixedFile::LowestPerComponent { height_mm } => {
                    FixedRegion::LowestPerComponent { height: c.positive(&format!("{field}.height_mm"), *height_mm)? * MM }
                }
            });
        }

        let skull = match &file.skull {
            None => None,
            Some(s) => {
                let containing = s.containing.as_ref().map(|x| c.sphere("skull.containing", x)).transpose()?;
                let excluding = s.excluding.as_ref().map(|x| c.sphere("skull.excluding", x)).transpose()?;
                if containing.is_none() && excluding.is_none() {
                    return Err(c.invalid("skull", "give `containing`, `excluding` or both (or leave `skull` out)"));
                }
                Some(Skull { containing, excluding })
            }
        };

        let trajectory = match &file.trajectory {
            None => None,
            Some(p) => {
                let path = c.existing_file("trajectory", p)?;
                let track = Trajectory::load(&path).map_err(|e| c.invalid("trajectory", e.to_string()))?;
                Some((path, track))
            }
        };

        if file.spatulas.is_empty() {
            return Err(c.invalid("spatulas", "at least one spatula is needed"));
        }
        let mut spatulas: Vec<SpatulaConfig> = Vec::with_capacity(file.spatulas.len());
        for (i, s) in file.spatulas.iter().enumerate() {
            let field = format!("spatulas[{i}]");
            if s.name.trim().is_empty() {
                return Err(c.invalid(&format!("{field}.name"), "must not be empty"));
            }
            if spatulas.iter().any(|o| o.name == s.name) {
                return Err(c.invalid(&format!("{field}.name"), format!("the name \"{}\" is used twice", s.name)));
            }
            let shape = SpatulaShape {
                length: c.positive(&format!("{field}.shape.length_mm"), s.shape.length_mm)? * MM,
                width: c.positive(&format!("{field}.shape.width_mm"), s.shape.width_mm)? * MM,
                thickness: c.positive(&format!("{field}.shape.thickness_mm"), s.shape.thickness_mm)? * MM,
            };
            let lf = format!("{field}.layout");
            let layout = match &s.layout {
                LayoutFile::Grid { along, across } => {
                    if *along == 0 || *across == 0 {
                        return Err(c.invalid(&lf, format!("a grid needs along >= 1 and across >= 1, got {along} x {across}")));
                    }
                    if u64::from(*along) * u64::from(*across) > MAX_NODES_PER_FACE {
                        return Err(c.invalid(&lf, format!("{along} x {across} nodes exceed {MAX_NODES_PER_FACE} a face")));
                    }
                    NodeLayout::Grid { along: *along, across: *across }
                }
                LayoutFile::TipConcentrated { count, tip_fraction } => {
                    if *count == 0 || u64::from(*count) > MAX_NODES_PER_FACE {
                        return Err(c.invalid(&format!("{lf}.count"), format!("must be in 1..={MAX_NODES_PER_FACE}, got {count}")));
                    }
                    let f = c.finite(&format!("{lf}.tip_fraction"), *tip_fraction)?;
                    if !(f > 0.0 && f <= 1.0) {
                        return Err(c.invalid(&format!("{lf}.tip_fraction"), format!("must be in (0, 1], got {f}")));
                    }
                    NodeLayout::TipConcentrated { count: *count, tip_fraction: f }
                }
                LayoutFile::Explicit(points) => {
                    if points.is_empty() || points.len() as u64 > MAX_NODES_PER_FACE {
                        return Err(c.invalid(&lf, format!("needs 1..={MAX_NODES_PER_FACE} points, got {}", points.len())));
                    }
                    let mut out = Vec::with_capacity(points.len());
                    for (k, p) in points.iter().enumerate() {
                        let pf = format!("{lf}[0][{k}]");
                        let x = c.finite(&format!("{pf}[0]"), p[0])? * MM;
                        let y = c.finite(&format!("{pf}[1]"), p[1])? * MM;
                        let tol = 1e-9;
                        if x < -tol || x > shape.length + tol || y.abs() > shape.width / 2.0 + tol {
                            return Err(c.invalid(&pf, format!(
                                "({}, {}) mm lies off the blade: need 0 <= x <= {} and |y| <= {}",
                                p[0], p[1], s.shape.length_mm, s.shape.width_mm / 2.0
                            )));
                        }
                        out.push([x, y]);
                    }
                    NodeLayout::Explicit(out)
                }
            };
            let pf = format!("{field}.pose");
            let position = c.vec_mm(&format!("{pf}.position_mm"), s.pose.position_mm)?;
            let rotation = c.rotation(&format!("{pf}.rotation"), &s.pose.rotation)?;
            let initial_pose = Pose { position, rotation };
            let input = match &s.input {
                InputFile::Keyboard => InputBinding::Keyboard,
                InputFile::Gamepad => InputBinding::Gamepad,
                InputFile::OpenIgtLink { device, workspace_mm, max_speed_mm_s } => {
                    if device.trim().is_empty() {
                        return Err(c.invalid(&format!("{field}.input.device"), "the OpenIGTLink device name must not be empty"));
                    }
                    let workspace_mm = c.positive(&format!("{field}.input.workspace_mm"), *workspace_mm)?;
                    let max_speed_mm_s = c.positive(&format!("{field}.input.max_speed_mm_s"), *max_speed_mm_s)?;
                    InputBinding::OpenIgtLink { device: device.clone(), workspace_m: workspace_mm * 1e-3, max_speed_m_s: max_speed_mm_s * 1e-3 }
                }
                InputFile::Trajectory => {
                    let Some((path, track)) = &trajectory else {
                        return Err(c.invalid(&format!("{field}.input"), "input `Trajectory` needs the scenario's `trajectory` file"));
                    };
                    if track.samples(i).is_empty() {
                        return Err(c.invalid(&format!("{field}.input"), format!(
                            "the trajectory {} has no rows for spatula {i}", path.display()
                        )));
                    }
                    InputBinding::Trajectory
                }
            };
            spatulas.push(SpatulaConfig { name: s.name.clone(), shape, layout, initial_pose, input });
        }

        let mut effects = EffectSet::default();
        for (i, e) in file.effects.iter().enumerate() {
            if !effects.insert(*e) {
                return Err(c.invalid(&format!("effects[{i}]"), format!("{e:?} is listed twice")));
            }
        }
        for (i, e) in file.effects.iter().enumerate() {
            let field = format!("effects[{i}]");
            match e {
                Effect::SkullSpheres if skull.is_none() => {
                    return Err(c.invalid(&field, "SkullSpheres needs the `skull` spheres, but `skull` is not given"));
                }
                Effect::Culling | Effect::ContactPressure if !effects.contains(Effect::Collision) => {
                    return Err(c.invalid(&field, format!("{e:?} needs the Collision effect")));
                }
                _ => {}
            }
        }

        let solver = SolverOptions {
            compliance_storage: match file.solver.compliance_storage {
                ComplianceStorage::LowRank { digits } if !(4..=12).contains(&digits) => {
                    return Err(c.invalid("solver.compliance_storage", format!("LowRank digits must be 4..=12, got {digits}")));
                }
                storage => storage,
            },
            region_of_interest: match &file.solver.region_of_interest {
                RegionOfInterestFile::Auto => RegionOfInterest::Auto,
                RegionOfInterestFile::All => RegionOfInterest::All,
                RegionOfInterestFile::Sphere { center_mm, radius_mm } => RegionOfInterest::Sphere(
                    c.sphere("solver.region_of_interest", &SphereFile { center_mm: *center_mm, radius_mm: *radius_mm })?,
                ),
            },
            cache_dir: match &file.solver.cache_dir {
                Some(d) if d.trim().is_empty() => return Err(c.invalid("solver.cache_dir", "the path is empty (use None for no cache)")),
                Some(d) => Some(PathBuf::from(d)),
                None => None,
            },
            spatula_contact: file.solver.spatula_contact,
        };

        let gravity = c.vec3("gravity_m_s2", file.gravity_m_s2)?;
        let density = c.positive("density_kg_m3", file.density_kg_m3)?;
        let time_step = c.positive("time_step_s", file.time_step_s)?;
        let duration = c.positive("duration_s", file.duration_s)?;
        if time_step > duration {
            return Err(c.invalid("time_step_s", format!("must not exceed duration_s ({duration} s), got {time_step}")));
        }
        if duration / time_step > 1e9 {
            return Err(c.invalid("duration_s", format!("{} steps of {time_step} s are too many (at most 1e9)", duration / time_step)));
        }
        if file.outputs.dir.trim().is_empty() {
            return Err(c.invalid("outputs.dir", "must not be empty"));
        }

        Ok(Scenario {
            name: file.name,
            source_path: document.path.clone(),
            mesh,
            material,
            region_materials,
            fixed,
            skull,
            spatulas,
            effects,
            collision_backend: file.collision.backend,
            swept_culling: file.collision.swept_culling,
            solver,
            gravity,
            density,
            time_step,
            duration,
            trajectory: trajectory.map(|(p, _)| p),
            outputs: Outputs { dir: PathBuf::from(&file.outputs.dir), vtk: file.outputs.vtk, frames: file.outputs.frames },
        })
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
        let _ = writeln!(
            s,
            "  material:  E = {} Pa, nu = {}{}",
            self.material.young_modulus,
            self.material.poisson_ratio,
            if self.region_materials.is_empty() { String::new() } else { format!(", {} region override(s)", self.region_materials.len()) }
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
                "  spatula {i} \"{}\": {:.1} x {:.1} x {:.2} mm, {layout}, at ({:.1}, {:.1}, {:.1}) mm, input {:?}",
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
        let _ = writeln!(s, "  collision: {:?}; compliance {:?}, region of interest {:?}", self.collision_backend, self.solver.compliance_storage, self.solver.region_of_interest);
        let _ = writeln!(s, "  time:      step {} s, duration {} s ({} steps)", self.time_step, self.duration, self.step_count());
        if let Some(t) = &self.trajectory {
            let _ = writeln!(s, "  trajectory: {}", t.display());
        }
        let _ = write!(s, "  outputs:   {} (vtk {}, frames {})", self.outputs.dir.display(), self.outputs.vtk, self.outputs.frames);
        s
    }
}

fn quoted(names: &[&str]) -> String {
    names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ")
}
