//! The paper's cases as scenes (Fukuhara et al. 2014): Fig. 8 (facing rule),
//! Fig. 6/10/11 (deep sideways move in a fissure, with and without culling),
//! Fig. 12 (V valley: both faces push, nothing culled; U channel with a tilted
//! spatula: the two faces' contact patterns differ). Every case runs on every
//! backend; the GPU one prints a skip line when no adapter exists.

use crate::common;

use fissure::collision::scenes::{heightfield_solid, linspace, merge, pose_from_axes, subdivided_box};
use fissure::collision::{BackendKind, CollisionConfig, CollisionOutput, CollisionStage, SpatulaSpec};
use fissure::geometry::{NodeLayout, Pose, SpatulaShape};
use fissure::math::Vec3;

const MM: f64 = 1e-3;

fn stage(backend: BackendKind, culling: bool, t: &[[u32; 3]], p: &[Vec3], spec: &SpatulaSpec) -> Option<CollisionStage> {
    let s = CollisionStage::new(CollisionConfig { backend, culling }, t, p, std::slice::from_ref(spec)).expect("valid stage");
    if backend == BackendKind::Gpu && s.backend() != BackendKind::Gpu {
        common::skip(&format!("no GPU adapter ({:?})", s.warnings()));
        return None;
    }
    Some(s)
}

const BACKENDS: [BackendKind; 3] = [BackendKind::Reference, BackendKind::Bvh, BackendKind::Gpu];

/// Kinematic stand-in for the FEM: constrained vertices sit on their targets, the rest at rest.
fn apply(rest: &[Vec3], out: &CollisionOutput) -> Vec<Vec3> {
    let mut cur = rest.to_vec();
    for t in &out.targets {
        cur[t.vertex as usize] = rest[t.vertex as usize] + t.displacement;
    }
    cur
}

#[test]
fn fig8_pair_only_when_the_triangle_faces_the_node() {
    let shape = SpatulaShape { length: 10.0 * MM, width: 4.0 * MM, thickness: 1.0 * MM };
    let spec = SpatulaSpec { shape, layout: NodeLayout::Explicit(vec![[5.0 * MM, 0.0]]) };
    // A triangle between the two faces (z = 0.2 mm), normal +z (CCW seen from +z).
    let p = vec![Vec3::new(0.0, -2.0 * MM, 0.2 * MM), Vec3::new(10.0 * MM, -2.0 * MM, 0.2 * MM), Vec3::new(5.0 * MM, 2.0 * MM, 0.2 * MM)];
    for backend in BACKENDS {
        for (tri, pair_face) in [([0u32, 1, 2], 1u8), ([0u32, 2, 1], 0u8)] {
            let Some(mut s) = stage(backend, true, &[tri], &p, &spec) else { continue };
            let out = s.step(&p, &[Pose::default()]).expect("step");
            // Both nodes have the triangle behind them; only the face whose normal opposes the triangle's pairs.
            assert_eq!(out.candidate_pairs.len(), 1, "{backend:?} {tri:?}: exactly one face must pair: {:?}", out.candidate_pairs);
            assert_eq!(out.candidate_pairs[0].face, pair_face, "{backend:?}: triangle {tri:?} faces face {pair_face}");
            assert!((out.candidate_pairs[0].t - if pair_face == 0 { -0.3 * MM } else { -0.7 * MM }).abs() < 1e-9);
        }
    }
}

/// Two boxes with a 2 mm gap (the inter-hemispheric fissure), a vertical spatula in the gap.
fn fissure_scene() -> ((Vec<[u32; 3]>, Vec<Vec3>), SpatulaSpec) {
    let left = subdivided_box(Vec3::new(-30.0, -20.0, -30.0) * MM, Vec3::new(-1.0, 20.0, 0.0) * MM, 29, 20);
    let right = subdivided_box(Vec3::new(1.0, -20.0, -30.0) * MM, Vec3::new(30.0, 20.0, 0.0) * MM, 29, 20);
    let shape = SpatulaShape { length: 40.0 * MM, width: 8.0 * MM, thickness: 1.0 * MM };
    (merge(&[left, right]), SpatulaSpec { shape, layout: NodeLayout::Grid { along: 8, across: 3 } })
}

