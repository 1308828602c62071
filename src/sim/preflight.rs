//! Preflight: everything a pipeline's build would refuse, checked without the
//! expensive work, so that `fissure check` and every command that builds a
//! pipeline (replay, run, study, screenshot) accept exactly the same scenes.
//!
//! In: a validated [`Scenario`] and optionally a trajectory that replaces its
//! own (`--trajectory`). Out: a [`Preflight`]: the mesh in metres with its
//! fixed-node mask ([`CheckedMesh`], what `Pipeline::build_checked` takes),
//! the pose track that will play ([`TrajectoryPoses`]), the warnings (the
//! scenario's and the played motion's) and the numbers `check` prints
//! ([`MeshFacts`], [`BladeTravel`]); or the first problem as a [`BuildError`] that names the scenario
//! file, line, column and field (or the trajectory file).
//!
//! Checks, in order: the mesh loads; the fixed selectors select a node, some
//! node stays free, and every connected component of the mesh has a fixed node
//! (else the stiffness is singular: the same `fem::assembly::check_components`
//! that `FemModel::new` runs); with `SkullSpheres`, every surface vertex at
//! rest lies inside `containing` and outside `excluding` (a brain that starts
//! through a sphere makes the unilateral solve chase thousands of rows); the
//! played trajectory loads and has no track for a spatula the scene lacks.
//! Warns when the played motion moves a blade more than its thickness in one
//! time step. Not done here: assembly, factorization and the compliance
//! precompute (seconds to minutes; with a validated material and a loaded mesh
//! they fail only on what these checks refuse, or on memory).
//! Stays true: no pipeline is built without these checks: `Pipeline::build`
//! runs [`preflight`] (the scenario's own trajectory), the replay runs it with
//! its `--trajectory` before `Pipeline::build_checked`, and
//! `Pipeline::build_with_mesh` (the study, which drives its own motion) runs
//! [`check_mesh`].

use std::path::Path;

use super::error::BuildError;
use super::pipeline::FrameInput;
use super::poses::TrajectoryPoses;
use super::scene_mesh::{fixed_nodes, load_mesh_noting};
use crate::fem::{self, FemError};
use crate::geometry::{Pose, SpatulaShape};
use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::mesh::quality::components;
use crate::scenario::error::ScenarioWarning;
use crate::scenario::{Effect, FixedRegion, Scenario, Sphere};

/// A surface vertex may lie this far (m) on the wrong side of a skull sphere
/// at rest (rounding in a landmark written to 0.1 mm is far larger).
pub const SKULL_REST_TOLERANCE_M: f64 = 1e-6;

/// At most this many time steps are walked to find the largest blade travel a
/// step; a longer motion is walked with a stride (the warning may then miss
/// a short burst).
pub const TRAVEL_STEPS_MAX: u64 = 200_000;

const MM: f64 = 1e-3;

/// The mesh in metres and its fixed-node mask, checked against the scenario.
pub struct CheckedMesh {
    /// The mesh, metres.
    pub mesh: TetMesh,
    /// Fixed-node mask (the union of the scenario's selectors): non-empty,
    /// leaves a node free, reaches every connected component.
    pub fixed: Vec<bool>,
    /// What the checks found.
    pub facts: MeshFacts,
}

/// Mesh numbers `fissure check` prints.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MeshFacts {
    /// Nodes.
    pub nodes: usize,
    /// Tetrahedra.
    pub tets: usize,
    /// Connected components.
    pub components: usize,
    /// Fixed nodes.
    pub fixed_nodes: usize,
    /// Surface vertices (counted only when the skull is checked).
    pub surface_vertices: Option<usize>,
    /// Smallest gap at rest between the surface and the containing sphere, m.
    pub containing_clearance: Option<f64>,
    /// Smallest gap at rest between the surface and the excluding sphere, m.
    pub excluding_clearance: Option<f64>,
    /// Nodes of the file or preset before any refinement.
    pub file_nodes: usize,
    /// Where the boundary was refined, in words; `None` when it was not.
    pub refined: Option<&'static str>,
}

/// The largest travel of one blade in one time step of the played motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BladeTravel {
    /// Spatula index.
    pub spatula: usize,
    /// Largest displacement of a blade corner in one step, m.
    pub travel: f64,
    /// End of that step, s.
    pub time_s: f64,
}

