//! One study run: the scene set to a run's [`Settings`], built, and replayed
//! over the study motion, recording what the accuracy and timing tables need.
//!
//! In: the validated base scene, a [`Settings`], the [`Motion`], a compliance
//! cache folder, and a [`MeshStore`] (meshes are generated or read once per
//! study). Out: a [`RunTrace`]: per frame the stage times, contact count,
//! total spatula force, crossed / penetrating vertices, and (when asked) the
//! surface displacement; plus the build time and compliance size. Stays true:
//! the run is deterministic (the same settings give bitwise-equal
//! displacements); nothing is written to disk except the compliance cache.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::motion::{FrameKey, Motion};
use super::plan::{MeshChoice, RoiChoice, Settings};
use crate::geometry::Pose;
use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::scenario::{Effect, EffectSet, FixedRegion, LengthUnit, MeshSource, RegionOfInterest, Scenario, Skull, Sphere};
use crate::sim::{BuildError, BuildOptions, FrameInput, Pipeline, StageTimes, StepError};

/// Why one run could not be done (the study goes on and its row says so).
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("mesh {mesh}: {message}")]
    Mesh { mesh: String, message: String },
    #[error("build: {0}")]
    Build(#[from] BuildError),
    #[error("{0}")]
    Step(#[from] StepError),
    /// Not started: the study was interrupted before it (same words as [`super::NOT_RUN_INTERRUPTED`]).
    #[error("not run: the study was interrupted (Ctrl-C)")]
    Interrupted,
}

/// What one frame left behind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameRecord {
    pub key: FrameKey,
    pub times: StageTimes,
    /// Surface vertices the spatulas push (the frame is in contact when > 0).
    pub contact: u32,
    /// Sum of the spatulas' forces on the tissue, N.
    pub force: Vec3,
    pub crossed: u32,
    pub penetrating: u32,
    pub max_penetration_m: f64,
    /// Highest mean contact pressure over the spatulas, mmHg.
    pub pressure_mmhg: f64,
    /// Inverted elements after the frame.
    pub inverted: u32,
}

/// A finished run.
#[derive(Debug, Clone, Default)]
pub struct RunTrace {
    pub frames: Vec<FrameRecord>,
    /// Per frame, per surface vertex displacement, m (empty unless asked for).
    pub displacements: Vec<Vec<Vec3>>,
    /// Rest positions of the surface vertices, m.
    pub rest: Vec<Vec3>,
    /// Surface triangles (surface-vertex indices).
    pub triangles: Vec<[u32; 3]>,
    /// Mesh nodes.
    pub nodes: usize,
    /// Wall time of the build (assembly, factorization, compliance), s.
    pub build_s: f64,
    /// Bytes of the stored compliance.
    pub compliance_bytes: usize,
    /// Compliance came from the disk cache.
    pub compliance_cached: bool,
}

/// A mesh of the study, in metres, with the skull its skull knob turns on.
pub struct StudyMesh {
    pub mesh: TetMesh,
    /// The skull's spheres: the scene's own, a brain phantom's landmarks, or a
    /// sphere containing the mesh with [`SKULL_CLEARANCE_M`] to spare.
    pub skull: Skull,
}

/// Clearance of the containing sphere made for a mesh without skull landmarks
/// (the brain phantoms' own clearance).
pub const SKULL_CLEARANCE_M: f64 = 0.005;

/// A sphere around the bounding box's centre that contains every node with
/// [`SKULL_CLEARANCE_M`] to spare.
pub fn containing_skull(mesh: &TetMesh) -> Skull {
    let (lo, hi) = mesh.bounding_box();
    let center = (lo + hi) * 0.5;
    let radius = mesh.positions.iter().map(|p| (p - center).norm()).fold(0.0, f64::max) + SKULL_CLEARANCE_M;
    Skull { containing: Some(Sphere { center, radius }), excluding: None }
}

/// Meshes loaded once per study, in metres, and their refinements.
#[derive(Default)]
pub struct MeshStore {
    entries: Vec<(MeshChoice, StudyMesh)>,
    /// (mesh, edges across a blade) -> the mesh refined along the motion.
    refined: Vec<(MeshChoice, f64, TetMesh)>,
}

/// Blade speed (thicknesses a frame) of the motion the refine knob refines
/// along: a fixed sampling of the path, so every run of a mesh and
/// refinement gets the same refined mesh whatever its own speed.
const REFINE_SAMPLING_SPEED: f64 = 1.0;

/// At most this many pose sets of that motion are refined along.
const REFINE_SAMPLES: usize = 200;

