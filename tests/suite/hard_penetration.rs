//! Hard cases, deep penetration: a blade jumping 5x its thickness through a
//! fissure wall in one frame, a blade starting inside the tissue, two blades
//! pressing the same vertices from opposite sides, a blade pushing a vertex
//! into a skull sphere. Every frame passes the shared invariants of
//! `common::scenes::check_frame` (finite values, skull constraints, conflict
//! rules, no adhesive force, inverted-element count printed).
//!
//! Scene units: millimetres in the mesh file, metres inside.

use crate::common;

use common::scenes::{Blade, Scene, check_frame, fissure_blocks, pose_mm, step_checked};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;

/// Quaternion (w, x, y, z) of +90 degrees about y: blade (x) points down (-z), face 0 normal (+z) points +x.
const BLADE_DOWN_FACE_PLUS_X: [f64; 4] = [std::f64::consts::FRAC_1_SQRT_2, 0.0, std::f64::consts::FRAC_1_SQRT_2, 0.0];
const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn vertical_blade(x_mm: f64) -> Blade {
    Blade {
        name: "blade",
        length_mm: 20.0,
        width_mm: 8.0,
        thickness_mm: 1.0,
        along: 10,
        across: 4,
        position_mm: [x_mm, 0.0, 30.0],
        rotation: "Quaternion(0.7071067811865476, 0.0, 0.7071067811865476, 0.0)".into(),
    }
}

/// Two 20 mm blocks with a 4 mm fissure between them (walls at x = -2 and x = +2 mm).
fn fissure_scene(blade_x_mm: f64) -> Scene {
    let mut s = Scene::new(fissure_blocks(4.0, 20.0, 20.0, 20.0, [5, 5, 5]), vec![vertical_blade(blade_x_mm)]);
    s.effects = "Collision, Culling, ForceOutput, ContactPressure, StressField".into();
    s
}

fn max_u(state: &fissure::sim::SimState) -> f64 {
    state.surface_displacement.iter().map(|u| u.norm()).fold(0.0, f64::max)
}

/// Rest-position selector of the fissure walls' vertices in the blade's footprint.
fn in_footprint_of_wall(x0: &Vec3, wall_x_m: f64) -> bool {
    (x0.x - wall_x_m).abs() < 1e-12 && x0.y.abs() <= 0.004 - 1e-9 && x0.z >= 0.010 + 1e-9 && x0.z <= 0.020
}

/// Runs the 5x-thickness jump: rest frame, one jump of +5 mm, three holds. Returns the jump frame.
fn jump(label: &str) -> (fissure::sim::Pipeline, fissure::sim::SimState, fissure::sim::FrameReport, common::scenes::FrameCheck) {
    let dir = tempfile::tempdir().unwrap();
    let (mut p, mut state) = fissure_scene(0.0).build(dir.path());
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([0.0, 0.0, 30.0], BLADE_DOWN_FACE_PLUS_X)], label);
    assert_eq!(r.constrained_vertices, 0, "{label}: the blade in the middle of the fissure touches nothing");
    // One frame: +5 mm = 5 thicknesses. Face 0 (+x) ends at x = 5.5 mm, 3.5 mm inside the right block.
    let (r, c) = step_checked(&mut p, &mut state, &[pose_mm([5.0, 0.0, 30.0], BLADE_DOWN_FACE_PLUS_X)], label);
    (p, state, r, c)
}

