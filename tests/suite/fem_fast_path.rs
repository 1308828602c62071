//! The fast path (precomputed compliance + Schur complement) against a direct
//! re-factorization with the constrained DOFs eliminated.

use crate::fem_common as common;

use common::*;
use fissure::fem::reference::solve_direct;
use fissure::fem::{
    BodyForce, Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution,
};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

/// Enforced displacements on the top-face nodes within a disc: a push down and sideways.
fn top_constraints(mesh: &TetMesh, center: (f64, f64), radius: f64, owner: u16, d: Vec3) -> Vec<Constraint> {
    mesh.positions
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.z - 0.03).abs() < 1e-12 && ((p.x - center.0).powi(2) + (p.y - center.1).powi(2)).sqrt() <= radius)
        .map(|(n, p)| Constraint { node: n as u32, owner, kind: ConstraintKind::Enforced { displacement: d + Vec3::new(0.0, 0.0, -0.05 * p.x) } })
        .collect()
}

/// Direct reference: fixed nodes and every enforced node prescribed.
fn reference(mesh: &TetMesh, model: &FemModel, fixed: &[bool], constraints: &[Constraint], forces: &[Vec3]) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut prescribed = Vec::new();
    for (n, &f) in fixed.iter().enumerate() {
        if f {
            for c in 0..3 {
                prescribed.push((3 * n, 0.0));
                prescribed.last_mut().unwrap().0 += c;
            }
        }
    }
    let first = prescribed.len();
    for c in constraints {
        if let ConstraintKind::Enforced { displacement } = c.kind {
            for k in 0..3 {
                prescribed.push((3 * c.node as usize + k, displacement[k]));
            }
        }
    }
    let sol = solve_direct(mesh, model.lame(), &prescribed, forces).expect("reference solve");
    let reactions =
        (0..constraints.len()).map(|i| Vec3::new(sol.reactions[first + 3 * i], sol.reactions[first + 3 * i + 1], sol.reactions[first + 3 * i + 2])).collect();
    (sol.displacement, reactions)
}

fn surface_of(model: &FemModel, nodal: &[Vec3]) -> Vec<Vec3> {
    model.surface().vertices.iter().map(|&n| nodal[n as usize]).collect()
}

fn run(storage: ComplianceStorage, roi_fraction: f64, gravity: bool) -> (f64, f64, FrameSolution) {
    let mesh = block(6, 4, 4);
    let fixed = bottom_fixed(&mesh);
    let options = FemOptions { gravity: gravity.then_some(BodyForce { density: 1040.0, acceleration: Vec3::new(0.0, 0.0, -9.81) }) };
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &options).expect("model");
    // ROI: surface nodes with x below a fraction of the length (the rest gets lazy columns)
    let roi: Vec<u32> = model.surface().vertices.iter().copied().filter(|&n| mesh.positions[n as usize].x <= 0.06 * roi_fraction + 1e-12).collect();
    let compliance = Compliance::compute(&model, &roi, storage, None, &mut |_, _| {}).expect("compliance");
    let mut solver = ConstrainedSolver::new(model, compliance).expect("solver");
    let mut constraints = top_constraints(&mesh, (0.02, 0.02), 0.012, 0, Vec3::new(0.001, 0.0, -0.002));
    constraints.extend(top_constraints(&mesh, (0.045, 0.02), 0.011, 1, Vec3::new(-0.001, 0.0005, -0.001)));
    let mut out = FrameSolution::default();
    solver.step(&constraints, &mut out).expect("step");
    let forces: Vec<Vec3> = if gravity {
        let mut f = vec![Vec3::zeros(); mesh.node_count()];
        for t in &mesh.tets {
            let w = Vec3::new(0.0, 0.0, -9.81) * (1040.0 * mesh.tet_volume(t) / 4.0);
            for &n in t {
                f[n as usize] += w;
            }
        }
        f
    } else {
        vec![]
    };
    let (u_ref, r_ref) = reference(&mesh, solver.model(), &fixed, &constraints, &forces);
    let e_u = rel_error(&out.displacement_surface, &surface_of(solver.model(), &u_ref));
    let e_r = rel_error(&out.reactions, &r_ref);
    // interior displacements agree too
    let mut all = Vec::new();
    solver.interior_displacements(&mut all).expect("interior");
    let e_i = rel_error(&all, &u_ref);
    assert!(e_i < 1e-6, "interior displacements differ from the direct solve: {e_i:e}");
    (e_u, e_r, out)
}

