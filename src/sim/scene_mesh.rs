//! The scene's mesh: loaded in metres, refined where the scenario's `refine`
//! asks (`Auto`, the default, along the blades' reach over the trajectory or
//! from their first poses), its fixed nodes, and the region of interest.
//!
//! In: a validated [`Scenario`] (and, for the region of interest, its mesh
//! and the pose sets the blades will visit). Out: a [`TetMesh`] in metres (a
//! refined mesh keeps the file's nodes first, in order), the fixed-node mask,
//! the region of interest's surface nodes, ascending. Stays true: the same
//! scenario gives the same mesh, mask and region, node for node; what
//! `refine: Auto` gives up is a note, never a refusal. The preflight checks
//! what these give; the build uses them.

use super::error::BuildError;
use super::pipeline::{SKULL_CANDIDATE_BAND_M, skull_gap};
use super::poses::TrajectoryPoses;
use crate::geometry::{Pose, distance_to_segment};
use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::mesh::quality::components;
use crate::mesh::refine::RefineError;
use crate::scenario::{Effect, FixedRegion, MeshSource, RefineChoice, RegionOfInterest, Scenario};

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
/// own trajectory (its initial poses, then the whole trajectory sampled from
/// its first row to its last), else its region-of-interest sphere, else (a
/// scene driven only by a keyboard, a gamepad or a tracker) the reach from the
/// blades' first poses.
///
/// The mesh is the scene's whatever is played on it: the run's length
/// (`duration_s`, which a session's debrief sets to its recording's) and a
/// trajectory played in place of the scene's own (`replay --trajectory`, a
/// window's recording) leave it as it is. A window's session, its recording's
/// replay and its debrief therefore run on one mesh, and a motion sampled
/// faster or slower meets the same tissue.
fn auto_region(scenario: &Scenario) -> Result<AutoRegion, BuildError> {
    if scenario.trajectory.is_some() {
        let poses = TrajectoryPoses::for_scenario(scenario, None)?;
        let span = poses.trajectory_end().unwrap_or(0.0).max(0.0);
        return Ok(AutoRegion::Trajectory(poses.samples(span, AUTO_REFINE_SAMPLES)));
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
                        let gap = skull_gap(&skull, &mesh.positions[n as usize]);
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
pub(super) fn blade_segments<'a>(scenario: &'a Scenario, set: &'a [Pose]) -> impl Iterator<Item = (Vec3, Vec3, f64)> + 'a {
    set.iter().zip(&scenario.spatulas).map(|(pose, sp)| {
        (pose.transform_point(&Vec3::zeros()), pose.transform_point(&Vec3::new(sp.shape.length, 0.0, 0.0)), 0.5 * sp.shape.width)
    })
}
