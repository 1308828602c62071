//! Scenario -> pipeline: load the mesh, choose fixed nodes and the region of
//! interest, and construct exactly the stages the scene's effects ask for.
//!
//! In: a validated [`Scenario`] (and optionally the trajectory it will play, to
//! widen the automatic region of interest). Out: a [`Pipeline`] with all
//! one-time work done (assembly, factorization, compliance precompute or cache
//! load) and the initial [`SimState`]. Stays true: every build runs the
//! checks of [`super::preflight`] first (so `fissure check` refuses what a
//! build refuses); a stage whose effect is not in the scene is `None` and
//! costs nothing per frame.

use super::pipeline::{Pipeline, SKULL_CANDIDATE_BAND_M, SimState, SkullStage};
use super::preflight::{CheckedMesh, check_mesh, preflight};
use super::report::StageId;
use crate::collision::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use crate::fem::{self, BodyForce, Compliance, ConstrainedSolver, FemModel, FemOptions, RegionMaterials};
use crate::geometry::Pose;
use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::mesh::refine::RefineError;
use crate::mesh::quality::components;
use crate::scenario::{
    CollisionBackend, ComplianceStorage as ScenarioStorage, Effect, FixedRegion, MeshSource, RefineChoice, RegionOfInterest, Scenario,
    ScenarioError, TrajectoryError,
};
use std::path::PathBuf;

