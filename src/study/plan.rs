//! What a study runs: sweeps of one knob each, every run a full [`Settings`].
//!
//! In: a preset (quick, full, ci) or a hand-made [`StudyPlan`]. Out: one
//! reference run for the whole study (the finest setting of every knob at once:
//! finest mesh, densest nodes, the brute-force reference backend, f64,
//! whole-surface compliance, half the smallest swept speed, the finest
//! sub-step) and the sweeps. Stays true: a sweep's runs differ from the base
//! only in the swept knob (the backend sweep also crosses the node count, to
//! draw time against nodes per backend; the contact sweep crosses culling, the
//! contact model and two speeds); the reference differs from the base in every
//! knob, so no swept run equals it by construction.

use crate::geometry::NodeLayout;
use crate::scenario::{CollisionBackend, ComplianceStorage, SpatulaContact};
use std::path::PathBuf;

use super::motion::Motion;

/// The knobs a study sweeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Knob {
    /// Source nodes a face and their layout.
    SourceNodes,
    /// Mesh resolution.
    Mesh,
    /// Spatula speed a frame, in blade thicknesses.
    Speed,
    /// His-flag culling on and off under each contact law (sliding, the
    /// default; unilateral stick; the paper's bilateral hold), at a slow and
    /// a fast speed.
    Contact,
    /// Sub-steps: the largest blade travel of one sub-step, at a fast speed.
    Substeps,
    /// Collision backend, across node counts.
    Backend,
    /// Storage of the precomputed compliance.
    Storage,
    /// Region of interest of the precomputed compliance.
    RegionOfInterest,
    /// The skull's spheres (the mesh's own skull landmarks, or a sphere
    /// containing the mesh) off and on.
    Skull,
    /// The boundary refined where the blades reach (what `refine: Auto`
    /// does), to a blade's width over this many edges; or the mesh as it is.
    Refine,
}

impl Knob {
    /// Name in the CSV and the report.
    pub fn name(self) -> &'static str {
        match self {
            Knob::SourceNodes => "source_nodes",
            Knob::Mesh => "mesh",
            Knob::Speed => "speed",
            Knob::Contact => "contact",
            Knob::Substeps => "substeps",
            Knob::Backend => "backend",
            Knob::Storage => "storage",
            Knob::RegionOfInterest => "region_of_interest",
            Knob::Skull => "skull",
            Knob::Refine => "refine",
        }
    }

    /// Which of a sweep's runs of this knob (by their [`RunSpec::value`]s) is
    /// its finest setting, the one
    /// each run's own convergence is judged against: the most source nodes,
    /// the finest mesh (meshes come coarsest first), the slowest blade, the
    /// shortest sub-step, the most edges across a blade. `None` for a knob
    /// whose settings are not coarser and finer versions of one another
    /// (contact law and culling, backend, storage, region, skull).
    pub fn finest(self, values: &[f64]) -> Option<usize> {
        let pick = |finer: fn(f64, f64) -> bool| {
            let mut best: Option<usize> = None;
            for (i, &v) in values.iter().enumerate() {
                if best.is_none_or(|b| finer(v, values[b])) {
                    best = Some(i);
                }
            }
            best
        };
        match self {
            Knob::SourceNodes | Knob::Mesh | Knob::Refine => pick(|a, b| a > b),
            Knob::Speed | Knob::Substeps => pick(|a, b| a < b),
            Knob::Contact | Knob::Backend | Knob::Storage | Knob::RegionOfInterest | Knob::Skull => None,
        }
    }

    /// The knob of a [`Knob::name`].
    pub fn from_name(name: &str) -> Option<Knob> {
        Knob::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Every knob, in report order.
    pub const ALL: [Knob; 10] = [
        Knob::SourceNodes,
        Knob::Mesh,
        Knob::Speed,
        Knob::Contact,
        Knob::Substeps,
        Knob::Backend,
        Knob::Storage,
        Knob::RegionOfInterest,
        Knob::Skull,
        Knob::Refine,
    ];
}

/// Which mesh a run uses.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshChoice {
    /// The scene's own mesh, as its file or preset has it (unrefined: the refine knob refines).
    Scene,
    /// A procedural phantom preset ("small", "paper-9k", "paper-12k").
    Phantom(String),
    /// A mesh file in millimetres whose lowest `fix_height_m` of each
    /// connected component is fixed (the real brain: two hemispheres); the
    /// spatula is placed above the gap between its two highest components.
    File { path: PathBuf, fix_height_m: f64 },
}

