//! How a scene's contact rows change from frame to frame, and why a frame takes
//! more than one active-set iteration:
//! `cargo run --release --example contact_churn -- config/sylvian.ron FROM TO [PATH=VALUE..]`.
//! For each frame from FROM to TO (the scene's own trajectory): its rows,
//! active-set iterations and active barrier rows, then the constraints that
//! came and went since the frame before (mesh node, blade, kind and the
//! normal's components in thousandths, with the force on the tissue, N) and
//! the rows that turned on or off. A settled hold lists none. With
//! `WATCH=node,node,..` it also prints where each watched mesh node starts
//! the frame in each blade's frame (mm; the footprint is 0 <= x <= length,
//! |y| <= width / 2, the faces at z = +-thickness / 2), which tells a vertex
//! lifted onto a face from one resting beside an edge.
use fissure::fem::ConstraintKind;
use fissure::math::Vec3;
use fissure::scenario::Scenario;
use fissure::sim::poses::TrajectoryPoses;
use fissure::sim::{BuildOptions, FrameInput, Pipeline};
use std::collections::BTreeMap;
use std::path::Path;

/// A constraint as the frame before can be matched to it: node, blade or sphere, kind, normal in thousandths.
type Key = (u32, u16, &'static str, [i64; 3]);

fn key(kind: &ConstraintKind, node: u32, owner: u16) -> Key {
    let milli = |n: &Vec3| [0, 1, 2].map(|i| (n[i] * 1000.0).round() as i64);
    match kind {
        ConstraintKind::Contact { normal, .. } => (node, owner, "contact", milli(normal)),
        ConstraintKind::Barrier { normal, .. } => (node, owner, "barrier", milli(normal)),
        ConstraintKind::Enforced { .. } => (node, owner, "enforced", [0; 3]),
        ConstraintKind::SphereInside { .. } | ConstraintKind::SphereOutside { .. } => (node, owner, "sphere", [0; 3]),
    }
}

fn listed<'a>(entries: impl Iterator<Item = (&'a Key, &'a f64)>) -> String {
    entries.map(|((node, owner, kind, n), f)| format!("{node}/{owner} {kind} ({}, {}, {}) {f:.2e}", n[0], n[1], n[2])).collect::<Vec<_>>().join("; ")
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: contact_churn SCENARIO FROM TO [PATH=VALUE..]");
        std::process::exit(2);
    }
    let from: u64 = args[2].parse().expect("FROM: a frame number");
    let to: u64 = args[3].parse().expect("TO: a frame number");
    let overrides: Vec<String> = args.iter().skip(4).cloned().collect();
    let scenario = Scenario::load(Path::new(&args[1]), &overrides).unwrap_or_else(|e| panic!("{e}"));
    let source = TrajectoryPoses::for_scenario(&scenario, None).expect("trajectory");
    let (mut pipeline, mut state) =
        Pipeline::build(&scenario, BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: None, ..BuildOptions::default() }).expect("build");
    let watch: Vec<u32> = std::env::var("WATCH").unwrap_or_default().split(',').filter_map(|s| s.trim().parse().ok()).collect();
    let mut input = FrameInput::default();
    let mut before: BTreeMap<Key, f64> = BTreeMap::new();
    for k in 0..=to.min(scenario.step_count().saturating_sub(1)) {
        source.poses_at((k + 1) as f64 * scenario.time_step, &mut input);
        if k >= from {
            for &node in &watch {
                let Some(v) = pipeline.surface().vertices.iter().position(|&n| n == node) else {
                    println!("  node {node}: not a surface vertex");
                    continue;
                };
                let p = state.surface_positions[v];
                for (s, pose) in state.poses.iter().enumerate() {
                    let q = pose.rotation.inverse_transform_vector(&(p - pose.position)) * 1e3;
                    println!("  node {node} starts at ({:.4}, {:.4}, {:.4}) mm in blade {s}'s frame", q.x, q.y, q.z);
                }
            }
        }
        pipeline.step(&mut state, &input).unwrap_or_else(|e| panic!("frame {k}: {e}"));
        if k < from {
            continue;
        }
        let s = pipeline.last_solution();
        let now: BTreeMap<Key, f64> =
            pipeline.last_constraints().iter().zip(&s.reactions).map(|(c, r)| (key(&c.kind, c.node, c.owner), r.norm())).collect();
        println!("frame {k}: {} constraints, {} rows, {} iterations, {} barrier rows active", now.len(), s.rows, s.iterations, s.barrier_contacts);
        if k > from {
            let came = listed(now.iter().filter(|(c, _)| !before.contains_key(c)));
            let went = listed(before.iter().filter(|(c, _)| !now.contains_key(c)));
            let switched = listed(now.iter().filter(|(c, f)| before.get(c).is_some_and(|b| (*b > 0.0) != (**f > 0.0))));
            for (what, list) in [("came", came), ("went", went), ("turned on or off", switched)] {
                if !list.is_empty() {
                    println!("  {what}: {list}");
                }
            }
        }
        before = now;
    }
}