/// A blade that starts inside the tissue.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BladeInside {
    /// Spatula index.
    pub spatula: usize,
    /// The pose is the played trajectory's at time 0 (else the scenario's initial pose).
    pub from_trajectory: bool,
    /// Depth below the tissue's surface of the blade's deepest sample point, m.
    pub depth: f64,
    /// Where that point is, world, m.
    pub deepest: Vec3,
    /// How many of the blade's sample points lie inside, of `samples`.
    pub inside: usize,
    /// Sample points over the blade's mid-plane.
    pub samples: usize,
}

/// Everything checked before a build, and what the checks found.
pub struct Preflight {
    /// The mesh and its fixed nodes.
    pub mesh: CheckedMesh,
    /// The poses the run plays (the trajectory given, else the scenario's, else the initial poses held).
    pub poses: TrajectoryPoses,
    /// The largest travel a step of each spatula that moves (empty without a trajectory).
    pub travel: Vec<BladeTravel>,
    /// The blades whose first pose lies inside the tissue (each warned about).
    pub inside_at_start: Vec<BladeInside>,
    /// The scenario's warnings, then the played motion's.
    pub warnings: Vec<ScenarioWarning>,
}

impl Preflight {
    /// Logs every warning (`tracing::warn!`): what a build does, where `check` prints them.
    pub fn log_warnings(&self) {
        for w in &self.warnings {
            tracing::warn!("{w}");
        }
    }
}

/// Loads the scene's mesh and runs every check of this module (see the
/// module's docs); `trajectory` replaces the scenario's own.
pub fn preflight(scenario: &Scenario, trajectory: Option<&Path>) -> Result<Preflight, BuildError> {
    let loaded = load_mesh_noting(scenario).map_err(|e| match e {
        BuildError::MeshFile(source) => BuildError::Scenario(scenario.invalid(mesh_field(scenario), source.to_string())),
        other => other,
    })?;
    let mut checked = preflight_with_mesh(scenario, loaded.mesh, trajectory)?;
    (checked.mesh.facts.file_nodes, checked.mesh.facts.refined) = (loaded.file_nodes, loaded.refined);
    checked.warnings.extend(loaded.notes.into_iter().map(|n| scenario.warning("refine", n)));
    Ok(checked)
}

/// [`preflight`] on a mesh already loaded (metres).
pub fn preflight_with_mesh(scenario: &Scenario, mesh: TetMesh, trajectory: Option<&Path>) -> Result<Preflight, BuildError> {
    let mesh = check_mesh(scenario, mesh)?;
    let poses = TrajectoryPoses::for_scenario(scenario, trajectory)?;
    let travel = blade_travel(scenario, &poses);
    let mut warnings = scenario.checks.warnings.clone();
    let played = trajectory.map(Path::to_path_buf).or_else(|| scenario.trajectory.clone());
    // With sub-steps (the default) a fast blade is split and needs no warning
    // (`fissure check` prints the largest travel a step); without them, a step
    // longer than the blade's thickness can pull thin tissue through it.
    for t in travel.iter().filter(|_| scenario.solver.substep_travel.is_none()) {
        let shape = &scenario.spatulas[t.spatula].shape;
        if t.travel > shape.thickness {
            let name = &scenario.spatulas[t.spatula].name;
            let path = played.as_deref().map_or_else(String::new, |p| format!(" {}", p.display()));
            warnings.push(scenario.warning(
                "time_step_s",
                format!(
                    "the trajectory{path} moves spatula {} (\"{name}\") {:.3} mm in one step (the step ending at {:.3} s), more than \
                     its blade's thickness {:.3} mm, and solver.substep_travel is None (one step a frame): tissue thinner than that \
                     travel can pass through the blade; use sub-steps (solver.substep_travel: Some(0.125)) or \
                     time_step_s <= {:.2e} s",
                    t.spatula,
                    t.travel / MM,
                    t.time_s,
                    shape.thickness / MM,
                    scenario.time_step * shape.thickness / t.travel,
                ),
            ));
        }
    }
    let inside_at_start = blades_inside_at_start(scenario, &mesh.mesh, &poses);
    for b in &inside_at_start {
        let name = &scenario.spatulas[b.spatula].name;
        let p = b.deepest / MM;
        let (field, when) = match (&played, b.from_trajectory) {
            (Some(t), true) => ("trajectory".to_string(), format!("at the first pose of the trajectory {}", t.display())),
            _ => (format!("spatulas[{}]", b.spatula), "at its initial pose".to_string()),
        };
        warnings.push(scenario.warning(
            &field,
            format!(
                "spatula {} (\"{name}\") starts inside the tissue {when}: {} of its blade's {} sample points are inside, the \
                 deepest {:.2} mm below the surface at ({:.1}, {:.1}, {:.1}) mm. The first frame moves the tissue around it onto the \
                 blade's faces: vertices pulled through and a failed integrity check are likely. Start the blade outside the tissue \
                 and let the trajectory bring it in",
                b.spatula, b.inside, b.samples, b.depth / MM, p.x, p.y, p.z
            ),
        ));
    }
    Ok(Preflight { mesh, poses, travel, inside_at_start, warnings })
}

