//! Scenes and the per-frame invariants of the hard-case suite (`tests/suite/hard_*.rs`, `tests/hard_endurance.rs`).
//!
//! In: a mesh in millimetres, a material, blades, effects, optional skull
//! spheres. Out: a built [`Pipeline`] and its state; after each frame,
//! [`check_frame`] asserts the invariants every hard case shares and returns
//! the numbers the case prints and asserts on.
//!
//! The invariants (each with a message that names the case and the frame):
//! - every surface position, displacement, reaction and force is finite;
//! - every skull constraint holds at every surface vertex the spatulas do not
//!   hold: `|x - c| <= R (1 + 1e-9)` (containing), `>= r (1 - 1e-9)` (excluding);
//! - the conflict rules (collision module docs, rule 4; FEM `constrained.rs`):
//!   one target per surface vertex (a vertex two spatulas claim goes to the
//!   deepest claim), every enforced vertex ends exactly at its target (the solve
//!   is exact, 1e-9 m), and a sphere row on an enforced vertex carries no force;
//! - no adhesive contact force: the FEM's reactions are forces ON the tissue
//!   (`constrained.rs`: `C^T lambda is the force ON the tissue`); a spatula
//!   pushes its tissue along its claiming face's outward normal N, so the force
//!   on the tissue summed over each face's held vertices satisfies `F . N >= 0`,
//!   and a sphere row never pulls (`lambda >= 0` along its feasible direction).
//!   Per vertex, the bilateral enforced constraint can pull (a rim vertex the
//!   elastic solution would carry past the face plane is held back onto it):
//!   the worst such pull is returned as `max_vertex_pull_n`, printed, and
//!   asserted zero only where a case says so (see `docs/hard_cases.md`).
//! - the frame report's inverted-element count is returned (and printed).
#![allow(dead_code)]

use fissure::fem::ConstraintKind;
use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::scenario::Scenario;
use fissure::sim::{BuildOptions, FrameReport, Pipeline, SimState};
use std::fmt::Write as _;
use std::path::Path;

/// Relative tolerance of a skull constraint (the FEM's `SPHERE_TOLERANCE`).
pub const SKULL_TOLERANCE: f64 = 1e-9;
/// An enforced vertex must end this close to its target, m.
pub const TARGET_TOLERANCE_M: f64 = 1e-9;

/// One spatula of a test scene (millimetres).
#[derive(Debug, Clone)]
pub struct Blade {
    pub name: &'static str,
    pub length_mm: f64,
    pub width_mm: f64,
    pub thickness_mm: f64,
    pub along: u32,
    pub across: u32,
    pub position_mm: [f64; 3],
    /// RON text of the rotation, e.g. `Quaternion(1.0, 0.0, 0.0, 0.0)`.
    pub rotation: String,
}

impl Blade {
    /// A blade lying flat (face 0 normal +z, pointing +x) with its handle end at `position_mm`.
    pub fn flat(name: &'static str, position_mm: [f64; 3]) -> Self {
        Self {
            name,
            length_mm: 20.0,
            width_mm: 10.0,
            thickness_mm: 1.0,
            along: 10,
            across: 5,
            position_mm,
            rotation: "Quaternion(1.0, 0.0, 0.0, 0.0)".into(),
        }
    }
}

/// Everything a hard-case scene varies.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Mesh in millimetres.
    pub mesh: TetMesh,
    pub young_modulus_pa: f64,
    pub poisson_ratio: f64,
    /// (region id, E Pa, nu) overrides.
    pub regions: Vec<(u32, f64, f64)>,
    /// RON list body of fixed selectors.
    pub fixed: String,
    /// RON of the `skull` field's value, e.g. `Some((containing: None, excluding: Some(...)))`.
    pub skull: Option<String>,
    pub blades: Vec<Blade>,
    /// RON list body of effects.
    pub effects: String,
    /// RON of the region of interest.
    pub roi: String,
    /// Collision backend name (`Bvh`, `Reference`).
    pub backend: &'static str,
    /// `solver.spatula_contact`: `Unilateral` (the default) or `Bilateral` (the paper's).
    pub contact: &'static str,
    /// `solver.substep_travel`: `Some(0.125)` (the default) or `None` (one step a frame).
    pub substep_travel: &'static str,
}