impl MeshStore {
    /// The mesh of `choice` (generated / read on first use).
    pub fn get(&mut self, choice: &MeshChoice, scene: &Scenario) -> Result<&StudyMesh, RunError> {
        if let Some(k) = self.entries.iter().position(|(c, _)| c == choice) {
            return Ok(&self.entries[k].1);
        }
        let fail = |message: String| RunError::Mesh { mesh: choice.label(), message };
        let (mesh, skull) = match choice {
            // As its file has it: the study's refine knob decides what is refined.
            MeshChoice::Scene => (crate::sim::scene_mesh::load_unrefined(scene)?, scene.skull.clone()),
            MeshChoice::Phantom(name) => {
                use crate::mesh::phantom::{Landmarks, Preset, UnknownPreset, generate};
                let preset: Preset = name.parse().map_err(|e: UnknownPreset| fail(e.to_string()))?;
                let p = generate(preset).map_err(|e| fail(e.to_string()))?;
                let skull = match &p.landmarks {
                    Landmarks::Brain(b) => Some(Skull {
                        containing: Some(Sphere { center: b.skull_containing.centre, radius: b.skull_containing.radius }),
                        excluding: Some(Sphere { center: b.skull_excluding.centre, radius: b.skull_excluding.radius }),
                    }),
                    Landmarks::Block(_) => None,
                };
                (p.mesh, skull)
            }
            MeshChoice::File { path, .. } => {
                let mut m = crate::mesh::io::load_tet_mesh(path).map_err(|e| fail(e.to_string()))?;
                m.scale(1e-3);
                (m, None)
            }
        };
        let skull = skull.unwrap_or_else(|| containing_skull(&mesh));
        let mesh = StudyMesh { mesh, skull };
        self.entries.push((choice.clone(), mesh));
        Ok(&self.entries.last().expect("just pushed").1)
    }

    /// The mesh of `choice` refined along the motion of `scene` (a run's
    /// configured scene: its spatulas where the unrefined mesh put them) to a
    /// blade's width over `edges_across`, as `refine: Auto` refines a scene
    /// along its trajectory (made on first use).
    pub fn refined(&mut self, choice: &MeshChoice, edges_across: f64, scene: &Scenario, motion: &Motion) -> Result<&TetMesh, RunError> {
        if let Some(k) = self.refined.iter().position(|(c, e, _)| c == choice && *e == edges_across) {
            return Ok(&self.refined[k].2);
        }
        let initial: Vec<Pose> = scene.spatulas.iter().map(|s| s.initial_pose).collect();
        let thickness = scene.spatulas.first().map(|s| s.shape.thickness).unwrap_or(0.001);
        let frames = motion.frames(&initial, thickness, REFINE_SAMPLING_SPEED);
        let stride = frames.len().div_ceil(REFINE_SAMPLES).max(1);
        let sets: Vec<Vec<Pose>> = std::iter::once(initial).chain(frames.iter().step_by(stride).map(|f| f.poses.clone())).collect();
        let mesh = crate::sim::scene_mesh::refine_along(scene, &self.get(choice, scene)?.mesh, &sets, edges_across)?;
        self.refined.push((choice.clone(), edges_across, mesh));
        Ok(&self.refined.last().expect("just pushed").2)
    }
}

/// Places the scene's first spatula above the gap between the two largest
/// components of `mesh` (tip 2 mm above the highest node), keeping its orientation.
fn pose_above_gap(mesh: &TetMesh, scene: &Scenario) -> Option<Pose> {
    let comps = crate::mesh::quality::components(mesh);
    let mut sizes = vec![0usize; comps.count];
    for &c in &comps.node_component {
        if (c as usize) < comps.count {
            sizes[c as usize] += 1;
        }
    }
    let mut order: Vec<usize> = (0..comps.count).collect();
    order.sort_by_key(|&c| std::cmp::Reverse(sizes[c]));
    if order.len() < 2 {
        return None;
    }
    let top = mesh.positions.iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
    let band = top - 0.030;
    let mean_x = |c: usize| {
        let xs: Vec<f64> = mesh.positions.iter().zip(&comps.node_component).filter(|(_, k)| **k as usize == c).map(|(p, _)| p.x).collect();
        xs.iter().sum::<f64>() / xs.len().max(1) as f64
    };
    let (left, right) = if mean_x(order[0]) < mean_x(order[1]) { (order[0], order[1]) } else { (order[1], order[0]) };
    let (mut left_max, mut right_min, mut y_sum, mut y_n) = (f64::NEG_INFINITY, f64::INFINITY, 0.0, 0usize);
    for (p, &c) in mesh.positions.iter().zip(&comps.node_component) {
        if p.z < band {
            continue;
        }
        if c as usize == left {
            left_max = left_max.max(p.x);
        } else if c as usize == right {
            right_min = right_min.min(p.x);
        } else {
            continue;
        }
        y_sum += p.y;
        y_n += 1;
    }
    let spatula = scene.spatulas.first()?;
    if !left_max.is_finite() || !right_min.is_finite() || y_n == 0 {
        return None;
    }
    let tip = Vec3::new(0.5 * (left_max + right_min), y_sum / y_n as f64, top + 0.002);
    let rotation = spatula.initial_pose.rotation;
    Some(Pose { position: tip - rotation * Vec3::new(spatula.shape.length, 0.0, 0.0), rotation })
}