impl MeshChoice {
    /// Short name for tables.
    pub fn label(&self) -> String {
        match self {
            MeshChoice::Scene => "scene".into(),
            MeshChoice::Phantom(p) => p.clone(),
            MeshChoice::File { path, .. } => crate::mesh::brain::label(path),
        }
    }
}

/// Region of interest of the compliance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RoiChoice {
    /// The solver's automatic choice from the spatula's path.
    Auto,
    /// Every surface vertex.
    All,
    /// Surface vertices within this radius (m) of the motion's working point.
    Sphere { radius_m: f64 },
}

impl RoiChoice {
    pub fn label(&self) -> String {
        match self {
            RoiChoice::Auto => "auto".into(),
            RoiChoice::All => "all".into(),
            RoiChoice::Sphere { radius_m } => format!("sphere {:.0} mm", radius_m * 1e3),
        }
    }
}

/// Everything that defines one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    pub mesh: MeshChoice,
    /// Source-node layout of every spatula face.
    pub layout: NodeLayout,
    pub backend: CollisionBackend,
    /// His-flag culling on.
    pub culling: bool,
    /// Sideways speed, blade thicknesses a frame (> 0).
    pub speed: f64,
    pub storage: ComplianceStorage,
    pub roi: RoiChoice,
    /// How a spatula holds the tissue it claims.
    pub contact: SpatulaContact,
    /// Largest blade travel of one sub-step, thicknesses; `None`: one step a frame.
    pub substep_travel: Option<f64>,
    /// The skull's spheres are simulated (see [`Knob::Skull`]).
    pub skull: bool,
    /// The boundary refined along the motion to the blade's width over this
    /// many edges (see [`Knob::Refine`]); `None`: the mesh as it is.
    pub refine: Option<f64>,
}

impl Settings {
    /// Source nodes a face.
    pub fn nodes_per_face(&self) -> usize {
        match &self.layout {
            NodeLayout::Grid { along, across } => (*along as usize) * (*across as usize),
            NodeLayout::TipConcentrated { count, .. } => *count as usize,
            NodeLayout::Explicit(v) => v.len(),
        }
    }

    pub fn layout_label(&self) -> String {
        match &self.layout {
            NodeLayout::Grid { along, across } => format!("grid {along}x{across}"),
            NodeLayout::TipConcentrated { count, tip_fraction } => format!("tip {count} ({tip_fraction})"),
            NodeLayout::Explicit(v) => format!("explicit {}", v.len()),
        }
    }
}

/// One run of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    /// The value of the knob, as a table shows it.
    pub label: String,
    /// The value as a number for plots (nodes a face, thicknesses a frame, ...).
    pub value: f64,
    pub settings: Settings,
}

/// One knob swept.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    pub knob: Knob,
    pub runs: Vec<RunSpec>,
}

/// A whole study.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyPlan {
    /// Name in the report ("quick", "full", "ci").
    pub name: String,
    pub motion: Motion,
    /// The settings each sweep changes one knob of.
    pub base: Settings,
    /// The run every other run is compared with.
    pub reference: RunSpec,
    pub sweeps: Vec<Sweep>,
    /// What the report should say about this plan's reference (where it
    /// departs from "the finest of every knob", and why).
    pub notes: Vec<String>,
    /// The reference's settings on the base mesh, when the reference's mesh
    /// differs from the base's (the `brain` preset's finer brain): the runs
    /// on the base mesh are also compared with it, which tells what the other
    /// knobs cost on that mesh apart from what the mesh itself costs.
    pub mesh_reference: Option<RunSpec>,
}

/// A uniform grid with about `n` nodes a face, 2:1 along:across where it divides.
pub fn grid(n: u32) -> NodeLayout {
    match n {
        8 => NodeLayout::Grid { along: 4, across: 2 },
        30 => NodeLayout::Grid { along: 6, across: 5 },
        150 => NodeLayout::Grid { along: 15, across: 10 },
        500 => NodeLayout::Grid { along: 50, across: 10 },
        2000 => NodeLayout::Grid { along: 100, across: 20 },
        _ => {
            let across = ((n as f64 / 2.0).sqrt().round() as u32).max(1);
            NodeLayout::Grid { along: (n / across).max(1), across }
        }
    }
}