#[test]
fn blade_jumping_five_thicknesses_into_a_fissure_wall_stays_finite_holds_and_releases() {
    let label = "5x-thickness jump";
    let (mut p, mut state, r, c) = jump(label);
    assert!(r.constrained_vertices > 0, "{label}: the wall under the blade must be claimed");
    // The leading face pushes the near wall (rest x = 2 mm) onto its plane (x = 5.5 mm).
    let rest = p.rest_positions().to_vec();
    let mut on_face = 0;
    for (v, x0) in rest.iter().enumerate() {
        if in_footprint_of_wall(x0, 0.002) {
            let x = state.surface_positions[v];
            assert!((x.x - 0.0055).abs() < 1e-9, "{label}: wall vertex {v} must be pushed onto face 0 (x = 5.5 mm), at {} mm", x.x * 1e3);
            on_face += 1;
        }
    }
    assert!(on_face >= 4, "{label}: only {on_face} wall vertices in the footprint");
    // Displacements are bounded by the enforced ones (factor 1: the maximum sits on a held vertex).
    let max_target = common::scenes::max_enforced_m(&p);
    assert!(c.max_displacement_m <= max_target + 1e-9, "{label}: max |u| {} m beyond the largest enforced {} m", c.max_displacement_m, max_target);
    println!("{label}: force {:?} N, inverted {} of all tets, crossed {}, penetrating {}", r.spatulas[0].force, r.inverted_elements, r.crossed_vertices, r.penetrating_vertices);
    // Hold: every frame passes the invariants and stays within the same bound (before the
    // collision's swept-side culling the claims alternated on a tangled surface: see below).
    for _ in 0..4 {
        let (_, c) = step_checked(&mut p, &mut state, &[pose_mm([5.0, 0.0, 30.0], BLADE_DOWN_FACE_PLUS_X)], label);
        let max_target = common::scenes::max_enforced_m(&p);
        assert!(c.max_displacement_m <= max_target + 1e-9, "{label}: holding, max |u| {} m beyond the enforced {} m", c.max_displacement_m, max_target);
    }
    // Withdraw up out of the fissure (z + 40 mm): back to rest.
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([5.0, 0.0, 70.0], BLADE_DOWN_FACE_PLUS_X)], label);
    assert_eq!(r.constrained_vertices, 0, "{label}: withdrawn, nothing is held");
    assert!(max_u(&state) < 1e-9, "{label}: withdrawn, the tissue returns to rest: max |u| {:e} m", max_u(&state));
}

#[test]
// Was BUG 1 (collision: the trailing face paired with the far side, 17.5 mm, 207 inverted tets);
// passes since the collision's swept-side culling (commit dfcedfb).
fn blade_jumping_five_thicknesses_moves_only_the_wall_it_hits() {
    let label = "5x-thickness jump, physics";
    let (p, state, r, c) = jump(label);
    let rest = p.rest_positions();
    for (v, x0) in rest.iter().enumerate() {
        if in_footprint_of_wall(x0, 0.022) {
            let moved = state.surface_displacement[v].norm();
            assert!(moved < 0.0035, "{label}: far-side vertex {v} (16.5 mm ahead of the blade) moved {moved} m");
        }
    }
    assert!(c.max_displacement_m <= 0.0035 + 1e-9, "{label}: max |u| {} m exceeds the 3.5 mm the blade pushed", c.max_displacement_m);
    assert_eq!(r.penetrating_vertices, 0, "{label}: no tissue may stay inside the blade");
    assert_eq!(r.crossed_vertices, 0, "{label}: no tissue may tunnel through the blade");
    assert_eq!(r.inverted_elements, 0, "{label}: a 3.5 mm push on 4 mm elements must invert nothing");
    // Held still, the tissue must stay still (measured with the bug: a period-2 cycle, 4.6 mm apart).
    let (mut p, mut state) = (p, state);
    let u_before = state.surface_displacement.clone();
    for _ in 0..3 {
        step_checked(&mut p, &mut state, &[pose_mm([5.0, 0.0, 30.0], BLADE_DOWN_FACE_PLUS_X)], label);
    }
    let drift = state.surface_displacement.iter().zip(&u_before).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(drift < 1e-9, "{label}: holding the blade still must hold the tissue still, drift {drift:e} m");
}