/// The base scene with a run's settings applied.
pub fn configure(base: &Scenario, settings: &Settings, motion: &Motion, mesh: &StudyMesh, cache_dir: Option<&Path>) -> Scenario {
    let mut s = base.clone();
    match &settings.mesh {
        MeshChoice::Scene => {}
        MeshChoice::Phantom(p) => s.mesh = MeshSource::Phantom { preset: p.clone() },
        MeshChoice::File { path, fix_height_m } => {
            s.mesh = MeshSource::File { path: path.clone(), units: LengthUnit::Millimetres };
            s.fixed = vec![FixedRegion::LowestPerComponent { height: *fix_height_m }];
            if let (Some(pose), Some(first)) = (pose_above_gap(&mesh.mesh, base), s.spatulas.first_mut()) {
                first.initial_pose = pose;
            }
        }
    }
    for sp in &mut s.spatulas {
        sp.layout = settings.layout.clone();
    }
    s.collision.backend = settings.backend;
    s.skull = settings.skull.then(|| mesh.skull.clone());
    let mut effects = EffectSet::default();
    for e in base.effects.iter() {
        if e != Effect::Culling && e != Effect::SkullSpheres {
            effects.insert(e);
        }
    }
    if settings.skull {
        effects.insert(Effect::SkullSpheres);
    }
    effects.insert(Effect::Collision);
    effects.insert(Effect::ForceOutput);
    effects.insert(Effect::ContactPressure);
    if settings.culling {
        effects.insert(Effect::Culling);
    }
    s.effects = effects;
    s.solver.compliance_storage = settings.storage;
    s.solver.region_of_interest = match settings.roi {
        RoiChoice::Auto => RegionOfInterest::Auto,
        RoiChoice::All => RegionOfInterest::All,
        RoiChoice::Sphere { radius_m } => {
            let (pose, length) = s.spatulas.first().map(|f| (f.initial_pose, f.shape.length)).unwrap_or_default();
            RegionOfInterest::Sphere(Sphere { center: motion.working_point(&pose, length), radius: radius_m })
        }
    };
    s.solver.cache_dir = cache_dir.map(PathBuf::from);
    s.solver.spatula_contact = settings.contact;
    s.solver.substep_travel = settings.substep_travel;
    s
}