/// The knob values of a preset.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanValues {
    pub base: Settings,
    /// Node counts a face (grid); the largest is the reference.
    pub nodes: Vec<u32>,
    /// Tip-concentrated counts a face.
    pub tip_nodes: Vec<u32>,
    /// Meshes from coarsest to finest (the last is the reference); empty: no mesh sweep.
    pub meshes: Vec<MeshChoice>,
    /// Speeds, thicknesses a frame (the reference runs at half the smallest).
    pub speeds: Vec<f64>,
    /// Speeds of the contact sweep (culling on/off x bilateral/unilateral).
    pub contact_speeds: Vec<f64>,
    /// Sub-step travels (thicknesses; `None`: one step a frame) swept at `substep_speed`.
    pub substeps: Vec<Option<f64>>,
    /// Speed of the sub-step sweep, thicknesses a frame.
    pub substep_speed: f64,
    /// Backends.
    pub backends: Vec<CollisionBackend>,
    /// Node counts the backend sweep crosses.
    pub backend_nodes: Vec<u32>,
    /// Storage sweep on.
    pub storage: bool,
    /// ROI sphere radii, m (All is the reference; Auto is added).
    pub roi_radii_m: Vec<f64>,
    /// Skull sweep (off, on) on.
    pub skull: bool,
    /// Refinements swept (edges across a blade; `None`: the mesh as it is);
    /// the reference takes the finest. Empty: no refine sweep.
    pub refine: Vec<Option<f64>>,
    /// The reference's backend: `Reference` (brute force), or `Bvh` where the
    /// brute force would take hours (the tests prove them equal bit for bit).
    pub reference_backend: CollisionBackend,
    /// The reference's region of interest: `All`, or `Auto` where the whole
    /// surface's compliance does not fit in memory (the ROI decides which
    /// columns are precomputed, not the answer).
    pub reference_roi: RoiChoice,
}

impl StudyPlan {
    /// Builds the reference and the sweeps from knob values.
    pub fn from_values(name: &str, motion: Motion, v: &PlanValues) -> StudyPlan {
        let base = &v.base;
        let sweeps = SWEEPS.iter().filter_map(|sweep| sweep(v)).collect();
        let reference = reference_run(v);
        let mesh_reference = (reference.settings.mesh != base.mesh).then(|| RunSpec {
            label: format!("{}, every other knob as the reference", base.mesh.label()),
            value: f64::NAN,
            settings: Settings { mesh: base.mesh.clone(), ..reference.settings.clone() },
        });
        StudyPlan { name: name.to_string(), motion, base: base.clone(), reference, sweeps, notes: reference_notes(v), mesh_reference }
    }

    /// Keeps only the sweeps of `knobs` (all when empty); the reference stays.
    pub fn retain_knobs(&mut self, knobs: &[Knob]) {
        if !knobs.is_empty() {
            self.sweeps.retain(|s| knobs.contains(&s.knob));
        }
    }

    /// Runs in the plan, the reference included.
    pub fn run_count(&self) -> usize {
        1 + usize::from(self.mesh_reference.is_some()) + self.sweeps.iter().map(|s| s.runs.len()).sum::<usize>()
    }
}

/// The sweeps a plan can have, in the report's order; each is `None` where the plan does not sweep its knob.
const SWEEPS: [fn(&PlanValues) -> Option<Sweep>; 10] =
    [node_sweep, mesh_sweep, speed_sweep, contact_sweep, substep_sweep, backend_sweep, storage_sweep, roi_sweep, skull_sweep, refine_sweep];

/// A run that changes the base by `change`.
fn run(v: &PlanValues, label: String, value: f64, change: impl FnOnce(&mut Settings)) -> RunSpec {
    let mut settings = v.base.clone();
    change(&mut settings);
    RunSpec { label, value, settings }
}

fn sweep(knob: Knob, runs: Vec<RunSpec>) -> Option<Sweep> {
    (!runs.is_empty()).then_some(Sweep { knob, runs })
}

/// Grid node counts a face, then tip-concentrated ones.
fn node_sweep(v: &PlanValues) -> Option<Sweep> {
    if v.nodes.is_empty() {
        return None;
    }
    let grids = v.nodes.iter().map(|&n| run(v, format!("grid {n}"), n as f64, |s| s.layout = grid(n)));
    let tips = v.tip_nodes.iter().map(|&n| {
        run(v, format!("tip {n}"), n as f64, |s| s.layout = NodeLayout::TipConcentrated { count: n, tip_fraction: 0.3 })
    });
    sweep(Knob::SourceNodes, grids.chain(tips).collect())
}

fn mesh_sweep(v: &PlanValues) -> Option<Sweep> {
    if v.meshes.len() < 2 {
        return None;
    }
    sweep(Knob::Mesh, v.meshes.iter().enumerate().map(|(k, m)| run(v, m.label(), k as f64, |s| s.mesh = m.clone())).collect())
}