#[test]
fn blade_starting_inside_the_tissue_stays_finite_and_releases_to_rest() {
    let dir = tempfile::tempdir().unwrap();
    // Start 10 mm deep inside the right block (its walls at x = 2 and x = 22 mm).
    let (mut p, mut state) = fissure_scene(12.0).build(dir.path());
    let label = "start inside";
    let inside = pose_mm([12.0, 0.0, 30.0], BLADE_DOWN_FACE_PLUS_X);
    let (r, c) = step_checked(&mut p, &mut state, &[inside], label);
    // The documented rule (collision rule 1: no depth limit behind, as in the paper): each face
    // pairs with the nearest facing surface behind it, however far, and pulls it onto its plane:
    // the near wall (x = 2 mm) onto face 0 (x = 12.5 mm), the far side (x = 22 mm) onto face 1 (11.5 mm).
    let rest = p.rest_positions().to_vec();
    let (mut near, mut far) = (0, 0);
    for (v, x0) in rest.iter().enumerate() {
        let x = state.surface_positions[v].x;
        if in_footprint_of_wall(x0, 0.002) {
            assert!((x - 0.0125).abs() < 1e-9, "{label}: near-wall vertex {v} at {} mm, expected on face 0 (12.5 mm)", x * 1e3);
            near += 1;
        }
        if in_footprint_of_wall(x0, 0.022) {
            assert!((x - 0.0115).abs() < 1e-9, "{label}: far-side vertex {v} at {} mm, expected on face 1 (11.5 mm)", x * 1e3);
            far += 1;
        }
    }
    assert!(near > 0 && far > 0, "{label}: both faces must claim ({near} near, {far} far)");
    let max_target = common::scenes::max_enforced_m(&p);
    assert!(
        c.max_displacement_m <= max_target + 1e-9,
        "{label}: no vertex may move further than the largest enforced displacement ({max_target} m), moved {} m",
        c.max_displacement_m
    );
    println!(
        "{label}: constrained {} max|u| {:.3e} m inverted {} (a 10 mm squeeze of 4 mm elements) penetrating {} force {:?}",
        r.constrained_vertices, c.max_displacement_m, r.inverted_elements, r.penetrating_vertices, r.spatulas[0].force
    );
    // Held still, the claims on the squeezed (tangled) surface alternate between two sets
    // (measured: 34 / 33 / 34 vertices, about 4.6 mm between the two states); each frame stays
    // bounded by its own enforced displacements.
    for _ in 0..4 {
        let (_, c) = step_checked(&mut p, &mut state, &[inside], label);
        let max_target = common::scenes::max_enforced_m(&p);
        assert!(c.max_displacement_m <= max_target + 1e-9, "{label}: holding, max |u| {} m beyond the enforced {} m", c.max_displacement_m, max_target);
    }
    // Pull the blade out upwards (z + 40 mm): nothing is held, the tissue is at rest.
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([12.0, 0.0, 70.0], BLADE_DOWN_FACE_PLUS_X)], label);
    assert_eq!(r.constrained_vertices, 0);
    assert!(max_u(&state) < 1e-9, "{label}: released, max |u| {:e} m", max_u(&state));
}

/// A roof-shaped body: x in [-10, 10] mm, y in [-10, 10], z from 0 to a ridge
/// at x = 0 (20 mm) sloping at 45 degrees to 10 mm at x = +-10.
fn roof() -> TetMesh {
    let mut m = common::block(10, 6, 5, Vec3::new(20.0, 20.0, 1.0), Vec3::new(-10.0, -10.0, 0.0));
    for p in m.positions.iter_mut() {
        p.z *= 20.0 - p.x.abs();
    }
    TetMesh::new(m.positions, m.tets, m.regions).expect("roof mesh is valid")
}