#[test]
fn f64_fast_path_matches_direct_refactorization() {
    let (e_u, e_r, out) = run(ComplianceStorage::F64, 1.0, false);
    println!("f64 full-surface ROI: displacement rel. error {e_u:e}, reaction rel. error {e_r:e}, cond(W) >= {:e}", out.conditioning);
    assert!(e_u < 1e-8, "surface displacement relative error {e_u:e} exceeds 1e-8");
    assert!(e_r < 1e-8, "reaction relative error {e_r:e} exceeds 1e-8");
    assert_eq!(out.lazy_solves, 0, "every constrained node is in the ROI");
    assert_eq!(out.owner_forces.len(), 2, "two spatulas, two force sums");
    let total: Vec3 = out.reactions.iter().sum();
    let by_owner: Vec3 = out.owner_forces.iter().map(|x| x.1).sum();
    assert!((total - by_owner).norm() < 1e-12 * total.norm(), "owner sums must add to the total");
}

#[test]
fn nodes_outside_the_roi_are_still_exact() {
    let (e_u, e_r, out) = run(ComplianceStorage::F64, 0.5, false);
    println!("f64 half ROI: displacement rel. error {e_u:e}, reaction {e_r:e}, lazy solves {}", out.lazy_solves);
    assert!(out.lazy_solves > 0, "the second spatula lies outside the ROI: its columns must be solved lazily");
    assert!(e_u < 1e-8 && e_r < 1e-8, "lazy columns must keep the solve exact: {e_u:e}, {e_r:e}");
}

#[test]
fn f32_storage_error_is_stated_and_small() {
    let (e_u, e_r, _) = run(ComplianceStorage::F32, 1.0, false);
    println!("f32 storage: displacement rel. error {e_u:e}, reaction rel. error {e_r:e}");
    assert!(e_u < 1e-5, "f32 compliance: displacement error {e_u:e} must stay under 1e-5");
    assert!(e_r < 1e-9, "f32 compliance: W is gathered from corrected ROI x ROI entries, so reactions are exact to round-off; got {e_r:e}");
    assert!(e_u > 1e-12, "f32 storage cannot be exact to f64 round-off; got {e_u:e} (is the f32 path used?)");
}

#[test]
fn gravity_is_included_exactly() {
    let (e_u, e_r, _) = run(ComplianceStorage::F64, 1.0, true);
    assert!(e_u < 1e-8 && e_r < 1e-8, "with gravity: {e_u:e}, {e_r:e}");
}

#[test]
fn repeated_steps_are_bitwise_deterministic() {
    let mesh = block(4, 3, 3);
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).unwrap();
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    let mut solver = ConstrainedSolver::new(model, c).unwrap();
    let cons = top_constraints(&mesh, (0.03, 0.02), 0.02, 0, Vec3::new(0.0, 0.0, -0.003));
    let (mut a, mut b) = (FrameSolution::default(), FrameSolution::default());
    solver.step(&cons, &mut a).unwrap();
    solver.step(&[], &mut b).unwrap();
    assert!(b.max_displacement == 0.0, "no constraints and no gravity: rest state");
    solver.step(&cons, &mut b).unwrap();
    assert_eq!(a, b, "the same constraints must give bitwise the same solution");
}

