//! Hard cases, geometry: rays exactly through mesh vertices and edges, zero-area
//! and needle triangles, sliver tetrahedra (a thin layer of our own and the real
//! brain mesh, mean-ratio quality down to about 0.02), a blade parallel to a
//! surface patch and rays lying in a surface's plane. Every pipeline frame passes
//! `common::scenes::check_frame`; the sliver cases also match the direct
//! reference solve (constrained DOFs eliminated, `K_FF` factored anew).

use crate::common;

use common::scenes::{Blade, Scene, pose_mm, reference_disagreement, step_checked};
use fissure::collision::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use fissure::geometry::{NodeLayout, Pose, SpatulaShape};
use fissure::math::{Quat, Vec3};
use fissure::mesh::TetMesh;
use fissure::mesh::quality::QualityReport;

const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
const BLADE_DOWN_FACE_PLUS_X: [f64; 4] = [std::f64::consts::FRAC_1_SQRT_2, 0.0, std::f64::consts::FRAC_1_SQRT_2, 0.0];

/// 40 x 40 x 20 mm block, 4 mm cells, top face at z = 20 mm.
fn block_mm() -> TetMesh {
    common::block(10, 10, 5, Vec3::new(40.0, 40.0, 20.0), Vec3::new(-20.0, -20.0, 0.0))
}

/// A blade whose 10 x 5 grid nodes fall on world x in {-10, -8, ..., 8} mm and y in {-4, ..., 4}:
/// every ray goes through a mesh vertex (multiples of 4 mm), an edge midpoint, or a cell's
/// diagonal (both coordinates odd multiples of 2 mm).
fn grid_on_vertices() -> Blade {
    Blade::flat("blade", [-11.0, 0.0, 21.0])
}

fn press_run(backend: &'static str) -> (Vec<fissure::collision::VertexTarget>, Vec<Vec3>, usize) {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = Scene::new(block_mm(), vec![grid_on_vertices()]);
    scene.backend = backend;
    let (mut p, mut state) = scene.build(dir.path());
    let label = format!("rays through vertices and edges ({backend})");
    let mut candidates = 0;
    for k in 0..=8 {
        // Face 1 from z = 20.5 mm down to 19.0 mm (1 mm into the top face).
        let z = 21.0 - 1.5 * k as f64 / 8.0;
        let before = state.surface_positions.clone();
        let (r, _) = step_checked(&mut p, &mut state, &[pose_mm([-11.0, 0.0, z], IDENTITY)], &label);
        let out = p.collision().unwrap().output();
        if z - 0.5 < 20.0 {
            // Every face-1 ray (50 of them) must find the top face: none slips through a vertex or an edge.
            assert_eq!(r.spatulas[0].candidate_pairs, 50, "{label}: frame {k}: every ray through a vertex/edge must find one triangle");
            for pair in &out.candidate_pairs {
                let node = out.source_nodes.iter().find(|n| n.spatula == pair.spatula && n.node == pair.node).unwrap();
                let tri = p.surface().triangles[pair.triangle as usize].map(|v| before[v as usize]);
                assert!(contains_xy(&tri, &node.position), "{label}: the triangle found for node {} must contain its ray", pair.node);
            }
            candidates = out.candidate_pairs.len();
        }
    }
    // Every vertex in the footprint sits on face 1 (z = 19 mm).
    for (v, x) in state.surface_positions.iter().enumerate() {
        let x0 = p.rest_positions()[v];
        if (x0.z - 0.020).abs() < 1e-12 && x0.x >= -0.010 && x0.x <= 0.008 && x0.y.abs() <= 0.004 {
            assert!((x.z - 0.019).abs() < 1e-9, "{label}: top vertex {v} at z = {} mm, expected 19 mm", x.z * 1e3);
        }
    }
    (p.collision().unwrap().output().targets.clone(), state.surface_positions.clone(), candidates)
}