/// Sample points over a blade's mid-plane in its own frame: a grid of
/// `ALONG` x `ACROSS` from the handle end to the tip and edge to edge.
fn blade_samples(shape: &SpatulaShape) -> Vec<Vec3> {
    const ALONG: usize = 13;
    const ACROSS: usize = 5;
    let mut out = Vec::with_capacity(ALONG * ACROSS);
    for i in 0..ALONG {
        for j in 0..ACROSS {
            let x = shape.length * i as f64 / (ALONG - 1) as f64;
            let y = shape.width * (j as f64 / (ACROSS - 1) as f64 - 0.5);
            out.push(Vec3::new(x, y, 0.0));
        }
    }
    out
}

/// The blades whose first pose (the initial pose, or the played trajectory's
/// pose at time 0) puts part of the blade inside the mesh: a sample point is
/// inside when the boundary's winding number about it exceeds one half (the
/// boundary is closed and oriented outwards), and its depth is its distance
/// to the nearest boundary triangle.
pub fn blades_inside_at_start(scenario: &Scenario, mesh: &TetMesh, poses: &TrajectoryPoses) -> Vec<BladeInside> {
    let surface = mesh.boundary();
    let positions = surface.gather_positions(&mesh.positions);
    let (lo, hi) = crate::mesh::bounding_box(&mesh.positions);
    let mut first = FrameInput::default();
    poses.poses_at(0.0, &mut first);
    let mut found = Vec::new();
    for (s, spatula) in scenario.spatulas.iter().enumerate() {
        let samples = blade_samples(&spatula.shape);
        let mut candidates = vec![(spatula.initial_pose, false)];
        if let Some(Some(p)) = first.poses.get(s).filter(|_| poses.trajectory_end().is_some()) {
            candidates.push((*p, true));
        }
        let mut worst: Option<BladeInside> = None;
        for (pose, from_trajectory) in candidates {
            let world: Vec<Vec3> = samples.iter().map(|q| pose.transform_point(q)).collect();
            let inside: Vec<Vec3> = world
                .iter()
                .copied()
                .filter(|p| (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k]))
                .filter(|p| winding_number(&surface.triangles, &positions, p) > 0.5)
                .collect();
            let deepest = inside
                .iter()
                .map(|p| (distance_to_surface(&surface.triangles, &positions, p), *p))
                .fold(None::<(f64, Vec3)>, |best, c| if best.is_none_or(|b| c.0 > b.0) { Some(c) } else { best });
            if let Some((depth, point)) = deepest
                && worst.is_none_or(|w| depth > w.depth)
            {
                worst = Some(BladeInside { spatula: s, from_trajectory, depth, deepest: point, inside: inside.len(), samples: samples.len() });
            }
        }
        found.extend(worst);
    }
    found
}

