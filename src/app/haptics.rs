//! 1 kHz force output between simulation frames.
//!
//! In: after each simulation frame, a [`HapticModel`] (the frame's poses, the
//! force each spatula exerts on the tissue, and each spatula's 3x3 contact
//! stiffness from the FEM stage's current contact compliance); at every tick, the
//! spatulas' current poses from a probe. Out: [`ForceOutput::latest`] — the
//! force ON each spatula (the reaction a haptic device renders), newtons, world
//! axes, with its timestamp — updated at 1 kHz on its own thread, and optionally
//! sent over OpenIGTLink (`SENSOR` message `Force_<spatula name>`).
//!
//! The model: with the active contact set of the last frame fixed, the force
//! on the tissue is linear in the spatula's displacement, `F(p) = F_frame +
//! K (p - p_frame)`, where column j of `K` is
//! `ConstrainedSolver::spatula_force_delta(owner, e_j)` (`W^-1` applied to a
//! unit translation of every enforced vertex of that spatula; exact for the
//! linear model while the contact set holds). The force on the tool is
//! `-F(p)`. Rotation between frames is not rendered until the next frame (at
//! most one time step later). Stays true: with the pose unchanged the output
//! equals the simulation's force to rounding; the tick loop does not allocate;
//! a missing pose holds the frame's pose.

use crate::geometry::Pose;
use crate::math::Vec3;
use crate::sim::{FrameReport, Pipeline};
use nalgebra::Matrix3;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The haptic rate, Hz.
pub const HAPTIC_RATE_HZ: f64 = 1000.0;

/// What the haptic loop needs from one simulation frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HapticModel {
    /// Simulated time of the frame, s.
    pub time_s: f64,
    /// Poses the frame used, per spatula.
    pub poses: Vec<Pose>,
    /// Force each spatula exerts on the tissue at those poses, N (= `FrameReport` force).
    pub tissue_force_n: Vec<Vec3>,
    /// d(tissue force)/d(spatula translation), N/m, per spatula.
    pub stiffness_n_per_m: Vec<Matrix3<f64>>,
}

impl HapticModel {
    /// The model of the frame just stepped. `scratch` is reused (no allocation once grown).
    pub fn of_frame(pipeline: &Pipeline, poses: &[Pose], report: &FrameReport, scratch: &mut Vec<f64>) -> Self {
        let mut model = Self::default();
        model.update(pipeline, poses, report, scratch);
        model
    }

    /// Refills `self` from the frame just stepped.
    pub fn update(&mut self, pipeline: &Pipeline, poses: &[Pose], report: &FrameReport, scratch: &mut Vec<f64>) {
        self.time_s = report.time_s;
        self.poses.clear();
        self.poses.extend_from_slice(poses);
        self.tissue_force_n.clear();
        self.stiffness_n_per_m.clear();
        for (k, s) in report.spatulas.iter().enumerate() {
            self.tissue_force_n.push(s.force);
            let mut m = Matrix3::zeros();
            if s.constrained_vertices > 0 {
                for j in 0..3 {
                    let mut e = Vec3::zeros();
                    e[j] = 1.0;
                    let column = pipeline.solver().spatula_force_delta(k as u16, e, scratch);
                    m.set_column(j, &column);
                }
            }
            self.stiffness_n_per_m.push(m);
        }
    }

    /// Force ON spatula `k` (the tool) at `pose`, N; zero for an unknown spatula.
    pub fn tool_force(&self, k: usize, pose: Option<&Pose>) -> Vec3 {
        let (Some(f), Some(stiffness), Some(frame_pose)) =
            (self.tissue_force_n.get(k), self.stiffness_n_per_m.get(k), self.poses.get(k))
        else {
            return Vec3::zeros();
        };
        let delta = match pose {
            Some(p) if p.is_valid() => p.position - frame_pose.position,
            _ => Vec3::zeros(),
        };
        -(f + stiffness * delta)
    }
}

/// Where the haptic loop reads the spatulas' current poses: `probe(k, since_frame_s)`
/// returns spatula k's pose now (`None` holds the frame's pose).
pub type PoseProbe = Box<dyn FnMut(usize, f64) -> Option<Pose> + Send>;

/// Where the haptic loop sends each tick's forces (e.g. OpenIGTLink): `(spatula, timestamp_s, force_n)`.
pub type ForceSink = Box<dyn FnMut(usize, f64, Vec3) + Send>;

#[derive(Debug, Default)]
struct Shared {
    model: Mutex<(Arc<HapticModel>, Option<Instant>)>,
    latest: Mutex<Vec<(Vec3, f64)>>,
    ticks: AtomicU64,
    stop: AtomicBool,
}

