//! What a study runs: sweeps of one knob each, every run a full [`Settings`].
//!
//! In: a preset (quick, full) or a hand-made [`StudyPlan`] (the CI test uses a
//! reduced one). Out: the list of sweeps, each with its reference run (the most
//! accurate value of its knob: densest nodes, smallest step, finest mesh, f64,
//! reference backend, whole-surface compliance). Stays true: a sweep's runs
//! differ from its base only in the swept knob (the backend sweep also crosses
//! the node count, to draw time against nodes per backend).

use crate::geometry::NodeLayout;
use crate::scenario::{CollisionBackend, ComplianceStorage};
use std::path::PathBuf;

use super::motion::Motion;

/// The knobs a study sweeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Knob {
    /// Source nodes a face and their layout.
    SourceNodes,
    /// Mesh resolution.
    Mesh,
    /// Spatula speed a frame, in blade thicknesses (with culling on and off).
    Speed,
    /// Collision backend (with culling on and off), across node counts.
    Backend,
    /// Storage of the precomputed compliance.
    Storage,
    /// Region of interest of the precomputed compliance.
    RegionOfInterest,
}

impl Knob {
    /// Name in the CSV and the report.
    pub fn name(self) -> &'static str {
        match self {
            Knob::SourceNodes => "source_nodes",
            Knob::Mesh => "mesh",
            Knob::Speed => "speed",
            Knob::Backend => "backend",
            Knob::Storage => "storage",
            Knob::RegionOfInterest => "region_of_interest",
        }
    }
}

/// Which mesh a run uses.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshChoice {
    /// The scene's own mesh.
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
            MeshChoice::File { path, .. } => path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "file".into()),
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

/// One knob swept, with its reference.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    pub knob: Knob,
    pub runs: Vec<RunSpec>,
    /// Index into `runs` of the reference run (the most accurate setting).
    pub reference: usize,
}

/// A whole study.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyPlan {
    /// Name in the report ("quick", "full", "ci").
    pub name: String,
    pub motion: Motion,
    pub sweeps: Vec<Sweep>,
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
    /// Extra meshes timed without an accuracy reference (other anatomy: the real brain).
    pub extra_meshes: Vec<MeshChoice>,
    /// Speeds, thicknesses a frame; the smallest is the reference.
    pub speeds: Vec<f64>,
    /// Backends (Reference first: the reference).
    pub backends: Vec<CollisionBackend>,
    /// Node counts the backend sweep crosses.
    pub backend_nodes: Vec<u32>,
    /// Storage sweep on.
    pub storage: bool,
    /// ROI sphere radii, m (All is the reference; Auto is added).
    pub roi_radii_m: Vec<f64>,
}

impl StudyPlan {
    /// Builds the sweeps from knob values.
    pub fn from_values(name: &str, motion: Motion, v: &PlanValues) -> StudyPlan {
        let base = &v.base;
        let mut sweeps = Vec::new();
        if !v.nodes.is_empty() {
            let mut runs: Vec<RunSpec> = v
                .nodes
                .iter()
                .map(|&n| RunSpec { label: format!("grid {n}"), value: n as f64, settings: Settings { layout: grid(n), ..base.clone() } })
                .collect();
            runs.extend(v.tip_nodes.iter().map(|&n| RunSpec {
                label: format!("tip {n}"),
                value: n as f64,
                settings: Settings { layout: NodeLayout::TipConcentrated { count: n, tip_fraction: 0.3 }, ..base.clone() },
            }));
            let reference = (0..v.nodes.len()).max_by_key(|&k| v.nodes[k]).unwrap_or(0);
            sweeps.push(Sweep { knob: Knob::SourceNodes, runs, reference });
        }
        if !v.meshes.is_empty() || !v.extra_meshes.is_empty() {
            let runs: Vec<RunSpec> = v
                .meshes
                .iter()
                .chain(&v.extra_meshes)
                .enumerate()
                .map(|(k, m)| RunSpec { label: m.label(), value: k as f64, settings: Settings { mesh: m.clone(), ..base.clone() } })
                .collect();
            sweeps.push(Sweep { knob: Knob::Mesh, reference: v.meshes.len().saturating_sub(1), runs });
        }
        if !v.speeds.is_empty() {
            let mut runs = Vec::new();
            for culling in [true, false] {
                for &s in &v.speeds {
                    runs.push(RunSpec {
                        label: format!("{s} h/frame, culling {}", if culling { "on" } else { "off" }),
                        value: s,
                        settings: Settings { speed: s, culling, ..base.clone() },
                    });
                }
            }
            let reference = (0..v.speeds.len()).min_by(|&a, &b| v.speeds[a].total_cmp(&v.speeds[b])).unwrap_or(0);
            sweeps.push(Sweep { knob: Knob::Speed, runs, reference });
        }
        if !v.backends.is_empty() {
            let mut runs = Vec::new();
            let mut reference = 0;
            let densest = v.backend_nodes.iter().copied().max().unwrap_or(150);
            for &n in &v.backend_nodes {
                for &b in &v.backends {
                    for culling in [true, false] {
                        if b == CollisionBackend::Reference && culling && n == densest {
                            reference = runs.len();
                        }
                        runs.push(RunSpec {
                            label: format!("{} {n}, culling {}", backend_name(b), if culling { "on" } else { "off" }),
                            value: n as f64,
                            settings: Settings { backend: b, culling, layout: grid(n), ..base.clone() },
                        });
                    }
                }
            }
            sweeps.push(Sweep { knob: Knob::Backend, runs, reference });
        }
        if v.storage {
            // Exact f64, rounded f32, block-low-rank at 8 and 6 digits: memory and time against accuracy.
            let runs = [ComplianceStorage::F64, ComplianceStorage::F32, ComplianceStorage::LowRank { digits: 8 }, ComplianceStorage::LowRank { digits: 6 }]
                .into_iter()
                .enumerate()
                .map(|(k, s)| RunSpec { label: storage_label(s), value: k as f64, settings: Settings { storage: s, ..base.clone() } })
                .collect();
            sweeps.push(Sweep { knob: Knob::Storage, runs, reference: 0 });
        }
        if !v.roi_radii_m.is_empty() {
            let mut runs: Vec<RunSpec> = v
                .roi_radii_m
                .iter()
                .map(|&r| RunSpec {
                    label: RoiChoice::Sphere { radius_m: r }.label(),
                    value: r * 1e3,
                    settings: Settings { roi: RoiChoice::Sphere { radius_m: r }, ..base.clone() },
                })
                .collect();
            runs.push(RunSpec { label: "auto".into(), value: f64::NAN, settings: Settings { roi: RoiChoice::Auto, ..base.clone() } });
            runs.push(RunSpec { label: "all".into(), value: f64::INFINITY, settings: Settings { roi: RoiChoice::All, ..base.clone() } });
            let reference = runs.len() - 1;
            sweeps.push(Sweep { knob: Knob::RegionOfInterest, runs, reference });
        }
        StudyPlan { name: name.to_string(), motion, sweeps }
    }