/// The generalised winding number of a closed triangle surface about `p`:
/// 1 inside, 0 outside (the sum of the triangles' solid angles over 4 pi,
/// Van Oosterom and Strackee's formula).
fn winding_number(triangles: &[[u32; 3]], positions: &[Vec3], p: &Vec3) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let (a, b, c) = (positions[t[0] as usize] - p, positions[t[1] as usize] - p, positions[t[2] as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let numerator = a.dot(&b.cross(&c));
        let denominator = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Distance from `p` to the nearest triangle of the surface.
fn distance_to_surface(triangles: &[[u32; 3]], positions: &[Vec3], p: &Vec3) -> f64 {
    triangles
        .iter()
        .map(|t| (crate::geometry::closest_point(p, &positions[t[0] as usize], &positions[t[1] as usize], &positions[t[2] as usize]) - p).norm_squared())
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

fn mesh_field(scenario: &Scenario) -> &'static str {
    match scenario.mesh {
        crate::scenario::MeshSource::File { .. } => "mesh.path",
        crate::scenario::MeshSource::Phantom { .. } => "mesh",
    }
}

/// The checks that need the mesh: fixed nodes (non-empty, one per connected
/// component, some node free) and, with `SkullSpheres`, the skull at rest.
pub fn check_mesh(scenario: &Scenario, mesh: TetMesh) -> Result<CheckedMesh, BuildError> {
    let invalid = |field: &str, problem: String| BuildError::Scenario(scenario.invalid(field, problem));
    let fixed = fixed_nodes(&mesh, &scenario.fixed);
    let fixed_count = fixed.iter().filter(|&&f| f).count();
    if fixed_count == 0 {
        return Err(invalid("fixed", format!("{} select no node of the mesh ({})", selectors(&scenario.fixed), mesh_outline(&mesh))));
    }
    let comps = components(&mesh);
    let used = comps.node_component.iter().filter(|&&c| (c as usize) < comps.count).count();
    let used_fixed = fixed.iter().zip(&comps.node_component).filter(|&(&f, &c)| f && (c as usize) < comps.count).count();
    if used_fixed == used {
        return Err(invalid("fixed", format!("{} fix every node of the mesh ({used}): nothing is left to move", selectors(&scenario.fixed))));
    }
    if let Err(e) = fem::assembly::check_components(&mesh, &fixed) {
        return Err(match e {
            FemError::UnfixedComponent { component, nodes, first_node } => {
                let p = mesh.positions[first_node as usize] / MM;
                invalid("fixed", format!(
                    "mesh component {component} of {} ({nodes} nodes, lowest node {first_node} at ({:.1}, {:.1}, {:.1}) mm) has no \
                     fixed node, so its stiffness is singular: {} reach only the other components (LowestPerComponent(height_mm: ..) \
                     fixes every component)",
                    comps.count,
                    p.x,
                    p.y,
                    p.z,
                    selectors(&scenario.fixed)
                ))
            }
            other => BuildError::Fem(other),
        });
    }
    let mut facts = MeshFacts { nodes: mesh.node_count(), tets: mesh.tets.len(), components: comps.count, fixed_nodes: fixed_count, file_nodes: mesh.node_count(), ..Default::default() };
    if let Some(skull) = scenario.skull.filter(|_| scenario.effects.contains(Effect::SkullSpheres)) {
        let surface = mesh.boundary();
        facts.surface_vertices = Some(surface.vertices.len());
        let rest: Vec<Vec3> = surface.vertices.iter().map(|&n| mesh.positions[n as usize]).collect();
        if let Some(s) = skull.containing {
            facts.containing_clearance = Some(check_sphere(scenario, "skull.containing", &s, true, &rest, &surface.vertices)?);
        }
        if let Some(s) = skull.excluding {
            facts.excluding_clearance = Some(check_sphere(scenario, "skull.excluding", &s, false, &rest, &surface.vertices)?);
        }
    }
    if scenario.effects.contains(Effect::Tethers) {
        check_tethers(scenario, &mesh)?;
    }
    Ok(CheckedMesh { mesh, fixed, facts })
}

/// The tethers against the mesh at rest: every surface point within
/// [`super::tethers::MAX_SNAP_DISTANCE_M`] of the surface, every anchor outside the tissue.
fn check_tethers(scenario: &Scenario, mesh: &TetMesh) -> Result<(), BuildError> {
    use crate::scenario::{TetherPoint, Tethers};
    let surface = mesh.boundary();
    let rest: Vec<Vec3> = surface.vertices.iter().map(|&n| mesh.positions[n as usize]).collect();
    let check = |field: String, point: &TetherPoint| -> Result<(), BuildError> {
        match point {
            TetherPoint::Surface(p) => {
                let distance = super::tethers::snap(&surface.triangles, &rest, p).map_or(f64::INFINITY, |s| s.distance);
                if distance > super::tethers::MAX_SNAP_DISTANCE_M {
                    return Err(BuildError::Scenario(scenario.invalid(&field, format!(
                        "({:.2}, {:.2}, {:.2}) mm is {:.2} mm from the brain's surface: a tether's surface point must lie within {} mm of it",
                        p.x / MM, p.y / MM, p.z / MM, distance / MM, super::tethers::MAX_SNAP_DISTANCE_M / MM
                    ))));
                }
            }
            TetherPoint::Anchor(p) => {
                if winding_number(&surface.triangles, &rest, p) > 0.5 {
                    return Err(BuildError::Scenario(scenario.invalid(&field, format!(
                        "the anchor ({:.2}, {:.2}, {:.2}) mm lies inside the tissue: an anchor is a fixed point outside the brain (a sinus, the dura)",
                        p.x / MM, p.y / MM, p.z / MM
                    ))));
                }
            }
        }
        Ok(())
    };
    for (v, vessel) in scenario.tethers.vessels.iter().enumerate() {
        for (p, point) in vessel.points.iter().enumerate() {
            check(Tethers::vessel_point_field(v, p), point)?;
        }
    }
    for (b, band) in scenario.tethers.bands.iter().enumerate() {
        check(Tethers::band_end_field(b, 0), &TetherPoint::Surface(band.from))?;
        check(Tethers::band_end_field(b, 1), &TetherPoint::Surface(band.to))?;
    }
    Ok(())
}

/// Checks the rest surface against one sphere; returns the smallest gap (m).
fn check_sphere(scenario: &Scenario, field: &str, s: &Sphere, containing: bool, rest: &[Vec3], nodes: &[u32]) -> Result<f64, BuildError> {
    // gap > 0: on the right side; violation = -gap.
    let gap = |p: &Vec3| if containing { s.radius - (p - s.center).norm() } else { (p - s.center).norm() - s.radius };
    let mut worst = (f64::INFINITY, 0usize);
    let mut wrong = 0usize;
    for (k, p) in rest.iter().enumerate() {
        let g = gap(p);
        if g < worst.0 {
            worst = (g, k);
        }
        if g < -SKULL_REST_TOLERANCE_M {
            wrong += 1;
        }
    }
    if wrong == 0 {
        return Ok(worst.0);
    }
    let c = s.center / MM;
    let distances = rest.iter().map(|p| (p - s.center).norm());
    let (side, limit) = if containing {
        ("outside", format!("the smallest containing sphere with this centre has radius {:.2} mm", distances.fold(0.0, f64::max) / MM))
    } else {
        ("inside", format!("the largest excluding sphere with this centre has radius {:.2} mm", distances.fold(f64::INFINITY, f64::min) / MM))
    };
    Err(BuildError::Scenario(scenario.invalid(field, format!(
        "{wrong} of {} surface vertices of the mesh at rest lie {side} the sphere (centre ({:.1}, {:.1}, {:.1}) mm, radius {:.2} mm), \
         the deepest {:.3} mm {side} (node {}); {limit}",
        rest.len(),
        c.x,
        c.y,
        c.z,
        s.radius / MM,
        -worst.0 / MM,
        nodes[worst.1],
    ))))
}

/// The selectors as the file writes them: `fixed [RegionId(9), Box(..)]`.
fn selectors(fixed: &[FixedRegion]) -> String {
    let mm = |v: &Vec3| format!("({}, {}, {})", round_mm(v.x), round_mm(v.y), round_mm(v.z));
    let list: Vec<String> = fixed
        .iter()
        .map(|f| match f {
            FixedRegion::RegionId(id) => format!("RegionId({id})"),
            FixedRegion::Box { min, max } => format!("Box(min_mm: {}, max_mm: {})", mm(min), mm(max)),
            FixedRegion::Sphere(s) => format!("Sphere(center_mm: {}, radius_mm: {})", mm(&s.center), round_mm(s.radius)),
            FixedRegion::LowestPerComponent { height } => format!("LowestPerComponent(height_mm: {})", round_mm(*height)),
        })
        .collect();
    format!("the fixed selectors [{}]", list.join(", "))
}

fn round_mm(m: f64) -> f64 {
    (m / MM * 1e6).round() / 1e6
}

/// Region ids and bounding box of a mesh, for a selector that missed it.
fn mesh_outline(mesh: &TetMesh) -> String {
    let mut ids = mesh.regions.clone();
    ids.sort_unstable();
    ids.dedup();
    let shown: Vec<String> = ids.iter().take(20).map(u32::to_string).collect();
    let more = if ids.len() > 20 { format!(" and {} more", ids.len() - 20) } else { String::new() };
    let (lo, hi) = crate::mesh::bounding_box(&mesh.positions);
    format!(
        "{} nodes; region ids {}{more}; bounding box ({:.1}, {:.1}, {:.1}) to ({:.1}, {:.1}, {:.1}) mm",
        mesh.node_count(),
        shown.join(", "),
        lo.x / MM,
        lo.y / MM,
        lo.z / MM,
        hi.x / MM,
        hi.y / MM,
        hi.z / MM
    )
}

/// The corners of a blade in its own frame, m.
fn corners(shape: &SpatulaShape) -> [Vec3; 8] {
    let (l, w, h) = (shape.length, shape.width / 2.0, shape.thickness / 2.0);
    let mut out = [Vec3::zeros(); 8];
    for (k, c) in out.iter_mut().enumerate() {
        *c = Vec3::new(if k & 1 == 0 { 0.0 } else { l }, if k & 2 == 0 { -w } else { w }, if k & 4 == 0 { -h } else { h });
    }
    out
}

fn corner_travel(shape: &SpatulaShape, a: &Pose, b: &Pose) -> f64 {
    corners(shape).iter().map(|c| (b.transform_point(c) - a.transform_point(c)).norm()).fold(0.0, f64::max)
}

/// The largest travel of a blade corner in one time step, per spatula that the
/// played trajectory moves, over the steps a headless run plays (frame `k`
/// goes from the poses at `k dt` (the initial poses for `k = 0`) to those at
/// `(k + 1) dt`, as the replay does).
pub fn blade_travel(scenario: &Scenario, poses: &TrajectoryPoses) -> Vec<BladeTravel> {
    let Some(end) = poses.trajectory_end() else { return Vec::new() };
    let dt = scenario.time_step;
    // After the trajectory's last row every pose holds: no travel.
    let steps = scenario.step_count().min(((end / dt).ceil() as u64).saturating_add(1));
    let stride = steps.div_ceil(TRAVEL_STEPS_MAX).max(1);
    let initial: Vec<Pose> = scenario.spatulas.iter().map(|s| s.initial_pose).collect();
    let mut best: Vec<Option<BladeTravel>> = vec![None; initial.len()];
    let (mut before, mut after) = (FrameInput::default(), FrameInput::default());
    let mut k = 0;
    while k < steps {
        if k == 0 {
            before.poses = initial.iter().copied().map(Some).collect();
        } else {
            poses.poses_at(k as f64 * dt, &mut before);
        }
        let t = (k + 1) as f64 * dt;
        poses.poses_at(t, &mut after);
        for (s, sp) in scenario.spatulas.iter().enumerate() {
            if let (Some(Some(a)), Some(Some(b))) = (before.poses.get(s), after.poses.get(s)) {
                let travel = corner_travel(&sp.shape, a, b);
                if travel > 0.0 && best[s].is_none_or(|x| travel > x.travel) {
                    best[s] = Some(BladeTravel { spatula: s, travel, time_s: t });
                }
            }
        }
        k += stride;
    }
    best.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(dir: &Path, extra: &str) -> Scenario {
        let text = format!(
            r#"(
    name: "preflight",
    mesh: Phantom(preset: "small"),
    material: (young_modulus_pa: 3000.0, poisson_ratio: 0.45),
    fixed: [RegionId(3)],
    spatulas: [(name: "a", shape: (length_mm: 20.0, width_mm: 6.0, thickness_mm: 1.0), layout: Grid(along: 2, across: 2),
                pose: (position_mm: (0.0, 0.0, 70.0), rotation: Quaternion(1.0, 0.0, 0.0, 0.0)), input: Keyboard)],
    time_step_s: 0.01,
    duration_s: 1.0,
    {extra}
)"#
        );
        Scenario::from_str(&text, &dir.join("scene.ron"), &[]).unwrap_or_else(|e| panic!("{e}"))
    }

    fn refusal(s: &Scenario) -> String {
        match preflight(s, None) {
            Ok(_) => panic!("the scene must be refused"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn the_skull_at_rest_is_checked_only_when_simulated_and_reports_the_fit() {
        let dir = tempfile::tempdir().expect("tmp");
        let sphere = |r: f64| format!("skull: Some((containing: Some((center_mm: (0.5, 0.1, -12.4), radius_mm: {r}))))");
        let ok = preflight(&scene(dir.path(), &format!("{}, effects: [SkullSpheres]", sphere(100.8))), None).expect("the landmark fits");
        let clearance = ok.mesh.facts.containing_clearance.expect("checked");
        assert!(clearance > 0.0 && clearance < 0.01, "the landmark sphere clears the brain by a few mm: {clearance} m");
        // 1 mm tighter than the brain's farthest surface vertex: refused, with that radius named.
        let fit = 100.8 - clearance / MM;
        let tight = scene(dir.path(), &format!("{}, effects: [SkullSpheres]", sphere(fit - 1.0)));
        let message = refusal(&tight);
        assert!(message.contains("skull.containing: ") && message.contains("lie outside the sphere"), "{message}");
        assert!(message.contains("the deepest 1.000 mm outside"), "{message}");
        assert!(message.contains(&format!("the smallest containing sphere with this centre has radius {fit:.2} mm")), "{message}");
        // Without SkullSpheres the pipeline builds no skull stage, so there is nothing to refuse.
        assert!(preflight(&scene(dir.path(), &format!("{}, effects: []", sphere(fit - 1.0))), None).is_ok());
    }

    #[test]
    fn fixed_selectors_must_reach_a_node_and_leave_one_free() {
        let dir = tempfile::tempdir().expect("tmp");
        let mut s = scene(dir.path(), "effects: []");
        s.fixed = vec![FixedRegion::RegionId(7), FixedRegion::LowestPerComponent { height: 0.0001 }];
        let ok = preflight(&s, None).expect("the lowest 0.1 mm holds a node");
        assert!(ok.mesh.facts.fixed_nodes >= 1);
        s.fixed = vec![FixedRegion::RegionId(7)];
        let message = refusal(&s);
        assert!(message.contains("scene.ron:5:12: fixed: the fixed selectors [RegionId(7)] select no node"), "{message}");
        s.fixed = vec![FixedRegion::Sphere(Sphere { center: Vec3::zeros(), radius: 1.0 })];
        assert!(refusal(&s).contains("nothing is left to move"));
    }

    #[test]
    fn blade_travel_is_the_largest_corner_step_of_the_played_motion() {
        let dir = tempfile::tempdir().expect("tmp");
        let csv = dir.path().join("t.csv");
        // Still until 0.3 s, 3 mm along +y in the step to 0.31 s, then 10 mm along z over 0.69 s (0.145 mm a step).
        std::fs::write(
            &csv,
            "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0,0,0,0,70,1,0,0,0\n0.3,0,0,0,70,1,0,0,0\n0.31,0,0,3,70,1,0,0,0\n1.0,0,0,3,80,1,0,0,0\n",
        )
        .expect("write");
        let s = scene(dir.path(), "effects: []");
        let checked = preflight(&s, Some(&csv)).expect("valid");
        let [t] = checked.travel[..] else { panic!("one moving spatula: {:?}", checked.travel) };
        assert!((t.travel - 0.003).abs() < 1e-9 && (t.time_s - 0.31).abs() < 1e-9, "{t:?}");
        assert!(!checked.warnings.iter().any(|w| w.to_string().contains("time_step_s:")), "sub-steps split the jump: no warning");
        let mut one_step = s.clone();
        one_step.solver.substep_travel = None;
        let checked = preflight(&one_step, Some(&csv)).expect("valid");
        let warning = checked.warnings.iter().map(ToString::to_string).find(|w| w.contains("time_step_s:")).expect("3 mm > 1 mm thick");
        assert!(warning.contains("scene.ron:8:18: time_step_s: the trajectory") && warning.contains("3.000 mm in one step"), "{warning}");
        assert!(warning.contains("time_step_s <= 3.33e-3 s"), "{warning}");
        // Without a trajectory nothing moves and nothing is reported.
        assert!(preflight(&s, None).expect("valid").travel.is_empty());
    }
}