/// The 1 kHz force loop and its latest output.
pub struct ForceOutput {
    shared: Arc<Shared>,
    start: Instant,
    thread: Option<JoinHandle<()>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl ForceOutput {
    /// Starts the loop for `spatulas` spatulas at `rate_hz` (> 0; [`HAPTIC_RATE_HZ`] normally).
    pub fn start(spatulas: usize, rate_hz: f64, mut probe: PoseProbe, mut sink: Option<ForceSink>) -> Self {
        let shared = Arc::new(Shared::default());
        *lock(&shared.latest) = vec![(Vec3::zeros(), 0.0); spatulas];
        let start = Instant::now();
        let period = Duration::from_secs_f64(1.0 / rate_hz.clamp(1.0, 20_000.0));
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("fissure-haptics".into())
            .spawn(move || {
                let mut next = Instant::now();
                let mut forces = vec![Vec3::zeros(); spatulas];
                while !s.stop.load(Ordering::Relaxed) {
                    let (model, published) = {
                        let g = lock(&s.model);
                        (g.0.clone(), g.1)
                    };
                    let since = published.map(|t| t.elapsed().as_secs_f64()).unwrap_or(0.0);
                    for (k, f) in forces.iter_mut().enumerate() {
                        let pose = probe(k, since);
                        *f = model.tool_force(k, pose.as_ref());
                    }
                    let now = start.elapsed().as_secs_f64();
                    {
                        let mut latest = lock(&s.latest);
                        for (slot, f) in latest.iter_mut().zip(&forces) {
                            *slot = (*f, now);
                        }
                    }
                    if let Some(sink) = sink.as_mut() {
                        for (k, f) in forces.iter().enumerate() {
                            sink(k, now, *f);
                        }
                    }
                    s.ticks.fetch_add(1, Ordering::Relaxed);
                    next += period;
                    let now = Instant::now();
                    if next > now {
                        std::thread::sleep(next - now);
                    } else if now - next > period * 10 {
                        next = now; // fell far behind (suspended): do not burst
                    }
                }
            })
            .ok();
        if thread.is_none() {
            tracing::warn!("could not start the haptic thread; force output stays at zero");
        }
        Self { shared, start, thread }
    }

    /// Publishes the model of a new simulation frame (cheap: an `Arc` swap).
    pub fn publish(&self, model: Arc<HapticModel>) {
        *lock(&self.shared.model) = (model, Some(Instant::now()));
    }

    /// The latest force ON spatula `k` (N, world axes) and when it was computed
    /// (s since this output started); `None` for an unknown spatula.
    pub fn latest(&self, k: usize) -> Option<(Vec3, f64)> {
        lock(&self.shared.latest).get(k).copied()
    }

    /// Ticks done so far.
    pub fn ticks(&self) -> u64 {
        self.shared.ticks.load(Ordering::Relaxed)
    }

    /// Seconds since the output started.
    pub fn elapsed_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Whether the loop thread is running.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }
}

impl Drop for ForceOutput {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> HapticModel {
        HapticModel {
            time_s: 0.1,
            poses: vec![Pose::default(); 2],
            tissue_force_n: vec![Vec3::new(0.0, 0.0, 0.5), Vec3::zeros()],
            stiffness_n_per_m: vec![Matrix3::from_diagonal(&Vec3::new(10.0, 20.0, 30.0)), Matrix3::zeros()],
        }
    }

    #[test]
    fn tool_force_is_minus_tissue_force_plus_stiffness_times_motion() {
        let m = model();
        assert_eq!(m.tool_force(0, None), Vec3::new(0.0, 0.0, -0.5), "no motion: minus the frame's force");
        let moved = Pose { position: Vec3::new(0.0, 0.0, 0.01), ..Pose::default() };
        let f = m.tool_force(0, Some(&moved));
        assert!((f - Vec3::new(0.0, 0.0, -0.8)).norm() < 1e-12, "0.5 + 30 N/m * 1 cm = 0.8 N, got {f:?}");
        assert_eq!(m.tool_force(5, None), Vec3::zeros(), "unknown spatula reads zero");
    }

    #[test]
    fn loop_ticks_and_reports_the_model_force() {
        let out = ForceOutput::start(2, HAPTIC_RATE_HZ, Box::new(|_, _| None), None);
        out.publish(Arc::new(model()));
        let deadline = Instant::now() + Duration::from_secs(5);
        while out.ticks() < 60 && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(out.ticks() >= 60, "the loop must tick (got {} ticks)", out.ticks());
        std::thread::sleep(Duration::from_millis(5));
        let (f, t) = out.latest(0).expect("spatula 0 exists");
        assert_eq!(f, Vec3::new(0.0, 0.0, -0.5), "pose unchanged: the frame's force, negated");
        assert!(t > 0.0, "timestamp must advance");
        assert!(out.latest(2).is_none());
    }
}