/// Errors building a pipeline; each says which input is at fault.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("loading the mesh: {0}")]
    MeshFile(#[from] crate::mesh::io::MeshFileError),
    #[error("generating phantom `{preset}`: {message}")]
    Phantom { preset: String, message: String },
    /// A scenario field that does not fit the mesh or the motion (fixed
    /// nodes, skull at rest, ...): file, line, column and field named.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The trajectory given in place of the scenario's cannot be read (the
    /// message is shown here, so it is not repeated as a cause).
    #[error("--trajectory: {0}")]
    Trajectory(TrajectoryError),
    /// The trajectory given in place of the scenario's has a track for a spatula the scene lacks.
    #[error("--trajectory: {problem}")]
    TrackCount { path: PathBuf, problem: String },
    #[error("scenario `{scenario}`: {message}")]
    Scene { scenario: PathBuf, message: String },
    #[error("FEM: {0}")]
    Fem(#[from] fem::FemError),
    #[error("collision: {0}")]
    Collision(#[from] crate::collision::CollisionError),
}

/// How far (m) from a spatula blade's centre line the automatic region of
/// interest reaches, beyond half the blade's width.
pub const AUTO_ROI_MARGIN_M: f64 = 0.020;

/// At most this many skull candidates at rest join the automatic region of
/// interest, least gap first (each costs a column of every surface row; a
/// contact beyond them gets its lazy column in the frame that needs it).
pub const AUTO_ROI_SKULL_MAX: usize = 64;

/// `refine: Auto` refines to this fraction of the narrowest blade's width: a
/// blade face then spans at least four edges across, so its force rests on a
/// patch of vertices rather than on the two or three a coarse surface puts
/// under it.
pub const AUTO_REFINE_EDGES_ACROSS: f64 = 4.0;

/// `refine: Auto` refines within this distance (m) beyond a blade's half
/// width of its centre line, at any pose the scenario's trajectory takes it
/// to: the face's footprint and a margin for the tissue it pushes aside.
pub const AUTO_REFINE_MARGIN_M: f64 = 0.003;

/// Pose sets sampled over the scenario's trajectory for `refine: Auto`.
const AUTO_REFINE_SAMPLES: usize = 200;

/// Loads the scene's mesh in metres, refined where the scenario's `refine`
/// asks; what `refine: Auto` had to give up is logged as a warning.
pub fn load_mesh(scenario: &Scenario) -> Result<TetMesh, BuildError> {
    let loaded = load_mesh_noting(scenario)?;
    for n in loaded.notes {
        tracing::warn!("{}", scenario.warning("refine", n));
    }
    Ok(loaded.mesh)
}

/// A scene's mesh as [`load_mesh_noting`] loaded it.
pub struct LoadedMesh {
    /// The mesh, metres.
    pub mesh: TetMesh,
    /// Nodes of the file or preset (a refined mesh keeps them first, in order).
    pub file_nodes: usize,
    /// Where the boundary was refined, in words; `None` with `refine: None`.
    pub refined: Option<&'static str>,
    /// What `refine: Auto` had to give up, each a warning on `refine` (the
    /// preflight reports them with its own).
    pub notes: Vec<String>,
}

/// [`load_mesh`], saying where it refined and what `refine: Auto` gave up.
pub fn load_mesh_noting(scenario: &Scenario) -> Result<LoadedMesh, BuildError> {
    let mesh = load_unrefined(scenario)?;
    let file_nodes = mesh.node_count();
    let loaded = |mesh, refined, notes| LoadedMesh { mesh, file_nodes, refined, notes };
    match &scenario.refine {
        RefineChoice::Off => Ok(loaded(mesh, None, Vec::new())),
        RefineChoice::Given(r) => {
            let mesh = refine(scenario, r.edge, &|p: &Vec3| r.within.iter().any(|v| v.contains(p)), &mesh)?;
            Ok(loaded(mesh, Some("inside the given volumes"), Vec::new()))
        }
        RefineChoice::Auto => {
            let region = auto_region(scenario)?;
            let (mesh, notes) = refine_auto(scenario, &region, mesh)?;
            Ok(loaded(mesh, Some(region.words()), notes))
        }
    }
}

/// `refine: Auto` over `region`: [`AUTO_REFINE_EDGES_ACROSS`] edges across
/// the narrowest blade; where that would pass the node limit (a small mesh
/// under a wide reach), half as many, with a note; where that too would, the
/// mesh as it is, with a note. A default never refuses a scene that says
/// nothing about refinement.
fn refine_auto(scenario: &Scenario, region: &AutoRegion, mesh: TetMesh) -> Result<(TetMesh, Vec<String>), BuildError> {
    let inside: Box<dyn Fn(&Vec3) -> bool + '_> = match region {
        AutoRegion::Trajectory(sets) | AutoRegion::FirstPoses(sets) => Box::new(along_inside(scenario, sets)),
        AutoRegion::Sphere(s) => Box::new(move |p: &Vec3| (p - s.center).norm() <= s.radius),
    };
    let mut passed = Vec::new();
    for across in [AUTO_REFINE_EDGES_ACROSS, AUTO_REFINE_EDGES_ACROSS / 2.0] {
        let edge = narrowest_blade(scenario) / across;
        match refine_boundary(edge, &*inside, &mesh) {
            Ok(refined) if passed.is_empty() => return Ok((refined, Vec::new())),
            Ok(refined) => {
                let note = format!("Auto refined to {:.3} mm edges ({across} across the narrowest blade), not {}", edge * 1e3, passed.join(", not "));
                return Ok((refined, vec![note]));
            }
            Err(RefineError::TooManyNodes { edge_mm, limit, .. }) => passed.push(format!("{edge_mm:.3} mm: that would pass {limit} nodes")),
            Err(e) => return Err(refine_refused(scenario, e)),
        }
    }
    let note = format!(
        "Auto left the mesh as it is, not {}; say `refine: None` to silence this, or give \
         `refine: Some((edge_mm: .., within: [..]))` a larger edge or a smaller volume",
        passed.join(", not ")
    );
    Ok((mesh, vec![note]))
}

/// Where `refine: Auto` refines.
enum AutoRegion {
    /// The blades' poses sampled over the scenario's trajectory.
    Trajectory(Vec<Vec<Pose>>),
    /// The scenario's region-of-interest sphere (a scene without a trajectory).
    Sphere(crate::scenario::Sphere),
    /// The reach from the blades' first poses ([`reach_from_start`]): a scene
    /// driven only by hand.
    FirstPoses(Vec<Vec<Pose>>),
}

impl AutoRegion {
    /// In words (`fissure check` says it).
    fn words(&self) -> &'static str {
        match self {
            AutoRegion::Trajectory(_) => "Auto, along the blades' reach over the trajectory",
            AutoRegion::Sphere(_) => "Auto, inside the region-of-interest sphere",
            AutoRegion::FirstPoses(_) => "Auto, along the blades' reach from their first poses (no trajectory: driven by hand)",
        }
    }
}

/// The region `refine: Auto` refines: the blades' reach along the scenario's
/// own trajectory (its initial poses, then the trajectory sampled over the
/// run), else its region-of-interest sphere, else (a scene driven only by a
/// keyboard, a gamepad or a tracker) the reach from the blades' first poses.
fn auto_region(scenario: &Scenario) -> Result<AutoRegion, BuildError> {
    if scenario.trajectory.is_some() {
        let poses = super::replay::PoseSource::for_scenario(scenario, None)?;
        return Ok(AutoRegion::Trajectory(poses.samples(scenario.duration, AUTO_REFINE_SAMPLES)));
    }
    Ok(match scenario.solver.region_of_interest {
        RegionOfInterest::Sphere(s) => AutoRegion::Sphere(s),
        _ => AutoRegion::FirstPoses(reach_from_start(scenario)),
    })
}

