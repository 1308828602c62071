//! The collision-stage benchmark behind `fissure bench collision` and
//! `cargo bench --bench collision`: every backend on the same scenes, in one run,
//! so their ratios are fair on a shared machine.
//!
//! Each case plays one motion: two blades (the given nodes a face) advance into the
//! surface from opposite sides over the frames, and the surface deforms to each
//! frame's targets (kinematically: vertices moved to their enforced displacement),
//! so the later frames cast through contact as a retraction does. Every backend
//! plays the same frames; since all give the same answers, the motion is the same,
//! and the run checks that (a blake3 hash of every frame's output).
//! Out: a row per (case, backend) with the stage's p50/p95 per frame and, for
//! `gpu`, the median split of a frame (upload, wait for the device, f64 decisions)
//! and the GPU's own refit and traversal time from timestamp queries.

use super::backend::gpu::GpuTimings;
use super::scenes::pose_from_axes;
use super::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use crate::geometry::{NodeLayout, Pose, SpatulaShape};
use crate::math::Vec3;
use std::time::Instant;

const MM: f64 = 1e-3;

/// One surface to cast against.
pub struct BenchSurface {
    pub name: String,
    pub triangles: Vec<[u32; 3]>,
    /// Rest positions, metres.
    pub positions: Vec<Vec3>,
}

impl BenchSurface {
    /// The boundary of the `paper-12k` phantom.
    pub fn paper12k() -> Result<Self, String> {
        let ph = crate::mesh::phantom::generate(crate::mesh::phantom::Preset::Paper12k).map_err(|e| format!("generating paper-12k: {e}"))?;
        let s = ph.mesh.boundary();
        Ok(Self { name: "paper-12k".into(), positions: s.gather_positions(&ph.mesh.positions), triangles: s.triangles })
    }

    /// The boundary of a tet mesh file in millimetres (the real brains).
    pub fn tet_mesh_mm(path: &std::path::Path, name: &str) -> Result<Self, String> {
        let mut mesh = crate::mesh::io::load_tet_mesh(path).map_err(|e| e.to_string())?;
        mesh.scale(MM);
        let s = mesh.boundary();
        Ok(Self { name: name.into(), positions: s.gather_positions(&mesh.positions), triangles: s.triangles })
    }
}

/// The standard cases: paper-12k at 150 / 500 / 2000 nodes a face, and the real
/// brains in `mesh_dir` (`brain_pial_coarse` and `brain_pial_q15`, `.msh.gz` or `.msh`) at 500 /
/// 2000; only surfaces whose name contains `only`, when given. A brain file that
/// is missing is skipped with a note; one that does not load is an error.
pub fn standard_surfaces(mesh_dir: &std::path::Path, only: Option<&str>, note: &mut dyn FnMut(String)) -> Result<Vec<(BenchSurface, Vec<u32>)>, String> {
    let wanted = |name: &str| only.is_none_or(|o| name.contains(o));
    let mut surfaces = Vec::new();
    if wanted("paper-12k") {
        surfaces.push((BenchSurface::paper12k()?, vec![150, 500, 2000]));
    }
    for (stem, name) in [(crate::mesh::brain::COARSE, "brain-coarse"), (crate::mesh::brain::FINE, "brain-q15")] {
        if !wanted(name) {
            continue;
        }
        let Some(path) = crate::mesh::brain::find_in(mesh_dir, stem) else {
            note(format!("neither {stem}.msh.gz nor {stem}.msh is in {}; the {name} cases are skipped", mesh_dir.display()));
            continue;
        };
        surfaces.push((BenchSurface::tet_mesh_mm(&path, name).map_err(|e| format!("{}: {e}", path.display()))?, vec![500, 2000]));
    }
    Ok(surfaces)
}

/// Every backend the benchmark times, in table order.
pub const ALL_BACKENDS: [BenchBackend; 4] = [BenchBackend::Bvh, BenchBackend::BvhAllCores, BenchBackend::Gpu, BenchBackend::Reference];

