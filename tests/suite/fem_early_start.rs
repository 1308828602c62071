//! `solver.early_start`: the compliance's columns ordered by the blades' reach
//! and computed in the background. A compliance read while it fills, and a
//! solver that runs its frames meanwhile, give what a build that waits gives,
//! bit for bit; the cache the background writes is the one the next start reads.

use crate::fem_common as common;

use common::*;
use fissure::fem::{Compliance, ComplianceStorage, ComputeOptions, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

/// Two disjoint blocks side by side (two free components, as the real
/// brain's hemispheres), each fixed at the bottom.
fn two_blocks() -> TetMesh {
    let a = block(6, 4, 4);
    let offset = a.positions.len() as u32;
    let mut positions = a.positions.clone();
    positions.extend(a.positions.iter().map(|p| p + Vec3::new(0.1, 0.0, 0.0)));
    let mut tets = a.tets.clone();
    tets.extend(a.tets.iter().map(|t| t.map(|n| n + offset)));
    TetMesh::new(positions, tets, vec![]).unwrap()
}

fn model() -> FemModel {
    let mesh = two_blocks();
    let fixed = bottom_fixed(&mesh);
    FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).unwrap()
}

/// A reach that is not the Morton order: distance (mm) from a point between the blocks.
fn reach(model: &FemModel) -> Vec<u32> {
    model.mesh().positions.iter().map(|p| ((p - Vec3::new(0.08, 0.02, 0.03)).norm() * 1e3) as u32).collect()
}

fn options<'a>(storage: ComplianceStorage, reach: &'a [u32], background: bool) -> ComputeOptions<'a> {
    ComputeOptions { reach: Some(reach), background, ..ComputeOptions::new(storage) }
}

#[test]
fn a_compliance_read_while_it_fills_equals_one_built_first() {
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    for storage in [ComplianceStorage::F64, ComplianceStorage::F32] {
        let waited = Compliance::compute_with(&m, &roi, options(storage, &reach, false), &mut |_, _| {}).unwrap();
        assert_eq!(waited.fill_progress(), None);
        let mut calls = Vec::new();
        let filling = Compliance::compute_with(&m, &roi, options(storage, &reach, true), &mut |d, t| calls.push((d, t))).unwrap();
        assert_eq!(calls, vec![(0, waited.column_count())], "{storage:?}: the build reports no columns and returns");
        // Read at once: each read waits for the columns it needs.
        assert_eq!(all_block_bits(&filling), all_block_bits(&waited), "{storage:?}: entries read while filling");
        filling.wait_complete().unwrap();
        assert_eq!(filling.fill_progress(), None);
        assert!(filling.stats().compute_seconds > 0.0, "the filling's time is kept");
        assert_eq!(filling.key(), waited.key());
    }
}

#[test]
fn columns_follow_the_reach_within_each_component() {
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    let c = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F64, &reach, false), &mut |_, _| {}).unwrap();
    let half = m.mesh().node_count() as u32 / 2;
    let cols = &c.row_nodes()[..c.column_count()];
    let split = cols.iter().position(|&n| n >= half).expect("both blocks in the ROI");
    for part in [&cols[..split], &cols[split..]] {
        assert!(part.windows(2).all(|w| reach[w[0] as usize] <= reach[w[1] as usize]), "a component's columns in reach order");
    }
    assert!(cols[split..].iter().all(|&n| n >= half), "components are not interleaved");
    let morton = Compliance::compute(&m, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    assert_ne!(morton.key(), c.key(), "the order is part of the cache key");
}

/// Pushes on the top of both blocks, more each frame.
fn frame_constraints(m: &FemModel, frame: usize) -> Vec<Constraint> {
    let d = 0.001 * (frame + 1) as f64;
    m.mesh()
        .positions
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.z - 0.03).abs() < 1e-12 && (p.y - 0.02).abs() < 0.011 && ((p.x - 0.03).abs() < 0.011 || (p.x - 0.13).abs() < 0.011))
        .map(|(n, p)| Constraint {
            node: n as u32,
            owner: u16::from(p.x > 0.08),
            kind: ConstraintKind::Enforced { displacement: Vec3::new(0.2 * d, 0.0, -d) },
        })
        .collect()
}

#[test]
fn frames_on_a_filling_compliance_equal_frames_on_a_finished_one() {
    let mut results: Vec<Vec<FrameSolution>> = Vec::new();
    for background in [false, true] {
        let m = model();
        let reach = reach(&m);
        let roi = m.surface().vertices.clone();
        let c = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F32, &reach, background), &mut |_, _| {}).unwrap();
        let mut solver = ConstrainedSolver::new(m, c).unwrap();
        let mut frames = Vec::new();
        for f in 0..4 {
            let constraints = frame_constraints(solver.model(), f);
            assert!(constraints.len() > 4, "the push holds several nodes");
            let mut out = FrameSolution::default();
            solver.step(&constraints, &mut out).unwrap();
            frames.push(out);
        }
        results.push(frames);
    }
    for (a, b) in results[0].iter().zip(&results[1]) {
        let bits = |s: &FrameSolution| -> Vec<u64> {
            s.displacement_surface.iter().chain(&s.reactions).flat_map(|v| v.iter().map(|x| x.to_bits())).collect()
        };
        assert_eq!(bits(a), bits(b), "a frame's answers do not depend on when its columns became final");
    }
    assert!(results[0][3].max_displacement > 0.003);
}