/// How far `refine: Auto` expects a blade of a scene with no trajectory to be
/// pushed on along its axis from its first pose, in blade lengths: a
/// retraction enters a fissure by a fraction of the blade (the shipped
/// openings go 18-19 mm deep with 60 mm blades).
pub const AUTO_REACH_ADVANCE_LENGTHS: f64 = 0.5;

/// How far `refine: Auto` expects such a blade to move along its face
/// normal, either way, in blade widths: a retraction spreads the fissure by
/// about a blade's width a side (the shipped openings: 7-13.5 mm with 8 mm blades).
pub const AUTO_REACH_SPREAD_WIDTHS: f64 = 1.5;

/// Steps sampled along each of the reach's two directions.
const AUTO_REACH_STEPS: usize = 8;

/// The pose sets a blade driven by hand can be expected to visit from its
/// first pose: pushed on along its axis by up to [`AUTO_REACH_ADVANCE_LENGTHS`]
/// of its length and moved along its face normal by up to
/// [`AUTO_REACH_SPREAD_WIDTHS`] of its width either way (each blade by its
/// own shape; the sets are a grid over the two).
pub fn reach_from_start(scenario: &Scenario) -> Vec<Vec<Pose>> {
    let steps = AUTO_REACH_STEPS;
    let mut sets = Vec::with_capacity((steps + 1) * (2 * steps + 1));
    for a in 0..=steps {
        for s in 0..=2 * steps {
            let (advance, spread) = (a as f64 / steps as f64, (s as f64 - steps as f64) / steps as f64);
            sets.push(
                scenario
                    .spatulas
                    .iter()
                    .map(|sp| {
                        let p = sp.initial_pose;
                        let along = p.rotation * Vec3::x() * (advance * AUTO_REACH_ADVANCE_LENGTHS * sp.shape.length);
                        let normal = p.rotation * Vec3::z() * (spread * AUTO_REACH_SPREAD_WIDTHS * sp.shape.width);
                        Pose { position: p.position + along + normal, ..p }
                    })
                    .collect(),
            );
        }
    }
    sets
}

/// `refine: Auto`'s edge length: the narrowest blade's width over [`AUTO_REFINE_EDGES_ACROSS`].
pub fn auto_edge(scenario: &Scenario) -> f64 {
    narrowest_blade(scenario) / AUTO_REFINE_EDGES_ACROSS
}

fn narrowest_blade(scenario: &Scenario) -> f64 {
    scenario.spatulas.iter().map(|s| s.shape.width).fold(f64::INFINITY, f64::min)
}

/// `mesh` refined as `refine: Auto` refines it, along the blades' reach at
/// `pose_sets` (each a pose a spatula of `scenario`): every boundary edge
/// within a blade's half width plus [`AUTO_REFINE_MARGIN_M`] of its centre
/// line at one of the poses, to the narrowest blade's width over
/// `edges_across`. The study's `refine` knob uses it with its own motion.
pub fn refine_along(scenario: &Scenario, mesh: &TetMesh, pose_sets: &[Vec<Pose>], edges_across: f64) -> Result<TetMesh, BuildError> {
    refine(scenario, narrowest_blade(scenario) / edges_across, &along_inside(scenario, pose_sets), mesh)
}

/// Whether a point lies within a blade's half width plus
/// [`AUTO_REFINE_MARGIN_M`] of its centre line at one of `pose_sets`.
fn along_inside(scenario: &Scenario, pose_sets: &[Vec<Pose>]) -> impl Fn(&Vec3) -> bool + use<> {
    let segments: Vec<(Vec3, Vec3, f64)> =
        pose_sets.iter().flat_map(|set| blade_segments(scenario, set).map(|(a, b, w)| (a, b, w + AUTO_REFINE_MARGIN_M)).collect::<Vec<_>>()).collect();
    let (lo, hi) = segments_box(&segments);
    move |p: &Vec3| (0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]) && segments.iter().any(|(a, b, r)| distance_to_segment(p, a, b) <= *r)
}

/// The box around every (a, b, r) segment grown by its r.
fn segments_box(segments: &[(Vec3, Vec3, f64)]) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
    for (a, b, r) in segments {
        lo = lo.inf(&(a.inf(b) - Vec3::repeat(*r)));
        hi = hi.sup(&(a.sup(b) + Vec3::repeat(*r)));
    }
    (lo, hi)
}

/// The scene's boundary refined to `edge` (m) where `inside`; at most four times the nodes.
fn refine(scenario: &Scenario, edge: f64, inside: &dyn Fn(&Vec3) -> bool, mesh: &TetMesh) -> Result<TetMesh, BuildError> {
    refine_boundary(edge, inside, mesh).map_err(|e| refine_refused(scenario, e))
}

