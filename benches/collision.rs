//! Collision stage timings (our Fig. 13): two spatulas x two faces x {30, 150, 500,
//! 2000} nodes a face, per backend, one full `step` (BVH refit / GPU upload, rays,
//! pairs, culling, targets) against a 20,480-triangle icosphere (r = 60 mm; the
//! paper-12k phantom replaces it once `mesh::phantom` provides it) and the real brain
//! surface (40,960 triangles; skipped when ../shared is absent).
//! Run: `cargo bench --bench collision` (GPU rows need an adapter; with lavapipe set
//! VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json WGPU_BACKEND=vulkan).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use fissure::collision::scenes::{icosphere, pose_from_axes};
use fissure::collision::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use fissure::geometry::{NodeLayout, Pose, SpatulaShape};
use fissure::math::Vec3;
use std::time::Duration;

const MM: f64 = 1e-3;

fn layout(n: u32) -> NodeLayout {
    let across = match n {
        0..=30 => 5,
        31..=500 => 10,
        _ => 20,
    };
    NodeLayout::Grid { along: n / across, across }
}

/// The real brain surface (OBJ, millimetres) in metres, through the project's own reader.
fn read_obj(path: &str) -> Option<(Vec<[u32; 3]>, Vec<Vec3>)> {
    let mut s = fissure::mesh::io::load_surface(std::path::Path::new(path)).ok()?;
    s.scale(MM);
    Some((s.triangles, s.positions))
}

/// Two spatulas whose blades enter the surface from opposite sides near `centre`.
fn poses(centre: Vec3, reach: f64) -> [Pose; 2] {
    [
        pose_from_axes(centre + Vec3::new(-reach, 2.0 * MM, 10.0 * MM), Vec3::new(1.0, 0.0, -0.3), Vec3::new(0.3, 0.0, 1.0)),
        pose_from_axes(centre + Vec3::new(reach, -2.0 * MM, 10.0 * MM), Vec3::new(-1.0, 0.1, -0.3), Vec3::new(0.0, 1.0, 0.0)),
    ]
}

fn bench_surface(c: &mut Criterion, name: &str, t: &[[u32; 3]], p: &[Vec3]) {
    let (lo, hi) = p.iter().fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(a, b), q| (a.inf(q), b.sup(q)));
    let centre = (lo + hi) / 2.0;
    let reach = (hi.x - lo.x) / 2.0 + 20.0 * MM;
    let shape = SpatulaShape { length: reach, width: 10.0 * MM, thickness: 1.0 * MM };
    let mut g = c.benchmark_group(format!("collision/{name}"));
    g.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(2));
    for backend in [BackendKind::Bvh, BackendKind::Reference, BackendKind::Gpu] {
        for n in [30u32, 150, 500, 2000] {
            let spec = SpatulaSpec { shape, layout: layout(n) };
            let mut stage = CollisionStage::new(CollisionConfig { backend, culling: true }, t, p, &[spec.clone(), spec]).expect("stage");
            if stage.backend() != backend {
                eprintln!("skip {backend:?}: {:?}", stage.warnings());
                break;
            }
            let ps = poses(centre, reach);
            let out = stage.step(p, &ps).expect("step");
            eprintln!("{name} {backend:?} {n}/face: {} candidates, {} feasible", out.candidate_pairs.len(), out.feasible_pairs.len());
            g.bench_with_input(BenchmarkId::new(format!("{backend:?}"), n), &n, |b, _| {
                b.iter(|| stage.step(p, &ps).expect("step").targets.len());
            });
        }
    }
    g.finish();
}

fn collision(c: &mut Criterion) {
    let (t, p) = icosphere(Vec3::zeros(), 60.0 * MM, 5);
    bench_surface(c, "icosphere-20k", &t, &p);
    match fissure::mesh::phantom::generate(fissure::mesh::phantom::Preset::Paper12k) {
        Ok(ph) => {
            let s = ph.mesh.boundary();
            let p = s.gather_positions(&ph.mesh.positions);
            bench_surface(c, "paper-12k", &s.triangles, &p);
        }
        Err(e) => eprintln!("skip paper-12k: {e}"),
    }
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/brain/brain_pial_coarse_surface.obj");
    match read_obj(path) {
        Some((t, p)) => bench_surface(c, "brain-41k", &t, &p),
        None => eprintln!("skip: real brain surface not found at {path}"),
    }
}

criterion_group!(benches, collision);
criterion_main!(benches);
