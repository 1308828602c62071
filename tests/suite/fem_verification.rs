//! Verification against closed forms: patch test, Lamé thick sphere, Sneddon
//! flat punch; the element's own identities (shape gradients, rigid modes,
//! material ranges) and the stress pass's closed-form eigenvalue. Sizes stay
//! small for CI; observed orders are printed.

use crate::fem_common as common;

use common::*;
use fissure::mesh::fixtures::{box_mesh, linspace, sphere_shell};
use fissure::fem::reference::solve_direct;
use fissure::fem::{
    Compliance, ComplianceStorage, ConstrainedSolver, Constraint, ConstraintKind, FemModel, FemOptions, FrameSolution, Material,
    element_stress,
};
use fissure::fem::element::{shape_gradients, tet_stiffness};
use fissure::fem::stress::largest_symmetric_eigenvalue;
use fissure::math::{Matrix3, Vec3};

#[test]
fn patch_test_uniaxial_bar_is_exact() {
    // Bar 0.1 x 0.02 x 0.02 m, rollers at x = 0, enforced u_x = d at x = L.
    let (l, d) = (0.1, 0.002);
    let mesh = box_mesh(&linspace(0.0, l, 6), &linspace(0.0, 0.02, 2), &linspace(0.0, 0.02, 3)).unwrap();
    let m = Material { young_modulus: 5e3, poisson_ratio: 0.3 };
    let lame = vec![m.lame(); mesh.tets.len()];
    let mut prescribed = Vec::new();
    for (n, p) in mesh.positions.iter().enumerate() {
        if p.x == 0.0 {
            prescribed.push((3 * n, 0.0));
            if p.y == 0.0 && p.z == 0.0 {
                prescribed.push((3 * n + 1, 0.0));
                prescribed.push((3 * n + 2, 0.0));
            }
            if p.y > 0.0 && p.z == 0.0 {
                prescribed.push((3 * n + 2, 0.0));
            }
        }
        if (p.x - l).abs() < 1e-12 {
            prescribed.push((3 * n, d));
        }
    }
    let sol = solve_direct(&mesh, &lame, &prescribed, &[]).unwrap();
    let exact: Vec<Vec3> = mesh.positions.iter().map(|p| Vec3::new(d * p.x / l, -m.poisson_ratio * d * p.y / l, -m.poisson_ratio * d * p.z / l)).collect();
    let e = rel_error(&sol.displacement, &exact);
    assert!(e < 1e-10, "uniaxial bar must be reproduced exactly, relative error {e:e}");
    // reaction at the end = E A eps
    let force: f64 = prescribed.iter().zip(&sol.reactions).filter(|((dof, v), _)| dof % 3 == 0 && *v > 0.0).map(|(_, r)| r).sum();
    let expected = m.young_modulus * 0.02 * 0.02 * d / l;
    assert!((force - expected).abs() < 1e-10 * expected, "end force {force} vs E A eps {expected}");
}

#[test]
fn patch_test_through_the_fast_path() {
    // Every boundary node gets the exact linear field u = g z (stretch and shear);
    // the fixed bottom face z = 0 has u = 0 there.
    let mesh = block(4, 3, 3);
    let g = Vec3::new(0.01, -0.004, 0.006);
    let exact: Vec<Vec3> = mesh.positions.iter().map(|p| g * p.z).collect();
    let fixed = bottom_fixed(&mesh);
    let model = FemModel::new(&mesh, &uniform(BRAIN), &fixed, &FemOptions::default()).unwrap();
    let roi = model.surface().vertices.clone();
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
    let mut solver = ConstrainedSolver::new(model, c).unwrap();
    let cons: Vec<Constraint> = roi
        .iter()
        .map(|&n| Constraint { node: n, owner: 0, kind: ConstraintKind::Enforced { displacement: exact[n as usize] } })
        .collect();
    let mut out = FrameSolution::default();
    solver.step(&cons, &mut out).unwrap();
    let mut all = Vec::new();
    solver.interior_displacements(&mut all).unwrap();
    let e = rel_error(&all, &exact);
    assert!(e < 1e-10, "interior nodes must follow the linear field, relative error {e:e}");
    // Every tet carries the field's constant strain eps = sym(g e_z^T): closed
    // forms for its largest principal strain and von Mises stress.
    let mut stress = Vec::new();
    element_stress(solver.model(), &all, &mut stress).unwrap();
    let shear2 = (g.x * g.x + g.y * g.y) / 4.0;
    let max_principal = g.z / 2.0 + (g.z * g.z / 4.0 + shear2).sqrt();
    let (_, mu) = BRAIN.lame();
    let eps_norm2 = g.z * g.z + 2.0 * shear2;
    let von_mises = 2.0 * mu * (1.5 * (eps_norm2 - g.z * g.z / 3.0)).sqrt();
    for (t, s) in stress.iter().enumerate() {
        assert!((s.max_principal_strain - max_principal).abs() < 1e-9 * max_principal, "tet {t}: principal strain {} vs {max_principal}", s.max_principal_strain);
        assert!((s.von_mises - von_mises).abs() < 1e-9 * von_mises, "tet {t}: von Mises {} vs {von_mises}", s.von_mises);
    }
    // A small rigid rotation strains nothing.
    let omega = Vec3::new(0.002, -0.001, 0.003);
    let rigid: Vec<Vec3> = mesh.positions.iter().map(|p| omega.cross(p)).collect();
    element_stress(solver.model(), &rigid, &mut stress).unwrap();
    let worst = stress.iter().fold(0.0_f64, |m, s| m.max(s.von_mises).max(s.max_principal_strain.abs()));
    assert!(worst < 1e-12, "rigid rotation gives stress or strain {worst:e}");
}

