//! Where a scene's start goes (model, factor, compliance) and what it keeps:
//! `cargo run --release --example startup_probe -- config/real_brain/interhemispheric.ron [PATH=VALUE..] [--background]`.
//! With `--background` (and `solver.early_start: true`) the build returns
//! before the columns are computed, as in the window; the probe then runs the
//! scene's motion paced in real time as the window paces it (one frame every
//! `time_step_s`; `--free-running`: as fast as they go) and says when its
//! first frame was done, which frames took over 50 ms (waiting for columns),
//! and when the last column was final. `--json PATH` also writes the figures
//! as JSON ([`StartupReport`], the type the performance page reads it as).
use fissure::perf::reports::{BuildFigures, ComplianceFigures, EarlyStartFigures, StartupReport};
use fissure::scenario::Scenario;
use fissure::sim::poses::TrajectoryPoses;
use fissure::sim::{BuildOptions, Pipeline};
use std::path::Path;
use std::time::Instant;

fn compliance_figures(pipeline: &Pipeline) -> ComplianceFigures {
    let cs = pipeline.solver().compliance().stats();
    ComplianceFigures {
        rows: cs.rows,
        cols: cs.cols,
        megabytes: cs.bytes as f64 / 1e6,
        compute_s: cs.compute_seconds,
        load_s: cs.load_seconds,
        from_cache: cs.from_cache,
    }
}

/// Writes the report where `--json PATH` says, if it does.
fn write_json(args: &[String], report: &StartupReport) {
    if let Some(path) = args.iter().position(|a| a == "--json").and_then(|i| args.get(i + 1)) {
        let text = serde_json::to_string_pretty(report).expect("the report serializes");
        std::fs::write(path, text).unwrap_or_else(|e| panic!("cannot write {path}: {e}"));
    }
}

fn peak_rss_mb() -> f64 {
    fissure::meminfo::peak_resident_bytes().map_or(f64::NAN, |b| b as f64 / (1024.0 * 1024.0))
}

fn main() {
    // "From start" is from here: the scenario's parse and the trajectory's load count.
    let t = Instant::now();
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).map(String::as_str).unwrap_or("config/sylvian.ron");
    let background = args.iter().any(|a| a == "--background");
    let free_running = args.iter().any(|a| a == "--free-running");
    let json_path = args.iter().position(|a| a == "--json").map(|i| i + 1);
    let overrides: Vec<String> =
        args.iter().enumerate().skip(2).filter(|(i, a)| !a.starts_with("--") && Some(*i) != json_path).map(|(_, a)| a.clone()).collect();
    let scenario = Scenario::load(Path::new(path), &overrides).expect("scenario");
    let source = TrajectoryPoses::for_scenario(&scenario, None).expect("trajectory");
    let mut first_progress: Option<f64> = None;
    let mut progress = |done: usize, _total: usize| {
        if done == 0 && first_progress.is_none() {
            first_progress = Some(t.elapsed().as_secs_f64());
        }
    };
    let (pipeline, _state) = Pipeline::build(
        &scenario,
        BuildOptions {
            expected_poses: source.samples(scenario.duration, 200),
            expected_step_s: scenario.duration / 200.0,
            progress: Some(&mut progress),
            background_columns: background,
        },
    )
    .expect("build");
    let total = t.elapsed().as_secs_f64();
    if background {
        // The scene's motion, frame after frame, as soon as the build returns.
        let mut pipeline = pipeline;
        let mut state = _state;
        let mut input = fissure::sim::FrameInput::default();
        let frames = (scenario.duration / scenario.time_step).round() as usize;
        let (mut first_frame, mut slow, mut worst, mut complete_at) = (None, Vec::new(), 0.0f64, None);
        let dt = std::time::Duration::from_secs_f64(scenario.time_step);
        let mut next = Instant::now();
        for f in 1..=frames {
            if !free_running {
                // The window's pacing: a frame every time step, and a frame
                // late by more than five steps does not make the next ones hurry.
                let now = Instant::now();
                if next > now {
                    std::thread::sleep(next - now);
                } else if now - next > 5 * dt {
                    next = now;
                }
                next += dt;
            }
            source.poses_at(f as f64 * scenario.time_step, &mut input);
            let s = Instant::now();
            pipeline.step(&mut state, &input).expect("frame");
            let ms = s.elapsed().as_secs_f64() * 1e3;
            first_frame.get_or_insert(t.elapsed().as_secs_f64());
            worst = worst.max(ms);
            if ms > 50.0 {
                slow.push((f, ms));
            }
            if complete_at.is_none() && pipeline.solver().compliance().fill_progress().is_none() {
                complete_at = Some((f, t.elapsed().as_secs_f64()));
            }
        }
        let motion_end = t.elapsed().as_secs_f64();
        pipeline.solver().compliance().wait_complete().expect("columns");
        println!("build returned {total:.2} s; first frame done {:.2} s from start", first_frame.unwrap_or(f64::NAN));
        println!(
            "{frames} frames done {motion_end:.2} s from start; slowest {worst:.0} ms; {} frames over 50 ms: {:?}",
            slow.len(),
            slow.iter().take(12).map(|(f, ms)| format!("{f}: {ms:.0} ms")).collect::<Vec<_>>()
        );
        let columns_final_s = complete_at.map_or_else(|| t.elapsed().as_secs_f64(), |(_, s)| s);
        match complete_at {
            Some((f, s)) => println!("every column final by frame {f} ({s:.2} s from start)"),
            None => println!("every column final {columns_final_s:.2} s from start (after the motion)"),
        }
        let cs = pipeline.solver().compliance().stats();
        println!(
            "compliance: rows {}, cols {}, {:.0} MB, {} in {:.2} s; peak RSS {:.0} MB",
            cs.rows,
            cs.cols,
            cs.bytes as f64 / 1e6,
            if cs.from_cache { "read from the cache" } else { "computed" },
            cs.compute_seconds + cs.load_seconds,
            peak_rss_mb()
        );
        let early_start = EarlyStartFigures {
            build_returned_s: total,
            first_frame_s: first_frame.unwrap_or(f64::NAN),
            frames,
            motion_done_s: motion_end,
            slowest_frame_ms: worst,
            frames_over_50ms: slow.len(),
            columns_final_s,
            peak_rss_mb: peak_rss_mb(),
            compliance: compliance_figures(&pipeline),
        };
        write_json(&args, &StartupReport { scenario: path.to_string(), build: None, early_start: Some(early_start) });
        return;
    }
    let model = pipeline.solver().model();
    let fs = model.stats();
    let cs = pipeline.solver().compliance().stats();
    println!("free dofs {}, nnz(K) {}, nnz(L) {}", fs.free_dofs, fs.nnz_k, fs.nnz_l);
    println!("symbolic {:.2} s, numeric {:.2} s", fs.symbolic_seconds, fs.numeric_seconds);
    println!("compliance: rows {}, cols {}, {:.0} MB, compute {:.2} s, load {:.2} s, from cache {}", cs.rows, cs.cols, cs.bytes as f64 / 1e6, cs.compute_seconds, cs.load_seconds, cs.from_cache);
    println!("before the compliance: {:.2} s; build done {:.2} s from start; peak RSS {:.0} MB", first_progress.unwrap_or(f64::NAN), total, peak_rss_mb());
    let build = BuildFigures {
        before_compliance_s: first_progress.unwrap_or(f64::NAN),
        build_s: total,
        peak_rss_mb: peak_rss_mb(),
        compliance: compliance_figures(&pipeline),
    };
    write_json(&args, &StartupReport { scenario: path.to_string(), build: Some(build), early_start: None });
}