/// A backend as the benchmark runs it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BenchBackend {
    /// The CPU BVH with its default thread count (min(pool, 2)).
    Bvh,
    /// The CPU BVH on every thread of rayon's pool.
    BvhAllCores,
    Gpu,
    /// Only where lines x triangles stay under [`REFERENCE_MAX_WORK`].
    Reference,
}

/// Largest lines x triangles the brute-force reference is timed on.
pub const REFERENCE_MAX_WORK: usize = 20_000_000;

impl BenchBackend {
    pub fn name(self) -> String {
        match self {
            Self::Bvh => "bvh".into(),
            Self::BvhAllCores => format!("bvh x{}", rayon::current_num_threads()),
            Self::Gpu => "gpu".into(),
            Self::Reference => "reference".into(),
        }
    }
}

/// One measured (case, backend).
#[derive(Debug, Clone)]
pub struct BenchRow {
    pub surface: String,
    pub triangles: usize,
    pub nodes_a_face: u32,
    pub backend: String,
    pub p50_ms: f64,
    pub p95_ms: f64,
    /// Medians of the caster's part (surface update and cast) and of the rest of
    /// the stage (rays, candidates, culling, targets: the same code on every backend).
    pub cast_p50_ms: f64,
    pub rest_p50_ms: f64,
    /// Median GPU breakdown (gpu rows).
    pub gpu: Option<GpuBreakdown>,
    /// Candidate pairs over the run (the same for every backend of a case).
    pub candidates: usize,
    /// blake3 of every frame's output: equal across backends of one case.
    pub answer_hash: String,
    /// The GPU adapter (gpu rows).
    pub device: Option<String>,
}

/// Medians of a GPU frame's parts, milliseconds.
#[derive(Debug, Clone, Copy, Default)]
pub struct GpuBreakdown {
    pub upload_ms: f64,
    pub wait_ms: f64,
    pub decide_ms: f64,
    pub refit_gpu_ms: Option<f64>,
    pub traverse_gpu_ms: Option<f64>,
    /// Share of lines the shader flagged for the CPU.
    pub flagged: f64,
    /// Share of lines flagged for a cluster of three, a grazing hit, a full stack.
    pub reasons: [f64; 3],
}

fn layout(n: u32) -> NodeLayout {
    let across = match n {
        0..=30 => 5,
        31..=500 => 10,
        _ => 20,
    };
    NodeLayout::Grid { along: n.div_ceil(across), across }
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1]
}

/// The two blades' poses at `s` in [0, 1] of the motion: they enter the box `lo..hi`
/// from opposite sides, tilted, and advance along their blades (of `length`).
pub fn poses(lo: Vec3, hi: Vec3, length: f64, s: f64) -> [Pose; 2] {
    let c = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let depth = 0.15 * half.x.min(half.y).min(half.z);
    let advance = length * (0.3 + 0.5 * s);
    let d0 = Vec3::new(1.0, 0.05, -0.3).normalize();
    let d1 = Vec3::new(-1.0, 0.1, -0.3).normalize();
    let tip0 = Vec3::new(lo.x - 0.5 * length, c.y + 2.0 * MM, hi.z - depth);
    let tip1 = Vec3::new(hi.x + 0.5 * length, c.y - 2.0 * MM, hi.z - depth);
    [
        pose_from_axes(tip0 + d0 * advance, d0, Vec3::new(0.3, 0.0, 1.0)),
        pose_from_axes(tip1 + d1 * advance, d1, Vec3::new(0.0, 1.0, 0.0)),
    ]
}

