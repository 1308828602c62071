//! Replays a scenario and, at every frame where a surface vertex ends inside a
//! blade, prints which vertex, how deep, where it sits in the blade's frame and
//! which constraint rows it had: a diagnosis aid for integrity failures.
//! Usage: cargo run --release --example penetration_probe -- SCENARIO [--set PATH=VALUE]...
use fissure::fem::ConstraintKind;
use fissure::math::Vec3;
use fissure::scenario::Scenario;
use fissure::sim::poses::TrajectoryPoses;
use fissure::sim::{BuildOptions, FrameInput, Pipeline};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().ok_or("usage: penetration_probe SCENARIO [--set PATH=VALUE]...")?;
    let sets: Vec<String> = args.iter().skip(1).filter(|a| *a != "--set").cloned().collect();
    let scenario = Scenario::load(std::path::Path::new(path), &sets)?;
    let source = TrajectoryPoses::for_scenario(&scenario, None)?;
    let (mut p, mut state) = Pipeline::build(&scenario, BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: None, ..BuildOptions::default() })?;
    let mut input = FrameInput::default();
    for k in 0..scenario.step_count() {
        source.poses_at((k + 1) as f64 * scenario.time_step, &mut input);
        let (before, poses_before) = (state.surface_positions.clone(), state.poses.clone());
        let r = p.step(&mut state, &input)?.clone();
        if r.penetrating_vertices == 0 && r.crossed_vertices == 0 {
            continue;
        }
        if r.crossed_vertices > 0 {
            for (s, ((shape, pb), pa)) in p.spatula_shapes().iter().zip(&poses_before).zip(&state.poses).enumerate() {
                for (v, (x0, x1)) in before.iter().zip(&state.surface_positions).enumerate() {
                    let q0 = pb.rotation.inverse_transform_vector(&(x0 - pb.position));
                    let q1 = pa.rotation.inverse_transform_vector(&(x1 - pa.position));
                    let over = |q: &Vec3| q.x >= 0.0 && q.x <= shape.length && q.y.abs() <= 0.5 * shape.width;
                    if over(&q1) && q0.z.signum() != q1.z.signum() && (over(&q0) || q0.z.abs() < shape.thickness) {
                        println!("  spatula {s} vertex {v}: frame start {:.4?} mm -> end {:.4?} mm (blade frames), rest {:.3?} mm", q0 * 1e3, q1 * 1e3, p.rest_positions()[v] * 1e3);
                        let node = p.surface().vertices[v];
                        for c in p.last_constraints().iter().filter(|c| c.node == node) {
                            println!("    row: owner {} {:?}", c.owner, c.kind);
                        }
                        if let Some(c) = p.collision() {
                            let t: Vec<_> = c.output().targets.iter().filter(|t| t.vertex as usize == v).map(|t| (t.spatula, t.face, t.depth * 1e3)).collect();
                            println!("    targets (spatula, face, depth mm): {t:?}");
                        }
                    }
                }
            }
        }
        println!("frame {} t {:.2}: penetrating {} (deepest {:.4} mm), crossed {}, substeps {}", r.frame, r.time_s, r.penetrating_vertices, r.max_penetration_m * 1e3, r.crossed_vertices, r.substeps);
        for (s, (shape, pose)) in p.spatula_shapes().iter().zip(&state.poses).enumerate() {
            for (v, x) in state.surface_positions.iter().enumerate() {
                let q = pose.rotation.inverse_transform_vector(&(x - pose.position));
                let inside = q.x >= 0.0 && q.x <= shape.length && q.y.abs() <= 0.5 * shape.width && q.z.abs() < 0.5 * shape.thickness - 1e-7;
                if !inside {
                    continue;
                }
                let node = p.surface().vertices[v];
                let rows: Vec<String> = p
                    .last_constraints()
                    .iter()
                    .filter(|c| c.node == node)
                    .map(|c| match c.kind {
                        ConstraintKind::Contact { displacement, normal } => format!("Contact(owner {}, target {:?} mm, n {:?})", c.owner, (p.rest_positions()[v] + displacement) * 1e3, normal),
                        ConstraintKind::Barrier { displacement, normal } => format!("Barrier(owner {}, plane point {:?} mm, n {:?})", c.owner, (p.rest_positions()[v] + displacement) * 1e3, normal),
                        ConstraintKind::Enforced { .. } => format!("Enforced(owner {})", c.owner),
                        _ => "sphere".into(),
                    })
                    .collect();
                let u: Vec3 = state.surface_displacement[v];
                if let Some(c) = p.collision() {
                    let t: Vec<_> = c.output().targets.iter().filter(|t| t.vertex as usize == v).map(|t| (t.spatula, t.face, t.depth * 1e3)).collect();
                    println!("    targets (spatula, face, depth mm): {t:?}");
                }
                let q0 = poses_before[s].rotation.inverse_transform_vector(&(before[v] - poses_before[s].position));
                println!("    at the frame's start: blade frame {:.4?} mm", q0 * 1e3);
                let fixed = p.solver().model().is_fixed(node);
                println!(
                    "  spatula {s} vertex {v} (node {node}{}): rest {:.3?} mm, blade frame {:.4?} mm, depth {:.4} mm, |u| {:.3} mm, rows {:?}",
                    if fixed { ", FIXED" } else { "" },
                    p.rest_positions()[v] * 1e3,
                    q * 1e3,
                    (0.5 * shape.thickness - q.z.abs()) * 1e3,
                    u.norm() * 1e3,
                    rows
                );
            }
        }
    }
    Ok(())
}