impl Scene {
    /// A scene with brain-like defaults: E = 3 kPa, nu = 0.45, lowest 1 mm of each body fixed,
    /// collision with culling and force output, every surface vertex in the ROI.
    pub fn new(mesh: TetMesh, blades: Vec<Blade>) -> Self {
        Self {
            mesh,
            young_modulus_pa: 3000.0,
            poisson_ratio: 0.45,
            regions: Vec::new(),
            fixed: "LowestPerComponent(height_mm: 1.0)".into(),
            skull: None,
            blades,
            effects: "Collision, Culling, ForceOutput".into(),
            roi: "All".into(),
            backend: "Bvh",
            contact: "Unilateral",
            substep_travel: "Some(0.125)",
        }
    }

    /// The validated scenario (the mesh is written into `dir`), on the mesh
    /// exactly as given (`refine: None`): each hard case is built on its
    /// geometry, vertex for vertex.
    pub fn scenario(&self, dir: &Path) -> Scenario {
        let path = super::write_mesh(dir, "scene.msh", &self.mesh);
        let mut spatulas = String::new();
        for b in &self.blades {
            write!(
                spatulas,
                "(name: \"{}\", shape: (length_mm: {:?}, width_mm: {:?}, thickness_mm: {:?}), layout: Grid(along: {}, across: {}), \
                 pose: (position_mm: ({:?}, {:?}, {:?}), rotation: {}), input: Keyboard),\n",
                b.name, b.length_mm, b.width_mm, b.thickness_mm, b.along, b.across, b.position_mm[0], b.position_mm[1], b.position_mm[2], b.rotation
            )
            .unwrap();
        }
        let regions: Vec<String> =
            self.regions.iter().map(|(id, e, nu)| format!("(id: {id}, young_modulus_pa: {e:?}, poisson_ratio: {nu:?})")).collect();
        let text = format!(
            r#"(
    name: "hard case",
    mesh: File(path: "{}", units: Millimetres),
    refine: None,
    material: (young_modulus_pa: {:?}, poisson_ratio: {:?}, regions: [{}]),
    fixed: [{}],
    skull: {},
    spatulas: [{}],
    effects: [{}],
    collision: (backend: {}),
    solver: (compliance_storage: F64, region_of_interest: {}, cache_dir: None, spatula_contact: {}, substep_travel: {}),
    time_step_s: 0.01,
    duration_s: 1.0,
)"#,
            path.display(),
            self.young_modulus_pa,
            self.poisson_ratio,
            regions.join(", "),
            self.fixed,
            self.skull.as_deref().unwrap_or("None"),
            spatulas,
            self.effects,
            self.backend,
            self.roi,
            self.contact,
            self.substep_travel,
        );
        Scenario::from_str(&text, &dir.join("scene.ron"), &[]).unwrap_or_else(|e| panic!("test scenario is invalid: {e}\n{text}"))
    }

    /// Builds the pipeline and its initial state.
    pub fn build(&self, dir: &Path) -> (Pipeline, SimState) {
        Pipeline::build(&self.scenario(dir), BuildOptions::default()).unwrap_or_else(|e| panic!("build: {e}"))
    }
}

/// A 20 mm cube (5 cells a side, bottom fixed, its top at z = 20 mm) and a
/// flat 12 x 8 x 1 mm blade over the middle of its top, face 0 up and face 1
/// down, its mid-plane at `z_mm`: the press of the fast-tool and jitter cases.
pub fn block_press(z_mm: f64) -> Scene {
    let mesh = super::block(5, 5, 5, Vec3::new(20.0, 20.0, 20.0), Vec3::new(-10.0, -10.0, 0.0));
    let blade = Blade {
        name: "blade",
        length_mm: 12.0,
        width_mm: 8.0,
        thickness_mm: 1.0,
        along: 12,
        across: 8,
        position_mm: [-6.0, 0.0, z_mm],
        rotation: "Quaternion(1.0, 0.0, 0.0, 0.0)".into(),
    };
    let mut s = Scene::new(mesh, vec![blade]);
    s.effects = "Collision, Culling, ForceOutput, ContactPressure".into();
    s
}

/// Merges meshes (each in its own region id `1 + k`).
pub fn merge(meshes: &[TetMesh]) -> TetMesh {
    let mut positions = Vec::new();
    let mut tets = Vec::new();
    let mut regions = Vec::new();
    for (k, m) in meshes.iter().enumerate() {
        let base = positions.len() as u32;
        positions.extend_from_slice(&m.positions);
        tets.extend(m.tets.iter().map(|t| t.map(|n| n + base)));
        regions.extend(std::iter::repeat_n(1 + k as u32, m.tets.len()));
    }
    TetMesh::new(positions, tets, regions).expect("merged meshes are valid")
}