#[test]
fn two_blades_pressing_the_ridge_from_opposite_sides_resolve_by_the_deepest_claim() {
    let dir = tempfile::tempdir().unwrap();
    let s2 = std::f64::consts::FRAC_1_SQRT_2;
    // Blade A lies on the left slope (normal (-1,0,1)/sqrt2) and presses 1.5 mm into it with
    // face 1 (outward (1,0,-1)/sqrt2); blade B mirrors it on the right slope, 1.0 mm deep.
    // Their footprints cross the ridge, so both claim the ridge vertices, from opposite sides.
    // Rotation about y by -45 deg: x -> (s2, 0, s2) (up the left slope), z -> (-s2, 0, s2).
    let qa = [(std::f64::consts::PI / 8.0).cos(), 0.0, -(std::f64::consts::PI / 8.0).sin(), 0.0];
    // Rotation about y by +45 deg then about z by 180 deg: blade up the right slope towards -x.
    let qb_rot = fissure::math::Quat::from_axis_angle(&Vec3::z_axis(), std::f64::consts::PI)
        * fissure::math::Quat::from_axis_angle(&Vec3::y_axis(), -std::f64::consts::FRAC_PI_4);
    let qb = [qb_rot.w, qb_rot.i, qb_rot.j, qb_rot.k];
    let n_left = Vec3::new(-s2, 0.0, s2);
    let n_right = Vec3::new(s2, 0.0, s2);
    // Handle ends: on the slope plane, offset outward by half the thickness plus a clearance
    // (then pressed). Blade length 16 mm from x = -9 reaches 2.3 mm past the ridge.
    let start_a = |depth_mm: f64| {
        let on_slope = Vec3::new(-9.0, 0.0, 11.0);
        let c = on_slope + n_left * (0.5 - depth_mm);
        [c.x, c.y, c.z]
    };
    let start_b = |depth_mm: f64| {
        let on_slope = Vec3::new(9.0, 0.0, 11.0);
        let c = on_slope + n_right * (0.5 - depth_mm);
        [c.x, c.y, c.z]
    };
    let blade = |name, pos: [f64; 3], q: [f64; 4]| Blade {
        name,
        length_mm: 16.0,
        width_mm: 8.0,
        thickness_mm: 1.0,
        along: 16,
        across: 4,
        position_mm: pos,
        rotation: format!("Quaternion({:?}, {:?}, {:?}, {:?})", q[0], q[1], q[2], q[3]),
    };
    let mut scene = Scene::new(roof(), vec![blade("a", start_a(-1.0), qa), blade("b", start_b(-1.0), qb)]);
    scene.effects = "Collision, Culling, ForceOutput, StressField".into();
    // The rule under test decides claims within one step: with sub-steps (the
    // default) each sub-step's claims are measured from the tissue the last one
    // moved, and the blade still advancing (B) out-claims the one whose face the
    // ridge already lies on (A): a different, equally finite resolution.
    scene.substep_travel = "None";
    let (mut p, mut state) = scene.build(dir.path());
    let label = "opposite blades on one ridge";
    let mut last = None;
    for k in 0..=6 {
        // Approach from 1 mm outside to 1.5 mm (A) and 1.0 mm (B) deep in 0.25 mm / 0.1667 mm steps.
        let da = -1.0 + 2.5 * k as f64 / 6.0;
        let db = -1.0 + 2.0 * k as f64 / 6.0;
        let poses = [pose_mm(start_a(da), qa), pose_mm(start_b(db), qb)];
        last = Some(step_checked(&mut p, &mut state, &poses, label));
    }
    let (r, c) = last.unwrap();
    let targets = p.collision().unwrap().output().targets.clone();
    let rest = p.rest_positions().to_vec();
    let ridge: Vec<usize> = (0..rest.len()).filter(|&v| rest[v].x.abs() < 1e-12 && (rest[v].z - 0.020).abs() < 1e-12 && rest[v].y.abs() < 0.004).collect();
    assert!(!ridge.is_empty(), "the roof has ridge vertices under the blades");
    let mut by_a = 0;
    for &v in &ridge {
        let t = targets.iter().find(|t| t.vertex as usize == v).unwrap_or_else(|| panic!("{label}: ridge vertex {v} must be claimed"));
        // The deeper blade (A, 1.5 mm) wins the ridge; the vertex ends on A's face plane.
        assert_eq!(t.spatula, 0, "{label}: ridge vertex {v}: the deepest claim (blade A) must win, got {t:?}");
        let plane_a = Vec3::new(-9.0, 0.0, 11.0) * 1e-3 + n_left * (-1.5e-3);
        let dist = (state.surface_positions[v] - plane_a).dot(&n_left);
        assert!(dist.abs() < 1e-9, "{label}: ridge vertex {v} must lie on blade A's face, off by {dist:e} m");
        by_a += 1;
    }
    assert!(r.spatulas[0].constrained_vertices > 0 && r.spatulas[1].constrained_vertices > 0, "both blades hold tissue: {:?}", r.spatulas);
    assert!(r.spatulas[0].force.dot(&-n_left) > 0.0 && r.spatulas[1].force.dot(&-n_right) > 0.0, "{label}: each blade pushes into its slope");
    println!("{label}: ridge vertices {by_a} all to A; max|u| {:.3e} m inverted {} cond {:.3e}", c.max_displacement_m, r.inverted_elements, c.conditioning);
    assert_eq!(r.inverted_elements, 0, "{label}: 1.5 mm on 2 mm elements inverts nothing");
}