/// A refinement's failure as the scenario's error on `refine`.
fn refine_refused(scenario: &Scenario, e: RefineError) -> BuildError {
    BuildError::Scenario(scenario.invalid("refine", e.to_string()))
}

/// [`crate::mesh::refine::refine_boundary`] with the scene's node limit, logged.
fn refine_boundary(edge: f64, inside: &dyn Fn(&Vec3) -> bool, mesh: &TetMesh) -> Result<TetMesh, RefineError> {
    let t = std::time::Instant::now();
    let limit = (4 * mesh.node_count()).max(mesh.node_count() + 10_000);
    let (refined, stats) = crate::mesh::refine::refine_boundary(mesh, edge, inside, limit)?;
    tracing::info!(
        "refined the boundary to {:.2} mm edges: {} nodes added ({} on the boundary), {} -> {} tetrahedra, {:.0} ms",
        edge * 1e3,
        stats.splits,
        stats.boundary_splits,
        mesh.tets.len(),
        refined.tets.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    Ok(refined)
}

/// Loads the scene's mesh in metres, as its file or preset has it.
pub fn load_unrefined(scenario: &Scenario) -> Result<TetMesh, BuildError> {
    match &scenario.mesh {
        MeshSource::Phantom { preset } => {
            let p: crate::mesh::phantom::Preset = preset
                .parse()
                .map_err(|e: crate::mesh::phantom::UnknownPreset| BuildError::Phantom { preset: preset.clone(), message: e.to_string() })?;
            let phantom = crate::mesh::phantom::generate(p)
                .map_err(|e| BuildError::Phantom { preset: preset.clone(), message: e.to_string() })?;
            Ok(phantom.mesh)
        }
        MeshSource::File { path, units } => {
            let mut mesh = crate::mesh::io::load_tet_mesh(path)?;
            mesh.scale(units.to_metres());
            Ok(mesh)
        }
    }
}

/// The fixed-node mask: the union of the scenario's selectors.
pub fn fixed_nodes(mesh: &TetMesh, fixed: &[FixedRegion]) -> Vec<bool> {
    let mut mask = vec![false; mesh.node_count()];
    for f in fixed {
        match *f {
            FixedRegion::RegionId(id) => {
                for (t, tet) in mesh.tets.iter().enumerate() {
                    if mesh.regions[t] == id {
                        for &n in tet {
                            mask[n as usize] = true;
                        }
                    }
                }
            }
            FixedRegion::Box { min, max } => {
                for (m, p) in mask.iter_mut().zip(&mesh.positions) {
                    *m |= (0..3).all(|k| p[k] >= min[k] && p[k] <= max[k]);
                }
            }
            FixedRegion::Sphere(s) => {
                for (m, p) in mask.iter_mut().zip(&mesh.positions) {
                    *m |= (p - s.center).norm() <= s.radius;
                }
            }
            FixedRegion::LowestPerComponent { height } => {
                let comps = components(mesh);
                let mut lowest = vec![f64::INFINITY; comps.count];
                for (n, p) in mesh.positions.iter().enumerate() {
                    let c = comps.node_component[n] as usize;
                    if c < comps.count {
                        lowest[c] = lowest[c].min(p.z);
                    }
                }
                for (n, p) in mesh.positions.iter().enumerate() {
                    let c = comps.node_component[n] as usize;
                    if c < comps.count && p.z <= lowest[c] + height {
                        mask[n] = true;
                    }
                }
            }
        }
    }
    mask
}

/// Distance from `p` to the segment a-b.
pub(super) fn distance_to_segment(p: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let s = if len2 > 0.0 { ((p - a).dot(&ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * s)).norm()
}

/// Surface nodes (mesh node ids) of the region of interest.
///
/// `Auto`: every surface vertex within `width/2 + AUTO_ROI_MARGIN_M` of a blade's
/// centre line at any of `poses` (the initial poses and the trajectory's samples),
/// and, when the scene asks for skull spheres, the skull candidates at rest
/// (within `SKULL_CANDIDATE_BAND_M` of a sphere; least gap first, at most
/// [`AUTO_ROI_SKULL_MAX`]), so a skull contact there never waits for a sparse solve.
pub fn region_of_interest(
    scenario: &Scenario,
    mesh: &TetMesh,
    surface_nodes: &[u32],
    poses: &[Vec<Pose>],
) -> Vec<u32> {
    match scenario.solver.region_of_interest {
        RegionOfInterest::All => surface_nodes.to_vec(),
        RegionOfInterest::Sphere(s) => {
            surface_nodes.iter().copied().filter(|&n| (mesh.positions[n as usize] - s.center).norm() <= s.radius).collect()
        }
        RegionOfInterest::Auto => {
            let segments: Vec<(Vec3, Vec3, f64)> =
                poses.iter().flat_map(|set| blade_segments(scenario, set)).map(|(a, b, w)| (a, b, w + AUTO_ROI_MARGIN_M)).collect();
            // A node within r of a segment is inside the segment's box grown
            // by r: one box test first skips the nodes far from every blade
            // (on the fine brain, most of 37k nodes against 400 segments).
            let (lo, hi) = segments_box(&segments);
            let mut roi: Vec<u32> = surface_nodes
                .iter()
                .copied()
                .filter(|&n| {
                    let p = mesh.positions[n as usize];
                    (0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]) && segments.iter().any(|(a, b, r)| distance_to_segment(&p, a, b) <= *r)
                })
                .collect();
            if let Some(skull) = scenario.skull.filter(|_| scenario.effects.contains(Effect::SkullSpheres)) {
                let mut near: Vec<(f64, u32)> = surface_nodes
                    .iter()
                    .filter(|n| roi.binary_search(n).is_err())
                    .filter_map(|&n| {
                        let gap = super::pipeline::skull_gap(&skull, &mesh.positions[n as usize]);
                        (gap < SKULL_CANDIDATE_BAND_M).then_some((gap, n))
                    })
                    .collect();
                near.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                roi.extend(near.iter().take(AUTO_ROI_SKULL_MAX).map(|x| x.1));
                roi.sort_unstable();
            }
            roi
        }
    }
}

/// Each blade of a pose set as its centre line (handle end, tip) and half width.
fn blade_segments<'a>(scenario: &'a Scenario, set: &'a [Pose]) -> impl Iterator<Item = (Vec3, Vec3, f64)> + 'a {
    set.iter().zip(&scenario.spatulas).map(|(pose, sp)| {
        (pose.transform_point(&Vec3::zeros()), pose.transform_point(&Vec3::new(sp.shape.length, 0.0, 0.0)), 0.5 * sp.shape.width)
    })
}

/// A blade "reaches" a node when the node is this close to the blade's
/// centre line beyond its half width (m): about where contact begins.
const REACH_MARGIN_M: f64 = 0.003;
/// Width of the distance shells that order the nodes no blade reaches (m).
const REACH_SHELL_M: f64 = 0.002;

/// How soon a blade reaches each ROI node (per mesh node; `u32::MAX` off the
/// ROI), which orders the compliance columns with `solver.early_start`: the
/// index of the first pose set (the start, then the expected poses in time
/// order) whose blades come within `width / 2 + REACH_MARGIN_M` of it, else
/// the number of sets plus its least distance to a blade over all the sets
/// in shells of [`REACH_SHELL_M`].
fn reach_ranks(scenario: &Scenario, mesh: &TetMesh, roi: &[u32], pose_sets: &[Vec<Pose>]) -> Vec<u32> {
    let segments: Vec<Vec<(Vec3, Vec3, f64)>> = pose_sets.iter().map(|set| blade_segments(scenario, set).collect()).collect();
    let mut rank = vec![u32::MAX; mesh.node_count()];
    for &n in roi {
        let p = mesh.positions[n as usize];
        let mut least = f64::INFINITY;
        let mut reached = None;
        for (k, set) in segments.iter().enumerate() {
            for (a, b, half_width) in set {
                let beyond = distance_to_segment(&p, a, b) - half_width;
                least = least.min(beyond);
                if beyond <= REACH_MARGIN_M {
                    reached = Some(k);
                }
            }
            if reached.is_some() {
                break;
            }
        }
        rank[n as usize] = match reached {
            Some(k) => k as u32,
            None => {
                let shells = if least.is_finite() { (least / REACH_SHELL_M).floor().clamp(0.0, 1e6) as u32 } else { 1_000_000 };
                (segments.len() as u32).saturating_add(shells)
            }
        };
    }
    rank
}

/// The speed a blade is assumed to move at toward tissue its expected path
/// does not reach (m/s): the keyboard's default speed. It dates the distance
/// shells of [`reach_ranks`] for [`reach_seconds`].
const REACH_HAND_SPEED_M_S: f64 = 0.01;

/// Seconds from the first frame until a blade is expected to reach a node of
/// reach `rank` ([`reach_ranks`], over `sets` pose sets: the start, then
/// expected sets `step_s` apart from time 0): the set's time; past the
/// expected path, its end plus the node's distance shells at
/// [`REACH_HAND_SPEED_M_S`]; never for a node off the ROI.
fn reach_seconds(rank: u32, sets: usize, step_s: f64) -> f64 {
    let r = rank as usize;
    if rank == u32::MAX {
        f64::INFINITY
    } else if r < sets {
        r.saturating_sub(1) as f64 * step_s
    } else {
        sets.saturating_sub(2) as f64 * step_s + (r - sets) as f64 * REACH_SHELL_M / REACH_HAND_SPEED_M_S
    }
}

/// Options of the build that are not in the scenario.
#[derive(Default)]
pub struct BuildOptions<'a> {
    /// Pose sets the spatulas will visit (e.g. trajectory samples), for `Auto` ROI.
    pub expected_poses: Vec<Vec<Pose>>,
    /// Seconds between the expected pose sets (the first at the first
    /// frame): when a blade reaches a node, for `background_columns`.
    pub expected_step_s: f64,
    /// Called with (done, total) while the compliance is computed.
    pub progress: Option<&'a mut dyn FnMut(usize, usize)>,
    /// With `solver.early_start`: return once the compliance's storage is
    /// allocated and the rest of its columns is predicted to stay ahead of
    /// the blades (each column final before the expected poses, or a blade
    /// at [`REACH_HAND_SPEED_M_S`] past them, reach its node:
    /// [`Compliance::wait_until_ahead`]), and compute the rest in the
    /// background (the window); a frame that still needs a column not yet
    /// computed waits for it. Otherwise every column is computed before the
    /// build returns.
    pub background_columns: bool,
}

