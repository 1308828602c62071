//! FEM stage benchmark: assembly, factorization, compliance precompute and
//! reload, per-frame constrained solve (100 / 300 constrained vertices, 10 / 30
//! new a frame), interior solve, memory peak. For `paper-12k` (the phantom
//! generator) and both shipped real brains (`assets/brain/brain_pial_coarse.msh.gz`
//! and `brain_pial_q15.msh.gz`). Before the precompute,
//! each model's `K_FF` is factored with AMD and with nested dissection.
//!
//! With 100 and 300 constrained it prints the floor of a frame measured in the
//! same run ([`floor_ms`]) and the frame p95 as a multiple of it.
//!
//! Run: `cargo bench --bench fem` (add `-- brain`, `-- coarse`, `-- q15` or
//! `-- paper` to run some models).
//! Storage: env `FEM_BENCH_STORAGE` = `f32` (default) | `f64`. After the frames, the last 300-constrained frame is solved
//! again with an f64 compliance whose ROI is exactly its constrained nodes (a
//! fresh model), and the relative displacement / reaction errors are printed.
//!
//! `cargo bench --bench fem -- audit` (add `paper`, `coarse`, ... to pick the
//! models) measures instead each per-frame optimisation of fem/ that
//! `fem::tuning` can switch off, on and off in the same run, alternating,
//! three rounds (the medians), on three frame sequences: a held set of 300
//! constrained vertices, a set growing by 30 a frame to 300, and the window
//! of 300 sliding by 30 a frame above; and the row-major sparse solve (one
//! 96-column solve, on and off). The scene-level switches run in
//! `scripts/fem_audit.sh`.
//!
//! A plain `main` (harness = false) with explicit percentiles: the one-shot
//! phases take seconds and cannot be repeated criterion-style.