#[test]
fn the_cache_the_background_writes_is_read_at_the_next_start() {
    let dir = tempfile::tempdir().unwrap();
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    let opts = |background| ComputeOptions { cache_dir: Some(dir.path()), ..options(ComplianceStorage::F64, &reach, background) };
    let first = Compliance::compute_with(&m, &roi, opts(true), &mut |_, _| {}).unwrap();
    first.wait_complete().unwrap();
    // The file is written after the last column, by the background thread.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let written = loop {
        let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "bin")).collect();
        if !files.is_empty() || std::time::Instant::now() > deadline {
            break files;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    assert_eq!(written.len(), 1, "one cache file, renamed into place when complete");
    let written_at = std::fs::metadata(&written[0]).unwrap().len();
    // The next start reads it in the background, batch by batch.
    let second = Compliance::compute_with(&m, &roi, opts(true), &mut |_, _| {}).unwrap();
    assert_eq!(all_block_bits(&second), all_block_bits(&first), "read while it loads, equal bit for bit");
    second.wait_complete().unwrap();
    assert!(second.stats().from_cache, "the next start reads it");
    assert_eq!(second.fill_progress(), None, "nothing left to fill");
    assert_eq!(all_block_bits(&second), all_block_bits(&first));
    assert_eq!(std::fs::metadata(&written[0]).unwrap().len(), written_at);
}

/// Four constrained frames, then every node's displacement (a solve with the factor).
fn run_frames(m: FemModel, c: Compliance) -> (Vec<FrameSolution>, Vec<Vec3>) {
    let mut solver = ConstrainedSolver::new(m, c).unwrap();
    let mut frames = Vec::new();
    for f in 0..4 {
        let constraints = frame_constraints(solver.model(), f);
        let mut out = FrameSolution::default();
        solver.step(&constraints, &mut out).unwrap();
        frames.push(out);
    }
    let mut interior = Vec::new();
    solver.interior_displacements(&mut interior).unwrap();
    solver.compliance().wait_complete().unwrap();
    (frames, interior)
}

fn solution_bits(frames: &[FrameSolution], interior: &[Vec3]) -> Vec<u64> {
    frames
        .iter()
        .flat_map(|s| s.displacement_surface.iter().chain(&s.reactions))
        .chain(interior)
        .flat_map(|v| v.iter().map(|x| x.to_bits()))
        .collect()
}

/// A start from the cache: the model's factor is not made before the first
/// frame (`FemModel::new_deferred`) and the columns are read in the
/// background; the frames and a solve with the factor equal those of a
/// model factored first and a compliance computed first, bit for bit.
#[test]
fn a_start_from_the_cache_without_the_factor_first_gives_the_same_frames() {
    let dir = tempfile::tempdir().unwrap();
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    let opts = |background| ComputeOptions { cache_dir: Some(dir.path()), ..options(ComplianceStorage::F32, &reach, background) };
    let computed = Compliance::compute_with(&m, &roi, opts(false), &mut |_, _| {}).unwrap();
    assert!(!computed.stats().from_cache);
    let (frames, interior) = run_frames(m, computed);
    assert!(frames[3].max_displacement > 0.003);

    let mesh = two_blocks();
    let deferred = FemModel::new_deferred(&mesh, &uniform(BRAIN), &bottom_fixed(&mesh), &FemOptions::default()).unwrap();
    let loaded = Compliance::compute_with(&deferred, &roi, opts(true), &mut |_, _| {}).unwrap();
    let (frames2, interior2) = run_frames(deferred, loaded);
    assert_eq!(solution_bits(&frames, &interior), solution_bits(&frames2, &interior2));
}