fn speed_sweep(v: &PlanValues) -> Option<Sweep> {
    sweep(Knob::Speed, v.speeds.iter().map(|&x| run(v, format!("{x} h/frame"), x, |s| s.speed = x)).collect())
}

/// Every contact model with culling on and off, at each of the contact sweep's speeds.
fn contact_sweep(v: &PlanValues) -> Option<Sweep> {
    let mut runs = Vec::new();
    for contact in [SpatulaContact::Sliding, SpatulaContact::Unilateral, SpatulaContact::Bilateral] {
        for culling in [true, false] {
            for &x in &v.contact_speeds {
                let label = format!("{}, culling {}, {x} h/frame", contact_name(contact), if culling { "on" } else { "off" });
                runs.push(run(v, label, x, |s| (s.speed, s.culling, s.contact) = (x, culling, contact)));
            }
        }
    }
    sweep(Knob::Contact, runs)
}

fn substep_sweep(v: &PlanValues) -> Option<Sweep> {
    let runs = v.substeps.iter().map(|&t| {
        run(v, substep_label(t), t.unwrap_or(f64::INFINITY), |s| (s.speed, s.substep_travel) = (v.substep_speed, t))
    });
    sweep(Knob::Substeps, runs.collect())
}

/// Every backend at each of the backend sweep's node counts.
fn backend_sweep(v: &PlanValues) -> Option<Sweep> {
    let runs = v.backend_nodes.iter().flat_map(|&n| {
        v.backends.iter().map(move |&b| run(v, format!("{} {n}", backend_name(b)), n as f64, |s| (s.backend, s.layout) = (b, grid(n))))
    });
    sweep(Knob::Backend, runs.collect())
}

/// Exact f64 against rounded f32: memory and time against accuracy.
fn storage_sweep(v: &PlanValues) -> Option<Sweep> {
    let runs = [ComplianceStorage::F64, ComplianceStorage::F32].into_iter().enumerate();
    v.storage.then(|| Sweep { knob: Knob::Storage, runs: runs.map(|(k, x)| run(v, storage_label(x), k as f64, |s| s.storage = x)).collect() })
}

/// The swept sphere radii, then the automatic region and the whole surface.
fn roi_sweep(v: &PlanValues) -> Option<Sweep> {
    if v.roi_radii_m.is_empty() {
        return None;
    }
    let spheres = v.roi_radii_m.iter().map(|&r| RoiChoice::Sphere { radius_m: r }).map(|roi| (roi.label(), roi_value(roi), roi));
    let rest = [("auto".to_string(), f64::NAN, RoiChoice::Auto), ("all".to_string(), f64::INFINITY, RoiChoice::All)];
    sweep(Knob::RegionOfInterest, spheres.chain(rest).map(|(label, value, roi)| run(v, label, value, |s| s.roi = roi)).collect())
}

fn roi_value(roi: RoiChoice) -> f64 {
    match roi {
        RoiChoice::Sphere { radius_m } => radius_m * 1e3,
        RoiChoice::Auto => f64::NAN,
        RoiChoice::All => f64::INFINITY,
    }
}

fn skull_sweep(v: &PlanValues) -> Option<Sweep> {
    v.skull.then(|| Sweep {
        knob: Knob::Skull,
        runs: [false, true].into_iter().map(|on| run(v, skull_label(on).into(), on as u8 as f64, |s| s.skull = on)).collect(),
    })
}

fn refine_sweep(v: &PlanValues) -> Option<Sweep> {
    sweep(Knob::Refine, v.refine.iter().map(|&r| run(v, refine_label(r), r.unwrap_or(0.0), |s| s.refine = r)).collect())
}

/// What the report says where the plan's reference is not the finest of every knob.
fn reference_notes(v: &PlanValues) -> Vec<String> {
    let mut notes = Vec::new();
    if v.reference_backend != CollisionBackend::Reference {
        notes.push(format!(
            "The reference collides with `{}` instead of the brute-force `reference` backend, which would take hours here; \
             the two give the same triangles bit for bit (tests/suite/collision_backends.rs, the real brains at 2000 nodes a face included).",
            backend_name(v.reference_backend)
        ));
    }
    if v.reference_roi != RoiChoice::All {
        notes.push(format!(
            "The reference's region of interest is `{}`, not the whole surface, whose compliance would not fit in memory; \
             the region decides which compliance columns are precomputed and which are solved when first touched, not the answer.",
            v.reference_roi.label()
        ));
    }
    notes
}

