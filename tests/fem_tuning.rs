//! The audit's switches (`fem::tuning`): every optimisation whose doc says
//! "the same answers" gives the same bits switched off, on a compliance
//! precompute and on frames whose held set is kept, grows and slides. Both
//! ways run here: the product's kept rows, its fused columns, its row chunks
//! (608 surface rows, more than a chunk), both builds of its kernel, the
//! row-major precompute solve, the huge-page advice and the active-set
//! loop's screening of candidates, within a frame and across frames (frames
//! with barrier rows on the whole top face, some of which engage over several
//! iterations, the last holding the press under a moved barrier). The candidates' kept
//! blocks need a compliance over 64 MB and candidates: the shipped scenes'
//! final states check them (`scripts/fem_audit.sh`).
//! Its own test binary: the switches are process-wide.

#[path = "fem_common/mod.rs"]
mod common;

use common::*;
use fissure::fem::tuning::{Optimisation, set_enabled};
use fissure::fem::{Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution};
use fissure::math::Vec3;

/// The switches documented as leaving every bit unchanged.
const BITWISE: [Optimisation; 14] = [
    Optimisation::Avx2Product,
    Optimisation::FusedColumns,
    Optimisation::RowChunks,
    Optimisation::KeptProductRows,
    Optimisation::CandidateBlocks,
    Optimisation::RowMajorSolve,
    Optimisation::HugePages,
    Optimisation::CandidateScreen,
    Optimisation::KeptRowPairs,
    Optimisation::ParallelProduct,
    Optimisation::ScreenAcrossFrames,
    Optimisation::PrefetchBlocks,
    Optimisation::ParallelCandidates,
    Optimisation::ParallelGather,
];

/// The compliance's ROI x ROI entries and the surface displacements of a
/// sequence of frames, as bits; and the candidate evaluations screened out.
fn run() -> ((Vec<u64>, Vec<u64>), usize) {
    let mesh = block(20, 16, 5);
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
    let roi: Vec<u32> = model.surface().vertices.iter().copied().filter(|&n| !model.is_fixed(n)).collect();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F32, None, &mut |_, _| {}).expect("compliance");
    let mut entries = Vec::new();
    for i in 0..c.stats().cols {
        for j in 0..=i {
            entries.extend(c.block(i, j).iter().map(|x| x.to_bits()));
        }
    }
    let mut top: Vec<u32> = roi.iter().copied().filter(|&n| (mesh.positions[n as usize].z - 0.03).abs() < 1e-12).collect();
    top.sort_by(|a, b| mesh.positions[*a as usize].x.total_cmp(&mesh.positions[*b as usize].x).then(a.cmp(b)));
    assert!(top.len() >= 24, "the block's top face has {} free nodes", top.len());
    let mut solver = ConstrainedSolver::new(model, c).expect("solver");
    // the candidates' kept blocks (and the prefetches of the blocks they lack) as on a large model
    solver.keep_candidate_blocks_always();
    let mut out = FrameSolution::default();
    let mut surface = Vec::new();
    // kept (the same set twice), grown by 3, slid by 3
    let sets: Vec<&[u32]> = vec![&top[..9], &top[..9], &top[..12], &top[..15], &top[3..18], &top[6..21], &top[9..24]];
    for (k, set) in sets.iter().enumerate() {
        let cons: Vec<Constraint> = set
            .iter()
            .map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.001 * (k + 1) as f64) } })
            .collect();
        solver.step(&cons, &mut out).expect("step");
        surface.extend(out.displacement_surface.iter().flat_map(|u| u.iter().map(|x| x.to_bits())).collect::<Vec<_>>());
    }
    // Pressed deeper, with a barrier under every other free node of the top
    // face: the nearest are dragged through it and engage, one iteration
    // after another; the far ones stay well above it. The last frame holds
    // the press and lifts the barrier a little: the far nodes' displacement
    // from the frame before shows them above it.
    let face: Vec<u32> = roi.iter().copied().filter(|&n| (mesh.positions[n as usize].z - 0.03).abs() < 1e-12 && !top[..9].contains(&n)).collect();
    let mut screened = 0;
    let mut iterations = 0;
    for (press, plane) in [(1.0, 1.0), (2.0, 2.0), (3.0, 3.0), (3.0, 2.9)] {
        let mut cons: Vec<Constraint> = top[..9]
            .iter()
            .map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.004 * press) } })
            .collect();
        cons.extend(face.iter().map(|&n| Constraint {
            node: n,
            owner: 0,
            kind: ConstraintKind::Barrier { displacement: Vec3::new(0.0, 0.0, -0.0015 * plane), normal: Vec3::z() },
        }));
        solver.step(&cons, &mut out).expect("step");
        screened += solver.timings().screened;
        iterations += out.iterations;
        surface.extend(out.displacement_surface.iter().flat_map(|u| u.iter().map(|x| x.to_bits())).collect::<Vec<_>>());
    }
    eprintln!("barrier frames: {iterations} iterations, {screened} evaluations screened out");
    assert!(iterations > 4, "some barrier frames must take more than one iteration ({iterations} in four frames)");
    ((entries, surface), screened)
}

#[test]
fn the_bitwise_switches_leave_every_bit() {
    let (on, screened) = run();
    assert!(screened > 0, "the screen must skip some evaluations here");
    for o in BITWISE {
        set_enabled(o, false);
    }
    let (off, none) = run();
    assert_eq!(none, 0, "screening off skips nothing");
    for o in BITWISE {
        set_enabled(o, true);
    }
    assert!(on.0 == off.0, "the compliance entries differ with the optimisations off");
    assert!(on.1 == off.1, "the frames' surface displacements differ with the optimisations off");
    // one at a time too (a difference two switches cancel would hide above)
    for o in BITWISE {
        set_enabled(o, false);
        let (one, fewer) = run();
        set_enabled(o, true);
        assert!(one == on, "{} switched off alone changes the answers", o.name());
        if o == Optimisation::ScreenAcrossFrames {
            // the far nodes of one barrier frame lie above the next one's plane
            assert!(fewer < screened, "records kept across frames must skip more evaluations ({fewer} without, {screened} with)");
        }
    }
}

#[test]
fn every_switch_is_listed_once_in_declaration_order() {
    let mut names = std::collections::BTreeSet::new();
    for (i, (o, name)) in Optimisation::ALL.into_iter().enumerate() {
        assert_eq!(o as usize, i, "{name} is listed out of order");
        assert!(names.insert(name), "{name} is listed twice");
        assert_eq!(o.name(), name);
    }
}