    /// Runs in the plan (before de-duplication of identical settings).
    pub fn run_count(&self) -> usize {
        self.sweeps.iter().map(|s| s.runs.len()).sum()
    }
}

/// The base every preset starts from: the scene's mesh, 150 grid nodes a face
/// (the paper's), BVH, culling on, half a thickness a frame, f64, automatic ROI.
pub fn base_settings(mesh: MeshChoice) -> Settings {
    Settings {
        mesh,
        layout: grid(150),
        backend: CollisionBackend::Bvh,
        culling: true,
        speed: 0.5,
        storage: ComplianceStorage::F64,
        roi: RoiChoice::Auto,
    }
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

/// The real brain mesh beside the checkout, when present.
pub fn real_brain_path() -> Option<PathBuf> {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/brain/brain_pial_coarse.msh"));
    p.exists().then_some(p)
}

/// `quick`: the paper-9k phantom, every knob, a few values each (under 5
/// minutes in release on 2 cores). `full`: the paper-12k phantom, more values,
/// the three phantom resolutions and the real brain when present.
pub fn preset_plan(full: bool) -> StudyPlan {
    let motion = Motion::default();
    if full {
        let values = PlanValues {
            base: base_settings(MeshChoice::Phantom("paper-12k".into())),
            nodes: vec![8, 30, 150, 500, 2000],
            tip_nodes: vec![30, 150],
            meshes: ["small", "paper-9k", "paper-12k"].iter().map(|s| MeshChoice::Phantom(s.to_string())).collect(),
            extra_meshes: real_brain_path().map(|path| MeshChoice::File { path, fix_height_m: 0.010 }).into_iter().collect(),
            speeds: vec![0.25, 0.5, 1.0, 2.0, 5.0],
            backends: vec![CollisionBackend::Reference, CollisionBackend::Bvh, CollisionBackend::Gpu],
            backend_nodes: vec![30, 150, 500, 2000],
            storage: true,
            roi_radii_m: vec![0.015, 0.030, 0.060],
        };
        StudyPlan::from_values("full", motion, &values)
    } else {
        let values = PlanValues {
            base: base_settings(MeshChoice::Phantom("paper-9k".into())),
            nodes: vec![8, 30, 150, 500, 2000],
            tip_nodes: vec![30],
            meshes: ["small", "paper-9k"].iter().map(|s| MeshChoice::Phantom(s.to_string())).collect(),
            extra_meshes: Vec::new(),
            speeds: vec![0.25, 0.5, 1.0, 2.0, 5.0],
            backends: vec![CollisionBackend::Reference, CollisionBackend::Bvh, CollisionBackend::Gpu],
            backend_nodes: vec![30, 150, 500],
            storage: true,
            roi_radii_m: vec![0.015, 0.030],
        };
        StudyPlan::from_values("quick", motion, &values)
    }
}

/// Short label of a compliance storage: `f64`, `f32`, `lowrank8`.
pub fn storage_label(s: ComplianceStorage) -> String {
    match s {
        ComplianceStorage::F64 => "f64".into(),
        ComplianceStorage::F32 => "f32".into(),
        ComplianceStorage::LowRank { digits } => format!("lowrank{digits}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_sweep_points_at_its_most_accurate_run() {
        for full in [false, true] {
            let plan = preset_plan(full);
            for s in &plan.sweeps {
                let r = &s.runs[s.reference].settings;
                match s.knob {
                    Knob::SourceNodes => assert!(s.runs.iter().all(|x| x.settings.nodes_per_face() <= r.nodes_per_face()), "densest nodes"),
                    Knob::Speed => assert!(r.culling && s.runs.iter().all(|x| x.settings.speed >= r.speed), "smallest step, culling on"),
                    Knob::Backend => assert!(r.backend == CollisionBackend::Reference && r.culling),
                    Knob::Storage => assert_eq!(r.storage, ComplianceStorage::F64),
                    Knob::RegionOfInterest => assert_eq!(r.roi, RoiChoice::All),
                    Knob::Mesh => assert!(matches!(&r.mesh, MeshChoice::Phantom(p) if p == if full { "paper-12k" } else { "paper-9k" })),
                }
            }
        }
    }

    #[test]
    fn grid_sizes_are_what_they_say() {
        for n in [8, 30, 150, 500, 2000] {
            let s = Settings { layout: grid(n), ..base_settings(MeshChoice::Scene) };
            assert_eq!(s.nodes_per_face(), n as usize);
        }
    }
}
