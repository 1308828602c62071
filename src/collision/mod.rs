//! The collision stage: spatula source nodes cast rays along their faces' normals;
//! pairs with the brain surface are found, culled by history (His-flags), and turned
//! into enforced displacements of surface vertices (Fukuhara et al. 2014).
//!
//! In: the boundary surface (triangles in surface-vertex indices, outward CCW), its
//! rest positions, the spatulas (shape + node layout) at construction; per frame the
//! deformed surface positions and one pose per spatula. Out: [`CollisionOutput`]:
//! candidate, culled and feasible pairs, per-vertex targets (displacement FROM REST),
//! per-spatula counts, source nodes for overlays.
//!
//! Rules (each tested in this folder or in `tests/suite/collision_*.rs`):
//! 1. **Rays** (`pairs.rs`). Node i on a face with outward normal N casts the line
//!    S_i + t N through the whole surface (watertight test, `geometry::ray`). B_i is
//!    the nearest hit with t <= e (behind), F_i the nearest with t > e, where
//!    e = 1e-6 x thickness is the contact tolerance: a triangle on the face plane
//!    (where last frame's constraint put it) is touching, whatever the rounding. An exact tie in t goes to the
//!    lower triangle index. There is no depth limit behind (as in the paper): a node
//!    deep inside tissue pairs with the nearest surface behind it, however far.
//!    The two nodes of a pair share ONE line (through both, along face 0's normal):
//!    each triangle is tested once for both, so F of one node and B of its partner
//!    come from the same arithmetic (no edge-rounding mismatch between them) and the
//!    casting work halves.
//! 2. **Candidate** (paper A2): (i, B_i) when N · N_tri(B_i) < 0, with N_tri the
//!    un-normalised (v1 - v0) x (v2 - v0); a zero-area triangle is never a candidate.
//! 3. **Culling** (`culling.rs`, paper B1–B3), per spatula: X = { F_i : His-flag_i on,
//!    node i of that spatula }; a candidate of that spatula whose triangle is in X is
//!    culled (reason: the lowest-numbered flagged node whose F_i it is). Then
//!    His-flag_i := (node i has a feasible pair this frame). With `culling: false`
//!    every candidate is feasible (the paper's comparison); flags are still kept.
//! 3b. **Swept-side culling** (ours, beyond the paper; `culling.rs`), when culling is
//!    on and the stage has a previous frame: a feasible pair whose hit point P (on the
//!    surface as it was at the end of the previous frame) lay, relative to the
//!    spatula's PREVIOUS pose, inside the blade's footprint and beyond its OTHER face
//!    (signed distance along this face's normal < -thickness/2 - e) is culled: that
//!    tissue was on the far side of the blade, so this face cannot push it without
//!    pulling it through the blade. His-flags only protect nodes whose partner was in
//!    contact last frame; this rule also covers a fast blade whose partner node was
//!    not touching (gyri, sulci, a first contact), the cause of the paper's Fig. 11b
//!    failure on a wall with relief. It never culls the face that leads the motion
//!    (its tissue was on its own side). Off with [`CollisionStage::set_swept_culling`].
//! 4. **Targets** (`displacement.rs`, Eq. 6): each vertex V of a feasible triangle,
//!    at its CURRENT position, with depth d = (S_i - V) · N (how far it lies behind
//!    the face plane). A vertex with d >= -e is claimed: V_proj = V + d N and
//!    U_enf = V_proj - V_rest. A vertex already in front of the plane (d < -e) is NOT
//!    claimed: projecting it would pull tissue onto the spatula (adhesion); the paper
//!    projects it, we leave it free. When several claims name one vertex, the deepest
//!    (largest d) wins; exact ties go to the lower spatula, then face, then node.
//!    Targets are sorted by vertex index.
//! 5. **Backends** (`backend/`): `reference`, `bvh` and `gpu` agree bit for bit;
//!    `gpu` finds candidates in f32 and leaves every decision, and every line its
//!    f32 bounds cannot settle, to the CPU in f64 (see `backend/gpu.rs`). A `gpu`
//!    request without an adapter falls back to `bvh` with a warning.
//!
//! The stage allocates only at construction and when its reused Vecs grow.