impl Pipeline {
    /// Builds the pipeline the scenario asks for, and the initial state, after
    /// the whole [`preflight`] (with the scenario's own trajectory) whose
    /// warnings it logs.
    pub fn build(scenario: &Scenario, options: BuildOptions<'_>) -> Result<(Pipeline, SimState), BuildError> {
        let checked = preflight(scenario, None)?;
        checked.log_warnings();
        Self::build_checked(scenario, checked.mesh, options)
    }

    /// As [`Pipeline::build`], with the mesh already loaded (in metres) and
    /// checked by [`check_mesh`] only (the caller drives the motion, e.g. the study).
    pub fn build_with_mesh(scenario: &Scenario, mesh: TetMesh, options: BuildOptions<'_>) -> Result<(Pipeline, SimState), BuildError> {
        Self::build_checked(scenario, check_mesh(scenario, mesh)?, options)
    }

    /// The build proper, on a mesh that passed [`check_mesh`] for this scenario.
    pub fn build_checked(scenario: &Scenario, checked: CheckedMesh, mut options: BuildOptions<'_>) -> Result<(Pipeline, SimState), BuildError> {
        let effects = scenario.effects;
        let CheckedMesh { mesh, fixed, .. } = checked;
        let to_fem = |m: crate::scenario::Material| fem::Material { young_modulus: m.young_modulus, poisson_ratio: m.poisson_ratio };
        let materials = RegionMaterials {
            default: to_fem(scenario.material),
            by_region: scenario.region_materials.iter().map(|r| (r.region, to_fem(r.material))).collect(),
        };
        let fem_options = FemOptions {
            gravity: effects
                .contains(Effect::Gravity)
                .then_some(BodyForce { density: scenario.density, acceleration: scenario.gravity }),
        };
        let initial: Vec<Pose> = scenario.spatulas.iter().map(|s| s.initial_pose).collect();
        let mut pose_sets = vec![initial.clone()];
        pose_sets.extend(options.expected_poses.drain(..));
        let early = scenario.solver.early_start;
        // The model (assembly) on this thread; the surface's side (region of
        // interest, reach, the collision stage's BVH) on a second one: neither
        // reads the other, and on a cache hit they are the start's critical
        // path (the fine brain: 0.36 s and 0.27 s). The boundary surface is a
        // function of the mesh, so both threads' copies are equal.
        let (model, side) = std::thread::scope(|scope| {
            let side = std::thread::Builder::new().name("fissure-build".into()).spawn_scoped(scope, || {
                let surface = mesh.boundary();
                surface_side(scenario, &mesh, &surface, &pose_sets, early)
            });
            // The factor is made by the compliance build (or, when every
            // column comes from the cache, beside the first frames).
            let model = FemModel::new_deferred(&mesh, &materials, &fixed, &fem_options);
            let side = match side {
                Ok(handle) => handle.join().unwrap_or_else(|_| {
                    Err(BuildError::Scene { scenario: scenario.source_path.clone(), message: "the build's second thread stopped".into() })
                }),
                // No second thread: the same work here.
                Err(_) => surface_side(scenario, &mesh, &mesh.boundary(), &pose_sets, early),
            };
            (model, side)
        });
        let model = model?;
        let SurfaceSide { roi, reach, collision, tethers } = side?;
        let surface = model.surface().clone();
        let rest: Vec<Vec3> = surface.gather_positions(&mesh.positions);
        let storage = match scenario.solver.compliance_storage {
            ScenarioStorage::F64 => fem::ComplianceStorage::F64,
            ScenarioStorage::F32 => fem::ComplianceStorage::F32,
        };
        let mut no_progress = |_: usize, _: usize| {};
        let progress: &mut dyn FnMut(usize, usize) = match options.progress {
            Some(p) => p,
            None => &mut no_progress,
        };
        let rows = working_rows(scenario, &mesh, &surface.vertices, &roi);
        let compute = fem::ComputeOptions {
            storage,
            cache_dir: scenario.solver.cache_dir.as_deref(),
            reach: early.then_some(reach.as_slice()),
            background: early && options.background_columns,
            rows: rows.as_deref(),
        };
        let background = compute.background;
        let compliance = Compliance::compute_with(&model, &roi, compute, progress)?;
        if background {
            let (sets, step) = (pose_sets.len(), options.expected_step_s);
            compliance.wait_until_ahead(&|n| reach_seconds(reach.get(n as usize).copied().unwrap_or(u32::MAX), sets, step), progress)?;
        }
        let mut solver = ConstrainedSolver::new(model, compliance)?;
        if let Some(t) = &tethers {
            solver.set_tethers(&t.solver_links(&surface))?;
        }
        let skull = if effects.contains(Effect::SkullSpheres) {
            let skull = scenario.skull.ok_or_else(|| BuildError::Scene {
                scenario: scenario.source_path.clone(),
                message: "the SkullSpheres effect needs a `skull`".into(),
            })?;
            Some(SkullStage::new(skull, &surface.vertices))
        } else {
            None
        };
        let pipeline = Pipeline::assemble(scenario, mesh, surface, rest, solver, collision, skull, tethers)?;
        let state = pipeline.initial_state(&initial);
        Ok((pipeline, state))
    }
}