/// The surface product keeps the gathered rows `K^-1[c, 0..c]` of forced
/// columns between calls: whatever it kept, the result is bitwise the one of a
/// fresh workspace and matches the block-by-block sum; a persisting force set
/// gathers nothing, new columns are gathered once.
#[test]
fn surface_product_reuses_gathered_rows_and_matches_the_block_sum() {
    // One body, and two (a fixed wall splits a longer block): the layout with two runs a column.
    let one = block(5, 4, 3);
    let two = fissure::mesh::fixtures::box_mesh(&fissure::mesh::fixtures::linspace(0.0, 0.12, 12), &fissure::mesh::fixtures::linspace(0.0, 0.04, 4), &fissure::mesh::fixtures::linspace(0.0, 0.03, 3)).unwrap();
    let wall = |m: &TetMesh| -> Vec<bool> { m.positions.iter().map(|p| p.z.abs() < 1e-12 || (p.x - 0.05).abs() < 1e-9).collect() };
    for (mesh, fixed) in [(one.clone(), bottom_fixed(&one)), (two.clone(), wall(&two))] {
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).unwrap();
    let roi = model.surface().vertices.clone();
    for storage in [ComplianceStorage::F64, ComplianceStorage::F32] {
        let c = Compliance::compute(&model, &roi, storage, None, &mut |_, _| {}).unwrap();
        let (rows, cols) = (c.row_nodes().len(), c.column_count());
        assert!(cols > 40, "the test wants a few dozen ROI columns, has {cols}");
        let force = |k: usize| Vec3::new(0.3 - 0.01 * k as f64, 0.1 * (k % 7) as f64, -1.0 + 0.02 * k as f64);
        // Sets of forced columns, ascending: shifting windows, a shrink, an empty frame, a grow back.
        let sets: Vec<Vec<usize>> = vec![
            (0..20).map(|k| 2 * k).collect(),
            (3..23).map(|k| 2 * k).collect(),
            (3..23).map(|k| 2 * k).collect(),
            vec![5, cols - 1],
            vec![],
            (cols / 2..cols).collect(),
            vec![0, 1, 2, cols / 3],
        ];
        let mut kept = fissure::fem::ProductWorkspace::default();
        let mut previous: Vec<usize> = Vec::new();
        for (frame, set) in sets.iter().enumerate() {
            let forces: Vec<(usize, Vec3)> = set.iter().map(|&j| (j, force(j))).collect();
            let mut u = vec![Vec3::new(1e-3, 0.0, -2e-3); rows];
            c.accumulate(&forces, &mut u, &mut kept);
            let new = set.iter().filter(|j| !previous.contains(j)).count();
            assert_eq!(kept.rows_gathered(), new, "{storage:?} frame {frame}: only columns new since the last call are gathered");
            let mut fresh_u = vec![Vec3::new(1e-3, 0.0, -2e-3); rows];
            c.accumulate(&forces, &mut fresh_u, &mut fissure::fem::ProductWorkspace::default());
            assert!(u == fresh_u, "{storage:?} frame {frame}: kept rows must give the bits of a fresh workspace");
            // Small chunks: columns covering a whole chunk stream in groups, the ones whose diagonal falls inside go alone.
            for chunk in [1, 7, 16, 40] {
                let mut chunked = vec![Vec3::new(1e-3, 0.0, -2e-3); rows];
                c.accumulate(&forces, &mut chunked, &mut fissure::fem::ProductWorkspace::with_chunk_rows(chunk));
                assert!(u == chunked, "{storage:?} frame {frame}: chunks of {chunk} rows change the bits");
            }
            // Split over two threads anywhere (in a component's ROI rows, its other rows, at their seams).
            for at in [1, 5, cols / 2, cols - 1, cols, cols + 3, rows - 1] {
                let mut split = vec![Vec3::new(1e-3, 0.0, -2e-3); rows];
                c.accumulate(&forces, &mut split, &mut fissure::fem::ProductWorkspace::with_split_row(at));
                assert!(u == split, "{storage:?} frame {frame}: split at row {at} changes the bits");
            }
            let scale = forces.iter().map(|f| f.1.norm()).sum::<f64>().max(1.0) * (0..rows).map(|r| c.product_block(r, 0).norm()).fold(0.0, f64::max);
            for (r, ur) in u.iter().enumerate() {
                let mut expected = Vec3::new(1e-3, 0.0, -2e-3);
                for &(j, f) in &forces {
                    expected += c.product_block(r, j) * f;
                }
                assert!((ur - expected).norm() <= 1e-12 * scale, "{storage:?} frame {frame} row {r}: {ur:?} vs {expected:?}");
            }
            // Bitwise: the documented arithmetic, one row at a time (9 partials
            // over the forces in ascending column order, lower blocks then the
            // transposed upper ones), whatever the kernel's chunking and fusing.
            for (r, ur) in u.iter().enumerate() {
                let mut want = Vec3::new(1e-3, 0.0, -2e-3);
                let mut p = [0.0f64; 9];
                for &(j, f) in forces.iter().filter(|x| x.0 <= r) {
                    let b = c.product_block(r, j);
                    for e in 0..9 {
                        p[e] += b[(e % 3, e / 3)] * f[e / 3];
                    }
                }
                want += Vec3::new(p[0] + p[3] + p[6], p[1] + p[4] + p[7], p[2] + p[5] + p[8]);
                if r < cols {
                    let mut a = [0.0f64; 9];
                    for &(j, f) in forces.iter().filter(|x| x.0 > r) {
                        let b = c.product_block(j, r);
                        for e in 0..9 {
                            a[e] += b[(e % 3, e / 3)] * f[e % 3];
                        }
                    }
                    want += Vec3::new(a[0] + a[1] + a[2], a[3] + a[4] + a[5], a[6] + a[7] + a[8]);
                }
                assert!(*ur == want, "{storage:?} frame {frame} row {r}: {ur:?}, the documented arithmetic gives {want:?}");
            }
            previous = set.clone();
        }
    }
    }
}