/// The finest setting of every knob at once: the finest mesh of the family,
/// the most source nodes, the plan's reference backend (brute force unless it
/// would take hours), culling on, half the smallest swept speed, the finest
/// sub-step, f64, the plan's reference region (the whole surface where it
/// fits), the default (sliding) contact, the skull simulated, the finest refinement.
pub fn reference_run(v: &PlanValues) -> RunSpec {
    let b = &v.base;
    let nodes = v.nodes.iter().chain(&v.backend_nodes).copied().max().map_or_else(|| b.layout.clone(), grid);
    let speed = v.speeds.iter().chain(&v.contact_speeds).copied().fold(b.speed, f64::min) / 2.0;
    let substep_travel = v.substeps.iter().flatten().copied().fold(b.substep_travel, |a, t| Some(a.map_or(t, |a: f64| a.min(t))));
    let settings = Settings {
        mesh: v.meshes.last().cloned().unwrap_or_else(|| b.mesh.clone()),
        layout: nodes,
        backend: v.reference_backend,
        culling: true,
        speed,
        storage: ComplianceStorage::F64,
        roi: v.reference_roi,
        contact: SpatulaContact::default(),
        substep_travel,
        skull: true,
        refine: v.refine.iter().flatten().copied().fold(b.refine, |a, r| Some(a.map_or(r, |a: f64| a.max(r)))),
    };
    let label = format!(
        "{}, {} nodes/face, {} backend, {speed} h/frame, ROI {}, skull, mesh {}",
        settings.mesh.label(),
        settings.nodes_per_face(),
        backend_name(settings.backend),
        settings.roi.label(),
        refine_label(settings.refine)
    );
    RunSpec { label, value: f64::NAN, settings }
}

/// `sliding` / `unilateral` / `bilateral`.
pub fn contact_name(c: SpatulaContact) -> &'static str {
    match c {
        SpatulaContact::Unilateral => "unilateral",
        SpatulaContact::Bilateral => "bilateral",
        SpatulaContact::Sliding => "sliding",
    }
}

/// `off` / `on`.
pub fn skull_label(on: bool) -> &'static str {
    if on { "on" } else { "off" }
}

/// `as it is` / `refined, 4 edges across` (a blade's width).
pub fn refine_label(r: Option<f64>) -> String {
    match r {
        None => "as it is".into(),
        Some(e) => format!("refined, {e} edges across"),
    }
}

/// `none` / `0.125 h`.
pub fn substep_label(t: Option<f64>) -> String {
    match t {
        None => "none (one step a frame)".into(),
        Some(t) => format!("{t} h a sub-step"),
    }
}

/// The base every preset starts from: the scene's mesh, 150 grid nodes a face
/// (the paper's), BVH, culling on, half a thickness a frame, f64, automatic
/// ROI, sliding contact (the default), sub-steps of 1/8 thickness (the shipped default:
/// without them the insertion, 2 blade thicknesses a frame, differs from the
/// reference's and that difference buries every other knob's; one step a
/// frame, the paper's, is a value of the sub-step sweep), the skull simulated
/// (the reference simulates it, and on the study motion the brain phantom
/// meets its skull-base sphere: without it every run would differ from the
/// reference by about 0.3 mm RMS; "off" is a value of the skull sweep).
pub fn base_settings(mesh: MeshChoice) -> Settings {
    Settings {
        mesh,
        layout: grid(150),
        backend: CollisionBackend::Bvh,
        culling: true,
        speed: 0.5,
        storage: ComplianceStorage::F64,
        roi: RoiChoice::Auto,
        contact: SpatulaContact::default(),
        substep_travel: Some(0.125),
        skull: true,
        refine: None,
    }
}