use fissure::perf::reports::{AuditBar, CompliancePrecompute, ErrorFigures, FemFigures, FrameFigures, OrderingFigures};
use fissure::fem::{
    Compliance, ComplianceStorage, ComputeOptions, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution, Material,
    RegionMaterials, element_stress,
};
use fissure::linalg::SparseCholesky;
use fissure::mesh::fixtures;
use fissure::linalg::FillOrdering;
use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn peak_rss_mb() -> f64 {
    fissure::meminfo::peak_resident_bytes().map_or(f64::NAN, |b| b as f64 / (1024.0 * 1024.0))
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn storage_from_env() -> ComplianceStorage {
    let v = std::env::var("FEM_BENCH_STORAGE").unwrap_or_default().to_ascii_lowercase();
    match v.as_str() {
        "" | "f32" => ComplianceStorage::F32,
        "f64" => ComplianceStorage::F64,
        _ => panic!("FEM_BENCH_STORAGE={v}: expected f32 or f64"),
    }
}

/// max |a - b| / max |b|
fn rel_error(a: &[Vec3], b: &[Vec3]) -> f64 {
    let diff = a.iter().zip(b).fold(0.0_f64, |m, (x, y)| m.max((x - y).norm()));
    diff / b.iter().fold(0.0_f64, |m, x| m.max(x.norm())).max(f64::MIN_POSITIVE)
}

fn run(name: &str, mesh: &TetMesh, roi_pred: &dyn Fn(&Vec3) -> bool, cache: &Path, audit_only: bool) {
    let storage = storage_from_env();
    println!("== {name}: {} nodes, {} tets", mesh.node_count(), mesh.tets.len());
    let mut figures = FemFigures { model: name.to_string(), nodes: mesh.node_count(), tets: mesh.tets.len(), ..FemFigures::default() };
    let fixed = fixtures::fix_bottom_of_each_component(mesh, 0.010);
    let materials = RegionMaterials::uniform(Material { young_modulus: 3.0e3, poisson_ratio: 0.45 });
    let t = Instant::now();
    let model = match FemModel::new(mesh, &materials, &fixed, &FemOptions::default()) {
        Ok(m) => m,
        Err(e) => {
            println!("model failed: {e}");
            return;
        }
    };
    figures.factor_total_s = t.elapsed().as_secs_f64();
    let s = model.stats();
    println!(
        "model: {} free DOFs, nnz(K lower) {}, nnz(L) {} ({:.0} MB); assembly {:.3} s, symbolic {:.3} s, numeric {:.3} s (total {:.3} s)",
        s.free_dofs,
        s.nnz_k,
        s.nnz_l,
        s.nnz_l as f64 * 8.0 / 1e6,
        s.assembly_seconds,
        s.symbolic_seconds,
        s.numeric_seconds,
        figures.factor_total_s
    );
    let mut audit = Vec::new();
    if audit_only {
        audit.extend(row_major_audit(&model));
    } else {
        figures.orderings = ordering_lines(&model);
    }
    let surface = model.surface().vertices.clone();
    let roi: Vec<u32> = surface.iter().copied().filter(|&n| roi_pred(&mesh.positions[n as usize]) && !model.is_fixed(n)).collect();
    // The working region's rows, as a scene with the default `solver.row_band_mm` stores them.
    let band = fissure::scenario::DEFAULT_ROW_BAND_MM * 1e-3;
    let rows = fissure::sim::build::rows_near(&mesh.positions, &surface, &roi, band, &|_| false);
    println!("surface vertices {}, ROI vertices {}, working-region rows {} (within {:.0} mm of the ROI)", surface.len(), roi.len(), rows.len(), band * 1e3);
    // FEM_BENCH_KEEP_CACHE=1 skips the fresh precompute (for profiling the frames)
    if std::env::var_os("FEM_BENCH_KEEP_CACHE").is_none() {
        let _ = std::fs::remove_dir_all(cache);
    }
    let t = Instant::now();
    let mut last = 0;
    let options = || ComputeOptions { cache_dir: Some(cache), rows: Some(&rows), ..ComputeOptions::new(storage) };
    let compliance = Compliance::compute_with(&model, &roi, options(), &mut |done, total| {
        if done * 10 / total.max(1) > last {
            last = done * 10 / total.max(1);
            eprint!("{}% ", last * 10);
        }
    })
    .expect("compliance");
    eprintln!();
    let cs = compliance.stats();
    println!(
        "compliance ({storage:?}): {} rows x {} cols, {:.0} MB, precompute {:.2} s (incl. cache write {:.2} s total)",
        cs.rows,
        cs.cols,
        cs.bytes as f64 / 1e6,
        cs.compute_seconds,
        t.elapsed().as_secs_f64()
    );
    let (precompute_s, megabytes) = (cs.compute_seconds, cs.bytes as f64 / 1e6);
    drop(compliance);
    let t = Instant::now();
    let compliance = Compliance::compute_with(&model, &roi, options(), &mut |_, _| {}).expect("reload");
    println!("compliance reload from disk cache: {:.3} s (from_cache = {})", t.elapsed().as_secs_f64(), compliance.stats().from_cache);
    figures.compliance = Some(CompliancePrecompute { rows: cs.rows, cols: cs.cols, megabytes, precompute_s, reload_s: t.elapsed().as_secs_f64() });
    // Frame sequence: a window sliding over ROI vertices near the ROI's top, ordered by x.
    let top = roi.iter().copied().max_by(|a, b| mesh.positions[*a as usize].z.total_cmp(&mesh.positions[*b as usize].z)).unwrap();
    let p0 = mesh.positions[top as usize];
    let mut near: Vec<u32> = roi.clone();
    near.sort_by(|a, b| (mesh.positions[*a as usize] - p0).norm().total_cmp(&(mesh.positions[*b as usize] - p0).norm()).then(a.cmp(b)));
    near.truncate(2400.min(near.len()));
    near.sort_by(|a, b| mesh.positions[*a as usize].x.total_cmp(&mesh.positions[*b as usize].x).then(a.cmp(b)));
    let mut solver = ConstrainedSolver::new(model, compliance).expect("solver");
    if audit_only {
        audit.extend(frame_audit(name, &mut solver, &near, &cache.parent().unwrap_or(cache).join("audit")));
        write_figures(cache, &format!("{name}_audit"), &audit);
        return;
    }
    let mut last_frame: (Vec<Constraint>, FrameSolution) = (Vec::new(), FrameSolution::default());
    for (count, fresh) in [(100usize, 10usize), (300, 30)] {
        let Some(m) = measure(&mut solver, &near, count, fresh, 60) else {
            println!("not enough ROI vertices for {count} constrained");
            continue;
        };
        println!(
            "frame solve + surface update, {count} constrained ({} rows), {fresh} new/frame, {} frames: p50 {:.2} ms, p95 {:.2} ms, max {:.2} ms; cond(W) est. {:.2e}, max |u| {:.2} mm",
            m.out.rows,
            m.frames,
            m.p50,
            m.p95,
            m.max,
            m.out.conditioning,
            m.out.max_displacement * 1e3
        );
        let p = m.phases;
        println!(
            "  mean phase times: gather {:.2} ms, factor+solve W {:.2} ms, candidates {:.2} ms, surface product {:.2} ms (of which gathering rows of new columns {:.2} ms), lazy columns {:.2} ms",
            p[0], p[1], p[2], p[3], p[4], p[5]
        );
        let mut frame = FrameFigures {
            constrained: count,
            p50_ms: m.p50,
            p95_ms: m.p95,
            max_ms: m.max,
            floor_ms: None,
            p95_over_floor: None,
            product_floor_ms: None,
            product_ms: m.phases[3],
            stream_gb_s: None,
            two_floors_ms: None,
            p95_over_two_floors: None,
        };
        let nodes: Vec<u32> = m.cons.iter().map(|c| c.node).collect();
        if let Some(f) = floor_ms(solver.compliance(), &nodes, fresh) {
            // the cheapest dense factor measured (on a busy machine the
            // threaded ones can lose to one thread at a few hundred rows)
            let floor = f.read_new + f.f32_par.min(f.f64_par).min(f.f64_seq);
            // The surface update reads every stored row of each constrained
            // node's column once: at best at this machine's streaming rate.
            let entry_bytes = match solver.compliance().storage() {
                ComplianceStorage::F64 => 8.0,
                ComplianceStorage::F32 => 4.0,
            };
            // rows a column stores: those of its own body (K^-1 between the
            // bodies K does not couple, such as the hemispheres, is zero and not stored)
            let c = solver.compliance();
            let rows = c.stats().rows;
            let stored_rows: usize = nodes
                .iter()
                .filter_map(|&n| c.col_of(n))
                .map(|col| (0..rows).filter(|&r| c.block(r, col) != fissure::math::Matrix3::zeros()).count())
                .sum();
            let product_bytes = 9.0 * stored_rows as f64 * entry_bytes;
            let rate = *STREAM_RATE.get_or_init(stream_bytes_per_s);
            let product_floor = product_bytes / rate * 1e3;
            println!(
                "  product floor, same run: the constrained columns ({:.1} MB) read once at {:.1} GB/s (this machine streaming a 256 MB buffer) = {product_floor:.2} ms; mean product {:.2} ms = {:.1}x it; frame p95 = {:.1}x (W floor + product floor = {:.2} ms)",
                product_bytes / 1e6,
                rate / 1e9,
                m.phases[3],
                m.phases[3] / product_floor,
                m.p95 / (floor + product_floor),
                floor + product_floor
            );
            println!(
                "  floor, same run: reading W's new entries {:.2} ms (all of W {:.2} ms), dense Cholesky of W {:.2} ms f64 one thread, {:.2} ms f64 every core ({}), {:.2} ms f32 every core; frame p95 = {:.1}x the floor (new entries + the cheapest of those factors = {floor:.2} ms)",
                f.read_new,
                f.read_all,
                f.f64_seq,
                f.f64_par,
                if f.par_bitwise { "bitwise the one-thread factor" } else { "differs from the one-thread factor" },
                f.f32_par,
                m.p95 / floor
            );
            frame.floor_ms = Some(floor);
            frame.p95_over_floor = Some(m.p95 / floor);
            frame.product_floor_ms = Some(product_floor);
            frame.stream_gb_s = Some(rate / 1e9);
            frame.two_floors_ms = Some(floor + product_floor);
            frame.p95_over_two_floors = Some(m.p95 / (floor + product_floor));
        }
        figures.frames.push(frame);
        last_frame = (m.cons, m.out);
    }
    // Frame time against the number of constrained vertices (a tenth new each frame): a table and a plot.
    let mut sweep = Vec::new();
    for count in [25usize, 50, 100, 150, 200, 250, 300] {
        if let Some(m) = measure(&mut solver, &near, count, count / 10, 40) {
            sweep.push((count, m));
        }
    }
    let dir = cache.parent().unwrap_or(cache).join("sweep");
    match write_sweep(name, &sweep, &dir) {
        Ok(png) => println!("constrained-vertex sweep ({} counts): {}", sweep.len(), png.display()),
        Err(e) => println!("constrained-vertex sweep not written: {e}"),
    }
    let mut all = Vec::new();
    let t = Instant::now();
    solver.interior_displacements(&mut all).expect("interior");
    let ti = t.elapsed().as_secs_f64() * 1e3;
    let mut stress = Vec::new();
    let t = Instant::now();
    element_stress(solver.model(), &all, &mut stress).expect("stress");
    println!("interior displacements (one sparse solve) {ti:.1} ms; element stress {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    println!("peak resident memory so far: {:.0} MB", peak_rss_mb());
    figures.peak_rss_mb = peak_rss_mb();
    drop(solver);
    if !last_frame.0.is_empty() {
        // Error of this storage: the same frame with an exact f64 compliance over its constrained nodes only.
        let (cons, out) = &last_frame;
        let nodes: Vec<u32> = cons.iter().map(|c| c.node).collect();
        let fixed = fixtures::fix_bottom_of_each_component(mesh, 0.010);
        let materials = RegionMaterials::uniform(Material { young_modulus: 3.0e3, poisson_ratio: 0.45 });
        let exact = FemModel::new(mesh, &materials, &fixed, &FemOptions::default())
            .and_then(|m| Compliance::compute(&m, &nodes, ComplianceStorage::F64, None, &mut |_, _| {}).map(|c| (m, c)))
            .and_then(|(m, c)| ConstrainedSolver::new(m, c))
            .and_then(|mut s| {
                let mut r = FrameSolution::default();
                s.step(cons, &mut r).map(|_| r)
            });
        match exact {
            Ok(r) => {
                // The working region's displacement (the rest of the surface is brought up to date only where an output reads it).
                let stored: std::collections::HashSet<u32> = rows.iter().copied().collect();
                let in_region = |u: &[Vec3]| -> Vec<Vec3> { surface.iter().zip(u).filter(|(n, _)| stored.contains(n)).map(|(_, u)| *u).collect() };
                let error = ErrorFigures {
                    constrained: cons.len(),
                    displacement: rel_error(&in_region(&out.displacement_surface), &in_region(&r.displacement_surface)),
                    reaction: rel_error(&out.reactions, &r.reactions),
                };
                println!(
                    "error vs f64 ({} constrained): displacement {:.2e} (the working region), reaction {:.2e} (relative, max norm)",
                    error.constrained, error.displacement, error.reaction
                );
                figures.error_vs_f64 = Some(error);
            }
            Err(e) => println!("f64 reference failed: {e}"),
        }
    }
    write_figures(cache, name, &figures);
}

/// Writes `figures` as `target/fem-bench-cache/figures/STEM.json` (beside the model's `cache`).
fn write_figures(cache: &Path, stem: &str, figures: &impl serde::Serialize) {
    let path = cache.parent().unwrap_or(cache).join("figures").join(format!("{stem}.json"));
    let written = std::fs::create_dir_all(path.parent().unwrap_or(cache))
        .and_then(|()| std::fs::write(&path, serde_json::to_string_pretty(figures).expect("the figures serialize")));
    match written {
        Ok(()) => println!("figures: {}", path.display()),
        Err(e) => println!("figures not written to {}: {e}", path.display()),
    }
}

/// The same `K_FF` factored with each fill-reducing ordering: entries of L,
/// analysis, numeric factor and one 96-column solve (the precompute's batch),
/// best of three. One thread, as the model factors.
fn ordering_lines(model: &FemModel) -> Vec<OrderingFigures> {
    let k = model.stiffness();
    let dofs = model.dofs();
    let mut base: Option<(f64, f64)> = None;
    let mut figures = Vec::new();
    for ordering in [FillOrdering::Amd, FillOrdering::NestedDissection] {
        let t = Instant::now();
        let chol = match SparseCholesky::new(k, ordering, &|d| dofs.name(d)) {
            Ok(c) => c,
            Err(e) => {
                println!("ordering {ordering:?}: factor failed: {e}");
                continue;
            }
        };
        let total = t.elapsed().as_secs_f64();
        let mut rhs = faer::Mat::<f64>::zeros(k.dim, 96);
        let mut scratch = chol.scratch(96).expect("scratch");
        let mut solve = f64::INFINITY;
        for rep in 0..3 {
            rhs.fill(0.0);
            for c in 0..96 {
                rhs[((c * 7919 + rep) % k.dim, c)] = 1.0;
            }
            let t = Instant::now();
            chol.solve_in_place(rhs.as_mut(), &mut scratch);
            solve = solve.min(t.elapsed().as_secs_f64());
        }
        let (nnz, numeric) = (chol.nnz_l() as f64, chol.numeric_seconds);
        let exact = chol.exact_nnz_l(k).map_or(f64::NAN, |e| e as f64 / 1e6);
        let ratio = base.map(|(n, s)| format!(" ({:.2}x AMD's entries, {:.2}x AMD's solve)", nnz / n, solve / s)).unwrap_or_default();
        figures.push(OrderingFigures {
            ordering: format!("{ordering:?}"),
            nnz_l_millions: nnz / 1e6,
            exact_nnz_l_millions: exact,
            solve_over_amd: base.map(|(_, s)| solve / s),
        });
        base.get_or_insert((nnz, solve));
        println!(
            "ordering {ordering:?}: nnz(L) {:.2} M stored ({exact:.2} M counted exactly), analysis {:.2} s, numeric {:.2} s, 96-column solve {:.1} ms, factor total {total:.2} s{ratio}",
            nnz / 1e6,
            chol.symbolic_seconds,
            numeric,
            solve * 1e3
        );
    }
    figures
}

/// The floor of one exact frame over `nodes` whose last `fresh` are new this
/// frame, measured in the same run as the frames (so the two meet the same
/// machine load), ms, each the best
/// of 5: reading the new entries of W (the compliance's 3x3 block of each new
/// node against every node: what a solver that keeps W must read), reading all
/// of W (for scale), and one dense Cholesky of W: f64 on one thread (what the
/// solver runs), f64 on every core (and whether it is bitwise the one-thread
/// factor), f32 on every core (usually the cheapest dense factor). `None`
/// when a node has no column.
struct Floor {
    read_new: f64,
    read_all: f64,
    f64_seq: f64,
    f64_par: f64,
    par_bitwise: bool,
    f32_par: f64,
}

fn floor_ms(compliance: &Compliance, nodes: &[u32], fresh: usize) -> Option<Floor> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt::factor::{LltRegularization, cholesky_in_place, cholesky_in_place_scratch};
    use faer::{MatMut, Par, Spec};
    let rows: Vec<usize> = nodes.iter().map(|&n| compliance.row_of(n)).collect::<Option<_>>()?;
    let cols: Vec<usize> = nodes.iter().map(|&n| compliance.col_of(n)).collect::<Option<_>>()?;
    let n = 3 * nodes.len();
    let mut w = vec![0.0f64; n * n];
    let best = |f: &mut dyn FnMut()| {
        (0..5)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    let read = |w: &mut [f64], from: usize| {
        for (j, &c) in cols.iter().enumerate().skip(from) {
            for (i, &r) in rows.iter().enumerate() {
                let b = compliance.block(r, c);
                for q in 0..3 {
                    for p in 0..3 {
                        w[(3 * j + q) * n + 3 * i + p] = b[(p, q)];
                    }
                }
            }
        }
    };
    let read_new = best(&mut || read(&mut w, nodes.len().saturating_sub(fresh)));
    let read_all = best(&mut || read(&mut w, 0));
    let factor = |w: &[f64], l: &mut [f64], par: Par, buf: &mut MemBuffer| {
        l.copy_from_slice(w);
        let mat = MatMut::from_column_major_slice_mut(l, n, n);
        let _ = cholesky_in_place(mat, LltRegularization::default(), par, MemStack::new(buf), Spec::default());
    };
    let (seq, par) = (Par::Seq, Par::rayon(0));
    let mut buf = MemBuffer::new(cholesky_in_place_scratch::<f64>(n, par, Spec::default()));
    let (mut l_seq, mut l_par) = (vec![0.0; n * n], vec![0.0; n * n]);
    let f64_seq = best(&mut || factor(&w, &mut l_seq, seq, &mut buf));
    let f64_par = best(&mut || factor(&w, &mut l_par, par, &mut buf));
    let par_bitwise = (0..n).all(|j| (j..n).all(|i| l_seq[j * n + i].to_bits() == l_par[j * n + i].to_bits()));
    let w32: Vec<f32> = w.iter().map(|&x| x as f32).collect();
    let mut l32 = w32.clone();
    let mut buf32 = MemBuffer::new(cholesky_in_place_scratch::<f32>(n, par, Spec::default()));
    let f32_par = best(&mut || {
        l32.copy_from_slice(&w32);
        let mat = MatMut::from_column_major_slice_mut(&mut l32, n, n);
        let _ = cholesky_in_place(mat, LltRegularization::default(), par, MemStack::new(&mut buf32), Spec::default());
    });
    Some(Floor { read_new, read_all, f64_seq, f64_par, par_bitwise, f32_par })
}

/// [`stream_bytes_per_s`], measured once at the start (its 256 MB buffer
/// would otherwise raise the peak memory the bench reports).
static STREAM_RATE: std::sync::OnceLock<f64> = std::sync::OnceLock::new();

/// Bytes a second this machine reads a 256 MB buffer (summed with 8
/// independent accumulators so the adds keep up), best of 3.
fn stream_bytes_per_s() -> f64 {
    let buffer = vec![1.0f32; 64 << 20];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        let mut acc = [0.0f32; 8];
        for chunk in buffer.chunks_exact(8) {
            for (a, x) in acc.iter_mut().zip(chunk) {
                *a += x;
            }
        }
        std::hint::black_box(acc);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (buffer.len() * 4) as f64 / best
}

/// Frame times of a window of `count` constrained vertices sliding over `near`
/// by `fresh` a frame (the oldest leave): percentiles over frames 1.., mean
/// phase times (ms: gather, W, candidates, product, new-row gather, lazy), the
/// last frame's constraints and solution. `None` when `near` is too short.
struct Measure {
    frames: usize,
    p50: f64,
    p95: f64,
    max: f64,
    phases: [f64; 6],
    cons: Vec<Constraint>,
    out: FrameSolution,
}

fn measure(solver: &mut ConstrainedSolver, near: &[u32], count: usize, fresh: usize, max_frames: usize) -> Option<Measure> {
    if near.len() < count + fresh || fresh == 0 {
        return None;
    }
    let frames = ((near.len() - count) / fresh).min(max_frames);
    let sets: Vec<&[u32]> = (0..frames).map(|k| &near[k * fresh..k * fresh + count]).collect();
    measure_sets(solver, &sets)
}

/// Frame times over the held sets `sets` (one a frame, each node pushed
/// 2 mm down); the first frame is left out of the statistics.
fn measure_sets(solver: &mut ConstrainedSolver, sets: &[&[u32]]) -> Option<Measure> {
    let frames = sets.len();
    if frames < 2 {
        return None;
    }
    let mut times = Vec::new();
    let mut phases = [0.0f64; 6];
    let mut out = FrameSolution::default();
    let mut cons: Vec<Constraint> = Vec::new();
    for k in 0..frames {
        cons.clear();
        cons.extend(sets[k].iter().map(|&n| Constraint {
            node: n,
            owner: 0,
            kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.002) },
        }));
        let t = Instant::now();
        solver.step(&cons, &mut out).expect("step");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if k > 0 {
            let p = solver.timings();
            for (acc, x) in phases.iter_mut().zip([p.gather, p.factor, p.candidates, p.surface, p.surface_gather, p.lazy]) {
                *acc += x * 1e3 / (frames - 1) as f64;
            }
        }
    }
    let mut sorted = times[1..].to_vec();
    sorted.sort_by(|a, b| a.total_cmp(b));
    Some(Measure {
        frames: sorted.len(),
        p50: percentile(&sorted, 0.5),
        p95: percentile(&sorted, 0.95),
        max: *sorted.last()?,
        phases,
        cons,
        out,
    })
}