/// Columns forced along one direction are streamed projected on it from the
/// second call in a row that forces them along the same direction: the first
/// call takes their 3x3 blocks, a changed direction takes them again, and every
/// call matches the block-by-block sum; a split over two threads and small
/// chunks leave the bits of a workspace with the same history.
#[test]
fn columns_forced_along_one_direction_are_projected_from_their_second_call() {
    let one = block(5, 4, 3);
    let model = FemModel::new(&one, &uniform(BRAIN), &bottom_fixed(&one), &FemOptions::default()).unwrap();
    let roi = model.surface().vertices.clone();
    for storage in [ComplianceStorage::F64, ComplianceStorage::F32] {
        let c = Compliance::compute(&model, &roi, storage, None, &mut |_, _| {}).unwrap();
        let (rows, cols) = (c.row_nodes().len(), c.column_count());
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let turned = Vec3::new(0.0, 0.6, 0.8);
        let lambda = |k: usize, call: usize| 0.2 + 0.01 * k as f64 - 0.03 * call as f64;
        // (columns along n, columns along the turned normal, the full-force columns) per call
        let along_cols: Vec<usize> = (0..cols).step_by(3).take(fissure::fem::PROJECTIONS_PER_CALL).collect();
        let full_cols: Vec<usize> = (1..cols).step_by(7).filter(|j| j % 3 != 0).collect();
        let half = along_cols.len() / 2;
        // (projections built, columns projected) each call should report
        let expected = [(0, 0), (along_cols.len(), along_cols.len()), (0, along_cols.len()), (0, along_cols.len() - half), (half, along_cols.len())];
        let mut workspaces = [
            fissure::fem::ProductWorkspace::default(),
            fissure::fem::ProductWorkspace::with_split_row(cols / 2 + 1),
            fissure::fem::ProductWorkspace::with_chunk_rows(7),
        ];
        for (call, want) in expected.iter().enumerate() {
            let along: Vec<(usize, Vec3, f64)> =
                along_cols.iter().enumerate().map(|(k, &j)| (j, if call >= 3 && k < half { turned } else { n }, lambda(k, call))).collect();
            let forces: Vec<(usize, Vec3)> = full_cols.iter().map(|&j| (j, Vec3::new(0.1, -0.2, 0.05 * call as f64))).collect();
            let mut results = Vec::new();
            for w in workspaces.iter_mut() {
                let mut u = vec![Vec3::new(1e-3, 0.0, -2e-3); rows];
                c.accumulate_along(&forces, &along, &mut u, w);
                assert_eq!(w.columns_projected(), *want, "{storage:?} call {call}: projections built and streamed");
                results.push(u);
            }
            assert!(results[1] == results[0], "{storage:?} call {call}: a split changes the bits");
            assert!(results[2] == results[0], "{storage:?} call {call}: chunks of 7 rows change the bits");
            let total = forces.iter().map(|f| f.1.norm()).sum::<f64>() + along.iter().map(|a| a.2.abs()).sum::<f64>();
            let scale = total.max(1.0) * (0..rows).map(|r| c.product_block(r, 0).norm()).fold(0.0, f64::max);
            for (r, ur) in results[0].iter().enumerate() {
                let mut expected = Vec3::new(1e-3, 0.0, -2e-3);
                for &(j, f) in &forces {
                    expected += c.product_block(r, j) * f;
                }
                for &(j, d, l) in &along {
                    expected += c.product_block(r, j) * (d * l);
                }
                assert!((ur - expected).norm() <= 1e-12 * scale, "{storage:?} call {call} row {r}: {ur:?} vs {expected:?}");
            }
        }
    }
}