/// The base in words, as the report gives it: "150 grid nodes a face, BVH, culling on, 0.5 blade thicknesses a
/// frame, f64 compliance, automatic region of interest, sliding contact, sub-steps of 1/8 blade thickness, the skull
/// simulated" (the mesh and a refinement are named where the base refines).
pub fn describe_base(s: &Settings) -> String {
    let layout = match &s.layout {
        NodeLayout::Grid { .. } => format!("{} grid nodes a face", s.nodes_per_face()),
        _ => format!("{} nodes a face ({})", s.nodes_per_face(), s.layout_label()),
    };
    let roi = match s.roi {
        RoiChoice::Auto => "automatic region of interest".to_string(),
        RoiChoice::All => "the whole surface as the region of interest".to_string(),
        RoiChoice::Sphere { radius_m } => format!("a {:.0} mm sphere as the region of interest", radius_m * 1e3),
    };
    let substeps = match s.substep_travel {
        None => "one step a frame".to_string(),
        Some(t) if (1.0 / t).fract() == 0.0 && t < 1.0 => format!("sub-steps of 1/{} blade thickness", 1.0 / t),
        Some(t) => format!("sub-steps of {t} blade thicknesses"),
    };
    let mut parts = vec![
        layout,
        match s.backend {
            CollisionBackend::Reference => "brute-force collision",
            CollisionBackend::Bvh => "BVH",
            CollisionBackend::Gpu => "GPU",
            CollisionBackend::Auto => "the automatic backend",
        }
        .to_string(),
        format!("culling {}", if s.culling { "on" } else { "off" }),
        format!("{} blade thicknesses a frame", s.speed),
        format!("{} compliance", storage_label(s.storage)),
        roi,
        format!("{} contact", contact_name(s.contact)),
        substeps,
        if s.skull { "the skull simulated" } else { "no skull" }.to_string(),
    ];
    if let Some(e) = s.refine {
        parts.push(format!("the mesh refined to {e} edges across a blade"));
    }
    parts.join(", ")
}

/// Lower-case backend name.
pub fn backend_name(b: CollisionBackend) -> &'static str {
    match b {
        CollisionBackend::Reference => "reference",
        CollisionBackend::Bvh => "bvh",
        CollisionBackend::Gpu => "gpu",
        CollisionBackend::Auto => "auto",
    }
}

/// The shipped real brains (`assets/brain/`), coarsest first, when both are present.
pub fn real_brain_family() -> Option<Vec<PathBuf>> {
    use crate::mesh::brain;
    let dir = brain::shipped_dir();
    [brain::COARSE, brain::FINE].iter().map(|stem| brain::find_in(&dir, stem)).collect()
}

/// Lowest height of each connected component fixed on a mesh file (the real
/// brain has no brain stem: each hemisphere rests on its lowest 10 mm).
pub const FILE_FIX_HEIGHT_M: f64 = 0.010;

/// `quick`: the paper-9k phantom, every knob, a few values each (minutes in
/// release on 2 cores). `full`: the paper-12k phantom, more values, the three
/// phantom resolutions. `ci`: a few values of the knobs that need no extra
/// compliance precompute, a short motion (the test suite re-runs it and
/// compares its accuracy columns with the committed `docs/study/ci/report.md`).
/// `brain`: a mesh family from files (millimetres, coarsest to finest; the
/// real brains when `mesh_files` is empty and the caller found them), the
/// coarsest as the base and the finest as the reference, with the knobs that
/// matter there. Non-empty `mesh_files` replace any preset's mesh family.
pub fn preset_plan(preset: super::StudyPreset, mesh_files: &[PathBuf]) -> StudyPlan {
    use super::StudyPreset as P;
    let files: Vec<MeshChoice> = mesh_files.iter().map(|path| MeshChoice::File { path: path.clone(), fix_height_m: FILE_FIX_HEIGHT_M }).collect();
    let (name, motion, mut values) = match preset {
        P::Full => ("full", Motion::default(), full_values()),
        P::Quick => ("quick", Motion::default(), quick_values()),
        // The paper-9k phantom's fissure is 9.4 mm wide: opening 10 mm pushes about 5 mm into the wall.
        P::Ci => ("ci", Motion { insert_m: 0.030, insert_step_m: 0.010, open_m: 0.010 }, ci_values()),
        P::Brain => ("brain", Motion::default(), brain_values(&files)),
    };
    if !files.is_empty() && preset != P::Brain {
        values.base.mesh = files[0].clone();
        values.meshes = files;
    }
    StudyPlan::from_values(name, motion, &values)
}

fn phantoms(names: &[&str]) -> Vec<MeshChoice> {
    names.iter().map(|s| MeshChoice::Phantom(s.to_string())).collect()
}