pub mod backend;
pub mod bench;
pub mod culling;
pub mod displacement;
pub mod pairs;
pub mod scenes;

use crate::geometry::{LayoutError, NodeLayout, Pose, SpatulaShape};
use crate::math::{Vec3, is_finite3};
use backend::{NearestHits, PairHits, PairLine, RayCaster, SourceRay};
use serde::{Deserialize, Serialize};

pub use culling::{CullReason, HisFlags};
pub use displacement::VertexTarget;
pub use pairs::Pair;

/// Which ray-casting backend the stage uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendKind {
    /// Every node against every triangle on the CPU, f64 (the oracle).
    Reference,
    /// Our binned-SAH BVH, refit per frame, a large cast's lines split over two threads; f64, bit for bit the answers of `reference`.
    Bvh,
    /// Our BVH refit and traversed on the GPU (wgpu compute, f32), every answer then
    /// decided in f64 on the CPU: bit for bit the answers of `reference`.
    Gpu,
    /// A request, never the backend in use: time `bvh` and `gpu` side by side on the
    /// first [`AUTO_TRIAL_FRAMES`] frames that cast lines and keep the faster (both
    /// give the same answers, so the choice never changes a result).
    Auto,
}

/// Frames with lines that an `Auto` stage times both backends on.
pub const AUTO_TRIAL_FRAMES: usize = 8;

/// Stage configuration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionConfig {
    pub backend: BackendKind,
    /// His-flag culling on (the paper's method) or off (every candidate is feasible).
    pub culling: bool,
}

/// One spatula: its blade and where its source nodes sit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpatulaSpec {
    pub shape: SpatulaShape,
    pub layout: NodeLayout,
}

/// Errors of the collision stage.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CollisionError {
    #[error("spatula {spatula}: {source}")]
    Layout { spatula: usize, source: LayoutError },
    #[error("{count} spatulas given; the stage handles 1 to 255")]
    SpatulaCount { count: usize },
    #[error("the surface has no triangles")]
    EmptySurface,
    #[error("triangle {triangle} refers to vertex {vertex}, but there are {count} vertices")]
    TriangleIndex { triangle: usize, vertex: u32, count: usize },
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex { vertex: usize },
    #[error("{got} vertex positions given, the surface has {expected}")]
    VertexCount { expected: usize, got: usize },
    #[error("{got} poses given, the stage has {expected} spatulas")]
    PoseCount { expected: usize, got: usize },
    #[error("pose of spatula {spatula} is non-finite or its quaternion is not unit")]
    InvalidPose { spatula: usize },
    #[error("GPU backend: {0}")]
    Gpu(String),
}

/// Per-spatula counts for one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SpatulaCounts {
    pub candidates: u32,
    pub culled: u32,
    pub feasible: u32,
    /// Surface vertices whose final target came from this spatula.
    pub constrained_vertices: u32,
    /// Nodes whose His-flag is on after this frame.
    pub flagged_nodes: u32,
}

/// A source node this frame (for overlays).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourceNode {
    /// World position, metres.
    pub position: Vec3,
    /// Outward unit normal of its face, world.
    pub normal: Vec3,
    pub spatula: u8,
    /// 0: the +z face, 1: the -z face.
    pub face: u8,
    /// Node index within its spatula: `face * pairs + k`.
    pub node: u32,
    /// His-flag after this frame.
    pub flagged: bool,
}

/// Everything the stage found in one frame. Reused from frame to frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CollisionOutput {
    /// One entry per constrained surface vertex, ascending by vertex.
    pub targets: Vec<VertexTarget>,
    /// Candidate pairs (A2 passed), in ray order (spatula, face, node).
    pub candidate_pairs: Vec<Pair>,
    /// Candidates removed by culling, with why.
    pub culled_pairs: Vec<(Pair, CullReason)>,
    /// Candidates kept.
    pub feasible_pairs: Vec<Pair>,
    pub per_spatula: Vec<SpatulaCounts>,
    pub source_nodes: Vec<SourceNode>,
}