/// Lamé: thick sphere a < r < b, u(a) = u_a radially, free outer surface.
fn lame_error(n: usize, layers: usize) -> f64 {
    let (a, b, ua): (f64, f64, f64) = (0.01, 0.02, 1e-4);
    let m = Material { young_modulus: 3e3, poisson_ratio: 0.3 };
    let (lambda, mu) = m.lame();
    // u = A r + B / r^2, sigma_rr(b) = (3 lambda + 2 mu) A - 4 mu B / b^3 = 0
    let k = 4.0 * mu / ((3.0 * lambda + 2.0 * mu) * b.powi(3));
    let bb = ua / (k * a + 1.0 / (a * a));
    let aa = k * bb;
    let mesh = sphere_shell(a, b, n, layers).unwrap();
    let lame = vec![(lambda, mu); mesh.tets.len()];
    let mut prescribed = Vec::new();
    for (i, p) in mesh.positions.iter().enumerate() {
        if (p.norm() - a).abs() < 1e-12 {
            let u = p.normalize() * ua;
            for c in 0..3 {
                prescribed.push((3 * i + c, u[c]));
            }
        }
    }
    let sol = solve_direct(&mesh, &lame, &prescribed, &[]).unwrap();
    // max error of the radial displacement at the outer surface, relative to u(b)
    let ub = aa * b + bb / (b * b);
    mesh.positions
        .iter()
        .zip(&sol.displacement)
        .filter(|(p, _)| (p.norm() - b).abs() < 1e-12)
        .map(|(p, u)| (u.dot(&p.normalize()) - ub).abs() / ub)
        .fold(0.0, f64::max)
}

#[test]
fn lame_thick_sphere_converges() {
    let coarse = lame_error(4, 2);
    let fine = lame_error(8, 4);
    let order = (coarse / fine).log2();
    println!("Lame thick sphere: outer radial error {coarse:e} (h) -> {fine:e} (h/2), observed order {order:.2}");
    assert!(fine < coarse, "error must decrease with refinement");
    assert!(order > 1.5, "observed order {order:.2} should be near 2 for linear tets");
    assert!(fine < 0.1, "fine-mesh error {fine:e} should be under 10 %");
}

/// Frictionless rigid flat punch of radius `a` pressed `d` into a block:
/// returns the force and Sneddon's half-space value 2 a E d / (1 - nu^2).
fn punch(cells: usize) -> (f64, f64) {
    let (a, d) = (0.005, 1e-4);
    let m = Material { young_modulus: 3e3, poisson_ratio: 0.45 };
    // quarter model by symmetry, graded toward the punch; block 20a wide, 20a deep
    let side = 20.0 * a;
    let grade = |n: usize| -> Vec<f64> { (0..=n).map(|i| side * (i as f64 / n as f64).powf(2.2)).collect() };
    let xs = grade(cells);
    let zs: Vec<f64> = grade(cells).iter().rev().map(|z| side - z).collect();
    let mesh = box_mesh(&xs, &xs, &zs).unwrap();
    let lame = vec![m.lame(); mesh.tets.len()];
    let mut prescribed = Vec::new();
    let mut punch_dofs = Vec::new();
    for (i, p) in mesh.positions.iter().enumerate() {
        if p.z == 0.0 {
            for c in 0..3 {
                prescribed.push((3 * i + c, 0.0));
            }
            continue;
        }
        if p.x == 0.0 {
            prescribed.push((3 * i, 0.0));
        }
        if p.y == 0.0 {
            prescribed.push((3 * i + 1, 0.0));
        }
        if (p.z - side).abs() < 1e-12 && (p.x * p.x + p.y * p.y).sqrt() <= a + 1e-12 {
            punch_dofs.push(prescribed.len());
            prescribed.push((3 * i + 2, -d));
        }
    }
    let sol = solve_direct(&mesh, &lame, &prescribed, &[]).unwrap();
    let force = -4.0 * punch_dofs.iter().map(|&k| sol.reactions[k]).sum::<f64>();
    (force, 2.0 * a * m.young_modulus * d / (1.0 - m.poisson_ratio.powi(2)))
}