/// `full`: the paper-12k phantom, every knob, the three phantom resolutions.
fn full_values() -> PlanValues {
    PlanValues {
        base: base_settings(MeshChoice::Phantom("paper-12k".into())),
        nodes: vec![8, 30, 150, 500, 2000],
        tip_nodes: vec![30, 150],
        meshes: phantoms(&["small", "paper-9k", "paper-12k"]),
        speeds: vec![0.25, 0.5, 1.0, 2.0, 5.0],
        contact_speeds: vec![0.5, 5.0],
        substeps: vec![None, Some(2.0), Some(1.0), Some(0.5), Some(0.125)],
        substep_speed: 5.0,
        backends: vec![CollisionBackend::Reference, CollisionBackend::Bvh, CollisionBackend::Gpu],
        backend_nodes: vec![30, 150, 500, 2000],
        storage: true,
        roi_radii_m: vec![0.015, 0.030, 0.060],
        skull: true,
        refine: vec![None, Some(2.0), Some(4.0)],
        reference_backend: CollisionBackend::Reference,
        reference_roi: RoiChoice::All,
    }
}

/// `quick`: the paper-9k phantom, every knob, a few values each.
fn quick_values() -> PlanValues {
    PlanValues {
        base: base_settings(MeshChoice::Phantom("paper-9k".into())),
        nodes: vec![8, 30, 150, 500, 2000],
        tip_nodes: vec![30],
        meshes: phantoms(&["small", "paper-9k"]),
        speeds: vec![0.25, 0.5, 1.0, 2.0, 5.0],
        contact_speeds: vec![0.5, 5.0],
        substeps: vec![None, Some(2.0), Some(0.5), Some(0.125)],
        substep_speed: 5.0,
        backends: vec![CollisionBackend::Reference, CollisionBackend::Bvh, CollisionBackend::Gpu],
        backend_nodes: vec![30, 150, 500],
        storage: true,
        roi_radii_m: vec![0.015, 0.030],
        skull: true,
        refine: vec![None, Some(2.0), Some(4.0)],
        reference_backend: CollisionBackend::Reference,
        reference_roi: RoiChoice::All,
    }
}

/// `ci`: the knobs that need no extra compliance precompute, a few values each.
fn ci_values() -> PlanValues {
    PlanValues {
        base: base_settings(MeshChoice::Phantom("paper-9k".into())),
        nodes: vec![8, 150],
        tip_nodes: Vec::new(),
        meshes: Vec::new(),
        speeds: vec![0.5, 5.0],
        contact_speeds: vec![5.0],
        substeps: vec![None, Some(0.5)],
        substep_speed: 5.0,
        backends: vec![CollisionBackend::Reference, CollisionBackend::Bvh],
        backend_nodes: vec![30],
        // Storage and ROI sweeps need extra compliance precomputes: presets only.
        storage: false,
        roi_radii_m: Vec::new(),
        // The reference simulates the skull; its sweep is the presets'.
        skull: false,
        // A refined mesh is another compliance precompute: presets only.
        refine: Vec::new(),
        reference_backend: CollisionBackend::Reference,
        reference_roi: RoiChoice::All,
    }
}

/// `brain`: the mesh family from files, coarsest the base, finest the reference.
fn brain_values(files: &[MeshChoice]) -> PlanValues {
    PlanValues {
        base: base_settings(files.first().cloned().unwrap_or(MeshChoice::Scene)),
        nodes: vec![30, 150, 500, 2000],
        tip_nodes: Vec::new(),
        meshes: files.to_vec(),
        speeds: vec![0.5, 2.0],
        contact_speeds: vec![0.5],
        substeps: vec![None, Some(0.5)],
        substep_speed: 5.0,
        // The GPU's figures on the real brains: `fissure bench collision`.
        backends: Vec::new(),
        backend_nodes: Vec::new(),
        storage: false,
        roi_radii_m: Vec::new(),
        skull: true,
        refine: vec![None, Some(4.0)],
        // Brute force at 2000 nodes a face on 67.7k triangles: seconds a frame.
        reference_backend: CollisionBackend::Bvh,
        // The whole surface of a real brain: tens of GB of compliance.
        reference_roi: RoiChoice::Auto,
    }
}