/// Static description of one ray slot.
#[derive(Debug, Clone, Copy)]
struct RaySlot {
    spatula: u8,
    face: u8,
    node: u32,
    local: Vec3,
}

/// Static description of one node pair's line.
#[derive(Debug, Clone, Copy)]
struct LineSlot {
    /// Ray slots of the face-0 and face-1 nodes.
    slots: [usize; 2],
    thickness: f64,
}

/// Scratch reused every frame.
#[derive(Default)]
struct Workspace {
    rays: Vec<SourceRay>,
    lines: Vec<PairLine>,
    pair_hits: Vec<PairHits>,
    hits: Vec<NearestHits>,
    claims: displacement::Claims,
}

/// The collision history between frames (His-flags and the last poses), saved
/// and restored around a frame that may have to be undone.
#[derive(Debug, Clone, Default)]
pub struct CollisionHistory {
    flags: HisFlags,
    poses: Option<Vec<Pose>>,
}

/// The collision stage (see the module docs for its rules).
pub struct CollisionStage {
    config: CollisionConfig,
    triangles: Vec<[u32; 3]>,
    rest: Vec<Vec3>,
    spatulas: Vec<SpatulaSpec>,
    slots: Vec<RaySlot>,
    line_slots: Vec<LineSlot>,
    /// First slot of each spatula, plus the total at the end.
    spatula_offsets: Vec<usize>,
    /// Contact tolerance of each spatula, metres.
    contact_tolerances: Vec<f64>,
    /// The spatulas' shapes (for the other-face claim rule).
    shapes: Vec<SpatulaShape>,
    caster: Box<dyn RayCaster>,
    flags: HisFlags,
    culler: culling::Culler,
    work: Workspace,
    output: CollisionOutput,
    warnings: Vec<String>,
    /// An `Auto` stage's trial: the GPU caster timed beside `caster` (the bvh).
    trial: Option<AutoTrial>,
    /// Poses of the last successful frame (for swept-side culling), if any.
    previous_poses: Option<Vec<Pose>>,
    swept_culling: bool,
    /// Seconds the last frame spent in its caster (surface update and cast); the
    /// rest of `step` is the backend-independent part (rays, candidates, culling,
    /// targets).
    last_cast_seconds: f64,
}

/// An `Auto` stage's side-by-side timing of `bvh` (the stage's caster) and `gpu`.
struct AutoTrial {
    gpu: Box<dyn RayCaster>,
    bvh_seconds: Vec<f64>,
    gpu_seconds: Vec<f64>,
    hits: Vec<PairHits>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { f64::NAN } else { v[v.len() / 2] }
}

/// Checks triangle indices and finiteness of positions.
pub(crate) fn validate_surface(triangles: &[[u32; 3]], positions: &[Vec3]) -> Result<(), CollisionError> {
    if triangles.is_empty() {
        return Err(CollisionError::EmptySurface);
    }
    for (triangle, t) in triangles.iter().enumerate() {
        for &vertex in t {
            if vertex as usize >= positions.len() {
                return Err(CollisionError::TriangleIndex { triangle, vertex, count: positions.len() });
            }
        }
    }
    check_finite(positions)
}

fn check_finite(positions: &[Vec3]) -> Result<(), CollisionError> {
    match positions.iter().position(|p| !is_finite3(p)) {
        Some(vertex) => Err(CollisionError::NonFiniteVertex { vertex }),
        None => Ok(()),
    }
}

