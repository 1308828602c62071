//! Where a scene's start goes (model, factor, compliance) and what it keeps:
//! `cargo run --release --example startup_probe -- config/real_brain/interhemispheric.ron [PATH=VALUE..]`.
use fissure::scenario::Scenario;
use fissure::sim::replay::PoseSource;
use fissure::sim::{BuildOptions, Pipeline};
use std::path::Path;
use std::time::Instant;

fn peak_rss_mb() -> f64 {
    fissure::fem::meminfo::peak_resident_bytes().map_or(f64::NAN, |b| b as f64 / (1024.0 * 1024.0))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).map(String::as_str).unwrap_or("config/sylvian.ron");
    let overrides: Vec<String> = args.iter().skip(2).cloned().collect();
    let scenario = Scenario::load(Path::new(path), &overrides).expect("scenario");
    let source = PoseSource::for_scenario(&scenario, None).expect("trajectory");
    let t = Instant::now();
    let mut first_progress: Option<f64> = None;
    let mut progress = |done: usize, _total: usize| {
        if done == 0 && first_progress.is_none() {
            first_progress = Some(t.elapsed().as_secs_f64());
        }
    };
    let (pipeline, _state) = Pipeline::build(
        &scenario,
        BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: Some(&mut progress), ..BuildOptions::default() },
    )
    .expect("build");
    let total = t.elapsed().as_secs_f64();
    let model = pipeline.solver().model();
    let fs = model.stats();
    let cs = pipeline.solver().compliance().stats();
    println!("free dofs {}, nnz(K) {}, nnz(L) {}", fs.free_dofs, fs.nnz_k, fs.nnz_l);
    println!("symbolic {:.2} s, numeric {:.2} s", fs.symbolic_seconds, fs.numeric_seconds);
    println!("compliance: rows {}, cols {}, {:.0} MB, compute {:.2} s, load {:.2} s, from cache {}", cs.rows, cs.cols, cs.bytes as f64 / 1e6, cs.compute_seconds, cs.load_seconds, cs.from_cache);
    println!("before the compliance: {:.2} s; whole build {:.2} s; peak RSS {:.0} MB", first_progress.unwrap_or(f64::NAN), total, peak_rss_mb());
}
