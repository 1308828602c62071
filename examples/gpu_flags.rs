//! Why the GPU collision shader flags lines for the CPU: plays the bench's motion on
//! paper-12k and prints how many lines each frame flags; for the first six flagged
//! lines from frame 8 on (the blades in contact) it lists every f64 hit along them.
//! `cargo run --release --example gpu_flags -- [nodes a face]` (needs a GPU adapter).

use fissure::collision::backend::gpu::GpuCaster;
use fissure::collision::backend::{PairLine, RayCaster};
use fissure::collision::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use fissure::geometry::{LineQuery, NodeLayout, SpatulaShape};
use fissure::math::Vec3;

fn main() {
    let nodes: u32 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(500);
    let paper = fissure::collision::bench::BenchSurface::paper12k().expect("paper-12k");
    let (t, rest) = (paper.triangles, paper.positions);
    let (lo, hi) = rest.iter().fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(a, b), q| (a.inf(q), b.sup(q)));
    let length = 0.35 * (hi.x - lo.x);
    let shape = SpatulaShape { length, width: 0.01, thickness: 0.001 };
    let spec = SpatulaSpec { shape, layout: NodeLayout::Grid { along: nodes.div_ceil(10), across: 10 } };
    let mut stage = CollisionStage::new(CollisionConfig { backend: BackendKind::Bvh, culling: true }, &t, &rest, &[spec.clone(), spec]).unwrap();
    let mut gpu = GpuCaster::new(&t, &rest, 10_000).expect("gpu");
    let mut cur = rest.clone();
    let mut shown = 0;
    for f in 0..25 {
        let poses = fissure::collision::bench::poses(lo, hi, length, f as f64 / 25.0);
        let out = stage.step(&cur, &poses).unwrap().clone();
        let lines: Vec<PairLine> = out.source_nodes.iter().filter(|n| n.face == 0).map(|n| PairLine { origin: n.position, direction: n.normal, thickness: 0.001 }).collect();
        gpu.update_surface(&cur).unwrap();
        let mut hits = Vec::new();
        gpu.cast(&lines, &mut hits).unwrap();
        let flags: Vec<u32> = gpu.last_flags().collect();
        let flagged = flags.iter().filter(|&&f| f != 0).count();
        println!("frame {f}: {flagged} of {} lines flagged, {} targets", lines.len(), out.targets.len());
        for (l, &fl) in lines.iter().zip(&flags) {
            if fl == 0 || shown >= 6 || f < 8 {
                continue;
            }
            shown += 1;
            let q = LineQuery::new(l.origin, l.direction).unwrap();
            let mut all: Vec<(f64, u32, f64, f64)> = t
                .iter()
                .enumerate()
                .filter_map(|(k, tri)| q.intersect(&cur[tri[0] as usize], &cur[tri[1] as usize], &cur[tri[2] as usize]).map(|h| (h.t, k as u32, h.u, h.v)))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            println!("  flag {fl}: hits (t mm, tri, u, v): {:?}", all.iter().map(|h| (h.0 * 1e3, h.1, h.2, h.3)).collect::<Vec<_>>());
        }
        cur.copy_from_slice(&rest);
        for tg in &out.targets {
            cur[tg.vertex as usize] = rest[tg.vertex as usize] + tg.displacement;
        }
    }
}
