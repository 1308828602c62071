//! Bad input and hard cases of the FEM model: unfixed components, invalid
//! materials, near-incompressibility and strong stiffness contrast.

use crate::fem_common as common;

use common::*;
use fissure::mesh::fixtures::{box_mesh, linspace};
use fissure::fem::{
    Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemError, FemModel, FemOptions, FrameSolution, Material,
    RegionMaterials,
};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

/// Two disjoint blocks (the real brain's hemispheres are separate bodies).
fn two_blocks() -> TetMesh {
    let a = block(2, 2, 2);
    let mut positions = a.positions.clone();
    let offset = a.positions.len() as u32;
    positions.extend(a.positions.iter().map(|p| p + Vec3::new(0.1, 0.0, 0.0)));
    let mut tets = a.tets.clone();
    tets.extend(a.tets.iter().map(|t| t.map(|n| n + offset)));
    TetMesh::new(positions, tets, vec![]).unwrap()
}

#[test]
fn a_component_without_fixed_nodes_is_named() {
    let mesh = two_blocks();
    let n = mesh.node_count();
    // fix the bottom of the first block only
    let fixed: Vec<bool> = (0..n).map(|i| i < n / 2 && mesh.positions[i].z == 0.0).collect();
    match FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()) {
        Err(FemError::UnfixedComponent { component, nodes, first_node }) => {
            assert_eq!(component, 1, "the second block is component 1");
            assert_eq!(nodes, n / 2, "it has half the nodes");
            assert_eq!(first_node as usize, n / 2, "its lowest node");
        }
        other => panic!("expected UnfixedComponent, got {other:?}"),
    }
    let fixed_both: Vec<bool> = mesh.positions.iter().map(|p| p.z == 0.0).collect();
    assert!(FemModel::new(&mesh, &uniform(BRAIN), &fixed_both, &FemOptions::default()).is_ok(), "fixing each component suffices");
}

#[test]
fn invalid_materials_are_errors() {
    let mesh = block(2, 2, 2);
    let fixed = bottom_fixed(&mesh);
    for (e, nu, field) in [(0.0, 0.3, "young_modulus"), (-5.0, 0.3, "young_modulus"), (1e3, 0.5, "poisson_ratio"), (1e3, -1.0, "poisson_ratio"), (1e3, 0.7, "poisson_ratio")] {
        let m = Material { young_modulus: e, poisson_ratio: nu };
        match FemModel::new(&mesh, &uniform(m), &fixed, &FemOptions::default()) {
            Err(FemError::InvalidMaterial { field: f, region: None, .. }) => assert_eq!(f, field, "E={e}, nu={nu}"),
            other => panic!("E={e}, nu={nu}: expected InvalidMaterial, got {other:?}"),
        }
    }
    // a bad region material names its region
    let mats = RegionMaterials { default: BRAIN, by_region: vec![(7, Material { young_modulus: -1.0, poisson_ratio: 0.3 })] };
    assert!(matches!(FemModel::new(&mesh, &mats, &fixed, &FemOptions::default()), Err(FemError::InvalidMaterial { region: Some(7), .. })));
    assert!(matches!(
        FemModel::new(&mesh, &uniform(BRAIN), &fixed[1..], &FemOptions::default()),
        Err(FemError::FixedLength { .. })
    ));
}

fn solve_hard(materials: &RegionMaterials, mesh: &TetMesh) -> FrameSolution {
    let fixed = bottom_fixed(mesh);
    let model = FemModel::new(mesh, materials, &fixed, &FemOptions::default()).expect("model builds");
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    let mut solver = ConstrainedSolver::new(model, c).unwrap();
    let cons: Vec<Constraint> = mesh
        .positions
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.z - 0.03).abs() < 1e-12 && p.x < 0.035)
        .map(|(n, _)| Constraint { node: n as u32, owner: 0, kind: ConstraintKind::Enforced { displacement: Vec3::new(0.0, 0.0, -0.002) } })
        .collect();
    let mut out = FrameSolution::default();
    solver.step(&cons, &mut out).expect("step");
    out
}

fn assert_finite(out: &FrameSolution, what: &str) {
    assert!(out.displacement_surface.iter().all(|u| u.iter().all(|x| x.is_finite())), "{what}: NaN in displacements");
    assert!(out.reactions.iter().all(|u| u.iter().all(|x| x.is_finite())), "{what}: NaN in reactions");
    assert!(out.max_displacement > 0.0 && out.max_displacement < 0.01, "{what}: implausible max displacement {}", out.max_displacement);
}

#[test]
fn near_incompressible_and_high_contrast_solve_without_nan() {
    let mesh = block(6, 4, 3);
    for nu in [0.49, 0.499] {
        let out = solve_hard(&uniform(Material { young_modulus: 3e3, poisson_ratio: nu }), &mesh);
        println!("nu = {nu}: cond(W) estimate {:e}, rows {}, dropped {}", out.conditioning, out.rows, out.dropped_rows);
        assert_finite(&out, &format!("nu = {nu}"));
    }
    // regions: the right half 1e4 times stiffer
    let regions: Vec<u32> = mesh.tets.iter().map(|t| if mesh.positions[t[0] as usize].x >= 0.03 { 1 } else { 0 }).collect();
    let mesh2 = TetMesh::new(mesh.positions.clone(), mesh.tets.clone(), regions).unwrap();
    let mats = RegionMaterials { default: BRAIN, by_region: vec![(1, Material { young_modulus: 3e7, poisson_ratio: 0.45 })] };
    let out = solve_hard(&mats, &mesh2);
    println!("E contrast 1e4: cond(W) estimate {:e}", out.conditioning);
    assert_finite(&out, "contrast 1e4");
}

#[test]
fn stiffness_is_symmetric_with_six_zero_energy_modes() {
    let mesh = box_mesh(&linspace(0.0, 0.02, 2), &linspace(0.0, 0.01, 2), &linspace(0.0, 0.01, 1)).unwrap();
    let lame: Vec<(f64, f64)> = vec![BRAIN.lame(); mesh.tets.len()];
    let trip = fissure::fem::assembly::assemble_full_triplets(&mesh, &lame);
    let n = 3 * mesh.node_count();
    let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
    for (r, c, v) in trip {
        k[(r, c)] += v;
    }
    let scale = k.abs().max();
    let asym = (&k - k.transpose()).abs().max();
    assert!(asym <= 1e-14 * scale, "K must be symmetric: max |K - K^T| = {asym:e} (scale {scale:e})");
    let eig = nalgebra::SymmetricEigen::new(k).eigenvalues;
    let mut ev: Vec<f64> = eig.iter().copied().collect();
    ev.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let zero = ev.iter().filter(|&&x| x.abs() < 1e-9 * scale).count();
    assert_eq!(zero, 6, "exactly six zero-energy (rigid) modes; smallest eigenvalues {:?}", &ev[..8]);
    assert!(ev[6] > 1e-6 * scale, "the seventh eigenvalue must be clearly positive: {:e}", ev[6]);
}