/// One corrupt byte costs one batch: it is computed again (the others are
/// read), the answers are those of the file before, and the file is rewritten.
#[test]
fn a_corrupt_batch_is_computed_again_and_the_file_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    for storage in [ComplianceStorage::F64, ComplianceStorage::F32] {
        for background in [false, true] {
            let opts = ComputeOptions { cache_dir: Some(dir.path()), ..options(storage, &reach, background) };
            let first = Compliance::compute_with(&m, &roi, ComputeOptions { background: false, ..opts }, &mut |_, _| {}).unwrap();
            let file = std::fs::read_dir(dir.path())
                .unwrap()
                .flatten()
                .map(|e| e.path())
                .find(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(&format!("compliance-{}", hex16(&first.key())))))
                .expect("the cache file");
            let mut bytes = std::fs::read(&file).unwrap();
            let at = bytes.len() * 3 / 4;
            bytes[at] ^= 0x10;
            std::fs::write(&file, &bytes).unwrap();
            let again = Compliance::compute_with(&m, &roi, opts, &mut |_, _| {}).unwrap();
            again.wait_complete().unwrap();
            assert!(!again.stats().from_cache, "{storage:?}: a corrupt batch is not read");
            assert_eq!(all_block_bits(&again), all_block_bits(&first), "{storage:?}: the batch computed again equals the one written");
            // The rewrite (by the filling thread, in the background) puts the byte back.
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
            while std::fs::read(&file).map(|b| b[at] == bytes[at]).unwrap_or(true) && std::time::Instant::now() < deadline {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            let third = Compliance::compute_with(&m, &roi, ComputeOptions { background: false, ..opts }, &mut |_, _| {}).unwrap();
            assert!(third.stats().from_cache, "{storage:?}: the rewritten file is read");
            assert_eq!(all_block_bits(&third), all_block_bits(&first));
        }
    }
}

fn hex16(key: &[u8; 32]) -> String {
    key[..16].iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn a_compliance_dropped_while_it_fills_lets_go() {
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    for _ in 0..3 {
        let c = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F64, &reach, true), &mut |_, _| {}).unwrap();
        drop(c);
    }
    // The filling threads stop after their batch; a new one still fills.
    let c = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F64, &reach, true), &mut |_, _| {}).unwrap();
    c.wait_complete().unwrap();
}

#[test]
fn a_start_that_waits_until_ahead_returns_once_the_rest_keeps_ahead_of_the_blades() {
    let m = model();
    let reach = reach(&m);
    let roi = m.surface().vertices.clone();
    let waited = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F64, &reach, false), &mut |_, _| {}).unwrap();
    // Every column due at once: the wait lasts until the last one is final,
    // reporting the columns as they come.
    let filling = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F64, &reach, true), &mut |_, _| {}).unwrap();
    let mut seen = Vec::new();
    filling.wait_until_ahead(&|_| 0.0, &mut |d, t| seen.push((d, t))).unwrap();
    assert_eq!(filling.fill_progress(), None, "nothing left to fill when every column is due now");
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "progress only grows: {seen:?}");
    assert_eq!(all_block_bits(&filling), all_block_bits(&waited));
    // No column ever due: back once the rate is measured (or all is done),
    // and the entries read afterwards are those of the build that waited.
    let filling = Compliance::compute_with(&m, &roi, options(ComplianceStorage::F64, &reach, true), &mut |_, _| {}).unwrap();
    filling.wait_until_ahead(&|_| f64::INFINITY, &mut |_, _| {}).unwrap();
    if let Some((done, total)) = filling.fill_progress() {
        assert!(done > 0 && done < total, "{done} / {total}");
    }
    assert_eq!(all_block_bits(&filling), all_block_bits(&waited));
    // A compliance built first: at once.
    waited.wait_until_ahead(&|_| 0.0, &mut |_, _| panic!("nothing is filling")).unwrap();
}

/// A scene opened as the window opens one driven by hand (no expected poses,
/// the columns in the background): when the build returns, the column of every
/// vertex the skull stage gives a candidate row at rest is readable, so the
/// first frame reads it without waiting. Dated by the blades alone, the default
/// scene's skull-base vertices (0.12 mm from their sphere at rest) left the
/// window's first frame waiting 0.5-0.9 s for the background fill.
#[test]
fn the_rows_of_the_first_frame_are_readable_when_a_hand_driven_scene_opens() {
    use fissure::scenario::Scenario;
    use fissure::sim::pipeline::{SKULL_CANDIDATE_BAND_M, skull_gap};
    use fissure::sim::{BuildOptions, Pipeline};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sylvian.ron");
    let hand = ["trajectory=None", "spatulas[0].input=Keyboard", "spatulas[1].input=Keyboard", "solver.cache_dir=None", "solver.early_start=true"];
    let scenario = Scenario::load(&path, &hand.map(String::from)).expect("the default scene, driven by hand");
    let options = BuildOptions { expected_poses: Vec::new(), expected_step_s: scenario.duration / 200.0, progress: None, background_columns: true };
    let (pipeline, _state) = Pipeline::build(&scenario, options).expect("build");
    let skull = pipeline.skull().expect("the default scene has skull spheres").skull();
    let compliance = pipeline.solver().compliance();
    let mut candidates = 0;
    for (&node, rest) in pipeline.surface().vertices.iter().zip(pipeline.rest_positions()) {
        if skull_gap(skull, rest) < SKULL_CANDIDATE_BAND_M {
            if let Some(col) = compliance.col_of(node) {
                candidates += 1;
                assert!(compliance.column_ready(col), "node {node}'s column (a skull candidate at rest) is still filling");
            }
        }
    }
    assert!(candidates > 10, "the default scene's skull-base vertices have columns: {candidates}");
}