fn fissure_pose(x_mm: f64) -> Pose {
    // Blade pointing down (-z), face 0 normal +x, handle end 25 mm above the top.
    pose_from_axes(Vec3::new(x_mm * MM, 0.0, 25.0 * MM), -Vec3::z(), Vec3::x())
}

#[test]
fn fig6_10_11_deep_sideways_move_is_culled_only_with_history() {
    let ((t, rest), spec) = fissure_scene();
    for backend in BACKENDS {
        let mut far_wall_pairs = [0usize; 2];
        for (c, culling) in [true, false].into_iter().enumerate() {
            let Some(mut s) = stage(backend, culling, &t, &rest, &spec) else { continue };
            let out = s.step(&rest, &[fissure_pose(0.0)]).expect("frame 0");
            assert!(out.candidate_pairs.is_empty(), "{backend:?}: centred in the 2 mm gap, a 1 mm spatula touches nothing");
            let out = s.step(&rest, &[fissure_pose(1.0)]).expect("frame 1");
            assert!(out.feasible_pairs.iter().all(|p| p.face == 0), "{backend:?}: first contact is face 0 only");
            assert_eq!(out.feasible_pairs.len(), 9, "{backend:?}: the 9 submerged nodes of face 0 touch the right wall");
            let cur = apply(&rest, out);
            // Jump 3 mm (3x the thickness) in one frame: both faces inside the right box.
            let out = s.step(&cur, &[fissure_pose(4.0)]).expect("frame 2");
            let far = |tri: u32| t[tri as usize].iter().all(|&v| rest[v as usize].x > 29.0 * MM);
            assert!(out.candidate_pairs.iter().any(|p| p.face == 1 && far(p.triangle)), "{backend:?}: face 1 must see the far wall as a candidate");
            far_wall_pairs[c] = out.feasible_pairs.iter().filter(|p| far(p.triangle)).count();
            if culling {
                assert_eq!(far_wall_pairs[c], 0, "{backend:?}: with culling no feasible pair may reach the far wall: {:?}", out.feasible_pairs);
                assert!(!out.culled_pairs.is_empty(), "{backend:?}: the far-wall candidates must be reported culled");
                for target in &out.targets {
                    let v = rest[target.vertex as usize];
                    assert!(v.x < 2.0 * MM && target.face == 0, "{backend:?}: vertex {v:?} pulled across the spatula");
                    assert!((v + target.displacement).x <= 4.5 * MM + 1e-12, "{backend:?}: target beyond face 0's plane");
                }
                assert!(out.feasible_pairs.iter().any(|p| p.face == 0), "{backend:?}: face 0 keeps pushing the near wall");
            } else {
                assert!(far_wall_pairs[c] > 0, "{backend:?}: without culling the paper's failure (Fig. 11b) must appear");
                assert!(out.targets.iter().any(|tg| rest[tg.vertex as usize].x > 29.0 * MM), "{backend:?}: far-wall vertices get pulled");
            }
        }
    }
}