/// Writes `DIR/NAME_constrained_sweep.csv` and `.png`: frame p50 and p95, mean W and
/// mean product time against the constrained vertices, with the bar (frame p95
/// 3 ms at 300 constrained vertices). Returns the PNG's path.
fn write_sweep(name: &str, sweep: &[(usize, Measure)], dir: &Path) -> Result<PathBuf, String> {
    use plotters::prelude::*;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut csv = String::from("constrained,new_per_frame,p50_ms,p95_ms,max_ms,w_ms,product_ms,new_row_gather_ms\n");
    for (count, m) in sweep {
        csv += &format!("{count},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n", count / 10, m.p50, m.p95, m.max, m.phases[1], m.phases[3], m.phases[4]);
    }
    let csv_path = dir.join(format!("{name}_constrained_sweep.csv"));
    std::fs::write(&csv_path, csv).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    let png = dir.join(format!("{name}_constrained_sweep.png"));
    let bytes = fissure::study::plot::png_bytes((1000, 640), |root| {
        let err = |e: &dyn std::fmt::Display| e.to_string();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let x_max = sweep.iter().map(|s| s.0).max().unwrap_or(300) as f64 * 1.05;
        let y_max = sweep.iter().map(|s| s.1.p95).fold(3.5_f64, f64::max) * 1.1;
        let mut chart = ChartBuilder::on(root)
            .caption(format!("{name}: exact frame solve + surface update (a tenth of the vertices new each frame)"), ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(64)
            .build_cartesian_2d(0.0..x_max, 0.0..y_max)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("constrained vertices (3 rows each)")
            .y_desc("time per frame, ms")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.0}"))
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| err(&e))?;
        type Series = (&'static str, RGBColor, fn(&Measure) -> f64);
        let series: [Series; 4] = [
            ("frame p95", RGBColor(23, 190, 207), |m| m.p95),
            ("frame p50", RGBColor(31, 119, 180), |m| m.p50),
            ("W gather + factor + solve (mean)", RGBColor(214, 39, 40), |m| m.phases[1]),
            ("surface product (mean)", RGBColor(44, 160, 44), |m| m.phases[3]),
        ];
        for (label, color, f) in series {
            let pts: Vec<(f64, f64)> = sweep.iter().map(|(c, m)| (*c as f64, f(m))).collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(3)))
                .map_err(|e| err(&e))?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, color.filled()))).map_err(|e| err(&e))?;
        }
        let bar = RGBColor(90, 90, 90);
        chart
            .draw_series(LineSeries::new(vec![(0.0, 3.0), (x_max, 3.0)], bar.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label("bar: p95 3 ms at 300 vertices")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], bar.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|e| err(&e))?;
        Ok(())
    })?;
    std::fs::write(&png, bytes).map_err(|e| format!("{}: {e}", png.display()))?;
    Ok(png)
}