/// A skull sphere's rows: the surface vertices within this gap (m) of a
/// sphere at rest get compliance rows (the skull stage's candidate band and
/// the far vertices' tracking margin: the brain deforms toward the skull).
pub const SKULL_ROWS_GAP_M: f64 = SKULL_CANDIDATE_BAND_M + super::pipeline::FAR_TRACK_MARGIN_M;

/// The surface nodes that get compliance rows besides the ROI's (the
/// working region, `solver.row_band_mm`): within the band of an ROI node at
/// rest, or within [`SKULL_ROWS_GAP_M`] of a skull sphere. `None`: every
/// surface node (no band, or the band holds them all).
pub fn working_rows(scenario: &Scenario, mesh: &TetMesh, surface_nodes: &[u32], roi: &[u32]) -> Option<Vec<u32>> {
    let band = scenario.solver.row_band?;
    let skull = scenario.skull.filter(|_| scenario.effects.contains(Effect::SkullSpheres));
    let rows = rows_near(&mesh.positions, surface_nodes, roi, band, &|p: &Vec3| {
        skull.as_ref().is_some_and(|s| super::pipeline::skull_gap(s, p) < SKULL_ROWS_GAP_M)
    });
    (rows.len() < surface_nodes.len()).then_some(rows)
}

/// The `surface_nodes` within `band` (m) of an `roi` node, or where `also`
/// holds, in their order: the working region's rows ([`working_rows`]; the
/// fem bench takes the same rows).
pub fn rows_near(positions: &[Vec3], surface_nodes: &[u32], roi: &[u32], band: f64, also: &dyn Fn(&Vec3) -> bool) -> Vec<u32> {
    // ROI nodes hashed into cells of the band's size: a node within the
    // band of one lies in one of the 27 cells around its own.
    let cell = |p: &Vec3| -> [i64; 3] { [0, 1, 2].map(|i| (p[i] / band).floor() as i64) };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<Vec3>> = std::collections::HashMap::new();
    for &n in roi {
        let p = positions[n as usize];
        grid.entry(cell(&p)).or_default().push(p);
    }
    let near_roi = |p: &Vec3| {
        let c = cell(p);
        (-1..=1).any(|i| {
            (-1..=1).any(|j| {
                (-1..=1).any(|k| grid.get(&[c[0] + i, c[1] + j, c[2] + k]).is_some_and(|ps| ps.iter().any(|q| (q - p).norm() <= band)))
            })
        })
    };
    surface_nodes
        .iter()
        .copied()
        .filter(|&n| {
            let p = positions[n as usize];
            near_roi(&p) || also(&p)
        })
        .collect()
}