/// Two blocks (mm) with a fissure of `gap_mm` between them along x, centred on
/// x = 0: left x in [-gap/2 - w, -gap/2], right x in [gap/2, gap/2 + w];
/// y in [-d/2, d/2], z in [0, h]. `cells` along each axis of each block.
pub fn fissure_blocks(gap_mm: f64, w: f64, d: f64, h: f64, cells: [usize; 3]) -> TetMesh {
    let [nx, ny, nz] = cells;
    let size = Vec3::new(w, d, h);
    let left = super::block(nx, ny, nz, size, Vec3::new(-0.5 * gap_mm - w, -0.5 * d, 0.0));
    let right = super::block(nx, ny, nz, size, Vec3::new(0.5 * gap_mm, -0.5 * d, 0.0));
    merge(&[left, right])
}

/// Numbers of one checked frame.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameCheck {
    pub max_displacement_m: f64,
    pub inverted_elements: u32,
    pub constrained_vertices: u32,
    pub skull_contacts: u32,
    /// Largest `(R - |x-c|)` deficit of a satisfied skull constraint, relative to R (<= 1e-9 when satisfied).
    pub worst_skull_violation: f64,
    /// Largest pull (-F . N, N) at one enforced vertex (0 when every vertex is pushed).
    pub max_vertex_pull_n: f64,
    /// Largest push (F . N, N) at one enforced vertex.
    pub max_vertex_push_n: f64,
    /// Largest pull (-sum F . N over one face's held vertices, N) beyond round-off; 0 when no face pulls.
    pub max_face_pull_n: f64,
    /// Unilateral contacts released or sliding this frame (their hold would have pulled).
    pub released_vertices: usize,
    /// Estimate of cond(W) from the solver.
    pub conditioning: f64,
    pub dropped_rows: usize,
}

fn finite(v: &Vec3) -> bool {
    v.iter().all(|c| c.is_finite())
}