/// Median of three or more values.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// `-- audit`: each per-frame optimisation that `fem::tuning` switches, on
/// and off in this run (alternating which goes first, three rounds), on
/// three sequences of 300 constrained vertices; the medians.
fn frame_audit(name: &str, solver: &mut ConstrainedSolver, near: &[u32], dir: &Path) -> Vec<AuditBar> {
    use fissure::fem::tuning::{Optimisation, Tuning};
    let count = 300.min(near.len() / 2);
    let step = count / 10;
    let held: Vec<&[u32]> = (0..30).map(|_| &near[..count]).collect();
    let growing: Vec<&[u32]> = (0..30).map(|k| &near[..(step * (k + 1)).min(count)]).collect();
    let sliding: Vec<&[u32]> = (0..((near.len() - count) / step).min(30)).map(|k| &near[k * step..k * step + count]).collect();
    let sequences: [(&'static str, Vec<&[u32]>); 3] = [("held", held), ("growing", growing), ("sliding", sliding)];
    println!("audit: {count} constrained vertices; frame p50 / p95 and the phase the switch touches, ms, median of three rounds, on -> off");
    let mut bars: Vec<AuditBar> = Vec::new();
    for (o, phase) in [
        (Optimisation::WFactorReuse, 1usize),
        (Optimisation::KeptProductRows, 3),
        (Optimisation::FusedColumns, 3),
        (Optimisation::RowChunks, 3),
        (Optimisation::Avx2Product, 3),
        (Optimisation::ParallelProduct, 3),
    ] {
        for (seq_name, sets) in &sequences {
            let mut on = (Vec::new(), Vec::new(), Vec::new());
            let mut off = (Vec::new(), Vec::new(), Vec::new());
            for round in 0..3 {
                for first_on in [round % 2 == 0, round % 2 != 0] {
                    solver.set_tuning(Tuning::ALL_ON.with(o, first_on));
                    let Some(m) = measure_sets(solver, sets) else { continue };
                    let to = if first_on { &mut on } else { &mut off };
                    to.0.push(m.p50);
                    to.1.push(m.p95);
                    to.2.push(m.phases[phase]);
                }
            }
            solver.set_tuning(Tuning::ALL_ON);
            if on.0.len() < 3 || off.0.len() < 3 {
                continue;
            }
            let phase_name = ["gather", "factor+solve W", "candidates", "surface product", "product gather", "lazy"][phase];
            let (p50, p95, ph) = (median(on.0), median(on.1), median(on.2));
            let (q50, q95, qh) = (median(off.0), median(off.1), median(off.2));
            println!(
                "audit {:<18} {seq_name:<8}: frame p50 {p50:.2} -> {q50:.2}, p95 {p95:.2} -> {q95:.2}; {phase_name} {ph:.2} -> {qh:.2} ({:.2}x faster with it)",
                o.name(),
                qh / ph
            );
            bars.push(AuditBar { switch: o.name().into(), sequence: seq_name.to_string(), phase: phase_name.to_string(), on: ph, off: qh, p95_on: Some(p95), p95_off: Some(q95) });
        }
    }
    match write_audit(name, count, &bars, dir) {
        Ok(png) => println!("audit plot: {}", png.display()),
        Err(e) => println!("audit plot not written: {e}"),
    }
    bars
}

/// Writes `DIR/NAME_audit.csv` and `.png`: for each switch and frame
/// sequence, how many times faster the phase it touches runs with it (log
/// scale). Returns the PNG's path.
fn write_audit(name: &str, count: usize, bars: &[AuditBar], dir: &Path) -> Result<PathBuf, String> {
    use plotters::prelude::*;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut csv = String::from("optimisation,sequence,phase,phase_on_ms,phase_off_ms,speedup,frame_p95_on_ms,frame_p95_off_ms\n");
    for b in bars {
        csv += &format!("{},{},{},{:.4},{:.4},{:.4},{:.4},{:.4}\n", b.switch, b.sequence, b.phase, b.on, b.off, b.off / b.on, b.p95_on.unwrap_or(f64::NAN), b.p95_off.unwrap_or(f64::NAN));
    }
    let csv_path = dir.join(format!("{name}_audit.csv"));
    std::fs::write(&csv_path, csv).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    let png = dir.join(format!("{name}_audit.png"));
    let bytes = fissure::study::plot::png_bytes((1000, 600), |root| {
        let err = |e: &dyn std::fmt::Display| e.to_string();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let mut switches: Vec<&str> = Vec::new();
        for b in bars {
            if !switches.contains(&b.switch.as_str()) {
                switches.push(&b.switch);
            }
        }
        let sequences = ["held", "growing", "sliding"];
        let colors = [RGBColor(31, 119, 180), RGBColor(44, 160, 44), RGBColor(214, 39, 40)];
        let y_max = bars.iter().map(|b| b.off / b.on).fold(2.0_f64, f64::max) * 1.5;
        let y_min = bars.iter().map(|b| b.off / b.on).fold(0.7_f64, f64::min) * 0.9;
        let mut chart = ChartBuilder::on(root)
            .caption(format!("{name}: what each per-frame optimisation buys ({count} constrained vertices)"), ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(0.0..switches.len() as f64, (y_min..y_max).log_scale())
            .map_err(|e| err(&e))?;
        let labels = switches.clone();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(switches.len() * 2 + 1)
            .x_label_formatter(&|x| {
                let i = x.floor() as usize;
                if (x - i as f64 - 0.5).abs() < 0.26 { labels.get(i).map(|s| s.to_string()).unwrap_or_default() } else { String::new() }
            })
            .y_desc("the phase it touches: time off / time on (x faster with it)")
            .y_label_formatter(&|y| format!("{y:.1}x"))
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(|e| err(&e))?;
        for (k, (seq, color)) in sequences.iter().zip(colors).enumerate() {
            let rects: Vec<_> = bars
                .iter()
                .filter(|b| b.sequence == *seq)
                .filter_map(|b| {
                    let i = switches.iter().position(|s| *s == b.switch)? as f64;
                    let x0 = i + 0.15 + 0.23 * k as f64;
                    Some(Rectangle::new([(x0, y_min), (x0 + 0.21, b.off / b.on)], color.filled()))
                })
                .collect();
            chart
                .draw_series(rects)
                .map_err(|e| err(&e))?
                .label(format!("300 constrained vertices {seq}"))
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 18, y + 6)], color.filled()));
        }
        let one = RGBColor(90, 90, 90);
        chart
            .draw_series(LineSeries::new(vec![(0.0, 1.0), (switches.len() as f64, 1.0)], one.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label("1x: no gain (below: slower with it)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], one.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|e| err(&e))?;
        Ok(())
    })?;
    std::fs::write(&png, bytes).map_err(|e| format!("{}: {e}", png.display()))?;
    Ok(png)
}

/// `-- audit`: one 96-column solve of the model's factor with the row-major
/// solve and with faer's, alternating, best of three each.
fn row_major_audit(model: &FemModel) -> Vec<AuditBar> {
    let k = model.stiffness();
    let mut chol = match SparseCholesky::new(k, FillOrdering::Best, &|d| model.dofs().name(d)) {
        Ok(c) => c,
        Err(e) => {
            println!("audit row-major-solve: factor failed: {e}");
            return Vec::new();
        }
    };
    let mut rhs = faer::Mat::<f64>::zeros(k.dim, 96);
    let mut scratch = chol.scratch(96).expect("scratch");
    let mut best = [f64::INFINITY; 2];
    for rep in 0..6 {
        let on = rep % 2 == (rep / 2) % 2;
        chol.set_row_major(on);
        rhs.fill(0.0);
        for c in 0..96 {
            rhs[((c * 7919 + rep) % k.dim, c)] = 1.0;
        }
        let t = Instant::now();
        chol.solve_in_place(rhs.as_mut(), &mut scratch);
        let s = t.elapsed().as_secs_f64() * 1e3;
        best[usize::from(!on)] = best[usize::from(!on)].min(s);
    }
    chol.set_row_major(true);
    println!(
        "audit row-major-solve      one 96-column solve: {:.1} -> {:.1} ms ({:.2}x faster with it; best of three each)",
        best[0],
        best[1],
        best[1] / best[0]
    );
    let solve = AuditBar { switch: "row-major-solve".into(), sequence: "one 96-column solve".into(), phase: "solve".into(), on: best[0], off: best[1], p95_on: None, p95_off: None };
    std::iter::once(solve).chain(pruned_solve_audit(model, &chol)).collect()
}

/// `-- audit`: one batch of the compliance's precompute (the unit columns of
/// the 32 free surface nodes nearest the highest one, 96 right-hand sides)
/// solved pruned along the elimination tree and in full, alternating, best
/// of three each; the answers are compared bit for bit.
fn pruned_solve_audit(model: &FemModel, chol: &SparseCholesky) -> Option<AuditBar> {
    let positions = &model.mesh().positions;
    let free: Vec<u32> = model.surface().vertices.iter().copied().filter(|&n| !model.is_fixed(n)).collect();
    let &top = free.iter().max_by(|a, b| positions[**a as usize].z.total_cmp(&positions[**b as usize].z))?;
    let mut near = free.clone();
    near.sort_by(|a, b| (positions[*a as usize] - positions[top as usize]).norm().total_cmp(&(positions[*b as usize] - positions[top as usize]).norm()));
    let first: Vec<usize> = near.iter().take(32).filter_map(|&n| model.dofs().dof(n)).collect();
    let (dim, m) = (chol.dim(), 3 * first.len());
    let mut scratch = chol.scratch(m).expect("scratch");
    let mut pruned = faer::Mat::<f64>::zeros(dim, m);
    let mut full = faer::Mat::<f64>::zeros(dim, m);
    let mut best = [f64::INFINITY; 2];
    for rep in 0..6 {
        let on = rep % 2 == (rep / 2) % 2;
        let t = Instant::now();
        if on {
            chol.solve_unit_columns(&first, pruned.as_mut(), None, &mut scratch);
        } else {
            full.fill(0.0);
            for (b, &d) in first.iter().enumerate() {
                for c in 0..3 {
                    full[(d + c, 3 * b + c)] = 1.0;
                }
            }
            chol.solve_in_place(full.as_mut(), &mut scratch);
        }
        best[usize::from(!on)] = best[usize::from(!on)].min(t.elapsed().as_secs_f64() * 1e3);
    }
    let same = (0..m).all(|j| (0..dim).all(|i| pruned[(i, j)].to_bits() == full[(i, j)].to_bits()));
    println!(
        "audit pruned-unit-columns  one batch of 32 nodes' unit columns: {:.1} -> {:.1} ms ({:.2}x faster pruned; best of three each; answers {})",
        best[0],
        best[1],
        best[1] / best[0],
        if same { "the same bits" } else { "DIFFER" }
    );
    let phase = if same { "unit columns (the same bits)" } else { "unit columns (answers DIFFER)" };
    Some(AuditBar { switch: "pruned-unit-columns".into(), sequence: "one batch of 32 nodes' unit columns".into(), phase: phase.into(), on: best[0], off: best[1], p95_on: None, p95_off: None })
}

fn main() {
    STREAM_RATE.get_or_init(stream_bytes_per_s);
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let audit_only = args.iter().any(|a| a == "audit");
    let filter: Vec<String> = args.into_iter().filter(|a| a != "audit").collect();
    let want = |n: &str| filter.is_empty() || filter.iter().any(|f| n.contains(f.as_str()));
    let cache: PathBuf = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/target/fem-bench-cache"));
    if want("paper-12k") {
        let t = Instant::now();
        match fissure::mesh::phantom::generate(fissure::mesh::phantom::Preset::Paper12k) {
            Ok(p) => {
                println!("phantom generated in {:.1} s", t.elapsed().as_secs_f64());
                let (lo, hi) = p.mesh.bounding_box();
                let zmid = 0.5 * (lo.z + hi.z);
                run("paper-12k", &p.mesh, &move |x: &Vec3| x.z > zmid, &cache.join("paper"), audit_only);
            }
            Err(e) => println!("paper-12k phantom unavailable: {e}"),
        }
    }
    for name in ["brain_pial_coarse", "brain_pial_q15"] {
        if !want(name) {
            continue;
        }
        let path = fissure::mesh::brain::shipped(name);
        match fissure::mesh::io::load_tet_mesh(&path) {
            Ok(mut mesh) => {
                mesh.scale(1e-3); // the file is in mm
                let (_, hi) = mesh.bounding_box();
                // ROI: the upper medial region around the inter-hemispheric fissure (|x| < 20 mm, top 40 mm)
                let roi = move |x: &Vec3| x.x.abs() < 0.020 && x.z > hi.z - 0.040;
                run(name, &mesh, &roi, &cache.join(name), audit_only);
            }
            Err(e) => println!("brain mesh {} failed to load: {e}", path.display()),
        }
    }
}