/// Short label of a compliance storage: `f64`, `f32`.
pub fn storage_label(s: ComplianceStorage) -> String {
    match s {
        ComplianceStorage::F64 => "f64".into(),
        ComplianceStorage::F32 => "f32".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report's words for the base come from the settings the plan ran: the shipped base reads as it always
    /// has, and a changed knob changes the words.
    #[test]
    fn the_base_is_described_from_its_settings() {
        let base = base_settings(MeshChoice::Scene);
        assert_eq!(
            describe_base(&base),
            "150 grid nodes a face, BVH, culling on, 0.5 blade thicknesses a frame, f64 compliance, automatic region of interest, \
             sliding contact, sub-steps of 1/8 blade thickness, the skull simulated"
        );
        let other = Settings { culling: false, substep_travel: None, skull: false, refine: Some(4.0), ..base.clone() };
        let words = describe_base(&other);
        for expected in ["culling off", "one step a frame", "no skull", "refined to 4 edges across a blade"] {
            assert!(words.contains(expected), "{expected}: {words}");
        }
        for preset in [crate::study::StudyPreset::Quick, crate::study::StudyPreset::Ci] {
            assert_eq!(preset_plan(preset, &[]).base, base_settings(MeshChoice::Phantom("paper-9k".into())), "{preset:?}");
        }
    }

    #[test]
    fn the_reference_is_finer_than_every_swept_run_in_every_knob() {
        use crate::study::StudyPreset;
        let files = [PathBuf::from("coarse.msh"), PathBuf::from("fine.msh")];
        for (preset, meshes) in
            [(StudyPreset::Quick, &[][..]), (StudyPreset::Full, &[]), (StudyPreset::Ci, &[]), (StudyPreset::Brain, &files), (StudyPreset::Quick, &files)]
        {
            let plan = preset_plan(preset, meshes);
            let r = &plan.reference.settings;
            assert_eq!((r.storage, r.culling, r.skull, r.contact), (ComplianceStorage::F64, true, true, SpatulaContact::Sliding));
            if preset == StudyPreset::Brain {
                // The documented departures, each with its note.
                assert_eq!((r.backend, r.roi), (CollisionBackend::Bvh, RoiChoice::Auto));
                assert_eq!(plan.notes.len(), 2, "{:?}", plan.notes);
            } else {
                assert_eq!((r.backend, r.roi), (CollisionBackend::Reference, RoiChoice::All));
                assert!(plan.notes.is_empty());
            }
            if !meshes.is_empty() {
                assert_eq!(r.mesh, MeshChoice::File { path: files[1].clone(), fix_height_m: FILE_FIX_HEIGHT_M }, "the finest file");
                let sweep = plan.sweeps.iter().find(|s| s.knob == Knob::Mesh).expect("a mesh sweep");
                assert_eq!(sweep.runs.len(), 2);
                // The reference's settings on the base (coarsest) mesh: the mesh's share of every error.
                let own = &plan.mesh_reference.as_ref().expect("a mesh reference when the reference's mesh is not the base's").settings;
                assert_eq!(own.mesh, sweep.runs[0].settings.mesh, "on the base mesh");
                assert_eq!(Settings { mesh: r.mesh.clone(), ..own.clone() }, *r, "every other knob as the reference");
                assert_eq!(plan.run_count(), 2 + plan.sweeps.iter().map(|s| s.runs.len()).sum::<usize>());
            } else {
                assert!(plan.mesh_reference.is_none(), "{preset:?}: the base mesh is the reference's");
            }
            for s in plan.sweeps.iter().flat_map(|s| &s.runs) {
                let s = &s.settings;
                assert!(s.nodes_per_face() <= r.nodes_per_face(), "densest nodes");
                assert!(s.speed > r.speed, "the reference's step is smaller than any run's");
                assert!(s.refine.unwrap_or(0.0) <= r.refine.unwrap_or(0.0), "the finest refinement");
                assert_ne!(s, r, "no swept run equals the reference");
            }
        }
    }

    #[test]
    fn knobs_are_found_by_name_and_a_plan_keeps_only_the_asked_sweeps() {
        for k in Knob::ALL {
            assert_eq!(Knob::from_name(k.name()), Some(k));
        }
        assert_eq!(Knob::from_name("skul"), None);
        let mut plan = preset_plan(crate::study::StudyPreset::Quick, &[]);
        let reference = plan.reference.clone();
        plan.retain_knobs(&[Knob::Skull, Knob::Speed]);
        let kept: Vec<Knob> = plan.sweeps.iter().map(|s| s.knob).collect();
        assert_eq!(kept, [Knob::Speed, Knob::Skull]);
        assert_eq!((&plan.reference.label, &plan.reference.settings), (&reference.label, &reference.settings), "the reference stays");
        let skull = &plan.sweeps[1].runs;
        assert_eq!(skull.iter().map(|r| r.settings.skull).collect::<Vec<_>>(), [false, true]);
    }

    #[test]
    fn grid_sizes_are_what_they_say() {
        for n in [8, 30, 150, 500, 2000] {
            let s = Settings { layout: grid(n), ..base_settings(MeshChoice::Scene) };
            assert_eq!(s.nodes_per_face(), n as usize);
        }
    }
}