impl CollisionStage {
    /// Builds the stage. `triangles`: the boundary surface in surface-vertex indices;
    /// `rest`: rest positions of the surface vertices. A `Gpu` request without an
    /// adapter falls back to `Bvh` and says so in [`Self::warnings`].
    pub fn new(config: CollisionConfig, triangles: &[[u32; 3]], rest: &[Vec3], spatulas: &[SpatulaSpec]) -> Result<Self, CollisionError> {
        validate_surface(triangles, rest)?;
        if spatulas.is_empty() || spatulas.len() > 255 {
            return Err(CollisionError::SpatulaCount { count: spatulas.len() });
        }
        let mut slots = Vec::new();
        let mut line_slots = Vec::new();
        let mut spatula_offsets = Vec::with_capacity(spatulas.len() + 1);
        for (s, spec) in spatulas.iter().enumerate() {
            let pairs = spec.shape.node_pairs(&spec.layout).map_err(|source| CollisionError::Layout { spatula: s, source })?;
            spatula_offsets.push(slots.len());
            for k in 0..pairs.len() {
                let first = slots.len();
                line_slots.push(LineSlot { slots: [first + k, first + pairs.len() + k], thickness: spec.shape.thickness });
            }
            for face in 0..2u8 {
                for (k, &xy) in pairs.iter().enumerate() {
                    let node = face as u32 * pairs.len() as u32 + k as u32;
                    slots.push(RaySlot { spatula: s as u8, face, node, local: spec.shape.node_local(xy, face) });
                }
            }
        }
        spatula_offsets.push(slots.len());
        let mut warnings = Vec::new();
        let mut trial = None;
        let caster: Box<dyn RayCaster> = match config.backend {
            BackendKind::Reference => Box::new(backend::reference::ReferenceCaster::new(triangles, rest)),
            BackendKind::Bvh => Box::new(backend::bvh::BvhCaster::new(triangles, rest)),
            BackendKind::Gpu => match backend::gpu::GpuCaster::new(triangles, rest, line_slots.len()) {
                Ok(g) => Box::new(g),
                Err(e) => {
                    warnings.push(format!("GPU collision backend unavailable ({e}); using bvh"));
                    Box::new(backend::bvh::BvhCaster::new(triangles, rest))
                }
            },
            BackendKind::Auto => {
                match backend::gpu::GpuCaster::new(triangles, rest, line_slots.len()) {
                    Ok(g) => {
                        trial = Some(AutoTrial { gpu: Box::new(g), bvh_seconds: Vec::new(), gpu_seconds: Vec::new(), hits: Vec::new() })
                    }
                    Err(e) => warnings.push(format!("auto collision backend: bvh (no GPU: {e})")),
                }
                Box::new(backend::bvh::BvhCaster::new(triangles, rest))
            }
        };
        let n = slots.len();
        let work = Workspace {
            rays: Vec::with_capacity(n),
            lines: Vec::with_capacity(line_slots.len()),
            pair_hits: Vec::with_capacity(line_slots.len()),
            hits: vec![NearestHits::default(); n],
            claims: displacement::Claims::default(),
        };
        let output = CollisionOutput {
            per_spatula: vec![SpatulaCounts::default(); spatulas.len()],
            source_nodes: Vec::with_capacity(n),
            ..Default::default()
        };
        Ok(Self {
            config,
            triangles: triangles.to_vec(),
            rest: rest.to_vec(),
            spatulas: spatulas.to_vec(),
            slots,
            line_slots,
            spatula_offsets,
            contact_tolerances: spatulas.iter().map(|s| backend::CONTACT_TOLERANCE_RELATIVE * s.shape.thickness).collect(),
            shapes: spatulas.iter().map(|s| s.shape).collect(),
            caster,
            flags: HisFlags::new(n),
            culler: culling::Culler::new(triangles.len()),
            work,
            output,
            warnings,
            trial,
            previous_poses: None,
            swept_culling: true,
            last_cast_seconds: 0.0,
        })
    }