/// Runs `frames` frames (after `warmup`) of one case on one backend.
fn run_case(surface: &BenchSurface, nodes: u32, backend: BenchBackend, frames: usize, warmup: usize) -> Result<BenchRow, String> {
    let (lo, hi) = surface.positions.iter().fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(a, b), q| (a.inf(q), b.sup(q)));
    let length = 0.35 * (hi.x - lo.x);
    let shape = SpatulaShape { length, width: 10.0 * MM, thickness: 1.0 * MM };
    let spec = SpatulaSpec { shape, layout: layout(nodes) };
    let kind = match backend {
        BenchBackend::Bvh | BenchBackend::BvhAllCores => BackendKind::Bvh,
        BenchBackend::Gpu => BackendKind::Gpu,
        BenchBackend::Reference => BackendKind::Reference,
    };
    let mut stage = CollisionStage::new(CollisionConfig { backend: kind, culling: true }, &surface.triangles, &surface.positions, &[spec.clone(), spec])
        .map_err(|e| format!("{}: {e}", surface.name))?;
    if stage.backend() != kind {
        return Err(stage.warnings().join("; "));
    }
    if backend == BenchBackend::BvhAllCores {
        stage.set_cpu_threads(rayon::current_num_threads());
    }
    let rest = &surface.positions;
    let mut cur = rest.clone();
    let mut times = Vec::with_capacity(frames);
    let mut cast_times = Vec::with_capacity(frames);
    let mut rest_times = Vec::with_capacity(frames);
    let mut gpu: Vec<GpuTimings> = Vec::new();
    let mut hasher = blake3::Hasher::new();
    let mut candidates = 0;
    let total = warmup + frames;
    for f in 0..total {
        let ps = poses(lo, hi, length, f as f64 / total.max(1) as f64);
        let t0 = Instant::now();
        stage.step(&cur, &ps).map_err(|e| format!("{} frame {f}: {e}", surface.name))?;
        let dt = t0.elapsed().as_secs_f64();
        if f >= warmup {
            times.push(dt * 1e3);
            cast_times.push(stage.last_cast_seconds() * 1e3);
            rest_times.push((dt - stage.last_cast_seconds()) * 1e3);
            if let Some(g) = stage.gpu_timings() {
                gpu.push(g);
            }
        }
        let out = stage.output();
        candidates += out.candidate_pairs.len();
        for p in &out.feasible_pairs {
            let (s, face, node, tri) = p.key();
            hasher.update(&[s, face]);
            hasher.update(&node.to_le_bytes());
            hasher.update(&tri.to_le_bytes());
        }
        cur.copy_from_slice(rest);
        for t in &out.targets {
            hasher.update(&t.vertex.to_le_bytes());
            for c in t.displacement.iter() {
                hasher.update(&c.to_bits().to_le_bytes());
            }
            cur[t.vertex as usize] = rest[t.vertex as usize] + t.displacement;
        }
    }
    let gpu = (!gpu.is_empty()).then(|| {
        let med = |f: &dyn Fn(&GpuTimings) -> f64| percentile(&mut gpu.iter().map(f).collect::<Vec<_>>(), 0.5);
        let med_opt = |f: &dyn Fn(&GpuTimings) -> Option<f64>| {
            let mut v: Vec<f64> = gpu.iter().filter_map(f).map(|x| x * 1e3).collect();
            (!v.is_empty()).then(|| percentile(&mut v, 0.5))
        };
        GpuBreakdown {
            upload_ms: med(&|g| g.upload * 1e3),
            wait_ms: med(&|g| g.wait * 1e3),
            decide_ms: med(&|g| g.decide * 1e3),
            refit_gpu_ms: med_opt(&|g| g.refit_gpu),
            traverse_gpu_ms: med_opt(&|g| g.traverse_gpu),
            flagged: gpu.iter().map(|g| g.flagged_lines as f64 / g.lines.max(1) as f64).sum::<f64>() / gpu.len() as f64,
            reasons: [0, 1, 2].map(|k| gpu.iter().map(|g| g.flag_reasons[k] as f64 / g.lines.max(1) as f64).sum::<f64>() / gpu.len() as f64),
        }
    });
    Ok(BenchRow {
        surface: surface.name.clone(),
        triangles: surface.triangles.len(),
        nodes_a_face: nodes,
        backend: backend.name(),
        p50_ms: percentile(&mut times.clone(), 0.5),
        p95_ms: percentile(&mut times, 0.95),
        cast_p50_ms: percentile(&mut cast_times, 0.5),
        rest_p50_ms: percentile(&mut rest_times, 0.5),
        gpu,
        candidates,
        answer_hash: hasher.finalize().to_hex()[..16].to_string(),
        device: stage.gpu_name(),
    })
}

