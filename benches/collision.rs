//! Collision stage timings per backend, in one run (our Fig. 13): paper-12k at 150 /
//! 500 / 2000 nodes a face and both shipped real brains (`assets/brain/`) at 500 /
//! 2000, p50 / p95 a frame of a retraction-like motion, with the GPU
//! backend's breakdown (upload, wait, f64 decisions, and refit / traversal from
//! timestamp queries). The same code as `fissure bench collision`, which runs from
//! the release binary alone (a GPU machine has no Rust toolchain).
//! Run: `cargo bench --bench collision` (GPU rows need an adapter; with lavapipe set
//! VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json WGPU_BACKEND=vulkan).
//! Frames: FISSURE_BENCH_FRAMES (default 40).

use fissure::collision::bench::{self, BenchSurface};

fn main() {
    // `cargo test --all-targets` builds benches; `cargo bench` passes --bench.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let frames = std::env::var("FISSURE_BENCH_FRAMES").ok().and_then(|v| v.parse().ok()).unwrap_or(40);
    let dir = fissure::mesh::brain::shipped_dir();
    let surfaces = bench::standard_surfaces(&dir, None, &mut |n| eprintln!("{n}")).expect("bench surfaces");
    let cases: Vec<(&BenchSurface, u32)> = surfaces.iter().flat_map(|(s, n)| n.iter().map(move |&k| (s, k))).collect();
    println!("{}", bench::TABLE_HEADER);
    let rows = bench::run(&cases, &bench::ALL_BACKENDS, frames, 5, &mut |r| match r {
        Ok(row) => println!("{}", bench::table_row(row)),
        Err(note) => eprintln!("{note}"),
    });
    println!("GPU adapter: {}", bench::device(&rows));
    let mismatch = bench::mismatches(&rows);
    assert!(mismatch.is_empty(), "backends gave different answers on: {mismatch:?}");
}