/// Many columns forced along one direction at once are projected a bounded
/// number a call, the rest on their blocks until their turn: every one is
/// projected in the end, and no call builds more than the bound.
#[test]
fn a_wide_contact_is_projected_a_bounded_number_of_columns_a_call() {
    let one = block(5, 4, 3);
    let model = FemModel::new(&one, &uniform(BRAIN), &bottom_fixed(&one), &FemOptions::default()).unwrap();
    let c = Compliance::compute(&model, &model.surface().vertices.clone(), ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    let (rows, cols) = (c.row_nodes().len(), c.column_count());
    let bound = fissure::fem::PROJECTIONS_PER_CALL;
    assert!(cols > 2 * bound, "the test wants more than twice {bound} columns, has {cols}");
    let along: Vec<(usize, Vec3, f64)> = (0..cols).map(|j| (j, Vec3::z(), 0.1)).collect();
    let mut w = fissure::fem::ProductWorkspace::default();
    let mut streamed = Vec::new();
    for _ in 0..cols.div_ceil(bound) + 2 {
        let mut u = vec![Vec3::zeros(); rows];
        c.accumulate_along(&[], &along, &mut u, &mut w);
        let (built, projected) = w.columns_projected();
        assert!(built <= bound, "{built} columns projected in one call");
        streamed.push(projected);
    }
    assert_eq!(streamed[0], 0, "the first call takes every column's blocks");
    assert_eq!(streamed[1], bound);
    assert_eq!(*streamed.last().unwrap(), cols, "every column is projected in the end: {streamed:?}");
}

/// Two blocks side by side (a 10 mm gap) and one block cut in two by a fixed
/// wall: `K^-1` between the parts is exactly zero. Dense storage keeps no block
/// between them (about half the bytes of one body with the same rows), every
/// stored block is the direct solve's, the cross blocks read back as zero, and
/// the fast path stays exact with spatulas on both parts.
#[test]
fn separate_bodies_store_no_coupling_and_stay_exact() {
    let a = block(4, 3, 3);
    let mut positions = a.positions.clone();
    positions.extend(a.positions.iter().map(|p| p + Vec3::new(0.07, 0.0, 0.0)));
    let shift = a.node_count() as u32;
    let mut tets = a.tets.clone();
    tets.extend(a.tets.iter().map(|t| t.map(|n| n + shift)));
    let regions = vec![0; tets.len()];
    let two = TetMesh::new(positions, tets, regions).expect("two blocks");
    let wall = block(6, 3, 3);
    let wall_fixed: Vec<bool> = wall.positions.iter().map(|p| p.z.abs() < 1e-12 || (p.x - 0.03).abs() < 1e-9).collect();
    assert!(wall_fixed.iter().filter(|&&f| f).count() > bottom_fixed(&wall).iter().filter(|&&f| f).count(), "the wall plane must hold nodes");
    for (name, mesh, fixed, spatulas) in [
        ("two blocks", two, None, [(0.02, 0.02, 0.012), (0.095, 0.02, 0.012)]),
        ("fixed wall", wall, Some(wall_fixed), [(0.015, 0.02, 0.012), (0.05, 0.02, 0.01)]),
    ] {
        let fixed = fixed.unwrap_or_else(|| bottom_fixed(&mesh));
        let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).expect("model");
        let roi = model.surface().vertices.clone();
        let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).expect("compliance");
        let (rows, cols) = (c.row_nodes().len(), c.column_count());
        let one_body = (cols * rows - cols * (cols - 1) / 2) * 72;
        let bytes = c.stats().bytes;
        println!("{name}: {rows} rows x {cols} cols, {bytes} bytes stored, {one_body} for one body");
        assert!((bytes as f64) < 0.6 * one_body as f64, "{name}: {bytes} bytes stored, one body would be {one_body}: cross blocks are stored");
        // Blocks against the direct solve for a unit force, a few columns on each side.
        let side = |n: u32| mesh.positions[n as usize].x > if name == "two blocks" { 0.065 } else { 0.03 };
        let mut checked = [0usize; 2];
        for j in (0..cols).step_by(7) {
            let node = c.row_nodes()[j];
            for k in 0..3 {
                let mut f = vec![Vec3::zeros(); mesh.node_count()];
                f[node as usize][k] = 1.0;
                let u = model.solve_nodal_forces(&f).expect("solve");
                let scale = max_norm(&u);
                for (r, &rn) in c.row_nodes().iter().enumerate() {
                    let got = c.block(r, j).column(k).into_owned();
                    if side(rn) != side(node) {
                        assert!(got == Vec3::zeros(), "{name}: block ({rn}, {node}) couples two bodies: {got:?}");
                    } else {
                        assert!((got - u[rn as usize]).norm() <= 1e-12 * scale, "{name}: block ({rn}, {node}) column {k}: {got:?} vs {:?}", u[rn as usize]);
                    }
                }
            }
            checked[side(node) as usize] += 1;
        }
        assert!(checked[0] > 2 && checked[1] > 2, "{name}: columns checked on each side: {checked:?}");
        // The fast path with a spatula on each part, against the direct re-factorization.
        let mut cons = Vec::new();
        for (owner, &(x, y, r)) in spatulas.iter().enumerate() {
            cons.extend(top_constraints(&mesh, (x, y), r, owner as u16, Vec3::new(0.0005, 0.0, -0.002)));
        }
        assert!(cons.iter().any(|k| side(k.node)) && cons.iter().any(|k| !side(k.node)), "{name}: constraints on both parts");
        let mut solver = ConstrainedSolver::new(model, c).expect("solver");
        let mut out = FrameSolution::default();
        solver.step(&cons, &mut out).expect("step");
        let (u_ref, r_ref) = reference(&mesh, solver.model(), &fixed, &cons, &[]);
        let e_u = rel_error(&out.displacement_surface, &surface_of(solver.model(), &u_ref));
        let e_r = rel_error(&out.reactions, &r_ref);
        println!("{name}: displacement rel. error {e_u:e}, reaction {e_r:e}");
        assert!(e_u < 1e-8 && e_r < 1e-8, "{name}: fast path vs direct: {e_u:e}, {e_r:e}");
    }
}