/// Asserts the shared invariants of a frame (see the module docs) except the
/// face-force sign, which it returns as `max_face_pull_n` ([`step_checked`]
/// asserts it); `label` names the case in messages.
pub fn check_frame(pipeline: &Pipeline, state: &SimState, report: &FrameReport, label: &str) -> FrameCheck {
    let f = report.frame;
    let ctx = |what: &str| format!("{label}, frame {f}: {what}");
    // 1. Finite values.
    for (v, (p, u)) in state.surface_positions.iter().zip(&state.surface_displacement).enumerate() {
        assert!(finite(p) && finite(u), "{}", ctx(&format!("surface vertex {v} is not finite: x {p:?}, u {u:?}")));
    }
    assert!(report.max_displacement_m.is_finite(), "{}", ctx("max displacement not finite"));
    let solution = pipeline.last_solution();
    for (k, r) in solution.reactions.iter().enumerate() {
        assert!(finite(r), "{}", ctx(&format!("reaction {k} is not finite: {r:?}")));
    }
    for (s, sr) in report.spatulas.iter().enumerate() {
        assert!(finite(&sr.force), "{}", ctx(&format!("spatula {s} force not finite")));
        assert!(sr.mean_pressure_pa.is_finite() && sr.contact_area_m2.is_finite(), "{}", ctx("pressure/area not finite"));
    }
    assert!(state.poses.iter().all(|p| p.is_valid()), "{}", ctx("a held pose is invalid"));

    // 2. Conflict rules: one target per vertex; enforced vertices exactly at their targets.
    let surface = pipeline.surface();
    let constraints = pipeline.last_constraints();
    let mut enforced_vertex = vec![false; state.surface_positions.len()];
    let targets = pipeline.collision().map(|c| c.output().targets.clone()).unwrap_or_default();
    for w in targets.windows(2) {
        assert!(w[0].vertex < w[1].vertex, "{}", ctx(&format!("vertex {} has two targets (conflict rule: one per vertex)", w[1].vertex)));
    }
    let mut max_pull: f64 = 0.0;
    let mut max_push: f64 = 0.0;
    let mut released_vertices = 0usize;
    let mut face_force = vec![[0.0f64; 2]; pipeline.spatula_shapes().len()];
    let released = pipeline.solver().released_nodes();
    let sliding = pipeline.solver().sliding_nodes();
    let mut held_nodes: Vec<u32> = constraints
        .iter()
        .filter(|c| c.kind.tool_displacement().is_some() && released.binary_search(&c.node).is_err() && sliding.binary_search(&c.node).is_err())
        .map(|c| c.node)
        .collect();
    held_nodes.sort_unstable();
    for (k, c) in constraints.iter().enumerate() {
        if let ConstraintKind::Barrier { displacement, normal } = c.kind {
            // A blade barrier: pushes along its normal only, and (unless a tool holds
            // the node) the vertex is not behind the face plane.
            let v = surface.node_to_vertex[c.node as usize] as usize;
            let n = normal.normalize();
            let r = solution.reactions[k];
            assert!((r - n * r.dot(&n)).norm() <= 1e-9 * r.norm() + 1e-15, "{}", ctx(&format!("barrier on vertex {v}: force {r:?} not along {n:?}")));
            assert!(r.dot(&n) >= -1e-12 * (1.0 + r.norm()), "{}", ctx(&format!("barrier pulls vertex {v}: {r:?}")));
            if held_nodes.binary_search(&c.node).is_err() && !pipeline.solver().model().is_fixed(c.node) {
                let gap = (state.surface_displacement[v] - displacement).dot(&n);
                assert!(gap >= -TARGET_TOLERANCE_M, "{}", ctx(&format!("vertex {v} lies {:e} m behind a blade barrier", -gap)));
            }
            continue;
        }
        if let Some(displacement) = c.kind.tool_displacement() {
            let v = surface.node_to_vertex[c.node as usize] as usize;
            if pipeline.solver().model().is_fixed(c.node) {
                // Conflict rule (FEM): a constraint on a fixed node is ignored, its reaction is zero.
                assert_eq!(solution.reactions[k], Vec3::zeros(), "{}", ctx(&format!("fixed vertex {v} carries a reaction")));
                assert_eq!(state.surface_displacement[v], Vec3::zeros(), "{}", ctx(&format!("fixed vertex {v} moved")));
                continue;
            }
            if released.binary_search(&c.node).is_ok() {
                // A released unilateral contact: no force, and not behind its face plane.
                assert_eq!(solution.reactions[k], Vec3::zeros(), "{}", ctx(&format!("released vertex {v} carries a reaction")));
                let ConstraintKind::Contact { normal, .. } = c.kind else {
                    panic!("{}", ctx(&format!("vertex {v} released but its constraint is bilateral")));
                };
                let gap = (state.surface_displacement[v] - displacement).dot(&normal.normalize());
                assert!(gap >= -TARGET_TOLERANCE_M, "{}", ctx(&format!("released vertex {v} lies {:e} m behind its face plane", -gap)));
                released_vertices += 1;
                continue;
            }
            if sliding.binary_search(&c.node).is_ok() {
                // Sliding on its face: on the plane, pushed along the normal only.
                let ConstraintKind::Contact { normal, .. } = c.kind else {
                    panic!("{}", ctx(&format!("vertex {v} slides but its constraint is bilateral")));
                };
                let n = normal.normalize();
                let r = solution.reactions[k];
                let gap = (state.surface_displacement[v] - displacement).dot(&n);
                assert!(gap.abs() <= TARGET_TOLERANCE_M, "{}", ctx(&format!("sliding vertex {v} is {gap:e} m off its face plane")));
                assert!((r - n * r.dot(&n)).norm() <= 1e-9 * r.norm() + 1e-15, "{}", ctx(&format!("sliding vertex {v}: force {r:?} not along the normal {n:?}")));
                assert!(r.dot(&n) >= -1e-12 * (1.0 + r.norm()), "{}", ctx(&format!("sliding vertex {v} is pulled: {r:?}")));
                max_push = max_push.max(r.dot(&n));
                released_vertices += 1;
                continue;
            }
            enforced_vertex[v] = true;
            let err = (state.surface_displacement[v] - displacement).norm();
            assert!(
                err <= TARGET_TOLERANCE_M,
                "{}",
                ctx(&format!("enforced vertex {v} misses its target by {err:e} m (exact solve): rest {:?}", pipeline.rest_positions()[v]))
            );
            // The claiming face of a collision target (a contact the pipeline adds itself
            // after a solve carries no target and is left out of the face sums).
            if let Ok(i) = targets.binary_search_by_key(&(v as u32), |t| t.vertex) {
                let t = targets[i];
                if t.displacement == displacement {
                    let along = solution.reactions[k].dot(&t.normal);
                    max_pull = max_pull.max(-along);
                    max_push = max_push.max(along);
                    face_force[t.spatula as usize][t.face as usize] += along;
                }
            }
        }
    }
    let reaction_scale = solution.reactions.iter().map(|r| r.norm()).fold(0.0, f64::max);
    // Round-off allowance: 1e-9 of the largest reaction, and 1e-12 N for a touching contact.
    let face_pull_tolerance = 1e-9 * reaction_scale + 1e-12;
    let mut max_face_pull: f64 = 0.0;
    for faces in &face_force {
        for &sum in faces {
            if -sum > face_pull_tolerance {
                max_face_pull = max_face_pull.max(-sum);
            }
        }
    }

    // 3. Skull: every sphere row pushes; every free surface vertex is on the right side.
    let mut worst: f64 = 0.0;
    if let Some(skull) = pipeline.skull() {
        let skull = skull.skull();
        for (k, c) in constraints.iter().enumerate() {
            let v = surface.node_to_vertex[c.node as usize] as usize;
            let r = solution.reactions[k];
            match c.kind {
                ConstraintKind::SphereInside { center, .. } => {
                    let inward = center - state.surface_positions[v];
                    if enforced_vertex[v] {
                        assert!(r.norm() == 0.0, "{}", ctx(&format!("sphere row on enforced vertex {v} carries {r:?} (enforced wins)")));
                    }
                    assert!(r.dot(&inward) >= -1e-12 * (1.0 + r.norm()), "{}", ctx(&format!("containing sphere pulls vertex {v}: {r:?}")));
                }
                ConstraintKind::SphereOutside { center, .. } => {
                    let outward = state.surface_positions[v] - center;
                    if enforced_vertex[v] {
                        assert!(r.norm() == 0.0, "{}", ctx(&format!("sphere row on enforced vertex {v} carries {r:?} (enforced wins)")));
                    }
                    assert!(r.dot(&outward) >= -1e-12 * (1.0 + r.norm()), "{}", ctx(&format!("excluding sphere pulls vertex {v}: {r:?}")));
                }
                ConstraintKind::Enforced { .. } | ConstraintKind::Contact { .. } | ConstraintKind::Barrier { .. } => {}
            }
        }
        for (v, p) in state.surface_positions.iter().enumerate() {
            if enforced_vertex[v] || pipeline.solver().model().is_fixed(surface.vertices[v]) {
                continue;
            }
            if let Some(s) = skull.containing {
                let excess = ((p - s.center).norm() - s.radius) / s.radius;
                worst = worst.max(excess);
                assert!(excess <= SKULL_TOLERANCE, "{}", ctx(&format!("vertex {v} outside the containing sphere by {excess:e} R")));
            }
            if let Some(s) = skull.excluding {
                let deficit = (s.radius - (p - s.center).norm()) / s.radius;
                worst = worst.max(deficit);
                assert!(deficit <= SKULL_TOLERANCE, "{}", ctx(&format!("vertex {v} inside the excluding sphere by {deficit:e} r")));
            }
        }
    }
    FrameCheck {
        max_displacement_m: report.max_displacement_m,
        inverted_elements: report.inverted_elements,
        constrained_vertices: report.constrained_vertices,
        skull_contacts: report.skull_contacts,
        worst_skull_violation: worst,
        max_vertex_pull_n: max_pull,
        max_vertex_push_n: max_push,
        max_face_pull_n: max_face_pull,
        released_vertices,
        conditioning: solution.conditioning,
        dropped_rows: solution.dropped_rows,
    }
}