    /// One frame: `current` = deformed surface-vertex positions (same order as
    /// `rest`), `poses` one per spatula. On error nothing changes (flags included).
    pub fn step(&mut self, current: &[Vec3], poses: &[Pose]) -> Result<&CollisionOutput, CollisionError> {
        self.check_inputs(current, poses)?;
        self.cast_rays(poses);
        self.cast_lines(current)?;
        for (l, h) in self.line_slots.iter().zip(&self.work.pair_hits) {
            self.work.hits[l.slots[0]] = h.face0;
            self.work.hits[l.slots[1]] = h.face1;
        }
        self.find_pairs(current);
        let out = &mut self.output;
        let other_side = displacement::OtherSide {
            shapes: &self.shapes,
            previous: self.previous_poses.as_deref(),
            tolerances: &self.contact_tolerances,
        };
        displacement::resolve_targets(
            &self.triangles,
            current,
            &self.rest,
            &self.work.rays,
            &out.feasible_pairs,
            &self.spatula_offsets,
            &self.contact_tolerances,
            &other_side,
            &mut self.work.claims,
            &mut out.targets,
        );

        match &mut self.previous_poses {
            Some(v) => v.copy_from_slice(poses),
            None => self.previous_poses = Some(poses.to_vec()),
        }
        self.count();
        Ok(&self.output)
    }

    /// The frame's inputs: a position a surface vertex, a valid pose a spatula, every number finite.
    fn check_inputs(&self, current: &[Vec3], poses: &[Pose]) -> Result<(), CollisionError> {
        if current.len() != self.rest.len() {
            return Err(CollisionError::VertexCount { expected: self.rest.len(), got: current.len() });
        }
        if poses.len() != self.spatulas.len() {
            return Err(CollisionError::PoseCount { expected: self.spatulas.len(), got: poses.len() });
        }
        if let Some(spatula) = poses.iter().position(|p| !p.is_valid()) {
            return Err(CollisionError::InvalidPose { spatula });
        }
        check_finite(current)?;
        Ok(())
    }

    /// This frame's rays, a source node each, and the lines of the nodes paired across a blade.
    fn cast_rays(&mut self, poses: &[Pose]) {
        let rays = &mut self.work.rays;
        rays.clear();
        // Every node of a face shares its direction: one rotation per (spatula, face).
        let mut face_dir: Option<(u8, u8, Vec3)> = None;
        for slot in &self.slots {
            let pose = &poses[slot.spatula as usize];
            let direction = match face_dir {
                Some((s, f, d)) if s == slot.spatula && f == slot.face => d,
                _ => {
                    let d = pose.transform_vector(&crate::geometry::face_normal_local(slot.face));
                    face_dir = Some((slot.spatula, slot.face, d));
                    d
                }
            };
            rays.push(SourceRay { origin: pose.transform_point(&slot.local), direction });
        }
        self.work.lines.clear();
        for l in &self.line_slots {
            let r = &self.work.rays[l.slots[0]];
            self.work.lines.push(PairLine { origin: r.origin, direction: r.direction, thickness: l.thickness });
        }
    }

    /// Candidate pairs from the hits, culled by the flags (and by the blades' sweep), and the flags for next frame.
    fn find_pairs(&mut self, current: &[Vec3]) {
        let out = &mut self.output;
        out.candidate_pairs.clear();
        out.culled_pairs.clear();
        out.feasible_pairs.clear();
        for c in out.per_spatula.iter_mut() {
            *c = SpatulaCounts::default();
        }
        pairs::collect_candidates(&self.triangles, current, &self.work.rays, &self.work.hits, SlotFaces(&self.slots), &mut out.candidate_pairs);
        for s in 0..self.spatulas.len() {
            let range = self.spatula_offsets[s]..self.spatula_offsets[s + 1];
            self.culler.cull_spatula(
                self.config.culling,
                &self.flags,
                range,
                &self.work.hits,
                &out.candidate_pairs,
                s as u8,
                &mut out.culled_pairs,
                &mut out.feasible_pairs,
            );
        }
        if self.config.culling && self.swept_culling {
            if let Some(previous) = &self.previous_poses {
                culling::cull_swept(&self.work.rays, &self.spatula_offsets, &self.spatulas, previous, &self.contact_tolerances, &mut out.feasible_pairs, &mut out.culled_pairs);
            }
        }
        // Flags := has a feasible pair this frame (feasible pairs are in ray order).
        self.flags.clear();
        for p in &out.feasible_pairs {
            let slot = self.spatula_offsets[p.spatula as usize] + p.node as usize;
            self.flags.set(slot, true);
        }
    }

