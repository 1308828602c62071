//! Collision stage timings per backend, in one run (our Fig. 13): paper-12k at 150 /
//! 500 / 2000 nodes a face and both real brains at 500 / 2000 (skipped when
//! ../shared is absent), p50 / p95 a frame of a retraction-like motion, with the GPU
//! backend's breakdown (upload, wait, f64 decisions, and refit / traversal from
//! timestamp queries). The same code as `fissure bench collision`, which runs from
//! the release binary alone (a GPU machine has no Rust toolchain).
//! Run: `cargo bench --bench collision` (GPU rows need an adapter; with lavapipe set
//! VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json WGPU_BACKEND=vulkan).
//! Frames: FISSURE_BENCH_FRAMES (default 40).

use fissure::collision::bench::{self, BenchBackend, BenchSurface};
use fissure::math::Vec3;

fn brain(file: &str, name: &str) -> Option<BenchSurface> {
    let path = format!("{}/../shared/data/brain/{file}", env!("CARGO_MANIFEST_DIR"));
    let Ok(mut mesh) = fissure::mesh::io::load_tet_mesh(std::path::Path::new(&path)) else {
        eprintln!("skip {name}: {path} not found");
        return None;
    };
    mesh.scale(1e-3);
    let s = mesh.boundary();
    let positions: Vec<Vec3> = s.gather_positions(&mesh.positions);
    Some(BenchSurface { name: name.into(), triangles: s.triangles.clone(), positions })
}

fn main() {
    // `cargo test --all-targets` builds benches; `cargo bench` passes --bench.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let frames = std::env::var("FISSURE_BENCH_FRAMES").ok().and_then(|v| v.parse().ok()).unwrap_or(40);
    let ph = fissure::mesh::phantom::generate(fissure::mesh::phantom::Preset::Paper12k).expect("paper-12k");
    let s = ph.mesh.boundary();
    let paper = BenchSurface { name: "paper-12k".into(), triangles: s.triangles.clone(), positions: s.gather_positions(&ph.mesh.positions) };
    let coarse = brain("brain_pial_coarse.msh", "brain-coarse");
    let q15 = brain("brain_pial_q15.msh", "brain-q15");
    let mut cases = vec![(&paper, 150), (&paper, 500), (&paper, 2000)];
    for s in [&coarse, &q15].into_iter().flatten() {
        cases.extend([(s, 500), (s, 2000)]);
    }
    println!("{}", bench::TABLE_HEADER);
    bench::run(&cases, &[BenchBackend::Bvh, BenchBackend::BvhAllCores, BenchBackend::Gpu, BenchBackend::Reference], frames, 5, &mut |r| match r {
        Ok(row) => println!("{}", bench::table_row(row)),
        Err(note) => eprintln!("{note}"),
    });
    println!("GPU adapter: {}", bench::device_name(&paper).unwrap_or_else(|| "none".into()));
}
