//! Scenario -> pipeline: on the scene's mesh ([`super::scene_mesh`]: loaded,
//! refined, its fixed nodes and region of interest), choose the compliance's
//! rows and columns, and construct exactly the stages the scene's effects ask for.
//!
//! In: a validated [`Scenario`] (and optionally the poses it will visit, to
//! widen the automatic region of interest). Out: a [`Pipeline`] with all
//! one-time work done (assembly, factorization, compliance precompute or cache
//! load) and the initial [`SimState`]. Stays true: every build runs the
//! checks of [`mod@super::preflight`] first (so `fissure check` refuses what a
//! build refuses); a stage whose effect is not in the scene is `None` and
//! costs nothing per frame.

use super::error::BuildError;
use super::pipeline::{Pipeline, SKULL_CANDIDATE_BAND_M, SimState, SkullStage};
use super::preflight::{CheckedMesh, check_mesh, preflight};
use super::scene_mesh::{blade_segments, fixed_nodes, region_of_interest};
use crate::collision::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use crate::fem::{self, BodyForce, Compliance, ConstrainedSolver, FemModel, FemOptions, RegionMaterials};
use crate::geometry::{Pose, distance_to_segment};
use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::scenario::{CollisionBackend, ComplianceStorage as ScenarioStorage, Effect, Scenario};

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

/// Dates at the first frame the ROI nodes that have rows before any blade
/// comes near: a vertex within the skull stage's candidate band of a sphere at
/// rest (a candidate row every step, which reads its column from the first
/// frame on) and the tethers' free nodes (`tether_nodes`, in the ROI). Dated
/// by the blades alone, the default scene's skull-base vertices (0.12 mm from
/// their sphere at rest) waited in the window's first frame for the background
/// fill to reach their columns: 0.5-0.9 s on its refined mesh.
fn due_at_start(scenario: &Scenario, mesh: &TetMesh, roi: &[u32], tether_nodes: &[u32], reach: &mut [u32]) {
    if let (true, Some(skull)) = (scenario.effects.contains(Effect::SkullSpheres), scenario.skull.as_ref()) {
        for &n in roi {
            if super::pipeline::skull_gap(skull, &mesh.positions[n as usize]) < SKULL_CANDIDATE_BAND_M {
                if let Some(r) = reach.get_mut(n as usize) {
                    *r = 0;
                }
            }
        }
    }
    for &n in tether_nodes {
        if let Some(r) = reach.get_mut(n as usize) {
            *r = 0;
        }
    }
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
            default: to_fem(scenario.body.material),
            by_region: scenario.body.region_materials.iter().map(|r| (r.region, to_fem(r.material))).collect(),
        };
        let fem_options = FemOptions {
            gravity: effects
                .contains(Effect::Gravity)
                .then_some(BodyForce { density: scenario.body.density, acceleration: scenario.body.gravity }),
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
    let mut tether_nodes = tethers.as_ref().map(|t| fem::ConstrainedSolver::tether_nodes(&t.solver_links(surface))).unwrap_or_default();
    if tethers.is_some() {
        let fixed = fixed_nodes(mesh, &scenario.fixed);
        tether_nodes.retain(|&n| !fixed[n as usize]);
        roi.extend_from_slice(&tether_nodes);
        roi.sort_unstable();
        roi.dedup();
    }
    let mut reach = if early { reach_ranks(scenario, mesh, &roi, pose_sets) } else { Vec::new() };
    if early {
        due_at_start(scenario, mesh, &roi, &tether_nodes, &mut reach);
    }
    let collision = if scenario.effects.contains(Effect::Collision) {
        let config = CollisionConfig {
            backend: match scenario.collision.backend {
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
        stage.set_swept_culling(scenario.collision.swept_culling);
        Some(stage)
    } else {
        None
    };
    Ok(SurfaceSide { roi, reach, collision, tethers })
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