/// Is the (x, y) of `p` in the closed xy-projection of the triangle (with a 1e-12 m margin)?
fn contains_xy(t: &[Vec3; 3], p: &Vec3) -> bool {
    let cross = |a: &Vec3, b: &Vec3, c: &Vec3| (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    let area = cross(&t[0], &t[1], &t[2]);
    let s = area.signum();
    let tol = 1e-12 * area.abs().sqrt();
    (0..3).all(|k| s * cross(&t[k], &t[(k + 1) % 3], p) >= -tol * 1e3)
}

#[test]
fn rays_exactly_through_vertices_and_edges_each_find_one_triangle_on_every_backend() {
    let (bvh_targets, bvh_positions, n) = press_run("Bvh");
    let (ref_targets, ref_positions, _) = press_run("Reference");
    assert_eq!(n, 50);
    assert_eq!(bvh_targets, ref_targets, "BVH and reference backends must claim the same vertices bit for bit");
    assert_eq!(bvh_positions, ref_positions, "and leave the same surface bit for bit");
}

#[test]
fn zero_area_and_needle_triangles_never_give_nan_or_a_pair() {
    let mm = |x: f64, y: f64, z: f64| Vec3::new(x, y, z) * 1e-3;
    let rest = vec![
        mm(0.0, 0.0, 0.0),   // 0
        mm(10.0, 0.0, 0.0),  // 1
        mm(10.0, 10.0, 0.0), // 2
        mm(0.0, 10.0, 0.0),  // 3
        mm(5.0, 5.0, 0.0),   // 4: on the diagonal 0-2
        mm(12.0, 2.0, 0.2),  // 5: needle, 6 mm long, 1e-9 mm wide
        mm(18.0, 2.0, 0.2),  // 6
        mm(18.0, 2.0 + 1e-9, 0.2), // 7
    ];
    let triangles = vec![
        [0, 1, 2], // 0: square, lower right
        [0, 2, 3], // 1: square, upper left
        [0, 4, 2], // 2: zero area (collinear), on the shared diagonal
        [4, 4, 2], // 3: zero area (repeated vertex)
        [5, 6, 7], // 4: needle, normal +z
    ];
    // A blade over the sheet (handle end at y = 5 mm so local y = world y - 5); face 1
    // (normal -z) at z = -0.5 mm has the sheet and the needle behind it.
    let shape = SpatulaShape { length: 0.020, width: 0.010, thickness: 0.001 };
    let nodes = vec![
        [0.005, 0.0],            // through vertex 4 and the diagonal shared by 0, 1, 2, 3
        [0.0025, 0.0025 - 0.005], // through the diagonal (edge 0-2)
        [0.003, 0.002],          // plain interior of triangle 1
        [0.015, 0.002 + 5e-13 - 0.005], // inside the needle
        [0.015, 0.002 - 0.005],  // on the needle's long edge
    ];
    for backend in [BackendKind::Reference, BackendKind::Bvh] {
        let mut stage = CollisionStage::new(
            CollisionConfig { backend, culling: true },
            &triangles,
            &rest,
            &[SpatulaSpec { shape, layout: NodeLayout::Explicit(nodes.clone()) }],
        )
        .expect("a surface with degenerate triangles is accepted");
        for frame in 0..3 {
            let pose = Pose { position: mm(0.0, 5.0, 0.0), rotation: Quat::identity() };
            let out = stage.step(&rest, &[pose]).expect("step");
            for t in &out.targets {
                assert!(t.displacement.iter().all(|c| c.is_finite()) && t.depth.is_finite(), "{backend:?} frame {frame}: target {t:?} is not finite");
            }
            for pair in &out.candidate_pairs {
                assert!(pair.t.is_finite(), "{backend:?}: pair {pair:?} has a non-finite t");
                assert!(pair.triangle != 2 && pair.triangle != 3, "{backend:?}: a zero-area triangle must never pair: {pair:?}");
            }
            let by_node = |node: u32| out.candidate_pairs.iter().filter(|p| p.face == 1 && p.node == node).count();
            let pairs = nodes.len() as u32;
            for k in 0..3 {
                assert_eq!(by_node(pairs + k), 1, "{backend:?} frame {frame}: face-1 node {k} (vertex / edge / interior ray) must find exactly one sheet triangle");
            }
            // The needle: its inner ray may hit it (area 3e-15 m^2) or pass; either way no NaN.
            println!("{backend:?} frame {frame}: candidates {:?}", out.candidate_pairs.iter().map(|p| (p.node, p.triangle)).collect::<Vec<_>>());
            // The sheet lies inside the blade: its vertices behind face 1 are claimed and moved to z = -0.5 mm.
            for t in &out.targets {
                if t.vertex <= 4 {
                    assert!((rest[t.vertex as usize].z + t.displacement.z + 0.0005).abs() < 1e-12, "{backend:?}: sheet vertex {} must go onto face 1", t.vertex);
                }
            }
        }
    }
}

/// The block with its top cell layer squashed to 0.005 mm: 4 x 4 x 0.005 mm Kuhn tets (slivers).
fn sliver_block() -> TetMesh {
    let mut m = block_mm();
    for p in m.positions.iter_mut() {
        p.z = if p.z <= 16.0 + 1e-9 { p.z * 19.995 / 16.0 } else { 19.995 + (p.z - 16.0) * 0.005 / 4.0 };
    }
    TetMesh::new(m.positions, m.tets, m.regions).expect("sliver block is valid")
}

#[test]
fn sliver_layer_press_is_exact_and_matches_the_direct_solve() {
    let mesh = sliver_block();
    let q = QualityReport::of(&mesh);
    println!("sliver block: min mean ratio {:.4}, median {:.4}", q.min_mean_ratio, q.median_mean_ratio);
    assert!(q.min_mean_ratio < 0.03, "the case needs slivers as bad as the real brain's (0.017-0.025), got {}", q.min_mean_ratio);
    let dir = tempfile::tempdir().unwrap();
    let mut scene = Scene::new(mesh, vec![Blade::flat("blade", [-10.0, 0.0, 21.0])]);
    scene.effects = "Collision, Culling, ForceOutput, StressField".into();
    let (mut p, mut state) = scene.build(dir.path());
    let label = "sliver layer";
    let mut last = None;
    for k in 0..=8 {
        // Face 1 from 20.5 mm to 19.5 mm: 0.5 mm, 100 times the sliver layer's thickness.
        let z = 21.0 - 1.0 * k as f64 / 8.0;
        last = Some(step_checked(&mut p, &mut state, &[pose_mm([-10.0, 0.0, z], IDENTITY)], label));
    }
    let (r, c) = last.unwrap();
    assert!(r.constrained_vertices > 0);
    let rel = reference_disagreement(&mut p, &state);
    println!("{label}: fast path vs direct solve {rel:.3e} relative; cond(W) {:.3e}; inverted {} of all tets", c.conditioning, r.inverted_elements);
    assert!(rel < 1e-8, "{label}: the fast path must match the direct solve to 1e-8 relative, got {rel:e}");
    assert!(c.conditioning.is_finite() && c.conditioning >= 1.0);
}

#[test]
fn real_brain_slivers_press_is_exact_and_finite() {
    let path = common::real_brain(fissure::mesh::brain::COARSE);
    let t0 = std::time::Instant::now();
    let mesh = fissure::mesh::io::load_tet_mesh(&path).expect("coarse brain loads");
    let q = QualityReport::of(&mesh);
    println!("real brain: {} nodes, min mean ratio {:.4}, loaded in {:.1} s", mesh.node_count(), q.min_mean_ratio, t0.elapsed().as_secs_f64());
    // Press the lateral-most point of the right hemisphere (largest x) with a blade whose face 1 points -x.
    let top = mesh.positions.iter().copied().fold(Vec3::new(f64::MIN, 0.0, 0.0), |a, p| if p.x > a.x { p } else { a });
    // Keep the mesh in mm in the file: the scene builder writes it and says Millimetres.
    let dir = tempfile::tempdir().unwrap();
    // Blade x along world +y, local z along world +x (face 1 outward normal -x): a cyclic permutation.
    let q3 = [0.5, 0.5, 0.5, 0.5];
    let handle = |x_mm: f64| [x_mm, top.y - 10.0, top.z];
    let blade = Blade {
        name: "blade",
        length_mm: 20.0,
        width_mm: 8.0,
        thickness_mm: 1.0,
        along: 10,
        across: 4,
        position_mm: handle(top.x + 1.5),
        rotation: "Quaternion(0.5, 0.5, 0.5, 0.5)".into(),
    };
    let mut scene = Scene::new(mesh, vec![blade]);
    scene.fixed = "LowestPerComponent(height_mm: 10.0)".into();
    scene.roi = format!("Sphere(center_mm: ({:?}, {:?}, {:?}), radius_mm: 14.0)", top.x, top.y, top.z);
    scene.effects = "Collision, Culling, ForceOutput".into();
    let t0 = std::time::Instant::now();
    let (mut p, mut state) = scene.build(dir.path());
    println!("real brain: built in {:.1} s (compliance {:?})", t0.elapsed().as_secs_f64(), p.solver().compliance().stats());
    let label = "real brain";
    let mut last = None;
    for k in 0..=6 {
        // Face 1 from 1 mm outside the lateral-most node to 2 mm inside.
        let x = top.x + 1.5 - 3.0 * k as f64 / 6.0;
        last = Some(step_checked(&mut p, &mut state, &[pose_mm(handle(x), q3)], label));
    }
    let (r, c) = last.unwrap();
    assert!(r.constrained_vertices > 0, "{label}: the blade must hold the lateral surface");
    assert!(r.spatulas[0].force.x < 0.0, "{label}: the blade pushes medially (-x): {:?}", r.spatulas[0].force);
    let t0 = std::time::Instant::now();
    let rel = reference_disagreement(&mut p, &state);
    println!("{label}: direct solve took {:.1} s", t0.elapsed().as_secs_f64());
    println!("{label}: fast path vs direct solve {rel:.3e}; cond(W) {:.3e}; max|u| {:.3e} m; inverted {} (surface tets)", c.conditioning, c.max_displacement_m, r.inverted_elements);
    assert!(rel < 1e-8, "{label}: the fast path must match the direct solve to 1e-8 relative, got {rel:e}");
    assert_eq!(r.inverted_elements, 0, "{label}: a 2 mm press inverts no surface tet");
    // Release.
    let (r, _) = step_checked(&mut p, &mut state, &[pose_mm(handle(top.x + 20.0), q3)], label);
    assert_eq!(r.constrained_vertices, 0);
    // The whole surface: the far vertices the press brought up to date are
    // left as they were until an output or a blade asks for them again.
    let whole = p.with_whole_surface(&state).expect("the whole surface");
    let max_u = whole.surface_displacement.iter().map(|u| u.norm()).fold(0.0, f64::max);
    assert!(max_u < 1e-9, "{label}: released, max |u| {max_u:e} m");
}

#[test]
fn blade_parallel_to_the_top_face_touching_then_pressing_by_a_nanometre() {
    let dir = tempfile::tempdir().unwrap();
    let (mut p, mut state) = Scene::new(block_mm(), vec![Blade::flat("blade", [-10.0, 0.0, 21.0])]).build(dir.path());
    let label = "parallel blade";
    // Face 1 exactly on the top face (z = 20 mm), then 1 nm, 1 um and 0.1 mm into it.
    let mut previous_count = None;
    for (k, depth_m) in [0.0, 1e-9, 1e-6, 1e-4].into_iter().enumerate() {
        let pose = Pose { position: Vec3::new(-0.010, 0.0, 0.0205 - depth_m), rotation: Quat::identity() };
        let input = fissure::sim::FrameInput { poses: vec![Some(pose)] };
        let r = p.step(&mut state, &input).expect("step").clone();
        let c = common::scenes::check_frame(&p, &state, &r, label);
        println!("{label}: depth {depth_m:e} m constrained {} max|u| {:e} m cond {:.3e}", r.constrained_vertices, c.max_displacement_m, c.conditioning);
        if depth_m > 0.0 {
            assert!(r.constrained_vertices > 0, "{label}: pressed {depth_m} m, the top face must be held");
            assert!((c.max_displacement_m - depth_m).abs() <= 1e-12 + 1e-9 * depth_m, "{label}: max |u| {} m must equal the press {depth_m} m", c.max_displacement_m);
            if let Some(n) = previous_count {
                assert!(r.constrained_vertices >= n, "{label}: deeper presses never hold fewer vertices ({} < {n})", r.constrained_vertices);
            }
            previous_count = Some(r.constrained_vertices);
        } else {
            // Touching exactly: held at zero displacement or free; either way nothing moves.
            assert!(c.max_displacement_m < 1e-15, "{label}: touching must not move the tissue: {} m", c.max_displacement_m);
        }
        let _ = k;
    }
}

#[test]
fn rays_lying_in_the_plane_of_the_top_face_claim_only_the_side_face() {
    let dir = tempfile::tempdir().unwrap();
    // A vertical blade left of the block (left face x = -20 mm), face 0 normal +x; its grid rows sit at
    // z = 30, 28, ..., 20, ..., 12 mm: the row at z = 20 mm casts rays in the plane of the top face.
    let mut blade = Blade {
        name: "blade",
        length_mm: 20.0,
        width_mm: 8.0,
        thickness_mm: 1.0,
        along: 10,
        across: 4,
        position_mm: [-21.5, 0.0, 31.0],
        rotation: "Quaternion(0.7071067811865476, 0.0, 0.7071067811865476, 0.0)".into(),
    };
    blade.across = 4;
    let (mut p, mut state) = Scene::new(block_mm(), vec![blade]).build(dir.path());
    let label = "rays in a face's plane";
    let mut last = None;
    for k in 0..=4 {
        // Face 0 from x = -21 mm to -19 mm (1 mm into the left face).
        let x = -21.5 + 2.0 * k as f64 / 4.0;
        last = Some(step_checked(&mut p, &mut state, &[pose_mm([x, 0.0, 31.0], BLADE_DOWN_FACE_PLUS_X)], label));
    }
    let (r, _) = last.unwrap();
    let out = p.collision().unwrap().output();
    let surface = p.surface();
    let rest = p.rest_positions();
    for pair in &out.candidate_pairs {
        let tri = surface.triangles[pair.triangle as usize];
        assert!(
            tri.iter().all(|&v| (rest[v as usize].x + 0.020).abs() < 1e-12),
            "{label}: pair {pair:?} uses a triangle off the left face (a coplanar top triangle must never pair)"
        );
    }
    // Rows z = 20 (in the top face's plane) down to 12 mm: 5 rows x 4 = 20 face-0 rays, all on the left face.
    let face0 = out.candidate_pairs.iter().filter(|p| p.face == 0).count();
    assert!(face0 >= 16, "{label}: the rays at z <= 20 mm must find the left face, got {face0}");
    for (v, x) in state.surface_positions.iter().enumerate() {
        let x0 = rest[v];
        if (x0.x + 0.020).abs() < 1e-12 && x0.z >= 0.012 && x0.y.abs() <= 0.004 - 1e-9 {
            assert!((x.x + 0.019).abs() < 1e-9, "{label}: left-face vertex {v} at x = {} mm, expected -19 mm", x.x * 1e3);
        }
    }
    println!("{label}: {} constrained, {face0} face-0 pairs, inverted {}", r.constrained_vertices, r.inverted_elements);
}