#[test]
fn fig12_v_valley_both_faces_push_and_nothing_is_culled() {
    let xs = linspace(-20.0 * MM, 20.0 * MM, 80);
    let ys = linspace(-10.0 * MM, 10.0 * MM, 10);
    let (t, rest) = heightfield_solid(&xs, &ys, -20.0 * MM, |x, _| 4.0 * x.abs());
    let shape = SpatulaShape { length: 20.0 * MM, width: 6.0 * MM, thickness: 1.0 * MM };
    let spec = SpatulaSpec { shape, layout: NodeLayout::Grid { along: 40, across: 4 } };
    for backend in BACKENDS {
        let Some(mut s) = stage(backend, true, &t, &rest, &spec) else { continue };
        let mut cur = rest.clone();
        let mut saw_both = false;
        for k in 0..15 {
            let tip = 3.0 - 0.2 * k as f64; // mm above the valley floor, down to 0.2
            let pose = pose_from_axes(Vec3::new(0.0, 0.0, (tip + 20.0) * MM), -Vec3::z(), Vec3::x());
            let out = s.step(&cur, &[pose]).expect("step");
            assert!(out.culled_pairs.is_empty(), "{backend:?} tip {tip} mm: culling cancelled feasible pairs: {:?}", out.culled_pairs);
            let faces = [0u8, 1].map(|f| out.feasible_pairs.iter().filter(|p| p.face == f).count());
            if faces[0] > 0 && faces[1] > 0 {
                saw_both = true;
                for target in &out.targets {
                    let x = rest[target.vertex as usize].x;
                    assert!((target.face == 0) == (x > 0.0) || x == 0.0, "{backend:?}: face {} claimed a vertex at x = {x} (face 0 looks +x and pushes the right slope)", target.face);
                }
            }
            cur = apply(&rest, out);
        }
        assert!(saw_both, "{backend:?}: both faces must push the two slopes of the V");
    }
}

#[test]
fn fig12_u_channel_tilted_spatula_contact_patterns_differ() {
    let mut xs = linspace(-15.0 * MM, -3.2 * MM, 24);
    xs.extend(linspace(-3.0 * MM, 3.0 * MM, 12));
    xs.extend(linspace(3.2 * MM, 15.0 * MM, 24));
    let ys = linspace(-10.0 * MM, 10.0 * MM, 10);
    let (t, rest) = heightfield_solid(&xs, &ys, -5.0 * MM, |x, _| if x.abs() <= 3.0 * MM + 1e-12 { 0.0 } else { 10.0 * MM });
    let shape = SpatulaShape { length: 20.0 * MM, width: 6.0 * MM, thickness: 1.0 * MM };
    let spec = SpatulaSpec { shape, layout: NodeLayout::Grid { along: 40, across: 4 } };
    // Tilted in the xz plane: tip low against the right wall, upper blade against the left rim.
    let blade = Vec3::new(6.0, 0.0, -9.0).normalize();
    let normal = Vec3::new(9.0, 0.0, 6.0).normalize();
    for backend in BACKENDS {
        let Some(mut s) = stage(backend, true, &t, &rest, &spec) else { continue };
        let mut cur = rest.clone();
        let mut last = None;
        for k in 0..=10 {
            let tip = Vec3::new(3.0 * MM, 0.0, 1.0 * MM) - blade * ((10 - k) as f64 * 0.5 * MM);
            let pose = pose_from_axes(tip - blade * shape.length, blade, normal);
            let out = s.step(&cur, &[pose]).expect("step");
            cur = apply(&rest, out);
            last = Some(out.clone());
        }
        let out = last.expect("frames ran");
        let by_face = |f: u8| out.targets.iter().filter(|tg| tg.face == f).map(|tg| rest[tg.vertex as usize]).collect::<Vec<_>>();
        let (f0, f1) = (by_face(0), by_face(1));
        assert!(!f0.is_empty() && !f1.is_empty(), "{backend:?}: both faces must hold contact: {} / {}", f0.len(), f1.len());
        assert!(f0.iter().all(|v| v.x > 0.0), "{backend:?}: face 0 (normal toward +x) pushes only the right wall");
        assert!(f1.iter().all(|v| v.x < 0.0), "{backend:?}: face 1 pushes only the left wall");
        let mean_z = |v: &[Vec3]| v.iter().map(|p| p.z).sum::<f64>() / v.len() as f64;
        assert!(mean_z(&f0) < mean_z(&f1), "{backend:?}: face 0 touches low (tip), face 1 high (rim)");
        for tg in &out.targets {
            let moved = tg.displacement - (cur[tg.vertex as usize] - rest[tg.vertex as usize]);
            assert!(moved.norm() < 1e-12, "targets are consistent with the kinematic surface");
            assert!((tg.normal.norm() - 1.0).abs() < 1e-12);
        }
    }
}