/// What the build derives from the boundary surface alone.
struct SurfaceSide {
    roi: Vec<u32>,
    /// Per node, how soon a blade reaches it (empty without `early_start`).
    reach: Vec<u32>,
    collision: Option<CollisionStage>,
    /// The tethers snapped to the surface (the `Tethers` effect).
    tethers: Option<super::tethers::TetherStage>,
}

/// The region of interest, the reach ranks and the collision stage, from the
/// mesh's boundary `surface` (the model's, computed apart).
fn surface_side(scenario: &Scenario, mesh: &TetMesh, surface: &crate::mesh::BoundarySurface, pose_sets: &[Vec<Pose>], early: bool) -> Result<SurfaceSide, BuildError> {
    let mut roi = region_of_interest(scenario, mesh, &surface.vertices, pose_sets);
    // The tethers' nodes join the region of interest: their rows read K^-1 between them and every row of W,
    // which a ROI column answers exactly without a sparse solve in the frame.
    let tethers = scenario.effects.contains(Effect::Tethers).then(|| {
        let rest: Vec<Vec3> = surface.gather_positions(&mesh.positions);
        super::tethers::TetherStage::new(&scenario.tethers, surface, &rest)
    });
    if let Some(t) = &tethers {
        let fixed = super::build::fixed_nodes(mesh, &scenario.fixed);
        roi.extend(fem::ConstrainedSolver::tether_nodes(&t.solver_links(surface)).into_iter().filter(|&n| !fixed[n as usize]));
        roi.sort_unstable();
        roi.dedup();
    }
    let reach = if early { reach_ranks(scenario, mesh, &roi, pose_sets) } else { Vec::new() };
    let collision = if scenario.effects.contains(Effect::Collision) {
        let config = CollisionConfig {
            backend: match scenario.collision_backend {
                CollisionBackend::Reference => BackendKind::Reference,
                CollisionBackend::Bvh => BackendKind::Bvh,
                CollisionBackend::Gpu => BackendKind::Gpu,
                CollisionBackend::Auto => BackendKind::Auto,
            },
            culling: scenario.effects.contains(Effect::Culling),
        };
        let specs: Vec<SpatulaSpec> = scenario.spatulas.iter().map(|s| SpatulaSpec { shape: s.shape, layout: s.layout.clone() }).collect();
        let rest: Vec<Vec3> = surface.gather_positions(&mesh.positions);
        let mut stage = CollisionStage::new(config, &surface.triangles, &rest, &specs)?;
        stage.set_swept_culling(scenario.swept_culling);
        Some(stage)
    } else {
        None
    };
    Ok(SurfaceSide { roi, reach, collision, tethers })
}