/// Steps one frame with `poses` and checks it; prints a one-line summary.
pub fn step_checked(pipeline: &mut Pipeline, state: &mut SimState, poses: &[fissure::geometry::Pose], label: &str) -> (FrameReport, FrameCheck) {
    let input = fissure::sim::FrameInput { poses: poses.iter().copied().map(Some).collect() };
    let report = pipeline.step(state, &input).unwrap_or_else(|e| panic!("{label}: step failed: {e}")).clone();
    let check = check_frame(pipeline, state, &report, label);
    assert!(check.max_face_pull_n == 0.0, "{label}, frame {}: a blade face pulls the tissue (adhesive): {:e} N", report.frame, check.max_face_pull_n);
    println!(
        "{label}: frame {} constrained {} skull {} max|u| {:.4e} m inverted {} ({}) cond(W) {:.3e} dropped {} released {} pull {:.3e} N push {:.3e} N crossed {} penetrating {}",
        report.frame,
        check.constrained_vertices,
        check.skull_contacts,
        check.max_displacement_m,
        check.inverted_elements,
        if report.inverted_scope_all { "all tets" } else { "surface tets" },
        check.conditioning,
        check.dropped_rows,
        check.released_vertices,
        check.max_vertex_pull_n,
        check.max_vertex_push_n,
        report.crossed_vertices,
        report.penetrating_vertices,
    );
    (report, check)
}