/// Runs `settings` over the motion. `keep_displacements` stores the surface
/// displacement of every frame (for accuracy comparisons).
pub fn execute(
    base: &Scenario,
    settings: &Settings,
    motion: &Motion,
    meshes: &mut MeshStore,
    cache_dir: Option<&Path>,
    keep_displacements: bool,
) -> Result<RunTrace, RunError> {
    let study_mesh = meshes.get(&settings.mesh, base)?;
    let scene = configure(base, settings, motion, study_mesh, cache_dir);
    let mesh = match settings.refine {
        None => study_mesh.mesh.clone(),
        Some(across) => meshes.refined(&settings.mesh, across, &scene, motion)?.clone(),
    };
    let initial: Vec<Pose> = scene.spatulas.iter().map(|s| s.initial_pose).collect();
    let thickness = scene.spatulas.first().map(|s| s.shape.thickness).unwrap_or(0.001);
    let frames = motion.frames(&initial, thickness, settings.speed);
    let stride = (frames.len() / 200).max(1);
    let expected_poses = frames.iter().step_by(stride).map(|f| f.poses.clone()).collect();
    let t = Instant::now();
    let (mut pipeline, mut state) = Pipeline::build_with_mesh(&scene, mesh, BuildOptions { expected_poses, progress: None, ..BuildOptions::default() })?;
    let build_s = t.elapsed().as_secs_f64();
    let stats = pipeline.solver().compliance().stats();
    let mut trace = RunTrace {
        rest: pipeline.rest_positions().to_vec(),
        triangles: pipeline.surface().triangles.clone(),
        nodes: pipeline.mesh().node_count(),
        build_s,
        compliance_bytes: stats.bytes,
        compliance_cached: stats.from_cache,
        ..Default::default()
    };
    let mut input = FrameInput::default();
    // Each kept frame's nodal forces, for its far surface.
    let mut forces: Vec<Vec<(u32, Vec3)>> = Vec::new();
    for f in &frames {
        input.poses.clear();
        input.poses.extend(f.poses.iter().map(|p| Some(*p)));
        let r = pipeline.step(&mut state, &input)?;
        trace.frames.push(FrameRecord {
            key: f.key,
            times: r.times,
            // A blade that pushes is in contact, with the pressure stage's patch or without it.
            contact: r.spatulas.iter().map(|s| s.contact_vertices.max(u32::from(s.force.norm() > 0.0))).sum(),
            force: r.spatulas.iter().map(|s| s.force).sum(),
            crossed: r.crossed_vertices,
            penetrating: r.penetrating_vertices,
            max_penetration_m: r.max_penetration_m,
            pressure_mmhg: r.spatulas.iter().map(|s| s.mean_pressure_mmhg()).fold(0.0, f64::max),
            inverted: r.inverted_elements,
        });
        if keep_displacements {
            trace.displacements.push(state.surface_displacement.clone());
            forces.push(pipeline.solver().last_forces().to_vec());
        }
    }
    // The whole surface: the far part (no compliance rows) brought up to date,
    // after the frames, so that its solves take nothing from their times
    // (a solve a frame streamed the factor through the caches between them).
    for (k, (u, f)) in trace.displacements.iter_mut().zip(&forces).enumerate() {
        pipeline.whole_surface_for(k as u64, f, u)?;
    }
    Ok(trace)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::plan::{MeshChoice, base_settings};

    #[test]
    fn the_skull_knob_adds_the_meshes_skull_and_its_stage_and_nothing_else() {
        let scene = crate::study::load_scene(None).expect("built-in study scene");
        let mut meshes = MeshStore::default();
        let choice = MeshChoice::Phantom("small".into());
        let mesh = meshes.get(&choice, &scene).expect("phantom");
        let off = Settings { skull: false, ..base_settings(choice.clone()) };
        let on = Settings { skull: true, ..off.clone() };
        let motion = Motion::default();
        let a = configure(&scene, &off, &motion, mesh, None);
        let b = configure(&scene, &on, &motion, mesh, None);
        assert!(a.skull.is_none() && !a.effects.contains(Effect::SkullSpheres));
        assert!(b.effects.contains(Effect::SkullSpheres));
        let skull = b.skull.clone().expect("a skull");
        // The brain phantoms bring their landmarks: a containing sphere and the skull-base bump.
        assert!(skull.containing.is_some() && skull.excluding.is_some(), "{skull:?}");
        let (mut a2, mut b2) = (a.clone(), b.clone());
        a2.skull = None;
        b2.skull = None;
        b2.effects = a2.effects.clone();
        assert_eq!(format!("{a2:?}"), format!("{b2:?}"), "only the skull differs");
        // A mesh without landmarks gets a sphere containing every node with the clearance.
        let c = containing_skull(&mesh.mesh).containing.expect("sphere");
        let far = mesh.mesh.positions.iter().map(|p| (p - c.center).norm()).fold(0.0, f64::max);
        assert!((c.radius - far - SKULL_CLEARANCE_M).abs() < 1e-12);
    }

    #[test]
    fn the_refine_knob_refines_along_the_motion_once_for_every_speed() {
        let scene = crate::study::load_scene(None).expect("built-in study scene");
        let mut meshes = MeshStore::default();
        let choice = MeshChoice::Phantom("small".into());
        let motion = Motion::default();
        let settings = Settings { refine: Some(4.0), ..base_settings(choice.clone()) };
        let configured = configure(&scene, &settings, &motion, meshes.get(&choice, &scene).expect("phantom"), None);
        let coarse = meshes.get(&choice, &scene).expect("phantom").mesh.clone();
        let fine = meshes.refined(&choice, 4.0, &configured, &motion).expect("refined").clone();
        assert!(fine.node_count() > coarse.node_count(), "{} -> {} nodes", coarse.node_count(), fine.node_count());
        assert_eq!(fine.positions[..coarse.node_count()], coarse.positions[..], "every node kept, same index");
        // New nodes only near the blade's path: none beyond its reach from the working point.
        let blade = &configured.spatulas[0];
        let centre = motion.working_point(&blade.initial_pose, blade.shape.length);
        let reach = blade.shape.length + motion.insert_m + motion.open_m + blade.shape.width;
        assert!(fine.positions[coarse.node_count()..].iter().all(|p| (p - centre).norm() < reach));
        // Kept: asked again (by a run at any speed: the refinement samples the
        // path at its own fixed speed), nothing is refined again.
        let again = meshes.refined(&choice, 4.0, &configured, &motion).expect("kept");
        assert_eq!(again.positions, fine.positions);
        assert_eq!(meshes.refined.len(), 1);
    }
}