/// The stages a scenario's effects build, in frame order (for output columns).
pub fn stages_for(scenario: &Scenario) -> Vec<StageId> {
    let e = scenario.effects;
    let mut v = Vec::new();
    if e.contains(Effect::Collision) {
        v.push(StageId::Collision);
    }
    if e.contains(Effect::SkullSpheres) {
        v.push(StageId::Skull);
    }
    v.push(StageId::Solve);
    if e.contains(Effect::ForceOutput) || e.contains(Effect::ContactPressure) {
        v.push(StageId::Forces);
    }
    if e.contains(Effect::StressField) {
        v.push(StageId::Stress);
    }
    if e.contains(Effect::Collision) {
        v.push(StageId::Monitor);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reach_dates_the_expected_sets_then_the_shells_at_hand_speed() {
        // The start and 201 expected sets 20 ms apart (a 4 s motion).
        let (sets, step) = (202, 0.02);
        assert_eq!(reach_seconds(0, sets, step), 0.0);
        assert_eq!(reach_seconds(1, sets, step), 0.0);
        assert!((reach_seconds(51, sets, step) - 1.0).abs() < 1e-12);
        assert!((reach_seconds(201, sets, step) - 4.0).abs() < 1e-12);
        // Past the path: 2 mm shells at 10 mm/s after its end.
        assert!((reach_seconds(202 + 3, sets, step) - 4.6).abs() < 1e-12);
        // Without an expected path (a hand drives): from the start.
        assert!((reach_seconds(1 + 5, 1, 0.0) - 1.0).abs() < 1e-12);
        assert_eq!(reach_seconds(u32::MAX, sets, step), f64::INFINITY);
    }
}