#[test]
fn sneddon_flat_punch_converges() {
    let levels = [8, 12, 16];
    let mut errors = Vec::new();
    let mut sneddon = 0.0;
    for &cells in &levels {
        let (f, s) = punch(cells);
        sneddon = s;
        errors.push((f - s).abs() / s);
        println!("Sneddon punch, {cells} cells a side: F = {f:.5e} N vs half-space {s:.5e} N, rel. difference {:.3}", errors.last().unwrap());
    }
    let order = (errors[1] / errors[2]).ln() / (16.0_f64 / 12.0).ln();
    println!("Sneddon punch: observed order {order:.2} (cells 12 -> 16), reference {sneddon:.5e} N");
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "the force must approach Sneddon's value with refinement: {errors:?}");
    assert!(errors[2] < 0.3, "finest level within 30 % (finite 20a block with a fixed base, staircase punch edge, edge singularity): {}", errors[2]);
}

fn unit_tet() -> [Vec3; 4] {
    [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()]
}

#[test]
fn gradients_sum_to_zero_and_reproduce_linear_fields() {
    let p = [Vec3::new(0.1, 0.0, 0.0), Vec3::new(1.2, 0.1, 0.0), Vec3::new(0.2, 0.9, 0.1), Vec3::new(0.0, 0.3, 1.1)];
    let (g, v) = shape_gradients(&p);
    assert!(v > 0.0, "positively oriented tet has positive volume, got {v}");
    assert!((g[0] + g[1] + g[2] + g[3]).norm() < 1e-13, "partition of unity: gradients sum to 0");
    // sum_a x_a g_a^T = I for the coordinate field
    let mut m = Matrix3::zeros();
    for a in 0..4 {
        m += p[a] * g[a].transpose();
    }
    assert!((m - Matrix3::identity()).norm() < 1e-12, "gradient of x must be I, got {m}");
}

#[test]
fn element_stiffness_is_symmetric_and_rigid_modes_have_zero_force() {
    let (l, m) = Material { young_modulus: 3e3, poisson_ratio: 0.45 }.lame();
    let k = tet_stiffness(&unit_tet(), l, m);
    for i in 0..12 {
        for j in 0..12 {
            assert!((k[i][j] - k[j][i]).abs() < 1e-9 * k[0][0].abs(), "K not symmetric at ({i},{j})");
        }
    }
    // rotation about z: u = w x p
    let w = Vec3::new(0.3, -0.2, 1.0);
    let u: Vec<f64> = unit_tet().iter().flat_map(|p| { let r = w.cross(p); [r.x, r.y, r.z] }).collect();
    for i in 0..12 {
        let f: f64 = (0..12).map(|j| k[i][j] * u[j]).sum();
        assert!(f.abs() < 1e-9 * k[0][0].abs(), "infinitesimal rotation gives force {f} at row {i}");
    }
}

#[test]
fn material_ranges_are_checked() {
    assert!(Material { young_modulus: 0.0, poisson_ratio: 0.3 }.validate(None).is_err());
    assert!(Material { young_modulus: -1.0, poisson_ratio: 0.3 }.validate(Some(2)).is_err());
    assert!(Material { young_modulus: 1.0, poisson_ratio: 0.5 }.validate(None).is_err());
    assert!(Material { young_modulus: 1.0, poisson_ratio: -1.0 }.validate(None).is_err());
    assert!(Material { young_modulus: 1.0, poisson_ratio: f64::NAN }.validate(None).is_err());
    assert!(Material { young_modulus: 1.0, poisson_ratio: 0.499 }.validate(None).is_ok());
}

/// Against nalgebra's iterative eigen solver: random symmetric matrices of
/// mixed scales, and degenerate spectra (double, triple, zero, rank one).
#[test]
fn largest_eigenvalue_matches_the_iterative_solver() {
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut cases: Vec<Matrix3<f64>> = Vec::new();
    for k in 0..2000 {
        let scale = 10f64.powi(k % 9 - 6);
        let m = Matrix3::from_fn(|_, _| next() * scale);
        cases.push((m + m.transpose()) * 0.5);
    }
    let v = Vec3::new(0.3, -0.5, 0.8).normalize();
    cases.push(Matrix3::zeros());
    cases.push(Matrix3::identity() * 2.5e-3);
    cases.push(Matrix3::from_diagonal(&Vec3::new(1e-3, 1e-3, -2e-3)));
    cases.push(Matrix3::from_diagonal(&Vec3::new(-1e-3, -1e-3, 2e-3)));
    cases.push(v * v.transpose() * 4e-3);
    cases.push(v * v.transpose() * -4e-3);
    cases.push(Matrix3::identity() * 1e-3 + v * v.transpose() * 1e-12);
    for a in &cases {
        let exact = a.symmetric_eigenvalues().iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        let got = largest_symmetric_eigenvalue(a);
        let norm = a.abs().max();
        assert!((got - exact).abs() <= 1e-13 * norm.max(f64::MIN_POSITIVE), "{a}: {got} vs {exact}");
    }
    assert!(largest_symmetric_eigenvalue(&Matrix3::from_element(f64::NAN)).is_nan());
}
