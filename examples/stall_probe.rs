//! Frames of a replay that take long, and why (lazy solves, phases):
//! `cargo run --release --example stall_probe -- config/sylvian.ron [ms] [PATH=VALUE..]`.
//! With `PACE=1` each frame starts no earlier than its time step after the
//! one before, as in the window (a headless replay otherwise runs several
//! times faster than real time, and work on other threads piles up).
//! `PERF_CTL=fifo PERF_FRAMES=a..b` profiles frames a..b alone: `perf record --control=fifo:fifo -D -1 ..`
//! starts disabled and the probe enables it around those frames.
//! `STOP=k` ends the replay after frame k (a profile's last milliseconds are then that frame's).
//! `TRAJ=path.csv` replays that trajectory instead of the scene's own.
//! `HAND=1` builds as the window does for blades driven by hand: no expected
//! poses (the region of interest from the blades' first poses), the columns in
//! the background (with `PACE=1`, a window session's recording replayed as it ran).
use fissure::scenario::Scenario;
use fissure::sim::poses::TrajectoryPoses;
use fissure::sim::{BuildOptions, FrameInput, Pipeline};
use std::path::Path;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).map(String::as_str).unwrap_or("config/sylvian.ron");
    let slow: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3.0);
    let overrides: Vec<String> = args.iter().skip(3).cloned().collect();
    let scenario = Scenario::load(Path::new(path), &overrides).expect("scenario");
    let traj = std::env::var_os("TRAJ").map(std::path::PathBuf::from);
    let source = TrajectoryPoses::for_scenario(&scenario, traj.as_deref()).expect("trajectory");
    let hand = std::env::var_os("HAND").is_some_and(|v| v == "1");
    let options = if hand {
        BuildOptions { expected_poses: Vec::new(), expected_step_s: scenario.duration / 200.0, progress: None, background_columns: true }
    } else {
        BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: None, ..BuildOptions::default() }
    };
    let (mut pipeline, mut state) = Pipeline::build(&scenario, options).expect("build");
    let mut input = FrameInput::default();
    let dt = scenario.time_step;
    let mut times = Vec::new();
    let mut phases = [0.0f64; 4];
    let (mut screened, mut evaluated) = (0, 0);
    let mut iterations = std::collections::BTreeMap::<usize, usize>::new();
    let pace = std::env::var_os("PACE").is_some_and(|v| v == "1");
    let stop: u64 = std::env::var("STOP").ok().and_then(|s| s.parse().ok()).unwrap_or(u64::MAX);
    let mut perf = PerfControl::from_env();
    let start = Instant::now();
    for k in 0..scenario.step_count().min(stop.saturating_add(1)) {
        source.poses_at((k + 1) as f64 * dt, &mut input);
        if pace {
            let due = std::time::Duration::from_secs_f64(k as f64 * dt);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        perf.around(k);
        let faults0 = minor_faults();
        let t = Instant::now();
        let rep = pipeline.step(&mut state, &input).expect("step").clone();
        let ms = t.elapsed().as_secs_f64() * 1e3;
        times.push(ms);
        let s = pipeline.last_solution();
        let p = pipeline.solver().timings();
        screened += p.screened;
        evaluated += p.evaluated;
        *iterations.entry(s.iterations).or_default() += 1;
        for (acc, t) in phases.iter_mut().zip([p.gather, p.factor, p.candidates, p.surface]) {
            *acc += t * 1e3;
        }
        let faults = minor_faults() - faults0;
        if ms > slow {
            println!(
                "frame {k}: {ms:.2} ms, {faults} page faults (the process's), rows {}, iterations {}, lazy solves {}, skull {}, gather {:.2} factor {:.2} cand {:.2} surface {:.2} (rows gathered {:.2}) lazy {:.2} ms, solve stage {:.2} collision {:.2}",
                s.rows,
                s.iterations,
                s.lazy_solves,
                s.active_sphere_contacts,
                p.gather * 1e3,
                p.factor * 1e3,
                p.candidates * 1e3,
                p.surface * 1e3,
                p.surface_gather * 1e3,
                p.lazy * 1e3,
                rep.times.get(fissure::sim::StageId::Solve).unwrap_or(0.0) * 1e3,
                rep.times.get(fissure::sim::StageId::Collision).unwrap_or(0.0) * 1e3,
            );
        }
    }
    let early = times.len().min(80);
    println!("frames 0..{early}: mean {:.2} ms", times[..early].iter().sum::<f64>() / early.max(1) as f64);
    times.sort_by(|a, b| a.total_cmp(b));
    let n = times.len();
    println!(
        "phases over all frames: gather {:.0} factor {:.0} candidates {:.0} ({evaluated} evaluations made, {screened} screened out) surface {:.0} ms",
        phases[0], phases[1], phases[2], phases[3]
    );
    println!("active-set iterations (count: frames): {iterations:?}");
    println!("{n} frames: p50 {:.2}, p95 {:.2}, max {:.2} ms", times[n / 2], times[n * 95 / 100], times[n - 1]);
}

/// `perf record --control` driven around a range of frames (`PERF_CTL`, `PERF_FRAMES=a..b`).
struct PerfControl {
    fifo: Option<std::fs::File>,
    frames: std::ops::Range<u64>,
    on: bool,
}

impl PerfControl {
    fn from_env() -> Self {
        let fifo = std::env::var_os("PERF_CTL").map(|p| std::fs::OpenOptions::new().write(true).open(p).expect("PERF_CTL fifo"));
        let frames = std::env::var("PERF_FRAMES")
            .ok()
            .and_then(|s| s.split_once("..").and_then(|(a, b)| Some(a.parse().ok()?..b.parse().ok()?)))
            .unwrap_or(0..u64::MAX);
        Self { fifo, frames, on: false }
    }

    /// Before frame `k`: profiling on inside the range, off outside.
    fn around(&mut self, k: u64) {
        use std::io::Write;
        let want = self.frames.contains(&k);
        if let Some(f) = self.fifo.as_mut().filter(|_| want != self.on) {
            let _ = f.write_all(if want { b"enable\n" } else { b"disable\n" });
            let _ = f.flush();
            self.on = want;
        }
    }
}

/// Minor page faults of the process so far (0 where the platform does not say).
fn minor_faults() -> i64 {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: rusage is plain integers (all-zero is a valid value), and getrusage writes the struct it is given.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0 {
            return usage.ru_minflt as i64;
        }
    }
    0
}