    /// Per-spatula counts and the source nodes as the overlays show them.
    fn count(&mut self) {
        let out = &mut self.output;
        for p in &out.candidate_pairs {
            out.per_spatula[p.spatula as usize].candidates += 1;
        }
        for (p, _) in &out.culled_pairs {
            out.per_spatula[p.spatula as usize].culled += 1;
        }
        for p in &out.feasible_pairs {
            out.per_spatula[p.spatula as usize].feasible += 1;
        }
        for t in &out.targets {
            out.per_spatula[t.spatula as usize].constrained_vertices += 1;
        }
        out.source_nodes.clear();
        for (r, (slot, ray)) in self.slots.iter().zip(&self.work.rays).enumerate() {
            let flagged = self.flags.get(r);
            if flagged {
                out.per_spatula[slot.spatula as usize].flagged_nodes += 1;
            }
            out.source_nodes.push(SourceNode {
                position: ray.origin,
                normal: ray.direction,
                spatula: slot.spatula,
                face: slot.face,
                node: slot.node,
                flagged,
            });
        }
    }

    /// Casts this frame's lines into `work.pair_hits`: the caster, an `Auto` trial
    /// beside it, and the switch to `bvh` when the GPU fails mid-run.
    fn cast_lines(&mut self, current: &[Vec3]) -> Result<(), CollisionError> {
        let t0 = std::time::Instant::now();
        let first = self.caster.update_surface(current).and_then(|()| self.caster.cast(&self.work.lines, &mut self.work.pair_hits));
        let caster_seconds = t0.elapsed().as_secs_f64();
        self.last_cast_seconds = caster_seconds;
        match first {
            Ok(()) => {}
            Err(CollisionError::Gpu(cause)) => {
                self.warnings.push(format!("GPU collision backend failed ({cause}); using bvh for the rest of the run"));
                let mut bvh = backend::bvh::BvhCaster::new(&self.triangles, &self.rest);
                bvh.update_surface(current)?;
                bvh.cast(&self.work.lines, &mut self.work.pair_hits)?;
                self.caster = Box::new(bvh);
                self.trial = None;
                return Ok(());
            }
            Err(e) => return Err(e),
        }
        if self.work.lines.is_empty() {
            return Ok(());
        }
        let Some(trial) = &mut self.trial else { return Ok(()) };
        let t1 = std::time::Instant::now();
        let gpu = trial.gpu.update_surface(current).and_then(|()| trial.gpu.cast(&self.work.lines, &mut trial.hits));
        let gpu_seconds = t1.elapsed().as_secs_f64();
        let verdict = match gpu {
            Err(e) => Some(format!("auto collision backend: bvh (the GPU failed in the trial: {e})")),
            Ok(()) if trial.hits != self.work.pair_hits => {
                Some("auto collision backend: bvh (the GPU's answers differed from bvh's in the trial; please report this)".to_string())
            }
            Ok(()) => {
                trial.bvh_seconds.push(caster_seconds);
                trial.gpu_seconds.push(gpu_seconds);
                None
            }
        };
        if let Some(v) = verdict {
            self.warnings.push(v);
            self.trial = None;
            return Ok(());
        }
        if trial.bvh_seconds.len() >= AUTO_TRIAL_FRAMES {
            let (b, g) = (median(&mut trial.bvh_seconds), median(&mut trial.gpu_seconds));
            let Some(trial) = self.trial.take() else { return Ok(()) };
            let chosen = if g < b { "gpu" } else { "bvh" };
            self.warnings.push(format!(
                "auto collision backend: {chosen} (median over {AUTO_TRIAL_FRAMES} frames: gpu {:.3} ms, bvh {:.3} ms)",
                g * 1e3,
                b * 1e3
            ));
            if g < b {
                self.caster = trial.gpu;
            }
        }
        Ok(())
    }