/// Runs every (surface, nodes a face) case on every backend; `report` gets each
/// row as it is measured (or the reason a backend was skipped).
pub fn run(cases: &[(&BenchSurface, u32)], backends: &[BenchBackend], frames: usize, warmup: usize, report: &mut dyn FnMut(Result<&BenchRow, String>)) -> Vec<BenchRow> {
    let mut rows = Vec::new();
    for &(surface, nodes) in cases {
        for &b in backends {
            if b == BenchBackend::Reference && 2 * nodes as usize * surface.triangles.len() > REFERENCE_MAX_WORK {
                continue;
            }
            match run_case(surface, nodes, b, frames, warmup) {
                Ok(row) => {
                    report(Ok(&row));
                    rows.push(row);
                }
                Err(e) => report(Err(format!("{} {nodes}/face {}: skipped ({e})", surface.name, b.name()))),
            }
        }
    }
    rows
}

/// The header of [`table_row`]'s Markdown table.
pub const TABLE_HEADER: &str = "| surface | triangles | nodes a face | backend | p50 ms | p95 ms | p50 ms: cast / rest of stage | gpu: upload / wait / f64 decide ms | gpu timestamps: refit / traversal ms | lines to CPU % (cluster / grazing / stack) | answers |\n|---|---:|---:|---|---:|---:|---|---|---|---:|---|";

/// One Markdown table row.
pub fn table_row(r: &BenchRow) -> String {
    let (split, stamps, flagged) = match &r.gpu {
        Some(g) => {
            let f = |x: Option<f64>| x.map_or("n/a".to_string(), |v| format!("{v:.3}"));
            (
                format!("{:.3} / {:.3} / {:.3}", g.upload_ms, g.wait_ms, g.decide_ms),
                format!("{} / {}", f(g.refit_gpu_ms), f(g.traverse_gpu_ms)),
                format!("{:.2} % ({:.2} / {:.2} / {:.2})", 100.0 * g.flagged, 100.0 * g.reasons[0], 100.0 * g.reasons[1], 100.0 * g.reasons[2]),
            )
        }
        None => ("".into(), "".into(), "".into()),
    };
    format!(
        "| {} | {} | {} | {} | {:.3} | {:.3} | {:.3} / {:.3} | {} | {} | {} | {} |",
        r.surface, r.triangles, r.nodes_a_face, r.backend, r.p50_ms, r.p95_ms, r.cast_p50_ms, r.rest_p50_ms, split, stamps, flagged, r.answer_hash
    )
}

/// The cases whose backends gave different answers (hashes), as "surface N/face".
pub fn mismatches(rows: &[BenchRow]) -> Vec<String> {
    let mut out = Vec::new();
    for (k, r) in rows.iter().enumerate() {
        let first = rows.iter().position(|q| q.surface == r.surface && q.nodes_a_face == r.nodes_a_face);
        if first == Some(k) && rows.iter().any(|q| q.surface == r.surface && q.nodes_a_face == r.nodes_a_face && q.answer_hash != r.answer_hash) {
            out.push(format!("{} {}/face", r.surface, r.nodes_a_face));
        }
    }
    out
}

/// The GPU adapter the rows ran on, or "none".
pub fn device(rows: &[BenchRow]) -> String {
    rows.iter().find_map(|r| r.device.clone()).unwrap_or_else(|| "none".into())
}