/// The pose of a blade given in millimetres and a quaternion (w, x, y, z).
pub fn pose_mm(position_mm: [f64; 3], q: [f64; 4]) -> fissure::geometry::Pose {
    fissure::geometry::Pose::checked(Vec3::new(position_mm[0], position_mm[1], position_mm[2]) * 1e-3, q).expect("valid test pose")
}

/// Relative disagreement `max |u_fast - u_direct| / max |u_direct|` over the surface
/// between the pipeline's last frame and the direct reference solve (constrained DOFs
/// eliminated, `K_FF` factored anew) with the same enforced displacements and fixed
/// nodes. Valid for frames without active skull rows and without gravity.
/// The pipeline's whole surface is compared: the working region as the frame
/// left it, the rest brought up to date ([`Pipeline::with_whole_surface`]).
pub fn reference_disagreement(pipeline: &mut Pipeline, state: &SimState) -> f64 {
    let whole = pipeline.with_whole_surface(state).expect("the whole surface").into_owned();
    let state = &whole;
    let model = pipeline.solver().model();
    let mesh = model.mesh();
    let mut prescribed = Vec::new();
    for n in 0..mesh.node_count() as u32 {
        if model.is_fixed(n) {
            for c in 0..3 {
                prescribed.push((3 * n as usize + c, 0.0));
            }
        }
    }
    let released = pipeline.solver().released_nodes();
    let sliding = pipeline.solver().sliding_nodes();
    for c in pipeline.last_constraints() {
        if let Some(displacement) = c.kind.tool_displacement() {
            if released.binary_search(&c.node).is_ok() || sliding.binary_search(&c.node).is_ok() {
                continue;
            }
            for k in 0..3 {
                prescribed.push((3 * c.node as usize + k, displacement[k]));
            }
        }
    }
    // Unilateral rows that are not holds (sliding, released, blade barriers) act on the
    // tissue through their reactions: the direct solve gets them as nodal forces.
    let mut forces = vec![Vec3::zeros(); mesh.node_count()];
    for (c, r) in pipeline.last_constraints().iter().zip(&pipeline.last_solution().reactions) {
        let held = c.kind.tool_displacement().is_some() && released.binary_search(&c.node).is_err() && sliding.binary_search(&c.node).is_err();
        if c.kind.is_tool() && !held {
            forces[c.node as usize] += r;
        }
    }
    let direct = fissure::fem::reference::solve_direct(mesh, model.lame(), &prescribed, &forces).expect("reference solve");
    let surface = pipeline.surface();
    let mut err: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for (v, &node) in surface.vertices.iter().enumerate() {
        let u_ref = direct.displacement[node as usize];
        err = err.max((state.surface_displacement[v] - u_ref).norm());
        scale = scale.max(u_ref.norm());
    }
    if scale == 0.0 { err } else { err / scale }
}

/// Largest enforced displacement of the last frame (collision targets and any
/// contact the pipeline added after a solve), m. A vertex a blade barrier pushed
/// (active row: its reaction is not zero) counts with its displacement: the blade
/// put it there.
pub fn max_enforced_m(pipeline: &Pipeline) -> f64 {
    let surface = pipeline.surface();
    let solution = pipeline.last_solution();
    pipeline
        .last_constraints()
        .iter()
        .zip(&solution.reactions)
        .filter_map(|(c, r)| match c.kind {
            _ if pipeline.solver().model().is_fixed(c.node) => None,
            ConstraintKind::Barrier { .. } if r.norm() > 0.0 => {
                solution.displacement_surface.get(surface.node_to_vertex[c.node as usize] as usize).map(|u| u.norm())
            }
            kind => kind.tool_displacement().map(|d| d.norm()),
        })
        .fold(0.0, f64::max)
}