    /// Seconds the last frame spent in its caster (surface update and cast), without
    /// the backend-independent rest of the stage.
    pub fn last_cast_seconds(&self) -> f64 {
        self.last_cast_seconds
    }

    /// Where the last frame's cast spent its time, when the GPU backend is in use.
    pub fn gpu_timings(&self) -> Option<backend::gpu::GpuTimings> {
        self.caster.gpu_timings()
    }

    /// The GPU adapter's name, when the GPU backend is in use (or in an `Auto` trial).
    pub fn gpu_name(&self) -> Option<String> {
        self.caster.device_name().or_else(|| self.trial.as_ref().and_then(|t| t.gpu.device_name()))
    }

    /// Splits the `bvh` backend's work over `threads` threads (the default is
    /// min(rayon's pool, 2)); other backends ignore it. Answers do not change.
    pub fn set_cpu_threads(&mut self, threads: usize) {
        self.caster.set_threads(threads);
    }

    /// True while an `Auto` stage is still timing both backends.
    pub fn auto_trial_running(&self) -> bool {
        self.trial.is_some()
    }

    /// Test hook: the GPU caster (in use or in an `Auto` trial) fails at its next
    /// cast as a lost device would. Returns false when there is none.
    #[doc(hidden)]
    pub fn simulate_gpu_loss(&mut self) -> bool {
        if let Some(t) = &mut self.trial {
            return t.gpu.simulate_device_loss();
        }
        self.caster.simulate_device_loss()
    }

    /// Clears every His-flag (e.g. after a scene reset or a teleported tool).
    pub fn reset_history(&mut self) {
        self.flags.clear();
        self.previous_poses = None;
    }

    /// Copies the history a frame reads (His-flags, last poses) into `into`
    /// (its buffers are reused): a frame whose solve fails can be undone with
    /// [`Self::restore_history`], so the next frame sees the last feasible one.
    pub fn save_history(&self, into: &mut CollisionHistory) {
        into.flags.clone_from(&self.flags);
        match (&mut into.poses, &self.previous_poses) {
            (Some(a), Some(b)) => a.clone_from(b),
            (a, b) => *a = b.clone(),
        }
    }

    /// Puts back a history saved by [`Self::save_history`].
    pub fn restore_history(&mut self, from: &CollisionHistory) {
        self.flags.clone_from(&from.flags);
        match (&mut self.previous_poses, &from.poses) {
            (Some(a), Some(b)) => a.clone_from(b),
            (a, b) => *a = b.clone(),
        }
    }

    /// Turns our swept-side culling rule (3b in the module docs) on or off; on by
    /// default. Off leaves exactly the paper's His-flag culling.
    pub fn set_swept_culling(&mut self, on: bool) {
        self.swept_culling = on;
    }

    /// The backend actually in use.
    pub fn backend(&self) -> BackendKind {
        self.caster.kind()
    }

    /// Warnings from construction and from frames so far (the GPU fallback, the
    /// `Auto` choice), in order.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The last frame's output.
    pub fn output(&self) -> &CollisionOutput {
        &self.output
    }

    /// The last frame's nearest hits behind and in front of every source node,
    /// one per ray slot, in the order of [`CollisionOutput::source_nodes`].
    pub fn nearest_hits(&self) -> &[NearestHits] {
        &self.work.hits
    }

    /// His-flags, one per ray slot (spatula by spatula, face 0 then face 1).
    pub fn his_flags(&self) -> &HisFlags {
        &self.flags
    }

    /// Number of source nodes (both faces, all spatulas).
    pub fn node_count(&self) -> usize {
        self.slots.len()
    }
}

/// Read access to the static (spatula, face, node) tags of the ray slots.
#[derive(Clone, Copy)]
pub(crate) struct SlotFaces<'a>(&'a [RaySlot]);

impl SlotFaces<'_> {
    /// (spatula, face, node) of ray slot `r`.
    #[inline]
    pub fn tag(&self, r: usize) -> (u8, u8, u32) {
        let s = &self.0[r];
        (s.spatula, s.face, s.node)
    }
}