#[test]
fn blade_pushing_vertices_into_an_excluding_sphere_wins_and_the_sphere_row_carries_no_force() {
    let dir = tempfile::tempdir().unwrap();
    // A 40 x 40 x 20 mm block; an excluding sphere (centre z = 10 mm, r = 9.8 mm) lies inside it,
    // 0.2 mm under the top face: the blade presses the top face 3 mm down, so the vertices it
    // holds end inside the sphere. The blade pushes them down, the sphere pushes them up: the
    // documented rule (FEM `constrained.rs`) is that the enforced displacement wins and the
    // sphere row is not used (reaction zero); every other vertex stays outside the sphere.
    let mesh = common::block(10, 10, 5, Vec3::new(40.0, 40.0, 20.0), Vec3::new(-20.0, -20.0, 0.0));
    let mut scene = Scene::new(mesh, vec![Blade::flat("blade", [-6.0, 0.0, 21.5])]);
    scene.blades[0].length_mm = 12.0;
    scene.blades[0].width_mm = 6.0;
    scene.blades[0].along = 12;
    scene.blades[0].across = 6;
    scene.skull = Some("Some((excluding: Some((center_mm: (0.0, 0.0, 10.0), radius_mm: 9.8))))".into());
    scene.effects = "Collision, Culling, SkullSpheres, ForceOutput, StressField".into();
    let (mut p, mut state) = scene.build(dir.path());
    let label = "blade against excluding sphere";
    let mut last = None;
    for k in 0..=10 {
        // Lower face from z = 21 mm to 17 mm: 3 mm into the block, 2.8 mm into the sphere.
        let z = 21.5 - 4.0 * k as f64 / 10.0;
        last = Some(step_checked(&mut p, &mut state, &[pose_mm([-6.0, 0.0, z], IDENTITY)], label));
    }
    let (r, c) = last.unwrap();
    let centre = Vec3::new(0.0, 0.0, 0.010);
    let constraints = p.last_constraints().to_vec();
    let enforced_nodes: Vec<u32> =
        constraints.iter().filter(|k| k.kind.is_tool() && p.solver().released_nodes().binary_search(&k.node).is_err()).map(|k| k.node).collect();
    let mut conflicts = 0;
    for (k, cons) in constraints.iter().enumerate() {
        if matches!(cons.kind, fissure::fem::ConstraintKind::SphereOutside { .. }) && enforced_nodes.contains(&cons.node) {
            let v = p.surface().node_to_vertex[cons.node as usize] as usize;
            if (state.surface_positions[v] - centre).norm() < 0.0098 {
                conflicts += 1;
                assert_eq!(p.last_solution().reactions[k], Vec3::zeros(), "{label}: the sphere row on a blade-held vertex must carry no force");
            }
        }
    }
    assert!(conflicts > 0, "{label}: the case needs blade-held vertices inside the sphere (found none)");
    println!("{label}: {conflicts} blade-held vertices inside the sphere (enforced wins), {} skull contacts, inverted {}", r.skull_contacts, r.inverted_elements);
    assert!(c.worst_skull_violation <= 1e-9);
    assert_eq!(r.inverted_elements, 0, "{label}: a 3 mm press on 4 mm elements inverts nothing");
    // Withdraw: both constraints release, the block returns to rest.
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([-6.0, 0.0, 40.0], IDENTITY)], label);
    assert_eq!(r.constrained_vertices, 0);
    assert!(max_u(&state) < 1e-9, "{label}: withdrawn, max |u| {:e} m", max_u(&state));
    let _ = check_frame;
}
